"""Regenerate docs/RESULTS.md: the paper's Tables I and II measured on synthetic scenes.

Runs, and records in the page, the commands anyone can run by hand:

    rovis synth WORK/table1 --protocol table1 --n N1 --seed S --force
    rovis eval  WORK/table1 --workers W --out WORK/table1-eval
    rovis synth WORK/table2 --protocol table2 --n N2 --seed S --force
    rovis eval  WORK/table2 --workers W --out WORK/table2-eval

then writes DOCS/RESULTS.md from the two ``report.txt`` (the tables ``rovis eval`` prints) with
the plots copied to DOCS/results/, stamped with the command line, the date and the git state.

    python scripts/results.py                     # 100 table1 + 128 table2 scenes (~10-20 min
                                                  # on 2 cores; see rovis bench for the rate)
    python scripts/results.py --n1 5 --n2 32 --docs /tmp/docs-check   # a quick check

``--n2`` defaults to 128: four arrangements of books, each under the 32 light conditions of
``table2`` (8 levels x daylight/artificial x auto/fixed exposure).
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import platform
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _git_state() -> str:
    """Commit and whether the tree had uncommitted changes (read-only git commands)."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, check=True,
                              capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "--no-optional-locks", "status", "--porcelain",
                                "--untracked-files=no"], cwd=REPO, check=True,
                               capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return f"{head}" + (" with uncommitted changes" if dirty else "")


def _run(argv: list[str], log: list[str]) -> None:
    from rovis.cli import main

    line = "rovis " + " ".join(shlex.quote(a) for a in argv)
    print(f"$ {line}", flush=True)
    log.append(line)
    code = main(argv)
    if code != 0:
        raise SystemExit(f"results.py: `{line}` exited with {code}")


def main(argv: list[str] | None = None) -> int:
    from rovis import __version__
    from rovis.evalplots import FIGURES
    from rovis.io import write_text_atomic

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n1", type=int, default=100, help="table1 scenes (default: %(default)s)")
    p.add_argument("--n2", type=int, default=128, help="table2 scenes (default: %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="dataset seed (default: %(default)s)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="rovis eval workers (default: all cores)")
    p.add_argument("--methods", default="closed,open,auto-median,auto-otsu,lsd,contour")
    p.add_argument("--work", default=str(REPO / "build" / "results"),
                   help="datasets and raw eval output (default: build/results)")
    p.add_argument("--docs", default=str(REPO / "docs"),
                   help="where RESULTS.md and results/*.png go (default: docs/)")
    args = p.parse_args(argv)

    work, docs = Path(args.work), Path(args.docs)
    commands: list[str] = []
    sections = []
    started = dt.datetime.now(dt.timezone.utc)
    git = _git_state()
    for protocol, n, title in (
            ("table1", args.n1, "Table I — constant 500 lx, books at random positions and yaw"),
            ("table2", args.n2, "Table II — the same books under 15–1200 lx, daylight and "
                                "artificial light, auto and fixed exposure")):
        ds, out = work / protocol, work / f"{protocol}-eval"
        _run(["synth", str(ds), "--protocol", protocol, "--n", str(n), "--seed", str(args.seed),
              "--force"], commands)
        _run(["eval", str(ds), "--methods", args.methods, "--workers", str(args.workers),
              "--out", str(out)], commands)
        (docs / "results").mkdir(parents=True, exist_ok=True)
        pictures = []
        for fig in FIGURES:
            target = docs / "results" / f"{protocol}-{fig}"
            shutil.copyfile(out / fig, target)
            pictures.append(f"![{protocol} {fig}](results/{target.name})")
        report = (out / "report.txt").read_text(encoding="utf-8").rstrip()
        sections.append(f"## {title}\n\n`{protocol}`, {n} scenes.\n\n```text\n{report}\n```\n\n"
                        + "\n".join(pictures))

    this = "python scripts/results.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))
    page = f"""# Results: the paper's Tables I and II on synthetic scenes

> **Snapshot.** Written by `{this.strip()}` on {started:%Y-%m-%d %H:%M} UTC, rovis
> {__version__}, git {git}, Python {platform.python_version()} on {platform.machine()}
> ({args.workers} eval workers). Detection is still being improved: rerun that command for
> today's figures. Table I: {args.n1} scenes; Table II: {args.n2} scenes.

The commands it ran (anyone can run them by hand):

```bash
{chr(10).join(commands)}
```

Scoring (DESIGN §5): a detection is matched to a true book when their centres are within 5 cm,
one-to-one (Hungarian assignment). Recall counts the true books matched, and separately the
books at least 90 % visible in both images; false positives are unmatched detections per image.
For the matched books, max / mean / std of the absolute errors |X_e|, |Y_e|, |Z_e| of the
centre O (world frame, metres) and Ψ_e of the long axis' yaw (degrees, modulo 180°, or 90°
for covers whose sides differ by less than 1 cm), beside the paper's own figures; then cover
length, width and height errors, and the breakdowns by light level, light and exposure.
`results.json` in the eval folder holds every number, per scene and method. The paper's open
loop used fixed thresholds tuned at 500 lx; so does `open` here.

{chr(10).join(sections)}
"""
    path = write_text_atomic(docs / "RESULTS.md", page)
    print(f"wrote {path} and {docs / 'results'}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
