"""Cover extent in 3D: each side of a reconstructed cover moved to the cover's real edge.

Beyond the paper. Two segmentation errors leave a cover's corners centimetres off while
every side still sits on a strong edge, so no test in one image can catch them:

- *partial cover*: a title band or printed block across the cover makes an edge as strong
  as the cover's own, and the quad stops there;
- *over-reach*: a side lies on a line beyond the cover's end (a shadow, the desk's grain, a
  neighbouring book's edge), and the quad takes in a strip of desk.

The two images together tell. The cover's plane is known from the triangulated corners
(parallel to the desk), so any side can be moved in that plane and projected into both
images. A side moved outward (:func:`_grow_side`) is kept where its two neighbouring sides
go on carrying edges in both images up to it and it is an edge itself in both; beyond a
real cover edge the neighbours' lines run over the desk, a page block or another book,
where no edge follows them. A side whose neighbours carry no edge next to it, over
``min_gap`` or more in both images (:func:`_shrink_side`), is moved inward to where their
edges start.

A side facing the camera must not end on its page block (the block's lines pass every test
of a cover edge, and such a side often runs along the epipolar lines, where stereo cannot
place it): it grows only beyond the block's foot in the image. A side grows only where both
its neighbours are the cover's own edges: a quad cut short on two adjacent sides (a printed
block in a corner) stays as it is. The search starts from the DLT corners (eq. 5), whatever
the pipeline's triangulation option.

Two lines look like a cover's edge in each image and are told apart by their height, by
stereo (:func:`_edge_height`: the side fit in each image on its own, the two fits
intersected): a thin book's cast shadow beyond its end continues its sides and ends in an
edge, but on the desk, so a side does not grow onto an edge stereo puts nearer the desk
than the cover (on a side whose page block is hidden: where the block shows, its foot is
such an edge). And a side that stereo puts at the cover's height is the cover's edge or a
print on it, not the desk a quad over-reached onto, so it is not pulled in. Where stereo
cannot tell (a side along the epipolar lines, a fit that fails), the moves stand.

:func:`grow_frame` grows a cover found as the frame printed inside its edges, where no
side's neighbours continue: each side moves out to the edge beyond a margin of the
cover's tone.

:func:`settle_facing_sides` and :func:`settle_block_sides` settle a side whose page block
shows, where the two images took different edges of it (the block's foot, boards, page
rows, the cover's own edge): at the height the cover's other sides give, the images'
lines must meet.

:func:`complete_open` places the sides of a cover candidate that no image saw (a three-,
two- or opposite-sided candidate of the segmentation) the same way: its seen sides give
the cover's height and orientation, and each unseen side goes where both images show a
step at once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis import geometry
from rovis.segment.edges import Gradients
from rovis.segment.boundary import Fit, inner_edges, refine_sides
from rovis.segment.lines import intersect, refine_segment
from rovis.sweep import SweepConfig, _plane_frame, on_plane, side_strip_ncc


@dataclass(frozen=True)
class ExtentConfig:
    """Limits of the side search (metres unless noted)."""

    grow: bool = True
    shrink: bool = True
    step: float = 0.001
    min_grow: float = 0.008  # a smaller move finds the same side again
    min_gap: float = 0.015  # a side's neighbours without edges this far: it is beyond the cover
    max_side: float = 0.45  # no book is larger (as DetectConfig.max_cover_side)
    reach: float = 0.01  # the neighbours' edges must reach the moved side: half of this
    min_support: float = 0.7  # of the samples, in both images: moved side and its neighbours
    # ...or, where no move passes that, a moved side that is an edge along weak_support in
    # both images (a picture cover's edge where the picture has the desk's tone), if stereo
    # puts that edge within weak_height of the cover's height (_grow_side)
    weak_support: float = 0.5
    weak_height: float = 0.004
    max_angle_deg: float = 25.0  # gradient this close to across the line counts
    gap_edge_ratio: float = 0.35  # of a side's median edge strength: where its edge is missing
    height_check: bool = True  # stereo height of a moved side's edge: see _on_desk, _holds_side
    height_sigma: float = 0.5  # ...asked where stereo places the edge this well, of the cover's height
    # a side the shrink would pull in stays where it lies on an edge at the cover's height:
    # within height_band (or height_band_ratio of that height, if larger) and nearer it than
    # the desk; one well below, or well above beyond a side facing away from the cameras,
    # is a neighbour's the side reaches onto (_holds_side)
    height_band: float = 0.008
    height_band_ratio: float = 0.25
    # A cover found as the frame printed inside it (grow_frame): each side moved out to
    # the nearest edge within frame_min-frame_max where the margin has the cover's tone
    # inside the side and what lies beyond differs by more than frame_tone (of the
    # brighter, or 4 grey levels)
    frame: bool = True
    frame_min: float = 0.003  # (a line's own other edge, blurred, is nearer)
    frame_max: float = 0.02
    frame_tone: float = 0.12
    frame_agree: float = 0.006  # the sides' moves differ at most so (an even margin)
    # ...found for this many sides at least; a side whose margin shows no step beyond it (the
    # cover's border of the desk's tone, the desk beyond) moves as far as their mean
    frame_sides: int = 3
    frame_print: float = 5.0  # ...where the inside shows print: grey levels (std, shading out)
    # A side of a book the height maps found not pulled inward over a strip they read at
    # the cover's height (the pipeline's Detector._fit_extents: a gap in a picture's edges,
    # not the cover's end), but for keep_print_margin next to the side's new place
    keep_print: bool = True
    keep_print_margin: float = 0.02  # the maps carry a cover's height 5-20 mm beyond its edge


def fit_extent(P: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
               grads: dict[str, Gradients], min_strength: dict[str, float],
               desk_plane: NDArray[np.float64], cfg: ExtentConfig = ExtentConfig(),
               still_cover: Callable[[NDArray[np.float64]], bool] | None = None,
               ) -> NDArray[np.float64] | None:
    """The cover's corners with its sides moved to the cover's edges, or None if none moves.

    Sides reaching beyond the cover are pulled in first, then sides short of it pushed out.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        Triangulated cover corners (world, metres), in cyclic order.
    Q : dict camera -> ndarray, shape (3, 4)
        World → ideal pixel projections of both cameras.
    grads : dict camera -> Gradients
        Both images' gradients.
    min_strength : dict camera -> float
        Gradient across a line (Sobel units) that counts as an edge, per image (the image's
        Canny low threshold).
    desk_plane : ndarray, shape (4,)
        ``[nx, ny, nz, d]`` (world, normal up): the cover plane is parallel to it at the
        corners' mean height.
    still_cover : callable, optional
        Asked of each pull inward longer than ``cfg.keep_print_margin``: the strip it would
        cut away, less that margin next to the side's new place, as world corners (4, 3)
        in order around it (the side's two ends, then the far edge's). True keeps the side
        where it is. (``cfg.keep_print`` is the pipeline's switch, not read here: the
        pipeline passes a callable that asks the height maps whether the strip stands at
        the cover's height.)

    Returns
    -------
    ndarray, shape (4, 3) or None
        The new corners (on the cover plane), same order.
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    c = P.mean(axis=0)
    P = P - np.outer((P - c) @ up, up)  # onto the cover plane
    drop = _drop(P, desk_plane)  # cover -> desk
    moved = False
    runs = _missing_runs(P, Q, grads, min_strength, cfg) if cfg.shrink else None
    for s in range(4 if cfg.shrink else 0):
        d = _shrink_side(P, s, runs, Q, grads, min_strength, cfg)
        if d < 0 and cfg.height_check and _holds_side(P, s, Q, grads, up, drop, cfg):
            d = 0.0  # on the cover's edge, a print on it, or a taller book hiding its end
        if d < -cfg.keep_print_margin and still_cover is not None:
            # the strip cut away, but for keep_print_margin next to the side's new place
            a, b = s, (s + 1) % 4
            inner = _moved(P, s, np.array([d + cfg.keep_print_margin]))[0]
            if still_cover(np.array([P[a], P[b], inner[b], inner[a]])):
                d = 0.0  # the cover's print goes on over the strip: the gap is in its print
        if d < 0:
            P = _moved(P, s, np.array([d]))[0]
            runs = _missing_runs(P, Q, grads, min_strength, cfg)
            moved = True
    for _ in range(2 if cfg.grow else 0):  # a side's growth lengthens its neighbours: twice
        changed = False
        for s in range(4):
            d = _grow_side(P, s, Q, grads, min_strength, drop, cfg)
            if d <= 0:
                continue
            grown = _moved(P, s, np.array([d]))[0]
            if cfg.height_check and _on_desk(grown, s, Q, grads, up, drop, cfg):
                continue  # a shadow's edge or a line on the desk: the cover ends where it was
            P = grown
            changed = moved = True
        if not changed:
            break
    return P if moved else None


def grow_frame(P: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
               grads: dict[str, Gradients], gray: dict[str, NDArray[np.uint8]],
               min_strength: dict[str, float], desk_plane: NDArray[np.float64],
               cfg: ExtentConfig = ExtentConfig()) -> NDArray[np.float64] | None:
    """The cover's corners with each side moved out to the cover's edge where the quad is
    a frame printed inside the cover, or None where it is not.

    A line printed at an even margin inside a cover's edges is as strong a quad as the
    cover's outline, and stronger where the cover's border is of the desk's tone.
    :func:`fit_extent` cannot grow its sides: beyond the frame's corners the neighbouring
    sides run over the plain margin, no edge. A frame's side is a thin line with the
    cover's tone on both sides of it; a cover's edge has the cover on one side and the
    desk, its page block or a shadow on the other. So each side moves out to the nearest
    edge in both images (:func:`_side_scores`) between ``cfg.frame_min`` and
    ``cfg.frame_max`` whose inner strip (1–2.5 mm) has the cover's tone inside the line
    (1.5–4 mm inside the side, or 4.5–7 mm where the quad lies on the line's outer edge;
    within ``cfg.frame_tone``) and whose outer strip (1–3.5 mm) does not, at the edge's
    strongest within 3 mm; ``cfg.frame_sides`` sides at least must find one, their moves
    within ``cfg.frame_agree`` of each other (the margin is even), and no moved side may
    lie on an edge stereo puts near the desk (:func:`_on_desk`). A side that finds none
    moves as far as the others' mean: where the cover's border has the desk's tone, its
    edge beyond the margin shows no step against the desk, while the sides with the page
    block or a shadow beyond them show theirs (the Table I renders' scene 96: a 263 × 234
    mm cover found as its frame, 28.6 and 25.3 mm short, one side with no step beyond its
    margin; grown, its length's and width's errors 1.7 mm together). Arguments as
    :func:`fit_extent`; ``gray``: both ideal images.
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    c = P.mean(axis=0)
    P = P - np.outer((P - c) @ up, up)  # onto the cover plane
    drop = _drop(P, desk_plane)
    mm = 0.001

    half = 0.5 * mm  # the tone profiles' sampling across the side
    u = np.arange(-7 * mm, cfg.frame_max + 3.5 * mm + 1e-9, half)

    def profile(s: int, cam: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        # grey summed along side s at each offset u across it (outward, in the cover
        # plane), the middle 70 % of the side, and the samples in view: every strip's tone
        # read from one gather
        a, b = P[s], P[(s + 1) % 4]
        n = _unit(np.cross(b - a, up))
        if n @ (0.5 * (a + b) - c) < 0:
            n = -n
        t = np.linspace(0.15, 0.85, 16)[:, None, None]
        pts = (a + t * (b - a) + u[None, :, None] * n).reshape(-1, 3)
        q = np.rint(geometry.project(Q[cam], pts)).astype(np.intp).reshape(16, len(u), 2)
        h, w = gray[cam].shape
        ok = (q[..., 0] >= 0) & (q[..., 0] < w) & (q[..., 1] >= 0) & (q[..., 1] < h)
        y, x = np.clip(q[..., 1], 0, h - 1), np.clip(q[..., 0], 0, w - 1)
        seen = grads[cam].seen
        if seen is not None:  # beyond the raw field of view the ideal image is black
            ok &= seen[y, x] > 0
        return (gray[cam][y, x] * ok).sum(axis=0), ok.sum(axis=0)

    def strip(prof: tuple[NDArray[np.float64], NDArray[np.int64]],
              near: NDArray[np.float64] | float,
              far: NDArray[np.float64] | float) -> NDArray[np.float64]:
        # mean grey between offsets near and far (metres; arrays: one per move), NaN where
        # no sample of it lies in view
        near, far = np.atleast_1d(near), np.atleast_1d(far)
        inner = (u[None] >= near[:, None] - 1e-9) & (u[None] <= far[:, None] + 1e-9)
        total, count = (inner @ v for v in prof)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / np.maximum(count, 1), np.nan)

    def alike(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.bool_]:
        return np.abs(x - y) <= np.maximum(cfg.frame_tone * np.maximum(x, y), 4.0)

    def printed() -> bool:
        # the inside shows print: the grey of its middle 80 % (both images' mean, its
        # shading, a plane, taken out) varies by cfg.frame_print grey levels or more
        g = np.linspace(0.1, 0.9, 20)
        pts = (P[0] + g[:, None, None] * (P[1] - P[0])
               + g[None, :, None] * (P[3] - P[0])).reshape(-1, 3)
        grey = np.zeros(len(pts))
        for cam in Q:
            h, w = gray[cam].shape
            q = np.rint(geometry.project(Q[cam], pts)).astype(np.intp)
            grey += gray[cam][np.clip(q[:, 1], 0, h - 1), np.clip(q[:, 0], 0, w - 1)] / len(Q)
        uv = np.column_stack([np.repeat(g, len(g)), np.tile(g, len(g)), np.ones(len(pts))])
        shading = uv @ np.linalg.lstsq(uv, grey, rcond=None)[0]
        return float(np.std(grey - shading)) >= cfg.frame_print

    d = np.arange(cfg.frame_min, cfg.frame_max + 1e-9, cfg.step)
    moves = []
    for s in range(4):
        # the nearest move whose inner strip has the cover's tone inside the side (next to
        # it, or beyond a line up to 2.5 mm wide whose outer edge the quad lies on) and
        # whose outer strip does not, in both images
        fits = np.ones(len(d), bool)
        for cam in Q:
            prof = profile(s, cam)
            margin = strip(prof, d - 2.5 * mm, d - 1 * mm)
            outer = strip(prof, d + 1 * mm, d + 3.5 * mm)
            fits &= ((alike(margin, strip(prof, -4 * mm, -1.5 * mm))
                      | alike(margin, strip(prof, -7 * mm, -4.5 * mm)))
                     & np.isfinite(outer) & ~alike(outer, margin))  # (NaN: alike nothing)
        hit = np.zeros(0, np.intp)
        if fits.any():
            is_edge, strength = _side_scores(_moved(P, s, d), s, (s + 1) % 4, Q, grads,
                                             min_strength, cfg)
            hit = np.flatnonzero(fits & is_edge)
        if len(hit) == 0:  # (the common case: a cover's own edge, the desk beyond)
            moves.append(None)
            if sum(m is None for m in moves) > 4 - cfg.frame_sides:
                return None
            continue
        # the tones change over the blurred edge's width: the edge is where it is strongest,
        # within 3 mm on (while it stays an edge)
        k = end = int(hit[0])
        reach = int(round(3 * mm / cfg.step))
        while end + 1 < len(d) and is_edge[end + 1] and end + 1 - k <= reach:
            end += 1
        moves.append(_peak(d, strength, k, end, cfg.step))
    found = [m for m in moves if m is not None]
    if len(found) < max(cfg.frame_sides, 1) or max(found) - min(found) > cfg.frame_agree:
        return None
    if len(found) < 4 and not printed():
        return None  # (a plain cover of the desk's tone: the desk beyond reads as a margin)
    mean = float(np.mean(found))
    for s, m in enumerate(moves):
        m = mean if m is None else m
        P = _moved(P, s, np.array([m]))[0]
    if cfg.height_check and any(_on_desk(P, s, Q, grads, up, drop, cfg) for s in range(4)):
        return None
    return P


def fit_pair_extent(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
                    grads: dict[str, Gradients], min_strength: dict[str, float],
                    desk_plane: NDArray[np.float64], cfg: ExtentConfig = ExtentConfig(),
                    gray: dict[str, NDArray[np.uint8]] | None = None,
                    still_cover: Callable[[NDArray[np.float64]], bool] | None = None,
                    ) -> dict[str, NDArray[np.float64]] | None:
    """:func:`fit_extent` for a stereo pair of ideal-pixel corners (4, 2) per camera, then
    with ``gray`` (both ideal images) and ``cfg.frame`` :func:`grow_frame` from where it
    left them: the new corners projected into both images (None if no side moved). They
    are not refit in each image alone: a page-block or neighbouring edge a pixel or two
    away would pull the two images apart and tilt the cover by degrees."""
    P = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    if not np.all(np.isfinite(P)):
        return None
    G = fit_extent(P, Q, grads, min_strength, desk_plane, cfg, still_cover)
    if cfg.frame and gray is not None:  # a printed frame taken for the cover, grown on
        F = grow_frame(P if G is None else G, Q, grads, gray, min_strength, desk_plane, cfg)
        G = G if F is None else F
    if G is None:
        return None
    return {cam: geometry.project(Q[cam], G) for cam in ("left", "right")}


def _drop(P: NDArray[np.float64], desk_plane: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3,): what moves a point of cover ``P`` (4, 3) straight down onto the desk (its
    centre's distance to ``desk_plane`` along the plane's normal, downward)."""
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    return -float(up @ P.mean(axis=0) + desk_plane[3] / np.linalg.norm(desk_plane[:3])) * up


def _moved(P: NDArray[np.float64], s: int, d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Corners (len(d), 4, 3) with side s (corner s to s+1) moved outward by ``d`` metres,
    its end corners sliding along the neighbouring sides."""
    a, b = s, (s + 1) % 4
    u_a = _unit(P[a] - P[(a - 1) % 4])  # side s-1, continued beyond corner a
    u_b = _unit(P[b] - P[(b + 1) % 4])  # side s+1, continued beyond corner b
    out = np.repeat(P[None], len(d), axis=0)
    out[:, a] += d[:, None] * u_a
    out[:, b] += d[:, None] * u_b
    return out


def _grow_side(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
               grads: dict[str, Gradients], min_strength: dict[str, float],
               drop: NDArray[np.float64], cfg: ExtentConfig, *, limit: float = np.inf,
               continuation: float | None = None) -> float:
    """How far side ``s`` may move outward (metres; 0: not at all). ``drop`` (3,) moves a
    cover point straight down onto the desk. ``limit``: the farthest move looked at
    (metres). ``continuation``: instead of both neighbouring sides carrying edges in both
    images (``cfg.min_support``, up to the moved side), each must in either image along
    this share of the way (:mod:`rovis.trim`'s grow, where the height map vouches for the
    cover beyond the side).

    Where no move's side is an edge along ``cfg.min_support`` of it in both images, a move
    whose side is along ``cfg.weak_support`` is taken: a picture cover's edge fades where the
    picture has the desk's tone. Then, unless the maps vouch (``continuation``), stereo
    must place that edge within ``cfg.weak_height`` of the cover's height, to that precision
    (:func:`_edge_height`; never a side along the epipolar lines)."""
    a, b = s, (s + 1) % 4
    # Neighbouring sides' lengths bound the growth (no book is larger than max_side).
    room = min(limit, cfg.max_side - max(np.linalg.norm(P[a] - P[(a - 1) % 4]),
                                         np.linalg.norm(P[b] - P[(b + 1) % 4])))
    if room < cfg.min_grow:
        return 0.0
    d = np.arange(cfg.step, room + 1e-9, cfg.step)
    moved = _moved(P, s, d)  # (D, 4, 3)
    ok = np.ones(len(d), bool)
    for cam in ("left", "right"):
        thr = min_strength[cam]
        # A side facing the camera shows the page block below it: lines on the block (the
        # pages, its bottom edge) pass every test of a cover edge, and a side along the
        # epipolar lines has no stereo check. The new side must lie beyond the block's
        # bottom edge in the image.
        q = geometry.project(Q[cam], P)
        side = q[b] - q[a]
        n_out = np.array([side[1], -side[0]]) / max(float(np.linalg.norm(side)), 1e-9)
        if n_out @ (0.5 * (q[a] + q[b]) - q.mean(axis=0)) < 0:
            n_out = -n_out
        bottom = geometry.project(Q[cam], 0.5 * (P[a] + P[b]) + drop)
        mid = geometry.project(Q[cam], 0.5 * (moved[:, a] + moved[:, b]))
        ok &= (mid - bottom) @ n_out > 2.0
        # the neighbouring sides' continuations: edge hits at each step, then the share of
        # hits from the old corner out to each offset
        if continuation is not None:  # (strict; else asked below, in either image)
            continue
        # both neighbours' points tested in one _edge call ((2, D, 2) points, each line's
        # start (2, 1, 2)): it is elementwise, so the same values as a call per neighbour
        ext = np.stack([geometry.project(Q[cam], moved[:, k]) for k in (a, b)])
        start = np.stack([geometry.project(Q[cam], P[k][None]) for k in (a, b)])
        for hit in _hits(grads[cam], start, ext, thr, cfg.max_angle_deg):
            n = np.arange(1, len(d) + 1)  # steps out to each offset
            n_hit = np.concatenate([[0], np.cumsum(hit)])
            ok &= n_hit[1:] / n >= cfg.min_support
            # ...and reach the moved side itself: no overshoot onto a line further out
            w = min(len(d), max(1, int(round(cfg.reach / cfg.step))))
            ok &= (n_hit[1:] - n_hit[np.maximum(n - w, 0)]) / np.minimum(n, w) >= 0.5
    if continuation is not None:  # each neighbour's, in either image, along this share
        share = np.zeros((2, len(d)))  # neighbours a and b, in one _edge call per image
        for cam in ("left", "right"):
            ext = np.stack([geometry.project(Q[cam], moved[:, k]) for k in (a, b)])
            start = np.stack([geometry.project(Q[cam], P[k][None]) for k in (a, b)])
            hit = _hits(grads[cam], start, ext, min_strength[cam], cfg.max_angle_deg)
            share = np.maximum(share, np.cumsum(hit, axis=1) / np.arange(1, len(d) + 1))
        ok &= share[0] >= continuation
        ok &= share[1] >= continuation
    ok &= d >= cfg.min_grow
    if not ok.any():  # (the common case: a cover's own side, its neighbours end there)
        return 0.0
    idx = np.nonzero(ok)[0]  # the moved side itself only where its neighbours reach
    is_edge, strength_at = _side_scores(moved[idx], a, b, Q, grads, min_strength, cfg)
    weak = not is_edge.any() and cfg.weak_support < cfg.min_support
    if weak:  # no clear edge: a faint one, checked below
        is_edge, strength_at = _side_scores(moved[idx], a, b, Q, grads, min_strength, cfg,
                                            min_support=cfg.weak_support)
    ok[idx] = is_edge
    if not ok.any():
        return 0.0
    strength = np.zeros(len(d))
    strength[idx] = strength_at
    # The edge is where the moved side is strongest within the last run of offsets that
    # pass (the ±1 px tolerance lets a few neighbouring offsets pass too).
    last = int(np.nonzero(ok)[0][-1])
    first = last
    while first > 0 and ok[first - 1]:
        first -= 1
    move = _peak(d, strength, first, last, cfg.step)
    if weak and continuation is None:  # a print's faint line beyond the cover is no edge
        h = float(np.linalg.norm(drop))
        if h <= 0.0:  # a cover on the desk: no up from its drop
            return 0.0
        z, sigma = _edge_height(_moved(P, s, np.array([move]))[0], s, Q, grads, -drop / h)
        if not (sigma < cfg.weak_height and abs(z) < cfg.weak_height):
            return 0.0
    return move


def _peak(d: NDArray[np.float64], strength: NDArray[np.float64], first: int, last: int,
          step: float) -> float:
    """The offset of ``d`` (metres) where ``strength`` peaks within ``first..last``; a
    parabola through the peak and its scored neighbours gives the sub-step offset."""
    k = first + int(np.argmax(strength[first:last + 1]))
    if first < k < last:
        s0, s1, s2 = strength[k - 1:k + 2]
        denom = s0 - 2 * s1 + s2
        if denom < 0:
            return float(d[k] + step * np.clip(0.5 * (s0 - s2) / denom, -0.5, 0.5))
    return float(d[k])


def _missing_runs(P: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
                  grads: dict[str, Gradients], min_strength: dict[str, float],
                  cfg: ExtentConfig) -> NDArray[np.float64]:
    """(4, 2): for each side, how far from its first and from its second corner (metres, up
    to half its length) its edge is missing in both images."""
    runs = np.zeros((4, 2))
    w = max(1, int(round(0.005 / cfg.step)))
    for k in range(4):
        length = float(np.linalg.norm(P[(k + 1) % 4] - P[k]))
        n = int(round(length / cfg.step)) + 1
        if n < 2 * w + 2:
            continue  # too short to hold a gap
        t = np.linspace(0.0, length, n)  # symmetric: the same distances from either end
        pts = P[k] + np.outer(t / length, P[(k + 1) % 4] - P[k])
        half = n // 2
        found = np.full(2, np.inf)
        for cam in ("left", "right"):
            q = geometry.project(Q[cam], pts)
            edge = _edge(grads[cam], q[0], q[None], cfg.max_angle_deg,
                         along=(q[-1] - q[0])[None])[0]
            # an edge like the side's own: in dim light the threshold alone passes desk grain
            hit = edge >= max(min_strength[cam], cfg.gap_edge_ratio * np.median(edge))
            for end, h in enumerate((hit[:half], hit[::-1][:half])):
                # where edges come back: most of 5 mm carry them
                dense = np.convolve(h.astype(float), np.ones(w) / w, mode="valid") >= 0.6
                run = float(t[int(np.argmax(dense))]) if dense.any() else float(t[half])
                found[end] = min(found[end], run)  # missing in both images
        runs[k] = found
    return runs


def _shrink_side(P: NDArray[np.float64], s: int, runs: NDArray[np.float64],
                 Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                 min_strength: dict[str, float], cfg: ExtentConfig) -> float:
    """How far side ``s`` must move inward (metres, negative; 0: it stays).

    A side placed beyond the cover's end (on a line of the desk or of a neighbouring book)
    leaves its neighbouring sides without edges next to it, in both images
    (:func:`_missing_runs`). If one does over ``cfg.min_gap`` or more, the side is looked
    for where that run of missing edges ends (−5 to +15 mm around it): the strongest
    offset at which the moved side is an edge in both images."""
    a, b = s, (s + 1) % 4
    gap = max(runs[(s - 1) % 4, 1], runs[(s + 1) % 4, 0])  # next to corner a, corner b
    if gap < cfg.min_gap:
        return 0.0
    d = -np.arange(gap - 0.005, gap + 0.015, cfg.step)
    d = d[-d < 0.8 * min(np.linalg.norm(P[a] - P[(a - 1) % 4]),  # short of the opposite side
                         np.linalg.norm(P[b] - P[(b + 1) % 4]))]
    if len(d) == 0:
        return 0.0
    ok, strength = _side_scores(_moved(P, s, d), a, b, Q, grads, min_strength, cfg)
    if not ok.any():
        return 0.0
    return float(d[np.argmax(np.where(ok, strength, -np.inf))])


def _side_scores(moved: NDArray[np.float64], a: int, b: int, Q: dict[str, NDArray[np.float64]],
                 grads: dict[str, Gradients], min_strength: dict[str, float],
                 cfg: ExtentConfig, cams: tuple[str, ...] = ("left", "right"),
                 min_support: float | None = None,
                 ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """For each candidate (D, 4, 3), whether its side from corner ``a`` to ``b`` is an edge
    in every image of ``cams`` (``min_support``, else ``cfg.min_support``, of 24 samples,
    ends trimmed), and its mean gradient across, summed over those images in units of each
    image's threshold."""
    ok = np.ones(len(moved), bool)
    strength = np.zeros(len(moved))
    u = np.linspace(0.1, 0.9, 24)
    for cam in cams:
        thr = min_strength[cam]
        pa = geometry.project(Q[cam], moved[:, a])
        pb = geometry.project(Q[cam], moved[:, b])
        pts = pa[:, None] + u[None, :, None] * (pb - pa)[:, None]  # (D, S, 2)
        edge, across = _edge(grads[cam], pa[:, None], pts, cfg.max_angle_deg,  # type: ignore[misc]
                             along=pb - pa, centre=True)
        ok &= (edge >= thr).mean(axis=1) >= (cfg.min_support if min_support is None
                                             else min_support)
        strength += across.mean(axis=1) / thr  # the mean gradient across, on the line itself
    return ok, strength


def _hits(grad: Gradients, start: NDArray[np.float64], pts: NDArray[np.float64], thr: float,
          max_angle_deg: float, along: NDArray[np.float64] | None = None) -> NDArray[np.bool_]:
    """Whether points lie on an edge: :func:`_edge` at least ``thr``."""
    return _edge(grad, start, pts, max_angle_deg, along) >= thr


def _edge(grad: Gradients, start: NDArray[np.float64], pts: NDArray[np.float64],
          max_angle_deg: float, along: NDArray[np.float64] | None = None, *,
          centre: bool = False,
          ) -> NDArray[np.float64] | tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gradient across a line at each point, best of the point and ±1 px across; 0 where the
    gradient is more than ``max_angle_deg`` off the line's normal. With ``centre``, also the
    gradient across at the points themselves, whatever its angle (the same samples).

    Either points ``pts`` (N, 2) on one line through ``start`` (2,) (or (L, N, 2) on L lines
    through ``start`` (L, 1, 2): :func:`_grow_side` asks both neighbours at once), or, with
    ``along`` (D, 2), points (D, S, 2) on D lines of those directions (``start`` unused).
    """
    if along is None:
        direction = pts - start
    else:  # one direction per line, normalised once, not once per point (the same values)
        direction = np.asarray(along, dtype=np.float64)[:, None, :]
    direction = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-9)
    # the normal's components, (N,) or (D, S) (with along: (D, 1), broadcast over S)
    nx, ny = -direction[..., 1], direction[..., 0]
    cos_max = np.cos(np.radians(max_angle_deg))
    # the three offsets' points sampled at once (one call's overhead, not three), and the
    # three offsets' tests in one pass over (3, ...) arrays: each value is computed as it
    # was offset by offset, elementwise
    offsets = np.array([-1.0, 0.0, 1.0]).reshape((3,) + (1,) * (pts.ndim - 1))
    gxs, gys = grad.sample(pts[..., 0] + offsets * nx, pts[..., 1] + offsets * ny)
    across = np.abs(gxs * nx + gys * ny)
    kept = np.where(across >= cos_max * np.hypot(gxs, gys), across, 0.0)
    # best of the three and 0, as np.maximum folded it (a max is exact in any order)
    best = np.maximum(np.maximum(np.maximum(0.0, kept[0]), kept[1]), kept[2])
    return (best, across[1]) if centre else best


def _on_desk(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
             grads: dict[str, Gradients], up: NDArray[np.float64], drop: NDArray[np.float64],
             cfg: ExtentConfig) -> bool:
    """Whether the edge that side ``s`` of the grown cover ``P`` (4, 3) now lies on is, by
    stereo, nearer the desk than the cover's height: a cast shadow's edge or a line on the
    desk. Asked only of a side whose page block is hidden: where the block shows, its foot
    is a desk-level line next to the cover's own edge."""
    if _block_shows(P, s, Q, drop):
        return False
    level = _edge_level(P, s, Q, grads, up, drop, cfg)
    return level is not None and level < 0.5 * float(np.linalg.norm(drop))


def _foot_is_edge(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                  grads: dict[str, Gradients], min_strength: dict[str, float],
                  drop: NDArray[np.float64], cfg: ExtentConfig, min_px: float = 2.0) -> bool:
    """Whether the foot of the page block below side ``s`` of cover ``P`` (4, 3) (the side
    moved by ``drop``, onto the desk) is an edge in each image where it lies at least
    ``min_px`` outside the cover (True where it shows in neither)."""
    foot = P + drop
    u = np.linspace(0.1, 0.9, 24)
    for cam in ("left", "right"):
        a, b = s, (s + 1) % 4
        q = geometry.project(Q[cam], np.array([P[a], P[b], foot[a], foot[b]]))
        n_out = np.array([q[1, 1] - q[0, 1], q[0, 0] - q[1, 0]])
        n_out /= max(float(np.linalg.norm(n_out)), 1e-9)
        if n_out @ (0.5 * (q[0] + q[1]) - geometry.project(Q[cam], P).mean(axis=0)) < 0:
            n_out = -n_out
        if (0.5 * (q[2] + q[3]) - 0.5 * (q[0] + q[1])) @ n_out < min_px:
            continue
        pts = q[2] + u[:, None] * (q[3] - q[2])
        edge = _edge(grads[cam], q[2], pts, cfg.max_angle_deg)
        if (edge >= min_strength[cam]).mean() < cfg.min_support:
            return False
    return True


def _block_shows(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                 drop: NDArray[np.float64], min_px: float = 1.0,
                 cams: tuple[str, ...] = ("left", "right")) -> bool:
    """Whether the page block below side ``s`` of cover ``P`` (4, 3) shows in any image of
    ``cams``: its foot (the side moved by ``drop``, onto the desk) lies at least ``min_px``
    outside the cover."""
    a, b = P[s], P[(s + 1) % 4]
    mid = 0.5 * (a + b)
    for cam in cams:
        q = geometry.project(Q[cam], np.array([a, b, mid, mid + drop]))
        n_out = np.array([q[1, 1] - q[0, 1], q[0, 0] - q[1, 0]])
        n_out /= max(float(np.linalg.norm(n_out)), 1e-9)
        if n_out @ (q[2] - geometry.project(Q[cam], P).mean(axis=0)) < 0:
            n_out = -n_out
        if (q[3] - q[2]) @ n_out >= min_px:
            return True
    return False


def _holds_side(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                grads: dict[str, Gradients], up: NDArray[np.float64],
                drop: NDArray[np.float64], cfg: ExtentConfig) -> bool:
    """Whether the edge side ``s`` of cover ``P`` (4, 3) lies on holds the side: by stereo,
    at the cover's height (nearer it than the desk, and within ``cfg.height_band``, or
    ``cfg.height_band_ratio`` of the height if larger: the cover's edge or a print on it),
    or well above it beyond a side facing the cameras (its page block shows in either
    image: :func:`_block_shows`).

    An edge well below is a lower neighbour's, which a side reaching past the cover lies on.
    One well above is a taller neighbour's: beyond a side facing the cameras it hides the
    cover's end, and the side may rightly lie on it; beyond a side facing away, the
    neighbour's face towards the cover shows above the cover's end, and a side on its top
    edge reaches over that face."""
    level = _edge_level(P, s, Q, grads, up, drop, cfg)
    h = float(np.linalg.norm(drop))
    band = max(cfg.height_band, cfg.height_band_ratio * h)
    if level is None or level < max(0.5 * h, h - band):
        return False
    return level <= h + band or _block_shows(P, s, Q, drop)


def _edge_level(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                grads: dict[str, Gradients], up: NDArray[np.float64], drop: NDArray[np.float64],
                cfg: ExtentConfig) -> float | None:
    """Height above the desk (metres) of the edge next to side ``s`` of cover ``P`` (4, 3),
    or None where stereo cannot tell it to within ``height_sigma`` of the cover's height."""
    h = float(np.linalg.norm(drop))
    z, sigma = _edge_height(P, s, Q, grads, up)
    return h + z if sigma < cfg.height_sigma * h else None


def _edge_height(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                 grads: dict[str, Gradients], up: NDArray[np.float64],
                 px_sigma: float = 0.1, half_width: float = 5.0) -> tuple[float, float]:
    """Height (metres, relative to the cover plane) of the edge next to side ``s`` of cover
    ``P`` (4, 3), with its standard deviation for a ``px_sigma`` error of each image's fit
    (inf where a fit fails).

    The side is fit in each image on its own (:func:`refine_segment`, within
    ``half_width`` pixels of its projection); the edge is the 3D
    line on both back-projected planes, found as the offset across the side (in the cover
    plane) and the height that put the side on both fitted lines: two linear equations,
    in pixels. Disparity moves a side only across it, so a side along the epipolar lines
    (horizontal in the image) has no height: its sigma is large.
    """
    a, b = P[s], P[(s + 1) % 4]
    fits = {}
    for cam in ("left", "right"):
        pa, pb = geometry.project(Q[cam], np.array([a, b]))
        fit = refine_segment(grads[cam], pa, pb, half_width=half_width)
        if fit is None:
            return 0.0, np.inf
        fits[cam] = fit
    return _line_height(fits, a, b, Q, up, px_sigma)


def _line_height(fits: dict[str, Fit],
                 a: NDArray[np.float64], b: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
                 up: NDArray[np.float64], px_sigma: float = 0.1) -> tuple[float, float]:
    """Height (metres, relative to the midpoint of ``a``-``b``) of the 3D line both images'
    fitted lines ``fits`` (point, direction) back-project to, with its standard deviation
    for a ``px_sigma`` error of each fit (inf: along the epipolar lines)."""
    m = 0.5 * (a + b)
    n = np.cross(up, _unit(b - a))
    rows, rhs = [], []
    for cam in ("left", "right"):
        p, d = fits[cam]
        line = np.array([-d[1], d[0], d[1] * p[0] - d[0] * p[1]])
        q = line @ Q[cam]
        w = float(Q[cam][2, :3] @ m + Q[cam][2, 3])
        rows.append([q[:3] @ n / w, q[:3] @ up / w])
        rhs.append(-(q[:3] @ m + q[3]) / w)
    A = np.array(rows)
    if abs(np.linalg.det(A)) < 1e-12:
        return 0.0, np.inf
    inv = np.linalg.inv(A)
    return float((inv @ np.array(rhs))[1]), float(px_sigma * np.linalg.norm(inv[1]))


def _facing(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
            down: tuple[float, float] = (0.0, 1.0)) -> bool:
    """Whether side ``s`` of cover ``P`` (4, 3) faces the camera in either image
    (:func:`_faces_down` of its projections, whatever the cover's height)."""
    return _faces_down({cam: geometry.project(Q[cam], P) for cam in ("left", "right")}, s, down)


def _faces_down(corners: dict[str, NDArray[np.float64]], s: int,
                down: tuple[float, float] = (0.0, 1.0)) -> bool:
    """Whether side ``s`` of a cover's image corners (4, 2) per camera faces that camera in
    any of them: its outward normal points down the image (more than 0.05 of it), where
    the page block below the side shows."""
    for q in corners.values():
        a, b = q[s], q[(s + 1) % 4]
        n = np.array([b[1] - a[1], a[0] - b[0]]) / max(float(np.linalg.norm(b - a)), 1e-9)
        if n @ (0.5 * (a + b) - q.mean(axis=0)) < 0:
            n = -n
        if n @ np.asarray(down) > 0.05:
            return True
    return False


@dataclass(frozen=True)
class SideHeightConfig:
    """A cover moved to the height its sides' edges give (:func:`height_from_sides`;
    metres).

    ``enabled`` turns it on; a side counts where stereo places its edge to within
    ``max_sigma`` (for a 0.1 px error of each image's line) and it does not face the
    cameras (:func:`_facing`);
    at least two such sides must agree to within ``agree``; the cover moves where their
    mean lies ``min_move`` or more from its corners' height.

    Where those sides give no height, ``any_sides`` sides or more, facing the cameras or
    not, each placed to within ``any_sigma`` and all within ``any_agree`` of one of them,
    give it, where their mean lies ``any_move`` or more from the corners' height (0 sides:
    not asked).
    """

    enabled: bool = True
    max_sigma: float = 0.006
    agree: float = 0.004
    min_move: float = 0.005
    any_sides: int = 3
    any_sigma: float = 0.010
    any_agree: float = 0.006
    any_move: float = 0.010

    def __post_init__(self) -> None:
        problems = [name for name, ok in (
            ("any_sides", 0 <= self.any_sides <= 4),
            ("max_sigma, agree, min_move, any_sigma, any_agree, any_move", all(
                v >= 0 for v in (self.max_sigma, self.agree, self.min_move, self.any_sigma,
                                 self.any_agree, self.any_move)))) if not ok]
        if problems:
            raise ValueError(f"side_height: bad {', '.join(problems)} (any_sides from 0 to "
                             f"4, the rest >= 0), got {self}")


def height_from_sides(P: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
                      grads: dict[str, Gradients], desk_plane: NDArray[np.float64],
                      cfg: SideHeightConfig = SideHeightConfig()) -> float | None:
    """The cover's height above the desk (metres) as its sides' edges give it, or None
    where fewer than two sides facing away from the cameras tell it or they disagree, and
    no ``cfg.any_sides`` sides, facing or not, agree on a height ``cfg.any_move`` or more
    from the corners'.

    A cover's height from its four triangulated corners (eq. 5) rests on each corner's
    disparity, and a pixel of disparity is a centimetre of height at 1.2 m: one image's
    side on the page block's edge instead of the cover's, a corner a pixel off, and the
    book comes out a centimetre high or low, flat all the same. A side that does not face
    the camera (:func:`_facing`) has no page block below it in the images, one edge,
    fitted in each image on its own (:func:`_edge_height`); two or more such sides placed
    well by stereo (not along the epipolar lines) and agreeing with each other give the
    height without the corners. (A facing side's fit may take the block's foot or a board
    of it: on a rendered 2 cm book those came out 2–5 mm low.)

    Where they give none (one of them along the epipolar lines, say), ``cfg.any_sides``
    (3) sides, facing or not, all within ``cfg.any_agree`` of one of them, give it (their
    mean), if it lies ``cfg.any_move`` (1 cm) or more from the corners' height: three
    sides' edges a centimetre or more from where the corners put the cover are more than
    a facing side's foot (the Table I renders' scene 69 book 0: 34 mm at its corners, 19
    mm by three of its sides, 21 mm in truth). A height so given is never within
    ``any_move`` of the corners'.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        Triangulated cover corners (world, metres), in cyclic order.
    Q, grads, desk_plane
        As :func:`fit_extent`.
    cfg : SideHeightConfig
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    c = P.mean(axis=0)
    P = P - np.outer((P - c) @ up, up)  # onto the cover plane
    h = float(up @ c + desk_plane[3] / np.linalg.norm(desk_plane[:3]))
    heights, every, facing = [], [], []
    for s in range(4):
        if _facing(P, s, Q):
            facing.append(s)  # the block's foot and boards are edges too, below the cover
            continue
        z, sigma = _edge_height(P, s, Q, grads, up)
        if sigma <= cfg.max_sigma:
            heights.append(h + z)
        if sigma <= cfg.any_sigma:
            every.append(h + z)
    if len(heights) >= 2 and np.ptp(heights) <= cfg.agree:
        return float(np.mean(heights))
    if cfg.any_sides <= 0 or len(every) + len(facing) < cfg.any_sides:
        return None
    for s in facing:  # asked only now: most covers' height is told above, or not at all
        z, sigma = _edge_height(P, s, Q, grads, up)
        if sigma <= cfg.any_sigma:
            every.append(h + z)
    if len(every) < cfg.any_sides:
        return None
    # the most sides within any_agree of one of them (the lowest such, where several are
    # as many: sorted, the answer does not hang on the order the sides were asked in)
    levels = np.sort(every)
    near = np.abs(levels[:, None] - levels[None, :]) <= cfg.any_agree
    most = near[int(np.argmax(near.sum(axis=1)))]
    mean = float(levels[most].mean())
    if np.count_nonzero(most) < cfg.any_sides or abs(mean - h) < cfg.any_move:
        return None
    return mean


@dataclass(frozen=True)
class FacingConfig:
    """Choosing, for a cover's sides facing the camera, which edge of the page block below
    each is the cover's in both images (:func:`settle_facing_sides`; metres unless noted).

    ``enabled`` turns on :func:`settle_facing_sides` (``block_sides`` is a switch of its
    own); the cover's height is the median of its other sides' stereo
    heights placed to within ``max_sigma`` (for a 0.1 px error of each image's line); a
    facing side is settled where its two images' lines, back-projected onto the cover's
    plane, lie more than ``tol`` apart across it, onto edges that lie within ``tol``;
    candidate edges are looked for up to ``max_px`` pixels (and a fifth of the quad's
    width) either way across it.

    ``block_sides`` turns on :func:`settle_block_sides` (the pipeline's flat refit of a
    tilted pair): a side whose page block shows ``block_px`` pixels or more in one image
    only, there ``block_share`` (low, high) of the block's width outside where the other
    image's side lies at the cover's height, is moved there. (Which blocks show is asked
    first where the tilted pair triangulates: a side far enough out reads as a cover low
    enough there for no block to show, which narrows the band in practice.)

    ``feet`` turns on :func:`foot_side` (the pipeline's ``Detector._off_feet``; a switch
    of its own, apart from ``enabled``): a facing side both images took on its page
    block's foot, moved to the cover's edge above it, where the block is ``foot_px``
    pixels wide or more in one image, a side that does not face the camera has its edge
    within ``foot_agree`` of the cover's height h, the side's own edge (fitted within
    ``foot_fit_px`` pixels of it) lies at ``foot_level`` of h or lower, and the edge at the
    moved side, where stereo places it, no lower than ``foot_cover`` of h; every stereo
    reading taken to within ``foot_sigma`` of h. ``foot_level``, ``foot_sigma``,
    ``foot_cover`` and ``foot_agree`` are shares of h, not metres.

    Where the corners' height h is itself wrong (a side on the foot pulls it down), the
    cover is first laid at the height its other sides give (:func:`height_off_feet`; the
    pipeline then asks :func:`foot_side` there, and at h where no side moves or the moved
    cover fails the pose checks): each side fitted within ``relay_fit_px`` pixels of where
    it lies, placed by stereo to within ``relay_sigma`` (metres, for a 0.1 px error of
    each image's line), two or more agreeing within ``relay_agree`` (metres), and their
    mean more than ``relay_min`` (metres) from h either way; a facing side whose block
    shows ``foot_px`` or more is not asked. ``relay`` turns it on, within ``feet``.

    ``under`` turns on :func:`under_taller` (the pipeline's ``Detector._under_taller``; a
    switch of its own, apart from ``enabled``): a facing side that lies on a side of a book
    ``under_step`` (metres) or more taller, in both images (within ``under_deg`` degrees
    of its direction and ``under_px`` pixels of it, along ``under_share`` of the side or
    more), a book that stands beyond it on the desk and whose side shares ``under_share``
    of its length, is moved out to straight under that side, where that move is
    ``under_min`` (metres) or more; not where the side is an edge beyond that book's side
    in either image (``under_free`` of its gradient alongside it or more), nor where an
    edge of the other polarity lies inside it within its page block's width
    (``under_inner`` of the side's gradient or more). A side that lies short of that
    book's side, within ``under_print_px`` pixels of it in both images (a value at or
    under ``under_px`` turns this off, as do no high-passed images), is moved too where
    the strip between, in the left image, shows the cover's print: from 1.5 px beyond the
    side to 1.5 px short of that book's side (3 px wide at least, so a side under 6 px
    short is not asked), and each half of it where it is 6 px wide or more (and wide
    enough to sample), it matches between the images at the cover's height, and better
    than on the desk (the sweep's ``strip_min_ncc`` and ``min_gap``); the side lay on a
    line of its print. Where the nearest move is such a side's, the inside test
    (``under_inner``) is not asked: what lies inside it is more print.
    """

    enabled: bool = True
    tol: float = 0.002
    max_sigma: float = 0.004
    max_px: float = 25.0
    block_sides: bool = True
    block_px: float = 1.0
    block_share: tuple[float, float] = (0.3, 1.3)
    feet: bool = True
    foot_px: float = 3.0
    foot_fit_px: float = 2.0
    foot_level: float = 0.4
    foot_sigma: float = 0.6
    foot_cover: float = 0.5
    foot_agree: float = 0.25
    relay: bool = True
    relay_fit_px: float = 2.0
    relay_sigma: float = 0.005
    relay_agree: float = 0.007
    relay_min: float = 0.004
    under: bool = True
    under_step: float = 0.008
    under_px: float = 4.0
    under_deg: float = 4.0
    under_share: float = 0.3
    under_min: float = 0.002
    under_free: float = 0.5
    under_inner: float = 0.2
    under_print_px: float = 20.0


def settle_facing_sides(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
                        grads: dict[str, Gradients], desk_plane: NDArray[np.float64],
                        cfg: FacingConfig = FacingConfig(), *,
                        down: tuple[float, float] = (0.0, 1.0),
                        ) -> dict[str, NDArray[np.float64]] | None:
    """A stereo pair's corners (4, 2) per camera with each side facing the camera moved,
    in one image or both, onto the page-block edge that puts it at the cover's height;
    None if no side moves.

    Below a side facing the camera the page block shows a stack of parallel edges: its
    foot on the desk, its boards, the rows of its pages, and the cover's own edge above
    them (:func:`rovis.segment.boundary.inner_edges`). Each image's segmentation picks one
    on its own, and where they pick different ones the side's disparity is off by pixels:
    the cover comes out centimetres low on that side (a 2 cm book alone on the desk, found
    1 cm low). The cover's other sides have no block below them and fix its height (the
    median of those stereo places well). On the cover's plane at that height, both images'
    lines of a side must meet; where they do not (within ``cfg.tol``), one image's line is
    kept and the other moved to the edge it offers (either way across the side) that meets
    it, the smallest such move. A side along the epipolar lines has no height of its own,
    but two different edges of its block still back-project apart on the plane.
    """
    P = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    if not np.all(np.isfinite(P)):
        return None
    lines = _side_lines(corners)

    def inward(cam: str, s: int) -> NDArray[np.float64]:
        c = corners[cam]
        d = lines[cam][s][1]
        n = np.array([-d[1], d[0]])
        return n if n @ (c.mean(axis=0) - lines[cam][s][0]) > 0 else -n

    facing = [_faces_down(corners, s, down) for s in range(4)]
    h_ref = _cover_height(lines, P, [not f for f in facing], Q, desk_plane, cfg.max_sigma)
    if h_ref is None:
        return None

    moved = False
    for s in range(4):
        if not facing[s]:
            continue
        m, n, now = _apart(lines, P, s, Q, desk_plane, h_ref)
        if not np.all(np.isfinite(now)) or abs(now[0] - now[1]) <= cfg.tol:
            continue
        options: dict[str, list[tuple[float, Fit]]] = {}
        for cam in ("left", "right"):
            c, n_in = corners[cam], inward(cam, s)
            pa, pb = c[s], c[(s + 1) % 4]
            reach = min(cfg.max_px, 0.2 * float(np.max((c - pa) @ n_in)))
            shifts = [*inner_edges(grads[cam], pa, pb, n_in, max_px=reach),
                      *(-o for o in inner_edges(grads[cam], pa, pb, -n_in, max_px=reach))]
            options[cam] = [(0.0, lines[cam][s])]
            for o in shifts:
                fit = refine_segment(grads[cam], pa + o * n_in, pb + o * n_in, half_width=1.5)
                if fit is not None:
                    options[cam].append((abs(o), fit))
        # the pair of edges that meet on the cover plane, one image's side kept where it
        # is, the smallest move
        best, best_key = None, (np.inf, np.inf)
        for i, (o_l, fit_l) in enumerate(options["left"]):
            for j, (o_r, fit_r) in enumerate(options["right"]):
                if (i == 0) == (j == 0):
                    continue
                gap = abs(_across(fit_l, Q["left"], m, n) - _across(fit_r, Q["right"], m, n))
                if gap <= cfg.tol and (o_l + o_r, gap) < best_key:
                    best, best_key = (fit_l, fit_r), (o_l + o_r, gap)
        if best is not None:
            lines["left"][s], lines["right"][s] = best
            moved = True
    return _corners_of(lines, corners) if moved else None


def settle_block_sides(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
                       desk_plane: NDArray[np.float64], cfg: FacingConfig = FacingConfig(),
                       ) -> dict[str, NDArray[np.float64]] | None:
    """A stereo pair's corners (4, 2) per camera with each side that one image saw on its
    page block's foot moved, in that image, to where the other image's side lies at the
    cover's height; None if no side moves.

    A book's page block shows below a side where the block's face is turned to the
    camera: below the near side in both images, and below a side end-on to the baseline in
    one image only (the right camera sees more of a book's right-hand face than the left
    does). Where it shows in one image only, that image's segmentation may take the
    block's outer edge (its foot, often the stronger step) for the side while the other
    takes the cover's own: the side's disparity is off by the block's width and the cover
    comes out tilted, or, fitted flat, centimetres low (build/t2 scene 49: a 4.6 cm book
    fitted at 2.7 cm). :func:`settle_facing_sides` asks the image for an edge that agrees;
    the cover's edge beside a lit block is often too faint to be one.

    The cover's height is the median of the stereo heights of the sides whose block
    shows in neither image (as in :func:`settle_facing_sides`, placed to within
    ``cfg.max_sigma``). A side whose block shows ``cfg.block_px`` or more in one image only
    (:func:`_block_shows`, the cover where its corners are, and again with the side at
    that height) and whose two images' lines, back-projected onto the cover's plane at
    that height, lie more than ``cfg.tol`` apart, is moved in the image where the block
    shows to where the other image's line lies on that plane, if it lies outside that by
    ``cfg.block_share`` of the block's width there (on the foot, not on some other edge).
    The corners a tilted pair triangulates to are where the blocks are judged first: a
    side's image moved far enough (beyond its foot, or inward) reads as a cover high or
    low enough there for a block to show in both images, or in neither.
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    P = geometry.triangulate(Q["left"], Q["right"], corners["left"], corners["right"])
    if not np.all(np.isfinite(P)):
        return None
    drop = _drop(P, desk_plane)
    shows = np.array([[_block_shows(P, s, Q, drop, cfg.block_px, cams=(cam,))
                       for cam in ("left", "right")] for s in range(4)])  # (4 sides, 2)
    lines = _side_lines(corners)
    h_ref = _cover_height(lines, P, ~shows.any(axis=1), Q, desk_plane, cfg.max_sigma)
    if h_ref is None:
        return None
    moved = False
    for s in np.flatnonzero(shows.sum(axis=1) == 1):
        _, _, now = _apart(lines, P, s, Q, desk_plane, h_ref)
        if not np.all(np.isfinite(now)) or abs(now[0] - now[1]) <= cfg.tol:
            continue
        cam, other = ("left", "right") if shows[s, 0] else ("right", "left")
        # the other image's line on the cover plane at h_ref, seen from each camera: where
        # the cover's edge lies there, and the block's foot below it (the block must show
        # below it at that height too, in ``cam`` only)
        p, d = lines[other][s]
        W = on_plane(Q[other], np.array([p - 20.0 * d, p + 20.0 * d]), desk_plane, h_ref)
        seen = {}
        for c in (cam, other):
            q = geometry.project(Q[c], np.vstack([W, W.mean(axis=0) - h_ref * up]))
            edge = 0.5 * (q[0] + q[1])
            n_out = _unit(np.array([q[0, 1] - q[1, 1], q[1, 0] - q[0, 0]]))
            if n_out @ (edge - corners[c].mean(axis=0)) < 0:
                n_out = -n_out
            seen[c] = (edge, _unit(q[1] - q[0]), n_out, float(n_out @ (q[2] - edge)))
        edge, d_edge, n_out, width = seen[cam]
        if width < cfg.block_px or seen[other][3] >= cfg.block_px:
            continue
        out = float(n_out @ (lines[cam][s][0] - edge))
        if cfg.block_share[0] * width <= out <= cfg.block_share[1] * width:
            lines[cam][s] = (edge, d_edge)
            moved = True
    return _corners_of(lines, corners) if moved else None


def _side_lines(corners: dict[str, NDArray[np.float64]]) -> dict[str, list[Fit]]:
    """Per camera, each side s (corner s to s + 1) of a quad (4, 2) as a line: (midpoint,
    unit direction)."""
    return {cam: [(0.5 * (c[s] + c[(s + 1) % 4]), _unit(c[(s + 1) % 4] - c[s])) for s in range(4)]
            for cam, c in corners.items()}


def _cover_height(lines: dict[str, list[Fit]], P: NDArray[np.float64],
                  use: Sequence[bool] | NDArray[np.bool_],
                  Q: dict[str, NDArray[np.float64]], desk_plane: NDArray[np.float64],
                  max_sigma: float) -> float | None:
    """The median height above the desk (metres) of the sides ``use`` of cover ``P``
    (4, 3) that stereo places to within ``max_sigma`` (:func:`_line_height` of both
    images' ``lines``), or None where none is."""
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    offset = float(desk_plane[3] / np.linalg.norm(desk_plane[:3]))
    ref = []
    for s in range(4):
        if use[s]:
            a, b = P[s], P[(s + 1) % 4]
            z, sigma = _line_height({cam: lines[cam][s] for cam in lines}, a, b, Q, up)
            if sigma <= max_sigma:
                ref.append(float(up @ (0.5 * (a + b)) + offset) + z)
    return float(np.median(ref)) if ref else None


def _apart(lines: dict[str, list[Fit]], P: NDArray[np.float64], s: int,
           Q: dict[str, NDArray[np.float64]], desk_plane: NDArray[np.float64], height: float,
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[float]]:
    """Side ``s`` of cover ``P`` (4, 3) on the plane ``height`` above the desk: its
    midpoint there, its normal in that plane, and where each image's line (left, right)
    back-projects onto that plane, as offsets from the midpoint along the normal."""
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    origin = -float(desk_plane[3] / np.linalg.norm(desk_plane[:3])) * up + height * up
    a, b = P[s], P[(s + 1) % 4]
    n = np.cross(up, _unit(b - a - ((b - a) @ up) * up))
    mid = 0.5 * (a + b)
    m = mid - ((mid - origin) @ up) * up  # the side's midpoint on that plane
    return m, n, [_across(lines[cam][s], Q[cam], m, n) for cam in ("left", "right")]


def _across(fit: Fit, Q: NDArray[np.float64], m: NDArray[np.float64],
            n: NDArray[np.float64]) -> float:
    """Where image line ``fit`` (point, direction), back-projected through camera ``Q`` (a
    plane), meets a plane parallel to the desk: its offset from ``m`` (in that plane)
    along ``n`` (across the side, in that plane); NaN where it runs along ``n``."""
    p, d = fit
    line = np.array([-d[1], d[0], d[1] * p[0] - d[0] * p[1]]) @ Q  # its plane (4,)
    denom = float(line[:3] @ n)
    return float("nan") if abs(denom) < 1e-12 else -float(line[:3] @ m + line[3]) / denom


def _corners_of(lines: dict[str, list[Fit]], corners: dict[str, NDArray[np.float64]],
                max_move_px: float = 40.0) -> dict[str, NDArray[np.float64]] | None:
    """Per camera, the corners (4, 2) where ``lines``' sides meet (corner k joins side
    k - 1 and side k), or None where two do not meet within ``max_move_px`` of the
    corner they replace."""
    out = {}
    for cam, c in corners.items():
        new = c.copy()
        for k in range(4):
            p = intersect(*lines[cam][k - 1], *lines[cam][k])
            if p is None or np.linalg.norm(p - c[k]) > max_move_px:
                return None
            new[k] = p
        out[cam] = new
    return out


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    return v / max(float(np.linalg.norm(v)), 1e-12)


@dataclass(frozen=True)
class CompleteConfig:
    """Placing a candidate's unseen sides in 3D (:func:`complete_open`; metres unless noted).

    ``enabled`` turns it on (the pipeline's candidate step). Each unseen side is looked for
    within ``search`` of where the segmentation guessed it, every ``step``; it must show a
    step across it (a derivative of ``threshold_ratio`` of each image's Canny low
    threshold, the gradient within ``max_angle_deg`` of across it) along ``min_support``
    of its samples in both images, and the strongest such offset is taken, or for a side
    facing the camera (``inner_edge``) the first from inside. A side's stereo height counts
    towards the cover's where its standard deviation is at most ``side_sigma`` (for 0.1 px
    per fit). Where no height is measured (two opposite sides along the epipolar lines),
    heights from the desk up to ``max_height`` are tried every ``height_step``, then every
    quarter of that within half a step of the best; no height is taken where one more than
    ``sweep_window`` from the best scores within ``sweep_margin`` of it (a fraction of the
    best score; 0 turns the test off): a flat sweep, the unseen sides finding steps at any
    height.

    ``at_ends`` (beyond the paper): an unseen side no offset of which within ``search`` is
    a step in both images at once (a cover of the desk's tone, its far sides against the
    desk) stays where the two images' seen sides end, if those ends agree within
    ``ends_agree``; only where stereo places a corner of two seen sides, every height
    measured within ``ends_spread`` of the others; the side facing away from the camera
    (no page block of its own to show); the seen sides next to it edges up to its corners
    and no further; and the cover plain inside (at most ``plain_share`` of its middle at
    the Canny low threshold).

    ``print_taller`` (beyond the paper): the pipeline asks whether a completed cover's print
    goes on beyond an unseen side (:func:`rovis.sweep.print_goes_on`: then the side lies on
    a band of the print, and the cover is not taken). A side half or more of which lies on
    or within ``SweepConfig.strip_px``'s far bound of the left image's outline of a book
    found ``taller_by`` or more higher than the cover is not asked: that book's page block
    rises through the cover's height, and matches there as the print would.
    """

    enabled: bool = True
    search: float = 0.025
    step: float = 0.001
    height_step: float = 0.008
    max_height: float = 0.10
    threshold_ratio: float = 0.5
    min_support: float = 0.45
    max_angle_deg: float = 25.0
    side_sigma: float = 0.008
    inner_edge: bool = True
    at_ends: bool = True
    ends_agree: float = 0.005
    ends_spread: float = 0.015
    plain_share: float = 0.02
    print_taller: bool = True
    taller_by: float = 0.01
    sweep_margin: float = 0.02
    sweep_window: float = 0.015


def complete_open(corners: dict[str, NDArray[np.float64]], seen: dict[str, NDArray[np.bool_]],
                  Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                  min_strength: dict[str, float], desk_plane: NDArray[np.float64],
                  cfg: CompleteConfig = CompleteConfig(), *,
                  height_range: tuple[float, float] = (0.0, np.inf),
                  side_range: tuple[float, float] = (0.048, 0.45),
                  fits: dict[str, list[Fit | None]] | None = None,
                  print_height: Callable[[], float | None] | None = None,
                  ends_refused: Callable[[NDArray[np.float64]], bool] | None = None,
                  ) -> NDArray[np.float64] | None:
    """A cover candidate with sides unseen, completed to a rectangle on the desk's parallel.

    A three- or two-sided candidate (:func:`rovis.segment.quads.three_sided_quads`,
    :func:`~rovis.segment.quads.two_sided_quads`) guesses its unseen sides in each image
    on its own, where its seen sides' edges end; refined there, one image's guess often
    snaps to a print or the page block's foot and the other's does not, and the pair is
    no flat cover (corners centimetres apart in height). A book lies on the desk, so its
    cover is a rectangle parallel to it: the seen sides, fitted in the images that saw
    them, give its height (at their corners, triangulated) and its orientation (laid on
    that plane); each unseen side is then one offset, looked for in 3D, where its
    projection shows a step in *both* images at once.

    Parameters
    ----------
    corners : dict camera -> ndarray, shape (4, 2)
        The candidate's corners in each ideal image, the same physical corner at one index.
    seen : dict camera -> ndarray, shape (4,), bool
        Which sides (side s from corner s to s + 1) were Hough lines in that image.
    Q, grads, min_strength, desk_plane
        As :func:`fit_extent`.
    cfg : CompleteConfig
    height_range : (float, float)
        The cover's height above the desk must lie within it (metres).
    side_range : (float, float)
        Every side of the completed cover must lie within it (metres).
    fits : dict camera -> list of 4 (point, direction) or None, optional
        Each side's line in each image (None where unseen or not refit), if already
        known (the pipeline fits each candidate once for every pair it is in); by default
        the seen sides refit here (:func:`rovis.segment.boundary.refine_sides`).
    print_height : callable, optional
        The cover's height above the desk by its print (metres; None where the print does
        not tell: :func:`rovis.sweep.print_height`), asked only where the seen sides give
        none. A side facing the camera shows its page block, whose foot on the desk is as
        strong an edge as the cover's: with no height the sweep below may place the
        unseen sides on the feet, at the desk (build/t2 scene 13's photo cover, 14 mm
        high, came out at 4 mm).
    ends_refused : callable, optional
        Given a rectangle (4, 3), whether ``cfg.at_ends`` may not give it (the pipeline:
        two of its sides other books' edges, the desk between them).

    Returns
    -------
    ndarray, shape (4, 3) or None
        World corners in the same order, or None: fewer than two sides seen, none unseen,
        no height, or an unseen side with no step in both images (but see
        ``CompleteConfig.at_ends``).
    """
    anchored = np.asarray(seen["left"], bool) | np.asarray(seen["right"], bool)
    if anchored.sum() < 2 or anchored.all():
        return None
    cams = ("left", "right")
    if fits is None:  # the seen sides refit as the covers' are (the page block's foot not)
        fits = {cam: [f if seen[cam][s] else None
                      for s, f in enumerate(refine_sides(grads[cam], corners[cam]))]
                for cam in cams}
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    # The cover's height, by stereo: at each corner of two sides fitted in both images
    # (intersected in each, triangulated) and along each side fitted in both images where
    # that is well conditioned (a side along the epipolar lines has none); the median, for
    # a corner or side on another book's edge or the page block's foot.
    estimates = []
    for c in range(4):
        if any(fits[cam][k] is None for cam in cams for k in (c - 1, c)):
            continue
        px = [intersect(*fits[cam][c - 1], *fits[cam][c]) for cam in cams]
        if px[0] is None or px[1] is None:
            continue
        P = geometry.triangulate_dlt(Q["left"], Q["right"], px[0][None], px[1][None])
        estimates.append(float(geometry.plane_distance(desk_plane, P)[0]))
    at_corner = bool(estimates)  # a corner of two seen sides, triangulated
    for s in range(4):
        if fits["left"][s] is None or fits["right"][s] is None:
            continue
        ab = geometry.triangulate_dlt(Q["left"], Q["right"], corners["left"][[s, (s + 1) % 4]],
                                      corners["right"][[s, (s + 1) % 4]])
        z, sigma = _line_height({cam: fits[cam][s] for cam in cams}, ab[0], ab[1], Q, up)
        if sigma <= cfg.side_sigma:
            estimates.append(float(geometry.plane_distance(desk_plane, ab.mean(axis=0)[None])[0]) + z)
    strength = {cam: cfg.threshold_ratio * min_strength[cam] for cam in cams}
    if estimates:
        h = float(np.nanmedian(estimates)) if np.any(np.isfinite(estimates)) else np.nan
        if not (np.isfinite(h) and height_range[0] <= h <= height_range[1]):
            return None
        # an unseen side showing no step may stay where the seen sides end (_place) where
        # stereo places a corner, every height agreeing
        at_ends = cfg.at_ends and at_corner and float(np.ptp(estimates)) <= cfg.ends_spread
        placed = _place(h, corners, fits, Q, grads, strength, desk_plane, cfg, side_range,
                        at_ends=at_ends, ends_refused=ends_refused)
        return None if placed is None else placed[0]
    # Two opposite sides along the epipolar lines (stereo cannot place them), their ends
    # where each image's edges happen to stop: no height. The cover's print tells it where
    # it can (then the unseen sides are placed there, or nowhere: no sweep after it).
    # Else the unseen sides, across the epipolar lines: the height whose rectangle has the
    # strongest unseen sides, every cfg.height_step over the range, then every quarter of
    # that around the best, from the desk up: a sheet on the desk must come out there, not
    # at the lowest height a cover may have
    lo, hi = 0.0, min(height_range[1], cfg.max_height)
    h = None if print_height is None else print_height()
    if h is not None:
        if not height_range[0] <= h <= hi:
            return None
        placed = _place(h, corners, fits, Q, grads, strength, desk_plane, cfg, side_range)
        return None if placed is None else placed[0]

    scored: list[tuple[float, float]] = []  # (height, score) of each height swept

    def sweep(heights: NDArray[np.float64], step: float,
              ) -> tuple[float, float, NDArray[np.float64]] | None:
        best = None  # (score, height, corners)
        for h in heights[(heights >= lo) & (heights <= hi)]:
            placed = _place(float(h), corners, fits, Q, grads, strength, desk_plane, cfg,
                            side_range, step=step)
            if placed is not None:
                scored.append((float(h), placed[1]))
                if best is None or placed[1] > best[0]:
                    best = (placed[1], float(h), placed[0])
        return best

    coarse = sweep(np.arange(lo, hi + 1e-9, cfg.height_step), 2 * cfg.step)  # every other offset
    if coarse is None:
        return None
    # a height well away from the best that scores about as well (so far only the coarse
    # sweep's): the unseen sides find steps whatever the height (a plain cover beside
    # another book's edges: build/t2 scene 49's 13 mm book scored 13.2 at the desk and 13.7
    # at 48 mm, and came out 46 mm high)
    if cfg.sweep_margin > 0 and any(
            abs(h - coarse[1]) > cfg.sweep_window
            and score >= (1.0 - cfg.sweep_margin) * coarse[0] for h, score in scored):
        return None
    fine = sweep(coarse[1] + cfg.height_step / 4 * np.arange(-2.0, 2.5), cfg.step)
    return None if fine is None or fine[1] < height_range[0] else fine[2]


def _place(h: float, corners: dict[str, NDArray[np.float64]],
           fits: dict[str, list[Fit | None]],
           Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
           strength: dict[str, float], desk_plane: NDArray[np.float64],
           cfg: CompleteConfig, side_range: tuple[float, float], step: float | None = None,
           at_ends: bool = False,
           ends_refused: Callable[[NDArray[np.float64]], bool] | None = None,
           ) -> tuple[NDArray[np.float64], float] | None:
    """:func:`complete_open`'s rectangle at cover height ``h``: its corners (4, 3) and the
    summed strength of its unseen sides (units of ``strength``), or None; the unseen sides
    looked for every ``step`` (default ``cfg.step``). With ``at_ends``, an unseen side no
    offset of which is a step in both images may stay at its guess (:func:`_at_ends`),
    unless ``ends_refused`` says no to the rectangle it makes."""
    cams = ("left", "right")
    on_desk, up, e1, e2 = _plane_frame(desk_plane)
    origin = on_desk + h * up

    def flat(X: NDArray[np.float64]) -> NDArray[np.float64]:  # cover plane coordinates
        return np.column_stack([(X - origin) @ e1, (X - origin) @ e2])

    # 1. each seen side on that plane: its fits' ends, both images
    ends: dict[int, list[NDArray[np.float64]]] = {s: [] for s in range(4)}
    guesses = {cam: flat(on_plane(Q[cam], corners[cam], desk_plane, h)) for cam in cams}
    guess = 0.5 * (guesses["left"] + guesses["right"])  # corners as the images guessed them
    for cam in cams:
        for s in range(4):
            f = fits[cam][s]
            if f is None:
                continue
            p, d = f
            t = [(corners[cam][k] - p) @ d for k in (s, (s + 1) % 4)]
            ends[s].append(flat(on_plane(Q[cam], np.array([p + t[0] * d, p + t[1] * d]),
                                          desk_plane, h)))
    fitted = [s for s in range(4) if ends[s]]
    if len(fitted) < 2:
        return None
    # 2. the rectangle's axes: the fitted sides' directions (odd sides turned by 90°)
    phi = np.array([np.arctan2(e[1, 1] - e[0, 1], e[1, 0] - e[0, 0])
                    + (np.pi / 2 if s % 2 else 0.0) for s in fitted for e in ends[s]])
    theta = 0.5 * np.arctan2(np.mean(np.sin(2 * phi)), np.mean(np.cos(2 * phi)))
    u = np.array([np.cos(theta), np.sin(theta)])
    v = np.array([-np.sin(theta), np.cos(theta)])
    normal = [v, u, v, u]  # side s lies on normal[s] · x = offset[s]
    offset = np.array([normal[s] @ (np.mean(ends[s], axis=(0, 1)) if ends[s] else
                                    0.5 * (guess[s] + guess[(s + 1) % 4])) for s in range(4)])

    def corners_at(o: NDArray[np.float64]) -> NDArray[np.float64]:
        """(D, 4, 3) world corners for offsets (D, 4)."""
        xy = np.empty((len(o), 4, 2))
        for c in range(4):  # corner c joins side c - 1 and side c
            a, b = (o[:, c - 1], o[:, c]) if c % 2 == 0 else (o[:, c], o[:, c - 1])
            xy[:, c] = a[:, None] * u + b[:, None] * v  # u·x = a, v·x = b
        return origin + xy[..., :1] * e1 + xy[..., 1:] * e2

    # 3. each unseen side: the offset near its guess that is a step in both images
    limits = ExtentConfig(min_support=cfg.min_support, max_angle_deg=cfg.max_angle_deg)
    open_sides = [s for s in range(4) if s not in fitted]
    total = 0.0
    adjacent = len(open_sides) == 2 and (open_sides[1] - open_sides[0]) % 2 == 1
    for _ in range(2 if adjacent else 1):  # two adjacent unseen sides bound each other
        total = 0.0
        for s in open_sides:
            d = np.arange(-cfg.search, cfg.search + 1e-9, step or cfg.step)
            o = np.repeat(offset[None], len(d), axis=0)
            o[:, s] += d
            P = corners_at(o)
            length = np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=2)
            idx = np.flatnonzero(np.all((length >= side_range[0])
                                        & (length <= side_range[1]), axis=1))
            if len(idx) == 0:
                return None
            edge, score = _side_scores(P[idx], s, (s + 1) % 4, Q, grads, strength, limits)
            if not edge.any():
                # no offset a step in both images at once (a cover of the desk's tone
                # against the desk): the side may stay at its guess (d = 0), where both
                # images' seen sides end (complete_open's at_ends)
                if not (at_ends and int(np.argmin(np.abs(d))) in idx
                        and _at_ends(corners_at(offset[None])[0], s, fitted, guesses,
                                     normal[s], h * up, Q, grads, strength, limits, cfg)
                        and not (ends_refused is not None
                                 and ends_refused(corners_at(offset[None])[0]))):
                    return None
                continue
            full = np.full(len(d), -np.inf)  # the score of every offset that is an edge
            full[idx[edge]] = score[edge]
            k = int(np.argmax(full))
            if cfg.inner_edge and _block_shows(corners_at(offset[None])[0], s, Q, -h * up):
                # a side facing the camera: its page block's foot, further out, is an edge
                # too, and along the epipolar lines stereo cannot tell their heights; the
                # cover's edge is the first from inside
                pad = np.concatenate([[-np.inf], full, [-np.inf]])
                peak = np.flatnonzero((full > -np.inf) & (full >= pad[:-2]) & (full >= pad[2:]))
                outward = np.sign(offset[s] - offset[(s + 2) % 4])
                k = int(peak[np.argmin(outward * d[peak])])
            offset[s] = o[k, s]
            total += float(full[k])
    return corners_at(offset[None])[0], total


def _at_ends(P: NDArray[np.float64], s: int, fitted: list[int],
             guesses: dict[str, NDArray[np.float64]], normal: NDArray[np.float64],
             lift: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
             grads: dict[str, Gradients], strength: dict[str, float], limits: ExtentConfig,
             cfg: CompleteConfig) -> bool:
    """Whether unseen side ``s`` of :func:`_place`'s rectangle ``P`` (4, 3), at its guess,
    may stay there with no step (:class:`CompleteConfig`'s ``at_ends``): the two images'
    guesses of it (``guesses``, corners (4, 2) on the cover's plane; ``normal``: the side's
    in that plane) within ``cfg.ends_agree``; the side facing away from the cameras (the
    page block below it hidden: ``lift`` is the cover's height times the desk's normal);
    the seen sides beside it ending at its corners (:func:`_ends_at`); and the cover plain
    inside in both images (:func:`strong_share` at the Canny low threshold)."""
    apart = [normal @ (0.5 * (g[s] + g[(s + 1) % 4])) for g in guesses.values()]
    if abs(apart[0] - apart[1]) > cfg.ends_agree or _block_shows(P, s, Q, -lift):
        return False
    if not _ends_at(P, s, fitted, Q, grads, strength, limits):
        return False
    # strength is cfg.threshold_ratio of each image's Canny low threshold
    return all(strong_share(grads[cam], geometry.project(Q[cam], P),
                            strength[cam] / cfg.threshold_ratio) <= cfg.plain_share
               for cam in Q)


def _ends_at(P: NDArray[np.float64], s: int, fitted: list[int], Q: dict[str, NDArray[np.float64]],
             grads: dict[str, Gradients], strength: dict[str, float], limits: ExtentConfig,
             reach: float = 0.02, stop: float = 0.25) -> bool:
    """Whether the seen sides next to side ``s`` of the rectangle ``P`` (4, 3) run on as
    edges, in both images, up to its corners (along ``limits.min_support`` of their last
    ``reach`` metres) and stop there (along less than ``stop`` of the next ``reach``, in
    each image). Side ``s`` then lies where they end, as the images guessed it."""
    near = [(k, s if k == (s - 1) % 4 else (s + 1) % 4) for k in ((s - 1) % 4, (s + 1) % 4)
            if k in fitted]
    for k, corner in near:
        other = k if corner == (k + 1) % 4 else (k + 1) % 4
        d = P[other] - P[corner]
        d = reach * d / max(float(np.linalg.norm(d)), 1e-9)
        end = np.stack([P[corner] + d, P[corner], P[corner], P[corner] - d])[None]
        edge, _ = _side_scores(end, 0, 1, Q, grads, strength, limits)
        if not edge[0]:
            return False
        # ...and stop there: a line of the desk's grain or a neighbour's edge runs on
        if any(_side_scores(end, 2, 3, Q, grads, strength, limits, cams=(cam,),
                            min_support=stop)[0][0] for cam in Q):
            return False
    return bool(near)


def strong_share(grad: Gradients, quad: NDArray[np.float64], min_gradient: float,
                 inset: float = 0.8) -> float:
    """The share of the pixels of a quad's middle (``inset`` of it about its centre) whose
    gradient is ``min_gradient`` or more: about 0 inside a plain cover.

    Parameters
    ----------
    grad : Gradients
    quad : ndarray, shape (4, 2)
        Ideal pixel corners.
    min_gradient : float
        Sobel units.
    inset : float
        The share of the quad's size (about its centre) looked at: its sides' own edges
        left out.

    Returns
    -------
    float
        In [0, 1]; 1 where the middle holds no pixel of the image (nothing shows it plain).
    """
    q = np.asarray(quad, dtype=np.float64)
    q = q.mean(axis=0) + inset * (q - q.mean(axis=0))
    h, w = grad.dx.shape
    x0, y0 = np.clip(np.floor(q.min(axis=0)).astype(int), 0, [w, h])
    x1, y1 = np.clip(np.ceil(q.max(axis=0)).astype(int) + 1, 0, [w, h])
    inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillPoly(inside, [np.round(q - (x0, y0)).astype(np.int32)], 1)
    dx = grad.dx[y0:y1, x0:x1].astype(np.float32)
    dy = grad.dy[y0:y1, x0:x1].astype(np.float32)
    strong = (dx * dx + dy * dy >= min_gradient ** 2) & (inside > 0)
    n_inside = np.count_nonzero(inside)
    return np.count_nonzero(strong) / n_inside if n_inside else 1.0


def lift_foot(corners: dict[str, NDArray[np.float64]], Q: dict[str, NDArray[np.float64]],
              grads: dict[str, Gradients], P: NDArray[np.float64],
              desk_plane: NDArray[np.float64], *, min_height: float = 0.006,
              max_height: float = 0.10, low_ratio: float = 0.3, agree: float = 0.004,
              max_sigma: float = 0.004) -> NDArray[np.float64] | None:
    """A cover one side of which both images took on the foot of its page block, lifted.

    Beyond the paper. Where a book's page block shows below a side, its foot on the desk is
    an edge as strong as the cover's own, a pixel or two beyond it: with that side on the
    foot in both images, its corners triangulate near the desk and the cover tilts. A book
    is a cuboid: its cover's edge lies straight above the foot. The side (``P``'s lowest,
    its mean height at most ``low_ratio`` of the opposite side's, which stands between
    ``min_height`` and ``max_height``) is back-projected onto the desk in each image; the two must
    agree (their ends within ``agree`` metres of the other's line), and lifted to the
    opposite side's height it closes the cover there, with the other three sides
    back-projected onto that plane (each image's, averaged). The page block below the
    side must show in one image at least (else its foot is hidden), and each of the
    three other sides that stereo places on its own (:func:`_edge_height`, to within
    ``max_sigma``) must stand at half that height or more: a sheet on the desk whose
    corners triangulate a centimetre apart is no book.

    Parameters
    ----------
    corners : dict camera -> ndarray, shape (4, 2)
        The pair's corners in each ideal image, the same physical corner at each index.
    Q : dict camera -> ndarray, shape (3, 4)
    grads : dict camera -> Gradients
        Both ideal images' gradients, for the other sides' heights.
    P : ndarray, shape (4, 3)
        The corners triangulated (world, metres).
    desk_plane : ndarray, shape (4,)
    min_height, max_height : float
        Metres: the range of the cover's height (the opposite side's).
    low_ratio : float
        The foot side's mean height, at most this share of the opposite side's.
    agree : float
        Metres: the two images' feet on the desk, each one's ends this near the other's
        line.
    max_sigma : float
        Metres: a side's stereo height (:func:`_edge_height`) counts where its standard
        deviation is at most this.

    Returns
    -------
    ndarray, shape (4, 3) or None
        The cover's corners in the order of ``corners``, or None where no side is such a
        foot.
    """
    h = geometry.plane_distance(desk_plane, P)
    side_h = 0.5 * (h + np.roll(h, -1))  # side s from corner s to s + 1
    s = int(np.argmin(side_h))
    top = float(side_h[(s + 2) % 4])
    if not (min_height <= top <= max_height and side_h[s] <= low_ratio * top):
        return None
    cams = ("left", "right")
    on_desk, up, e1, e2 = _plane_frame(desk_plane)

    def ends(k: int, height: float) -> list[NDArray[np.float64]]:
        # side k's ends back-projected onto the plane at ``height``, each image's (plane
        # coordinates, (2, 2) each)
        out = []
        for cam in cams:
            X = on_plane(Q[cam], corners[cam][[k, (k + 1) % 4]], desk_plane, height) - on_desk
            out.append(np.column_stack([X @ e1, X @ e2]))
        return out

    def line(e: list[NDArray[np.float64]]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        mid = 0.5 * (e[0] + e[1])  # the two images' mean: a point and a unit direction
        return 0.5 * (mid[0] + mid[1]), _unit(mid[1] - mid[0])

    feet = ends(s, 0.0)
    for a, b in ((0, 1), (1, 0)):  # the images' feet on one line of the desk
        d = _unit(feet[b][1] - feet[b][0])
        if np.abs((feet[a] - feet[b][0]) @ np.array([-d[1], d[0]])).max() > agree:
            return None
    sides = {s: line(feet)}
    for k in (s + 1, s + 2, s + 3):
        sides[k % 4] = line(ends(k % 4, top))
    out = np.empty((4, 3))
    for c in range(4):  # corner c joins side c - 1 and side c
        x = intersect(*sides[(c - 1) % 4], *sides[c])
        if x is None:
            return None
        out[c] = on_desk + top * up + x[0] * e1 + x[1] * e2
    if not _block_shows(out, s, Q, -top * up):
        return None  # the block below the side is hidden: its foot is seen in neither image
    for k in (s + 1, s + 2, s + 3):
        z, sigma = _edge_height(out, k % 4, Q, grads, up)
        if sigma <= max_sigma and top + z < 0.5 * top:
            return None
    return out


def foot_side(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
              grads: dict[str, Gradients], desk_plane: NDArray[np.float64],
              cfg: FacingConfig = FacingConfig()) -> float:
    """How far (metres, inward) side ``s`` of cover ``P`` (4, 3) must move where both
    images took it on the foot of its page block: 0 where they did not.

    Beyond the paper. Below a side facing the camera the page block shows; where the
    cover's edge above it is faint (a light cover on white pages), both images' sides may
    take the block's foot instead, and no stereo test of the pair tells: on the cover's
    plane the two lines meet, the cover lies flat at its height, only one side longer by
    the block's depth in view (h times the cotangent of the camera's elevation: a 6 cm
    book seen from 45° up, 6 cm). A book is a cuboid: where the side is the foot, the
    cover's edge lies straight above it. The side's ends are back-projected onto the desk
    in each image, lifted by the cover's height ``h``, and the move is the mean of the two
    images' inward offsets to that line (across the side; :func:`_moved` slides its
    corners along the sides beside it). It is taken where

    - the block it hides is ``cfg.foot_px`` pixels wide or more in one image (below that,
      the foot and the cover's edge are one edge to the fits);
    - a side of the cover that does not face the camera has its edge, by stereo, within
      ``cfg.foot_agree`` of ``h`` (to within ``cfg.foot_sigma`` of ``h``): the cover lies
      at ``h``;
    - the side's edge, fitted in each image within ``cfg.foot_fit_px`` of it, lies by
      stereo (:func:`_line_height`) at ``cfg.foot_level`` of ``h`` or lower, to within
      ``cfg.foot_sigma`` of ``h``: nearer the desk than the cover;
    - the edge at the moved side, where stereo places one as well, is not lower than
      ``cfg.foot_cover`` of ``h`` (a shadow's edge on the desk beyond the foot: no cover
      edge above it);
    - the move is less than half the sides beside it (a cover's page block, seen from
      above, is never as deep as the cover).

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        Cover corners on a plane parallel to the desk (world, metres), in cyclic order.
    s : int
        The side, from corner ``s`` to ``s + 1``.
    Q, grads, desk_plane
        As :func:`fit_extent`.
    cfg : FacingConfig

    Returns
    -------
    float
        Metres inward (0: the side stays).
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    h = float(np.mean(geometry.plane_distance(desk_plane, P)))
    if not h > 0 or not _facing(P, s, Q) or not _block_shows(P, s, Q, -h * up):
        return 0.0  # (not h > 0: NaN corners too)
    a, b = P[s], P[(s + 1) % 4]
    inward = np.cross(up, _unit(b - a))
    if inward @ (P.mean(axis=0) - 0.5 * (a + b)) < 0:
        inward = -inward
    moves, width = [], 0.0
    for cam in ("left", "right"):
        q = geometry.project(Q[cam], np.array([a, b]))
        cover = on_plane(Q[cam], q, desk_plane, 0.0) + h * up  # the foot, lifted
        moves.append(float(np.mean((cover - np.array([a, b])) @ inward)))
        r = geometry.project(Q[cam], cover)
        n = np.array([q[0, 1] - q[1, 1], q[1, 0] - q[0, 0]])
        width = max(width, abs(float(n @ (r.mean(axis=0) - q.mean(axis=0))))
                    / max(float(np.linalg.norm(n)), 1e-9))
    move = float(np.mean(moves))
    beside = 0.5 * (np.linalg.norm(P[s] - P[(s - 1) % 4])
                    + np.linalg.norm(P[(s + 1) % 4] - P[(s + 2) % 4]))
    if width < cfg.foot_px or not 0 < move < 0.5 * beside:
        return 0.0

    def level(corners: NDArray[np.float64]) -> tuple[float, float]:
        # the side's edge above the desk by stereo, and its standard deviation (metres)
        z, sigma = _edge_height(corners, s, Q, grads, up, half_width=cfg.foot_fit_px)
        return h + z, sigma

    z, sigma = level(P)
    if not (sigma <= cfg.foot_sigma * h and z <= cfg.foot_level * h):
        return 0.0
    z, sigma = level(_moved(P, s, np.array([-move]))[0])
    if sigma <= cfg.foot_sigma * h and z < cfg.foot_cover * h:
        return 0.0
    # last (the dearest test, and most sides are refused above): the cover's height, as
    # a side with no block below it places its edge; a cover placed at another height
    # lifts the foot by the wrong amount
    if not any(sigma <= cfg.foot_sigma * h and abs(z) <= cfg.foot_agree * h
               for z, sigma in (_edge_height(P, k, Q, grads, up) for k in range(4)
                                if k != s and not _facing(P, k, Q))):
        return 0.0
    return move


def height_off_feet(P: NDArray[np.float64], Q: dict[str, NDArray[np.float64]],
                    grads: dict[str, Gradients], desk_plane: NDArray[np.float64],
                    cfg: FacingConfig = FacingConfig()) -> float | None:
    """The cover's height above the desk (metres) as its sides give it where none of them
    could be its page block's foot, or None where fewer than two tell it or they disagree.

    Beyond the paper. A side both images took on the block's foot is triangulated on the
    desk, and the cover's corners with it: rendered books 1–5 cm thick came out 1–3 cm
    low, so :func:`foot_side`, asking for a side at that height, found none and lifted
    nothing. Here each side is fitted within ``cfg.relay_fit_px`` pixels of where it lies
    (the side itself, not an edge beside it, as :func:`height_from_sides`'s wider fit may
    take) and placed by stereo (:func:`_edge_height`). A side facing the camera is not
    asked where its block would show ``cfg.foot_px`` pixels or more at the corners' height
    (a foot :func:`foot_side` could move; below that the foot and the cover's edge are one
    edge to the fits). NaN corners, or corners on or below the desk: None.

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        Cover corners on a plane parallel to the desk (world, metres), in cyclic order.
    Q, grads, desk_plane
        As :func:`fit_extent`.
    cfg : FacingConfig
        ``relay_fit_px``, ``relay_sigma``, ``relay_agree`` and ``foot_px``.
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    h = float(np.mean(geometry.plane_distance(desk_plane, P)))
    if not (h > 0 and np.all(np.isfinite(P))):
        return None
    levels = []
    for s in range(4):
        if _facing(P, s, Q) and _block_shows(P, s, Q, -h * up, min_px=cfg.foot_px):
            continue  # maybe the foot
        z, sigma = _edge_height(P, s, Q, grads, up, half_width=cfg.relay_fit_px)
        if sigma <= cfg.relay_sigma:  # (inf where a fit fails)
            levels.append(h + z)
    if len(levels) < 2 or np.ptp(levels) > cfg.relay_agree:
        return None
    return float(np.mean(levels))


def under_taller(P: NDArray[np.float64], s: int, taller: Sequence[NDArray[np.float64]],
                 Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                 desk_plane: NDArray[np.float64], cfg: FacingConfig = FacingConfig(), *,
                 texture: dict[str, NDArray[np.float32]] | None = None,
                 sweep: SweepConfig = SweepConfig()) -> float:
    """How far side ``s`` of cover ``P`` goes on hidden under a taller book in front of it.

    A book in front of a lower one (nearer the cameras) and taller than it hides the strip
    of the lower cover behind its top edge, and the lower cover's quad ends at that edge in
    both images: its side facing the cameras comes out short. Books stand apart or flush on
    the desk, so the hidden side lies no further out than the taller book's side, and
    flush (as books put down together are), right under it. So where side ``s`` lies on a
    side of one of ``taller`` in both images, that book stands beyond it on the desk and
    the two sides share a stretch, the side is moved out, in the cover's plane, to straight
    under the taller book's side (the nearest such side, where several qualify). Not
    where the side shows as an edge beyond that stretch in either image (it is the cover's
    own edge, which goes on where nothing hides it), nor where an edge of the other
    polarity lies inside it within its page block's width (the cover's edge, with the
    block between it and the taller book's edge). A gap between the books that the
    taller one's edge hides is taken into the cover.

    With ``texture``, a side that lies short of the taller book's side, by up to
    ``cfg.under_print_px`` in both images, is moved too where the strip between is the
    cover's print (:func:`_print_between`): the side lay on a line of its print, the
    cover in view beyond it up to the taller book's edge. Where the nearest move is such
    a side's, the inside test is not asked (an edge of the other polarity inside it is
    more print, not the cover's edge).

    Parameters
    ----------
    P : ndarray, shape (4, 3)
        The cover's corners (world, metres), in order around it.
    s : int
        The side (corner s to s + 1); the caller asks this of a side facing the cameras
        (:func:`_facing`).
    taller : sequence of ndarray, shape (4, 3)
        The covers of the books found ``cfg.under_step`` or more taller.
    Q : dict
        "left", "right": world → ideal pixel projections (3, 4).
    grads : dict
        "left", "right": :class:`Gradients` of the ideal images.
    desk_plane : ndarray, shape (4,)
        ``[nx, ny, nz, d]``, n·X + d = 0, n up, world.
    cfg : FacingConfig
        ``under_px``, ``under_deg``, ``under_share``, ``under_min``, ``under_inner``,
        ``under_free``, ``under_print_px``.
    texture : dict, optional
        "left", "right": the high-passed ideal images (:func:`rovis.sweep.high_pass`), for
        the print test of a side short of the taller book's (none without them).
    sweep : SweepConfig
        ``strip_min_ncc`` and ``min_gap`` of that test.

    Returns
    -------
    float
        The outward move (metres), 0 where the side stays.
    """
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    a, b = P[s], P[(s + 1) % 4]
    m, length = 0.5 * (a + b), float(np.linalg.norm(b - a))
    u = (b - a) / length
    n = _unit(np.cross(up, u))  # (u may tilt a little: the corners as triangulated)
    if n @ (m - P.mean(axis=0)) < 0:
        n = -n  # outward
    reach = max(cfg.under_px, cfg.under_print_px if texture is not None else 0.0)
    seen = {c: geometry.project(Q[c], np.array([a, b])) for c in Q}  # the side, each image
    moves = []
    for PB in taller:
        for t in range(4):
            top = PB[[t, (t + 1) % 4]]
            # how far the side lies from that book's side in each image, nearest and
            # furthest (inf: not along it, or further than reach)
            gaps = {c: _on_side(seen[c], geometry.project(Q[c], top), cfg, reach) for c in Q}
            if max(far for _, far in gaps.values()) > reach:
                continue
            # the taller book's side straight below, in the cover's plane
            e0, e1 = top - np.outer((top - m) @ up, up)
            ends = sorted([float((e0 - a) @ u), float((e1 - a) @ u)])
            shared = max(0.0, min(ends[1], length) - max(ends[0], 0.0)) / length
            if (PB.mean(axis=0) - m) @ n <= 0 or shared < cfg.under_share:
                continue  # behind the side, or beside it
            # m + x n on the line e0 + y (e1 - e0)
            (x, _), *_ = np.linalg.lstsq(np.column_stack([n, e0 - e1]), e0 - m, rcond=None)
            if x < cfg.under_min or _edge_beyond(np.array([a, b]), top, Q, grads,
                                                cfg.under_free):
                continue
            short = max(far for _, far in gaps.values()) > cfg.under_px
            if short and not _print_between(P, s, top, gaps["left"][0], Q, desk_plane,
                                            texture, sweep):
                continue  # short of it: the strip between must be the cover's print
            moves.append((float(x), short))
    if not moves:
        return 0.0
    # the nearest taller book's side bounds the hidden one; a side short of it with the
    # cover's print beyond is no edge of the cover's, whatever lies inside it (more print)
    move, short = min(moves)
    if not short and _edge_inside(P, s, Q, grads, _drop(P, desk_plane), cfg.under_inner):
        return 0.0
    return move


def _on_side(qa: NDArray[np.float64], qb: NDArray[np.float64], cfg: FacingConfig,
             reach: float) -> tuple[float, float]:
    """How far segment ``qa`` (2, 2) lies from the line of segment ``qb`` (2, 2) in one
    image, pixels, nearest and furthest, over the stretch where ``qb`` runs alongside:
    where ``qa`` runs within ``cfg.under_deg`` of its direction, along ``cfg.under_share``
    of ``qa`` or more, within ``reach`` of it all along that stretch ((inf, inf)
    otherwise)."""
    da, db = qa[1] - qa[0], qb[1] - qb[0]
    la, lb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
    if la < 1 or lb < 1 or abs(da @ db) < np.cos(np.radians(cfg.under_deg)) * la * lb:
        return np.inf, np.inf
    ub = db / lb
    pts = qa[0] + np.linspace(0.0, 1.0, 21)[:, None] * da
    along = (pts - qb[0]) @ ub
    beside = (along >= 0) & (along <= lb)
    across = np.abs((pts - qb[0]) @ np.array([-ub[1], ub[0]]))[beside]
    if not beside.any() or beside.mean() < cfg.under_share or np.any(across > reach):
        return np.inf, np.inf
    return float(across.min()), float(across.max())


def _print_between(P: NDArray[np.float64], s: int, top: NDArray[np.float64], gap_px: float,
                   Q: dict[str, NDArray[np.float64]], desk_plane: NDArray[np.float64],
                   texture: dict[str, NDArray[np.float32]] | None, cfg: SweepConfig) -> bool:
    """Whether the strip beyond side ``s`` of cover ``P`` (outward from the quad's middle,
    in the left image), out to where the taller book's side ``top`` (2, 3) is seen
    ``gap_px`` pixels away, is the cover's print: from 1.5 px beyond the side to 1.5 px
    short of ``top``, and each half of that where it is 6 px wide or more, it matches
    between the images at the cover's height with an NCC of ``cfg.strip_min_ncc`` or more,
    and by ``cfg.min_gap`` better than on the desk (:func:`rovis.sweep.side_strip_ncc`).
    (A strip of print, then the cover's edge and its page block, matches at the cover's
    height by its inner half alone.) A half too thin to sample (a side about level in the
    image) tells nothing and is not asked. False where ``top`` is not seen beyond the
    side, or the strip is under 3 px wide or gives no sweep (it tells nothing)."""
    near, far = 1.5, gap_px - 1.5
    if texture is None or far - near < 3.0:
        return False
    q = geometry.project(Q["left"], P)
    mid = 0.5 * (q[s] + q[(s + 1) % 4])
    if (geometry.project(Q["left"], top).mean(axis=0) - mid) @ (mid - q.mean(axis=0)) <= 0:
        return False  # (the taller book's side seen inward of this one: no strip between)
    height = float(np.mean(geometry.plane_distance(desk_plane, P)))
    half = 0.5 * (near + far)
    strips = [(near, far)] + ([(near, half), (half, far)] if far - near >= 6.0 else [])
    for k, (a, b) in enumerate(strips):
        ncc = side_strip_ncc(texture["left"], texture["right"], Q["left"], Q["right"], q,
                             desk_plane, [height, 0.0], s, near_px=a, far_px=b)
        if ncc is None:
            if k == 0:
                return False  # the whole strip gives no sweep
            continue  # a half too thin to sample
        if ncc[0] < cfg.strip_min_ncc or ncc[0] - ncc[1] <= cfg.min_gap:
            return False
    return True


def _edge_beyond(side: NDArray[np.float64], top: NDArray[np.float64],
                 Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients],
                 ratio: float) -> bool:
    """Whether a cover's ``side`` (2, 3) (world) is an edge, in either image, where the
    taller book's side ``top`` (2, 3) does not run alongside it (15 % of the side or more,
    3 px from its ends): its median gradient across there (:func:`_edge`, within 30° of
    the side's normal) ``ratio`` or more of that along the stretch they share (so always,
    where the shared stretch shows no gradient across)."""
    for c in Q:
        qa, qb = geometry.project(Q[c], side), geometry.project(Q[c], top)
        lb = float(np.linalg.norm(qb[1] - qb[0]))
        pts = qa[0] + np.linspace(0.02, 0.98, 49)[:, None] * (qa[1] - qa[0])
        along = (pts - qb[0]) @ ((qb[1] - qb[0]) / lb)
        free = (along < -3.0) | (along > lb + 3.0)
        if free.mean() < 0.15 or np.count_nonzero(~free) < 5:
            continue
        edge = _edge(grads[c], qa[0], pts, 30.0)
        if np.median(edge[free]) >= ratio * np.median(edge[~free]):
            return True
    return False


def _edge_inside(P: NDArray[np.float64], s: int, Q: dict[str, NDArray[np.float64]],
                 grads: dict[str, Gradients], drop: NDArray[np.float64], ratio: float) -> bool:
    """Whether, in either image, an edge of the other polarity than side ``s``'s own lies
    inside it within its page block's width and 1.5 px (from 1.5 px in): its median
    gradient across, over the middle 60 % of the side, at ``ratio`` or more of the
    side's. That is the cover's own edge, where the side lies on a taller book's edge
    with the cover's page block between; a cover hidden under that book shows none there
    (unless print, or the taller book's shadow, lies along the side). ``drop`` (3,) moves
    the cover onto the desk (:func:`_drop`)."""
    a, b = P[s], P[(s + 1) % 4]
    mid = 0.5 * (a + b)
    for c in Q:
        q = geometry.project(Q[c], np.array([a, b, mid, mid + drop]))
        d = q[1] - q[0]
        inward = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        if inward @ (q[2] - geometry.project(Q[c], P).mean(axis=0)) > 0:
            inward = -inward
        block = abs(float((q[3] - q[2]) @ inward))
        base = q[0] + np.linspace(0.2, 0.8, 25)[:, None] * d
        offsets = np.arange(-1.0, block + 1.51, 0.5)
        pts = base[None] + offsets[:, None, None] * inward
        gx, gy = grads[c].sample(pts[..., 0], pts[..., 1])
        across = np.median(gx * inward[0] + gy * inward[1], axis=1)  # (offsets,)
        own = across[np.abs(offsets) <= 1.0]
        sign = np.sign(own[np.argmax(np.abs(own))])
        if np.any(-sign * across[offsets > 1.0] >= ratio * np.max(np.abs(own))):
            return True
    return False
