"""Line stage (paper §3.A): standard Hough lines with votes, edge support, sub-pixel refit.

A line is ``x·cos θ + y·sin θ = ρ`` (OpenCV's Hough form), θ in [0, π). Its foot point is
``ρ·n`` with ``n = (cos θ, sin θ)``; positions along it are ``t`` in the direction
``d = (−sin θ, cos θ)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis.segment.edges import Gradients

RHO_STEP = 1.0  # px
THETA_STEP = np.pi / 180  # 1°


@dataclass(frozen=True, eq=False)
class Lines:
    """Hough lines sorted by votes, strongest first.

    Attributes
    ----------
    rho : ndarray, shape (N,), float64 — pixels
    theta : ndarray, shape (N,), float64 — radians in [0, π)
    votes : ndarray, shape (N,), int64 — accumulator count (edge pixels on the line)
    """

    rho: NDArray[np.float64]
    theta: NDArray[np.float64]
    votes: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.rho)

    @classmethod
    def empty(cls) -> Lines:
        return cls(np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64))

    def take(self, index: NDArray[np.intp] | slice) -> Lines:
        return Lines(self.rho[index], self.theta[index], self.votes[index])

    def shifted(self, offset: NDArray[np.float64]) -> Lines:
        """The same lines in a pixel frame moved by ``offset`` (2,): ``p' = p + offset``
        (ρ may then be negative; θ stays in [0, π))."""
        if len(self) == 0 or not np.any(offset):
            return self
        return Lines(self.rho + self.normals @ np.asarray(offset, dtype=np.float64), self.theta,
                     self.votes)

    @property
    def normals(self) -> NDArray[np.float64]:
        """Unit normals (N, 2)."""
        return np.column_stack([np.cos(self.theta), np.sin(self.theta)])

    @property
    def directions(self) -> NDArray[np.float64]:
        """Unit directions (N, 2)."""
        return np.column_stack([-np.sin(self.theta), np.cos(self.theta)])


def hough_lines(edges: NDArray[np.uint8], min_votes: int, *, grad: Gradients | None = None,
                max_lines: int | None = None, box: tuple[int, int, int, int] | None = None,
                bins: int = 8, margin: float = np.radians(12.0), rho_tol: float = 3.0,
                theta_tol: float = np.radians(1.5)) -> Lines:
    """Standard Hough transform, keeping every line with at least ``min_votes`` votes.

    One call serves every T_HG ≥ ``min_votes`` of the controller's inner loop: a threshold
    is a cut on ``votes``. Near-duplicates (the same edge in neighbouring accumulator cells)
    are merged into the strongest, within ``rho_tol`` px and ``theta_tol`` rad; with
    ``max_lines`` only that many distinct lines are kept (the strongest).

    With ``grad``, an edge pixel votes only for lines its gradient is normal to (within
    ``margin``): the θ range is split into ``bins`` and each is transformed with the edge
    pixels of matching orientation. Printed text or a graphic is a dense blob of edges that
    would otherwise give every line through it as many votes as a book's side; gated, it
    votes only along its own edges. ``box`` ``(x0, y0, x1, y1)`` restricts the transform to
    the ROI's bounding box: the accumulator, whose size sets Hough's fixed cost, shrinks.
    """
    x0, y0, x1, y1 = box if box is not None else (0, 0, edges.shape[1], edges.shape[0])
    crop = edges[y0:y1, x0:x1]
    if crop.size == 0 or not crop.any():
        return Lines.empty()
    threshold = max(int(min_votes), 1)
    if grad is None:
        found = [cv2.HoughLinesWithAccumulator(crop, RHO_STEP, THETA_STEP, threshold)]
    else:
        # The edge pixels, row by row as np.nonzero gives them (cv2.findNonZero: ~4x faster),
        # as flat indices into the full image and into the crop.
        xy = cv2.findNonZero(crop).reshape(-1, 2).astype(np.intp)
        at = (xy[:, 1] + y0) * grad.shape[1] + (xy[:, 0] + x0)
        in_crop = xy[:, 1] * crop.shape[1] + xy[:, 0]
        phi = np.arctan2(grad.dy.ravel()[at].astype(np.float32),
                         grad.dx.ravel()[at].astype(np.float32))
        # phi % π without np.remainder (~6x slower): over arctan2's [-π, π] it is phi,
        # phi + π or phi - π; the same float32 values, checked for every float32 there (but
        # -0.0 stays -0.0 where % gives +0.0: the same x below, where a centre is subtracted)
        phi = np.where(phi < 0, phi + np.pi, np.where(phi >= np.pi, phi - np.pi, phi))
        found = []
        width = np.pi / bins
        lo = [b * width for b in range(bins)]
        hi = [(b + 1) * width for b in range(bins)]
        # distance of each pixel's normal angle to each bin, on the circle of lines (mod π);
        # all bins in one (bins, pixels) pass. The bin centres as float32: the values a
        # Python float centre takes in float32 arithmetic (NEP 50), so each row is what a
        # pass per bin gave, bit for bit.
        centre = np.array([0.5 * (a + b) for a, b in zip(lo, hi)], dtype=np.float32)
        x = phi[None, :] - centre[:, None] + np.pi / 2  # float32, in (-π, 2π)
        # x % π without np.remainder (the slowest step here): over that range it is
        # x, x + π or x - π; the same float32 values, checked for every float32 in
        # [-π, 2π] (off is bit-identical)
        x = np.where(x < 0, x + np.pi, np.where(x >= np.pi, x - np.pi, x))
        off = np.abs(x - np.pi / 2)
        sel = off <= 0.5 * width + margin
        part = np.zeros(crop.shape, np.uint8)  # one bin's edge pixels at a time
        flat = part.ravel()
        for b in range(bins):
            pixels = in_crop[sel[b]]
            if len(pixels) <= threshold:  # OpenCV keeps cells of more votes than threshold,
                continue  # and a pixel votes once per angle: no line (3% of the bins here)
            flat[pixels] = 255
            found.append(cv2.HoughLinesWithAccumulator(part, RHO_STEP, THETA_STEP, threshold,
                                                       min_theta=lo[b], max_theta=hi[b]))
            flat[pixels] = 0
    found = [f.reshape(-1, 3) for f in found if f is not None and len(f)]
    if not found:
        return Lines.empty()
    rows = np.vstack(found).astype(np.float64)
    order = np.argsort(-rows[:, 2], kind="stable")
    if max_lines is not None:  # gated Hough gives few duplicates per distinct line
        order = order[:3 * max_lines + 32]
    rho, theta, votes = rows[order, 0], rows[order, 1], rows[order, 2].astype(np.int64)
    rho = rho + x0 * np.cos(theta) + y0 * np.sin(theta)  # back to full-image coordinates
    keep = suppress_duplicates(rho, theta, rho_tol, theta_tol, max_lines)
    return Lines(rho[keep], theta[keep], votes[keep])


def suppress_duplicates(rho: NDArray[np.float64], theta: NDArray[np.float64], rho_tol: float,
                         theta_tol: float, max_lines: int | None) -> NDArray[np.intp]:
    """Indices of lines not within tolerance of a stronger kept line (input sorted by votes).

    Kept lines are hashed on a (ρ, θ) grid of the tolerances, so each candidate is compared
    with the kept lines of its neighbouring cells only. (ρ, θ) and (−ρ, θ ± π) are one line:
    a kept line near that seam is also stored in its mirrored form.
    """
    grid: dict[tuple[int, int], list[tuple[float, float]]] = {}
    kept: list[int] = []
    # Python floats and math.floor: NumPy scalars and ufuncs on them cost ~1 us a call,
    # most of this loop's time (the values and cells are the same)
    rhos = np.asarray(rho, dtype=np.float64).tolist()
    thetas = np.asarray(theta, dtype=np.float64).tolist()
    for i, (r, t) in enumerate(zip(rhos, thetas)):
        if max_lines is not None and len(kept) >= max_lines:
            break
        ri, ti = math.floor(r / rho_tol), math.floor(t / theta_tol)
        # the kept lines in its cell and the eight around it (plain loops: a generator
        # over them took half as long again)
        near = False
        for cell in ((ri - 1, ti - 1), (ri - 1, ti), (ri - 1, ti + 1), (ri, ti - 1), (ri, ti),
                     (ri, ti + 1), (ri + 1, ti - 1), (ri + 1, ti), (ri + 1, ti + 1)):
            for rk, tk in grid.get(cell, ()):
                if abs(tk - t) < theta_tol and abs(rk - r) < rho_tol:
                    near = True
                    break
            if near:
                break
        if near:
            continue
        kept.append(i)
        forms = [(r, t)]
        if t < theta_tol:
            forms.append((-r, t + np.pi))
        if t > np.pi - theta_tol:
            forms.append((-r, t - np.pi))
        for rf, tf in forms:
            grid.setdefault((math.floor(rf / rho_tol), math.floor(tf / theta_tol)), []).append((rf, tf))
    return np.asarray(kept, dtype=np.intp)


@dataclass(frozen=True, eq=False)
class SupportProfile:
    """Edge hits sampled every pixel along each line, as cumulative sums.

    Line ``i`` is sampled at positions ``t0[i] + k``; ``cum[i, k]`` counts the hits before
    sample ``k``. The support of a segment ``[ta, tb]`` is a difference of two entries, so
    any quad side costs O(1).
    """

    cum: NDArray[np.int32]  # (N, L + 1)
    t0: NDArray[np.float64]  # (N,)
    t_in: NDArray[np.float64] | None = None  # (N, 2): where each line is inside the image
    _gaps: dict[int, tuple[NDArray[np.intp], NDArray[np.intp]]] = field(
        default_factory=dict, init=False, repr=False)  # gaps(), by gap length

    def gaps(self, g: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Where the gaps of ``g`` samples with no hit start, and where they end, on every
        line: sorted flat indices ``line·L + m``, the starts closed by ``N·L`` and the ends
        opened by −1. Found once per ``g``: the three- and two-sided candidates of one
        profile both follow runs to their gaps (:func:`rovis.segment.quads._run_end`)."""
        if g not in self._gaps:
            cum = self.cum
            n_lines, n_samples = cum.shape[0], cum.shape[1] - 1
            # a gap starts at m when samples m .. m+g-1 hold no hit (beyond the samples: none)
            ahead = window_hits(cum, 0, g)
            # a gap ends at m when samples m-g+1 .. m hold no hit
            behind = window_hits(cum, 1 - g, 1)
            self._gaps[g] = (np.append(np.flatnonzero(ahead == 0), n_lines * n_samples),
                             np.concatenate([[-1], np.flatnonzero(behind == 0)]))
        return self._gaps[g]

    def visible(self, line: NDArray[np.intp], ta: NDArray[np.float64],
                tb: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The part ``[lo, hi]`` of each segment inside the image (``hi < lo`` if none)."""
        lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
        if self.t_in is None:
            return lo, hi
        return np.maximum(lo, self.t_in[line, 0]), np.minimum(hi, self.t_in[line, 1])

    def hits(self, line: NDArray[np.intp], ta: NDArray[np.float64],
             tb: NDArray[np.float64]) -> NDArray[np.float64]:
        """Edge hits between positions ``ta`` and ``tb`` (any order) on ``line`` (vectorised)."""
        last = self.cum.shape[1] - 1
        t0 = self.t0[line]
        lo = np.rint(np.minimum(ta, tb) - t0).astype(np.intp)
        hi = np.rint(np.maximum(ta, tb) - t0).astype(np.intp)
        # flat indices into cum: cheaper than 2-D fancy indexing and np.clip's wrapper
        row = line * self.cum.shape[1]
        flat = self.cum.ravel()
        return (flat[row + np.minimum(np.maximum(hi, 0), last)]
                - flat[row + np.minimum(np.maximum(lo, 0), last)]).astype(np.float64)


def window_hits(cum: NDArray[np.int32], a: int, b: int) -> NDArray[np.int32]:
    """The hits in samples ``m + a`` to ``m + b - 1`` (``a <= b``; those beyond the samples
    count none) for every sample ``m`` of every line, from a profile's cumulative sums
    ``cum`` (N, L + 1): shape (N, L), ``cum[:, clip(m + b)] - cum[:, clip(m + a)]``
    with the indices clipped to [0, L]. Slices of ``cum`` padded with its first and last
    columns: a third of the time of gathering the clipped columns."""
    n_samples = cum.shape[1] - 1
    left, right = max(-a, 0), max(b - 1, 0)
    padded = np.concatenate([np.repeat(cum[:, :1], left, axis=1), cum,
                             np.repeat(cum[:, -1:], right, axis=1)], axis=1)
    return padded[:, left + b:left + b + n_samples] - padded[:, left + a:left + a + n_samples]


def support_profile(lines: Lines, edges: NDArray[np.uint8], grad: Gradients | None = None, *,
                    box: tuple[int, int, int, int] | None = None,
                    max_angle_deg: float = 25.0, near: NDArray[np.uint8] | None = None,
                    seen: NDArray[np.uint8] | None = None) -> SupportProfile:
    """Sample edges along every line where it crosses ``box`` (default: the image).

    A sample is a hit when an edge pixel lies within 1 px (3×3 dilation) and, given
    ``grad``, the image gradient there points across the line (within ``max_angle_deg``):
    the alignment test keeps dense texture or noise from supporting arbitrary lines.
    Samples where ``seen`` (default: ``grad.seen``) is 0 are out of view, as beyond the
    image (:attr:`SupportProfile.t_in`); ``near``: the edges' 3×3 dilation, if done already.
    """
    h, w = edges.shape
    x0, y0, x1, y1 = box if box is not None else (0, 0, w, h)
    centre = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    half = 0.5 * float(np.hypot(x1 - x0, y1 - y0)) + 2.0
    t = np.arange(-half, half + 1.0)
    if len(lines) == 0:
        return SupportProfile(np.zeros((0, len(t) + 1), dtype=np.int32), np.zeros(0))
    if near is None:  # (``near``: this dilation, done already)
        near = cv2.dilate(edges, np.ones((3, 3), np.uint8))  # an edge within 1 px counts
    n, d = lines.normals, lines.directions
    t_c = d @ centre  # position of the box centre's projection on each line
    along = t_c[:, None] + t[None, :]  # each sample's position on its line (N, L)
    # rho·n + along·d per coordinate, the sum formed in place (b + a: the same values)
    x = along * d[:, :1]
    x += lines.rho[:, None] * n[:, :1]
    y = np.multiply(along, d[:, 1:], out=along)  # (along is not needed after this)
    y += lines.rho[:, None] * n[:, 1:]
    # in place where the (N, L) temporaries allow: the same values, fewer passes
    xi, yi = np.rint(x, out=x).astype(np.intp), np.rint(y, out=y).astype(np.intp)
    # 0 <= v < size as one unsigned comparison (a negative v wraps to a huge one)
    inside = (xi.view(np.uintp) < w) & (yi.view(np.uintp) < h)
    # Flat pixel index of every sample (0 outside the image, masked by ``inside``): one
    # gather for all lines instead of compressing the samples first.
    at = yi
    at *= w
    at += xi
    at *= inside
    if seen is None and grad is not None:
        seen = grad.seen
    if seen is not None:  # beyond the raw field of view: out of view
        inside &= seen.ravel()[at] > 0
    # (``at`` of a sample out of view is a pixel of the image still: read, then masked)
    hit = near.ravel()[at] > 0
    hit &= inside
    if grad is not None:
        # The alignment test only where there is an edge to align (a few % of the samples).
        k = np.flatnonzero(hit)
        rows, px = k // hit.shape[1], at.ravel()[k]
        gx, gy = grad.dx.ravel()[px].astype(np.float64), grad.dy.ravel()[px].astype(np.float64)
        # (1-D gathers of each normal's x and y: cheaper than n[rows, 0], the same values)
        across = np.abs(gx * n[:, 0].take(rows) + gy * n[:, 1].take(rows))
        hit.ravel()[k] = across >= np.cos(np.radians(max_angle_deg)) * np.hypot(gx, gy)
    cum = np.zeros((len(lines), len(t) + 1), dtype=np.int32)
    np.cumsum(hit, axis=1, out=cum[:, 1:])
    any_in = inside.any(axis=1)
    first = np.where(any_in, np.argmax(inside, axis=1), len(t))
    last = np.where(any_in, len(t) - 1 - np.argmax(inside[:, ::-1], axis=1), -1)
    t_in = np.column_stack([t_c - half + first, t_c - half + last])
    return SupportProfile(cum, t_c - half, t_in)


def refine_lines(lines: Lines, edges: NDArray[np.uint8], profile: SupportProfile,
                 grad: Gradients | None = None, *, box: tuple[int, int, int, int] | None = None,
                 passes: int = 2, min_span_px: float = 250.0, max_turn_deg: float = 0.6,
                 max_scatter_px: float = 0.5,
                 near: NDArray[np.uint8] | None = None) -> tuple[Lines, SupportProfile]:
    """Beyond the paper: each long line fitted to the edge pixels it is supported by.

    Hough's 1° cells leave a line up to 0.5° off its edge: 1 px off at 115 px from where
    they cross, so a long side (a sheet of paper, a large book close to the camera) has
    edge support near one of its ends only, and its corner there has no arm on the line
    (:func:`rovis.segment.quads._arm`). For every sample of ``profile`` with a hit, the
    edge pixel's offset across the line (−1, 0 or +1 px, the nearest with an edge) is
    read, and offset = a + b·t is fitted by least squares over the line's hits; the line
    is moved by that (by at most a pixel where its hits are, as their offsets are; a turn
    of at most ``max_turn_deg`` — Hough's cells are 1 px and 1° —, for hits spread over at least
    ``min_span_px`` and scattered by at most ``max_scatter_px`` (RMS) about the fit; a
    line with hits over less than ~230 px is within a pixel of its edge wherever it has
    them, and stays as it is: with 150 px, Table II dev-set books 194 → 189).
    The hits seen from a tilted line cover the part of the edge near it only, so the fit
    is repeated (``passes``) on the moved lines' new hits. Lines made equal by the fit
    (two Hough cells of one edge) are merged into the strongest.

    Parameters
    ----------
    lines : Lines
    edges : ndarray, shape (H, W), uint8
        The edge map ``profile`` was sampled from.
    profile : SupportProfile
        :func:`support_profile` of ``lines`` on ``edges`` (with ``grad`` and ``box``).
    grad, box
        As given to :func:`support_profile`: the moved lines are sampled again so.
    near : ndarray, shape (H, W), uint8, optional
        The edges' 3×3 dilation, if done already (as for :func:`support_profile`).

    Returns
    -------
    (Lines, SupportProfile)
        The lines, strongest first as given (votes unchanged: T_HG still cuts on Hough's
        votes), and their profile (the moved lines' rows sampled again).
    """
    if len(lines) == 0:
        return lines, profile
    rho, theta = lines.rho.copy(), lines.theta.copy()
    cum, t0 = profile.cum, profile.t0
    t_in = profile.t_in
    # the hits' extent along each line, from the cumulative sums: first and last hit
    total = cum[:, -1]
    first = np.argmax(cum > 0, axis=1)
    last = np.argmax(cum >= total[:, None], axis=1)
    # (and hits along half that at least: a line through texture has scattered hits only)
    todo = np.flatnonzero((total >= 0.5 * min_span_px) & (last - first >= min_span_px))
    copied = False
    for _ in range(passes):
        if len(todo) == 0:
            break
        part = Lines(rho[todo], theta[todo], lines.votes[todo])
        prof = SupportProfile(cum[todo], t0[todo], None if t_in is None else t_in[todo])
        new_rho, new_theta, moved = _fit_to_hits(part, edges, prof, min_span_px=min_span_px,
                                                 max_turn_deg=max_turn_deg,
                                                 max_scatter_px=max_scatter_px)
        todo = todo[moved]
        if len(todo) == 0:
            break
        rho[todo], theta[todo] = new_rho[moved], new_theta[moved]
        if near is None:
            near = cv2.dilate(edges, np.ones((3, 3), np.uint8))  # as support_profile does
        fresh = support_profile(Lines(rho[todo], theta[todo], lines.votes[todo]), edges, grad,
                                box=box, near=near)
        if not copied:  # the caller's profile stays as it was
            cum, t0 = cum.copy(), t0.copy()
            t_in = None if t_in is None else t_in.copy()
            copied = True
        cum[todo], t0[todo] = fresh.cum, fresh.t0
        if t_in is not None and fresh.t_in is not None:
            t_in[todo] = fresh.t_in
    if not copied:
        return lines, profile
    keep = _without_merged(rho, theta, np.flatnonzero((rho != lines.rho) | (theta != lines.theta)))
    return (Lines(rho[keep], theta[keep], lines.votes[keep]),
            SupportProfile(cum[keep], t0[keep], None if t_in is None else t_in[keep]))


def _without_merged(rho: NDArray[np.float64], theta: NDArray[np.float64],
                    moved: NDArray[np.intp], rho_tol: float = 0.5,
                    theta_tol: float = np.radians(0.2)) -> NDArray[np.intp]:
    """Indices of the lines (strongest first) left when the lines a moved line now
    equals (within ``rho_tol`` px and ``theta_tol`` rad, (ρ, θ) and (−ρ, θ ± π) being one
    line) are merged into the strongest of them, moved or not."""
    drop = np.zeros(len(rho), bool)
    for i in moved.tolist():
        if drop[i]:
            continue
        dth = np.abs(theta - theta[i])
        same = (((dth < theta_tol) & (np.abs(rho - rho[i]) < rho_tol))
                | ((np.abs(dth - np.pi) < theta_tol) & (np.abs(rho + rho[i]) < rho_tol)))
        same[i] = False
        stronger = np.flatnonzero(same[:i] & ~drop[:i])
        if len(stronger):
            drop[i] = True  # into the strongest (the input is sorted by votes)
        else:
            drop[np.flatnonzero(same)] = True  # a weaker line that now equals this one
    return np.flatnonzero(~drop)


def _fit_to_hits(lines: Lines, edges: NDArray[np.uint8], profile: SupportProfile, *,
                 min_span_px: float, max_turn_deg: float, max_scatter_px: float) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                 NDArray[np.bool_]]:
    """One pass of :func:`refine_lines`: the fitted (ρ, θ) of every line and which moved."""
    N = len(lines)
    h, w = edges.shape
    hit = np.diff(profile.cum, axis=1)  # (N, L): 0/1 per sample
    row, k = np.nonzero(hit)  # sorted by line, then position
    nx, ny = np.cos(lines.theta), np.sin(lines.theta)
    t = profile.t0[row] + k  # position along the line
    # the sample's point rho·n + t·d (d = (−ny, nx)), per coordinate: 1-D arrays are faster
    nxr, nyr = nx[row], ny[row]
    rr = lines.rho[row]
    x, y = rr * nxr - t * nyr, rr * nyr + t * nxr
    flat = edges.ravel()
    offset = np.zeros(len(row))
    found = np.zeros(len(row), bool)
    for o in (0.0, -1.0, 1.0):  # the nearest offset with an edge pixel wins
        xi = np.rint(x + o * nxr).astype(np.intp)
        yi = np.rint(y + o * nyr).astype(np.intp)
        # 0 <= v < size as one unsigned comparison (a negative v wraps to a huge one)
        inside = (xi.view(np.uintp) < w) & (yi.view(np.uintp) < h)
        on = flat[(yi * w + xi) * inside] > 0
        on &= inside
        on &= ~found
        offset[on] = o
        found |= on
    row, t, offset = row[found], t[found], offset[found]
    s1 = np.bincount(row, minlength=N).astype(np.float64)
    count = np.maximum(s1, 1.0)
    tm = np.bincount(row, t, N) / count  # centred positions: a stable fit
    tc = t - tm[row]
    stt = np.bincount(row, tc * tc, N)
    mean_o = np.bincount(row, offset, N) / count
    b = np.where(stt > 0, np.bincount(row, tc * offset, N) / np.maximum(stt, 1e-12), 0.0)
    a = mean_o - b * tm  # the offset at t = 0
    # the offsets' scatter about the fit: a straight edge's whole-pixel offsets stay within
    # ~0.4 px of it; hits gathered from texture or from two edges scatter more
    var = np.bincount(row, offset * offset, N) / count - mean_o ** 2 - b * b * stt / count
    first = np.searchsorted(row, np.arange(N))
    last = np.searchsorted(row, np.arange(N), side="right") - 1
    span = np.where(last >= first, t[np.maximum(last, 0)] - t[np.minimum(first, len(t) - 1)], 0.0) \
        if len(t) else np.zeros(N)
    moved = ((span >= min_span_px) & (np.abs(b) <= np.tan(np.radians(max_turn_deg)))
             & (var <= max_scatter_px ** 2)
             & ((np.abs(a) > 1e-3) | (np.abs(b) > 1e-6)))
    # the fitted line runs through rho·n + a·n along d + b·n
    n, d = lines.normals, lines.directions
    dn = d + b[:, None] * n
    dn /= np.linalg.norm(dn, axis=1, keepdims=True)
    nn = np.column_stack([dn[:, 1], -dn[:, 0]])  # the normal, turned with the direction
    nn[(nn * n).sum(axis=1) < 0] *= -1
    rho = ((lines.rho + a)[:, None] * n * nn).sum(axis=1)
    theta = np.arctan2(nn[:, 1], nn[:, 0])
    # back to θ in [0, π): (ρ, θ) and (−ρ, θ ± π) are one line
    low, high = theta < 0, theta >= np.pi
    theta = np.where(low, theta + np.pi, np.where(high, theta - np.pi, theta))
    rho = np.where(low | high, -rho, rho)
    return rho, theta, moved


def refine_segment(grad: Gradients, p_a: NDArray[np.float64], p_b: NDArray[np.float64], *,
                   half_width: float = 3.0, trim: float = 4.0,
                   iterations: int = 2) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Fit a side between approximate corners ``p_a``, ``p_b`` to the gradient, sub-pixel.

    Hough's 1 px / 1° cells leave a 200 px side up to ~2 px off at its ends. Along the side,
    every pixel, the directional derivative across it is sampled over ±``half_width`` px; its
    peak (refined by a parabola) is an edge point; a total-least-squares line through those
    points, after dropping outliers, is the refined side.

    Returns
    -------
    (point, direction) : ndarray, shape (2,) each — a point on the line and its unit direction,
    or None when too few edge points support the side.
    """
    p_a, p_b = np.asarray(p_a, dtype=np.float64), np.asarray(p_b, dtype=np.float64)
    # a frame fits one side of many candidate quads more than once (one in eight fits of
    # rovis bench's frames): the first fit is kept on the gradients (Gradients.fits)
    key = (p_a.tobytes(), p_b.tobytes(), half_width, trim, iterations)
    if key not in grad.fits:
        grad.fits[key] = _refine_segment(grad, p_a, p_b, half_width, trim, iterations)
    fit = grad.fits[key]
    return None if fit is None else (fit[0].copy(), fit[1].copy())


def _refine_segment(grad: Gradients, p_a: NDArray[np.float64], p_b: NDArray[np.float64],
                    half_width: float, trim: float, iterations: int,
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """:func:`refine_segment`'s fit, each time."""
    length = float(np.linalg.norm(p_b - p_a))
    if length < 2 * trim + 4:
        return None
    point, d = 0.5 * (p_a + p_b), (p_b - p_a) / length
    offsets = np.arange(-half_width, half_width + 0.5, 1.0)
    t = np.arange(-0.5 * length + trim, 0.5 * length - trim + 0.5, 1.0)
    width = len(offsets)
    mid = width // 2
    for _ in range(iterations):
        n = np.array([-d[1], d[0]])
        base = point + t[:, None] * d  # (S, 2)
        xs = base[:, None, 0] + offsets[None, :] * n[0]
        ys = base[:, None, 1] + offsets[None, :] * n[1]
        gx, gy = grad.sample(xs, ys)
        g = gx * n[0] + gy * n[1]  # derivative across the side, (S, O)
        # One side of a boundary is brighter all along it; judge which from the columns at
        # the line itself, not the window, which may reach a stronger neighbouring edge.
        sign = np.sign(g[:, mid - 1:mid + 2].sum())
        if sign < 0:  # (times 1: the same values)
            g = g * sign
        k = np.argmax(g, axis=1)
        interior = (k > 0) & (k < width - 1)
        rows = np.flatnonzero(interior)
        # flat indices of each row's peak: 1-D gathers, cheaper than (rows, k) pairs
        at = rows * width
        at += k[rows]
        flat = g.reshape(-1)
        g1 = flat[at]
        strong = g1 > 0.5 * _median(g1) if len(g1) else np.zeros(0, bool)
        # the parabola through the peak and its neighbours, for the strong rows only (the
        # others are dropped: the same points)
        at, g1 = at[strong], g1[strong]
        g0, g2 = flat[at - 1], flat[at + 1]
        denom = g0 - 2 * g1 + g2
        delta = np.zeros(len(at))
        np.divide(0.5 * (g0 - g2), denom, out=delta, where=denom < 0)
        # clip to ±0.5 (np.clip's values, without its wrapper's cost)
        offs = offsets[at % width] + np.minimum(np.maximum(delta, -0.5), 0.5)
        pts = base[at // width] + offs[:, None] * n
        if len(pts) < max(6, 0.3 * len(t)):
            return None
        fit = _fit_line(pts)
        if fit is None:
            return None
        point_new, d_new = fit
        if d_new @ d < 0:
            d_new = -d_new
        # Keep the segment's extent: re-centre on the projection of the old midpoint.
        point = point_new + ((point - point_new) @ d_new) * d_new
        d = d_new
        # The next pass samples the same window around the refitted line. (Narrowing it
        # to ±1.5 px, as a dead assignment here once meant to, found 168 instead of 170
        # build/t1 books, 142 instead of 146 within 1 cm.)
    return point, d


def _fit_line(pts: NDArray[np.float64], *, outlier_px: float = 1.0) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Total-least-squares line through ``pts`` (M, 2), refit once without > outlier_px points."""
    for _ in range(2):
        c = pts.sum(axis=0) / len(pts)  # pts.mean(axis=0), without its wrapper's cost
        x, y = pts[:, 0] - c[0], pts[:, 1] - c[1]
        # the principal axis of the 2x2 scatter in closed form (what an SVD of the
        # centred points gives, at a fraction of its cost on a few hundred points)
        angle = 0.5 * np.arctan2(2.0 * (x @ y), x @ x - y @ y)
        d = np.array([np.cos(angle), np.sin(angle)])
        resid = np.abs(x * -d[1] + y * d[0])
        inliers = resid < max(outlier_px, 2.5 * _median(resid))
        kept = np.count_nonzero(inliers)
        if kept == len(pts) or kept < 6:
            break
        pts = pts[inliers]
    return c, d


def _median(a: NDArray[np.float64]) -> float:
    """np.median of a non-empty 1-D array of finite numbers, by the same partition and
    the same mean of the middle values, without np.median's overhead (~7x on the few
    hundred values of a side; refinement takes several per side). ``+ 0.0``: np.median's
    mean sums from +0.0, so its zero median is +0.0, never -0.0."""
    k = len(a) // 2
    if len(a) % 2:
        return float(np.partition(a, k)[k] + 0.0)
    part = np.partition(a, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2 + 0.0)


def intersect(p1: NDArray[np.float64], d1: NDArray[np.float64], p2: NDArray[np.float64],
              d2: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Intersection of two lines given as point + direction (2,), or None if parallel."""
    A = np.column_stack([d1, -d2])
    det = np.linalg.det(A)
    if abs(det) < 1e-9:
        return None
    s = np.linalg.solve(A, p2 - p1)[0]
    return p1 + s * d1
