"""Where the stereo pipeline loses books: each visible book's fate, from the covers the two
images' segmentations found to the books in the world.

Runs the closed loop (``rovis detect``'s defaults, or ``--set``) on the scenes of a dataset
written by ``rovis synth`` and, for every book at least 90 % visible in both images, names
what became of it:

- ``found``: matched to a detected book (centres within 5 cm, one-to-one: ``rovis eval``'s
  match);
- ``both``: each image's segmentation has a quad within 25 px of the book's cover there
  (every corner; ``< 3 px``: in each image some quad has every corner within 3 px, else
  ``>= 3 px``: a partial cover or one reaching beyond it); if the book was still lost, the
  check a dropped pair of such quads failed (``tilted``, ``height``, ``side on desk``,
  ``too long``, ``degenerate``: :data:`rovis.pipeline.DROP_REASONS`), or ``no dropped
  pair`` when no pair of them was dropped (never paired, or paired and then lost another
  way, e.g. to an overlapping book);
- ``one image``: a quad within 25 px in one image only (the one-image search may find the
  other);
- ``neither``: no quad within 25 px in either image (lost in segmentation).

    python scripts/stereo_losses.py build/results/table1 --n 40
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import numpy as np

from rovis import geometry
from rovis.calib import load_calibration
from rovis.evaluate import list_scenes, load_scene, match_books
from rovis.pipeline import DetectConfig, Detector, with_settings
from rovis.segment.quads import order_corners

EXACT_PX, NEAR_PX = 3.0, 25.0  # px


def corner_error(quads: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Largest corner distance (px) of each quad (K, 4, 2) to ``truth`` (4, 2), eq. 1 order."""
    if len(quads) == 0:
        return np.zeros(0)
    ordered = np.array([order_corners(q) for q in quads])
    return np.linalg.norm(ordered - truth[None], axis=2).max(axis=1)


def fate(result, rig, book: dict, found: bool) -> str:  # type: ignore[no-untyped-def]
    """What became of one true book in one frame's result (``found``: matched to a book)."""
    if found:
        return "found"
    P = np.asarray(book["corners"], dtype=np.float64)
    truth = {cam: order_corners(geometry.project(Q, P)) for cam, Q in (("left", rig.Q_L),
                                                                        ("right", rig.Q_R))}
    err = {cam: corner_error(result.covers[cam], truth[cam]) for cam in truth}
    near = {cam: bool(np.any(err[cam] < NEAR_PX)) for cam in truth}
    if near["left"] and near["right"]:
        exact = all(np.any(err[cam] < EXACT_PX) for cam in truth)
        how = f"both ({'<' if exact else '>='} {EXACT_PX:g} px)"
        for why, left, right in result.dropped:
            if corner_error(left[None], truth["left"])[0] < NEAR_PX and \
                    corner_error(right[None], truth["right"])[0] < NEAR_PX:
                return f"lost: {how}, dropped: {why}"
        return f"lost: {how}, no dropped pair"
    if near["left"] or near["right"]:
        return "lost: one image"
    return "lost: neither"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a folder written by rovis synth")
    ap.add_argument("--n", type=int, default=None, help="only the first N scenes")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a DetectConfig setting, as rovis eval --set")
    args = ap.parse_args()
    scenes = list_scenes(args.dataset)[:args.n]
    rig = load_calibration(f"{args.dataset}/calib.yaml")
    detector = Detector(rig, with_settings(DetectConfig(), args.set))
    fates: Counter[str] = Counter()
    for k, scene in enumerate(scenes):
        doc, _, left, right = load_scene(scene)
        detector.reset()  # each scene on its own, as rovis eval
        result = detector.detect(left, right)
        matched = {t for t, _ in match_books([b["center"] for b in doc["books"]],
                                             [o.pose.center for o in result.objects])}
        for k_book, book in enumerate(doc["books"]):
            if min(book["visible_left"], book["visible_right"]) >= 0.9:
                fates[fate(result, rig, book, k_book in matched)] += 1
        print(f"\r{k + 1}/{len(scenes)} scenes", end="", flush=True)
    total = sum(fates.values())
    print(f"\n\n{total} books >= 90 % visible in both images, {len(scenes)} scenes of "
          f"{args.dataset}\n")
    print("| fate | books | share |\n|---|---|---|")
    for name, n in sorted(fates.items(), key=lambda kv: (kv[0] != "found", -kv[1])):
        print(f"| {name} | {n} | {100 * n / total:.0f}% |")
    print("\n" + json.dumps(dict(fates)))


if __name__ == "__main__":
    main()
