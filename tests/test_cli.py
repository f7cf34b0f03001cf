"""The command line: help, bench, and clean failures (detect and demo: test_detect_cli)."""

from __future__ import annotations

import pytest

from rovis.cli import main


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


def test_bench_triangulation_runs_small(capsys):
    assert main(["bench", "triangulation", "--points", "2000", "--repeats", "2"]) == 0
    out = capsys.readouterr().out
    assert "triangulate dlt" in out and "triangulate optimal" in out and "M points/s" in out


def test_bench_rejects_a_bad_count(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "triangulation", "--points", "0"])
    assert exc.value.code == 2
    assert "expected a positive integer" in capsys.readouterr().err
