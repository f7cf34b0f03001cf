"""Calibration readers and writer: every format round-trips; bad files are refused by key."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from rovis import geometry
from rovis.calib import StereoRig, load_calibration, save_calibration
from rovis.cli import main

SIZE = (1024, 768)


@pytest.fixture
def verged_rig() -> StereoRig:
    """A rig whose cameras are not parallel, so R and T conventions are really exercised."""
    K1 = np.array([[801.0, 0.0, 515.0], [0.0, 799.0, 380.0], [0.0, 0.0, 1.0]])
    K2 = np.array([[805.0, 0.0, 509.0], [0.0, 803.5, 386.0], [0.0, 0.0, 1.0]])
    R = Rotation.from_euler("xyz", [0.4, -2.0, 0.3], degrees=True).as_matrix()
    return StereoRig.from_arrays(K1=K1, D1=[-0.1, 0.05, 0.001, -0.0005, 0.0], K2=K2,
                                 D2=[-0.09, 0.04, 0.0, 0.0, 0.0], R=R, T=[-0.12, 0.002, 0.004],
                                 image_size=SIZE)


def _assert_same_rig(a: StereoRig, b: StereoRig, atol: float = 1e-9) -> None:
    for key in ("K1", "D1", "K2", "D2", "R", "T", "T_world_left"):
        np.testing.assert_allclose(getattr(a, key), getattr(b, key), atol=atol, err_msg=key)
    assert a.image_size == b.image_size


def _write_opencv(path: Path, values: dict) -> Path:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in values.items():
        fs.write(key, value)
    fs.release()
    return path


def _canonical_values(rig: StereoRig) -> dict:
    return dict(image_width=SIZE[0], image_height=SIZE[1], K1=rig.K1, D1=rig.D1.reshape(1, 5),
                K2=rig.K2, D2=rig.D2.reshape(1, 5), R=rig.R, T=rig.T.reshape(3, 1))


def test_canonical_yaml_round_trips(tmp_path, verged_rig, rig):
    save_calibration(verged_rig, tmp_path / "calib.yaml")
    _assert_same_rig(load_calibration(tmp_path / "calib.yaml"), verged_rig, atol=1e-12)
    save_calibration(rig, tmp_path / "world.yaml")  # with a world transform
    back = load_calibration(tmp_path / "world.yaml")
    _assert_same_rig(back, rig, atol=1e-12)
    assert back.world_frame == "marker"
    assert list(tmp_path.iterdir()) == [tmp_path / "calib.yaml", tmp_path / "world.yaml"] or \
        sorted(p.name for p in tmp_path.iterdir()) == ["calib.yaml", "world.yaml"]  # no temp left


def test_boofcv_stereo_yaml_is_converted_to_metres_and_left_to_right(bumblebee_dir):
    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    assert rig.image_size == (640, 480)
    assert rig.K1[0, 0] == pytest.approx(524.6141554796689)
    assert rig.D1[:2] == pytest.approx([-0.3625365821238732, 0.17532754393079863])
    assert rig.baseline == pytest.approx(0.12005, abs=1e-5)  # 120.05 mm
    assert rig.T[0] < 0  # the right camera sits at +x of the left: X_right = X_left - B
    # Round trip of one point between the two camera frames.
    R_rl = np.array([0.9999694757041413, -0.002167658916924345, 0.007506591423858594,
                     0.002144760822245101, 0.9999930270271246, 0.0030571061711613945,
                     -0.007513165844052039, -0.003040913011953583, 0.999967152054033]).reshape(3, 3)
    t_rl = np.array([120.04374261980637, 0.8974418603859871, -0.9149583203134171]) / 1000
    X_right = np.array([0.1, -0.05, 0.4])
    np.testing.assert_allclose(rig.R @ (R_rl @ X_right + t_rl) + rig.T, X_right, atol=1e-12)


def test_kalibr_camchain(tmp_path, verged_rig):
    r = verged_rig
    chain = {
        f"cam{i}": {"camera_model": "pinhole", "distortion_model": "radtan",
                    "intrinsics": [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])],
                    "distortion_coeffs": D[:4].tolist(), "resolution": list(SIZE)}
        for i, (K, D) in enumerate([(r.K1, r.D1), (r.K2, r.D2)])}
    chain["cam1"]["T_cn_cnm1"] = r.T_right_left.tolist()
    (tmp_path / "camchain.yaml").write_text(yaml.safe_dump(chain))
    _assert_same_rig(load_calibration(tmp_path / "camchain.yaml"), verged_rig)


def test_ros_camera_info_pair(tmp_path, verged_rig):
    r = verged_rig
    R1, R2, P1, P2, *_ = cv2.stereoRectify(r.K1, r.D1, r.K2, r.D2, SIZE, r.R, r.T.reshape(3, 1).copy())
    paths = []
    for side, K, D, Rr, P in (("left", r.K1, r.D1, R1, P1), ("right", r.K2, r.D2, R2, P2)):
        info = {"image_width": SIZE[0], "image_height": SIZE[1], "camera_name": side,
                "camera_matrix": {"rows": 3, "cols": 3, "data": K.ravel().tolist()},
                "distortion_model": "plumb_bob",
                "distortion_coefficients": {"rows": 1, "cols": 5, "data": D.tolist()},
                "rectification_matrix": {"rows": 3, "cols": 3, "data": Rr.ravel().tolist()},
                "projection_matrix": {"rows": 3, "cols": 4, "data": P.ravel().tolist()}}
        paths.append(tmp_path / f"{side}.yaml")
        paths[-1].write_text(yaml.safe_dump(info))
    _assert_same_rig(load_calibration(*paths), verged_rig, atol=1e-9)
    with pytest.raises(ValueError, match="give the right camera's file too"):
        load_calibration(paths[0])
    with pytest.raises(ValueError, match="swapped"):
        load_calibration(paths[1], paths[0])


def test_paper_projection_matrices(tmp_path, rig):
    # The paper's form has no distortion: build the same rig without it.
    ideal = StereoRig.from_arrays(K1=rig.K1, D1=np.zeros(5), K2=rig.K2, D2=np.zeros(5), R=rig.R,
                                  T=rig.T, image_size=SIZE, T_world_left=rig.T_world_left)
    (tmp_path / "q.yaml").write_text(yaml.safe_dump(
        {"Q_L": (3.0 * ideal.Q_L).tolist(), "Q_R": ideal.Q_R.tolist()}))
    back = load_calibration(tmp_path / "q.yaml")
    assert back.image_size is None and back.world_frame == "calibration"
    np.testing.assert_allclose(back.Q_L, ideal.Q_L, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(back.Q_R, ideal.Q_R, rtol=1e-9, atol=1e-9)
    P = np.array([[0.3, 0.2, 0.05]])
    np.testing.assert_allclose(back.triangulate(ideal.project(P, "left"), ideal.project(P, "right")),
                               P, atol=1e-9)


def test_project_and_undistort_are_inverse(verged_rig):
    rng = np.random.default_rng(0)
    P = rng.uniform([-0.4, -0.3, 0.8], [0.4, 0.3, 1.5], (200, 3))
    for cam in ("left", "right"):
        raw = verged_rig.project(P, cam)
        ideal = verged_rig.undistort_points(raw, cam)
        K = verged_rig.K1 if cam == "left" else verged_rig.K2
        P_cam = geometry.transform_points(verged_rig.T_camera_world(cam), P)
        np.testing.assert_allclose(ideal, (P_cam @ K.T)[:, :2] / P_cam[:, 2:], atol=1e-8)


# ----------------------------------------------------------------------------- bad input


def _bad(values: dict, key: str, value) -> dict:
    out = dict(values)
    if value is None:
        out.pop(key)
    else:
        out[key] = value
    return out


BAD_CASES = [
    ("K1", None, r"K1: missing"),
    ("K1", np.eye(3, 4), r"K1: expected shape \(3, 3\), got \(3, 4\)"),
    ("K2", np.diag([-800.0, 800.0, 1.0]), r"K2: focal lengths must be positive"),
    ("K1", np.diag([0.0, 800.0, 1.0]), r"K1: focal lengths must be positive"),
    ("R", np.diag([1.0, 1.0, 2.0]), r"R: expected a rotation matrix"),
    ("R", np.diag([1.0, 1.0, -1.0]), r"R: expected a rotation matrix"),
    ("T", np.array([[np.nan], [0.0], [0.0]]), r"T: contains NaN"),
    ("T", np.zeros((2, 1)), r"T: expected shape \(3,\)"),
    ("D1", np.zeros((1, 3)), r"D1: expected 1x5 distortion coefficients"),
    ("image_width", -5, r"image_width: expected a positive integer"),
    ("image_height", None, r"image_height: missing"),
]


@pytest.mark.parametrize("key, value, message", BAD_CASES)
def test_bad_calibration_is_refused_naming_the_key(tmp_path, verged_rig, key, value, message):
    path = _write_opencv(tmp_path / "calib.yaml", _bad(_canonical_values(verged_rig), key, value))
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


@pytest.mark.parametrize("key, value, message", BAD_CASES[:5])
def test_cli_prints_one_line_and_exits_2_on_a_bad_calibration(tmp_path, capsys, verged_rig,
                                                              key, value, message):
    path = _write_opencv(tmp_path / "calib.yaml", _bad(_canonical_values(verged_rig), key, value))
    assert main(["calib", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert str(path) in err and message.split(":")[0] in err


@pytest.mark.parametrize("content, message", [
    ("", "expected a YAML mapping"),
    ("foo: [1, 2\n", "not valid YAML at line"),
    ("just: a mapping\n", "unrecognised calibration format"),
    ("\x00\x01\x02binary", "expected a YAML mapping|not valid YAML"),
])
def test_unreadable_or_unknown_files_are_refused(tmp_path, content, message):
    path = tmp_path / "c.yaml"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        load_calibration(path)


def test_missing_file(tmp_path):
    with pytest.raises(ValueError, match="calibration file not found"):
        load_calibration(tmp_path / "nope.yaml")


def test_boofcv_missing_key_is_named(tmp_path, bumblebee_dir):
    data = yaml.safe_load((bumblebee_dir / "chess" / "stereo.yaml").read_text())
    del data["right"]["pinhole"]["fx"]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=r"right\.pinhole\.fx: missing"):
        load_calibration(tmp_path / "s.yaml")


def test_calib_cli_converts_to_canonical(tmp_path, capsys, bumblebee_dir):
    out = tmp_path / "calib.yaml"
    assert main(["calib", str(bumblebee_dir / "chess" / "stereo.yaml"), "--out", str(out)]) == 0
    assert "baseline       120.05 mm" in capsys.readouterr().out
    _assert_same_rig(load_calibration(out), load_calibration(bumblebee_dir / "chess" / "stereo.yaml"),
                     atol=1e-12)
