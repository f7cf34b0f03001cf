"""Geometry of the paper's §4: triangulation (eq. 3–5), book pose from four corners (eq. 6–7).

Conventions (DESIGN §2): transforms are 4×4 ``T_a_b`` mapping frame-``b`` coordinates into
frame ``a``; points are rows, ``(N, 3)``; metres and radians inside, degrees at the output.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

TriangulationMethod = Literal["dlt", "optimal"]

# Below this sin(Θ) the ZXZ angles of eq. 7 are 0/0 (book lying flat): Φ := 0, Ψ := heading.
_GIMBAL_EPS = 1e-7


# --------------------------------------------------------------------------- transforms


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """3×3 cross-product matrix: ``skew(a) @ b == np.cross(a, b)``."""
    x, y, z = np.asarray(v, dtype=np.float64).ravel()
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def make_transform(R: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """4×4 rigid transform from a rotation ``R`` (3, 3) and a translation ``t`` (3,)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=np.float64).ravel()
    return T


def invert_transform(T: ArrayLike) -> NDArray[np.float64]:
    """Inverse of a 4×4 rigid transform (``T_b_a`` from ``T_a_b``)."""
    T = np.asarray(T, dtype=np.float64)
    R, t = T[:3, :3], T[:3, 3]
    return make_transform(R.T, -R.T @ t)


def transform_points(T_a_b: ArrayLike, P_b: ArrayLike) -> NDArray[np.float64]:
    """Map points ``P_b`` (N, 3) from frame ``b`` into frame ``a``; returns (N, 3)."""
    T = np.asarray(T_a_b, dtype=np.float64)
    P = np.asarray(P_b, dtype=np.float64).reshape(-1, 3)
    return P @ T[:3, :3].T + T[:3, 3]


def nearest_rotation(M: ArrayLike) -> NDArray[np.float64]:
    """The proper rotation (det +1) closest to ``M`` (3, 3) in Frobenius norm (polar factor)."""
    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=np.float64))
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ S @ Vt


def decompose_projection(Q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Split a 3×4 projection ``Q = s·K [R | t]`` into ``K`` (3, 3) and ``T_cam_world`` (4, 4).

    ``K`` is normalised to ``K[2, 2] = 1`` with positive focal lengths (RQ decomposition).
    """
    Q = np.asarray(Q, dtype=np.float64)
    # RQ of the left block via QR of its row-reversed transpose.
    flip = np.eye(3)[::-1]
    q, r = np.linalg.qr((flip @ Q[:, :3]).T)
    K = flip @ r.T @ flip
    R = flip @ q.T
    signs = np.diag(np.sign(np.diag(K)))  # make K's diagonal positive
    K, R = K @ signs, signs @ R
    t = np.linalg.solve(K, Q[:, 3])
    if np.linalg.det(R) < 0:  # Q was given up to a negative scale
        R, t = -R, -t
    return K / K[2, 2], make_transform(R, t)


def project(Q: ArrayLike, P: ArrayLike) -> NDArray[np.float64]:
    """Pixels (N, 2) of world points ``P`` (N, 3) under a 3×4 projection ``Q`` (eq. 3)."""
    Q = np.asarray(Q, dtype=np.float64)
    h = np.asarray(P, dtype=np.float64).reshape(-1, 3) @ Q[:, :3].T + Q[:, 3]
    return h[:, :2] / h[:, 2:]


def fundamental_from_projections(Q_L: ArrayLike, Q_R: ArrayLike) -> NDArray[np.float64]:
    """Fundamental matrix ``F`` (3, 3) with ``p_R^T F p_L = 0`` (Hartley & Zisserman eq. 9.1)."""
    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    C = np.linalg.svd(Q_L)[2][-1]  # left camera centre, homogeneous: Q_L @ C = 0
    F = skew(Q_R @ C) @ Q_R @ np.linalg.pinv(Q_L)
    return F / np.linalg.norm(F)


# --------------------------------------------------------------------------- triangulation


def triangulate(Q_L: ArrayLike, Q_R: ArrayLike, p_L: ArrayLike, p_R: ArrayLike, *,
                method: TriangulationMethod = "dlt") -> NDArray[np.float64]:
    """Triangulate corresponding ideal (undistorted) image points (eq. 3–5).

    Parameters
    ----------
    Q_L, Q_R : array_like, shape (3, 4)
        World → image projection matrices (eq. 3), in the units of ``p_L``/``p_R``.
    p_L, p_R : array_like, shape (N, 2)
        Corresponding points, pixels (or normalised coordinates with ``Q = [R | t]``).
    method : {"dlt", "optimal"}
        ``"dlt"``: the linear least-squares solution of eq. 5.
        ``"optimal"``: first move the points the least distance onto each other's epipolar
        lines (Lindstrom 2010, niter2), then DLT — the maximum-likelihood point under
        Gaussian pixel noise.

    Returns
    -------
    P : ndarray, shape (N, 3), float64
        World points.
    """
    if method == "dlt":
        return triangulate_dlt(Q_L, Q_R, p_L, p_R)
    if method == "optimal":
        p_L, p_R = correct_matches(fundamental_from_projections(Q_L, Q_R), p_L, p_R)
        return triangulate_dlt(Q_L, Q_R, p_L, p_R)
    raise ValueError(f"method: expected 'dlt' or 'optimal', got {method!r}")


def triangulate_dlt(Q_L: ArrayLike, Q_R: ArrayLike, p_L: ArrayLike,
                    p_R: ArrayLike) -> NDArray[np.float64]:
    """Linear triangulation of eq. 4–5, vectorised over N points.

    Eq. 4 (``p × Q·P = 0``) gives two independent rows per camera, so ``A P = 0`` has four
    rows; with ``P = (x, y, z, 1)`` (the paper's "not at infinity") it becomes
    ``M X = -b``, solved in the least-squares sense. The paper solves that by SVD; the
    minimiser is unique, so here it comes from the 3×3 normal equations in closed form,
    which is the same point (checked against ``np.linalg.lstsq`` in the tests) and runs
    at millions of points per second on one core; batched SVD and ``cv2.triangulatePoints``
    manage ~0.2 M.

    Parameters
    ----------
    Q_L, Q_R : array_like, shape (3, 4)
    p_L, p_R : array_like, shape (N, 2)

    Returns
    -------
    ndarray, shape (N, 3), float64
        NaN for a point whose rays are parallel (no unique solution).
    """
    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    p_L = np.asarray(p_L, dtype=np.float64).reshape(-1, 2)
    p_R = np.asarray(p_R, dtype=np.float64).reshape(-1, 2)
    if p_L.shape != p_R.shape:
        raise ValueError(f"p_R: expected shape {p_L.shape} like p_L, got {p_R.shape}")
    # A[k, i, n]: row k of eq. 4 for point n, rows u·q3 − q1 and v·q3 − q2 per camera.
    # Stored row-major over points so every step below is a contiguous vector operation.
    A = np.empty((4, 4, len(p_L)))
    for k, (Q, p, j) in enumerate(((Q_L, p_L, 0), (Q_L, p_L, 1), (Q_R, p_R, 0), (Q_R, p_R, 1))):
        np.multiply.outer(Q[2], p[:, j], out=A[k])
        A[k] -= Q[j][:, None]

    # G[i, j]: column i · column j per point (i < 3), the rows' products summed in order,
    # k = 0..3, as np.einsum("kn,kn->n") sums them (the same values), in five array
    # operations instead of nine calls
    prod = A[:, :3, None] * A[:, None]  # (4, 3, 4, N)
    G = prod[0] + prod[1]
    G += prod[2]
    G += prod[3]
    # Normal equations (M^T M) X = -M^T b, M = A[:, :3], b = A[:, 3]; solved by the adjugate.
    a, b, c, d, e, f = G[0, 0], G[0, 1], G[0, 2], G[1, 1], G[1, 2], G[2, 2]
    r0, r1, r2 = -G[0, 3], -G[1, 3], -G[2, 3]
    A00, A01, A02 = d * f - e * e, c * e - b * f, b * e - c * d
    A11, A12, A22 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * A00 + b * A01 + c * A02
    scale = (a + d + f) ** 3  # det is of this order when the rays are not parallel
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(np.abs(det) > 1e-12 * scale, 1.0 / det, np.nan)
    return np.column_stack([(A00 * r0 + A01 * r1 + A02 * r2) * inv_det,
                            (A01 * r0 + A11 * r1 + A12 * r2) * inv_det,
                            (A02 * r0 + A12 * r1 + A22 * r2) * inv_det])


def correct_matches(F: ArrayLike, p_L: ArrayLike,
                    p_R: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Move corresponding points the least total distance so ``p_R^T F p_L = 0``.

    Lindstrom, "Triangulation made easy" (CVPR 2010), algorithm niter2: two non-iterative
    steps, vectorised over N. Equivalent to Hartley–Sturm's optimal correction to well
    below 1e-6 px for realistic noise.

    Parameters
    ----------
    F : array_like, shape (3, 3)
    p_L, p_R : array_like, shape (N, 2)

    Returns
    -------
    p_L_hat, p_R_hat : ndarray, shape (N, 2), float64
    """
    F = np.asarray(F, dtype=np.float64)
    p_L = np.asarray(p_L, dtype=np.float64).reshape(-1, 2)
    p_R = np.asarray(p_R, dtype=np.float64).reshape(-1, 2)
    xl = np.column_stack([p_L, np.ones(len(p_L))])  # Lindstrom's x'
    xr = np.column_stack([p_R, np.ones(len(p_R))])  # Lindstrom's x;  x^T F x' = 0
    Ft = F[:2, :2]
    n = (xl @ F.T)[:, :2]   # S F x'
    n_ = (xr @ F)[:, :2]    # S F^T x
    a = np.einsum("ni,ij,nj->n", n, Ft, n_)
    b = 0.5 * (np.einsum("ni,ni->n", n, n) + np.einsum("ni,ni->n", n_, n_))
    c = np.einsum("ni,ij,nj->n", xr, F, xl)
    d = np.sqrt(np.maximum(b * b - a * c, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(b + d > 0, c / (b + d), 0.0)
        dx, dx_ = lam[:, None] * n, lam[:, None] * n_
        n = n - dx_ @ Ft.T
        n_ = n_ - dx @ Ft
        denom = np.einsum("ni,ni->n", n, n) + np.einsum("ni,ni->n", n_, n_)
        lam = np.where(denom > 0, lam * 2.0 * d / denom, 0.0)
    return p_L - lam[:, None] * n_, p_R - lam[:, None] * n


# --------------------------------------------------------------------------- planes


def fit_plane(points: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray[np.float64]:
    """Least-squares plane through ``points`` (N ≥ 3, 3) as ``[nx, ny, nz, d]``.

    ``n·X + d = 0`` with ``|n| = 1`` and ``n`` on the side of ``up``.
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(P) < 3:
        raise ValueError(f"points: a plane needs at least 3 points, got {len(P)}")
    c = P.mean(axis=0)
    _, s, Vt = np.linalg.svd(P - c)
    if s[1] < 1e-9 * max(s[0], 1e-300):
        raise ValueError("points: collinear, no unique plane")
    n = Vt[2] if np.dot(Vt[2], up) >= 0 else -Vt[2]
    return np.append(n, -n @ c)


def plane_distance(plane: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """Signed distance (N,) of ``points`` (N, 3) above ``plane`` ``[n, d]``, metres."""
    plane = np.asarray(plane, dtype=np.float64)
    return np.asarray(points, dtype=np.float64).reshape(-1, 3) @ plane[:3] + plane[3]


# --------------------------------------------------------------------------- orientation


def euler_zxz_deg(R: ArrayLike) -> tuple[float, float, float]:
    """The paper's ZXZ Euler angles (eq. 7), degrees: ``(phi, theta, psi)``.

    ``R = Rz(psi) · Rx(theta) · Rz(phi)`` (intrinsic Z-X'-Z'', i.e. SciPy's
    ``Rotation.from_euler("ZXZ", [psi, theta, phi], degrees=True)``), so eq. 7's
    ``Φ = atan(w31/w32)``, ``Θ = acos(w33)``, ``Ψ = −atan(w13/w23)`` hold with quadrant-correct
    ``atan2``. ``phi, psi`` in [0, 360), ``theta`` in [0, 180].

    At ``Θ ≈ 0`` (and 180°) both ratios of eq. 7 are 0/0 — the normal case of a book lying
    flat. There only ``phi + psi`` is defined; rovis returns ``phi = 0`` and gives the whole
    heading to ``psi``, the angle the manipulator uses (paper §4.B).
    """
    R = np.asarray(R, dtype=np.float64)
    theta = float(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))
    if np.hypot(R[2, 0], R[2, 1]) < _GIMBAL_EPS or np.hypot(R[0, 2], R[1, 2]) < _GIMBAL_EPS:
        phi = 0.0
        # Rz(psi)·Rx(0 or π): first column is (cos psi, sin psi, 0) either way.
        psi = float(np.arctan2(R[1, 0], R[0, 0]))
    else:
        phi = float(np.arctan2(R[2, 0], R[2, 1]))
        psi = float(np.arctan2(R[0, 2], -R[1, 2]))
    return (float(np.degrees(phi) % 360.0), float(np.degrees(theta)), float(np.degrees(psi) % 360.0))


def yaw_deg(R: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> float:
    """Heading of the book's x axis projected on the plane normal to ``up``, degrees [0, 360).

    Measured from the world x axis projected on that plane, counter-clockwise seen from
    ``up``; with ``up = z`` this is ``atan2(x_y, x_x)``.
    """
    R = np.asarray(R, dtype=np.float64)
    n = np.asarray(up, dtype=np.float64)
    n = n / np.linalg.norm(n)
    e1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(e1) < 1e-6:  # world x is vertical: measure from world y instead
        e1 = np.array([0.0, 1.0, 0.0]) - n[1] * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    x = R[:, 0]
    return float(np.degrees(np.arctan2(x @ e2, x @ e1)) % 360.0)


def quaternion_xyzw(R: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion ``[x, y, z, w]`` (ROS/SciPy order) with ``w >= 0``."""
    q = Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_quat()
    return -q if q[3] < 0 else q


# --------------------------------------------------------------------------- book pose


@dataclass(frozen=True, eq=False)
class BookPose:
    """A book's pose and cuboid (paper §4.B, DESIGN §2).

    Attributes
    ----------
    center : ndarray, shape (3,)
        ``O``, the intersection of the cover's diagonals, world frame, metres.
    R : ndarray, shape (3, 3)
        Columns are the book's x, y, z axes in the world (eq. 6); a proper rotation.
    size : ndarray, shape (3,)
        Extent along the book's x, y and z axes, metres; ``size[2]`` (the height above the
        desk) is NaN when the desk plane is unknown.
    up : ndarray, shape (3,)
        The desk normal (or world z) used for ``yaw_deg``.
    """

    center: NDArray[np.float64]
    R: NDArray[np.float64]
    size: NDArray[np.float64]
    up: NDArray[np.float64]

    @property
    def T_world_book(self) -> NDArray[np.float64]:
        """4×4 pose of the book frame in the world."""
        return make_transform(self.R, self.center)

    @property
    def quaternion_xyzw(self) -> NDArray[np.float64]:
        return quaternion_xyzw(self.R)

    @property
    def euler_zxz_deg(self) -> tuple[float, float, float]:
        """``(phi, theta, psi)`` of eq. 7, degrees."""
        return euler_zxz_deg(self.R)

    @property
    def yaw_deg(self) -> float:
        return yaw_deg(self.R, self.up)

    @property
    def corners(self) -> NDArray[np.float64]:
        """The cover corners P1..P4 (4, 3) of the fitted rectangle, world frame."""
        return corners_from_pose(self.center, self.R, self.size[:2])

    def cuboid_corners(self) -> NDArray[np.float64]:
        """The cuboid's 8 vertices (8, 3): cover P1..P4, then the same down by the height."""
        top = self.corners
        h = 0.0 if np.isnan(self.size[2]) else self.size[2]
        return np.vstack([top, top - h * self.R[:, 2]])


def corners_from_pose(center: ArrayLike, R: ArrayLike, size_xy: ArrayLike) -> NDArray[np.float64]:
    """Cover corners P1..P4 (4, 3) of a rectangle: the inverse of :func:`pose_from_corners`.

    With x ∥ P3→P2 and y ∥ P3→P4 (eq. 6): P3 = O − (sx·x + sy·y)/2, P2 = P3 + sx·x,
    P4 = P3 + sy·y, P1 = P3 + sx·x + sy·y.
    """
    O = np.asarray(center, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    hx, hy = 0.5 * np.asarray(size_xy, dtype=np.float64)[:2]
    x, y = hx * R[:, 0], hy * R[:, 1]
    return np.array([O + x + y, O + x - y, O - x - y, O - x + y])


def pose_from_corners(corners: ArrayLike, desk_plane: ArrayLike | None = None, *,
                      up: ArrayLike = (0.0, 0.0, 1.0)) -> BookPose:
    """Book pose and cuboid from its four 3D cover corners (paper §4.B, eq. 6).

    Parameters
    ----------
    corners : array_like, shape (4, 3)
        P1..P4, world frame, metres, top-left first and clockwise as seen in the image.
    desk_plane : array_like, shape (4,), optional
        ``[nx, ny, nz, d]`` with n up; gives the height (``size[2]``) and the yaw reference.
    up : array_like, shape (3,)
        Used for the yaw when no desk plane is given.

    Returns
    -------
    BookPose
        ``O`` = the point nearest both diagonals P1P3 and P2P4; x ∥ P3→P2, y ∥ P3→P4,
        z = x × y. From noisy corners each axis averages its two parallel sides and the
        frame is the nearest proper rotation, never skewed.

    Raises
    ------
    ValueError
        If the corners are not finite or span no quadrilateral.
    """
    P = np.asarray(corners, dtype=np.float64)
    if P.shape != (4, 3):
        raise ValueError(f"corners: expected shape (4, 3), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError("corners: contains NaN or infinity")
    P1, P2, P3, P4 = P
    x_dir = (P2 - P3) + (P1 - P4)
    y_dir = (P4 - P3) + (P1 - P2)
    z_dir = np.cross(x_dir, y_dir)
    sx = 0.5 * (np.linalg.norm(P2 - P3) + np.linalg.norm(P1 - P4))
    sy = 0.5 * (np.linalg.norm(P4 - P3) + np.linalg.norm(P1 - P2))
    if min(sx, sy) <= 0 or np.linalg.norm(z_dir) <= 1e-6 * sx * sy:
        raise ValueError("corners: degenerate quadrilateral (repeated or collinear corners)")
    axes = np.column_stack([x_dir / np.linalg.norm(x_dir), y_dir / np.linalg.norm(y_dir),
                            z_dir / np.linalg.norm(z_dir)])
    R = nearest_rotation(axes)
    O = _diagonal_intersection(P1, P3, P2, P4)
    if desk_plane is None:
        height, n = np.nan, np.asarray(up, dtype=np.float64)
    else:
        plane = np.asarray(desk_plane, dtype=np.float64)
        height, n = float(plane_distance(plane, O)[0]), plane[:3]
    return BookPose(center=O, R=R, size=np.array([sx, sy, height]), up=n / np.linalg.norm(n))


def _diagonal_intersection(A: NDArray[np.float64], B: NDArray[np.float64],
                           C: NDArray[np.float64], D: NDArray[np.float64]) -> NDArray[np.float64]:
    """Midpoint of the shortest segment between lines AB and CD (they rarely meet in 3D)."""
    u, v, w = B - A, D - C, A - C
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    if den <= 1e-12 * a * c:
        raise ValueError("corners: the diagonals are parallel")
    s, t = (b * e - c * d) / den, (a * e - b * d) / den
    return 0.5 * ((A + s * u) + (C + t * v))


def look_at(eye: ArrayLike, target: ArrayLike,
            up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray[np.float64]:
    """``T_world_cam`` (4, 4) of an OpenCV camera (x right, y down, z forward) at ``eye``
    looking at ``target``, with image-up as close to ``up`` as possible (world, metres)."""
    eye, target = np.asarray(eye, dtype=np.float64), np.asarray(target, dtype=np.float64)
    z = target - eye
    if np.linalg.norm(z) == 0:
        raise ValueError("look_at: eye and target coincide")
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("look_at: viewing direction is parallel to up")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return make_transform(np.column_stack([x, y, z]), eye)


def fit_rectangle(Q_L: ArrayLike, Q_R: ArrayLike, px_left: ArrayLike, px_right: ArrayLike,
                  corners: ArrayLike, desk_plane: ArrayLike | None = None) -> NDArray[np.float64]:
    """One 3D rectangle fitted to a cover's corners in both images (beyond the paper).

    Triangulating each corner alone (eq. 3–5) leaves four points that are neither coplanar
    nor a rectangle. Here the cover is a rectangle — pose (rotation vector, centre) and
    length, width: 8 parameters — whose projected corners best fit the 16 measured corner
    coordinates of both images (Levenberg–Marquardt, scipy.optimize.least_squares), started
    from the corners' own pose (:func:`pose_from_corners`). With ``desk_plane``, the
    rectangle lies parallel to the desk: its heading about the desk's normal, centre and
    length, width (6 parameters).

    Parameters
    ----------
    Q_L, Q_R : array_like, shape (3, 4)
        World → pixel projections of the images the corners were measured in.
    px_left, px_right : array_like, shape (4, 2)
        Corresponding corners, pixels.
    corners : array_like, shape (4, 3)
        Their triangulation (world, metres): the starting point.
    desk_plane : array_like, shape (4,), optional
        ``[nx, ny, nz, d]`` (world, normal up).

    Returns
    -------
    ndarray, shape (4, 3)
        The rectangle's corners, in the order of ``corners``.
    """
    from scipy.optimize import least_squares

    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    pl = np.asarray(px_left, dtype=np.float64).reshape(4, 2)
    pr = np.asarray(px_right, dtype=np.float64).reshape(4, 2)
    P0 = np.asarray(corners, dtype=np.float64).reshape(4, 3)
    pose = pose_from_corners(P0)
    # which quadrant of the book frame each corner lies in (x, y signs)
    signs = np.sign((P0 - pose.center) @ pose.R[:, :2])
    signs[signs == 0] = 1.0

    if desk_plane is None:
        def rectangle(x: NDArray[np.float64]) -> NDArray[np.float64]:
            R = Rotation.from_rotvec(x[:3]).as_matrix()
            local = np.column_stack([0.5 * x[6] * signs[:, 0], 0.5 * x[7] * signs[:, 1],
                                     np.zeros(4)])
            return x[3:6] + local @ R.T

        x0 = np.concatenate([Rotation.from_matrix(pose.R).as_rotvec(), pose.center,
                             pose.size[:2]])
        scale = np.r_[[0.01] * 3, [0.001] * 3, [0.001] * 2]
        jac: Any = "2-point"
    else:
        rectangle, jac_P, x0 = _flat_rectangle(P0, desk_plane)
        scale = np.r_[0.01, [0.001] * 3, [0.001] * 2]

        def jacobian(x: NDArray[np.float64]) -> NDArray[np.float64]:
            # analytic: the fit runs once per book and frame in tracking, where the
            # 2-point differences' six extra evaluations per step cost most of its time
            return _projection_jacobian(rectangle(x), jac_P(x), Q_L, Q_R)

        jac = jacobian

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        P = rectangle(x)
        return np.concatenate([(project(Q_L, P) - pl).ravel(), (project(Q_R, P) - pr).ravel()])

    sol = least_squares(residuals, x0, jac=jac, method="lm", x_scale=scale)
    return rectangle(sol.x)


def _flat_rectangle(P0: NDArray[np.float64], desk_plane: ArrayLike) -> tuple[
        Any, Any, NDArray[np.float64]]:
    """A rectangle parallel to the desk, parametrised for a fit started at corners ``P0``
    (4, 3): ``x`` = heading about the desk's normal (rad), centre (3, metres), length,
    width (metres). Returns ``rectangle(x)`` (its corners (4, 3), in ``P0``'s order),
    ``jac(x)`` (d corners / d x, (4, 3, 6)) and the start ``x0`` (6,)."""
    pose = pose_from_corners(P0)
    n = np.asarray(desk_plane, dtype=np.float64)[:3]
    n = n / np.linalg.norm(n)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    x_axis = pose.R[:, 0] - (pose.R[:, 0] @ n) * n  # the heading, on the desk
    x_axis /= np.linalg.norm(x_axis)
    # the corners' quadrants in the frame the fit turns (y = up × x, whichever way
    # round the corners go)
    signs = np.sign((P0 - pose.center) @ np.column_stack([x_axis, np.cross(n, x_axis)]))
    signs[signs == 0] = 1.0

    # the heading's axes: xd = cos·e1 + sin·e2, and yd = n × xd = cos·e2 − sin·e1
    # (e1, e2, n right-handed; np.cross costs more than the rest of the fit)
    def rectangle(x: NDArray[np.float64]) -> NDArray[np.float64]:
        c, s = np.cos(x[0]), np.sin(x[0])
        xd, yd = c * e1 + s * e2, c * e2 - s * e1
        return x[1:4] + 0.5 * x[4] * signs[:, :1] * xd + 0.5 * x[5] * signs[:, 1:] * yd

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        c, s = np.cos(x[0]), np.sin(x[0])
        xd, yd = c * e1 + s * e2, c * e2 - s * e1
        dP = np.empty((4, 3, 6))  # d corner / d (heading, centre, length, width)
        dP[:, :, 0] = 0.5 * x[4] * signs[:, :1] * yd - 0.5 * x[5] * signs[:, 1:] * xd
        dP[:, :, 1:4] = np.eye(3)
        dP[:, :, 4] = 0.5 * signs[:, :1] * xd
        dP[:, :, 5] = 0.5 * signs[:, 1:] * yd
        return dP

    x0 = np.concatenate([[np.arctan2(x_axis @ e2, x_axis @ e1)], pose.center, pose.size[:2]])
    return rectangle, jac, x0


def fit_rectangle_sides(Q_L: ArrayLike, Q_R: ArrayLike, px_left: ArrayLike,
                        px_right: ArrayLike, corners: ArrayLike, desk_plane: ArrayLike, *,
                        use: ArrayLike | None = None,
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One rectangle parallel to the desk fitted to a cover's sides in both images, not its
    corners (beyond the paper).

    A side one image saw on its page block's foot, or on the soft edge of the cover's
    shadow, moves both of that image's corners on it, and the two corners of the sides
    next to it along them: :func:`fit_rectangle` spreads that error over every corner.
    Here each image's side is a line (through its two measured corners), and the residuals
    are the distances of the rectangle's projected corners to the lines of the sides they
    end (2 per side, 16 in all), so a side can be left out (``use``) without losing the
    others.

    Parameters
    ----------
    Q_L, Q_R : array_like, shape (3, 4)
        World → pixel projections.
    px_left, px_right : array_like, shape (4, 2)
        Corresponding corners, pixels; side s runs from corner s to s + 1.
    corners : array_like, shape (4, 3)
        Their triangulation (world, metres): the starting point.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]`` (world, normal up).
    use : array_like of bool, shape (2, 4), optional
        Which sides (left image, right image) the fit uses; all by default. Both images'
        sides must be among them, three or more in all (one image's sides alone give no
        depth).

    Returns
    -------
    corners : ndarray, shape (4, 3)
        The rectangle's corners (world, metres), in the order of ``corners``.
    off : ndarray, shape (2, 4)
        Per image and side, the larger distance (pixels) of the side's two projected
        corners from its measured line, signed: positive where the measured line lies
        outside the fitted quad.
    """
    from scipy.optimize import least_squares

    Q_L, Q_R = np.asarray(Q_L, dtype=np.float64), np.asarray(Q_R, dtype=np.float64)
    px = np.stack([np.asarray(px_left, dtype=np.float64).reshape(4, 2),
                   np.asarray(px_right, dtype=np.float64).reshape(4, 2)])  # (2, 4, 2)
    rectangle, jac_P, x0 = _flat_rectangle(np.asarray(corners, dtype=np.float64).reshape(4, 3),
                                           desk_plane)
    used = np.ones((2, 4), bool) if use is None else np.asarray(use, bool)
    if used.shape != (2, 4) or not used.any(axis=1).all() or used.sum() < 3:
        raise ValueError("fit_rectangle_sides: use must be (2, 4), with sides of both images, "
                         "three or more")
    d = np.roll(px, -1, axis=1) - px
    length = np.linalg.norm(d, axis=-1)
    if not np.all(length > 1e-9):
        raise ValueError("fit_rectangle_sides: a side of zero length")
    # each side's normal pointing out of its quad: (dy, -dx) is outward for a quad whose
    # corners run clockwise in the image (y down), the shoelace area's sign says which way
    # they run
    area = np.sum(px[..., 0] * np.roll(px[..., 1], -1, axis=1)
                  - np.roll(px[..., 0], -1, axis=1) * px[..., 1], axis=1)  # (2,), twice
    normal = np.stack([d[..., 1], -d[..., 0]], axis=-1) / length[..., None]
    normal *= np.where(area < 0, -1.0, 1.0)[:, None, None]
    ends = np.array([[s, (s + 1) % 4] for s in range(4)])  # (side, end) -> corner
    mask = used.repeat(2).ravel()

    def distances(x: NDArray[np.float64]) -> NDArray[np.float64]:
        P = rectangle(x)
        uv = np.stack([project(Q_L, P), project(Q_R, P)])[:, ends]  # (2, 4, 2 ends, 2)
        # > 0 where the projected corner lies outside the measured side's line
        return np.einsum("csek,csk->cse", uv - px[:, :, None], normal)  # (2, 4, 2)

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return distances(x).ravel()[mask]

    def jacobian(x: NDArray[np.float64]) -> NDArray[np.float64]:
        J = _projection_jacobian(rectangle(x), jac_P(x), Q_L, Q_R).reshape(2, 4, 2, 6)
        return np.einsum("csekp,csk->csep", J[:, ends], normal).reshape(16, 6)[mask]

    scale = np.r_[0.01, [0.001] * 3, [0.001] * 2]
    sol = least_squares(residuals, x0, jac=jacobian, method="lm", x_scale=scale)
    dist = distances(sol.x)
    # the measured line outside the fit: the projected corners inside it (negative)
    off = -np.where(np.abs(dist[..., 0]) >= np.abs(dist[..., 1]), dist[..., 0], dist[..., 1])
    return rectangle(sol.x), off


def _projection_jacobian(P: NDArray[np.float64], dP: NDArray[np.float64], Q_L: NDArray[np.float64],
                         Q_R: NDArray[np.float64]) -> NDArray[np.float64]:
    """d (both images' pixels of points ``P`` (N, 3), as :func:`fit_rectangle`'s residuals
    order them) / d parameters, from ``dP`` (N, 3, K) = d P / d parameters: (4N, K)."""
    rows = []
    for Q in (Q_L, Q_R):
        h = P @ Q[:, :3].T + Q[:, 3]  # (N, 3) homogeneous pixels
        uv = h[:, :2] / h[:, 2:]
        # d (u, v) / d P = (Q[:2, :3] - (u, v) Q[2, :3]) / w, per point: (N, 2, 3)
        d_uv = (Q[None, :2, :3] - uv[:, :, None] * Q[None, 2:3, :3]) / h[:, 2, None, None]
        rows.append(np.einsum("nij,njk->nik", d_uv, dP).reshape(-1, dP.shape[2]))
    return np.concatenate(rows)
