"""How long ``rovis.stereo.pool_pairs`` takes on one frame's candidate quads.

Runs the closed loop on one scene of a dataset written by ``rovis synth`` (one core), keeps
the inputs of the frame's first ``pool_pairs`` call (the pool pass's: both images' full
candidate pools), then times that call ``--repeat`` times and prints the fastest, with the
pools' sizes and the number of pairs it returns. Run it against another version of the
source (``PYTHONPATH=OTHER/src``) for a before/after on the same inputs.

    python scripts/pool_pairs_timing.py build/mx 0017
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import cv2

import rovis.pipeline as pipeline
from rovis.calib import load_calibration
from rovis.evaluate import load_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", help="a folder written by rovis synth")
    ap.add_argument("scene", help="the scene's folder name, e.g. 0017")
    ap.add_argument("--repeat", type=int, default=3, help="timed calls (the fastest is printed)")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    root = Path(args.dataset)
    try:
        _, _, left, right = load_scene(root / "scenes" / args.scene)
        rig = load_calibration(root / "calib.yaml")
    except (OSError, ValueError) as e:
        raise SystemExit(f"{root}: scene {args.scene}: {e}") from None
    first: list[tuple[tuple[Any, ...], dict[str, Any]]] = []
    original = pipeline.pool_pairs

    def keep_first(*a: Any, **k: Any) -> Any:
        if not first:
            first.append((a, k))
        return original(*a, **k)

    pipeline.pool_pairs = keep_first  # type: ignore[assignment]
    try:
        pipeline.Detector(rig, pipeline.DetectConfig()).detect(left, right)
    finally:
        pipeline.pool_pairs = original  # type: ignore[assignment]
    if not first:
        raise SystemExit(f"{root / 'scenes' / args.scene}: the frame made no pool pass")
    a, k = first[0]
    times, n = [], 0
    for _ in range(max(1, args.repeat)):
        t = time.perf_counter()
        n = len(original(*a, **k))
        times.append(time.perf_counter() - t)
    print(f"{root / 'scenes' / args.scene}: {len(a[0])} x {len(a[1])} candidates, {n} pairs; "
          f"pool_pairs {1e3 * min(times):.1f} ms (fastest of {len(times)}, one core)")


if __name__ == "__main__":
    main()
