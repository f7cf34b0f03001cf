"""``rovis detect`` (one pair, sequences, bad input), ``rovis demo``, and the pictures."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

import rovis
from rovis.cli import main
from rovis.sequence import FramePair, pair_images
from rovis.synth import write_dataset

DETECTION_KEYS = {"objects", "desk_plane", "world_frame", "segmentation", "timing_ms", "warnings"}
OBJECT_KEYS = {"id", "center", "R", "quaternion_xyzw", "euler_zxz_deg", "yaw_deg", "size",
               "corners_world", "corners_left_px", "corners_right_px", "reprojection_error_px",
               "quality", "source"}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """Two synthetic scenes (DESIGN §3 layout), rendered once for the module."""
    return write_dataset(tmp_path_factory.mktemp("ds") / "ds", n=2, seed=3)


def _scene(ds: Path, i: int) -> tuple[str, str]:
    d = ds / "scenes" / f"{i:04d}"
    return str(d / "left.png"), str(d / "right.png")


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    return lines[0]


# --------------------------------------------------------------------------- one pair


def test_detect_one_pair_writes_the_design_json_and_pictures(dataset, tmp_path, capsys):
    left, right = _scene(dataset, 0)
    out_json, out_dir, view = tmp_path / "det.json", tmp_path / "ov", tmp_path / "world.png"
    assert main(["detect", left, right, "--calib", str(dataset / "calib.yaml"), "--json",
                 str(out_json), "--overlay", str(out_dir), "--view", str(view)]) == 0
    out = capsys.readouterr().out
    assert "book" in out and str(out_json) in out
    doc = json.loads(out_json.read_text())
    assert DETECTION_KEYS <= set(doc)
    assert doc["left"] == left and doc["right"] == right
    assert doc["world_frame"] == "marker"
    assert set(doc["segmentation"]) == {"left", "right"}
    for info in doc["segmentation"].values():
        assert {"T_H", "T_HG", "y", "iterations"} <= set(info)
    for obj in doc["objects"]:
        assert OBJECT_KEYS <= set(obj)
        assert np.shape(obj["corners_left_px"]) == (4, 2)
    h, w = cv2.imread(left, cv2.IMREAD_UNCHANGED).shape[:2]
    for cam in ("left", "right"):
        img = cv2.imread(str(out_dir / f"{cam}.png"), cv2.IMREAD_UNCHANGED)
        assert img.shape == (h, w, 3) and img.dtype == np.uint8
    assert cv2.imread(str(view)) is not None
    assert not list(tmp_path.rglob(".*"))  # no temporary files left behind


def test_detect_missing_file_is_one_line_and_exit_2(dataset, tmp_path, capsys):
    left, _ = _scene(dataset, 0)
    missing = str(tmp_path / "nope.png")
    assert main(["detect", left, missing, "--calib", str(dataset / "calib.yaml")]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "nope.png" in line and "not found" in line


def test_detect_size_mismatch_is_one_line_and_exit_2(dataset, tmp_path, capsys):
    left, right = _scene(dataset, 0)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), cv2.imread(left, cv2.IMREAD_UNCHANGED)[:600, :800])
    assert main(["detect", str(small), right, "--calib", str(dataset / "calib.yaml")]) == 2
    assert "image sizes differ" in _one_error_line(capsys.readouterr().err)
    assert main(["detect", str(small), str(small), "--calib", str(dataset / "calib.yaml")]) == 2
    assert "does not match the calibration" in _one_error_line(capsys.readouterr().err)


def test_detect_broken_calibration_is_one_line_and_exit_2(dataset, tmp_path, capsys):
    left, right = _scene(dataset, 0)
    bad = tmp_path / "calib.yaml"
    bad.write_text("%YAML:1.0\n---\nimage_width: 1024\nimage_height: 768\n")
    assert main(["detect", left, right, "--calib", str(bad)]) == 2
    assert "calib.yaml" in _one_error_line(capsys.readouterr().err)


# --------------------------------------------------------------------------- sequences


def _copy_with_truncated_frame(dataset: Path, tmp_path: Path) -> Path:
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    bad = ds / "scenes" / "0001" / "left.png"
    data = bad.read_bytes()
    bad.write_bytes(data[: len(data) // 2])  # a truncated PNG
    return ds


def test_sequence_skips_a_truncated_image_and_keeps_the_rest(dataset, tmp_path, capsys):
    ds = _copy_with_truncated_frame(dataset, tmp_path)
    jsonl = tmp_path / "out" / "frames.jsonl"
    code = main(["detect", str(ds / "scenes" / "*" / "left.png"),
                 str(ds / "scenes" / "*" / "right.png"), "--calib", str(ds / "calib.yaml"),
                 "--json", str(jsonl), "--overlay", str(tmp_path / "ov")])
    assert code == 0
    cap = capsys.readouterr()
    assert "0001/left.png" in cap.err and "cannot read image" in cap.err
    assert "2 frames" in cap.out or "of 2 frames" in cap.out
    frames = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert [f["frame"] for f in frames] == [0, 1]
    good, bad = frames
    assert DETECTION_KEYS <= set(good) and "error" not in good
    assert good["left"].endswith("0000/left.png") and good["right"].endswith("0000/right.png")
    assert "cannot read image" in bad["error"] and bad["left"].endswith("0001/left.png")
    assert (tmp_path / "ov" / "0000_left.png").exists()
    assert not (tmp_path / "ov" / "0001_left.png").exists()


def test_sequence_with_no_good_frame_exits_2(dataset, tmp_path, capsys):
    ds = _copy_with_truncated_frame(dataset, tmp_path)
    (ds / "scenes" / "0000" / "right.png").write_bytes(b"not a png")
    jsonl = tmp_path / "frames.jsonl"
    assert main(["detect", str(ds / "scenes" / "*" / "left.png"),
                 str(ds / "scenes" / "*" / "right.png"), "--calib", str(ds / "calib.yaml"),
                 "--json", str(jsonl)]) == 2
    assert "no frame could be processed" in capsys.readouterr().err
    assert all("error" in json.loads(line) for line in jsonl.read_text().splitlines())


def test_sequence_interrupted_keeps_the_frames_done(dataset, tmp_path, capsys, monkeypatch):
    import rovis.sequence as sequence

    real = sequence.run_pair
    calls = []

    def interrupt_second(detector, pair, **kw):
        calls.append(pair.index)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(detector, pair, **kw)

    monkeypatch.setattr(sequence, "run_pair", interrupt_second)
    jsonl = tmp_path / "frames.jsonl"
    assert main(["detect", str(dataset / "scenes" / "*" / "left.png"),
                 str(dataset / "scenes" / "*" / "right.png"), "--calib",
                 str(dataset / "calib.yaml"), "--json", str(jsonl)]) == 130
    assert "interrupted" in capsys.readouterr().out
    lines = jsonl.read_text().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["frame"] == 0
    assert not list(tmp_path.glob(".*"))


def test_pairs_by_shared_name_or_sorted_order(tmp_path):
    p = [Path(s) for s in ("a/left01.jpg", "a/left02.jpg", "a/left03.jpg")]
    q = [Path(s) for s in ("a/right02.jpg", "a/right01.jpg")]
    pairs = pair_images(p, sorted(q))
    assert pairs[0] == FramePair(0, p[0], Path("a/right01.jpg"))
    assert pairs[2] == FramePair(2, p[2], None)  # no partner: a bad frame, not a shift
    scenes = pair_images([Path("ds/0000/left.png"), Path("ds/0001/left.png")],
                         [Path("ds/0000/right.png"), Path("ds/0001/right.png")])
    assert [(f.left.parent.name, f.right.parent.name) for f in scenes] == [("0000", "0000"),
                                                                            ("0001", "0001")]
    by_order = pair_images([Path("L/a.png"), Path("L/b.png")], [Path("R/x.png"), Path("R/y.png")])
    assert [(f.left.name, f.right.name) for f in by_order] == [("a.png", "x.png"),
                                                                ("b.png", "y.png")]
    with pytest.raises(ValueError, match="2 left images but 1 right"):
        pair_images([Path("L/a.png"), Path("L/b.png")], [Path("R/x.png")])


# --------------------------------------------------------------------------- pictures, API, demo


def test_overlay_and_world_view_have_the_right_size(dataset, tmp_path):
    from rovis import viz

    left, right = _scene(dataset, 0)
    rig = rovis.load_calibration(dataset / "calib.yaml")
    res = rovis.detect(cv2.imread(left), cv2.imread(right), rig)
    truth = json.loads((dataset / "scenes" / "0000" / "truth.json").read_text())
    for img_path, cam in ((left, "left"), (right, "right")):
        img16 = cv2.imread(img_path, cv2.IMREAD_UNCHANGED).astype(np.uint16) * 257
        drawn = viz.overlay(img16, res, cam, rig=rig)
        assert drawn.shape == (*img16.shape[:2], 3) and drawn.dtype == np.uint8
    png = viz.world_view(res, tmp_path / "w" / "world.png", truth=truth)
    img = cv2.imread(str(png))
    assert img is not None and img.shape[0] > 300 and img.shape[1] > 300
    assert len(viz.truth_cuboids(truth)) == len(truth["books"])


def test_the_python_api_exports_detect_and_detector():
    assert {"detect", "Detector", "DetectConfig", "FrameResult"} <= set(rovis.__all__)
    assert rovis.Detector is rovis.pipeline.Detector


def test_demo_writes_its_folder_and_reports_against_the_truth(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "true books" in text and str(out) in text
    for name in ("detections.json", "overlay_left.png", "overlay_right.png", "world.png",
                 "calib.yaml", "left.png", "right.png"):
        assert (out / name).is_file(), name
    doc = json.loads((out / "detections.json").read_text())
    assert DETECTION_KEYS <= set(doc) and doc["world_frame"] == "marker"
    assert cv2.imread(str(out / "overlay_left.png")).shape == (768, 1024, 3)
    # every detection the demo matched lies on a true book within the 1 cm grasp tolerance
    truth = json.loads((out / "truth.json").read_text())
    centres = np.array([b["center"] for b in truth["books"]])
    assert doc["objects"], "the demo scene should show at least one book found"
    for obj in doc["objects"]:
        err = np.abs(centres - obj["center"]).max(axis=1).min()
        assert err < 0.01 or "false detection" in text
