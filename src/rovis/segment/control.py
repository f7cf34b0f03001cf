"""The closed-loop cascade controller (paper §3.B, Fig. 4).

Outer loop: the Canny threshold T_H, searched on a log scale to maximise the segmentation
quality y (eq. 2). Inner loop: the Hough threshold T_HG for each T_H, solved exactly inside
:func:`rovis.segment.boundary.evaluate`. In a sequence the search starts from the previous
frame's optimum and only climbs locally, falling back to the full search when the scene has
changed so much that the local optimum is empty. Beyond the paper, the covers other
evaluated T_H found where the optimum found none are kept too (:func:`with_other_covers`),
and so are the clearest covers with one side unseen (:func:`with_three_sided_covers`); the
candidates with sides unseen of the remaining T_H go to stereo late
(:func:`unseen_candidates`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace
from itertools import zip_longest

import numpy as np

from rovis.segment.boundary import (Evaluation, SegmentConfig, Segmentation, candidate_pool,
                                   evaluate, finish, open_candidates, roi_area,
                                   split_small, two_sided_candidates, without_near)
from rovis.segment.edges import Gradients
from rovis.segment.quads import Quads, order_corners, quad_overlap


class CascadeController:
    """Sets T_H (outer) and T_HG (inner) by maximising eq. 2's y; remembers its optimum.

    Parameters
    ----------
    cfg : SegmentConfig
    warm_start : bool, optional
        Start each image's search from the previous image's optimum (sequences); default
        ``cfg.warm_start``.
    """

    def __init__(self, cfg: SegmentConfig | None = None, *,
                 warm_start: bool | None = None) -> None:
        self.cfg = cfg or SegmentConfig()
        self.warm_start = self.cfg.warm_start if warm_start is None else warm_start
        self.last_T_H: float | None = None
        self.last_extra_T_H: list[float] = []  # the other T_H whose covers were kept

    def reset(self) -> None:
        """Forget the previous optimum (next image gets a full search)."""
        self.last_T_H = None
        self.last_extra_T_H = []

    def segment(self, grad: Gradients, *, timing: dict[str, float] | None = None,
                more: Sequence[Evaluation] = (), refine: Gradients | None = None) -> Segmentation:
        """Search T_H and T_HG for one image, then refine the best covers (``timing``: see
        :func:`rovis.segment.boundary.evaluate`). ``more``: covers from other line sources
        (``SegmentConfig.lsd``), kept like another T_H's where the loop found none (with
        ``SegmentConfig.union``; they add no candidates to the pool). ``refine``: the
        gradients the chosen covers are refined on (:func:`rovis.segment.boundary.finish`)."""
        area = roi_area(grad)
        seen: dict[float, Evaluation] = {}
        pool: list[Quads] = []  # every evaluation's candidates (Segmentation.pool)
        smalls: list[Quads] = []  # and those under QuadConfig.min_area_px (small_pool)

        def run(log_T_H: float) -> Evaluation:
            lo, hi = np.log(self.cfg.T_H_range[0]), np.log(self.cfg.T_H_range[1])
            key = round(float(np.clip(log_T_H, lo, hi)), 3)
            if key not in seen:
                ev = evaluate(grad, float(np.exp(key)), self.cfg, area=area, timing=timing)
                if ev.selection is not None:
                    pool.append(candidate_pool([ev.selection.quads], self.cfg.pool_size))
                if ev.small is not None and len(ev.small):
                    smalls.append(candidate_pool([ev.small], self.cfg.pool_size))
                # an evaluation's candidates (megabytes on busy texture) serve only the
                # optimum's alternatives: those of one below the best so far are let go
                top = max(seen.values(), key=lambda e: e.y, default=None)
                if top is not None and ev.y < top.y:
                    ev = replace(ev, selection=None)
                elif top is not None and top.y < ev.y:
                    for k, e in seen.items():
                        if e.selection is not None:
                            seen[k] = replace(e, selection=None)
                seen[key] = ev
            return seen[key]

        best = None
        if self.warm_start and self.last_T_H is not None:
            best = self._climb(run, np.log(self.last_T_H))
            if best.y > 0 and self.cfg.union:
                for T_H in self.last_extra_T_H:  # where the last image's other covers were
                    run(np.log(T_H))
        if best is None or best.y <= 0:
            best = self._full_search(run)
        self.last_T_H = best.T_H if best.y > 0 else self.last_T_H
        iterations = sum(ev.inner_iterations for ev in seen.values())
        alternatives: tuple[np.ndarray, ...] = ()
        sources: list[Evaluation] = []
        if self.cfg.union and (best.y > 0 or any(len(ev.covers) for ev in more)):
            best, sources, alternatives = with_other_covers(best, [*seen.values(), *more],
                                                            self.cfg.quads.max_overlap)
            # the T_H a warm start evaluates again: the loop's own, not another source's
            self.last_extra_T_H = sorted({ev.T_H for ev in sources
                                          if any(ev is e for e in seen.values())})
        if self.cfg.pool_lines > self.cfg.n_max and best.T_H > 0:
            # beyond the paper: at the optimum's T_H, the candidates of more lines than eq. 2
            # allows (a short cover side is outvoted by the desk's long lines), for stereo
            loose = replace(self.cfg, n_max=self.cfg.pool_lines,
                            quads=replace(self.cfg.quads, min_support=self.cfg.pool_min_support))
            wide = evaluate(grad, best.T_H, loose, T_HG=self.cfg.T_HG_min, area=area,
                            timing=timing)
            if wide.selection is not None:
                pool.append(candidate_pool([wide.selection.quads], self.cfg.pool_size))
        full = candidate_pool(pool, self.cfg.pool_size)
        open_pool = late_pool = None
        small_open: list[Quads] = []  # (SegmentConfig.small_open) after the four-sided ones
        if self.cfg.three_sided:
            # beyond the paper: covers with one side unseen, at the T_H whose covers were
            # kept and the best few others
            ranked = sorted((e for e in seen.values() if e.y > 0), key=lambda e: -e.y)
            chosen = [best, *sources, *ranked[:self.cfg.three_sided_evaluations]]
            if not ranked:  # no cover at any T_H (y = 0): each evaluation may hold one
                chosen += list(seen.values())
            best, alternatives, open_pool = with_open_candidates(
                grad, best, alternatives, chosen, full, self.cfg, area=area, timing=timing,
                smalls=small_open)
            if self.cfg.late_open:
                rest = [e for e in seen.values() if e.y > 0
                        and all(e.profile is not c.profile for c in chosen)]
                late_pool = unseen_candidates(grad, rest, Quads.concat([full, open_pool]),
                                              self.cfg, area=area, timing=timing,
                                              smalls=small_open)
        small_pool = small_candidates(smalls, small_open, self.cfg)
        return finish(grad, best, iterations, timing=timing, alternatives=alternatives,
                      pool=full, refine=refine, open_pool=open_pool, late_pool=late_pool,
                      small_pool=small_pool)

    def _full_search(self, run) -> Evaluation:  # type: ignore[no-untyped-def]
        lo, hi = np.log(self.cfg.T_H_range[0]), np.log(self.cfg.T_H_range[1])
        grid = np.linspace(lo, hi, self.cfg.coarse_steps)
        best = max((run(u) for u in grid), key=lambda ev: ev.y)
        step = (grid[1] - grid[0]) / 2 if len(grid) > 1 else 0.0
        for _ in range(self.cfg.refine_steps):
            u = np.log(best.T_H)
            best = max((best, run(u - step), run(u + step)), key=lambda ev: ev.y)
            step /= 2
        return best

    def _climb(self, run, u0: float) -> Evaluation:  # type: ignore[no-untyped-def]
        step = np.log(self.cfg.warm_step)
        best = run(u0)
        for direction in (+1, -1):
            u = np.log(best.T_H)
            while True:
                trial = run(u + direction * step)
                if trial.y <= best.y:
                    break
                best, u = trial, u + direction * step
        return best


def with_other_covers(best: Evaluation, evaluations: Iterable[Evaluation], max_overlap: float,
                      ) -> tuple[Evaluation, list[Evaluation], tuple[np.ndarray, ...]]:
    """``best`` with the covers other evaluations (other T_H) found where it found none,
    the evaluations that gave them, and per cover the other evaluations' quads over it.

    Beyond the paper: eq. 2 picks one T_H per image, but a faint book may show all its
    sides only at a lower T_H, and one on a busy background only at a higher. A cover of
    another evaluation is added when it overlaps no cover kept so far by more than
    ``max_overlap`` (of the smaller), taking the evaluations by decreasing y. The
    thresholds, y and lines stay the optimum's.

    Each optimum cover's alternatives are the other evaluations' covers that overlap it
    (at another T_H the same book came out otherwise: its cover where the kept quad is its
    outline with the page block, or the reverse), strongest evaluation first, and the
    candidates it won over at the optimum's T_HG (:meth:`CoverSelection.losers`: the union
    of two touching books wins over each of them), taken in turn, near-duplicates (all
    corners within 3 px) once. Stereo tries them when the cover fails a pose check.
    """
    kept = list(best.covers.corners)
    # the candidates the optimum's covers won over at its T_HG
    losers = ([list(map(order_corners, q)) for q in best.selection.losers(best.T_HG)]
              if best.selection is not None else [[] for _ in kept])
    alts: list[list[np.ndarray]] = [[] for _ in kept]  # the other T_H's covers over them
    extra, sources = [], []
    for ev in sorted((e for e in evaluations if e is not best), key=lambda e: -e.y):
        for i, quad in enumerate(ev.covers.corners):
            over = [k for k, q in enumerate(kept) if quad_overlap(quad, q) > max_overlap]
            if not over:
                kept.append(quad)
                alts.append([])
                extra.append(ev.covers.take(np.array([i])))
                if not sources or sources[-1] is not ev:
                    sources.append(ev)
                continue
            ordered = order_corners(quad)
            for k in over:
                if all(np.abs(ordered - order_corners(q)).max() > 3.0
                       for q in [kept[k], *alts[k]]):
                    alts[k].append(ordered)
    # the two kinds taken in turn, the other T_H's first: a cap on them keeps both
    for k, lost in enumerate(losers):
        merged: list[np.ndarray] = []
        for pair in zip_longest(alts[k], lost):
            merged += [q for q in pair if q is not None and all(
                np.abs(q - m).max() > 3.0 for m in merged)]
        alts[k] = merged
    alternatives = tuple(np.array(a).reshape(-1, 4, 2) for a in alts)
    if not extra:
        return best, [], alternatives
    return replace(best, covers=Quads.concat([best.covers, *extra])), sources, alternatives


def with_three_sided_covers(best: Evaluation, alternatives: tuple[np.ndarray, ...],
                            open_pool: Quads, min_support: float, max_overlap: float,
                            ) -> tuple[Evaluation, tuple[np.ndarray, ...]]:
    """``best`` with the three-sided candidates (:func:`rovis.segment.quads.three_sided_quads`)
    whose three seen sides are all at least ``min_support`` covered by edge pixels, where
    they overlap no cover kept so far by more than ``max_overlap`` (of the smaller), the
    most edge pixels first; each new cover has no alternatives.

    Beyond the paper: a cover of the desk's brightness, or one meeting its own shadow,
    shows three sides and no fourth; with all three clearly seen it is kept as a cover of
    the image (measured: docs/segmentation.md), not only offered to stereo.
    """
    kept = list(best.covers.corners)
    extra = []
    for k in range(len(open_pool)):  # the most edge pixels first
        seen = open_pool.lines[k] >= 0  # the open side has no line
        quad = open_pool.corners[k]
        if np.count_nonzero(~seen) == 1 and open_pool.support[k][seen].min() >= min_support \
                and not any(
                quad_overlap(quad, q) > max_overlap for q in kept):
            kept.append(quad)
            extra.append(k)
    if not extra:
        return best, alternatives
    covers = Quads.concat([best.covers, open_pool.take(np.array(extra))])
    if alternatives:
        alternatives = alternatives + tuple(np.zeros((0, 4, 2)) for _ in extra)
    return replace(best, covers=covers), alternatives


def with_open_candidates(grad: Gradients, best: Evaluation, alternatives: tuple[np.ndarray, ...],
                         chosen: Sequence[Evaluation], full: Quads, cfg: SegmentConfig, *,
                         area: float, timing: dict[str, float] | None = None,
                         smalls: list[Quads] | None = None,
                         ) -> tuple[Evaluation, tuple[np.ndarray, ...], Quads]:
    """The candidates with sides unseen of the ``chosen`` evaluations (beyond the paper):
    ``best`` with the clearly seen three-sided ones kept as covers
    (:func:`with_three_sided_covers`, ``cfg.three_sided_support``), its ``alternatives``,
    and :attr:`Segmentation.open_pool` (three-sided, then with ``cfg.two_sided`` two-sided
    candidates, for stereo only), less those ``full`` (the four-sided pool) already holds;
    with ``cfg.small_open``, those smaller than a cover are appended to ``smalls``.
    The closed loop asks it of the T_H it kept and the best few others; a method with one
    evaluation, of that one."""
    # one evaluation may appear as itself and as a copy with more covers
    # (with_other_covers): the same lines and edge hits, asked once
    chosen = [e for k, e in enumerate(chosen)
              if all(e.profile is not c.profile for c in chosen[:k])]
    open_pool = unseen_candidates(grad, chosen, full, cfg, area=area, timing=timing,
                                  smalls=smalls)
    if cfg.three_sided_support <= 1.0:  # (a two-sided candidate has two sides unseen)
        best, alternatives = with_three_sided_covers(
            best, alternatives, open_pool, cfg.three_sided_support, cfg.quads.max_overlap)
    return best, alternatives, open_pool


def small_candidates(four_sided: list[Quads], unseen: list[Quads],
                     cfg: SegmentConfig) -> Quads | None:
    """:attr:`Segmentation.small_pool`: the four-sided candidates smaller than a cover, then
    those with sides unseen (``cfg.small_open``) that are not near one of them, each the most
    edge pixels first (at most ``cfg.pool_size``, ``cfg.two_sided_size`` of the latter)."""
    full = candidate_pool(four_sided, cfg.pool_size) if four_sided else None
    if not unseen:
        return full
    rest = candidate_pool(unseen, cfg.two_sided_size)
    if full is None:
        return rest
    return Quads.concat([full, without_near(rest, full, cfg.quads.duplicate_px)])


def unseen_candidates(grad: Gradients, evaluations: Sequence[Evaluation], near: Quads,
                      cfg: SegmentConfig, *, area: float,
                      timing: dict[str, float] | None = None,
                      smalls: list[Quads] | None = None) -> Quads:
    """The candidates with sides unseen (three-sided, then with ``cfg.two_sided`` two-sided)
    of ``evaluations``, less those ``near`` holds (beyond the paper):
    :attr:`Segmentation.open_pool` of the evaluations :func:`with_open_candidates` is asked
    of, and :attr:`Segmentation.late_pool` (``cfg.late_open``) of the closed loop's other
    T_H with covers. With ``cfg.small_open``, those smaller than a cover are appended to
    ``smalls`` instead (for :attr:`Segmentation.small_pool`; without ``smalls`` they are
    let go)."""
    if not evaluations:
        return Quads.empty()

    def parted(quads: list[Quads]) -> list[Quads]:  # the cover-sized ones; the rest to smalls
        if not cfg.small_open:
            return quads
        parts = [split_small(q, cfg) for q in quads]
        if smalls is not None:
            smalls.extend(small for _, small in parts if len(small))
        return [big for big, _ in parts]

    late = without_near(candidate_pool(
        parted([open_candidates(grad, e, cfg, area=area, timing=timing) for e in evaluations]),
        cfg.pool_size), near, cfg.quads.duplicate_px)
    if cfg.two_sided:
        two = without_near(candidate_pool(
            parted([two_sided_candidates(grad, e, cfg, area=area, timing=timing)
                    for e in evaluations]),
            cfg.two_sided_size), Quads.concat([near, late]), cfg.quads.duplicate_px)
        late = Quads.concat([late, two])
    return late
