"""How well a book found agrees with the images (rovis.agreement): the output's quality and
reprojection error."""

from __future__ import annotations

import numpy as np
import pytest

from rovis import geometry
from rovis.agreement import AgreementConfig, agreement, edge_offsets, side_offsets
from rovis.pipeline import Detector
from rovis.segment import gradients
from rovis.synth import render, sample_scene

# a 200 x 120 px bright rectangle on a dark ground, corners clockwise from top-left
QUAD = np.array([[300.0, 200.0], [500.0, 200.0], [500.0, 320.0], [300.0, 320.0]])


@pytest.fixture(scope="module")
def grad():
    img = np.full((480, 800), 60, np.uint8)
    img[200:320, 300:500] = 180  # rows 200..319, columns 300..499: edges at x = 299.5, 499.5
    return gradients(img)


def test_side_offsets_are_the_rms_distance_along_each_side():
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    along_x = np.array([1.0, 0.0])
    lines = [(np.array([0.0, 2.0]), along_x),  # 2 px off all along
             (np.array([10.0, 5.0]), np.array([0.0, 1.0])),  # on the side
             # through the side's middle, its ends 1 px either way: rms sqrt(1/3)
             (np.array([5.0, 10.0]), np.array([10.0, 2.0]) / np.hypot(10.0, 2.0)),
             None]
    off = side_offsets(square, lines)
    assert off[:3] == pytest.approx([2.0, 0.0, np.sqrt(1.0 / 3.0) * 10.0 / np.hypot(10, 2)])
    assert np.isnan(off[3])


def test_edge_offsets_measure_how_far_the_image_edge_lies(grad):
    # on the rectangle: the sides lie half a pixel from the edges at most
    assert np.all(edge_offsets(grad, QUAD - 0.5) < 0.15)
    # 1.5 px to the right: the two upright sides 1.5 px off their edges, the others on theirs
    off = edge_offsets(grad, QUAD - 0.5 + [1.5, 0.0])
    assert off[[1, 3]] == pytest.approx([1.5, 1.5], abs=0.15)
    assert np.all(off[[0, 2]] < 0.15)
    # 10 px off: no edge within the 3 px looked at for the upright sides
    off = edge_offsets(grad, QUAD - 0.5 + [10.0, 0.0])
    assert np.all(np.isnan(off[[1, 3]])) and np.all(off[[0, 2]] < 0.15)


def test_agreement_is_one_and_zero_on_the_edges_and_falls_off_them(grad):
    both = {"left": grad, "right": grad}
    thresholds = {"left": 20.0, "right": 20.0}  # Sobel scale: the step gives ~480
    quality, error_px, support = agreement(both, {"left": QUAD - 0.5, "right": QUAD - 0.5},
                                           thresholds)
    assert quality == 1.0 and error_px < 0.15
    assert set(support) == {"left", "right"} and support["left"].shape == (4,)
    # the right image's quad 10 px off: its upright sides show no step and count the 3 px
    # reach each (2 of 8 sides: rms sqrt(2 * 9 / 8) = 1.5 px), its horizontal sides lose
    # the 10 px beyond the rectangle's corners
    off = {"left": QUAD - 0.5, "right": QUAD - 0.5 + [10.0, 0.0]}
    quality, error_px, support = agreement(both, off, thresholds)
    assert error_px == pytest.approx(1.5, abs=0.05)
    assert np.all(support["right"][[1, 3]] == 0.0) and quality < 0.5
    # a quad on no edge at all
    nowhere = {"left": QUAD * 0.5, "right": QUAD * 0.5}
    quality, error_px, _ = agreement(both, nowhere, thresholds, reach_px=2.0)
    assert quality == 0.0 and error_px == 2.0


def test_agreement_settings_are_checked():
    with pytest.raises(ValueError, match="agreement"):
        AgreementConfig(reach_px=0.0)
    assert AgreementConfig().reach_px == 3.0


@pytest.fixture(scope="module")
def still_detection():
    """A rendered scene's books as detected, and the detector's frame of it (its ideal
    images' gradients, its rig) and edge strengths."""
    sc = sample_scene(11, lux=500.0)
    frame = render(sc, 11)
    det = Detector(sc.rig)
    result = det.detect(frame.left, frame.right)
    assert len(result.objects) >= 3
    return det, det._prepare(frame.left, frame.right), result.objects, \
        det._edge_strength(result.segmentation)


def test_a_detected_book_moved_off_its_edges_agrees_less(still_detection):
    """The detector's own numbers: they are the cover's world corners against its images;
    a cover that agrees with them to a pixel no longer does once moved 8 mm along the
    desk (about 6 px in these images)."""
    det, f, objects, strength = still_detection
    thresholds = {cam: det.cfg.agreement.evidence * strength[cam] for cam in strength}

    def agree(P: np.ndarray) -> tuple[float, float, dict[str, np.ndarray]]:
        return agreement(f.grads, {"left": geometry.project(f.rig.Q_L, P),
                                   "right": geometry.project(f.rig.Q_R, P)}, thresholds)

    close = 0
    for obj in objects:
        quality, error_px, _ = agree(obj.corners_world)
        assert quality == pytest.approx(obj.quality, abs=1e-3)
        assert error_px == pytest.approx(obj.reprojection_error_px, abs=1e-3)
        assert 0.0 <= quality <= 1.0 and 0.0 <= error_px <= 3.0
        if error_px < 1.0:
            close += 1
            for shift in ([0.008, 0.0, 0.0], [0.0, 0.008, 0.0]):
                assert agree(obj.corners_world + shift)[1] > error_px + 1.0
    assert close >= 3
