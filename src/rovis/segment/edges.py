"""Edge stage (paper §3.A): Sobel gradients once per image, Canny for any T_H from them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

CANNY_LOW_RATIO = 0.4  # T_L = 0.4 · T_H (paper §3.A)


@dataclass(frozen=True, eq=False)
class Gradients:
    """Sobel derivatives of one (smoothed) image, reused for every threshold.

    Attributes
    ----------
    dx, dy : ndarray, shape (H, W), int16 (float32 from :func:`linear_gradients`)
        3×3 Sobel derivatives, the input cv2.Canny accepts instead of an image.
    mask : ndarray, shape (H, W), uint8 or None
        Region of interest (non-zero inside); edges outside it are dropped.
    box : (x0, y0, x1, y1)
        The ROI's bounding box (the whole image without a mask); Hough runs on this crop.
    seen : ndarray, shape (H, W), uint8 or None
        Where the image shows the scene (non-zero), if not everywhere: an ideal image grown
        to the raw field of view (:class:`rovis.undistort.IdealView`) is black beyond it, and
        a side running there is out of view, as beyond the image's edge (None: all of it).
    fits : dict
        The sides :func:`rovis.segment.lines.refine_segment` fitted on these gradients,
        by their end points and settings: a frame fits the same side of many candidate
        quads again. Not an argument: each instance (and each :func:`dataclasses.replace`
        of one) starts empty, so the arrays must not be changed in place once sides are
        fitted on them.
    """

    dx: NDArray[np.int16]
    dy: NDArray[np.int16]
    mask: NDArray[np.uint8] | None
    box: tuple[int, int, int, int]
    seen: NDArray[np.uint8] | None = None
    fits: dict[Any, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def shape(self) -> tuple[int, int]:
        return self.dx.shape  # type: ignore[return-value]

    def sample(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bilinear dx, dy at float pixel positions (any shape); 0 outside the image."""
        h, w = self.shape
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        if x.shape != y.shape:
            x, y = np.broadcast_arrays(x, y)
        xf, yf = np.floor(x), np.floor(y)
        x0, y0 = xf.astype(np.intp), yf.astype(np.intp)
        # 0 <= v < size - 1 as one unsigned comparison (a negative v wraps to a huge one)
        inside = x0.view(np.uintp) < w - 1
        inside &= y0.view(np.uintp) < h - 1
        # flat index of each top-left neighbour (0 outside: read, then masked); the four
        # neighbours of dx and dy in two flat gathers, (dx or dy, neighbour, sample): a
        # fraction of the cost of eight
        at = y0 * w
        at += x0
        at *= inside
        at = at.reshape(1, -1) + np.array([[0], [1], [w], [w + 1]])
        g = np.empty((2,) + at.shape, self.dx.dtype)
        np.take(self.dx.reshape(-1), at, out=g[0], mode="wrap")  # (no out-of-range index)
        np.take(self.dy.reshape(-1), at, out=g[1], mode="wrap")
        # x - floor(x): x - x0 where it matters (inside), without the int-to-float cast
        fx, fy = x.reshape(-1) - xf.reshape(-1), y.reshape(-1) - yf.reshape(-1)
        wx, wy = 1 - fx, 1 - fy
        # dx and dy at once, in the same order of operations as one at a time:
        # (g00·wx + g01·fx)·wy + (g10·wx + g11·fx)·fy
        top = g[:, 0] * wx
        top += g[:, 1] * fx
        top *= wy
        bottom = g[:, 2] * wx
        bottom += g[:, 3] * fx
        bottom *= fy
        top += bottom
        v = np.where(inside.reshape(-1), top, 0.0)
        return v[0].reshape(x.shape), v[1].reshape(x.shape)


def gradients(gray: NDArray[np.uint8], mask: NDArray[np.uint8] | None = None, *,
              sigma: float = 1.0, region: tuple[int, int, int, int] | None = None) -> Gradients:
    """Smooth lightly and take 3×3 Sobel derivatives (computed once per image).

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    mask : ndarray, shape (H, W), uint8, optional
        ROI, non-zero inside.
    sigma : float
        Gaussian pre-smoothing, pixels (Canny's own first step; 0 disables).
    region : (x0, y0, x1, y1), optional
        Only this box is differentiated, 0 elsewhere, for a caller that samples only well
        inside it: within 3σ + 1 px of its border (4 px at σ = 1) the smoothing and the
        Sobel kernel see the box's border, not the image beyond.
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ValueError(f"gray: expected a 2-D uint8 image, got {gray.dtype} {gray.shape}")
    if mask is not None and mask.shape != gray.shape:
        raise ValueError(f"mask: expected shape {gray.shape}, got {mask.shape}")
    if region is None:
        return _sobel(gray, mask, sigma, cv2.CV_16S)
    x0, y0, x1, y1 = _check_region(region, gray.shape)
    part = _sobel(gray[y0:y1, x0:x1], None, sigma, cv2.CV_16S)
    dx, dy = (np.zeros(gray.shape, np.int16) for _ in range(2))
    dx[y0:y1, x0:x1], dy[y0:y1, x0:x1] = part.dx, part.dy
    return Gradients(dx=dx, dy=dy, mask=mask, box=_box(mask, gray.shape))


def _check_region(region: tuple[int, int, int, int],
                  shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """``region`` (x0, y0, x1, y1) as ints, or ValueError unless 0 <= x0 < x1 <= W and
    0 <= y0 < y1 <= H for an image of ``shape`` (H, W)."""
    x0, y0, x1, y1 = (int(v) for v in region)
    h, w = shape[:2]
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise ValueError(f"region: expected 0 <= x0 < x1 <= {w} and 0 <= y0 < y1 <= {h}, "
                         f"got {tuple(region)}")
    return x0, y0, x1, y1


def _box(mask: NDArray[np.uint8] | None, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """The ROI's bounding box (x0, y0, x1, y1): the whole image of ``shape`` without a mask."""
    if mask is None:
        return (0, 0, shape[1], shape[0])
    x, y, bw, bh = cv2.boundingRect(mask)
    return (x, y, x + bw, y + bh)


def linear_gradients(gray: NDArray[np.uint8], mask: NDArray[np.uint8] | None = None, *,
                     gamma: float = 2.2, sigma: float = 1.0) -> Gradients:
    """Sobel derivatives of the image's linear intensities, for sub-pixel refinement.

    A camera encodes light with a gamma (about 1/2.2) after the optics blurred it, and an
    edge's steepest grey-level step then lies nearer its dark side than the edge does.
    Undoing the gamma first (``gray/255`` to the power ``gamma``, times 255, in float32)
    puts the steepest step back on the edge (measured in docs/segmentation.md). Not for
    Canny: its thresholds are in the image's own grey levels.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    mask : ndarray, shape (H, W), uint8, optional
    gamma : float
        The encoding's exponent to undo (1 leaves the image as it is).
    sigma : float
        Gaussian pre-smoothing, pixels, as :func:`gradients`.
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ValueError(f"gray: expected a 2-D uint8 image, got {gray.dtype} {gray.shape}")
    if not gamma > 0:
        raise ValueError(f"gamma: expected a positive number, got {gamma!r}")
    lut = (255.0 * (np.arange(256, dtype=np.float64) / 255.0) ** gamma).astype(np.float32)
    return _sobel(lut[gray], mask, sigma, cv2.CV_32F)


def _sobel(img: NDArray[np.generic], mask: NDArray[np.uint8] | None, sigma: float,
           ddepth: int) -> Gradients:
    """Smooth ``img`` (Gaussian ``sigma`` px, 0: not), take 3×3 Sobel derivatives of depth
    ``ddepth`` and the ROI's bounding box."""
    if sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    dx = cv2.Sobel(img, ddepth, 1, 0, ksize=3)
    dy = cv2.Sobel(img, ddepth, 0, 1, ksize=3)
    return Gradients(dx=dx, dy=dy, mask=mask, box=_box(mask, img.shape))


def canny(grad: Gradients, T_H: float, T_L: float | None = None) -> NDArray[np.uint8]:
    """Canny edges with hysteresis T_L = 0.4·T_H on the L2 gradient magnitude, ROI applied.

    ``T_L`` may be given explicitly (the automatic-threshold baselines use other ratios).

    Returns
    -------
    ndarray, shape (H, W), uint8
        255 on edge pixels.
    """
    low = CANNY_LOW_RATIO * float(T_H) if T_L is None else float(T_L)
    edges = cv2.Canny(grad.dx, grad.dy, low, float(T_H), L2gradient=True)
    if grad.mask is not None:
        edges = cv2.bitwise_and(edges, grad.mask)
    return edges
