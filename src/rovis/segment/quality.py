"""The segmentation quality measure y of eq. 2 (paper §3.B)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

# The paper prints e^{+N/N_max}, which grows with the number of lines N; its text says the
# term should favour solutions with few lines, i.e. e^{-N/N_max}. Both are available
# (`sign`); docs/segmentation.md reports which detects better and why it is the default.
PRINTED = +1
AS_DESCRIBED = -1


def quality(n_lines: int, n_f: ArrayLike, roi_area: float, n_max: int, *,
            sign: int = AS_DESCRIBED) -> float:
    """Eq. 2: ``y = e^{±N/N_max} · Σ_n N_f(n) / A_ROI`` if ``N ≤ N_max``, else 0.

    Parameters
    ----------
    n_lines : int
        N, the number of Hough lines above T_HG.
    n_f : array_like, shape (N_#,)
        Edge pixels covered by the lines of each candidate object.
    roi_area : float
        A_ROI, pixels.
    n_max : int
        N_max, the most lines allowed.
    sign : {+1, -1}
        +1 as printed, -1 as the text describes.
    """
    if sign not in (PRINTED, AS_DESCRIBED):
        raise ValueError(f"sign: expected +1 or -1, got {sign!r}")
    if n_lines > n_max or roi_area <= 0:
        return 0.0
    return float(np.exp(sign * n_lines / n_max) * np.sum(n_f) / roi_area)
