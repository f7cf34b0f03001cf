"""One scene of a ``rovis synth`` dataset, rendered as that command renders it, for the
tests that pin down what the pipeline does on a development set's scene (build/t1, t1b and
t1c are ``--protocol table1`` with seeds 1, 2 and 3, build/t1d with seed 4; build/t2
``--protocol table2`` with seed 1, build/t2b with seed 2)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rovis.synth import render
from rovis.synth.dataset import dataset_scenes


def dataset_scene(protocol: str, seed: int, i: int) -> tuple[Any, Any]:
    """Scene ``i`` of ``rovis synth --protocol PROTOCOL --seed SEED``: the scene and its
    rendering (the same sensor noise: :func:`rovis.synth.dataset.write_dataset`'s)."""
    sc = next(s for k, s in dataset_scenes(protocol, i + 1, seed=seed) if k == i)
    return sc, render(sc, np.random.default_rng([seed, 9, i]))
