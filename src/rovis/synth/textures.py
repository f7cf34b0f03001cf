"""Textures of the synthetic library desk, as albedo maps.

Every texture is a ``float32`` array of diffuse albedo in [0, 1] (the camera is monochrome, so
one channel is enough). Textures that do not depend on the scene (wood, the marker, the floor,
scikit-image's sample photographs) are built once per process and cached; per-object textures
(covers, page blocks, paper sheets) are built from a small frozen spec and cached too, so a
scene rendered under many lights (protocol ``table2``) builds them once.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

Texture = NDArray[np.float32]

MARKER_DICT = cv2.aruco.DICT_4X4_50
MARKER_ID = 0
MARKER_SIZE = 0.10  # m, the black square
MARKER_PAPER = 0.14  # m, the printed sheet around it (white quiet zone of 2 cm)

COVER_PX_PER_M = 1500.0  # ~1 texel per supersampled pixel at 1 m
PAGE_PX_PER_M = 2000.0
PAPER_PX_PER_M = 1000.0

CoverKind = Literal["plain", "dark", "light", "desk", "printed", "photo"]
COVER_KINDS: tuple[CoverKind, ...] = ("plain", "dark", "light", "desk", "printed", "photo")

# Real photographs bundled with scikit-image (no download needed), used as picture covers.
PHOTO_NAMES = ("astronaut", "camera", "cat", "chelsea", "coffee", "rocket", "moon", "coins",
               "clock", "immunohistochemistry", "hubble_deep_field", "retina", "brick", "grass",
               "gravel", "page", "text")

_LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
_FONTS = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_COMPLEX,
          cv2.FONT_HERSHEY_TRIPLEX, cv2.FONT_HERSHEY_PLAIN)


# --------------------------------------------------------------------------- shared helpers


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], scale: float) -> Texture:
    """Band-limited noise, zero mean, unit std, features of about ``scale`` pixels."""
    h, w = shape
    sh, sw = max(2, int(np.ceil(h / scale)) + 2), max(2, int(np.ceil(w / scale)) + 2)
    coarse = rng.standard_normal((sh, sw)).astype(np.float32)
    out = cv2.resize(coarse, (int(sw * scale), int(sh * scale)), interpolation=cv2.INTER_CUBIC)[:h, :w]
    out -= out.mean()
    return out / max(float(out.std()), 1e-6)


def _to_albedo(img_u8: NDArray[np.uint8], lo: float = 0.03, hi: float = 0.88) -> Texture:
    """8-bit reflectance print → albedo: paper white ``hi``, full ink ``lo``."""
    return (lo + (hi - lo) * img_u8.astype(np.float32) / 255.0).astype(np.float32)


# --------------------------------------------------------------------------- scene-independent


@lru_cache(maxsize=8)
def wood(variant: int = 0) -> Texture:
    """A wood-grain desk top, 1 texel per mm, grain along the texture's x (rows), 2.0 × 1.5 m.

    ``variant`` picks one of a few tones and grain patterns; the same variant is the same
    texture in every process.
    """
    rng = np.random.default_rng(1000 + variant)
    h, w = 1500, 2000
    base = (0.28, 0.42, 0.55, 0.20)[variant % 4]  # oak, beech, maple, walnut-ish
    # Growth rings cut lengthwise: iso-lines of a field that bends slowly along the grain
    # (x) and faster across it, with late wood a narrow dark band in each ring.
    yy = np.arange(h, dtype=np.float32)[:, None]
    warp = 25.0 * _anisotropic_noise(rng, (h, w), (120.0, 900.0)) \
        + 4.0 * _anisotropic_noise(rng, (h, w), (20.0, 200.0))
    phase = (yy + warp) / rng.uniform(6.0, 11.0)
    late = np.clip(3.0 * np.cos(2 * np.pi * phase) - 1.8, 0.0, 1.0)
    pores = 0.6 * _anisotropic_noise(rng, (h, w), (1.0, 40.0))  # streaks along the grain
    tone = 0.05 * _anisotropic_noise(rng, (h, w), (150.0, 600.0))
    tex = base * (1.0 - 0.16 * late + 0.03 * pores + tone)
    # Plank joints every ~15-25 cm across the grain, each plank its own shade.
    y = 0
    while y < h:
        y += int(rng.integers(150, 260))
        tex[max(0, y - 1):y + 1] *= 0.55
        tex[y + 1:] *= rng.uniform(0.93, 1.07)
    return np.clip(tex, 0.02, 0.95).astype(np.float32)


def _anisotropic_noise(rng: np.random.Generator, shape: tuple[int, int],
                       scale: tuple[float, float]) -> Texture:
    """Smooth noise with features ``scale`` = (across rows, along columns) pixels, unit std."""
    h, w = shape
    sh, sw = max(2, int(np.ceil(h / scale[0])) + 3), max(2, int(np.ceil(w / scale[1])) + 3)
    coarse = rng.standard_normal((sh, sw)).astype(np.float32)
    out = cv2.resize(coarse, (int(sw * scale[1]), int(sh * scale[0])),
                     interpolation=cv2.INTER_CUBIC)[:h, :w]
    out -= out.mean()
    return out / max(float(out.std()), 1e-6)


@lru_cache(maxsize=1)
def floor() -> Texture:
    """Grey carpet/floor far below the desk, 1 texel per 5 mm, 512 × 512."""
    rng = np.random.default_rng(7)
    tex = 0.18 * (1.0 + 0.15 * _smooth_noise(rng, (512, 512), 3.0)
                  + 0.10 * _smooth_noise(rng, (512, 512), 60.0))
    return np.clip(tex, 0.02, 0.9).astype(np.float32)


@lru_cache(maxsize=1)
def marker() -> Texture:
    """The ArUco marker (DICT_4X4_50, id 0) printed on a white sheet, 2400 texels per metre.

    The black square spans the central ``MARKER_SIZE`` of the ``MARKER_PAPER`` sheet; texel rows
    run from the marker's top (world +y) down, columns along world +x.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(MARKER_DICT)
    side = 240  # px for 0.10 m
    img = cv2.aruco.generateImageMarker(dictionary, MARKER_ID, side)
    pad = int(round((MARKER_PAPER - MARKER_SIZE) / 2 / MARKER_SIZE * side))
    img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
    return _to_albedo(img, lo=0.04, hi=0.85)


@lru_cache(maxsize=1)
def _photos() -> tuple[Texture, ...]:
    """scikit-image's bundled sample photographs as grey albedo, loaded once per process."""
    import skimage.data  # heavy import; kept out of module import and the per-frame path

    out = []
    for name in PHOTO_NAMES:
        img = np.asarray(getattr(skimage.data, name)())
        if img.ndim == 3:
            img = cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
        out.append(_to_albedo(img.astype(np.uint8), lo=0.03, hi=0.85))
    return tuple(out)


# --------------------------------------------------------------------------- per object


@dataclass(frozen=True)
class CoverSpec:
    """What a book cover looks like.

    Attributes
    ----------
    kind : {"plain", "dark", "light", "desk", "printed", "photo"}
    albedo : float
        Base diffuse reflectance of the cover material.
    seed : int
        Seeds the procedural print / the photo crop.
    """

    kind: CoverKind
    albedo: float
    seed: int


def _texture_size(size_m: tuple[float, float], px_per_m: float) -> tuple[int, int]:
    return max(8, int(round(size_m[0] * px_per_m))), max(8, int(round(size_m[1] * px_per_m)))


def _random_words(rng: np.random.Generator, n: int) -> str:
    return " ".join("".join(rng.choice(list(_LETTERS), size=int(rng.integers(2, 9))))
                    for _ in range(n))


def _print_text(img: NDArray[np.uint8], rng: np.random.Generator, text: str, org: tuple[int, int],
                height_px: float, color: int, max_width: int) -> int:
    """Draw ``text`` about ``height_px`` tall, shrunk to fit ``max_width``; returns its height."""
    font = int(rng.choice(_FONTS))
    thick = int(rng.integers(1, 4)) if height_px > 20 else 1
    (tw, th), _ = cv2.getTextSize(text, font, 1.0, thick)
    scale = min(height_px / max(th, 1), max_width / max(tw, 1))
    cv2.putText(img, text, org, font, scale, color, thick, cv2.LINE_AA)
    return int(th * scale)


@lru_cache(maxsize=256)
def cover(spec: CoverSpec, size_m: tuple[float, float]) -> Texture:
    """Albedo map of a cover ``size_m`` = (along book x, along book y) metres.

    Returns
    -------
    ndarray, shape (H, W), float32
        Columns along the book's x axis, rows from +y (top) to −y, ``COVER_PX_PER_M``.
    """
    rng = np.random.default_rng(spec.seed)
    w, h = _texture_size(size_m, COVER_PX_PER_M)
    a = float(spec.albedo)
    # Cloth / paper grain: low contrast even on a "plain" cover.
    grain = 0.025 * rng.standard_normal((h, w)).astype(np.float32) \
        + 0.03 * _smooth_noise(rng, (h, w), 80.0)
    if spec.kind in ("plain", "dark", "light", "desk"):
        tex = a * (1.0 + grain)
        if spec.kind == "desk":  # a wood-look or desk-toned binding
            tex *= 1.0 + 0.04 * _smooth_noise(rng, (h, w), 25.0)
        elif rng.random() < 0.5:  # a faint embossed title, barely visible
            img = np.full((h, w), 128, np.uint8)
            _print_text(img, rng, _random_words(rng, 2), (w // 8, h // 3), h / 10, 118, int(w * 0.75))
            tex *= img.astype(np.float32) / 128.0
        return np.clip(tex, 0.01, 0.95).astype(np.float32)
    if spec.kind == "photo":
        photos = _photos()
        photo = photos[int(rng.integers(len(photos)))]
        ph, pw = photo.shape
        aspect = w / h
        ch = int(min(ph, pw / aspect) * rng.uniform(0.6, 1.0))
        cw = int(ch * aspect)
        y0, x0 = int(rng.integers(0, ph - ch + 1)), int(rng.integers(0, pw - cw + 1))
        tex = cv2.resize(photo[y0:y0 + ch, x0:x0 + cw], (w, h), interpolation=cv2.INTER_AREA)
        if rng.random() < 0.7:  # a title band over the picture
            band = np.full((max(4, h // 5), w), int(255 * rng.uniform(0.0, 1.0)), np.uint8)
            ink = 0 if band[0, 0] > 128 else 240
            _print_text(band, rng, _random_words(rng, 2), (w // 12, int(band.shape[0] * 0.75)),
                        band.shape[0] * 0.55, ink, int(w * 0.85))
            y = int(rng.uniform(0.05, 0.75) * h)
            tex[y:y + band.shape[0]] = _to_albedo(band)[: h - y]
        return np.clip(tex * (1.0 + 0.5 * grain), 0.01, 0.95).astype(np.float32)
    # printed: background, graphics, title, author
    bg = int(255 * np.clip((a - 0.03) / 0.85, 0, 1))
    img = np.full((h, w), bg, np.uint8)
    ink = 20 if bg > 110 else 235
    for _ in range(int(rng.integers(1, 5))):
        shade = int(rng.integers(0, 256))
        kind = rng.integers(3)
        if kind == 0:  # a band across the cover
            y, t = int(rng.uniform(0, h)), int(rng.uniform(0.03, 0.25) * h)
            img[y:y + t] = shade
        elif kind == 1:  # a block
            x0, y0 = int(rng.uniform(0, 0.7) * w), int(rng.uniform(0, 0.7) * h)
            cv2.rectangle(img, (x0, y0), (x0 + int(rng.uniform(0.1, 0.5) * w),
                                          y0 + int(rng.uniform(0.1, 0.4) * h)), shade, -1)
        else:  # a disc or ring
            c = (int(rng.uniform(0.2, 0.8) * w), int(rng.uniform(0.2, 0.8) * h))
            cv2.circle(img, c, int(rng.uniform(0.08, 0.3) * min(w, h)), shade,
                       -1 if rng.random() < 0.6 else int(rng.integers(2, 8)), cv2.LINE_AA)
    if rng.random() < 0.4:  # a frame near the edge
        m = int(rng.uniform(0.03, 0.08) * min(w, h))
        cv2.rectangle(img, (m, m), (w - m, h - m), ink, int(rng.integers(1, 4)))
    y = int(rng.uniform(0.12, 0.35) * h)
    for _ in range(int(rng.integers(1, 3))):
        y += _print_text(img, rng, _random_words(rng, int(rng.integers(1, 3))), (w // 10, y),
                         rng.uniform(0.06, 0.12) * h, ink, int(w * 0.8)) + h // 25
    _print_text(img, rng, _random_words(rng, 2).title(), (w // 10, int(h * 0.9)),
                rng.uniform(0.03, 0.05) * h, ink, int(w * 0.6))
    return np.clip(_to_albedo(img) * (1.0 + 0.5 * grain), 0.01, 0.95).astype(np.float32)


@lru_cache(maxsize=256)
def page_block(length_m: float, thickness_m: float, board_albedo: float, seed: int) -> Texture:
    """Side of a book: page edges between the two cover boards.

    Returns
    -------
    ndarray, shape (H, 32), float32
        Rows from the top cover (row 0) down to the desk, ``PAGE_PX_PER_M`` per metre;
        constant along the length (32 columns, stretched by the homography).
    """
    rng = np.random.default_rng(seed)
    h = max(6, int(round(thickness_m * PAGE_PX_PER_M)))
    rows = rng.uniform(0.70, 0.85) * (1.0 + 0.05 * rng.standard_normal(h))
    board = max(1, int(round(0.0015 * PAGE_PX_PER_M)))  # 1.5 mm boards
    rows[:board] = rows[-board:] = 0.6 * board_albedo  # board edges are darker than the face
    tex = np.repeat(rows[:, None], 32, axis=1)
    return np.clip(tex, 0.01, 0.95).astype(np.float32)


@lru_cache(maxsize=256)
def spine(length_m: float, thickness_m: float, spec: CoverSpec) -> Texture:
    """Spine of a book: cover material with a few printed bands, rows from the top cover down.

    Returns
    -------
    ndarray, shape (H, W), float32
        Columns along the book's x axis.
    """
    rng = np.random.default_rng(spec.seed + 1)
    w = max(8, int(round(length_m * COVER_PX_PER_M / 2)))
    h = max(4, int(round(thickness_m * COVER_PX_PER_M)))
    tex = np.full((h, w), spec.albedo, np.float32)
    for _ in range(int(rng.integers(0, 4))):
        x, t = int(rng.uniform(0, w)), int(rng.uniform(0.01, 0.1) * w)
        tex[:, x:x + t] = rng.uniform(0.03, 0.85)
    return tex


@lru_cache(maxsize=64)
def paper(size_m: tuple[float, float], seed: int) -> Texture:
    """A loose printed sheet: white paper with lines of text (grey word blocks).

    Returns
    -------
    ndarray, shape (H, W), float32
        Columns along the sheet's x axis, ``PAPER_PX_PER_M``.
    """
    rng = np.random.default_rng(seed)
    w, h = _texture_size(size_m, PAPER_PX_PER_M)
    white = rng.uniform(0.78, 0.88)
    tex = np.full((h, w), white, np.float32)
    margin = int(0.1 * w)
    y, line = int(0.08 * h), max(2, int(rng.uniform(0.004, 0.007) * PAPER_PX_PER_M))
    if rng.random() < 0.2:  # a blank sheet or a sticky note
        return (tex * (1.0 + 0.01 * rng.standard_normal((h, w)))).astype(np.float32)
    while y < h - int(0.08 * h):
        x = margin
        end = w - margin if rng.random() > 0.15 else int(rng.uniform(0.3, 0.8) * w)
        while x < end:
            word = int(rng.integers(2, 9)) * max(1, line // 2)
            tex[y:y + line // 2 + 1, x:min(x + word, end)] = white * rng.uniform(0.35, 0.6)
            x += word + max(1, line // 2)
        y += int(line * rng.uniform(1.6, 2.0))
        if rng.random() < 0.08:
            y += 2 * line  # paragraph break
    return tex


@lru_cache(maxsize=4)
def gaussian_blob(n: int = 64) -> Texture:
    """A unit-peak 2-D Gaussian on an ``n × n`` grid spanning ±3 σ (specular highlights)."""
    x = np.linspace(-3.0, 3.0, n, dtype=np.float32)
    g = np.exp(-0.5 * x * x)
    return np.outer(g, g).astype(np.float32)
