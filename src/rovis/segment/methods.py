"""Segmentation methods selectable by name: the paper's closed loop and the baselines.

Every method ends in the same downstream chain (cover selection, sub-pixel refinement,
eq. 1 corner order, and for stereo its candidates and those with sides unseen:
:attr:`Segmentation.pool`, :attr:`Segmentation.open_pool`), so their results differ only
by how edges and lines are found:

- ``closed``: the cascade controller of §3.B (eq. 2);
- ``open``: fixed T_H, T_HG (tuned once at 500 lx);
- ``auto-median``: T_L, T_H = 0.67, 1.33 × the median intensity of the ROI;
- ``auto-otsu``: T_H = Otsu's threshold of the ROI, T_L = 0.5·T_H;
- ``lsd``: OpenCV's line segment detector instead of Canny + Hough;
- ``contour``: Canny → findContours → approxPolyDP quadrilaterals.
"""

from __future__ import annotations

import time
from dataclasses import replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis.segment.boundary import (Evaluation, SegmentConfig, Segmentation, candidate_pool,
                                    evaluate, finish, roi_area)
from rovis.segment.control import (CascadeController, small_candidates,
                                   with_open_candidates)
from rovis.segment.edges import Gradients, canny, linear_gradients
from rovis.segment.lines import Lines, suppress_duplicates, support_profile
from rovis.segment.quads import CoverSelection, Quads, candidate_quads

METHODS = ("closed", "open", "auto-median", "auto-otsu", "lsd", "contour")


def segment(gray: NDArray[np.uint8], grad: Gradients, method: str = "closed", *,
            controller: CascadeController | None = None,
            cfg: SegmentConfig | None = None,
            timing: dict[str, float] | None = None) -> Segmentation:
    """Find book covers in one image with the named method.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        The image (the intensity-based baselines and LSD read it).
    grad : Gradients
        Its gradients and ROI, from :func:`rovis.segment.gradients`.
    method : str
        One of :data:`METHODS`.
    controller : CascadeController, optional
        For ``closed``: a controller that keeps its optimum across a sequence.
    timing : dict, optional
        Accumulates milliseconds per step of the chain (Canny, Hough, quads, refine; see
        :func:`rovis.segment.boundary.evaluate`).
    """
    cfg = cfg or (controller.cfg if controller is not None else SegmentConfig())
    # sub-pixel sides on linear intensities (SegmentConfig.refine_gamma)
    clock = time.perf_counter()
    refine = (None if cfg.refine_gamma == 1.0
              else linear_gradients(gray, grad.mask, gamma=cfg.refine_gamma))
    if refine is not None and grad.seen is not None:
        # beyond the field of view (Gradients.seen) no edge to refine onto, as on ``grad``
        for g in (refine.dx, refine.dy):
            g[grad.seen == 0] = 0
        refine = replace(refine, seen=grad.seen)
    if timing is not None:
        timing["refine"] = timing.get("refine", 0.0) + 1e3 * (time.perf_counter() - clock)
    if method == "closed":
        more = ()
        if cfg.lsd:  # beyond the paper: a second line source's covers (SegmentConfig.lsd)
            clock = time.perf_counter()
            # its covers only: the loop's own evaluations fill the pool and the open one
            more = (replace(_lsd(gray, grad, cfg), selection=None, all_lines=None, profile=None),)
            if timing is not None:
                timing["lsd"] = timing.get("lsd", 0.0) + 1e3 * (time.perf_counter() - clock)
        return (controller or CascadeController(cfg, warm_start=False)).segment(
            grad, timing=timing, more=more, refine=refine)
    if method == "open":
        return _finish_one(grad, evaluate(grad, cfg.open_T_H, cfg, T_HG=cfg.open_T_HG,
                                          timing=timing), cfg, timing=timing, refine=refine)
    if method in ("auto-median", "auto-otsu"):
        pixels = gray[grad.mask > 0] if grad.mask is not None else gray.ravel()
        if pixels.size == 0:
            return Segmentation.empty()
        if method == "auto-median":
            v = float(np.median(pixels))
            T_L, T_H = 0.67 * v, 1.33 * v
        else:
            T_H = float(cv2.threshold(pixels.reshape(1, -1), 0, 255,
                                      cv2.THRESH_BINARY | cv2.THRESH_OTSU)[0])
            T_L = 0.5 * T_H
        T_H = max(T_H, 1.0)
        return _finish_one(grad, evaluate(grad, T_H, cfg, T_HG=cfg.open_T_HG, T_L=T_L,
                                          timing=timing), cfg, timing=timing, refine=refine)
    if method == "lsd":
        return _finish_one(grad, _lsd(gray, grad, cfg), cfg, timing=timing, refine=refine)
    if method == "contour":
        return _finish_one(grad, _contours(grad, cfg), cfg, timing=timing, refine=refine)
    raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")


def _finish_one(grad: Gradients, ev: Evaluation, cfg: SegmentConfig, *,
                timing: dict[str, float] | None, refine: Gradients | None) -> Segmentation:
    """A one-evaluation method's segmentation, with the candidates the closed loop adds
    for stereo from its evaluations (``SegmentConfig.three_sided``, ``two_sided``:
    :func:`rovis.segment.control.with_open_candidates`), from this one: every method
    ends in the same downstream chain."""
    full = candidate_pool([ev.selection.quads] if ev.selection is not None else [],
                          cfg.pool_size)
    open_pool, alternatives = None, ()
    small_open: list[Quads] = []
    if cfg.three_sided:
        ev, alternatives, open_pool = with_open_candidates(
            grad, ev, alternatives, [ev], full, cfg, area=roi_area(grad), timing=timing,
            smalls=small_open)
    four_sided = [ev.small] if ev.small is not None and len(ev.small) else []
    return finish(grad, ev, 1, timing=timing, alternatives=alternatives, pool=full,
                  refine=refine, open_pool=open_pool,
                  small_pool=small_candidates(four_sided, small_open, cfg))


_LSD = None


def _lsd(gray: NDArray[np.uint8], grad: Gradients, cfg: SegmentConfig) -> Evaluation:
    """Line segments from LSD, merged into lines (votes = segment length), then quads."""
    global _LSD
    if _LSD is None:  # created once per process
        _LSD = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD)
    area = roi_area(grad)
    segs = _LSD.detect(gray)[0]
    if segs is None:
        return Evaluation(0.0, 0, 0.0, Lines.empty(), Quads.empty(), 1)
    segs = segs.reshape(-1, 4).astype(np.float64)
    if grad.mask is not None:  # keep segments whose midpoint is in the ROI
        mid = np.rint(0.5 * (segs[:, :2] + segs[:, 2:])).astype(int)
        h, w = grad.shape
        ok = (mid[:, 0] >= 0) & (mid[:, 0] < w) & (mid[:, 1] >= 0) & (mid[:, 1] < h)
        ok[ok] = grad.mask[mid[ok, 1], mid[ok, 0]] > 0
        segs = segs[ok]
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    segs, length = segs[length >= cfg.quads.min_side_px / 3], length[length >= cfg.quads.min_side_px / 3]
    if len(segs) == 0:
        return Evaluation(0.0, 0, 0.0, Lines.empty(), Quads.empty(), 1)
    # Normal form of each segment's line, θ in [0, π).
    theta = np.arctan2(segs[:, 2] - segs[:, 0], -(segs[:, 3] - segs[:, 1])) % np.pi
    rho = segs[:, 0] * np.cos(theta) + segs[:, 1] * np.sin(theta)
    order = np.argsort(-length)
    rho, theta, length = rho[order], theta[order], length[order]
    keep = suppress_duplicates(rho, theta, 3.0, np.radians(1.5), cfg.n_max)
    lines = Lines(rho[keep], theta[keep], np.rint(length[keep]).astype(np.int64))
    drawn = np.zeros(grad.shape, np.uint8)  # the segments are LSD's "edge pixels"
    for x1, y1, x2, y2 in segs[order]:
        cv2.line(drawn, (int(round(x1)), int(round(y1))), (int(round(x2)), int(round(y2))), 255, 1)
    profile = support_profile(lines, drawn, seen=grad.seen)
    selection = CoverSelection(candidate_quads(lines, profile, grad.shape, area, cfg.quads),
                               cfg.quads)
    return Evaluation(0.0, 0, 0.0, lines, selection.at(0), 1, selection=selection,
                      all_lines=lines, profile=profile)


def _contours(grad: Gradients, cfg: SegmentConfig) -> Evaluation:
    """Quadrilaterals approximating Canny contours (no Hough lines)."""
    edges = canny(grad, cfg.open_T_H)
    contours, _ = cv2.findContours(edges, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    area = roi_area(grad)
    found = []
    for c in contours:
        peri = cv2.arcLength(c, True)
        if peri < 4 * cfg.quads.min_side_px:
            continue
        approx = cv2.approxPolyDP(c, 0.02 * peri, True).reshape(-1, 2)
        a = cv2.contourArea(approx.astype(np.float32))
        if (len(approx) == 4 and cv2.isContourConvex(approx)
                and cfg.quads.min_area_px <= a <= cfg.quads.max_area_frac * area):
            found.append((approx.astype(np.float64), peri))
    if not found:
        return Evaluation(cfg.open_T_H, 0, 0.0, Lines.empty(), Quads.empty(), 1)
    corners = np.array([f[0] for f in found])
    quads = Quads(np.tile(np.arange(4), (len(found), 1)) + 4 * np.arange(len(found))[:, None],
                  corners, np.ones((len(found), 4)), np.array([f[1] for f in found]),
                  np.zeros(len(found), np.int64))
    selection = CoverSelection(quads, cfg.quads)
    return Evaluation(cfg.open_T_H, 0, 0.0, Lines.empty(), selection.at(0), 1, selection=selection)
