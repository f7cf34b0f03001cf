"""Scoring detections against ground truth (DESIGN §5): ``rovis eval``.

Every scene of a dataset (DESIGN §3 layout) is run through the pipeline once per method, on the
same images; detections are matched to the true books by centre distance (≤ 5 cm, one-to-one,
Hungarian) and the matched books' errors are summarised in the layout of the paper's Tables I
and II, beside the paper's own figures.

Each scene is scored on its own: the detectors are :meth:`~rovis.pipeline.Detector.reset`
before every scene, so a scene's score does not depend on which scenes ran before it on the
same worker, and a serial run, a process pool and a Dask cluster give identical numbers.

The per-scene records are plain JSON-able dicts (what ``results.json`` holds); the summaries
are computed from them, so a saved ``results.json`` can be summarised and plotted again.
"""

from __future__ import annotations

import json
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rovis import geometry

METHODS: tuple[str, ...] = ("closed", "open", "auto-median", "auto-otsu", "lsd", "contour")
MATCH_RADIUS_M = 0.05  # DESIGN §5: a detection within 5 cm of a true book's centre
GRASP_TOLERANCE_M = 0.01  # the mission's 1 cm: a book found this well can be grasped
VISIBLE_MIN = 0.90  # "well visible": this fraction of the cover seen in both images
SQUARE_TOL_M = 0.01  # length and width closer than this: the cover is a square (yaw mod 90°)
LUX_EDGES: tuple[float, ...] = (15.0, 50.0, 150.0, 500.0, 1200.0)
ERROR_KEYS: tuple[str, ...] = ("x", "y", "z", "psi_deg", "length", "width", "height")
# the bands of each detection's agreement with the images (rovis.agreement) the report
# counts within and beyond the grasp tolerance: quality from the top, the error from 0
AGREEMENT_BANDS: dict[str, tuple[float, ...]] = {"quality": (0.95, 0.9, 0.8),
                                                 "reprojection_error_px": (0.5, 1.0, 1.5)}
SCHEMA = "rovis-eval/1"

Progress = Callable[[int, int, int], None]  # (done, total, skipped)


# --------------------------------------------------------------------------- the paper's figures


@dataclass(frozen=True)
class PaperTable:
    """One block of the paper's Tables I/II: max, mean and std of |X_e|, |Y_e|, |Z_e| (m)
    and Ψ_e (deg)."""

    title: str
    max: tuple[float, float, float, float]
    mean: tuple[float, float, float, float]
    std: tuple[float, float, float, float]


PAPER_TABLE_I = PaperTable("paper Table I (ROVIS, constant 500 lx)",
                           max=(0.008, 0.011, 0.004, 3.5), mean=(0.005, 0.007, 0.001, 2.0),
                           std=(0.002, 0.004, 0.002, 1.5))
PAPER_TABLE_II_OPEN = PaperTable("paper Table II (open loop, 15-1200 lx)",
                                 max=(0.6294, 0.2513, 0.7881, 34.0),
                                 mean=(0.1291, 0.1202, 0.2493, 15.0),
                                 std=(0.0360, 0.0229, 0.0437, 8.0))
PAPER_TABLE_II_ROVIS = PaperTable("paper Table II (ROVIS, 15-1200 lx)",
                                  max=(0.0127, 0.0134, 0.0069, 6.0),
                                  mean=(0.0101, 0.0054, 0.0038, 4.0),
                                  std=(0.0043, 0.0045, 0.0011, 2.0))


def paper_reference(method: str, protocol: str | None) -> PaperTable | None:
    """The paper's figures to print beside ``method``'s: Table II for a ``table2`` dataset
    (closed and open loop), Table I otherwise (closed loop only); None for the baselines."""
    if protocol == "table2":
        return {"closed": PAPER_TABLE_II_ROVIS, "open": PAPER_TABLE_II_OPEN}.get(method)
    return PAPER_TABLE_I if method == "closed" else None


# --------------------------------------------------------------------------- books and matching


@dataclass(frozen=True)
class Book:
    """A book's pose as scored: centre, axes and size, world frame.

    Attributes
    ----------
    center : ndarray, shape (3,) — metres
    R : ndarray, shape (3, 3) — the book's x, y, z axes as columns
    size : ndarray, shape (3,) — extent along x, y, z (the height may be NaN), metres
    visible : bool or None
        Truth only: at least :data:`VISIBLE_MIN` of the cover visible in both images
        (None when the truth does not say).
    id : int
    """

    center: NDArray[np.float64]
    R: NDArray[np.float64]
    size: NDArray[np.float64]
    visible: bool | None = None
    id: int = 0

    @classmethod
    def from_pose(cls, pose: Any, id: int = 0) -> Book:
        """From a :class:`rovis.geometry.BookPose` (a detection)."""
        return cls(center=np.asarray(pose.center, np.float64), R=np.asarray(pose.R, np.float64),
                   size=np.asarray(pose.size, np.float64), id=id)


def parse_truth(doc: Any) -> list[Book]:
    """The true books of a ``truth.json`` document (DESIGN §3).

    Raises
    ------
    ValueError
        A missing key or a value of the wrong shape, naming it.
    """
    if not isinstance(doc, dict):
        raise ValueError(f"expected a JSON object, got {type(doc).__name__}")
    books = doc.get("books")
    if not isinstance(books, list):
        raise ValueError("books: expected a list")
    out = []
    for i, b in enumerate(books):
        if not isinstance(b, dict):
            raise ValueError(f"books[{i}]: expected an object")
        arrays = {}
        for key, shape in (("center", (3,)), ("R", (3, 3)), ("size", (3,))):
            try:
                a = np.asarray(b[key], dtype=np.float64)
            except KeyError:
                raise ValueError(f"books[{i}].{key}: missing") from None
            except (TypeError, ValueError):
                raise ValueError(f"books[{i}].{key}: not numbers") from None
            if a.shape != shape:
                raise ValueError(f"books[{i}].{key}: expected shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"books[{i}].{key}: not finite")
            arrays[key] = a
        vis_l, vis_r = b.get("visible_left"), b.get("visible_right")
        visible = None
        if isinstance(vis_l, (int, float)) and isinstance(vis_r, (int, float)):
            visible = bool(min(vis_l, vis_r) >= VISIBLE_MIN)
        out.append(Book(arrays["center"], arrays["R"], arrays["size"], visible,
                        int(b.get("id", i))))
    return out


def match_books(true_centers: ArrayLike, est_centers: ArrayLike, *,
                radius: float = MATCH_RADIUS_M) -> list[tuple[int, int]]:
    """One-to-one matches of detections to true books by centre distance.

    The Hungarian assignment (scipy's ``linear_sum_assignment``) on the distances, with pairs
    farther than ``radius`` priced out: it finds the most matches, and among those the smallest
    total distance.

    Parameters
    ----------
    true_centers : array_like, shape (N, 3) — metres
    est_centers : array_like, shape (M, 3) — metres
    radius : float — metres

    Returns
    -------
    list of (truth index, detection index), sorted by truth index.
    """
    from scipy.optimize import linear_sum_assignment

    T = np.asarray(true_centers, np.float64).reshape(-1, 3)
    E = np.asarray(est_centers, np.float64).reshape(-1, 3)
    if len(T) == 0 or len(E) == 0:
        return []
    dist = np.linalg.norm(T[:, None, :] - E[None, :, :], axis=2)
    ok = dist <= radius
    # A price above any sum of feasible distances: the assignment first avoids those pairs.
    big = 1.0 + radius * (min(len(T), len(E)) + 1)
    rows, cols = linear_sum_assignment(np.where(ok, dist, big))
    return sorted((int(r), int(c)) for r, c in zip(rows, cols) if ok[r, c])


def long_axis_heading_deg(R: ArrayLike, size: ArrayLike,
                          up: ArrayLike = (0.0, 0.0, 1.0)) -> float:
    """Heading of a book's long axis on the desk plane, degrees [0, 360).

    The long axis is the book's x axis when ``size[0] >= size[1]``, its y axis otherwise.
    """
    R = np.asarray(R, np.float64)
    size = np.asarray(size, np.float64)
    if size[0] < size[1]:
        R = R[:, [1, 0, 2]]
    return geometry.yaw_deg(R, up)


def yaw_error_deg(R_true: ArrayLike, size_true: ArrayLike, R_est: ArrayLike,
                  size_est: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> float:
    """Signed yaw error Ψ_e of the long axis, degrees, in [−90, 90) — or [−45, 45) for a
    square cover (the true length and width differ by less than 1 cm): a rectangle looks the
    same turned by 180°, a square by 90° (DESIGN §2)."""
    s = np.asarray(size_true, np.float64)
    period = 90.0 if abs(s[0] - s[1]) < SQUARE_TOL_M else 180.0
    d = long_axis_heading_deg(R_est, size_est, up) - long_axis_heading_deg(R_true, s, up)
    return float((d + 0.5 * period) % period - 0.5 * period)


def book_errors(true: Book, est: Book, up: ArrayLike = (0.0, 0.0, 1.0)) -> dict[str, float | None]:
    """Errors of one matched book, estimate minus truth (world frame).

    Returns
    -------
    dict
        ``x``, ``y``, ``z`` (m, of the centre), ``psi_deg`` (:func:`yaw_error_deg`),
        ``length``, ``width`` (m, of the cover's longer and shorter side), ``height`` (m; None
        when the estimate has no height).
    """
    d = est.center - true.center
    ls, lt = np.sort(est.size[:2]), np.sort(true.size[:2])
    height = est.size[2] - true.size[2]
    return {"x": float(d[0]), "y": float(d[1]), "z": float(d[2]),
            "psi_deg": yaw_error_deg(true.R, true.size, est.R, est.size, up),
            "length": float(ls[1] - lt[1]), "width": float(ls[0] - lt[0]),
            "height": float(height) if np.isfinite(height) else None}


def score_books(truth: Sequence[Book], detections: Sequence[Book], *,
                up: ArrayLike = (0.0, 0.0, 1.0), radius: float = MATCH_RADIUS_M) -> dict[str, Any]:
    """Score one image's detections against its true books.

    Returns
    -------
    dict
        ``n_detections``, ``false_positives`` (detections matched to no book), ``found``
        (per true book, its detection index or None) and ``matches``: per matched book its
        ``truth`` and ``detection`` index, centre ``distance`` (m), ``errors``
        (:func:`book_errors`), the estimated ``center`` and long-axis ``yaw_deg``.
    """
    pairs = match_books([b.center for b in truth], [d.center for d in detections], radius=radius)
    found: list[int | None] = [None] * len(truth)
    matches = []
    for i, j in pairs:
        t, e = truth[i], detections[j]
        found[i] = j
        matches.append({"truth": i, "detection": j,
                        "distance": float(np.linalg.norm(e.center - t.center)),
                        "errors": book_errors(t, e, up),
                        "center": [float(v) for v in e.center],
                        "yaw_deg": long_axis_heading_deg(e.R, e.size, up)})
    return {"n_detections": len(detections), "false_positives": len(detections) - len(pairs),
            "found": found, "matches": matches}


# --------------------------------------------------------------------------- one scene


def _scene_info(doc: dict[str, Any], truth: Sequence[Book], up: NDArray[np.float64]) -> dict[str, Any]:
    lux = doc.get("lux")
    return {
        "protocol": doc.get("protocol") if isinstance(doc.get("protocol"), str) else None,
        "lux": float(lux) if isinstance(lux, (int, float)) and math.isfinite(lux) else None,
        "light": doc.get("light") if isinstance(doc.get("light"), str) else None,
        "exposure": doc.get("exposure") if isinstance(doc.get("exposure"), str) else None,
        "books": [{"id": b.id, "center": [float(v) for v in b.center],
                   "yaw_deg": long_axis_heading_deg(b.R, b.size, up),
                   "size": [float(v) for v in b.size], "visible": b.visible,
                   **_cover_of(doc, k)} for k, b in enumerate(truth)],
    }


def _cover_of(doc: dict[str, Any], k: int) -> dict[str, str]:
    """``{"cover": kind}``, the cover kind (DESIGN §4) ``truth.json`` gives its ``k``-th
    book, or nothing where it gives none."""
    books = doc.get("books")
    if isinstance(books, list) and k < len(books) and isinstance(books[k], dict):
        kind = books[k].get("cover")
        if isinstance(kind, str):
            return {"cover": kind}
    return {}


def _up(doc: dict[str, Any]) -> NDArray[np.float64]:
    plane = doc.get("desk_plane")
    try:
        n = np.asarray(plane, np.float64)[:3]
        if n.shape == (3,) and np.all(np.isfinite(n)) and np.linalg.norm(n) > 0:
            return n / np.linalg.norm(n)
    except (TypeError, ValueError, IndexError):
        pass
    return np.array([0.0, 0.0, 1.0])


def load_scene(scene_dir: str | os.PathLike[str]) -> tuple[dict[str, Any], list[Book], Any, Any]:
    """``truth.json`` (its document and books) and the left and right images of a scene.

    Raises
    ------
    ValueError
        Naming the file and what is wrong with it.
    """
    from rovis.imageio import read_gray

    scene_dir = Path(scene_dir)
    path = scene_dir / "truth.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError("truth.json: not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"truth.json: unreadable ({exc})") from None
    try:
        truth = parse_truth(doc)
    except ValueError as exc:
        raise ValueError(f"truth.json: {exc}") from None
    images = []
    for cam in ("left", "right"):
        image_path = scene_dir / f"{cam}.png"
        try:
            images.append(read_gray(image_path))
        except ValueError as exc:
            raise ValueError(f"{cam}.png: {str(exc).removeprefix(f'{image_path}: ')}") from None
    return doc, truth, images[0], images[1]


def score_scene(scene_dir: str | os.PathLike[str], detectors: Mapping[str, Any]) -> dict[str, Any]:
    """Run every detector on one scene and score it.

    Parameters
    ----------
    scene_dir : path
        ``DATASET/scenes/NNNN``, holding ``left.png``, ``right.png``, ``truth.json``.
    detectors : mapping of method name to :class:`rovis.pipeline.Detector`
        Each is reset before the scene.

    Returns
    -------
    dict
        ``scene`` (the folder's name), the scene's ``protocol``, ``lux``, ``light``,
        ``exposure`` and true ``books``, per method the :func:`score_books` record under
        ``methods`` (with ``sources``: per detection, how it was found,
        :attr:`rovis.results.BookDetection.source`; and ``quality`` and
        ``reprojection_error_px``, per detection too), and ``timing_ms`` (per method, the
        pipeline's wall time). A method that raised on the scene has ``failed`` (the
        exception, named) in its record and no detections: its books count as missed. A
        scene no method can run on (unreadable, or images the calibration does not fit) is
        ``{"scene": name, "skipped": reason}`` instead.
    """
    name = Path(scene_dir).name
    try:
        doc, truth, left, right = load_scene(scene_dir)
    except ValueError as exc:
        return {"scene": name, "skipped": str(exc)}
    up = _up(doc)
    record = {"scene": name, **_scene_info(doc, truth, up), "methods": {}, "timing_ms": {}}
    for detector in detectors.values():
        try:
            detector.check_input(left, right)
        except ValueError as exc:  # images the calibration does not fit: no method can run
            return {"scene": name, "skipped": str(exc)}
    for method, detector in detectors.items():
        detector.reset()
        t0 = time.perf_counter()
        try:
            result = detector.detect(left, right)
        except Exception as exc:  # noqa: BLE001 — a detector bug: named, not fatal
            # that method found nothing here (its books count as missed); the other
            # methods' scores of the scene are kept
            record["timing_ms"][method] = 1e3 * (time.perf_counter() - t0)
            record["methods"][method] = {**score_books(truth, [], up=up), "sources": [],
                                         "failed": f"{type(exc).__name__}: {exc}"}
            continue
        record["timing_ms"][method] = 1e3 * (time.perf_counter() - t0)
        dets = [Book.from_pose(obj.pose, obj.id) for obj in result.objects]
        record["methods"][method] = score_books(truth, dets, up=up)
        record["methods"][method]["sources"] = [obj.source for obj in result.objects]
        # per detection, how well it agrees with the images (rovis.agreement)
        record["methods"][method]["quality"] = [round(obj.quality, 4) for obj in result.objects]
        record["methods"][method]["reprojection_error_px"] = [
            round(obj.reprojection_error_px, 4) for obj in result.objects]
    return record


# --------------------------------------------------------------------------- workers

_WORKER = threading.local()  # per thread: a Dask worker may run several task threads


def _init_worker(calib: str, methods: tuple[str, ...], one_thread: bool,
                 settings: tuple[str, ...] = ()) -> None:
    """Build one Detector per method, once per worker process (or thread)."""
    from rovis.calib import load_calibration
    from rovis.pipeline import DetectConfig, Detector, with_settings

    if one_thread:
        import cv2

        cv2.setNumThreads(1)  # the pool already uses the cores
    rig = load_calibration(calib)
    base = with_settings(DetectConfig(), settings)
    _WORKER.detectors = {m: Detector(rig, replace(base, method=m)) for m in methods}
    _WORKER.key = (calib, methods, settings)


def _score_in_worker(scene_dir: str) -> dict[str, Any]:
    return score_scene(scene_dir, _WORKER.detectors)


def _score_on_dask(scene_dir: str, calib: str, methods: tuple[str, ...],
                   settings: tuple[str, ...] = ()) -> dict[str, Any]:
    if getattr(_WORKER, "key", None) != (calib, methods, settings):
        _init_worker(calib, methods, False, settings)
    return _score_in_worker(scene_dir)


# --------------------------------------------------------------------------- a dataset


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The scored scenes of one ``rovis eval`` run.

    Attributes
    ----------
    dataset : str
    methods : tuple of str
    scenes : list of dict
        One :func:`score_scene` record per scored scene, in scene order.
    skipped : list of dict
        ``{"scene", "reason"}`` per scene that could not be scored.
    settings : tuple of str
        Detector settings changed from the defaults (``NAME=VALUE``, as ``--set`` takes).
    """

    dataset: str
    methods: tuple[str, ...]
    scenes: list[dict[str, Any]]
    skipped: list[dict[str, str]] = field(default_factory=list)
    settings: tuple[str, ...] = ()

    @property
    def protocol(self) -> str | None:
        """The dataset's protocol (the one most scenes carry), or None."""
        names = [s["protocol"] for s in self.scenes if s.get("protocol")]
        return max(set(names), key=names.count) if names else None

    def summary(self) -> dict[str, Any]:
        """:func:`summarize` of these scenes."""
        return summarize(self.scenes, self.methods)

    def to_dict(self) -> dict[str, Any]:
        """What ``results.json`` holds: the summary, the breakdowns and every scene."""
        return {"schema": SCHEMA, "dataset": self.dataset, "protocol": self.protocol,
                "methods": list(self.methods),
                "settings": {"match_radius_m": MATCH_RADIUS_M, "visible_min": VISIBLE_MIN,
                             "square_tol_m": SQUARE_TOL_M, "detector": list(self.settings)},
                "n_scenes": len(self.scenes), "n_skipped": len(self.skipped),
                "summary": self.summary(),
                "breakdown": {**breakdown(self.scenes, self.methods),
                              "source": source_breakdown(self.scenes, self.methods),
                              "cover": cover_breakdown(self.scenes, self.methods)},
                "skipped": list(self.skipped), "scenes": list(self.scenes)}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> Evaluation:
        """Back from a ``results.json`` document."""
        return cls(dataset=doc["dataset"], methods=tuple(doc["methods"]),
                   scenes=list(doc["scenes"]), skipped=list(doc.get("skipped", [])),
                   settings=tuple(doc.get("settings", {}).get("detector", ())))


def list_scenes(dataset: str | os.PathLike[str]) -> list[Path]:
    """The scene folders ``DATASET/scenes/*`` in sorted order.

    Raises
    ------
    ValueError
        No such folder, no ``calib.yaml``, or no scene in it.
    """
    ds = Path(dataset)
    if not ds.exists():
        raise ValueError(f"{ds}: no such folder")
    if not ds.is_dir():
        raise ValueError(f"{ds}: not a folder")
    if not (ds / "calib.yaml").is_file():
        raise ValueError(f"{ds}: no calib.yaml (expected a dataset written by rovis synth: "
                         "calib.yaml, scenes/NNNN/)")
    scenes = sorted(p for p in (ds / "scenes").glob("*") if p.is_dir()) \
        if (ds / "scenes").is_dir() else []
    if not scenes:
        raise ValueError(f"{ds}: no scenes (expected folders {ds / 'scenes'}/NNNN/ with "
                         "left.png, right.png, truth.json)")
    return scenes


def evaluate(dataset: str | os.PathLike[str], methods: Sequence[str] = METHODS, *,
             workers: int = 1, dask: str | None = None, limit: int | None = None,
             settings: Sequence[str] = (), progress: Progress | None = None) -> Evaluation:
    """Score every scene of a dataset with every method.

    Parameters
    ----------
    dataset : path
        A folder of DESIGN §3's layout: ``calib.yaml`` and ``scenes/NNNN/``.
    methods : sequence of str
        Segmentation methods (:data:`METHODS`).
    workers : int
        1: in this process. More: a local process pool of that many workers, each building
        its detectors once (OpenCV then runs single-threaded in each).
    dask : str, optional
        Address of a Dask distributed scheduler (``tcp://host:8786``): score the scenes there
        (``client.map`` over scenes) instead. The dataset must be readable at the same path on
        the workers. Needs the ``dask`` extra.
    limit : int, optional
        Only the first ``limit`` scenes.
    settings : sequence of str
        Detector settings to change, ``NAME=VALUE`` (:func:`rovis.pipeline.with_settings`).
    progress : callable, optional
        ``progress(done, total, skipped)`` after each scene.

    Raises
    ------
    ValueError
        An unknown method, a bad count or setting, or a dataset that is not one (see
        :func:`list_scenes`).
    ImportError
        ``dask`` given without dask.distributed installed.
    """
    from rovis.calib import load_calibration
    from rovis.pipeline import DetectConfig, with_settings

    methods = tuple(dict.fromkeys(methods))
    settings = tuple(settings)
    with_settings(DetectConfig(), settings)  # a bad setting is one error here
    if not methods:
        raise ValueError("methods: expected at least one")
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"methods: unknown {', '.join(bad)} (expected some of "
                         f"{', '.join(METHODS)})")
    if workers < 1:
        raise ValueError(f"workers: expected a positive integer, got {workers}")
    if limit is not None and limit < 1:
        raise ValueError(f"limit: expected a positive integer, got {limit}")
    scenes = list_scenes(dataset)[:limit]
    calib = str(Path(dataset) / "calib.yaml")
    load_calibration(calib)  # a bad calibration is one error here, not one per scene
    paths = [str(p) for p in scenes]

    if dask is not None:
        records = _run_dask(dask, paths, calib, methods, settings, progress)
    elif workers == 1:
        _init_worker(calib, methods, False, settings)
        records = _collect(map(_score_in_worker, paths), len(paths), progress)
    else:
        records = _run_pool(workers, paths, calib, methods, settings, progress)
    scored = [r for r in records if "skipped" not in r]
    skipped = [{"scene": r["scene"], "reason": r["skipped"]} for r in records if "skipped" in r]
    return Evaluation(str(dataset), methods, scored, skipped, settings)


def _collect(results: Iterable[dict[str, Any]], total: int,
             progress: Progress | None) -> list[dict[str, Any]]:
    out, skipped = [], 0
    for record in results:
        out.append(record)
        skipped += "skipped" in record
        if progress is not None:
            progress(len(out), total, skipped)
    return out


def _run_pool(workers: int, paths: list[str], calib: str, methods: tuple[str, ...],
              settings: tuple[str, ...], progress: Progress | None) -> list[dict[str, Any]]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # spawn, not fork: a child forked after OpenCV's thread pool has run can deadlock in it
    with ProcessPoolExecutor(max_workers=min(workers, len(paths)), initializer=_init_worker,
                             initargs=(calib, methods, True, settings),
                             mp_context=multiprocessing.get_context("spawn")) as pool:
        # map keeps the scene order; chunks of one keep the workers evenly busy
        return _collect(pool.map(_score_in_worker, paths, chunksize=1), len(paths), progress)


def _run_dask(address: str, paths: list[str], calib: str, methods: tuple[str, ...],
              settings: tuple[str, ...], progress: Progress | None) -> list[dict[str, Any]]:
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise ImportError("--dask needs dask.distributed: pip install 'rovis[dask]'") from exc
    try:
        client = Client(address, timeout=30, set_as_default=False)
    except OSError as exc:
        raise OSError(f"--dask {address}: cannot reach the scheduler ({exc})") from None
    with client:
        futures = client.map(_score_on_dask, paths, calib=calib, methods=methods,
                             settings=settings, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        records: list[dict[str, Any] | None] = [None] * len(paths)
        done = skipped = 0
        for fut in as_completed(futures, loop=client.loop):
            record = fut.result()
            records[index[fut.key]] = record
            done += 1
            skipped += "skipped" in record
            if progress is not None:
                progress(done, len(paths), skipped)
    return [r for r in records if r is not None]


# --------------------------------------------------------------------------- statistics


def _within_grasp(errors: Mapping[str, float]) -> bool:
    """Whether a matched book's errors (metres) lie within the grasp tolerance on every
    axis of X, Y, Z (exactly 1 cm off counts as within)."""
    return max(abs(errors[c]) for c in ("x", "y", "z")) <= GRASP_TOLERANCE_M


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    """max, mean and std (population) of the absolute values, as the paper's tables give
    them, and their median and 95th percentile (linear interpolation): a few books found
    centimetres or 90° off carry most of a mean, and the median and 95th percentile say
    what the rest come to. None for no values."""
    a = np.abs(np.asarray([v for v in values if v is not None], np.float64))
    if a.size == 0:
        return {"max": None, "mean": None, "std": None, "median": None, "p95": None, "n": 0}
    return {"max": float(a.max()), "mean": float(a.mean()), "std": float(a.std()),
            "median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
            "n": int(a.size)}


def summarize_method(records: Iterable[Mapping[str, Any]], method: str) -> dict[str, Any]:
    """One method's figures over scene records (:func:`score_scene`).

    Returns
    -------
    dict
        ``images``, ``books``, ``found``, ``recall`` (None without books); the same for books
        at least 90 % visible in both images (``visible_books``, ``visible_found``,
        ``recall_visible``); ``false_positives`` and ``fp_per_image``; and ``errors``: per
        error (``x y z psi_deg length width height``) the ``max``, ``mean``, ``std``,
        ``median`` and ``p95`` (95th percentile) of its absolute value over the matched
        books, with their count ``n``; ``within_1cm``: the
        matched books within 1 cm of the truth along each of X, Y, Z (the grasp tolerance);
        ``failed``: the images on which the method raised (their books counted as missed).
    """
    images = books = found = vis_books = vis_found = fps = within = failed = 0
    errs: dict[str, list[float]] = {k: [] for k in ERROR_KEYS}
    for rec in records:
        score = rec["methods"].get(method)
        if score is None:
            continue
        images += 1
        failed += "failed" in score
        books += len(rec["books"])
        found += sum(j is not None for j in score["found"])
        for b, j in zip(rec["books"], score["found"]):
            if b.get("visible"):
                vis_books += 1
                vis_found += j is not None
        fps += score["false_positives"]
        for m in score["matches"]:
            for k in ERROR_KEYS:
                errs[k].append(m["errors"][k])
            within += _within_grasp(m["errors"])
    return {"images": images, "books": books, "found": found, "within_1cm": within,
            "recall": found / books if books else None,
            "visible_books": vis_books, "visible_found": vis_found,
            "recall_visible": vis_found / vis_books if vis_books else None,
            "false_positives": fps, "fp_per_image": fps / images if images else None,
            "failed": failed, "errors": {k: _stats(v) for k, v in errs.items()}}


def summarize(records: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """:func:`summarize_method` for each method."""
    return {m: summarize_method(records, m) for m in methods}


def lux_band(lux: float | None, edges: Sequence[float] = LUX_EDGES) -> str | None:
    """The band ``"15-50 lx"`` … ``"500-1200 lx"`` holding ``lux`` (lower edge included, the
    top one too); ``"<15 lx"`` / ``">1200 lx"`` outside; None for an unknown level."""
    if lux is None:
        return None
    if lux < edges[0]:
        return f"<{edges[0]:g} lx"
    if lux > edges[-1]:
        return f">{edges[-1]:g} lx"
    for lo, hi in zip(edges[:-1], edges[1:]):
        if lux < hi:
            return f"{lo:g}-{hi:g} lx"
    return f"{edges[-2]:g}-{edges[-1]:g} lx"


def _band_order(label: str) -> float:
    text = label.lstrip("<>").split("-")[0].split(" ")[0]
    return float(text) - (0.5 if label.startswith("<") else 0.0)


def breakdown(records: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """The summary per lux band, per light (daylight / artificial) and per exposure mode —
    each only where the truth records it."""
    keys: dict[str, Callable[[Mapping[str, Any]], str | None]] = {
        "lux": lambda r: lux_band(r.get("lux")),
        "light": lambda r: r.get("light"),
        "exposure": lambda r: r.get("exposure"),
    }
    out: dict[str, Any] = {}
    for name, key in keys.items():
        groups: dict[str, list[Mapping[str, Any]]] = {}
        for rec in records:
            label = key(rec)
            if label is not None:
                groups.setdefault(label, []).append(rec)
        order = sorted(groups, key=_band_order) if name == "lux" else sorted(groups)
        out[name] = {label: summarize(groups[label], methods) for label in order}
    return out


def source_breakdown(records: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """Per method and per source (how each detection was found,
    :attr:`rovis.results.BookDetection.source`): ``detections``, ``matched``,
    ``false_positives``, ``over_1cm`` (matched books more than 1 cm off along some axis:
    beyond the grasp tolerance) and the ``errors`` of the matched ones (as
    :func:`summarize_method`). Records without sources (an older results.json) count
    nothing."""
    out: dict[str, Any] = {}
    for method in methods:
        groups: dict[str, dict[str, Any]] = {}
        for rec in records:
            score = rec["methods"].get(method)
            if score is None or "sources" not in score:
                continue
            matched = {m["detection"]: m for m in score["matches"]}
            for j, source in enumerate(score["sources"]):
                g = groups.setdefault(source, {"detections": 0, "matched": 0, "over_1cm": 0,
                                               "errs": {k: [] for k in ERROR_KEYS}})
                g["detections"] += 1
                if j in matched:
                    g["matched"] += 1
                    e = matched[j]["errors"]
                    g["over_1cm"] += not _within_grasp(e)
                    for k in ERROR_KEYS:
                        g["errs"][k].append(e[k])
        out[method] = {src: {"detections": g["detections"], "matched": g["matched"],
                             "false_positives": g["detections"] - g["matched"],
                             "over_1cm": g["over_1cm"],
                             "errors": {k: _stats(v) for k, v in g["errs"].items()}}
                       for src, g in sorted(groups.items(), key=lambda kv: -kv[1]["detections"])}
    return out


def cover_breakdown(records: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """Per method and per cover kind of the true books (``cover`` in ``truth.json``: plain,
    dark, light, desk, printed, photo; DESIGN §4): ``books``, ``found`` (matched),
    ``within_1cm`` (matched within the grasp tolerance on every axis of X, Y, Z) and the
    ``errors`` of the matched ones (as :func:`summarize_method`). Books whose truth names
    no kind (real data, an older results.json) count nothing. Where a method's books are
    lost or misplaced, by what their covers look like."""
    out: dict[str, Any] = {}
    for method in methods:
        groups: dict[str, dict[str, Any]] = {}
        for rec in records:
            score = rec["methods"].get(method)
            if score is None:
                continue
            matched = {m["truth"]: m for m in score["matches"]}
            for t, book in enumerate(rec.get("books", [])):
                kind = book.get("cover")
                if not isinstance(kind, str):
                    continue
                g = groups.setdefault(kind, {"books": 0, "found": 0, "within_1cm": 0,
                                             "errs": {k: [] for k in ERROR_KEYS}})
                g["books"] += 1
                if t in matched:
                    g["found"] += 1
                    e = matched[t]["errors"]
                    g["within_1cm"] += _within_grasp(e)
                    for k in ERROR_KEYS:
                        g["errs"][k].append(e[k])
        out[method] = {kind: {"books": g["books"], "found": g["found"],
                              "within_1cm": g["within_1cm"],
                              "errors": {k: _stats(v) for k, v in g["errs"].items()}}
                       for kind, g in sorted(groups.items(), key=lambda kv: -kv[1]["books"])}
    return out


def furthest_books(records: Sequence[Mapping[str, Any]], method: str,
                   n: int = 10) -> list[dict[str, Any]]:
    """The ``n`` matched books ``method`` found furthest off along their worst axis of X, Y,
    Z, furthest first: per book its ``scene``, ``lux``, ``truth`` (the book's index in the
    scene's truth), ``worst`` (m), ``errors`` (:func:`book_errors`) and, where the record
    has them, the detection's ``source`` and ``quality``. Where to look first: a few books
    far off carry most of a mean (:func:`_stats`)."""
    rows = []
    for rec in records:
        score = rec["methods"].get(method)
        if score is None:
            continue
        for m in score["matches"]:
            e = m["errors"]
            row = {"scene": rec.get("scene"), "lux": rec.get("lux"), "truth": m["truth"],
                   "worst": max(abs(e[c]) for c in ("x", "y", "z")), "errors": e}
            for key, name in (("sources", "source"), ("quality", "quality")):
                if key in score:
                    row[name] = score[key][m["detection"]]
            rows.append(row)
    # (a NaN error, which no check lets through, would sort first rather than anywhere)
    rows.sort(key=lambda r: -r["worst"] if np.isfinite(r["worst"]) else -np.inf)
    return rows[:n]


def agreement_breakdown(records: Sequence[Mapping[str, Any]],
                        methods: Sequence[str]) -> dict[str, Any]:
    """Per method and per measure of how well each detection agrees with the images
    (``quality``, ``reprojection_error_px``: :mod:`rovis.agreement`), per band of it
    (:data:`AGREEMENT_BANDS`, best first): ``detections``, ``within_1cm`` (matched, within
    the grasp tolerance on every axis), ``over_1cm`` (matched, beyond it) and
    ``false_positives``. What a robot can expect of a book reported with such a value.
    Records without the measures (an older results.json) count nothing."""
    out: dict[str, Any] = {}
    for method in methods:
        per: dict[str, dict[str, dict[str, int]]] = {}
        for measure, edges in AGREEMENT_BANDS.items():
            # a value on a band's edge counts in the better band: [0.9, 0.95), (0.5, 1]
            best_high = measure == "quality"
            labels = ([f"[{edges[0]:g}, 1]"]
                      + [f"[{b:g}, {a:g})" for a, b in zip(edges, edges[1:])]
                      + [f"[0, {edges[-1]:g})"]) if best_high else (
                [f"[0, {edges[0]:g}]"] + [f"({a:g}, {b:g}]" for a, b in zip(edges, edges[1:])]
                + [f"> {edges[-1]:g}"])
            bands = {label: {"detections": 0, "within_1cm": 0, "over_1cm": 0,
                             "false_positives": 0} for label in labels}
            counted = False
            for rec in records:
                score = rec["methods"].get(method)
                if score is None or measure not in score:
                    continue
                counted = True
                matched = {m["detection"]: m for m in score["matches"]}
                for j, value in enumerate(score[measure]):
                    k = (len(edges) if not np.isfinite(value)  # unmeasured: the worst band
                         else sum(value < e for e in edges) if best_high
                         else sum(value > e for e in edges))
                    band = bands[labels[k]]
                    band["detections"] += 1
                    if j not in matched:
                        band["false_positives"] += 1
                    elif _within_grasp(matched[j]["errors"]):
                        band["within_1cm"] += 1
                    else:
                        band["over_1cm"] += 1
            if counted:
                per[measure] = bands
        out[method] = per
    return out


# --------------------------------------------------------------------------- text


_LABELS = {"closed": "closed (ROVIS)", "open": "open loop"}
_COLS = ("x", "y", "z", "psi_deg")


def _num(v: float | None, width: int, nd: int) -> str:
    return f"{'-':>{width}}" if v is None else f"{v:{width}.{nd}f}"


def _pct(v: float | None) -> str:
    return "   -" if v is None else f"{100 * v:5.1f}%"


def method_table(method: str, s: Mapping[str, Any], paper: PaperTable | None) -> str:
    """One method's block in the layout of the paper's Tables I/II, the paper's figures on
    the right; below its max, mean and std, the median and 95th percentile (the paper
    gives none)."""
    found = (f"{s['found']} of {s['books']} books found (recall {_pct(s['recall']).strip()}; "
             f"{_pct(s['recall_visible']).strip()} of the {s['visible_books']} at least "
             f"{VISIBLE_MIN:.0%} visible in both images)")
    fp = "-" if s["fp_per_image"] is None else f"{s['fp_per_image']:.2f}"
    failed = (f"; failed on {s['failed']} image{'s' if s['failed'] != 1 else ''} (books "
              "counted as missed)" if s.get("failed") else "")
    lines = [f"{_LABELS.get(method, method)} — {s['images']} images: {found}, "
             f"{fp} false positives per image{failed}"]
    cols = f"{'X_e [m]':>9}{'Y_e [m]':>9}{'Z_e [m]':>9}{'Ψ_e [°]':>9}"
    if paper is not None:
        lines.append(f"{'':16}{'ours':^36}   | {paper.title}")
        lines.append(f"{'':16}{cols}   |{cols}")
    else:
        lines.append(f"{'':16}{cols}")
    e = s["errors"]
    for row, stat in (("Max error", "max"), ("Mean", "mean"), ("St. deviation", "std")):
        line = f"{row:<16}" + "".join(_num(e[k][stat], 9, 4) for k in _COLS[:3]) \
            + _num(e["psi_deg"][stat], 9, 2)
        if paper is not None:
            ref = getattr(paper, stat)
            line += "   |" + "".join(f"{v:9.4f}" for v in ref[:3]) + f"{ref[3]:9.1f}"
        lines.append(line)
    # not in the paper's tables: what the typical book comes to, without the few far off
    for row, stat in (("Median", "median"), ("95th percentile", "p95")):
        if stat in e["x"]:  # (an older results.json has only max, mean and std)
            lines.append(f"{row:<16}" + "".join(_num(e[k][stat], 9, 4) for k in _COLS[:3])
                         + _num(e["psi_deg"][stat], 9, 2) + ("   |" if paper is not None else ""))
    size = "  ".join(f"{k} {_num(e[k]['mean'], 0, 4).strip()} ± {_num(e[k]['std'], 0, 4).strip()}"
                     for k in ("length", "width", "height"))
    lines.append(f"{'size |error| [m]':<16} mean ± std: {size}  (n = {e['x']['n']} matched)")
    if "within_1cm" in s:  # (an older results.json has no count)
        lines.append(f"{'grasp tolerance':<16} {s['within_1cm']} of the {e['x']['n']} matched "
                     f"books within {GRASP_TOLERANCE_M * 100:g} cm of the truth along each of "
                     f"X, Y, Z")
    return "\n".join(lines)


def summary_table(summary: Mapping[str, Mapping[str, Any]]) -> str:
    """All methods, one row each: recall, false positives and mean absolute errors."""
    head = (f"{'method':<14}{'images':>7}{'books':>7}{'recall':>8}{'vis≥90%':>9}{'FP/img':>8}"
            f"{'|X_e| m':>9}{'|Y_e| m':>9}{'|Z_e| m':>9}{'|Ψ_e| °':>9}{'|len| m':>9}"
            f"{'|wid| m':>9}{'|hgt| m':>9}")
    rows = [head]
    for m, s in summary.items():
        e = s["errors"]
        rows.append(f"{m:<14}{s['images']:>7}{s['books']:>7}{_pct(s['recall']):>8}"
                    f"{_pct(s['recall_visible']):>9}{_num(s['fp_per_image'], 8, 2)}"
                    + "".join(_num(e[k]["mean"], 9, 4) for k in ("x", "y", "z"))
                    + _num(e["psi_deg"]["mean"], 9, 2)
                    + "".join(_num(e[k]["mean"], 9, 4) for k in ("length", "width", "height")))
    return "\n".join(rows)


def breakdown_table(groups: Mapping[str, Mapping[str, Mapping[str, Any]]], title: str) -> str:
    """Recall, false positives, mean position/yaw error and the largest position error per
    group and method (the grasp tolerance is on the largest); where a method raised on
    some image (:func:`score_scene`), a last column counts those images per group."""
    methods = list(next(iter(groups.values())).keys()) if groups else []
    failed = any(s.get("failed") for per_method in groups.values() for s in per_method.values())
    rows = [f"{title:<14}{'method':<14}{'images':>7}{'recall':>8}{'FP/img':>8}"
            f"{'|X_e| m':>9}{'|Y_e| m':>9}{'|Z_e| m':>9}{'|Ψ_e| °':>9}"
            f"{'max|X_e|':>10}{'max|Y_e|':>10}{'max|Z_e|':>10}"
            + (f"{'failed':>8}" if failed else "")]
    for label, per_method in groups.items():
        for k, m in enumerate(methods):
            s = per_method[m]
            e = s["errors"]
            rows.append(f"{label if k == 0 else '':<14}{m:<14}{s['images']:>7}"
                        f"{_pct(s['recall']):>8}{_num(s['fp_per_image'], 8, 2)}"
                        + "".join(_num(e[c]["mean"], 9, 4) for c in ("x", "y", "z"))
                        + _num(e["psi_deg"]["mean"], 9, 2)
                        + "".join(_num(e[c]["max"], 10, 4) for c in ("x", "y", "z"))
                        + (f"{s.get('failed', 0):>8}" if failed else ""))
    return "\n".join(rows)


def source_table(sources: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str:
    """Detections, matches, false positives and errors per method and source."""
    rows = [f"{'method':<14}{'found by':<14}{'detections':>11}{'matched':>8}{'FP':>5}"
            f"{'>1 cm':>6}{'|X_e| m':>9}{'|Y_e| m':>9}{'|Z_e| m':>9}"
            f"{'max|X_e|':>10}{'max|Y_e|':>10}{'max|Z_e|':>10}"]
    for method, per_source in sources.items():
        for k, (src, s) in enumerate(per_source.items()):
            e = s["errors"]
            rows.append(f"{method if k == 0 else '':<14}{src:<14}{s['detections']:>11}"
                        f"{s['matched']:>8}{s['false_positives']:>5}{s['over_1cm']:>6}"
                        + "".join(_num(e[c]["mean"], 9, 4) for c in ("x", "y", "z"))
                        + "".join(_num(e[c]["max"], 10, 4) for c in ("x", "y", "z")))
    return "\n".join(rows)


def cover_table(covers: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str:
    """True books, found, within 1 cm and mean absolute errors (mm, °) per method and cover
    kind (:func:`cover_breakdown`)."""
    rows = [f"{'method':<14}{'cover':<10}{'books':>6}{'found':>6}{'within 1 cm':>12}"
            f"{'|X_e| mm':>9}{'|Y_e| mm':>9}{'|Z_e| mm':>9}{'|Ψ_e| °':>8}"
            f"{'|len| mm':>9}{'|wid| mm':>9}"]

    def mm(v: float | None) -> float | None:
        return None if v is None else 1000.0 * v

    for method, per_kind in covers.items():
        for k, (kind, c) in enumerate(per_kind.items()):
            e = c["errors"]
            rows.append(f"{method if k == 0 else '':<14}{kind:<10}{c['books']:>6}"
                        f"{c['found']:>6}{c['within_1cm']:>12}"
                        + "".join(_num(mm(e[a]["mean"]), 9, 1) for a in ("x", "y", "z"))
                        + _num(e["psi_deg"]["mean"], 8, 2)
                        + "".join(_num(mm(e[a]["mean"]), 9, 1) for a in ("length", "width")))
    return "\n".join(rows)


def agreement_table(agreement: Mapping[str, Mapping[str, Mapping[str, Mapping[str, int]]]],
                    ) -> str:
    """Detections within and beyond the grasp tolerance, and false positives, per method,
    measure and band of it (:func:`agreement_breakdown`)."""
    rows = [f"{'method':<14}{'measure':<24}{'band':<13}{'detections':>11}{'within 1 cm':>12}"
            f"{'>1 cm':>6}{'FP':>5}{'within':>8}"]
    for method, per in agreement.items():
        first = True
        for measure, bands in per.items():
            name = "quality" if measure == "quality" else "reprojection error px"
            for k, (label, b) in enumerate(bands.items()):
                share = (f"{100.0 * b['within_1cm'] / b['detections']:7.0f}%"
                         if b["detections"] else f"{'-':>8}")
                rows.append(f"{method if first else '':<14}{name if k == 0 else '':<24}"
                            f"{label:<13}{b['detections']:>11}{b['within_1cm']:>12}"
                            f"{b['over_1cm']:>6}{b['false_positives']:>5}{share}")
                first = False
    return "\n".join(rows)


def furthest_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """:func:`furthest_books` as text: errors in millimetres and degrees, ``-`` where
    unknown (a book with no height, a record without lux, quality or source)."""
    def mm(e: Mapping[str, Any], keys: tuple[str, ...]) -> str:
        return "".join(_num(None if e[k] is None else 1000 * e[k], 8, 1) for k in keys)

    out = [f"{'scene':<8}{'book':>5}{'lux':>7}{'X_e mm':>8}{'Y_e mm':>8}{'Z_e mm':>8}{'Ψ_e °':>8}"
           f"{'len mm':>8}{'wid mm':>8}{'hgt mm':>8}  {'quality':>7}  found by"]
    for r in rows:
        e = r["errors"]
        out.append(f"{str(r['scene']):<8}{r['truth']:>5}{_num(r.get('lux'), 7, 0)}"
                   f"{mm(e, ('x', 'y', 'z'))}{_num(e['psi_deg'], 8, 2)}"
                   f"{mm(e, ('length', 'width', 'height'))}"
                   f"  {_num(r.get('quality'), 7, 2)}  {r.get('source', '-')}")
    return "\n".join(out)


def report(ev: Evaluation) -> str:
    """The text ``rovis eval`` prints: per method the Tables I/II block, a summary of all
    methods, and the breakdowns by light level, light and exposure (means, and the largest
    position errors in metres), by how each detection was found, by the true books' cover
    kind and by how well each detection agrees with the images; last, the first method's
    ten books furthest off (:func:`furthest_books`)."""
    summary = ev.summary()
    parts = [method_table(m, summary[m], paper_reference(m, ev.protocol)) for m in ev.methods]
    if ev.settings:
        parts.insert(0, "detector settings changed: " + ", ".join(ev.settings))
    parts.append("All methods (mean absolute errors of the matched books):\n"
                 + summary_table(summary))
    bd = breakdown(ev.scenes, ev.methods)
    for name, title in (("lux", "light level"), ("light", "light"), ("exposure", "exposure")):
        if len(bd[name]) > 1 or (name == "lux" and bd[name]):
            parts.append(f"By {title}:\n" + breakdown_table(bd[name], title))
    sources = source_breakdown(ev.scenes, ev.methods)
    if any(sources.values()):
        parts.append("By how each detection was found (>1 cm: matched books beyond the grasp "
                     "tolerance on some axis):\n" + source_table(sources))
    covers = cover_breakdown(ev.scenes, ev.methods)
    if any(covers.values()):
        parts.append("By the true book's cover (truth.json's kind; mean absolute errors of the "
                     "matched books):\n" + cover_table(covers))
    agreement = agreement_breakdown(ev.scenes, ev.methods)
    if any(agreement.values()):
        parts.append("By how well each detection agrees with the images (its quality and "
                     "reprojection error; within: the share of its band within 1 cm):\n"
                     + agreement_table(agreement))
    if ev.methods:
        furthest = furthest_books(ev.scenes, ev.methods[0])
        if furthest:
            name = _LABELS.get(ev.methods[0], ev.methods[0])
            parts.append(f"The {len(furthest)} matched books {name} found furthest off on "
                         "their worst axis of X, Y, Z (estimate minus truth):\n"
                         + furthest_table(furthest))
    return "\n\n".join(parts)


# --------------------------------------------------------------------------- files


def write_results(ev: Evaluation, out: str | os.PathLike[str], *, plots: bool = True) -> list[Path]:
    """Write ``OUT/results.json`` (everything), ``OUT/report.txt`` (the printed tables) and,
    with ``plots``, the figures of :mod:`rovis.evalplots` — each file whole (temporary file and
    rename).

    Raises
    ------
    ImportError
        ``plots`` without matplotlib installed (``results.json`` is written first).
    """
    from rovis.io import write_text_atomic

    out = Path(out)
    doc = ev.to_dict()
    written = [write_text_atomic(out / "results.json", json.dumps(doc, indent=1) + "\n"),
               write_text_atomic(out / "report.txt", report(ev) + "\n")]
    if plots:
        from rovis import evalplots

        written += evalplots.write_plots(doc, out)
    return written


def stderr_progress(prefix: str = "rovis eval") -> Progress:
    """A ``progress`` callback: a ``\\r`` counter on a terminal; on a log, a line each tenth
    of the way."""
    live = sys.stderr.isatty()

    def show(done: int, total: int, skipped: int) -> None:
        text = f"{prefix}: {done}/{total} scenes" + (f", {skipped} skipped" if skipped else "")
        if live:
            print("\r" + text, end="\n" if done == total else "", file=sys.stderr, flush=True)
        elif done == total or done * 10 // total != (done - 1) * 10 // total:
            print(text, file=sys.stderr, flush=True)  # a log: every tenth of the way

    return show
