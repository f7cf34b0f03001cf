"""What each step beyond the paper buys: the closed loop with one step turned off at a time.

Runs ``rovis eval DATASET --methods closed`` once with the detector's defaults and once per
step below with that step off (``--set``), then prints one Markdown table: books found
(and within the 1 cm grasp tolerance along X, Y and Z), false positives per image, the
matched books' mean |X|, |Y|, |Z| errors, and the median time per frame from
``results.json`` (pass ``--workers 1`` for times not shared with another process).

    python scripts/ablation.py build/t1 --workers 1 --work /tmp/ablation

Each row is the command printed above the table; anyone can run it by hand.
"""

from __future__ import annotations

import argparse
import json
import shlex
from pathlib import Path

import numpy as np

# (what is turned off, the settings that turn it off); the first row turns nothing off
STEPS: list[tuple[str, list[str]]] = [
    ("nothing (the defaults)", []),
    ("covers of the other T_H (segment.union)", ["segment.union=false"]),
    ("three-sided candidates and covers", ["segment.three_sided=false"]),
    ("two-sided candidates", ["segment.two_sided=false", "segment.opposite_sided=false"]),
    ("the other T_H's candidates, paired last", ["segment.late_open=false"]),
    ("the candidate pool (stereo step 4)", ["stereo.pool=false"]),
    ("completing a candidate in 3D", ["complete.enabled=false"]),
    ("a flat height sweep refused", ["complete.sweep_margin=0"]),
    ("the one-image search (stereo step 3)", ["stereo.transfer=false"]),
    ("the alternatives (stereo step 2)", ["stereo.alternatives=false"]),
    ("the print's height test and placing", ["sweep.check=false", "sweep.transfer=false"]),
    ("the height map", ["heightmap.enabled=false"]),
    ("the smooth height map (covers without print)", ["heightmap.smooth=false"]),
    ("one image's candidate looked for in the other", ["stereo.pool_transfer=false"]),
    ("small candidates with sides unseen, paired last", ["segment.small_open=false"]),
    ("the facing sides' edge", ["facing.enabled=false"]),
    ("a side on its block's foot in one image", ["facing.block_sides=false"]),
    ("a side on its foot, lifted", ["lift_foot=false"]),
    ("a side left out of the flat refit", ["flat_refit_sides=0"]),
    ("the height from the sides", ["side_height.enabled=false"]),
    ("the extent step", ["extent.grow=false", "extent.shrink=false"]),
    ("a printed frame grown to the cover's edges", ["extent.frame=false"]),
    ("the split of touching books", ["split.enabled=false"]),
    ("the join of a cover's halves", ["split.join=false"]),
    ("a cover over a segmented one dropped", ["stereo.over_segmented=0"]),
    ("the trim by the height map", ["trim.enabled=false"]),
    ("the height check by the height map", ["trim.map_height=false"]),
    ("the grow by the height map", ["trim.grow=false"]),
    ("the grow by the print", ["trim.print_grow=false"]),
    ("a refused grow asked again", ["trim.grow_tries=1"]),
    ("the maps cut again without the found covers (the wide slabs too)",
     ["heightmap.taken_px=-1"]),
    ("the smooth map cut again in wide slabs", ["heightmap.wide_slab=0"]),
    ("a height-map book's print kept from the extent's cut", ["extent.keep_print=false"]),
    ("a split the maps read at one height refused", ["split.map_check=false"]),
    ("a height-map book over a segmented one cut back", ["stereo.over_cut=false"]),
    ("two overlapping covers, the strip read at one's height: the other cut back",
     ["stereo.height_cut=0"]),
    ("the grow to where a cover's neighbouring sides end", ["trim.lateral_grow=false"]),
    ("two books the maps read at two heights split", ["split.by_map=false"]),
    ("the late pool looked for in the other image", ["stereo.pool_transfer_late=false"]),
    ("a transferred cover laid on its sides from end to end", ["stereo.pool_transfer_fit=false"]),
    ("a transferred cover's own unseen end excused, last", ["stereo.pool_transfer_excuse_px=0"]),
    ("a piece of a grown cover taken in", ["trim.grow_absorb=0"]),
    ("the pool looked at again under a cover dropped at the end", ["stereo.pool_freed=false"]),
    ("the desk between books dropped (a side unseen)", ["stereo.desk_unseen=0"]),
    ("the desk inside four seen sides dropped", ["stereo.desk_seen_ncc=1.01"]),
    ("a printed frame grown with a side whose margin meets the desk", ["extent.frame_sides=4"]),
    ("a facing side moved off its page block's foot (both images)", ["facing.feet=false"]),
    ("a neighbour's edge of another height holds no side", ["extent.height_band=1"]),
    ("a side hidden under a taller book in front", ["facing.under=false"]),
    ("a skewed cover's side looked for out to its ends", ["unskew_reach=0"]),
    ("a cover its sides hold kept off the maps' height", ["trim.map_sides=0"]),
    ("three sides, facing or not, give the height", ["side_height.any_sides=0"]),
    ("a side no page block shows grown by print nearer than 20 mm", ["trim.print_far=0.02"]),
    ("a print edge taken only where it parts two heights", ["trim.print_apart=0"]),
    ("a move up by print told beyond its most textured quarter (or half)",
     ["sweep.beyond_quarter=false"]),
    ("a completed cover's unseen side beside a taller book not asked for print",
     ["complete.print_taller=false"]),
    ("a print edge run into the side's own tried", ["trim.print_dip=0"]),
    ("a third print edge tried", ["trim.print_edges=2"]),
    ("a side on a line of print short of a taller book in front", ["facing.under_print_px=0"]),
    ("a pool pair reaching over a taller pair's footprint gives way to it",
     ["stereo.pool_taller_share=1"]),
    ("a small cover between books of other heights taken by its print",
     ["stereo.small_open_between=false"]),
]


def _row(results: Path) -> dict[str, float]:
    """The closed loop's figures from one ``rovis eval`` folder's results.json."""
    doc = json.loads((results / "results.json").read_text())
    s = doc["summary"]["closed"]
    times = [scene["timing_ms"]["closed"] for scene in doc["scenes"]
             if "closed" in scene.get("timing_ms", {})]
    return {"books": s["books"], "found": s["found"], "within": s["within_1cm"],
            "fp": s["fp_per_image"], "x": 1e3 * s["errors"]["x"]["mean"],
            "y": 1e3 * s["errors"]["y"]["mean"], "z": 1e3 * s["errors"]["z"]["mean"],
            "ms": float(np.median(times)) if times else float("nan")}


def _rows(text: str) -> set[int]:
    """``--only``'s row numbers, each one of :data:`STEPS`' (argparse names a bad one)."""
    try:
        rows = {int(k) for k in text.split(",")}
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected row numbers like 0,9, got {text!r}") from None
    if not rows <= set(range(len(STEPS))):
        raise argparse.ArgumentTypeError(f"rows are 0-{len(STEPS) - 1}, got {text!r}")
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a folder written by rovis synth")
    ap.add_argument("--work", default="build/ablation", help="where the eval folders go")
    ap.add_argument("--workers", type=int, default=1, help="rovis eval workers (default: 1)")
    ap.add_argument("--only", default=None, type=_rows,
                    help="comma-separated row numbers to run (0: the defaults), e.g. 0,9")
    args = ap.parse_args()
    from rovis.cli import main as rovis

    rows = list(enumerate(STEPS))
    if args.only is not None:
        rows = [(k, step) for k, step in rows if k in args.only]
    table = []
    for k, (what, settings) in rows:
        out = Path(args.work) / f"step{k:02d}"
        argv = ["eval", args.dataset, "--methods", "closed", "--workers", str(args.workers),
                "--out", str(out), "--no-plots"]
        for s in settings:
            argv += ["--set", s]
        print("$ rovis " + " ".join(shlex.quote(a) for a in argv), flush=True)
        if rovis(argv) != 0:
            raise SystemExit(f"ablation.py: rovis eval failed for row {k} ({what})")
        table.append((what, _row(out)))
    print(f"\n{args.dataset}, closed loop, one step off at a time\n")
    print("| off | books found | within 1 cm | false positives / image "
          "| mean \\|X\\|, \\|Y\\|, \\|Z\\| mm | median ms / frame |")
    print("|---|---|---|---|---|---|")
    for what, r in table:
        print(f"| {what} | {r['found']} of {r['books']} | {r['within']} | {r['fp']:.2f} "
              f"| {r['x']:.1f}, {r['y']:.1f}, {r['z']:.1f} | {r['ms']:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
