"""Covers from a height map over the desk: a dense plane sweep (beyond the paper).

The boundary chain finds a cover only where its four sides are Canny edges and Hough
lines; a photo cover breaks its own sides into texture, a desk-coloured cover shows one
side faintly, and the quads never form. Stereo sees those books anyway: a book stands out of
the desk. Through the plane parallel to the desk at height h, the right image maps into the
left by that plane's homography, and wherever the scene lies on that plane the two agree.
Swept over the heights books have, the best-agreeing height per pixel (windowed NCC of the
high-passed images, as :mod:`rovis.sweep` does per cover) is a height map of the workspace:
a printed or photo cover shows as a filled patch at its height, a plain one as its outline
(its edges are its only texture), papers and the desk's grain at zero.

Edges along the epipolar lines match at every height, so pixels whose texture runs mostly
along them testify to nothing (plank seams, a cover's side parallel to the baseline).

:func:`raised_covers` cuts the map into slabs of one height and fits each connected patch
with the smallest rectangle in the desk plane (:func:`cv2.minAreaRect` on its pixels laid
on that plane): a cover candidate in world coordinates, which the pipeline projects into
both images, refines to their edges and puts through the pose checks like any other.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rovis import geometry
from rovis.segment.edges import Gradients
from rovis.segment.quads import quad_overlap
from rovis.sweep import _plane_frame, high_pass, plane_homography


@dataclass(frozen=True)
class HeightMapConfig:
    """The height map and the covers cut from it (metres unless noted).

    ``enabled`` turns the step on (it needs the desk plane). Heights from ``min_height`` to
    ``max_height`` above the desk every ``step`` are swept; ``window_px``: the NCC window
    (odd, pixels); a pixel counts when its best NCC reaches ``min_ncc`` and its texture
    across the epipolar lines (mean squared derivative along them, grey levels² of the
    high-passed image) reaches ``min_texture``; ``raised``: a pixel at least this high is
    above the desk; a slab is each swept height ± ``slab``; a patch needs ``min_pixels``
    pixels; ``min_fill``: the share of its rectangle's outline (4 mm cells along it) with
    patch pixels from 4 mm outside to 8 mm inside it must reach this (a cover's outline or
    more).

    The pipeline's use of the rectangles (:meth:`rovis.pipeline.Detector._from_height_map`):
    ``snap_reach``, ``snap_inward``: how far each side may move onto an edge
    (:func:`snap_sides`); ``min_side``: a cover narrower than this is not taken (a printed
    band across a cover, more often than a whole one).

    ``smooth*``: the half-resolution sweep for covers without fine print
    (:func:`smooth_height_map`). ``dense*``: the semi-global disparity map
    (:func:`dense_height_map`), last, for what no other step found: ``dense_block_px``, the
    matching block (odd, pixels); slabs from ``dense_raised`` up, each ± ``dense_slab``, its
    patches eroded by ``dense_erode_px``; a rectangle is taken where one of the two sweeps
    reads heights over ``dense_min_read`` of its inner part or more and neither reads the
    desk over more than ``dense_max_desk`` of its readings (:func:`sweeps_confirm`); its
    sides move outward onto an edge over no strip where the sweeps read, on at least
    ``dense_snap_read`` of the strip's samples, a height below the cover's by more than
    ``dense_snap_tol`` and half its height (:func:`snap_sides`: a lower neighbour the
    disparity map ran on over).

    ``taken_px``: late, the sweeps are cut again without the found covers' pixels and those
    within this many of the map's pixels around them (on the half-resolution smooth map,
    two image pixels each), for a book whose patch ran on over a found one of about its
    height (negative: not cut again); a cover so found is not taken where it lies over a
    found one by more than ``taken_overlap`` of the smaller quad in either image.
    ``wide_slab``: then (where ``taken_px`` >= 0 and ``smooth`` is on) the smooth map is
    cut once more so, without the pixels of the covers found before, in slabs this wide
    (± metres; 0: not), each wholly above ``raised``, for a cover whose heights the map
    reads spread wider than ``slab``, so that each thin slab holds a broken patch of it.
    A cover so found is taken only where its print answers the fine sweep within ``step``
    of its slab's height (:func:`rovis.sweep.sweep_heights`) with an NCC of
    ``wide_min_ncc`` or more (-1: any print): one whose print does not (a cover of the
    desk's tone, its mottle read ± 7 mm) is laid at the slab's height and its faint sides'
    edges, centimetres off. Nor is one taken over a book the thin slabs' cut again found
    (by more than ``StereoConfig.transfer_max_overlap`` of the smaller quad).
    """

    enabled: bool = True
    min_height: float = 0.0
    max_height: float = 0.075
    step: float = 0.003
    window_px: int = 9
    min_ncc: float = 0.6
    min_texture: float = 4.0
    raised: float = 0.006
    slab: float = 0.0045
    min_pixels: int = 150
    min_fill: float = 0.4
    snap_reach: float = 0.03  # a patch falls 1-4 cm short of, or beyond, a plain cover's edge
    snap_inward: float = 0.02
    min_side: float = 0.085
    smooth: bool = True
    smooth_sigma_px: float = 6.0
    smooth_window_px: int = 11
    smooth_min_texture: float = 0.3
    smooth_erode_px: int = 2
    dense: bool = True
    dense_block_px: int = 5
    dense_raised: float = 0.010
    dense_slab: float = 0.006
    dense_erode_px: int = 2
    dense_max_desk: float = 0.2
    dense_min_read: float = 0.1
    dense_snap_tol: float = 0.006
    dense_snap_read: float = 0.5
    taken_px: int = 4
    taken_overlap: float = 0.15
    wide_slab: float = 0.010
    wide_min_ncc: float = 0.85

    def __post_init__(self) -> None:
        if not (0 < self.step and self.max_height > self.min_height + self.step
                and self.window_px >= 3 and self.window_px % 2 == 1 and self.slab > 0
                and self.smooth_window_px >= 3 and self.smooth_window_px % 2 == 1
                and self.smooth_sigma_px > 0 and self.smooth_erode_px >= 0
                and self.dense_block_px >= 3 and self.dense_block_px % 2 == 1
                and self.dense_slab > 0 and self.dense_erode_px >= 0
                and 0.0 <= self.dense_max_desk <= 1.0 and 0.0 <= self.dense_min_read <= 1.0
                and self.dense_snap_tol > 0 and 0.0 < self.dense_snap_read <= 1.0
                and 0.0 <= self.taken_overlap <= 1.0 and isinstance(self.taken_px, int)
                and self.wide_slab >= 0 and -1.0 <= self.wide_min_ncc <= 1.0):
            raise ValueError("heightmap: step and slab must be positive, max_height above "
                             "min_height by more than a step, window_px and "
                             "smooth_window_px odd and >= 3, smooth_sigma_px positive, "
                             "smooth_erode_px >= 0, dense_block_px odd and >= 3, "
                             "dense_slab positive, dense_erode_px >= 0, dense_max_desk, "
                             "dense_min_read and taken_overlap in [0, 1], dense_snap_tol "
                             "positive, dense_snap_read in (0, 1], taken_px an int, "
                             f"wide_slab >= 0, wide_min_ncc in [-1, 1], got {self}")


@dataclass(frozen=True, eq=False)
class HeightMap:
    """Height above the desk per left image pixel (ideal, or rectified for
    :func:`dense_height_map`), where the two images agree.

    Attributes
    ----------
    height : ndarray, shape (H, W), float32
        Metres above the desk; NaN where no height was found (outside the box, no texture
        across the epipolar lines, no agreement).
    heights : ndarray, shape (K,)
        The swept heights, metres.
    box : (x0, y0, x1, y1)
        The pixels swept (outside it ``height`` is NaN).
    """

    height: NDArray[np.float32]
    heights: NDArray[np.float64]
    box: tuple[int, int, int, int]


def height_map(left: NDArray[np.float32], right: NDArray[np.float32], Q_L: ArrayLike,
               Q_R: ArrayLike, desk_plane: ArrayLike, *,
               box: tuple[int, int, int, int] | None = None,
               cfg: HeightMapConfig = HeightMapConfig()) -> HeightMap:
    """The plane sweep: each left pixel's best-agreeing height above the desk.

    Parameters
    ----------
    left, right : ndarray, shape (H, W), float32
        Both ideal images, high-passed (:func:`rovis.sweep.high_pass`).
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, world, normal up.
    box : (x0, y0, x1, y1), optional
        Left pixels to compute (the ROI's bounding box); the whole image by default.

    Returns
    -------
    HeightMap
    """
    h_img, w_img = left.shape
    x0, y0, x1, y1 = box if box is not None else (0, 0, w_img, h_img)
    heights = np.arange(cfg.min_height, cfg.max_height + 1e-9, cfg.step)
    height = np.full((h_img, w_img), np.nan, np.float32)
    if x1 <= x0 or y1 <= y0:  # an empty ROI: no height anywhere
        return HeightMap(height, heights, (x0, y0, x1, y1))
    crop = left[y0:y1, x0:x1]
    on_desk, n, e1, e2 = _plane_frame(desk_plane)
    win = (cfg.window_px, cfg.window_px)

    def mean(img: NDArray[np.float32],
             out: NDArray[np.float32] | None = None) -> NDArray[np.float32]:
        return cv2.boxFilter(img, -1, win, dst=out, borderType=cv2.BORDER_REFLECT)

    shift = np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]])  # crop → image
    m_l = mean(crop)
    v_l = mean(crop * crop) - m_l * m_l
    best = np.full(crop.shape, -np.inf, np.float32)
    # the index of the best height so far (the first of equals), and buffers for it
    arg = np.zeros(crop.shape, np.uint8 if len(heights) <= 256 else np.int32)
    beats = np.empty(crop.shape, np.bool_)
    index = np.empty_like(arg)

    def crop_to_right(h: float) -> NDArray[np.float64]:
        origin = on_desk + h * n
        return (plane_homography(Q_R, origin, e1, e2)
                @ np.linalg.inv(plane_homography(Q_L, origin, e1, e2)) @ shift)

    # the same arithmetic as ncc = (mean(l·r) − m_l·m_r) / sqrt(max(v_l·v_r, 1e-6)), in
    # place: a fresh array per step and height was half the sweep's time
    tmp, warped, m_r, v_r, num = (np.empty_like(crop) for _ in range(5))
    least = np.full(crop.shape, 1e-6, np.float32)  # (np.maximum is 3x slower with a scalar)
    for k, h in enumerate(heights):
        H = crop_to_right(float(h))
        cv2.warpPerspective(right, H, crop.shape[::-1], dst=warped,
                            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
        mean(warped, m_r)
        mean(np.multiply(warped, warped, out=tmp), v_r)
        v_r -= np.multiply(m_r, m_r, out=tmp)
        mean(np.multiply(crop, warped, out=tmp), num)
        num -= np.multiply(m_l, m_r, out=tmp)
        np.multiply(v_l, v_r, out=tmp)
        np.maximum(tmp, least, out=tmp)
        np.sqrt(tmp, out=tmp)
        ncc = np.divide(num, tmp, out=num)
        # arg = k where ncc beats best: k is above every index so far, so that is the
        # larger of arg and k·beats (a masked copy costs ten times as much)
        np.greater(ncc, best, out=beats)
        np.maximum(arg, np.multiply(beats.view(np.uint8), arg.dtype.type(k), out=index),
                   out=arg)
        np.fmax(best, ncc, out=best)  # a NaN (none expected) leaves best as it was
    # the epipolar direction at the box's centre: where the heights move a pixel
    centre = np.array([0.5 * (x1 - x0), 0.5 * (y1 - y0), 1.0])
    p0, p1 = crop_to_right(float(heights[0])) @ centre, crop_to_right(float(heights[-1])) @ centre
    d = p1[:2] / p1[2] - p0[:2] / p0[2]
    d = d / max(float(np.linalg.norm(d)), 1e-12)
    gx = cv2.Sobel(crop, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(crop, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    along = mean((gx * np.float32(d[0]) + gy * np.float32(d[1])) ** 2)
    ok = (best >= cfg.min_ncc) & (along >= cfg.min_texture)
    height[y0:y1, x0:x1] = np.where(ok, heights[arg].astype(np.float32), np.nan)
    return HeightMap(height, heights, (x0, y0, x1, y1))


def smooth_height_map(left: NDArray[np.uint8], right: NDArray[np.uint8], Q_L: ArrayLike,
                      Q_R: ArrayLike, desk_plane: ArrayLike, *,
                      box: tuple[int, int, int, int] | None = None,
                      cfg: HeightMapConfig = HeightMapConfig(),
                      ) -> tuple[HeightMap, NDArray[np.float64], HeightMapConfig]:
    """The plane sweep for covers without fine print, at half resolution.

    :func:`height_map` compares the print finer than a pixel or two; a cover of the desk's
    colour, or a plain one with a mottled finish, has none, and its only edges are faint.
    Its mottle (blobs of tens of pixels) still matches between the images at the cover's
    height: this sweep compares the images band-passed at ``cfg.smooth_sigma_px``, in
    ``cfg.smooth_window_px`` windows, on images halved (the band holds nothing finer, and
    the sweep costs a quarter).

    Parameters
    ----------
    left, right : ndarray, shape (H, W), uint8
        Both ideal images.
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections.
    desk_plane : array_like, shape (4,)
    box : (x0, y0, x1, y1), optional
        Left pixels to compute, full resolution.

    Returns
    -------
    (HeightMap, Q_L_half, cfg_half)
        The map over the halved left image, that image's projection (for
        :func:`raised_covers`) and the settings to cut covers from it with.
    """
    # cv2.pyrDown blurs about every even pixel and keeps it: u' = u / 2 (until git 20496f3
    # this read u' = (u - ½) / 2, half a full pixel off)
    S = np.diag([0.5, 0.5, 1.0])
    Q_L2, Q_R2 = S @ np.asarray(Q_L, np.float64), S @ np.asarray(Q_R, np.float64)
    band = [high_pass(cv2.pyrDown(img), cfg.smooth_sigma_px) for img in (left, right)]
    h, w = band[0].shape
    if box is not None:
        x0, y0, x1, y1 = box
        box = (x0 // 2, y0 // 2, min(-(-x1 // 2), w), min(-(-y1 // 2), h))
    half = replace(cfg, window_px=cfg.smooth_window_px, min_texture=cfg.smooth_min_texture,
                   min_pixels=max(cfg.min_pixels // 4, 1))
    return height_map(band[0], band[1], Q_L2, Q_R2, desk_plane, box=box, cfg=half), Q_L2, half


@dataclass(frozen=True, eq=False)
class Rectification:
    """Both ideal images turned into one row-aligned pair (:func:`cv2.stereoRectify`), for
    semi-global matching (:func:`dense_height_map`).

    It depends on the two cameras only, not on the world frame: made once per rig
    (:meth:`of`).

    Attributes
    ----------
    maps : dict
        Per camera, the :func:`cv2.remap` maps from its ideal image, fixed point: shape
        (H, W, 2) int16 and (H, W) uint16.
    K : ndarray, shape (3, 3)
        Both rectified cameras' matrix, pixels (zero disparity at infinity).
    R_rect_left : ndarray, shape (3, 3)
        Rotation from the left camera's frame to the rectified left camera's.
    K_ideal : ndarray, shape (3, 3)
        The left ideal image's camera matrix (where the ROI mask is drawn).
    baseline : float
        Metres; 0 where the right camera is not to the left camera's right along the
        rows (a vertical or swapped rig: no dense map).
    """

    maps: dict[str, tuple[NDArray[np.generic], NDArray[np.generic]]]
    K: NDArray[np.float64]
    R_rect_left: NDArray[np.float64]
    K_ideal: NDArray[np.float64]
    baseline: float

    @classmethod
    def of(cls, K1: ArrayLike, K2: ArrayLike, R: ArrayLike, T: ArrayLike,
           size: tuple[int, int]) -> Rectification:
        """The rectification of two ideal (undistorted) cameras ``K1``, ``K2`` (3, 3) with
        ``X_right = R @ X_left + T`` (metres), images ``size`` = (width, height)."""
        K1, K2 = np.asarray(K1, np.float64), np.asarray(K2, np.float64)
        none = np.zeros((1, 5))  # ideal images: no distortion left
        R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(
            K1, none, K2, none, size, np.asarray(R, np.float64),
            np.asarray(T, np.float64).reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
        maps = {cam: cv2.initUndistortRectifyMap(K, none, Rc, P, size, cv2.CV_16SC2)
                for cam, K, Rc, P in (("left", K1, R1, P1), ("right", K2, R2, P2))}
        # P2[0, 3] = -f * baseline for a right camera along +x; a vertical rig's shift is
        # in P2[1, 3] instead, and its rows are no epipolar lines for SGBM
        along_rows = P2[0, 3] < 0 and abs(P2[1, 3]) < 1e-9 * abs(P2[0, 3])
        return cls(maps=maps, K=P1[:, :3].copy(), R_rect_left=R1, K_ideal=K1,
                   baseline=float(-P2[0, 3] / P2[0, 0]) if along_rows else 0.0)

    def projection(self, T_left_world: ArrayLike) -> NDArray[np.float64]:
        """World → rectified left pixel projection (3, 4), for the left camera's pose
        ``T_left_world`` (4, 4, world → left camera)."""
        return self.K @ self.R_rect_left @ np.asarray(T_left_world, np.float64)[:3]


MAX_DISPARITY = 512  # pixels: a desk so near is not a workspace (0.19 m for the synthetic rig)


def dense_height_map(left: NDArray[np.uint8], right: NDArray[np.uint8], rect: Rectification,
                     T_left_world: ArrayLike, desk_plane: ArrayLike, *,
                     mask: NDArray[np.uint8] | None = None,
                     cfg: HeightMapConfig = HeightMapConfig(),
                     ) -> tuple[HeightMap, NDArray[np.float64], HeightMapConfig]:
    """Heights above the desk from a semi-global disparity map (:class:`cv2.StereoSGBM`).

    The plane sweeps compare windows on their own; a cover of the desk's colour or a plain
    one has too little texture for a window to tell its height, and the smooth sweep's
    wide windows mix it with the desk around it. Semi-global matching carries the match
    from a cover's faint mottle and edges across it (a penalty on changes of disparity
    between neighbours), so the cover comes out as one raised region. Its heights are
    noisier than the sweeps' (a few millimetres), so the pipeline only cuts covers from
    it, last, where nothing else found a book (:meth:`rovis.pipeline.Detector._from_dense_map`).

    Parameters
    ----------
    left, right : ndarray, shape (H, W), uint8
        Both ideal images.
    rect : Rectification
        Of the rig whose ideal images these are.
    T_left_world : array_like, shape (4, 4)
        World → left camera.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, world, normal up.
    mask : ndarray, shape (H, W), uint8, optional
        The ROI in the left ideal image (non-zero inside); the whole image by default.

    Returns
    -------
    (HeightMap, Q_rect, cfg_dense)
        The map over the rectified left image (its ``height`` and ``box`` in rectified
        pixels; NaN where SGBM found no disparity, outside the ROI, and everywhere for an
        empty ROI, a rig not along the rows or a desk too near), that image's world →
        pixel projection (for :func:`raised_covers`) and the settings to cut covers from
        it with.

    Raises
    ------
    ValueError
        Images (or a mask) not uint8 of the rectification's size.
    """
    shape = rect.maps["left"][0].shape[:2]
    if left.shape != shape or right.shape != shape or left.dtype != np.uint8 \
            or right.dtype != np.uint8 or (mask is not None and mask.shape != shape):
        raise ValueError(f"dense_height_map: expected uint8 images (and a mask) of the "
                         f"rectification's shape {shape}, got {left.dtype} {left.shape}, "
                         f"{right.dtype} {right.shape}"
                         + ("" if mask is None else f", mask {mask.shape}"))
    size = (left.shape[1], left.shape[0])
    heights = np.arange(cfg.min_height, cfg.max_height + 1e-9, cfg.step)
    dense = replace(cfg, raised=cfg.dense_raised, slab=cfg.dense_slab)
    height = np.full(left.shape, np.nan, np.float32)
    Q_rect = rect.projection(T_left_world)
    # the ROI in the rectified frame: the left camera only turned, so a homography
    if mask is None:
        roi = np.full(left.shape, 255, np.uint8)
    else:
        H = rect.K @ rect.R_rect_left @ np.linalg.inv(rect.K_ideal)
        roi = cv2.warpPerspective(mask, H, size, flags=cv2.INTER_NEAREST)
    x, y, w, h = cv2.boundingRect(roi)
    box = (x, y, x + w, y + h)
    if w == 0 or h == 0 or rect.baseline <= 0:
        return HeightMap(height, heights, box), Q_rect, dense
    # the desk plane in the rectified left camera: n·X + d = height above it
    T_rect_world = geometry.make_transform(rect.R_rect_left, np.zeros(3)) @ np.asarray(
        T_left_world, np.float64)
    plane = np.asarray(desk_plane, np.float64) / np.linalg.norm(desk_plane[:3])
    n = T_rect_world[:3, :3] @ plane[:3]
    d = plane[3] - n @ T_rect_world[:3, 3]
    f, cx, cy = rect.K[0, 0], rect.K[0, 2], rect.K[1, 2]

    def slope(u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        # n · ray for the ray (u - cx, v - cy, f) / f through each pixel
        return (n[0] * (u - cx) + n[1] * (v - cy)) / f + n[2]

    # the disparities the ROI's corners have from max_height below the desk to twice it
    # above (a plane's disparity is affine in the pixel: its extremes are at the corners).
    # Beyond the heights books have: a pixel SGBM cannot match lands anywhere in the
    # range, and a wide range puts most of those outside every slab.
    u = np.array([x, x + w, x, x + w], np.float64)
    v = np.array([y, y, y + h, y + h], np.float64)
    disparity = [f * rect.baseline * slope(u, v) / (level - d)
                 for level in (-cfg.max_height, 2 * cfg.max_height)]
    disparity = np.concatenate(disparity)
    disparity = disparity[np.isfinite(disparity) & (disparity > 0)]
    if len(disparity) == 0:  # the desk is not in front of the camera here
        return HeightMap(height, heights, box), Q_rect, dense
    lo = max(int(np.floor(disparity.min())) - 2, 0)
    count = int(np.ceil((disparity.max() + 2 - lo) / 16.0)) * 16
    # both images cut to the ROI's rows and the columns its matches can reach
    c0 = max(x - lo - count, 0)
    if lo + count > MAX_DISPARITY or x + w - c0 <= lo + count:
        # a desk a few centimetres from the camera, or an ROI at the image's left border
        # narrower than the range: no match to make (and SGBM fails on such a crop)
        return HeightMap(height, heights, box), Q_rect, dense
    crop_left, crop_right = (
        cv2.remap(img, *(m[y:y + h, c0:x + w] for m in rect.maps[cam]), cv2.INTER_LINEAR)
        for cam, img in (("left", left), ("right", right)))
    block = cfg.dense_block_px
    # OpenCV's own suggested smoothness penalties for one channel
    sgbm = cv2.StereoSGBM_create(minDisparity=lo, numDisparities=count, blockSize=block,
                                 P1=8 * block * block, P2=32 * block * block,
                                 uniquenessRatio=5, speckleWindowSize=100, speckleRange=2,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    # fixed point, 4 fractional bits; no match is (lo - 1) · 16
    disp = sgbm.compute(crop_left, crop_right).astype(np.float32) / 16.0
    disp = disp[:, x - c0:]
    ok = (disp > lo) & (roi[y:y + h, x:x + w] > 0)
    ray = slope(np.arange(x, x + w, dtype=np.float64)[None, :],
                np.arange(y, y + h, dtype=np.float64)[:, None])  # (h, w)
    # On weak texture (a plain desk, a desk-toned cover) the 3-way mode's disparities come
    # out a few tenths of a pixel low (measured: tests' desk 4 mm low, its cover with it).
    # The desk, known from the marker and most of the workspace, gives the offset: the
    # median residual of the pixels within a pixel of its disparity.
    residual = disp - f * rect.baseline * ray / (-d)
    on_desk = ok & (np.abs(residual) < 1.0)
    if np.count_nonzero(on_desk) > 1000:
        disp = disp - np.float32(np.median(residual[on_desk]))
    ok &= disp > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        above = ray * (f * rect.baseline / disp) + d
    height[y:y + h, x:x + w] = np.where(ok, above, np.nan).astype(np.float32)
    return HeightMap(height, heights, box), Q_rect, dense


def sweeps_confirm(P: ArrayLike, maps: list[tuple[HeightMap, NDArray[np.float64]]], *,
                   max_desk: float, min_read: float, level: float = 0.004,
                   inner: float = 0.8, min_readings: int = 20) -> bool:
    """Whether the plane sweeps back a rectangle the disparity map raised.

    Semi-global matching carries a book's disparity on into the desk beside it where the
    desk shows little texture (a shadow, a dim scene) and fills a pocket of desk between
    books with their heights. The plane sweeps compare each window on their own: there
    they read nothing, or the desk. Each map ``(HeightMap, Q)`` is read over the inner part
    (``inner`` of the size, about the centre) of the rectangle ``P`` (4, 3) projected by
    ``Q``. The rectangle is backed where some map reads heights over at least ``min_read``
    of that part and no map with ``min_readings`` or more reads the desk (within ``level``
    metres of it) over more than ``max_desk`` of its readings.

    Parameters
    ----------
    P : array_like, shape (4, 3)
        World corners of the rectangle, metres.
    maps : list of (HeightMap, ndarray (3, 4))
        Each sweep's map and the world → pixel projection of its image.
    max_desk, min_read : float
        Shares, 0-1.

    Returns
    -------
    bool
        True where the sweeps back the rectangle.
    """
    P = np.asarray(P, np.float64)
    read_enough = False
    for hm, Q in maps:
        q = geometry.project(Q, P)
        q = q.mean(axis=0) + inner * (q - q.mean(axis=0))
        inside = np.zeros(hm.height.shape, np.uint8)
        cv2.fillConvexPoly(inside, np.round(q).astype(np.int32), 1)
        part = hm.height[inside > 0]
        read = part[np.isfinite(part)]
        if len(part) and len(read) >= min_read * len(part):
            read_enough = True
        if len(read) >= min_readings and np.mean(np.abs(read) < level) > max_desk:
            return False
    return read_enough


def read_heights(hm: HeightMap, Q: NDArray[np.float64],
                 pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """The map's height (N,) at world points ``pts`` (N, 3) seen through ``Q`` (3, 4), at
    the nearest pixel; NaN outside the map or where it has none."""
    uv = np.round(geometry.project(Q, pts)).astype(int)
    h, w = hm.height.shape
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    z = np.full(len(uv), np.nan)
    z[inside] = hm.height[uv[inside, 1], uv[inside, 0]]
    return z


def row_medians(rows: NDArray[np.float64], count: NDArray[np.intp]) -> NDArray[np.float64]:
    """Each row's median over its values that are not NaN, ``count`` of them (K,) in rows
    (K, M): as np.median of those values (np.sort puts NaN last; np.nanmedian is several
    times slower on short rows)."""
    ordered = np.sort(rows, axis=1)
    r = np.arange(len(rows))
    return 0.5 * (ordered[r, (count - 1) // 2] + ordered[r, count // 2])


def raised_covers(hm: HeightMap, Q_L: ArrayLike, desk_plane: ArrayLike, *,
                  side_range: tuple[float, float] = (0.05, 0.45),
                  cfg: HeightMapConfig = HeightMapConfig(), erode_px: int = 0,
                  exclude: NDArray[np.bool_] | None = None,
                  above: float | None = None,
                  ) -> list[tuple[NDArray[np.float64], float, float]]:
    """Cover candidates: rectangles fitted to patches of one height above the desk.

    Each swept height from ``cfg.raised`` up (but the top one) is a slab (± ``cfg.slab``);
    the slab's pixels are joined into patches (8-connected, after closing gaps of up to
    4 px) and each patch of at least ``cfg.min_pixels`` is laid on the plane at that height
    and fitted with its smallest rectangle. Rectangles with sides in ``side_range`` whose
    outline the patch fills (``cfg.min_fill``) are kept, the most pixels first; one
    overlapping a kept one by more than half (in the image) is the same cover seen in a
    neighbouring slab.
    ``erode_px`` > 0 shrinks each slab's joined patches by that many pixels first (a wide
    NCC window's patch reaches past the cover's edge by about half the window).
    ``exclude``, if given (bool, the map's shape), marks pixels left out of every slab.
    ``above``, if given: a slab reaching below this height (h − ``cfg.slab``, metres) is
    not cut (a wide slab's patch there takes in the desk).

    Returns
    -------
    list of (corners, height, fill)
        World corners (4, 3) of each rectangle at its height (metres) and the share of its
        outline the patch fills, most pixels first.
    """
    Q_L = np.asarray(Q_L, dtype=np.float64)
    on_desk, n, e1, e2 = _plane_frame(desk_plane)
    x0, y0, x1, y1 = hm.box  # work on the swept part only
    height = hm.height[y0:y1, x0:x1]
    # the top height also holds everything above it (a mug's rim): in no slab
    valid = np.isfinite(height) & (height < hm.heights[-1] - 0.5 * cfg.step)
    if exclude is not None:
        if exclude.shape != hm.height.shape:
            raise ValueError(f"exclude: expected shape {hm.height.shape} (the map's), got "
                             f"{exclude.shape}")
        valid &= ~exclude[y0:y1, x0:x1]
    found: list[tuple[int, NDArray[np.float64], float, float, NDArray[np.float64]]] = []
    kernel = np.ones((5, 5), np.uint8)
    shift = np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]])  # crop → image
    # the valid pixels (row by row) and their heights: each slab is picked from these
    at_valid = np.flatnonzero(valid)
    valid_height = height.ravel()[at_valid]
    width = height.shape[1]
    cut = (hm.heights >= cfg.raised) & (hm.heights < hm.heights[-1] - 0.5 * cfg.step)
    if above is not None:
        cut &= hm.heights - cfg.slab >= above - 1e-9  # (a swept height's rounding)
    for h in hm.heights[cut]:
        bounds = _slab_bounds(float(h), cfg.slab) if height.dtype == np.float32 else None
        if bounds is None:
            at = at_valid[np.abs(valid_height.astype(np.float64) - h) <= cfg.slab]
        else:  # the same pixels (the slab's, row by row)
            at = at_valid[(valid_height >= bounds[0]) & (valid_height <= bounds[1])]
        if len(at) < cfg.min_pixels:
            continue
        # The morphology and the labels in the slab's box only, 3 px beyond it (the
        # closing reaches 2 px: that ring stays 0, so every pixel of the box comes out as
        # in the whole map, the erosion's too), from an even row and column: the labelling
        # scans 2 x 2 blocks, and each patch's label is its first block's rank in that
        # scan, the same in the box as in the map where the blocks align (nothing but 0
        # lies outside the box).
        box_y0, box_y1 = max(int(at[0]) // width - 3, 0), int(at[-1]) // width + 4
        ys_at = at // width
        xs_at = at - ys_at * width
        box_x0, box_x1 = max(int(xs_at.min()) - 3, 0), int(xs_at.max()) + 4
        box_y0, box_x0 = box_y0 - box_y0 % 2, box_x0 - box_x0 % 2
        slab = np.zeros(height[box_y0:box_y1, box_x0:box_x1].shape, np.uint8)
        in_box = (ys_at - box_y0) * slab.shape[1] + (xs_at - box_x0)  # at, in the box
        slab.ravel()[in_box] = 1
        joined = cv2.morphologyEx(slab, cv2.MORPH_CLOSE, kernel)
        if erode_px > 0:
            joined = cv2.erode(joined, np.ones((2 * erode_px + 1,) * 2, np.uint8))
            kept = joined.ravel()[in_box] > 0
            at, in_box = at[kept], in_box[kept]
        # labels only (the stats cost three times the labelling): the slab is inside the
        # joined patches, so a patch with min_pixels slab pixels has that area too. 16-bit
        # labels (less to write) where they cannot run out: no more patches than pixels.
        ltype = cv2.CV_16U if cv2.countNonZero(joined) < 65535 else cv2.CV_32S
        count, labels = cv2.connectedComponents(joined, connectivity=8, ltype=ltype)
        label = labels.ravel()[in_box]
        per_patch = np.bincount(label, minlength=count)
        origin = on_desk + h * n
        to_plane = np.linalg.inv(plane_homography(Q_L, origin, e1, e2)) @ shift  # → (u, v)
        for c in np.flatnonzero(per_patch[1:] >= cfg.min_pixels) + 1:
            ys, xs = np.divmod(at[label == c], width)
            uv = _apply(to_plane, np.column_stack([xs, ys]))
            # (a window straddling a cover's edge agrees at the cover's height and one at
            # the desk's: the patch ends about at the edge, and the sides are snapped later)
            (cu, cv_), (a, b), angle = cv2.minAreaRect(uv.astype(np.float32))
            if not (side_range[0] <= min(a, b) and max(a, b) <= side_range[1]):
                continue
            rect = cv2.boxPoints(((cu, cv_), (a, b), angle)).astype(np.float64)  # (4, 2) u, v
            fill = _outline_fill(uv, rect)
            if fill < cfg.min_fill:
                continue
            corners = origin + rect[:, :1] * e1 + rect[:, 1:] * e2
            px = _apply(np.linalg.inv(to_plane), rect)
            found.append((len(xs), corners, float(h), fill, px))
    found.sort(key=lambda f: -f[0])
    kept: list[tuple[int, NDArray[np.float64], float, float, NDArray[np.float64]]] = []
    for item in found:
        if not any(quad_overlap(item[4], k[4]) > 0.5 for k in kept):
            kept.append(item)
    return [(corners, h, fill) for _, corners, h, fill, _ in kept]


def _slab_bounds(h: float, slab: float) -> tuple[np.float32, np.float32] | None:
    """The least and the greatest float32 height v with |v − h| <= slab in float64 (as
    ``np.abs(v.astype(np.float64) - h) <= slab`` reads it); None where the slab is too
    thin to find them. v − h rounds monotonically, so the heights within are the ones
    between the two: a slab is picked by comparing the float32 map with them (cheaper)."""

    def within(v: np.float32) -> bool:
        return abs(float(v) - h) <= slab

    def walk(v: np.float32, inward: np.float32, outward: np.float32) -> np.float32 | None:
        # float32(h ± slab) lies a step or two from the bound (near 0, where float32 is
        # much finer than h's float64, it may not: None)
        for _ in range(4):
            if within(v):
                break
            v = np.nextafter(v, inward)
        else:
            return None
        for _ in range(4):
            step = np.nextafter(v, outward)
            if not within(step):
                return v
            v = step
        return None

    up, down = np.float32(np.inf), np.float32(-np.inf)
    lo, hi = walk(np.float32(h - slab), up, down), walk(np.float32(h + slab), down, up)
    return None if lo is None or hi is None else (lo, hi)


def _apply(H: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points (N, 2) through homography H."""
    q = np.ones((len(p), 3))  # (p, 1) as float64, in one array
    q[:, :2] = p
    q = q @ H.T
    return q[:, :2] / q[:, 2:]


def _outline_fill(uv: NDArray[np.float64], rect: NDArray[np.float64], band: float = 0.004,
                  cell: float = 0.004) -> float:
    """The share of the rectangle's outline (cells of ``cell`` metres along it) with patch
    points within ``band`` of it or inside: a cover's outline fills it, a stray blob does
    not."""
    fill = []
    centre = rect.mean(axis=0)
    for k in range(4):
        a, b = rect[k], rect[(k + 1) % 4]
        length = float(np.linalg.norm(b - a))
        if length < 1e-6:
            return 0.0
        d = (b - a) / length
        normal = np.array([-d[1], d[0]])
        rel = uv - a
        t, s = rel @ d, rel @ normal
        s *= 1.0 if (centre - a) @ normal > 0 else -1.0  # inward positive
        near = (t >= 0) & (t <= length) & (s >= -band) & (s <= 2 * band)
        # the cells with a point (0 <= t <= length: cell ceil(length / cell) at most)
        n_cells = max(int(np.ceil(length / cell)), 1)
        seen = np.zeros(n_cells + 1, np.bool_)
        seen[np.floor(t[near] / cell).astype(int)] = True
        fill.append(np.count_nonzero(seen) / n_cells)
    return float(np.mean(fill))


def snap_sides(P: ArrayLike, Q: dict[str, NDArray[np.float64]], grads: dict[str, Gradients], *,
               reach: float = 0.012, inward: float = 0.012, step: float = 0.001,
               samples: int = 24, sides: tuple[int, ...] = (0, 1, 2, 3),
               maps: Sequence[tuple[HeightMap, NDArray[np.float64]]] = (),
               height: float | None = None, strip_tol: float = 0.006,
               strip_read: float = 0.5) -> NDArray[np.float64]:
    """A cover rectangle's sides moved, in its plane, onto the edge both images show.

    Each side of ``P`` (4, 3) is slid along its outward normal within the cover's plane by
    up to ``reach`` metres outward and ``inward`` metres inward; projected into each image,
    it scores the median gradient across it there, and the offset whose weaker image
    scores highest wins. An edge at another height (a page block's foot on the desk, a
    neighbour's cover) lies elsewhere on this plane in the two images and scores in one of
    them only. A side facing the camera takes the innermost strong edge: beyond it lies
    the page block, whose foot often runs along the baseline, where stereo cannot tell it
    from the cover's edge.

    With ``maps`` and ``height``, a side moves outward over no strip the maps read well
    below the cover: the first row of samples beyond the side where they read, on
    ``strip_read`` of its samples or more, a median below ``height`` by more than
    ``strip_tol`` and more than half ``height`` (a lower neighbour, or the desk) bounds its
    move (the rows at and beyond it are not asked). A plain cover's own edge is faint, and
    a lower neighbour's print beyond it still scores in both images within a few
    millimetres of the cover's height (:func:`dense_height_map`'s rectangles run on over
    such a neighbour). Near a cover's edge the sweeps' windows straddle it and read
    heights between the two surfaces: hence half the height, not ``strip_tol`` alone.

    Parameters
    ----------
    P : array_like, shape (4, 3)
        World corners of a rectangle (a height-map cover), in order around it.
    Q : dict of ndarray, shape (3, 4)
        ``{"left": Q_L, "right": Q_R}``.
    grads : dict of Gradients
        Both ideal images' gradients.
    sides : tuple of int
        The sides to move (side s from corner s to s + 1); the others stay.
    maps : sequence of (HeightMap, ndarray (3, 4))
        Height maps with the world → pixel projection of the image each is over; a
        sample takes the height of the first map that has one there.
    height : float, optional
        The cover's height above the desk, metres (needed with ``maps``).
    strip_tol, strip_read : float
        Metres, and a share of a row's samples (see above).

    Returns
    -------
    ndarray, shape (4, 3)
        The moved rectangle's corners (the neighbouring sides' lines stay; the corners are
        where the moved sides meet them).
    """
    if maps and height is None:
        raise ValueError("snap_sides: maps need the cover's height")
    P = np.asarray(P, dtype=np.float64).reshape(4, 3).copy()
    offsets = np.arange(-inward, reach + 1e-9, step)
    u = np.linspace(0.15, 0.85, samples)
    centre = P.mean(axis=0)
    normal = np.cross(P[1] - P[0], P[3] - P[0])
    normal /= np.linalg.norm(normal)
    moves = np.zeros(4)
    outward = np.zeros((4, 3))
    M = Q["left"][:, :3]
    camera = -np.linalg.solve(M, Q["left"][:, 3])  # the left camera's centre, world
    for s in range(4):
        a, b = P[s], P[(s + 1) % 4]
        out = np.cross(b - a, normal)
        out /= np.linalg.norm(out)
        if out @ (centre - a) > 0:
            out = -out
        outward[s] = out
        if s not in sides:
            continue
        pts = a + u[:, None] * (b - a)  # (S, 3) along the side
        moved = pts[None] + offsets[:, None, None] * out  # (O, S, 3)
        worst = None
        for cam in ("left", "right"):
            px = geometry.project(Q[cam], moved.reshape(-1, 3)).reshape(len(offsets), samples, 2)
            along = px[:, -1] - px[:, 0]
            n_img = np.stack([-along[:, 1], along[:, 0]], axis=1)
            n_img /= np.maximum(np.linalg.norm(n_img, axis=1, keepdims=True), 1e-9)
            gx, gy = grads[cam].sample(px[..., 0], px[..., 1])
            score = np.median(np.abs(gx * n_img[:, None, 0] + gy * n_img[:, None, 1]), axis=1)
            worst = score if worst is None else np.minimum(worst, score)
        assert worst is not None
        if maps and height is not None:  # (None with maps was refused above)
            bound = _strip_bound(moved, offsets, maps, height, strip_tol, strip_read)
            if bound is not None:
                worst = np.where(np.arange(len(offsets)) < bound, worst, -np.inf)
        best = int(np.argmax(worst))
        if out @ (camera - 0.5 * (a + b)) > 0:
            # a side facing the camera shows the page block beyond it, whose foot is an
            # edge too (and often along the baseline, where stereo cannot tell it): the
            # cover's edge is the innermost strong one
            padded = np.r_[-np.inf, worst, -np.inf]  # no neighbour past either end
            peak = (worst >= 0.5 * worst[best]) & (worst >= padded[:-2]) & (worst >= padded[2:])
            best = int(np.flatnonzero(peak)[0]) if peak.any() else best
        moves[s] = offsets[best]
    # each side's line moved by its offset; corner s joins side s - 1 and side s
    return np.array([P[s] + moves[s] * outward[s] + moves[s - 1] * outward[s - 1]
                     for s in range(4)])


def _strip_bound(moved: NDArray[np.float64], offsets: NDArray[np.float64],
                 maps: Sequence[tuple[HeightMap, NDArray[np.float64]]], height: float,
                 tol: float, min_read: float) -> int | None:
    """The first row of ``moved`` (O, S, 3), a side's samples at each of ``offsets`` (O,)
    (metres, outward positive), beyond the side (offset > 0) that ``maps`` read, on
    ``min_read`` of its S samples or more, at a median below ``height`` by more than
    ``tol`` and more than half ``height``; None where no row does."""
    n_rows, n = moved.shape[:2]
    z = np.full(n_rows * n, np.nan)
    for hm, Q in maps:  # each sample from the first map with a height there
        z = np.where(np.isnan(z), read_heights(hm, Q, moved.reshape(-1, 3)), z)
    z = z.reshape(n_rows, n)
    count = np.count_nonzero(np.isfinite(z), axis=1)
    lower = row_medians(z, count) < height - max(tol, 0.5 * height)
    beyond = np.arange(n_rows) > np.argmin(np.abs(offsets))  # (np.arange's 0 is not exact)
    other = beyond & (count >= min_read * n) & lower
    return int(np.flatnonzero(other)[0]) if other.any() else None
