"""Stereo correspondence of book covers (paper §4, before eq. 3).

Each left cover quad is matched to at most one right quad. A right corner must lie where
the left corner's ray can be seen: on its epipolar line, and — with a known desk plane —
between the ray's points at desk height and at ``max_height`` above it (a short segment of
that line: books lie on the desk). Without a desk plane the depth range bounds the segment.
Among the four cyclic corner orders the best is kept, so the same physical corner is P1 in
both images; the covers' appearance (normalised cross-correlation of the two rectified
cover patches) breaks ties between similar shapes. The assignment is one-to-one
(Hungarian).

Beyond the paper: a cover the segmentation found in one image only is looked for in the
other (:func:`find_in_other_view`). Books lie flat, so with the desk plane known the cover's
one unknown is its height; its predicted sides are checked against the other image's
gradient and refit there. The segmentation often finds a cover in one image and misses it
in the other; this recovers those books instead of needing both images' chains to succeed.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from rovis import geometry
from rovis.segment.boundary import refine_quad
from rovis.segment.edges import Gradients
from rovis.sweep import on_plane

_PATCH = (48, 36)  # rectified cover patch, px
_POOL_BLOCK = 8192  # pairs of candidates per block of pool_pairs' corner test
_PLAIN_STD = 4.0  # grey levels: a cover patch varying less than this is plain
_PLAIN_MEAN = 20.0  # grey levels: two plain patches this close in brightness look alike
_HIGHLIGHT_NCC = 0.5  # two plain patches but for a highlight: above StereoConfig.min_ncc,
# and in match_quads' cost still behind a pair whose print correlates better


@dataclass(frozen=True)
class StereoConfig:
    """Gates of the correspondence search (pixels, metres)."""

    max_error_px: float = 3.0  # mean distance of the right corners to their segments
    max_height: float = 0.40  # above the desk plane
    min_depth: float = 0.2  # without a desk plane
    max_depth: float = 5.0
    min_ncc: float = 0.2  # covers must look alike
    appearance_weight_px: float = 2.0  # cost of (1 - NCC), in pixels
    # Finding a cover seen in one image only in the other (find_in_other_view):
    transfer: bool = True
    min_height: float = 0.006  # cover height range searched above the desk, metres (a
    # sheet on the desk read 4.1 mm at 15 lx and was placed by its print at 4 mm)
    max_cover_height: float = 0.10  # (the ROI's height)
    height_step: float = 0.002  # ~0.1 px of disparity at 1-2 m
    max_refine_px: float = 4.0  # refined corners this close to the predicted ones (the source
    # quad may be a few pixels off: a side on its page block, or stopped short)
    transfer_max_overlap: float = 0.3  # of the smaller quad, with one already used
    # A cover found otherwise than by both segmentations (every side seen) is dropped, last,
    # where it overlaps one they found by more than this share of the smaller quad in both
    # images (0: never; Detector._without_overlaps)
    over_segmented: float = 0.15
    # ...but a height-map book over one such book only, across a side of it, is cut back to
    # where that cover ends and kept if it then passes the pose checks and lies over no other
    # book (its print stands out of the desk there: Detector._cut_off)
    over_cut: bool = True
    # Two covers found overlapping on the desk by a strip this wide or more (metres; 0:
    # never): where the height maps and the print read the strip at one's height and not
    # the other's, and the first's side there shows a step in both images, the other is
    # cut back off it (Detector._cut_by_height)
    height_cut: float = 0.008
    height_cut_gap: float = 0.05  # NCC, at one height against the other
    height_cut_support: float = 0.6  # share of that side
    # Without the desk plane the search fixes less (the plane comes from the quad itself,
    # the depth from 0.2 to 5 m): only a quad its own image backs this well (mean edge
    # support of its sides) is looked for. On the real pairs the chess sheet's quads had
    # 0.98-1.0, the chair parts a robot would have taken for books 0.83-0.90.
    free_transfer_support: float = 0.95
    # A pair that fails a pose check (rovis.pipeline.ALTERNATIVE_REASONS) is retried with
    # the other quads the closed loop found over it (Segmentation.alternatives).
    alternatives: bool = True
    max_alternatives: int = 4  # per image, the first found (each pairing costs a sweep)
    # ...and first with each image's quad refined without the inward search for the cover
    # edge (a step to a faint edge in one image only tilts the cover)
    plain_alternative: bool = True
    # A pool candidate with two sides unseen (Segmentation.open_pool) is kept only where
    # every refined side shows a step along at least this share of it, in both images
    # (rovis.segment.boundary.side_evidence)
    two_sided_evidence: float = 0.45
    two_sided_flatness: float = 0.015  # metres: its refined corners' heights differ at most so
    transfer_alternatives: int = 2  # tried as sources when a quad is found in one image only
    # Where no book is yet, books among the candidate quads neither image's selection kept
    # (Segmentation.pool): pairs that make a flat, book-sized rectangle (pool_pairs).
    pool: bool = True
    pool_max_pairs: int = 300  # refined per frame, the smallest epipolar error first
    small_max_pairs: int = 20  # ...in the pass of the small candidates (Segmentation.small_pool)
    # A pair whose two opposite sides both images saw and whose other two neither did (two
    # plain books end to end, their ends unseen) has its corners where each image's edges
    # happened to end, centimetres off in depth: pool_pairs asks of it only that its seen
    # sides lie at a cover's height and that it is roughly a rectangle
    pool_opposite: bool = True
    # A pair that refines to no flat cover and has every side seen in one image or the
    # other is refit as one rectangle parallel to the desk (as DetectConfig.flat_refit_px);
    # taken last in its pass, after the completions. At most this many per pass, the most
    # edge pixels first, of those over no book found by then (each is a least-squares fit
    # and the pose checks)
    pool_flat_refits: int = 20
    # Books stand side by side on the desk, not one inside another. A pool pair that
    # refined flat and whose book covers more than pool_taller_share of the desk footprint
    # of a pair of the pass not yet considered gives way to it: it is asked again after
    # the pass's other flat pairs (before the completions and refits), and taken then if
    # still free (it may lie over the taller book, if found, by up to
    # transfer_max_overlap in each image). That pair's Hough quad lies over the book's
    # left quad (more than 10 % of the smaller), leaving 40 % of it or more uncovered (not
    # the book's own quads at another disparity), over no book found; it stands higher
    # than the book on its Hough corners, has one side unseen at most and, refined, its
    # corners at one height (within two_sided_flatness) CompleteConfig.taller_by or more
    # above the book's, and makes a book that tall by the pose checks (its print swept)
    # and its pass's own bounds.
    # A cover flush behind a taller book made one quad with that book's cover, its far
    # side on the taller cover, at the cover's height (1 or more: never)
    pool_taller_share: float = 0.2
    # Where no book is yet, last, a candidate quad of one image (Segmentation.pool) looked
    # for in the other (find_in_other_view) where, refined, its own image shows its sides:
    # every side's step along pool_transfer_seen of it (rovis.segment.boundary.side_evidence),
    # or all but one, which shows it along pool_transfer_part to pool_transfer_seen: a
    # neighbour of the cover's tone touches that side (two plain books end to end), and
    # the other image need not show it either.
    pool_transfer: bool = True
    pool_transfer_max: int = 24  # candidates looked for per image, the most edge pixels first
    pool_transfer_seen: float = 0.8
    pool_transfer_part: float = 0.15
    # ...the late pool's candidates too (Segmentation.late_pool), after the others, the
    # first pool_transfer_max of them; one with a side unseen is a book only as the fit
    # below makes it
    pool_transfer_late: bool = True
    # A candidate with a side unseen is laid flat on its sides (geometry.fit_rectangle_sides)
    # but, in the other image, the unseen one and its opposite, where that fit lies within
    # DetectConfig.flat_refit_sides of the sides it used (pipeline._transferred_fit); only
    # so may the other image show a side along the epipolar lines short as well
    # (find_in_other_view's along_short)
    pool_transfer_fit: bool = True
    # ...and where that fit missed its own image's unseen side (placed where its
    # neighbours' edges end, a few pixels off and askew at a seam) and no book came of the
    # candidate, once every candidate is tried the same fit with that side excused up to
    # this many pixels (pipeline._transferred_fit's excuse_px; 0: never): the Table II
    # renders' plain book end to end with a taller one of its tone. Not for a candidate
    # only the strict fit makes a book of (the late pool's, the loose look's)
    pool_transfer_excuse_px: float = 5.0
    # Where a quarter or more of a cover found before the extent step lies under no cover
    # after it (a pool pair that was two touching books, cut back to one), the pool is
    # looked at again: the other book's pair had given way to the union
    pool_again: bool = True
    # A cover dropped at the end (narrower than a book, or over one both segmentations
    # found) was found before the pool's pass and kept the candidates under it out of it
    # (a piece of a cover cut at a band of its print): the pool looked at again there. A
    # book it gives must lie over no found book by more than freed_overlap of the smaller
    # quad in either image, nor beside one at its height with two corners within
    # freed_touch (metres) of its outline: the other part of that book's cover
    pool_freed: bool = True
    freed_overlap: float = 0.1
    freed_touch: float = 0.02
    # The desk between books: a found cover with a side neither image shows as a step
    # (rovis.segment.boundary.side_evidence under desk_unseen along it, in both images)
    # whose inside matches between the images at the desk's height (NCC at least desk_ncc)
    # as well as at its own or better is dropped at the end, unless the height map found it
    # (Detector._without_desk; 0: never). The desk's grain and the plank seams close such a
    # quad with a book's edge.
    desk_unseen: float = 0.3
    desk_ncc: float = 0.3
    # ...and one whose every side shows, where its inside matches between the images best at
    # the desk (a sweep from the desk to 5 mm above the cover, every millimetre, peaking
    # desk_peak metres above the desk or lower) with an NCC of at least desk_seen_ncc, and
    # desk_margin more than at its own height (desk_seen_ncc above 1: never): a sheet's
    # printed text block, or the desk closed on all four sides by books', sheets' and
    # shadows' edges.
    desk_peak: float = 0.002
    desk_seen_ncc: float = 0.5
    desk_margin: float = 0.05
    # After the height maps, a pair with a quad among the other T_H's candidates
    # (Segmentation.late_pool):
    # the rectangle fitted to both images' corners must reproject within this mean
    # distance of them (px: the corners' triangulation residual, not the output's
    # reprojection_error_px, which rovis.agreement measures at the end of the frame; a
    # pair whose near side is the cover's edge in one image and its page
    # block's foot in the other makes a flat cover at the wrong height, 3 px off; a pair
    # completed in 3D or moved by its print is its 3D cover's projection, 0 px off)
    late_max_reprojection_px: float = 1.0
    # Last of all, a pair with a small candidate with sides unseen (SegmentConfig.small_open),
    # as the late pool's pairs (late_max_reprojection_px too); the book must not be the desk
    # between books found (two sides on theirs), and each side must be at least this long
    # after the extent step and at the end (metres: the scene model's narrowest book is
    # 9 cm; a piece of a cover cut short at a band of its print, or a strip of desk, is
    # narrower)
    small_open_min_side: float = 0.075
    # ...but one between books found is taken where it is a book of its own there
    # (small_open_between; Detector._from_pool): its print, swept from the desk up to
    # SweepConfig.max_height, matches between the images best within the larger of
    # small_open_print_tol (metres) and a quarter of its height of that height, with an
    # NCC of at least small_open_print_ncc and at least small_open_print_gap above the
    # desk's, and each book whose outline holds one of its sides stands at least
    # small_open_apart (metres) higher or lower (a piece of that book cut at a band of
    # its print, flush with it, stands at its height)
    small_open_between: bool = True
    small_open_print_tol: float = 0.003
    small_open_print_ncc: float = 0.6
    small_open_print_gap: float = 0.1
    small_open_apart: float = 0.004


@dataclass(frozen=True, eq=False)
class Match:
    """One left quad matched to one right quad.

    Attributes
    ----------
    left, right : int
        Indices into the left and right quads.
    corners_right : ndarray, shape (4, 2)
        The right quad's corners reordered to correspond to the left's P1..P4.
    error_px : float
        Mean distance of the right corners to their allowed segments.
    ncc : float
        Appearance similarity in [-1, 1].
    """

    left: int
    right: int
    corners_right: NDArray[np.float64]
    error_px: float
    ncc: float


def match_quads(quads_left: ArrayLike, quads_right: ArrayLike, Q_L: ArrayLike, Q_R: ArrayLike, *,
                desk_plane: ArrayLike | None = None, gray_left: NDArray[np.uint8] | None = None,
                gray_right: NDArray[np.uint8] | None = None,
                cfg: StereoConfig = StereoConfig()) -> list[Match]:
    """Match cover quads between the (undistorted) left and right images.

    Parameters
    ----------
    quads_left, quads_right : array_like, shape (K, 4, 2) and (M, 4, 2)
        Ideal (undistorted) pixel corners.
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections (eq. 3).
    desk_plane : array_like, shape (4,), optional
        ``[nx, ny, nz, d]`` in the world frame, normal up.
    gray_left, gray_right : ndarray, optional
        The undistorted images, for the appearance check.

    Returns
    -------
    list of Match, sorted by left index.
    """
    qL = np.asarray(quads_left, dtype=np.float64).reshape(-1, 4, 2)
    qR = np.asarray(quads_right, dtype=np.float64).reshape(-1, 4, 2)
    if len(qL) == 0 or len(qR) == 0:
        return []
    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    near_px, far_px = _segments(qL.reshape(-1, 2), Q_L, Q_R, desk_plane, cfg)  # (4K, 2) each
    near_px, far_px = near_px.reshape(-1, 4, 2), far_px.reshape(-1, 4, 2)

    shifts = np.array([np.roll(np.arange(4), -s) for s in range(4)])  # right corner order
    cost = np.full((len(qL), len(qR)), np.inf)
    best: dict[tuple[int, int], tuple[NDArray[np.float64], float, float]] = {}
    for k in range(len(qL)):
        cand = qR[:, shifts]  # (M, 4 shifts, 4 corners, 2)
        d = _point_segment_distance(cand, near_px[k][None, None], far_px[k][None, None])
        err = d.mean(axis=2)  # (M, 4)
        s_best = np.argmin(err, axis=1)
        e_best = err[np.arange(len(qR)), s_best]
        for m in np.nonzero(e_best <= cfg.max_error_px)[0]:
            corners_r = cand[m, s_best[m]]
            ncc = 1.0
            if gray_left is not None and gray_right is not None:
                ncc = _cover_ncc(gray_left, qL[k], gray_right, corners_r)
                if ncc < cfg.min_ncc:
                    continue
            cost[k, m] = e_best[m] + cfg.appearance_weight_px * (1.0 - ncc)
            best[(k, m)] = (corners_r, float(e_best[m]), ncc)
    finite = np.isfinite(cost)
    if not finite.any():
        return []
    rows, cols = linear_sum_assignment(np.where(finite, cost, 1e9))
    out = [Match(int(k), int(m), *best[(k, m)]) for k, m in zip(rows, cols) if finite[k, m]]
    return sorted(out, key=lambda mt: mt.left)


@dataclass(frozen=True, eq=False)
class PoolPairs:
    """Pairs of candidate quads (one per image) that make a flat, book-sized rectangle.

    Attributes
    ----------
    left, right : ndarray, shape (P,), intp
        Indices into the left and right pools.
    corners_right : ndarray, shape (P, 4, 2)
        The right quad's corners reordered to correspond to the left's P1..P4.
    shift : ndarray, shape (P,), intp
        That order: ``corners_right[p] = pool_right[right[p]][(k + shift[p]) % 4]``.
    error_px : ndarray, shape (P,)
        Mean distance of the right corners to their allowed segments.
    """

    left: NDArray[np.intp]
    right: NDArray[np.intp]
    corners_right: NDArray[np.float64]
    shift: NDArray[np.intp]
    error_px: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.left)

    def take(self, index: NDArray[np.intp]) -> PoolPairs:
        return PoolPairs(self.left[index], self.right[index], self.corners_right[index],
                         self.shift[index], self.error_px[index])

    @classmethod
    def concat(cls, parts: list[PoolPairs]) -> PoolPairs:
        """The pairs of ``parts`` in order (their indices into the same two pools)."""
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                     ("left", "right", "corners_right", "shift", "error_px")))


def pool_pairs(pool_left: ArrayLike, pool_right: ArrayLike, Q_L: ArrayLike, Q_R: ArrayLike, *,
               desk_plane: ArrayLike | None = None, side_range: tuple[float, float] = (0.05, 0.45),
               max_skew_deg: float = 25.0, max_tilt_deg: float = 25.0,
               height_slack: float = 0.04, cfg: StereoConfig = StereoConfig(),
               seen_left: ArrayLike | None = None, seen_right: ArrayLike | None = None,
               ) -> PoolPairs:
    """Every left × right pair of candidate quads that could be one book's cover.

    Beyond the paper. Each image's segmentation chooses its covers alone, by edge pixels;
    there a union of two touching books, a book's outline or a square of a printed pattern
    can win over the cover. Seen from two cameras most of those are no flat rectangle,
    so the two images' candidates (:attr:`rovis.segment.Segmentation.pool`) are paired here:
    the right corners on their epipolar segments (as :func:`match_quads`), and the
    triangulated corners roughly a flat rectangle (:func:`flat_rectangle`). The gates are
    loose by default: Hough corners are 1–4 px off, a few centimetres of height; the
    caller refines the pairs that pass and checks them again. Vectorised over all pairs: a
    coarse gate on the quads' centres first, the corner test on those that pass.

    Parameters
    ----------
    pool_left, pool_right : array_like, shape (K, 4, 2) and (M, 4, 2)
        Ideal pixel corners, each in eq. 1 order.
    Q_L, Q_R : array_like, shape (3, 4)
    desk_plane : array_like, shape (4,), optional
    side_range, max_skew_deg, max_tilt_deg, height_slack
        :func:`flat_rectangle`'s gates.
    seen_left, seen_right : array_like, shape (K, 4) and (M, 4), bool, optional
        Which sides of each candidate lie on a Hough line (side s from corner s to s + 1;
        ``Quads.lines >= 0``). With both, the desk plane and ``cfg.pool_opposite``, a pair
        whose two opposite sides both images saw and whose other two neither did (as
        :func:`rovis.segment.quads.opposite_sided_quads` gives) is judged, instead of by
        its corners' flatness (its corners are where each image's edges happened to end,
        and along a side a few pixels are centimetres of depth), by its seen sides: each
        that stereo can measure (:func:`_seen_side_heights`) must lie from
        ``cfg.min_height`` to ``cfg.max_cover_height`` + ``height_slack`` above the desk,
        one at least must be measurable, and both images' quads laid at their median
        height must roughly be a rectangle (sides within half the lower and 1.5 times the
        upper ``side_range``, angles within 45° of 90°). The caller places its unseen
        sides in 3D (:func:`rovis.extent.complete_open`).

    Returns
    -------
    PoolPairs
    """
    qL = np.asarray(pool_left, dtype=np.float64).reshape(-1, 4, 2)
    qR = np.asarray(pool_right, dtype=np.float64).reshape(-1, 4, 2)
    none = PoolPairs(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 4, 2)),
                     np.zeros(0, np.intp), np.zeros(0))
    if len(qL) == 0 or len(qR) == 0:
        return none
    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    near, far = _segments(qL.reshape(-1, 2), Q_L, Q_R, desk_plane, cfg)
    near, far = near.reshape(-1, 4, 2), far.reshape(-1, 4, 2)
    # coarse gate: the right centre near the segment of the left corners' mean
    d = _point_segment_distance(qR.mean(axis=1)[None], near.mean(axis=1)[:, None],
                                far.mean(axis=1)[:, None])  # (K, M)
    i, j = np.nonzero(d <= 2.0 * cfg.max_error_px)
    if len(i) == 0:
        return none
    shifts = np.array([np.roll(np.arange(4), -s) for s in range(4)])
    # the corner test in blocks of pairs: a frame of many candidates has half a million
    # pairs past the coarse gate, whose arrays in one piece (hundreds of megabytes) took
    # four to five times as long (build/mx scene 17)
    err = np.empty((len(i), 4))
    for start in range(0, len(i), _POOL_BLOCK):
        block = slice(start, start + _POOL_BLOCK)
        cand = qR[j[block]][:, shifts]  # (block, 4 shifts, 4 corners, 2)
        err[block] = _point_segment_distance(cand, near[i[block]][:, None],
                                             far[i[block]][:, None]).mean(axis=2)
    s_best = np.argmin(err, axis=1)
    e_best = err[np.arange(len(i)), s_best]
    ok = e_best <= cfg.max_error_px
    if not ok.any():
        return none
    i, j, s_best, e_best = i[ok], j[ok], s_best[ok], e_best[ok]
    corners_r = qR[j[:, None], shifts[s_best]]  # (P, 4, 2), each in its best shift
    P = geometry.triangulate_dlt(Q_L, Q_R, qL[i].reshape(-1, 2),
                                 corners_r.reshape(-1, 2)).reshape(-1, 4, 3)
    heights = (cfg.min_height - height_slack, cfg.max_cover_height + height_slack)
    ok = flat_rectangle(P, desk_plane, side_range=side_range, max_skew_deg=max_skew_deg,
                        max_tilt_deg=max_tilt_deg, height_range=heights)
    if (cfg.pool_opposite and seen_left is not None and seen_right is not None
            and desk_plane is not None):
        seen_l = np.asarray(seen_left, bool).reshape(-1, 4)[i]
        seen_r = np.take_along_axis(np.asarray(seen_right, bool).reshape(-1, 4)[j],
                                    shifts[s_best], axis=1)  # in the left's corner order
        both, neither = seen_l & seen_r, ~seen_l & ~seen_r
        # sides 0 and 2 seen in both images and 1 and 3 in neither, or the other way round
        opposite = np.flatnonzero(~ok & (
            (both[:, 0] & both[:, 2] & neither[:, 1] & neither[:, 3])
            | (both[:, 1] & both[:, 3] & neither[:, 0] & neither[:, 2])))
        if len(opposite):
            h = _seen_side_heights(qL[i[opposite]], corners_r[opposite],
                                   both[opposite], Q_L, Q_R, desk_plane, cfg)
            known = np.isfinite(h).any(axis=1)
            at_cover = known & np.all(np.isnan(h) | ((h >= cfg.min_height)
                                                     & (h <= heights[1])), axis=1)
            # the shape: both images' quads laid at the seen sides' height, averaged
            level = np.zeros(len(opposite))
            if at_cover.any():  # (there every height is finite or NaN, one at least finite)
                level[at_cover] = np.nanmedian(h[at_cover], axis=1)
            laid = np.array([0.5 * (on_plane(Q_L, a, desk_plane, z)
                                    + on_plane(Q_R, b, desk_plane, z))
                             for a, b, z in zip(qL[i[opposite]], corners_r[opposite], level)])
            ok[opposite] = at_cover & flat_rectangle(
                laid, side_range=(0.5 * side_range[0], 1.5 * side_range[1]), max_skew_deg=45.0)
    return PoolPairs(i[ok], j[ok], corners_r[ok], s_best[ok], e_best[ok])


def _seen_side_heights(left: NDArray[np.float64], right: NDArray[np.float64],
                       seen: NDArray[np.bool_], Q_L: NDArray[np.float64],
                       Q_R: NDArray[np.float64], desk_plane: ArrayLike, cfg: StereoConfig,
                       min_angle_deg: float = 10.0) -> NDArray[np.float64]:
    """Height above the desk (metres) of each seen side of paired quads, whatever their
    corners: the left side's midpoint matched where the right side crosses that point's
    epipolar segment (:func:`_segments`), triangulated.

    Parameters
    ----------
    left, right : ndarray, shape (N, 4, 2)
        The pairs' corners in each ideal image, corresponding.
    seen : ndarray, shape (N, 4), bool
        The sides to measure (side s from corner s to s + 1).

    Returns
    -------
    ndarray, shape (N, 4)
        NaN for a side not measured or within ``min_angle_deg`` of its epipolar segment
        (along the epipolar lines a side has no disparity); +inf where the right side
        crosses the segment's line outside the segment (above ``cfg.max_height``, or more
        than 2 % of its depth below the desk: a little below the desk reads as a negative
        height).
    """
    out = np.full(seen.shape, np.nan)
    n, s = np.nonzero(seen)
    if len(n) == 0:
        return out
    a, b = left[n, s], left[n, (s + 1) % 4]
    mid = 0.5 * (a + b)
    near, far = _segments(mid, Q_L, Q_R, desk_plane, cfg)
    c, d = right[n, s], right[n, (s + 1) % 4]
    # near + t (far - near) on the right side's line: (x - c) × (d - c) = 0
    seg, side = far - near, d - c
    cross = seg[:, 0] * side[:, 1] - seg[:, 1] * side[:, 0]
    sine = np.abs(cross) / np.maximum(np.linalg.norm(seg, axis=1)
                                      * np.linalg.norm(side, axis=1), 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((c[:, 0] - near[:, 0]) * side[:, 1] - (c[:, 1] - near[:, 1]) * side[:, 0]) / cross
    # (parallel: t infinite or NaN, the side's height NaN below; 0 here, no inf · 0)
    on = near + np.where(np.isfinite(t), t, 0.0)[:, None] * seg
    X = geometry.triangulate_dlt(Q_L, Q_R, mid, on)
    h = geometry.plane_distance(np.asarray(desk_plane, dtype=np.float64), X)
    h = np.where((t >= 0.0) & (t <= 1.0), h, np.inf)
    out[n, s] = np.where(sine >= np.sin(np.radians(min_angle_deg)), h, np.nan)
    return out


def side_lengths_and_corner_cos(P: ArrayLike,
                                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The sides' lengths of quads of world corners ``P`` (..., 4, 3) and how far each
    corner's angle is from a right angle.

    Returns
    -------
    length : ndarray, shape (..., 4)
        Side k from corner k to k + 1 (metres).
    cos : ndarray, shape (..., 4)
        |cos| of the angle at corner k, between side k - 1 and side k: 0 for a right
        angle, the sine of its deviation from 90° (:func:`rovis.pipeline._skew_deg`); 1
        where either side has no length (no rectangle).
    """
    P = np.asarray(P, dtype=np.float64)
    side = np.roll(P, -1, axis=-2) - P
    length = np.linalg.norm(side, axis=-1)
    unit = side / np.maximum(length[..., None], 1e-12)
    cos = np.abs(np.sum(unit * np.roll(unit, 1, axis=-2), axis=-1))
    short = length < 1e-9
    cos[short | np.roll(short, 1, axis=-1)] = 1.0
    return length, cos


def flat_rectangle(P: ArrayLike, desk_plane: ArrayLike | None = None, *,
                   side_range: tuple[float, float] = (0.05, 0.45), max_skew_deg: float = 12.0,
                   max_tilt_deg: float = 6.0,
                   height_range: tuple[float, float] = (0.0, 0.10)) -> NDArray[np.bool_]:
    """Which quads of world corners ``P`` (N, 4, 3) could be a book's cover on the desk.

    Every side within ``side_range`` (metres), every angle within ``max_skew_deg`` of 90°
    (a side of no length makes none: :func:`side_lengths_and_corner_cos`); with the desk
    plane, the normal of the diagonals within ``max_tilt_deg`` of the desk's
    and every corner within ``height_range`` (metres) above it.

    Returns
    -------
    ndarray, shape (N,), bool
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 4, 3)
    length, cos = side_lengths_and_corner_cos(P)
    with np.errstate(invalid="ignore"):
        ok = (np.all(np.isfinite(P), axis=(1, 2))
              & np.all((length >= side_range[0]) & (length <= side_range[1]), axis=1)
              & np.all(cos <= np.sin(np.radians(max_skew_deg)), axis=1))
        if desk_plane is not None:
            plane = np.asarray(desk_plane, dtype=np.float64)
            normal = np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1])  # of the diagonals
            normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
            height = P @ plane[:3] + plane[3]  # (N, 4)
            ok &= ((np.abs(normal @ plane[:3]) >= np.cos(np.radians(max_tilt_deg)))
                   & np.all((height >= height_range[0]) & (height <= height_range[1]), axis=1))
    return ok


def find_in_other_view(corners: ArrayLike, Q_from: ArrayLike, Q_to: ArrayLike,
                       desk_plane: ArrayLike | None, grad_to: Gradients, min_strength: float, *,
                       gray_from: NDArray[np.uint8] | None = None,
                       gray_to: NDArray[np.uint8] | None = None,
                       unseen: int | None = None, along_short: bool = False,
                       cfg: StereoConfig = StereoConfig()) -> tuple[NDArray[np.float64], float] | None:
    """The cover found in one image, looked for in the other by its height above the desk.

    A book's cover is parallel to the desk: its corners' rays meet the plane at height h
    in four points, whose projections are the cover in the other image. h is swept from
    ``cfg.min_height`` to ``cfg.max_cover_height``; the h whose predicted sides show the
    strongest edges (median gradient across each, best of ±1 px, weighted by how much the
    side crosses the epipolar lines) wins if every side reaches ``min_strength`` (but one
    within 30° of the epipolar lines may fall short: beyond the paper, a far side of the
    desk's brightness shows no step; with ``unseen``, that side instead, or with
    ``along_short`` as well); its sides are refit to the gradient
    (:func:`rovis.segment.boundary.refine_quad`). Used for covers the segmentation found
    in one image only: their edges are often there in the other image too, just below what
    its Hough stage kept.

    Without the desk plane, the cover's own plane is taken from the quad
    (:func:`rectangle_normal`: a rectangle's image fixes its plane's orientation) and swept
    in depth instead, from ``cfg.min_depth`` to ``cfg.max_depth`` along the quad's centre
    ray, in steps of at most half a pixel of motion in the other image.

    Parameters
    ----------
    corners : array_like, shape (4, 2)
        Ideal pixel corners in the image where the cover was found.
    Q_from, Q_to : array_like, shape (3, 4)
        World → ideal pixel projections of that image and of the other.
    desk_plane : array_like, shape (4,), or None
        ``[nx, ny, nz, d]`` in the world frame, normal up; None: unknown.
    grad_to : Gradients
        The other image's gradients.
    min_strength : float
        Every predicted side's median gradient across it must reach this (Sobel units; the
        other image's Canny low threshold is a natural choice).
    gray_from, gray_to : ndarray, optional
        Both undistorted images: the two covers must then also look alike (``cfg.min_ncc``).
    unseen : int, optional
        A side (from corner ``unseen`` to the next) that need show no edge in the other
        image either, and places no height: its own image shows it along part of its
        length only (a neighbour of the cover's tone touches it there). Beyond it, every
        side must show its edge, unless ``along_short``: then one side along the epipolar
        lines may still fall short, as without ``unseen`` (with one side across the lines
        left to place the height, the caller must check the cover it makes).

    Returns
    -------
    (corners_to, value) : ndarray, shape (4, 2), and float, or None
        Corners in the other image, in the same physical order as ``corners``; the height
        above the desk (metres), or without the desk plane the distance along the centre
        ray (metres).
    """
    if unseen is not None and not 0 <= unseen < 4:
        raise ValueError(f"unseen: expected a side 0-3, got {unseen}")
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    Q_from, Q_to = np.asarray(Q_from, dtype=np.float64), np.asarray(Q_to, dtype=np.float64)
    swept = (_over_heights(c, Q_from, Q_to, np.asarray(desk_plane, dtype=np.float64), cfg)
             if desk_plane is not None else _over_depths(c, Q_from, Q_to, cfg))
    if swept is None:
        return None
    pred, values = swept
    strength = _side_strength(grad_to, pred)  # (H, 4)
    # A side along the epipolar lines slides onto itself at every height: only sides across
    # them place the cover. Weight each side by the sine of its angle to the corners' motion.
    side = np.roll(pred[0], -1, axis=0) - pred[0]
    motion = pred[-1] - pred[0]
    motion = 0.5 * (motion + np.roll(motion, -1, axis=0))  # at each side's middle
    w = np.abs(side[:, 0] * motion[:, 1] - side[:, 1] * motion[:, 0]) / np.maximum(
        np.linalg.norm(side, axis=1) * np.linalg.norm(motion, axis=1), 1e-9)
    if unseen is not None:
        w[unseen] = 0.0
    score = strength @ w / max(w.sum(), 1e-9)
    best = int(np.argmax(score))
    # Every side must show its edge, except one along the epipolar lines (w < 0.5: within
    # 30° of them), which places no height: the cover of the desk's brightness shows no
    # step at its far side, in this image as in the other. (The ``unseen`` side instead,
    # or with ``along_short`` as well.)
    weak = strength[best] < min_strength
    if unseen is not None:
        weak[unseen] = False  # it places nothing
        if not along_short and weak.any():
            return None
    if weak.sum() > 1 or (weak.any() and w[weak].max() >= 0.5):
        return None
    refined = refine_quad(grad_to, pred[best])
    if np.linalg.norm(refined - pred[best], axis=1).max() > cfg.max_refine_px:
        return None
    if gray_from is not None and gray_to is not None and \
            _cover_ncc(gray_from, c, gray_to, refined) < cfg.min_ncc:
        return None
    return refined, float(values[best])


def _over_heights(c: NDArray[np.float64], Q_from: NDArray[np.float64], Q_to: NDArray[np.float64],
                  plane: NDArray[np.float64], cfg: StereoConfig,
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The quad ``c`` laid parallel to the desk at each height of the sweep: its corners
    in the other image (H, 4, 2), and the heights (H,)."""
    C, rays = _rays(Q_from, c)
    heights = np.arange(cfg.min_height, cfg.max_cover_height + 1e-9, cfg.height_step)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -(plane[:3] @ C + plane[3] - heights[:, None]) / (rays @ plane[:3])[None, :]  # (H, 4)
    if not np.all(np.isfinite(s) & (s > 0)):
        return None
    return geometry.project(Q_to, C + s[..., None] * rays[None]).reshape(len(heights), 4, 2), heights


def _over_depths(c: NDArray[np.float64], Q_from: NDArray[np.float64], Q_to: NDArray[np.float64],
                 cfg: StereoConfig, max_steps: int = 4000,
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The quad ``c`` laid on the plane its rectangle implies (:func:`rectangle_normal`),
    at each depth of the sweep (the distance along the centre ray, from ``cfg.min_depth``
    to ``cfg.max_depth``, uniform in inverse depth): corners in the other image (H, 4, 2),
    and the depths (H,)."""
    normal = rectangle_normal(c, Q_from)
    if normal is None:
        return None
    C, rays = _rays(Q_from, c)
    centre = rays.mean(axis=0)
    centre /= np.linalg.norm(centre)
    along = rays @ normal  # each corner ray's and the centre ray's speed toward the plane
    if np.any(np.sign(along) != np.sign(centre @ normal)) or np.any(np.abs(along) < 1e-6):
        return None  # a plane seen edge-on
    ratio = (centre @ normal) / along  # corner distance = ratio · centre distance

    def at(depth: NDArray[np.float64]) -> NDArray[np.float64]:
        X = C + (depth[:, None, None] * ratio[None, :, None]) * rays[None]
        return geometry.project(Q_to, X.reshape(-1, 3)).reshape(len(depth), 4, 2)

    ends = at(np.array([cfg.min_depth, cfg.max_depth]))
    travel = float(np.linalg.norm(ends[1] - ends[0], axis=1).max())
    steps = int(np.clip(np.ceil(travel / 0.5), 2, max_steps))
    depth = 1.0 / np.linspace(1.0 / cfg.min_depth, 1.0 / cfg.max_depth, steps)
    return at(depth), depth


def rectangle_normal(corners: ArrayLike, Q: ArrayLike,
                     max_skew_deg: float = 12.0) -> NDArray[np.float64] | None:
    """The world unit normal (3,) of the plane of a rectangle whose image is ``corners``.

    Opposite sides of a rectangle are parallel in 3D: each pair meets at a vanishing point
    ``v`` (at infinity for sides parallel in the image too), the image of the direction
    ``M⁻¹ v`` (M = Q[:, :3]). The two directions span the plane; they must be within
    ``max_skew_deg`` of perpendicular, or the quad is no rectangle's image (None). The
    normal points away from the camera.

    Parameters
    ----------
    corners : array_like, shape (4, 2)
        Ideal pixels, in cyclic order.
    Q : array_like, shape (3, 4)
        World → ideal pixel projection of that image.
    """
    p = np.column_stack([np.asarray(corners, dtype=np.float64).reshape(4, 2), np.ones(4)])
    side = [np.cross(p[s], p[(s + 1) % 4]) for s in range(4)]  # homogeneous lines
    M = np.asarray(Q, dtype=np.float64)[:, :3]
    dirs = []
    for a, b in ((0, 2), (1, 3)):
        v = np.cross(side[a], side[b])
        if not np.linalg.norm(v) > 0:
            return None
        D = np.linalg.solve(M, v / np.linalg.norm(v))
        dirs.append(D / np.linalg.norm(D))
    if abs(dirs[0] @ dirs[1]) > np.sin(np.radians(max_skew_deg)):
        return None
    n = np.cross(dirs[0], dirs[1])
    n /= np.linalg.norm(n)
    ray = np.linalg.solve(M, p.mean(axis=0))  # toward the quad's centre (as _rays gives)
    return n if n @ ray > 0 else -n


def _side_strength(grad: Gradients, quads: NDArray[np.float64], samples: int = 24) -> NDArray[np.float64]:
    """Median gradient across each side of quads (..., 4, 2), best of offsets −1, 0, +1 px."""
    a, b = quads, np.roll(quads, -1, axis=-2)
    length = np.linalg.norm(b - a, axis=-1, keepdims=True)
    n = (b - a)[..., ::-1] * np.array([1.0, -1.0]) / np.maximum(length, 1e-9)  # unit normal
    u = np.linspace(0.1, 0.9, samples)
    pts = a[..., None, :] + u[:, None] * (b - a)[..., None, :]  # (..., 4, S, 2)
    best = None
    # the three offsets' points sampled at once (one call's overhead, not three)
    offsets = np.array([-1.0, 0.0, 1.0]).reshape((3,) + (1,) * pts.ndim)
    q = pts + offsets * n[..., None, :]
    for gx, gy in zip(*grad.sample(q[..., 0], q[..., 1])):
        g = np.abs(gx * n[..., None, 0] + gy * n[..., None, 1])
        best = g if best is None else np.maximum(best, g)
    return np.median(best, axis=-1)


def _rays(Q: NDArray[np.float64], p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The camera centre (3,) and unit world directions (N, 3) of pixels ``p`` (N, 2)."""
    M = Q[:, :3]
    C = -np.linalg.solve(M, Q[:, 3])
    rays = np.linalg.solve(M, np.column_stack([p, np.ones(len(p))]).T).T
    return C, rays / np.linalg.norm(rays, axis=1, keepdims=True)


def _segments(p_L: NDArray[np.float64], Q_L: NDArray[np.float64], Q_R: NDArray[np.float64],
              desk_plane: ArrayLike | None,
              cfg: StereoConfig) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """For each left pixel, the right-image end points of where its 3D point may be."""
    C, rays = _rays(Q_L, p_L)  # left camera centre and world directions
    if desk_plane is not None:
        plane = np.asarray(desk_plane, dtype=np.float64)
        n, d = plane[:3], plane[3]
        denom = rays @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            s_desk = -(n @ C + d) / denom
            s_top = -(n @ C + d - cfg.max_height) / denom
        s_near = np.where(np.isfinite(s_top) & (s_top > 0), s_top, cfg.min_depth)
        s_far = np.where(np.isfinite(s_desk) & (s_desk > 0), s_desk, cfg.max_depth)
        # a little below the desk too: the plane comes from a marker a few metres of error away
        s_far = s_far * 1.02
    else:
        s_near = np.full(len(p_L), cfg.min_depth)
        s_far = np.full(len(p_L), cfg.max_depth)
    return geometry.project(Q_R, C + s_near[:, None] * rays), geometry.project(Q_R, C + s_far[:, None] * rays)



def _point_segment_distance(p: NDArray[np.float64], a: NDArray[np.float64],
                            b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from points ``p`` to segments ``a``–``b`` (broadcast over leading axes).

    Parameters
    ----------
    p, a, b : ndarray, shape (..., D)
        Points and the segments' end points: image points (D = 2, pixels) or world points
        (D = 3, metres: a cover's outline in :mod:`rovis.split`).

    Returns
    -------
    ndarray, shape (...)
        In the points' unit.
    """
    if p.shape[-1] != 2 or a.shape[-1] != 2 or b.shape[-1] != 2:
        ab = b - a
        t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-12),
                    0, 1)
        return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)
    # image points, x and y apart: numpy's reduction over an axis of length 2 costs more
    # than the arithmetic (pool_pairs' half a million pairs); the same sums in the same
    # order, so the same floats as the form above
    px, py, ax, ay = p[..., 0], p[..., 1], a[..., 0], a[..., 1]
    abx, aby = b[..., 0] - ax, b[..., 1] - ay
    t = np.clip(((px - ax) * abx + (py - ay) * aby) / np.maximum(abx * abx + aby * aby, 1e-12),
                0, 1)
    dx, dy = px - (ax + t * abx), py - (ay + t * aby)
    return np.sqrt(dx * dx + dy * dy)


def _cover_ncc(gray_l: NDArray[np.uint8], c_l: NDArray[np.float64], gray_r: NDArray[np.uint8],
               c_r: NDArray[np.float64]) -> float:
    """NCC of the two covers warped to the same small rectangle (corners in matching order)."""
    w, h = _PATCH
    dst = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32)
    patches = []
    for img, c in ((gray_l, c_l), (gray_r, c_r)):
        H = cv2.getPerspectiveTransform(c.astype(np.float32), dst)
        patches.append(cv2.warpPerspective(img, H, (w, h), flags=cv2.INTER_AREA).astype(np.float64))
    a, b = (p[3:-3, 3:-3].ravel() for p in patches)  # the border may catch the desk
    # Two plain covers: what varies in them is sensor noise, whose NCC is ~0 whatever the
    # match (0.0-0.18 for right matches of dark covers at 15-60 lx, a one-off measurement).
    # Plain on both sides is a match if equally bright; plain against textured is not (the
    # NCC then is low).
    if max(a.std(), b.std()) < _PLAIN_STD:
        return 1.0 if abs(a.mean() - b.mean()) <= _PLAIN_MEAN else 0.0
    # A glossy plain cover shows a highlight that moves between the views (NCC 0.03 for
    # build/t1 scene 0020 book 1): plain below its median (a highlight is brighter than
    # the cover, a title band or print may be darker), as bright by the median, it passes
    plain = (max(_spread_below(a), _spread_below(b)) < _PLAIN_STD
             and abs(np.median(a) - np.median(b)) <= _PLAIN_MEAN)
    a, b = a - a.mean(), b - b.mean()
    denom = np.sqrt((a @ a) * (b @ b))
    ncc = float(a @ b / denom) if denom > 1e-6 else 0.0
    return max(ncc, _HIGHLIGHT_NCC) if plain else ncc


def _spread_below(x: NDArray[np.float64]) -> float:
    """The standard deviation of a normal sample whose 10th percentile lies as far below
    its median as ``x``'s does (the spread of its darker part alone)."""
    return float((np.median(x) - np.percentile(x, 10)) / 1.2816)
