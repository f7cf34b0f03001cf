"""Tracking against detecting afresh, in a still camera's sequence of synthetic frames.

Renders ``--n`` table1 scenes (``rovis synth``'s scenes for ``--seed``), each as ``--frames``
frames with fresh sensor noise (a camera that does not move), and runs two detectors over
every scene's frames, timed on one core:

- ``detect``: :meth:`rovis.pipeline.Detector.detect` on every frame (controllers
  warm-started from the previous frame, as ``rovis detect`` on a sequence);
- ``track``: the policy of ``rovis detect --track K`` (:func:`rovis.sequence.run_sequence`):
  detect on the first frame and every K-th, follow the books on the others
  (:meth:`~rovis.pipeline.Detector.track`), detect afresh where following fails.

For each it prints the frames, the median time per frame, and the books against the truth
(matched as ``rovis eval`` matches them: centres within 5 cm, one-to-one): found, mean
|X|, |Y|, |Z| (mm), and how many are within the 1 cm grasp tolerance on every axis. Then,
per scene, the frame after the first with one book taken away: whether following noticed
(returned None, so the detector ran afresh).

    python scripts/track_study.py --n 20 --frames 5 --every 10
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import cv2
import numpy as np

from rovis.evaluate import match_books
from rovis.pipeline import Detector
from rovis.synth.dataset import dataset_rig, dataset_scenes
from rovis.synth.render import render


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20, help="scenes (default 20)")
    ap.add_argument("--frames", type=int, default=5, help="frames per scene (default 5)")
    ap.add_argument("--every", type=int, default=10,
                    help="detect afresh every this many frames when tracking (default 10)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if args.n < 1 or args.frames < 2 or args.every < 1:
        ap.error("--n and --every must be at least 1, --frames at least 2")
    cv2.setNumThreads(1)
    rig = dataset_rig(args.seed)
    stats = {name: {"ms": [], "found": 0, "books": 0, "err": [], "tracked": 0, "frames": 0}
             for name in ("detect", "track")}
    noticed, removals = 0, 0
    for i, scene in dataset_scenes("table1", args.n, args.seed):
        frames = [render(scene, np.random.default_rng([args.seed, 9, i, take]))
                  for take in range(args.frames)]
        truth = np.array([b["center"] for b in frames[0].truth["books"]]).reshape(-1, 3)
        for name in stats:
            det = Detector(rig)
            for k, fr in enumerate(frames):
                t0 = time.perf_counter()
                result = None
                if name == "track" and k % args.every != 0:
                    result = det.track(fr.left, fr.right)
                tracked = result is not None
                if result is None:
                    result = det.detect(fr.left, fr.right)
                s = stats[name]
                s["ms"].append(1e3 * (time.perf_counter() - t0))
                s["frames"] += 1
                s["tracked"] += tracked
                s["books"] += len(truth)
                est = np.array([o.pose.center for o in result.objects]).reshape(-1, 3)
                for t, e in match_books(truth, est):
                    s["found"] += 1
                    s["err"].append(np.abs(est[e] - truth[t]))
        # one book taken away after the first frame: following must notice
        if len(scene.books) > 1:
            det = Detector(rig)
            det.detect(frames[0].left, frames[0].right)
            gone = render(replace(scene, books=scene.books[1:]),
                          np.random.default_rng([args.seed, 9, i, 99]))
            removals += 1
            noticed += det.track(gone.left, gone.right) is None
        print(f"scene {i + 1}/{args.n}", end="\r", flush=True)
    print(f"{args.n} table1 scenes (seed {args.seed}) x {args.frames} frames, still camera; "
          f"track: detect every {args.every} frames")
    print(f"{'policy':<8} {'frames':>6} {'tracked':>7} {'median ms':>9} {'found':>11} "
          f"{'|X| mm':>7} {'|Y| mm':>7} {'|Z| mm':>7} {'within 1 cm':>11}")
    for name, s in stats.items():
        err = np.array(s["err"]).reshape(-1, 3)
        within = int(np.sum(np.all(err <= 0.01, axis=1)))
        mean = 1e3 * err.mean(axis=0) if len(err) else np.full(3, np.nan)
        print(f"{name:<8} {s['frames']:>6} {s['tracked']:>7} {np.median(s['ms']):>9.1f} "
              f"{s['found']:>5}/{s['books']:<5} {mean[0]:>7.2f} {mean[1]:>7.2f} {mean[2]:>7.2f} "
              f"{within:>11}")
    print(f"one book taken away: following noticed it in {noticed} of {removals} scenes")


if __name__ == "__main__":
    main()
