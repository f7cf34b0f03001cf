"""A cover's height from its texture: a plane sweep between the two images (beyond the paper).

The corners give a cover's height through their disparity, and a few pixels of error in
one image move it by centimetres: at 1 m from a 12 cm baseline one pixel of disparity is
about 1 cm of height. A side taken on the page block's outer edge in one image, or a faint
side taken on a print line near it, shifts that image's quad, and the two quads still
triangulate to a flat, book-sized cover at the wrong height (Table I had covers 41 and 44 mm
too high). No test on the corners can see it.

The cover's own print is an independent witness. Seen through the plane parallel to the
desk at height h, the right image maps into the left by that plane's homography; inside the
cover the two agree best at the cover's true height. :func:`sweep_heights` scores heights
by the normalised cross-correlation (NCC) of the high-passed left image inside the cover
(inset from its sides, which may be wrong) and the right image warped through each plane.
A cover whose texture matches clearly better at another height than its corners' is moved
there by the pipeline when the match is near perfect (one flat surface), and dropped
otherwise (reason ``"texture height"``): a weaker match is a quad over more than one
surface.

A plain cover has no texture to match: its best NCC stays low and it testifies to nothing.
Where a taller neighbour hides one of its corners, that neighbour's edge or print is all the
texture inside the quad, and it matches at the neighbour's height: a move up must hold
beyond the cover's most textured quarter (or half) too (:func:`contradicts_beyond_quarter`).

The same sweep places a printed cover that one image's segmentation found and the other's
did not (:func:`find_by_print`), where the edge-based one-image search of
:mod:`rovis.stereo` finds nothing to refit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rovis import geometry


@dataclass(frozen=True)
class SweepConfig:
    """The texture check of each cover's height (metres unless noted).

    ``check`` turns it on; ``sigma_px``: the high-pass removes shading smoother than this
    Gaussian (pixels), leaving the print; heights from ``min_height`` to ``max_height``
    above the desk are tried every ``coarse_step``, then every ``step`` near the best;
    ``inset``: the cover is shrunk by this fraction of its smaller image side (half of it
    from each side) before comparing;
    ``max_samples``: the most left pixels compared;
    the texture contradicts the corners when its best NCC reaches ``min_ncc`` and beats the
    NCC at the corners' height by more than ``min_gap`` (corners outside the swept range:
    no evidence). The cover is then moved to the texture's
    height if its best NCC reaches ``min_ncc_to_move`` (one flat surface) and both images'
    quads, laid on that plane, agree within ``max_spread`` at every corner; otherwise it is
    dropped. ``beyond_quarter``: a move up must be told beyond the cover's most textured
    quarter too, or half where its texture fills one (:func:`contradicts_beyond_quarter`),
    or the cover stays: a taller neighbour's edge or print over one corner or along one
    side of a plain cover is no print of it. (Nothing lower than a cover shows through
    it, and a weaker match drops the cover either way: only moves up are asked.)

    ``transfer``: a cover found in one image only, that the one-image search of
    :mod:`rovis.stereo` cannot find in the other, is placed by its print
    (:func:`find_by_print`): its best NCC must reach ``min_ncc_to_move`` and beat every
    height ``peak_apart`` or more away by ``min_gap``, and the print must not go on beyond
    any side: the strip ``strip_px`` pixels outside it must not match at the cover's
    height (NCC ≥ ``strip_min_ncc``) better than on the desk by ``min_gap``.
    """

    check: bool = True
    sigma_px: float = 1.5
    min_height: float = 0.0
    max_height: float = 0.12
    coarse_step: float = 0.004
    step: float = 0.001
    inset: float = 0.1
    max_samples: int = 2000
    min_ncc: float = 0.3
    min_gap: float = 0.1
    min_ncc_to_move: float = 0.85
    max_spread: float = 0.015
    transfer: bool = True
    peak_apart: float = 0.02
    strip_px: tuple[float, float] = (3.0, 10.0)
    strip_min_ncc: float = 0.3
    beyond_quarter: bool = True

    def __post_init__(self) -> None:
        # (cv2.remap takes maps of at most 32767 columns and rows)
        n_coarse = (self.max_height - self.min_height) / self.coarse_step if self.coarse_step > 0 else 0
        if not (self.sigma_px > 0 and 0 < self.step <= self.coarse_step
                and self.max_height > self.min_height and 50 <= self.max_samples < 32767
                and n_coarse < 32000 and 0 <= self.inset < 1 and self.peak_apart > 0
                and 0 <= self.strip_px[0] < self.strip_px[1]):
            raise ValueError("sweep: sigma_px and peak_apart must be positive, 0 < step <= "
                             "coarse_step, max_height above min_height by fewer than 32000 "
                             "coarse steps, 50 <= max_samples < 32767, 0 <= inset < 1 and "
                             f"0 <= strip_px[0] < strip_px[1], got {self}")


@dataclass(frozen=True, eq=False)
class Sweep:
    """NCC of the cover's texture between the two images, per height above the desk.

    Attributes
    ----------
    heights : ndarray, shape (H,), metres, in increasing order (a height may repeat)
    ncc : ndarray, shape (H,), in [-1, 1]
    """

    heights: NDArray[np.float64]
    ncc: NDArray[np.float64]

    @property
    def best_height(self) -> float:
        return float(self.heights[int(np.argmax(self.ncc))])

    @property
    def best_ncc(self) -> float:
        return float(self.ncc.max())


def high_pass(gray: NDArray[np.uint8], sigma_px: float) -> NDArray[np.float32]:
    """The image less its Gaussian blur: print and texture without the shading."""
    img = gray.astype(np.float32)
    return img - cv2.GaussianBlur(img, (0, 0), sigma_px)


def plane_homography(Q: ArrayLike, origin: ArrayLike, e1: ArrayLike, e2: ArrayLike) -> NDArray[np.float64]:
    """3×3 homography from plane coordinates (u, v) to pixels: X = origin + u·e1 + v·e2.

    Parameters
    ----------
    Q : array_like, shape (3, 4)
        World → pixel projection.
    origin, e1, e2 : array_like, shape (3,)
        A point of the plane and two directions in it (world, metres).
    """
    B = np.zeros((4, 3))
    B[:3, 0], B[:3, 1], B[:3, 2], B[3, 2] = e1, e2, origin, 1.0
    return np.asarray(Q, dtype=np.float64) @ B


def sweep_heights(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                  Q_R: ArrayLike, quad_left: ArrayLike, desk_plane: ArrayLike,
                  heights: ArrayLike, *, inset: float = 0.1,
                  max_samples: int = 2000) -> Sweep | None:
    """NCC of the cover's texture between the images for each height above the desk.

    Parameters
    ----------
    left, right : ndarray, shape (H, W), float32
        High-passed ideal images (:func:`high_pass`).
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections.
    quad_left : array_like, shape (4, 2)
        The cover in the left ideal image, pixels.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, n·X + d = 0, n up, world.
    heights : array_like, shape (H,)
        Metres above the desk.
    inset : float
        The quad is shrunk by this fraction of its smaller side (pixels), half of it from
        each side.
    max_samples : int
        Left pixels compared at most (an even subsample of the cover): the cost per
        height stays small whatever the cover's size.

    Returns
    -------
    Sweep or None
        None when the cover is too small or outside the image, has no texture at all, or
        falls outside the right image at some height.
    """
    quad = np.asarray(quad_left, dtype=np.float64)
    if quad.shape != (4, 2):
        raise ValueError(f"quad_left: expected shape (4, 2), got {quad.shape}")
    # (a cover is swept again and again: texture_height sweeps it twice, each step's
    # checks once more)
    samples = _samples_of(quad.tobytes(), left.shape, inset, max_samples)
    if samples is None:
        return None
    return _sweep_pixels(left, right, Q_L, Q_R, *samples, desk_plane, heights)


def _sweep_pixels(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                  Q_R: ArrayLike, xs: NDArray[np.intp], ys: NDArray[np.intp],
                  desk_plane: ArrayLike, heights: ArrayLike) -> Sweep | None:
    """:func:`sweep_heights` over the left pixels (xs, ys), each shape (N,)."""
    h_img, w_img = left.shape
    # Each left pixel through each plane into the right image: a plane's homography to the
    # left pixels (H_L) and to the right (H_R) give right ← left = H_R · H_L⁻¹.
    heights = np.asarray(heights, dtype=np.float64)
    on_desk, n, e1, e2 = _plane_frame(desk_plane)
    B = np.zeros((len(heights), 4, 3))  # plane (u, v, 1) → world, one plane per height
    B[:, :3, 0], B[:, :3, 1], B[:, 3, 2] = e1, e2, 1.0
    B[:, :3, 2] = on_desk + heights[:, None] * n
    H_L = np.asarray(Q_L, dtype=np.float64) @ B
    H_R = np.asarray(Q_R, dtype=np.float64) @ B
    p = np.stack([xs, ys, np.ones(len(xs))]).astype(np.float64)  # (3, N)
    q = (H_R @ np.linalg.inv(H_L)) @ p  # (heights, 3, N)
    map_x = (q[:, 0] / q[:, 2]).astype(np.float32)
    map_y = (q[:, 1] / q[:, 2]).astype(np.float32)
    # only the pixels seen in the right image at every height (the border is no texture)
    seen = np.all((map_x >= 0) & (map_x <= w_img - 1) & (map_y >= 0) & (map_y <= h_img - 1), axis=0)
    n_seen = int(np.count_nonzero(seen))
    if n_seen < 0.9 * len(xs):
        return None
    if n_seen < len(xs):  # (mostly all are: then no copies)
        xs, ys, map_x, map_y = xs[seen], ys[seen], map_x[:, seen], map_y[:, seen]
    a = left[ys, xs].astype(np.float64)
    sa = a.std()
    if sa <= 0:
        return None
    a = (a - a.mean()) / (sa * a.size)
    b = cv2.remap(right, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT).astype(np.float64)
    centred = b - b.mean(axis=1, keepdims=True)
    # b.std(axis=1) as NumPy computes it (the same bits), from the centred values kept
    sb = np.sqrt(np.add.reduce(centred * centred, axis=1) / b.shape[1])
    ncc = np.where(sb > 0, centred @ a / np.maximum(sb, 1e-12), 0.0)
    return Sweep(heights, ncc)


@lru_cache(maxsize=64)
def _samples_of(quad: bytes, shape: tuple[int, int], inset: float, max_samples: int,
                ) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
    """The left pixels :func:`sweep_heights` compares for the quad whose (4, 2) float64
    corners are ``quad``, in an image of ``shape``: (xs, ys), read-only; None where the
    quad is too small or has fewer than 50 pixels inside its inset."""
    corners = np.frombuffer(quad, dtype=np.float64).reshape(4, 2)
    h_img, w_img = shape
    x0, y0 = np.maximum(np.floor(corners.min(axis=0)).astype(int), 0)
    x1, y1 = np.minimum(np.ceil(corners.max(axis=0)).astype(int) + 1, [w_img, h_img])
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(mask, np.rint(corners - [x0, y0]).astype(np.int32), 255)
    sides = np.linalg.norm(corners - corners[[1, 2, 3, 0]], axis=1)
    k = 2 * max(1, int(round(inset * sides.min() / 2))) + 1
    ys, xs = np.nonzero(cv2.erode(mask, np.ones((k, k), np.uint8)))
    if len(xs) < 50:
        return None
    keep = np.linspace(0, len(xs) - 1, min(len(xs), max_samples)).astype(np.intp)
    xs, ys = xs[keep] + x0, ys[keep] + y0
    for v in (xs, ys):  # shared by every caller
        v.setflags(write=False)
    return xs, ys


def find_by_print(tex_src: NDArray[np.float32], tex_dst: NDArray[np.float32], Q_src: ArrayLike,
                  Q_dst: ArrayLike, quad_src: ArrayLike, desk_plane: ArrayLike,
                  min_height: float, cfg: SweepConfig = SweepConfig()) -> NDArray[np.float64] | None:
    """A cover found in one image only, placed in the other by its print; None if its print
    does not tell.

    The cover's print, swept over the heights (:func:`texture_height`), must match nearly
    perfectly at one height at least ``min_height`` above the desk, clearly better than
    anywhere ``cfg.peak_apart`` away (a print repeating along the epipolar lines would
    match at several). And the quad must be the whole cover: where one side is a print's
    edge inside the cover (a title band, a printed block), the print goes on beyond it at
    the cover's height, while beyond a cover's own edge lies the desk, a page block or
    another book. So no strip just outside a side may match at the cover's height
    (NCC ≥ ``cfg.strip_min_ncc``) better than on the desk by ``cfg.min_gap``.

    Parameters
    ----------
    tex_src, tex_dst : ndarray, shape (H, W), float32
        High-passed ideal images (:func:`high_pass`): the one the cover was found in, the other.
    Q_src, Q_dst : array_like, shape (3, 4)
        Their world → ideal pixel projections.
    quad_src : array_like, shape (4, 2)
        The cover in the source image, ideal pixels.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, n·X + d = 0, n up, world.
    min_height : float
        Metres above the desk: a print on the desk (a sheet) is no cover.

    Returns
    -------
    ndarray, shape (4, 2) or None
        The cover's corners in the other image (same order), ideal pixels.
    """
    h = print_height(tex_src, tex_dst, Q_src, Q_dst, quad_src, desk_plane, cfg)
    if h is None or h < min_height or print_goes_on(tex_src, tex_dst, Q_src, Q_dst, quad_src,
                                                    desk_plane, h, cfg):
        return None
    return geometry.project(Q_dst, on_plane(Q_src, quad_src, desk_plane, h))


def print_goes_on(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                  Q_R: ArrayLike, quad_left: ArrayLike, desk_plane: ArrayLike, height: float,
                  cfg: SweepConfig = SweepConfig(), sides: Sequence[int] = range(4)) -> bool:
    """Whether the print of the cover ``quad_left`` at ``height`` (metres above the desk)
    goes on beyond one of its ``sides`` (side s from corner s to s + 1): the strip
    ``cfg.strip_px`` outside it matches at that height (NCC ≥ ``cfg.strip_min_ncc``)
    better than on the desk by ``cfg.min_gap``. Such a side is a print's edge inside the
    cover (a title band, a printed block), not the cover's. The strip beyond a cover's own
    side next to a taller book matches too (that book's page block rises through every
    lower height): ``sides`` leaves out the sides that may lie there. Arguments as
    :func:`sweep_heights`."""
    for side in sides:
        ncc = side_strip_ncc(left, right, Q_L, Q_R, quad_left, desk_plane, [height, 0.0], side,
                             near_px=cfg.strip_px[0], far_px=cfg.strip_px[1])
        if ncc is not None and ncc[0] >= cfg.strip_min_ncc and ncc[0] - ncc[1] > cfg.min_gap:
            return True
    return False


def print_height(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                 Q_R: ArrayLike, quad_left: ArrayLike, desk_plane: ArrayLike,
                 cfg: SweepConfig = SweepConfig()) -> float | None:
    """The height above the desk (metres) at which the print inside ``quad_left`` matches
    between the images, or None where it does not tell: the sweep's best NCC
    (:func:`texture_height`) must reach ``cfg.min_ncc_to_move`` and beat every height
    ``cfg.peak_apart`` or more away by ``cfg.min_gap`` (a print repeating along the
    epipolar lines would match at several). Arguments as :func:`sweep_heights`."""
    sweep, _ = texture_height(left, right, Q_L, Q_R, quad_left, desk_plane, float("nan"), cfg)
    if sweep is None or sweep.best_ncc < cfg.min_ncc_to_move:
        return None
    h = sweep.best_height
    apart = np.abs(sweep.heights - h) >= cfg.peak_apart
    if apart.any() and sweep.ncc[apart].max() > sweep.best_ncc - cfg.min_gap:
        return None
    return h


def side_strip_ncc(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                   Q_R: ArrayLike, quad_left: ArrayLike, desk_plane: ArrayLike,
                   heights: ArrayLike, side: int, *, near_px: float = 3.0, far_px: float = 10.0,
                   trim: float = 0.15) -> NDArray[np.float64] | None:
    """NCC per height of the strip just outside one side of a quad (:func:`sweep_heights`
    on the strip).

    Parameters
    ----------
    left, right : ndarray, shape (H, W), float32
        High-passed ideal images: the one the quad is in, and the other.
    Q_L, Q_R : array_like, shape (3, 4)
        Their world → ideal pixel projections.
    quad_left : array_like, shape (4, 2)
        The quad, pixels of ``left``.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, n·X + d = 0, n up, world.
    heights : array_like, shape (K,)
        Metres above the desk.
    side : int
        The side from corner ``side`` to the next.
    near_px, far_px : float
        The strip lies this far beyond the side, pixels (the sampling erodes it by about a
        pixel more).
    trim : float
        Fraction of the side's length left out at each end (the corners).

    Returns
    -------
    ndarray, shape (K,), or None
        None where the strip gives no sweep (too small, no texture, out of view).
    """
    quad = np.asarray(quad_left, dtype=np.float64)
    a, b = quad[side], quad[(side + 1) % 4]
    d = b - a
    n = np.array([d[1], -d[0]]) / max(float(np.linalg.norm(d)), 1e-9)
    if n @ (0.5 * (a + b) - quad.mean(axis=0)) < 0:
        n = -n
    a, b = a + trim * d, b - trim * d
    strip = np.array([a + near_px * n, b + near_px * n, b + far_px * n, a + far_px * n])
    sweep = sweep_heights(left, right, Q_L, Q_R, strip, desk_plane, heights, inset=0.0)
    return None if sweep is None else sweep.ncc


def on_plane(Q: ArrayLike, px: ArrayLike, desk_plane: ArrayLike, height: float) -> NDArray[np.float64]:
    """Pixels back-projected onto the plane parallel to the desk at ``height`` above it.

    Parameters
    ----------
    Q : array_like, shape (3, 4)
        World → ideal pixel projection of the camera that saw ``px``.
    px : array_like, shape (N, 2)
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, n·X + d = 0, n up, world.
    height : float
        Metres above the desk.

    Returns
    -------
    ndarray, shape (N, 3) — world points, metres.
    """
    on_desk, n, e1, e2 = _plane_frame(desk_plane)
    origin = on_desk + height * n
    uv1 = np.linalg.solve(plane_homography(Q, origin, e1, e2),
                          np.column_stack([np.asarray(px, dtype=np.float64), np.ones(len(px))]).T)
    uv = (uv1[:2] / uv1[2]).T
    return origin + uv[:, :1] * e1 + uv[:, 1:] * e2


def _plane_frame(desk_plane: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """The desk's point nearest the origin, its unit normal (up) and two unit directions in it
    (read-only arrays)."""
    plane = np.asarray(desk_plane, dtype=np.float64)
    # asked thousands of times a frame of one plane: kept by its value (a copy's bytes)
    return _plane_frame_of(plane.shape, plane.tobytes())


@lru_cache(maxsize=8)
def _plane_frame_of(shape: tuple[int, ...], data: bytes) -> tuple[NDArray[np.float64], ...]:
    """:func:`_plane_frame` of the plane whose float64 values are ``data``."""
    plane = np.frombuffer(data, dtype=np.float64).reshape(shape)
    n = plane[:3] / np.linalg.norm(plane[:3])
    on_desk = -plane[3] * plane[:3] / (plane[:3] @ plane[:3])
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    frame = (on_desk, n, e1, np.cross(n, e1))
    for v in frame:  # shared by every caller
        v.setflags(write=False)
    return frame


def texture_height(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
                   Q_R: ArrayLike, quad_left: ArrayLike, desk_plane: ArrayLike,
                   corner_height: float, cfg: SweepConfig = SweepConfig()) -> tuple[Sweep | None, float]:
    """Sweep coarsely over the whole height range, then finely near the best and at the
    corners' height; the sweep (None: no texture to test) and the NCC at ``corner_height``.

    Parameters
    ----------
    corner_height : float
        The cover's height above the desk from its triangulated corners, metres. Outside
        the swept range the NCC there is NaN: no evidence either way.
    """
    coarse = np.arange(cfg.min_height, cfg.max_height + 1e-9, cfg.coarse_step)
    first = sweep_heights(left, right, Q_L, Q_R, quad_left, desk_plane, coarse, inset=cfg.inset,
                          max_samples=cfg.max_samples)
    if first is None:
        return None, 0.0
    best = first.best_height
    fine = np.arange(best - cfg.coarse_step, best + cfg.coarse_step + 1e-9, cfg.step)
    fine = fine[(fine >= cfg.min_height) & (fine <= cfg.max_height)]
    inside = cfg.min_height <= corner_height <= cfg.max_height
    at = corner_height if inside else cfg.min_height
    extra = sweep_heights(left, right, Q_L, Q_R, quad_left, desk_plane, np.append(fine, at),
                          inset=cfg.inset, max_samples=cfg.max_samples)
    if extra is None:  # (the fine heights lie within the coarse ones: not expected)
        return first, float("nan")
    heights = np.concatenate([first.heights, extra.heights[:-1]])
    ncc = np.concatenate([first.ncc, extra.ncc[:-1]])
    order = np.argsort(heights, kind="stable")
    return Sweep(heights[order], ncc[order]), float(extra.ncc[-1]) if inside else float("nan")


def contradicts(sweep: Sweep | None, ncc_at_corners: float, cfg: SweepConfig = SweepConfig()) -> bool:
    """True when the cover's texture clearly puts it at another height than its corners."""
    return (sweep is not None and sweep.best_ncc >= cfg.min_ncc
            and sweep.best_ncc - ncc_at_corners > cfg.min_gap)  # False for NaN


def contradicts_beyond_quarter(left: NDArray[np.float32], right: NDArray[np.float32],
                               Q_L: ArrayLike, Q_R: ArrayLike, quad_left: ArrayLike,
                               desk_plane: ArrayLike, best_height: float, corner_height: float,
                               cfg: SweepConfig = SweepConfig(), *, half_share: float = 0.9,
                               half_each: float = 0.25) -> bool:
    """Whether the cover's texture, less its most textured quarter (or half), still puts
    it at ``best_height`` rather than at ``corner_height`` (metres above the desk).

    A plain cover has no texture of its own, and where a taller neighbour hides one of its
    corners, that neighbour's edge or print inside the quad is all the texture there is:
    it matches at the neighbour's height, and would move the cover there (build/t1d scene
    7 book 2, a plain cover 13 mm high under a corner of a 48 mm book: moved to 45 mm). A
    cover's own print tells its height over more of it than one quarter. The quad is cut
    into quarters by the lines joining its opposite sides' midpoints; the pixels
    :func:`sweep_heights` compares, less the quarter where their high-passed values vary
    most, must still match at ``best_height`` (metres above the desk) well enough
    (``cfg.min_ncc``) and better than at ``corner_height``: the rest of a plain cover
    matches at neither, and the rest of one whose corners are right matches better there.
    Other arguments as :func:`sweep_heights`.

    A neighbour along a side reaches into two neighbouring quarters: where those hold
    over ``half_share`` of the texture together and over ``half_each`` each, their half is
    left out instead (build/t1d scene 72 book 2, a dark cover 8 mm high beside a 25 mm
    printed book: 47 % and 51 % of its texture in the quarters along that book, moved to
    26 mm).

    Returns
    -------
    bool
        False also where the rest gives no sweep (under 50 pixels, none of its texture, or
        some of it outside the right image): the cover stays.
    """
    quad = np.asarray(quad_left, dtype=np.float64)
    samples = _samples_of(quad.tobytes(), left.shape, cfg.inset, cfg.max_samples)
    if samples is None:
        return False
    xs, ys = samples
    # each pixel's coordinates along the lines joining opposite sides' midpoints (through
    # the corners' mean): from side 3 towards side 1, and from side 0 towards side 2
    across = 0.5 * ((quad[1] + quad[2]) - (quad[0] + quad[3]))
    along = 0.5 * ((quad[2] + quad[3]) - (quad[0] + quad[1]))
    p = np.stack([xs, ys]) - quad.mean(axis=0)[:, None]  # (2, N)
    s, t = np.linalg.solve(np.column_stack([across, along]), p)
    quarter = 2 * (s > 0) + (t > 0)  # (N,) in 0..3
    a = left[ys, xs].astype(np.float64)
    energy = np.bincount(quarter, weights=(a - a.mean()) ** 2, minlength=4)
    out = [int(np.argmax(energy))]
    for half in ([0, 1], [2, 3], [0, 2], [1, 3]):  # two neighbouring quarters (one at most)
        if (energy[half].sum() > half_share * energy.sum()
                and energy[half].min() > half_each * energy.sum()):
            out = half
    rest = ~np.isin(quarter, out)
    if np.count_nonzero(rest) < 50:  # (as _samples_of asks of a whole cover)
        return False
    sweep = _sweep_pixels(left, right, Q_L, Q_R, xs[rest], ys[rest], desk_plane,
                          [best_height, corner_height])
    if sweep is None:
        return False
    return bool(sweep.ncc[0] >= cfg.min_ncc and sweep.ncc[0] > sweep.ncc[1])


__all__ = ["SweepConfig", "Sweep", "find_by_print", "high_pass", "on_plane", "plane_homography",
           "print_goes_on", "print_height", "side_strip_ncc", "sweep_heights",
           "texture_height", "contradicts",
           "contradicts_beyond_quarter"]
