"""Cover extent in 3D (rovis.extent): sides moved to the cover's edges in both images; and
the pose checks that drop quads no book makes."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from rovis import extent, geometry
from rovis.extent import CompleteConfig, ExtentConfig, complete_open, fit_pair_extent
from rovis.heightmap import HeightMapConfig
from rovis.pipeline import DetectConfig, Detector, Pair, with_settings
from rovis.segment import SegmentConfig, gradients
from rovis.segment.edges import CANNY_LOW_RATIO
from rovis.synth import render, sample_scene
from rovis.synth.scene import Book, Light
from rovis.synth import textures
from rovis.synth.textures import COVER_PX_PER_M, CoverSpec
from rovis.sweep import SweepConfig, high_pass, on_plane

from conftest import ideal_images, nearest_book
from dataset_scene import dataset_scene

THICKNESS = 0.02


LONE_BOOK = Book(center=(0.45, 0.33, THICKNESS), yaw_deg=20.0, size=(0.22, 0.15, THICKNESS),
                 cover=CoverSpec(kind="plain", albedo=0.08, seed=1))


def _rendered(books, light=None):
    """A clean desk (no clutter) with ``books`` at 500 lx (or under ``light``): the
    rendering, both ideal images' gradients and the projections."""
    sc = sample_scene(3, lux=500.0, n_books=0)
    sc = replace(sc, books=tuple(books), papers=(), mugs=(), pens=(), cables=())
    if light is not None:
        sc = replace(sc, light=light)
    r = render(sc, 3)
    grads = {cam: gradients(img) for cam, img in ideal_images(sc.rig, r).items()}
    return r, grads, {"left": sc.rig.Q_L, "right": sc.rig.Q_R}, sc.rig


@pytest.fixture(scope="module")
def lone_book():
    """One plain dark book, 22 × 15 × 2 cm, alone on the desk at 500 lx."""
    r, grads, Q, rig = _rendered([LONE_BOOK])
    return np.array(r.truth["books"][0]["corners"]), Q, grads, np.asarray(r.truth["desk_plane"]), rig


def _side_moved(P, s, d):
    """Corners with side s (corner s to s+1) moved outward by d metres (inward if d < 0)."""
    out = P.copy()
    a, b = s, (s + 1) % 4
    out[a] += d * (P[a] - P[a - 1]) / np.linalg.norm(P[a] - P[a - 1])
    out[b] += d * (P[b] - P[(b + 1) % 4]) / np.linalg.norm(P[b] - P[(b + 1) % 4])
    return out


def _fit(P, Q, grads, desk):
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    corners = {cam: geometry.project(Q[cam], P) for cam in Q}
    new = fit_pair_extent(corners, Q, grads, {"left": strength, "right": strength}, desk)
    if new is None:
        return None
    return geometry.triangulate(Q["left"], Q["right"], new["left"], new["right"])


@pytest.mark.parametrize("cut", [((2, -0.06),), ((0, -0.05), (2, -0.04)), ((3, -0.03),)])
def test_a_cover_cut_short_grows_to_its_edges(lone_book, cut):
    # a quad ending at printed lines across the cover (one band, or one each side); the
    # sides next to a cut side are the cover's own edges
    P, Q, grads, desk, _ = lone_book
    partial = P
    for s, d in cut:
        partial = _side_moved(partial, s, d)
    got = _fit(partial, Q, grads, desk)
    assert got is not None
    # every corner back on the true one, to grasping accuracy
    assert np.linalg.norm(got - P, axis=1).max() < 0.004


def test_a_side_beyond_the_cover_is_pulled_in(lone_book):
    P, Q, grads, desk, _ = lone_book
    got = _fit(_side_moved(P, 1, 0.035), Q, grads, desk)
    assert got is not None
    assert np.linalg.norm(got - P, axis=1).max() < 0.004


@pytest.mark.parametrize("still_cover", [True, False])
def test_a_side_stays_where_the_strip_it_would_cut_is_still_cover(lone_book, still_cover):
    # the extent asks the caller about the strip a pull inward cuts away, less the margin
    # next to the side's new place; True keeps the side where it is
    P, Q, grads, desk, _ = lone_book
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    out = 0.035  # m, beyond the cover's edge
    wide = _side_moved(P, 1, out)
    asked = []

    def answer(strip):
        asked.append(strip)
        return still_cover

    new = fit_pair_extent({cam: geometry.project(Q[cam], wide) for cam in Q}, Q, grads,
                          {"left": strength, "right": strength}, desk, still_cover=answer)
    margin = ExtentConfig().keep_print_margin
    assert len(asked) == 1
    strip = asked[0]
    # the strip runs along side 1, from where the side was to `margin` short of the cut
    assert np.linalg.norm(strip[0] - wide[1]) < 1e-6 and np.linalg.norm(strip[1] - wide[2]) < 1e-6
    assert np.linalg.norm(strip[3] - strip[0]) == pytest.approx(out - margin, abs=0.003)
    if still_cover:
        assert new is None  # the side stays, and nothing else moves
    else:
        got = geometry.triangulate(Q["left"], Q["right"], new["left"], new["right"])
        assert np.linalg.norm(got - P, axis=1).max() < 0.004


def test_a_pull_within_the_margin_is_not_asked_about(lone_book):
    # a pull no longer than extent.keep_print_margin (the maps carry a cover's height up to
    # 2 cm beyond its edge) is the edges' call alone: here a 3.5 cm pull under a 5 cm margin
    P, Q, grads, desk, _ = lone_book
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    wide = _side_moved(P, 1, 0.035)
    cfg = ExtentConfig(keep_print_margin=0.05)

    def never(strip):
        raise AssertionError("asked about a cut within the margin")

    new = fit_pair_extent({cam: geometry.project(Q[cam], wide) for cam in Q}, Q, grads,
                          {"left": strength, "right": strength}, desk, cfg, still_cover=never)
    got = geometry.triangulate(Q["left"], Q["right"], new["left"], new["right"])
    assert np.linalg.norm(got - P, axis=1).max() < 0.004


@pytest.mark.parametrize("scene, book", [(4, 1), (41, 3)])
def test_a_book_the_maps_found_is_not_cut_at_a_gap_in_its_print(scene, book):
    # build/t1d (`rovis synth build/t1d --protocol table1 --n 100 --seed 4`) scenes 4 and 41:
    # photo covers 36 and 52 mm high, found from the height maps; without the maps' say the
    # extent step pulls a side in by 55 mm (scene 4) or two by 34 and 46 mm (scene 41), over
    # the picture the maps read at the cover's height, to 59 and 27 mm wide, and the book is
    # dropped as too narrow
    sc, r = dataset_scene("table1", 4, scene)
    truth = np.asarray(r.truth["books"][book]["center"])

    def nearest(settings):
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        return min((float(np.abs(o.pose.center - truth).max()) for o in res.objects),
                   default=np.inf)

    assert nearest([]) < 0.005  # m, along each axis
    assert nearest(["extent.keep_print=false"]) > 0.05  # m: lost


def test_a_whole_cover_keeps_its_sides(lone_book):
    P, Q, grads, desk, _ = lone_book
    got = _fit(P, Q, grads, desk)
    assert got is None or np.linalg.norm(got - P, axis=1).max() < 0.002


def test_switched_off_the_pipeline_skips_it():
    r, _, _, rig = _rendered([LONE_BOOK])
    on = Detector(rig).detect(r.left, r.right)
    off = Detector(rig, DetectConfig(extent=ExtentConfig(grow=False, shrink=False))).detect(
        r.left, r.right)
    assert "extent" in on.timing_ms and "extent" not in off.timing_ms
    assert len(off.objects) == len(on.objects) == 1


@pytest.mark.parametrize("low, kept", [(0.003, True), (0.001, False)])
def test_a_quad_with_a_side_on_the_desk_is_no_cover(lone_book, low, kept):
    # one side on a line of the desk (a shadow's edge, a page block's foot), the other at
    # cover height: flat enough for the tilt test (< 6°), but no cover
    P, Q, _, desk, rig = lone_book
    quad = P.copy()
    quad[:2, 2] = 0.012
    quad[2:, 2] = low
    pair = Pair(geometry.project(Q["left"], quad), geometry.project(Q["right"], quad), 1.0, 0.0)
    _, book, why = Detector(rig)._reconstruct_or_why(rig, pair, desk)
    assert (book is not None) == kept
    assert why == ("" if kept else "side on desk")


@pytest.mark.parametrize("rise, kept", [(0.005, True), (0.03, False)])
def test_a_cover_tilted_against_the_desk_is_dropped_and_says_so(lone_book, rise, kept):
    # two corners raised: 2° (kept) or 11° (an outline in one image, a cover in the other)
    P, Q, _, desk, rig = lone_book
    quad = P.copy()
    quad[:2, 2] += rise
    pair = Pair(geometry.project(Q["left"], quad), geometry.project(Q["right"], quad), 1.0, 0.0)
    _, book, why = Detector(rig)._reconstruct_or_why(rig, pair, desk)
    assert (book is not None) == kept
    assert why == ("" if kept else "tilted")


@pytest.mark.parametrize("length, kept", [(0.30, True), (0.50, False)])
def test_a_cover_longer_than_any_book_is_dropped(lone_book, length, kept):
    # e.g. two books end to end taken for one cover
    P, Q, _, desk, rig = lone_book
    quad = _side_moved(P, 1, length - np.linalg.norm(P[1] - P[0]))
    pair = Pair(geometry.project(Q["left"], quad), geometry.project(Q["right"], quad), 1.0, 0.0)
    _, book, why = Detector(rig)._reconstruct_or_why(rig, pair, desk)
    assert (book is not None) == kept
    assert why == ("" if kept else "too long")
    if kept:
        assert max(book.pose.size[:2]) == pytest.approx(length, abs=1e-3)


@pytest.mark.parametrize("width, kept", [(0.08, True), (0.03, False)])
def test_a_cover_narrower_than_any_book_is_dropped(lone_book, width, kept):
    # e.g. a printed square of a chessboard, a label
    P, Q, _, desk, rig = lone_book
    sides = [np.linalg.norm(P[(k + 1) % 4] - P[k]) for k in range(4)]
    short = int(np.argmin(sides[:2]))  # side 0 or 1; its neighbour side is moved
    quad = _side_moved(P, short + 1, width - sides[short])
    pair = Pair(geometry.project(Q["left"], quad), geometry.project(Q["right"], quad), 1.0, 0.0)
    det = Detector(rig)
    # with the desk plane, last (the extent step may grow a piece to the whole cover)
    pair, book, why = det._reconstruct_or_why(rig, pair, desk)
    assert book is not None, why
    assert min(book.pose.size[:2]) == pytest.approx(width, abs=1e-3)
    found, small = det._without_small([(pair, book)])
    assert len(found) == kept
    assert [why for why, _, _ in small] == ([] if kept else ["too small"])
    # without it (the real chess pairs have none) no extent step follows: dropped at once,
    # its quads left free for the one-image search
    _, book, why = det._reconstruct_or_why(rig, pair, None)
    assert (book is not None) == kept and why == ("" if kept else "too small")


@pytest.fixture(scope="module")
def book_with_neighbour():
    """The lone book with a thicker, shorter one flush against its side 2 (P3–P4)."""
    a = LONE_BOOK
    mid = 0.5 * (a.corners[2] + a.corners[3])
    normal = (mid - np.array(a.center))[:2]
    reach = float(np.linalg.norm(normal))
    normal /= reach
    along_x = abs(normal @ a.R[:2, 0]) > 0.5  # side 2 faces along the book's length?
    size = (0.08, 0.6 * a.size[1], 0.04) if along_x else (0.6 * a.size[0], 0.08, 0.04)
    depth = size[0] if along_x else size[1]
    xy = np.array(a.center[:2]) + normal * (reach + 0.5 * depth + 0.001)
    b = Book(center=(float(xy[0]), float(xy[1]), size[2]), yaw_deg=20.0, size=size,
             cover=CoverSpec(kind="light", albedo=0.75, seed=2))
    r, grads, Q, _ = _rendered([a, b])
    return np.array(r.truth["books"][0]["corners"]), Q, grads, np.asarray(r.truth["desk_plane"])


def test_growth_stops_at_the_cover_edge_next_to_another_book(book_with_neighbour):
    P, Q, grads, desk = book_with_neighbour
    got = _fit(_side_moved(P, 2, -0.05), Q, grads, desk)
    assert got is not None
    # back to the true edge, not onto the neighbour's cover or its far edge
    assert np.linalg.norm(got - P, axis=1).max() < 0.004


def _faded(P, Q, grads, s):
    """``grads`` with no gradient along the middle fifth of side s of P, 9 px wide (both
    images): a picture cover's edge where the picture has the desk's tone. Of the 24
    samples a side test reads (10-90 % of it), 62-67 % are left on the lone book's sides:
    less than ``ExtentConfig.min_support``, more than ``weak_support``."""
    a, b = P[s], P[(s + 1) % 4]
    out = {}
    for cam in Q:
        ends = geometry.project(Q[cam], np.array([a + 0.4 * (b - a), a + 0.6 * (b - a)]))
        mask = np.zeros(grads[cam].shape, np.uint8)
        cv2.line(mask, *(tuple(int(v) for v in np.rint(q)) for q in ends), 255, 9)
        keep = mask == 0
        out[cam] = replace(grads[cam], dx=grads[cam].dx * keep, dy=grads[cam].dy * keep)
    return out


@pytest.mark.parametrize("weak_support, grows", [(0.5, True), (0.7, False)])
def test_a_faint_cover_edge_that_stereo_places_is_grown_to(lone_book, weak_support, grows):
    # side 0 runs steeply in the image (stereo places it to 2 mm); its middle faded, no
    # move passes min_support: the cover cut 3 cm short grows back only on the faint edge
    P, Q, grads, desk, _ = lone_book
    faded = _faded(P, Q, grads, 0)
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    short = _side_moved(P, 0, -0.03)
    d = extent._grow_side(short, 0, Q, faded, {"left": strength, "right": strength},
                          extent._drop(short, desk), ExtentConfig(weak_support=weak_support))
    if grows:
        assert d == pytest.approx(0.03, abs=0.002)
    else:
        assert d < 0.02  # (at most onto a line of the print; the plain cover has none)


def test_a_faint_side_along_the_epipolar_lines_grows_only_where_the_maps_vouch(lone_book):
    # side 1 runs near the image rows: stereo cannot place it, and a faint line in a
    # cover's print would pass as well as the cover's edge
    P, Q, grads, desk, _ = lone_book
    faded = _faded(P, Q, grads, 1)
    strength = {cam: CANNY_LOW_RATIO * SegmentConfig().open_T_H for cam in Q}
    short = _side_moved(P, 1, -0.03)
    drop = extent._drop(short, desk)
    assert extent._grow_side(short, 1, Q, faded, strength, drop, ExtentConfig()) == 0.0
    # (as the pipeline's grow by the height maps: as far as they carry the cover's height)
    vouched = extent._grow_side(short, 1, Q, faded, strength, drop, ExtentConfig(),
                                limit=0.04, continuation=0.5)
    assert vouched == pytest.approx(0.03, abs=0.002)


def test_detect_reports_the_lone_book_where_it_is(lone_book):
    P, _, _, _, rig = lone_book
    r, _, _, _ = _rendered([LONE_BOOK])
    result = Detector(rig).detect(r.left, r.right)
    assert len(result.objects) == 1
    found = result.objects[0]
    np.testing.assert_allclose(found.corners_world.mean(axis=0), P.mean(axis=0), atol=0.005)
    assert sorted(found.pose.size[:2]) == pytest.approx(sorted(LONE_BOOK.size[:2]), abs=0.006)
    # eq. 1 order: P1 is the top-left corner in the left image
    px = found.corners_left_px
    assert np.argmin(px.sum(axis=1)) == 0


def _shadow_scene(elevation_deg, azimuth_deg, thickness):
    """A thin light book alone on the desk under a low sun: its cast shadow lies beyond one
    end, its sides running on along the book's long sides."""
    sun = (np.cos(np.radians(elevation_deg)) * np.cos(np.radians(azimuth_deg)),
           np.cos(np.radians(elevation_deg)) * np.sin(np.radians(azimuth_deg)),
           np.sin(np.radians(elevation_deg)))
    light = Light(kind="daylight", lux=300.0, direction=sun, ambient=0.2, mullions=0,
                  penumbra_px=1.5)
    book = replace(LONE_BOOK, center=(0.45, 0.33, thickness), size=(0.22, 0.15, thickness),
                   cover=CoverSpec(kind="plain", albedo=0.7, seed=1))
    r, grads, Q, _ = _rendered([book], light=light)
    return np.array(r.truth["books"][0]["corners"]), Q, grads, np.asarray(r.truth["desk_plane"])


# sun behind either end of the book (its yaw is 20°): the shadow beyond side 2, or side 0
@pytest.mark.parametrize("azimuth, side", [(20.0, 2), (200.0, 0)])
def test_a_cover_does_not_grow_over_its_shadow(azimuth, side):
    P, Q, grads, desk = _shadow_scene(12.0, azimuth, 0.006)
    up = desk[:3]
    # stereo places the cover's own end at its height, the shadow's far edge on the desk
    # (the book is 6 mm thick: about half a pixel of disparity)
    assert extent._edge_level(P, side, Q, grads, up, -0.006 * up, ExtentConfig()) == \
        pytest.approx(0.006, abs=0.003)
    # without the height test the cover grows over the shadow (the case is real) ...
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    corners = {cam: geometry.project(Q[cam], P) for cam in Q}
    blind = fit_pair_extent(corners, Q, grads, {"left": strength, "right": strength}, desk,
                            ExtentConfig(height_check=False))
    assert blind is not None
    grown = geometry.triangulate(Q["left"], Q["right"], blind["left"], blind["right"])
    assert np.linalg.norm(grown - P, axis=1).max() > 0.015
    shadow_side = _side_moved(P, side, float(np.linalg.norm(grown - P, axis=1).max()))
    assert extent._edge_level(shadow_side, side, Q, grads, up, -0.006 * up,
                              ExtentConfig()) == pytest.approx(0.0, abs=0.003)
    # ... with it, the cover keeps its sides
    got = _fit(P, Q, grads, desk)
    assert got is None or np.linalg.norm(got - P, axis=1).max() < 0.003


def test_stereo_places_a_cover_side_at_the_cover_height(lone_book):
    # the lone book is 2 cm thick: a side whose page block is hidden, where stereo can
    # place it, is measured at the cover's height, so a shrink may not move it (it is the
    # cover's edge, or a print on it)
    P, Q, grads, desk, _ = lone_book
    up, drop = desk[:3], -THICKNESS * desk[:3]
    measured = 0
    for s in range(4):
        level = extent._edge_level(P, s, Q, grads, up, drop, ExtentConfig())
        if level is not None and not extent._block_shows(P, s, Q, drop):
            measured += 1
            assert level == pytest.approx(THICKNESS, abs=0.005)
            assert extent._holds_side(P, s, Q, grads, up, drop, ExtentConfig())
    assert measured >= 1


def test_a_cover_found_otherwise_is_not_grown_over_a_segmented_one(monkeypatch):
    """Two touching books of one height: the extent step may take the edge beyond the
    second for the first one's far side. A cover from the candidates (or one image, or the
    height map) then keeps its sides instead of swallowing the cover both segmentations
    found; a segmented cover grown over another found otherwise still takes its place."""
    import rovis.pipeline as pipeline
    from rovis.results import BookDetection
    from rovis.segment.boundary import Segmentation

    sc = sample_scene(3, lux=500.0, n_books=0)
    det = Detector(sc.rig)
    a = np.array([[100.0, 100], [200, 100], [200, 180], [100, 180]])
    b = a + [105.0, 0.0]  # the touching neighbour, right of a
    union = np.array([[100.0, 100], [305, 100], [305, 180], [100, 180]])

    def book(pair):
        pose = geometry.BookPose(np.zeros(3), np.eye(3), np.array([0.2, 0.1, 0.02]),
                                 np.array([0.0, 0.0, 1.0]))
        return BookDetection(0, pose, np.zeros((4, 3)), pair.left, pair.right, 0.0, 1.0,
                             source=pair.source)

    monkeypatch.setattr(pipeline, "fit_pair_extent",
                        lambda quads, *args, **kw: {"left": union, "right": union}
                        if np.allclose(quads["left"], a) else None)
    monkeypatch.setattr(Detector, "_reconstruct_or_why",
                        lambda self, rig, pair, *args: (pair, book(pair), ""))
    for grown, other, kept in (("candidates", "segmentation", 2),
                               ("segmentation", "candidates", 1)):
        pa, pb = Pair(a, a, 1.0, 0.0, source=grown), Pair(b, b, 1.0, 0.0, source=other)
        segs = {cam: Segmentation.empty(T_H=60.0) for cam in ("left", "right")}
        out = det._fit_extents(sc.rig, segs, {}, [(pa, book(pa)), (pb, book(pb))],
                               np.array([0.0, 0, 1, 0]))
        assert len(out) == kept
        if kept == 2:  # both as they were
            np.testing.assert_array_equal(out[0][0].left, a)
            np.testing.assert_array_equal(out[1][0].left, b)
        else:  # the segmented cover, moved, in place of the other
            np.testing.assert_array_equal(out[0][0].left, union)


# -- completing a candidate with sides unseen (complete_open) -------------------------------


def _complete(P, guess_left, guess_right, unseen, lone_book, **kw):
    _, Q, grads, desk, _ = lone_book
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    seen = np.ones(4, bool)
    seen[list(unseen)] = False
    corners = {"left": geometry.project(Q["left"], guess_left),
               "right": geometry.project(Q["right"], guess_right)}
    return complete_open(corners, {"left": seen, "right": seen}, Q, grads,
                         {"left": strength, "right": strength}, desk, **kw)


def _sizes(P):
    side = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    return np.array([side[0] + side[2], side[1] + side[3]]) / 2


@pytest.fixture(scope="module")
def refined_whole(lone_book):
    """Worst corner error (m) of the lone book refined with all four sides seen, both
    images, triangulated: what segmentation gives when nothing is hidden."""
    from rovis.segment.boundary import refine_quad
    P, Q, grads, _, _ = lone_book
    px = {cam: refine_quad(grads[cam], geometry.project(Q[cam], P)) for cam in Q}
    X = geometry.triangulate_dlt(Q["left"], Q["right"], px["left"], px["right"])
    return float(np.linalg.norm(X - P, axis=1).max())


@pytest.mark.parametrize("unseen", [(0,), (1,), (2,), (3,), (0, 1), (1, 2), (2, 3), (3, 0),
                                    (0, 2), (1, 3)])
def test_unseen_sides_are_placed_in_3d_where_both_images_show_an_edge(lone_book, refined_whole,
                                                                      unseen):
    # each image guessed the unseen sides a centimetre or so off, differently: refined in
    # each image alone they would make no flat cover. Placed in 3D from the seen sides,
    # the cover is as good as with every side seen.
    P = lone_book[0]
    left, right = P, P
    for s, (dl, dr) in zip(unseen, ((0.012, -0.008), (-0.010, 0.015))):
        left, right = _side_moved(left, s, dl), _side_moved(right, s, dr)
    got = _complete(P, left, right, unseen, lone_book)
    assert got is not None
    worst = float(np.linalg.norm(got - P, axis=1).max())
    assert worst < refined_whole + 0.002  # m
    assert worst < 0.012  # m
    np.testing.assert_allclose(_sizes(got), _sizes(P), atol=0.004)  # m
    # a rectangle parallel to the desk
    assert np.ptp(got[:, 2]) < 1e-9


def test_the_print_gives_the_height_where_the_seen_sides_give_none(lone_book):
    # sides 1 and 3 run near the image rows: seen alone, stereo cannot place them, and the
    # unseen ends (each guessed a centimetre off) go where the print puts the cover
    P = lone_book[0]
    left, right = _side_moved(P, 0, 0.012), _side_moved(P, 2, -0.010)
    asked = []

    def by_print(h):
        def ask():
            asked.append(h)
            return h
        return ask

    got = _complete(P, left, right, (0, 2), lone_book, print_height=by_print(THICKNESS))
    assert asked == [THICKNESS]
    assert got is not None
    assert np.linalg.norm(got - P, axis=1).max() < 0.004  # m
    # a print at the desk's height (a sheet) is no cover
    assert _complete(P, left, right, (0, 2), lone_book, height_range=(0.006, 0.1),
                     print_height=by_print(0.0)) is None

    def never():
        raise AssertionError("the seen sides give the height: the print is not asked")

    # seen sides 0 and 2 run steeply in the images: stereo places them
    assert _complete(P, _side_moved(P, 1, 0.012), _side_moved(P, 3, -0.010), (1, 3),
                     lone_book, print_height=never) is not None


def test_no_edge_where_a_side_is_guessed_gives_no_cover(lone_book):
    P, Q, grads, desk, _ = lone_book
    # the far side guessed 6 cm out, on bare desk: nothing within the search shows a step
    far = _side_moved(P, 3, 0.06)
    assert _complete(P, far, far, (3,), lone_book) is None
    # a featureless image: no side to fit, no edge anywhere
    blank = {cam: gradients(np.full(grads[cam].shape, 120, np.uint8)) for cam in grads}
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    seen = np.array([True, True, True, False])
    corners = {cam: geometry.project(Q[cam], P) for cam in Q}
    assert complete_open(corners, {"left": seen, "right": seen}, Q, blank,
                         {"left": strength, "right": strength}, desk) is None
    # nothing to complete: every side seen, or fewer than two
    assert _complete(P, P, P, (), lone_book) is None
    assert _complete(P, P, P, (0, 1, 2), lone_book) is None
    # a height outside the range asked for
    assert _complete(P, _side_moved(P, 2, 0.01), P, (2,), lone_book,
                     height_range=(0.03, 0.10)) is None


@pytest.fixture(scope="module")
def desk_toned_book():
    """build/t1b's scene 25, book 3: a plain 5.1 cm book of the desk's tone whose two far
    sides show no step in either image (against the desk, and against another plain book)."""
    sc, r = dataset_scene("table1", 2, 25)
    grads = {cam: gradients(img) for cam, img in ideal_images(sc.rig, r).items()}
    Q = {"left": sc.rig.Q_L, "right": sc.rig.Q_R}
    return np.array(r.truth["books"][3]["corners"]), Q, grads, np.asarray(r.truth["desk_plane"])


def _complete_far(book, guess_left, guess_right, **kw):
    # sides 1 and 2 (its far sides) unseen; the seen sides 3 and 0 meet at its near corner
    P, Q, grads, desk = book
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    seen = np.array([True, False, False, True])
    corners = {"left": geometry.project(Q["left"], guess_left),
               "right": geometry.project(Q["right"], guess_right)}
    return complete_open(corners, {"left": seen, "right": seen}, Q, grads,
                         {"left": strength, "right": strength}, desk, CompleteConfig(**kw))


def test_unseen_sides_with_no_step_stay_where_the_seen_sides_end(desk_toned_book):
    P = desk_toned_book[0]
    got = _complete_far(desk_toned_book, P, P)
    assert got is not None
    assert np.linalg.norm(got - P, axis=1).max() < 0.004  # m
    # without the step (CompleteConfig.at_ends off) nothing places those sides
    assert _complete_far(desk_toned_book, P, P, at_ends=False) is None


@pytest.mark.parametrize("move", [-0.03, 0.03])
def test_no_side_where_the_seen_sides_run_on_or_stop_short(desk_toned_book, move):
    # both images guess the far side 3 cm inside the cover (the seen sides' edges run on
    # beyond) or 3 cm out on the desk (they stop short of it): no cover
    P = desk_toned_book[0]
    moved = _side_moved(P, 1, move)
    assert _complete_far(desk_toned_book, moved, moved) is None
    # (the ends test is what refuses it: without it, a cover 3 cm off)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(extent, "_ends_at", lambda *a, **k: True)
        got = _complete_far(desk_toned_book, moved, moved)
        assert got is not None and np.linalg.norm(got - P, axis=1).max() > 0.025


def test_no_side_where_the_two_images_guess_it_apart(desk_toned_book):
    P = desk_toned_book[0]
    apart = _side_moved(P, 1, 0.01)  # the left image's guess 1 cm further out
    assert _complete_far(desk_toned_book, apart, P) is None
    assert _complete_far(desk_toned_book, apart, P, ends_agree=0.02) is not None


@pytest.mark.parametrize("gate", ["plain", "spread", "facing", "side_range"])
def test_each_test_of_the_ends_can_refuse_the_side(desk_toned_book, monkeypatch, gate):
    P = desk_toned_book[0]
    kw = {}
    if gate == "plain":  # edges inside: a print, or another book's side, under the cover
        monkeypatch.setattr(extent, "strong_share", lambda *a, **k: 0.05)
    elif gate == "spread":  # the heights stereo measured disagree
        kw["ends_spread"] = 0.0
    elif gate == "facing":  # a side facing the camera would show its own page block
        monkeypatch.setattr(extent, "_block_shows", lambda *a, **k: True)
    else:  # the guess makes a side shorter than side_range allows (one side unseen: no
        # other side's search bounds it; the ends test passed, to reach the guess)
        _, Q, grads, desk = desk_toned_book
        monkeypatch.setattr(extent, "_ends_at", lambda *a, **k: True)
        strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
        seen = np.array([True, False, True, True])
        corners = {cam: geometry.project(Q[cam], P) for cam in Q}
        short = min(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1))

        def complete(lowest):
            return complete_open(corners, {"left": seen, "right": seen}, Q, grads,
                                 {"left": strength, "right": strength}, desk,
                                 side_range=(lowest, 0.45))

        assert complete(0.05) is not None
        assert complete(short + 0.005) is None
        return
    assert _complete_far(desk_toned_book, P, P, **kw) is None


def test_strong_share_counts_the_edges_inside_a_quad():
    img = np.full((200, 200), 120, np.uint8)
    quad = np.array([[40.0, 40.0], [160.0, 40.0], [160.0, 160.0], [40.0, 160.0]])
    assert extent.strong_share(gradients(img), quad, 20.0) == 0.0  # plain
    img[:, 100:] = 180  # a step across the middle
    share = extent.strong_share(gradients(img), quad, 20.0)
    assert 0.0 < share < 0.1  # a line of a few pixels' width
    # a quad whose middle no pixel of the image holds: nothing shows it plain
    assert extent.strong_share(gradients(img), quad + 1000.0, 20.0) == 1.0


def test_no_desk_between_found_books_from_the_plain_rule(monkeypatch):
    # rovis demo's scene: the bare desk between a photo book and a light one, an "L" of
    # their two sides, is plain inside; let in by the plain rule and completed there it
    # was a 159 x 226 mm "book" at 16 mm. Two of its sides are found books' edges: refused.
    import rovis.pipeline as pipeline
    from rovis.demo import DEMO_LUX, DEMO_SEED

    scene = sample_scene(DEMO_SEED, lux=DEMO_LUX, light="artificial")
    pair = render(scene, DEMO_SEED)
    truth = np.array([b["center"] for b in pair.truth["books"]])

    def false_positives():
        res = Detector(scene.rig).detect(pair.left, pair.right)
        return sum(np.linalg.norm(truth[:, :2] - o.pose.center[:2], axis=1).min() > 0.05
                   for o in res.objects)

    assert false_positives() == 0
    monkeypatch.setattr(pipeline, "_sides_on", lambda quad, regions, **kw: np.zeros(4, bool))
    assert false_positives() == 1


@pytest.mark.parametrize("seed, scene, book", [(2, 25, 3), (1, 8, 4), (1, 30, 3)])
def test_the_pipeline_finds_books_of_the_desks_tone(seed, scene, book):
    # build/t1b's scene 25 book 3, build/t1's scene 8 book 4 and scene 30 book 3: plain
    # covers of the desk's tone, 3.4-5.8 cm high, whose far sides show no step in either
    # image; each is a candidate with two sides unseen, completed where its near sides end
    sc, r = dataset_scene("table1", seed, scene)
    truth = np.asarray(r.truth["books"][book]["center"])

    def nearest(cfg):
        res = Detector(sc.rig, cfg).detect(r.left, r.right)
        return min((np.abs(o.pose.center - truth).max() for o in res.objects), default=np.inf)

    assert nearest(DetectConfig()) < 0.006  # m, along each axis
    without = CompleteConfig(at_ends=False)
    if (seed, scene) == (2, 25):
        # the dense map finds this one too (at 1.0 mm) since stop 62: the sweeps read
        # under 30 % of its rectangle, no longer too few (heightmap.dense_min_read)
        assert nearest(DetectConfig(complete=without)) < 0.006
        assert nearest(DetectConfig(complete=without,
                                    heightmap=HeightMapConfig(dense_min_read=0.3))) > 0.05
    else:
        assert nearest(DetectConfig(complete=without)) > 0.05  # m


def _with_near_side_on_its_foot(P, Q):
    """The projection by ``Q`` of cover ``P`` (4, 3) with the side facing the camera taken at
    its page block's foot (the side dropped onto the desk, z = 0), where a segmentation
    may take it; and that side's index."""
    from rovis.segment.lines import intersect

    q = geometry.project(Q, P)
    centre = q.mean(axis=0)

    def outward_down(k):  # how far down the image side k's outward normal points
        d = q[(k + 1) % 4] - q[k]
        n = np.array([d[1], -d[0]]) / np.linalg.norm(d)
        if n @ (0.5 * (q[k] + q[(k + 1) % 4]) - centre) < 0:
            n = -n
        return n[1]

    s = max(range(4), key=outward_down)
    a, b = s, (s + 1) % 4
    foot = geometry.project(Q, P[[a, b]] * [1.0, 1.0, 0.0])
    d_foot = (foot[1] - foot[0]) / np.linalg.norm(foot[1] - foot[0])
    out = q.copy()
    for k, other in ((a, (a - 1) % 4), (b, (b + 1) % 4)):  # along the lateral sides
        lateral = (q[k] - q[other]) / np.linalg.norm(q[k] - q[other])
        out[k] = intersect(foot[0], d_foot, q[other], lateral)
    return out, s


def test_a_side_facing_the_camera_is_settled_on_the_edge_both_images_share(lone_book):
    # the right image's near side on the page block's foot, the left's on the cover edge:
    # 4-10 px of disparity apart, the cover centimetres low on that side
    P, Q, grads, desk, _ = lone_book
    truth = {cam: geometry.project(Q[cam], P) for cam in Q}
    corners = dict(truth)
    corners["right"], _ = _with_near_side_on_its_foot(P, Q["right"])
    before = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    assert np.linalg.norm(before - P, axis=1).max() > 0.01
    got = extent.settle_facing_sides(corners, Q, grads, desk)
    assert got is not None
    np.testing.assert_allclose(got["left"], truth["left"], atol=0.1)  # kept
    assert np.abs(got["right"] - truth["right"]).max() < 1.0  # px: on the cover edge
    after = geometry.triangulate(Q["left"], Q["right"], got["left"], got["right"])
    assert np.linalg.norm(after - P, axis=1).max() < 0.004


def test_sides_both_images_agree_on_stay(lone_book):
    P, Q, grads, desk, _ = lone_book
    truth = {cam: geometry.project(Q[cam], P) for cam in Q}
    assert extent.settle_facing_sides(truth, Q, grads, desk) is None


def test_the_cover_height_comes_from_the_sides_that_do_not_face(lone_book):
    # as above, and the left image's other facing side 3 px off too: the facing sides'
    # heights are wrong (11 mm), the others' right (20 mm); the right image's near side
    # is settled at the latter
    P, Q, grads, desk, _ = lone_book
    truth = {cam: geometry.project(Q[cam], P) for cam in Q}
    corners = dict(truth)
    corners["right"], near = _with_near_side_on_its_foot(P, Q["right"])
    facing = [k for k in range(4) if extent._faces_down(truth, k)]
    other = next(k for k in facing if k != near)
    left = truth["left"].copy()
    left[[other, (other + 1) % 4]] += [0.0, 3.0]  # px, down the image
    corners["left"] = left
    got = extent.settle_facing_sides(corners, Q, grads, desk)
    assert got is not None
    assert np.abs(got["right"][[near, (near + 1) % 4]]
                  - truth["right"][[near, (near + 1) % 4]]).max() < 1.0  # px


# -- a side on its page block's foot in one image only (extent.settle_block_sides)

@pytest.fixture(scope="module")
def tall_book_aside():
    """build/t2's scene 49 (rovis synth --protocol table2 --n 64 --seed 1: 30 lx,
    daylight): book 6, a light cover 4.6 cm thick left of the image centre, whose
    right-hand page block the right camera sees and the left hardly; the rendering and its
    corners (4, 3), the projections, the desk plane and that side."""
    sc, r = dataset_scene("table2", 1, 49)
    P = np.array(r.truth["books"][6]["corners"])
    Q = {"left": sc.rig.Q_L, "right": sc.rig.Q_R}
    desk = np.asarray(r.truth["desk_plane"])
    drop = extent._drop(P, desk)
    shows = [[extent._block_shows(P, k, Q, drop, cams=(cam,)) for cam in ("left", "right")]
             for k in range(4)]
    s = next(k for k in range(4) if shows[k] == [False, True])
    return sc, r, P, Q, desk, s


def _one_side_moved(P, Q, s, share):
    """Both images' corners of cover ``P``, the right image's side ``s`` moved outward by
    ``share`` of its page block's width there (1: onto the block's foot)."""
    corners = {cam: geometry.project(Q[cam], P) for cam in Q}
    foot = _side_on_its_foot(P, Q["right"], s)
    corners["right"] = corners["right"] + share * (foot - corners["right"])
    return corners


def test_a_side_on_its_block_in_one_image_is_moved_to_the_cover_height(tall_book_aside):
    # the right image took the side at its page block's foot (3-4 px out), the left at the
    # cover's edge: the side's corners triangulate centimetres low
    _, _, P, Q, desk, s = tall_book_aside
    truth = {cam: geometry.project(Q[cam], P) for cam in Q}
    corners = _one_side_moved(P, Q, s, 1.0)
    assert np.abs(corners["right"] - truth["right"]).max() > 2.5  # px
    before = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    assert np.linalg.norm(before - P, axis=1).max() > 0.02  # m
    got = extent.settle_block_sides(corners, Q, desk)
    assert got is not None
    np.testing.assert_allclose(got["left"], corners["left"], atol=1e-9)  # kept
    assert np.abs(got["right"] - truth["right"]).max() < 0.05  # px: on the cover edge
    after = geometry.triangulate(Q["left"], Q["right"], got["left"], got["right"])
    assert np.linalg.norm(after - P, axis=1).max() < 0.001  # m
    # half-way to the foot (a blurred edge) is moved too
    assert extent.settle_block_sides(_one_side_moved(P, Q, s, 0.5), Q, desk) is not None


@pytest.mark.parametrize("share", [0.0, -0.3, 2.0])
def test_a_side_off_its_block_stays(tall_book_aside, share):
    # where both images agree (no gap on the cover plane), or the right image's side lies
    # inside the cover or twice the block's width out: there the tilted pair triangulates
    # the side high enough for its block to show in both images, or low enough for it to
    # show in neither, and the side is no candidate (the band of the next test is not
    # reached); nothing moves
    _, _, P, Q, desk, s = tall_book_aside
    assert extent.settle_block_sides(_one_side_moved(P, Q, s, share), Q, desk) is None


@pytest.mark.parametrize("band, moves", [((0.3, 1.3), True), ((1.1, 1.3), False),
                                         ((0.0, 0.9), False)])
def test_the_side_must_lie_on_the_block(tall_book_aside, band, moves):
    # the right image's side on the block's foot: moved only where the band of the block's
    # width outside the cover's edge holds it
    _, _, P, Q, desk, s = tall_book_aside
    got = extent.settle_block_sides(_one_side_moved(P, Q, s, 1.0), Q, desk,
                                    extent.FacingConfig(block_share=band))
    assert (got is not None) == moves


def test_a_side_whose_block_both_images_see_is_left_to_its_edges(tall_book_aside):
    # the near side (its block below it in both images) on its foot in the right image:
    # which edge is the cover's is settle_facing_sides' question, asked of the image
    _, _, P, Q, desk, _ = tall_book_aside
    drop = extent._drop(P, desk)
    near = next(k for k in range(4) if all(extent._block_shows(P, k, Q, drop, cams=(cam,))
                                           for cam in ("left", "right")))
    assert extent.settle_block_sides(_one_side_moved(P, Q, near, 1.0), Q, desk) is None


@pytest.fixture(scope="module")
def scene_49_detected(tall_book_aside):
    """``detect`` of build/t2's scene 49 with the defaults."""
    sc, r = tall_book_aside[:2]
    return Detector(sc.rig).detect(r.left, r.right)


@pytest.mark.parametrize("block_sides", [True, False])
def test_detect_finds_the_tall_book_at_its_height(tall_book_aside, scene_49_detected,
                                                  block_sides):
    # the scene's segmentation gives book 6 with its right-hand side on the block's foot
    # in the right image: fitted flat, the book came out 1.9 cm low
    sc, r, P, _, _, _ = tall_book_aside
    if block_sides:
        res = scene_49_detected
    else:
        cfg = DetectConfig()
        cfg = replace(cfg, facing=replace(cfg.facing, block_sides=False))
        res = Detector(sc.rig, cfg).detect(r.left, r.right)
    truth = r.truth["books"][6]
    book, off = nearest_book(res, truth["center"], on_desk=True)
    assert off < 0.03  # m
    height_error = abs(book.pose.size[2] - truth["size"][2])
    if block_sides:
        assert height_error < 0.003  # m
        assert np.linalg.norm(book.corners_world - P, axis=1).max() < 0.006  # m
    else:
        assert height_error > 0.01


# -- complete_open's height sweep, where no side gives a height

def _swept(monkeypatch, score, **kw):
    """complete_open of a candidate whose seen sides no image shares (no stereo height:
    the sweep), with ``_place`` scoring each height ``score(h)``: the height it returns
    (``kw``: CompleteConfig's settings)."""
    def place(h, *args, **kwargs):
        return np.full((4, 3), h), score(h)

    monkeypatch.setattr(extent, "_place", place)
    corners = {cam: np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0], [0.0, 80.0]])
               for cam in ("left", "right")}
    seen = {"left": np.array([True, False, False, False]),
            "right": np.array([False, True, False, False])}
    fits = {"left": [(corners["left"][0], np.array([1.0, 0.0])), None, None, None],
            "right": [None, (corners["right"][1], np.array([0.0, 1.0])), None, None]}
    got = complete_open(corners, seen, {}, {}, {"left": 10.0, "right": 10.0},
                        np.array([0.0, 0.0, 1.0, 0.0]), CompleteConfig(**kw), fits=fits)
    return None if got is None else float(got[0, 0])


def test_the_sweep_takes_a_clear_best_height(monkeypatch):
    h = _swept(monkeypatch, lambda h: 10.0 - 100.0 * abs(h - 0.03))  # m
    assert h is not None and abs(h - 0.03) < 0.002
    # a broad peak (as good only within 15 mm of the best, sweep_window) still gives it
    h = _swept(monkeypatch, lambda h: 10.0 - 100.0 * max(abs(h - 0.032) - 0.006, 0.0))
    assert h is not None and abs(h - 0.032) <= 0.0061


@pytest.mark.parametrize("score", [
    lambda h: 10.0 + 0.01 * h,  # flat: steps at every height
    lambda h: max(10.0 - 100.0 * abs(h - 0.016), 9.9 - 100.0 * abs(h - 0.064)),  # two
], ids=["flat", "two peaks"])
def test_a_flat_sweep_gives_no_height(monkeypatch, score):
    assert _swept(monkeypatch, score) is None
    # (with no margin the best is taken)
    assert _swept(monkeypatch, score, sweep_margin=0.0) is not None


def test_a_plain_book_beside_others_is_not_guessed_high(tall_book_aside, scene_49_detected):
    # build/t2 scene 49's book 5 (light, 13 mm, against a dark book): its candidate's seen
    # sides give no height, and the sweep scored every height from the desk to 56 mm
    # within 4 %; it came out 46 mm high (33 mm off). Now it is found otherwise, at its
    # height.
    sc, r = tall_book_aside[:2]
    truth = r.truth["books"][5]
    book, off = nearest_book(scene_49_detected, truth["center"], on_desk=True)
    assert off < 0.03  # m
    assert abs(book.pose.size[2] - truth["size"][2]) < 0.005  # m
    cfg = DetectConfig()
    cfg = replace(cfg, complete=replace(cfg.complete, sweep_margin=0.0))
    book, off = nearest_book(Detector(sc.rig, cfg).detect(r.left, r.right), truth["center"],
                             on_desk=True)
    assert off < 0.03 and book.pose.size[2] - truth["size"][2] > 0.02  # m


# -- a side on its page block's foot in both images, lifted (extent.lift_foot)

def _side_on_its_foot(P, Q, s):
    """The projection by ``Q`` of cover ``P`` (4, 3) with side ``s`` taken at its page
    block's foot (dropped onto the desk, z = 0), the sides beside it followed there."""
    from rovis.segment.lines import intersect

    q = geometry.project(Q, P)
    a, b = s, (s + 1) % 4
    foot = geometry.project(Q, P[[a, b]] * [1.0, 1.0, 0.0])
    d_foot = (foot[1] - foot[0]) / np.linalg.norm(foot[1] - foot[0])
    out = q.copy()
    for k, other in ((a, (a - 1) % 4), (b, (b + 1) % 4)):
        lateral = (q[k] - q[other]) / np.linalg.norm(q[k] - q[other])
        out[k] = intersect(foot[0], d_foot, q[other], lateral)
    return out


@pytest.fixture(scope="module")
def book_3cm():
    """A plain book 3 cm thick alone on the desk: its corners (4, 3), the projections,
    gradients, desk plane, its unit normal, a short side whose page block shows, the rig."""
    book = Book(center=(0.60, 0.33, 0.03), yaw_deg=20.0, size=(0.22, 0.15, 0.03),
                cover=CoverSpec(kind="plain", albedo=0.5, seed=1))
    r, grads, Q, rig = _rendered([book])
    P = np.array(r.truth["books"][0]["corners"])
    desk = np.asarray(r.truth["desk_plane"])
    up = desk[:3] / np.linalg.norm(desk[:3])
    s = next(k for k in (0, 2) if extent._block_shows(P, k, Q, -0.03 * up))  # a short side
    return P, Q, grads, desk, up, s, rig


def test_a_side_on_its_foot_in_both_images_is_lifted_to_the_cover(book_3cm):
    """A book 3 cm thick whose short side, its page block showing, both images took at the
    block's foot: its corners there triangulate near the desk (a tilted cover); lifted,
    the cover is back within millimetres."""
    P, Q, grads, desk, up, s, _ = book_3cm
    corners = {cam: _side_on_its_foot(P, Q[cam], s) for cam in Q}
    before = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    h = geometry.plane_distance(desk, before)
    assert h[[s, (s + 1) % 4]].max() < 0.01 and h.max() > 0.025  # tilted, metres
    got = extent.lift_foot(corners, Q, grads, before, desk)
    assert got is not None
    assert np.linalg.norm(got - P, axis=1).max() < 0.003  # metres, every corner
    # a cover triangulated whole has no side on the desk: nothing to lift
    whole = {cam: geometry.project(Q[cam], P) for cam in Q}
    assert extent.lift_foot(whole, Q, grads, P, desk) is None
    # nor does a side whose page block no image shows (its foot is hidden)
    hidden = next(k for k in (0, 2) if k != s)
    assert not extent._block_shows(P, hidden, Q, -0.03 * up)
    corners = {cam: _side_on_its_foot(P, Q[cam], hidden) for cam in Q}
    before = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    assert extent.lift_foot(corners, Q, grads, before, desk) is None


def test_the_detector_lifts_a_pair_only_where_no_book_is_in_either_image(book_3cm):
    P, Q, grads, desk, _, s, rig = book_3cm
    tilted = Pair(_side_on_its_foot(P, Q["left"], s), _side_on_its_foot(P, Q["right"], s),
                  1.0, 0.0)
    det = Detector(rig)
    books = [(tilted, None, "tilted")]
    lifted = det._lifted(rig, grads, books, [], desk, None)
    assert len(lifted) == 1
    assert np.linalg.norm(lifted[0][1].corners_world - P, axis=1).max() < 0.005  # m
    # a book found over it in the right image only (its left quad elsewhere): not again
    elsewhere = tilted.left + [300.0, 0.0]
    found = [(Pair(elsewhere, geometry.project(Q["right"], P), 1.0, 0.0), lifted[0][1])]
    assert det._lifted(rig, grads, books, found, desk, None) == []


def test_a_sheet_on_the_desk_is_not_lifted_into_a_book():
    """A paper on the desk paired with its far side a centimetre too high (the corners
    triangulate tilted): its far edge, placed by stereo, lies on the desk, so no cover is
    made of it."""
    from rovis.synth.scene import Paper

    sc = sample_scene(3, lux=500.0, n_books=0)
    paper = Paper(center=(0.45, 0.33), yaw_deg=20.0, size=(0.21, 0.15), seed=2)
    sc = replace(sc, books=(), papers=(paper,), mugs=(), pens=(), cables=())
    r = render(sc, 3)
    grads = {cam: gradients(img) for cam, img in ideal_images(sc.rig, r).items()}
    Q = {"left": sc.rig.Q_L, "right": sc.rig.Q_R}
    desk = np.asarray(r.truth["desk_plane"])
    flat = np.column_stack([paper.footprint(), np.zeros(4)])
    _, s = _with_near_side_on_its_foot(flat + [0, 0, 0.01], Q["left"])  # the near side
    tilted = flat.copy()
    tilted[[(s + 2) % 4, (s + 3) % 4], 2] = 0.012  # the far side read 12 mm up
    corners = {cam: geometry.project(Q[cam], tilted) for cam in Q}
    assert extent.lift_foot(corners, Q, grads, tilted, desk) is None
    # the check that refuses it: without the gradients the lift would place a book
    blank = {cam: gradients(np.zeros_like(img)) for cam, img in ideal_images(sc.rig, r).items()}
    assert extent.lift_foot(corners, Q, blank, tilted, desk) is not None


# -- a facing side on its page block's foot in both images, the cover flat at its height
# (extent.foot_side)

@pytest.fixture(scope="module")
def light_tall_book():
    """A light plain book 5.5 cm thick alone on the desk (its cover's edge above the white
    page block is faint): its corners (4, 3), the projections, gradients, desk plane, and
    the cover laid at its height with its facing side where its page block's foot is in
    the left image (the foot, back-projected onto the cover's plane), that side."""
    book = Book(center=(0.60, 0.33, 0.055), yaw_deg=90.0, size=(0.16, 0.13, 0.055),
                cover=CoverSpec(kind="plain", albedo=0.8, seed=2))
    r, grads, Q, _ = _rendered([book])
    P = np.array(r.truth["books"][0]["corners"])
    desk = np.asarray(r.truth["desk_plane"])
    up = desk[:3] / np.linalg.norm(desk[:3])
    s = next(k for k in range(4)
             if extent._facing(P, k, Q) and extent._block_shows(P, k, Q, -0.055 * up))
    ends = [s, (s + 1) % 4]
    on_foot = P.copy()
    on_foot[ends] = on_plane(Q["left"], geometry.project(Q["left"], P[ends] * [1.0, 1.0, 0.0]),
                             desk, 0.055)
    return P, Q, grads, desk, up, s, on_foot


def test_a_side_on_its_foot_in_both_images_moves_to_the_cover_edge(light_tall_book):
    P, Q, grads, desk, _, s, on_foot = light_tall_book
    ends = [s, (s + 1) % 4]
    out = np.linalg.norm((on_foot - P)[ends], axis=1)
    assert out.min() > 0.045  # m: the cover 4.5-5 cm too long
    # both images see the side on the foot (the right image's line within a pixel of it)
    foot_right = geometry.project(Q["right"], P[ends] * [1.0, 1.0, 0.0])
    side_right = geometry.project(Q["right"], on_foot[ends])
    d = (side_right[1] - side_right[0]) / np.linalg.norm(side_right[1] - side_right[0])
    assert np.abs((foot_right - side_right[0]) @ [-d[1], d[0]]).max() < 1.0  # px
    move = extent.foot_side(on_foot, s, Q, grads, desk)
    assert move > 0
    got = extent._moved(on_foot, s, np.array([-move]))[0]
    assert np.linalg.norm((got - P)[ends], axis=1).max() < 0.008  # m, the side's corners
    # the true cover: no side moves
    assert all(extent.foot_side(P, k, Q, grads, desk) == 0.0 for k in range(4))


@pytest.mark.parametrize("change", ["foot_px", "foot_level", "foot_agree", "foot_cover"])
def test_a_side_moves_off_its_foot_only_where_every_test_holds(light_tall_book, change):
    _, Q, grads, desk, _, s, on_foot = light_tall_book
    assert extent.foot_side(on_foot, s, Q, grads, desk) > 0
    cfg = extent.FacingConfig()
    if change == "foot_px":  # a block narrower in the images than this
        cfg = replace(cfg, foot_px=100.0)
    elif change == "foot_level":  # the side's edge must lie lower than the desk
        cfg = replace(cfg, foot_level=-0.5)
    elif change == "foot_agree":  # a side that does not face, exactly at the height
        cfg = replace(cfg, foot_agree=0.0)  # (the cover too high: the test below)
    else:  # the edge at the moved side (the cover's, placed by stereo) must lie this high
        cfg = replace(cfg, foot_cover=2.0)
    assert extent.foot_side(on_foot, s, Q, grads, desk, cfg) == 0.0


def test_a_cover_placed_too_high_lifts_no_foot(light_tall_book):
    # 3 cm too high, its foot would be lifted too far: the sides that do not face the
    # camera say the cover is not there (the other checks let it through)
    _, Q, grads, desk, up, s, on_foot = light_tall_book
    high = on_foot + 0.03 * up
    loose = extent.FacingConfig(foot_level=1.0, foot_cover=-1.0)
    assert extent.foot_side(high, s, Q, grads, desk, loose) == 0.0
    assert extent.foot_side(high, s, Q, grads, desk, replace(loose, foot_agree=1.0)) > 0


def test_a_move_as_deep_as_half_the_cover_is_no_foot(light_tall_book):
    # the same side on a cover cut to 9 cm along the sides beside it: the 4.8 cm move
    # would leave less than half of it
    P, Q, grads, desk, _, s, on_foot = light_tall_book
    move = extent.foot_side(on_foot, s, Q, grads, desk)
    beside = np.linalg.norm(on_foot[(s + 1) % 4] - on_foot[(s + 2) % 4])
    short = extent._moved(on_foot, (s + 2) % 4, np.array([1.9 * move - beside]))[0]
    assert np.linalg.norm(short[(s + 1) % 4] - short[(s + 2) % 4]) < 2 * move
    assert extent.foot_side(short, s, Q, grads, desk) == 0.0
    # cut to 11 cm, more than twice the move: it moves
    longer = extent._moved(on_foot, (s + 2) % 4, np.array([2.3 * move - beside]))[0]
    assert extent.foot_side(longer, s, Q, grads, desk) > 0


def test_the_sides_give_the_height_of_a_cover_laid_low(light_tall_book):
    P, Q, grads, desk, up, s, on_foot = light_tall_book
    assert abs(extent.height_off_feet(P, Q, grads, desk) - 0.055) < 0.003  # m
    # the cover laid 2 cm low (each image's quad on that plane, their mean, as the
    # pipeline lays it): its sides, fitted where it projects, still say 5.5 cm
    low = 0.5 * sum(on_plane(Q[cam], geometry.project(Q[cam], P), desk, 0.035)
                    for cam in ("left", "right"))
    assert abs(extent.height_off_feet(low, Q, grads, desk) - 0.055) < 0.003  # m
    # a side on the foot is not asked: fitted there, stereo puts it on the desk
    assert abs(extent.height_off_feet(on_foot, Q, grads, desk) - 0.055) < 0.003  # m
    ends = on_foot[[s, (s + 1) % 4]]
    fits = {cam: extent.refine_segment(grads[cam], *geometry.project(Q[cam], ends),
                                       half_width=2.0) for cam in ("left", "right")}
    z, _ = extent._line_height(fits, ends[0], ends[1], Q, up)
    assert 0.055 + z < 0.015  # m
    # no two sides agree to within nothing: no height
    exact = extent.FacingConfig(relay_agree=0.0)
    assert extent.height_off_feet(low, Q, grads, desk, exact) is None
    # NaN corners, or a cover on the desk: no height either
    assert extent.height_off_feet(np.full((4, 3), np.nan), Q, grads, desk) is None
    assert extent.height_off_feet(P - 0.055 * up, Q, grads, desk) is None


def _nearest_found(scene, book, *runs):
    """Scene ``scene`` of rovis synth --protocol table1 --seed 1 detected once per list of
    settings in ``runs``: per run, book ``book``'s true centre and the book found nearest."""
    sc, r = dataset_scene("table1", 1, scene)
    true = np.array(r.truth["books"][book]["center"])
    out = []
    for settings in runs:
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        assert res.objects, settings
        out.append((true, min(res.objects,
                              key=lambda o: np.linalg.norm(o.pose.center - true))))
    return out


@pytest.fixture(scope="module")
def scene_54_detected():
    """Scene 54 of rovis synth --protocol table1 --seed 1 detected with the defaults and
    with ``facing.feet=false``: per run, book 2's true centre and the book found nearest."""
    return _nearest_found(54, 2, [], ["facing.feet=false"])


def test_detect_takes_the_cover_not_its_page_block(scene_54_detected):
    """build/rt1's scene 54 (rovis synth --protocol table1 --n 100 --seed 1): book 2, a
    light cover 5.9 cm thick, both images' near side on its page block's foot: found
    17.8 mm off, its long axis turned 90°, before extent.foot_side."""
    (true, got), (_, off) = scene_54_detected
    assert np.linalg.norm(got.pose.center - true) < 0.003  # m
    assert np.linalg.norm(off.pose.center - true) > 0.01


@pytest.mark.parametrize("protocol, seed, scene, book", [("table2", 1, 104, 1),
                                                       ("table1", 4, 49, 2)])
def test_a_cover_its_foot_pulled_low_is_laid_where_its_sides_are(protocol, seed, scene, book):
    """A side on its page block's foot put the corners at the wrong height, no side where
    foot_side looks for one; its other sides say where the cover is, and the foot is
    lifted there.

    - build/rt2's scene 104 (rovis synth --protocol table2 --n 128 --seed 1), book 1
      (159 x 91 x 50 mm): corners 29 mm low, found 30.7 mm off.
    - build/t1d's scene 49 (--protocol table1 --n 100 --seed 4), book 2 (162 x 94 x 40
      mm): found 12.0 mm off, 9 mm low. Its second side facing the camera shows its page
      block 2.3 px wide, under ``facing.foot_px``: no foot, and asked, it reads the
      cover's height."""
    sc, r = dataset_scene(protocol, seed, scene)
    true = np.array(r.truth["books"][book]["center"])
    got = []
    for settings in ([], ["facing.relay=false"]):
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        got.append(nearest_book(res, true)[1])
    assert got[0] < 0.006  # m
    assert got[1] > 0.01  # m


@pytest.fixture(scope="module")
def scene_79_detected():
    """Scene 79 of rovis synth --protocol table1 --seed 1 detected with the defaults and
    with ``extent.height_band=1`` (any edge nearer the cover's height than the desk holds a
    side, as before stop 60), both without the bound on the dense map's snap (stop 62,
    ``heightmap.dense_snap_tol``: the sweeps read the strips beyond two sides of its dense
    rectangle 0-16 mm high, and those sides' snaps stop there; the defaults then put book
    6 11.8 mm off, 8.9 mm on its worst axis): per run, book 6's true centre and the book
    found nearest."""
    unbound = "heightmap.dense_snap_tol=1"
    return _nearest_found(79, 6, [unbound], [unbound, "extent.height_band=1"])


def test_a_taller_neighbours_edge_holds_no_side(scene_79_detected):
    """build/rt1's scene 79: book 6 (159 x 103 x 18 mm), found by the dense map reaching
    53 mm past its end, up to a 49 mm book's edge. The extent step finds the gap in its
    sides' edges and the cover's end; stereo reads the edge the side lies on 31 mm above
    the cover, beyond a side facing away from the cameras. As an edge nearer the cover's
    height than the desk, it used to hold the side (25.8 mm off, the long axis turned 90
    degrees). Both runs leave the dense map's snap unbounded (see the fixture)."""
    (true, got), (_, held) = scene_79_detected
    assert np.linalg.norm(got.pose.center - true) < 0.01  # m
    assert np.linalg.norm(held.pose.center - true) > 0.02
    L, W = sorted(got.pose.size[:2])[::-1]
    assert abs(L - 0.159) < 0.015 and abs(W - 0.103) < 0.01


# -- the cover's height from its sides' edges (extent.height_from_sides)


def _shifted_right(P, Q, dx_px):
    """Both images' corners of cover ``P``, the right image's moved ``dx_px`` along its
    rows: a disparity error that puts the corners' plane about a centimetre off."""
    left, right = geometry.project(Q["left"], P), geometry.project(Q["right"], P)
    return left, right + np.array([dx_px, 0.0])


def _corner_height(Q, left, right, desk):
    return float(geometry.plane_distance(
        desk, geometry.triangulate(Q["left"], Q["right"], left, right)).mean())


@pytest.fixture(scope="module")
def turned_book():
    """The lone book turned to 45°: its two sides that do not face the cameras both cross
    the epipolar lines (at 20° one runs nearly along them and tells no height)."""
    r, grads, Q, rig = _rendered([replace(LONE_BOOK, yaw_deg=45.0)])
    return np.array(r.truth["books"][0]["corners"]), Q, grads, np.asarray(r.truth["desk_plane"]), rig


@pytest.mark.parametrize("dx_px", [0.0, 1.0, -1.0])
def test_the_sides_give_the_height_the_corners_miss(turned_book, dx_px):
    P, Q, grads, desk, _ = turned_book
    left, right = _shifted_right(P, Q, dx_px)
    at_corners = _corner_height(Q, left, right, desk)
    if dx_px:
        assert abs(at_corners - THICKNESS) > 0.006  # the error the step is for
    h = extent.height_from_sides(geometry.triangulate(Q["left"], Q["right"], left, right),
                                 Q, grads, desk)
    assert h is not None
    assert abs(h - THICKNESS) < 0.002


def test_one_side_alone_gives_no_height(lone_book):
    P, Q, grads, desk, _ = lone_book  # at 20°, one side that does not face the cameras
    alone = extent.SideHeightConfig(any_sides=0)  # (three sides, facing or not: below)
    assert extent.height_from_sides(P, Q, grads, desk, alone) is None


def test_sides_that_disagree_give_no_height(turned_book):
    P, Q, grads, desk, _ = turned_book
    strict = extent.SideHeightConfig(agree=0.0, any_sides=0)  # no two fits agree exactly
    assert extent.height_from_sides(P, Q, grads, desk, strict) is None


@pytest.mark.parametrize("dx_px", [1.0, -1.0])
def test_three_sides_facing_or_not_give_the_height_where_the_two_facing_away_do_not(
        turned_book, dx_px):
    """The turned book's corners a pixel of disparity off (about 13 mm), its two sides
    facing away from the cameras refused (``max_sigma`` 0): its four sides, the two
    facing the cameras 2 mm low on their page block's boards, agree on its height."""
    P, Q, grads, desk, _ = turned_book
    left, right = _shifted_right(P, Q, dx_px)
    assert abs(_corner_height(Q, left, right, desk) - THICKNESS) > 0.01
    corners = geometry.triangulate(Q["left"], Q["right"], left, right)
    away_refused = extent.SideHeightConfig(max_sigma=0.0)
    h = extent.height_from_sides(corners, Q, grads, desk, away_refused)
    assert h is not None and abs(h - THICKNESS) < 0.0025
    # not asked: no height
    assert extent.height_from_sides(corners, Q, grads, desk,
                                    replace(away_refused, any_sides=0)) is None
    # a move under any_move (1 cm) is no height of theirs either
    assert extent.height_from_sides(corners, Q, grads, desk,
                                    replace(away_refused, any_move=0.02)) is None


def test_three_sides_give_no_height_near_the_corners(turned_book):
    P, Q, grads, desk, _ = turned_book  # the corners at the book's height
    cfg = extent.SideHeightConfig(max_sigma=0.0)
    assert extent.height_from_sides(P, Q, grads, desk, cfg) is None
    # ...where they agree on it: any_move alone refuses them
    h = extent.height_from_sides(P, Q, grads, desk, replace(cfg, any_move=0.0))
    assert h is not None and abs(h - THICKNESS) < 0.0025


def test_bad_side_height_settings_are_refused():
    for bad in ({"any_sides": 5}, {"any_sides": -1}, {"any_move": -0.01}, {"max_sigma": -1.0}):
        with pytest.raises(ValueError, match="side_height: bad"):
            extent.SideHeightConfig(**bad)


@pytest.mark.parametrize("scene, book", [(69, 0), (55, 4)])
def test_detect_lays_a_cover_at_the_height_three_sides_give(scene, book):
    """build/rt1 (rovis synth --protocol table1 --n 100 --seed 1): scene 69's book 0 (288
    x 121 x 21 mm, dark) came out 34 mm high at its corners, scene 55's book 4 (124 x 91 x
    19 mm, printed) 29 mm: more than 1 cm off, while three of each one's sides put it at
    its height."""
    sc, r = dataset_scene("table1", 1, scene)
    truth = r.truth["books"][book]
    true = np.array(truth["center"])
    for settings in ([], ["side_height.any_sides=0"]):
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        got = nearest_book(res, true)[0]
        off = np.abs(got.pose.center - true).max()
        if settings:
            assert off > 0.01  # m: beyond the grasp tolerance
        else:
            assert off < 0.003  # m
            assert got.pose.size[2] == pytest.approx(truth["size"][2], abs=0.0025)


def test_an_edge_well_below_the_cover_holds_no_side(turned_book):
    """The lone 20 mm book's cover laid 12 mm high: stereo reads three of its sides' edges
    at the book's top, 12-15 mm below that cover. They hold no side pulled in
    (``extent.height_band``, 8 mm), where before stop 60 any edge nearer the cover's
    height than the desk did (``height_band`` 1 m); at the true height every side holds."""
    P, Q, grads, desk = turned_book[:4]
    up = desk[:3] / np.linalg.norm(desk[:3])
    high = P + 0.012 * up
    drop = extent._drop(high, desk)
    for s in (0, 1, 2):
        level = extent._edge_level(high, s, Q, grads, up, drop, ExtentConfig())
        assert level is not None and abs(level - THICKNESS) < 0.003
        assert not extent._holds_side(high, s, Q, grads, up, drop, ExtentConfig())
        assert extent._holds_side(high, s, Q, grads, up, drop, ExtentConfig(height_band=1.0))
    assert all(extent._holds_side(P, s, Q, grads, up, extent._drop(P, desk), ExtentConfig())
               for s in range(4))


def test_an_edge_well_above_holds_only_a_side_facing_the_cameras(turned_book):
    """The same cover laid 12 mm low: its sides' edges read 10-12 mm above it. Beyond a side
    facing the cameras a taller neighbour would hide the cover's end, and the edge holds
    the side; beyond one facing away, the neighbour's face would show above the cover's
    end, and it does not."""
    P, Q, grads, desk = turned_book[:4]
    up = desk[:3] / np.linalg.norm(desk[:3])
    low = P - 0.012 * up
    drop = extent._drop(low, desk)
    away, facing = 0, 2
    assert not extent._block_shows(low, away, Q, drop) and extent._block_shows(low, facing, Q, drop)
    for s in (away, facing):
        level = extent._edge_level(low, s, Q, grads, up, drop, ExtentConfig())
        assert level is not None and abs(level - THICKNESS) < 0.003
        assert extent._holds_side(low, s, Q, grads, up, drop, ExtentConfig(height_band=1.0))
    assert not extent._holds_side(low, away, Q, grads, up, drop, ExtentConfig())
    assert extent._holds_side(low, facing, Q, grads, up, drop, ExtentConfig())


@pytest.mark.parametrize("enabled", [True, False])
def test_detect_moves_a_cover_to_its_sides_height(turned_book, enabled):
    P, Q, grads, desk, rig = turned_book
    left, right = _shifted_right(P, Q, 1.0)
    cfg = DetectConfig(side_height=extent.SideHeightConfig(enabled=enabled))
    det = Detector(rig, cfg)
    pair, book, why = det._reconstruct_or_why(rig, Pair(left, right, 1.0, 0.0), desk)
    assert book is not None, why
    [(_, moved)] = det._with_side_heights(rig, grads, [(pair, book)], desk, None) \
        if enabled else [(pair, book)]
    if enabled:
        assert abs(moved.pose.size[2] - THICKNESS) < 0.002
        # laid on that plane from both images: the centre moves less than 2 mm across
        assert np.linalg.norm(moved.pose.center[:2] - P[:, :2].mean(axis=0)) < 0.002
    else:
        assert abs(moved.pose.size[2] - THICKNESS) > 0.006


FRAME_MARGIN, FRAME_LINE = 0.008, 0.002  # metres: a printed frame's inset and line width


def _framed_cover(spec, size_m):
    """A light cover with a dark line printed FRAME_MARGIN inside its edges (the line
    FRAME_LINE wide, centred there), in place of rovis.synth.textures.cover."""
    w, h = (max(8, int(round(v * COVER_PX_PER_M))) for v in size_m)
    tex = np.full((h, w), spec.albedo, np.float32)
    m, t = (int(round(v * COVER_PX_PER_M)) for v in (FRAME_MARGIN, FRAME_LINE))
    cv2.rectangle(tex, (m, m), (w - 1 - m, h - 1 - m), 0.08, t)
    return tex


@pytest.fixture(scope="module")
def framed_book():
    """LONE_BOOK with a light cover and a dark frame printed inside its edges: its true
    corners, projections, gradients, ideal images and the desk plane."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(textures, "cover", _framed_cover)
        book = replace(LONE_BOOK, cover=CoverSpec(kind="light", albedo=0.9, seed=1))
        r, grads, Q, rig = _rendered([book])
    return (np.array(r.truth["books"][0]["corners"]), Q, grads, ideal_images(rig, r),
            np.asarray(r.truth["desk_plane"]))


def _inset(P, d):
    """Corners of cover P (4, 3) with every side moved inward by d metres."""
    for s in range(4):
        P = _side_moved(P, s, -d)
    return P


@pytest.mark.parametrize("edge", [-0.5, 0.5])  # the frame line's inner or outer edge
def test_a_cover_found_as_its_printed_frame_grows_to_its_edges(framed_book, edge):
    P, Q, grads, gray, desk = framed_book
    frame = _inset(P, FRAME_MARGIN - edge * FRAME_LINE)
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    corners = {cam: geometry.project(Q[cam], frame) for cam in Q}
    args = (corners, Q, grads, {"left": strength, "right": strength}, desk)
    # without the frame step nothing grows it: beyond the frame's corners its neighbouring
    # sides run over the plain margin, no edge
    assert fit_pair_extent(*args, replace(ExtentConfig(), frame=False), gray=gray) is None
    new = fit_pair_extent(*args, ExtentConfig(), gray=gray)
    assert new is not None
    G = geometry.triangulate(Q["left"], Q["right"], new["left"], new["right"])
    assert np.abs(_sizes(G) - _sizes(P)).max() < 0.003  # metres
    assert np.linalg.norm(G.mean(axis=0)[:2] - P.mean(axis=0)[:2]) < 0.002


def test_a_cover_found_whole_is_no_frame(framed_book):
    # beyond the cover's own edges lie the desk and its page block, not its margin
    P, Q, grads, gray, desk = framed_book
    strength = CANNY_LOW_RATIO * SegmentConfig().open_T_H
    assert extent.grow_frame(P, Q, grads, gray, {"left": strength, "right": strength},
                             desk) is None


def test_the_four_moves_must_agree(framed_book):
    # the frame's four moves to the cover's edges differ by a millimetre or two (the
    # blurred edges' peaks): an agreement tighter than that refuses the grow
    P, Q, grads, gray, desk = framed_book
    frame = _inset(P, FRAME_MARGIN + 0.5 * FRAME_LINE)
    strength = {cam: CANNY_LOW_RATIO * SegmentConfig().open_T_H for cam in Q}
    assert extent.grow_frame(frame, Q, grads, gray, strength, desk) is not None
    tight = replace(ExtentConfig(), frame_agree=0.0002)
    assert extent.grow_frame(frame, Q, grads, gray, strength, desk, tight) is None


def _desk_as_margin(P, Q, gray, sides, *, print_inside=True):
    """Both ideal images with the desk beyond each of cover P's ``sides`` (2 cm of it)
    painted in the tone of the cover's margin there: no step past the margin; with
    ``print_inside``, two dark blocks printed in the cover's middle as well."""
    inside = _inset(P, 0.003)  # in the margin, between the frame's line and the edge
    painted = {cam: img.copy() for cam, img in gray.items()}
    for s in sides:
        out = _side_moved(P, s, 0.02)
        beyond = np.array([P[s], P[(s + 1) % 4], out[(s + 1) % 4], out[s]])
        for cam, img in painted.items():
            at = geometry.project(Q[cam], inside[[s, (s + 1) % 4]]).mean(axis=0)
            tone = int(gray[cam][int(round(at[1])), int(round(at[0]))])
            cv2.fillConvexPoly(img, np.round(geometry.project(Q[cam], beyond)).astype(np.int32),
                               tone)
    if print_inside:
        for a, b in ((0.30, 0.45), (0.55, 0.70)):  # bands across the cover's middle
            block = np.array([P[0] + a * (P[1] - P[0]) + t * (P[3] - P[0]) for t in (0.3, 0.7)]
                             + [P[0] + b * (P[1] - P[0]) + t * (P[3] - P[0]) for t in (0.7, 0.3)])
            for cam, img in painted.items():
                cv2.fillConvexPoly(img, np.round(geometry.project(Q[cam], block)).astype(np.int32),
                                   40)
    return painted


def test_a_frame_whose_border_meets_the_desk_in_its_tone_grows_on_three_sides(framed_book):
    # a side with no step past its margin moves as far as the other three
    P, Q, grads, gray, desk = framed_book
    frame = _inset(P, FRAME_MARGIN + 0.5 * FRAME_LINE)
    strength = {cam: CANNY_LOW_RATIO * SegmentConfig().open_T_H for cam in Q}
    one = _desk_as_margin(P, Q, gray, [0])
    assert extent.grow_frame(frame, Q, grads, one, strength, desk,
                             replace(ExtentConfig(), frame_sides=4)) is None
    G = extent.grow_frame(frame, Q, grads, one, strength, desk)
    assert G is not None
    assert np.abs(_sizes(G) - _sizes(P)).max() < 0.003  # metres
    # two such sides are too many for the default, enough with frame_sides=2
    two = _desk_as_margin(P, Q, gray, [0, 1])
    assert extent.grow_frame(frame, Q, grads, two, strength, desk) is None
    G = extent.grow_frame(frame, Q, grads, two, strength, desk,
                          replace(ExtentConfig(), frame_sides=2))
    assert G is not None and np.abs(_sizes(G) - _sizes(P)).max() < 0.003


def test_a_plain_inside_grows_on_four_sides_only(framed_book):
    # no print inside the frame's line: a plain cover of the desk's tone reads the desk
    # beyond its sides as a margin, so three sides are not enough there
    P, Q, grads, gray, desk = framed_book
    frame = _inset(P, FRAME_MARGIN + 0.5 * FRAME_LINE)
    strength = {cam: CANNY_LOW_RATIO * SegmentConfig().open_T_H for cam in Q}
    plain = _desk_as_margin(P, Q, gray, [0], print_inside=False)
    assert extent.grow_frame(frame, Q, grads, plain, strength, desk) is None
    G = extent.grow_frame(frame, Q, grads, plain, strength, desk,
                          replace(ExtentConfig(), frame_print=0.0))
    assert G is not None and np.abs(_sizes(G) - _sizes(P)).max() < 0.003


@pytest.mark.parametrize("sides", [0, 5])
def test_a_frame_count_out_of_range_grows_nothing_it_cannot_back(framed_book, sides):
    # frame_sides 0 asks no side and 5 more than a cover has: neither may grow a frame with
    # fewer sides found than asked (0: at least one), nor fail
    P, Q, grads, gray, desk = framed_book
    frame = _inset(P, FRAME_MARGIN + 0.5 * FRAME_LINE)
    strength = {cam: CANNY_LOW_RATIO * SegmentConfig().open_T_H for cam in Q}
    cfg = replace(ExtentConfig(), frame_sides=sides)
    four = _desk_as_margin(P, Q, gray, [0, 1, 2, 3])  # no side finds its edge
    assert extent.grow_frame(frame, Q, grads, four, strength, desk, cfg) is None
    G = extent.grow_frame(frame, Q, grads, gray, strength, desk, cfg)
    assert (G is None) == (sides == 5)


def _behind_a_taller_book(gap, kind="plain", width=0.16):
    """A light book 1.5 cm thick (a plain cover, or ``kind``), 22 cm wide, a 4.5 cm one
    ``width`` metres wide in front of it, ``gap`` metres apart (flush at 0), alone on the
    desk at 500 lx: the low book's corners (4, 3), the taller one's, the projections,
    gradients, desk plane, the low book's side facing the taller one (and the cameras),
    how far the taller book's top edge, seen from the left camera on the low cover's
    plane, lies inward of that side (metres; negative: outward, the side in view), and
    both ideal images' print (the sweep's high-pass)."""
    low = Book(center=(0.45, 0.42, 0.015), yaw_deg=0.0, size=(0.22, 0.15, 0.015),
               cover=CoverSpec(kind=kind, albedo=0.6, seed=1))
    near = 0.42 - 0.075  # y of the low book's side towards the cameras
    tall = Book(center=(0.45, near - gap - 0.045, 0.045), yaw_deg=0.0, size=(width, 0.09, 0.045),
                cover=CoverSpec(kind="plain", albedo=0.75, seed=2))
    r, grads, Q, rig = _rendered([low, tall])
    P, PB = (np.array(b["corners"]) for b in r.truth["books"])
    desk = np.asarray(r.truth["desk_plane"])
    s = next(k for k in range(4) if abs(0.5 * (P[k, 1] + P[(k + 1) % 4, 1]) - near) < 1e-6)
    t = next(k for k in range(4) if abs(0.5 * (PB[k, 1] + PB[(k + 1) % 4, 1]) - near + gap) < 1e-6)
    top = on_plane(Q["left"], geometry.project(Q["left"], PB[[t, (t + 1) % 4]]), desk, 0.015)
    texture = {cam: high_pass(img, SweepConfig().sigma_px)
               for cam, img in ideal_images(rig, r).items()}
    return P, PB, Q, grads, desk, s, float(np.mean(top[:, 1]) - near), texture


def test_a_side_a_taller_book_in_front_hides_goes_on_under_it():
    P, PB, Q, grads, desk, s, reach, _ = _behind_a_taller_book(0.0)
    assert extent._facing(P, s, Q)
    assert reach > 0.025  # m: the taller book hides 2.5 cm or more of the low cover
    # the low cover as both images end it, at the taller book's edge
    seen = extent._moved(P, s, np.array([-reach]))[0]
    move = extent.under_taller(seen, s, [PB], Q, grads, desk)
    assert abs(move - reach) < 0.002  # m: back out to the true side, under the taller book's
    # not without a taller book, nor with no angle tolerance
    assert extent.under_taller(seen, s, [], Q, grads, desk) == 0.0
    assert extent.under_taller(seen, s, [PB], Q, grads, desk,
                               extent.FacingConfig(under_deg=0.0)) == 0.0


def test_a_side_on_a_line_of_print_short_of_a_taller_book_goes_on_under_it():
    """Flush, behind a taller book wider than it, a photo cover found 3 cm short of where
    that book hides it, its side on a line of its print (12 px inside in the images): the
    strip between is its print, at its height, so the side goes out under the taller
    book's side, with the print test (``facing.under_print_px``) only."""
    P, PB, Q, grads, desk, s, reach, texture = _behind_a_taller_book(0.0, "photo", 0.26)
    short = extent._moved(P, s, np.array([-(reach + 0.03)]))[0]
    # beyond under_px, within under_print_px of the taller book's side, in both images
    cfg = extent.FacingConfig()
    for cam in Q:
        near, far = _gap_px(short, s, PB, Q[cam], cfg)
        assert cfg.under_px < near <= far < cfg.under_print_px
    move = extent.under_taller(short, s, [PB], Q, grads, desk, texture=texture)
    assert abs(move - (reach + 0.03)) < 0.002  # m: out to the true side
    # not without the print, nor with the reach of the old test (under_px) only
    assert extent.under_taller(short, s, [PB], Q, grads, desk) == 0.0
    no_print = extent.FacingConfig(under_print_px=0.0)
    assert extent.under_taller(short, s, [PB], Q, grads, desk, no_print, texture=texture) == 0.0


def _gap_px(P, s, PB, Q, cfg):
    """Pixels from side s of P to the taller book PB's side it lies along (nearest,
    furthest) in the image of projection Q, within 50 px (inf: none)."""
    side = geometry.project(Q, P[[s, (s + 1) % 4]])
    gaps = [extent._on_side(side, geometry.project(Q, PB[[t, (t + 1) % 4]]), cfg, 50.0)
            for t in range(4)]
    return min(gaps)


def test_a_plain_side_short_of_a_taller_book_stays():
    """The same, the cover plain: the strip between shows no print that matches better at
    the cover's height than on the desk, so nothing tells it from the desk seen between
    two books, and the side stays."""
    P, PB, Q, grads, desk, s, reach, texture = _behind_a_taller_book(0.0, "plain", 0.26)
    short = extent._moved(P, s, np.array([-(reach + 0.03)]))[0]
    assert extent.under_taller(short, s, [PB], Q, grads, desk, texture=texture) == 0.0


def test_a_photo_covers_own_edge_short_of_a_taller_book_apart_stays():
    """6 cm apart, the photo cover's own edge in view 13 px short of the taller book's
    side in both images, its page block and the desk between: the strip matches no better
    at the cover's height than on the desk, so the side stays, whatever the other
    refusals say; taken as on that side (``under_px`` 30 px), it would go 6 cm out."""
    P, PB, Q, grads, desk, s, reach, texture = _behind_a_taller_book(0.06, "photo", 0.26)
    assert reach < -0.02  # m: the cover's edge in view
    cfg = extent.FacingConfig(under_inner=np.inf, under_free=np.inf)
    for cam in Q:
        near, far = _gap_px(P, s, PB, Q[cam], cfg)
        assert cfg.under_px < near <= far < cfg.under_print_px
    assert extent.under_taller(P, s, [PB], Q, grads, desk, cfg, texture=texture) == 0.0
    wide = replace(cfg, under_px=30.0)
    assert extent.under_taller(P, s, [PB], Q, grads, desk, wide) > 0.05  # m


def test_a_side_on_a_taller_books_edge_beyond_its_page_block_stays():
    """4 cm apart, the low cover's edge shows, its page block below it hidden in part: a
    side taken on the taller book's edge beyond the block is not moved further out (an
    edge of the other polarity lies inside it: the cover's own)."""
    P, PB, Q, grads, desk, s, reach, texture = _behind_a_taller_book(0.04)
    assert reach < -0.005  # m: the taller book's edge lies beyond the low cover's
    on_edge = extent._moved(P, s, np.array([-reach]))[0]
    assert extent.under_taller(on_edge, s, [PB], Q, grads, desk) == 0.0
    assert extent.under_taller(on_edge, s, [PB], Q, grads, desk, texture=texture) == 0.0
    assert extent.under_taller(on_edge, s, [PB], Q, grads, desk,
                               extent.FacingConfig(under_inner=np.inf)) > 0.02  # m


def test_a_side_in_view_on_a_taller_books_edge_stays():
    """3 cm apart, the taller book's edge lies on the low cover's own edge in both images
    (within 0.5 mm on the cover's plane): that edge goes on beyond the taller book, which is
    narrower, so the side is not moved, even with the inside test off."""
    P, PB, Q, grads, desk, s, reach, texture = _behind_a_taller_book(0.03)
    assert abs(reach) < 0.0005  # m
    on_edge = extent._moved(P, s, np.array([-reach]))[0]
    no_inside = extent.FacingConfig(under_inner=np.inf)
    assert extent.under_taller(on_edge, s, [PB], Q, grads, desk, no_inside) == 0.0
    assert extent.under_taller(on_edge, s, [PB], Q, grads, desk, no_inside,
                               texture=texture) == 0.0
    # without that test too, it goes out under the taller book's side, the gap taken in
    neither = extent.FacingConfig(under_inner=np.inf, under_free=np.inf)
    assert abs(extent.under_taller(on_edge, s, [PB], Q, grads, desk, neither) - 0.03) < 0.002


@pytest.mark.parametrize("seed, scene, book", [(3, 20, 0), (1, 87, 4)])
def test_detect_takes_a_cover_on_under_a_taller_book_in_front(seed, scene, book):
    """build/t1c's scene 20 (rovis synth --protocol table1 --n 40 --seed 3), book 0 (283 x
    238 x 8 mm, 97 % visible), and build/rt1's scene 87 (--n 100 --seed 1), book 4 (247 x
    94 x 20 mm, 87 % visible): a taller book in front hides the cover's near side, and
    the found cover ended at its edge, 26 and 14 mm short. (Scene 87's book is found 5 mm
    off along its length either way.)"""
    sc, r = dataset_scene("table1", seed, scene)
    truth = r.truth["books"][book]
    true = np.array(truth["center"])
    short = []
    for settings in ([], ["facing.under=false"]):
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        got = nearest_book(res, true)[0]
        assert np.linalg.norm(got.pose.center[:2] - true[:2]) < (0.007 if not settings else 0.02)
        short.append(min(truth["size"][:2]) - min(got.pose.size[:2]))
    assert abs(short[0]) < 0.004  # m
    assert short[1] > 0.01  # m


@pytest.mark.parametrize("scene", [108, 118])
def test_detect_takes_a_photo_cover_on_from_a_line_of_its_print_under_a_taller_book(scene):
    """The Table II renders' scenes 108 and 118 (rovis synth --protocol table2 --n 128
    --seed 1), book 0: a photo cover 130 x 128 x 16 mm, a 5 cm plain book flush in front
    of it that hides a strip of it. The cover was found 26 and 40 mm narrow: its side
    facing that book lay on a line of its print 8-9 and 15-16 px short of the book's edge
    in both images, beyond the reach of the old test (``facing.under_px``). The strip
    between matches at the cover's height: the side goes out under the taller book's
    (``facing.under_print_px``). In scene 118 the print inside the side is an edge of the
    other polarity, which the inside test (``facing.under_inner``) took for the cover's
    own edge: it is not asked of a side with the cover's print beyond it."""
    sc, r = dataset_scene("table2", 1, scene)
    truth = r.truth["books"][0]
    true = np.array(truth["center"])
    got = {}
    for settings in ([], ["facing.under_print_px=0"]):
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        got[bool(settings)] = nearest_book(res, true, on_desk=True)[0]
    assert np.abs(got[False].pose.center[:2] - true[:2]).max() < 0.003  # m
    assert np.abs(np.sort(got[False].pose.size[:2]) - np.sort(truth["size"][:2])).max() < 0.007
    # without it, 26 mm narrow or more and its centre a centimetre off
    assert np.abs(got[True].pose.center[:2] - true[:2]).max() > 0.008
    assert min(truth["size"][:2]) - min(got[True].pose.size[:2]) > 0.02


def test_detect_leaves_a_side_with_its_block_beyond_the_print_short_of_a_taller_book():
    """The held-out mixed renders' scene 19 (rovis synth --protocol mixed --n 40 --seed 9),
    book 0: a printed cover 161 x 159 x 42 mm found 8 mm short, its side on a line of its
    print 16-19 px short of a 57 mm book's side. The strip between matches at the cover's
    height by its inner half (the print, NCC 0.99) and not by its outer (the cover's edge,
    its page block and the desk: 0.27): both halves are asked, and the side stays, its
    centre within 6 mm. Asked as one strip (NCC 0.99 against -0.64 on the desk), it went
    35 mm out, 24 mm too long."""
    sc, r = dataset_scene("mixed", 9, 19)
    truth = r.truth["books"][0]
    true = np.array(truth["center"])
    got = nearest_book(Detector(sc.rig, DetectConfig()).detect(r.left, r.right), true,
                       on_desk=True)[0]
    assert np.abs(got.pose.center[:2] - true[:2]).max() < 0.006  # m
    # no more than 3 mm longer than it is (it went 24 mm too long)
    assert max(got.pose.size[:2]) < max(truth["size"][:2]) + 0.003
