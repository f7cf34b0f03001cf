"""The desk marker stage (paper §3, DESIGN §3): ArUco marker → pose, desk plane, workspace ROI.

The marker (``DICT_4X4_50`` id 0, 0.10 m side by default) lies flat on the desk. Its frame has
the origin at the marker centre, x along its top edge (left → right as printed), y toward its
top, z up out of the desk. OpenCV reports the four outer corners top-left, top-right,
bottom-right, bottom-left, which in that frame are ``(-s/2, s/2)``, ``(s/2, s/2)``,
``(s/2, -s/2)``, ``(-s/2, -s/2)``.

A 0.10 m marker at ~1.1 m is only ~70 px wide, so one view fixes its tilt poorly. The stereo
pose therefore fits one rigid pose to the corners seen in *both* images: a closed-form start
(Kabsch on the triangulated corners), then least squares on the reprojection error in both
images (the maximum-likelihood pose under Gaussian corner noise).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from rovis import geometry
from rovis.calib import Camera, StereoRig, undistort_iter
from rovis.imageio import to_gray_u8

DICTIONARY = cv2.aruco.DICT_4X4_50
MARKER_ID = 0
MARKER_SIDE = 0.10  # metres
WORKSPACE_X = (0.05, 0.85)  # metres, marker frame
WORKSPACE_Y = (0.05, 0.65)


@dataclass(frozen=True, eq=False)
class MarkerCorners:
    """One detected marker.

    Attributes
    ----------
    marker_id : int
    corners_px : ndarray, shape (4, 2), float64
        Raw (distorted) pixel coordinates, OpenCV order: top-left, top-right, bottom-right,
        bottom-left of the printed marker.
    """

    marker_id: int
    corners_px: NDArray[np.float64]


def marker_model(side: float = MARKER_SIDE) -> NDArray[np.float64]:
    """The four marker corners (4, 3) in the marker frame, metres, OpenCV corner order."""
    h = 0.5 * side
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


@functools.lru_cache(maxsize=8)
def _detector(dictionary: int) -> cv2.aruco.ArucoDetector:
    """One detector per dictionary, built once (building it per frame costs ~1 ms)."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 4
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.001
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(dictionary), params)


def detect_marker(image: NDArray[np.generic], *, dictionary: int = DICTIONARY,
                  marker_id: int = MARKER_ID,
                  intrinsics: tuple[ArrayLike, ArrayLike] | None = None,
                  refine: bool = True) -> MarkerCorners | None:
    """Find the desk marker in one image.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3), uint8 (or anything :func:`to_gray_u8` takes)
        The raw camera image; colour is converted to gray.
    dictionary : int
        A ``cv2.aruco.DICT_*`` constant.
    marker_id : int
        The marker to look for; other markers are ignored.
    intrinsics : (K, D), optional
        The camera's matrix (3, 3) and distortion (5,). With them the edge refinement works
        in undistorted coordinates, where the marker's edges are straight.
    refine : bool
        Refine the corners by fitting lines to the four outer edges
        (:func:`refine_marker_corners`); otherwise keep ArUco's own sub-pixel corners.

    Returns
    -------
    MarkerCorners or None
        None when that marker is not visible (an expected result, not an error). If the id is
        seen more than once, the largest one is returned.
    """
    gray = to_gray_u8(image)
    corners, ids, _ = _detector(dictionary).detectMarkers(gray)
    if ids is None or len(corners) == 0:
        return None
    found = [np.asarray(c, dtype=np.float64).reshape(4, 2)
             for c, i in zip(corners, np.asarray(ids).ravel()) if int(i) == marker_id]
    if not found:
        return None
    best = max(found, key=lambda c: abs(cv2.contourArea(c.astype(np.float32))))
    if refine:
        best = refine_marker_corners(gray, best, intrinsics=intrinsics)
    return MarkerCorners(marker_id=marker_id, corners_px=best)


def refine_marker_corners(gray: NDArray[np.uint8], corners_px: ArrayLike, *,
                          intrinsics: tuple[ArrayLike, ArrayLike] | None = None,
                          iterations: int = 2) -> NDArray[np.float64]:
    """Sub-pixel marker corners from lines fitted to the square's four outer edges.

    ArUco's corner refinement (``cornerSubPix``) is biased by 0.1–0.4 px at the L-shaped
    outer corners of a blurred marker, and a 0.3 px corner error tilts a 70 px marker's pose
    by ~0.3°. Here each edge is sampled across its middle 70 % by short intensity profiles
    along its normal, reaching no further than a third of a cell either side (inside the
    black border, outside in the white quiet zone the marker needs anyway); the area under
    each normalised profile gives one edge point, a line is fitted to each edge, and
    neighbouring lines intersect in the corners (≈ 0.02 px on rendered markers). With
    ``intrinsics`` the profiles run in undistorted coordinates, where the edges are straight.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    corners_px : array_like, shape (4, 2)
        Raw pixels, OpenCV order (the square's corners in order around it).
    intrinsics : (K, D), optional
        Camera matrix (3, 3) and distortion (5,).
    iterations : int
        Re-centre the profiles on the refined corners this many times.

    Returns
    -------
    ndarray, shape (4, 2), float64
        Raw pixels; the input corners unchanged where an edge gives too few points.
    """
    raw = _as_corners(corners_px, "corners_px")
    if intrinsics is None:
        K, D = np.eye(3), np.zeros(5)
    else:
        K, D = (np.asarray(a, dtype=np.float64) for a in intrinsics)
    img = np.ascontiguousarray(gray, dtype=np.float32)
    q = _undistort(raw, K, D)  # ideal coordinates (pixels of K, or raw when no intrinsics)
    for _ in range(iterations):
        side = np.mean(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1))
        # Inside the black border (one cell = side/6) and outside in the white quiet zone only.
        reach = float(np.clip(0.35 * side / 6.0, 1.5, 6.0))
        lines = []
        for i in range(4):
            line = _fit_edge(img, q[i], q[(i + 1) % 4], q, reach, K, D)
            if line is None:
                return raw
            lines.append(line)
        new_q = np.array([_intersect(lines[i - 1], lines[i]) for i in range(4)])
        if not np.all(np.isfinite(new_q)) or np.abs(new_q - q).max() > max(2.0, 0.1 * side):
            return raw  # the fit disagrees with the detection: keep what ArUco said
        q = new_q
    return _distort(q, K, D)


def _undistort(px: NDArray[np.float64], K: NDArray[np.float64],
               D: NDArray[np.float64]) -> NDArray[np.float64]:
    if not np.any(D):
        return px.copy()
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    return undistort_iter(px.reshape(-1, 1, 2), K, D, K, crit).reshape(-1, 2)


def _distort(ideal: NDArray[np.float64], K: NDArray[np.float64],
             D: NDArray[np.float64]) -> NDArray[np.float64]:
    if not np.any(D):
        return ideal.copy()
    xy = (ideal - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T
    P = np.column_stack([xy, np.ones(len(xy))]).reshape(-1, 1, 3)
    px, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, D)
    return px.reshape(-1, 2)


def _fit_edge(img: NDArray[np.float32], a: NDArray[np.float64], b: NDArray[np.float64],
              quad: NDArray[np.float64], reach: float, K: NDArray[np.float64],
              D: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Line ``[nx, ny, c]`` (``n·p + c = 0``, ideal coordinates) through one dark→light edge."""
    d = b - a
    length = float(np.linalg.norm(d))
    if length < 4:
        return None
    d /= length
    n = np.array([d[1], -d[0]])
    if n @ (a - quad.mean(axis=0)) < 0:  # point the normal outward, from ink to paper
        n = -n
    n_prof = max(8, int(length))
    t = np.linspace(0.15, 0.85, n_prof) * length
    s = np.arange(-reach, reach + 1e-9, 0.25)
    pts = a + t[:, None, None] * d + s[None, :, None] * n  # (profiles, samples, 2)
    raw = _distort(pts.reshape(-1, 2), K, D).astype(np.float32)
    shape = (len(t), len(s))  # a 2D map: cv2.remap refuses more than 32767 columns
    prof = cv2.remap(img, raw[:, 0].reshape(shape), raw[:, 1].reshape(shape), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    k = max(2, len(s) // 5)
    lo = np.median(prof[:, :k], axis=1)
    hi = np.median(prof[:, -k:], axis=1)
    # Edge position from the area under the normalised profile: for a step from 0 to 1 at
    # position e, its integral over [s0, s1] is s1 - e. Unlike the 50 % crossing of
    # interpolated samples, the area does not depend on where the edge falls between pixels.
    ok = np.all(prof >= 0, axis=1) & (hi - lo >= 20)  # on the image, enough contrast
    norm = (prof - lo[:, None]) / np.maximum(hi - lo, 1e-9)[:, None]
    area = np.trapezoid(norm, s, axis=1)
    e = s[-1] - area
    ok &= np.abs(e) < reach - 0.5
    if ok.sum() < max(4, n_prof // 3):
        return None
    P = pts[ok, 0] + (e[ok] - s[0])[:, None] * n
    for _ in range(2):  # total least squares, then once more without outliers
        c = P.mean(axis=0)
        normal = np.linalg.svd(P - c)[2][1]
        r = (P - c) @ normal
        keep = np.abs(r) <= max(3.0 * np.std(r), 0.05)
        if keep.sum() < 4:
            return None
        P = P[keep]
    c = P.mean(axis=0)
    normal = np.linalg.svd(P - c)[2][1]
    return np.array([normal[0], normal[1], -normal @ c])


def _intersect(l1: NDArray[np.float64], l2: NDArray[np.float64]) -> NDArray[np.float64]:
    p = np.cross(l1, l2)
    if abs(p[2]) < 1e-12:
        return np.array([np.nan, np.nan])
    return p[:2] / p[2]


def marker_pose_mono(K: ArrayLike, D: ArrayLike, corners_px: ArrayLike,
                     side: float = MARKER_SIDE) -> NDArray[np.float64]:
    """Marker pose from one view (IPPE for squares): ``T_cam_marker`` (4, 4).

    Parameters
    ----------
    K : array_like, shape (3, 3)
    D : array_like, shape (5,)
    corners_px : array_like, shape (4, 2)
        Raw pixels, OpenCV corner order.
    side : float
        Marker side, metres.
    """
    obj = marker_model(side)
    img = np.asarray(corners_px, dtype=np.float64).reshape(4, 1, 2)
    ok, rvec, tvec = cv2.solvePnP(obj.reshape(4, 1, 3), img, np.asarray(K, dtype=np.float64),
                                  np.asarray(D, dtype=np.float64), flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not ok:
        raise ValueError("corners_px: solvePnP found no marker pose (degenerate corners)")
    return geometry.make_transform(cv2.Rodrigues(rvec)[0], tvec.ravel())


def _rigid_fit(P_src: NDArray[np.float64], P_dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """``T_dst_src`` (4, 4) minimising ``sum |T·P_src - P_dst|²`` (Kabsch, no scale)."""
    cs, cd = P_src.mean(axis=0), P_dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((P_dst - cd).T @ (P_src - cs))
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    R = U @ S @ Vt
    return geometry.make_transform(R, cd - R @ cs)


def marker_pose_stereo(rig: StereoRig, corners_left_px: ArrayLike, corners_right_px: ArrayLike,
                       side: float = MARKER_SIDE) -> NDArray[np.float64]:
    """Marker pose from both views: ``T_left_marker`` (4, 4), left-camera frame, metres.

    The corners are triangulated and a rigid transform of the model square fitted to them
    (Kabsch), then refined by minimising the reprojection error of the four corners in both
    images (Levenberg–Marquardt over the 6 pose parameters).

    Parameters
    ----------
    rig : StereoRig
        Only the intrinsics and the left→right transform are used, not the world frame.
    corners_left_px, corners_right_px : array_like, shape (4, 2)
        Raw pixels of the same marker, OpenCV corner order.
    side : float
        Marker side, metres.

    Raises
    ------
    ValueError
        For corners of the wrong shape or that do not triangulate in front of both cameras.
    """
    cl = _as_corners(corners_left_px, "corners_left_px")
    cr = _as_corners(corners_right_px, "corners_right_px")
    model = marker_model(side)
    P_left = geometry.transform_points(rig.T_left_world, rig.triangulate(cl, cr))
    if not np.all(np.isfinite(P_left)) or np.any(P_left[:, 2] <= 0):
        raise ValueError("marker corners do not triangulate in front of the cameras "
                         "(left and right detections disagree)")
    T0 = _rigid_fit(model, P_left)
    T_right_left = rig.T_right_left
    obs = np.concatenate([cl.ravel(), cr.ravel()])

    def project(x: NDArray[np.float64]) -> NDArray[np.float64]:
        T = geometry.make_transform(cv2.Rodrigues(x[:3])[0], x[3:])
        P_l = geometry.transform_points(T, model)
        P_r = geometry.transform_points(T_right_left, P_l)
        pl, _ = cv2.projectPoints(P_l.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), rig.K1, rig.D1)
        pr, _ = cv2.projectPoints(P_r.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), rig.K2, rig.D2)
        return np.concatenate([pl.ravel(), pr.ravel()]) - obs

    x0 = np.concatenate([cv2.Rodrigues(T0[:3, :3])[0].ravel(), T0[:3, 3]])
    sol = least_squares(project, x0, method="lm", x_scale=np.r_[[0.01] * 3, [0.001] * 3],
                        xtol=1e-12, ftol=1e-12)
    return geometry.make_transform(cv2.Rodrigues(sol.x[:3])[0], sol.x[3:])


def _as_corners(value: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(value, dtype=np.float64)
    if arr.size != 8:
        raise ValueError(f"{name}: expected shape (4, 2), got {arr.shape}")
    arr = arr.reshape(4, 2)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains NaN or infinity")
    return arr


def desk_plane_from_marker(T_world_marker: ArrayLike) -> NDArray[np.float64]:
    """The desk plane ``[nx, ny, nz, d]`` (world, ``n·X + d = 0``, n = marker z, up).

    Parameters
    ----------
    T_world_marker : array_like, shape (4, 4)
    """
    T = np.asarray(T_world_marker, dtype=np.float64)
    n = T[:3, 2] / np.linalg.norm(T[:3, 2])
    return np.append(n, -n @ T[:3, 3])


def workspace_polygon(rig: StereoRig, camera: Camera = "left", *,
                      T_world_marker: ArrayLike | None = None,
                      x: tuple[float, float] = WORKSPACE_X, y: tuple[float, float] = WORKSPACE_Y,
                      step: float = 0.01) -> NDArray[np.float64]:
    """The workspace rectangle of the marker frame projected into one raw image (the ROI).

    The rectangle is first clipped in 3D to the part in front of the camera and within its
    field of view (lens distortion is meaningless far outside it: the polynomial folds
    back); the remaining edges are sampled every ``step`` metres and projected with lens
    distortion, so the polygon follows the curved image of a straight desk edge; last, the
    polygon is clipped to the image.

    Parameters
    ----------
    rig : StereoRig
    camera : {"left", "right"}
    T_world_marker : array_like, shape (4, 4), optional
        The marker's pose in the rig's world; identity (world = marker frame) when omitted.
    x, y : (min, max), metres
        The rectangle in the marker frame.
    step : float
        Sampling step along the edges, metres.

    Returns
    -------
    ndarray, shape (N, 2), float64
        Raw pixel polygon; empty (0, 2) if the workspace is not in view.
    """
    T_wm = np.eye(4) if T_world_marker is None else np.asarray(T_world_marker, dtype=np.float64)
    (x0, x1), (y0, y1) = x, y
    rect = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    T_cam_marker = rig.T_camera_world(camera) @ T_wm
    poly = geometry.transform_points(T_cam_marker, rect)
    half_spaces = [np.array([0.0, 0.0, 1.0, -1e-3])]  # z >= 1 mm
    if rig.image_size is not None:
        w, h = rig.image_size
        border = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1],
                           [(w - 1) / 2, 0], [w - 1, (h - 1) / 2], [(w - 1) / 2, h - 1],
                           [0, (h - 1) / 2]], dtype=np.float64)
        tan = np.abs(rig.undistort_points(border, camera, normalized=True)).max(axis=0) * 1.05
        half_spaces += [np.array([-1.0, 0.0, tan[0], 0.0]), np.array([1.0, 0.0, tan[0], 0.0]),
                        np.array([0.0, -1.0, tan[1], 0.0]), np.array([0.0, 1.0, tan[1], 0.0])]
    for hs in half_spaces:
        poly = _clip_half_space(poly, hs)
        if len(poly) < 3:
            return np.zeros((0, 2))
    pts = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + np.linspace(0.0, 1.0, n + 1)[:-1, None] * (b - a))
    P_cam = np.vstack(pts)
    K, D = rig.intrinsics(camera)
    px, _ = cv2.projectPoints(P_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    px = px.reshape(-1, 2)
    if rig.image_size is None:
        return px
    return _clip_polygon(px, rig.image_size)


def _clip_half_space(poly: NDArray[np.float64], hs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sutherland–Hodgman clip of a 3D polygon (N, 3) to ``hs[:3]·P + hs[3] >= 0``."""
    f = poly @ hs[:3] + hs[3]
    out = []
    for i in range(len(poly)):
        p, q, fp, fq = poly[i - 1], poly[i], f[i - 1], f[i]
        if (fp >= 0) != (fq >= 0):
            out.append(p + fp / (fp - fq) * (q - p))
        if fq >= 0:
            out.append(q)
    return np.asarray(out, dtype=np.float64).reshape(-1, 3)


def _clip_polygon(poly: NDArray[np.float64], size: tuple[int, int]) -> NDArray[np.float64]:
    """Sutherland–Hodgman clip of a polygon (N, 2) to the image ``[0, w-1] × [0, h-1]``."""
    w, h = size
    edges = ((0, 0.0, 1.0), (0, w - 1.0, -1.0), (1, 0.0, 1.0), (1, h - 1.0, -1.0))
    out = poly.tolist()  # plain floats: this loop runs over every sampled point
    for axis, bound, sign in edges:
        if not out:
            break
        res = []
        p = out[-1]
        pin = sign * (p[axis] - bound) >= 0
        for q in out:
            qin = sign * (q[axis] - bound) >= 0
            if qin != pin:
                t = (bound - p[axis]) / (q[axis] - p[axis])
                res.append([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])])
            if qin:
                res.append(q)
            p, pin = q, qin
        out = res
    out = np.asarray(out, dtype=np.float64).reshape(-1, 2)
    return out
