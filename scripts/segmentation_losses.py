"""Where the closed loop loses books: each visible book's fate, stage by stage.

Renders ``--n`` mixed scenes like ``segmentation_study.py``, runs the closed loop on the
undistorted left image and, for every book whose cover is >= 90 % visible, names the first
stage of the chain that lost it, at the T_H the controller chose:

- ``found``: all four refined corners within 3 px of the truth;
- ``refine``: the chosen cover's Hough corners were within 5 px, refinement moved them away;
- ``selection``: a candidate quad within 5 px existed at the chosen T_HG but lost the
  one-quad-per-book selection;
- ``T_HG``: a candidate existed only below the chosen T_HG;
- ``quads``: all four sides are among the lines, but no candidate quad was formed;
- ``lines-K``: K sides are not among the ``N_max`` strongest Hough lines (4 px, 2.5°).

It also prints the oracle: the books found when T_H is picked per image by the truth
(from a 9-step log grid), which bounds what a better controller alone could gain, and each
book's weakest side contrast (median gradient across the side over the ROI's median
gradient), which bounds what any edge-based chain could see; and the share of books whose
four true sides pass the quad stage's edge-support test at one T_H of the grid, which bounds
what this chain, with its support rule, can find.

    python scripts/segmentation_losses.py --n 12 --seed 100
"""

from __future__ import annotations

import argparse
from collections import Counter

import cv2
import numpy as np

from rovis.pipeline import roi_mask
from rovis.segment import CascadeController, SegmentConfig, canny, gradients, hough_lines
from rovis.segment.boundary import evaluate, finish, roi_area
from rovis.segment.lines import Lines, support_profile
from rovis.segment.quads import _canonical, candidate_quads, order_corners
from rovis.synth import render, sample_scene


def side_rank(lines: Lines, a: np.ndarray, b: np.ndarray, tol_px: float = 4.0,
              tol_deg: float = 2.5) -> int:
    """Rank of the strongest line within tolerance of segment a–b, or -1."""
    d = b - a
    theta = (np.arctan2(d[1], d[0]) + np.pi / 2) % np.pi
    rho = a[0] * np.cos(theta) + a[1] * np.sin(theta)
    dth = np.abs(lines.theta - theta)
    rho_l = np.where(dth > np.pi / 2, -lines.rho, lines.rho)  # (ρ, θ) ≡ (−ρ, θ ± π)
    dth = np.minimum(dth, np.pi - dth)
    hit = np.nonzero((np.degrees(dth) < tol_deg) & (np.abs(rho_l - rho) < tol_px))[0]
    return int(hit[0]) if len(hit) else -1


def near(quads: np.ndarray, truth: np.ndarray, tol: float) -> bool:
    if len(quads) == 0:
        return False
    return bool(np.linalg.norm(_canonical(quads) - truth[None], axis=2).max(axis=1).min() < tol)


def side_contrast(grad, truth: np.ndarray, noise: float) -> float:  # type: ignore[no-untyped-def]
    """The weakest side's median gradient across it (best of ±2 px), over ``noise``."""
    worst = np.inf
    for k in range(4):
        a, b = truth[k], truth[(k + 1) % 4]
        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]])
        t = np.linspace(0.1, 0.9, 40)[:, None]
        best = 0.0
        for off in np.arange(-2.0, 2.5, 0.5):
            p = a + t * (b - a) + off * n
            gx, gy = grad.sample(p[:, 0], p[:, 1])
            best = max(best, float(np.median(np.abs(gx * n[0] + gy * n[1]))))
        worst = min(worst, best / max(noise, 1.0))
    return worst


def side_support(grad, edges: np.ndarray, truth: np.ndarray, trim: float = 3.0) -> float:  # type: ignore[no-untyped-def]
    """The weakest true side's edge coverage: the quad stage's support test (edge pixel
    within 1 px, gradient across the side) applied to the truth."""
    rho, theta, ta, tb = [], [], [], []
    for k in range(4):
        a, b = truth[k], truth[(k + 1) % 4]
        t = (np.arctan2(b[1] - a[1], b[0] - a[0]) + np.pi / 2) % np.pi
        d = np.array([-np.sin(t), np.cos(t)])
        rho.append(a[0] * np.cos(t) + a[1] * np.sin(t))
        theta.append(t)
        ta.append(a @ d)
        tb.append(b @ d)
    lines = Lines(np.array(rho), np.array(theta), np.ones(4, np.int64))
    lo = np.minimum(ta, tb) + trim
    hi = np.maximum(ta, tb) - trim
    hits = support_profile(lines, edges, grad).hits(np.arange(4), lo, hi)
    return float(np.min(hits / np.maximum(hi - lo, 1.0)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=100)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cfg = SegmentConfig()
    grid = np.exp(np.linspace(np.log(cfg.T_H_range[0]), np.log(cfg.T_H_range[1]), 9))
    fate: Counter[str] = Counter()
    oracle = contrast_ok = edge_bound = total = 0
    for i in range(args.n):
        sc = sample_scene(args.seed + i)
        r = render(sc, args.seed + i)
        rig = sc.rig
        maps = cv2.initUndistortRectifyMap(rig.K1, rig.D1, None, rig.K1, rig.image_size, cv2.CV_16SC2)
        ideal = cv2.remap(r.left, *maps, cv2.INTER_LINEAR)
        mask = roi_mask(rig, "left", np.eye(4))
        grad = gradients(ideal, mask)
        g = np.hypot(grad.dx.astype(np.float64), grad.dy.astype(np.float64))
        noise = float(np.median(g[mask > 0]))
        books = []
        for b in r.truth["books"]:
            if b["visible_left"] >= 0.9:
                h = np.array(b["corners"]) @ rig.Q_L[:, :3].T + rig.Q_L[:, 3]
                books.append(order_corners(h[:, :2] / h[:, 2:]))
        seg = CascadeController(cfg, warm_start=False).segment(grad)
        edges = canny(grad, seg.T_H)
        lines = hough_lines(edges, cfg.T_HG_min, grad=grad, max_lines=cfg.n_max + 1, box=grad.box)
        quads = candidate_quads(lines, support_profile(lines, edges, grad, box=grad.box), grad.shape,
                                roi_area(grad), cfg.quads)
        strong = quads.min_votes >= seg.T_HG
        per_th = [finish(grad, evaluate(grad, t, cfg), 1).corners for t in grid]
        oracle += max(sum(near(c, tc, 3.0) for tc in books) for c in per_th)
        grid_edges = [canny(grad, t) for t in grid]
        for tc in books:
            total += 1
            edge_bound += max(side_support(grad, e, tc) for e in grid_edges) >= cfg.quads.min_support
            contrast_ok += side_contrast(grad, tc, noise) >= 3.0
            ranks = [side_rank(lines, tc[k], tc[(k + 1) % 4]) for k in range(4)]
            if near(seg.corners, tc, 3.0):
                stage = "found"
            elif near(seg.coarse, tc, 5.0):
                stage = "refine"
            elif near(quads.corners[strong], tc, 5.0):
                stage = "selection"
            elif near(quads.corners, tc, 5.0):
                stage = "T_HG"
            elif min(ranks) >= 0:
                stage = "quads"
            else:
                stage = f"lines-{sum(k < 0 for k in ranks)}"
            fate[stage] += 1
        print(f"scene {args.seed + i}: {r.truth['lux']:.0f} lx, T_H {seg.T_H:.0f}, T_HG {seg.T_HG}, "
              f"{len(books)} books", flush=True)
    print(f"\n{total} books >= 90 % visible in {args.n} scenes (seeds {args.seed}-{args.seed + args.n - 1})\n")
    print("| where lost | books | share |\n|---|---|---|")
    for stage, k in sorted(fate.items(), key=lambda kv: -kv[1]):
        print(f"| {stage} | {k} | {k / total:.0%} |")
    print(f"\noracle T_H per image: {oracle / total:.0%} found; controller: {fate['found'] / total:.0%}")
    print(f"books whose weakest side has contrast >= 3x the ROI's median gradient: {contrast_ok / total:.0%}")
    print(f"books whose four true sides pass the quad stage's edge-support test (>= "
          f"{cfg.quads.min_support:.0%} covered) at some T_H of the grid: {edge_bound / total:.0%}")


if __name__ == "__main__":
    main()
