"""Books chosen by stereo among both images' candidate quads (Segmentation.pool,
rovis.stereo.pool_pairs and flat_rectangle, Detector._from_pool)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from rovis import geometry, stereo
from rovis.pipeline import DetectConfig, Detector, Pair, _is_union, _skew_deg, with_settings
from rovis.segment import gradients
from rovis.segment.boundary import Segmentation
from rovis.segment.quads import Quads, order_corners
from rovis.stereo import StereoConfig, _seen_side_heights, flat_rectangle, pool_pairs
from rovis.synth import render, sample_scene
from rovis.synth.scene import Book
from rovis.synth.textures import CoverSpec

from conftest import ideal_images, nearest_book

DESK = np.array([0.0, 0.0, 1.0, 0.0])  # z = 0, normal up


def _rectangle(center=(0.4, 0.3), size=(0.20, 0.14), z=0.03, yaw_deg=20.0, tilt_deg=0.0):
    """World corners (4, 3) of a rectangle at height z, tilted about its x axis."""
    return geometry.corners_from_pose(
        (*center, z), _rotation(yaw_deg, tilt_deg), size)


def _rotation(yaw_deg, tilt_deg):
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("zx", [yaw_deg, tilt_deg], degrees=True).as_matrix()


def test_flat_rectangle_keeps_a_cover_and_names_nothing_else():
    good = _rectangle()
    tilted = _rectangle(tilt_deg=10.0)
    long = _rectangle(size=(0.50, 0.14))
    tiny = _rectangle(size=(0.20, 0.03))
    skew = good.copy()  # a parallelogram: the far side slid 5 cm along, angles 70 and 110 deg
    along = (good[1] - good[0]) / np.linalg.norm(good[1] - good[0])
    skew[2:] += 0.05 * along
    low = _rectangle(z=0.0)
    P = np.stack([good, tilted, long, tiny, skew, low])
    np.testing.assert_array_equal(flat_rectangle(P, DESK, height_range=(0.006, 0.1)),
                                  [True, False, False, False, False, False])
    # without a desk plane only the shape counts: tilted and on the desk are rectangles
    np.testing.assert_array_equal(flat_rectangle(P), [True, True, False, False, False, True])


@pytest.fixture(scope="module")
def book():
    """One plain book, 22 × 15 × 3 cm, alone on a clean desk at 500 lx: its true corners,
    both ideal images' gradients and the rig."""
    sc = sample_scene(5, lux=500.0, n_books=0)
    b = Book(center=(0.42, 0.30, 0.03), yaw_deg=25.0, size=(0.22, 0.15, 0.03),
             cover=CoverSpec(kind="plain", albedo=0.15, seed=2))
    sc = replace(sc, books=(b,), papers=(), mugs=(), pens=(), cables=())
    r = render(sc, 5)
    grads = {cam: gradients(img) for cam, img in ideal_images(sc.rig, r).items()}
    return np.array(r.truth["books"][0]["corners"]), grads, sc.rig


def _pool(quads):
    quads = np.array([order_corners(q) for q in quads])
    n = len(quads)
    return Quads(np.zeros((n, 4), np.intp), quads, np.ones((n, 4)),
                 np.arange(n, 0, -1).astype(np.float64) * 100, np.full(n, 50, np.int64))


def _projected(rig, P):
    """The world corners ``P`` (4, 3) in each ideal image."""
    return {cam: geometry.project(Q, P) for cam, Q in (("left", rig.Q_L), ("right", rig.Q_R))}


def _offered(quads, pool):
    """Per camera, a segmentation whose only candidate is that camera's quad, in ``pool``
    (a :class:`Segmentation` field: "pool", "open_pool", "late_pool", "small_pool")."""
    return {cam: replace(Segmentation.empty(100.0, 30), **{pool: _pool([q])})
            for cam, q in quads.items()}


def test_pool_pairs_pairs_the_same_cover_in_both_images(book):
    P, _, rig = book
    decoy = _rectangle(center=(0.7, 0.5), size=(0.15, 0.10), z=0.02, yaw_deg=-30.0)
    left = [geometry.project(rig.Q_L, P), geometry.project(rig.Q_L, decoy)]
    right = [geometry.project(rig.Q_R, decoy), geometry.project(rig.Q_R, P)]
    pl, pr = _pool(left).corners, _pool(right).corners
    pp = pool_pairs(pl, pr, rig.Q_L, rig.Q_R, desk_plane=DESK)
    assert sorted(zip(pp.left.tolist(), pp.right.tolist())) == [(0, 1), (1, 0)]
    for a, b, c, s in zip(pp.left, pp.right, pp.corners_right, pp.shift):
        # the right corners correspond to the left's, and shift says how they were reordered
        np.testing.assert_allclose(c, np.roll(pr[b], -s, axis=0))
        X = geometry.triangulate_dlt(rig.Q_L, rig.Q_R, pl[a], c)
        assert np.abs(X[:, 2] - X[:, 2].mean()).max() < 1e-6  # one flat cover, not a twisted one
    assert np.all(pp.error_px < 1e-6)


def test_pool_pairs_drops_a_tilted_pair_and_a_pattern_on_the_desk(book):
    P, _, rig = book
    tilted = _rectangle(center=(0.3, 0.2), tilt_deg=35.0, z=0.05)
    on_desk = _rectangle(center=(0.6, 0.45), z=-0.06)  # below the loose height gate
    quads = [P, tilted, on_desk]
    pp = pool_pairs([geometry.project(rig.Q_L, q) for q in quads],
                    [geometry.project(rig.Q_R, q) for q in quads], rig.Q_L, rig.Q_R,
                    desk_plane=DESK)
    assert pp.left.tolist() == [0] and pp.right.tolist() == [0]


def test_pool_pairs_gives_the_same_pairs_in_blocks_of_any_size(book, monkeypatch):
    # many candidates: 27 covers (three places, sizes and heights), each seen twice in each
    # image with 1 px of noise
    _, _, rig = book
    rng = np.random.default_rng(0)
    covers = [_rectangle(center=(x, y), size=size, z=z, yaw_deg=yaw)
              for x, y in ((0.3, 0.2), (0.5, 0.35), (0.7, 0.5))
              for size in ((0.20, 0.14), (0.16, 0.12), (0.24, 0.10))
              for z, yaw in ((0.02, 10.0), (0.04, 25.0), (0.06, -15.0))]
    left, right = ([geometry.project(Q, P) + rng.normal(0, 1.0, (4, 2))
                    for P in covers for _ in range(2)] for Q in (rig.Q_L, rig.Q_R))
    whole = pool_pairs(left, right, rig.Q_L, rig.Q_R, desk_plane=DESK)
    monkeypatch.setattr(stereo, "_POOL_BLOCK", 7)  # a block ends inside a left quad's run
    blocks = pool_pairs(left, right, rig.Q_L, rig.Q_R, desk_plane=DESK)
    assert len(whole) >= 2 * len(covers)  # each cover's two quads in each image, at least
    for field in ("left", "right", "corners_right", "shift", "error_px"):
        np.testing.assert_array_equal(getattr(blocks, field), getattr(whole, field))


def test_point_segment_distance_is_the_distance_to_the_nearest_point_of_the_segment():
    rng = np.random.default_rng(1)
    p, a, b = rng.uniform(-50, 50, (3, 200, 2))
    b[:20] = a[:20]  # a segment of no length: the distance to its point
    t = np.linspace(0, 1, 20001)[:, None, None]
    brute = np.linalg.norm(p - (a + t * (b - a)), axis=-1).min(axis=0)
    d = stereo._point_segment_distance(p, a, b)
    np.testing.assert_allclose(d, brute, atol=0.01)  # pixels (the brute force's 1/20000 step)
    np.testing.assert_allclose(d[:20], np.linalg.norm(p[:20] - a[:20], axis=-1))
    # world points too (rovis.split's outlines, metres), and in the plane z = 0 exactly the
    # floats of image points (the fast path for D = 2 adds as the vector form does)
    p3, a3, b3 = (np.concatenate([v, rng.uniform(-50, 50, (200, 1))], axis=1)
                  for v in (p, a, b))
    brute3 = np.linalg.norm(p3 - (a3 + t * (b3 - a3)), axis=-1).min(axis=0)
    np.testing.assert_allclose(stereo._point_segment_distance(p3, a3, b3), brute3, atol=0.01)
    flat = [np.concatenate([v, np.zeros((200, 1))], axis=1) for v in (p, a, b)]
    np.testing.assert_array_equal(stereo._point_segment_distance(*flat), d)
    # broadcast over leading axes, as pool_pairs asks: (P, 4 shifts, 4 corners)
    many = stereo._point_segment_distance(p[:48].reshape(3, 4, 4, 2), a[None, None, :4],
                                          b[None, None, :4])
    np.testing.assert_allclose(many.reshape(-1, 4),
                               stereo._point_segment_distance(p[:48].reshape(-1, 4, 2),
                                                              a[:4], b[:4]))


def _ends_slid(q, px):
    """Quad ``q`` (4, 2) with corners 1 and 2 slid ``px`` pixels outward along sides 0 and 2:
    an opposite-sided candidate's ends, guessed where each image's edges stopped."""
    q = q.copy()
    for c, other in ((1, 0), (2, 3)):
        q[c] += px * (q[c] - q[other]) / np.linalg.norm(q[c] - q[other])
    return q


def test_pool_pairs_keeps_an_opposite_sided_pair_by_its_seen_sides(book):
    _, _, rig = book
    P = _rectangle(center=(0.42, 0.30), size=(0.22, 0.15), z=0.03, yaw_deg=10.0)
    # each image's ends 8 px off along the seen sides, the other way: 13 and 12 cm of
    # height at those corners (truth 3 cm), no flat rectangle
    left = _ends_slid(order_corners(geometry.project(rig.Q_L, P)), 8.0)
    right = _ends_slid(order_corners(geometry.project(rig.Q_R, P)), -8.0)
    X = geometry.triangulate_dlt(rig.Q_L, rig.Q_R, left, right)
    assert X[1:3, 2].min() > 0.10
    seen = np.array([[True, False, True, False]])  # sides 0 and 2 seen, 1 and 3 not

    def pairs(desk=DESK, cfg=StereoConfig(), seen_left=seen, seen_right=seen, right=right,
              left=left, side_range=(0.05, 0.45)):
        return len(pool_pairs(left[None], right[None], rig.Q_L, rig.Q_R, desk_plane=desk,
                              seen_left=seen_left, seen_right=seen_right, cfg=cfg,
                              side_range=side_range))

    assert pairs(seen_left=None, seen_right=None) == 0  # by its corners: no cover
    assert pairs() == 1  # its seen sides lie at 3 cm
    for r in range(1, 4):  # whatever corner the right quad starts at, its flags with it
        assert pairs(right=np.roll(right, -r, axis=0), seen_right=np.roll(seen, -r, axis=1)) == 1
    # the shape laid at that height must be a book's: not where 22 cm is over 1.5 x 12 cm
    assert pairs(side_range=(0.05, 0.12)) == 0
    # the seen sides measured: 3 cm above the desk (the unseen ones not asked)
    h = _seen_side_heights(left[None], right[None], seen, rig.Q_L, rig.Q_R, DESK,
                           StereoConfig())[0]
    np.testing.assert_allclose(h[[0, 2]], 0.03, atol=0.001)
    assert np.isnan(h[[1, 3]]).all()
    # ...but not where those sides lie 5 mm above the desk (under StereoConfig.min_height),
    assert pairs(desk=np.array([0.0, 0.0, 1.0, -0.025])) == 0
    # nor with the rule off, nor where one image saw every side (no opposite-sided pair)
    assert pairs(cfg=StereoConfig(pool_opposite=False)) == 0
    assert pairs(seen_right=np.ones((1, 4), bool)) == 0
    # nor 20 cm above the desk (over StereoConfig.max_cover_height and its slack)
    high = _rectangle(center=(0.42, 0.30), size=(0.22, 0.15), z=0.20, yaw_deg=10.0)
    assert pairs(left=_ends_slid(order_corners(geometry.project(rig.Q_L, high)), 8.0),
                 right=_ends_slid(order_corners(geometry.project(rig.Q_R, high)), -8.0)) == 0
    # nor where stereo can measure no seen side: turned by -5 deg, sides 0 and 2 run within
    # 10 deg of the epipolar lines
    along = _rectangle(center=(0.42, 0.30), size=(0.22, 0.15), z=0.03, yaw_deg=-5.0)
    left = _ends_slid(order_corners(geometry.project(rig.Q_L, along)), 8.0)
    right = _ends_slid(order_corners(geometry.project(rig.Q_R, along)), -8.0)
    h = _seen_side_heights(left[None], right[None], seen, rig.Q_L, rig.Q_R, DESK,
                           StereoConfig())[0]
    assert np.isnan(h).all()
    assert pairs(left=left, right=right) == 0


def test_a_book_from_the_pools_where_no_selection_kept_it(book):
    P, grads, rig = book
    rng = np.random.default_rng(0)
    # Hough-like corners: about a pixel off; and a decoy on the desk in each image only
    quads = {cam: geometry.project(Q, P) + rng.normal(0, 0.8, (4, 2))
             for cam, Q in (("left", rig.Q_L), ("right", rig.Q_R))}
    segs = {cam: replace(Segmentation.empty(100.0, 30), pool=_pool([q])) for cam, q in quads.items()}
    det = Detector(rig, DetectConfig())
    found = det._from_pool(rig, segs, grads, [], DESK, None)
    assert len(found) == 1
    pair, got = found[0]
    center = P.mean(axis=0)
    assert np.linalg.norm(got.pose.center - center) < 0.005  # metres, from refined corners
    assert abs(got.pose.size[2] - 0.03) < 0.004
    assert pair.source == got.source == "candidates"
    # where a book already stands the pool adds nothing
    assert det._from_pool(rig, segs, grads, found, DESK, None) == []


def test_a_union_of_two_touching_books_gives_way():
    a = np.array([[0, 0], [100, 0], [100, 60], [0, 60]], np.float64)
    b = a + [101, 0]
    union = np.array([[0, 0], [201, 0], [201, 60], [0, 60]], np.float64)
    quads = np.stack([union, a, b])
    area = np.array([cv2.contourArea(q.astype(np.float32)) for q in quads])
    assert _is_union(0, quads, area, 0.3)
    assert not _is_union(1, quads, area, 0.3)
    # one book inside a bigger cover is no union (a printed panel on a cover)
    assert not _is_union(0, quads[:2], area[:2], 0.3)


def test_without_the_desk_plane_the_pools_are_not_asked(book, monkeypatch):
    # nothing then tells a book from a flat rectangle of a pattern (a chessboard's squares)
    from rovis.calib import StereoRig
    P, grads, rig = book
    bare = StereoRig.from_arrays(K1=rig.K1, D1=rig.D1, K2=rig.K2, D2=rig.D2, R=rig.R, T=rig.T,
                                 image_size=rig.image_size)
    asked = []
    monkeypatch.setattr(Detector, "_from_pool", lambda self, *a, **k: asked.append(a) or [])
    img = np.full((rig.image_size[1], rig.image_size[0]), 90, np.uint8)
    Detector(bare, DetectConfig(use_marker=False)).detect(img, img)
    assert asked == []
    Detector(rig, DetectConfig()).detect(img, img)  # registered to the desk: asked
    assert len(asked) == 1
    off = DetectConfig(stereo=replace(DetectConfig().stereo, pool=False))
    Detector(rig, off).detect(img, img)  # switched off: not asked
    assert len(asked) == 1


def test_a_book_from_the_three_sided_candidates(book):
    # the same cover offered only among the candidates with one side unseen
    P, grads, rig = book
    quads = _projected(rig, P)
    segs = _offered(quads, "open_pool")
    found = Detector(rig, DetectConfig())._from_pool(rig, segs, grads, [], DESK, None)
    assert len(found) == 1
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # metres


def test_a_book_from_the_late_candidates_only_when_they_are_asked(book):
    # the same cover offered only among the other T_H's candidates (Segmentation.late_pool)
    P, grads, rig = book
    quads = _projected(rig, P)
    det = Detector(rig, DetectConfig())
    late = _offered(quads, "late_pool")
    assert det._from_pool(rig, late, grads, [], DESK, None) == []  # not before the others
    found = det._from_pool(rig, late, grads, [], DESK, None, extra="late")
    assert len(found) == 1
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # metres
    # one image's quad late, the other's among the candidates: paired too
    mixed = {"left": late["left"],
             "right": replace(Segmentation.empty(100.0, 30), pool=_pool([quads["right"]]))}
    assert len(det._from_pool(rig, mixed, grads, [], DESK, None, extra="late")) == 1
    # a pair of the earlier pools alone is not tried again
    early = _offered(quads, "pool")
    assert det._from_pool(rig, early, grads, [], DESK, None, extra="late") == []


def test_a_book_from_the_small_candidates_in_a_pass_of_their_own(book):
    # the same cover offered only among the candidates smaller than a cover of one image
    # (Segmentation.small_pool): paired in the "small" pass only, never in the late one
    P, grads, rig = book
    quads = _projected(rig, P)
    det = Detector(rig, DetectConfig())
    small = _offered(quads, "small_pool")
    assert det._from_pool(rig, small, grads, [], DESK, None) == []
    assert det._from_pool(rig, small, grads, [], DESK, None, extra="late") == []
    found = det._from_pool(rig, small, grads, [], DESK, None, extra="small")
    assert len(found) == 1
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # metres
    # the small and the late pool in one segmentation, one cache for the small pass and
    # the late one after it: each refined quad is cached under its own corners, the
    # refinement of that quad (whichever pool it is in)
    from rovis.segment.boundary import refine_quad_fits
    decoy = _rectangle(center=(0.7, 0.5), size=(0.15, 0.10), z=0.02, yaw_deg=-30.0)
    both = {cam: replace(small[cam], late_pool=_pool([q]))
            for cam, q in _projected(rig, decoy).items()}
    refined: dict = {}
    assert len(det._from_pool(rig, both, grads, [], DESK, None, refined, extra="small")) == 1
    own = {(cam, both[cam].small_pool.corners[0].tobytes()) for cam in both}
    assert set(refined) == own  # the small quads only
    det._from_pool(rig, both, grads, [], DESK, None, refined, extra="late")
    late = {(cam, both[cam].late_pool.corners[0].tobytes()) for cam in both}
    assert set(refined) == own | late  # the decoy's too, apart
    for cam, key in refined:
        corners = np.frombuffer(key).reshape(4, 2)
        np.testing.assert_array_equal(refined[cam, key][0],
                                      refine_quad_fits(grads[cam], corners)[0])
    # a small quad is no partner in the late pass: the book's small quad in one image and
    # its late one in the other make no pair there (nor in the small pass, without the late)
    mixed = {"left": small["left"],
             "right": replace(Segmentation.empty(100.0, 30), late_pool=_pool([quads["right"]]))}
    assert det._from_pool(rig, mixed, grads, [], DESK, None, extra="late") == []
    assert det._from_pool(rig, mixed, grads, [], DESK, None, extra="small") == []


def test_a_pair_tilted_by_the_inward_cover_edge_search_is_refined_without_it(book, monkeypatch):
    # A printed line inside a side facing the camera can pull one image's refined side
    # inward (rovis.segment.boundary.cover_edge_offset): the pair then looks tilted. Here
    # the right image's search is made to move the near corners 6 px along the epipolar
    # lines (1 cm higher): the pair is refined again without it.
    import rovis.pipeline as pipeline
    P, grads, rig = book
    quads = _projected(rig, P)
    segs = {cam: replace(Segmentation.empty(100.0, 30), pool=_pool([q]))
            for cam, q in quads.items()}
    refine = pipeline.refine_quad_fits
    calls = []

    def pulled(grad, corners, **kw):
        inward, plain, fits = refine(grad, corners, **kw)
        calls.append(grad is grads["right"])
        if grad is grads["right"]:
            inward = inward.copy()
            inward[np.argsort(inward[:, 1])[2:]] -= [6.0, 0.0]  # the near corners 6 px off
        return inward, plain, fits

    monkeypatch.setattr(pipeline, "refine_quad_fits", pulled)
    found = Detector(rig, DetectConfig())._from_pool(rig, segs, grads, [], DESK, None)
    assert calls == [False, True]  # each image's quad refined once, both ways
    assert len(found) == 1
    assert abs(found[0][1].pose.size[2] - 0.03) < 0.004  # metres: flat at its true height


def test_refining_both_ways_and_the_sides_at_once_gives_each_one(book):
    # Detector._from_pool refines a candidate and fits its sides in one go
    # (refine_quad_fits): the same corners as refine_quad, the same fits as refine_sides
    from rovis.segment.boundary import refine_quad, refine_quad_fits, refine_sides
    P, grads, rig = book
    jog = np.array([[1.5, -1.0], [-1.0, 2.0], [0.5, 1.5], [2.0, 0.5]])
    for cam, quad in _projected(rig, P).items():
        for q in (quad, quad + jog, quad - 3 * jog):
            inward, plain, fits = refine_quad_fits(grads[cam], q)
            np.testing.assert_array_equal(inward, refine_quad(grads[cam], q))
            np.testing.assert_array_equal(plain, refine_quad(grads[cam], q, down=(0.0, 0.0)))
            for fit, want in zip(fits, refine_sides(grads[cam], q), strict=True):
                assert (fit is None) == (want is None)
                if fit is not None:
                    np.testing.assert_array_equal(fit[0], want[0])
                    np.testing.assert_array_equal(fit[1], want[1])


def _tilted_right(monkeypatch, grads):
    """Make the right image's refined quads (both ways) 0.8 px off along the epipolar
    lines at the near corners and 0.8 px the other way at the far ones: far from the
    camera, a few millimetres of height that tilt the cover."""
    import rovis.pipeline as pipeline
    refine = pipeline.refine_quad_fits

    def tilted(grad, corners, **kw):
        out = refine(grad, corners, **kw)
        if grad is not grads["right"]:
            return out
        moved = [q.copy() for q in out[:2]]  # both ways' corners (not the sides' fits)
        for q in moved:
            rows = np.argsort(q[:, 1])
            q[rows[2:]] += [0.8, 0.0]
            q[rows[:2]] -= [0.8, 0.0]
        return (*moved, out[2])

    monkeypatch.setattr(pipeline, "refine_quad_fits", tilted)


@pytest.mark.parametrize("refits", [20, 0])
def test_a_pair_no_flat_cover_with_every_side_seen_is_refit_flat(book, monkeypatch, refits):
    # Far from the camera a pixel of disparity is centimetres of height, and a cover's
    # refined corners come out tilted. Here the right image's are (_tilted_right), and the
    # tilt allowed is 0.5°: no flat cover, and no side unseen to complete. Refit as one
    # rectangle parallel to the desk (within DetectConfig.flat_refit_px of both images'
    # corners), the book is found.
    P, grads, rig = book
    _tilted_right(monkeypatch, grads)
    cfg = DetectConfig(max_tilt_deg=0.5)
    cfg = replace(cfg, stereo=replace(cfg.stereo, pool_flat_refits=refits))
    found = Detector(rig, cfg)._from_pool(rig, _offered(_projected(rig, P), "pool"), grads, [],
                                          DESK, None)
    assert len(found) == (1 if refits else 0)
    if refits:
        book = found[0][1]
        assert abs(book.pose.size[2] - 0.03) < 0.004  # metres
        assert np.linalg.norm(np.asarray(book.pose.center[:2]) - P.mean(axis=0)[:2]) < 0.005


def test_a_pair_with_a_side_unseen_is_never_refit_flat(book, monkeypatch):
    # as above, but the far side is unseen in both images and completion is off: the
    # guessed side is no evidence to fit a rectangle to
    from rovis.extent import CompleteConfig
    P, grads, rig = book
    _tilted_right(monkeypatch, grads)
    segs = _offered(_projected(rig, P), "open_pool")
    for seg in segs.values():
        seg.open_pool.lines[:, 2] = -1  # (a side no Hough line gave)
    cfg = DetectConfig(max_tilt_deg=0.5, complete=CompleteConfig(enabled=False))
    assert Detector(rig, cfg)._from_pool(rig, segs, grads, [], DESK, None) == []
    # every side seen: refit
    segs = _offered(_projected(rig, P), "open_pool")
    assert len(Detector(rig, cfg)._from_pool(rig, segs, grads, [], DESK, None)) == 1


def test_only_the_pairs_closest_to_their_epipolar_segments_are_refined(book, monkeypatch):
    # busy texture gives thousands of pairs of candidates: StereoConfig.pool_max_pairs
    # bounds the refinement to those the epipolar geometry fits best
    import rovis.pipeline as pipeline
    P, grads, rig = book
    decoy = _rectangle(center=(0.7, 0.5), size=(0.15, 0.10), z=0.02, yaw_deg=-30.0)
    off = geometry.project(rig.Q_R, decoy) + [0.0, 2.0]  # 2 px off its epipolar lines
    segs = {"left": replace(Segmentation.empty(100.0, 30), pool=_pool(
                [geometry.project(rig.Q_L, decoy), geometry.project(rig.Q_L, P)])),
            "right": replace(Segmentation.empty(100.0, 30), pool=_pool(
                [off, geometry.project(rig.Q_R, P)]))}
    refined = []
    refine = pipeline.refine_quad_fits
    monkeypatch.setattr(pipeline, "refine_quad_fits",
                        lambda grad, corners, **kw: refined.append(corners) or
                        refine(grad, corners, **kw))
    cfg = with_settings(DetectConfig(), ["stereo.pool_max_pairs=1"])
    found = Detector(rig, cfg)._from_pool(rig, segs, grads, [], DESK, None)
    assert len(found) == 1
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # metres
    assert len(refined) == 2  # the book's quads, one per image; the decoy's not


def test_the_pairs_over_a_book_already_found_are_not_refined(book, monkeypatch):
    # the same cover twice in each image's pool (one copy a pixel off): the pair with the
    # most edge pixels is refined and gives the book; the other pairs lie over it and are
    # passed over on their Hough quads, unrefined
    import rovis.pipeline as pipeline
    P, grads, rig = book
    quads = _projected(rig, P)
    segs = {cam: replace(Segmentation.empty(100.0, 30), pool=_pool([q, q + [1.0, 0.5]]))
            for cam, q in quads.items()}
    assert len(pool_pairs(segs["left"].pool.corners, segs["right"].pool.corners, rig.Q_L,
                          rig.Q_R, desk_plane=DESK)) == 4
    refined = []
    refine = pipeline.refine_quad_fits
    monkeypatch.setattr(pipeline, "refine_quad_fits",
                        lambda grad, corners, **kw: refined.append(corners) or
                        refine(grad, corners, **kw))
    found = Detector(rig, DetectConfig())._from_pool(rig, segs, grads, [], DESK, None)
    assert len(found) == 1
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # metres
    assert len(refined) == 2  # the first copy in each image
    for got, want in zip(refined, (quads["left"], quads["right"])):
        np.testing.assert_allclose(got, order_corners(want))


def test_a_union_cut_back_by_the_extent_step_frees_the_other_book():
    """The demo scene: the pool's first pick there spans two touching photo covers (its
    pair beat the smaller book's, which gave way to it); the extent step cuts it back to
    one of them, and the pool looked at again finds the other, within 1 cm."""
    from rovis.demo import DEMO_LUX, DEMO_SEED
    from rovis.synth import render, sample_scene

    scene = sample_scene(DEMO_SEED, lux=DEMO_LUX, light="artificial")
    pair = render(scene, DEMO_SEED)
    truth = np.array([b["center"] for b in pair.truth["books"]])

    def within_1cm(settings):
        result = Detector(scene.rig, with_settings(DetectConfig(), settings)).detect(
            pair.left, pair.right)
        c = np.array([o.pose.center for o in result.objects]).reshape(-1, 3)
        return {t for t in range(len(truth))
                if len(c) and np.abs(c - truth[t]).max(axis=1).min() <= 0.01}

    # (the height map cut again without the found covers finds that book too, later:
    # heightmap.taken_px, off here to see the pool's own)
    again = within_1cm(["heightmap.taken_px=-1"])
    once = within_1cm(["heightmap.taken_px=-1", "stereo.pool_again=false"])
    assert once < again  # the same books and more
    assert len(again) == len(truth)
    assert len(within_1cm(["stereo.pool_again=false"])) == len(truth)


def test_a_late_pair_that_fits_no_rectangle_is_refused(book, monkeypatch):
    # the right quad's near corners 6 px off their epipolar lines, kept there (refinement
    # off): no rectangle projects onto both quads, 1.5 px of mean reprojection error
    import rovis.pipeline as pipeline
    P, grads, rig = book
    quads = _projected(rig, P)
    skewed = quads["right"].copy()
    skewed[np.argsort(skewed[:, 1])[2:], 1] += 6.0  # the two lowest corners in the image
    segs = {"left": replace(Segmentation.empty(100.0, 30), late_pool=_pool([quads["left"]])),
            "right": replace(Segmentation.empty(100.0, 30), late_pool=_pool([skewed]))}
    refine = pipeline.refine_quad_fits  # the corners as they are, the sides' fits as fitted
    monkeypatch.setattr(pipeline, "refine_quad_fits",
                        lambda grad, q, **kw: (q, q, refine(grad, q)[2]))
    assert Detector(rig, DetectConfig())._from_pool(rig, segs, grads, [], DESK, None,
                                                    extra="late") == []
    loose = with_settings(DetectConfig(), ["stereo.late_max_reprojection_px=3"])
    kept = Detector(rig, loose)._from_pool(rig, segs, grads, [], DESK, None, extra="late")
    assert len(kept) == 1 and 1.0 < kept[0][1].reprojection_error_px <= 3.0


def test_skew_names_each_corner_off_a_right_angle():
    good = _rectangle(yaw_deg=0.0)
    assert np.all(_skew_deg(good) < 1e-6)
    cut = good.copy()  # corner 2 slid 4 cm along side 1 towards corner 1: side 2 a diagonal
    cut[2] += 0.04 * (good[1] - good[2]) / np.linalg.norm(good[1] - good[2])
    off = _skew_deg(cut)
    assert off[0] < 1e-6 and off[1] < 1e-6  # corners 0 and 1 keep their right angles
    expected = np.degrees(np.arctan2(0.04, np.linalg.norm(good[3] - good[2])))
    np.testing.assert_allclose(off[2:], expected, atol=1e-6)  # both ends of side 2


@pytest.mark.parametrize("side, cut_mm", [(0, 40.0), (1, 40.0), (2, 30.0), (2, 40.0), (3, 40.0)])
def test_a_cover_with_a_side_on_a_diagonal_is_completed_to_its_rectangle(book, side, cut_mm):
    P, grads, rig = book
    cut = P.copy()  # the quad a printed diagonal gives: corner `side` slid along side - 1
    back = P[side - 1] - P[side]
    cut[side] += cut_mm / 1000 * back / np.linalg.norm(back)
    assert np.argmax(_skew_deg(cut) + np.roll(_skew_deg(cut), -1)) == side
    det = Detector(rig, DetectConfig())
    pair, before, why = det._reconstruct_or_why(
        rig, Pair(geometry.project(rig.Q_L, cut), geometry.project(rig.Q_R, cut), 1.0, 0.0),
        DESK, None)
    assert why == "" and np.linalg.norm(before.pose.center - P.mean(axis=0)) > 0.004
    segs = {cam: Segmentation.empty(100.0, 30) for cam in ("left", "right")}
    [(_, after)], dropped = det._unskewed(rig, segs, grads, [(pair, before)], DESK, None)
    assert dropped == []
    # each true corner within 3 mm of one of the completed cover's
    d = np.linalg.norm(after.corners_world[:, None] - P[None], axis=2)
    assert d.min(axis=0).max() < 0.003
    # a rectangle is left as it is
    good, fine, _ = det._reconstruct_or_why(rig, Pair(*_projected(rig, P).values(), 1.0, 0.0),
                                            DESK, None)
    [(same, kept)], _ = det._unskewed(rig, segs, grads, [(good, fine)], DESK, None)
    assert same is good and kept is fine
    # no height allowed to change: the cut cover stays as it was (skewed, not dropped: one
    # side alone makes it no rectangle)
    det.cfg = replace(det.cfg, unskew_height=0.0)
    [(same, kept)], dropped = det._unskewed(rig, segs, grads, [(pair, before)], DESK, None)
    assert same is pair and kept is before and dropped == []


@pytest.mark.parametrize("side", [0, 3])
def test_a_side_reaching_far_out_at_one_end_is_looked_for_between_its_ends(book, side):
    # one corner 8 cm out along its neighbouring side, on the bare desk (a side on a desk
    # line or a neighbour's edge, build/rt1 scene 66's book 4): the side's middle lies 4 cm
    # out, beyond complete.search of where the cover's own edge is. (Sides 1 and 2 so
    # moved find another edge within complete.search and are laid there, their corners
    # then 26 and 15 mm off: the near search goes first, docs/stereo.md.)
    P, grads, rig = book
    out = P.copy()
    on = P[side] - P[side - 1]
    out[side] += 0.08 * on / np.linalg.norm(on)
    assert np.argmax(_skew_deg(out) + np.roll(_skew_deg(out), -1)) == side
    det = Detector(rig, DetectConfig())
    pair, before, why = det._reconstruct_or_why(
        rig, Pair(*_projected(rig, out).values(), 1.0, 0.0), DESK, None)
    assert why == "" and _skew_deg(before.corners_world).max() > 8.0
    segs = {cam: Segmentation.empty(100.0, 30) for cam in ("left", "right")}
    [(_, after)], dropped = det._unskewed(rig, segs, grads, [(pair, before)], DESK, None)
    d = np.linalg.norm(after.corners_world[:, None] - P[None], axis=2)
    assert dropped == [] and d.min(axis=0).max() < 0.003  # m
    # looked for within complete.search only, it stays as it was or is laid on another
    # edge there: a corner more than 1 cm off
    det.cfg = replace(det.cfg, unskew_reach=0.0)
    [(_, kept)], _ = det._unskewed(rig, segs, grads, [(pair, before)], DESK, None)
    d = np.linalg.norm(kept.corners_world[:, None] - P[None], axis=2)
    assert d.min(axis=0).max() > 0.01  # m


def test_a_side_of_no_length_makes_no_right_angle():
    P = _rectangle()
    P[2] = P[1]  # side 1 collapsed: corners 1 and 2 make no angle
    np.testing.assert_allclose(_skew_deg(P)[[1, 2]], 90.0)


def test_a_parallelogram_with_no_right_angle_is_dropped(book):
    P, grads, rig = book
    # lines crossing 3 cm above the bare desk, beside the book: every angle 12.8° off
    # 90°, and no edge for a side to be placed on again
    slid = P + [0.25, 0.15, 0.0]
    along = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0])
    slid[2:] += 0.05 * along
    det = Detector(rig, DetectConfig())
    pair, quad, why = det._reconstruct_or_why(
        rig, Pair(*_projected(rig, slid).values(), 1.0, 0.0), DESK, None)
    assert why == "" and _skew_deg(quad.corners_world).min() > 12.0  # the pose checks pass it
    segs = {cam: Segmentation.empty(100.0, 30) for cam in ("left", "right")}
    kept, dropped = det._unskewed(rig, segs, grads, [(pair, quad)], DESK, None)
    assert kept == [] and [why for why, _, _ in dropped] == ["skewed"]
    # with every angle allowed, it is kept
    det.cfg = replace(det.cfg, unskew_deg=20.0)
    kept, dropped = det._unskewed(rig, segs, grads, [(pair, quad)], DESK, None)
    assert kept == [(pair, quad)] and dropped == []


def _with_unseen(seg, sides=(2,)):
    """``seg`` with the given sides of its small pool's candidates unseen (line -1)."""
    lines = seg.small_pool.lines.copy()
    lines[:, list(sides)] = -1
    return replace(seg, small_pool=replace(seg.small_pool, lines=lines))


def test_small_candidates_with_sides_unseen_are_paired_in_the_last_pass_only(book):
    # Segmentation.small_pool holds the four-sided small candidates, then (with
    # SegmentConfig.small_open) those with sides unseen: only the "small_open" pass pairs
    # the latter, with any pool's quad as the partner, and marks its books
    P, grads, rig = book
    quads = _projected(rig, P)
    det = Detector(rig, DetectConfig())
    unseen = {cam: _with_unseen(seg) for cam, seg in _offered(quads, "small_pool").items()}
    for extra in (None, "small", "late"):
        assert det._from_pool(rig, unseen, grads, [], DESK, None, extra=extra) == []
    found = det._from_pool(rig, unseen, grads, [], DESK, None, extra="small_open")
    assert len(found) == 1 and found[0][0].small_open
    assert np.linalg.norm(found[0][1].pose.center - P.mean(axis=0)) < 0.005  # m
    # its partner from the late pool
    mixed = {"left": unseen["left"],
             "right": replace(Segmentation.empty(100.0, 30), late_pool=_pool([quads["right"]]))}
    assert det._from_pool(rig, mixed, grads, [], DESK, None, extra="late") == []
    found = det._from_pool(rig, mixed, grads, [], DESK, None, extra="small_open")
    assert len(found) == 1 and found[0][0].small_open
    # no quad of its own: the last pass pairs nothing; the small pass pairs a four-sided one
    assert det._from_pool(rig, _offered(quads, "pool"), grads, [], DESK, None,
                          extra="small_open") == []
    found = det._from_pool(rig, _offered(quads, "small_pool"), grads, [], DESK, None,
                           extra="small")
    assert len(found) == 1 and not found[0][0].small_open


def _near(protocol: str, seed: int, scene: int, book: int, settings: list[str]) -> list[float]:
    """Distances (m, on the desk) of the books found in a development set's scene from one
    true book's centre, nearest first."""
    from dataset_scene import dataset_scene

    sc, r = dataset_scene(protocol, seed, scene)
    centre = np.asarray(r.truth["books"][book]["center"])[:2]
    res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
    return sorted(float(np.linalg.norm(o.pose.center[:2] - centre)) for o in res.objects)


def test_the_pool_is_looked_at_again_under_a_cover_dropped_at_the_end():
    # Table I's scene 45 (rovis synth --protocol table1 --seed 1): book 3, a printed cover
    # 228 x 91 x 21 mm, is found early as its part beyond a band (under 6 cm wide), which
    # keeps the pool's pairs of the whole cover out of the pool's pass and is dropped as
    # too narrow at the end; looked at again, the pool gives the cover
    assert _near("table1", 1, 45, 3, [])[0] < 0.02  # m
    assert _near("table1", 1, 45, 3, ["stereo.pool_freed=false"])[0] > 0.05


def test_the_other_part_of_a_cover_found_is_no_book_from_the_freed_pool():
    # build/t1b's scene 29 (rovis synth --protocol table1 --seed 2): book 3, a photo cover
    # 276 x 177 x 25 mm, is found as its part beyond a band; the pool looked at again
    # under a piece dropped there gives the part on the other side of it, at its height,
    # beside it: no new book (with freed_touch 0 it is one, a false positive)
    assert len([d for d in _near("table1", 2, 29, 3, []) if d < 0.08]) == 1
    assert len([d for d in _near("table1", 2, 29, 3, ["stereo.freed_touch=0"])
                if d < 0.08]) == 2


@pytest.mark.parametrize("scene, book", [(66, 4), (70, 1)])
def test_detect_lays_a_cover_with_a_side_far_out_at_one_end_again(scene, book):
    # build/rt1 (rovis synth --protocol table1 --n 100 --seed 1): scene 66's book 4 (dark,
    # 120 x 108 x 11 mm) and scene 70's book 1 (desk-toned, 132 x 105 x 25 mm) were found
    # 26-27° off a rectangle, one side on a desk line reaching 3-5 cm past the cover
    assert _near("table1", 1, scene, book, [])[0] < 0.003  # m
    assert _near("table1", 1, scene, book, ["unskew_reach=0"])[0] > 0.01


@pytest.mark.parametrize("scene", [101, 117])
def test_a_cover_flush_behind_a_taller_book_gives_way_to_it(scene):
    # The Table II renders (rovis synth --protocol table2 --n 128 --seed 1), scenes 101
    # and 117 (500 lx): book 0, a photo cover 130 x 128 x 16 mm, lies flush behind book 1,
    # a plain one 159 x 91 x 50 mm that hides a corner of it. One pool pair took the
    # photo's three far sides and book 1's cover for one quad, its fourth side guessed on
    # book 1: a book at 16 mm, 8 cm too long, over book 1's footprint, and book 1 lost
    from dataset_scene import dataset_scene

    sc, r = dataset_scene("table2", 1, scene)
    true_0, true_1 = r.truth["books"][:2]
    for share, kept in ((0.2, True), (1.0, False)):
        settings = [f"stereo.pool_taller_share={share}"]
        res = Detector(sc.rig, with_settings(DetectConfig(), settings)).detect(r.left, r.right)
        got_0, off_0 = nearest_book(res, true_0["center"], on_desk=True)
        longer_0 = float(max(got_0.pose.size[:2]) - max(true_0["size"][:2]))
        _, off_1 = nearest_book(res, true_1["center"], on_desk=True)
        if kept:
            assert off_0 < 0.005 and abs(longer_0) < 0.005  # m
            assert off_1 < 0.008
        else:
            assert longer_0 > 0.05  # the quad over both books
            assert off_1 > 0.03  # and nothing found on book 1


@pytest.mark.parametrize("protocol, seed, scene, book, method, tol", [
    ("table2", 1, 58, 4, "closed", 0.002), ("table1", 1, 94, 0, "closed", 0.006),
    ("table1", 5, 55, 1, "closed", 0.003), ("table1", 1, 48, 4, "lsd", 0.006)])
def test_a_book_gives_way_to_no_mismatch_of_its_own_quads(protocol, seed, scene, book,
                                                          method, tol):
    # pairs a book does not give way to (stereo.pool_taller_share; rovis synth --seed
    # SEED): the Table II renders' scene 58, a desk-toned cover 18 mm high, its own quads
    # at another disparity (67 mm; a two-sided pair covering all of its left quad); the
    # Table I renders' scene 94, a printed cover 36 mm high, a two-sided pair at 79 mm over
    # it (no book stands 79 mm there; it covers 54-59 % of the cover's left quad);
    # build/h1's scene 55, its own cover at 24 mm, covering 67 % of its left quad; the
    # Table I renders' scene 48 with the lsd method, a photo cover 22 mm high, a pair of
    # four seen sides at 69 mm covering 42 % of it, which its print lays at 22 mm. Giving
    # way to them, the first two and the last were lost, the third found 5.1 mm off
    # (1.7 mm)
    from dataset_scene import dataset_scene

    sc, r = dataset_scene(protocol, seed, scene)
    res = Detector(sc.rig, DetectConfig(method=method)).detect(r.left, r.right)
    c = np.asarray(r.truth["books"][book]["center"])
    got, _ = nearest_book(res, c)
    assert np.abs(got.pose.center - c).max() < tol  # m
