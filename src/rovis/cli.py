"""The ``rovis`` command line: thin subcommands that parse arguments and call the library."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rovis import __version__

EXIT_BAD_INPUT = 2


class InputError(ValueError):
    """Bad input the user can fix; printed as one line, exit code 2."""


def _cmd_demo(args: argparse.Namespace) -> int:
    from rovis.demo import run_demo

    report = run_demo(Path(args.out))
    print(report.text)
    print(f"\nwrote {Path(args.out)}/: " + ", ".join(p.name for p in report.files))
    return 0


def _cmd_detect(args: argparse.Namespace) -> int:
    from rovis.calib import load_calibration
    from rovis.pipeline import DetectConfig, Detector, with_settings
    from rovis.sequence import is_sequence_source

    sequence = is_sequence_source(args.left) or is_sequence_source(args.right)
    if not sequence:
        for what, path in (("LEFT", args.left), ("RIGHT", args.right)):
            if not Path(path).is_file():
                raise InputError(f"{what}: {path}: image file not found")
    rig = load_calibration(args.calib)
    cfg = DetectConfig(method=args.method, triangulation=args.triangulation,
                       fit_rectangle=args.fit_rectangle)
    detector = Detector(rig, with_settings(cfg, args.set))
    if sequence:
        return _detect_sequence(args, detector)
    return _detect_pair(args, detector)


def _detect_pair(args: argparse.Namespace, detector: Any) -> int:
    from rovis.imageio import read_gray
    from rovis.io import write_text_atomic
    from rovis.results import books_table

    left, right = read_gray(args.left), read_gray(args.right)
    result = detector.detect(left, right)
    n = len(result.objects)
    print(f"{args.left} | {args.right}: {n} book{'s' if n != 1 else ''} "
          f"(method {args.method}, world = {result.world_frame} frame)")
    if n:
        print(books_table(result.objects))
    for warning in result.warnings:
        print(f"warning: {warning}")
    written = []
    if args.json:
        doc = result.to_dict(left=str(args.left), right=str(args.right))
        written.append(write_text_atomic(args.json, json.dumps(doc, indent=2) + "\n"))
    written += _write_pictures(args, detector.rig, result, left, right, suffix="")
    if written:
        print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _write_pictures(args: argparse.Namespace, rig: Any, result: Any, left: Any, right: Any, *,
                    suffix: str) -> list[Path]:
    """--overlay DIR/{prefix}left.png, right.png and --view F.png (F_NNNN.png in a sequence)."""
    written: list[Path] = []
    if args.overlay or args.view:
        from rovis import viz
        from rovis.io import write_image_atomic
    if args.overlay:
        for cam, image in (("left", left), ("right", right)):
            name = f"{suffix}_{cam}.png" if suffix else f"{cam}.png"
            written.append(write_image_atomic(Path(args.overlay) / name,
                                              viz.overlay(image, result, cam, rig=rig)))
    if args.view:
        view = Path(args.view)
        if suffix:
            view = view.with_name(f"{view.stem}_{suffix}{view.suffix or '.png'}")
        written.append(viz.world_view(result, view))
    return written


class _Progress:
    """A one-line ``\r`` counter on stderr that other messages erase before they print; when
    stderr is not a terminal (a log file), only the final count, on a line of its own."""

    def __init__(self, total: int) -> None:
        self.total, self.done, self.failed, self._shown = total, 0, 0, 0
        self._live = sys.stderr.isatty()

    def _text(self) -> str:
        return (f"rovis detect: {self.done}/{self.total} frames"
                + (f", {self.failed} skipped" if self.failed else ""))

    def show(self) -> None:
        if self._live:
            text = self._text()
            print("\r" + text, end="", file=sys.stderr, flush=True)
            self._shown = len(text)

    def clear(self) -> None:
        if self._shown:
            print("\r" + " " * self._shown + "\r", end="", file=sys.stderr, flush=True)
            self._shown = 0

    def finish(self) -> None:
        self.clear()
        print(self._text(), file=sys.stderr, flush=True)


def _detect_sequence(args: argparse.Namespace, detector: Any) -> int:
    from rovis.io import LinesWriter
    from rovis.sequence import list_images, pair_images, run_sequence

    pairs = pair_images(list_images(args.left, "LEFT", "left"),
                        list_images(args.right, "RIGHT", "right"))
    progress = _Progress(len(pairs))
    writer = LinesWriter(args.json) if args.json else None
    want_images = bool(args.overlay or args.view)
    books = tracked = 0
    interrupted = False
    progress.show()
    try:
        for outcome in run_sequence(detector, pairs, keep_images=want_images,
                                    track_every=args.track):
            progress.clear()
            pair = outcome.pair
            if writer is not None:
                writer.write(json.dumps(outcome.to_dict()))
            if outcome.result is None:
                progress.failed += 1
                print(f"rovis detect: skipped frame {pair.index} ({pair.left} | {pair.right}): "
                      f"{outcome.error}", file=sys.stderr)
            else:
                n = len(outcome.result.objects)
                books += n
                tracked += outcome.result.tracked
                print(f"{pair.index:5d}  {pair.left}  {n} book{'s' if n != 1 else ''}"
                      + ("  (tracked)" if outcome.result.tracked else ""))
                _write_pictures(args, detector.rig, outcome.result, outcome.left_image,
                                outcome.right_image, suffix=f"{pair.index:04d}")
            progress.done += 1
            progress.show()
    except KeyboardInterrupt:
        interrupted = True
    finally:
        progress.finish()
        if writer is not None:
            writer.close()
    ok = progress.done - progress.failed
    print(f"{progress.done} of {len(pairs)} frames: {ok} detected "
          f"({books} book{'s' if books != 1 else ''}"
          + (f"; {tracked} frames tracked" if args.track > 1 else "") + "), "
          f"{progress.failed} skipped" + (", interrupted" if interrupted else "")
          + (f"; wrote {args.json}" if writer is not None else ""))
    if interrupted:
        return 130
    if ok == 0:
        print("rovis detect: error: no frame could be processed", file=sys.stderr)
        return EXIT_BAD_INPUT
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


def _methods(text: str) -> tuple[str, ...]:
    from rovis.evaluate import METHODS

    names = tuple(dict.fromkeys(m.strip() for m in text.split(",") if m.strip()))
    bad = [m for m in names if m not in METHODS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"expected a comma-separated list of {', '.join(METHODS)}, got {text!r}")
    return names


def _cmd_eval(args: argparse.Namespace) -> int:
    from rovis import evaluate

    if args.dask is not None and args.workers != 1:
        raise InputError("--dask and --workers: give one (the cluster has its own workers)")
    from rovis.pipeline import DetectConfig, with_settings

    ds = Path(args.dataset)
    evaluate.list_scenes(ds)  # a folder that is not a dataset: one line, before any work
    with_settings(DetectConfig(), args.set)  # so is a bad --set
    where = (f"Dask scheduler {args.dask}" if args.dask else
             f"{args.workers} worker process{'es' if args.workers != 1 else ''}"
             if args.workers > 1 else "1 process")
    print(f"rovis eval {ds}: methods {', '.join(args.methods)}; {where}", file=sys.stderr)
    ev = evaluate.evaluate(ds, args.methods, workers=args.workers, dask=args.dask,
                           limit=args.limit, settings=args.set,
                           progress=evaluate.stderr_progress())
    for item in ev.skipped:
        print(f"rovis eval: skipped scene {item['scene']}: {item['reason']}", file=sys.stderr)
    for rec in ev.scenes:
        for method, score in rec["methods"].items():
            if "failed" in score:
                print(f"rovis eval: method {method} failed on scene {rec['scene']} (its books "
                      f"counted as missed): {score['failed']}", file=sys.stderr)
    total = len(ev.scenes) + len(ev.skipped)
    print(f"dataset {ds} ({ev.protocol or 'unknown protocol'}): {len(ev.scenes)} of {total} "
          f"scenes scored, {len(ev.skipped)} skipped; matched within "
          f"{evaluate.MATCH_RADIUS_M * 100:g} cm of the true centre, errors in the world frame")
    if not ev.scenes:
        print("rovis eval: error: no scene could be scored", file=sys.stderr)
        return EXIT_BAD_INPUT
    print()
    print(evaluate.report(ev))
    if args.out:
        try:
            written = evaluate.write_results(ev, args.out, plots=not args.no_plots)
        except ImportError as exc:
            print(f"rovis eval: warning: {exc}; wrote {Path(args.out) / 'results.json'} only",
                  file=sys.stderr)
        else:
            print("\nwrote " + ", ".join(str(p) for p in written))
    print(f"\n{len(ev.skipped)} scene{'s' if len(ev.skipped) != 1 else ''} skipped")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from rovis.bench import bench_triangulation

    if args.what == "pipeline":
        from rovis.bench import bench_pipeline

        report = bench_pipeline(n=args.n, size=args.size, method=args.method,
                                workers=args.workers, protocol=args.protocol, seed=args.seed,
                                settings=args.set, repeats=args.repeats or 1,
                                progress=lambda text: print(text, file=sys.stderr, flush=True))
        print(report.text())
        return 0
    repeats = args.repeats or 7
    if args.what == "triangulation":
        print(f"triangulation of {args.points:,} points, one core, {repeats} runs")
        for timing in bench_triangulation(args.points, repeats=repeats):
            print(timing.line())
        return 0
    if args.what == "synth":
        import numpy as np

        from rovis.synth.bench import bench_synth

        print(f"synthetic scenes: 1024x768 stereo pairs, 2x2 supersampling, one core, "
              f"{repeats} scenes")
        for t in bench_synth(repeats):
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

    p = sub.add_parser("detect", help="find the books in a stereo pair, or in a sequence of "
                                      "pairs; print them, write JSON and pictures")
    p.add_argument("left", metavar="LEFT",
                   help="left image; or a folder, or a quoted glob ('DS/scenes/*/left.png'), "
                        "for a sequence")
    p.add_argument("right", metavar="RIGHT", help="right image, folder or quoted glob; pairs by "
                   "the name both share (left01/right01, 0000/left, 0000/right) or sorted order")
    p.add_argument("--calib", required=True, help="calibration file (any supported format)")
    p.add_argument("--method", default="closed",
                   choices=["closed", "open", "auto-median", "auto-otsu", "lsd", "contour"],
                   help="segmentation: closed loop (the paper's), open loop, or a baseline "
                        "(default: %(default)s)")
    p.add_argument("--triangulation", default="dlt", choices=["dlt", "optimal"],
                   help="corner triangulation: linear (eq. 5) or optimal (Lindstrom) "
                        "(default: %(default)s)")
    p.add_argument("--fit-rectangle", action="store_true",
                   help="replace each cover's four triangulated corners by one 3D rectangle "
                        "fitted to both images (beyond the paper)")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="change a detector setting, e.g. --set extent.grow=false "
                        "(DetectConfig's fields, nested with dots; repeatable)")
    p.add_argument("--json", metavar="F", help="write the detection JSON here (a sequence: "
                                               "JSON Lines, one frame a line)")
    p.add_argument("--overlay", metavar="DIR", help="write the images with what was found "
                   "drawn on them: DIR/left.png, right.png (a sequence: NNNN_left.png …)")
    p.add_argument("--view", metavar="F.png", help="write the world model, top and side view "
                   "(a sequence: F_NNNN.png)")
    p.add_argument("--track", metavar="N", type=_positive_int, default=1,
                   help="a still camera's sequence: detect every N frames and follow the books "
                        "found in the frames between (tens of ms a frame; detects afresh where "
                        "a book moved or went, but holds a height-map book it cannot follow; "
                        "new books wait for the next detection). "
                        "Default 1: detect in every frame")
    p.set_defaults(func=_cmd_detect)

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

    p = sub.add_parser("eval", help="score the methods on a synthetic dataset: the paper's "
                                    "Tables I/II beside its figures, results.json and plots")
    p.add_argument("dataset", metavar="DATASET",
                   help="a dataset folder (calib.yaml, scenes/NNNN/) as rovis synth writes")
    p.add_argument("--methods", type=_methods, default=("closed", "open", "auto-median",
                                                        "auto-otsu", "lsd", "contour"),
                   help="comma-separated (default: closed,open,auto-median,auto-otsu,lsd,"
                        "contour)")
    p.add_argument("--workers", type=_positive_int, default=1,
                   help="local worker processes (default: %(default)s)")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="score on a Dask distributed scheduler instead (tcp://host:8786; "
                        "the dataset must be at the same path there; needs rovis[dask])")
    p.add_argument("--out", metavar="DIR", help="write DIR/results.json, report.txt and the "
                                                "plots positions.png, yaw.png, lux.png")
    p.add_argument("--no-plots", action="store_true", help="with --out: no plots")
    p.add_argument("--limit", type=_positive_int, default=None,
                   help="only the first N scenes")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="change a detector setting, e.g. --set extent.grow=false --set "
                        "max_tilt_deg=4 (DetectConfig's fields, nested with dots; repeatable)")
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser("bench", help="benchmarks on one core: the pipeline per frame and stage "
                                     "(default), triangulation, scene rendering")
    p.add_argument("what", nargs="?", default="pipeline",
                   choices=["pipeline", "triangulation", "synth"],
                   help="what to time (default: %(default)s)")
    p.add_argument("--n", type=_positive_int, default=30,
                   help="pipeline: synthetic scenes (default: %(default)s)")
    p.add_argument("--size", type=_image_size, default=(1024, 768),
                   help="pipeline: image size WxH (default: 1024x768)")
    p.add_argument("--method", default="closed",
                   choices=["closed", "open", "auto-median", "auto-otsu", "lsd", "contour"],
                   help="pipeline: the method timed; closed and open are both run for the "
                        "segmentation-time ratio (default: %(default)s)")
    p.add_argument("--protocol", choices=["table1", "table2", "mixed"], default="mixed",
                   help="pipeline: the scenes' protocol (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="pipeline: scene seed (default: 0)")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="pipeline: processes for the all-cores rate (default: all cores)")
    p.add_argument("--points", type=_positive_int, default=1_000_000,
                   help="triangulation: points per run (default: %(default)s)")
    p.add_argument("--repeats", type=_positive_int, default=None,
                   help="triangulation, synth: runs (default: 7); pipeline: runs of each "
                        "frame on one core, the fastest kept (default: 1)")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="pipeline: change a detector setting for every method timed, e.g. "
                        "--set segment.lsd=true (DetectConfig's fields, nested with dots; "
                        "repeatable)")
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


def _image_size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT like 1024x768, got {text!r}")
    w, h = (int(p) for p in parts)
    if not (64 <= w <= 8192 and 64 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"expected 64-8192 pixels a side, got {text!r}")
    return w, h


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
    except (ValueError, OSError, ImportError) as exc:  # bad input: one line, no traceback
        print(f"rovis {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
