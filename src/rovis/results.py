"""Result records and their JSON form (DESIGN §3)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rovis.geometry import BookPose


def _round(a: Any, nd: int = 6) -> Any:
    """Plain Python numbers rounded to ``nd`` decimals (µm for metres); NaN becomes None."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 0:
        return None if np.isnan(arr) else round(float(arr), nd)
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
