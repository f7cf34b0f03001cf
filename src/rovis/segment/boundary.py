"""Boundary segmentation of one image (paper Fig. 2, left column).

``evaluate`` runs one T_H of the chain — Canny → Hough with votes → cover quadrilaterals —
and finds the best T_HG for it (the controller's inner loop, exactly and cheaply: see
:func:`evaluate`). ``finish`` refines the chosen covers' sides to sub-pixel accuracy and
orders their corners (eq. 1).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from rovis.segment.edges import Gradients, canny
from rovis.segment.lines import (Lines, SupportProfile, hough_lines, intersect, refine_lines,
                                 refine_segment, support_profile)
from rovis.segment.quads import (CoverSelection, CornerGraph, QuadConfig, Quads, _canonical,
                                 _corner_graph, canonical_quads, cover_sized,
                                 _distinct, candidate_quads, opposite_sided_quads, order_corners,
                                 three_sided_quads, two_sided_quads)
from rovis.segment.quality import PRINTED, quality


@dataclass(frozen=True)
class SegmentConfig:
    """Tuning of the boundary segmentation and its controller.

    Attributes
    ----------
    n_max : int
        N_max of eq. 2: the most Hough lines allowed in the ROI.
    T_H_range : (float, float)
        Canny high threshold search range, on the L2 Sobel magnitude (0–1442 for 8 bit).
    T_HG_min : int
        Lowest Hough accumulator threshold tried (votes = edge pixels on a line).
    quality_sign : {-1, +1}
        Exponent sign of eq. 2 (see :mod:`rovis.segment.quality`).
    open_T_H, open_T_HG : float, int
        The open loop's fixed thresholds, tuned once at 500 lx (scripts/tune_open_loop.py).
    max_inner : int
        Most T_HG values the inner loop evaluates per T_H.
    max_edge_frac : float
        An edge map denser than this (of the ROI) is noise: its Hough lines would exceed
        N_max anyway, so y = 0 without running Hough (saves the most expensive evaluations).
    coarse_steps, refine_steps : int
        Outer-loop search: a log-spaced grid, then halving steps around the best.
    warm_start : bool
        In a sequence, start each image's search from the previous image's optimum and
        climb locally (the paper's design; faster). Off: a full search every image, which
        evaluates more T_H and may keep more covers (measured: docs/segmentation.md).
    warm_step : float
        Multiplicative T_H step of a warm-started (sequence) search.
    union : bool
        Beyond the paper: also keep the covers found at the other T_H the search evaluated
        that overlap none found at the optimum (a faint book's edges may need a lower T_H
        than the image's optimum, a busy one's a higher).
    lsd : bool
        Beyond the paper, off by default: also keep the covers OpenCV's line segment
        detector finds (the ``lsd`` method's) where the closed loop found none, and offer
        those over its covers as alternatives (with ``union`` only, which does that for
        the other T_H's covers). A few more books, for one LSD pass per image (measured:
        docs/segmentation.md).
    pool_size : int
        Most candidate quads kept per evaluation and per image for stereo to choose from
        (:attr:`Segmentation.pool`), the most edge pixels first.
    pool_min_area_px : float
        Beyond the paper: the candidates with all four sides seen of this area (pixels²)
        up to ``quads.min_area_px`` are offered to stereo on their own
        (:attr:`Segmentation.small_pool`), never covers of one image: a small book at the
        far side of the workspace, among more printed blocks and papers (measured:
        docs/segmentation.md, "The smallest cover"). At ``quads.min_area_px`` or above: none.
    small_open : bool
        Beyond the paper: with ``three_sided`` (and ``two_sided``), the candidates with sides
        unseen of ``pool_min_area_px`` up to ``quads.min_area_px`` join
        :attr:`Segmentation.small_pool` too: a small plain book at the far side of the
        workspace shows its near sides (the page block's) and little of the far ones
        (measured: docs/segmentation.md, "Small candidates with sides unseen").
    refine_gamma : float
        Beyond the paper, off by default (1: refine on the image as it is): the camera's
        gamma, undone for the sub-pixel refinement of the covers' sides
        (:func:`rovis.segment.edges.linear_gradients`; 2.2 for an sRGB-like 8-bit camera,
        as the synthetic scenes). Closer corners in 2D, but in dim scenes the linear image's
        weak darks lose books (measured: docs/segmentation.md).
    pool_lines, pool_min_support : int, float
        Beyond the paper, off by default (``pool_lines`` = ``n_max``): where
        ``pool_lines`` is above ``n_max``, the closed loop also forms candidates from this
        many Hough lines at its optimum's T_H, with this edge support per side
        (``quads.min_support`` for the covers), for the pool only (eq. 2 and the covers
        still use ``n_max``; measured in docs/stereo.md, "The height map").
    refine_lines : bool
        Beyond the paper: each Hough line fitted to its edge pixels before quads are formed
        (:func:`rovis.segment.lines.refine_lines`; Hough's 1° cells leave a long side's
        line a pixel or more off its edge at one end).
    three_sided, three_sided_evaluations : bool, int
        Beyond the paper: at the T_H whose covers were kept and at the
        ``three_sided_evaluations`` of highest y (at every evaluated T_H where none gave a
        cover), also offer stereo the candidates with one side unseen (:func:`rovis.segment.quads.three_sided_quads`;
        :attr:`Segmentation.open_pool`). A cover of the desk's brightness shows almost no
        step where it meets the desk behind it (measured: docs/stereo.md).
    three_sided_support : float
        Beyond the paper: a three-sided candidate whose seen sides are all this much
        covered by edge pixels, overlapping no cover, is kept as a cover of the image too
        (:func:`rovis.segment.control.with_three_sided_covers`; above 1: never).
    two_sided : bool
        Beyond the paper: at the same evaluations, also offer stereo the candidates with
        two adjacent sides seen and two unseen (:func:`rovis.segment.quads.two_sided_quads`),
        never kept as covers of one image (measured: docs/stereo.md, "Two-sided covers").
    two_sided_size : int
        Most two-sided candidates kept per image, the most edge pixels first.
    opposite_sided : bool
        With ``two_sided``: also the candidates with two opposite sides seen, joined where
        their edges end (:func:`rovis.segment.quads.opposite_sided_quads`).
    late_open : bool
        Beyond the paper: with ``three_sided``, the candidates with sides unseen at every
        other T_H with a cover (y > 0) the closed loop evaluated too, for stereo to pair
        after the height maps, before the one-image search (:attr:`Segmentation.late_pool`).
        A faint cover shows its sides at a low T_H whose y ranks low: the desk's texture
        outvotes its short sides there.
    """

    n_max: int = 100
    T_H_range: tuple[float, float] = (12.0, 480.0)
    T_HG_min: int = 30
    quality_sign: int = PRINTED  # measured: see docs/segmentation.md
    open_T_H: float = 100.0  # scripts/tune_open_loop.py, 500 lx
    open_T_HG: int = 30
    coarse_steps: int = 5
    refine_steps: int = 2
    warm_start: bool = True
    warm_step: float = 1.25
    max_inner: int = 12
    max_edge_frac: float = 0.08
    union: bool = True
    lsd: bool = False
    pool_size: int = 400
    refine_gamma: float = 1.0
    pool_lines: int = 100
    pool_min_support: float = 0.7
    refine_lines: bool = True
    pool_min_area_px: float = 2500.0
    small_open: bool = True
    three_sided: bool = True
    three_sided_evaluations: int = 3
    three_sided_support: float = 0.95
    two_sided: bool = True
    two_sided_size: int = 400
    opposite_sided: bool = True
    late_open: bool = True
    quads: QuadConfig = field(default_factory=QuadConfig)


@dataclass(frozen=True, eq=False)
class Evaluation:
    """One T_H of the outer loop with its best T_HG."""

    T_H: float
    T_HG: int
    y: float
    lines: Lines  # the lines above T_HG, strongest first
    covers: Quads  # the selected cover candidates at T_HG
    inner_iterations: int
    selection: CoverSelection | None = None  # for the candidates the covers won over
    # every line above T_HG_min (at most N_max) and their edge hits, which the candidates
    # were formed from: for the three-sided candidates (open_candidates)
    all_lines: Lines | None = None
    profile: SupportProfile | None = None
    # candidates under QuadConfig.min_area_px (down to SegmentConfig.pool_min_area_px):
    # never covers of this image, for stereo's pool only
    small: Quads | None = None
    # all_lines' corner graph (rovis.segment.quads._corner_graph, under the SegmentConfig
    # evaluated with): the candidates with sides unseen from the same lines reuse it
    graph: CornerGraph | None = None


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Book covers found in one image.

    Attributes
    ----------
    corners : ndarray, shape (K, 4, 2), float64
        Sub-pixel cover corners, eq. 1 order (top-left first, clockwise on screen), in the
        pixel frame of the image that was segmented.
    coarse : ndarray, shape (K, 4, 2)
        The same corners from Hough line intersections alone (before refinement).
    support : ndarray, shape (K,)
        Mean fraction of each cover's sides covered by edge pixels (its seen sides, for a
        three-sided cover).
    lines : Lines
        The Hough lines above T_HG (for overlays).
    T_H, T_HG, y : the thresholds used and the quality they reached (eq. 2)
    iterations : int
        Evaluations of the chain (outer × inner loop steps; 1 for the open loop).
    alternatives : tuple of ndarray, shape (M_k, 4, 2) each, or ()
        Per cover, the other quads the closed loop found over it: other T_H's covers and
        the candidates it won over at its T_HG (Hough corners, not refined; closed loop
        with ``SegmentConfig.union`` only). Where the chosen one is no cover in 3D (an
        outline with its page block, a union of two books), stereo may try these (beyond
        the paper).
    pool : Quads
        Beyond the paper: every distinct candidate quad the chain formed (at the optimum
        and, in the closed loop, at the other T_H it evaluated), corners in eq. 1 order
        (Hough corners, not refined), the most edge pixels first; stereo picks books among
        them where no cover gave one (:func:`rovis.stereo.pool_pairs`). Its per-side
        ``lines`` and ``support`` follow the corners (side s from corner s to s + 1), and
        ``lines`` index the Lines of the evaluation it came from. Empty for methods
        without candidates.
    open_pool : Quads
        Beyond the paper: candidates with three sides on Hough lines and the fourth where
        the edges of the two beside it end (:func:`three_sided_quads`; with
        ``SegmentConfig.three_sided``), corners in eq. 1 order, the most edge pixels
        first, for stereo like :attr:`pool`; ``lines`` and ``support`` follow the corners
        as in :attr:`pool`, an unseen side's ``lines`` −1 and ``support`` 0. With
        ``SegmentConfig.two_sided``, followed by the candidates with two sides unseen
        (:func:`two_sided_quads`, :func:`opposite_sided_quads`).
    late_pool : Quads
        Beyond the paper: as :attr:`open_pool`, from the closed loop's other evaluations
        (``SegmentConfig.late_open``), less those near :attr:`pool` or :attr:`open_pool`;
        stereo pairs them after the height maps, and the one-image search looks for them
        in the other image after the others (``StereoConfig.pool_transfer_late``).
    small_pool : Quads
        Beyond the paper: the four-sided candidates of every evaluation smaller than a
        cover (``SegmentConfig.pool_min_area_px`` to ``QuadConfig.min_area_px``), the most
        edge pixels first, corners in eq. 1 order; stereo pairs them in a pass of their own
        after the other pools (``StereoConfig.small_max_pairs`` pairs at most). With
        ``SegmentConfig.small_open``, followed by the candidates with sides unseen of that
        size (``lines`` −1 there) from the evaluations :attr:`open_pool` and
        :attr:`late_pool` come from, which stereo pairs last of all.
    three_sided : ndarray, shape (K,), bool
        Per cover, whether it is one of the three-sided candidates, kept as a cover
        (``SegmentConfig.three_sided_support``): its fourth side unseen; its ``support``
        is that of the three seen sides. Empty where no cover is.
    """

    corners: NDArray[np.float64]
    coarse: NDArray[np.float64]
    support: NDArray[np.float64]
    lines: Lines
    T_H: float
    T_HG: int
    y: float
    iterations: int
    alternatives: tuple[NDArray[np.float64], ...] = ()
    pool: Quads = field(default_factory=Quads.empty)
    open_pool: Quads = field(default_factory=Quads.empty)
    late_pool: Quads = field(default_factory=Quads.empty)
    small_pool: Quads = field(default_factory=Quads.empty)
    three_sided: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))

    def __len__(self) -> int:
        return len(self.corners)

    @classmethod
    def empty(cls, T_H: float = 0.0, T_HG: int = 0, iterations: int = 0) -> Segmentation:
        return cls(np.zeros((0, 4, 2)), np.zeros((0, 4, 2)), np.zeros(0), Lines.empty(), T_H,
                   T_HG, 0.0, iterations)


def roi_area(grad: Gradients) -> float:
    """A_ROI of eq. 2, pixels."""
    if grad.mask is None:
        return float(grad.shape[0] * grad.shape[1])
    return float(np.count_nonzero(grad.mask))


def evaluate(grad: Gradients, T_H: float, cfg: SegmentConfig, *, T_HG: int | None = None,
             T_L: float | None = None, area: float | None = None,
             timing: dict[str, float] | None = None) -> Evaluation:
    """Run Canny → Hough → quads at one T_H and pick T_HG (or use the one given).

    The inner loop is exact and cheap: one Hough pass at the lowest threshold gives every
    line with its votes; a quad exists for every T_HG up to its weakest side's votes (an
    outline gives way to its nested covers up to theirs, :class:`CoverSelection`: the same
    breakpoints). Between those breakpoints the covers stay the same and only N changes,
    falling as T_HG rises: with e^{-N/N_max} y is highest at the top of each such interval, with the
    printed e^{+N/N_max} at its bottom (one above the next breakpoint down, or the lowest
    T_HG with N ≤ N_max). Only those T_HG are evaluated (at most ``cfg.max_inner``).

    ``timing``, if given, accumulates the milliseconds spent in Canny (``"canny"``), Hough
    (``"hough"``) and the quad stage with the inner loop (``"quads"``).
    """
    area = roi_area(grad) if area is None else area
    clock = time.perf_counter()
    edges = canny(grad, T_H, T_L)
    clock = _lap(timing, "canny", clock)
    low = cfg.T_HG_min if T_HG is None else int(T_HG)
    if T_HG is None and cv2.countNonZero(edges) > cfg.max_edge_frac * area:
        return Evaluation(T_H, low, 0.0, Lines.empty(), Quads.empty(), 1)
    lines = hough_lines(edges, low, grad=grad, max_lines=cfg.n_max + 1, box=grad.box)
    clock = _lap(timing, "hough", clock)
    if len(lines) > cfg.n_max:  # above the (N_max+1)-th line's votes N ≤ N_max holds
        low = max(low, int(lines.votes[cfg.n_max]) + 1)
        lines = lines.take(lines.votes >= low)
    if len(lines) == 0:
        return Evaluation(T_H, low, 0.0, lines, Quads.empty(), 1)
    # the edges' 3×3 dilation (an edge within 1 px of a line supports it), once for both
    near = cv2.dilate(edges, np.ones((3, 3), np.uint8))
    profile = support_profile(lines, edges, grad, box=grad.box, near=near)
    if cfg.refine_lines:  # Hough's 1° cells, undone: a long side's corners keep their arms
        lines, profile = refine_lines(lines, edges, profile, grad, box=grad.box, near=near)
    graph = _corner_graph(lines, profile, grad.shape, cfg.quads)  # (no area in it)
    quads = candidate_quads(lines, profile, grad.shape, area,
                            replace(cfg.quads, min_area_px=min(cfg.quads.min_area_px,
                                                               cfg.pool_min_area_px)),
                            graph=graph)
    big = cover_sized(quads, cfg.quads)
    small = _distinct(quads.take(~big), cfg.quads.duplicate_px)[0]  # (near-duplicates)
    selection = CoverSelection(quads.take(big), cfg.quads)
    if T_HG is not None:
        candidates = [low]
    else:
        # the T_HG at which the covers change: a quad appears at or below its votes (an
        # outline gives way up to its nested covers' votes, which are among them)
        tops = {int(v) for v in selection.votes if v >= low}
        if cfg.quality_sign > 0:  # each interval's bottom: one above the top below it
            highest = max(tops, default=low)
            tops = {t + 1 for t in tops if t + 1 <= highest}
        candidates = sorted(tops | {low}, reverse=True)
        if len(candidates) > cfg.max_inner:
            pick = np.linspace(0, len(candidates) - 1, cfg.max_inner).round().astype(int)
            candidates = [candidates[i] for i in sorted(set(pick))]
    best: Evaluation | None = None
    for t in candidates:  # inner loop over T_HG, from the highest
        n = int(np.count_nonzero(lines.votes >= t))
        covers = selection.at(t)
        y = quality(n, covers.n_f, area, cfg.n_max, sign=cfg.quality_sign)
        if best is None or y > best.y:
            best = Evaluation(T_H, t, y, lines.take(lines.votes >= t), covers, len(candidates),
                              selection, lines, profile, small, graph)
    assert best is not None
    _lap(timing, "quads", clock)
    return best


def _lap(timing: dict[str, float] | None, stage: str, since: float) -> float:
    """Add the milliseconds since ``since`` to ``timing[stage]`` (if timing is kept); now."""
    now = time.perf_counter()
    if timing is not None:
        timing[stage] = timing.get(stage, 0.0) + 1e3 * (now - since)
    return now


def finish(grad: Gradients, ev: Evaluation, iterations: int, *,
           timing: dict[str, float] | None = None,
           alternatives: tuple[NDArray[np.float64], ...] = (),
           pool: Quads | None = None, pool_size: int = 400,
           refine: Gradients | None = None, open_pool: Quads | None = None,
           late_pool: Quads | None = None, small_pool: Quads | None = None) -> Segmentation:
    """Refine the chosen covers to sub-pixel corners and order them (eq. 1), on
    ``refine``'s gradients if given (:func:`rovis.segment.edges.linear_gradients`), else on
    ``grad``'s; ``timing`` accumulates the milliseconds under ``"refine"``; ``alternatives``: per cover of ``ev``,
    other quads over it (kept as they are); ``pool``: the candidates for
    :attr:`Segmentation.pool` (default: ``ev``'s own, at most ``pool_size``,
    :func:`candidate_pool`); ``open_pool``, ``late_pool``, ``small_pool``:
    :attr:`Segmentation.open_pool`'s, :attr:`Segmentation.late_pool`'s and
    :attr:`Segmentation.small_pool`'s."""
    clock = time.perf_counter()
    open_pool, late_pool, small_pool = (
        canonical_quads(q) if q is not None and len(q) else Quads.empty()
        for q in (open_pool, late_pool, small_pool))
    if pool is None:
        pool = candidate_pool([ev.selection.quads] if ev.selection is not None else [],
                              pool_size)
    pool = canonical_quads(pool) if len(pool) else Quads.empty()
    if len(ev.covers) == 0:
        _lap(timing, "refine", clock)
        return Segmentation(np.zeros((0, 4, 2)), np.zeros((0, 4, 2)), np.zeros(0), ev.lines,
                            ev.T_H, ev.T_HG, ev.y, iterations, pool=pool, open_pool=open_pool,
                            late_pool=late_pool, small_pool=small_pool)
    refined, coarse = [], []
    for quad in ev.covers.corners:
        refined.append(order_corners(refine_quad(refine or grad, quad)))
        coarse.append(order_corners(quad))
    _lap(timing, "refine", clock)
    seen = ev.covers.lines >= 0  # a three-sided cover's open side has no line (-1)
    support = (ev.covers.support * seen).sum(axis=1) / seen.sum(axis=1)  # of the seen sides
    return Segmentation(np.array(refined), np.array(coarse), support, ev.lines, ev.T_H,
                        ev.T_HG, ev.y, iterations, alternatives, pool=pool,
                        open_pool=open_pool, late_pool=late_pool, small_pool=small_pool,
                        three_sided=~seen.all(axis=1))


def candidate_pool(parts: Iterable[Quads], most: int = 400, duplicate_px: float = 3.0) -> Quads:
    """The distinct quads of ``parts`` (the candidates of one or more evaluations'
    :class:`CoverSelection`, at every T_HG), near-duplicates (all corners within
    ``duplicate_px``) once, the ``most`` with the most edge pixels. Beyond the paper: the
    quads a per-image selection passed over, for stereo to choose from
    (:attr:`Segmentation.pool`)."""
    parts = [q for q in parts if len(q)]
    if not parts:
        return Quads.empty()
    quads = parts[0] if len(parts) == 1 else _distinct(Quads.concat(parts), duplicate_px)[0]
    order = np.argsort(-quads.n_f, kind="stable")[:most]  # the most edge pixels first
    return quads.take(order)


def without_near(quads: Quads, others: Quads, tol_px: float) -> Quads:
    """``quads`` less those whose four corners all lie within ``tol_px`` of one of
    ``others``' (any corner order)."""
    if len(quads) == 0 or len(others) == 0:
        return quads
    a, b = (_canonical(q.corners).reshape(-1, 8) for q in (quads, others))
    # a k-d tree on the eight corner coordinates, Chebyshev metric (as _distinct's): the
    # same quads as comparing every pair, at a sixth of the time (big leaves: as there)
    tree = cKDTree(b, leafsize=256)
    near = tree.query_ball_point(a, tol_px, p=np.inf, return_length=True) > 0
    return quads.take(~near)


def open_candidates(grad: Gradients, ev: Evaluation, cfg: SegmentConfig, *,
                    area: float | None = None,
                    timing: dict[str, float] | None = None) -> Quads:
    """The three-sided candidates (:func:`three_sided_quads`) of one evaluation (made with
    ``cfg``): from the lines its candidates were formed from (``timing``: under
    ``"three_sided"``); with ``cfg.small_open`` down to ``cfg.pool_min_area_px``
    (:func:`split_small` parts them)."""
    if ev.all_lines is None or ev.profile is None or len(ev.all_lines) < 3:
        return Quads.empty()
    clock = time.perf_counter()
    area = roi_area(grad) if area is None else area
    quads = three_sided_quads(ev.all_lines, ev.profile, grad.shape, area, _open_quads(cfg),
                              graph=ev.graph)
    _lap(timing, "three_sided", clock)
    return quads


def _open_quads(cfg: SegmentConfig) -> QuadConfig:
    """The quad rules for the candidates with sides unseen: with ``cfg.small_open``, down
    to ``cfg.pool_min_area_px`` (``QuadConfig.small_area_px``; :func:`split_small` parts
    them from the covers' size)."""
    if not cfg.small_open:
        return cfg.quads
    return replace(cfg.quads, small_area_px=cfg.pool_min_area_px)


def split_small(quads: Quads, cfg: SegmentConfig) -> tuple[Quads, Quads]:
    """``quads`` parted into those of a cover's area (``cfg.quads.min_area_px`` or more,
    pixels²) and the smaller ones."""
    big = cover_sized(quads, cfg.quads)
    return quads.take(big), quads.take(~big)


def two_sided_candidates(grad: Gradients, ev: Evaluation, cfg: SegmentConfig, *,
                         area: float | None = None,
                         timing: dict[str, float] | None = None) -> Quads:
    """The two-sided candidates (:func:`two_sided_quads`, and with
    ``cfg.opposite_sided`` :func:`opposite_sided_quads`) of one evaluation (made with
    ``cfg``), from the lines its candidates were formed from (``timing``: under
    ``"two_sided"``); with ``cfg.small_open`` down to ``cfg.pool_min_area_px``
    (:func:`split_small` parts them)."""
    if ev.all_lines is None or ev.profile is None or len(ev.all_lines) < 2:
        return Quads.empty()
    clock = time.perf_counter()
    area = roi_area(grad) if area is None else area
    graph = ev.graph if ev.graph is not None else _corner_graph(  # for both
        ev.all_lines, ev.profile, grad.shape, cfg.quads)
    qc = _open_quads(cfg)
    quads = two_sided_quads(ev.all_lines, ev.profile, grad.shape, area, qc, graph=graph)
    if cfg.opposite_sided:
        quads = Quads.concat([quads, opposite_sided_quads(ev.all_lines, ev.profile, grad.shape,
                                                          area, qc, graph=graph)])
    _lap(timing, "two_sided", clock)
    return quads


def refine_quad(grad: Gradients, corners: NDArray[np.float64], *,
                down: tuple[float, float] = (0.0, 1.0),
                half_width: float | Sequence[float] = 3.0) -> NDArray[np.float64]:
    """Sub-pixel corners (4, 2): each side refit to the gradient, neighbours intersected.

    A book seen from above and in front shows its page block below the cover's near sides,
    so a Hough line there may sit on the block's outer edge. On sides facing the camera
    (outward normal along ``down``, the image direction of the world's vertical) the cover
    edge is looked for inside the first one (:func:`cover_edge_offset`). A side that cannot
    be refit keeps its Hough position. ``half_width``: how far from the side (px) its
    edge is looked for (:func:`rovis.segment.lines.refine_segment`), one for all or per
    side (side s from corner s to s + 1).
    """
    return _refit(grad, corners, down, both=False, half_width=half_width)[0]


def refine_quad_both(grad: Gradients, corners: NDArray[np.float64], *,
                     down: tuple[float, float] = (0.0, 1.0),
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`refine_quad` with the inward search for the cover edge and without it
    (``down`` = (0, 0)), sharing the fits of the sides the search leaves where they are."""
    inward, plain, _ = refine_quad_fits(grad, corners, down=down)
    return inward, plain


def refine_quad_fits(grad: Gradients, corners: NDArray[np.float64], *,
                     down: tuple[float, float] = (0.0, 1.0),
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[Fit | None]]:
    """:func:`refine_quad_both`'s corners (4, 2) and :func:`refine_sides`'s fits, from one
    fit per side (a candidate refined, then completed in 3D from its sides' fits, is
    fitted once)."""
    inward, plain, fits = _refit(grad, corners, down, both=True)
    assert plain is not None
    return inward, plain, fits


Fit = tuple[NDArray[np.float64], NDArray[np.float64]]  # a line: point, unit direction


def refine_sides(grad: Gradients, corners: NDArray[np.float64], *,
                 down: tuple[float, float] = (0.0, 1.0)) -> list[Fit | None]:
    """Each side of a quad (4, 2) refit as :func:`refine_quad` refits it (the cover edge
    looked for inside a side facing the camera): side s (corner s to s + 1) as a point and
    unit direction, or None where it cannot be refit."""
    return [_fit_side(grad, corners, s, down, both=False)[0] for s in range(4)]


def _fit_side(grad: Gradients, corners: NDArray[np.float64], s: int, down: tuple[float, float],
              *, both: bool, half_width: float = 3.0) -> tuple[Fit | None, Fit | None, Fit, float]:
    """Side ``s`` refit with the inward search for the cover edge and (``both``, where the
    search moved it) without it, each None where it fails; the segment the first was fit
    from (its midpoint and direction: its fallback); the search's shift (px)."""
    a, b = corners[s], corners[(s + 1) % 4]
    d = (b - a) / np.linalg.norm(b - a)
    n_in = np.array([-d[1], d[0]])
    if n_in @ (corners.mean(axis=0) - a) < 0:
        n_in = -n_in
    shift = 0.0
    if -n_in @ np.asarray(down) > 0.05:
        across = float(np.max((corners - a) @ n_in))  # the quad's extent across this side
        shift = cover_edge_offset(grad, a, b, n_in, max_px=min(25.0, 0.2 * across))
    p, q = a + shift * n_in, b + shift * n_in
    inward = refine_segment(grad, p, q, half_width=half_width)
    plain = refine_segment(grad, a, b, half_width=half_width) if both and shift != 0.0 else None
    return inward, plain, (0.5 * (p + q), d), shift


def _refit(grad: Gradients, corners: NDArray[np.float64], down: tuple[float, float], *,
           both: bool, half_width: float | Sequence[float] = 3.0,
           ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, list[Fit | None]]:
    """:func:`refine_quad`'s corners, (``both``) those without the inward search, and
    each side's fit (None where it failed)."""
    inward, plain, fits = [], [], []
    widths = np.broadcast_to(np.asarray(half_width, dtype=np.float64), (4,))
    for s in range(4):
        fit_in, fit_plain, fallback, shift = _fit_side(grad, corners, s, down, both=both,
                                                       half_width=float(widths[s]))
        fits.append(fit_in)
        # a side that cannot be refit keeps the segment it was fit from
        inward.append(fit_in if fit_in is not None else fallback)
        if both:
            a, b = corners[s], corners[(s + 1) % 4]
            plain.append(inward[-1] if shift == 0.0 else fit_plain if fit_plain is not None
                         else (0.5 * (a + b), fallback[1]))
    return _join(inward, corners), (_join(plain, corners) if both else None), fits


def _join(sides: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
          corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Corners (4, 2) where neighbouring refitted sides (point, direction) meet; a corner
    whose sides meet more than 40 px from it (or not at all) stays."""
    out = corners.copy()
    for s in range(4):  # corner s joins side s-1 and side s
        p = intersect(*sides[s - 1], *sides[s])
        if p is not None and np.linalg.norm(p - corners[s]) < 40.0:
            out[s] = p
    return out


def side_evidence(grad: Gradients, corners: NDArray[np.float64], threshold: float, *,
                  reach_px: float = 1.0, trim_px: float = 3.0) -> NDArray[np.float64]:
    """Per side of a quad (4, 2), the share of its pixels where the derivative across it
    reaches ``threshold`` (grey levels per pixel, the Sobel scale), at the best offset
    within ``reach_px`` of the side: shape (4,), each in [0, 1].

    A weaker test than Canny's (no hysteresis, no thinning, no maximum): it asks whether a
    side hypothesised where no line was found shows any step at all, as a faint cover
    edge does along its length and the desk's grain or a neighbour's print mostly does not.
    """
    out = np.zeros(4)
    offsets = np.arange(-reach_px, reach_px + 1e-9, 0.5)
    # the four sides' samples side by side, (offsets, their pixels): one sample call
    xs, ys, nx, ny, sides, counts = [], [], [], [], [], []
    for s in range(4):
        a, b = corners[s], corners[(s + 1) % 4]
        length = float(np.linalg.norm(b - a))
        t = np.arange(trim_px, length - trim_px, 1.0)
        if length < 1e-9 or len(t) == 0:
            continue
        d = (b - a) / length
        n = np.array([-d[1], d[0]])
        p = a + t[:, None] * d  # (T, 2)
        xs.append(p[None, :, 0] + offsets[:, None] * n[0])
        ys.append(p[None, :, 1] + offsets[:, None] * n[1])
        nx.append(np.full(len(t), n[0]))
        ny.append(np.full(len(t), n[1]))
        sides.append(s)
        counts.append(len(t))
    if not sides:
        return out
    gx, gy = grad.sample(np.hstack(xs), np.hstack(ys))  # (offsets, ΣT)
    strong = np.abs(gx * np.hstack(nx) + gy * np.hstack(ny)) >= threshold
    # each side's share per offset: whole counts over its length, strong.mean(axis=1)'s values
    starts = np.cumsum([0] + counts[:-1])
    hits = np.add.reduceat(strong, starts, axis=1, dtype=np.intp)  # (offsets, sides)
    out[sides] = (hits / np.array(counts)).max(axis=0)
    return out


def cover_edge_offset(grad: Gradients, a: NDArray[np.float64], b: NDArray[np.float64],
                      n_in: NDArray[np.float64], *, max_px: float = 25.0,
                      min_ratio: float = 0.15, min_consistency: float = 0.6) -> float:
    """How far inside side ``a``–``b`` (px, along ``n_in``) the cover edge lies; 0 if here
    (−1 where the line lies 2–3 px inside the outer edge and the cover edge between them).

    The nearest of :func:`inner_edges`: the derivative across the side is sampled along it
    at offsets from −3 px (outside) to ``max_px`` inside (a page block is at most ~25 px
    wide at these distances; a printed frame further in must not be taken for it).
    """
    inner = inner_edges(grad, a, b, n_in, max_px=max_px, min_ratio=min_ratio,
                        min_consistency=min_consistency)
    return inner[0] if inner else 0.0


def _median_columns(g: NDArray[np.float64]) -> NDArray[np.float64]:
    """np.median(g, axis=0) of a 2-D array of finite numbers, none -0.0 (g >= 0 here): the
    same order statistics by one partition and, for an even count, the same mean of the
    middle two ((lo + hi) / 2), without np.median's overhead."""
    k = len(g) // 2
    if len(g) % 2:
        return np.partition(g, k, axis=0)[k]
    part = np.partition(g, (k - 1, k), axis=0)
    return (part[k - 1] + part[k]) / 2


def inner_edges(grad: Gradients, a: NDArray[np.float64], b: NDArray[np.float64],
                n_in: NDArray[np.float64], *, max_px: float = 25.0, min_ratio: float = 0.15,
                min_consistency: float = 0.6) -> list[float]:
    """The edges inside side ``a``–``b`` that may be a cover's edge above its page block:
    offsets (px along ``n_in``, from the side, nearest first; empty where there are none).

    The derivative across the side is sampled along it at offsets from −3 px (outside) to
    ``max_px`` inside. An inner edge counts when the median profile peaks there with at
    least ``min_ratio`` of the outer edge's strength (the detected edge, within ±3 px of
    the side), and at least ``min_consistency`` of the samples along the side agree. A
    page block shows several: its pages' rows, its boards' edges, the cover's own.
    """
    length = float(np.linalg.norm(b - a))
    if length < 20:
        return []
    d = (b - a) / length
    t = np.arange(0.15 * length, 0.85 * length, 2.0)
    offsets = np.arange(-3.0, max_px + 0.5, 1.0)
    base = a + t[:, None] * d
    gx, gy = grad.sample(base[:, None, 0] + offsets[None, :] * n_in[0],
                         base[:, None, 1] + offsets[None, :] * n_in[1])
    g = np.abs(gx * n_in[0] + gy * n_in[1])  # (samples, offsets)
    profile = _median_columns(g)
    outer = int(np.argmax(profile[:7]))  # the detected edge, within ±3 px of the line
    peak = profile[outer]
    if peak <= 0:
        return []
    inner = np.arange(outer + 2, len(offsets) - 1)
    is_max = (profile[inner] >= profile[inner - 1]) & (profile[inner] >= profile[inner + 1])
    found = []
    for k in inner[is_max & (profile[inner] >= min_ratio * peak)]:
        valley = profile[outer:k].min()
        level = valley + 0.5 * (profile[k] - valley)  # half way up the inner peak
        if np.mean(g[:, k - 1:k + 2].max(axis=1) >= level) >= min_consistency:
            # from the side (not from the outer edge, which may lie up to 3 px off it)
            found.append(float(offsets[k]))
    return found
