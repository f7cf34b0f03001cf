"""Stereo correspondence of book covers (paper §4, before eq. 3).

Each left cover quad is matched to at most one right quad. A right corner must lie where
the left corner's ray can be seen: on its epipolar line, and — with a known desk plane —
between the ray's points at desk height and at ``max_height`` above it (a short segment of
that line: books lie on the desk). Without a desk plane the depth range bounds the segment.
Among the four cyclic corner orders the best is kept, so the same physical corner is P1 in
both images; the covers' appearance (normalised cross-correlation of the two rectified
cover patches) breaks ties between similar shapes. The assignment is one-to-one
(Hungarian).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from rovis import geometry

_PATCH = (48, 36)  # rectified cover patch, px


@dataclass(frozen=True)
class StereoConfig:
    """Gates of the correspondence search (pixels, metres)."""

    max_error_px: float = 3.0  # mean distance of the right corners to their segments
    max_height: float = 0.40  # above the desk plane
    min_depth: float = 0.2  # without a desk plane
    max_depth: float = 5.0
    min_ncc: float = 0.2  # covers must look alike
    appearance_weight_px: float = 2.0  # cost of (1 - NCC), in pixels


@dataclass(frozen=True, eq=False)
class Match:
    """One left quad matched to one right quad.

    Attributes
    ----------
    left, right : int
        Indices into the left and right quads.
    corners_right : ndarray, shape (4, 2)
        The right quad's corners reordered to correspond to the left's P1..P4.
    error_px : float
        Mean distance of the right corners to their allowed segments.
    ncc : float
        Appearance similarity in [-1, 1].
    """

    left: int
    right: int
    corners_right: NDArray[np.float64]
    error_px: float
    ncc: float


def match_quads(quads_left: ArrayLike, quads_right: ArrayLike, Q_L: ArrayLike, Q_R: ArrayLike, *,
                desk_plane: ArrayLike | None = None, gray_left: NDArray[np.uint8] | None = None,
                gray_right: NDArray[np.uint8] | None = None,
                cfg: StereoConfig = StereoConfig()) -> list[Match]:
    """Match cover quads between the (undistorted) left and right images.

    Parameters
    ----------
    quads_left, quads_right : array_like, shape (K, 4, 2) and (M, 4, 2)
        Ideal (undistorted) pixel corners.
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections (eq. 3).
    desk_plane : array_like, shape (4,), optional
        ``[nx, ny, nz, d]`` in the world frame, normal up.
    gray_left, gray_right : ndarray, optional
        The undistorted images, for the appearance check.

    Returns
    -------
    list of Match, sorted by left index.
    """
    qL = np.asarray(quads_left, dtype=np.float64).reshape(-1, 4, 2)
    qR = np.asarray(quads_right, dtype=np.float64).reshape(-1, 4, 2)
    if len(qL) == 0 or len(qR) == 0:
        return []
    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    near_px, far_px = _segments(qL.reshape(-1, 2), Q_L, Q_R, desk_plane, cfg)  # (4K, 2) each
    near_px, far_px = near_px.reshape(-1, 4, 2), far_px.reshape(-1, 4, 2)

    shifts = np.array([np.roll(np.arange(4), -s) for s in range(4)])  # right corner order
    cost = np.full((len(qL), len(qR)), np.inf)
    best: dict[tuple[int, int], tuple[NDArray[np.float64], float, float]] = {}
    for k in range(len(qL)):
        cand = qR[:, shifts]  # (M, 4 shifts, 4 corners, 2)
        d = _point_segment_distance(cand, near_px[k][None, None], far_px[k][None, None])
        err = d.mean(axis=2)  # (M, 4)
        s_best = np.argmin(err, axis=1)
        e_best = err[np.arange(len(qR)), s_best]
        for m in np.nonzero(e_best <= cfg.max_error_px)[0]:
            corners_r = cand[m, s_best[m]]
            ncc = 1.0
            if gray_left is not None and gray_right is not None:
                ncc = _cover_ncc(gray_left, qL[k], gray_right, corners_r)
                if ncc < cfg.min_ncc:
                    continue
            cost[k, m] = e_best[m] + cfg.appearance_weight_px * (1.0 - ncc)
            best[(k, m)] = (corners_r, float(e_best[m]), ncc)
    finite = np.isfinite(cost)
    if not finite.any():
        return []
    rows, cols = linear_sum_assignment(np.where(finite, cost, 1e9))
    out = [Match(int(k), int(m), *best[(k, m)]) for k, m in zip(rows, cols) if finite[k, m]]
    return sorted(out, key=lambda mt: mt.left)


def _segments(p_L: NDArray[np.float64], Q_L: NDArray[np.float64], Q_R: NDArray[np.float64],
              desk_plane: ArrayLike | None,
              cfg: StereoConfig) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """For each left pixel, the right-image end points of where its 3D point may be."""
    M = Q_L[:, :3]
    C = -np.linalg.solve(M, Q_L[:, 3])  # left camera centre, world
    rays = np.linalg.solve(M, np.column_stack([p_L, np.ones(len(p_L))]).T).T  # world directions
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    if desk_plane is not None:
        plane = np.asarray(desk_plane, dtype=np.float64)
        n, d = plane[:3], plane[3]
        denom = rays @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            s_desk = -(n @ C + d) / denom
            s_top = -(n @ C + d - cfg.max_height) / denom
        s_near = np.where(np.isfinite(s_top) & (s_top > 0), s_top, cfg.min_depth)
        s_far = np.where(np.isfinite(s_desk) & (s_desk > 0), s_desk, cfg.max_depth)
        # a little below the desk too: the plane comes from a marker a few metres of error away
        s_far = s_far * 1.02
    else:
        s_near = np.full(len(p_L), cfg.min_depth)
        s_far = np.full(len(p_L), cfg.max_depth)
    return geometry.project(Q_R, C + s_near[:, None] * rays), geometry.project(Q_R, C + s_far[:, None] * rays)



def _point_segment_distance(p: NDArray[np.float64], a: NDArray[np.float64],
                            b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from points ``p`` to segments ``a``–``b`` (broadcast over leading axes)."""
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-12), 0, 1)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def _cover_ncc(gray_l: NDArray[np.uint8], c_l: NDArray[np.float64], gray_r: NDArray[np.uint8],
               c_r: NDArray[np.float64]) -> float:
    """NCC of the two covers warped to the same small rectangle (corners in matching order)."""
    w, h = _PATCH
    dst = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32)
    patches = []
    for img, c in ((gray_l, c_l), (gray_r, c_r)):
        H = cv2.getPerspectiveTransform(c.astype(np.float32), dst)
        patches.append(cv2.warpPerspective(img, H, (w, h), flags=cv2.INTER_AREA).astype(np.float64))
    a, b = (p[3:-3, 3:-3].ravel() for p in patches)  # the border may catch the desk
    a, b = a - a.mean(), b - b.mean()
    denom = np.sqrt((a @ a) * (b @ b))
    if denom < 1e-6:  # a plain cover: both flat is a match, flat vs textured is not
        return 1.0 if max(a.std(), b.std()) < 2.0 else 0.0
    return float(a @ b / denom)
