"""Benchmarks (``rovis bench``): one-core timings with median and spread."""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from rovis import geometry
from rovis.calib import make_rig


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
    p_L, p_R = (_project(Q, P) + rng.normal(0, 0.5, (n_points, 2)) for Q in (rig.Q_L, rig.Q_R))
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


def _project(Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    h = P @ Q[:, :3].T + Q[:, 3]
    return h[:, :2] / h[:, 2:]
