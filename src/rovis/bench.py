"""Benchmarks (``rovis bench``): one-core timings with median and spread — the whole pipeline
per frame and stage on synthetic scenes, and triangulation."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

from rovis import geometry
from rovis.calib import StereoRig, make_rig

if TYPE_CHECKING:
    from rovis.pipeline import DetectConfig


@dataclass(frozen=True)
class Timing:
    """Wall-clock seconds of repeated runs of one stage."""

    name: str
    seconds: np.ndarray  # shape (repeats,)
    items: int  # items processed per run

    @property
    def median(self) -> float:
        return float(np.median(self.seconds))

    @property
    def rate(self) -> float:
        """Items per second at the median time."""
        return self.items / self.median

    def line(self) -> str:
        q1, q3 = np.percentile(self.seconds, [25, 75])
        return (f"{self.name:<24} median {self.median * 1e3:9.2f} ms  "
                f"(IQR {q1 * 1e3:.2f}-{q3 * 1e3:.2f} ms, n={len(self.seconds)})  "
                f"{self.rate / 1e6:7.2f} M points/s")


def bench_triangulation(n_points: int = 1_000_000, *, repeats: int = 7,
                        rng: np.random.Generator | int | None = 0) -> list[Timing]:
    """Time DLT and optimal triangulation of ``n_points`` on one core.

    Points are drawn 0.8–1.6 m in front of a Bumblebee2-like rig, projected and disturbed by
    0.5 px Gaussian noise; timings exclude the set-up.
    """
    if n_points <= 0 or repeats <= 0:
        raise ValueError(f"n_points and repeats must be positive, got {n_points}, {repeats}")
    cv2.setNumThreads(1)
    rng = np.random.default_rng(rng)
    rig = make_rig()
    P = rng.uniform([-0.5, -0.4, 0.8], [0.5, 0.4, 1.6], size=(n_points, 3))
    p_L, p_R = (geometry.project(Q, P) + rng.normal(0, 0.5, (n_points, 2)) for Q in (rig.Q_L, rig.Q_R))
    out = []
    for method in ("dlt", "optimal"):
        geometry.triangulate(rig.Q_L, rig.Q_R, p_L[:1000], p_R[:1000], method=method)  # warm-up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            geometry.triangulate(rig.Q_L, rig.Q_R, p_L, p_R, method=method)
            times.append(time.perf_counter() - t0)
        out.append(Timing(f"triangulate {method}", np.array(times), n_points))
    return out



# --------------------------------------------------------------------------- the pipeline

PIPELINE_STAGES = ("marker", "undistort", "gradients", "segmentation", "stereo", "pose", "heightmap",
                   "dense", "unskew", "side_height", "extent", "split", "trim", "feet", "join",
                   "overlaps", "under", "agreement", "track")
SEGMENTATION_STEPS = ("canny", "hough", "quads", "three_sided", "two_sided", "refine", "lsd")  # parts of "segmentation"


@dataclass(frozen=True)
class PipelineTiming:
    """Per-frame times of one method on one core: ``stages`` (ms, per stage of
    ``FrameResult.timing_ms``) and ``total_ms`` (wall time of ``Detector.detect``)."""

    method: str
    stages: dict[str, np.ndarray]  # stage -> shape (n,); also "segmentation.<step>"
    total_ms: np.ndarray  # shape (n,)
    books: int  # books found over all frames
    iterations: np.ndarray | None = None  # shape (n,): evaluations of the chain, both images

    @property
    def fps(self) -> float:
        """Frames per second on one core over all the frames (comparable with the pool's)."""
        return 1e3 * len(self.total_ms) / float(np.sum(self.total_ms))


@dataclass(frozen=True)
class PipelineBench:
    """What ``rovis bench pipeline`` measured."""

    n: int
    size: tuple[int, int]
    protocol: str
    method: str
    timings: dict[str, PipelineTiming]  # method -> timing; ``method`` and closed/open
    workers: int
    fps_all_cores: float | None  # frames/s of ``method`` over a pool of ``workers`` processes
    repeats: int = 1  # runs of each frame on one core, the fastest kept

    @property
    def segmentation_ratio(self) -> float | None:
        """Median segmentation time of closed loop over open loop."""
        if "closed" not in self.timings or "open" not in self.timings:
            return None
        closed = np.median(self.timings["closed"].stages["segmentation"])
        opened = np.median(self.timings["open"].stages["segmentation"])
        return float(closed / opened) if opened > 0 else None

    def text(self) -> str:
        """The table ``rovis bench`` prints."""
        w, h = self.size
        methods = list(self.timings)
        lines = [f"pipeline: {self.n} synthetic scenes ({self.protocol}), {w}x{h} stereo pairs, "
                 f"one core (cv2.setNumThreads(1)), detector reset before each frame "
                 f"(closed, warm: before each pair of frames of one scene, the second timed; "
                 f"closed, tracked: the second frame's books followed from the first, "
                 f"Detector.track, detected afresh where that fails); ms per frame, median (IQR)"
                 + (f", each frame the fastest of {self.repeats} runs" if self.repeats > 1
                    else "")]
        lines.append(f"{'stage':<14}" + "".join(f"{m:>26}" for m in methods))

        def cell(a: np.ndarray) -> str:
            q1, med, q3 = np.percentile(a, [25, 50, 75])
            return f"{med:9.1f} ({q1:7.1f}-{q3:7.1f})"

        for stage in PIPELINE_STAGES:
            lines.append(f"{stage:<14}" + "".join(f"{cell(self.timings[m].stages[stage]):>26}"
                                                  for m in methods))
            if stage == "segmentation":  # its steps, indented: they make up most of it
                for step in SEGMENTATION_STEPS:
                    key = f"segmentation.{step}"
                    lines.append(f"{'  ' + step:<14}" + "".join(
                        f"{cell(self.timings[m].stages[key]) if key in self.timings[m].stages else '-':>26}"
                        for m in methods))
                lines.append(f"{'  iterations':<14}" + "".join(
                    f"{np.median(self.timings[m].iterations) if self.timings[m].iterations is not None else float('nan'):>9.0f}{'':>17}"
                    for m in methods))
        lines.append(f"{'total':<14}" + "".join(f"{cell(self.timings[m].total_ms):>26}"
                                                for m in methods))
        lines.append(f"{'books found':<14}" + "".join(f"{self.timings[m].books:>26}"
                                                      for m in methods))
        ratio = self.segmentation_ratio
        if ratio is not None:
            lines.append(f"segmentation time, closed / open loop: {ratio:.2f}x (medians)")
        t = self.timings[self.method]
        rate = f"{self.method}: {t.fps:.2f} frames/s on one core"
        if self.fps_all_cores is not None:
            rate += (f", {self.fps_all_cores:.2f} frames/s on {self.workers} cores "
                     f"(process pool over the {self.n} frames)")
        lines.append(rate)
        return "\n".join(lines)


def scaled_rig(rig: StereoRig, size: tuple[int, int]) -> StereoRig:
    """The same cameras seen at another image size: intrinsics scaled about the pixel centres
    (``u' + ½ = s·(u + ½)``), distortion (in normalised coordinates) unchanged."""
    w0, h0 = rig.image_size  # type: ignore[misc]
    sx, sy = size[0] / w0, size[1] / h0
    S = np.array([[sx, 0.0, (sx - 1) / 2], [0.0, sy, (sy - 1) / 2], [0.0, 0.0, 1.0]])
    return StereoRig.from_arrays(K1=S @ rig.K1, D1=rig.D1, K2=S @ rig.K2, D2=rig.D2, R=rig.R,
                                 T=rig.T, image_size=size, T_world_left=rig.T_world_left,
                                 world_frame=rig.world_frame)


def render_frames(n: int, *, size: tuple[int, int] = (1024, 768), protocol: str = "mixed",
                  seed: int = 0, take: int = 0) -> tuple[StereoRig, list[tuple[np.ndarray, np.ndarray]]]:
    """``n`` synthetic stereo pairs (:mod:`rovis.synth`) and their rig, resized to ``size``
    when it is not the renderer's own. ``take`` > 0 renders the same scenes again with other
    sensor noise: the next frame of a camera that has not moved."""
    from rovis.synth.dataset import dataset_rig, dataset_scenes
    from rovis.synth.render import render

    rig = dataset_rig(seed)
    frames = []
    for i, scene in dataset_scenes(protocol, n, seed):
        r = render(scene, np.random.default_rng([seed, 9, i] + ([take] if take else [])))
        frames.append((r.left, r.right))
    if tuple(size) != tuple(rig.image_size):  # type: ignore[arg-type]
        interp = cv2.INTER_AREA if size[0] < rig.image_size[0] else cv2.INTER_LINEAR  # type: ignore[index]
        frames = [(cv2.resize(a, size, interpolation=interp),
                   cv2.resize(b, size, interpolation=interp)) for a, b in frames]
        rig = scaled_rig(rig, size)
    return rig, frames


def time_pipeline(rig: StereoRig, frames: list[tuple[np.ndarray, np.ndarray]], method: str, *,
                  previous: list[tuple[np.ndarray, np.ndarray]] | None = None,
                  cfg: DetectConfig | None = None, track: bool = False,
                  repeats: int = 1) -> PipelineTiming:
    """Per-frame and per-stage times of one Detector over ``frames``, on one core; the
    detector is reset before each frame, and a first warm-up frame is not counted.
    ``repeats``: each frame is timed that many times and its fastest run kept, stages and
    all (a run slowed by the machine's other work is left out, as :mod:`timeit` advises;
    the detector gives the same books every time). The runs after a frame's first find the
    detector's small caches of it filled, so compare two versions at the same ``repeats``.

    With ``previous`` (one frame per frame, e.g. the same scene with other sensor noise), each
    timed frame follows its previous one untimed, as in a still camera's sequence: the closed
    loop's controller then starts from that frame's optimum (warm start); with ``track``
    too, each timed frame follows the previous one's books (:meth:`Detector.track`) and is
    detected afresh only where that fails. ``cfg``: the detector's settings (its method
    replaced by ``method``)."""
    from rovis.pipeline import DetectConfig, Detector

    if repeats < 1:
        raise ValueError(f"repeats: expected a positive integer, got {repeats}")
    cv2.setNumThreads(1)
    detector = Detector(rig, replace(cfg or DetectConfig(), method=method))
    detector.detect(*frames[0])  # warm-up
    keys = PIPELINE_STAGES + tuple(f"segmentation.{step}" for step in SEGMENTATION_STEPS)
    stages: dict[str, list[float]] = {s: [] for s in keys}
    total, books, iterations = [], 0, []
    for k, (left, right) in enumerate(frames):
        best = None  # (ms, result) of the frame's fastest run
        for _ in range(repeats):
            detector.reset()
            if previous is not None:
                detector.detect(*previous[k])
            t0 = time.perf_counter()
            run = detector.track(left, right) if track else None
            if run is None:
                run = detector.detect(left, right)
            ms = 1e3 * (time.perf_counter() - t0)
            if best is None or ms < best[0]:
                best = (ms, run)
        assert best is not None
        ms, result = best
        total.append(ms)
        books += len(result.objects)
        iterations.append(sum(info.iterations for info in result.segmentation.values()))
        for s in keys:
            stages[s].append(result.timing_ms.get(s, np.nan))
    name = method if previous is None else f"{method}, {'tracked' if track else 'warm'}"
    # a stage the method never ran (lsd has no Canny) is left out; one it skipped counts 0
    timed = {s: np.nan_to_num(np.array(v)) for s, v in stages.items()
             if s in PIPELINE_STAGES or not np.all(np.isnan(v))}
    return PipelineTiming(name, timed, np.array(total), books, np.array(iterations))


_BENCH: dict[str, object] = {}


def _bench_init(rig: StereoRig, cfg: DetectConfig,
                frames: list[tuple[np.ndarray, np.ndarray]]) -> None:
    from rovis.pipeline import Detector

    cv2.setNumThreads(1)
    detector = Detector(rig, cfg)
    detector.detect(*frames[0])  # warm-up
    _BENCH.update(detector=detector, frames=frames)


def _bench_ready() -> int:
    return os.getpid()


def _bench_frame(i: int) -> int:
    detector, frames = _BENCH["detector"], _BENCH["frames"]
    detector.reset()  # type: ignore[attr-defined]
    return len(detector.detect(*frames[i]).objects)  # type: ignore[attr-defined, index]


def rate_all_cores(rig: StereoRig, frames: list[tuple[np.ndarray, np.ndarray]], method: str,
                   workers: int, cfg: DetectConfig | None = None) -> float:
    """Frames per second of ``method`` over a process pool of ``workers`` (one Detector and
    one OpenCV thread each; ``cfg``: its settings); the pool's start-up and warm-up are not
    counted."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, wait

    from rovis.pipeline import DetectConfig

    # spawn, not fork: a child forked after OpenCV's thread pool has run can deadlock in it
    with ProcessPoolExecutor(max_workers=workers, initializer=_bench_init,
                             initargs=(rig, replace(cfg or DetectConfig(), method=method),
                                       frames),
                             mp_context=multiprocessing.get_context("spawn")) as pool:
        wait([pool.submit(_bench_ready) for _ in range(workers)])
        t0 = time.perf_counter()
        list(pool.map(_bench_frame, range(len(frames)), chunksize=1))
        return len(frames) / (time.perf_counter() - t0)


def cpu_count() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def bench_pipeline(n: int = 30, *, size: tuple[int, int] = (1024, 768), method: str = "closed",
                   workers: int | None = None, protocol: str = "mixed", seed: int = 0,
                   settings: Sequence[str] = (), repeats: int = 1,
                   progress: Callable[[str], None] | None = None) -> PipelineBench:
    """Time the whole pipeline per frame and per stage (``rovis bench``).

    ``n`` synthetic scenes are rendered once; ``method`` is timed on one core, and so are
    closed and open loop (for their segmentation-time ratio), each frame from scratch; then
    the closed loop in a still-camera sequence (``closed, warm``: each scene's frame after
    one of the same scene, the controller warm-started), and the same with that frame's
    books followed into the next (``closed, tracked``); then ``method``'s rate over a
    process pool of ``workers`` (default: all cores; none with one core). ``settings``:
    ``NAME=VALUE`` changes to the detector's settings, as ``rovis eval --set``, for every
    method timed. ``repeats``: each frame on one core is timed that many times, the fastest
    run kept (:func:`time_pipeline`), for comparing two versions on a busy machine; the
    pool's rate is measured once.
    """
    from rovis.pipeline import METHODS, DetectConfig, with_settings

    if n <= 0:
        raise ValueError(f"n: expected a positive integer, got {n}")
    if repeats <= 0:
        raise ValueError(f"repeats: expected a positive integer, got {repeats}")
    if method not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    cfg = with_settings(DetectConfig(), settings)  # a bad setting fails before any rendering
    workers = cpu_count() if workers is None else workers
    say = progress or (lambda text: None)
    say(f"rovis bench: rendering {n} scenes")
    rig, frames = render_frames(n, size=size, protocol=protocol, seed=seed)
    timings = {}
    for m in dict.fromkeys((method, "closed", "open")):
        say(f"rovis bench: timing {m} on one core")
        timings[m] = time_pipeline(rig, frames, m, cfg=cfg, repeats=repeats)
    if "closed" in timings:  # the controller's warm start only pays in a sequence
        say("rovis bench: timing closed on one core, each frame after one of the same scene")
        _, next_frames = render_frames(n, size=size, protocol=protocol, seed=seed, take=1)
        timings["closed, warm"] = time_pipeline(rig, next_frames, "closed", previous=frames,
                                                cfg=cfg, repeats=repeats)
        say("rovis bench: timing closed on one core, each frame's books followed from the "
            "frame before")
        timings["closed, tracked"] = time_pipeline(rig, next_frames, "closed", previous=frames,
                                                   cfg=cfg, track=True, repeats=repeats)
    fps_all = None
    if workers > 1:
        say(f"rovis bench: timing {method} on {workers} cores")
        fps_all = rate_all_cores(rig, frames, method, workers, cfg)
    return PipelineBench(n=n, size=tuple(size), protocol=protocol, method=method,  # type: ignore[arg-type]
                         timings=timings, workers=workers, fps_all_cores=fps_all,
                         repeats=repeats)
