"""Result records and their JSON form (DESIGN §3)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rovis.geometry import BookPose


def _round(a: Any, nd: int = 6) -> Any:
    """Plain Python numbers rounded to ``nd`` decimals (µm for metres); NaN becomes None."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 0:
        return None if not np.isfinite(arr) else round(float(arr), nd)
    return [_round(v, nd) for v in arr]


def pose_to_dict(pose: BookPose, **extra: Any) -> dict[str, Any]:
    """The pose part of one detected object of the detection JSON (DESIGN §3).

    ``extra`` adds fields such as ``id``, ``corners_left_px`` or ``reprojection_error_px``.
    """
    phi, theta, psi = pose.euler_zxz_deg
    out: dict[str, Any] = dict(extra)
    out.update(
        center=_round(pose.center),
        R=_round(pose.R, 9),
        quaternion_xyzw=_round(pose.quaternion_xyzw, 9),
        euler_zxz_deg={"phi": _round(phi, 4), "theta": _round(theta, 4), "psi": _round(psi, 4)},
        yaw_deg=_round(pose.yaw_deg, 4),
        size=_round(pose.size),
        corners_world=_round(pose.corners),
    )
    return out


@dataclass(frozen=True, eq=False)
class BookDetection:
    """One book found in a stereo pair.

    Attributes
    ----------
    id : int
    pose : BookPose
        Centre, rotation, size (x, y extent and height above the desk), world frame.
    corners_world : ndarray, shape (4, 3)
        The triangulated cover corners P1..P4, metres.
    corners_left_px, corners_right_px : ndarray, shape (4, 2)
        The cover corners in the raw images, pixels, P1 (top-left in the left image) first.
    reprojection_error_px : float
        How far the cover, projected from ``corners_world`` into both images, lies from the
        edges the images show along its sides: the root mean square distance over its
        eight sides (four per image), pixels, each side's edge looked for within
        ``agreement.reach_px`` (3 px) of it and a side without one counting that much
        (:mod:`rovis.agreement`). In a tracked frame, from the sides the tracker refit
        within ``track.window_px`` of where they were (:func:`rovis.track.follow`).
        Inside the detector, until the end of the frame, it is the corners' triangulation
        residual (what ``stereo.late_max_reprojection_px`` bounds).
    quality : float
        How much of the cover's outline, as projected from ``corners_world``, shows a
        step across it: per side the share of its length, the mean over its four sides,
        in the worse of the two images; in [0, 1] (:mod:`rovis.agreement`). Inside the
        detector, until the end of the frame, it is its pair's segmentation support.
    stereo_error_px : float
        Mean distance of the right corners to where the left corners allow them (0 for a
        cover found in one image's segmentation only).
    source : str
        How the cover was found: ``"segmentation"`` (each image's segmentation kept it),
        ``"one image"`` (one image's, then found in the other), ``"candidates"`` (a pair
        of candidate quads neither image's selection kept, chosen by stereo) or ``"height
        map"`` (a patch standing out of the desk in the stereo height map; its outline is
        the least exact: see docs/stereo.md).
    """

    id: int
    pose: BookPose
    corners_world: NDArray[np.float64]
    corners_left_px: NDArray[np.float64]
    corners_right_px: NDArray[np.float64]
    reprojection_error_px: float
    quality: float
    stereo_error_px: float = 0.0
    source: str = "segmentation"

    def to_dict(self) -> dict[str, Any]:
        out = pose_to_dict(self.pose, id=self.id)
        out["corners_world"] = _round(self.corners_world)  # measured, not the fitted rectangle
        out.update(corners_left_px=_round(self.corners_left_px, 3),
                   corners_right_px=_round(self.corners_right_px, 3),
                   reprojection_error_px=_round(self.reprojection_error_px, 4),
                   quality=_round(self.quality, 4), source=self.source)
        return out


@dataclass(frozen=True)
class SegmentationInfo:
    """What the segmentation of one image settled on."""

    T_H: float
    T_HG: int
    y: float
    iterations: int
    n_quads: int

    def to_dict(self) -> dict[str, Any]:
        return {"T_H": _round(self.T_H, 3), "T_HG": int(self.T_HG), "y": _round(self.y, 8),
                "iterations": int(self.iterations), "n_quads": int(self.n_quads)}


@dataclass(frozen=True, eq=False)
class FrameResult:
    """Everything found in one stereo pair (the detection JSON of DESIGN §3)."""

    objects: list[BookDetection]
    desk_plane: NDArray[np.float64] | None
    world_frame: str
    segmentation: dict[str, SegmentationInfo]
    timing_ms: dict[str, float]  # per stage; "segmentation.X": its steps (both images)
    warnings: list[str]
    T_world_left: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    lines: dict[str, Any] = field(default_factory=dict)  # Hough lines per camera, for overlays
    # for overlays and diagnosis (ideal pixels): each camera's cover quads (K, 4, 2), and
    # the stereo pairs of quads no book came from, with the check each failed
    covers: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    dropped: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]] = field(
        default_factory=list)
    # the books followed from the previous frame (Detector.track), not detected afresh
    tracked: bool = False

    def __len__(self) -> int:
        return len(self.objects)

    def to_dict(self, **extra: Any) -> dict[str, Any]:
        out: dict[str, Any] = dict(extra)
        out.update(
            objects=[o.to_dict() for o in self.objects],
            desk_plane=None if self.desk_plane is None else _round(self.desk_plane, 9),
            world_frame=self.world_frame,
            T_world_left=_round(self.T_world_left, 9),
            segmentation={cam: info.to_dict() for cam, info in self.segmentation.items()},
            timing_ms={k: _round(v, 3) for k, v in self.timing_ms.items()},
            warnings=list(self.warnings), tracked=self.tracked)
        return out

    def to_json(self, **extra: Any) -> str:
        return json.dumps(self.to_dict(**extra))


def books_table(objects: list[BookDetection]) -> str:
    """A fixed-width text table of detected books, one row each: id, centre (m), yaw (°),
    cover size and height (mm), reprojection error (px) and quality (:class:`BookDetection`'s),
    how it was found."""
    header = (" id   center x      y      z [m]   yaw [°]   size [mm]    height [mm]"
              "   reproj [px]   quality   found by")
    rows = [header]
    for obj in objects:
        c, s = obj.pose.center, obj.pose.size * 1000.0
        height = f"{s[2]:8.1f}" if np.isfinite(s[2]) else "       -"
        rows.append(f"{obj.id:>3}   {c[0]:8.3f} {c[1]:6.3f} {c[2]:6.3f}   {obj.pose.yaw_deg:7.1f}"
                    f"   {s[0]:5.0f} x {s[1]:3.0f}   {height}"
                    f"      {obj.reprojection_error_px:8.2f}   {obj.quality:7.2f}   {obj.source}")
    return "\n".join(rows)
