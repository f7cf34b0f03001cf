"""Real Bumblebee2 data: the calibration conventions, checked on a 30 mm chessboard.

With BoofCV's stereo.yaml read by rovis, the 4x6 inner corners of every pair, undistorted and
triangulated, must lie 30.0 mm apart. A wrong R/T direction, unit, or distortion convention
shows up here at once as millimetres of error.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rovis import geometry, load_calibration

PATTERN = (4, 6)  # inner corners per row, rows
SQUARE = 0.030  # metres
MAX_STEP_ERROR = 0.6e-3  # 0.6 mm for any single neighbour distance


def _corners(path) -> np.ndarray:
    gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert gray is not None, path
    found, corners = cv2.findChessboardCorners(gray, PATTERN)
    assert found, f"no chessboard in {path.name}"
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    return cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria).reshape(-1, 2).astype(np.float64)


def _pairs(bumblebee_dir):
    lefts = sorted((bumblebee_dir / "chess").glob("left*.jpg"))
    assert len(lefts) == 11
    return [(p, p.with_name(p.name.replace("left", "right"))) for p in lefts]


def test_triangulated_chessboard_corners_are_30mm_apart(bumblebee_dir):
    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    for method in ("dlt", "optimal"):
        means = []
        for left, right in _pairs(bumblebee_dir):
            px_l, px_r = _corners(left), _corners(right)
            # The 5x7-square board is 180-degree symmetric: detection order may flip.
            if np.dot(px_l[-1] - px_l[0], px_r[-1] - px_r[0]) < 0:
                px_r = px_r[::-1]
            grid = rig.triangulate(px_l, px_r, method=method).reshape(PATTERN[1], PATTERN[0], 3)
            steps = np.concatenate([np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel(),
                                    np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()])
            means.append(steps.mean())
            assert steps.mean() == pytest.approx(SQUARE, abs=0.3e-3), (left.name, method)  # 0.3 mm
            assert np.abs(steps - SQUARE).max() < MAX_STEP_ERROR, (left.name, method)
            flatness = geometry.plane_distance(geometry.fit_plane(grid.reshape(-1, 3)), grid.reshape(-1, 3))
            assert np.abs(flatness).max() < 1e-3  # the board is flat to 1 mm
        assert np.mean(means) == pytest.approx(SQUARE, abs=0.1e-3)


def test_ignoring_distortion_is_caught(bumblebee_dir):
    # The same check must fail when the pixels are not undistorted: the test has teeth.
    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    worst = 0.0
    for left, right in _pairs(bumblebee_dir):
        px_l, px_r = _corners(left), _corners(right)
        if np.dot(px_l[-1] - px_l[0], px_r[-1] - px_r[0]) < 0:
            px_r = px_r[::-1]
        grid = rig.triangulate(px_l, px_r, distorted=False).reshape(PATTERN[1], PATTERN[0], 3)
        worst = max(worst, np.abs(np.linalg.norm(np.diff(grid, axis=1), axis=2) - SQUARE).max())
    assert worst > MAX_STEP_ERROR


def test_the_sheet_under_the_board_is_found_in_every_pair(bumblebee_dir):
    # issue 5: no marker, world = left camera, BoofCV's calibration; the white sheet (US
    # Letter, 215.9 x 279.4 mm) is found and measures 216 ± 3 x 279 ± 4 mm, in every pair,
    # as a sequence (the warm-started controller) as `rovis detect` runs it
    from rovis.pipeline import Detector

    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    det = Detector(rig)
    for left, right in _pairs(bumblebee_dir):
        result = det.detect(cv2.imread(str(left)), cv2.imread(str(right)))
        assert result.desk_plane is None and result.world_frame == "left_camera"
        sizes = [sorted(o.pose.size[:2]) for o in result.objects]
        assert any(abs(a - 0.216) <= 0.003 and abs(b - 0.279) <= 0.004 for a, b in sizes), \
            (left.name, sizes)
        assert all(0.0 <= o.quality <= 1.0 for o in result.objects)


def test_the_sheet_needs_the_whole_field_of_view(bumblebee_dir):
    # the test above has teeth: undistorted into the frame of the raw image's size (which
    # cuts ~70 px off each side), the sheet is missed in pairs where a side falls outside
    from rovis.pipeline import DetectConfig, Detector

    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    det = Detector(rig, DetectConfig(full_view=False))
    missed = 0
    for left, right in _pairs(bumblebee_dir):
        result = det.detect(cv2.imread(str(left)), cv2.imread(str(right)))
        sizes = [sorted(o.pose.size[:2]) for o in result.objects]
        missed += not any(abs(a - 0.216) <= 0.003 and abs(b - 0.279) <= 0.004 for a, b in sizes)
    assert missed >= 3
