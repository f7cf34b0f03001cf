"""A matched pair that is no cover, retried with the other quads the closed loop found over
it (Segmentation.alternatives, Detector._alternative)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rovis import geometry
from rovis.pipeline import DetectConfig, Detector, Pair, with_settings
from rovis.segment import gradients
from rovis.segment.boundary import Segmentation, refine_quad
from rovis.segment.lines import Lines
from rovis.segment.quads import order_corners
from rovis.stereo import Match
from rovis.synth import render, sample_scene
from rovis.synth.scene import Book
from rovis.synth.textures import CoverSpec

from conftest import ideal_images
from test_triangulation import _side_moved_out

THICKNESS = 0.03


@pytest.fixture(scope="module")
def book():
    """One plain book, 24 × 16 × 3 cm, alone on a clean desk at 500 lx: its true corners,
    both ideal images, their gradients, the desk plane and the rig."""
    sc = sample_scene(3, lux=500.0, n_books=0)
    b = Book(center=(0.45, 0.33, THICKNESS), yaw_deg=15.0, size=(0.24, 0.16, THICKNESS),
             cover=CoverSpec(kind="plain", albedo=0.12, seed=4))
    sc = replace(sc, books=(b,), papers=(), mugs=(), pens=(), cables=())
    r = render(sc, 3)
    ideal = ideal_images(sc.rig, r)
    grads = {cam: gradients(img) for cam, img in ideal.items()}
    P = np.array(r.truth["books"][0]["corners"])
    return P, ideal, grads, np.asarray(r.truth["desk_plane"]), sc.rig, (r.left, r.right)


def _segmentation(quad, alternatives):
    c = order_corners(quad)[None]
    return Segmentation(c, c, np.ones(1), Lines.empty(), 100.0, 30, 0.1, 1,
                        (np.array(alternatives, dtype=np.float64).reshape(-1, 4, 2),))


def _outline(P, rig):
    """The left quad of the cover with its page block's side: the two corners on the right
    moved 8 px further right (along the epipolar lines, so the pair makes a tilted cover)."""
    quad = geometry.project(rig.Q_L, P)
    right = np.argsort(quad[:, 0])[2:]
    quad[right, 0] += 8.0
    return quad


def _covers(P, grads, rig):
    """The cover's Hough-like corners in the left image (the alternative, refined when
    tried) and its refined corners in the right (as the segmentation leaves them)."""
    left = order_corners(geometry.project(rig.Q_L, P))
    right = order_corners(refine_quad(grads["right"], geometry.project(rig.Q_R, P)))
    return {"left": left, "right": right}


def _retry(book, settings=()):
    P, ideal, grads, desk, rig, _ = book
    cover = _covers(P, grads, rig)
    segs = {"left": _segmentation(_outline(P, rig), [cover["left"]]),
            "right": _segmentation(cover["right"], [])}
    det = Detector(rig, with_settings(DetectConfig(), list(settings)))
    first = Pair(segs["left"].corners[0], cover["right"], 1.0, 0.0)
    pair, book_, why = det._reconstruct_or_why(rig, first, desk)
    assert book_ is None and why == "tilted"  # the outline with the cover is no cover
    mt = Match(0, 0, cover["right"], 0.0, 1.0)
    return det._alternative(rig, segs, grads, ideal, mt, pair, why, desk, None, []), P


def test_an_outline_paired_with_a_cover_is_retried_with_the_cover_found_at_another_T_H(book):
    (pair, found, why), P = _retry(book)
    assert found is not None and why == ""
    assert pair.alternative
    # within the grasp tolerance (the refinement of the near sides leaves a few mm)
    assert np.linalg.norm(np.asarray(found.pose.center) - P.mean(axis=0)) < 0.01
    assert abs(found.pose.size[2] - THICKNESS) < 0.006


def test_an_alternative_passes_the_same_checks_as_a_first_pair(book):
    # a tilt bar no cover can pass: the failed pair and its reason come back
    (pair, found, why), _ = _retry(book, ["max_tilt_deg=-1"])
    assert found is None and why == "tilted" and not pair.alternative


def test_an_alternative_overlapping_a_book_already_found_is_not_tried(book):
    P, ideal, grads, desk, rig, _ = book
    cover = _covers(P, grads, rig)
    segs = {"left": _segmentation(_outline(P, rig), [cover["left"]]),
            "right": _segmentation(cover["right"], [])}
    det = Detector(rig)
    first = Pair(segs["left"].corners[0], cover["right"], 1.0, 0.0)
    _, found, why = det._alternative(rig, segs, grads, ideal, Match(0, 0, cover["right"], 0.0, 1.0),
                                     first, "tilted", desk, None, [cover["left"]])
    assert found is None and why == "tilted"


def _stub_outline_pair(book, monkeypatch) -> list[str]:
    """``detect``'s segmentation stubbed for ``book``: the left image's quad is the
    outline (:func:`_outline`), the cover only its alternative; the right image's is the
    cover. Returns the settings that leave the pair to the steps under test (the one-image
    search and the extent step off; full_view off: the stub's quads are in the rig's own
    ideal pixels)."""
    import rovis.pipeline as pipeline
    P, _, grads, _, rig, _ = book
    cover = _covers(P, grads, rig)
    segs = {"left": _segmentation(_outline(P, rig), [cover["left"]]),
            "right": _segmentation(cover["right"], [])}
    calls: list[str] = []

    def fake_segment(gray, grad, method, *, controller, cfg, timing):
        calls.append("left" if len(calls) % 2 == 0 else "right")  # detect: left, then right
        return segs[calls[-1]]

    monkeypatch.setattr(pipeline, "segment", fake_segment)
    # (the smooth map's wide slabs off too: they find this book on their own)
    return ["stereo.transfer=false", "extent.grow=false", "extent.shrink=false",
            "full_view=false", "heightmap.wide_slab=0"]


def test_detect_retries_a_tilted_pair_and_finds_the_book_only_with_alternatives(book, monkeypatch):
    # the segmentation stubbed: the left image's quad is the outline, the cover only its
    # alternative; with the one-image search, the extent step and the side fit off, only
    # the retry can find the book
    P, _, _, _, rig, (raw_left, raw_right) = book
    off = _stub_outline_pair(book, monkeypatch) + ["flat_refit_sides=0"]
    on = Detector(rig, with_settings(DetectConfig(), off)).detect(raw_left, raw_right)
    without = Detector(rig, with_settings(DetectConfig(), off + ["stereo.alternatives=false"])
                       ).detect(raw_left, raw_right)
    assert len(on.objects) == 1 and not on.dropped
    assert np.linalg.norm(np.asarray(on.objects[0].pose.center) - P.mean(axis=0)) < 0.01
    assert not without.objects and [why for why, _, _ in without.dropped] == ["tilted"]


def test_the_outline_pair_fitted_to_its_sides_gives_the_cover(book, monkeypatch):
    # the same stub, the retry off: the outline's right-hand side (8 px out, as if on the
    # page block's foot) lies outside the cover in the left image only, so the flat fit to
    # the pair's sides with that side left out is the cover (fit_rectangle_sides)
    P, _, _, _, rig, (raw_left, raw_right) = book
    off = _stub_outline_pair(book, monkeypatch) + ["stereo.alternatives=false"]
    res = Detector(rig, with_settings(DetectConfig(), off)).detect(raw_left, raw_right)
    assert len(res.objects) == 1
    got = np.asarray(res.objects[0].corners_world)
    assert np.linalg.norm(got[:, None] - P[None], axis=2).min(axis=1).max() < 0.003  # m


def test_the_alternatives_come_before_the_side_fit(book, monkeypatch):
    # the same stub with the side fit on: the alternative (the cover) is taken, and the
    # side fit is not asked for the pair; with the alternatives off, it is
    P, _, _, _, rig, (raw_left, raw_right) = book
    off = _stub_outline_pair(book, monkeypatch)
    fits: list[Pair] = []
    side_fit = Detector._side_fit

    def counted(self, rig_, pair, *args):
        fits.append(pair)
        return side_fit(self, rig_, pair, *args)

    monkeypatch.setattr(Detector, "_side_fit", counted)
    res = Detector(rig, with_settings(DetectConfig(), off)).detect(raw_left, raw_right)
    assert len(res.objects) == 1 and fits == []
    res = Detector(rig, with_settings(DetectConfig(), off + ["stereo.alternatives=false"])
                   ).detect(raw_left, raw_right)
    assert len(res.objects) == 1 and len(fits) == 1


@pytest.mark.parametrize("out_px, fits", [(3.0, True), (1.5, False)])
def test_the_side_left_out_must_lie_clear_of_the_fit(book, out_px, fits):
    # the right image's side running most nearly across the epipolar lines moved out:
    # 3 px is fitted (the left-out side more than twice flat_refit_px outside), 1.5 px
    # is not
    P, _, _, desk, rig, _ = book
    left, right = geometry.project(rig.Q_L, P), geometry.project(rig.Q_R, P)
    d = np.roll(right, -1, axis=0) - right
    s = int(np.argmax(np.abs(d[:, 1]) / np.linalg.norm(d, axis=1)))  # across the baseline
    pair = Pair(left, _side_moved_out(right, s, out_px), 1.0, 0.0)
    det = Detector(rig)
    if fits:
        assert det._reconstruct_or_why(rig, pair, desk)[2] == "tilted"
    got = det._side_fit(rig, pair, desk, None)
    assert (got is not None) == fits
    if fits:
        assert np.abs(np.asarray(got[1].corners_world) - P).max() < 0.001  # m


def test_a_cover_from_the_alternatives_must_stand_above_the_desk(book):
    # a sheet on the desk (3 mm) passes as a first pair, not as an alternative
    P, _, _, desk, rig, _ = book
    sheet = P.copy()
    sheet[:, 2] = 0.003
    corners = {cam: geometry.project(Q, sheet)
               for cam, Q in (("left", rig.Q_L), ("right", rig.Q_R))}
    det = Detector(rig)
    first = Pair(corners["left"], corners["right"], 1.0, 0.0)
    assert det._reconstruct_or_why(rig, first, desk)[1] is not None
    _, found, why = det._reconstruct_or_why(rig, replace(first, alternative=True), desk)
    assert found is None and why == "height"


def test_a_quad_seen_in_one_image_only_is_looked_for_through_its_alternatives(book, monkeypatch):
    # the right image's segmentation found nothing; the left kept the outline, the cover is
    # its alternative: the one-image search finds the cover from the alternative only
    import rovis.pipeline as pipeline
    P, ideal, grads, desk, rig, (raw_left, raw_right) = book
    cover = _covers(P, grads, rig)
    empty = Segmentation(np.zeros((0, 4, 2)), np.zeros((0, 4, 2)), np.zeros(0), Lines.empty(),
                         100.0, 30, 0.0, 1)
    segs = {"left": _segmentation(_outline(P, rig), [cover["left"]]), "right": empty}
    calls: list[str] = []

    def fake_segment(gray, grad, method, *, controller, cfg, timing):
        calls.append("left" if len(calls) % 2 == 0 else "right")  # detect: left, then right
        return segs[calls[-1]]

    monkeypatch.setattr(pipeline, "segment", fake_segment)
    off = ["extent.grow=false", "extent.shrink=false", "full_view=false",  # the stub's pixels
           "heightmap.wide_slab=0"]  # the smooth map's wide slabs find this book on their own
    on = Detector(rig, with_settings(DetectConfig(), off)).detect(raw_left, raw_right)
    without = Detector(rig, with_settings(DetectConfig(), off + ["stereo.transfer_alternatives=0"])
                       ).detect(raw_left, raw_right)
    assert len(on.objects) == 1 and not without.objects
    assert np.linalg.norm(np.asarray(on.objects[0].pose.center) - P.mean(axis=0)) < 0.01
