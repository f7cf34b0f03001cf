"""Two touching books taken for one cover, split along the seam between them (beyond the paper).

Books laid flush side by side, of nearly one width, make one quadrilateral: the outline of
both. Where the seam between them shows only faintly (two covers of one brightness), no
candidate quad of either book exists, and the union passes every check of a cover: it is
book-sized, nearly flat (two books a centimetre apart in height tilt a 30 cm union by 2°)
and on the desk. The robot would reach for the middle of two books.

Two cues tell the union from one book with a printed band across it, both from stereo:

- *the seam*: a line across the quad, parallel to two of its sides, where both images show
  a step along most of its length (:func:`seam_profile`), at the same place on the cover;
- *the step in height*: each of the two other sides is two books' edges, one each side of
  the seam; fitted in both images on its own, each half placed in 3D
  (:func:`rovis.extent._edge_height`), the halves stand at heights that differ by at least
  ``min_step``. A band printed on one cover leaves both halves at one height.

A side facing the camera is not measured (the page block below it shows edges of every
height between the desk and the cover), nor one along the epipolar lines (stereo cannot
place it). Where both sides are measured they must agree: a side may run along a taller
neighbour and take that one's edge.

Two touching books of one height leave no step; their seam alone is a printed band's. A
third cue tells them apart where their widths differ or they lie offset across the seam:

- *the jog*: a side the seam cuts is one straight edge on one book, but two on two books
  of different widths, the second stopping a few millimetres short of the first's line
  (:func:`_jogs_at`): read along the side, the edge breaks from one straight line onto
  another, by as much and the same way in both images, where the books meet.

Two books of one height and one width laid flush and aligned are not told apart. Where
the seam shows no step (the nearer book the taller and both covers of one brightness, it
hides the seam behind its top edge), a fourth cue, the detector's, can still tell them:

- *the maps' step*: the height maps (:mod:`rovis.heightmap`) read the union's two parts at
  two heights, either side of a line across it (:func:`map_step`, on the profile
  :func:`rovis.trim.height_profile` reads).

The reverse, :func:`join_halves`: one cover found as two books either side of a printed
band, the two at one height, sharing a whole side and making one rectangle, is joined.
Two touching books of one height and one size, laid flush and aligned, are joined too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rovis import geometry
from rovis.extent import _edge_height, _unit
from rovis.heightmap import row_medians
from rovis.segment.edges import Gradients
from rovis.segment.lines import intersect, refine_segment
from rovis.stereo import _point_segment_distance, flat_rectangle


@dataclass(frozen=True)
class SplitConfig:
    """Splitting a cover that is two touching books (:func:`split_union`; metres unless
    noted).

    ``enabled`` turns it on; seams are looked for every ``step`` across the cover, each
    part at least ``min_part`` long across the seam (the smallest book's side); the seam
    must show a step (the derivative across it at least each image's Canny low
    threshold) along ``min_share`` of its middle, at the best offset within ``reach_px``
    pixels of each image's line, and the two images' seams must lie within ``agree`` of
    each other along the cover; the two halves of a side (each
    placed by stereo to within ``max_sigma``) must stand at least ``min_step`` apart in
    height, and where both sides are measured, their halves within ``max_spread`` of each
    other's, every half within ``height_range`` above the desk (a book's). The
    ``max_seams`` strongest seams of each axis are tried, the strongest that steps kept.
    With ``lay``, parts whose own fits pass the pose checks but lose the step (or turn it
    round) are laid at the heights that split them, their sides but the seam moved onto the
    edges both images show within ``lay_reach`` (the detector's split step).

    With ``jog``, where no seam's sides step in height, a side across the seams that jogs
    splits the cover at the strongest seam line within ``agree`` of the jog
    (:func:`_jogs_at`): the side's edge, read within ``jog_reach_px`` of it, breaks from
    one straight line onto another, ``min_jog_px`` or more off, the same way in both
    images and within ``jog_agree_px`` of each other, within ``agree`` of each other along
    the cover, each part about ``min_part`` long or more. Every jog is tried, the largest
    first; the seam line there needs a step along ``jog_min_share`` of its middle only (two
    cues at one place). ``jog_facing``: a side facing the camera is read too (its page
    block's edges below it mostly break onto no straight line, but a clean jog there is a
    seam).

    With ``map_check`` (the detector's split step, where it has the height maps): a split
    by the step is refused where the maps read both parts (:func:`rovis.trim.map_height`)
    less than ``min_step`` apart: one cover whose sides' edges stand at two heights (a
    picture's line taken for a seam), not two books.

    With ``by_map`` (the detector's split step, where it has the height maps and no split
    by a seam was kept): a cover the maps read at two heights, either side of a line
    across it, is split there (:func:`map_step`, which reads ``min_part``, ``min_step`` and
    the ``map_*`` settings), where both parts, each laid at its height, pass the pose
    checks and neither lies over another found book.

    The reverse (:func:`join_halves`, with ``join``): two books whose mean heights lie
    within ``join_step`` of each other, sharing a whole side (both its ends within
    ``join_touch``) and lying either side of it, whose outer corners make a rectangle
    (each angle within ``join_angle_deg`` of 90°, the shared corners within
    ``join_touch`` of its sides), are one cover cut at a printed band.
    """

    enabled: bool = True
    step: float = 0.001
    min_part: float = 0.085
    min_share: float = 0.7
    reach_px: float = 2.0
    agree: float = 0.006
    min_step: float = 0.005
    max_sigma: float = 0.004
    max_spread: float = 0.004
    max_seams: int = 3
    height_range: tuple[float, float] = (0.003, 0.08)
    lay: bool = True
    lay_reach: float = 0.01
    join: bool = True
    join_touch: float = 0.004
    join_step: float = 0.003
    join_angle_deg: float = 8.0
    jog: bool = True
    min_jog_px: float = 2.0  # build/t1b's scene 6: 2.35 and 2.97 px (docs/stereo.md)
    jog_facing: bool = True
    jog_min_share: float = 0.4  # build/t1c's scene 1: 0.60 and 0.48 (docs/stereo.md)
    jog_agree_px: float = 1.0
    jog_reach_px: float = 6.0
    map_check: bool = True
    by_map: bool = True
    map_known: float = 0.5
    map_reduction: float = 0.5
    map_agree: float = 0.5
    map_tolerance: float = 0.0035  # the maps sweep every 3 mm (float32 heights)

    def __post_init__(self) -> None:
        problems = [name for name, ok in (
            ("lay_reach", self.lay_reach >= 0),
            ("map_known", 0 <= self.map_known <= 1),
            ("map_reduction", 0 <= self.map_reduction <= 1),
            ("map_agree", 0 <= self.map_agree <= 1),
            ("map_tolerance", self.map_tolerance > 0),
            ("join_touch", self.join_touch >= 0), ("join_step", self.join_step >= 0),
            ("join_angle_deg", 0 <= self.join_angle_deg < 90),
            ("min_jog_px", self.min_jog_px > 0), ("jog_agree_px", self.jog_agree_px >= 0),
            ("jog_min_share", 0 <= self.jog_min_share <= 1),
            ("jog_reach_px", self.jog_reach_px > 0)) if not ok]
        if problems:
            raise ValueError(f"split: bad {', '.join(problems)} (lay_reach, join_touch, "
                             "join_step and jog_agree_px at least 0; join_angle_deg in "
                             "[0, 90); min_jog_px, jog_reach_px and map_tolerance positive; "
                             "jog_min_share, map_known, map_reduction and map_agree in "
                             "[0, 1])")


def seam_profile(grad: Gradients, corners: NDArray[np.float64], k: int, t: NDArray[np.float64],
                 threshold: float, *, reach_px: float = 2.0, trim: float = 0.15,
                 ) -> NDArray[np.float64]:
    """For lines across quad ``corners`` (4, 2) parallel to its sides ``k`` and ``k + 2``,
    the share of each line's middle where the derivative across it reaches ``threshold``.

    The line at ``t`` joins the points a fraction ``t`` of the way from side ``k`` to side
    ``k + 2`` along the two other sides; it is sampled every pixel over its middle (``trim``
    of its length left out at either end, where the corners' own edges are), at offsets
    within ``reach_px`` along the cover; the best offset counts.

    Returns
    -------
    share, offset : ndarray, shape (len(t),) each
        The share in [0, 1] at each line's best offset, and that offset (px, along
        ``(-d_y, d_x)`` for ``d`` the mean direction from side ``k + 3``'s end of the lines
        to side ``k + 1``'s).
    """
    c = np.asarray(corners, dtype=np.float64)
    a0, b0 = c[k], c[(k + 1) % 4]  # side k runs a0 -> b0
    a1, b1 = c[(k + 3) % 4], c[(k + 2) % 4]  # side k + 2, the same way round
    t = np.asarray(t, dtype=np.float64)
    p = a0 + t[:, None] * (a1 - a0)  # (T, 2): the seam's ends
    q = b0 + t[:, None] * (b1 - b0)
    length = float(np.median(np.linalg.norm(q - p, axis=1)))
    s = np.arange(trim * length, (1 - trim) * length, 2.0) / max(length, 1e-9)
    if len(s) == 0:
        return np.zeros(len(t)), np.zeros(len(t))
    d = _unit(0.5 * (b0 + b1) - 0.5 * (a0 + a1))  # along the seam, on average
    n = np.array([-d[1], d[0]])
    offsets = np.arange(-reach_px, reach_px + 1e-9, 0.5)
    pts = p[:, None, :] + s[None, :, None] * (q - p)[:, None, :]  # (T, S, 2)
    x = pts[:, None, :, 0] + offsets[None, :, None] * n[0]  # (T, O, S)
    y = pts[:, None, :, 1] + offsets[None, :, None] * n[1]
    gx, gy = grad.sample(x, y)
    share = (np.abs(gx * n[0] + gy * n[1]) >= threshold).mean(axis=2)  # (T, O)
    best = np.argmax(share, axis=1)
    return share[np.arange(len(t)), best], offsets[best]


# the two parts of a split cover, each its corners (4, 2) per camera: the part at side k
# of the cover first, then the part at side k + 2
Parts = tuple[dict[str, NDArray[np.float64]], dict[str, NDArray[np.float64]]]


class Split(NamedTuple):
    """A cover split into two books (:func:`split_union_heights`).

    Attributes
    ----------
    parts : Parts
        Each part's corners (4, 2) per camera, in the cover's corner order.
    heights : (float, float)
        Per part, metres above the desk: the height its edges along the two cut sides
        stand at (the mean over the sides measured); for a split by the jog, the cover's
        own (the mean of its triangulated corners) for both.
    seams : (int, int)
        Per part, the index of its side on the seam (side s runs from corner s to s + 1).
    by_step : bool
        Split by the step in height (else by the jog, :func:`_jogs_at`).
    """

    parts: Parts
    heights: tuple[float, float]
    seams: tuple[int, int]
    by_step: bool


def split_union(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
                grads: dict[str, Gradients], strength: dict[str, float],
                desk_plane: NDArray[np.float64], cfg: SplitConfig = SplitConfig(), *,
                down: tuple[float, float] = (0.0, 1.0)) -> Parts | None:
    """A stereo pair's cover (corners (4, 2) per camera, eq. 1 order) split into two
    touching books' covers, or None where it is one book.

    For each pair of opposite sides, the seams are the lines parallel to them with a step
    in both images (:func:`seam_profile`'s peaks), a part at least ``cfg.min_part`` long
    on either side; each image's seam line is fitted to its edge (:func:`refine_segment`)
    and cut by the other two sides for the parts' corners. The strongest seam where those
    sides step in height by ``cfg.min_step`` or more (see the module's notes) gives the
    parts; failing that (with ``cfg.jog``), the seam where a side jogs (:func:`_jogs_at`).

    Parameters
    ----------
    corners : dict camera -> ndarray, shape (4, 2)
        Ideal pixels in each image.
    Q : dict camera -> ndarray, shape (3, 4)
    grads : dict camera -> Gradients
    strength : dict camera -> float
        The derivative a seam's step must reach (the Canny low threshold), per camera.
    desk_plane : ndarray, shape (4,)
        ``[nx, ny, nz, d]`` (world, normal up).
    down : (float, float)
        The image direction towards the camera's side of the desk: a side whose outward
        normal points this way faces the camera.

    Returns
    -------
    (dict, dict) or None
        Each part's corners (4, 2) per camera, in the cover's corner order.
    """
    found = split_union_heights(corners, Q, grads, strength, desk_plane, cfg, down=down)
    return None if found is None else found.parts


def split_union_heights(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
                        grads: dict[str, Gradients], strength: dict[str, float],
                        desk_plane: NDArray[np.float64], cfg: SplitConfig = SplitConfig(), *,
                        down: tuple[float, float] = (0.0, 1.0)) -> Split | None:
    """:func:`split_union`, with what placed the parts (:class:`Split`). Where no seam's
    sides step in height, the seam where a side jogs (``cfg.jog``, :func:`_jogs_at`; the
    largest jog whose seam shows in both images and whose parts fit) splits the cover.

    Parameters are :func:`split_union`'s.
    """
    P = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    if not np.all(np.isfinite(P)):
        return None
    seams = []  # (score, k, per camera (t, offset)): every candidate seam, both axes
    profiles, spans = {}, {}  # per axis k: t and each camera's seam_profile; the span
    for k in (0, 1):
        # across the seam: from side k to side k + 2, along sides k + 1 and k + 3
        span = 0.5 * (np.linalg.norm(P[(k + 2) % 4] - P[(k + 1) % 4])
                      + np.linalg.norm(P[k] - P[(k + 3) % 4]))
        if span < 2 * cfg.min_part:
            continue
        t = np.arange(cfg.min_part, span - cfg.min_part + 1e-9, cfg.step) / span
        found = {cam: seam_profile(grads[cam], corners[cam], k, t, strength[cam],
                                   reach_px=cfg.reach_px) for cam in corners}
        profiles[k], spans[k] = (t, found), span
        prof = {cam: share for cam, (share, _) in found.items()}
        # the images' seams may lie a few millimetres apart along the cover (the
        # interpolation is in each image, the perspective differs a little): the best of
        # the right's within ``agree`` of each of the left's
        w = max(int(round(cfg.agree / cfg.step)), 0)
        right = np.array([prof["right"][max(i - w, 0):i + w + 1].max() for i in range(len(t))])
        score = np.minimum(prof["left"], right)
        # the local maxima that pass, a print's edge among them (a photo's title band):
        # the step in height picks the seam
        padded = np.r_[-np.inf, score, -np.inf]
        peaks = np.flatnonzero((score >= cfg.min_share) & (score >= padded[:-2])
                               & (score > padded[2:]))
        for i in peaks[np.argsort(-score[peaks], kind="stable")][:cfg.max_seams].tolist():
            j = _right_seam(prof["right"], i, w)
            seams.append((float(score[i]), k, {"left": (t[i], found["left"][1][i]),
                                               "right": (t[j], found["right"][1][j])}))
    for _, k, t_seam in sorted(seams, key=lambda item: -item[0]):  # the strongest first
        parts = _parts(corners, grads, k, t_seam)
        if parts is not None:
            heights = _step_in_height(corners, parts, k, Q, grads, desk_plane, cfg, down=down)
            if heights is not None:
                return Split(parts, heights, ((k + 2) % 4, k), True)
    if not cfg.jog:
        return None
    # no step in height: a side's jog places the seam, at the strongest seam line within
    # ``agree`` of the jog in the left image, the right's nearest it; the largest jog
    # first (build/t1c's scene 27: one side's larger jog lies near a corner, the other
    # side's at the seam)
    jogged = []
    w = max(int(round(cfg.agree / cfg.step)), 0)
    least = min(cfg.jog_min_share, cfg.min_share)  # a jog asks less of the seam line, not more
    for k, (t, found) in profiles.items():
        if not all(np.any(share >= least) for share, _ in found.values()):
            continue  # no seam line in an image: nothing to cut at
        # each part about ``min_part`` long or more: a neighbour's edge near a corner is
        # no jog (``t`` spans the cover's middle, less ``min_part`` at either end)
        jogged += [(size, k, where) for size, where in
                   _jogs_at(corners, k, grads, cfg, tol=cfg.agree / spans[k], down=down)
                   if all(t[0] <= v <= t[-1] for v in where.values())]
    for _, k, where in sorted(jogged, key=lambda item: -item[0]):
        t, found = profiles[k]
        (share_l, off_l), (share_r, off_r) = found["left"], found["right"]
        i = int(np.argmin(np.abs(t - where["left"])))
        window = np.arange(max(i - w, 0), min(i + w + 1, len(t)))
        i = int(window[np.argmax(share_l[window])])
        j = _right_seam(share_r, i, w)
        if min(share_l[i], share_r[j]) < least:
            continue
        parts = _parts(corners, grads, k, {"left": (t[i], off_l[i]), "right": (t[j], off_r[j])})
        if parts is not None:
            h = float(np.mean(geometry.plane_distance(desk_plane, P)))
            return Split(parts, (h, h), ((k + 2) % 4, k), False)
    return None


def _right_seam(share: NDArray[np.float64], i: int, w: int) -> int:
    """The right image's seam for the left's at index ``i``: of the right's lines within
    ``w`` indices of it that score within 0.05 of the best there (``share``, the right's
    :func:`seam_profile`), the nearest ``i`` (the same edge of a page block's face, not
    its other one)."""
    window = np.arange(max(i - w, 0), min(i + w + 1, len(share)))
    near_best = window[share[window] >= share[window].max() - 0.05]
    return int(near_best[np.argmin(np.abs(near_best - i))])


def _parts(corners: dict[str, NDArray[np.float64]], grads: dict[str, Gradients], k: int,
           t_seam: dict[str, tuple[float, float]]) -> Parts | None:
    """The two parts of a cover cut at the seam of axis ``k`` at ``t_seam`` (per camera
    :func:`seam_profile`'s ``t`` and offset; :func:`_seam_corners`), or None where a
    seam does not cut the sides."""
    parts: Parts = ({}, {})
    for cam, c in corners.items():
        seam = _seam_corners(grads[cam], c, k, *t_seam[cam])
        if seam is None:
            return None
        near, far = c.copy(), c.copy()  # the part at side k, the part at side k + 2
        near[(k + 3) % 4], near[(k + 2) % 4] = seam
        far[k], far[(k + 1) % 4] = seam
        parts[0][cam], parts[1][cam] = near, far
    return parts


class MapStep(NamedTuple):
    """Where the height maps read a cover at two heights (:func:`map_step`).

    Attributes
    ----------
    k : int
        The step lies between strips ``k - 1`` and ``k`` of the profile.
    heights : (float, float)
        The median height of strips ``0 .. k - 1`` and of strips ``k ..`` (metres above the
        desk).
    reduction : float
        How much better two heights explain the profile than one, 0 to 1: one less the
        summed distance of each part's strips from its median over that of all strips from
        theirs.
    """

    k: int
    heights: tuple[float, float]
    reduction: float


def map_step(profile: NDArray[np.float64], strip: float,
             cfg: SplitConfig = SplitConfig()) -> MapStep | None:
    """The step between two touching books in their union's height profile, or None.

    Two books of different heights laid flush, their covers of one tone, may show no seam
    in either image (the taller one's edge hides the line between them), but the height
    maps (:mod:`rovis.heightmap`) read each at its own height. The step is put where two
    heights, each part's median, explain the profile best: the largest fall in the summed
    distance of the strips from their part's height, among the places where each part is
    known over ``cfg.map_known`` of its strips and the two heights lie ``cfg.min_step``
    apart or more (where several places tie, as a seam in a run of unknown strips, the
    middle one). There each part must be ``cfg.min_part`` long or more (the maps carry a
    cover's height 5-20 mm past its edge: a single cover's profile steps at its ends), the
    fall ``cfg.map_reduction`` of the one-height distance or more, and each part's known
    strips within ``cfg.map_tolerance`` of its height over ``cfg.map_agree`` of them (a
    part over a page block and a shadow reads every height).

    Parameters
    ----------
    profile : ndarray, shape (S,)
        Heights of strips across the cover, each ``strip`` wide (metres above the desk,
        NaN unknown; :func:`rovis.trim.height_profile`).
    strip : float
        The strips' width, metres.
    cfg : SplitConfig
        ``min_part``, ``min_step``, ``map_known``, ``map_reduction``, ``map_agree``,
        ``map_tolerance``.

    Returns
    -------
    MapStep or None
        None where the maps read one height, or no step clear enough.
    """
    profile = np.asarray(profile, dtype=np.float64)
    n = len(profile)
    known = np.isfinite(profile)
    if not known.any() or strip <= 0:
        return None
    spread = float(np.abs(profile[known] - np.median(profile[known])).sum())
    if spread <= 0.0:
        return None
    # every place k (the step between strips k - 1 and k) at once: each part as a row of
    # the profile, NaN beyond it (a Python loop over the places cost ~2 ms a profile)
    k = np.arange(1, n)
    before = np.cumsum(known)[:-1]  # known strips in the part before each place
    after = int(np.count_nonzero(known)) - before
    usable = (before > 0) & (after > 0) & (before >= cfg.map_known * k) \
        & (after >= cfg.map_known * (n - k))
    k, before, after = k[usable], before[usable], after[usable]
    head = np.where(np.arange(n) < k[:, None], profile, np.nan)  # (K, S)
    tail = np.where(np.arange(n) >= k[:, None], profile, np.nan)
    ha, hb = row_medians(head, before), row_medians(tail, after)
    deviation = (np.nansum(np.abs(head - ha[:, None]), axis=1)
                 + np.nansum(np.abs(tail - hb[:, None]), axis=1))
    apart = np.abs(ha - hb) >= cfg.min_step
    if not apart.any():
        return None
    k, ha, hb = k[apart], ha[apart], hb[apart]
    reduction = 1.0 - deviation[apart] / spread
    tied = reduction >= reduction.max() - 1e-12
    first = last = int(np.argmax(tied))
    # the run of places tied with the first best, next to each other: its middle
    while last + 1 < len(k) and tied[last + 1] and k[last + 1] == k[last] + 1:
        last += 1
    i = (first + last) // 2
    best = MapStep(int(k[i]), (float(ha[i]), float(hb[i])), float(reduction[i]))
    # where the step is, not where a step is allowed: a short run of another height at an
    # end moves no step inward onto the cover
    if best.reduction < cfg.map_reduction or min(best.k, n - best.k) * strip < cfg.min_part - 1e-9:
        return None
    for part, h in ((profile[:best.k], best.heights[0]), (profile[best.k:], best.heights[1])):
        part = part[np.isfinite(part)]
        if np.mean(np.abs(part - h) <= cfg.map_tolerance) < cfg.map_agree:
            return None
    return best


def join_halves(A: NDArray[np.float64], B: NDArray[np.float64], desk_plane: NDArray[np.float64],
                cfg: SplitConfig = SplitConfig()) -> NDArray[np.float64] | None:
    """One cover from two found books that are its halves, or None.

    A photo's title band or a printed stripe across a cover is a step as clear as the
    cover's own edge: the segmentation may find the two parts either side of it as two
    covers, and stereo places both at the cover's height. Two books that are halves of one
    lie at one height (within ``cfg.join_step``), share a whole side (both its ends
    within ``cfg.join_touch``), lie either side of it, and together make a rectangle
    (each corner's angle within ``cfg.join_angle_deg`` of 90°, the shared side's ends
    within ``cfg.join_touch`` of the union's sides: no kink where the parts meet). Two
    books of one height and one size, laid flush and aligned, pass these tests too
    (:func:`split_union` cannot tell them from a band either).

    Parameters
    ----------
    A, B : ndarray, shape (4, 3)
        The two covers' world corners, each in cyclic order (metres).
    desk_plane : ndarray, shape (4,)
        ``[nx, ny, nz, d]`` (world, normal up).
    cfg : SplitConfig

    Returns
    -------
    ndarray, shape (4, 3) or None
        The union's corners in cyclic order, starting with ``A``'s corners away from the
        shared side.
    """
    h = geometry.plane_distance(desk_plane, np.vstack([A, B]))
    if abs(h[:4].mean() - h[4:].mean()) > cfg.join_step:
        return None
    for s in range(4):
        a0, a1 = A[s], A[(s + 1) % 4]
        for t in range(4):
            for m0, m1 in (((t + 1) % 4, t), (t, (t + 1) % 4)):  # B's side either way round
                if max(np.linalg.norm(a0 - B[m0]), np.linalg.norm(a1 - B[m1])) > cfg.join_touch:
                    continue
                # B's corners away from the shared side: the neighbour of each shared one
                far0 = B[(m0 + (m0 - m1)) % 4]
                far1 = B[(m1 + (m1 - m0)) % 4]
                # ...across the shared side from A's (not a half of A lying on A)
                if (far0 - a0) @ (A[(s + 3) % 4] - a0) >= 0 or \
                        (far1 - a1) @ (A[(s + 2) % 4] - a1) >= 0:
                    continue
                U = np.array([A[(s + 2) % 4], A[(s + 3) % 4], far0, far1])
                if flat_rectangle(U, side_range=(0.0, np.inf),
                                  max_skew_deg=cfg.join_angle_deg)[0] and all(
                        _off_line(p, U[i], U[j]) <= cfg.join_touch
                        for p, i, j in ((a0, 1, 2), (a1, 3, 0))):
                    return U
    return None


def piece_of(U: NDArray[np.float64], B: NDArray[np.float64], desk_plane: NDArray[np.float64],
             touch: float, step: float) -> bool:
    """Whether found book ``B`` is a piece of cover ``U``: the part of one cover beyond a
    printed band, found on its own, that a side of the other part grew over.

    ``B`` lies at ``U``'s height (its mean within ``step``), and each of its corners, laid
    on ``U``'s plane, lies within ``touch`` of ``U``'s outline. A piece spans the cover from
    side to side, so its corners are the cover's own or lie on its sides; a neighbouring
    book a grown side went over is narrower or wider than the cover, or lies beside it,
    and leaves corners off them. (:func:`join_halves` asks the same of two halves that
    touch; here they may overlap, each refined on its own, and a few millimetres apart at
    the corners.)

    Parameters
    ----------
    U : ndarray, shape (4, 3)
        The cover's world corners in cyclic order (metres), a rectangle parallel to the desk.
    B : ndarray, shape (4, 3)
        The found book's world corners (metres), in any order.
    desk_plane : ndarray, shape (4,)
        ``[nx, ny, nz, d]`` (world, normal up).
    touch, step : float
        Metres.

    Returns
    -------
    bool
    """
    d = _to_outline(U, B, desk_plane, step)
    return d is not None and bool(np.all(d <= touch))


def beside(B: NDArray[np.float64], F: NDArray[np.float64], desk_plane: NDArray[np.float64],
           touch: float, step: float) -> bool:
    """Whether book ``B`` (4, 3) lies beside found book ``F`` (4, 3) as the other part of
    its cover: at its height (means within ``step``) with two corners or more, laid on
    ``F``'s plane, within ``touch`` of ``F``'s outline (metres)."""
    d = _to_outline(F, B, desk_plane, step)
    return d is not None and int(np.count_nonzero(d <= touch)) >= 2


def _to_outline(U: NDArray[np.float64], B: NDArray[np.float64], desk_plane: NDArray[np.float64],
                step: float) -> NDArray[np.float64] | None:
    """Each corner of ``B`` (4, 3), laid on ``U``'s plane, its distance (4,) to ``U``'s
    outline (metres); None where their mean heights differ by more than ``step``."""
    h = geometry.plane_distance(desk_plane, np.vstack([U, B]))
    if abs(h[:4].mean() - h[4:].mean()) > step:
        return None
    up = _unit(np.asarray(desk_plane[:3], np.float64))
    c = U.mean(axis=0)
    B = B - np.outer((B - c) @ up, up)  # onto the cover's plane
    # each corner's distance to each of U's sides (segments), (4 corners, 4 sides)
    d = _point_segment_distance(B[:, None], U[None], np.roll(U, -1, axis=0)[None])
    return d.min(axis=1)


def _off_line(p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """The distance of point ``p`` from the line through ``a`` and ``b`` (3-D)."""
    d = _unit(b - a)
    r = p - a
    return float(np.linalg.norm(r - (r @ d) * d))


def _seam_corners(grad: Gradients, c: NDArray[np.float64], k: int, t: float, offset: float,
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The seam's ends in one image: the line at ``t``, moved by ``offset`` across it
    (:func:`seam_profile`'s best) and fitted to its edge where that succeeds (within 1 px),
    cut by sides ``k + 3`` and ``k + 1``; None where they do not cut it."""
    p = c[k] + t * (c[(k + 3) % 4] - c[k])
    q = c[(k + 1) % 4] + t * (c[(k + 2) % 4] - c[(k + 1) % 4])
    d = _unit(0.5 * (c[(k + 1) % 4] + c[(k + 2) % 4]) - 0.5 * (c[k] + c[(k + 3) % 4]))
    n = np.array([-d[1], d[0]])
    line = (0.5 * (p + q) + offset * n, _unit(q - p))
    # the middle only, as the seam was found: its ends run into the sides' own edges; a
    # page block's face between two books' edges may leave no single edge to fit
    fit = refine_segment(grad, p + 0.15 * (q - p) + offset * n, q - 0.15 * (q - p) + offset * n,
                         half_width=1.5)
    if fit is not None and abs((fit[0] - line[0]) @ n) <= 1.0:
        line = fit
    ends = []
    for a, b in ((c[(k + 3) % 4], c[k]), (c[(k + 1) % 4], c[(k + 2) % 4])):
        x = intersect(line[0], line[1], a, _unit(b - a))
        if x is None or np.linalg.norm(x - (p if not ends else q)) > 10.0:
            return None
        ends.append(x)
    return ends[0], ends[1]


def _step_in_height(corners: dict[str, NDArray[np.float64]], parts: Parts, k: int,
                    Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                    desk_plane: NDArray[np.float64], cfg: SplitConfig, *,
                    down: tuple[float, float]) -> tuple[float, float] | None:
    """The heights the sides the seam cuts (``k + 1`` and ``k + 3``) stand at either side
    of it (metres above the desk, per part the mean over the measured sides), or None
    unless each measured side's two halves (one per part) lie ``cfg.min_step`` apart or
    more, the same way round, within ``cfg.height_range``, and two measured sides' halves
    within ``cfg.max_spread`` of each other's."""
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    placed = [geometry.triangulate(Q["left"], Q["right"], part["left"], part["right"])
              for part in parts]
    if not all(np.all(np.isfinite(P)) for P in placed):
        return None
    steps = []
    for s in ((k + 1) % 4, (k + 3) % 4):
        if _faces_camera(corners, s, down):
            continue
        halves = []
        for P in placed:
            z, sigma = _edge_height(P, s, Q, grads, up)
            if sigma > cfg.max_sigma:
                break
            # above the desk: the side's midpoint's distance to it, moved by the edge's z
            mid = 0.5 * (P[s] + P[(s + 1) % 4])
            halves.append(float(geometry.plane_distance(desk_plane, mid)[0]) + z)
        if len(halves) == 2:
            steps.append(halves)
    if not steps:
        return None
    h = np.array(steps)  # (sides, 2): each measured side's heights, near part first
    step = h[:, 0] - h[:, 1]
    if np.any(h < cfg.height_range[0]) or np.any(h > cfg.height_range[1]) \
            or np.any(np.abs(step) < cfg.min_step) or np.any(np.sign(step) != np.sign(step[0])) \
            or np.any(np.ptp(h, axis=0) > cfg.max_spread):
        return None
    near, far = h.mean(axis=0)
    return float(near), float(far)


def _jogs_at(corners: dict[str, NDArray[np.float64]], k: int, grads: dict[str, Gradients],
             cfg: SplitConfig, *, tol: float, down: tuple[float, float],
             ) -> list[tuple[float, dict[str, float]]]:
    """Where each side across the seams of axis ``k`` (``k + 1`` and ``k + 3``) jogs in both
    images: per side that does, the jog (px, the smaller image's) and per camera the point
    as :func:`seam_profile`'s ``t`` (the fraction of the way from side ``k`` to side
    ``k + 2`` along the side).

    One book's side is one straight edge, whatever is printed across the cover; two
    touching books of different widths, or laid offset across the seam, show one edge
    each, parallel and a few pixels apart. Along the side, the edge's offset across it is
    read every pixel of its middle 90 % (:func:`_edge_offsets`, within
    ``cfg.jog_reach_px``); where those offsets break from one straight line onto another
    (:func:`_step_along`), it jogs. It counts where the second line lies ``cfg.min_jog_px``
    or more off the first there, the same way in both images and within
    ``cfg.jog_agree_px`` of each other, at points within ``tol`` (a fraction of the way)
    of each other. A side facing the camera is asked only with ``cfg.jog_facing``: its
    page block shows several edges below it, which seldom make two clean runs.
    """
    found: list[tuple[float, dict[str, float]]] = []
    for s in ((k + 1) % 4, (k + 3) % 4):
        if not cfg.jog_facing and _faces_camera(corners, s, down):
            continue
        jogs, where = [], {}
        for cam, c in corners.items():
            a, b = c[s], c[(s + 1) % 4]
            length = float(np.linalg.norm(b - a))
            inward = np.array([a[1] - b[1], b[0] - a[0]]) / max(length, 1e-9)
            if inward @ (c.mean(axis=0) - a) < 0:
                inward = -inward
            step = _step_along(*_edge_offsets(grads[cam], a, b, inward, cfg.jog_reach_px))
            if step is None:
                break
            # side k + 1 runs from side k to side k + 2, side k + 3 the other way
            where[cam] = step[0] / length if s == (k + 1) % 4 else 1.0 - step[0] / length
            jogs.append(step[1])
        if len(jogs) < len(corners):
            continue
        jog = min(abs(j) for j in jogs)
        if jog >= cfg.min_jog_px and len({np.sign(j) for j in jogs}) == 1 \
                and np.ptp(jogs) <= cfg.jog_agree_px and np.ptp(list(where.values())) <= tol:
            found.append((jog, where))
    return found


def _edge_offsets(grad: Gradients, a: NDArray[np.float64], b: NDArray[np.float64],
                  inward: NDArray[np.float64], reach_px: float,
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Along side ``a``-``b`` every pixel (its ends' 5 % left out), the offset (px along
    ``inward``, within ``reach_px``) of the strongest derivative across it: the positions
    along the side (px from ``a``) and the offsets, NaN where the derivative is under half
    the side's median peak (no edge there)."""
    length = float(np.linalg.norm(b - a))
    t = np.arange(0.05 * length, 0.95 * length, 1.0)
    if len(t) == 0:
        return t, t.copy()
    offsets = np.arange(-reach_px, reach_px + 0.5, 1.0)
    pts = a + t[:, None] * (b - a) / length
    gx, gy = grad.sample(pts[:, None, 0] + offsets[None, :] * inward[0],
                         pts[:, None, 1] + offsets[None, :] * inward[1])
    g = np.abs(gx * inward[0] + gy * inward[1])  # (T, O)
    best = np.argmax(g, axis=1)
    peak = g[np.arange(len(t)), best]
    return t, np.where(peak >= 0.5 * np.median(peak), offsets[best], np.nan)


def _step_along(t: NDArray[np.float64], e: NDArray[np.float64], min_run: int = 10,
                max_rms: float = 1.0) -> tuple[float, float] | None:
    """Where offsets ``e`` along ``t`` (NaN: none) break from one straight line onto
    another: the break that leaves the least squared residual about a line fitted to each
    run (each ``min_run`` samples or more), and the second line's offset there less the
    first's; None where too few samples, or a run strays from its line by more than
    ``max_rms`` (RMS): no two edges there.

    Lines, not levels: a quad's side fitted over two books' edges runs at a small angle to
    each (prefix sums give every break's fits at once).
    """
    ok = np.isfinite(e)
    t, e = t[ok], e[ok]
    n = len(e)
    if n < 2 * min_run:
        return None
    a0, b0, r0 = _prefix_lines(t, e)  # index i: the line through samples [0, i]
    a1, b1, r1 = (v[::-1] for v in _prefix_lines(t[::-1], e[::-1]))  # i: through [i, n)
    cut = np.arange(min_run, n - min_run + 1)  # the first run is [0, cut), the second [cut, n)
    j = int(cut[np.argmin(r0[cut - 1] + r1[cut])])
    if max(r0[j - 1] / j, r1[j] / (n - j)) > max_rms ** 2:
        return None
    at = 0.5 * (t[j - 1] + t[j])
    return float(at), float((a1[j] + b1[j] * at) - (a0[j - 1] + b0[j - 1] * at))


def _prefix_lines(t: NDArray[np.float64], e: NDArray[np.float64],
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """For every prefix of the samples (``e`` at ``t``), the least-squares line
    ``alpha + beta t`` through them and its sum of squared residuals: three arrays, index
    i for the prefix ending at sample i (beta 0 where it is one sample)."""
    n, st, se, stt, ste, see = (np.cumsum(v) for v in (np.ones_like(t), t, e, t * t, t * e,
                                                       e * e))
    det = n * stt - st * st
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(det > 0, (n * ste - st * se) / det, 0.0)
    alpha = (se - beta * st) / n
    return alpha, beta, np.maximum(see - alpha * se - beta * ste, 0.0)


def _faces_camera(corners: dict[str, NDArray[np.float64]], s: int,
                  down: tuple[float, float]) -> bool:
    """Whether side ``s`` faces the camera in either image: its outward normal points
    ``down`` the image (its page block shows below it)."""
    for c in corners.values():
        d = _unit(c[(s + 1) % 4] - c[s])
        n = np.array([-d[1], d[0]])
        if n @ (c.mean(axis=0) - 0.5 * (c[s] + c[(s + 1) % 4])) > 0:
            n = -n  # outward
        if n @ np.asarray(down) > 0.05:
            return True
    return False
