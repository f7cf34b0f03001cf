"""scripts/segmentation_study.py: its --set reaches the SegmentConfig each method runs with, and
its scoring of one image's quads."""

from __future__ import annotations

import numpy as np
import pytest

from rovis.segment import SegmentConfig

from script_module import load_script

study = load_script("segmentation_study")


def test_settings_reach_the_segment_config():
    cfg = study.segment_config(-1, 2.2, ["n_max=200", "quads.min_support=0.6"])
    assert cfg.n_max == 200 and cfg.quads.min_support == 0.6
    # the method's own sign and the gamma stay
    assert cfg.quality_sign == -1 and cfg.refine_gamma == 2.2


def test_no_settings_is_the_methods_config():
    assert study.segment_config(+1, 1.0, []) == SegmentConfig(quality_sign=+1)


@pytest.mark.parametrize("setting,match", [
    ("bogus=1", r"--set bogus: no setting 'bogus'"),  # named as given, not segment.bogus
    ("n_max=abc", r"--set n_max=abc: expected int"),
    ("n_max", r"--set 'n_max': expected NAME=VALUE"),
    # each method's sign and --refine-gamma are not overridden behind the table's labels
    ("quality_sign=-1", r"each method sets it"),
    ("refine_gamma=2.2", r"--refine-gamma sets it"),
])
def test_a_wrong_setting_is_refused(setting, match):
    with pytest.raises(ValueError, match=match):
        study.segment_config(+1, 1.0, [setting])


def test_the_command_line_refuses_a_wrong_setting_with_exit_code_2(capsys):
    with pytest.raises(SystemExit) as e:
        study.main(["--n", "1", "--set", "bogus=1"])
    assert e.value.code == 2
    assert "no setting 'bogus'" in capsys.readouterr().err


SQUARE = np.array([[100.0, 100.0], [300.0, 100.0], [300.0, 250.0], [100.0, 250.0]])


def test_a_quad_within_3_px_in_any_cyclic_order_finds_the_cover():
    quad = np.roll(SQUARE + [2.0, -1.0], 2, axis=0)  # another corner first, 2.2 px off
    found, errors, false = study.score_image([(SQUARE, True)], [quad])
    assert found == [True] and false == 0
    assert np.allclose(errors, np.hypot(2.0, 1.0))


def test_a_quad_with_one_corner_4_px_off_finds_nothing_and_is_false():
    quad = SQUARE.copy()
    quad[2] += [4.0, 0.0]
    found, errors, false = study.score_image([(SQUARE, True)], [quad])
    assert found == [False] and errors == [] and false == 1


def test_a_cover_not_counted_for_recall_still_takes_its_quad():
    other = SQUARE + [400.0, 0.0]
    found, errors, false = study.score_image([(SQUARE, True), (other, False)],
                                             [other + 0.5, SQUARE + 10.0])
    # the counted cover is missed, the uncounted one found: its quad is no false one
    assert found == [False] and len(errors) == 4 and false == 1


def test_no_quads_find_nothing():
    assert study.score_image([(SQUARE, True)], []) == ([False], [], 0)


def test_an_unknown_method_is_refused_with_exit_code_2(capsys):
    with pytest.raises(SystemExit) as e:
        study.main(["--n", "1", "--methods", "closed+,bogus"])
    assert e.value.code == 2
    assert "unknown bogus" in capsys.readouterr().err


def test_a_quad_5_px_off_is_detected_but_not_found():
    quad = SQUARE + [5.0, 0.0]  # IoU 195·150 / 205·150 = 0.95
    found, _, false = study.score_image([(SQUARE, True)], [quad])
    detected, errors = study.detect_image([(SQUARE, True)], [quad])
    assert found == [False] and false == 1
    assert detected == [True] and errors == pytest.approx([5.0] * 4)


@pytest.mark.parametrize("turn", [0, 1, 2, 3])
@pytest.mark.parametrize("reverse", [False, True])
def test_detected_corners_are_compared_corner_for_corner_in_any_order(turn, reverse):
    quad = SQUARE + [0.0, 6.0]
    quad = np.roll(quad[::-1] if reverse else quad, turn, axis=0)
    detected, errors = study.detect_image([(SQUARE, True)], [quad])
    assert detected == [True] and errors == pytest.approx([6.0] * 4)


def test_a_quad_over_just_over_half_of_a_cover_is_detected_and_under_half_is_not():
    part = SQUARE.copy()
    part[1:3, 0] = 210.0  # 110 of 200 px wide, three sides shared: IoU 0.55
    detected, errors = study.detect_image([(SQUARE, True)], [part])
    assert detected == [True] and len(errors) == 4
    part[1:3, 0] = 195.0  # 95 px: IoU 0.475
    assert study.detect_image([(SQUARE, True)], [part]) == ([False], [])


def test_a_quad_over_two_covers_detects_neither():
    other = SQUARE + [200.0, 0.0]
    both = np.array([[100.0, 100.0], [520.0, 100.0], [520.0, 250.0], [100.0, 250.0]])  # 0.48 each
    assert study.detect_image([(SQUARE, True), (other, True)], [both]) == ([False, False], [])


@pytest.mark.parametrize("first", [True, False])
def test_one_quad_detects_one_cover_the_one_it_overlaps_most(first):
    other = SQUARE + [30.0, 0.0]  # two overlapping true covers, one quad between them
    quad = SQUARE + [10.0, 0.0]  # IoU 0.91 with SQUARE, 0.82 with other
    truth = [(SQUARE, True), (other, True)] if first else [(other, True), (SQUARE, True)]
    detected, errors = study.detect_image(truth, [quad])
    assert detected == ([True, False] if first else [False, True])
    assert errors == pytest.approx([10.0] * 4)
    # a second quad on the other cover detects it too
    detected, errors = study.detect_image(truth, [quad, other])
    assert detected == [True, True] and len(errors) == 8


def test_a_cover_not_counted_still_takes_the_quad_that_overlaps_it_most():
    other = SQUARE + [30.0, 0.0]
    quad = SQUARE + [25.0, 0.0]  # IoU 0.78 with SQUARE, 0.94 with the uncounted cover
    detected, errors = study.detect_image([(SQUARE, True), (other, False)], [quad])
    assert detected == [False] and errors == pytest.approx([5.0] * 4)


def test_the_cover_kind_table_adds_up_to_the_summary(capsys):
    import re

    study.main(["--n", "2", "--seed", "100", "--methods", "open"])
    out = capsys.readouterr().out
    found, n, detected = (int(x) for x in re.search(
        r"open: (\d+) of (\d+) books found over all bands, (\d+) detected", out).groups())
    row = [line for line in out.splitlines() if line.startswith("| open |")][-1]  # by kind
    cells = re.findall(r"(\d+) / (\d+) of (\d+)", row)
    assert n > 0 and len(cells) >= 2  # two kinds at least in these two scenes
    assert sum(int(f) for f, _, _ in cells) == found
    assert sum(int(d) for _, d, _ in cells) == detected
    assert sum(int(c) for _, _, c in cells) == n
