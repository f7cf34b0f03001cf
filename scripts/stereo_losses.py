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

With ``--pools``, each lost book is also placed by the candidates stereo chooses among
(every quad of both images' :attr:`rovis.segment.Segmentation.pool`, ``open_pool``,
``late_pool`` and ``small_pool``, from the images' segmentations run again as the detector
runs them): ``pools: both`` (a candidate with every corner within 8 px of the cover in each
image; ``, under a book``: one of them lies under a book found in the end, by more than
30 % of the smaller quad in the left image), ``pools: one image`` or ``pools: neither``.

    python scripts/stereo_losses.py build/results/table1 --n 40
    python scripts/stereo_losses.py build/rt1 --pools

With ``--list``, each lost book is also named, one line each: its scene, its index in the
scene's truth.json, its cover, its height and its fate (and with ``--pools`` its place).
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
from rovis.results import FrameResult
from rovis.segment import CascadeController
from rovis.segment.methods import segment
from rovis.segment.quads import order_corners, quad_overlap

EXACT_PX, NEAR_PX = 3.0, 25.0  # px
POOL_PX = 8.0  # px: a candidate of the pools this near the cover at every corner


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


def pool_fate(detector: Detector, left: np.ndarray, right: np.ndarray,
              result: FrameResult, books: list[dict]) -> list[str]:
    """Where each of ``books`` (truth dicts) stands in both images' candidate pools, one
    line of ``--pools``' table each (``result``: the frame's detection, for "under a
    book")."""
    frame = detector._prepare(left, right)  # the detector's own undistortion and ROI
    quads = {}
    for cam in ("left", "right"):
        seg = segment(frame.ideal[cam], frame.grads[cam], detector.cfg.method,
                      controller=CascadeController(detector.cfg.segment, warm_start=False),
                      cfg=detector.cfg.segment)
        quads[cam] = np.concatenate([q.corners.reshape(-1, 4, 2) for q in (
            seg.pool, seg.open_pool, seg.late_pool, seg.small_pool)])
    Q = {"left": frame.rig.Q_L, "right": frame.rig.Q_R}
    found = [geometry.project(Q["left"], np.asarray(o.corners_world)) for o in result.objects]
    out = []
    for book in books:
        P = np.asarray(book["corners"], dtype=np.float64)
        near = {cam: corner_error(quads[cam], order_corners(geometry.project(Q[cam], P)))
                <= POOL_PX for cam in Q}
        if near["left"].any() and near["right"].any():
            under = any(quad_overlap(q, f) > 0.3 for q in quads["left"][near["left"]]
                        for f in found)
            out.append("pools: both" + (", under a book" if under else ""))
        elif near["left"].any() or near["right"].any():
            out.append("pools: one image")
        else:
            out.append("pools: neither")
    return out


def lost_line(scene: str, k: int, book: dict, what: str, place: str | None = None) -> str:
    """``--list``'s line for book ``k`` (its index in the scene's truth.json) of ``scene``:
    its cover, height and fate (and its place in the pools, if known)."""
    return (f"{scene} book {k}: {book.get('cover', '?')} cover, {book['size'][2] * 1e3:.0f} mm "
            f"high, {what}" + (f", {place}" if place is not None else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a folder written by rovis synth")
    ap.add_argument("--n", type=int, default=None, help="only the first N scenes")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a DetectConfig setting, as rovis eval --set")
    ap.add_argument("--pools", action="store_true",
                    help="also place each lost book by the candidate pools (slower)")
    ap.add_argument("--list", action="store_true", help="also name each lost book")
    args = ap.parse_args()
    scenes = list_scenes(args.dataset)[:args.n]
    rig = load_calibration(f"{args.dataset}/calib.yaml")
    detector = Detector(rig, with_settings(DetectConfig(), args.set))
    fates: Counter[str] = Counter()
    pools: Counter[str] = Counter()
    for k, scene in enumerate(scenes):
        doc, _, left, right = load_scene(scene)
        detector.reset()  # each scene on its own, as rovis eval
        result = detector.detect(left, right)
        matched = {t for t, _ in match_books([b["center"] for b in doc["books"]],
                                             [o.pose.center for o in result.objects])}
        lost = []  # (index in truth.json, book, fate)
        for k_book, book in enumerate(doc["books"]):
            if min(book["visible_left"], book["visible_right"]) >= 0.9:
                what = fate(result, rig, book, k_book in matched)
                fates[what] += 1
                if k_book not in matched:
                    lost.append((k_book, book, what))
        places = (pool_fate(detector, left, right, result, [b for _, b, _ in lost])
                  if args.pools and lost else [])
        pools.update(places)
        if args.list:
            for i, (k_book, book, what) in enumerate(lost):
                print("\r" + lost_line(scene.name, k_book, book, what,
                                       places[i] if places else None))
        print(f"\r{k + 1}/{len(scenes)} scenes", end="", flush=True)
    total = sum(fates.values())
    print(f"\n\n{total} books >= 90 % visible in both images, {len(scenes)} scenes of "
          f"{args.dataset}\n")
    print("| fate | books | share |\n|---|---|---|")
    for name, n in sorted(fates.items(), key=lambda kv: (kv[0] != "found", -kv[1])):
        print(f"| {name} | {n} | {100 * n / total:.0f}% |")
    if args.pools:
        print(f"\n{sum(pools.values())} lost books by their candidates ({POOL_PX:g} px)\n")
        print("| candidates | books |\n|---|---|")
        for name, n in pools.most_common():
            print(f"| {name} | {n} |")
    print("\n" + json.dumps(dict(fates) | ({"pools": dict(pools)} if args.pools else {})))


if __name__ == "__main__":
    main()
