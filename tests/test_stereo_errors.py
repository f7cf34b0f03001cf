"""scripts/stereo_errors.py: a far-off book's sides against the truth."""

from __future__ import annotations

import numpy as np

from script_module import load_script

stereo_errors = load_script("stereo_errors")


def _cover(x0, x1, y0, y1, yaw_deg=30.0):
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    R = np.array([[c, -s], [s, c]])
    xy = np.array([[x0, y1], [x1, y1], [x1, y0], [x0, y0]]) @ R.T
    return np.column_stack([xy, np.full(4, 0.02)])


def test_a_cover_cut_short_at_a_band_is_called_so():
    truth = _cover(0.0, 0.22, 0.0, 0.15)
    found = _cover(0.0, 0.22, 0.03, 0.15)  # the side at y = 0 taken 3 cm in
    offsets = stereo_errors.side_offsets(truth, found)
    np.testing.assert_allclose(np.sort(offsets), [-0.03, 0.0, 0.0, 0.0], atol=1e-9)
    assert stereo_errors.kind(offsets, 0.0) == "cut short"


def test_a_cover_reaching_over_and_one_too_high_are_told_apart():
    truth = _cover(0.0, 0.22, 0.0, 0.15)
    over = stereo_errors.side_offsets(truth, _cover(0.0, 0.26, 0.0, 0.15))
    assert abs(np.nanmax(over) - 0.04) < 1e-9
    assert stereo_errors.kind(over, 0.0) == "over-reach"
    assert stereo_errors.kind(stereo_errors.side_offsets(truth, truth), 0.012) == "height"
    assert stereo_errors.kind(stereo_errors.side_offsets(truth, truth), 0.003) == "other"
