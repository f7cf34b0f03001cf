"""``rovis bench synth``: one-core timing of scene sampling and stereo rendering."""

from __future__ import annotations

import time

import cv2
import numpy as np

from rovis.bench import Timing
from rovis.synth.dataset import dataset_rig
from rovis.synth.render import render
from rovis.synth.scene import sample_scene


def bench_synth(repeats: int = 7, *, seed: int = 0) -> list[Timing]:
    """Time :func:`sample_scene` and :func:`render` (one 1024×768 stereo pair, 2×2
    supersampling, mixed light) on one core, over ``repeats`` different scenes.

    The first render of a rig builds its distortion map and the cached textures; that warm-up
    is excluded, as in a dataset run where it happens once.
    """
    if repeats <= 0:
        raise ValueError(f"repeats: expected a positive integer, got {repeats}")
    cv2.setNumThreads(1)
    rig = dataset_rig(seed)
    render(sample_scene(np.random.default_rng([seed, 0]), rig=rig), 0)  # warm-up
    t_sample, t_render = [], []
    for k in range(repeats):
        t0 = time.perf_counter()
        scene = sample_scene(np.random.default_rng([seed, 1, k]), rig=rig)
        t1 = time.perf_counter()
        render(scene, k)
        t2 = time.perf_counter()
        t_sample.append(t1 - t0)
        t_render.append(t2 - t1)
    return [Timing("sample_scene", np.array(t_sample), 1),
            Timing("render stereo pair", np.array(t_render), 1)]
