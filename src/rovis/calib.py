"""Stereo rig model and calibration files.

A :class:`StereoRig` holds what the paper's projection matrices Q_L, Q_R (eq. 3) are made
of: intrinsics and plumb-bob distortion per camera, the right-from-left transform and the pose
of the left camera in the world. Readers recognise a file's format from its content:

- the canonical OpenCV FileStorage YAML (``K1 D1 K2 D2 R T [T_world_left]``, DESIGN §3);
- a pair of ROS ``camera_info`` YAML files (left, right);
- a Kalibr camchain YAML (``cam0``, ``cam1`` with ``T_cn_cnm1``);
- BoofCV's ``stereo.yaml`` (``left``, ``right``, ``rightToLeft`` in millimetres);
- the paper's form, 3×4 world→pixel projection matrices ``Q_L``, ``Q_R``.

Every reader ends in :meth:`StereoRig.from_arrays`, which validates once and names the key
that is wrong.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from rovis import geometry
from rovis.io import publish

Camera = Literal["left", "right"]
WorldFrame = Literal["calibration", "marker", "left_camera"]

_DIST_LENGTHS = (4, 5, 8, 12, 14)  # the plumb-bob family OpenCV accepts
_ROT_TOL = 1e-3  # files print R to ~6 digits; beyond this it is not a rotation


# --------------------------------------------------------------------------- validation


def _as_matrix(value: Any, key: str, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """Convert ``value`` to a finite float64 array of ``shape`` or raise naming ``key``."""
    if value is None:
        raise ValueError(f"{key}: missing (expected a {'x'.join(map(str, shape))} matrix)")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: expected numbers, got {value!r:.60}") from None
    if arr.size == int(np.prod(shape)) and arr.ndim <= 2 and (arr.ndim < 2 or 1 in arr.shape
                                                           or arr.shape == shape):
        arr = arr.reshape(shape)  # accept 3x1, 1x3 and flat for vectors
    if arr.shape != shape:
        raise ValueError(f"{key}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{key}: contains NaN or infinity")
    return arr


def _as_intrinsics(value: Any, key: str) -> NDArray[np.float64]:
    K = _as_matrix(value, key, (3, 3))
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"{key}: focal lengths must be positive, got fx={K[0, 0]:g}, fy={K[1, 1]:g}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0], atol=1e-9) or K[1, 0] != 0:
        raise ValueError(f"{key}: expected an upper-triangular camera matrix with last row [0 0 1]")
    return K


def _as_distortion(value: Any, key: str) -> NDArray[np.float64]:
    if value is None:
        raise ValueError(f"{key}: missing (expected 1x5 plumb-bob coefficients k1 k2 p1 p2 k3)")
    arr = np.asarray(value, dtype=np.float64).ravel() if _is_numeric(value) else None
    if arr is None or arr.size not in _DIST_LENGTHS:
        got = "non-numbers" if arr is None else f"{arr.size} values"
        raise ValueError(f"{key}: expected 1x5 distortion coefficients (k1 k2 p1 p2 k3), got {got}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{key}: contains NaN or infinity")
    return arr


def _is_numeric(value: Any) -> bool:
    try:
        np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return True


def _as_rotation(value: Any, key: str) -> NDArray[np.float64]:
    R = _as_matrix(value, key, (3, 3))
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > _ROT_TOL or np.linalg.det(R) <= 0:
        raise ValueError(
            f"{key}: expected a rotation matrix (R^T R = I, det +1), "
            f"got |R^T R - I| = {err:.2g}, det = {np.linalg.det(R):.4g}")
    return geometry.nearest_rotation(R)  # remove the rounding of a printed file


def as_transform(value: Any, key: str) -> NDArray[np.float64]:
    T = _as_matrix(value, key, (4, 4))
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ValueError(f"{key}: expected a 4x4 rigid transform with last row [0 0 0 1]")
    out = T.copy()
    out[:3, :3] = _as_rotation(T[:3, :3], f"{key} (rotation part)")
    return out


def _as_size(width: Any, height: Any) -> tuple[int, int]:
    for key, v in (("image_width", width), ("image_height", height)):
        if v is None:
            raise ValueError(f"{key}: missing (expected a positive integer, pixels)")
        if not _is_numeric(v) or np.ndim(v) != 0 or float(v) != int(float(v)) or int(float(v)) <= 0:
            raise ValueError(f"{key}: expected a positive integer, got {v!r}")
    return int(float(width)), int(float(height))


def undistort_iter(pts: NDArray[np.float64], K: NDArray[np.float64], D: NDArray[np.float64],
                   P: NDArray[np.float64] | None, criteria: tuple[int, int, float]
                   ) -> NDArray[np.float64]:
    """``cv2.undistortPoints`` run to ``criteria``: (N, 1, 2) raw pixels → (N, 1, 2) ideal
    pixels (``P=K``) or normalised coordinates (``P=None``).

    OpenCV 4 takes the stopping criteria only through ``cv2.undistortPointsIter``; OpenCV 5
    dropped that name and takes them as ``undistortPoints``'s ``criteria`` argument.
    """
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(pts, K, D, None, P, criteria)
    return cv2.undistortPoints(pts, K, D, R=None, P=P, criteria=criteria)


# --------------------------------------------------------------------------- the rig


@dataclass(frozen=True, eq=False)
class StereoRig:
    """A calibrated stereo camera.

    Attributes
    ----------
    K1, K2 : ndarray, shape (3, 3)
        Left / right camera matrices, pixels.
    D1, D2 : ndarray, shape (5,) (or 4, 8, 12, 14)
        Plumb-bob distortion coefficients k1 k2 p1 p2 k3 (OpenCV order).
    R : ndarray, shape (3, 3)
        Rotation right from left: ``X_right = R @ X_left + T``.
    T : ndarray, shape (3,)
        Translation right from left, metres.
    image_size : tuple of int
        ``(width, height)`` in pixels, or None where the file does not say (paper form).
    T_world_left : ndarray, shape (4, 4)
        Pose of the left camera in the world frame; identity when the world is the left camera.
    world_frame : {"calibration", "marker", "left_camera"}
        What the world frame is (DESIGN §2).
    """

    K1: NDArray[np.float64]
    D1: NDArray[np.float64]
    K2: NDArray[np.float64]
    D2: NDArray[np.float64]
    R: NDArray[np.float64]
    T: NDArray[np.float64]
    image_size: tuple[int, int] | None
    T_world_left: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    world_frame: WorldFrame = "left_camera"

    @classmethod
    def from_arrays(cls, *, K1: Any, D1: Any, K2: Any, D2: Any, R: Any, T: Any,
                    image_size: tuple[Any, Any] | None, T_world_left: Any = None,
                    world_frame: WorldFrame | None = None) -> StereoRig:
        """Validate raw values (lists, arrays) and build a rig.

        Raises
        ------
        ValueError
            Naming the key that is missing, of the wrong shape, not finite, not a rotation,
            or with a non-positive focal length.
        """
        size = None if image_size is None else _as_size(*image_size)
        T_wl = np.eye(4) if T_world_left is None else as_transform(T_world_left, "T_world_left")
        if world_frame is None:
            world_frame = "left_camera" if T_world_left is None else "calibration"
        rig = cls(K1=_as_intrinsics(K1, "K1"), D1=_as_distortion(D1, "D1"),
                  K2=_as_intrinsics(K2, "K2"), D2=_as_distortion(D2, "D2"),
                  R=_as_rotation(R, "R"), T=_as_matrix(T, "T", (3,)),
                  image_size=size, T_world_left=T_wl, world_frame=world_frame)
        if np.linalg.norm(rig.T) == 0:
            raise ValueError("T: the baseline is zero; a stereo rig needs two distinct centres")
        for arr in (rig.K1, rig.D1, rig.K2, rig.D2, rig.R, rig.T, rig.T_world_left):
            arr.setflags(write=False)
        return rig

    # -- frames --------------------------------------------------------------------------

    @property
    def T_right_left(self) -> NDArray[np.float64]:
        """4×4 transform from left-camera to right-camera coordinates."""
        return geometry.make_transform(self.R, self.T)

    @property
    def T_left_world(self) -> NDArray[np.float64]:
        return geometry.invert_transform(self.T_world_left)

    @property
    def T_right_world(self) -> NDArray[np.float64]:
        return self.T_right_left @ self.T_left_world

    @property
    def baseline(self) -> float:
        """Distance between the optical centres, metres."""
        return float(np.linalg.norm(self.T))

    @property
    def Q_L(self) -> NDArray[np.float64]:
        """3×4 world → (undistorted) left pixel projection matrix, eq. 3."""
        return self.K1 @ self.T_left_world[:3]

    @property
    def Q_R(self) -> NDArray[np.float64]:
        """3×4 world → (undistorted) right pixel projection matrix, eq. 3."""
        return self.K2 @ self.T_right_world[:3]

    @property
    def F(self) -> NDArray[np.float64]:
        """Fundamental matrix of undistorted pixels: ``p_R^T F p_L = 0``."""
        E = geometry.skew(self.T) @ self.R
        return np.linalg.inv(self.K2).T @ E @ np.linalg.inv(self.K1)

    def intrinsics(self, camera: Camera) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(K, D)`` of one camera."""
        if camera == "left":
            return self.K1, self.D1
        if camera == "right":
            return self.K2, self.D2
        raise ValueError(f"camera: expected 'left' or 'right', got {camera!r}")

    def T_camera_world(self, camera: Camera) -> NDArray[np.float64]:
        self.intrinsics(camera)  # validates the name
        return self.T_left_world if camera == "left" else self.T_right_world

    def with_world(self, T_world_left: ArrayLike,
                   world_frame: WorldFrame = "calibration") -> StereoRig:
        """The same rig with another world frame (e.g. the desk marker's)."""
        T = as_transform(T_world_left, "T_world_left")
        T.setflags(write=False)
        return replace(self, T_world_left=T, world_frame=world_frame)

    # -- projection ----------------------------------------------------------------------

    def project(self, P_world: ArrayLike, camera: Camera = "left") -> NDArray[np.float64]:
        """Project world points into one camera's raw (distorted) image.

        Parameters
        ----------
        P_world : array_like, shape (N, 3)
            Points in the world frame, metres.
        camera : {"left", "right"}

        Returns
        -------
        ndarray, shape (N, 2), float64
            Pixel coordinates with lens distortion applied.
        """
        K, D = self.intrinsics(camera)
        P_cam = geometry.transform_points(self.T_camera_world(camera), P_world)
        if len(P_cam) == 0:
            return np.zeros((0, 2))
        px, _ = cv2.projectPoints(P_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
        return px.reshape(-1, 2)

    def undistort_points(self, px: ArrayLike, camera: Camera = "left", *,
                         normalized: bool = False) -> NDArray[np.float64]:
        """Remove lens distortion from pixel coordinates.

        Parameters
        ----------
        px : array_like, shape (N, 2)
            Raw pixel coordinates.
        camera : {"left", "right"}
        normalized : bool
            Return normalised camera coordinates (x/z, y/z) instead of ideal pixels.

        Returns
        -------
        ndarray, shape (N, 2), float64
        """
        K, D = self.intrinsics(camera)
        pts = np.asarray(px, dtype=np.float64).reshape(-1, 1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        # The default 5 iterations leave ~0.1 px at the corners of a k1 = -0.36 lens.
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        out = undistort_iter(pts, K, D, None if normalized else K, criteria)
        return out.reshape(-1, 2)

    def distort_points(self, ideal_px: ArrayLike, camera: Camera = "left") -> NDArray[np.float64]:
        """Add lens distortion to ideal pixel coordinates (the inverse of
        :meth:`undistort_points`); ``(N, 2)`` → ``(N, 2)``, pixels."""
        K, D = self.intrinsics(camera)
        pts = np.asarray(ideal_px, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        rays = np.column_stack([(pts - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T, np.ones(len(pts))])
        px, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
        return px.reshape(-1, 2)

    def triangulate(self, px_left: ArrayLike, px_right: ArrayLike, *,
                    method: Literal["dlt", "optimal"] = "dlt",
                    distorted: bool = True) -> NDArray[np.float64]:
        """Triangulate corresponding raw pixels into world points (eq. 3–5).

        Parameters
        ----------
        px_left, px_right : array_like, shape (N, 2)
            Corresponding pixel coordinates in the left and right image.
        method : {"dlt", "optimal"}
            Linear least squares of eq. 5, or Lindstrom's optimal correction then DLT.
        distorted : bool
            Whether the pixels still carry lens distortion (raw image coordinates).

        Returns
        -------
        P_world : ndarray, shape (N, 3), float64
            Metres, world frame.
        """
        pl = np.asarray(px_left, dtype=np.float64).reshape(-1, 2)
        pr = np.asarray(px_right, dtype=np.float64).reshape(-1, 2)
        if pl.shape != pr.shape:
            raise ValueError(f"px_right: expected shape {pl.shape} like px_left, got {pr.shape}")
        if distorted:
            pl, pr = self.undistort_points(pl, "left"), self.undistort_points(pr, "right")
        return geometry.triangulate(self.Q_L, self.Q_R, pl, pr, method=method)

    def summary(self) -> str:
        """A few human-readable lines: sizes, focal lengths, baseline, world frame."""
        size = "unknown" if self.image_size is None else "%dx%d" % self.image_size
        lines = [f"image size     {size} px"]
        for name, (K, D) in (("left", (self.K1, self.D1)), ("right", (self.K2, self.D2))):
            lines.append(f"{name:<6} camera   f = ({K[0, 0]:.2f}, {K[1, 1]:.2f}) px, "
                         f"c = ({K[0, 2]:.2f}, {K[1, 2]:.2f}) px, "
                         f"D = [{' '.join(f'{d:.4g}' for d in D)}]")
        angle = np.degrees(np.arccos(np.clip((np.trace(self.R) - 1) / 2, -1, 1)))
        lines.append(f"baseline       {self.baseline * 1000:.2f} mm "
                     f"(T = [{' '.join(f'{t * 1000:.2f}' for t in self.T)}] mm), "
                     f"rotation {angle:.3f} deg")
        lines.append(f"world frame    {self.world_frame}")
        return "\n".join(lines)


# --------------------------------------------------------------------------- readers


def load_calibration(path: str | os.PathLike[str],
                     right: str | os.PathLike[str] | None = None) -> StereoRig:
    """Read a stereo calibration, recognising its format from the content.

    Parameters
    ----------
    path : path-like
        A canonical ``calib.yaml``, a Kalibr camchain, a BoofCV ``stereo.yaml``, a file with
        the paper's ``Q_L``/``Q_R``, or the *left* ROS ``camera_info`` file.
    right : path-like, optional
        The right camera's ROS ``camera_info`` file (only for that format).

    Raises
    ------
    ValueError
        Unreadable file, unknown format, or a bad value (the message names the key).
    """
    path = Path(path)
    text = _read_text(path)
    if text.lstrip().startswith("%YAML") or "!!opencv-matrix" in text:
        return _read_opencv(path)
    data = _parse_yaml(text, path)
    try:
        if "rightToLeft" in data:
            return _from_boofcv(data)
        if "cam0" in data and "cam1" in data:
            return _from_kalibr(data)
        if "Q_L" in data or "Q_R" in data:
            return _from_paper(data)
        if "camera_matrix" in data:
            if right is None:
                raise ValueError("a ROS camera_info file describes one camera: "
                                 "give the right camera's file too")
            right_data = _parse_yaml(_read_text(Path(right)), Path(right))
            return _from_ros(data, right_data)
        if "K1" in data:
            return _from_canonical(data.get)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    raise ValueError(
        f"{path}: unrecognised calibration format (expected OpenCV calib.yaml with K1 D1 K2 D2 R T, "
        "ROS camera_info, Kalibr camchain, BoofCV stereo.yaml, or Q_L/Q_R)")


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path}: calibration file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read calibration file ({exc})") from None


def _parse_yaml(text: str, path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" at line {where.line + 1}" if where is not None else ""
        raise ValueError(f"{path}: not valid YAML{line}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a YAML mapping of calibration keys, got {type(data).__name__}")
    return data


def _read_opencv(path: Path) -> StereoRig:
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error:
        raise ValueError(f"{path}: not a readable OpenCV FileStorage YAML") from None
    if not fs.isOpened():
        raise ValueError(f"{path}: not a readable OpenCV FileStorage YAML")

    def get(key: str) -> Any:
        node = fs.getNode(key)
        if node.empty():
            return None
        if node.isInt() or node.isReal():
            return node.real()
        if node.isString():
            return node.string()
        if node.isSeq():
            return [node.at(i).real() for i in range(node.size())]
        mat = node.mat()
        if mat is None:
            raise ValueError(f"{key}: not a matrix")
        return mat

    try:
        return _from_canonical(get)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    finally:
        fs.release()


def _from_canonical(get: Any) -> StereoRig:
    T_wl = get("T_world_left")
    frame = get("world_frame")
    if frame is not None and frame not in ("calibration", "marker", "left_camera"):
        raise ValueError(f"world_frame: expected calibration, marker or left_camera, got {frame!r}")
    return StereoRig.from_arrays(
        K1=get("K1"), D1=get("D1"), K2=get("K2"), D2=get("D2"), R=get("R"), T=get("T"),
        image_size=(get("image_width"), get("image_height")), T_world_left=T_wl,
        world_frame=frame)


def _require(data: dict[str, Any], dotted: str) -> Any:
    """Look up ``a.b.c`` in nested mappings, raising a ValueError that names the key."""
    node: Any = data
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            raise ValueError(f"{dotted}: missing")
        node = node[part]
    return node


def _from_boofcv(data: dict[str, Any]) -> StereoRig:
    Ks, Ds, size = [], [], None
    for cam in ("left", "right"):
        p = _require(data, f"{cam}.pinhole")
        fx, fy = _require(data, f"{cam}.pinhole.fx"), _require(data, f"{cam}.pinhole.fy")
        K = [[fx, p.get("skew", 0.0), _require(data, f"{cam}.pinhole.cx")],
             [0.0, fy, _require(data, f"{cam}.pinhole.cy")], [0.0, 0.0, 1.0]]
        rt = data[cam].get("radial_tangential") or {}
        radial = list(rt.get("radial") or [])
        if len(radial) > 3:
            raise ValueError(f"{cam}.radial_tangential.radial: expected at most 3 terms, got {len(radial)}")
        radial += [0.0] * (3 - len(radial))
        Ks.append(_as_intrinsics(K, f"{cam}.pinhole"))
        Ds.append([radial[0], radial[1], rt.get("t1", 0.0), rt.get("t2", 0.0), radial[2]])
        size = size or (p.get("width"), p.get("height"))
    # BoofCV stores right→left (X_left = R·X_right + T) in the target's unit, millimetres for
    # its example data; rovis keeps left→right in metres.
    R_lr = _as_rotation(_require(data, "rightToLeft.rotation"), "rightToLeft.rotation")
    t_lr = _as_matrix([_require(data, f"rightToLeft.{a}") for a in "xyz"], "rightToLeft.xyz", (3,))
    return StereoRig.from_arrays(K1=Ks[0], D1=Ds[0], K2=Ks[1], D2=Ds[1], R=R_lr.T,
                                 T=-R_lr.T @ t_lr / 1000.0, image_size=size)


def _from_kalibr(data: dict[str, Any]) -> StereoRig:
    Ks, Ds, size = [], [], None
    for cam in ("cam0", "cam1"):
        model = data[cam].get("camera_model", "pinhole")
        dist_model = data[cam].get("distortion_model", "radtan")
        if model != "pinhole" or dist_model not in ("radtan", "none"):
            raise ValueError(f"{cam}: only the pinhole + radtan model is supported, "
                             f"got {model} + {dist_model}")
        fu, fv, pu, pv = _as_matrix(_require(data, f"{cam}.intrinsics"), f"{cam}.intrinsics", (4,))
        Ks.append(_as_intrinsics([[fu, 0, pu], [0, fv, pv], [0, 0, 1]], f"{cam}.intrinsics"))
        coeffs = list(data[cam].get("distortion_coeffs") or [0.0] * 4)
        if len(coeffs) != 4:
            raise ValueError(f"{cam}.distortion_coeffs: expected 4 radtan values, got {len(coeffs)}")
        Ds.append(coeffs + [0.0])
        size = size or tuple(_as_matrix(_require(data, f"{cam}.resolution"), f"{cam}.resolution", (2,)))
    T_10 = as_transform(_require(data, "cam1.T_cn_cnm1"), "cam1.T_cn_cnm1")  # X_cam1 = T·X_cam0
    return StereoRig.from_arrays(K1=Ks[0], D1=Ds[0], K2=Ks[1], D2=Ds[1], R=T_10[:3, :3],
                                 T=T_10[:3, 3], image_size=size)


def _ros_matrix(data: dict[str, Any], key: str, shape: tuple[int, int], side: str) -> NDArray[np.float64]:
    return _as_matrix(_require(data, f"{key}.data"), f"{side} {key}", shape)


def _from_ros(left: dict[str, Any], right: dict[str, Any]) -> StereoRig:
    cams = {}
    for side, d in (("left", left), ("right", right)):
        model = d.get("distortion_model", "plumb_bob")
        if model not in ("plumb_bob", "rational_polynomial"):
            raise ValueError(f"{side} distortion_model: expected plumb_bob, got {model!r}")
        cams[side] = dict(
            K=_ros_matrix(d, "camera_matrix", (3, 3), side),
            D=_as_distortion(_require(d, "distortion_coefficients.data"),
                             f"{side} distortion_coefficients"),
            R=_as_rotation(_require(d, "rectification_matrix.data"), f"{side} rectification_matrix"),
            P=_ros_matrix(d, "projection_matrix", (3, 4), side),
            size=(d.get("image_width"), d.get("image_height")))
    P_r = cams["right"]["P"]
    if P_r[0, 3] == 0 and cams["left"]["P"][0, 3] != 0:
        raise ValueError("the files look swapped: the first must be the left camera_info "
                         "(projection_matrix Tx = 0), the second the right (Tx = -fx*B)")
    # ROS: a point in the left rectified frame projects into the right rectified image by P_r,
    # so X_rect_right = X_rect_left + t with t = (Tx/fx', Ty/fy', 0).
    t = np.array([P_r[0, 3] / P_r[0, 0], P_r[1, 3] / P_r[1, 1], P_r[2, 3]])
    R1, R2 = cams["left"]["R"], cams["right"]["R"]
    return StereoRig.from_arrays(K1=cams["left"]["K"], D1=cams["left"]["D"], K2=cams["right"]["K"],
                                 D2=cams["right"]["D"], R=R2.T @ R1, T=R2.T @ t,
                                 image_size=cams["left"]["size"])


def _from_paper(data: dict[str, Any]) -> StereoRig:
    poses, Ks = [], []
    for key in ("Q_L", "Q_R"):
        Q = _as_matrix(data.get(key), key, (3, 4))
        if abs(np.linalg.det(Q[:, :3])) < 1e-12:
            raise ValueError(f"{key}: the left 3x3 block is singular; not a camera projection")
        K, T_cam_world = geometry.decompose_projection(Q)
        Ks.append(_as_intrinsics(K, key))
        poses.append(T_cam_world)
    T_right_left = poses[1] @ geometry.invert_transform(poses[0])
    size = None
    if "image_width" in data or "image_height" in data:
        size = (data.get("image_width"), data.get("image_height"))
    return StereoRig.from_arrays(K1=Ks[0], D1=data.get("D1", [0.0] * 5), K2=Ks[1],
                                 D2=data.get("D2", [0.0] * 5), R=T_right_left[:3, :3],
                                 T=T_right_left[:3, 3], image_size=size,
                                 T_world_left=geometry.invert_transform(poses[0]))


# --------------------------------------------------------------------------- writer


def save_calibration(rig: StereoRig, path: str | os.PathLike[str]) -> None:
    """Write the canonical OpenCV FileStorage YAML (DESIGN §3), whole or not at all."""
    path = Path(path)
    if rig.image_size is None:
        raise ValueError("image_size: unknown; the canonical calib.yaml needs image_width/height")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".yaml", dir=path.parent)
    os.close(fd)
    try:
        fs = cv2.FileStorage(tmp, cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", int(rig.image_size[0]))
        fs.write("image_height", int(rig.image_size[1]))
        fs.write("K1", rig.K1)
        fs.write("D1", rig.D1.reshape(1, -1))
        fs.write("K2", rig.K2)
        fs.write("D2", rig.D2.reshape(1, -1))
        fs.write("R", rig.R)
        fs.write("T", rig.T.reshape(3, 1))
        if rig.world_frame != "left_camera":
            fs.write("T_world_left", rig.T_world_left)
            fs.write("world_frame", rig.world_frame)
        fs.release()
        publish(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def make_rig(*, image_size: tuple[int, int] = (1024, 768), f_px: float = 800.0,
             baseline: float = 0.12, distortion: ArrayLike = (-0.08, 0.03, 0.0, 0.0, 0.0),
             T_world_left: ArrayLike | None = None,
             world_frame: WorldFrame = "calibration") -> StereoRig:
    """A Bumblebee2-like rig (DESIGN §4): two identical parallel cameras, right of left by
    ``baseline`` metres along the left camera's x axis, principal point at the image centre.

    Parameters
    ----------
    image_size : (width, height), pixels
    f_px : float
        Focal length, pixels.
    baseline : float
        Metres.
    distortion : array_like, shape (5,)
        Plumb-bob coefficients shared by both cameras.
    T_world_left : array_like, shape (4, 4), optional
        Left-camera pose in the world; the left camera's own frame when omitted.
    """
    w, h = image_size
    K = np.array([[f_px, 0.0, (w - 1) / 2.0], [0.0, f_px, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    frame: WorldFrame = "left_camera" if T_world_left is None else world_frame
    return StereoRig.from_arrays(K1=K, D1=distortion, K2=K, D2=distortion, R=np.eye(3),
                                 T=[-baseline, 0.0, 0.0], image_size=image_size,
                                 T_world_left=T_world_left, world_frame=frame)
