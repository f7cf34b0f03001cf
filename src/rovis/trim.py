"""Cover trim by the height map: a cover that takes in a neighbour, cut back to its own height.

Beyond the paper. A quad whose sides all sit on strong edges can still span two books: a
book lying on another with their sides in line, or two books side by side whose outer
sides meet at the quad's corners. Every side passes the edge tests of :mod:`rovis.extent`,
and the pose is that of a flat rectangle, centimetres too long. The height map
(:mod:`rovis.heightmap`) tells: across the cover, strip by strip, the surface is at the
cover's height over the book itself and at another height over the part that is not.

:func:`height_profile` reads the maps along one axis of the cover; :func:`trim_side` finds
the longest run of strips at the cover's height and, where the cover goes on beyond it
at another height for long enough, cuts it there. The pipeline then moves the cut side
onto the edge both images show (:func:`rovis.heightmap.snap_sides`, that side only).

Before that, :func:`map_height` reads the maps over the cover's middle: a plain cover
whose sides misled stereo by a centimetre or more in height is laid at the maps' height
(the pipeline's ``Detector._at_map_height``).

:func:`grow_run` reads the maps beyond each side, for a cover cut short at a printed band
to grow to where they leave its height; :func:`print_grow` asks the cover's print instead,
where the maps are too coarse to tell (a thin book): the strip beyond the side lines up
between the images at the cover's height up to its true edge, and not past it; and
:func:`lateral_grow` asks the cover's neighbouring sides, where the maps go on but its
edge shows no step (a picture of the desk's tone along it): they end at its corners.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rovis import geometry
from rovis.extent import (ExtentConfig, _block_shows, _drop, _edge_height, _hits, _moved,
                          _side_scores, _unit)
from rovis.heightmap import HeightMap, read_heights, row_medians
from rovis.segment.edges import Gradients
from rovis.sweep import Sweep, sweep_heights


@dataclass(frozen=True)
class TrimConfig:
    """Settings of the trim and the height check (metres unless noted).

    ``enabled`` turns the trim on, ``map_height`` the height check (both need the height
    map). The check: a book ``min_height_move`` or more from :func:`map_height`'s height
    is moved there; the map must have values at ``min_height_share`` of the points read,
    and ``min_height_agree`` of those within ``tolerance`` of their median. Its sides are
    then moved onto the edges both images show within ``snap_reach`` either way. A book
    stays where two or more of its sides that do not face the cameras, placed by stereo,
    agree on its height to within ``map_sides`` and not on the maps' (the height its
    sides' edges give, :func:`rovis.extent.height_from_sides` with the pipeline's
    ``side_height`` settings, whether or not that step is on; 0 turns the test off).

    The trim: the cover is read in strips ``strip`` wide across each axis, ``samples``
    points per strip over ``span`` of the other axis; a strip's height is the median of
    the fine map's values where it has at least ``min_samples``, else of the smooth
    map's where that has as many (else unknown). A strip is at the cover's height within
    ``tolerance`` (or ``tolerance_ratio`` of that height, if larger), and lower below
    that. The cover is cut where, beyond its longest run of strips at its height (unknown
    or higher strips up to ``max_gap`` bridged), at least ``min_cut`` of it goes on, with
    at least ``min_other`` of those strips lower and their median more than the tolerance
    below; the part kept must be ``min_keep`` long. The cut side is moved onto the edge
    both images show within ``snap_reach`` outward and ``snap_inward`` inward, and kept
    only where it is one, or, with no edge there, where the step scores
    ``min_score_unseen`` or more (:func:`trim_side`; above 1: never).

    The grow (``grow``), the trim's counterpart: a side that stops short of where the maps
    go on at the cover's height (:func:`grow_run`, read over ``grow_reach`` beyond it; at
    least ``grow_min_same`` of the run's strips known to be at the height) is moved out to the
    last edge both images show up to ``grow_margin`` from that run's end (negative: short
    of it, since the maps carry a cover's height some 5-20 mm beyond its edge), at least
    ``grow_min`` (:func:`rovis.extent._grow_side` with that limit). Each of its
    neighbouring sides must go on as an edge, in either image, along ``grow_continuation``
    of the way; with ``grow_foot``, where the new side's page block shows, its foot must be
    an edge in each image that shows it (a shadow's or the desk's line beyond the block has
    no block of its own); and the strip added may lie over another book by at most
    ``print_max_overlap`` of it, as the grow by print's (the extent step's faint edges,
    ``weak_support``, are taken here without stereo, and a neighbour of the cover's
    height carries the maps on).

    The grow by print (``print_grow``, :func:`print_grow`), where the maps cannot tell (a
    thin book, a cover whose sides carry no edge beyond a band): a side moves out to an
    edge both images show, at least ``print_min`` and at most ``print_reach`` beyond it
    (and the book no longer than the extent step's ``max_side``); where a page block
    shows below the side, at least ``print_near`` and ``print_foot_margin`` beyond where
    its foot would show (the nearer of those and ``print_min``); where none shows, at
    least ``print_far`` (the nearer of it and ``print_min``: a printed frame near the
    edge stops a side a few millimetres short, and no block's foot lies beyond a side
    facing away; in effect about a centimetre, the strip between too narrow to sweep
    under that). The strip between must line up between the images at the cover's
    height (the sweep's best within the tolerance above, NCC at least ``print_min_ncc``
    and ``print_margin`` above the desk's; from ``print_min`` out, each ``print_piece``
    of it best within the tolerance) and the strip ``print_beyond`` wide past the edge
    does not (best more than half the tolerance off), nor within ``print_apart`` of the
    tolerance of where the strip between does. The first ``print_piece`` beyond the side
    is looked at first: a side whose print there lines up at another height stays,
    unscanned. The first ``print_edges`` edges beyond the side are tried, nearest first
    (an edge whose far side lines up at the cover's height was print, and so was one far
    enough out, a neighbouring side going on to it, whose far side lies within
    ``print_apart`` of the tolerance of the strip between's; one whose far side shows no
    print leaves the side where it is). The run of offsets that starts at the side's own
    edge may hold more: where the edge strength between two peaks in it falls below
    ``print_dip`` of the weaker, the later is another edge (0: none; a line printed near
    the cover's edge, blurred, runs into it). One neighbouring side must go on as an edge,
    in either image, along ``print_continuation`` of the way, and the strip added may lie
    over another book by at most ``print_max_overlap`` of it (in the left image).

    Either grow's move refused by these guards (the strip over another book, the new side
    on the desk, no edge at its page block's foot) is asked again, ending ``grow_retry``
    short of it, for a nearer edge: ``grow_tries`` asks in all (1: the first move only).
    A found book the strip lies over is no bar where it is a piece of the grown cover
    (``grow_absorb``, :func:`rovis.split.piece_of`: at its height within the split's
    ``join_step``, each corner within ``grow_absorb`` of the grown cover's outline): the
    cover's part beyond a printed band, found on its own. The grown cover takes its place
    (0: never).

    The grow to the neighbours' ends (``lateral_grow``, :func:`lateral_grow`; stop 51):
    where the maps' grow finds no edge beyond a side (a picture cover's edge of the
    desk's tone), the side moves to where both neighbouring sides stop being edges, if
    the maps go on ``lateral_run`` or more at the cover's height; the settings ``lateral_*``
    are that function's.
    """

    enabled: bool = True
    strip: float = 0.005
    samples: int = 20
    span: float = 0.8
    min_samples: int = 5
    tolerance: float = 0.006
    tolerance_ratio: float = 0.25
    max_gap: float = 0.015
    min_cut: float = 0.033  # 7 strips: 6 (30 mm) cut sound covers short (docs/stereo.md)
    min_other: float = 0.6
    min_keep: float = 0.07
    snap_reach: float = 0.01
    snap_inward: float = 0.02
    min_score_unseen: float = 0.9
    grow: bool = True
    grow_reach: float = 0.15  # scene 76's height 12 cm beyond a band (docs/stereo.md)
    grow_margin: float = -0.005  # the maps carry a cover's height 5-20 mm beyond its edge
    grow_min_same: float = 0.3
    grow_min: float = 0.015  # smaller moves took a shadow's or block's line, measured
    grow_continuation: float = 0.5
    grow_foot: bool = True
    map_height: bool = True
    min_height_move: float = 0.003  # the maps sweep every 3 mm
    min_height_share: float = 0.4
    min_height_agree: float = 0.5
    map_sides: float = 0.004  # side_height.agree: the sides' own spread
    print_grow: bool = True
    print_reach: float = 0.15  # scene 48's print 11 cm beyond a band (docs/stereo.md)
    print_min: float = 0.02  # at 15 mm covers nearly right grew onto their block's foot
    print_near: float = 0.008  # from the side, where past the block's foot (docs/stereo.md)
    print_far: float = 0.004  # no block's foot to grow onto: any edge past the side's own
    print_apart: float = 0.5  # of the tolerance, the strip beyond against the one inside
    print_foot_margin: float = 0.004
    print_min_ncc: float = 0.6
    print_margin: float = 0.05
    print_max_overlap: float = 0.1
    print_beyond: float = 0.01
    print_piece: float = 0.012
    print_edges: int = 3  # a picture's two edges may lie before the cover's (stop 70)
    print_dip: float = 0.5  # of the weaker peak: a printed line's run merged with the edge's
    print_continuation: float = 0.5
    grow_tries: int = 3  # asks for a side's grow, a refused move's nearer edge after it
    grow_retry: float = 0.005  # how far short of a refused move the next ask ends
    grow_absorb: float = 0.008  # a piece's corners within this of the grown cover's outline
    lateral_grow: bool = True
    lateral_run: float = 0.03  # the maps' spill beyond a cover's edge is 5-20 mm
    lateral_start: float = 0.003  # at a cover's own corner its sides end
    lateral_gap: float = 0.006
    lateral_spread: float = 0.012
    lateral_back: float = 0.003  # a corner's edge fades a pixel or two short of it
    lateral_ahead: float = 0.008
    lateral_min: float = 0.032  # a shadow or the desk's grain carries a side on 2-3 cm
    lateral_sigmas: float = 3.0

    def __post_init__(self) -> None:
        problems = [name for name, ok in (
            ("strip", self.strip > 0), ("samples", self.samples >= 1),
            ("span", 0 < self.span <= 1), ("min_samples", 1 <= self.min_samples <= self.samples),
            ("tolerance", self.tolerance >= 0 and self.tolerance_ratio >= 0),
            ("max_gap", self.max_gap >= 0), ("min_cut", self.min_cut > 0),
            ("min_other", 0 <= self.min_other <= 1), ("min_keep", self.min_keep > 0),
            ("snap_reach", self.snap_reach >= 0 and self.snap_inward >= 0),
            ("min_height_move", self.min_height_move >= 0),
            ("map_sides", self.map_sides >= 0),
            ("min_height_share", 0 <= self.min_height_share <= 1
             and 0 <= self.min_height_agree <= 1),
            ("grow_reach", self.grow_reach > 0 and self.grow_min > 0),
            ("grow_min_same", 0 <= self.grow_min_same <= 1
             and 0 <= self.grow_continuation <= 1),
            ("print_reach", self.print_reach > 0 and self.print_min > 0
             and self.print_near > 0 and self.print_far > 0
             and self.print_foot_margin >= 0
             and self.print_beyond > 0 and self.print_piece > 0),
            ("print_edges", self.print_edges >= 1), ("print_apart", self.print_apart >= 0),
            ("print_dip", 0 <= self.print_dip <= 1),
            ("grow_tries", self.grow_tries >= 1), ("grow_retry", self.grow_retry > 0),
            ("grow_absorb", self.grow_absorb >= 0),
            ("lateral_*", all(v >= 0 for v in (
                self.lateral_run, self.lateral_start, self.lateral_gap, self.lateral_spread,
                self.lateral_back, self.lateral_ahead, self.lateral_sigmas))
             and self.lateral_min > 0.01),
            ("print_continuation", 0 <= self.print_continuation <= 1
             and 0 <= self.print_max_overlap <= 1 and -1 <= self.print_min_ncc <= 1
             and -2 <= self.print_margin <= 2)) if not ok]
        if problems:
            raise ValueError(f"trim: bad {', '.join(problems)} (strip, min_cut and min_keep "
                             "positive, as are grow_reach and grow_min; span in (0, 1]; "
                             "min_other, min_height_share, min_height_agree, grow_min_same, "
                             "grow_continuation, print_continuation and print_max_overlap "
                             "in [0, 1]; print_reach, print_min, print_near, print_far, "
                             "print_beyond and print_piece positive, print_foot_margin >= 0, "
                             "print_edges >= 1, print_apart >= 0, print_dip in [0, 1], "
                             "grow_tries >= 1, "
                             "grow_retry > 0, "
                             "grow_absorb >= 0, "
                             "the lateral_* settings >= 0 and lateral_min over 0.01, "
                             "print_min_ncc in "
                             "[-1, 1], print_margin in [-2, 2]; min_samples from 1 to samples; "
                             "grow_margin of any sign; the "
                             f"rest >= 0), got {self}")


def height_profile(P: NDArray[np.float64], axis: int,
                   maps: list[tuple[HeightMap, NDArray[np.float64]]],
                   cfg: TrimConfig = TrimConfig()) -> NDArray[np.float64]:
    """Surface height (metres above the desk, NaN: unknown) in strips across a cover.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        The cover's corners (world, metres), a rectangle in order around it.
    axis : {0, 1}
        0: strips along side 0's direction, from corner 0 (or 3) towards corner 1 (2);
        1: along side 1's, from corner 1 (0) towards corner 2 (3).
    maps : list of (HeightMap, ndarray (3, 4))
        Height maps with the projection of the image each is over, finest first.
    cfg : TrimConfig
        ``strip``, ``samples``, ``span``, ``min_samples``.

    Returns
    -------
    ndarray, shape (S,)
        One height per strip of the cover's extent along ``axis``: S = its length over
        ``cfg.strip``, rounded, strips of the length over S.
    """
    origin = P[0] if axis == 0 else P[1]
    along = (P[1] - P[0]) if axis == 0 else (P[2] - P[1])
    across = (P[3] - P[0]) if axis == 0 else (P[0] - P[1])
    length = float(np.linalg.norm(along))
    n_strips = max(1, int(round(length / cfg.strip)))
    t = (np.arange(n_strips) + 0.5) / n_strips  # strip centres, share of the length
    g = 0.5 + cfg.span * (np.linspace(0.0, 1.0, cfg.samples) - 0.5)  # share of the width
    pts = origin + t[:, None, None] * along + g[None, :, None] * across  # (S, G, 3)
    out = np.full(n_strips, np.nan)
    for hm, Q in maps:
        z = read_heights(hm, Q, pts.reshape(-1, 3)).reshape(n_strips, cfg.samples)
        count = np.count_nonzero(np.isfinite(z), axis=1)
        enough = np.flatnonzero(np.isnan(out) & (count >= cfg.min_samples))
        if len(enough):
            out[enough] = row_medians(z[enough], count[enough])
    return out


def map_height(P: NDArray[np.float64], maps: list[tuple[HeightMap, NDArray[np.float64]]],
               cfg: TrimConfig = TrimConfig()) -> float | None:
    """The height the maps read over a cover's middle (metres above the desk), or None.

    A 15 × 15 grid over the middle 70 % of the cover is read in each map, finest first.
    The first map with values at ``cfg.min_height_share`` of the points decides: the
    median of its values, refined to the mean of those within ``cfg.tolerance`` of it (the
    maps' heights come in steps of a few millimetres); or None where fewer than
    ``cfg.min_height_agree`` of its values lie that near (the next map is not asked: the
    finer map's values disagreeing is no reason to trust the coarser one).

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        The cover's corners (world, metres), a rectangle in order around it.
    maps : list of (HeightMap, ndarray (3, 4))
        Height maps with the projection of the image each is over, finest first.
    cfg : TrimConfig

    Returns
    -------
    float or None
        Metres above the desk.
    """
    g = np.linspace(0.15, 0.85, 15)
    s, r = np.meshgrid(g, g)
    pts = P[0] + s.reshape(-1, 1) * (P[1] - P[0]) + r.reshape(-1, 1) * (P[3] - P[0])
    for hm, Q in maps:
        z = read_heights(hm, Q, pts)
        z = z[np.isfinite(z)]
        if len(z) and len(z) >= cfg.min_height_share * len(pts):
            mid = float(np.median(z))
            near = np.abs(z - mid) <= cfg.tolerance
            # a dark cover's noise matches at random heights: most values must agree
            if np.count_nonzero(near) < cfg.min_height_agree * len(z):
                return None
            return float(np.mean(z[near]))
    return None


def trim_side(profile: NDArray[np.float64], height: float, cfg: TrimConfig = TrimConfig(),
              *, strip: float | None = None) -> tuple[int, float, float] | None:
    """Where to cut a cover whose height profile shows another surface at one end.

    Parameters
    ----------
    profile : ndarray, shape (S,)
        :func:`height_profile` (metres; NaN unknown).
    height : float
        The cover's height above the desk (metres).
    cfg : TrimConfig
        ``tolerance``, ``tolerance_ratio``, ``max_gap``, ``min_keep``, ``min_cut``,
        ``min_other``.
    strip : float, optional
        The profile's strip width (metres; :func:`height_profile`'s length over S), by
        default ``cfg.strip``.

    Returns
    -------
    (end, cut, score) or None
        ``end`` 0: the part from the profile's start is cut away, 1: from its end; ``cut``:
        how much (metres); ``score``: how clear the step is (the share of strips at the
        cover's height in the part kept times the share at another height in the part cut,
        0 to 1). None where the cover is at its height throughout (or the evidence is too
        thin).
    """
    width = cfg.strip if strip is None else strip
    tol = max(cfg.tolerance, cfg.tolerance_ratio * height)
    known = np.isfinite(profile)
    same = known & (np.abs(profile - height) <= tol)
    # only a lower surface tells the cover is not there: a higher one is another book
    # lying on it, with the cover going on beneath
    other = known & (profile < height - tol)
    n = len(profile)
    # the longest run of strips at the cover's height, bridging short unknown gaps
    max_gap = int(round(cfg.max_gap / cfg.strip))
    best, start = (0, 0), None
    gap = 0
    for k in range(n + 1):
        if k < n and same[k]:
            start = k if start is None else start
            gap = 0
            end = k + 1
            if end - start > best[1] - best[0]:
                best = (start, end)
        elif k < n and not other[k] and start is not None and gap < max_gap:
            gap += 1
        else:
            start, gap = None, 0
    lo, hi = best
    if (hi - lo) * width < cfg.min_keep:
        return None
    cuts = []
    for end, part in ((0, slice(0, lo)), (1, slice(hi, n))):
        k = np.arange(n)[part]
        if len(k) * width < cfg.min_cut or not known[k].any():
            continue
        off = height - profile[k[known[k]]]
        share = np.count_nonzero(other[k]) / len(k)
        if share >= cfg.min_other and np.median(off) > tol:
            kept = np.count_nonzero(same[lo:hi]) / (hi - lo)
            cuts.append((share * kept, end, len(k) * width))
    if not cuts:
        return None
    score, end, cut = max(cuts)  # the clearer, if both ends look cut
    return end, cut, score


def cut_cover(P: NDArray[np.float64], axis: int, end: int,
              cut: float) -> tuple[NDArray[np.float64], int]:
    """A rectangle with one end cut off.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        The cover's corners (world, metres), a rectangle in order around it.
    axis, end : int
        As :func:`height_profile` and :func:`trim_side`.
    cut : float
        Metres taken off.

    Returns
    -------
    (ndarray (4, 3), int)
        The new corners (the two at the cut end moved along ``axis``) and the side that
        moved (side s from corner s to s + 1).
    """
    P = P.copy()
    a, b = (0, 1) if axis == 0 else (1, 2)
    u = (P[b] - P[a]) / np.linalg.norm(P[b] - P[a])
    # axis 0 runs from side 3 to side 1, axis 1 from side 0 to side 2
    side = (3, 1)[end] if axis == 0 else (0, 2)[end]
    for k in (side, (side + 1) % 4):
        P[k] = P[k] + (cut if end == 0 else -cut) * u
    return P, side


def grow_run(P: NDArray[np.float64], s: int, height: float,
             maps: list[tuple[HeightMap, NDArray[np.float64]]],
             cfg: TrimConfig = TrimConfig()) -> float:
    """How far beyond one side of a cover the maps go on at the cover's height.

    Strips ``cfg.strip`` wide are read outward over ``cfg.grow_reach`` (:func:`height_profile`,
    the rectangle beyond the side, its neighbouring sides continued): the run goes from the
    side to the last strip at the cover's height (within the trim's tolerance) before one
    at another height, lower or higher; unknown strips are bridged up to ``cfg.max_gap``.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        The cover's corners (world, metres), a rectangle in order around it.
    s : int
        The side, from corner ``s`` to ``s + 1``.
    height : float
        The cover's height above the desk (metres).
    maps : list of (HeightMap, ndarray (3, 4))
        Height maps with the projection of the image each is over, finest first.
    cfg : TrimConfig

    Returns
    -------
    float
        The run's length (metres); 0 where it is empty or fewer than ``cfg.grow_min_same``
        of its strips are known to be at the cover's height.
    """
    a, b = s, (s + 1) % 4
    u_a = P[a] - P[(a - 1) % 4]  # the neighbouring sides continued, as extent._moved
    u_b = P[b] - P[(b + 1) % 4]
    u_a, u_b = (u / max(float(np.linalg.norm(u)), 1e-12) for u in (u_a, u_b))
    R = np.array([P[a], P[b], P[b] + cfg.grow_reach * u_b, P[a] + cfg.grow_reach * u_a])
    profile = height_profile(R, 1, maps, cfg)
    width = cfg.grow_reach / len(profile)
    tol = max(cfg.tolerance, cfg.tolerance_ratio * height)
    known = np.isfinite(profile)
    same = known & (np.abs(profile - height) <= tol)
    max_gap = int(round(cfg.max_gap / cfg.strip))
    last, gap = -1, 0
    for k in range(len(profile)):
        if same[k]:
            last, gap = k, 0
        elif known[k] or gap >= max_gap:
            break
        else:
            gap += 1
    if last < 0 or np.count_nonzero(same[:last + 1]) < cfg.grow_min_same * (last + 1):
        return 0.0
    return (last + 1) * width


def print_grow(P: NDArray[np.float64], s: int, height: float, Q: dict[str, NDArray[np.float64]],
               grads: dict[str, Gradients], min_strength: dict[str, float],
               texture: dict[str, NDArray[np.float32]], desk_plane: NDArray[np.float64],
               ext: ExtentConfig, cfg: TrimConfig = TrimConfig(), *,
               limit: float = np.inf) -> float:
    """How far side ``s`` of cover ``P`` (4, 3) moves out onto the cover's own edge, as its
    print tells (metres; 0: not at all); ``limit``: the farthest move looked at.

    A side cut short at a printed band has more cover beyond it: between the two images
    its print lines up on the cover's plane, while beyond the cover's edge the desk, or
    the page block's face, lines up at another height (:func:`rovis.sweep.sweep_heights`
    on a strip of the cover's plane; the tolerance is the trim's, the larger of
    ``cfg.tolerance`` and ``cfg.tolerance_ratio`` of ``height``).

    1. The first ``cfg.print_piece`` beyond the side must sweep best within the tolerance
       of ``height`` (or show no print): most sides are the cover's own, and are spared
       the edge scan, most of the cost.
    2. The edges both images show beyond the side (:func:`rovis.extent._side_scores`,
       offsets 1 mm apart from 4 mm out, up to ``cfg.print_reach`` or what makes the book
       ``ext.max_side`` long; a run of offsets from the first one is the side's own edge,
       not looked at, but for the edges after a dip in it, :func:`_run_peaks` with
       ``cfg.print_dip``: a line printed near the cover's edge and the edge, blurred,
       make one run) are taken nearest first, at most ``cfg.print_edges`` of them, each
       at its strongest offset.
    3. An edge may be the cover's from ``cfg.print_min`` out; where a page block shows
       below the side (:func:`rovis.extent._block_shows`), from ``cfg.print_near`` out
       if that is ``cfg.print_foot_margin`` beyond where the block's foot would show in
       both images (:func:`_foot_offset`; its face, the side's own, spans the image
       from the side to there, and a side nearly right would grow onto its foot); where
       none shows, from ``cfg.print_far`` out (no foot lies beyond the side; a frame
       printed a few millimetres inside the cover's edge stops it there). For
       such an edge, the strip from the side to it must sweep best within the
       tolerance, with an NCC of at least ``cfg.print_min_ncc`` and
       ``cfg.print_margin`` above the NCC at the desk's height, and from
       ``cfg.print_min`` out each ``cfg.print_piece`` of it (that shows print) best
       within the tolerance; otherwise, or with no print in it, the side stays. A nearer
       edge is judged by the strip beyond it alone.
    4. Where the strip ``cfg.print_beyond`` wide beyond the edge shows no print, nothing
       tells, and the side stays; where it sweeps best within half the tolerance of
       ``height``, the edge was print, and the next is tried. Otherwise the edge must be
       far enough out (3) and one neighbouring side must go on as an edge, in either
       image, along ``cfg.print_continuation`` of the way (:func:`_continued`), or the
       side stays; then, where that strip lies within ``cfg.print_apart`` of the
       tolerance of the strip inside it (3) (one surface both sides of the edge, a few
       millimetres off the given height; 0: not asked), the edge was print too, and the
       next is tried; else the side moves there.
    """
    a, b = s, (s + 1) % 4
    room = min(cfg.print_reach, limit,
               ext.max_side - max(np.linalg.norm(P[a] - P[(a - 1) % 4]),
                                  np.linalg.norm(P[b] - P[(b + 1) % 4])))
    gap = 0.002  # the edges themselves, left out of the strips
    d = np.arange(2 * gap, room + 1e-9, ext.step)
    least = cfg.print_min  # the nearest edge that may be the cover's (step 3)
    drop = _drop(P, desk_plane)
    if _block_shows(P, s, Q, drop):
        least = min(least, max(cfg.print_near, _foot_offset(P, s, Q, drop)
                               + cfg.print_foot_margin))
    else:  # no block's foot beyond the side to grow onto (a printed frame may stop it short)
        least = min(least, cfg.print_far)
    if room < least or len(d) == 0:
        return 0.0
    moved = _moved(P, s, d)  # (D, 4, 3)
    tol = max(cfg.tolerance, cfg.tolerance_ratio * height)
    heights = np.arange(0.0, height + 2 * tol + 1e-9, 0.001)
    u_a, u_b = _unit(P[a] - P[(a - 1) % 4]), _unit(P[b] - P[(b + 1) % 4])  # as _moved

    def sweep(near: float, far: float) -> Sweep | None:
        # the strip between offsets near and far (metres), a tenth left out at each end
        A, B = P[a] + near * u_a, P[b] + near * u_b
        C, D = P[b] + far * u_b, P[a] + far * u_a
        inset = 0.1 * (B - A)
        strip = np.array([A + inset, B - inset, C - inset, D + inset])
        return sweep_heights(texture["left"], texture["right"], Q["left"], Q["right"],
                             geometry.project(Q["left"], strip), desk_plane, heights, inset=0.0)

    outside = sweep(gap, gap + cfg.print_piece)
    if outside is not None and abs(outside.best_height - height) > tol:
        return 0.0
    # the edge test in the left image first, in the right only where the left passes
    edge, strength = _side_scores(moved, a, b, Q, grads, min_strength, ext, ("left",))
    both = np.flatnonzero(edge)
    edge[both], right = _side_scores(moved[both], a, b, Q, grads, min_strength, ext,
                                     ("right",))
    strength[both] += right
    # each run's strongest offset; the run from 0 is the side's own edge, its peaks after a
    # dip alone looked at (a line printed near the cover's edge runs into it)
    peaks = [k for first, last in _runs(edge)
             for k in ([first + int(np.argmax(strength[first:last + 1]))] if first > 0
                       else _run_peaks(strength, first, last, cfg.print_dip)[1:])]
    for k in peaks[:cfg.print_edges]:
        if d[k] >= least:
            inside = sweep(gap, d[k] - gap)
            if inside is None or not (abs(inside.best_height - height) <= tol
                                      and inside.best_ncc >= cfg.print_min_ncc
                                      and inside.best_ncc - inside.ncc[0] >= cfg.print_margin):
                return 0.0  # no print to tell, or the strip is no cover: the side stays
        if d[k] >= cfg.print_min:
            # ...and no part of it is another surface (a page block's face below the cover)
            cuts = np.linspace(gap, d[k] - gap,
                               int(np.ceil((d[k] - 2 * gap) / cfg.print_piece)) + 1)
            parts = ([sweep(u, v) for u, v in zip(cuts[:-1], cuts[1:])] if len(cuts) > 2
                     else [])
            if any(p is not None and abs(p.best_height - height) > tol for p in parts):
                return 0.0
        beyond = sweep(d[k] + gap, d[k] + gap + cfg.print_beyond)
        if beyond is None:
            return 0.0
        if abs(beyond.best_height - height) > 0.5 * tol:
            if d[k] < least or _continued(P, moved[:k + 1], s, Q, grads, min_strength,
                                                   ext) < cfg.print_continuation:
                return 0.0
            # ...and it parts two surfaces: a strip beyond at the inside strip's own height
            # is more of it (its height a few millimetres off the cover's given one): print,
            # and the next edge is tried
            if cfg.print_apart > 0 and \
                    abs(beyond.best_height - inside.best_height) <= cfg.print_apart * tol:
                continue
            return float(d[k])
    return 0.0


def _foot_offset(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                 drop: NDArray[np.float64]) -> float:
    """How far beyond side ``s`` of cover ``P`` (4, 3), across it in the cover's plane, the
    foot of the page block below its midpoint shows (metres; the farther of the two
    images, 0 at least): where the ray from each camera through the foot (the midpoint
    moved by ``drop``, onto the desk) crosses the cover's plane. A side moved out that far
    has the foot's image on it."""
    a, b = s, (s + 1) % 4
    out = _unit(P[a] - P[(a - 1) % 4])  # outward across side s, as _moved moves it
    mid = 0.5 * (P[a] + P[b])
    foot = mid + drop
    up = -_unit(drop)
    far = 0.0
    for cam in ("left", "right"):
        centre = -np.linalg.solve(Q[cam][:, :3], Q[cam][:, 3])  # the camera's, world frame
        ray = foot - centre
        if abs(up @ ray) < 1e-12:
            continue
        crossing = centre + (up @ (mid - centre)) / (up @ ray) * ray
        far = max(far, float((crossing - mid) @ out))
    return far


def _run_peaks(strength: NDArray[np.float64], first: int, last: int,
               dip: float) -> list[int]:
    """The edges in one run of offsets ``first``..``last`` (indices into ``strength``, the
    edge strength at each offset, none negative), nearest first: its strongest, or, where
    the strength between two of its local peaks falls below ``dip`` of the weaker of them,
    each such peak (0: one edge). A run that falls from its first offset has its peak
    there (an edge before it: :func:`print_grow` drops that of the side's own). A line
    printed a few millimetres inside the cover's edge, blurred, makes one run of offsets
    with the edge."""
    if dip <= 0:
        return [first + int(np.argmax(strength[first:last + 1]))]
    peaks: list[int] = []
    top, low = first, np.inf  # the current edge's peak; the least strength since it
    for i in range(first + 1, last + 1):
        peak = strength[i] >= strength[i - 1] and (i == last or strength[i] >= strength[i + 1])
        if strength[i] > strength[top] and low >= dip * strength[top]:
            top, low = i, np.inf  # no dip since: the same edge, stronger
        elif peak and low < dip * min(strength[top], strength[i]):
            peaks.append(top)  # a dip, then another peak: another edge
            top, low = i, np.inf
        else:
            low = min(low, strength[i])
    return peaks + [top]


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The runs of True in ``mask`` (1-D), each as (first, last) index."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return list(zip(starts.tolist(), ends.tolist()))


def _continued(P: NDArray[np.float64], moved: NDArray[np.float64], s: int,
               Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
               min_strength: dict[str, float], ext: ExtentConfig) -> float:
    """How far (share of the way) the better of side ``s``'s two neighbouring sides goes
    on as an edge, in either image, from cover ``P`` (4, 3) out to the last of ``moved``
    (D, 4, 3), :func:`rovis.extent._moved`'s covers one step apart."""
    best = 0.0
    for k in (s, (s + 1) % 4):  # the corners the neighbours run out through
        for cam in ("left", "right"):
            start = geometry.project(Q[cam], P[k][None])[0]
            hit = _hits(grads[cam], start, geometry.project(Q[cam], moved[:, k]),
                        min_strength[cam], ext.max_angle_deg)
            best = max(best, float(hit.mean()))
    return best


def lateral_grow(P: NDArray[np.float64], s: int, height: float,
                 Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                 min_strength: dict[str, float], texture: dict[str, NDArray[np.float32]],
                 desk_plane: NDArray[np.float64], ext: ExtentConfig,
                 cfg: TrimConfig = TrimConfig(), *, limit: float = np.inf) -> float:
    """How far side ``s`` of cover ``P`` (4, 3) moves out to where its neighbouring sides
    end (metres; 0: not at all), for a cover whose own edge there shows no step (a picture
    with the desk's tone along it).

    Such a cover still shows its two neighbouring sides up to its corners.

    1. ``limit``, how far the maps go on at the cover's height beyond the side
       (:func:`grow_run`; the pipeline passes the smaller of that and a refused move's
       retry bound), must be at least ``cfg.lateral_run``: their spill past a cover's edge
       is 5-20 mm. The offsets looked at, every ``ext.step``, go out to ``limit`` plus
       ``cfg.lateral_ahead`` (and no farther than makes the book ``ext.max_side`` long),
       which must be ``cfg.lateral_min`` at least.
    2. Each neighbouring side, continued beyond side ``s``, is an edge
       (:func:`rovis.extent._hits`, in either image) from within ``cfg.lateral_start`` of
       the side out, misses up to ``cfg.lateral_gap`` bridged, along at least
       ``ext.min_support`` of it: its end is the end of that run, or the farthest offset
       looked at. The two ends must lie within ``cfg.lateral_spread`` of each other.
    3. The side moves to the offset of the largest gradient across it, summed over both
       images (:func:`rovis.extent._side_scores`' strength; neither need pass as an edge),
       from ``cfg.lateral_back`` short of the farther end (a corner's edge fades a pixel
       or two short of it) to ``cfg.lateral_ahead`` beyond it; at least
       ``cfg.lateral_min`` out and, where the page block below the side shows, at least
       ``cfg.print_foot_margin`` beyond where its foot would show (:func:`_foot_offset`):
       the block's upright edges go on from the corners.
    4. Stereo must not place the edge there clearly off the cover's height
       (:func:`rovis.extent._edge_height`: by more than ``ext.weak_height`` and
       ``cfg.lateral_sigmas`` of its standard deviation; a side along the epipolar lines,
       or one whose fit fails, has no height and passes), and the strip added (5 mm left
       out at either edge, then the sweep's own inset) must line up between the images at
       the cover's height (:func:`rovis.sweep.sweep_heights`: best within the trim's
       tolerance, and ``cfg.print_margin`` above the NCC at the desk's height).
    """
    a, b = s, (s + 1) % 4
    if limit < cfg.lateral_run:
        return 0.0
    room = min(limit + cfg.lateral_ahead,
               ext.max_side - max(np.linalg.norm(P[a] - P[(a - 1) % 4]),
                                  np.linalg.norm(P[b] - P[(b + 1) % 4])))
    if room < cfg.lateral_min:
        return 0.0
    d = np.arange(ext.step, room + 1e-9, ext.step)
    moved = _moved(P, s, d)  # (D, 4, 3)
    # step 2: each neighbouring side's run of edge hits, in either image
    hits = np.zeros((2, len(d)), bool)
    for cam in ("left", "right"):
        out = np.stack([geometry.project(Q[cam], moved[:, k]) for k in (a, b)])
        start = np.stack([geometry.project(Q[cam], P[k][None]) for k in (a, b)])
        hits |= _hits(grads[cam], start, out, min_strength[cam], ext.max_angle_deg)
    gap = int(round(cfg.lateral_gap / ext.step))
    ends = []
    for hit in hits:
        idx = np.flatnonzero(hit)
        if len(idx) == 0 or d[idx[0]] > cfg.lateral_start:
            return 0.0  # (a cover's own corner: its sides end there)
        breaks = np.flatnonzero(np.diff(idx) > gap + 1)
        end = int(idx[breaks[0]] if len(breaks) else idx[-1])
        if hit[:end + 1].mean() < ext.min_support:
            return 0.0
        ends.append(float(d[end]))
    if max(ends) - min(ends) > cfg.lateral_spread:
        return 0.0
    # step 3: the strongest step near the farther end
    near = np.flatnonzero((d >= max(ends) - cfg.lateral_back)
                          & (d <= max(ends) + cfg.lateral_ahead))
    if len(near) == 0:
        return 0.0
    _, strength = _side_scores(moved[near], a, b, Q, grads, min_strength, ext)
    move = float(d[near[int(np.argmax(strength))]])
    least = cfg.lateral_min
    drop = _drop(P, desk_plane)
    if _block_shows(P, s, Q, drop):
        least = max(least, _foot_offset(P, s, Q, drop) + cfg.print_foot_margin)
    if move < least:  # (no farther than limit + lateral_ahead: the offsets end there)
        return 0.0
    # step 4: the edge not clearly at another height (a shadow's on the desk)...
    z, sigma = _edge_height(_moved(P, s, np.array([move]))[0], s, Q, grads,
                            -drop / max(float(np.linalg.norm(drop)), 1e-12))
    if abs(z) > max(ext.weak_height, cfg.lateral_sigmas * sigma):
        return 0.0
    # ...and the strip added the cover's: its print lines up at the cover's height (the
    # edges left out: a step lines up at its own height, print or not)
    inner = _moved(P, s, np.array([0.005, move - 0.005]))
    strip = np.array([inner[0, a], inner[0, b], inner[1, b], inner[1, a]])
    tol = max(cfg.tolerance, cfg.tolerance_ratio * height)
    swept = sweep_heights(texture["left"], texture["right"], Q["left"], Q["right"],
                          geometry.project(Q["left"], strip), desk_plane,
                          np.arange(0.0, height + 2 * tol + 1e-9, 0.001))
    if swept is None or not (abs(swept.best_height - height) <= tol
                             and swept.best_ncc - swept.ncc[0] >= cfg.print_margin):
        return 0.0
    return move
