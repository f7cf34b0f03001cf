"""Sampling of synthetic library-desk scenes (DESIGN §4) into frozen dataclasses.

World frame = the desk marker's frame (DESIGN §2–3): origin at the marker centre, x along its
top edge, y toward its top, z up; the desk top is ``z = 0``. Books lie flat inside the
workspace ``x ∈ [0.05, 0.85], y ∈ [0.05, 0.65]`` m; clutter lies anywhere on the desk but
never on the marker. A scene says *what* is there; :func:`rovis.synth.render` draws it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from rovis import geometry
from rovis.calib import StereoRig, make_rig
from rovis.synth.textures import COVER_KINDS, MARKER_PAPER, CoverSpec, CoverKind

LightKind = Literal["daylight", "artificial"]
ExposureMode = Literal["auto", "fixed"]
LIGHT_KINDS: tuple[LightKind, ...] = ("daylight", "artificial")
EXPOSURE_MODES: tuple[ExposureMode, ...] = ("auto", "fixed")

WORKSPACE = ((0.05, 0.85), (0.05, 0.65))  # x range, y range, metres (DESIGN §3)
DESK = ((-0.40, 1.30), (-0.35, 1.00))  # the desk top, metres
DESK_THICKNESS = 0.03
FLOOR_Z = -0.75
LUX_RANGE = (15.0, 1200.0)  # the paper's §5 range
_KEEP_OUT = 0.5 * MARKER_PAPER + 0.005  # nothing may touch the marker sheet, metres
_WOOD_ALBEDO = (0.28, 0.42, 0.55, 0.20)  # mean albedo of textures.wood(variant)


# --------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class Book:
    """A closed book lying flat on the desk.

    Attributes
    ----------
    center : tuple of float, (3,)
        Centre of the top cover (the diagonals' intersection), world, metres; ``z = size[2]``.
    yaw_deg : float
        Heading of the book's x axis from world x, counter-clockwise seen from above, degrees.
    size : tuple of float, (3,)
        Extent along the book's x, y, z axes (length, width, thickness), metres.
    cover : CoverSpec
    spine_side : {+1, -1}
        The spine is the side at ``y = spine_side · size[1] / 2`` (a long side).
    gloss : float
        Peak specular reflectance of the cover relative to a white diffuse one; 0 = matte.
    gloss_sigma : float
        Size of the highlight on the cover (std of a Gaussian), metres.
    """

    center: tuple[float, float, float]
    yaw_deg: float
    size: tuple[float, float, float]
    cover: CoverSpec
    spine_side: int = 1
    gloss: float = 0.0
    gloss_sigma: float = 0.03

    @property
    def R(self) -> NDArray[np.float64]:
        """Book axes as columns (3, 3): x along its length, z up."""
        c, s = np.cos(np.radians(self.yaw_deg)), np.sin(np.radians(self.yaw_deg))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    @property
    def corners(self) -> NDArray[np.float64]:
        """Top-cover corners P1..P4 (4, 3), world, metres (geometry.corners_from_pose)."""
        return geometry.corners_from_pose(self.center, self.R, self.size[:2])

    def footprint(self) -> NDArray[np.float64]:
        """The rectangle it covers on the desk, (4, 2), metres."""
        return self.corners[:, :2]


@dataclass(frozen=True)
class Paper:
    """A loose sheet (or note) flat on the desk: centre (x, y), yaw, size (sx, sy), metres."""

    center: tuple[float, float]
    yaw_deg: float
    size: tuple[float, float]
    seed: int

    def footprint(self) -> NDArray[np.float64]:
        return _rectangle(self.center, self.yaw_deg, self.size)


@dataclass(frozen=True)
class Mug:
    """A cylindrical mug: base centre (x, y), radius, height (m), albedo, handle heading (deg)."""

    center: tuple[float, float]
    radius: float
    height: float
    albedo: float
    handle_deg: float

    def footprint(self) -> NDArray[np.float64]:
        reach = self.radius + 0.035  # the handle
        return _rectangle(self.center, 0.0, (2 * reach, 2 * reach))


@dataclass(frozen=True)
class Pen:
    """A pen or pencil: a hexagonal prism lying on the desk (centre, yaw, length, radius)."""

    center: tuple[float, float]
    yaw_deg: float
    length: float
    radius: float
    albedo: float

    def footprint(self) -> NDArray[np.float64]:
        return _rectangle(self.center, self.yaw_deg, (self.length, 2 * self.radius))


@dataclass(frozen=True)
class Cable:
    """A cable lying on the desk: a polyline ``points`` ((N, 2) as tuples), width, albedo."""

    points: tuple[tuple[float, float], ...]
    width: float
    albedo: float


@dataclass(frozen=True)
class Light:
    """The illumination of the desk.

    ``lux`` is the illuminance of a horizontal, unshadowed surface at the workspace centre;
    elsewhere it follows the light's spatial profile.

    Attributes
    ----------
    kind : {"daylight", "artificial"}
    lux : float
        Illuminance at the workspace centre, lx.
    position : tuple of float, (3,)
        Artificial: the ceiling lamp, world metres. Daylight: unused.
    direction : tuple of float, (3,)
        Daylight: unit vector toward the sun/window. Artificial: unused.
    ambient : float
        Fraction of the illuminance that is diffuse (no shadows), 0–1.
    gradient : float
        Daylight: illuminance ratio between the window side and the far side of the
        workspace (0.8 m); artificial: unused.
    hotspot : float
        Artificial: relative amplitude of the lamp's hotspot; daylight: unused.
    hotspot_sigma : float
        Artificial: hotspot radius (std), metres.
    mullions : int
        Daylight: shadows of window bars across the desk (0–2).
    penumbra_px : float
        Blur of cast shadows, output pixels (std).
    """

    kind: LightKind
    lux: float
    position: tuple[float, float, float] = (0.45, 0.35, 1.8)
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    ambient: float = 0.4
    gradient: float = 1.0
    hotspot: float = 0.0
    hotspot_sigma: float = 0.25
    mullions: int = 0
    penumbra_px: float = 3.0


@dataclass(frozen=True, eq=False)
class Scene:
    """Everything a stereo pair shows.

    Attributes
    ----------
    rig : StereoRig
        Calibrated camera with ``T_world_left`` in the marker frame.
    books, papers, mugs, pens, cables : tuples of the dataclasses above
    light : Light
    exposure : {"auto", "fixed"}
        ``fixed``: exposure and gain frozen at what auto-exposure chose at 500 lx.
    desk_variant : int
        Which wood texture.
    desk_offset : tuple of float, (2,)
        Shift of the wood texture, metres.
    blur_px : float
        Lens/defocus blur, output pixels (std).
    """

    rig: StereoRig
    books: tuple[Book, ...]
    papers: tuple[Paper, ...]
    mugs: tuple[Mug, ...]
    pens: tuple[Pen, ...]
    cables: tuple[Cable, ...]
    light: Light
    exposure: ExposureMode = "auto"
    desk_variant: int = 0
    desk_offset: tuple[float, float] = (0.0, 0.0)
    blur_px: float = 0.6

    def with_light(self, light: Light | None = None, *, lux: float | None = None,
                   exposure: ExposureMode | None = None) -> Scene:
        """The same objects under another light, level or exposure mode."""
        new = light if light is not None else self.light
        if lux is not None:
            new = replace(new, lux=_check_lux(lux))
        return replace(self, light=new, exposure=_check_exposure(exposure or self.exposure))


# --------------------------------------------------------------------------- validation


def _check_lux(lux: float) -> float:
    lux = float(lux)
    if not np.isfinite(lux) or lux <= 0:
        raise ValueError(f"lux: expected a positive illuminance, got {lux:g}")
    return lux


def _check_exposure(mode: str) -> ExposureMode:
    if mode not in EXPOSURE_MODES:
        raise ValueError(f"exposure: expected 'auto' or 'fixed', got {mode!r}")
    return mode  # type: ignore[return-value]


def _check_light_kind(kind: str) -> LightKind:
    if kind not in LIGHT_KINDS:
        raise ValueError(f"light: expected 'daylight' or 'artificial', got {kind!r}")
    return kind  # type: ignore[return-value]


# --------------------------------------------------------------------------- footprints


def _rectangle(center: tuple[float, float] | NDArray[np.float64], yaw_deg: float,
               size: tuple[float, float]) -> NDArray[np.float64]:
    """Corners (4, 2) of a rectangle on the desk."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    local = np.array([[hx, hy], [hx, -hy], [-hx, -hy], [-hx, hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(center, dtype=np.float64)[:2]


def _overlap(a: NDArray[np.float64], b: NDArray[np.float64], tol: float = 1e-9) -> bool:
    """Whether two convex polygons (N, 2) overlap by more than ``tol`` (touching is not overlap)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for nx, ny in np.column_stack([-edges[:, 1], edges[:, 0]]):
            n = np.array([nx, ny]) / np.hypot(nx, ny)
            pa, pb = a @ n, b @ n
            if pa.max() <= pb.min() + tol or pb.max() <= pa.min() + tol:
                return False
    return True


def _marker_keep_out() -> NDArray[np.float64]:
    return _rectangle((0.0, 0.0), 0.0, (2 * _KEEP_OUT, 2 * _KEEP_OUT))


def _inside(poly: NDArray[np.float64], box: tuple[tuple[float, float], tuple[float, float]]) -> bool:
    (x0, x1), (y0, y1) = box
    return bool(np.all((poly[:, 0] >= x0) & (poly[:, 0] <= x1)
                       & (poly[:, 1] >= y0) & (poly[:, 1] <= y1)))


# --------------------------------------------------------------------------- camera


def sample_rig(rng: np.random.Generator | int | None = None, *, margin_px: float = 12.0,
               max_tries: int = 500) -> StereoRig:
    """A Bumblebee2-like rig (make_rig defaults: 1024×768, f = 800 px, 0.12 m baseline, mild
    distortion) 0.9–1.4 m from the desk, looking down 40–70°, from the robot's side of the
    desk (−y), placed so that the whole workspace (up to book height) and the marker sheet
    project at least ``margin_px`` inside both images.

    Returns
    -------
    StereoRig
        ``world_frame = "marker"``.
    """
    rng = np.random.default_rng(rng)
    (x0, x1), (y0, y1) = WORKSPACE
    k = 0.5 * MARKER_PAPER
    pts = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (0.0, 0.06)]
    pts += [(x, y, 0.0) for x in (-k, k) for y in (-k, k)]
    P = np.array(pts)
    for _ in range(max_tries):
        dist = rng.uniform(0.9, 1.4)
        elev = np.radians(rng.uniform(40.0, 70.0))
        azim = np.radians(-90.0 + rng.uniform(-30.0, 30.0))
        target = np.array([0.42 + rng.normal(0, 0.03), 0.30 + rng.normal(0, 0.03), 0.0])
        eye = target + dist * np.array([np.cos(elev) * np.cos(azim),
                                        np.cos(elev) * np.sin(azim), np.sin(elev)])
        rig = make_rig(T_world_left=geometry.look_at(eye, target), world_frame="marker")
        w, h = rig.image_size  # type: ignore[misc]
        ok = True
        for cam in ("left", "right"):
            px = rig.project(P, cam)
            ok &= bool(np.all((px >= margin_px) & (px <= [w - 1 - margin_px, h - 1 - margin_px])))
        if ok:
            return rig
    raise RuntimeError("sample_rig: found no camera pose that sees the workspace and the marker")


# --------------------------------------------------------------------------- light


def sample_light(rng: np.random.Generator | int | None = None, kind: LightKind = "artificial",
                 lux: float = 500.0) -> Light:
    """A random daylight (window, strong gradient, hard shadows) or artificial light (ceiling
    lamp, near uniform with a hotspot, soft shadows) giving ``lux`` at the workspace centre."""
    rng = np.random.default_rng(rng)
    kind, lux = _check_light_kind(kind), _check_lux(lux)
    if kind == "artificial":
        return Light(kind=kind, lux=lux,
                     position=(rng.uniform(0.0, 0.9), rng.uniform(-0.1, 0.8), rng.uniform(1.3, 2.1)),
                     ambient=rng.uniform(0.25, 0.45), hotspot=rng.uniform(0.2, 0.6),
                     hotspot_sigma=rng.uniform(0.12, 0.3), penumbra_px=rng.uniform(2.5, 5.0))
    azim, elev = np.radians(rng.uniform(0, 360)), np.radians(rng.uniform(20, 45))
    direction = (np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev))
    return Light(kind=kind, lux=lux, direction=tuple(float(d) for d in direction),
                 ambient=rng.uniform(0.18, 0.35), gradient=rng.uniform(3.0, 8.0),
                 mullions=int(rng.choice([0, 0, 1, 2])), penumbra_px=rng.uniform(1.0, 2.5))


# --------------------------------------------------------------------------- objects


def _sample_cover(rng: np.random.Generator, desk_albedo: float) -> CoverSpec:
    kind: CoverKind = COVER_KINDS[int(rng.choice(6, p=[0.2, 0.1, 0.1, 0.1, 0.3, 0.2]))]
    albedo = {"plain": rng.uniform(0.1, 0.7), "dark": rng.uniform(0.02, 0.07),
              "light": rng.uniform(0.65, 0.85),
              "desk": desk_albedo * rng.uniform(0.92, 1.08)}.get(kind, rng.uniform(0.05, 0.85))
    return CoverSpec(kind=kind, albedo=float(albedo), seed=int(rng.integers(2**31)))


def _sample_books(rng: np.random.Generator, n: int, desk_albedo: float) -> list[Book]:
    books: list[Book] = []
    keep_out = _marker_keep_out()
    for _ in range(60 * n):
        if len(books) == n:
            break
        size = (rng.uniform(0.12, 0.32), 0.0, np.exp(rng.uniform(np.log(0.008), np.log(0.06))))
        size = (size[0], rng.uniform(0.09, min(0.25, size[0])), size[2])
        if books and rng.random() < 0.4:  # touching an existing book, flush along one side
            other = books[int(rng.integers(len(books)))]
            yaw = other.yaw_deg + 90.0 * int(rng.integers(4))
            R = other.R
            side = int(rng.integers(4))
            normal = (R[:2, 0], -R[:2, 0], R[:2, 1], -R[:2, 1])[side]
            along = R[:2, 1] if side < 2 else R[:2, 0]
            n_local = np.abs(np.array([np.cos(np.radians(yaw)), np.sin(np.radians(yaw))]) @ normal)
            half_new = 0.5 * (size[0] * n_local + size[1] * np.sqrt(max(0.0, 1 - n_local**2)))
            half_other = 0.5 * (other.size[0] if side < 2 else other.size[1])
            slide = rng.uniform(-0.5, 0.5) * (other.size[1] if side < 2 else other.size[0])
            xy = np.asarray(other.center[:2]) + (half_other + half_new) * normal + slide * along
        else:
            yaw = rng.uniform(0.0, 360.0)
            xy = np.array([rng.uniform(*WORKSPACE[0]), rng.uniform(*WORKSPACE[1])])
        book = Book(center=(float(xy[0]), float(xy[1]), float(size[2])), yaw_deg=float(yaw % 360.0),
                    size=tuple(float(s) for s in size), cover=_sample_cover(rng, desk_albedo),
                    spine_side=int(rng.choice([-1, 1])),
                    gloss=float(rng.uniform(0.8, 3.0)) if rng.random() < 0.35 else 0.0,
                    gloss_sigma=float(rng.uniform(0.015, 0.05)))
        fp = book.footprint()
        if (_inside(fp, WORKSPACE) and not _overlap(fp, keep_out)
                and not any(_overlap(fp, b.footprint()) for b in books)):
            books.append(book)
    return books


def _clutter_xy(rng: np.random.Generator) -> NDArray[np.float64]:
    """A spot on the desk around (and a little beyond) the workspace."""
    return np.array([rng.uniform(-0.25, 1.05), rng.uniform(-0.15, 0.85)])


def _sample_clutter(rng: np.random.Generator, books: list[Book]) -> tuple[
        tuple[Paper, ...], tuple[Mug, ...], tuple[Pen, ...], tuple[Cable, ...]]:
    keep_out = _marker_keep_out()
    solid = [b.footprint() for b in books]
    papers: list[Paper] = []
    for _ in range(int(rng.integers(0, 4))):
        for _ in range(30):
            size = (rng.uniform(0.08, 0.30), rng.uniform(0.07, 0.21))
            p = Paper(center=tuple(_clutter_xy(rng)), yaw_deg=float(rng.uniform(0, 360)),
                      size=size, seed=int(rng.integers(2**31)))
            if not _overlap(p.footprint(), keep_out):
                papers.append(p)
                break
    mugs: list[Mug] = []
    for _ in range(int(rng.choice([0, 1, 1, 2]))):
        for _ in range(30):
            m = Mug(center=tuple(_clutter_xy(rng)), radius=rng.uniform(0.035, 0.045),
                    height=rng.uniform(0.08, 0.11), albedo=rng.uniform(0.05, 0.85),
                    handle_deg=rng.uniform(0, 360))
            fp = m.footprint()
            if not _overlap(fp, keep_out) and not any(_overlap(fp, s) for s in solid):
                mugs.append(m)
                solid.append(fp)
                break
    pens: list[Pen] = []
    for _ in range(int(rng.integers(0, 4))):
        for _ in range(30):
            p = Pen(center=tuple(_clutter_xy(rng)), yaw_deg=rng.uniform(0, 360),
                    length=rng.uniform(0.12, 0.17), radius=rng.uniform(0.0035, 0.005),
                    albedo=float(rng.choice([0.04, 0.08, 0.5, 0.6, 0.25])))
            fp = p.footprint()
            if not _overlap(fp, keep_out) and not any(_overlap(fp, s) for s in solid):
                pens.append(p)
                solid.append(fp)
                break
    cables: list[Cable] = []
    if rng.random() < 0.5:
        xy = np.array([rng.uniform(-0.3, 1.1), rng.choice([-0.3, 0.95])])
        heading = np.arctan2(0.35 - xy[1], 0.45 - xy[0]) + rng.normal(0, 0.5)
        pts = [xy.copy()]
        for _ in range(60):
            heading += rng.normal(0, 0.25)
            xy = xy + 0.03 * np.array([np.cos(heading), np.sin(heading)])
            if np.max(np.abs(xy)) < _KEEP_OUT + 0.02:  # steer around the marker
                break
            pts.append(xy.copy())
        if len(pts) > 3:
            cables.append(Cable(points=tuple((float(x), float(y)) for x, y in pts),
                                width=rng.uniform(0.004, 0.007), albedo=rng.uniform(0.03, 0.6)))
    return tuple(papers), tuple(mugs), tuple(pens), tuple(cables)


def sample_scene(rng: np.random.Generator | int | None = None, *, rig: StereoRig | None = None,
                 n_books: int | None = None, lux: float | None = None,
                 light: LightKind | Light | None = None,
                 exposure: ExposureMode = "auto") -> Scene:
    """Draw a random library-desk scene (deterministic for a given seed).

    Parameters
    ----------
    rng : Generator, int or None
        Randomness; an int is a seed.
    rig : StereoRig, optional
        The camera (world = marker frame); sampled with :func:`sample_rig` when omitted.
    n_books : int, optional
        Number of books to place (3–7 at random when omitted); fewer when they do not fit.
    lux : float, optional
        Illuminance at the workspace centre, lx; log-uniform in 15–1200 when omitted.
    light : {"daylight", "artificial"} or Light, optional
        Random kind when omitted; a :class:`Light` is used as given (``lux`` then overrides
        its level if given).
    exposure : {"auto", "fixed"}

    Returns
    -------
    Scene
    """
    rng = np.random.default_rng(rng)
    exposure = _check_exposure(exposure)
    if n_books is not None and (int(n_books) != n_books or n_books < 0):
        raise ValueError(f"n_books: expected a non-negative integer, got {n_books!r}")
    if lux is not None:
        lux = _check_lux(lux)
    rng_cam, rng_obj, rng_light = rng.spawn(3)  # the light may change without moving books
    rig = rig if rig is not None else sample_rig(rng_cam)
    variant = int(rng_obj.integers(4))
    books = _sample_books(rng_obj, int(rng_obj.integers(3, 8)) if n_books is None else int(n_books),
                          _WOOD_ALBEDO[variant])
    papers, mugs, pens, cables = _sample_clutter(rng_obj, books)
    if isinstance(light, Light):
        the_light = light if lux is None else replace(light, lux=lux)
    else:
        kind = _check_light_kind(light) if light is not None else \
            LIGHT_KINDS[int(rng_light.integers(2))]
        level = lux if lux is not None else float(np.exp(rng_light.uniform(*np.log(LUX_RANGE))))
        the_light = sample_light(rng_light, kind, level)
    return Scene(rig=rig, books=tuple(books), papers=papers, mugs=mugs, pens=pens, cables=cables,
                 light=the_light, exposure=exposure, desk_variant=variant,
                 desk_offset=(float(rng_obj.uniform(0, 0.3)), float(rng_obj.uniform(0, 0.15))),
                 blur_px=float(rng_obj.uniform(0.45, 0.8)))
