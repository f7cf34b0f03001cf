"""The ``rovis`` command line: thin subcommands that parse arguments and call the library."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from rovis import __version__

EXIT_BAD_INPUT = 2


class InputError(ValueError):
    """Bad input the user can fix; printed as one line, exit code 2."""


def _cmd_demo(args: argparse.Namespace) -> int:
    from rovis.demo import run_demo

    table, json_path = run_demo(Path(args.out))
    print("rovis demo: 3 books, true corners projected into a Bumblebee2-like rig with 0.3 px "
          "noise,\nthen triangulated (DLT, eq. 5) and posed (eq. 6-7). World = desk marker frame.\n")
    print(table)
    print(f"\nwrote {json_path} and {json_path.parent / 'calib.yaml'}")
    print("not built yet: scene rendering, segmentation and stereo matching; "
          "this demo starts from corners, not images.")
    return 0


def _cmd_calib(args: argparse.Namespace) -> int:
    from rovis.calib import load_calibration, save_calibration

    rig = load_calibration(args.file, args.right)
    print(rig.summary())
    if args.out:
        save_calibration(rig, args.out)
        print(f"wrote {args.out}")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from rovis.bench import bench_triangulation

    if args.what == "triangulation":
        print(f"triangulation of {args.points:,} points, one core, {args.repeats} runs")
        for timing in bench_triangulation(args.points, repeats=args.repeats):
            print(timing.line())
        return 0
    raise InputError(f"bench: unknown benchmark {args.what!r}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rovis",
        description="Find books on a desk with a stereo camera: pose and cuboid per book "
                    "(ROVIS closed-loop boundary segmentation + stereo triangulation).")
    parser.add_argument("--version", action="version", version=f"rovis {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("demo", help="run the pipeline on a built-in scene and print the books")
    p.add_argument("--out", default="rovis-demo", help="output folder (default: %(default)s)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("calib", help="read a calibration in any supported format, print it, "
                                     "optionally write the canonical calib.yaml")
    p.add_argument("file", help="calib.yaml, Kalibr camchain, BoofCV stereo.yaml, Q_L/Q_R file, "
                                "or the left ROS camera_info")
    p.add_argument("right", nargs="?", help="the right ROS camera_info (only for that format)")
    p.add_argument("--out", help="write the canonical OpenCV calib.yaml here")
    p.set_defaults(func=_cmd_calib)

    p = sub.add_parser("bench", help="benchmarks on one core")
    p.add_argument("what", choices=["triangulation"], help="what to time")
    p.add_argument("--points", type=_positive_int, default=1_000_000,
                   help="points per run (default: %(default)s)")
    p.add_argument("--repeats", type=_positive_int, default=7, help="runs (default: %(default)s)")
    p.set_defaults(func=_cmd_bench)
    return parser


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rovis`` script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] | None = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 0
    try:
        return func(args)
    except (ValueError, OSError) as exc:  # bad input: one line, no traceback
        print(f"rovis {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
