"""The datasets ``rovis synth`` writes (DESIGN §3) under the paper's protocols (§5).

- ``table1``: 500 lx artificial light, books at random positions and yaw over 0–360°;
- ``table2``: the same books kept in place while the light sweeps 15–1200 lx, daylight and
  artificial, auto and fixed exposure (``TABLE2_LUX`` × 2 lights × 2 modes per arrangement);
- ``mixed``: random scenes, log-uniform 15–1200 lx, random light.

One camera pose (one ``calib.yaml``) per dataset; each scene is written to a temporary folder
and renamed into place, so a scene folder is whole or absent.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis.calib import StereoRig, save_calibration
from rovis.io import publish
from rovis.synth.render import render
from rovis.synth.scene import (EXPOSURE_MODES, LIGHT_KINDS, ExposureMode, Scene, _check_exposure,
                               _check_lux, sample_light, sample_rig, sample_scene)

PROTOCOLS = ("table1", "table2", "mixed")
TABLE2_LUX = (15.0, 30.0, 60.0, 120.0, 250.0, 500.0, 800.0, 1200.0)
PREVIEW_TILES = 12

Progress = Callable[[int, int], None]


def _check_args(protocol: str, n: int, seed: int, exposure: str | None,
                lux: float | None) -> None:
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol: expected one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    if isinstance(n, bool) or int(n) != n or n <= 0:
        raise ValueError(f"n: expected a positive number of scenes, got {n!r}")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    if exposure is not None:
        _check_exposure(exposure)
    if lux is not None:
        _check_lux(lux)
        if protocol == "table2":
            raise ValueError("lux: table2 sweeps the light over 15-1200 lx itself; leave lux out")


def dataset_rig(seed: int) -> StereoRig:
    """The dataset's camera (one pose for all its scenes), from its seed."""
    return sample_rig(np.random.default_rng([seed, 7]))


def dataset_scenes(protocol: str = "table1", n: int = 10, seed: int = 0, *,
                   exposure: ExposureMode | None = None,
                   lux: float | None = None) -> Iterator[tuple[int, Scene]]:
    """The ``n`` scenes of a dataset, in order: ``(index, scene)``; deterministic in ``seed``.

    Parameters
    ----------
    protocol : {"table1", "table2", "mixed"}
    n : int
        Number of scenes (stereo pairs).
    seed : int
    exposure : {"auto", "fixed"}, optional
        Default: ``auto`` for table1 and mixed; both modes for table2.
    lux : float, optional
        Fixes the illuminance (table1 and mixed only).
    """
    _check_args(protocol, n, seed, exposure, lux)
    rig = dataset_rig(seed)
    if protocol == "table2":
        modes = (exposure,) if exposure is not None else EXPOSURE_MODES
        conditions = [(m, kind, level) for m in modes for kind in LIGHT_KINDS for level in TABLE2_LUX]
        base: Scene | None = None
        for i in range(n):
            arrangement, c = divmod(i, len(conditions))
            mode, kind, level = conditions[c]
            if base is None or c == 0:
                base = sample_scene(np.random.default_rng([seed, 2, arrangement]), rig=rig,
                                    lux=500.0, light="artificial")
            light = sample_light(np.random.default_rng([seed, 2, arrangement,
                                                        LIGHT_KINDS.index(kind)]), kind, level)
            yield i, base.with_light(light, exposure=mode)
        return
    for i in range(n):
        rng = np.random.default_rng([seed, 1 if protocol == "table1" else 3, i])
        if protocol == "table1":
            yield i, sample_scene(rng, rig=rig, lux=500.0 if lux is None else lux,
                                  light="artificial", exposure=exposure or "auto")
        else:
            yield i, sample_scene(rng, rig=rig, lux=lux, exposure=exposure or "auto")


def _prepare_out(out: Path, force: bool) -> None:
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise ValueError(f"{out}: exists and is not empty (use --force to replace the dataset in it)")
        shutil.rmtree(out / "scenes", ignore_errors=True)
        for name in ("calib.yaml", "preview.png"):
            (out / name).unlink(missing_ok=True)


def _umask_mode(mode: int) -> int:
    """``mode`` less the process umask: what a plain mkdir/open would have given."""
    umask = os.umask(0)
    os.umask(umask)
    return mode & ~umask


def _imwrite(path: Path, image: NDArray[np.uint8]) -> None:
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: could not write the image")


def write_dataset(out: str | os.PathLike[str], *, protocol: str = "table1", n: int = 10,
                  seed: int = 0, exposure: ExposureMode | None = None, lux: float | None = None,
                  force: bool = False, preview: bool = False,
                  progress: Progress | None = None) -> Path:
    """Render a dataset into ``out``: ``calib.yaml`` and ``scenes/NNNN/{left,right}.png,
    truth.json`` (DESIGN §3), and with ``preview`` a contact sheet ``preview.png``.

    Parameters are those of :func:`dataset_scenes`, plus ``force`` (replace a dataset in a
    non-empty ``out``) and ``progress(done, total)`` called after each scene. The preview
    shows up to 12 scenes spread over the dataset, dimmest first.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    ValueError
        Impossible parameters or a non-empty ``out`` without ``force`` — before anything is
        written.
    """
    _check_args(protocol, n, seed, exposure, lux)
    out = Path(out)
    _prepare_out(out, force)
    scenes_dir = out / "scenes"
    scenes_dir.mkdir(parents=True, exist_ok=True)
    save_calibration(dataset_rig(seed), out / "calib.yaml")
    picks = set(np.linspace(0, n - 1, min(n, PREVIEW_TILES)).round().astype(int).tolist())
    tiles: list[tuple[NDArray[np.uint8], str, float]] = []
    for i, scene in dataset_scenes(protocol, n, seed, exposure=exposure, lux=lux):
        result = render(scene, np.random.default_rng([seed, 9, i]))
        truth = {"scene": i, "protocol": protocol, "seed": seed, **result.truth}
        tmp = Path(tempfile.mkdtemp(prefix=f".{i:04d}.", dir=scenes_dir))
        try:
            _imwrite(tmp / "left.png", result.left)
            _imwrite(tmp / "right.png", result.right)
            (tmp / "truth.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
            os.chmod(tmp, _umask_mode(0o777))  # mkdtemp makes it private
            os.rename(tmp, scenes_dir / f"{i:04d}")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        if preview and i in picks:
            tiles.append((result.left, _label(i, scene), scene.light.lux))
        if progress is not None:
            progress(i + 1, n)
    if preview:
        tiles.sort(key=lambda t: t[2])  # dim to bright
        sheet = contact_sheet([t[0] for t in tiles], [t[1] for t in tiles])
        fd, tmp_png = tempfile.mkstemp(prefix=".preview.", suffix=".png", dir=out)
        os.close(fd)
        try:
            _imwrite(Path(tmp_png), sheet)
            publish(tmp_png, out / "preview.png")
        finally:
            Path(tmp_png).unlink(missing_ok=True)
    return out


def _label(i: int, scene: Scene) -> str:
    return f"#{i}  {scene.light.lux:.0f} lx  {scene.light.kind}  {scene.exposure}"


def contact_sheet(images: list[NDArray[np.uint8]], labels: list[str] | None = None, *,
                  cols: int = 4, tile_width: int = 320, gap: int = 4) -> NDArray[np.uint8]:
    """Thumbnails in a grid, each labelled on a dark strip at its bottom.

    Parameters
    ----------
    images : list of ndarray, shape (H, W), uint8
    labels : list of str, optional
    cols : int
    tile_width : int
        Thumbnail width, pixels.

    Returns
    -------
    ndarray, shape (rows · (h + gap) − gap, cols · (w + gap) − gap), uint8
    """
    if not images:
        raise ValueError("images: nothing to put on a contact sheet")
    h0, w0 = images[0].shape[:2]
    tw, th = tile_width, int(round(tile_width * h0 / w0))
    cols = min(cols, len(images))
    rows = -(-len(images) // cols)
    sheet = np.full((rows * (th + gap) - gap, cols * (tw + gap) - gap), 255, np.uint8)
    for k, img in enumerate(images):
        tile = cv2.resize(img, (tw, th), interpolation=cv2.INTER_AREA)
        if labels is not None:
            tile[th - 18:] = tile[th - 18:] // 4
            cv2.putText(tile, labels[k], (6, th - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.42, 255, 1,
                        cv2.LINE_AA)
        r, c = divmod(k, cols)
        sheet[r * (th + gap):r * (th + gap) + th, c * (tw + gap):c * (tw + gap) + tw] = tile
    return sheet
