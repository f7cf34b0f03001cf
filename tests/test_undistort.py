"""The ideal frame that holds the raw field of view (rovis.undistort.IdealView)."""

from __future__ import annotations

import numpy as np
import pytest

from rovis import geometry
from rovis.calib import make_rig
from rovis.undistort import IdealView

# the real Bumblebee2's lens (../shared/data/bumblebee2/chess/stereo.yaml), on a 640x480 rig
WIDE = dict(image_size=(640, 480), f_px=400.0, distortion=(-0.36, 0.17, 0.0, 0.0, 0.0))


def _border(w: int, h: int, n: int = 50) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return np.vstack([np.column_stack([t * (w - 1), np.zeros(n)]),
                      np.column_stack([t * (w - 1), np.full(n, h - 1.0)]),
                      np.column_stack([np.zeros(n), t * (h - 1)]),
                      np.column_stack([np.full(n, w - 1.0), t * (h - 1)])])


def test_every_raw_pixel_lies_in_the_grown_frame():
    rig = make_rig(**WIDE)
    view = IdealView.of(rig)
    w, h = view.size
    assert view.grown and w > 640 + 100 and h > 480 + 80  # ~70 px lost per side before
    for cam in ("left", "right"):
        ideal = view.from_rig_ideal(rig.undistort_points(_border(640, 480), cam))
        assert ideal.min() >= 0 and ideal[:, 0].max() <= w - 1 and ideal[:, 1].max() <= h - 1
        # the frame of the rig's own size would have cut them off
        assert rig.undistort_points(_border(640, 480), cam).min() < -50


def test_valid_marks_the_pixels_the_raw_image_gives():
    rig = make_rig(**WIDE)
    view = IdealView.of(rig)  # 3 px inside the raw border: no black blended in
    valid = view.valid["left"] > 0
    # the ideal image of the principal point, and of a raw pixel near a corner, are valid
    c = np.rint(view.from_rig_ideal(rig.K1[:2, 2])).astype(int)
    corner = np.rint(view.from_rig_ideal(rig.undistort_points([[5.0, 5.0]], "left")[0])).astype(int)
    assert valid[c[1], c[0]] and valid[corner[1], corner[0]]
    assert not valid[0, 0] and not valid[-1, -1]  # the grown frame's corners see past the lens
    raw = np.full((480, 640), 200, np.uint8)
    img = view.undistort(raw, "left")
    assert img.shape == (view.size[1], view.size[0])
    assert np.all(img[valid][:1000] == 200) and img[0, 0] == 0


def test_the_view_rig_projects_into_the_grown_frame():
    rig = make_rig(**WIDE)
    view = IdealView.of(rig)
    work = view.rig(rig)
    P = np.array([[0.05, -0.03, 0.6], [-0.2, 0.1, 0.5]])
    for Q_rig, Q_view in ((rig.Q_L, work.Q_L), (rig.Q_R, work.Q_R)):
        np.testing.assert_allclose(geometry.project(Q_view, P),
                                   view.from_rig_ideal(geometry.project(Q_rig, P)), atol=1e-9)
    # triangulation is the same in either frame
    pl, pr = geometry.project(work.Q_L, P), geometry.project(work.Q_R, P)
    np.testing.assert_allclose(work.triangulate(pl, pr, distorted=False), P, atol=1e-9)
    np.testing.assert_allclose(view.to_rig_ideal(view.from_rig_ideal(pl)), pl)


def test_without_full_view_or_barrel_distortion_the_frame_is_the_rigs():
    rig = make_rig(**WIDE)
    plain = IdealView.of(rig, full=False)
    assert plain.size == (640, 480) and not np.any(plain.offset) and plain.rig(rig) is rig
    pincushion = make_rig(image_size=(640, 480), f_px=400.0, distortion=(0.05, 0, 0, 0, 0))
    view = IdealView.of(pincushion)
    assert view.size == (640, 480) and not np.any(view.offset)


def test_a_lens_without_distortion_keeps_its_frame_and_every_pixel():
    rig = make_rig(image_size=(640, 480), f_px=400.0, distortion=(0, 0, 0, 0, 0))
    view = IdealView.of(rig)
    assert view.size == (640, 480) and not np.any(view.offset) and not view.grown
    assert view.rig(rig) is rig and view.valid["left"].all()


def test_a_lens_model_that_folds_back_is_not_grown():
    # k1 = -0.36 without k2 peaks inside the image: its border does not invert
    rig = make_rig(image_size=(640, 480), f_px=400.0, distortion=(-0.36, 0, 0, 0, 0))
    view = IdealView.of(rig)
    assert view.size == (640, 480) and not np.any(view.offset)


def test_no_image_size_is_refused():
    rig = make_rig(**WIDE)
    from dataclasses import replace
    with pytest.raises(ValueError, match="image size"):
        IdealView.of(replace(rig, image_size=None))


def test_overlays_draw_the_lines_of_the_whole_field_of_view():
    # a Hough line in the band the grown frame added (left of the rig's own ideal frame)
    # is drawn in the raw image, near its left edge
    from rovis.segment.lines import Lines
    from rovis.viz import _line_polylines
    rig = make_rig(**WIDE)
    x = float(rig.undistort_points([[3.0, 240.0]], "left")[0, 0]) + 5.0  # ideal x < 0
    assert x < -50
    lines = Lines(np.array([x]), np.array([0.0]), np.array([100]))  # the vertical x = const
    polylines = _line_polylines(lines, (640, 480), rig, "left")
    assert len(polylines) == 1
    raw = polylines[0]
    assert raw[:, 0].max() < 40 and raw[:, 1].max() - raw[:, 1].min() > 200
    assert np.all((raw >= 0) & (raw <= [639, 479]))


def test_a_region_is_undistorted_as_the_whole_image_is():
    """Tracking undistorts only around the books it follows: those pixels are the whole
    image's, the rest black."""
    rig = make_rig(**WIDE)
    view = IdealView.of(rig)
    raw = np.random.default_rng(3).integers(0, 256, (480, 640), dtype=np.uint8)
    whole = view.undistort(raw, "right")
    box = (100, 80, 420, 300)
    part = view.undistort(raw, "right", box)
    assert part.shape == whole.shape
    assert np.array_equal(part[80:300, 100:420], whole[80:300, 100:420])
    part[80:300, 100:420] = 0
    assert not part.any()

    with pytest.raises(ValueError, match="region"):
        view.undistort(raw, "right", (100, 80, 100, 300))  # empty
    with pytest.raises(ValueError, match="region"):
        view.undistort(raw, "right", (-5, 80, 420, 300))


def test_gradients_beyond_the_raw_field_of_view_are_zero():
    """The black beyond a wide lens's raw image is no edge: the detector's gradients are 0
    wherever the grown ideal frame shows nothing of the raw image."""
    from rovis.pipeline import Detector

    rig = make_rig(**WIDE)
    det = Detector(rig)
    raw = np.full((480, 640), 180, np.uint8)
    f = det._prepare(raw, raw)
    for cam in ("left", "right"):
        outside = det._view.valid[cam] == 0
        assert outside.any()
        assert not f.grads[cam].dx[outside].any() and not f.grads[cam].dy[outside].any()
    # ...where the undistorted image does step, from the raw image's 180 to black
    assert f.ideal["left"][det._view.valid["left"] > 0].min() > 150
    assert f.ideal["left"][0, 0] == 0
