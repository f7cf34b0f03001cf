"""scripts/stereo_losses.py --pools: a lost book placed by the candidate pools."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from rovis.pipeline import Detector
from rovis.synth import render, sample_scene
from rovis.synth.scene import Book
from rovis.synth.textures import CoverSpec

from script_module import load_script

stereo_losses = load_script("stereo_losses")


def test_a_book_the_pools_hold_and_one_they_do_not_are_told_apart():
    # one plain book alone on a clean desk: both images' pools hold its cover; a "book"
    # 25 cm beside it on the bare desk is in neither
    sc = sample_scene(5, lux=500.0, n_books=0)
    b = Book(center=(0.42, 0.30, 0.03), yaw_deg=25.0, size=(0.22, 0.15, 0.03),
             cover=CoverSpec(kind="plain", albedo=0.15, seed=2))
    sc = replace(sc, books=(b,), papers=(), mugs=(), pens=(), cables=())
    r = render(sc, 5)
    book = r.truth["books"][0]
    beside = dict(book, corners=(np.asarray(book["corners"]) + [0.0, 0.25, 0.0]).tolist())
    detector = Detector(sc.rig)
    nothing = SimpleNamespace(objects=[])
    assert stereo_losses.pool_fate(detector, r.left, r.right, nothing, [book, beside]) == [
        "pools: both", "pools: neither"]
    # the book found, lying over its own candidates
    found = detector.detect(r.left, r.right)
    assert len(found.objects) == 1
    assert stereo_losses.pool_fate(detector, r.left, r.right, found, [book]) == [
        "pools: both, under a book"]


def test_a_lost_book_is_named_on_one_line():
    book = {"cover": "photo", "size": [0.201, 0.111, 0.0114]}
    assert stereo_losses.lost_line("0024", 2, book, "lost: neither", "pools: both") == (
        "0024 book 2: photo cover, 11 mm high, lost: neither, pools: both")
    assert stereo_losses.lost_line("0024", 2, book, "lost: neither") == (
        "0024 book 2: photo cover, 11 mm high, lost: neither")
