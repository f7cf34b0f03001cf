"""The command line: help, demo, bench, and clean failures."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rovis.cli import main
from rovis.demo import demo_books


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for command in ("demo", "calib", "bench"):
        assert command in out


def test_no_command_prints_help(capsys):
    assert main([]) == 0
    assert "usage: rovis" in capsys.readouterr().out


def test_demo_reconstructs_the_books_within_a_centimetre(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "yaw" in out and str(tmp_path / "demo") in out
    doc = json.loads((tmp_path / "demo" / "detections.json").read_text())
    assert doc["world_frame"] == "marker" and len(doc["objects"]) == 3
    for obj, book in zip(doc["objects"], demo_books()):
        assert np.abs(np.subtract(obj["center"], book.center)).max() < 0.01  # 1 cm grasp tolerance
        assert abs((obj["yaw_deg"] - book.yaw_deg + 180) % 360 - 180) < 2.0
        assert len(obj["quaternion_xyzw"]) == 4 and len(obj["corners_world"]) == 4
    assert (tmp_path / "demo" / "calib.yaml").exists()


def test_bench_triangulation_runs_small(capsys):
    assert main(["bench", "triangulation", "--points", "2000", "--repeats", "2"]) == 0
    out = capsys.readouterr().out
    assert "triangulate dlt" in out and "triangulate optimal" in out and "M points/s" in out


def test_bench_rejects_a_bad_count(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "triangulation", "--points", "0"])
    assert exc.value.code == 2
    assert "expected a positive integer" in capsys.readouterr().err
