"""Segmentation study: each method's 2D cover detection on rendered scenes, by lux band.

Renders ``--n`` mixed scenes (15-1200 lx, daylight and artificial, auto exposure), undistorts
the left image, searches the workspace ROI with each method and compares the cover corners
with the truth projected into the same image. A book counts as found when all four corners
are within 3 px; recall is over books whose cover is >= 90 % visible. It counts as detected
when a quad overlaps its cover with an intersection over union of 0.5 or more (one quad per
cover): "detected" against "found" tells a cover missed from one placed a few pixels off.
Prints a Markdown table.

``detect:closed`` and ``detect:open`` run the whole detector (``rovis detect``'s defaults, with
that segmentation) on the stereo pair instead, and score the corners it reports in the left
image (``corners_left_px``, undistorted into the same image): the 2D corners a robot gets, after
stereo has refined, completed and checked them. Their time is the whole detector's, both images.

    python scripts/segmentation_study.py --n 50 --seed 100 [--methods closed+,open]
    python scripts/segmentation_study.py --n 50 --seed 100 --methods closed+,detect:closed
    python scripts/segmentation_study.py --n 40 --seed 100 --methods closed+ --refine-gamma 2.2
    python scripts/segmentation_study.py --n 40 --seed 100 --methods closed+ --set n_max=200

``closed-`` is eq. 2 with e^{-N/N_max} (the text's intent), ``closed+`` as printed
(e^{+N/N_max}, rovis's default: it finds more books in 3D, docs/segmentation.md).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict
from collections.abc import Sequence

import cv2
import numpy as np

from rovis.pipeline import DetectConfig, Detector, roi_mask, with_settings
from rovis.segment import SegmentConfig, gradients
from rovis.segment.methods import segment
from rovis.segment.quads import order_corners
from rovis.synth import render, sample_scene
from rovis.synth.textures import COVER_KINDS

BANDS = [(15, 50), (50, 150), (150, 500), (500, 1200)]
METHODS = {"closed-": ("closed", -1), "closed+": ("closed", +1), "open": ("open", -1),
           "auto-median": ("auto-median", -1), "auto-otsu": ("auto-otsu", -1),
           "lsd": ("lsd", -1), "contour": ("contour", -1),
           "detect:closed": ("closed", +1), "detect:open": ("open", +1)}
FOUND_PX = 3.0  # a book is found where every corner lies this near its true one
DETECTED_IOU = 0.5  # ...and detected where a quad overlaps it by this much (PASCAL VOC)


# set otherwise than by --set: the sign by each method, the gamma by --refine-gamma
OWN = {"quality_sign": "each method sets it (closed- / closed+)",
       "refine_gamma": "--refine-gamma sets it"}


def segment_config(sign: int, refine_gamma: float, settings: Sequence[str]) -> SegmentConfig:
    """The SegmentConfig a method runs with: eq. 2's sign, the refinement's gamma, then
    ``settings`` (``NAME=VALUE``, fields of SegmentConfig, as ``rovis eval --set
    segment.NAME=VALUE`` reads them).

    Raises
    ------
    ValueError
        A setting that is no field, a value of the wrong type, or one of :data:`OWN`
        (each method's sign, ``--refine-gamma``), naming it as given.
    """
    for item in settings:
        name = item.partition("=")[0].strip()
        if name in OWN:
            raise ValueError(f"--set {item}: not here, {OWN[name]}")
    seg = SegmentConfig(quality_sign=sign, refine_gamma=refine_gamma)
    try:
        cfg = with_settings(DetectConfig(segment=seg), [f"segment.{s}" for s in settings])
    except ValueError as e:  # (the names as given, not with_settings' segment.NAME)
        raise ValueError(str(e).replace("--set segment.", "--set ")
                         .replace("--set 'segment.", "--set '")) from None
    return cfg.segment


def score_image(truth: Sequence[tuple[np.ndarray, bool]], quads: Sequence[np.ndarray],
                ) -> tuple[list[bool], list[float], int]:
    """Score one image's cover quads against its true covers.

    Parameters
    ----------
    truth : sequence of (ndarray (4, 2), bool)
        Each true cover's corners in eq. 1's order (pixels) and whether it counts for recall
        (>= 90 % visible).
    quads : sequence of ndarray (4, 2)
        The quads found, pixels, any cyclic order.

    Returns
    -------
    found : list of bool
        Per counted true cover, whether some quad has every corner within ``FOUND_PX``.
    errors : list of float
        The corner errors (pixels) of every true cover found, counted or not.
    false : int
        Quads that found no true cover.
    """
    ordered = [order_corners(np.asarray(q, dtype=np.float64)) for q in quads]
    used, found, errors = set(), [], []
    for corners, counted in truth:
        errs = [np.linalg.norm(q - corners, axis=1) for q in ordered]
        k = int(np.argmin([e.max() for e in errs])) if errs else -1
        ok = k >= 0 and errs[k].max() < FOUND_PX
        if ok:
            used.add(k)
            errors.extend(errs[k].tolist())
        if counted:
            found.append(ok)
    return found, errors, len(ordered) - len(used)


def detect_image(truth: Sequence[tuple[np.ndarray, bool]], quads: Sequence[np.ndarray],
                 ) -> tuple[list[bool], list[float]]:
    """Score one image's cover quads as detections: a true cover is detected where a quad
    overlaps it by ``DETECTED_IOU`` or more (area of intersection over union, PASCAL VOC's
    threshold), each quad detecting one cover at most (the largest overlaps first). A quad
    is taken as its convex hull.

    Parameters
    ----------
    truth, quads : as :func:`score_image`.

    Returns
    -------
    detected : list of bool
        Per counted true cover, whether a quad detects it.
    errors : list of float
        The corner errors (pixels) of every true cover detected, counted or not: each true
        corner against the quad's corner at the same place once the quad is in eq. 1's
        order and turned by the quarter that fits best (the smallest worst corner: a quad
        near 45° may start at either of two corners).
    """
    hulls = [cv2.convexHull(np.asarray(q, dtype=np.float32)) for q in quads]
    areas = [cv2.contourArea(h) for h in hulls]
    overlaps = []
    for t, (corners, _) in enumerate(truth):
        c = cv2.convexHull(np.asarray(corners, dtype=np.float32))
        area_t = cv2.contourArea(c)
        for k, h in enumerate(hulls):
            # (clipped: OpenCV's intersection has misjudged polygons that share an edge)
            inter = min(max(cv2.intersectConvexConvex(c, h)[0], 0.0), area_t, areas[k])
            union = area_t + areas[k] - inter
            if union > 0 and inter / union >= DETECTED_IOU:
                overlaps.append((inter / union, t, k))
    match: dict[int, int] = {}
    used: set[int] = set()
    for _, t, k in sorted(overlaps, reverse=True):
        if t not in match and k not in used:
            match[t] = k
            used.add(k)
    detected, errors = [], []
    for t, (corners, counted) in enumerate(truth):
        if t in match:
            q = order_corners(np.asarray(quads[match[t]], dtype=np.float64))
            turns = [np.linalg.norm(np.roll(q, r, axis=0) - corners, axis=1) for r in range(4)]
            errors.extend(min(turns, key=lambda e: e.max()).tolist())
        if counted:
            detected.append(t in match)
    return detected, errors


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated subset")
    ap.add_argument("--refine-gamma", type=float, default=1.0,
                    help="SegmentConfig.refine_gamma: the gamma undone for sub-pixel refinement "
                         "(default: %(default)s, none)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a SegmentConfig field for every method, e.g. n_max=200 or "
                         "quads.min_support=0.6 (repeatable; as rovis eval --set segment.NAME; "
                         "not quality_sign or refine_gamma)")
    args = ap.parse_args(argv)
    unknown = [m for m in args.methods.split(",") if m not in METHODS]
    if unknown:
        ap.error(f"--methods: unknown {', '.join(unknown)} (choose from {', '.join(METHODS)})")
    methods = {m: METHODS[m] for m in args.methods.split(",")}
    try:
        configs = {m: segment_config(sign, args.refine_gamma, args.set)
                   for m, (_, sign) in methods.items()}
    except ValueError as e:
        ap.error(str(e))
    cv2.setNumThreads(1)
    stats: dict[tuple[str, int], dict[str, list]] = defaultdict(lambda: defaultdict(list))
    # found and detected, per method and cover kind (DESIGN §4), over all bands
    by_cover: dict[tuple[str, str], dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for i in range(args.n):
        sc = sample_scene(args.seed + i)
        r = render(sc, args.seed + i)  # seeded sensor noise: reproducible
        rig = sc.rig
        K1, D1 = rig.K1, rig.D1
        maps = cv2.initUndistortRectifyMap(K1, D1, None, K1, rig.image_size, cv2.CV_16SC2)
        ideal = cv2.remap(r.left, *maps, cv2.INTER_LINEAR)
        grad = gradients(ideal, roi_mask(rig, "left", np.eye(4)))
        truth = []
        for b in r.truth["books"]:
            h = np.array(b["corners"]) @ rig.Q_L[:, :3].T + rig.Q_L[:, 3]
            truth.append((order_corners(h[:, :2] / h[:, 2:]), b["visible_left"] >= 0.9))
        kinds = [b["cover"] for b in r.truth["books"] if b["visible_left"] >= 0.9]
        band = next(k for k, (lo, hi) in enumerate(BANDS) if r.truth["lux"] < hi or k == len(BANDS) - 1)
        for name, (method, _) in methods.items():
            st = stats[(name, band)]
            t0 = time.perf_counter()
            if name.startswith("detect:"):
                # the detector built for this scene's rig (each scene stands its cameras
                # elsewhere), its set-up left out of the time
                det = Detector(rig, DetectConfig(method=method, segment=configs[name]))
                t0 = time.perf_counter()
                res = det.detect(r.left, r.right)
                quads = [rig.undistort_points(o.corners_left_px, "left") for o in res.objects]
            else:
                quads = list(segment(ideal, grad, method, cfg=configs[name]).corners)
            st["ms"].append(1e3 * (time.perf_counter() - t0))
            found, errors, false = score_image(truth, quads)
            st["found"].extend(found)
            st["err"].extend(errors)
            st["fp"].append(false)
            detected, det_errors = detect_image(truth, quads)
            st["detected"].extend(detected)
            st["det_err"].extend(det_errors)
            for kind, ok, seen in zip(kinds, found, detected):
                by_cover[(name, kind)]["found"].append(ok)
                by_cover[(name, kind)]["detected"].append(seen)
    options = [f"--refine-gamma {args.refine_gamma}"] if args.refine_gamma != 1.0 else []
    options += [f"--set {item}" for item in args.set]
    print(f"{args.n} scenes, seeds {args.seed}-{args.seed + args.n - 1}"
          + (f"; {' '.join(options)}" if options else "") + "\n")
    print("| method | lux | books | recall | median corner error [px] | false quads / image "
          f"| detected (IoU >= {DETECTED_IOU:g}) | median corner error, detected [px] "
          "| median time [ms] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in methods:
        for band, (lo, hi) in enumerate(BANDS):
            st = stats.get((name, band))
            if not st or not st["ms"]:
                continue
            rec = np.mean(st["found"]) if st["found"] else float("nan")
            err = np.median(st["err"]) if st["err"] else float("nan")
            det = np.mean(st["detected"]) if st["detected"] else float("nan")
            det_err = np.median(st["det_err"]) if st["det_err"] else float("nan")
            print(f"| {name} | {lo}-{hi} | {len(st['found'])} | {rec:.2f} | {err:.2f} | "
                  f"{np.mean(st['fp']):.1f} | {det:.2f} | {det_err:.2f} | "
                  f"{np.median(st['ms']):.0f} |")
    print()
    for name in methods:
        found = [ok for band in range(len(BANDS)) for ok in stats[(name, band)]["found"]]
        detected = [ok for band in range(len(BANDS)) for ok in stats[(name, band)]["detected"]]
        print(f"{name}: {sum(found)} of {len(found)} books found over all bands, "
              f"{sum(detected)} detected")
    print()
    print("By cover kind, over all bands: books found / detected of those counted")
    print()
    print("| method | " + " | ".join(COVER_KINDS) + " |")
    print("|---|" + "---|" * len(COVER_KINDS))
    for name in methods:
        cells = []
        for kind in COVER_KINDS:
            st = by_cover.get((name, kind))
            cells.append(f"{sum(st['found'])} / {sum(st['detected'])} of {len(st['found'])}"
                         if st else "-")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
