"""Making a calibration: stereo calibration from chessboard pairs, and world registration.

- :func:`calibrate_stereo`: find the chessboard in each left/right pair, calibrate each camera
  (``cv2.calibrateCamera``), then refine both together with the stereo geometry
  (``cv2.stereoCalibrate``), dropping pairs whose reprojection error stands out.
- :func:`register`: the left camera's pose in the world from the desk marker seen in one
  stereo pair (world = the marker frame, or the robot base when the marker's pose there is
  given).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from rovis import geometry, marker
from rovis.calib import StereoRig, as_transform
from rovis.imageio import read_gray, to_gray_u8

Distortion = Literal["k1k2", "k1k2k3", "k1k2p1p2", "full"]

# The plumb-bob terms each model estimates; the others are held at zero.
DISTORTION_FLAGS: dict[str, int] = {
    "k1k2": cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3,
    "k1k2k3": cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2p1p2": cv2.CALIB_FIX_K3,
    "full": 0,  # k1 k2 p1 p2 k3
}
MIN_PAIRS = 3
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


# --------------------------------------------------------------------------- chessboard


def find_chessboard(gray: NDArray[np.uint8],
                    board: tuple[int, int]) -> NDArray[np.float64] | None:
    """Inner chessboard corners in one image, sub-pixel.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    board : (columns, rows)
        Inner corners per row and number of rows (OpenCV's ``patternSize``).

    Returns
    -------
    ndarray, shape (rows * columns, 2), float64, or None
        Raw pixels, row by row, in the order :func:`canonical_order` gives; None when the
        board is not found.
    """
    found, corners = cv2.findChessboardCorners(
        gray, board, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if found:
        pts = corners.reshape(-1, 2)
        grid = pts.reshape(board[1], board[0], 2)
        spacing = min(np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
                      np.linalg.norm(np.diff(grid, axis=1), axis=2).min())
        # the window must stay inside one square around its corner
        win = int(np.clip(0.3 * spacing, 2, 10))
        corners = cv2.cornerSubPix(gray, corners, (win, win), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4))
    else:  # the sector-based detector finds boards the classic one misses (blur, glare)
        found, corners = cv2.findChessboardCornersSB(gray, board, flags=cv2.CALIB_CB_ACCURACY)
        if not found:
            return None
    return canonical_order(np.asarray(corners, dtype=np.float64).reshape(-1, 2), board)


def _orderings(grid: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """The row-major orderings of a (rows, cols, 2) corner grid a symmetric board allows."""
    cands = [grid, grid[::-1, ::-1], grid[::-1, :], grid[:, ::-1]]
    if grid.shape[0] == grid.shape[1]:
        cands += [g.transpose(1, 0, 2) for g in cands]
    return cands


def _axes(grid: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean unit directions along a row and down a column of a corner grid (image px)."""
    along = (grid[:, -1] - grid[:, 0]).sum(axis=0)
    down = (grid[-1] - grid[0]).sum(axis=0)
    return along / np.linalg.norm(along), down / np.linalg.norm(down)


def canonical_order(corners_px: ArrayLike, board: tuple[int, int]) -> NDArray[np.float64]:
    """Order a symmetric board's corners the same way in every image.

    A board whose squares are 180° symmetric (e.g. 4 × 6 inner corners, 5 × 7 squares) can be
    reported starting from either end. This keeps the orderings whose rows and columns turn
    like the image's x and y (no mirror) and, of those, the one starting nearest the image's
    top-left corner.

    Parameters
    ----------
    corners_px : array_like, shape (rows * cols, 2)
    board : (cols, rows)

    Returns
    -------
    ndarray, shape (rows * cols, 2), float64
    """
    grid = np.asarray(corners_px, dtype=np.float64).reshape(board[1], board[0], 2)
    best, best_key = grid, None
    for g in _orderings(grid):
        along, down = _axes(g)
        mirrored = along[0] * down[1] - along[1] * down[0] < 0
        key = (mirrored, float(np.hypot(*g[0, 0])))
        if best_key is None or key < best_key:
            best, best_key = g, key
    return best.reshape(-1, 2).copy()


def order_like(reference_px: ArrayLike, corners_px: ArrayLike,
               board: tuple[int, int]) -> NDArray[np.float64]:
    """Reorder ``corners_px`` so its rows and columns run the way ``reference_px``'s do.

    Used for the right image of a pair: both cameras see the board from nearly the same
    direction, so the ordering whose row and column directions agree best with the left
    image's is the one that puts the same physical corner at the same index.

    Parameters
    ----------
    reference_px, corners_px : array_like, shape (rows * cols, 2)
    board : (cols, rows)
    """
    ref_along, ref_down = _axes(np.asarray(reference_px, dtype=np.float64)
                                .reshape(board[1], board[0], 2))
    grid = np.asarray(corners_px, dtype=np.float64).reshape(board[1], board[0], 2)

    def agreement(g: NDArray[np.float64]) -> float:
        along, down = _axes(g)
        return float(along @ ref_along + down @ ref_down)

    return max(_orderings(grid), key=agreement).reshape(-1, 2).copy()


def board_points(board: tuple[int, int], square: float) -> NDArray[np.float64]:
    """The inner corners in the board's frame (rows * cols, 3), metres, row by row, z = 0."""
    cols, rows = board
    xy = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    return np.column_stack([xy, np.zeros(len(xy))])


# --------------------------------------------------------------------------- calibration


@dataclass(frozen=True)
class PairResult:
    """Reprojection error of one chessboard pair, pixels (RMS over its corners)."""

    left: str
    right: str
    rms_left_px: float
    rms_right_px: float

    @property
    def rms_px(self) -> float:
        """RMS over both images of the pair."""
        return float(np.sqrt(0.5 * (self.rms_left_px ** 2 + self.rms_right_px ** 2)))


@dataclass(frozen=True, eq=False)
class CalibrationReport:
    """The result of :func:`calibrate_stereo`.

    Attributes
    ----------
    rig : StereoRig
        The calibration; its world is the left camera.
    rms_px : float
        RMS reprojection error over all used pairs and both images, pixels.
    pairs : tuple of PairResult
        The pairs used, in input order.
    skipped : tuple of (str, str)
        ``(pair name, reason)`` of every pair left out: board not found, or an outlier.
    distortion : str
        The distortion model (a key of :data:`DISTORTION_FLAGS`, or ``"fixed"``).
    intrinsics_fixed : bool
        Whether K and D were taken from another calibration and kept.
    """

    rig: StereoRig
    rms_px: float
    pairs: tuple[PairResult, ...]
    skipped: tuple[tuple[str, str], ...]
    distortion: str
    intrinsics_fixed: bool

    def lines(self) -> list[str]:
        """Human-readable report: one line per pair, then the summary."""
        out = [f"{'pair':<28} {'left':>8} {'right':>8} {'RMS px':>8}"]
        for p in self.pairs:
            out.append(f"{_pair_name(p.left, p.right):<28} {p.rms_left_px:8.3f} "
                       f"{p.rms_right_px:8.3f} {p.rms_px:8.3f}")
        for name, reason in self.skipped:
            out.append(f"skipped {name}: {reason}")
        model = "intrinsics fixed" if self.intrinsics_fixed else f"distortion {self.distortion}"
        out.append(f"total RMS {self.rms_px:.3f} px over {len(self.pairs)} pairs ({model})")
        out.append(self.rig.summary())
        return out


def _pair_name(left: str, right: str) -> str:
    return f"{Path(left).name}/{Path(right).name}"


def calibrate_stereo(left_paths: Sequence[str | os.PathLike[str]],
                     right_paths: Sequence[str | os.PathLike[str]],
                     board: tuple[int, int] = (4, 6), square: float = 0.030, *,
                     fix_intrinsics_from: StereoRig | None = None,
                     distortion: Distortion = "full",
                     max_pair_rms: float | None = None) -> CalibrationReport:
    """Stereo calibration from chessboard image pairs.

    Parameters
    ----------
    left_paths, right_paths : sequence of path-like
        The pairs' images, matched by position; same count, all of one size.
    board : (cols, rows)
        Inner corners per row and rows (a 5 × 7-square board is ``(4, 6)``).
    square : float
        Side of one square, metres.
    fix_intrinsics_from : StereoRig, optional
        Take K1, D1, K2, D2 from this calibration and keep them; only R, T are estimated.
    distortion : {"k1k2", "k1k2k3", "k1k2p1p2", "full"}
        Which plumb-bob terms to estimate (ignored with fixed intrinsics).
    max_pair_rms : float, optional
        A pair whose RMS exceeds this (pixels) is dropped and the calibration redone, worst
        first. Default: 3 × the median pair RMS, but at least 1 px.

    Returns
    -------
    CalibrationReport

    Raises
    ------
    ValueError
        No images, unequal counts, unreadable images, images of different sizes, an unknown
        distortion model, or fewer than 3 pairs with the board found.
    """
    cols, rows = (int(v) for v in board)
    if cols < 2 or rows < 2:
        raise ValueError(f"board: expected at least 2x2 inner corners, got {cols}x{rows}")
    if not square > 0:
        raise ValueError(f"square: expected a positive size in metres, got {square}")
    if distortion not in DISTORTION_FLAGS:
        raise ValueError(f"distortion: expected one of {', '.join(DISTORTION_FLAGS)}, "
                         f"got {distortion!r}")
    lefts, rights = [str(p) for p in left_paths], [str(p) for p in right_paths]
    if not lefts:
        raise ValueError("left images: none given")
    if len(lefts) != len(rights):
        raise ValueError(f"expected as many right images as left ones, got {len(lefts)} left "
                         f"and {len(rights)} right")

    size: tuple[int, int] | None = None
    size_from = ""
    found: list[tuple[str, str, NDArray[np.float64], NDArray[np.float64]]] = []
    skipped: list[tuple[str, str]] = []
    for lp, rp in zip(lefts, rights):
        gl, gr = read_gray(lp), read_gray(rp)
        for path, g in ((lp, gl), (rp, gr)):
            s = (g.shape[1], g.shape[0])
            if size is None:
                size, size_from = s, path
            elif s != size:
                raise ValueError(f"{path}: image size {s[0]}x{s[1]} differs from "
                                 f"{size[0]}x{size[1]} of {size_from}")
        cl, cr = find_chessboard(gl, (cols, rows)), find_chessboard(gr, (cols, rows))
        if cl is None or cr is None:
            where = " and ".join(n for n, c in (("left", cl), ("right", cr)) if c is None)
            skipped.append((_pair_name(lp, rp), f"no {cols}x{rows} chessboard found in the {where} image"))
            continue
        found.append((lp, rp, cl, order_like(cl, cr, (cols, rows))))
    assert size is not None  # lefts is not empty
    if fix_intrinsics_from is not None and fix_intrinsics_from.image_size not in (None, size):
        w, h = fix_intrinsics_from.image_size
        raise ValueError(f"intrinsics: calibrated for {w}x{h} images, the chessboard images "
                         f"are {size[0]}x{size[1]}")

    obj = board_points((cols, rows), square).astype(np.float32)
    while True:
        if len(found) < MIN_PAIRS:
            why = "; ".join(f"{name}: {reason}" for name, reason in skipped)
            raise ValueError(f"only {len(found)} usable chessboard pair(s) of {len(lefts)}; "
                             f"stereo calibration needs at least {MIN_PAIRS} ({why})")
        rig, rms, per_view = _solve(found, obj, size, fix_intrinsics_from, distortion)
        pair_rms = np.sqrt(0.5 * (per_view ** 2).sum(axis=1))
        limit = max_pair_rms if max_pair_rms is not None else max(1.0, 3.0 * np.median(pair_rms))
        worst = int(np.argmax(pair_rms))
        if pair_rms[worst] <= limit or len(found) <= MIN_PAIRS:
            break
        lp, rp = found[worst][:2]
        skipped.append((_pair_name(lp, rp), f"outlier: RMS {pair_rms[worst]:.3f} px > "
                                            f"{limit:.3f} px; calibrated again without it"))
        del found[worst]

    pairs = tuple(PairResult(lp, rp, float(e[0]), float(e[1]))
                  for (lp, rp, _, _), e in zip(found, per_view))
    return CalibrationReport(rig=rig, rms_px=float(rms), pairs=pairs, skipped=tuple(skipped),
                             distortion="fixed" if fix_intrinsics_from is not None else distortion,
                             intrinsics_fixed=fix_intrinsics_from is not None)


def _solve(found: list[tuple[str, str, NDArray[np.float64], NDArray[np.float64]]],
           obj: NDArray[np.float32], size: tuple[int, int], fixed: StereoRig | None,
           distortion: str) -> tuple[StereoRig, float, NDArray[np.float64]]:
    """One stereo calibration: (rig, total RMS px, per-pair (N, 2) RMS of left and right)."""
    objs = [obj] * len(found)
    img_l = [f[2].astype(np.float32).reshape(-1, 1, 2) for f in found]
    img_r = [f[3].astype(np.float32).reshape(-1, 1, 2) for f in found]
    if fixed is not None:
        K1, D1, K2, D2 = (np.array(a, dtype=np.float64) for a in
                          (fixed.K1, fixed.D1, fixed.K2, fixed.D2))
        flags = cv2.CALIB_FIX_INTRINSIC
    else:
        # Each camera alone first: with few pairs the joint problem started from scratch is
        # poorly conditioned; from good single-camera estimates it converges reliably.
        dist_flags = DISTORTION_FLAGS[distortion]
        _, K1, D1, _, _ = cv2.calibrateCamera(objs, img_l, size, None, None, flags=dist_flags,
                                              criteria=_CRITERIA)
        _, K2, D2, _, _ = cv2.calibrateCamera(objs, img_r, size, None, None, flags=dist_flags,
                                              criteria=_CRITERIA)
        flags = cv2.CALIB_USE_INTRINSIC_GUESS | dist_flags
    out = cv2.stereoCalibrateExtended(objs, img_l, img_r, K1, D1, K2, D2, size, None, None,
                                      flags=flags, criteria=_CRITERIA)
    rms, K1, D1, K2, D2, R, T = out[:7]
    per_view = np.asarray(out[11], dtype=np.float64).reshape(len(found), 2)
    rig = StereoRig.from_arrays(K1=K1, D1=np.ravel(D1)[:5], K2=K2, D2=np.ravel(D2)[:5], R=R,
                                T=np.ravel(T), image_size=size)
    return rig, float(rms), per_view


# --------------------------------------------------------------------------- registration


def register(rig: StereoRig, left: NDArray[np.generic] | str | os.PathLike[str],
             right: NDArray[np.generic] | str | os.PathLike[str], *,
             T_base_marker: ArrayLike | None = None, side: float = marker.MARKER_SIDE,
             dictionary: int = marker.DICTIONARY,
             marker_id: int = marker.MARKER_ID) -> StereoRig:
    """Put the rig in the world: ``T_world_left`` from the desk marker seen by both cameras.

    Parameters
    ----------
    rig : StereoRig
        The calibration; its current world frame is ignored.
    left, right : ndarray, shape (H, W) or (H, W, 3), or path-like
        One stereo pair showing the marker (images or image files).
    T_base_marker : array_like, shape (4, 4), optional
        The marker's pose in the robot base frame. Given: world = robot base
        (``world_frame="calibration"``); omitted: world = the marker frame (``"marker"``).
    side : float
        Marker side, metres.
    dictionary, marker_id : int
        The ArUco dictionary (``cv2.aruco.DICT_*``) and marker id.

    Returns
    -------
    StereoRig
        The same rig with ``T_world_left`` set.

    Raises
    ------
    ValueError
        An image that cannot be read, does not match the calibration's size, or does not
        show the marker (the message names the image).
    """
    T_bm = None if T_base_marker is None else as_transform(T_base_marker, "T_base_marker")
    corners = []
    for camera, image in (("left", left), ("right", right)):
        if isinstance(image, (str, os.PathLike)):
            name, gray = f"{camera} image {image}", read_gray(image)
        else:
            name, gray = f"{camera} image", to_gray_u8(image, f"{camera} image")
        size = (gray.shape[1], gray.shape[0])
        if rig.image_size is not None and size != tuple(rig.image_size):
            raise ValueError(f"{name}: size {size[0]}x{size[1]} does not match the calibration's "
                             f"{rig.image_size[0]}x{rig.image_size[1]}")
        found = marker.detect_marker(gray, dictionary=dictionary, marker_id=marker_id,
                                     intrinsics=rig.intrinsics(camera))
        if found is None:
            raise ValueError(f"{name}: no ArUco marker id {marker_id} found "
                             f"(dictionary {_dictionary_name(dictionary)})")
        corners.append(found.corners_px)
    T_left_marker = marker.marker_pose_stereo(rig, corners[0], corners[1], side=side)
    T_marker_left = geometry.invert_transform(T_left_marker)
    if T_bm is None:
        return rig.with_world(T_marker_left, "marker")
    return rig.with_world(T_bm @ T_marker_left, "calibration")


def _dictionary_name(dictionary: int) -> str:
    for name in dir(cv2.aruco):
        if name.startswith("DICT_") and getattr(cv2.aruco, name) == dictionary:
            return name
    return str(dictionary)


def read_pose(values: Sequence[str] | str | os.PathLike[str]) -> NDArray[np.float64]:
    """A 4×4 rigid transform from 16 numbers (row-major) or a file.

    Parameters
    ----------
    values : sequence of str, str, or path-like
        Sixteen numbers (as strings, or in one string separated by spaces or commas), or a
        path to a YAML file (a 4×4 nested list, 16 numbers, or a mapping with one such
        entry, e.g. ``T_base_marker:``; OpenCV FileStorage matrices with ``data:`` too) or a
        plain text file of 16 numbers.

    Raises
    ------
    ValueError
        Not 16 numbers, unreadable file, or not a rigid transform (the message says which).
    """
    if isinstance(values, os.PathLike):
        values = str(values)
    if isinstance(values, str):
        tokens = values.replace(",", " ").split()
        values = tokens if tokens and all(_is_number(t) for t in tokens) else [values]
    vals = list(values)
    if len(vals) == 1 and not _is_number(vals[0]):
        return as_transform(_pose_from_file(Path(vals[0])), "marker pose")
    if len(vals) != 16 or not all(_is_number(v) for v in vals):
        raise ValueError(f"marker pose: expected 16 numbers (a row-major 4x4) or one file, "
                         f"got {len(vals)} value(s)")
    return as_transform(np.array([float(v) for v in vals]).reshape(4, 4), "marker pose")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _pose_from_file(path: Path) -> Any:
    if not path.is_file():
        raise ValueError(f"{path}: marker pose file not found")
    text = path.read_text(encoding="utf-8")
    if text.lstrip().startswith("%YAML"):  # OpenCV FileStorage: drop the directive and tags
        text = "\n".join(line for line in text.splitlines() if not line.startswith("%"))
        text = text.replace("!!opencv-matrix", "")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError:
        data = None
    if isinstance(data, str) or data is None:  # plain whitespace-separated numbers
        try:
            data = [float(v) for v in text.replace(",", " ").replace("[", " ").replace("]", " ").split()]
        except ValueError:
            raise ValueError(f"{path}: expected 16 numbers or a YAML 4x4 matrix") from None
    if isinstance(data, dict):
        entries = [v for v in data.values() if isinstance(v, (list, dict))]
        if len(entries) != 1:
            raise ValueError(f"{path}: expected one 4x4 matrix, found keys {', '.join(map(str, data))}")
        data = entries[0]
        if isinstance(data, dict):
            if "data" not in data:
                raise ValueError(f"{path}: expected a 4x4 matrix (a list, or a mapping with data:)")
            data = data["data"]
    try:
        arr = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: expected 16 numbers or a YAML 4x4 matrix") from None
    if arr.size != 16:
        raise ValueError(f"{path}: expected 16 numbers (a 4x4 matrix), got {arr.size}")
    return arr.reshape(4, 4)
