"""Following known books into the next frame of a still camera (beyond the paper).

A robot's stereo camera looks at the same desk frame after frame, and most frames show the
books where they were. Detecting afresh (the closed loop, stereo, the steps after it) costs
most of a second on one core; a book already found only needs its sides measured again.
:func:`follow` refits each side of its cover to the gradient within a pixel or two of where
it was, in both images, and fits one rectangle parallel to the desk to the two images'
corners (:func:`rovis.geometry.fit_rectangle`): the book's new pose, from this frame's
pixels. A book that is no longer there, or has moved further than the search reaches, shows
it: a side loses the edge it had. The caller (:meth:`rovis.pipeline.Detector.track`) then detects afresh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rovis import geometry
from rovis.agreement import side_offsets
from rovis.extent import _side_lines
from rovis.segment.boundary import side_evidence
from rovis.segment.edges import Gradients
from rovis.segment.lines import intersect, refine_segment


@dataclass(frozen=True)
class TrackConfig:
    """How :func:`follow` measures a known book again.

    Attributes
    ----------
    window_px : float
        Pixels: each side's edge is looked for this far either side of where it was. Small,
        so that a side stays on its own edge and does not jump to a neighbouring one (a
        page block's outer edge lies 1–3 px outside the cover's): a book that moved
        further is lost and detected afresh.
    evidence : float
        A side's edge evidence (:func:`rovis.segment.boundary.side_evidence`) counts the
        pixels along it whose derivative across it reaches this share of the image's Canny
        low threshold.
    keep : float
        Each side must keep this share of the evidence it had when the book was detected,
        in both images (a side that showed no edge then, e.g. a desk-coloured cover's far
        side, needs none now).
    max_fit_px : float
        Pixels: the rectangle parallel to the desk fitted to the refit corners is the
        cover where every corner, in both images, lies within this of it; else the
        corners are triangulated one by one, as the detection did.
    hold_height_map : bool
        A book the height map found (``source`` "height map") that :func:`follow` cannot
        measure again (a side not refit, or short of its edge evidence) is kept where it
        was, instead of the whole frame being detected afresh: a desk-toned cover's faint
        sides tell little of whether it moved, and the caller's next
        :meth:`rovis.pipeline.Detector.detect` checks it again. A height-map book taken
        away is therefore reported until then.
    """

    window_px: float = 1.5
    evidence: float = 0.5
    keep: float = 0.6
    max_fit_px: float = 1.5
    hold_height_map: bool = True

    def __post_init__(self) -> None:
        if not (self.window_px > 0 and self.evidence > 0 and 0 <= self.keep <= 1
                and self.max_fit_px > 0):
            raise ValueError(f"track: window_px, evidence and max_fit_px must be positive and "
                             f"keep in [0, 1], got {self}")


def refit_quad(grad: Gradients, corners: NDArray[np.float64], window_px: float,
               ) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
    """A quad's sides (corners (4, 2), pixels) refit to the gradient within ``window_px``
    of where they are, neighbours intersected: the new corners (4, 2) and which sides were
    refit (4,), or None where two sides no longer meet near their corner. A side with too
    few edge points keeps its place (:func:`rovis.segment.lines.refine_segment`)."""
    sides, fitted = [], np.zeros(4, bool)
    for s in range(4):
        a, b = corners[s], corners[(s + 1) % 4]
        fit = refine_segment(grad, a, b, half_width=window_px)
        fitted[s] = fit is not None
        sides.append(fit if fit is not None
                     else (0.5 * (a + b), (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)))
    out = np.empty_like(corners)
    for s in range(4):  # corner s joins side s-1 and side s
        p = intersect(*sides[s - 1], *sides[s])
        # a corner may move further than its sides at an acute angle, not without bound
        if p is None or np.linalg.norm(p - corners[s]) > 4.0 * window_px:
            return None
        out[s] = p
    return out, fitted


def follow(grads: dict[str, Gradients], corners: dict[str, NDArray[np.float64]],
           evidence: dict[str, NDArray[np.float64]], P_before: ArrayLike, Q_L: ArrayLike,
           Q_R: ArrayLike, desk_plane: ArrayLike, strength: dict[str, float],
           cfg: TrackConfig = TrackConfig(), *, reach_px: float = 3.0,
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                      float] | None:
    """One known book measured again in a new frame.

    Parameters
    ----------
    grads : dict of Gradients
        ``"left"``, ``"right"``: the new frame's gradients (ideal images).
    corners : dict of ndarray, shape (4, 2)
        The cover's corners in each ideal image where it was last seen, the same physical
        corner at each index.
    evidence : dict of ndarray, shape (4,)
        Each side's edge evidence when it was detected
        (:func:`rovis.segment.boundary.side_evidence` at ``cfg.evidence * strength``).
    P_before : array_like, shape (4, 3)
        The cover's world corners then (metres, in the order of ``corners``): where the
        rectangle fit starts (a still book's is its answer, reached in a step or two).
    Q_L, Q_R : array_like, shape (3, 4)
        World → ideal pixel projections.
    desk_plane : array_like, shape (4,)
        ``[nx, ny, nz, d]``, world, normal up.
    strength : dict of float
        Per camera, the derivative across a side that counts as an edge (the Canny low
        threshold of the frame the book was detected in).
    reach_px : float
        What a side this frame could not refit counts in the error, pixels (as a side
        without an edge counts in :func:`rovis.agreement.agreement`).

    Returns
    -------
    (P, left, right, error) or None
        The cover's corners in the world (4, 3), metres (a rectangle parallel to the desk
        where one fits); their projections into both ideal images (4, 2) each; the root
        mean square distance of those projected sides to the sides refit in this frame,
        over both images' eight sides (px; a side it could not refit counts ``reach_px``):
        :mod:`rovis.agreement`'s error, from edges looked for within ``cfg.window_px`` of
        where the sides were rather than ``reach_px`` of the projected sides. None where
        the book is not where it was: a corner whose sides no longer meet near it, or a
        side that lost its edge.
    """
    refit, fitted = {}, {}
    for cam in ("left", "right"):
        got = refit_quad(grads[cam], np.asarray(corners[cam], dtype=np.float64), cfg.window_px)
        if got is None:
            return None
        c, fitted[cam] = got
        now = side_evidence(grads[cam], c, cfg.evidence * strength[cam])
        if np.any(now < cfg.keep * np.asarray(evidence[cam])):
            return None  # a side lost its edge: the book moved or is gone
        refit[cam] = c
    P0 = geometry.triangulate_dlt(Q_L, Q_R, refit["left"], refit["right"])
    if not np.all(np.isfinite(P0)):
        return None
    try:
        P = geometry.fit_rectangle(Q_L, Q_R, refit["left"], refit["right"], P_before,
                                   desk_plane)
    except ValueError:
        P = P0
    if not _fits(P, Q_L, Q_R, refit, cfg.max_fit_px):
        # no flat rectangle (a cover the detection left tilted, or with a side it
        # completed off its edge): its corners triangulated one by one, as detected
        P = P0
    left, right = geometry.project(Q_L, P), geometry.project(Q_R, P)
    lines = _side_lines(refit)
    off = np.concatenate([np.where(fitted[cam], side_offsets(model, lines[cam]), reach_px)
                          for cam, model in (("left", left), ("right", right))])
    off = np.minimum(off, reach_px)
    return P, left, right, float(np.sqrt(np.mean(off ** 2)))


def _fits(P: NDArray[np.float64], Q_L: ArrayLike, Q_R: ArrayLike,
          px: dict[str, NDArray[np.float64]], max_px: float) -> bool:
    """Whether the world corners ``P`` (4, 3) project within ``max_px`` of the corners
    ``px`` measured in each image."""
    off = max(float(np.linalg.norm(geometry.project(Q, P) - px[cam], axis=1).max())
              for cam, Q in (("left", Q_L), ("right", Q_R)))
    return bool(np.isfinite(off) and off <= max_px)
