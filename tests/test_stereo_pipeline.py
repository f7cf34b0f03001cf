"""Stereo correspondence (paper §4) and the detect() pipeline on synthetic scenes."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from rovis.extent import SideHeightConfig
from rovis.pipeline import DROP_REASONS, DetectConfig, Detector, Pair, detect, with_settings
from rovis.segment import canny
from rovis.stereo import StereoConfig, find_in_other_view, match_quads, rectangle_normal
from rovis.synth import render, sample_scene
from rovis.trim import TrimConfig

from conftest import nearest_book
from dataset_scene import dataset_scene


@pytest.fixture(scope="module")
def scene():
    sc = sample_scene(11, lux=500.0)
    return sc, render(sc, 11)  # seeded sensor noise: the same pair every run


def _ideal(rig, P, Q):
    h = P @ Q[:, :3].T + Q[:, 3]
    return h[:, :2] / h[:, 2:]


def test_matching_recovers_every_pair_and_the_corner_order(scene):
    sc, r = scene
    rig = sc.rig
    books = r.truth["books"]
    left = np.array([_ideal(rig, np.array(b["corners"]), rig.Q_L) for b in books])
    right = np.array([_ideal(rig, np.array(b["corners"]), rig.Q_R) for b in books])
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(books))
    shifted = np.array([np.roll(right[k], -int(rng.integers(4)), axis=0) for k in perm])
    matches = match_quads(left, shifted, rig.Q_L, rig.Q_R, desk_plane=r.truth["desk_plane"])
    assert len(matches) == len(books)
    for m in matches:
        assert perm[m.right] == m.left
        np.testing.assert_allclose(m.corners_right, right[m.left], atol=1e-9)
        assert m.error_px < 1e-6


def test_the_desk_plane_rejects_a_quad_at_the_wrong_depth(scene):
    sc, r = scene
    rig = sc.rig
    b = r.truth["books"][0]
    P = np.array(b["corners"])
    left = _ideal(rig, P, rig.Q_L)[None]
    # the same cover shifted along the epipolar line: a 25 px disparity error, far below the desk
    wrong = _ideal(rig, P, rig.Q_R)[None] + [25.0, 0.0]
    assert match_quads(left, wrong, rig.Q_L, rig.Q_R, desk_plane=r.truth["desk_plane"]) == []
    assert len(match_quads(left, _ideal(rig, P, rig.Q_R)[None], rig.Q_L, rig.Q_R,
                           desk_plane=r.truth["desk_plane"])) == 1


def _cover_image(quad, shape, rng, cover_texture=0.0, cover_grey=30.0, highlight=None):
    """A desk of grey 90 with a dark cover (grey 30, plus texture of this std) on it, and
    sensor noise of 2.5 grey levels: a plain cover in dim light. ``highlight``: the share
    of the way from corner 0 to corner 2 where a glossy cover's highlight (a bright blob
    of a quarter of its width) lies."""
    import cv2

    img = np.full(shape, 90.0)
    inside = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(inside, np.rint(quad).astype(np.int32), 1)
    texture = cover_grey + cover_texture * rng.standard_normal(shape)
    if highlight == "band":  # a darker title band across a fifth of the cover: another cover
        inside_band = np.zeros(shape, np.uint8)
        a, b = quad[0] + 0.4 * (quad[3] - quad[0]), quad[1] + 0.4 * (quad[2] - quad[1])
        c, d = quad[1] + 0.6 * (quad[2] - quad[1]), quad[0] + 0.6 * (quad[3] - quad[0])
        cv2.fillConvexPoly(inside_band, np.rint([a, b, c, d]).astype(np.int32), 1)
        texture = np.where(inside_band > 0, texture - 25.0, texture)
    elif highlight is not None:
        x0, y0 = quad[0] + highlight * (quad[2] - quad[0])
        yy, xx = np.mgrid[:shape[0], :shape[1]]
        radius = 0.125 * np.linalg.norm(quad[1] - quad[0])
        texture = texture + 200.0 * np.exp(-((xx - x0) ** 2 + (yy - y0) ** 2) / (2 * radius ** 2))
    img = np.where(inside > 0, texture, img) + 2.5 * rng.standard_normal(shape)
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("right_texture, right_grey, highlights, matched",
                         [(0.0, 30.0, None, True), (30.0, 30.0, None, False),
                          (0.0, 70.0, None, False), (0.0, 30.0, (0.3, 0.6), True),
                          (30.0, 30.0, (0.3, 0.6), False), (0.0, 70.0, (0.3, 0.6), False),
                          (0.0, 30.0, (0.3, "band"), False)])
def test_two_plain_covers_match_despite_their_noise(scene, right_texture, right_grey,
                                                    highlights, matched):
    # what varies on a plain cover is noise, uncorrelated between the cameras: the
    # appearance test must not read it as two different covers (nor a plain one as a
    # textured one, or as a plain one far brighter); nor a glossy one's highlight, which
    # lies elsewhere on the cover in each view
    sc, r = scene
    rig = sc.rig
    P = np.array(r.truth["books"][0]["corners"])
    left, right = _ideal(rig, P, rig.Q_L), _ideal(rig, P, rig.Q_R)
    shape = rig.image_size[::-1]
    spot_l, spot_r = highlights or (None, None)
    gray_l = _cover_image(left, shape, np.random.default_rng(1), highlight=spot_l)
    gray_r = _cover_image(right, shape, np.random.default_rng(2), cover_texture=right_texture,
                          cover_grey=right_grey, highlight=spot_r)
    found = match_quads(left[None], right[None], rig.Q_L, rig.Q_R,
                        desk_plane=r.truth["desk_plane"], gray_left=gray_l, gray_right=gray_r)
    assert (len(found) == 1) == matched


def _sines(rig, P, plane):
    """Per side of a cover (world corners P, (4, 3)), the sine of its angle in the right
    image to its epipolar lines there (~0 along them): the motion of the left image's
    corners, laid on the plane 1 cm higher and projected."""
    from rovis.sweep import on_plane
    src, dst = _ideal(rig, P, rig.Q_L), _ideal(rig, P, rig.Q_R)
    height = float(np.mean(P @ plane[:3] + plane[3]))
    motion = _ideal(rig, on_plane(rig.Q_L, src, plane, height + 0.01), rig.Q_R) - dst
    motion = 0.5 * (motion + np.roll(motion, -1, axis=0))
    side = np.roll(dst, -1, axis=0) - dst
    return np.abs(side[:, 0] * motion[:, 1] - side[:, 1] * motion[:, 0]) / (
        np.linalg.norm(side, axis=1) * np.linalg.norm(motion, axis=1))


def _sides_moved(quad, px):
    """``quad`` (4, 2) with side s (corner s to s + 1) moved outward by ``px[s]`` pixels,
    the corners where the moved sides meet."""
    from rovis.segment.lines import intersect
    centre = quad.mean(axis=0)
    lines = []
    for s in range(4):
        a, c = quad[s], quad[(s + 1) % 4]
        d = (c - a) / np.linalg.norm(c - a)
        n = np.array([d[1], -d[0]])
        n = n if n @ (a - centre) > 0 else -n
        lines.append((a + px.get(s, 0.0) * n, d))
    return np.array([intersect(*lines[s - 1], *lines[s]) for s in range(4)])


def _blinded(grad, quad, sides):
    """``grad`` with no gradient along the middle 70 % of the given sides of ``quad``
    (4, 2), 7 px wide: sides that show no edge."""
    import cv2
    mask = np.zeros(grad.shape, np.uint8)
    for s in sides:
        a, c = quad[s], quad[(s + 1) % 4]
        cv2.line(mask, tuple(np.rint(a + 0.15 * (c - a)).astype(int)),
                 tuple(np.rint(a + 0.85 * (c - a)).astype(int)), 255, 7)
    return replace(grad, dx=np.where(mask > 0, 0, grad.dx).astype(grad.dx.dtype),
                   dy=np.where(mask > 0, 0, grad.dy).astype(grad.dy.dtype))


def _ideal_grad(rig, raw, camera):
    import cv2

    from rovis.segment import gradients

    K, D = rig.intrinsics(camera)
    maps = cv2.initUndistortRectifyMap(K, D, None, K, rig.image_size, cv2.CV_16SC2)
    ideal = cv2.remap(raw, *maps, cv2.INTER_LINEAR)
    return ideal, gradients(ideal)


def _quad_mask(quad, shape, grow_px=3):
    import cv2

    mask = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(mask, np.rint(quad).astype(np.int32), 255)
    return cv2.dilate(mask, np.ones((2 * grow_px + 1,) * 2, np.uint8))


@pytest.mark.parametrize("with_desk", [True, False])
def test_a_cover_found_in_one_image_is_found_in_the_other(scene, with_desk):
    # without the desk plane (the real chessboard pairs have no marker) the quad's
    # rectangle gives its plane's orientation, and the depth is swept instead of the height
    sc, r = scene
    rig = sc.rig
    gray_l, _ = _ideal_grad(rig, r.left, "left")
    gray_r, grad_r = _ideal_grad(rig, r.right, "right")
    C = -np.linalg.solve(rig.Q_L[:, :3], rig.Q_L[:, 3])  # the left camera's centre
    found = 0
    for b in r.truth["books"]:
        if min(b["visible_left"], b["visible_right"]) < 0.99:
            continue
        P = np.array(b["corners"])
        if not with_desk:
            normal = rectangle_normal(_ideal(rig, P, rig.Q_L), rig.Q_L)
            assert normal is not None and abs(normal @ [0, 0, 1]) > np.cos(np.radians(3.0))
        got = find_in_other_view(_ideal(rig, P, rig.Q_L), rig.Q_L, rig.Q_R,
                                 r.truth["desk_plane"] if with_desk else None, grad_r, 10.0,
                                 gray_from=gray_l, gray_to=gray_r)
        if got is not None:
            found += 1
            # corners in the same physical order, to a pixel or two wherever the sweep
            # stopped (the plane of one quad's vanishing points starts the refit a few
            # pixels off; a lateral page block seen at a grazing angle, 4 px wide in the
            # left image and 2 px in the right, moves a side 1.3-1.6 px outward there)
            assert np.abs(got[0] - _ideal(rig, P, rig.Q_R)).max() < 2.0
            if not with_desk:  # the depth swept to, before the refit
                assert got[1] == pytest.approx(np.linalg.norm(P.mean(axis=0) - C), rel=0.05)
    assert found >= 2


def test_a_cover_a_few_pixels_off_in_its_image_is_still_found_in_the_other(scene):
    # the source quad's side P1-P2 2.5 px out (on a line beyond the cover, say): the cover
    # predicted in the other image is off too, and refining it there moves its corners by
    # more than a pixel; it is still the cover, which the extent step then fits in both images
    sc, r = scene
    rig = sc.rig
    gray_l, _ = _ideal_grad(rig, r.left, "left")
    gray_r, grad_r = _ideal_grad(rig, r.right, "right")
    found = {1.0: 0, 4.0: 0}
    for b in r.truth["books"]:
        if min(b["visible_left"], b["visible_right"]) < 0.99:
            continue
        P = np.array(b["corners"])
        src = _ideal(rig, P, rig.Q_L)
        d = src[1] - src[0]
        out = np.array([d[1], -d[0]]) / np.linalg.norm(d)
        if out @ (src[0] - src.mean(axis=0)) < 0:
            out = -out
        src[0:2] += 2.5 * out
        for limit in found:
            got = find_in_other_view(src, rig.Q_L, rig.Q_R, r.truth["desk_plane"], grad_r, 10.0,
                                     gray_from=gray_l, gray_to=gray_r,
                                     cfg=StereoConfig(max_refine_px=limit))
            if got is not None:
                found[limit] += 1
                assert np.abs(got[0] - _ideal(rig, P, rig.Q_R)).max() < 3.5
    assert found[4.0] > found[1.0] and StereoConfig().max_refine_px == 4.0


def test_a_quad_no_rectangle_projects_to_has_no_plane(scene):
    sc, r = scene
    rig = sc.rig
    P = np.array(r.truth["books"][0]["corners"])
    quad = _ideal(rig, P, rig.Q_L)
    assert rectangle_normal(quad, rig.Q_L) is not None
    kite = quad.copy()
    kite[2] += 0.6 * (kite[2] - kite[0])  # one corner pulled out along the diagonal
    assert rectangle_normal(kite, rig.Q_L) is None


def test_without_the_desk_plane_a_rectangle_printed_on_a_cover_gives_way(scene):
    sc, r = scene
    rig = sc.rig
    b = r.truth["books"][0]
    P = np.array(b["corners"])
    centre = P.mean(axis=0)
    inner = centre + 0.7 * (P - centre)  # a print on the cover, in its plane
    lifted = inner + [0.0, 0.0, 0.03]  # the same, 3 cm above it: a book on the book
    det = Detector(rig)
    books = []
    for Q in (P, inner, lifted):
        pair = Pair(_ideal(rig, Q, rig.Q_L), _ideal(rig, Q, rig.Q_R), 1.0, 0.0)
        pair, book, why = det._reconstruct_or_why(rig, pair, None)
        assert book is not None, why
        books.append((pair, book))
    kept, printed = det._without_prints(books)
    assert [bk for _, bk in printed] == [books[1][1]]
    assert [bk for _, bk in kept] == [books[0][1], books[2][1]]


def test_a_print_dropped_without_the_desk_plane_is_reported(monkeypatch):
    # a rectangle printed on the largest cover, found as a book of its own, gives way to
    # the cover (Detector._without_prints) and is reported as dropped, "printed"
    import rovis.pipeline as P
    from rovis.calib import StereoRig
    sc = sample_scene(16, lux=500.0)
    r = render(sc, 16)
    rig = sc.rig
    bare = StereoRig.from_arrays(K1=rig.K1, D1=rig.D1, K2=rig.K2, D2=rig.D2, R=rig.R, T=rig.T,
                                 image_size=rig.image_size)
    drop_prints = P.Detector._without_prints

    def with_a_print(self, found, **kw):
        pair, book = max(found, key=lambda pb: float(np.prod(pb[1].pose.size[:2])))
        W = book.corners_world
        inner = W.mean(axis=0) + 0.75 * (W - W.mean(axis=0))
        view = self._view_rig(bare)
        inner_pair, inner_book, why = self._reconstruct_or_why(
            view, P._pair_at(view, pair, inner), None)
        assert inner_book is not None, why
        return drop_prints(self, found + [(inner_pair, inner_book)], **kw)

    monkeypatch.setattr(P.Detector, "_without_prints", with_a_print)
    res = Detector(bare, DetectConfig(use_marker=False)).detect(r.left, r.right)
    assert res.desk_plane is None
    assert [why for why, *_ in res.dropped].count("printed") == 1
    assert any("printed: 1" in w for w in res.warnings)


def test_no_cover_is_invented_where_the_other_image_shows_desk(scene):
    sc, r = scene
    rig = sc.rig
    gray_l, _ = _ideal_grad(rig, r.left, "left")
    gray_r, grad_r = _ideal_grad(rig, r.right, "right")
    b = r.truth["books"][0]
    # the first book's cover, moved 40 cm back along the desk: bare desk in the right image
    P = np.array(b["corners"]) + [0.0, 0.40, 0.0]
    assert canny(grad_r, 60.0)[_quad_mask(_ideal(rig, P, rig.Q_R), grad_r.shape) > 0].sum() == 0
    assert find_in_other_view(_ideal(rig, P, rig.Q_L), rig.Q_L, rig.Q_R, r.truth["desk_plane"],
                              grad_r, 10.0, gray_from=gray_l, gray_to=gray_r) is None
    assert StereoConfig().transfer


def test_detect_returns_the_design_json_for_a_scene(scene):
    sc, r = scene
    res = detect(r.left, r.right, sc.rig)
    doc = json.loads(res.to_json())
    assert doc["world_frame"] == "marker"
    np.testing.assert_allclose(doc["desk_plane"], [0, 0, 1, 0], atol=2e-3)
    assert set(doc["segmentation"]) == {"left", "right"}
    assert {"marker", "undistort", "segmentation", "stereo", "pose"} <= set(doc["timing_ms"])
    for obj in doc["objects"]:
        for key in ("id", "center", "R", "quaternion_xyzw", "euler_zxz_deg", "yaw_deg", "size",
                    "corners_world", "corners_left_px", "corners_right_px",
                    "reprojection_error_px", "quality", "source"):
            assert key in obj
        assert obj["source"] in ("segmentation", "one image", "candidates", "height map")
    # every reported book is a real one; those both segmentations found within the 1 cm
    # grasp tolerance (a cover stereo chose among the candidates, or the height map's, is
    # the least exact: docs/stereo.md; here a desk-coloured cover seen on three sides; the
    # smooth height map's desk-toned cover, which nothing else finds, 3.1 cm off)
    truth = np.array([b["center"] for b in r.truth["books"]])
    tolerance = {"segmentation": 0.01, "one image": 0.01, "candidates": 0.02, "height map": 0.035}
    for obj in res.objects:
        error = np.abs(truth - obj.pose.center).max(axis=1).min()
        assert error < tolerance[obj.source]


def test_no_marker_means_left_camera_frame_and_says_so():
    sc = sample_scene(16, lux=500.0)
    r = render(sc, 16)
    rig = sc.rig
    from rovis.calib import StereoRig
    bare = StereoRig.from_arrays(K1=rig.K1, D1=rig.D1, K2=rig.K2, D2=rig.D2, R=rig.R, T=rig.T,
                                 image_size=rig.image_size)
    res = detect(r.left, r.right, bare, cfg=DetectConfig(use_marker=False))
    assert res.world_frame == "left_camera" and res.desk_plane is None
    # covers found in one image only are among them (the one-image search on the quad's
    # own plane); every quality is an edge-support fraction
    assert res.objects and all(0.0 <= o.quality <= 1.0 for o in res.objects)
    # without the desk plane only a clean quad (its segmentation's edge support at least
    # stereo.free_transfer_support) is looked for in the other image: here a real cover
    # one image found, 88 % edge-supported, is looked for (and found, 8 mm off) only when
    # any quad may be: the price of no chair parts on the real scenes
    loose = detect(r.left, r.right, bare, cfg=with_settings(
        DetectConfig(use_marker=False), ["stereo.free_transfer_support=0"]))
    kept = [o.pose.center for o in res.objects if o.source == "one image"]
    added = [o for o in loose.objects if o.source == "one image"
             and all(np.linalg.norm(o.pose.center - c) > 0.02 for c in kept)]
    assert added and len(res.objects) < len(loose.objects)
    blank = np.full_like(r.left, 120)
    res = detect(blank, blank, bare)
    assert res.world_frame == "left_camera" and len(res) == 0
    assert any("marker" in w for w in res.warnings)


@pytest.mark.parametrize("left, right, message", [
    (np.zeros((768, 1024), np.uint8), np.zeros((700, 1024), np.uint8), "image sizes differ"),
    (np.zeros((480, 640), np.uint8), np.zeros((480, 640), np.uint8), "does not match the calibration"),
    (np.zeros((0, 0), np.uint8), np.zeros((0, 0), np.uint8), "empty"),
])
def test_bad_images_are_refused_with_a_reason(scene, left, right, message):
    sc, _ = scene
    with pytest.raises(ValueError, match=message):
        Detector(sc.rig).detect(left, right)


def test_colour_and_16_bit_input_are_converted(scene):
    sc, r = scene
    colour = np.repeat(r.left[..., None], 3, axis=2)
    wide = r.right.astype(np.uint16) * 257
    res = detect(colour, wide, sc.rig, method="open")
    assert res.world_frame == "marker"


def test_dropped_pairs_are_kept_with_the_check_they_failed(scene):
    # no tilt allowed: every pair fails the tilt test, and the result says so (the height
    # map's covers, laid flat on the plane their print gives, the completed candidates and
    # the pairs refit flat, built parallel to the desk, would pass it: off here)
    sc, r = scene
    result = Detector(sc.rig, with_settings(DetectConfig(), [
        "max_tilt_deg=0", "heightmap.enabled=false", "complete.enabled=false",
        "flat_refit_px=0"])).detect(r.left, r.right)
    assert sorted(result.covers) == ["left", "right"]
    assert all(q.ndim == 3 and q.shape[1:] == (4, 2) for q in result.covers.values())
    reasons = [why for why, _, _ in result.dropped]
    assert "tilted" in reasons and set(reasons) <= set(DROP_REASONS)
    assert not result.objects
    assert any(f"tilted: {reasons.count('tilted')}" in w for w in result.warnings)
    assert all(left.shape == right.shape == (4, 2) for _, left, right in result.dropped)


def test_settings_by_name_reach_nested_fields_and_name_bad_ones():
    cfg = with_settings(DetectConfig(), ["extent.grow=false", "segment.n_max=150",
                                         "max_tilt_deg=4", "segment.T_H_range=10,400"])
    assert cfg.extent.grow is False and cfg.segment.n_max == 150
    assert cfg.max_tilt_deg == 4.0 and cfg.segment.T_H_range == (10.0, 400.0)
    assert DetectConfig().extent.grow is True  # the defaults untouched
    for bad, word in (("nope=1", "nope"), ("extent=1", "group"), ("max_tilt_deg=abc", "float"),
                      ("extent.grow=maybe", "bool"), ("x", "NAME=VALUE"),
                      ("method=foo", "method")):
        with pytest.raises(ValueError, match=word):
            with_settings(DetectConfig(), [bad])


def _found_whole(rig, r, gray_l, gray_r, grad_r):
    """Per book of rendering ``r`` whole in both images that :func:`find_in_other_view`
    finds in the right image from its left quad, with every side showing: its world corners
    (4, 3), its right quad (4, 2) and the call's first four arguments."""
    for b in r.truth["books"]:
        if min(b["visible_left"], b["visible_right"]) < 0.99:
            continue
        P = np.array(b["corners"])
        src, dst = _ideal(rig, P, rig.Q_L), _ideal(rig, P, rig.Q_R)
        args = (src, rig.Q_L, rig.Q_R, r.truth["desk_plane"])
        if find_in_other_view(*args, grad_r, 10.0, gray_from=gray_l, gray_to=gray_r) is not None:
            yield P, dst, args


def test_a_cover_is_found_in_the_other_image_with_one_side_along_the_epipolar_lines_unseen(scene):
    # a far side of the desk's brightness shows no step in either image: the sides across
    # the epipolar lines still place the cover; without one of those, no cover (unless the
    # caller names that side: find_in_other_view's ``unseen``)
    sc, r = scene
    rig = sc.rig
    gray_l, _ = _ideal_grad(rig, r.left, "left")
    gray_r, grad_r = _ideal_grad(rig, r.right, "right")
    checked = {"along": 0, "across": 0}
    excused: list[bool] = []
    for P, dst, args in _found_whole(rig, r, gray_l, gray_r, grad_r):
        for s in range(4):
            a, c = dst[s], dst[(s + 1) % 4]
            slope = abs(c[1] - a[1]) / np.linalg.norm(c - a)  # epipolar lines: about horizontal
            kind = "along" if slope < 0.25 else "across" if slope > 0.8 else None
            if kind is None:
                continue
            blind = _blinded(grad_r, dst, [s])
            got = find_in_other_view(*args, blind, 10.0, gray_from=gray_l, gray_to=gray_r)
            if kind == "along":
                assert got is not None and np.abs(got[0] - dst).max() < 1.5  # px
            else:
                assert got is None
                # ...unless that side is the one the caller excuses (its own image shows it
                # along part of its length only): the other three place the cover, though
                # with one side across the epipolar lines left, less surely (another edge
                # beside it, the page block's foot, may win the height sweep)
                got = find_in_other_view(*args, blind, 10.0, gray_from=gray_l, gray_to=gray_r,
                                         unseen=s)
                excused.append(got is not None and np.abs(got[0] - dst).max() < 2.5)  # px
                # excusing another side excuses nothing: the blinded one still must show
                assert find_in_other_view(*args, blind, 10.0, gray_from=gray_l, gray_to=gray_r,
                                          unseen=(s + 1) % 4) is None
            checked[kind] += 1
    assert checked["along"] >= 1 and checked["across"] >= 1
    assert np.mean(excused) >= 0.6  # (6 of 8 when written)


def test_with_a_side_excused_one_side_along_the_epipolar_lines_may_still_fall_short(scene):
    # a plain cover of the desk's tone end to end with another (its end, the excused side,
    # shows no edge) whose long side along the epipolar lines shows only its page block's
    # foot in the other image: with ``along_short``, its other end, across the lines,
    # still places it.
    sc, r = scene
    rig = sc.rig
    gray_l, _ = _ideal_grad(rig, r.left, "left")
    gray_r, grad_r = _ideal_grad(rig, r.right, "right")
    placed: list[bool] = []
    for P, dst, args in _found_whole(rig, r, gray_l, gray_r, grad_r):
        sine = _sines(rig, P, np.asarray(r.truth["desk_plane"], dtype=np.float64))
        along = [s for s in range(4) if sine[s] < 0.3]
        across = [s for s in range(4) if sine[s] > 0.8]
        if not along or len(across) < 2:
            continue
        u, a = across[0], along[0]
        blind = _blinded(grad_r, dst, [u, a])
        # by default every side but the excused one must show (the pipeline asks this
        # first, and the looser look only where it then fits the cover, _transferred_fit)
        assert find_in_other_view(*args, blind, 10.0, gray_from=gray_l, gray_to=gray_r,
                                  unseen=u) is None
        got = find_in_other_view(*args, blind, 10.0, gray_from=gray_l, gray_to=gray_r,
                                 unseen=u, along_short=True)
        placed.append(got is not None and np.abs(got[0] - dst).max() < 2.5)  # px
    assert len(placed) >= 2
    assert np.mean(placed) >= 0.5


def test_a_transferred_cover_is_laid_on_the_sides_from_its_unseen_end_to_the_other(scene):
    # two plain books end to end: the one-image search's candidate has its end at the seam
    # unseen (6 px off in the other image), and its other end 2 px outward in its own
    # image (a thick book's end face blurs it). Fitted to every side but the unseen one,
    # the cover comes out centimetres off in height; fitted in the other image to the two
    # sides from end to end only (and to every side of its own), it is the cover
    from rovis import geometry
    from rovis.pipeline import _transferred_fit
    sc, r = scene
    rig, plane = sc.rig, np.asarray(r.truth["desk_plane"], dtype=np.float64)
    heights = []
    for b in r.truth["books"]:
        P = np.array(b["corners"])
        src, dst = _ideal(rig, P, rig.Q_L), _ideal(rig, P, rig.Q_R)
        sine = _sines(rig, P, plane)
        unseen = int(np.argmax(sine))  # an end across the epipolar lines: it places height
        if sine[(unseen + 2) % 4] < 0.8:
            continue
        left = _sides_moved(src, {(unseen + 2) % 4: 2.0})
        right = _sides_moved(dst, {unseen: 6.0})
        got = _transferred_fit(rig, Pair(left, right, 1.0, 0.0, transferred="left"), "right",
                               unseen, plane, 1.0)
        assert got is not None
        heights.append(float(np.mean(got[:, 2])))
        assert abs(heights[-1] - b["size"][2]) < 0.0015  # m
        assert np.abs(got - P)[:, :2].max() < 0.006  # m: the blurred end, a few mm out
        # fitted to every side but the unseen one, the height is off
        use = np.ones((2, 4), bool)
        use[1, unseen] = False
        P0 = geometry.triangulate(rig.Q_L, rig.Q_R, left, right)
        every, _ = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, left, right, P0, plane,
                                                use=use)
        assert abs(float(np.mean(every[:, 2])) - b["size"][2]) > 0.005  # m
        # a side it uses that its fit must miss by more than max_off: no cover (a corner
        # of its own image 4 px off makes no rectangle's image)
        bad = left.copy()
        bad[0] += 4.0 * (src[0] - src.mean(axis=0)) / np.linalg.norm(src[0] - src.mean(axis=0))
        assert _transferred_fit(rig, Pair(bad, right, 1.0, 0.0, transferred="left"), "right",
                                unseen, plane, 1.0) is None
        # found in the right image instead, looked for in the left: the same
        swapped = _transferred_fit(rig, Pair(_sides_moved(src, {unseen: 6.0}),
                                             _sides_moved(dst, {(unseen + 2) % 4: 2.0}),
                                             1.0, 0.0, transferred="right"),
                                   "left", unseen, plane, 1.0)
        assert swapped is not None and abs(float(np.mean(swapped[:, 2])) - b["size"][2]) < 0.002
    assert len(heights) >= 2


def test_the_transferred_fit_may_excuse_its_own_images_unseen_side(scene):
    # the one-image search closes a candidate's unseen side where the edges of the two
    # sides beside it end: at a seam (Table II's plain books end to end) it is a few pixels
    # off and askew, and no rectangle lies on it. The strict fit turns the cover down; with
    # excuse_px that side is still fitted to but may be missed by up to that many pixels,
    # and the cover comes out at its height, its corners a few millimetres off
    from rovis.pipeline import _transferred_fit
    sc, r = scene
    rig, plane = sc.rig, np.asarray(r.truth["desk_plane"], dtype=np.float64)

    def askew(quad, s):
        # quad with the corner that starts side s 4 px on along the side before it
        out = quad.copy()
        along = out[s] - out[s - 1]
        out[s] += 4.0 * along / np.linalg.norm(along)
        return out

    tried = 0
    for b in r.truth["books"]:
        P = np.array(b["corners"])
        src, dst = _ideal(rig, P, rig.Q_L), _ideal(rig, P, rig.Q_R)
        sine = _sines(rig, P, plane)
        unseen = int(np.argmax(sine))
        if sine[(unseen + 2) % 4] < 0.8:
            continue
        end = (unseen + 2) % 4
        pair = Pair(askew(_sides_moved(src, {end: 2.0}), unseen),
                    _sides_moved(dst, {unseen: 6.0}), 1.0, 0.0, transferred="left")
        assert _transferred_fit(rig, pair, "right", unseen, plane, 1.0) is None
        got = _transferred_fit(rig, pair, "right", unseen, plane, 1.0, excuse_px=5.0)
        assert got is not None
        assert abs(float(np.mean(got[:, 2])) - b["size"][2]) < 0.0015  # m
        assert np.abs(got - P)[:, :2].max() < 0.006  # m
        # missed by more than it is excused: no cover
        assert _transferred_fit(rig, pair, "right", unseen, plane, 1.0, excuse_px=1.0) is None
        # a side the fit must lie on, askew, is not excused: the other end
        other = replace(pair, left=askew(_sides_moved(src, {end: 2.0}), end))
        assert _transferred_fit(rig, other, "right", unseen, plane, 1.0, excuse_px=5.0) is None
        # found in the right image instead, looked for in the left: the same
        right = askew(_sides_moved(dst, {end: 2.0}), unseen)
        swapped = Pair(_sides_moved(src, {unseen: 6.0}), right, 1.0, 0.0, transferred="right")
        assert _transferred_fit(rig, swapped, "left", unseen, plane, 1.0) is None
        got = _transferred_fit(rig, swapped, "left", unseen, plane, 1.0, excuse_px=5.0)
        assert got is not None and abs(float(np.mean(got[:, 2])) - b["size"][2]) < 0.0015
        tried += 1
    assert tried >= 2


def _false_books(res, truth):
    """The detections whose centre lies 5 cm or more from every true book's."""
    centres = np.array([b["center"][:2] for b in truth["books"]])
    return [o for o in res.objects
            if np.linalg.norm(centres - o.pose.center[:2], axis=1).min() > 0.05]


def test_a_cover_over_a_segmented_one_is_dropped():
    # build/t2 scene 56: the candidate pool made a false 294 x 141 mm "book" over a book
    # both segmentations found (22 % of the smaller quad); dropped, and reported so. (The
    # height map cut again without the found covers, heightmap.taken_px, finds a false
    # piece of the lost 8 mm photo cover there: off, to see this step's own.)
    sc, r = dataset_scene("table2", 1, 56)
    settings = ["heightmap.taken_px=-1"]
    res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
    assert _false_books(res, r.truth) == []
    assert any(why == "overlaps" for why, _, _ in res.dropped)
    assert any("over a cover the segmentations found" in w for w in res.warnings)
    off = Detector(sc.rig, with_settings(DetectConfig(), [*settings, "stereo.over_segmented=0"]))
    res = off.detect(r.left, r.right)
    assert len(_false_books(res, r.truth)) == 1
    assert not any(why == "overlaps" for why, _, _ in res.dropped)


def test_only_covers_over_a_segmented_one_give_way():
    # unit: a pool cover over a segmented one by 25 % of its area in both images gives
    # way; one over it by 10 %, or by 25 % in one image only, or over a cover the pool
    # found, or a segmented cover itself, stays
    det = Detector(sample_scene(11, lux=500.0).rig)
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])

    def found(source, dx, three_sided=False, dx_right=None):
        q = square + [dx, 0.0]
        r = square + [dx if dx_right is None else dx_right, 0.0] - [60.0, 0.0]
        book = type("Book", (), {"source": source})()
        return Pair(q, r, 1.0, 0.0, source=source, three_sided=three_sided), book

    seg = found("segmentation", 0.0)
    kept, over = det._without_overlaps([seg, found("candidates", 75.0),
                                        found("candidates", 90.0),
                                        found("candidates", 75.0, dx_right=95.0)])
    assert [p.left[0, 0] for p, _ in kept] == [0.0, 90.0, 75.0]
    assert [why for why, _, _ in over] == ["overlaps"]
    # over a pool cover, or over a segmented one with a side unseen: no one gives way
    for base in (found("candidates", 0.0), found("segmentation", 0.0, three_sided=True)):
        kept, over = det._without_overlaps([base, found("height map", 75.0)])
        assert len(kept) == 2 and over == []
    # whatever the order, the segmented cover is the one kept
    kept, _ = det._without_overlaps([found("candidates", 0.0), seg])
    assert [book.source for _, book in kept] == ["segmentation"]


def test_a_cover_tilted_by_one_images_cover_edge_step_is_refit_without_it():
    # Table II's scene 38 (rovis synth --protocol table2 --seed 1): a light cover on a
    # white page-block strip ~1 px wide. One image's inward search for the cover edge
    # steps onto another edge than the other image's: pixels of disparity tilt the cover.
    # Refined without that search in one image, the pair is flat. (Scene 36's, the same
    # book, was the case before the renderer filled its faces exactly; there the book is
    # now lost: the right image's closed loop settles at T_H 96 instead of 30.)
    sc, r = dataset_scene("table2", 1, 38)
    book = r.truth["books"][2]
    assert book["cover"] == "light"

    def nearest(plain_alternative: bool, side_height: bool = True, map_height: bool = True,
                sides: bool = True):
        cfg = DetectConfig(stereo=StereoConfig(plain_alternative=plain_alternative),
                           side_height=SideHeightConfig(enabled=side_height),
                           trim=TrimConfig(map_height=map_height),
                           flat_refit_sides=1.0 if sides else 0.0)
        res = Detector(sc.rig, cfg).detect(r.left, r.right)
        return nearest_book(res, book["center"])[0]

    o = nearest(True)
    assert np.linalg.norm(o.pose.center - book["center"]) < 0.01  # m
    assert abs(o.pose.size[2] - book["size"][2]) < 0.004  # m: the height
    np.testing.assert_allclose(sorted(o.pose.size[:2]), sorted(book["size"][:2]), atol=0.01)
    # the retry is what finds it (without it, the sides' height, the height map's check
    # and the flat refit to the pair's sides, at most a cover centimetres off); the sides'
    # height alone also puts a candidate pair there, and so do the height map's check
    # (rovis.trim.map_height) and the side fit (flat_refit_sides)
    assert np.linalg.norm(nearest(False, False, False, False).pose.center
                          - book["center"]) > 0.02
    assert np.linalg.norm(nearest(False, False, False).pose.center - book["center"]) < 0.01
    assert np.linalg.norm(nearest(False).pose.center - book["center"]) < 0.01
    assert np.linalg.norm(nearest(False, False).pose.center - book["center"]) < 0.01


def test_a_plain_cover_showing_two_sides_is_found_by_stereo_among_two_sided_candidates():
    # Table II's scene 18 (rovis synth --protocol table2 --seed 1, 60 lx daylight): a plain
    # 165 mm cover, 51 mm high, whose far and one lateral side meet a background of its own
    # brightness: two sides seen, no quad of three or four in either image.
    from rovis.segment import SegmentConfig

    sc, r = dataset_scene("table2", 1, 18)
    book = r.truth["books"][3]
    assert book["cover"] == "plain"

    def near(two_sided: bool):
        res = Detector(sc.rig, DetectConfig(segment=SegmentConfig(two_sided=two_sided))
                       ).detect(r.left, r.right)
        return [o for o in res.objects if np.linalg.norm(o.pose.center - book["center"]) < 0.05]

    found = near(True)
    assert len(found) == 1
    o = found[0]
    assert np.linalg.norm(o.pose.center - book["center"]) < 0.01  # m
    assert o.source == "candidates"
    assert abs(o.pose.size[2] - book["size"][2]) < 0.005  # m
    assert near(False) == []


def _near_book(sc, r, book, settings: list[str]):
    """The detections within 5 cm of ``book`` with these settings."""
    res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
    return [o for o in res.objects if np.linalg.norm(o.pose.center - book["center"]) < 0.05]


def test_a_cover_seen_on_two_sides_is_completed_in_3d():
    # Table II's scene 21: a plain cover of the desk's brightness, 233 × 102 × 23 mm, two
    # adjacent sides seen in each image. Each image closes the other two where its own
    # edges end, a few pixels apart: refined there, the pair is no flat cover. Its unseen sides placed in 3D from its seen ones
    # (rovis.extent.complete_open), it is found to grasping accuracy.
    sc, r = dataset_scene("table2", 1, 21)
    book = r.truth["books"][1]
    assert book["cover"] == "plain"

    found = _near_book(sc, r, book, ["complete.enabled=true"])
    assert len(found) == 1
    o = found[0]
    assert o.source == "candidates"
    assert np.linalg.norm(o.pose.center - book["center"]) < 0.01  # m
    assert abs(o.pose.size[2] - book["size"][2]) < 0.004  # m: the height
    np.testing.assert_allclose(sorted(o.pose.size[:2]), sorted(book["size"][:2]), atol=0.01)
    assert _near_book(sc, r, book, ["complete.enabled=false"]) == []


def test_one_of_two_plain_books_end_to_end_is_found_from_one_images_candidate():
    # Table II's scene 12 (250 lx): two plain books of the desk's tone end to end, 246 ×
    # 116 × 30 and 233 × 102 × 23 mm. Where they touch no edge shows in either image, so
    # neither is a segmented cover and no pair of candidates makes one (the right image's
    # Hough lines miss the first's faint front side). The left image's candidate for the
    # first, refined, ends on the step where the widths differ (its end side seen along
    # about 40 % of it); looked for in the right image with that side excused, it is the
    # book. Its long sides run near the epipolar lines; refined in the right image, they
    # put it ~12 mm low: laid flat on its two sides from end to end (_transferred_fit), it is
    # found to grasping accuracy.
    sc, r = dataset_scene("table2", 1, 12)
    book = r.truth["books"][0]
    assert book["cover"] == "plain"

    found = _near_book(sc, r, book, ["stereo.pool_transfer=true"])
    assert len(found) == 1
    o = found[0]
    assert o.source == "one image"
    assert np.abs(o.pose.center - book["center"]).max() < 0.006  # m, on each axis
    assert abs(o.pose.size[2] - book["size"][2]) < 0.004  # m: the height
    np.testing.assert_allclose(sorted(o.pose.size[:2]), sorted(book["size"][:2]), atol=0.01)
    assert _near_book(sc, r, book, ["stereo.pool_transfer=false"]) == []
    # fitted to every side of both images instead, it is found too, but lower
    low = _near_book(sc, r, book, ["stereo.pool_transfer_fit=false"])
    assert len(low) == 1 and book["center"][2] - low[0].pose.center[2] > 0.008  # m


def test_the_late_candidates_are_looked_for_in_the_other_image_too():
    # Table II's scene 13 (artificial light, 500 lx): the same two books. Only the late pool
    # (the closed loop's other T_H, Segmentation.late_pool) holds a candidate for the
    # first, in the left image; looked for in the right with its end excused, and laid on
    # its two sides from end to end there, it is the book.
    sc, r = dataset_scene("table2", 1, 13)
    book = r.truth["books"][0]
    assert book["cover"] == "plain"
    found = _near_book(sc, r, book, [])
    assert len(found) == 1 and found[0].source == "one image"
    assert np.abs(found[0].pose.center - book["center"]).max() < 0.006  # m, on each axis
    assert _near_book(sc, r, book, ["stereo.pool_transfer_late=false"]) == []
    assert _near_book(sc, r, book, ["stereo.pool_transfer_fit=false"]) == []


def test_a_plain_book_end_to_end_with_a_taller_one_is_laid_on_its_excused_end():
    # Table II's scene 17 (30 lx): the 233 × 102 × 23 mm plain book end to end with the
    # 30 mm one of its tone. The right image's candidate closes its end at the seam where
    # its long sides' edges end, askew; the left image shows little edge there. The pair
    # as it is tilts, and the fit that must lie on that end misses it by 4.4 px: lost.
    # Fitted with that end excused (stereo.pool_transfer_excuse_px), it is the book.
    sc, r = dataset_scene("table2", 1, 17)
    book = r.truth["books"][1]
    assert book["cover"] == "plain"
    found = _near_book(sc, r, book, [])
    assert len(found) == 1 and found[0].source == "one image"
    assert np.abs(found[0].pose.center - book["center"]).max() < 0.006  # m, on each axis
    assert abs(found[0].pose.size[2] - book["size"][2]) < 0.004  # m: the height
    assert _near_book(sc, r, book, ["stereo.pool_transfer_excuse_px=0"]) == []


def test_a_late_candidate_with_a_side_unseen_is_a_book_only_as_the_fit_makes_it():
    # build/t2b's scene 25 (rovis synth --protocol table2 --seed 2): the late pool holds a
    # candidate over the desk between books, its far side unseen, that the other image
    # shows only with a side along the epipolar lines short. Reconstructed as it is, it
    # passed the pose checks: a false book (with the pipeline's fit_only forced False, and
    # in a trial without the rule). Laid on its sides from end to end, it misses them.
    sc, r = dataset_scene("table2", 2, 25)
    res = Detector(sc.rig).detect(r.left, r.right)
    assert _false_books(res, r.truth) == []
def test_desk_between_found_books_is_no_book(monkeypatch):
    # Table II's scene 44: the desk between a dark and two light books, each found; a
    # candidate there has its sides on theirs, and the other image shows them too, a few
    # millimetres up (the desk's grain is along the epipolar lines: its print places no
    # height). Two sides on found books' outlines (cover and page block) mark it.
    import rovis.pipeline as pl

    sc, r = dataset_scene("table2", 1, 44)
    gap = np.array([0.648, 0.279])  # where it was reported, 7-8 mm up

    def near_gap(**settings) -> int:
        res = Detector(sc.rig, DetectConfig(**settings)).detect(r.left, r.right)
        return sum(np.linalg.norm(o.pose.center[:2] - gap) < 0.03 for o in res.objects)

    assert not any(np.linalg.norm(np.array(b["center"][:2]) - gap) < 0.06
                   for b in r.truth["books"])
    assert near_gap() == 0
    monkeypatch.setattr(pl, "_sides_on", lambda quad, regions, **kw: np.zeros(4, bool))
    assert near_gap(unskew_deg=0.0) == 1  # (its angles are 25-38° off 90°: no rectangle,
    assert near_gap() == 0  # which the unskew step drops too)


def test_a_small_cover_between_books_of_other_heights_is_a_book_by_its_print():
    # build/t1d's scene 72 (rovis synth --protocol table1 --seed 4): a light 156 x 109 x 9
    # mm cover at the far side of the workspace, between a dark book 19 mm high and a
    # light one 55 mm high, two of its sides on their outlines. Only the small candidates
    # with sides unseen hold it (about 3700 px² in the left image); the pair makes a flat
    # cover, which the desk-between-books rule turned down. Its print matches between the
    # images at its height (NCC 0.99, the desk 0.86-0.89: the desk is under a pixel of
    # disparity below a 9 mm cover) and neither neighbour stands there: a book of its own
    # (stereo.small_open_between).
    sc, r = dataset_scene("table1", 4, 72)
    book = r.truth["books"][0]
    assert book["cover"] == "light" and abs(book["size"][2] - 0.009) < 0.001
    found = _near_book(sc, r, book, [])
    assert len(found) == 1 and found[0].source == "candidates"
    assert np.abs(found[0].pose.center - book["center"]).max() < 0.008  # m, on each axis
    assert abs(found[0].pose.size[2] - book["size"][2]) < 0.003  # m: the height
    np.testing.assert_allclose(sorted(found[0].pose.size[:2]), sorted(book["size"][:2]),
                               atol=0.008)
    assert _near_book(sc, r, book, ["stereo.small_open_between=false"]) == []
    # its print must beat the desk's NCC by a clear margin (0.10-0.13 here: not 0.2)
    assert _near_book(sc, r, book, ["stereo.small_open_print_gap=0.2"]) == []


def test_a_piece_flush_with_a_book_of_its_height_stays_the_desk_between_books():
    # Table I's scene 8 (rovis synth --protocol table1 --seed 1): a small candidate beside
    # a 21 mm photo cover, two sides on found books' outlines, its print matching at 21-26
    # mm. A book of that height holds one of its sides: a piece of it, not a book of its
    # own. Without that condition (stereo.small_open_apart=0) it is a false book.
    sc, r = dataset_scene("table1", 1, 8)
    res = Detector(sc.rig).detect(r.left, r.right)
    assert _false_books(res, r.truth) == []
    loose = with_settings(DetectConfig(), ["stereo.small_open_apart=0"])
    false = _false_books(Detector(sc.rig, loose).detect(r.left, r.right), r.truth)
    assert len(false) == 1 and false[0].source == "candidates"
    assert 0.018 < false[0].pose.size[2] < 0.025  # m: at the photo cover's height


def test_sides_on_found_books():
    from rovis.pipeline import _sides_on

    a = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0], [0.0, 50.0]])
    b = a + [200.0, 0.0]
    gap = np.array([[101.0, 0.0], [199.0, 1.0], [198.5, 50.0], [101.5, 50.0]])  # between them
    assert _sides_on(gap, [a, b]).tolist() == [False, True, False, True]
    assert _sides_on(gap, [a]).sum() == 1
    assert _sides_on(gap, [a], tol_px=0.5).sum() == 0  # 1-1.5 px away
    assert _sides_on(gap + [-20.0, 0.0], [a]).tolist() == [False, False, False, True]  # inside
    assert not _sides_on(gap + [0.0, 80.0], [a, b]).any()  # beyond both
    assert not _sides_on(gap, []).any()


def test_a_cover_a_pixel_off_at_each_corner_is_refit_flat():
    # Table I's scene 14 (rovis synth --protocol table1 --seed 1): a 1.2 cm plain book
    # whose covers both images' closed loops kept, each corner within 1.4 px. Those pixels
    # put two corners 10 mm lower than the others: a side on the desk, dropped, and a
    # wrong pair of candidates 5 cm high took its place. Refit as one rectangle parallel
    # to the desk, the pair is the book.
    sc, r = dataset_scene("table1", 1, 14)
    book = r.truth["books"][0]

    def nearest(flat_refit_px: float) -> float:
        res = Detector(sc.rig, DetectConfig(flat_refit_px=flat_refit_px)).detect(r.left, r.right)
        return nearest_book(res, book["center"])[1]

    assert nearest(1.0) < 0.01  # m
    assert nearest(0.0) > 0.03


@pytest.mark.parametrize("sides", [True, False])
def test_a_side_on_the_shadows_edge_is_left_out_of_the_flat_refit(sides):
    # build/t2 scene 10 (60 lx, a lamp): book 3, a dark plain cover 51 mm high; the right
    # image took its right-hand side on the soft edge of its shadow, 4-5 px outside the
    # cover, and the pair came out tilted (corner heights 50, -25, -15 and 49 mm). Fitted
    # flat to its sides with that one left out, the book is within 3 mm of its height;
    # without, the one-image search placed it 8 mm low
    sc, r = dataset_scene("table2", 1, 10)
    settings = [] if sides else ["flat_refit_sides=0"]
    res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
    truth = r.truth["books"][3]
    book, _ = nearest_book(res, truth["center"], on_desk=True)
    assert np.linalg.norm(book.pose.center[:2] - truth["center"][:2]) < 0.03  # m
    height_error = abs(book.pose.size[2] - truth["size"][2])
    if sides:
        assert height_error < 0.003  # m
        assert np.abs(book.pose.center - truth["center"]).max() < 0.003
    else:
        assert height_error > 0.006
