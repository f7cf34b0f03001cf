"""Pictures of a detection: image overlays (the paper's Fig. 3c) and a world model (Fig. 9).

:func:`overlay` draws with OpenCV on a copy of the raw image; :func:`world_view` plots with
matplotlib (the ``plot`` extra), imported only when it is called and always through the Agg
canvas, so no display and no global pyplot state are involved.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from rovis import geometry, marker
from rovis.calib import StereoRig
from rovis.imageio import to_gray_u8
from rovis.io import write_figure_atomic
from rovis.results import FrameResult
from rovis.undistort import ideal_bounds

Camera = Literal["left", "right"]

# BGR colours, chosen to stay apart on a grey image.
_ROI = (0, 215, 255)  # amber
_LINE = (255, 200, 0)  # light blue
_BOOK = (60, 220, 60)  # green
_TEXT_BG = (0, 0, 0)
_SHIFT = 4  # sub-pixel bits for cv2 drawing
_LINE_SAMPLES = 64  # points per Hough line when it is bent by lens distortion


def overlay(image: NDArray[np.generic], result: FrameResult, camera: Camera, *,
            rig: StereoRig | None = None) -> NDArray[np.uint8]:
    """Draw what the pipeline saw on one raw camera image.

    Draws the workspace ROI (desk level; only when the world is the marker frame and ``rig``
    is given), the Hough lines the segmentation settled on, each book's cover quadrilateral
    with its corners numbered 1–4 (P1 top-left in the left image, clockwise; the paper's
    Fig. 3c) and the book's id, and a caption with the segmentation's thresholds.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3|4); uint8, uint16 or float
        The raw (distorted) image of ``camera``; converted to 8-bit grey, drawn in colour.
    result : FrameResult
        The detection of the stereo pair this image belongs to.
    camera : {"left", "right"}
    rig : StereoRig, optional
        The calibration. Hough lines live in undistorted (ideal) pixels: with the rig they
        are drawn bent by the lens distortion as they lie in the raw image; without it they
        are drawn straight (off by the distortion, a few pixels near the border).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        BGR.
    """
    if camera not in ("left", "right"):
        raise ValueError(f"camera: expected 'left' or 'right', got {camera!r}")
    gray = to_gray_u8(image, f"{camera} image")
    h, w = gray.shape
    # A slightly darkened, lower-contrast background lets thin coloured lines stand out.
    canvas = cv2.cvtColor(cv2.convertScaleAbs(gray, alpha=0.75, beta=20), cv2.COLOR_GRAY2BGR)
    thick = max(1, round(min(w, h) / 400))

    roi = _roi_polygon(result, camera, rig)
    if len(roi) >= 3:
        cv2.polylines(canvas, [_fixed(roi)], True, _ROI, thick, cv2.LINE_AA, _SHIFT)

    lines = result.lines.get(camera)
    if lines is not None and len(lines) > 0:
        layer = canvas.copy()
        for pts in _line_polylines(lines, (w, h), rig, camera):
            cv2.polylines(layer, [_fixed(pts)], False, _LINE, 1, cv2.LINE_AA, _SHIFT)
        canvas = cv2.addWeighted(layer, 0.5, canvas, 0.5, 0.0)

    scale = max(0.45, min(w, h) / 1100)
    for obj in result.objects:
        quad = np.asarray(obj.corners_left_px if camera == "left" else obj.corners_right_px,
                          dtype=np.float64)
        if quad.shape != (4, 2) or not np.all(np.isfinite(quad)):
            continue
        cv2.polylines(canvas, [_fixed(quad)], True, _BOOK, thick + 1, cv2.LINE_AA, _SHIFT)
        centre = quad.mean(axis=0)
        for k, corner in enumerate(quad, start=1):
            # Number each corner just inside the quad, so labels of touching books stay apart.
            inward = centre - corner
            inward *= min(18.0 * scale / 0.7, 0.3 * np.linalg.norm(inward)) / max(
                np.linalg.norm(inward), 1e-9)
            cv2.circle(canvas, _fixed(corner[None])[0], (3 * thick) << _SHIFT, _BOOK, -1,
                       cv2.LINE_AA, _SHIFT)
            _label(canvas, str(k), corner + inward, scale * 0.8, _BOOK)
        _label(canvas, f"book {obj.id}", centre, scale, (255, 255, 255), box=True)

    seg = result.segmentation.get(camera)
    caption = f"{camera}: {len(result.objects)} book{'s' if len(result.objects) != 1 else ''}"
    if seg is not None:
        caption += f"   T_H {seg.T_H:.0f}  T_HG {seg.T_HG}  y {seg.y:.3g}  ({seg.iterations} it.)"
    _label(canvas, caption, None, scale, (255, 255, 255), box=True)
    return canvas


def _fixed(px: NDArray[np.float64]) -> NDArray[np.int32]:
    """Pixel coordinates as cv2's fixed-point drawing coordinates (``_SHIFT`` bits)."""
    return np.rint(np.asarray(px, dtype=np.float64).reshape(-1, 2) * (1 << _SHIFT)).astype(np.int32)


def _label(canvas: NDArray[np.uint8], text: str, at: NDArray[np.float64] | None, scale: float,
           colour: tuple[int, int, int], *, box: bool = False) -> None:
    """Text centred on ``at`` (or in the top-left corner when None), on a dark outline/box."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    weight = max(1, round(2 * scale))
    (tw, th), base = cv2.getTextSize(text, font, scale, weight)
    h, w = canvas.shape[:2]
    if at is None:
        x, y = 6, 6 + th
    else:
        x, y = int(round(at[0] - tw / 2)), int(round(at[1] + th / 2))
    x = int(np.clip(x, 2, max(2, w - tw - 2)))
    y = int(np.clip(y, th + 2, max(th + 2, h - base - 2)))
    if box:
        pad = 3
        sub = canvas[max(0, y - th - pad):y + base + pad, max(0, x - pad):x + tw + pad]
        sub[...] = (0.35 * sub).astype(np.uint8)  # a translucent dark box
    else:
        cv2.putText(canvas, text, (x, y), font, scale, _TEXT_BG, weight + 2, cv2.LINE_AA)
    cv2.putText(canvas, text, (x, y), font, scale, colour, weight, cv2.LINE_AA)


def _roi_polygon(result: FrameResult, camera: Camera, rig: StereoRig | None) -> NDArray[np.float64]:
    """The desk-level workspace rectangle in the raw image, when the world is the marker's."""
    if rig is None or result.world_frame != "marker":
        return np.zeros((0, 2))
    # The result's world may be the marker found in this frame, not the calibration's world.
    in_world = rig.with_world(result.T_world_left, "marker")
    return marker.workspace_polygon(in_world, camera)


def _line_polylines(lines: Any, size: tuple[int, int], rig: StereoRig | None,
                    camera: Camera) -> list[NDArray[np.float64]]:
    """Each Hough line (ideal pixels, ``x cos θ + y sin θ = ρ``) as a raw-image polyline.

    With a rig the lines are clipped to the ideal pixels the raw image's whole field of view
    covers (:func:`rovis.undistort.ideal_bounds`: the detector searches there), then drawn
    through the lens, their points outside the raw image left out."""
    w, h = size
    box = (0.0, 0.0, w - 1.0, h - 1.0)
    if rig is not None and rig.image_size is not None:
        lo, hi = ideal_bounds(rig)
        box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    out = []
    for rho, theta in zip(np.asarray(lines.rho, dtype=np.float64),
                          np.asarray(lines.theta, dtype=np.float64)):
        seg = _clip_line(rho, theta, box)
        if seg is None:
            continue
        t = np.linspace(0.0, 1.0, _LINE_SAMPLES if rig is not None else 2)[:, None]
        ideal = seg[0] + t * (seg[1] - seg[0])
        if rig is None:
            out.append(ideal)
            continue
        raw = rig.distort_points(ideal, camera)
        keep = np.all((raw >= 0) & (raw <= [w - 1.0, h - 1.0]), axis=1)
        if keep.sum() >= 2:
            out.append(raw[keep])
    return out


def _clip_line(rho: float, theta: float,
               box: tuple[float, float, float, float]) -> NDArray[np.float64] | None:
    """The two ends (2, 2) of the line's part inside ``box`` (x0, y0, x1, y1), or None."""
    n = np.array([np.cos(theta), np.sin(theta)])
    d = np.array([-n[1], n[0]])
    p0 = rho * n
    lo, hi = -np.inf, np.inf
    for axis, start, limit in ((0, box[0], box[2]), (1, box[1], box[3])):
        if abs(d[axis]) < 1e-12:
            if not start <= p0[axis] <= limit:
                return None
            continue
        a, b = (start - p0[axis]) / d[axis], (limit - p0[axis]) / d[axis]
        lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
    if not hi > lo:
        return None
    return np.array([p0 + lo * d, p0 + hi * d])


# --------------------------------------------------------------------------- world model


def truth_cuboids(truth: Mapping[str, Any] | Sequence[Mapping[str, Any]],
                  ) -> list[NDArray[np.float64]]:
    """The 8 cuboid vertices (8, 3) of each true book of a ``truth.json`` (DESIGN §3).

    Parameters
    ----------
    truth : dict or list of dict
        The ``truth.json`` content, or its ``books`` list (``center``, ``R``, ``size``).

    Returns
    -------
    list of ndarray, shape (8, 3)
        Cover P1..P4, then the same down by the thickness; world, metres.
    """
    books = truth["books"] if isinstance(truth, Mapping) else truth
    out = []
    for b in books:
        R = np.asarray(b["R"], dtype=np.float64)
        size = np.asarray(b["size"], dtype=np.float64)
        top = geometry.corners_from_pose(b["center"], R, size[:2])
        out.append(np.vstack([top, top - size[2] * R[:, 2]]))
    return out


def world_view(result: FrameResult, path: str | os.PathLike[str], *,
               truth: Mapping[str, Any] | Sequence[Mapping[str, Any]] | None = None,
               title: str | None = None) -> Path:
    """Write a PNG of the world model: a top view and a side view of the books' cuboids.

    Like the paper's Fig. 9: the desk (its plane, and when the world is the desk marker's
    frame the 0.10 m marker at the origin and the workspace rectangle), each detected book's
    cuboid (solid, its cover corner P1 marked) and, when given, the true books (dashed).

    Parameters
    ----------
    result : FrameResult
    path : path-like
        The PNG to write (atomically: a temporary file in the same folder, then a rename).
    truth : dict or list of dict, optional
        ``truth.json`` content (or its ``books`` list): drawn dashed.
    title : str, optional

    Returns
    -------
    Path
        ``path``.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D
    except ImportError as exc:
        raise ImportError("the world view needs matplotlib: pip install 'rovis[plot]'") from exc

    path = Path(path)
    detected = [obj.pose.cuboid_corners() for obj in result.objects]
    true = truth_cuboids(truth) if truth is not None else []
    on_marker = result.world_frame == "marker"

    # Extents: everything drawn, plus the workspace when the marker frame says where it is.
    pts = [c for c in detected + true]
    if on_marker:
        (x0, x1), (y0, y1) = marker.WORKSPACE_X, marker.WORKSPACE_Y
        pts.append(np.array([[x0, y0, 0.0], [x1, y1, 0.0], [-0.06, -0.06, 0.0]]))
    allp = np.vstack(pts) if pts else np.zeros((1, 3))
    allp = allp[np.all(np.isfinite(allp), axis=1)]
    if len(allp) == 0:
        allp = np.zeros((1, 3))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    pad = 0.05 + 0.05 * float(np.max(hi[:2] - lo[:2]))
    xlim = _span(lo[0] - pad, hi[0] + pad, 0.5)
    ylim = _span(lo[1] - pad, hi[1] + pad, 0.4)
    desk_z = _desk_height(result.desk_plane, 0.5 * (lo[:2] + hi[:2]))
    z_base = desk_z if desk_z is not None else lo[2]
    zlim = (min(lo[2], z_base) - 0.03, max(hi[2], z_base + 0.10) + 0.03)

    # Both panels at one scale (equal aspect), so the side view's height follows its z range —
    # unless a panel would be absurdly tall (books far apart in depth, no desk): then not.
    width_in = 8.0
    xr = xlim[1] - xlim[0]
    h_top = width_in * (ylim[1] - ylim[0]) / xr
    h_side = width_in * (zlim[1] - zlim[0]) / xr
    equal = 2.0 <= h_top <= 9.0 and h_side <= 5.0
    h_top, h_side = float(np.clip(h_top, 2.0, 9.0)), float(np.clip(h_side, 1.2, 5.0))
    fig = Figure(figsize=(width_in + 1.0, h_top + h_side + 1.3), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(2, 1, height_ratios=[h_top, h_side])
    top = fig.add_subplot(gs[0])
    side = fig.add_subplot(gs[1], sharex=top)

    if on_marker:
        (x0, x1), (y0, y1) = marker.WORKSPACE_X, marker.WORKSPACE_Y
        top.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="0.6", lw=1, ls=":")
        top.text(x0, y1 + 0.01, "workspace", color="0.45", fontsize=8, va="bottom")
        s = 0.5 * marker.MARKER_SIDE
        top.fill([-s, s, s, -s], [-s, -s, s, s], facecolor="0.15", edgecolor="0.0", lw=1)
        top.fill([-0.6 * s, 0.6 * s, 0.6 * s, -0.6 * s], [-0.6 * s, -0.6 * s, 0.6 * s, 0.6 * s],
                 facecolor="0.9", edgecolor="none")
        top.text(0.0, -s - 0.012, "marker", ha="center", va="top", fontsize=8, color="0.2")
    if desk_z is not None:
        top.set_facecolor("#f3ede2")  # the desk
        side.axhspan(zlim[0], desk_z, color="#d9c7a7", lw=0)
        side.axhline(desk_z, color="#8a6d3b", lw=1.2)
        side.text(xlim[0] + 0.01, desk_z - 0.004, "desk plane", fontsize=8, va="top",
                  color="#6b5330")
    if on_marker:
        side.plot([-0.05, 0.05], [0.0, 0.0], color="0.0", lw=4, solid_capstyle="butt")

    colours = [f"C{k % 10}" for k in range(len(detected))]
    for cub in true:
        _draw_cuboid(top, side, cub, colour="0.15", ls="--", lw=1.2, fill=False)
    for obj, cub, colour in zip(result.objects, detected, colours):
        _draw_cuboid(top, side, cub, colour=colour, ls="-", lw=1.8, fill=True)
        top.plot(*cub[0, :2], marker="o", ms=4, color=colour)  # P1
        c = obj.pose.center
        top.text(c[0], c[1], str(obj.id), ha="center", va="center", fontsize=10,
                 fontweight="bold", color=colour)

    frame = {"marker": "desk marker frame", "calibration": "calibration's world frame",
             "left_camera": "left camera frame"}.get(result.world_frame, result.world_frame)
    if result.world_frame == "left_camera":  # OpenCV optical frame: z is depth, y down
        top.set_title("x-y plane (as the camera sees it, y down)", fontsize=10, loc="left")
        side.set_title("x-z plane (depth z up the page)", fontsize=10, loc="left")
        top.invert_yaxis()
    else:
        top.set_title("top view", fontsize=10, loc="left")
        side.set_title("side view (looking along +y)", fontsize=10, loc="left")
    aspect = "equal" if equal else "auto"
    top.set(xlim=xlim, ylim=ylim, ylabel="y [m]", aspect=aspect)
    side.set(ylim=zlim, xlabel="x [m]", ylabel="z [m]", aspect=aspect)
    if not detected:
        top.text(0.5, 0.5, "no book detected", transform=top.transAxes, ha="center",
                 va="center", fontsize=12, color="0.4")
    top.tick_params(labelbottom=True)
    for ax in (top, side):
        ax.grid(True, color="0.85", lw=0.5)
        ax.set_axisbelow(True)
    handles = [Line2D([], [], color="C0", lw=1.8, label=f"detected ({len(detected)})")]
    if truth is not None:
        handles.append(Line2D([], [], color="0.15", lw=1.2, ls="--", label=f"truth ({len(true)})"))
    top.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.9)
    fig.suptitle(title or f"rovis world model — {frame}"
                 + ("" if desk_z is not None else ", desk plane unknown"), fontsize=11)

    return write_figure_atomic(fig, path)


def _span(lo: float, hi: float, at_least: float) -> tuple[float, float]:
    """``(lo, hi)`` widened about its middle to at least ``at_least``."""
    half = max(0.5 * (hi - lo), 0.5 * at_least)
    mid = 0.5 * (lo + hi)
    return mid - half, mid + half


def _desk_height(plane: ArrayLike | None, xy: NDArray[np.float64]) -> float | None:
    """World z of the desk plane at ``xy``, or None (unknown, or too steep to draw)."""
    if plane is None:
        return None
    n = np.asarray(plane, dtype=np.float64)
    if abs(n[2]) < 0.5:
        return None
    return float(-(n[3] + n[0] * xy[0] + n[1] * xy[1]) / n[2])


def _draw_cuboid(top: Any, side: Any, cub: NDArray[np.float64], *, colour: str, ls: str,
                 lw: float, fill: bool) -> None:
    """One cuboid (8, 3): its cover outline seen from above, its hull seen along y."""
    if not np.all(np.isfinite(cub)):
        return
    cover = cub[[0, 1, 2, 3, 0]]
    if fill:
        top.fill(cover[:, 0], cover[:, 1], color=colour, alpha=0.25, lw=0)
    top.plot(cover[:, 0], cover[:, 1], color=colour, ls=ls, lw=lw)
    xz = cub[:, [0, 2]].astype(np.float32)
    hull = cv2.convexHull(xz).reshape(-1, 2)
    hull = np.vstack([hull, hull[:1]])
    if fill:
        side.fill(hull[:, 0], hull[:, 1], color=colour, alpha=0.25, lw=0)
    side.plot(hull[:, 0], hull[:, 1], color=colour, ls=ls, lw=lw)
