"""Rendering a :class:`~rovis.synth.scene.Scene` into a stereo pair and its ground truth.

Per camera (DESIGN §4):

1. every planar face (floor, desk, marker, sheets, book covers and sides, mugs, pens) is
   drawn far to near into a supersampled *ideal pinhole* canvas — textured faces by the
   homography texture → image (``cv2.warpPerspective`` limited to the face's bounding box),
   plain ones by a constant — over the canvas pixels whose centres lie inside it
   (:func:`_convex_mask`), with an id buffer beside it;
2. the canvas is averaged down (``INTER_AREA``) and lit: an illuminance map from the light's
   spatial profile, Lambert factors per face, cast shadows (each object's outline projected
   from the light onto the desk, blurred by the penumbra), contact shadows, specular
   highlights on glossy covers;
3. the calibration's lens distortion is applied by ``cv2.remap`` with a per-rig map (for each
   raw pixel, where it lies in the ideal image), then vignetting and a mild blur;
4. photometry (:mod:`rovis.synth.photometry`) turns luminance into noisy 8-bit pixels with one
   exposure shared by both cameras (the Bumblebee2 exposes them together).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis.calib import StereoRig, undistort_iter
from rovis.synth import textures
from rovis.synth.photometry import Exposure, choose_exposure, expose
from rovis.synth.scene import (DESK, DESK_THICKNESS, FLOOR_Z, Book, Light, Mug, Pen, Scene)
from rovis.synth.textures import MARKER_ID, MARKER_PAPER, MARKER_SIZE

Camera = Literal["left", "right"]

# Id buffer values: what each pixel shows.
ID_FLOOR, ID_DESK, ID_MARKER, ID_CLUTTER, ID_BOOK_SIDE = 0, 1, 2, 3, 4
ID_COVER = 100  # + book index

DESK_PLANE = (0.0, 0.0, 1.0, 0.0)  # world z = 0, normal up
_SHIFT = 4  # sub-pixel bits for cv2 polygon filling
_AO_STRENGTH = 0.45  # how much the desk's ambient light dims right next to an object
_VIGNETTING = 0.6  # fraction of the natural cos^4 fall-off that the lens does not correct
_FLOOR_FACTOR = 0.3  # the floor far below the desk gets less light


@dataclass(frozen=True, eq=False)
class Rendering:
    """A rendered stereo pair.

    Attributes
    ----------
    left, right : ndarray, shape (H, W), uint8
        Raw (distorted) grey images.
    truth : dict
        The scene's ground truth, DESIGN §3's ``truth.json`` content.
    exposure : Exposure
        Exposure time and gain used for both cameras.
    ids_left, ids_right : ndarray, shape (H, W), int16
        What each raw pixel shows: ``ID_FLOOR``, ``ID_DESK``, ``ID_MARKER``, ``ID_CLUTTER``,
        ``ID_BOOK_SIDE``, or ``ID_COVER + k`` for the cover of book ``k``.
    """

    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    truth: dict[str, Any]
    exposure: Exposure
    ids_left: NDArray[np.int16]
    ids_right: NDArray[np.int16]


# --------------------------------------------------------------------------- per-rig cache


@dataclass(frozen=True, eq=False)
class _Optics:
    """What depends only on one camera's intrinsics: canvas geometry and the distortion map."""

    size: tuple[int, int]  # raw image (W, H)
    canvas: tuple[int, int]  # ideal low-res canvas (W, H), raw image plus margins
    K_lo: NDArray[np.float64]  # ideal canvas intrinsics
    map_x: NDArray[np.float32]  # (H, W): raw pixel -> ideal canvas x
    map_y: NDArray[np.float32]
    valid: NDArray[np.bool_]  # (Hc, Wc): ideal canvas pixels the raw image sees
    vignette: NDArray[np.float32]  # (H, W)
    prnu: NDArray[np.float32]  # (H, W)


_OPTICS: dict[tuple[bytes, bytes, tuple[int, int], str], _Optics] = {}


def _optics(rig: StereoRig, camera: Camera) -> _Optics:
    K, D = rig.intrinsics(camera)
    if rig.image_size is None:
        raise ValueError("rig: image_size unknown; the renderer needs the image size")
    w, h = rig.image_size
    key = (K.tobytes(), D.tobytes(), (w, h), camera)
    if key in _OPTICS:
        return _OPTICS[key]
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    raw = np.column_stack([uu.ravel(), vv.ravel()]).reshape(-1, 1, 2)
    # For each raw (distorted) pixel, its ideal pinhole position: the inverse of the lens model
    # that rig.project applies, so rendered and projected truth agree.
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    ideal = undistort_iter(raw, K, D, K, criteria).reshape(h, w, 2)
    mx = int(np.ceil(max(0.0, -ideal[..., 0].min(), ideal[..., 0].max() - (w - 1)))) + 3
    my = int(np.ceil(max(0.0, -ideal[..., 1].min(), ideal[..., 1].max() - (h - 1)))) + 3
    K_lo = K.copy()
    K_lo[0, 2] += mx
    K_lo[1, 2] += my
    map_x = (ideal[..., 0] + mx).astype(np.float32)
    map_y = (ideal[..., 1] + my).astype(np.float32)
    canvas = (w + 2 * mx, h + 2 * my)
    border = np.concatenate([np.column_stack([map_x[0], map_y[0]]),
                             np.column_stack([map_x[:, -1], map_y[:, -1]]),
                             np.column_stack([map_x[-1, ::-1], map_y[-1, ::-1]]),
                             np.column_stack([map_x[::-1, 0], map_y[::-1, 0]])])
    valid = np.zeros((canvas[1], canvas[0]), np.uint8)
    cv2.fillPoly(valid, [np.round(border * (1 << _SHIFT)).astype(np.int32)], 1, cv2.LINE_8, _SHIFT)
    # Natural vignetting cos^4 of the field angle, mostly but not fully corrected by the lens.
    r2 = ((ideal[..., 0] - K[0, 2]) / K[0, 0]) ** 2 + ((ideal[..., 1] - K[1, 2]) / K[1, 1]) ** 2
    vignette = (1.0 - _VIGNETTING * (1.0 - 1.0 / (1.0 + r2) ** 2)).astype(np.float32)
    prnu_rng = np.random.default_rng(11 if camera == "left" else 12)
    prnu = (1.0 + 0.01 * prnu_rng.standard_normal((h, w))).astype(np.float32)
    out = _Optics(size=(w, h), canvas=canvas, K_lo=K_lo, map_x=map_x, map_y=map_y,
                  valid=valid.astype(bool), vignette=vignette, prnu=prnu)
    _OPTICS[key] = out
    return out


# --------------------------------------------------------------------------- light


def _light_dir(light: Light, P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit vectors (N, 3) from points ``P`` (N, 3) toward the light."""
    P = np.atleast_2d(P)
    if light.kind == "daylight":
        d = np.asarray(light.direction, dtype=np.float64)
        return np.broadcast_to(d / np.linalg.norm(d), P.shape)
    v = np.asarray(light.position) - P
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _face_factor(light: Light, normal: NDArray[np.float64], point: NDArray[np.float64]) -> float:
    """Illuminance on a face of ``normal`` relative to the desk's at the same spot (Lambert):
    1 for a face looking up, ``ambient`` for one turned away from the light."""
    l = _light_dir(light, point)[0]
    direct = max(0.0, float(normal @ l)) / max(float(l[2]), 0.2)
    return float(min(light.ambient + (1.0 - light.ambient) * direct, 2.5))


def illuminance_profile(light: Light, xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Relative illuminance ``E / lux`` of the desk at points ``xy`` (N, 2), world metres;
    1 at the workspace centre (0.45, 0.35), without cast shadows."""
    c = np.array([0.45, 0.35])
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    a = light.ambient
    if light.kind == "artificial":
        L = np.asarray(light.position)

        def profile(p: NDArray[np.float64]) -> NDArray[np.float64]:
            d2 = ((p - L[:2]) ** 2).sum(axis=1)
            direct = L[2] / (d2 + L[2] ** 2) ** 1.5  # point source on a horizontal surface
            hot = 1.0 + light.hotspot * np.exp(-0.5 * d2 / light.hotspot_sigma**2)
            return direct, hot

        d, hot = profile(xy)
        d0, hot0 = profile(c[None])
        g = (a + (1.0 - a) * d / d0) * hot / hot0
    else:
        u = np.asarray(light.direction[:2], dtype=np.float64)
        u = u / max(np.linalg.norm(u), 1e-9)
        g = np.exp(np.log(light.gradient) / 0.8 * ((xy - c) @ u))
        if light.mullions:
            t = (xy - c) @ np.array([-u[1], u[0]])
            bars = np.zeros(len(xy))
            for k in range(light.mullions):
                centre = -0.2 + 0.45 * k + 0.1 * np.sin(7.0 * light.direction[0])
                bars = np.maximum(bars, np.clip(1.5 - np.abs(t - centre) / 0.015, 0.0, 1.0))
            g = g * (1.0 - 0.9 * (1.0 - a) * bars)
    return np.clip(g, 0.02, 20.0)


def _shadow_points(light: Light, P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Where points ``P`` (N, 3) cast their shadow on the desk z = 0, (N, 2)."""
    if light.kind == "daylight":
        d = np.asarray(light.direction, dtype=np.float64)
        return P[:, :2] - P[:, 2:3] / d[2] * d[:2]
    L = np.asarray(light.position)
    s = L[2] / np.maximum(L[2] - P[:, 2:3], 1e-3)
    return L[:2] + (P[:, :2] - L[:2]) * s


# --------------------------------------------------------------------------- the canvas


class _Canvas:
    """Supersampled ideal image of one camera: two float layers and an id buffer.

    Layer 0 holds light that is already final relative to the local desk illuminance
    (albedo × face factor, plus highlights); layer 1 holds the albedo of desk-level surfaces,
    which cast shadows and contact shadows darken later.
    """

    def __init__(self, optics: _Optics, T_cam_world: NDArray[np.float64], ss: int):
        self.ss = ss
        S = np.array([[ss, 0.0, (ss - 1) / 2.0], [0.0, ss, (ss - 1) / 2.0], [0.0, 0.0, 1.0]])
        self.K = S @ optics.K_lo
        self.T = T_cam_world
        self.C = -T_cam_world[:3, :3].T @ T_cam_world[:3, 3]  # camera centre, world
        wc, hc = optics.canvas
        self.w, self.h = wc * ss, hc * ss
        self.layers = np.zeros((self.h, self.w, 2), np.float32)
        self.ids = np.zeros((self.h, self.w), np.int16)

    def project(self, P_world: NDArray[np.float64]) -> NDArray[np.float64]:
        """Ideal supersampled pixel coordinates (N, 2) of world points (N, 3)."""
        P = np.asarray(P_world, dtype=np.float64).reshape(-1, 3) @ self.T[:3, :3].T + self.T[:3, 3]
        p = P @ self.K.T
        return p[:, :2] / p[:, 2:3]

    def faces_camera(self, normal: NDArray[np.float64], point: NDArray[np.float64]) -> bool:
        return float(normal @ (self.C - point)) > 0.0

    def px_per_m(self, point: NDArray[np.float64]) -> float:
        depth = float((self.T[:3, :3] @ point + self.T[:3, 3])[2])
        return self.K[0, 0] / max(depth, 1e-3)

    def _bbox(self, px: NDArray[np.float64]) -> tuple[int, int, int, int] | None:
        x0, y0 = np.floor(px.min(axis=0)).astype(int) - 1
        x1, y1 = np.ceil(px.max(axis=0)).astype(int) + 2
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, self.w), min(y1, self.h)
        return None if x1 <= x0 or y1 <= y0 else (x0, y0, x1, y1)

    def flat(self, P_world: NDArray[np.float64], value: tuple[float, float], face_id: int) -> None:
        """Fill the convex polygon ``P_world`` (N, 3) with a constant (layer0, layer1)."""
        px = self.project(P_world)
        box = self._bbox(px) if np.abs(px).max() < 2**26 else None
        if box is None:
            return
        x0, y0, x1, y1 = box
        m = _convex_mask((y1 - y0, x1 - x0), px - np.array([x0, y0], dtype=np.float64))
        self.layers[y0:y1, x0:x1][m] = np.array(value, np.float32)
        self.ids[y0:y1, x0:x1][m] = face_id

    def polyline(self, P_world: NDArray[np.float64], width_m: float, value: tuple[float, float],
                 face_id: int) -> None:
        """A thick open polyline (cables, mug handles)."""
        px = self.project(P_world)
        thick = max(1, int(round(width_m * self.px_per_m(P_world.mean(axis=0)))))
        pts = [np.round(px * (1 << _SHIFT)).astype(np.int32)]
        cv2.polylines(self.layers, pts, False, (float(value[0]), float(value[1]), 0.0, 0.0),
                      thick, cv2.LINE_8, _SHIFT)
        cv2.polylines(self.ids, pts, False, int(face_id), thick, cv2.LINE_8, _SHIFT)

    def textured(self, quad_world: NDArray[np.float64], tex: NDArray[np.float32],
                 value: tuple[float, float], face_id: int, *,
                 src: NDArray[np.float64] | None = None,
                 highlight: tuple[NDArray[np.float64], float] | None = None) -> None:
        """Map ``tex`` onto the planar quad ``quad_world`` (4, 3) — corners at the texture's
        top-left, top-right, bottom-right, bottom-left (or at ``src`` (4, 2) texel coords) —
        scaled by ``value`` = (layer-0 factor, layer-1 factor). ``highlight`` = (quad (4, 3),
        amplitude) adds a Gaussian specular blob on the same face."""
        dst = self.project(quad_world)
        box = self._bbox(dst)
        if box is None:
            return
        x0, y0, x1, y1 = box
        th, tw = tex.shape
        if src is None:
            src = np.array([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]])
        off = np.array([x0, y0], dtype=np.float64)
        H = cv2.getPerspectiveTransform(src.astype(np.float32), (dst - off).astype(np.float32))
        size = (x1 - x0, y1 - y0)
        warped = cv2.warpPerspective(tex, H, size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        m = _convex_mask((size[1], size[0]), dst - off)
        region = self.layers[y0:y1, x0:x1]
        if value[0]:
            layer0 = warped * np.float32(value[0])
            if highlight is not None:
                blob = textures.gaussian_blob()
                bq = self.project(highlight[0]) - off
                n = blob.shape[0]
                Hb = cv2.getPerspectiveTransform(
                    np.array([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]],
                             np.float32), bq.astype(np.float32))
                layer0 += np.float32(highlight[1]) * cv2.warpPerspective(
                    blob, Hb, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
            region[..., 0][m] = layer0[m]
        else:
            region[..., 0][m] = 0.0
        region[..., 1][m] = warped[m] * np.float32(value[1]) if value[1] else 0.0
        self.ids[y0:y1, x0:x1][m] = face_id


def _convex_mask(shape: tuple[int, int], px: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The pixels (``shape`` = (h, w)) whose centres (integer coordinates) lie inside the
    convex polygon ``px`` (N, 2): a centre-sampled fill, exact to the sub-pixel position of
    every edge. (``cv2.fillConvexPoly`` also fills the pixels an edge only touches, each
    face half a canvas pixel too large on every side: a cover edge rendered ~0.25 px
    outward at 2× supersampling.)"""
    h, w = shape
    y = np.arange(h, dtype=np.float64)
    lo, hi = np.full(h, -np.inf), np.full(h, np.inf)  # each row's inside span in x
    nxt = np.roll(px, -1, axis=0)
    orient = 1.0 if np.sum(px[:, 0] * nxt[:, 1] - nxt[:, 0] * px[:, 1]) >= 0 else -1.0
    for a, b in zip(px, nxt):
        # inside edge a→b: orient·((b−a) × (p−a)) ≥ 0, i.e. k·x ≤ c(y) for each row y
        k = orient * (b[1] - a[1])
        c = orient * ((b[0] - a[0]) * (y - a[1]) + (b[1] - a[1]) * a[0])
        if k > 0:
            hi = np.minimum(hi, c / k)
        elif k < 0:
            lo = np.maximum(lo, c / k)
        else:
            hi = np.where(c >= 0, hi, -np.inf)  # a horizontal edge: rows in or out
    x = np.arange(w, dtype=np.float64)
    return (x[None, :] >= lo[:, None]) & (x[None, :] <= hi[:, None])


# --------------------------------------------------------------------------- objects


def _book_faces(book: Book) -> tuple[NDArray[np.float64], list[tuple[NDArray[np.float64],
                                                                     NDArray[np.float64], str]]]:
    """Cover quad (4, 3) in texture order [TL, TR, BR, BL] and the four sides as
    (quad (4, 3) top edge first, outward normal (3,), "spine" | "pages")."""
    P1, P2, P3, P4 = book.corners
    R = book.R
    down = np.array([0.0, 0.0, book.size[2]])
    sides = []
    for a, b, normal, along_y in ((P1, P2, R[:, 0], False), (P3, P4, -R[:, 0], False),
                                  (P4, P1, R[:, 1], True), (P2, P3, -R[:, 1], True)):
        is_spine = along_y and float(normal @ R[:, 1]) * book.spine_side > 0
        sides.append((np.array([a, b, b - down, a - down]), normal, "spine" if is_spine else "pages"))
    return np.array([P4, P1, P2, P3]), sides


def _draw_book(cv: _Canvas, book: Book, k: int, light: Light) -> None:
    cover_quad, sides = _book_faces(book)
    sx, sy, sz = book.size
    for quad, normal, kind in sides:
        centre = quad.mean(axis=0)
        if not cv.faces_camera(normal, centre):
            continue
        f = _face_factor(light, normal, centre)
        length = float(np.linalg.norm(quad[1] - quad[0]))
        if kind == "spine":
            tex = textures.spine(round(length, 4), round(sz, 4), book.cover)
        else:
            tex = textures.page_block(round(length, 4), round(sz, 4), book.cover.albedo,
                                      book.cover.seed + int(normal @ book.R[:, 0] > 0.5))
        cv.textured(quad, tex, (f, 0.0), ID_BOOK_SIDE)
    tex = textures.cover(book.cover, (round(sx, 4), round(sy, 4)))
    cv.textured(cover_quad, tex, (1.0, 0.0), ID_COVER + k,
                highlight=_highlight(cv, book, light))


def _highlight(cv: _Canvas, book: Book, light: Light) -> tuple[NDArray[np.float64], float] | None:
    """Mirror reflection of the light in a glossy cover, seen from this camera: a Gaussian
    blob (quad on the cover plane, amplitude) or None when it falls off the cover."""
    if book.gloss <= 0:
        return None
    h = book.size[2]
    C = cv.C
    if light.kind == "artificial":
        L = np.asarray(light.position)
        Cm = np.array([C[0], C[1], 2 * h - C[2]])  # camera mirrored in the cover plane
        t = (h - Cm[2]) / (L[2] - Cm[2])
        p = Cm + t * (L - Cm)
    else:
        d = np.asarray(light.direction)
        r = np.array([-d[0], -d[1], d[2]])  # the mirror direction toward the camera
        p = C - (C[2] - h) / r[2] * r
    # Off the cover by more than the blob's reach: no highlight.
    local = book.R.T @ (p - np.asarray(book.center))
    s = 3.0 * book.gloss_sigma
    if abs(local[0]) > 0.5 * book.size[0] + s or abs(local[1]) > 0.5 * book.size[1] + s:
        return None
    quad = p + np.array([[-s, s, 0.0], [s, s, 0.0], [s, -s, 0.0], [-s, -s, 0.0]])
    return quad, book.gloss * (1.0 - light.ambient)


def _mug_rings(mug: Mug, n: int = 24) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([mug.center[0] + mug.radius * np.cos(t),
                            mug.center[1] + mug.radius * np.sin(t), np.zeros(n)])
    top = ring + [0.0, 0.0, mug.height]
    return ring, top


def _draw_mug(cv: _Canvas, mug: Mug, light: Light) -> None:
    bottom, top = _mug_rings(mug)
    n = len(bottom)
    c = np.array([mug.center[0], mug.center[1], 0.0])
    hd = np.radians(mug.handle_deg)
    hdir = np.array([np.cos(hd), np.sin(hd), 0.0])
    s = np.linspace(0.0, np.pi, 12)
    handle = c + np.outer(mug.radius - 0.003 + 0.028 * np.sin(s), hdir) \
        + np.outer(0.5 * mug.height + 0.032 * np.cos(s), [0.0, 0.0, 1.0])
    handle_front = cv.faces_camera(hdir, c + mug.radius * hdir)
    handle_value = (mug.albedo * _face_factor(light, hdir, handle.mean(axis=0)), 0.0)
    if not handle_front:
        cv.polyline(handle, 0.008, handle_value, ID_CLUTTER)
    for i in range(n):
        j = (i + 1) % n
        quad = np.array([top[i], top[j], bottom[j], bottom[i]])
        normal = quad.mean(axis=0) - c
        normal[2] = 0.0
        normal /= np.linalg.norm(normal)
        if cv.faces_camera(normal, quad.mean(axis=0)):
            cv.flat(quad, (mug.albedo * _face_factor(light, normal, quad.mean(axis=0)), 0.0),
                    ID_CLUTTER)
    cv.flat(top, (mug.albedo, 0.0), ID_CLUTTER)
    inner = c + (top - c) * ((mug.radius - 0.004) / mug.radius)
    inner[:, 2] = mug.height
    cv.flat(inner, (0.25 * mug.albedo * light.ambient + 0.01, 0.0), ID_CLUTTER)
    if handle_front:
        cv.polyline(handle, 0.008, handle_value, ID_CLUTTER)


def _pen_vertices(pen: Pen) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Hexagon vertices at both ends, (6, 3) each, and the axis (3,)."""
    yaw = np.radians(pen.yaw_deg)
    d = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    e1, e2 = np.array([-np.sin(yaw), np.cos(yaw), 0.0]), np.array([0.0, 0.0, 1.0])
    phi = np.radians(60.0 * np.arange(6))
    apothem = pen.radius * np.cos(np.radians(30.0))
    axis = np.array([pen.center[0], pen.center[1], apothem])
    ring = axis + pen.radius * (np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2))
    half = 0.5 * pen.length * d
    return ring - half, ring + half, d


def _draw_pen(cv: _Canvas, pen: Pen, light: Light) -> None:
    a, b, d = _pen_vertices(pen)
    centre = 0.5 * (a.mean(axis=0) + b.mean(axis=0))
    faces = [(np.array([a[i], a[(i + 1) % 6], b[(i + 1) % 6], b[i]])) for i in range(6)]
    faces += [a, b[::-1]]
    for quad in faces:
        normal = quad.mean(axis=0) - centre
        if len(quad) == 6:
            normal = -d if np.allclose(quad, a) else d
        normal = normal / np.linalg.norm(normal)
        if cv.faces_camera(normal, quad.mean(axis=0)):
            cv.flat(quad, (pen.albedo * _face_factor(light, normal, quad.mean(axis=0)), 0.0),
                    ID_CLUTTER)


def _solid_points(obj: Book | Mug | Pen) -> NDArray[np.float64]:
    """Vertices (N, 3) whose shadow outline is the object's."""
    if isinstance(obj, Book):
        top = obj.corners
        return np.vstack([top, top - [0.0, 0.0, obj.size[2]]])
    if isinstance(obj, Mug):
        return np.vstack(_mug_rings(obj, 16))
    a, b, _ = _pen_vertices(obj)
    return np.vstack([a, b])


def _centre(obj: Book | Mug | Pen) -> NDArray[np.float64]:
    return _solid_points(obj).mean(axis=0)


# --------------------------------------------------------------------------- one camera


def _draw_scene(cv: _Canvas, scene: Scene) -> None:
    light = scene.light
    # Floor far below, in a frame that starts under the camera (every corner in front of it).
    fwd = cv.T[2, :3].copy()  # camera z axis in world
    fwd[2] = 0.0
    fwd = fwd / max(np.linalg.norm(fwd), 1e-9)
    side = np.array([-fwd[1], fwd[0], 0.0])
    foot = np.array([cv.C[0], cv.C[1], FLOOR_Z])
    floor_quad = np.array([foot - 6 * side + 8 * fwd, foot + 6 * side + 8 * fwd,
                           foot + 6 * side, foot - 6 * side])
    cv.textured(floor_quad, textures.floor(), (_FLOOR_FACTOR, 0.0), ID_FLOOR)
    # Desk slab: edges, then the wood top.
    (x0, x1), (y0, y1) = DESK
    top = np.array([[x0, y1, 0.0], [x1, y1, 0.0], [x1, y0, 0.0], [x0, y0, 0.0]])
    down = np.array([0.0, 0.0, DESK_THICKNESS])
    wood_albedo = float(textures.wood(scene.desk_variant).mean())
    for i, normal in enumerate(([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0])):
        a, b = top[i], top[(i + 1) % 4]
        quad = np.array([a, b, b - down, a - down])
        n = np.array(normal)
        if cv.faces_camera(n, quad.mean(axis=0)):
            cv.flat(quad, (0.8 * wood_albedo * _face_factor(light, n, quad.mean(axis=0)), 0.0),
                    ID_DESK)
    ox, oy = scene.desk_offset
    src = 1000.0 * np.array([[ox, oy], [ox + x1 - x0, oy], [ox + x1 - x0, oy + y1 - y0],
                             [ox, oy + y1 - y0]]) - 0.5  # 1 texel per mm
    cv.textured(top, textures.wood(scene.desk_variant), (0.0, 1.0), ID_DESK, src=src)
    # Flat things on the desk: marker sheet, loose paper, cables.
    k = 0.5 * MARKER_PAPER
    marker_quad = np.array([[-k, k, 0.0], [k, k, 0.0], [k, -k, 0.0], [-k, -k, 0.0]])
    cv.textured(marker_quad, textures.marker(), (0.0, 1.0), ID_MARKER)
    for paper in scene.papers:
        fp = paper.footprint()
        quad = np.column_stack([fp[[3, 0, 1, 2]], np.full(4, 2e-4)])
        cv.textured(quad, textures.paper(paper.size, paper.seed), (0.0, 1.0), ID_CLUTTER)
    for cable in scene.cables:
        pts = np.column_stack([np.asarray(cable.points), np.full(len(cable.points), cable.width / 2)])
        cv.polyline(pts, cable.width, (0.0, cable.albedo), ID_CLUTTER)
    # Solid objects, far to near.
    solids: list[tuple[float, Any, int]] = [(0.0, b, i) for i, b in enumerate(scene.books)]
    solids += [(0.0, m, -1) for m in scene.mugs] + [(0.0, p, -1) for p in scene.pens]
    order = sorted(solids, key=lambda s: -float(np.linalg.norm(_centre(s[1]) - cv.C)))
    for _, obj, i in order:
        if isinstance(obj, Book):
            _draw_book(cv, obj, i, light)
        elif isinstance(obj, Mug):
            _draw_mug(cv, obj, light)
        else:
            _draw_pen(cv, obj, light)


def _render_camera(scene: Scene, camera: Camera, ss: int) -> tuple[
        NDArray[np.float32], NDArray[np.int16], NDArray[np.float64]]:
    """Luminance (H, W) cd/m² of the raw image, its id map (H, W), and the visible fraction of
    each book's cover (n_books,)."""
    rig, light = scene.rig, scene.light
    optics = _optics(rig, camera)
    T = rig.T_camera_world(camera)
    cv = _Canvas(optics, T, ss)
    _draw_scene(cv, scene)
    wc, hc = optics.canvas
    layers = cv2.resize(cv.layers, (wc, hc), interpolation=cv2.INTER_AREA) if ss > 1 else cv.layers
    ids_ideal = cv.ids[::ss, ::ss]
    K = optics.K_lo

    def to_px(P: NDArray[np.float64]) -> NDArray[np.float64]:
        Pc = P @ T[:3, :3].T + T[:3, 3]
        p = Pc @ K.T
        return p[:, :2] / p[:, 2:3]

    # Illuminance over the image from the desk point each pixel looks at (coarse grid).
    step = 8
    gx, gy = np.meshgrid(np.arange(0, wc + step, step, dtype=np.float64),
                         np.arange(0, hc + step, step, dtype=np.float64))
    H_desk = K @ T[:3][:, [0, 1, 3]]  # desk (x, y, 1) -> ideal pixel
    q = np.column_stack([gx.ravel(), gy.ravel(), np.ones(gx.size)]) @ np.linalg.inv(H_desk).T
    xy = q[:, :2] / np.where(np.abs(q[:, 2:3]) < 1e-12, 1e-12, q[:, 2:3])
    g = illuminance_profile(light, xy).reshape(gx.shape).astype(np.float32)
    g = cv2.resize(g, (gx.shape[1] * step, gx.shape[0] * step), interpolation=cv2.INTER_LINEAR)
    g = g[:hc, :wc]
    # Cast shadows (blurred by the penumbra) and contact shadows next to each object's base.
    shadow = np.zeros((hc, wc), np.float32)
    contact = np.zeros((hc, wc), np.float32)
    solids = list(scene.books) + list(scene.mugs) + list(scene.pens)
    for obj in solids:
        P = _solid_points(obj)
        on_desk = np.column_stack([_shadow_points(light, P), np.zeros(len(P))])
        hull = cv2.convexHull(np.round(to_px(on_desk) * (1 << _SHIFT)).astype(np.int32))
        cv2.fillConvexPoly(shadow, hull, 1.0, cv2.LINE_8, _SHIFT)
        base = P[P[:, 2] < 1e-3] if isinstance(obj, Book | Mug) else P
        base = np.column_stack([base[:, :2], np.zeros(len(base))])
        hull = cv2.convexHull(np.round(to_px(base) * (1 << _SHIFT)).astype(np.int32))
        cv2.fillConvexPoly(contact, hull, 1.0, cv2.LINE_8, _SHIFT)
    shadow = cv2.GaussianBlur(shadow, (0, 0), light.penumbra_px)
    contact = cv2.GaussianBlur(contact, (0, 0), 6.0)
    a = np.float32(light.ambient)
    desk_light = a * (1.0 - np.float32(_AO_STRENGTH) * contact) + (1.0 - a) * (1.0 - shadow)
    luminance = np.float32(light.lux / np.pi) * g * (layers[..., 0] + layers[..., 1] * desk_light)
    # Lens distortion, vignetting, blur.
    raw = cv2.remap(luminance, optics.map_x, optics.map_y, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    raw *= optics.vignette
    raw = cv2.GaussianBlur(raw, (0, 0), scene.blur_px)
    ids_raw = cv2.remap(np.ascontiguousarray(ids_ideal), optics.map_x, optics.map_y,
                        cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
    # Visible share of each cover: cover pixels on screen / the whole cover's area.
    counts = np.bincount((ids_ideal[optics.valid].astype(np.int64) - ID_COVER).clip(-1) + 1,
                         minlength=len(scene.books) + 1)[1:]
    visible = np.zeros(len(scene.books))
    for i, book in enumerate(scene.books):
        px = to_px(book.corners)
        area = 0.5 * abs(np.dot(px[:, 0], np.roll(px[:, 1], -1)) - np.dot(px[:, 1], np.roll(px[:, 0], -1)))
        visible[i] = min(1.0, counts[i] / max(area, 1e-9))
    return raw, ids_raw, visible


# --------------------------------------------------------------------------- public


def render(scene: Scene, rng: np.random.Generator | int | None = None, *,
           supersample: int = 2) -> Rendering:
    """Render a stereo pair of ``scene`` with its ground truth.

    Parameters
    ----------
    scene : Scene
    rng : Generator, int or None
        Sensor noise only (the scene is already fixed); the same seed gives the same images.
    supersample : int
        Supersampling factor per axis (2 → 4 samples per pixel).

    Returns
    -------
    Rendering
    """
    if int(supersample) != supersample or supersample < 1:
        raise ValueError(f"supersample: expected a positive integer, got {supersample!r}")
    rng = np.random.default_rng(rng)
    lum_l, ids_l, vis_l = _render_camera(scene, "left", int(supersample))
    lum_r, ids_r, vis_r = _render_camera(scene, "right", int(supersample))
    exposure = choose_exposure(float(np.median(lum_l[::4, ::4])), scene.light.lux, scene.exposure)
    left = expose(lum_l, exposure, rng, prnu=_optics(scene.rig, "left").prnu)
    right = expose(lum_r, exposure, rng, prnu=_optics(scene.rig, "right").prnu)
    return Rendering(left=left, right=right, truth=scene_truth(scene, vis_l, vis_r, exposure),
                     exposure=exposure, ids_left=ids_l, ids_right=ids_r)


def scene_truth(scene: Scene, visible_left: NDArray[np.float64], visible_right: NDArray[np.float64],
                exposure: Exposure | None = None) -> dict[str, Any]:
    """DESIGN §3's ``truth.json`` content for ``scene`` (world = marker frame, metres)."""
    books = []
    for i, book in enumerate(scene.books):
        books.append({
            "id": i,
            "center": [float(v) for v in book.center],
            "R": book.R.tolist(),
            "size": [float(v) for v in book.size],
            "corners": book.corners.tolist(),
            "visible_left": round(float(visible_left[i]), 4),
            "visible_right": round(float(visible_right[i]), 4),
            "yaw_deg": float(book.yaw_deg),
            "cover": book.cover.kind,
            "glossy": book.gloss > 0,
        })
    light = scene.light
    out: dict[str, Any] = {
        "lux": float(light.lux),
        "light": light.kind,
        "exposure": scene.exposure,
        "desk_plane": list(DESK_PLANE),
        "world_frame": "marker",
        "T_world_left": scene.rig.T_world_left.tolist(),
        "marker": {"dictionary": "DICT_4X4_50", "id": MARKER_ID, "size": MARKER_SIZE},
        "books": books,
    }
    if exposure is not None:
        out["exposure_s"] = exposure.time_s
        out["gain"] = exposure.gain
    return out

