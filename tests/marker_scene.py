"""A self-contained render of the desk marker on a textured desk, for the marker/register tests.

Kept independent of ``rovis.synth`` (built separately) so the marker stage is tested against an
image formation it does not share: each plane texture is mapped by its exact homography into a
supersampled ideal image, box-downsampled, then lens distortion is applied by sampling the ideal
image at the undistorted position of every raw pixel.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis import geometry
from rovis.calib import StereoRig, make_rig, undistort_iter

SIDE = 0.10  # metres
_MASTER_PX = 1200  # master texture pixels across the black square (200 per cell)


def marker_texture(side_px: int = _MASTER_PX) -> tuple[NDArray[np.uint8], float]:
    """The printed marker (DICT_4X4_50 id 0) with a one-cell white quiet border, and metres/px.

    ``side_px`` texels across the black square: an area-averaged reduction of a sharp master,
    so that a texel's grey level is its ink coverage. Sampled at about one texel per
    supersampled pixel, edges then land where they are, not on the texel grid.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    img = cv2.aruco.generateImageMarker(dictionary, 0, _MASTER_PX)
    quiet = _MASTER_PX // 6
    img = cv2.copyMakeBorder(img, quiet, quiet, quiet, quiet, cv2.BORDER_CONSTANT, value=255)
    img = np.where(img > 127, 235.0, 20.0).astype(np.float32)  # paper and ink
    n = int(round(side_px * img.shape[0] / _MASTER_PX))
    if n < img.shape[0]:
        img = cv2.resize(img, (n, n), interpolation=cv2.INTER_AREA)
    extent = SIDE * (_MASTER_PX + 2 * quiet) / _MASTER_PX  # metres across the texture
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), extent / img.shape[0]


def desk_texture(rng: np.random.Generator, n: int = 1200) -> tuple[NDArray[np.uint8], float]:
    """A wood-ish grey desk covering 2.4 m × 2.4 m around the marker, and metres/pixel."""
    noise = cv2.GaussianBlur(rng.normal(0, 1, (n, n)).astype(np.float32), (0, 0), 6)
    stripes = np.sin(np.linspace(0, 60, n))[None, :].astype(np.float32)
    img = 120 + 40 * noise / noise.std() + 10 * stripes
    return np.clip(img, 0, 255).astype(np.uint8), 2.4 / n


def _texture_to_plane(n_px: int, m_per_px: float) -> NDArray[np.float64]:
    """3×3 map texture pixel (u, v) → marker-plane (x, y): centred, y up (v down)."""
    c = (n_px - 1) / 2.0
    return np.array([[m_per_px, 0.0, -c * m_per_px], [0.0, -m_per_px, c * m_per_px], [0, 0, 1]])


def render_view(rig: StereoRig, camera: str, rng: np.random.Generator, *,
                supersample: int = 3, noise: float = 2.0) -> NDArray[np.uint8]:
    """Render the desk plane (world z = 0 = marker frame) into one raw camera image."""
    w, h = rig.image_size
    K, D = rig.intrinsics(camera)
    T_cam_world = rig.T_camera_world(camera)
    H_plane = K @ T_cam_world[:3][:, [0, 1, 3]]  # plane (x, y, 1) → ideal pixel
    s = supersample
    # ideal pixel p (integer centres) ↔ supersampled q = s·p + (s − 1)/2
    S = np.array([[s, 0, (s - 1) / 2.0], [0, s, (s - 1) / 2.0], [0, 0, 1]])
    big = np.zeros((h * s, w * s), np.uint8)
    # about one marker texel per supersampled pixel where the marker looks largest
    ends = K @ T_cam_world[:3] @ np.array([[-SIDE / 2, -SIDE / 2, 0, 1], [SIDE / 2, -SIDE / 2, 0, 1],
                                            [SIDE / 2, SIDE / 2, 0, 1], [-SIDE / 2, SIDE / 2, 0, 1]]).T
    ends = (ends[:2] / ends[2]).T
    side_px = s * np.linalg.norm(ends - np.roll(ends, 1, axis=0), axis=1).max()
    for tex, mpp in (desk_texture(rng), marker_texture(int(np.ceil(side_px)))):
        H = S @ H_plane @ _texture_to_plane(tex.shape[0], mpp)
        mask = cv2.warpPerspective(np.full_like(tex, 255), H, (w * s, h * s), flags=cv2.INTER_NEAREST)
        warped = cv2.warpPerspective(tex, H, (w * s, h * s), flags=cv2.INTER_LINEAR)
        big = np.where(mask > 0, warped, big)
    ideal = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    # raw pixel d shows what the ideal camera sees at undistort(d)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), axis=-1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
    und = undistort_iter(grid.astype(np.float64), K, D, K, crit).reshape(h, w, 2)
    raw = cv2.remap(ideal, und[..., 0].astype(np.float32), und[..., 1].astype(np.float32),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    raw += rng.normal(0.0, noise, raw.shape).astype(np.float32)
    return np.clip(np.rint(raw), 0, 255).astype(np.uint8)


def marker_scene(rng: np.random.Generator | int | None = None, *, distance: float | None = None,
                 down_deg: float | None = None) -> tuple[StereoRig, NDArray[np.uint8], NDArray[np.uint8]]:
    """A rig 0.9–1.4 m from the marker looking down 40–70°, and its left/right images.

    Returns the true rig (world = marker frame) and the two raw images.
    """
    rng = np.random.default_rng(rng)
    distance = rng.uniform(0.9, 1.4) if distance is None else distance
    down = np.radians(rng.uniform(40, 70) if down_deg is None else down_deg)
    heading = rng.uniform(0, 2 * np.pi)
    # look at a point beside the marker so it is not always at the image centre
    target = np.array([*rng.uniform(-0.15, 0.15, 2), 0.0])
    back = np.array([-np.cos(heading), -np.sin(heading), 0.0])
    eye = target + distance * (np.cos(down) * back + np.array([0.0, 0.0, np.sin(down)]))
    rig = make_rig(T_world_left=geometry.look_at(eye, target), world_frame="marker")
    return rig, render_view(rig, "left", rng), render_view(rig, "right", rng)
