"""Stereo calibration from chessboard pairs (real Bumblebee2 data) and `rovis calibrate`."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from rovis import load_calibration
from rovis.calibrate import calibrate_stereo, canonical_order, find_chessboard, order_like
from rovis.cli import main

BOARD = (4, 6)  # inner corners per row, rows (5 x 7 squares)
SQUARE = 0.030  # metres


def _pairs(bumblebee_dir):
    lefts = sorted((bumblebee_dir / "chess").glob("left*.jpg"))
    assert len(lefts) == 11
    return lefts, [p.with_name(p.name.replace("left", "right")) for p in lefts]


@pytest.fixture
def reference(bumblebee_dir):
    return load_calibration(bumblebee_dir / "chess" / "stereo.yaml")


def _assert_close_to_reference(rig, ref):
    for K, K_ref in ((rig.K1, ref.K1), (rig.K2, ref.K2)):
        for idx in ((0, 0), (1, 1), (0, 2), (1, 2)):  # fx, fy, cx, cy
            assert abs(K[idx] - K_ref[idx]) <= 0.02 * K_ref[idx], idx  # 2 %


@pytest.mark.parametrize("distortion", ["full", "k1k2"])
def test_real_chessboard_calibration_matches_boofcv(bumblebee_dir, reference, distortion):
    lefts, rights = _pairs(bumblebee_dir)
    report = calibrate_stereo(lefts, rights, BOARD, SQUARE, distortion=distortion)
    assert len(report.pairs) == 11 and report.skipped == ()
    assert report.rms_px <= 0.3  # pixels
    assert max(p.rms_px for p in report.pairs) <= 0.3
    assert report.rig.baseline == pytest.approx(0.120, abs=1e-3)  # 1 mm
    assert report.rig.image_size == (640, 480)
    _assert_close_to_reference(report.rig, reference)
    # the right camera sits ~120 mm along the left camera's +x: T = -R·C_right points to -x
    assert report.rig.T[0] < -0.119


def test_real_calibration_with_fixed_intrinsics(bumblebee_dir, reference):
    lefts, rights = _pairs(bumblebee_dir)
    report = calibrate_stereo(lefts, rights, BOARD, SQUARE, fix_intrinsics_from=reference)
    assert report.intrinsics_fixed
    np.testing.assert_allclose(report.rig.K1, reference.K1)
    np.testing.assert_allclose(report.rig.D2, reference.D2)
    assert report.rms_px <= 0.15  # pixels
    assert report.rig.baseline == pytest.approx(reference.baseline, abs=0.5e-3)  # 0.5 mm
    angle = np.degrees(np.arccos((np.trace(report.rig.R.T @ reference.R) - 1) / 2))
    assert angle < 0.1  # degrees


def test_corner_order_is_made_consistent(bumblebee_dir):
    lefts, rights = _pairs(bumblebee_dir)
    gray_l = cv2.imread(str(lefts[0]), cv2.IMREAD_GRAYSCALE)
    gray_r = cv2.imread(str(rights[0]), cv2.IMREAD_GRAYSCALE)
    cl, cr = find_chessboard(gray_l, BOARD), find_chessboard(gray_r, BOARD)
    assert cl.shape == (24, 2) and cr.shape == (24, 2)
    assert np.hypot(*cl[0]) < np.hypot(*cl[-1])  # starts nearest the top-left
    np.testing.assert_array_equal(canonical_order(cl[::-1], BOARD), cl)
    np.testing.assert_array_equal(order_like(cl, cr[::-1], BOARD), order_like(cl, cr, BOARD))
    # same physical corner at the same index: the disparity is the same sign and size for all
    disparity = (cl - order_like(cl, cr, BOARD))[:, 0]
    assert np.all(disparity > 0) and np.ptp(disparity) < 0.5 * disparity.mean()


def test_pairs_without_a_board_are_skipped_by_name(bumblebee_dir, tmp_path):
    lefts, rights = _pairs(bumblebee_dir)
    scene = bumblebee_dir / "scenes" / "wall01_right.jpg"
    if not scene.exists():
        pytest.skip("scene image missing")
    rights = list(rights)
    rights[4] = shutil.copy(scene, tmp_path / "right05.jpg")
    report = calibrate_stereo(lefts, rights, BOARD, SQUARE)
    assert len(report.pairs) == 10
    assert len(report.skipped) == 1
    name, reason = report.skipped[0]
    assert name == "left05.jpg/right05.jpg" and "right image" in reason
    assert any("skipped left05.jpg/right05.jpg" in line for line in report.lines())


def test_outlier_pairs_are_dropped_with_a_message(bumblebee_dir):
    lefts, rights = _pairs(bumblebee_dir)
    report = calibrate_stereo(lefts, rights, BOARD, SQUARE, max_pair_rms=0.088)
    assert 3 <= len(report.pairs) < 11
    assert all(p.rms_px <= 0.088 for p in report.pairs)
    assert all("outlier" in reason for _, reason in report.skipped)
    assert len(report.pairs) + len(report.skipped) == 11


def test_fewer_than_three_pairs_is_an_error(bumblebee_dir, tmp_path):
    lefts, rights = _pairs(bumblebee_dir)
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    with pytest.raises(ValueError, match=r"only 2 usable chessboard pair\(s\) of 3.*blank.png"):
        calibrate_stereo(lefts[:3], [rights[0], rights[1], blank], BOARD, SQUARE)


def test_bad_images_are_refused(bumblebee_dir, tmp_path):
    lefts, rights = _pairs(bumblebee_dir)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((240, 320), np.uint8))
    with pytest.raises(ValueError, match=r"small.png: image size 320x240 differs from 640x480"):
        calibrate_stereo(lefts[:3], [rights[0], small, rights[2]], BOARD, SQUARE)
    junk = tmp_path / "junk.jpg"
    junk.write_text("not an image")
    with pytest.raises(ValueError, match=r"junk.jpg: cannot read image"):
        calibrate_stereo([junk], [rights[0]], BOARD, SQUARE)
    with pytest.raises(ValueError, match="as many right images as left"):
        calibrate_stereo(lefts[:3], rights[:2], BOARD, SQUARE)
    with pytest.raises(ValueError, match="distortion: expected one of"):
        calibrate_stereo(lefts[:3], rights[:3], BOARD, SQUARE, distortion="k9")


def test_cli_calibrate_writes_calib_yaml(bumblebee_dir, tmp_path, capsys):
    chess = bumblebee_dir / "chess"
    out = tmp_path / "calib.yaml"
    code = main(["calibrate", "--left", str(chess / "left*.jpg"), "--right",
                 str(chess / "right*.jpg"), "--board", "4x6", "--square", "0.030",
                 "--distortion", "k1k2p1p2", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "left07.jpg/right07.jpg" in text and "total RMS" in text and "baseline" in text
    rig = load_calibration(out)
    assert rig.baseline == pytest.approx(0.120, abs=1e-3)  # 1 mm
    assert rig.D1[4] == 0.0  # k3 not estimated in this model


def test_cli_calibrate_with_fixed_intrinsics(bumblebee_dir, tmp_path, capsys):
    chess = bumblebee_dir / "chess"
    out = tmp_path / "calib.yaml"
    assert main(["calibrate", "--left", str(chess / "left0*.jpg"), "--right",
                 str(chess / "right0*.jpg"), "--intrinsics", str(chess / "stereo.yaml"),
                 "--out", str(out)]) == 0
    assert "intrinsics fixed" in capsys.readouterr().out
    np.testing.assert_allclose(load_calibration(out).K2,
                               load_calibration(chess / "stereo.yaml").K2, rtol=1e-12)


def test_cli_calibrate_bad_input_exits_2(tmp_path, capsys):
    assert main(["calibrate", "--left", str(tmp_path / "left*.jpg"), "--right",
                 str(tmp_path / "right*.jpg"), "--out", str(tmp_path / "c.yaml")]) == 2
    err = capsys.readouterr().err
    assert "--left: no file matches" in err and err.count("\n") == 1
    assert main(["calibrate", "--left", "a.jpg", "--right", "b.jpg", "--board", "4by6"]) == 2
    assert "--board: expected COLSxROWS" in capsys.readouterr().err
    assert not (tmp_path / "c.yaml").exists()
