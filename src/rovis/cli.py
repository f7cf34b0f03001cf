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


def _expand_images(patterns: Sequence[str], what: str) -> list[str]:
    """Paths from quoted glob patterns (sorted) or from paths the shell already expanded."""
    import glob

    paths: list[str] = []
    for pattern in patterns:
        if glob.has_magic(pattern):
            matched = sorted(glob.glob(pattern))
            if not matched:
                raise InputError(f"{what}: no file matches {pattern!r}")
            paths.extend(matched)
        else:
            paths.append(pattern)
    return paths


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from rovis.calib import load_calibration, save_calibration
    from rovis.calibrate import calibrate_stereo

    board = _board_size(args.board)
    left = _expand_images(args.left, "--left")
    right = _expand_images(args.right, "--right")
    fixed = load_calibration(args.intrinsics) if args.intrinsics else None
    print(f"{len(left)} pairs, board {board[0]}x{board[1]} inner corners, "
          f"{args.square * 1000:g} mm squares")
    report = calibrate_stereo(left, right, board, args.square, fix_intrinsics_from=fixed,
                              distortion=args.distortion, max_pair_rms=args.max_pair_rms)
    print("\n".join(report.lines()))
    save_calibration(report.rig, args.out)
    print(f"wrote {args.out}")
    return 0


def _cmd_register(args: argparse.Namespace) -> int:
    import numpy as np

    from rovis.calib import load_calibration, save_calibration
    from rovis.calibrate import read_pose, register

    rig = load_calibration(args.calib)
    T_base_marker = read_pose(args.marker_pose) if args.marker_pose else None
    registered = register(rig, args.left, args.right, T_base_marker=T_base_marker,
                          side=args.side, marker_id=args.marker_id)
    T = registered.T_world_left
    world = "robot base" if T_base_marker is not None else "desk marker"
    print(f"T_world_left (world = {world} frame, metres):")
    print("\n".join("  " + " ".join(f"{v:10.6f}" for v in row) for row in T))
    down = np.degrees(np.arcsin(np.clip(-T[2, 2], -1.0, 1.0)))
    print(f"left camera at ({T[0, 3]:.4f}, {T[1, 3]:.4f}, {T[2, 3]:.4f}) m, "
          f"looking {down:.1f} deg below the world's horizontal")
    out = args.out or args.calib
    save_calibration(registered, out)
    print(f"wrote {out}")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from rovis.synth import write_dataset

    def progress(done: int, total: int) -> None:
        end = "\n" if done == total else ""
        print(f"\rrovis synth: {done}/{total} scenes", end=end, file=sys.stderr, flush=True)

    out = write_dataset(args.out, protocol=args.protocol, n=args.n, seed=args.seed,
                        exposure=args.exposure, lux=args.lux, force=args.force,
                        preview=args.preview, progress=progress)
    print(f"wrote {args.n} stereo pair{'s' if args.n != 1 else ''} ({args.protocol}) to {out}"
          + (f", contact sheet {out / 'preview.png'}" if args.preview else ""))
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from rovis.bench import bench_triangulation

    if args.what == "triangulation":
        print(f"triangulation of {args.points:,} points, one core, {args.repeats} runs")
        for timing in bench_triangulation(args.points, repeats=args.repeats):
            print(timing.line())
        return 0
    if args.what == "synth":
        import numpy as np

        from rovis.synth.bench import bench_synth

        print(f"synthetic scenes: 1024x768 stereo pairs, 2x2 supersampling, one core, "
              f"{args.repeats} scenes")
        for t in bench_synth(args.repeats):
            q1, q3 = np.percentile(t.seconds, [25, 75])
            print(f"{t.name:<24} median {t.median * 1e3:9.2f} ms  "
                  f"(IQR {q1 * 1e3:.2f}-{q3 * 1e3:.2f} ms, n={len(t.seconds)})")
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

    p = sub.add_parser("calibrate", help="stereo calibration from chessboard image pairs; "
                                         "writes calib.yaml")
    p.add_argument("--left", nargs="+", required=True,
                   help="left images: a quoted glob ('DIR/left*.jpg') or paths")
    p.add_argument("--right", nargs="+", required=True,
                   help="right images, paired with the left ones in sorted order")
    p.add_argument("--board", default="4x6",
                   help="inner corners per row x rows (default: %(default)s = 5x7 squares)")
    p.add_argument("--square", type=_positive_float, default=0.030,
                   help="square side in metres (default: %(default)s)")
    p.add_argument("--intrinsics", help="take K/D from this calibration (any supported "
                                        "format) and keep them fixed")
    p.add_argument("--distortion", choices=["k1k2", "k1k2k3", "k1k2p1p2", "full"],
                   default="full", help="distortion terms to estimate (default: %(default)s "
                                        "= k1 k2 p1 p2 k3)")
    p.add_argument("--max-pair-rms", type=_positive_float, default=None,
                   help="drop pairs above this RMS, px (default: 3x the median, at least 1)")
    p.add_argument("--out", default="calib.yaml", help="output file (default: %(default)s)")
    p.set_defaults(func=_cmd_calibrate)

    p = sub.add_parser("register", help="set the world frame of a calibration from the desk "
                                        "marker seen in one stereo pair")
    p.add_argument("--calib", required=True, help="calibration file (any supported format)")
    p.add_argument("left", help="left image showing the marker")
    p.add_argument("right", help="right image showing the marker")
    p.add_argument("--marker-pose", metavar="T",
                   help="the marker's pose in the robot base frame: 16 numbers in one quoted "
                        "argument (row-major 4x4) or a YAML/text file; world = robot base "
                        "then (default: world = marker frame)")
    p.add_argument("--side", type=_positive_float, default=0.10,
                   help="marker side in metres (default: %(default)s)")
    p.add_argument("--marker-id", type=int, default=0,
                   help="ArUco DICT_4X4_50 id (default: %(default)s)")
    p.add_argument("--out", help="output calib.yaml (default: overwrite --calib)")
    p.set_defaults(func=_cmd_register)

    p = sub.add_parser("synth", help="render a synthetic stereo dataset of books on a desk "
                                     "(calib.yaml, scenes/NNNN/left.png right.png truth.json)")
    p.add_argument("out", help="output folder")
    p.add_argument("--protocol", choices=["table1", "table2", "mixed"], default="table1",
                   help="table1: 500 lx artificial, random poses; table2: same books, light "
                        "swept 15-1200 lx (daylight, artificial, both exposure modes); mixed: "
                        "random scenes and light (default: %(default)s)")
    p.add_argument("--n", type=int, default=10, help="stereo pairs (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--exposure", choices=["auto", "fixed"], default=None,
                   help="auto-exposure, or frozen at what auto chose at 500 lx (default: auto; "
                        "table2 renders both)")
    p.add_argument("--lux", type=float, default=None,
                   help="fix the illuminance, lx (table1, mixed; default: the protocol's)")
    p.add_argument("--force", action="store_true",
                   help="replace the dataset in a non-empty OUT")
    p.add_argument("--preview", action="store_true", help="also write OUT/preview.png, a "
                                                          "contact sheet of up to 12 scenes")
    p.set_defaults(func=_cmd_synth)

    p = sub.add_parser("bench", help="benchmarks on one core")
    p.add_argument("what", choices=["triangulation", "synth"], help="what to time")
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


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {value}")
    return value


def _board_size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise InputError(f"--board: expected COLSxROWS inner corners like 4x6, got {text!r}")
    cols, rows = (int(p) for p in parts)
    if cols < 2 or rows < 2:
        raise InputError(f"--board: expected at least 2x2 inner corners, got {text!r}")
    return cols, rows


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
