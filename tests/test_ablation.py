"""scripts/ablation.py: every row turns a real step off, and the table reads results.json."""

from __future__ import annotations

import json
from dataclasses import asdict

import pytest

from rovis.pipeline import DetectConfig, with_settings

from script_module import load_script

ablation = load_script("ablation")


@pytest.mark.parametrize("what,settings", ablation.STEPS[1:])
def test_each_row_changes_the_detector(what, settings):
    # a setting renamed in the detector must fail here, not run the defaults under its name
    changed = with_settings(DetectConfig(), settings)
    assert asdict(changed) != asdict(DetectConfig()), what


def test_the_first_row_is_the_defaults():
    assert ablation.STEPS[0][1] == []


def test_a_row_is_read_from_results_json(tmp_path):
    doc = {"summary": {"closed": {
        "books": 10, "found": 8, "within_1cm": 7, "fp_per_image": 0.25,
        "errors": {"x": {"mean": 0.002}, "y": {"mean": 0.003}, "z": {"mean": 0.001}}}},
        "scenes": [{"timing_ms": {"closed": t}} for t in (100.0, 300.0, 200.0)]}
    (tmp_path / "results.json").write_text(json.dumps(doc))
    row = ablation._row(tmp_path)
    assert (row["found"], row["books"], row["within"]) == (8, 10, 7)
    assert row["fp"] == pytest.approx(0.25)
    assert (row["x"], row["y"], row["z"]) == pytest.approx((2.0, 3.0, 1.0))
    assert row["ms"] == pytest.approx(200.0)  # the median, not the mean
