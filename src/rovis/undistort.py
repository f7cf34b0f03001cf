"""Step 2 of the paper's Fig. 2: the ideal (undistorted) images, where lines are straight.

The ideal image of a rig's camera is the pinhole image of its own camera matrix K. With
barrel distortion (k1 < 0) the raw image's border maps *outside* the K frame of the raw
image's size: a wide lens loses a band of its field of view along every edge there
(72 px of 640 at the sides and 57 px of 480 at the top for the real Bumblebee2 pairs,
k1 = −0.36; 22 px of 1024 for the synthetic rig, k1 = −0.08). :class:`IdealView` grows the ideal frame until the whole raw
field of view is in it: the same K with its principal point moved by ``offset``, on a larger
canvas, and a mask of the pixels that come from the raw image. A cover near the raw image's
edge keeps all four sides (on the chessboard pairs the sheet's fourth side was beyond the
ideal image in 5 of the 11 pairs; docs/segmentation.md).

Pixel coordinates in this frame are the rig's ideal pixels plus ``offset``;
:meth:`IdealView.rig` is the rig whose projection matrices give them, for everything
computed on the ideal images (stereo, triangulation, height maps), and
:meth:`IdealView.to_rig_ideal` takes them back to the rig's ideal pixels (what results
report, with the lens added back).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis.calib import Camera, StereoRig

# Raw-border samples per image side: the undistorted border is a smooth curve, whose
# extreme is at a corner or a side's middle; 64 samples place it to well under a pixel.
_BORDER_SAMPLES = 64


def ideal_bounds(rig: StereoRig) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The smallest box (lo, hi), (2,) each, of the rig's ideal pixels that holds both raw
    images' whole field of view and the raw image's own pixel box.

    The raw border is undistorted at ``_BORDER_SAMPLES`` points a side. A lens model that
    folds back within the image (strong barrel distortion without the term that bounds it)
    does not invert there: then the raw image's own box is returned, as without growing.
    """
    assert rig.image_size is not None
    w, h = rig.image_size
    lo, hi = np.zeros(2), np.array([w - 1.0, h - 1.0])
    t = np.linspace(0.0, 1.0, _BORDER_SAMPLES)
    border = np.vstack([np.column_stack([t * (w - 1), np.zeros_like(t)]),
                        np.column_stack([t * (w - 1), np.full_like(t, h - 1.0)]),
                        np.column_stack([np.zeros_like(t), t * (h - 1)]),
                        np.column_stack([np.full_like(t, w - 1.0), t * (h - 1)])])
    grown_lo, grown_hi = lo.copy(), hi.copy()
    for cam in ("left", "right"):
        ideal = rig.undistort_points(border, cam)
        if not np.all(np.isfinite(ideal)) or \
                np.abs(rig.distort_points(ideal, cam) - border).max() > 0.5:
            return lo, hi
        grown_lo = np.minimum(grown_lo, ideal.min(axis=0))
        grown_hi = np.maximum(grown_hi, ideal.max(axis=0))
    # at most twice the raw size: beyond that the model is extrapolating
    if np.any(grown_hi - grown_lo > 2.0 * np.array([w, h])):
        return lo, hi
    return grown_lo, grown_hi


@dataclass(frozen=True, eq=False)
class IdealView:
    """The undistorted images' pixel frame for one rig, and the maps that make them.

    Attributes
    ----------
    offset : ndarray, shape (2,), float64
        Pixels: an ideal pixel of the rig (camera matrix K) is at ``px + offset`` here.
        Zero where the raw field of view fits the raw image's size on the top and left
        (``full=False``, or a lens without barrel or tangential distortion).
    size : (int, int)
        Width and height of the ideal images, pixels.
    maps : dict
        Per camera, the ``cv2.remap`` maps (fixed point) from the raw image.
    valid : dict
        Per camera, ndarray (H, W) uint8: 255 where the ideal pixel comes from the raw image
        at least ``margin_px`` inside its border (the rest is black, and its step is no edge).
    """

    offset: NDArray[np.float64]
    size: tuple[int, int]
    maps: dict[str, tuple[NDArray[np.generic], NDArray[np.generic]]]
    valid: dict[str, NDArray[np.uint8]]

    @classmethod
    def of(cls, rig: StereoRig, *, full: bool = True, margin_px: int = 3) -> IdealView:
        """The ideal frame of ``rig``: grown to the raw field of view (``full``) or not.

        Parameters
        ----------
        rig : StereoRig
            With its image size.
        full : bool
            Grow the frame so that every raw pixel is in it (the same offset and size for
            both cameras; :func:`ideal_bounds`); else the raw image's size and K as they are.
        margin_px : int
            The band inside the raw image's border left out of :attr:`valid`: the 3×3
            Sobel and the Gaussian before it see the black beyond the border that far.
        """
        if rig.image_size is None:
            raise ValueError("calibration: image size unknown; give image_width/height")
        w, h = rig.image_size
        lo, hi = ideal_bounds(rig) if full else (np.zeros(2), np.array([w - 1.0, h - 1.0]))
        offset = -np.floor(lo)
        size = (int(np.ceil(hi[0]) + offset[0]) + 1, int(np.ceil(hi[1]) + offset[1]) + 1)
        maps, valid = {}, {}
        for cam in ("left", "right"):
            K, D = rig.intrinsics(cam)
            K_view = K.copy()
            K_view[:2, 2] += offset
            mx, my = cv2.initUndistortRectifyMap(K, D, None, K_view, size, cv2.CV_32FC1)
            # half a pixel of slack: a lens without distortion maps row 0 to y = -1e-5
            inside = ((mx >= -0.5) & (mx <= w - 0.5) & (my >= -0.5) & (my <= h - 0.5))
            inside = inside.astype(np.uint8) * 255
            if margin_px > 0 and not inside.all():
                k = 2 * margin_px + 1
                inside = cv2.erode(inside, np.ones((k, k), np.uint8), borderType=cv2.BORDER_CONSTANT,
                                   borderValue=0)  # the canvas edge is the raw border too
            maps[cam] = cv2.convertMaps(mx, my, cv2.CV_16SC2)
            valid[cam] = inside
        return cls(offset.astype(np.float64), size, maps, valid)

    @property
    def grown(self) -> bool:
        """Whether the ideal images hold pixels the raw images do not give (a larger
        canvas, or a pincushion lens's corners): then :attr:`valid` matters."""
        return bool(np.any(self.offset != 0)) or not all(v.all() for v in self.valid.values())

    def undistort(self, raw: NDArray[np.uint8], camera: Camera,
                  region: tuple[int, int, int, int] | None = None) -> NDArray[np.uint8]:
        """The ideal image of one raw image (bilinear; black outside the raw image).

        ``region`` ``(x0, y0, x1, y1)``: only those ideal pixels are computed, the rest
        left black (each ideal pixel is its own lookup, so those are the whole image's)."""
        if region is None:
            return cv2.remap(raw, *self.maps[camera], cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT)
        x0, y0, x1, y1 = (int(v) for v in region)
        if not (0 <= x0 < x1 <= self.size[0] and 0 <= y0 < y1 <= self.size[1]):
            raise ValueError(f"region: expected 0 <= x0 < x1 <= {self.size[0]} and "
                             f"0 <= y0 < y1 <= {self.size[1]}, got {tuple(region)}")
        out = np.zeros((self.size[1], self.size[0]), dtype=raw.dtype)
        out[y0:y1, x0:x1] = cv2.remap(raw, *(m[y0:y1, x0:x1] for m in self.maps[camera]),
                                      cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        return out

    def rig(self, rig: StereoRig) -> StereoRig:
        """``rig`` with its camera matrices' principal points moved by :attr:`offset` and the
        image size of this frame: its ``Q_L``, ``Q_R`` (and ``triangulate(...,
        distorted=False)``) work in this frame's pixels. Not for raw pixels (its
        ``distort_points`` and ``undistort_points`` would be off by the offset): use
        :meth:`to_rig_ideal` and the original rig for those."""
        if not np.any(self.offset) and self.size == rig.image_size:
            return rig
        S = np.array([[1.0, 0.0, self.offset[0]], [0.0, 1.0, self.offset[1]], [0.0, 0.0, 1.0]])
        return StereoRig.from_arrays(K1=S @ rig.K1, D1=rig.D1, K2=S @ rig.K2, D2=rig.D2, R=rig.R,
                                     T=rig.T, image_size=self.size, T_world_left=rig.T_world_left,
                                     world_frame=rig.world_frame)

    def to_rig_ideal(self, px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixels of this frame (..., 2) as the rig's ideal pixels."""
        return np.asarray(px, dtype=np.float64) - self.offset

    def from_rig_ideal(self, px: NDArray[np.float64]) -> NDArray[np.float64]:
        """The rig's ideal pixels (..., 2) in this frame."""
        return np.asarray(px, dtype=np.float64) + self.offset
