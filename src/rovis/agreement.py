"""How well each book found agrees with the images: the output's ``quality`` and
``reprojection_error_px`` (beyond the paper).

The steps after the segmentation move a cover's sides (:mod:`rovis.extent`, the trims, the
grows), and most books leave the pipeline as a 3D rectangle whose corners in each image are
its projections. The corners' own reprojection error is then about 0 whatever the images
show. So the book as reported is checked against both images once more, at the end:

- **edge support** (:func:`rovis.segment.boundary.side_evidence`): per side, the share of
  its length that shows a step across it; a book's ``quality`` is the mean over its four
  sides, in the worse of the two images;
- **edge offset** (:func:`edge_offsets`): per side, the root mean square distance along it
  between the side as projected and the edge the image shows within ``reach_px`` of it;
  a book's ``reprojection_error_px`` is the root mean square over its eight sides (four per
  image), a side with no edge there counting ``reach_px``.

Neither is a probability. Measured on the synthetic sets (docs/stereo.md, "How well a book
agrees with the images"), books found beyond the grasp tolerance and false positives have
the lower quality and the larger offset more often than books within it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rovis.segment.boundary import side_evidence
from rovis.segment.edges import Gradients
from rovis.segment.lines import refine_segment

Line = tuple[NDArray[np.float64], NDArray[np.float64]]  # a point and a unit direction


@dataclass(frozen=True)
class AgreementConfig:
    """How a book found is checked against the images at the end of a frame.

    Attributes
    ----------
    evidence : float
        The derivative across a side that counts as a step, as a share of the image's
        Canny low threshold (:meth:`rovis.pipeline.Detector._edge_strength`): what
        ``quality`` counts (the tracker's ``track.evidence`` by default).
    reach_px : float
        Pixels: how far from a projected side its edge is looked for, and what a side
        without one counts in ``reprojection_error_px``.
    """

    evidence: float = 0.5
    reach_px: float = 3.0

    def __post_init__(self) -> None:
        if not (self.evidence > 0 and self.reach_px > 0):
            raise ValueError(f"agreement: evidence and reach_px must be positive, got {self}")


def side_offsets(quad: NDArray[np.float64], lines: Sequence[Line | None]) -> NDArray[np.float64]:
    """Per side of ``quad`` (4, 2), pixels: the root mean square distance along it to
    ``lines[s]`` (side s runs from corner s to corner s + 1), NaN where that is None.

    The distance to a line changes linearly along a segment, from d_a at one end to d_b at
    the other; its mean square over the segment is (d_a² + d_a·d_b + d_b²) / 3.
    """
    out = np.full(4, np.nan)
    for s, line in enumerate(lines):
        if line is None:
            continue
        p, d = line
        n = np.array([-d[1], d[0]])
        da, db = (quad[s] - p) @ n, (quad[(s + 1) % 4] - p) @ n
        out[s] = np.sqrt(max(da * da + da * db + db * db, 0.0) / 3.0)
    return out


def edge_offsets(grad: Gradients, quad: NDArray[np.float64], *,
                 reach_px: float = 3.0) -> NDArray[np.float64]:
    """Per side of ``quad`` (4, 2), pixels: how far the edge the image shows along it lies
    from it (:func:`side_offsets`), the edge fitted within ``reach_px`` of the side
    (:func:`rovis.segment.lines.refine_segment`); NaN where too few edge points lie there."""
    lines = [refine_segment(grad, quad[s], quad[(s + 1) % 4], half_width=reach_px)
             for s in range(4)]
    return side_offsets(quad, lines)


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
    support = {cam: side_evidence(grads[cam], quads[cam], thresholds[cam]) for cam in quads}
    offsets = np.concatenate([edge_offsets(grads[cam], quads[cam], reach_px=reach_px)
                              for cam in quads])
    offsets = np.minimum(np.nan_to_num(offsets, nan=reach_px), reach_px)
    quality = float(min(s.mean() for s in support.values()))
    return quality, float(np.sqrt(np.mean(offsets ** 2))), support
