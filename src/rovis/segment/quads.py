"""Quadrilateral stage (paper §3.A): book-cover candidates from Hough line intersections.

Every book cover is bounded by two pairs of roughly parallel lines. All pairs of such pairs
are tried at once (vectorised); a candidate survives when its four sides are long enough,
its angles plausible for a rectangle seen in perspective, and edge pixels lie along most of
every side. Among overlapping survivors one is kept; a book's outline (cover plus the page
block seen obliquely) loses to the cover nested in it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from rovis.segment.lines import Lines, SupportProfile, window_hits


# _corner_graph's output: intersections X (N, N, 2), positions T (N, N), corner and
# opposite-side pairs (N, N) each
CornerGraph = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]


@dataclass(frozen=True)
class QuadConfig:
    """What counts as a book cover in the image (pixels, degrees).

    ``min_area_px`` (pixels²) is the smallest cover: 5000, the bound the quad stages
    applied until git 173c5d1 took areas at half their value. As a cover's bound 2500 finds
    a few more of the smallest books, but more printed blocks, title bands and papers
    inside or beside covers win eq. 2 and the stereo pairing; the four-sided candidates
    down to ``SegmentConfig.pool_min_area_px`` go to stereo on their own instead
    (measured: docs/segmentation.md, "The smallest cover").
    """

    min_side_px: float = 30.0
    max_side_px: float = 700.0
    min_area_px: float = 5000.0
    max_area_frac: float = 0.5  # of the ROI area
    parallel_deg: float = 30.0  # opposite sides: at most this far from parallel
    min_corner_deg: float = 40.0  # interior angles within [min, 180 - min]
    min_support: float = 0.7  # fraction of every side covered by edge pixels
    corner_trim_px: float = 3.0  # ignore this much of each side near its corners
    arm_px: float = 12.0  # a corner needs edge support this long on both lines next to it
    arm_gap_px: float = 24.0  # ...starting at most this far from the intersection
    max_overlap: float = 0.15  # of the smaller quad, between two accepted covers
    nested_min_area: float = 0.6  # a cover fills at least this much of its outline
    duplicate_px: float = 3.0  # candidates with all corners this close are one
    outside_frac: float = 0.25  # corners may lie this far outside the image (of its size)
    # ...if the least-seen side's part in view is at least this share of the shortest
    # side (not each side's own: per side, measured, the no-marker test scene of
    # tests/test_stereo_pipeline.py lost a book and no dev-set book changed)
    min_in_view: float = 0.6
    max_candidates: int = 4000  # per edge map, strongest first (bounds the time on busy texture)
    # The candidates with sides unseen (three_sided_quads, two_sided_quads,
    # opposite_sided_quads) down to this area (pixels²) too, if it is under min_area_px:
    # near-duplicates are merged among the cover-sized ones and among the smaller ones
    # apart, so the cover-sized ones are those min_area_px alone gives
    # (SegmentConfig.small_open; None: min_area_px)
    small_area_px: float | None = None


@dataclass(frozen=True, eq=False)
class Quads:
    """Candidate cover quadrilaterals.

    Attributes
    ----------
    lines : ndarray, shape (M, 4), intp
        Indices into the Lines they came from; side s runs from corner s to corner s+1.
    corners : ndarray, shape (M, 4, 2), float64
        Corner pixels, in cyclic order (not yet ordered per eq. 1).
    support : ndarray, shape (M, 4), float64
        Fraction of each side covered by edge pixels.
    n_f : ndarray, shape (M,), float64
        Edge pixels covered by the four sides (eq. 2's N_f(n)).
    min_votes : ndarray, shape (M,), int64
        The weakest side's Hough votes: the quad exists for every T_HG up to this.
    """

    lines: NDArray[np.intp]
    corners: NDArray[np.float64]
    support: NDArray[np.float64]
    n_f: NDArray[np.float64]
    min_votes: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.n_f)

    def take(self, index: NDArray[np.intp] | NDArray[np.bool_]) -> Quads:
        return Quads(self.lines[index], self.corners[index], self.support[index], self.n_f[index],
                     self.min_votes[index])

    @classmethod
    def empty(cls) -> Quads:
        return cls(np.zeros((0, 4), np.intp), np.zeros((0, 4, 2)), np.zeros((0, 4)), np.zeros(0),
                   np.zeros(0, np.int64))

    @classmethod
    def concat(cls, parts: list[Quads]) -> Quads:
        """The quads of ``parts`` in order (their ``lines`` still index each part's Lines)."""
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(q, f) for q in parts]) for f in
                     ("lines", "corners", "support", "n_f", "min_votes")))


def candidate_quads(lines: Lines, profile: SupportProfile, image_shape: tuple[int, int],
                    roi_area: float, cfg: QuadConfig = QuadConfig(), *,
                    graph: CornerGraph | None = None) -> Quads:
    """Cover candidates: 4-cycles of a corner graph over the lines.

    Two crossing lines make a corner when both carry edge pixels next to their
    intersection (an L-junction, :func:`_arm`). A cover is a cycle i–j–k–l of four corners
    whose opposite lines are near-parallel; the cycles are found as pairs of common corner
    neighbours (j, l) of each near-parallel pair (i, k), so the work grows with the corners
    found, not with the fourth power of the number of lines. Survivors must have long
    enough sides, edge pixels along most of every side, plausible angles and area.

    Parameters
    ----------
    lines : Lines
    profile : SupportProfile
        Edge hits along those lines.
    image_shape : (H, W)
    roi_area : float
        Pixels; bounds the largest plausible cover.
    graph : CornerGraph, optional
        :func:`_corner_graph`'s output for these lines, if already computed.
    """
    n = len(lines)
    if n < 4:
        return Quads.empty()
    X, T, corner, par = graph if graph is not None else _corner_graph(lines, profile,
                                                                       image_shape, cfg)
    iu, ku = _nonzero2(np.triu(par, 1))
    common = corner[iu] & corner[ku]  # (pairs, n): lines crossing both with a corner
    p, j, l = _pairs_within_rows(common)  # every two common neighbours j < l of pair p
    keep = par[j, l]
    if not keep.any():
        return Quads.empty()
    # Side s of cycle i–j–k–l runs on line (i, j, k, l)[s], between its intersections with
    # the previous and the next side's lines. The side lengths are checked on the index
    # arrays first: most cycles fail here, before any (cycles, 4) array is built.
    i, j, k, l = iu[p[keep]], j[keep], ku[p[keep]], l[keep]
    flat_T = T.ravel()
    ta4 = [flat_T[a * n + b] for a, b in ((i, l), (j, i), (k, j), (l, k))]  # T[side, prev]
    tb4 = [flat_T[a * n + b] for a, b in ((i, j), (j, k), (k, l), (l, i))]  # T[side, next]
    length4 = [np.abs(b - a) for a, b in zip(ta4, tb4)]
    ok = ((_min4(length4) >= cfg.min_side_px) & (_max4(length4) <= cfg.max_side_px))
    side_lines = np.column_stack([i[ok], j[ok], k[ok], l[ok]])  # side s on line [:, s]
    ta = flat_T[side_lines * n + side_lines[:, [3, 0, 1, 2]]]  # the same values, survivors only
    tb = flat_T[side_lines * n + side_lines[:, [1, 2, 3, 0]]]
    length = np.abs(tb - ta)
    trim = np.minimum(cfg.corner_trim_px, 0.25 * length)
    lo, hi = profile.visible(side_lines.ravel(), (np.minimum(ta, tb) + trim).ravel(),
                             (np.maximum(ta, tb) - trim).ravel())
    lo, hi = lo.reshape(-1, 4), hi.reshape(-1, 4)
    seen = np.maximum(hi - lo, 0.0)  # the part of each side inside the image
    hits = profile.hits(side_lines.ravel(), lo.ravel(), np.maximum(hi, lo).ravel()).reshape(-1, 4)
    support = np.minimum(hits / np.maximum(seen, 1.0), 1.0)  # rounding: a sample over, at most
    ok = (_min4(support.T) >= cfg.min_support) & \
        (_min4(seen.T) >= cfg.min_in_view * _min4(np.maximum(length - 2 * trim, 1.0).T))
    side_lines, hits, support = side_lines[ok], hits[ok], support[ok]
    if len(side_lines) > cfg.max_candidates:  # busy texture: keep the best-supported
        best = np.argsort(-hits.sum(axis=1), kind="stable")[:cfg.max_candidates]
        side_lines, hits, support = side_lines[best], hits[best], support[best]
    s0, s1, s2, s3 = side_lines.T
    corners = np.stack([X[s3, s0], X[s0, s1], X[s1, s2], X[s2, s3]], axis=1)  # corner s starts side s
    area = np.abs(_shoelace(corners))  # pixels²
    keep = ((area >= cfg.min_area_px) & (area <= cfg.max_area_frac * roi_area)
            & _convex_with_angles(corners, cfg.min_corner_deg))
    keep[keep] = ~_twins(side_lines[keep], corners[keep], area[keep], n)
    quads = Quads(side_lines[keep], corners[keep], support[keep], hits[keep].sum(axis=1),
                  lines.votes[side_lines[keep]].min(axis=1))
    return quads


def _twins(side_lines: NDArray[np.intp], corners: NDArray[np.float64],
           area: NDArray[np.float64], n: int) -> NDArray[np.bool_]:
    """Which of :func:`candidate_quads`' cycles are the second of their twin: each cycle
    i–j–k–l (i < k, j < l) comes once from its opposite pair (i, k) and once from (j, l), as
    j–i–l–k, the same corners reversed. The second (from the later pair: the larger first
    line; the same N_f, so after the first in :func:`_distinct`'s order too) is dropped
    where it can only join the first's group there: the
    same area (its sum runs in another order) and a unique smallest x + y corner (the same
    :func:`_canonical` corners); the same sides, edge pixels and votes it has anyway."""
    s0, s1, s2, s3 = side_lines.T
    second = s0 > s1
    key = ((s0 * n + s1) * n + s2) * n + s3
    partner = ((s1 * n + s0) * n + s3) * n + s2  # the twin's key
    first = np.flatnonzero(~second)
    if len(first) == 0:
        return np.zeros(len(key), bool)
    order = first[np.argsort(key[first])]
    # each second's twin among the firsts (where it survived: the keys then match)
    twin = order[np.minimum(np.searchsorted(key[order], partner), len(order) - 1)]
    xy = corners[..., 0] + corners[..., 1]
    unique_min = np.count_nonzero(xy == xy.min(axis=1, keepdims=True), axis=1) == 1
    return second & (key[twin] == partner) & (area[twin] == area) & unique_min


def three_sided_quads(lines: Lines, profile: SupportProfile, image_shape: tuple[int, int],
                      roi_area: float, cfg: QuadConfig = QuadConfig(), *,
                      max_gap_px: float = 8.0, max_run_px: float = 400.0,
                      max_skew_deg: float = 8.0, graph: CornerGraph | None = None) -> Quads:
    """Beyond the paper: cover candidates with three sides on lines and the fourth where
    the other two sides' edges end.

    A cover of the desk's brightness shows almost no step where it meets the desk behind
    it, while its other sides do (the page block, a shadow, the desk in front): no Hough
    line, no 4-cycle. Here a "U" — a base line with a corner (:func:`_arm`) at each end
    and two near-parallel lateral lines — is closed by following each lateral line's edge
    pixels from its corner until a gap of ``max_gap_px``; the line through the two ends is
    the fourth side. The same rules as :func:`candidate_quads` apply to the three seen
    sides (length, ``min_support``) and to the quad (angles, area); its fourth side must
    be within ``max_skew_deg`` of parallel to the base (a cover's far and near sides are,
    in perspective, at this size), which the two ends of a cover's sides are and those
    of unrelated edges mostly not. Too loose for one image to trust: stereo checks them
    (:attr:`rovis.segment.Segmentation.open_pool`). ``graph``: :func:`_corner_graph`'s
    output for these lines, if already computed.

    Returns
    -------
    Quads
        Side 2 is the open one (its ``lines`` entry −1, ``support`` 0); ``n_f`` counts
        the edge pixels of the three seen sides.
    """
    n = len(lines)
    if n < 3:
        return Quads.empty()
    X, T, corner, par = graph if graph is not None else _corner_graph(lines, profile,
                                                                       image_shape, cfg)
    iu, ku = _nonzero2(np.triu(par, 1))
    p, b = _nonzero2(corner[iu] & corner[ku])  # base b crosses laterals a, c with corners
    a, c = iu[p], ku[p]
    flat_T = T.ravel()
    tba, tbc = flat_T[b * n + a], flat_T[b * n + c]  # the corners along the base
    base = np.abs(tbc - tba)
    trim = cfg.corner_trim_px
    ok = (base >= cfg.min_side_px) & (base <= cfg.max_side_px)
    a, b, c, tba, tbc, base = a[ok], b[ok], c[ok], tba[ok], tbc[ok], base[ok]
    base_hits = profile.hits(b, np.minimum(tba, tbc) + trim, np.maximum(tba, tbc) - trim)
    ok = base_hits >= cfg.min_support * np.maximum(base - 2 * trim, 1.0)
    a, b, c, base_hits = a[ok], b[ok], c[ok], base_hits[ok]
    if len(a) == 0:
        return Quads.empty()
    # Both laterals leave the base on the same side of it, either side (σ = ±1): along
    # line a the direction whose image vector points to that side of b.
    nrm, d = lines.normals, lines.directions
    # (which way each lateral leaves the base, once per U: the same for both σ)
    side_a = np.sign(np.sum(d[a] * nrm[b], axis=1))
    side_c = np.sign(np.sum(d[c] * nrm[b], axis=1))
    a, b, c, base_hits, side_a, side_c = (np.concatenate([v, v]) for v in
                                          (a, b, c, base_hits, side_a, side_c))
    sigma = np.repeat([1.0, -1.0], len(a) // 2)
    sa, sc = sigma * side_a, sigma * side_c
    # A lateral's run depends on its line, its corner with the base and its direction
    # only: each such run is followed once, however many U's share it.
    keys = np.concatenate([(a * n + b) * 2 + (sa > 0), (c * n + b) * 2 + (sc > 0)])
    # np.unique(keys, return_inverse=True), from a mark per possible key (2·N² of them)
    # instead of sorting the keys (many more)
    mark = np.zeros(2 * n * n, bool)
    mark[keys] = True
    runs, inverse = np.flatnonzero(mark), (np.cumsum(mark) - 1)[keys]
    line, other, up = runs // 2 // n, runs // 2 % n, np.where(runs % 2 == 1, 1.0, -1.0)
    end, hit = _run_end(profile, line, flat_T[line * n + other], up, trim, max_gap_px,
                        max_run_px)
    end_a, run_a = end[inverse[:len(a)]], hit[inverse[:len(a)]]
    end_c, run_c = end[inverse[len(a):]], hit[inverse[len(a):]]
    ok = ((end_a >= cfg.min_side_px) & (end_c >= cfg.min_side_px)
          & (run_a >= cfg.min_support * np.maximum(end_a - trim, 1.0))
          & (run_c >= cfg.min_support * np.maximum(end_c - trim, 1.0)))
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return Quads.empty()
    a, b, c, sa, sc = a[idx], b[idx], c[idx], sa[idx], sc[idx]
    end_a, end_c, run_a, run_c, base_hits = end_a[idx], end_c[idx], run_a[idx], run_c[idx], base_hits[idx]
    far_a = lines.rho[a, None] * nrm[a] + (flat_T[a * n + b] + sa * end_a)[:, None] * d[a]
    far_c = lines.rho[c, None] * nrm[c] + (flat_T[c * n + b] + sc * end_c)[:, None] * d[c]
    corners = np.stack([X[a, b], X[b, c], far_c, far_a], axis=1)  # sides: b, c, open, a
    far = far_a - far_c
    far_len = np.hypot(far[:, 0], far[:, 1])
    base_dir = X[b, c] - X[a, b]
    cos_far = np.abs(np.sum(far * base_dir, axis=1)) / (
        far_len * np.hypot(base_dir[:, 0], base_dir[:, 1]) + 1e-12)
    h, w = image_shape
    inside = np.all((far_a >= 0) & (far_a < [w, h]), axis=1) & np.all((far_c >= 0) & (far_c < [w, h]), axis=1)
    area = np.abs(_shoelace(corners))  # pixels²
    keep = ((far_len >= cfg.min_side_px) & (far_len <= cfg.max_side_px)
            & (cos_far >= np.cos(np.radians(max_skew_deg))) & inside
            & (area >= _least_area(cfg)) & (area <= cfg.max_area_frac * roi_area)
            & _convex_with_angles(corners, cfg.min_corner_deg))
    if not keep.any():
        return Quads.empty()
    base_len = np.hypot(base_dir[:, 0], base_dir[:, 1])
    support = np.column_stack([base_hits / np.maximum(base_len - 2 * trim, 1.0),
                               run_c / np.maximum(end_c - trim, 1.0), np.zeros(len(a)),
                               run_a / np.maximum(end_a - trim, 1.0)])
    quads = Quads(np.column_stack([b, c, np.full(len(a), -1), a])[keep], corners[keep],
                  np.minimum(support[keep], 1.0), (base_hits + run_a + run_c)[keep],
                  lines.votes[np.column_stack([a, b, c])[keep]].min(axis=1))
    return _distinct_apart(quads, cfg)


def two_sided_quads(lines: Lines, profile: SupportProfile, image_shape: tuple[int, int],
                    roi_area: float, cfg: QuadConfig = QuadConfig(), *,
                    max_gap_px: float = 8.0, max_run_px: float = 400.0,
                    graph: CornerGraph | None = None) -> Quads:
    """Beyond the paper: cover candidates with two adjacent sides on lines and the other
    two where those sides' edges end.

    A cover whose far side and one lateral side meet the desk at its own brightness shows
    only its two other sides (the page block, a shadow): an "L", no U and no 4-cycle. Each
    corner of two lines (:func:`_arm`) is followed along both lines, each way, until a gap
    of ``max_gap_px`` (:func:`_run_end`); the two ends and the corner span a parallelogram,
    the quad. At a book's size the perspective bends its far sides by a few pixels only,
    which the sub-pixel refinement takes up where they show an edge. The same rules as
    :func:`candidate_quads` apply to the two seen sides (length, ``min_support``) and to the
    quad (angles, area, in the image). Looser still than :func:`three_sided_quads`: for
    stereo to check only (:attr:`rovis.segment.Segmentation.open_pool`). ``graph``:
    :func:`_corner_graph`'s output for these lines, if already computed.

    Returns
    -------
    Quads
        Sides 1 and 2 are the open ones (``lines`` −1, ``support`` 0); ``n_f`` counts the
        edge pixels of the two seen sides.
    """
    n = len(lines)
    if n < 2:
        return Quads.empty()
    X, T, corner, _ = graph if graph is not None else _corner_graph(lines, profile,
                                                                     image_shape, cfg)
    a, b = _nonzero2(np.triu(corner, 1))
    if len(a) == 0:
        return Quads.empty()
    trim = cfg.corner_trim_px
    flat_T = T.ravel()
    # each line of each corner followed both ways from the corner
    line = np.concatenate([a, a, b, b])
    other = np.concatenate([b, b, a, a])
    sign = np.repeat([1.0, -1.0, 1.0, -1.0], len(a))
    end, hit = _run_end(profile, line, flat_T[line * n + other], sign, trim, max_gap_px,
                        max_run_px)
    ok = (end >= cfg.min_side_px) & (hit >= cfg.min_support * np.maximum(end - trim, 1.0))
    m = len(a)
    end, hit, ok, sign = (v.reshape(4, m) for v in (end, hit, ok, sign))
    # the four ways of an L: (a forward or back) x (b forward or back)
    ia, ib = np.array([0, 0, 1, 1]), np.array([2, 3, 2, 3])
    k, w = _nonzero2(ok[ia] & ok[ib])  # (way, corner)
    if len(k) == 0:
        return Quads.empty()
    ra, rb = ia[k], ib[k]
    la, lb = a[w], b[w]
    nrm, d = lines.normals, lines.directions
    x = X[la, lb]
    end_a = lines.rho[la, None] * nrm[la] + (flat_T[la * n + lb] + sign[ra, w] * end[ra, w])[:, None] * d[la]
    end_b = lines.rho[lb, None] * nrm[lb] + (flat_T[lb * n + la] + sign[rb, w] * end[rb, w])[:, None] * d[lb]
    corners = np.stack([x, end_a, end_a + end_b - x, end_b], axis=1)  # sides: a, open, open, b
    h, wid = image_shape
    inside = np.all((corners >= 0) & (corners < [wid, h]), axis=(1, 2))
    area = np.abs(_shoelace(corners))  # pixels²
    keep = (inside & (end[ra, w] <= cfg.max_side_px) & (end[rb, w] <= cfg.max_side_px)
            & (area >= _least_area(cfg)) & (area <= cfg.max_area_frac * roi_area)
            & _convex_with_angles(corners, cfg.min_corner_deg))
    if not keep.any():
        return Quads.empty()
    zero = np.zeros(len(k))
    support = np.column_stack([hit[ra, w] / np.maximum(end[ra, w] - trim, 1.0), zero, zero,
                               hit[rb, w] / np.maximum(end[rb, w] - trim, 1.0)])
    open_side = np.full(len(k), -1)
    quads = Quads(np.column_stack([la, open_side, open_side, lb])[keep], corners[keep],
                  np.minimum(support[keep], 1.0), (hit[ra, w] + hit[rb, w])[keep],
                  np.minimum(lines.votes[la], lines.votes[lb])[keep])
    return _distinct_apart(quads, cfg)


def opposite_sided_quads(lines: Lines, profile: SupportProfile, image_shape: tuple[int, int],
                         roi_area: float, cfg: QuadConfig = QuadConfig(), *,
                         max_gap_px: float = 8.0, max_shift: float = 0.15,
                         graph: CornerGraph | None = None) -> Quads:
    """Beyond the paper: cover candidates with two opposite sides on lines and the other
    two joining where those sides' edges end.

    A cover whose two lateral sides meet a background of its own brightness shows only
    its far and near sides. Each line's edge pixels are cut into runs at gaps of
    ``max_gap_px``; two runs on near-parallel lines (:func:`_corner_graph`'s opposite
    sides) whose ends face each other, within ``max_shift`` of the runs' length along the
    lines, are joined end to end. The same rules as :func:`candidate_quads` apply to the
    two seen sides (length, ``min_support``) and to the quad (angles, area, in the image).
    For stereo to check only, like :func:`two_sided_quads` (``graph``: as there).

    Returns
    -------
    Quads
        Sides 1 and 3 are the open ones (``lines`` −1, ``support`` 0); ``n_f`` counts the
        edge pixels of the two seen sides.
    """
    n = len(lines)
    if n < 2:
        return Quads.empty()
    _, _, _, par = graph if graph is not None else _corner_graph(lines, profile,
                                                                  image_shape, cfg)
    pi, pk = _nonzero2(np.triu(par, 1))
    if len(pi) == 0:
        return Quads.empty()
    # each line's runs of edge pixels, all lines at once: a run starts at a hit with none
    # in the g samples before it and ends at one with none in the g after it
    g = max(int(round(max_gap_px)), 1)
    cum = profile.cum  # (N, L + 1): hits before each sample
    hit = cum[:, 1:] > cum[:, :-1]
    behind, ahead = window_hits(cum, -g, 0), window_hits(cum, 1, g + 1)
    r_line, r_lo = _nonzero2(hit & (behind == 0))  # by line, then position: in step
    _, r_end = _nonzero2(hit & (ahead == 0))
    r_hi = r_end + 1
    r_hits = cum[r_line, r_hi] - cum[r_line, r_lo]
    ok = ((r_hi - r_lo) >= cfg.min_side_px) & (r_hits >= cfg.min_support * (r_hi - r_lo))
    r_line, r_lo, r_hi, r_hits = r_line[ok], r_lo[ok], r_hi[ok], r_hits[ok]
    if len(r_line) == 0:
        return Quads.empty()
    r_line_a = r_line.astype(np.intp)
    count = np.bincount(r_line_a, minlength=n)
    first = np.cumsum(count) - count
    combos = count[pi] * count[pk]
    pair = np.repeat(np.arange(len(pi)), combos)
    if len(pair) == 0:
        return Quads.empty()
    m = np.arange(len(pair)) - np.repeat(np.cumsum(combos) - combos, combos)
    ra = first[pi[pair]] + m // count[pk[pair]]
    rb = first[pk[pair]] + m % count[pk[pair]]
    lo_s, hi_s = np.asarray(r_lo, np.float64), np.asarray(r_hi, np.float64)
    nrm, d = lines.normals, lines.directions
    # each run's end points and their positions along its line, once per run (a run is in
    # many pairs); then per pair only what the test below needs, the points for those kept
    foot, along = lines.rho[r_line_a, None] * nrm[r_line_a], d[r_line_a]
    e0 = foot + (profile.t0[r_line_a] + lo_s)[:, None] * along
    e1 = foot + (profile.t0[r_line_a] + hi_s)[:, None] * along
    t_e0, t_e1 = np.sum(e0 * along, axis=1), np.sum(e1 * along, axis=1)
    la, lb = r_line_a[ra], r_line_a[rb]
    t_a0, t_a1 = t_e0[ra], t_e1[ra]
    # line b's ends along line a: its direction may run either way (np.sum over x and y
    # written out: the same values)
    dx, dy = d[la, 0], d[la, 1]
    s0, s1 = e0[rb, 0] * dx + e0[rb, 1] * dy, e1[rb, 0] * dx + e1[rb, 1] * dy
    flip = s0 > s1
    s0, s1 = np.minimum(s0, s1), np.maximum(s0, s1)
    length = 0.5 * ((t_a1 - t_a0) + (s1 - s0))
    ok = (np.abs(s0 - t_a0) <= max_shift * length) & (np.abs(s1 - t_a1) <= max_shift * length)
    if not ok.any():
        return Quads.empty()
    ra, rb, la, lb, flip = ra[ok], rb[ok], la[ok], lb[ok], flip[ok, None]
    b0, b1 = np.where(flip, e1[rb], e0[rb]), np.where(flip, e0[rb], e1[rb])
    corners = np.stack([e0[ra], e1[ra], b1, b0], axis=1)  # sides: a, open, b, open
    lat = np.hypot(*(corners[:, 2] - corners[:, 1]).T), np.hypot(*(corners[:, 0] - corners[:, 3]).T)
    h, w = image_shape
    inside = np.all((corners >= 0) & (corners < [w, h]), axis=(1, 2))
    area = np.abs(_shoelace(corners))  # pixels²
    side_a, side_b = (t_a1 - t_a0)[ok], (s1 - s0)[ok]
    keep = (inside & (np.minimum(lat[0], lat[1]) >= cfg.min_side_px)
            & (np.maximum(lat[0], lat[1]) <= cfg.max_side_px)
            & (np.maximum(side_a, side_b) <= cfg.max_side_px)
            & (area >= _least_area(cfg)) & (area <= cfg.max_area_frac * roi_area)
            & _convex_with_angles(corners, cfg.min_corner_deg))
    if not keep.any():
        return Quads.empty()
    hits_a = np.asarray(r_hits, np.float64)[ra]
    hits_b = np.asarray(r_hits, np.float64)[rb]
    zero = np.zeros(len(hits_a))
    support = np.column_stack([hits_a / np.maximum(side_a, 1.0), zero,
                               hits_b / np.maximum(side_b, 1.0), zero])
    open_side = np.full(len(hits_a), -1)
    quads = Quads(np.column_stack([la, open_side, lb, open_side])[keep], corners[keep],
                  np.minimum(support[keep], 1.0), (hits_a + hits_b)[keep],
                  np.minimum(lines.votes[la], lines.votes[lb])[keep])
    return _distinct_apart(quads, cfg)


def _run_end(profile: SupportProfile, line: NDArray[np.intp], t0: NDArray[np.float64],
             sign: NDArray[np.float64], start: float, max_gap: float, most: float,
             ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """How far (px) the edge pixels on ``line`` run from position ``t0`` in direction
    ``sign`` (±1), from ``start`` on, before a gap of ``max_gap`` px (at most ``most``
    px); and the hits on the way (vectorised over the lines).

    Where gaps start (end) is found once per profile, for every sample of every line
    (:meth:`SupportProfile.gaps`); a run's nearest gap ahead of (behind) its first sample is
    a binary search among them (a running minimum over every sample took twice as long). The
    end is the gap's first sample, one past the last hit (a hit is an edge pixel within
    1 px): that makes up for Canny's rounding of a corner, whose edge stops short of it
    (on the drawn cover of tests/test_three_sided.py the far corners come out within 2 px;
    one or two pixels shorter, within 3 and 4).
    """
    cum = profile.cum  # (N, L + 1): hits before each sample
    n_samples = cum.shape[1] - 1
    starts, ends = profile.gaps(max(int(round(max_gap)), 1))
    k0 = np.rint(t0 - profile.t0[line]).astype(np.intp)  # the corner's sample
    up = sign > 0
    first = np.clip(np.where(up, k0 + int(start), k0 - int(start)), 0, n_samples - 1)
    row = line * n_samples
    fwd = starts[np.searchsorted(starts, row + first)] - row  # first gap at or after
    bwd = ends[np.searchsorted(ends, row + first, side="right") - 1] - row  # last at or before
    # (none on the line: past its last sample, before its first)
    stop = np.where(up, np.minimum(fwd, n_samples), np.maximum(bwd, -1))
    end = np.minimum(np.abs(stop - k0), most).astype(np.float64)
    stop = np.where(up, k0 + end.astype(np.intp), k0 - end.astype(np.intp))
    lo = np.clip(np.where(up, first, stop + 1), 0, n_samples)
    hi = np.clip(np.where(up, stop, first + 1), 0, n_samples)
    hits = np.maximum(cum[line, hi] - cum[line, lo], 0).astype(np.float64)
    inside = (k0 >= 0) & (k0 < n_samples)
    return np.where(inside, end, 0.0), np.where(inside, hits, 0.0)


def _corner_graph(lines: Lines, profile: SupportProfile, image_shape: tuple[int, int],
                  cfg: QuadConfig) -> CornerGraph:
    """The lines' intersections X (N, N, 2) and positions T (N, N) along each line, which
    pairs of lines make a corner (N, N: an L-junction, :func:`_arm`), and which pairs could
    be a cover's opposite sides (N, N: near-parallel, a plausible side length apart)."""
    th = lines.theta
    dth = np.abs(th[:, None] - th[None, :])
    dth = np.minimum(dth, np.pi - dth)
    X, T = _intersections(lines)
    h, w = image_shape
    # A corner may lie outside the image (a book cut by the frame): its lines still place it.
    m = cfg.outside_frac * max(h, w)
    inside = ((X[..., 0] > -m) & (X[..., 0] < w + m) & (X[..., 1] > -m) & (X[..., 1] < h + m))
    corner = (dth > np.radians(cfg.min_corner_deg)) & inside & inside.T
    ci, cj = _nonzero2(np.triu(corner, 1))
    # both lines' arms in one call (each test is its own: the same values, half the calls)
    both = _arm(profile, np.concatenate([ci, cj]), np.concatenate([T[ci, cj], T[cj, ci]]), cfg)
    ok = both[:len(ci)] & both[len(ci):]
    corner[:] = False
    corner[ci[ok], cj[ok]] = corner[cj[ok], ci[ok]] = True
    sep = np.abs(lines.rho[:, None] - lines.rho[None, :])
    sep = np.where(np.abs(th[:, None] - th[None, :]) > np.pi / 2,  # θ wrapped: ρ flips sign
                   np.abs(lines.rho[:, None] + lines.rho[None, :]), sep)
    par = (dth < np.radians(cfg.parallel_deg)) & (sep >= cfg.min_side_px * 0.5) & (sep <= cfg.max_side_px)
    return X, T, corner, par


def _pairs_within_rows(m: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """All ``(row, j, l)`` with ``j < l`` and ``m[row, j]``, ``m[row, l]`` both set (vectorised
    over the rows: the k set entries of a row give k(k-1)/2 triples)."""
    row, col = _nonzero2(m)  # sorted by row, then column
    count = np.bincount(row, minlength=m.shape[0])
    start = np.cumsum(count) - count
    after = count[row] - (np.arange(len(row)) - start[row]) - 1  # entries later in its row
    first = np.repeat(np.arange(len(row)), after)
    # the k-th partner of entry e is entry e + 1 + k
    second = first + 1 + np.arange(len(first)) - np.repeat(np.cumsum(after) - after, after)
    return row[first], col[first], col[second]


def _nonzero2(m: NDArray[np.generic]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """``np.nonzero`` of a 2-D array, the same indices in the same order (by row, then
    column), from the flat ones: on the sparse masks here several times faster."""
    return np.divmod(np.flatnonzero(m), m.shape[1])


def _min4(c: NDArray[np.float64] | list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Elementwise minimum of four arrays ``c[0..3]`` (a reduction along a short axis of
    length 4 costs several times more in NumPy)."""
    return np.minimum(np.minimum(c[0], c[1]), np.minimum(c[2], c[3]))


def _max4(c: NDArray[np.float64] | list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Elementwise maximum of four arrays ``c[0..3]``."""
    return np.maximum(np.maximum(c[0], c[1]), np.maximum(c[2], c[3]))


def _arm(profile: SupportProfile, line: NDArray[np.intp], t: NDArray[np.float64],
         cfg: QuadConfig) -> NDArray[np.bool_]:
    """Whether ``line`` carries edge pixels along ``arm_px`` on either side of position ``t``
    (or of where the line enters the image, for a corner outside it), starting at most
    ``arm_gap_px`` away (a book's outline reaches its corner a page-block strip later)."""
    if profile.t_in is not None:
        # A corner outside the image (a book cut by the frame) shows its arms from where
        # its lines enter the image; the sides' in-view share is checked later.
        t = np.clip(t, profile.t_in[line, 0], profile.t_in[line, 1])
    need = cfg.min_support * cfg.arm_px
    gaps = (cfg.corner_trim_px, 0.5 * cfg.arm_gap_px, cfg.arm_gap_px)
    # The six windows (after and before, at three gaps) in one vectorised look-up.
    ta = np.concatenate([t + g for g in gaps] + [t - g - cfg.arm_px for g in gaps])
    tb = np.concatenate([t + g + cfg.arm_px for g in gaps] + [t - g for g in gaps])
    hits = profile.hits(np.tile(line, 2 * len(gaps)), ta, tb).reshape(2 * len(gaps), len(line))
    return np.any(hits >= need, axis=0)


def _intersections(lines: Lines) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pairwise intersections X (N, N, 2) and positions T[i, j] of X[i, j] along line i."""
    nrm, d = lines.normals, lines.directions
    a1, b1, r1 = nrm[:, None, 0], nrm[:, None, 1], lines.rho[:, None]
    a2, b2, r2 = nrm[None, :, 0], nrm[None, :, 1], lines.rho[None, :]
    det = a1 * b2 - a2 * b1
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (r1 * b2 - r2 * b1) / det
        y = (a1 * r2 - a2 * r1) / det
    X = np.stack([x, y], axis=-1)
    X[~np.isfinite(X)] = 1e9  # parallel: far outside every image
    T = X[..., 0] * d[:, None, 0] + X[..., 1] * d[:, None, 1]
    return X, T


def _shoelace(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Signed area of quads (M, 4, 2); positive when clockwise on screen (y down)."""
    x, y = c[..., 0], c[..., 1]
    nxt = [1, 2, 3, 0]  # the next corner: np.roll's values, without its per-call overhead
    return 0.5 * np.sum(x * y[..., nxt] - x[..., nxt] * y, axis=-1)


def _convex_with_angles(c: NDArray[np.float64], min_deg: float) -> NDArray[np.bool_]:
    """Which quads (M, 4, 2) are convex with every interior angle in [min_deg, 180 -
    min_deg] degrees."""
    # corner by corner, (4, M) rows: reductions over the four corners along the first axis
    # and each side's edge vector and length once (the edge leaving corner s arrives at
    # s + 1), the same values as per corner from its arriving and leaving edges
    x, y = np.ascontiguousarray(c.transpose(2, 1, 0))  # (x or y, corner, quad)
    nxt, prv = [1, 2, 3, 0], [3, 0, 1, 2]
    ox, oy = x[nxt] - x, y[nxt] - y  # edge leaving each corner (side s)
    ix, iy = ox[prv], oy[prv]  # ...and arriving: the previous side
    z = ix * oy - iy * ox
    convex = np.all(z > 0, axis=0) | np.all(z < 0, axis=0)
    # the dot product and norms written out over x, y: what np.sum / np.linalg.norm
    # compute along the last axis, without their per-call and short-axis overhead
    length = np.sqrt(ox * ox + oy * oy)
    cosang = -(ix * ox + iy * oy) / (length[prv] * length + 1e-12)
    ang = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
    return convex & np.all((ang >= min_deg) & (ang <= 180 - min_deg), axis=0)


class CoverSelection:
    """Choosing one quad per book, prepared once per edge map for every T_HG.

    Near-identical candidates are merged (a group exists up to its strongest member's
    T_HG); an outline (cover plus the page-block sides of a book seen obliquely) that
    contains a cover sharing two or three of its lines gives way to that cover; of
    overlapping survivors the one with the most edge pixels (N_f) is kept. The geometry is
    computed here once; :meth:`at` only applies a threshold.
    """

    def __init__(self, quads: Quads, cfg: QuadConfig = QuadConfig()) -> None:
        quads, group_votes = _distinct(quads, cfg.duplicate_px)
        self.quads, self.votes, self.cfg = quads, group_votes, cfg
        areas = np.abs(_shoelace(quads.corners))
        lo, hi = quads.corners.min(axis=1), quads.corners.max(axis=1)
        # boxes overlapping in x and in y (per coordinate: np.all along an axis of two
        # costs more than the comparisons)
        (x0, y0), (x1, y1) = lo.T, hi.T
        self.near = ((x0[:, None] <= x1[None, :]) & (x0[None, :] <= x1[:, None])
                     & (y0[:, None] <= y1[None, :]) & (y0[None, :] <= y1[:, None]))
        # (small, big) pairs that may be cover and outline; the exact test only for those.
        maybe = (self.near & (areas[:, None] < areas[None, :])
                 & (areas[:, None] >= cfg.nested_min_area * areas[None, :]))
        small, big = _nonzero2(maybe)
        # sharing two or three lines: counted for these pairs only (all pairs: 16 (K, K)
        # comparisons, the most time here)
        L = quads.lines
        shared = (L[small][:, :, None] == L[big][:, None, :]).sum(axis=(1, 2)) >= 2
        small, big = small[shared], big[shared]
        nested = _inside_convex(quads.corners[small], _canonical(quads.corners)[big], ordered=True)
        # An outline gives way while any cover nested in it exists, i.e. up to the highest
        # T_HG among its covers (the lowest integer: it contains none).
        self.cover_votes = np.full(len(quads), np.iinfo(np.int64).min, np.int64)
        np.maximum.at(self.cover_votes, big[nested], group_votes[small[nested]])
        self.order = np.argsort(-quads.n_f, kind="stable")
        self._conflict: dict[tuple[int, int], bool] = {}

    def _conflicts(self, a: int, b: int) -> bool:
        if not self.near[a, b]:
            return False
        key = (min(a, b), max(a, b))
        if key not in self._conflict:
            self._conflict[key] = quad_overlap(self.quads.corners[a], self.quads.corners[b]) > self.cfg.max_overlap
        return self._conflict[key]

    def at(self, T_HG: int) -> Quads:
        """The selected covers among the candidates that exist at ``T_HG``."""
        return self.quads.take(np.asarray(self._kept(T_HG), dtype=np.intp))

    def losers(self, T_HG: int, most: int = 4) -> list[NDArray[np.float64]]:
        """Per cover selected at ``T_HG`` (in :meth:`at`'s order), the candidates that
        exist there and gave way to it (an overlap, or a cover nested in an outline),
        the most edge pixels first, at most ``most``: shape (M, 4, 2) each."""
        exists = self.votes >= T_HG
        out = []
        for p in self._kept(T_HG):
            near = np.flatnonzero(self.near[:, p] & exists)
            near = near[np.argsort(-self.quads.n_f[near], kind="stable")]
            lost: list[int] = []
            for q in near.tolist():
                if len(lost) == most:
                    break
                if q != p and self._conflicts(q, p):
                    lost.append(q)
            out.append(self.quads.corners[np.asarray(lost, dtype=np.intp)].reshape(-1, 4, 2))
        return out

    def _kept(self, T_HG: int) -> list[int]:
        exists = self.votes >= T_HG
        free = exists & ~(self.cover_votes >= T_HG)  # exists, and no cover nested in it does
        kept: list[int] = []
        for q in self.order[free[self.order]].tolist():
            if not any(self._conflicts(q, p) for p in kept):
                kept.append(q)
        return kept


def _least_area(cfg: QuadConfig) -> float:
    """The smallest candidate with sides unseen (pixels²): ``cfg.small_area_px`` if set and
    under ``cfg.min_area_px``, else that."""
    if cfg.small_area_px is None:
        return cfg.min_area_px
    return min(cfg.small_area_px, cfg.min_area_px)


def cover_sized(quads: Quads, cfg: QuadConfig) -> NDArray[np.bool_]:
    """Per candidate, whether it has a cover's area (``cfg.min_area_px`` or more, pixels²)."""
    return np.abs(_shoelace(quads.corners)) >= cfg.min_area_px


def _distinct_apart(quads: Quads, cfg: QuadConfig) -> Quads:
    """:func:`_distinct` among the candidates of a cover's area (``cfg.min_area_px`` or
    more) and among the smaller ones apart (the cover-sized first): a smaller near-copy
    does not take the place of a cover-sized candidate."""
    if _least_area(cfg) >= cfg.min_area_px:
        return _distinct(quads, cfg.duplicate_px)[0]
    big = cover_sized(quads, cfg)
    return Quads.concat([_distinct(quads.take(big), cfg.duplicate_px)[0],
                         _distinct(quads.take(~big), cfg.duplicate_px)[0]])


def _distinct(quads: Quads, tol_px: float) -> tuple[Quads, NDArray[np.int64]]:
    """Greedy by N_f: a candidate whose four corners all lie within ``tol_px`` of a stronger
    kept one's joins that one's group (the same cover from neighbouring lines). Each kept
    candidate claims its reach at once from a k-d tree on the eight corner coordinates
    (Chebyshev metric), so the work grows with the kept candidates, not with the pairs of
    duplicates. Returns the kept quads and, per kept quad, the highest T_HG at which any
    member of its group exists."""
    if len(quads) == 0:
        return quads, np.zeros(0, np.int64)
    order = np.argsort(-quads.n_f, kind="stable")
    flat = _canonical(quads.corners[order]).reshape(len(order), 8)
    # Candidates share corners (they are cycles of the same lines), which an 8-D tree with
    # small leaves prunes poorly: big leaves measured fastest (identical results).
    tree = cKDTree(flat, leafsize=256)
    # The kept candidate each one joins, as a Python list: the tree answers in lists, and a
    # claim per entry costs less than NumPy's per-call overhead on a few indices (a kept
    # candidate has 2 within reach at the median, itself included; measured: this loop
    # and NumPy's search for the next unclaimed one took a third more time).
    joins = [-1] * len(order)
    for a in range(len(order)):
        if joins[a] >= 0:
            continue  # claimed by a stronger kept one
        joins[a] = a  # no stronger kept candidate within reach: keep it, and let it claim
        for b in tree.query_ball_point(flat[a], tol_px, p=np.inf):
            if joins[b] < 0:  # ...the unclaimed within its reach (all weaker)
                joins[b] = a
    group = np.asarray(joins, dtype=np.intp)
    kept = np.nonzero(group == np.arange(len(order)))[0]
    votes = np.zeros(len(order), np.int64)
    np.maximum.at(votes, group, quads.min_votes[order])
    return quads.take(order[kept]), votes[kept]


def _canonical(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quads (M, 4, 2) reordered clockwise on screen, smallest x + y first (eq. 1 order)."""
    c = np.where((_shoelace(c) < 0)[:, None, None], c[:, ::-1], c)
    start = np.argmin(c[..., 0] + c[..., 1], axis=1)  # x + y: what c.sum(axis=2) adds
    # the four rotations as one flat gather (np.take_along_axis: the same values, slower)
    idx = (start[:, None] + np.arange(4)) % 4 + 4 * np.arange(len(c))[:, None]
    return c.reshape(-1, 2)[idx]


def canonical_quads(quads: Quads) -> Quads:
    """``quads`` with their corners in :func:`_canonical` order and each side's line and
    support moved with it (side s still runs from corner s to corner s + 1)."""
    if len(quads) == 0:
        return quads
    c = quads.corners
    rev = _shoelace(c) < 0
    c = np.where(rev[:, None, None], c[:, ::-1], c)
    start = np.argmin(c[..., 0] + c[..., 1], axis=1)
    k = (start[:, None] + np.arange(4)) % 4  # canonical corner i = (reversed) corner k
    rows = np.arange(len(c))[:, None]
    # a reversed quad's side from its corners k to k + 1 is the original's side 2 - k
    side = np.where(rev[:, None], (2 - k) % 4, k)
    return Quads(quads.lines[rows, side], c[rows, k], quads.support[rows, side], quads.n_f,
                 quads.min_votes)


def _inside_convex(inner: NDArray[np.float64], outer: NDArray[np.float64],
                   tol: float = 2.0, *, ordered: bool = False) -> NDArray[np.bool_]:
    """For quad pairs (M, 4, 2): are all of ``inner``'s corners inside convex ``outer``
    (within ``tol`` px)? Vectorised over the pairs. ``ordered``: ``outer`` is already in
    :func:`_canonical` order (a caller with many pairs per quad orders each quad once)."""
    if len(inner) == 0:
        return np.zeros(0, bool)
    o = outer if ordered else _canonical(outer)  # clockwise on screen: inside is to the right of every edge
    edge = np.roll(o, -1, axis=1) - o  # (M, 4, 2)
    rel = inner[:, None, :, :] - o[:, :, None, :]  # (M, 4 edges, 4 points, 2)
    cross = edge[:, :, None, 0] * rel[..., 1] - edge[:, :, None, 1] * rel[..., 0]
    return np.all(cross >= -tol * np.linalg.norm(edge, axis=2)[:, :, None], axis=(1, 2))


def quad_overlap(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Intersection area of two convex quads (4, 2) over the smaller one's area."""
    inter, _ = cv2.intersectConvexConvex(a.astype(np.float32), b.astype(np.float32))
    smaller = min(cv2.contourArea(a.astype(np.float32)), cv2.contourArea(b.astype(np.float32)))
    return float(inter) / smaller if smaller > 0 else 1.0


def order_corners(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Eq. 1's order: top-left corner first (smallest x + y), then clockwise on screen.

    Parameters
    ----------
    corners : ndarray, shape (4, 2) — pixels, any cyclic order

    Returns
    -------
    ndarray, shape (4, 2)
    """
    return _canonical(np.asarray(corners, dtype=np.float64)[None])[0]
