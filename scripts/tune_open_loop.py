"""Tune the open loop's fixed thresholds once, at 500 lx (paper §5: "determined under an
optimal office lighting level of 500 lx"), as rovis's `open` baseline uses them.

Renders ``--n`` scenes at 500 lx artificial light (auto exposure), grid-searches T_H and T_HG
for the best 2D cover recall (all four corners within 3 px; books >= 90 % visible) on the
undistorted left images, and prints the grid and the winner.

    python scripts/tune_open_loop.py --n 12 --seed 500
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from rovis.pipeline import roi_mask
from rovis.segment import SegmentConfig, gradients
from rovis.segment.methods import segment
from rovis.segment.quads import order_corners
from rovis.synth import render, sample_scene

T_H_GRID = (20, 30, 45, 70, 100, 150, 220)
T_HG_GRID = (30, 40, 50, 60, 80)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=500)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    frames = []
    for i in range(args.n):
        sc = sample_scene(args.seed + i, lux=500.0, light="artificial")
        r, rig = render(sc, args.seed + i), sc.rig  # seeded sensor noise
        maps = cv2.initUndistortRectifyMap(rig.K1, rig.D1, None, rig.K1, rig.image_size, cv2.CV_16SC2)
        ideal = cv2.remap(r.left, *maps, cv2.INTER_LINEAR)
        truth = []
        for b in r.truth["books"]:
            if b["visible_left"] >= 0.9:
                h = np.array(b["corners"]) @ rig.Q_L[:, :3].T + rig.Q_L[:, 3]
                truth.append(order_corners(h[:, :2] / h[:, 2:]))
        frames.append((ideal, gradients(ideal, roi_mask(rig, "left", np.eye(4))), truth))
    total = sum(len(t) for _, _, t in frames)
    best = (-1, None)
    print(f"{args.n} scenes at 500 lx, {total} books; recall per T_H (rows) x T_HG (columns)")
    print("T_H \\ T_HG " + " ".join(f"{t:6d}" for t in T_HG_GRID))
    for T_H in T_H_GRID:
        row = []
        for T_HG in T_HG_GRID:
            cfg = SegmentConfig(open_T_H=T_H, open_T_HG=T_HG)
            found = 0
            for ideal, grad, truth in frames:
                seg = segment(ideal, grad, "open", cfg=cfg)
                found += sum(any(np.linalg.norm(q - c, axis=1).max() < 3.0 for q in seg.corners)
                             for c in truth)
            row.append(found / max(total, 1))
            if found > best[0]:
                best = (found, (T_H, T_HG))
        print(f"{T_H:10d} " + " ".join(f"{v:6.2f}" for v in row))
    print(f"best: T_H = {best[1][0]}, T_HG = {best[1][1]} ({best[0]}/{total} books)")


if __name__ == "__main__":
    main()
