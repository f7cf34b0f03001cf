"""Covers with one side unseen (rovis.segment.quads.three_sided_quads, Segmentation.open_pool)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from rovis.segment import CascadeController, SegmentConfig, canny, gradients, hough_lines
from rovis.segment.boundary import evaluate, open_candidates, roi_area
from rovis.segment.control import unseen_candidates
from rovis.segment.lines import support_profile
from rovis.segment.quads import (QuadConfig, Quads, _canonical, candidate_quads, order_corners,
                                 three_sided_quads)

H, W = 480, 640
COVER = np.array([[212.0, 180.0], [452.0, 180.0], [468.0, 330.0], [196.0, 330.0]])  # px


def far_side_hidden(noise: float = 2.0) -> np.ndarray:
    """A light cover (180) on a grey desk (100), its far side (y = 180) against a band of
    the cover's own brightness: no step there, while the band's edge beside the cover
    makes a Hough line through the hidden side. Drawn 8x supersampled."""
    S = 8
    img = np.full((H * S, W * S), 100, np.float32)
    img[:180 * S + S // 2] = 180  # the band ends where the cover's far side is
    pts = np.rint((COVER * S + (S - 1) / 2) * 16).astype(np.int32)
    cv2.fillPoly(img, [pts], 180, lineType=cv2.LINE_8, shift=4)
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(3)
    return np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)


def _worst_corner_px(quads: np.ndarray) -> float:
    """Worst corner error (px) of the nearest quad to COVER, inf if none."""
    if len(quads) == 0:
        return np.inf
    err = np.linalg.norm(_canonical(quads) - order_corners(COVER)[None], axis=2).max(axis=1)
    return float(err.min())


def _chain(img: np.ndarray, T_H: float = 60.0):
    grad = gradients(img)
    edges = canny(grad, T_H)
    lines = hough_lines(edges, 30, grad=grad, max_lines=100)
    return grad, lines, support_profile(lines, edges, grad)


def test_a_cover_whose_far_side_shows_no_step_is_closed_where_its_sides_end():
    grad, lines, profile = _chain(far_side_hidden())
    full = candidate_quads(lines, profile, grad.shape, roi_area(grad))
    assert _worst_corner_px(full.corners) > 10.0  # no 4-cycle: the far side has no edge
    open_ = three_sided_quads(lines, profile, grad.shape, roi_area(grad))
    assert _worst_corner_px(open_.corners) < 3.0  # px: within the gap tolerance
    k = int(np.argmin(np.linalg.norm(_canonical(open_.corners) - order_corners(COVER)[None],
                                     axis=2).max(axis=1)))
    assert open_.lines[k, 2] == -1 and open_.support[k, 2] == 0.0  # side 2 is the open one
    assert np.all(open_.support[k, [0, 1, 3]] >= 0.7)


def test_three_sided_candidates_need_three_supported_sides():
    # the same cover with two sides gone: a bright L on the band gives no U
    img = far_side_hidden()
    img[:, :212] = img[0, 0]  # the band's brightness left of the cover: its left side gone
    grad, lines, profile = _chain(img)
    assert _worst_corner_px(three_sided_quads(lines, profile, grad.shape,
                                              roi_area(grad)).corners) > 10.0


def test_blank_images_give_no_three_sided_candidates():
    for img in (np.zeros((H, W), np.uint8), np.full((H, W), 255, np.uint8)):
        grad = gradients(img)
        ev = evaluate(grad, 60.0, SegmentConfig())
        assert len(open_candidates(grad, ev, SegmentConfig())) == 0


def test_an_evaluation_keeps_the_lines_and_hits_its_candidates_came_from():
    grad = gradients(far_side_hidden())
    ev = evaluate(grad, 60.0, SegmentConfig())
    assert ev.all_lines is not None and len(ev.all_lines) >= len(ev.lines)
    assert _worst_corner_px(open_candidates(grad, ev, SegmentConfig()).corners) < 3.0


def test_the_closed_loop_offers_them_to_stereo_in_its_open_pool():
    grad = gradients(far_side_hidden())
    seg = CascadeController(SegmentConfig(three_sided_support=2.0),
                            warm_start=False).segment(grad)
    assert _worst_corner_px(seg.corners) > 10.0  # the closed loop's own covers miss it
    assert _worst_corner_px(seg.open_pool.corners) < 3.0
    np.testing.assert_allclose(seg.open_pool.corners[0], order_corners(seg.open_pool.corners[0]))
    off = CascadeController(SegmentConfig(three_sided=False), warm_start=False).segment(grad)
    assert len(off.open_pool) == 0


def test_the_pools_sides_follow_their_corners_put_in_eq_1_order():
    # the open side is still the one with no line once the corners are reordered: the far
    # side (y = 180), whatever index it now has
    grad = gradients(far_side_hidden())
    pool = CascadeController(SegmentConfig(three_sided_support=2.0),
                             warm_start=False).segment(grad).open_pool
    k = int(np.argmin(np.linalg.norm(pool.corners - order_corners(COVER)[None],
                                     axis=2).max(axis=1)))
    q, unseen = pool.corners[k], np.flatnonzero(pool.lines[k] < 0)
    assert len(unseen) == 1 and pool.support[k, unseen[0]] == 0.0
    s = int(unseen[0])
    np.testing.assert_allclose(0.5 * (q[s] + q[(s + 1) % 4]), [332.0, 180.0], atol=3.0)  # px
    from rovis.segment.quads import Quads, canonical_quads
    # reversed and rotated: each side keeps its line and support
    c = COVER[None, [2, 1, 0, 3]]  # corners 2, 1, 0, 3: its sides are the original 1, 0, 3, 2
    got = canonical_quads(Quads(np.array([[11, 10, 13, 12]]), c, np.array([[1.0, 0.0, 3.0, 2.0]]),
                                np.ones(1), np.ones(1, np.int64)))
    np.testing.assert_array_equal(got.corners[0], order_corners(COVER))
    for side in range(4):  # the original side s runs from COVER[s] to COVER[s + 1]
        a, b = got.corners[0, side], got.corners[0, (side + 1) % 4]
        original = next(t for t in range(4) if {tuple(COVER[t]), tuple(COVER[(t + 1) % 4])}
                        == {tuple(a), tuple(b)})
        assert got.lines[0, side] == 10 + original
        assert got.support[0, side] == original


def test_a_run_of_edge_pixels_ends_at_its_first_long_gap_both_ways():
    from rovis.segment.lines import SupportProfile
    from rovis.segment.quads import _run_end
    hit = np.zeros(120, np.int32)
    hit[10:60] = 1
    hit[30:35] = 0  # a 5 px hole: shorter than the 8 px gap, the run goes on
    profile = SupportProfile(np.concatenate([[0], np.cumsum(hit)]).astype(np.int32)[None],
                             np.array([-50.0]))  # sample k at position k - 50
    line = np.zeros(2, np.intp)
    corner = np.array([5.0, 64.0]) - 50.0  # one corner before the run, one after it
    end, hits = _run_end(profile, line, corner, np.array([1.0, -1.0]), 3.0, 8.0, 400.0)
    # px to the gap's first sample, one past the run's last hit: samples 60 and 9
    np.testing.assert_array_equal(end, [55.0, 55.0])
    np.testing.assert_array_equal(hits, [45.0, 45.0])  # its 50 samples less the hole
    end, _ = _run_end(profile, line, corner, np.array([1.0, -1.0]), 3.0, 8.0, 20.0)
    np.testing.assert_array_equal(end, [20.0, 20.0])  # at most ``most``


def test_every_run_ends_where_a_walk_sample_by_sample_finds_its_gap():
    # several lines, runs reaching either end of a line and lines with no gap or no hit
    from rovis.segment.lines import SupportProfile
    from rovis.segment.quads import _run_end
    rng = np.random.default_rng(7)
    n_lines, n_samples, g, start = 6, 90, 8, 3
    hit = (rng.random((n_lines, n_samples)) < rng.uniform(0.3, 1.0, (n_lines, 1))).astype(int)
    hit[0], hit[1] = 1, 0
    hit[2, :25] = hit[2, -25:] = 1
    cum = np.concatenate([np.zeros((n_lines, 1), int), np.cumsum(hit, axis=1)], axis=1)
    profile = SupportProfile(cum.astype(np.int32), rng.uniform(-50, 50, n_lines))
    line = rng.integers(0, n_lines, 400)
    k0 = rng.integers(-3, n_samples + 3, 400)  # the corner's sample, a few outside the line
    sign = rng.choice([-1.0, 1.0], 400)
    end, hits = _run_end(profile, line, profile.t0[line] + k0, sign, start, g, 60.0)

    def gap(i, m, up):  # a gap starts (up) or ends at sample m: g samples with no hit
        lo, hi = (m, m + g) if up else (m - g + 1, m + 1)
        return not hit[i, max(lo, 0):max(min(hi, n_samples), 0)].any()

    for q in range(400):
        i, k, up = line[q], k0[q], sign[q] > 0
        if not 0 <= k < n_samples:
            assert end[q] == hits[q] == 0
            continue
        m = min(max(k + start if up else k - start, 0), n_samples - 1)
        while 0 <= m < n_samples and not gap(i, m, up):
            m += 1 if up else -1
        want = min(abs(m - k), 60)
        stop = k + want if up else k - want
        first = min(max(k + start if up else k - start, 0), n_samples - 1)
        span = hit[i, first:max(stop, first)] if up else hit[i, max(stop + 1, 0):first + 1]
        assert (end[q], hits[q]) == (want, span.sum()), q

def test_where_no_threshold_gave_a_cover_every_evaluation_offers_its_three_sided(monkeypatch):
    import rovis.segment.control as control
    asked = []
    real = control.open_candidates
    monkeypatch.setattr(control, "open_candidates",
                        lambda grad, ev, *a, **k: asked.append(ev.T_H) or real(grad, ev, *a, **k))
    seg = CascadeController(SegmentConfig(), warm_start=False).segment(
        gradients(far_side_hidden()))
    assert seg.y == 0.0  # no cover at any T_H
    # every T_H the search evaluated (at least its coarse grid), each once
    assert len(asked) == len(set(asked)) >= SegmentConfig().coarse_steps


def test_a_three_sided_candidate_with_its_three_sides_clearly_seen_is_a_cover():
    grad = gradients(far_side_hidden())
    seg = CascadeController(SegmentConfig(), warm_start=False).segment(grad)
    assert len(seg) == 1 and _worst_corner_px(seg.corners) < 3.0  # px
    assert seg.three_sided.tolist() == [True]
    assert seg.support[0] >= 0.95  # of its three seen sides, not diluted by the open one
    assert seg.alternatives == ()  # no cover at any T_H: the union kept none
    # where a cover already lies, or below the support asked for, it stays a candidate
    from rovis.segment.control import with_three_sided_covers
    from rovis.segment.boundary import Evaluation
    from rovis.segment.lines import Lines
    from rovis.segment.quads import Quads
    pool = seg.open_pool
    one = Quads(np.zeros((1, 4), np.intp), COVER[None] + 1.0, np.ones((1, 4)), np.ones(1),
                np.ones(1, np.int64))
    ev = Evaluation(60.0, 30, 1.0, Lines.empty(), one, 1)
    assert len(with_three_sided_covers(ev, (), pool, 0.95, 0.15)[0].covers) == 1
    far = Quads(np.zeros((1, 4), np.intp), COVER[None] + [[0.0, 200.0]], np.ones((1, 4)),
                np.ones(1), np.ones(1, np.int64))  # a cover elsewhere, with an alternative
    ev = Evaluation(60.0, 30, 1.0, Lines.empty(), far, 1)
    got, alts = with_three_sided_covers(ev, (np.ones((2, 4, 2)),), pool, 0.95, 0.15)
    assert len(got.covers) == len(alts) == 2  # one alternatives entry per cover
    assert alts[0].shape == (2, 4, 2) and alts[1].shape == (0, 4, 2)
    empty = Evaluation(60.0, 30, 0.0, Lines.empty(), Quads.empty(), 1)
    assert len(with_three_sided_covers(empty, (), pool, 0.95, 0.15)[0].covers) >= 1
    assert len(with_three_sided_covers(empty, (), pool, 1.01, 0.15)[0].covers) == 0


def test_a_segmented_cover_with_a_side_unseen_must_stand_as_high_as_any_found_otherwise():
    # a quad of three lines on a flat pattern of the desk is no book: the 6 mm floor of
    # the covers found otherwise than by both segmentations applies to it too
    from rovis import geometry
    from rovis.pipeline import DetectConfig, Detector, Pair
    from rovis.synth import sample_scene
    det = Detector(sample_scene(3, lux=500.0, n_books=0).rig, DetectConfig())
    desk = np.array([0.0, 0.0, 1.0, 0.0])
    P = geometry.corners_from_pose((0.4, 0.3, 0.004), np.eye(3), (0.2, 0.14))  # 4 mm up
    pose = geometry.pose_from_corners(P, desk)
    quad = np.zeros((4, 2))
    assert det._pose_fails(pose, P, desk, Pair(quad, quad, 1.0, 0.0)) == ""
    assert det._pose_fails(pose, P, desk, Pair(quad, quad, 1.0, 0.0, three_sided=True)) == "height"


# -- two sides unseen (two_sided_quads) ----------------------------------------------------

SLANT = np.array([[212.0, 180.0], [452.0, 180.0], [468.0, 330.0], [228.0, 330.0]])  # px


def _drawn(polys, seed: int, noise: float, *, top_rows: int = 0) -> np.ndarray:
    """Polygons (px) of the cover's brightness (180) on the desk (100), and the first
    ``top_rows`` rows too, drawn 8x supersampled, with seeded sensor noise."""
    S = 8
    img = np.full((H * S, W * S), 100, np.float32)
    if top_rows:
        img[:top_rows * S + S // 2] = 180
    for poly in polys:
        pts = np.rint((poly * S + (S - 1) / 2) * 16).astype(np.int32)
        cv2.fillPoly(img, [pts], 180, lineType=cv2.LINE_8, shift=4)
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(seed)
    return np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)


def far_and_left_sides_hidden(noise: float = 2.0) -> np.ndarray:
    """A light cover (180) on a grey desk (100), a parallelogram, its far and left sides
    against bands of its own brightness: only its right and near sides show a step (an
    "L"). The left band's lower edge is not in line with the near side, so that side's
    edge ends at the cover's corner."""
    band = np.array([[0.0, 180.0], [212.0, 180.0], [228.0, 330.0], [0.0, 200.0]])
    return _drawn((SLANT, band), 5, noise, top_rows=180)


def _nearest(quads: np.ndarray, truth: np.ndarray) -> tuple[float, int]:
    """The worst corner error (px) of the quad nearest ``truth``, and its index (inf, -1
    if none)."""
    if len(quads) == 0:
        return np.inf, -1
    err = np.linalg.norm(_canonical(quads) - order_corners(truth)[None], axis=2).max(axis=1)
    return float(err.min()), int(np.argmin(err))


def _worst_to(quads: np.ndarray, truth: np.ndarray) -> float:
    return _nearest(quads, truth)[0]


def test_a_cover_showing_two_sides_is_closed_where_their_edges_end():
    from rovis.segment.quads import two_sided_quads
    grad, lines, profile = _chain(far_and_left_sides_hidden())
    area = roi_area(grad)
    assert _worst_to(candidate_quads(lines, profile, grad.shape, area).corners, SLANT) > 10.0
    assert _worst_to(three_sided_quads(lines, profile, grad.shape, area).corners, SLANT) > 10.0
    two = two_sided_quads(lines, profile, grad.shape, area)
    err, k = _nearest(two.corners, SLANT)
    assert err < 3.0  # px
    assert two.lines[k, 1] == two.lines[k, 2] == -1  # sides 1 and 2 are the open ones
    assert np.all(two.support[k, [0, 3]] >= 0.7) and np.all(two.support[k, [1, 2]] == 0.0)


def test_blank_images_give_no_two_sided_candidates():
    from rovis.segment.boundary import two_sided_candidates
    for img in (np.zeros((H, W), np.uint8), np.full((H, W), 255, np.uint8)):
        grad = gradients(img)
        ev = evaluate(grad, 60.0, SegmentConfig())
        assert len(two_sided_candidates(grad, ev, SegmentConfig())) == 0


def test_the_closed_loop_offers_two_sided_candidates_to_stereo_only():
    grad = gradients(far_and_left_sides_hidden())
    seg = CascadeController(SegmentConfig(), warm_start=False).segment(grad)
    assert _worst_to(seg.corners, SLANT) > 10.0  # never a cover of one image
    assert _worst_to(seg.open_pool.corners, SLANT) < 3.0
    off = CascadeController(SegmentConfig(two_sided=False), warm_start=False).segment(grad)
    assert _worst_to(off.open_pool.corners, SLANT) > 10.0


def test_side_evidence_tells_a_faint_step_from_none():
    from rovis.segment.boundary import side_evidence
    grad = gradients(far_and_left_sides_hidden())
    ev = side_evidence(grad, order_corners(SLANT), 12.0)  # grey levels / px (Sobel)
    # eq. 1 order: far (top), right, near (bottom), left
    assert ev[1] > 0.9 and ev[2] > 0.9  # the seen sides, along their whole length
    assert ev[0] < 0.1 and ev[3] < 0.1  # no step where the cover meets its bands
    faint = far_and_left_sides_hidden(noise=0.0).astype(np.float32)
    faint[:180] = 172  # the far band 8 grey levels darker than the cover: a faint step
    ev = side_evidence(gradients(np.clip(faint, 0, 255).astype(np.uint8)), order_corners(SLANT), 12.0)
    assert ev[0] > 0.9


def laterals_hidden(noise: float = 2.0) -> np.ndarray:
    """The parallelogram cover again, its two lateral sides against bands of its own
    brightness and only its far and near sides showing a step; the bands' own edges leave
    the cover's corners steeply (a shallow one would carry the side's edge run on past the
    corner, up to the 8 px gap)."""
    bands = (np.array([[120.0, 0.0], [212.0, 180.0], [228.0, 330.0], [120.0, 479.0]]),
             np.array([[452.0, 180.0], [560.0, 0.0], [580.0, 479.0], [468.0, 330.0]]))
    return _drawn((SLANT, *bands), 7, noise)


def test_a_cover_showing_its_far_and_near_sides_is_closed_between_their_ends():
    from rovis.segment.quads import opposite_sided_quads
    grad, lines, profile = _chain(laterals_hidden())
    area = roi_area(grad)
    assert _worst_to(candidate_quads(lines, profile, grad.shape, area).corners, SLANT) > 10.0
    assert _worst_to(three_sided_quads(lines, profile, grad.shape, area).corners, SLANT) > 10.0
    two = opposite_sided_quads(lines, profile, grad.shape, area)
    err, k = _nearest(two.corners, SLANT)
    assert err < 3.0  # px
    assert two.lines[k, 1] == two.lines[k, 3] == -1  # sides 1 and 3 are the open ones
    assert np.all(two.support[k, [0, 2]] >= 0.7)
    # runs whose ends do not face each other are not joined
    shifted = laterals_hidden()
    shifted[320:340, 300:480] = 180  # the near side's edge gone from x = 300 on
    grad, lines, profile = _chain(shifted)
    assert _worst_to(opposite_sided_quads(lines, profile, grad.shape, area).corners,
                     SLANT) > 10.0



def test_the_other_evaluations_offer_theirs_late_and_once(monkeypatch):
    # a dark cover gives the loop an optimum; every other T_H with a cover is asked for its
    # candidates with sides unseen once, for the late pool
    import rovis.segment.control as control
    img = far_side_hidden()
    img[380:460, 40:200] = 30  # a dark cover on the grey desk, all four sides seen
    asked, evaluated = [], {}
    real_open, real_eval = control.open_candidates, control.evaluate
    monkeypatch.setattr(control, "open_candidates",
                        lambda grad, ev, *a, **k: asked.append(ev.T_H)
                        or real_open(grad, ev, *a, **k))

    def evaluate(grad, T_H, cfg, **kw):
        ev = real_eval(grad, T_H, cfg, **kw)
        evaluated.setdefault(ev.T_H, ev.y)
        return ev

    monkeypatch.setattr(control, "evaluate", evaluate)
    cfg = SegmentConfig(three_sided_evaluations=0, union=False, three_sided_support=2.0)
    seg = CascadeController(cfg, warm_start=False).segment(gradients(img))
    assert seg.y > 0 and asked[0] == seg.T_H  # the optimum's first, for the open pool
    others = {T_H for T_H, y in evaluated.items() if y > 0 and T_H != seg.T_H}
    assert len(others) >= 1
    assert sorted(asked[1:]) == sorted(others)  # then each other T_H with a cover, once
    asked.clear()
    off = CascadeController(replace(cfg, late_open=False), warm_start=False).segment(
        gradients(img))
    assert asked == [off.T_H] and len(off.late_pool) == 0
    np.testing.assert_allclose(off.open_pool.corners, seg.open_pool.corners)


def test_the_unseen_candidates_are_those_no_earlier_pool_holds():
    # a faint cover (8 grey levels over the desk) shows its three sides at a low T_H only
    img = far_side_hidden(noise=1.0).astype(np.int16)
    img = np.where(img > 140, 108, 100).astype(np.uint8)  # the band and the cover, faint
    grad = gradients(img)
    cfg = SegmentConfig()
    low, high = evaluate(grad, 20.0, cfg), evaluate(grad, 120.0, cfg)
    assert _worst_corner_px(open_candidates(grad, high, cfg).corners) > 10.0  # unseen there
    late = unseen_candidates(grad, [low], Quads.empty(), cfg, area=roi_area(grad))
    assert _worst_corner_px(late.corners) < 3.0  # px
    near = open_candidates(grad, low, cfg)  # offered earlier: not again
    again = unseen_candidates(grad, [low], near, cfg, area=roi_area(grad))
    assert _worst_corner_px(again.corners) > 10.0
    assert len(unseen_candidates(grad, [], Quads.empty(), cfg, area=roi_area(grad))) == 0


def test_the_quad_stage_bounds_a_candidate_s_area_in_square_pixels():
    # a 96 x 64 px cover: 6144 px². Until git 173c5d1 the quad stages took an area at half
    # its value (QuadConfig.min_area_px acted as twice itself, max_area_frac as twice itself)
    cover = np.array([[300.0, 200.0], [396.0, 200.0], [396.0, 264.0], [300.0, 264.0]])
    grad, lines, profile = _chain(_drawn((cover,), 11, 2.0))
    area = roi_area(grad)
    kept = candidate_quads(lines, profile, grad.shape, area, QuadConfig(min_area_px=6000.0))
    assert _worst_to(kept.corners, cover) < 1.5  # px
    # below the bound, or over half of the region of interest: no candidate
    for cfg, roi in ((QuadConfig(min_area_px=6300.0), area), (QuadConfig(), 12000.0)):
        assert _worst_to(candidate_quads(lines, profile, grad.shape, roi, cfg).corners,
                         cover) > 10.0


def test_a_cover_smaller_than_the_covers_bound_goes_to_stereo_only():
    # 80 x 50 px: 4000 px², under QuadConfig.min_area_px = 5000, over pool_min_area_px
    small = np.array([[300.0, 200.0], [380.0, 200.0], [380.0, 250.0], [300.0, 250.0]])
    img = _drawn((small,), 12, 2.0)
    grad = gradients(img)
    seg = CascadeController(SegmentConfig(), warm_start=False).segment(grad)
    assert _worst_to(seg.corners, small) > 10.0 and _worst_to(seg.pool.corners, small) > 10.0
    assert _worst_to(seg.small_pool.corners, small) < 1.5  # px, Hough corners
    off = CascadeController(SegmentConfig(pool_min_area_px=5000.0), warm_start=False)
    assert len(off.segment(grad).small_pool) == 0
    # distinct candidates (each 4-cycle is formed twice, once per pair of opposite lines),
    # the most edge pixels first, from the one-evaluation methods too
    from rovis.segment.methods import segment
    for method in ("closed", "open"):
        pool = segment(img, grad, method).small_pool
        assert len(pool) >= 1 and np.all(np.diff(pool.n_f) <= 0)
        c = _canonical(pool.corners).reshape(len(pool), 8)
        apart = np.abs(c[:, None] - c[None]).max(axis=2) + np.eye(len(pool)) * 1e9
        assert apart.min() > 3.0  # px
