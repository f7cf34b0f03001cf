"""What makes the matched books' errors: each stage's books and the ones far off, side by side.

Runs the closed loop (``rovis detect``'s defaults, or ``--set``) on the scenes of a dataset
written by ``rovis synth``, matches detections to true books as ``rovis eval`` does (centres
within 5 cm, one-to-one), and prints:

- per ``source`` (the pipeline stage that found the book: ``segmentation``, ``one image``,
  ``candidates``, ``height map``): how many, their mean and median |X|, |Y|, |Z| centre
  errors, and how many are more than ``--far`` (8 mm) off on some axis;
- the mean errors with and without those far-off books;
- each far-off book: for every side of the true cover, how far the detected cover's side
  on that side lies outward of it (mm; negative: inward), its height error, and what that
  makes it: ``cut short`` (a side 15 mm or more inward: a printed band taken for the cover's
  end), ``over-reach`` (15 mm or more outward: onto a neighbour or the desk), ``height``
  (8 mm or more off in height), else ``other``.

    python scripts/stereo_errors.py build/results/table1 --workers 2
"""

from __future__ import annotations

import argparse
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rovis.calib import load_calibration
from rovis.evaluate import list_scenes, load_scene, match_books
from rovis.pipeline import DetectConfig, Detector, with_settings

_detector: Detector | None = None


def side_offsets(truth: NDArray[np.float64], found: NDArray[np.float64]) -> NDArray[np.float64]:
    """For each side of the true cover (corner s to s + 1, world XY), how far outward of it
    (metres; negative: inward) the detected cover's side on the same side of the centre and
    within ~25° of its direction lies, at its midpoint; NaN where none is.

    Parameters
    ----------
    truth, found : ndarray, shape (4, 3)
        Cover corners, world frame, metres, in cyclic order.
    """
    centre = truth[:, :2].mean(axis=0)
    out = np.full(4, np.nan)
    for s in range(4):
        a, b = truth[s, :2], truth[(s + 1) % 4, :2]
        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]])
        if n @ (centre - a) > 0:
            n = -n  # outward
        for k in range(4):
            p, q = found[k, :2], found[(k + 1) % 4, :2]
            e = (q - p) / np.linalg.norm(q - p)
            mid = 0.5 * (p + q)
            if abs(e @ d) >= 0.9 and (mid - centre) @ n > 0:
                out[s] = float((mid - a) @ n)
    return out


def kind(offsets: NDArray[np.float64], dz: float, *, side: float = 0.015,
         height: float = 0.008) -> str:
    """What a far-off book's error is (see the module's docstring)."""
    if np.nanmin(offsets, initial=np.inf) <= -side:
        return "cut short"
    if np.nanmax(offsets, initial=-np.inf) >= side:
        return "over-reach"
    if abs(dz) >= height:
        return "height"
    return "other"


def _scene(args: tuple[str, str, list[str]]) -> list[dict]:  # type: ignore[type-arg]
    """The matched books of one scene: source, centre error (3,), height error, side offsets."""
    scene, calib, settings = args
    global _detector
    if _detector is None:  # one detector per worker process
        _detector = Detector(load_calibration(calib), with_settings(DetectConfig(), settings))
    doc, _, left, right = load_scene(Path(scene))
    _detector.reset()  # each scene on its own, as rovis eval
    result = _detector.detect(left, right)
    rows = []
    for t, d in match_books([b["center"] for b in doc["books"]],
                            [o.pose.center for o in result.objects]):
        book, found = doc["books"][t], result.objects[d]
        rows.append({
            "scene": Path(scene).name, "book": t, "source": found.source,
            "error": np.asarray(found.pose.center) - np.asarray(book["center"]),
            "dz": float(found.pose.size[2] - book["size"][2]),
            "sides": side_offsets(np.asarray(book["corners"]), np.asarray(found.corners_world)),
        })
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a folder written by rovis synth")
    ap.add_argument("--n", type=int, default=None, help="only the first N scenes")
    ap.add_argument("--workers", type=int, default=1, help="worker processes (default: 1)")
    ap.add_argument("--far", type=float, default=8.0,
                    help="mm: a book this far off on some axis is listed (default: 8)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a DetectConfig setting, as rovis eval --set")
    args = ap.parse_args()
    try:
        scenes = [str(s) for s in list_scenes(args.dataset)[:args.n]]
        calib = f"{args.dataset}/calib.yaml"
        load_calibration(calib)  # a broken calibration: said once, before any work
    except (OSError, ValueError) as e:
        raise SystemExit(f"stereo_errors: {e}") from None
    jobs = [(s, calib, args.set) for s in scenes]
    rows: list[dict] = []  # type: ignore[type-arg]
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        for k, found in enumerate(pool.map(_scene, jobs)):
            rows += found
            print(f"\r{k + 1}/{len(scenes)} scenes", end="", flush=True)
    if not rows:
        print(f"\nno book matched in {len(scenes)} scenes of {args.dataset}")
        return
    err = 1000 * np.abs(np.array([r["error"] for r in rows]))  # mm
    far = err.max(axis=1) > args.far
    source = np.array([r["source"] for r in rows])
    print(f"\n\n{len(rows)} books matched in {len(scenes)} scenes of {args.dataset}\n")
    print(f"| source | books | mean |X|, |Y|, |Z| mm | median mm | over {args.far:g} mm |")
    print("|---|---|---|---|---|")
    for name in sorted(set(source), key=lambda n: -np.count_nonzero(source == n)):
        e = err[source == name]
        print(f"| {name} | {len(e)} | {', '.join(f'{v:.1f}' for v in e.mean(axis=0))} | "
              f"{', '.join(f'{v:.1f}' for v in np.median(e, axis=0))} | "
              f"{np.count_nonzero(far[source == name])} |")
    print(f"\nmean |X|, |Y|, |Z|: {', '.join(f'{v:.2f}' for v in err.mean(axis=0))} mm; "
          f"without the {np.count_nonzero(far)} over {args.far:g} mm: "
          + (", ".join(f"{v:.2f}" for v in err[~far].mean(axis=0)) if (~far).any() else "-")
          + " mm\n")
    kinds: Counter[str] = Counter()
    print("| scene | book | source | error X, Y, Z mm | height error mm "
          "| sides outward mm | kind |\n|---|---|---|---|---|---|---|")
    for r, e in zip(rows, far):
        if not e:
            continue
        what = kind(r["sides"], r["dz"])
        kinds[what] += 1
        print(f"| {r['scene']} | {r['book']} | {r['source']} | "
              f"{', '.join(f'{1000 * v:+.1f}' for v in r['error'])} | {1000 * r['dz']:+.1f} | "
              f"{' '.join(f'{1000 * v:+.0f}' for v in r['sides'])} | {what} |")
    print("\n" + ", ".join(f"{name}: {n}" for name, n in kinds.most_common()))


if __name__ == "__main__":
    main()
