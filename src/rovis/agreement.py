"""How well each book found agrees with the images: the output's ``quality`` and
``reprojection_error_px`` (beyond the paper).

The steps after the segmentation move a cover's sides (:mod:`rovis.extent`, the trims, the
grows), and most books leave the pipeline as a 3D rectangle whose corners in each image are
its projections. The corners' own reprojection error is then about 0 whatever the images
show. So the book as reported is checked against both images once more, at the end:

- **edge support** (:func:`edge_quality`, :func:`rovis.segment.boundary.side_evidence`):
  per side, the share of its length that shows a step across it; a book's ``quality`` is
  the mean over its four sides, in the worse of the two images;
- **edge offset** (:func:`edge_offsets`): per side, the root mean square distance along it
  between the side as projected and the edge the image shows within ``reach_px`` of it;
  a book's ``reprojection_error_px`` is the root mean square over its eight sides (four per
  image), a side with no edge there counting ``reach_px``. The edge is fitted as the
  segmentation refines a side (:func:`rovis.segment.lines.refine_segment`), whose peaks
  must lie inside its window: an edge is found up to about half a pixel less far than
  ``reach_px``, and a side further off counts ``reach_px``.

In a frame :meth:`rovis.pipeline.Detector.track` follows, the quality is measured the same
way, and the error from the sides the tracker refit (:func:`rovis.track.follow`).

Neither is a probability. Measured on the synthetic sets (docs/stereo.md, "How well a book
agrees with the images"), books found beyond the grasp tolerance and false positives have
the lower quality and the larger offset more often than books within it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rovis.segment.boundary import Fit, side_evidence
from rovis.segment.edges import Gradients
from rovis.segment.lines import refine_segment


@dataclass(frozen=True)
class AgreementConfig:
    """How a book found is checked against the images at the end of a frame.

    Attributes
    ----------
    evidence : float
        The derivative across a side that counts as a step, as a share of the image's
        Canny low threshold (:meth:`rovis.pipeline.Detector._edge_strength`): what
        ``quality`` counts (0.5, as ``track.evidence``'s default; the two are set apart).
    reach_px : float
        Pixels: how far from a projected side its edge is looked for, and what a side
        without one counts in ``reprojection_error_px``.
    """

    evidence: float = 0.5
    reach_px: float = 3.0

    def __post_init__(self) -> None:
        if not (self.evidence > 0 and self.reach_px > 0):
            raise ValueError(f"agreement: evidence and reach_px must be positive, got {self}")


def side_offsets(quad: NDArray[np.float64], lines: Sequence[Fit | None]) -> NDArray[np.float64]:
    """Per side of a quad, the root mean square distance along it to a line.

    The distance to a line changes linearly along a segment, from d_a at one end to d_b at
    the other; its mean square over the segment is (d_a² + d_a·d_b + d_b²) / 3.

    Parameters
    ----------
    quad : ndarray, shape (4, 2)
        Corners, pixels; side s runs from corner s to corner s + 1.
    lines : sequence of 4 (point, unit direction) or None
        The line each side is measured against, pixels.

    Returns
    -------
    ndarray, shape (4,)
        Pixels; NaN where the line is None.
    """
    out = np.full(4, np.nan)
    for s, line in enumerate(lines):
        if line is None:
            continue
        p, d = line
        n = np.array([-d[1], d[0]])
        da, db = (quad[s] - p) @ n, (quad[(s + 1) % 4] - p) @ n
        out[s] = np.sqrt((da * da + da * db + db * db) / 3.0)
    return out


def edge_offsets(grad: Gradients, quad: NDArray[np.float64], *,
                 reach_px: float = 3.0) -> NDArray[np.float64]:
    """Per side of a quad, how far the edge the image shows along it lies from it.

    Parameters
    ----------
    grad : Gradients
        The image's gradients.
    quad : ndarray, shape (4, 2)
        Corners, pixels (the image's ideal frame); side s from corner s to corner s + 1.
    reach_px : float
        How far from each side its edge is fitted
        (:func:`rovis.segment.lines.refine_segment`'s ``half_width``).

    Returns
    -------
    ndarray, shape (4,)
        :func:`side_offsets` to each side's fitted edge, pixels; NaN where too few edge
        points lie within reach. A side tilted against its edge may read more than
        ``reach_px``.
    """
    lines = [refine_segment(grad, quad[s], quad[(s + 1) % 4], half_width=reach_px)
             for s in range(4)]
    return side_offsets(quad, lines)


def edge_quality(grads: dict[str, Gradients], quads: dict[str, NDArray[np.float64]],
                 thresholds: dict[str, float]) -> tuple[float, dict[str, NDArray[np.float64]]]:
    """A book's ``quality``: the mean edge support of its four sides, in the worse image.

    Parameters are :func:`agreement`'s. Returns the quality, in [0, 1], and per camera each
    side's edge support (4,) (:func:`rovis.segment.boundary.side_evidence`).
    """
    support = {cam: side_evidence(grads[cam], quads[cam], thresholds[cam]) for cam in quads}
    return float(min(s.mean() for s in support.values())), support


def agreement(grads: dict[str, Gradients], quads: dict[str, NDArray[np.float64]],
              thresholds: dict[str, float], *, reach_px: float = 3.0,
              ) -> tuple[float, float, dict[str, NDArray[np.float64]]]:
    """A book's ``quality`` and ``reprojection_error_px`` (see the module's docstring).

    Parameters
    ----------
    grads : dict of Gradients
        Per camera (``"left"``, ``"right"``), the image's gradients.
    quads : dict of ndarray, shape (4, 2)
        Per camera, the cover as projected from its world corners (ideal pixels).
    thresholds : dict of float
        Per camera, the derivative across a side that counts as a step (the Sobel scale).
    reach_px : float
        How far from a side its edge is looked for; a side without one counts this much.

    Returns
    -------
    quality : float
        The mean edge support of the four sides, in the worse image; in [0, 1].
    error_px : float
        The root mean square edge offset over the eight sides, in [0, ``reach_px``].
    support : dict of ndarray, shape (4,)
        Per camera, each side's edge support.
    """
    quality, support = edge_quality(grads, quads, thresholds)
    offsets = np.concatenate([edge_offsets(grads[cam], quads[cam], reach_px=reach_px)
                              for cam in quads])
    offsets = np.minimum(np.nan_to_num(offsets, nan=reach_px), reach_px)
    return quality, float(np.sqrt(np.mean(offsets ** 2))), support
