"""``detect``: the paper's Fig. 2, top to bottom, for one stereo pair.

1. marker → desk plane and image ROI (the workspace rectangle), in both images;
2. undistort both images (lines are straight only there);
3. boundary segmentation of each image (closed loop or a baseline) → cover corners;
4. stereo correspondence of the covers;
5. triangulation of the four corners (eq. 3–5) → pose (eq. 6–7) and cuboid;

and, beyond the paper, where no book is yet: the covers one image found looked for in the
other, stereo's choice among both images' candidate quads (three-sided ones included: a
cover whose fourth side shows no edge), the covers that stand out of the desk in a stereo
height map, one image's candidates looked for in the other; then each cover's sides moved
to its edges (docs/stereo.md).

A :class:`Detector` keeps what is set up once per rig (undistortion maps) and, in a
sequence, the controllers' previous optimum (warm start).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import Any, Literal, Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from rovis import geometry, marker
from rovis.agreement import AgreementConfig, agreement, edge_quality
from rovis.calib import StereoRig
from rovis.extent import (CompleteConfig, ExtentConfig, FacingConfig, SideHeightConfig,
                          _drop, _facing, _foot_is_edge, _grow_side, _moved, _on_desk,
                          _side_scores, _unit, complete_open, fit_pair_extent, foot_side,
                          height_from_sides, height_off_feet, lift_foot, settle_block_sides,
                          settle_facing_sides, strong_share, under_taller)
from rovis.heightmap import (HeightMap, HeightMapConfig, Rectification, dense_height_map,
                             height_map, raised_covers, smooth_height_map, snap_sides,
                             sweeps_confirm)
from rovis.imageio import to_gray_u8
from rovis.results import BookDetection, FrameResult, SegmentationInfo
from rovis.segment import CascadeController, SegmentConfig, Segmentation, gradients
from rovis.segment.edges import CANNY_LOW_RATIO, Gradients
from rovis.segment.lines import Lines
from rovis.segment.methods import METHODS, segment
from rovis.segment.boundary import (Fit, refine_quad, refine_quad_both, refine_quad_fits,
                                    side_evidence)
from rovis.segment.quads import Quads, _shoelace, order_corners, quad_overlap
from rovis.split import (Split, SplitConfig, beside, join_halves, map_step, piece_of,
                         split_union_heights)
from rovis.track import TrackConfig, follow
from rovis.trim import (TrimConfig, cut_cover, grow_run, height_profile, lateral_grow, map_height,
                        print_grow, trim_side)
from rovis.stereo import (Match, PoolPairs, StereoConfig, _point_segment_distance,
                          find_in_other_view, flat_rectangle, match_quads, pool_pairs,
                          side_lengths_and_corner_cos)
from rovis.sweep import (Sweep, SweepConfig, _plane_frame, contradicts,
                         contradicts_beyond_quarter, find_by_print, high_pass,
                         on_plane, print_goes_on, print_height, sweep_heights, texture_height)
from rovis.undistort import IdealView


# Why a stereo pair of quads makes no book (:meth:`Detector._reconstruct_or_why`): its
# corners do not triangulate to a quadrilateral; a side is longer than any book (or, after
# the extent step — at once without the desk plane, where none follows — shorter than any
# book's: a printed square, a label); the cover
# is tilted against the desk; it stands below the desk (or, found in one image only or
# among the alternatives, lower than any book) or more than StereoConfig.max_height above
# it; a side lies on the desk; its print matches between the images at another height
# than its corners (rovis.sweep); without the desk plane, a cover found in one image only
# whose corners make no rectangle in 3D (with it, one with no corner near a right angle:
# Detector._unskewed), or a rectangle inside a larger cover, in its plane (a print on it);
# last, a cover over one both segmentations found (Detector._without_overlaps), and the
# desk between books: its inside matching on the desk, with a side unseen or, with every
# side seen, best and clearly so (Detector._without_desk).
DROP_REASONS = ("degenerate", "too long", "too small", "tilted", "height", "side on desk",
                "texture height", "skewed", "printed", "overlaps", "desk")
# A frame's pool candidates refined (Detector._from_pool, read again by
# Detector._from_pool_one_image): (camera, the candidate's corners as bytes: whichever pool
# it is in) → corners with and without the inward search, (4, 2) each, and each side's fit
# (refine_sides's, with the inward search): :func:`refine_quad_fits`.
Refined = dict[tuple[str, bytes], tuple[NDArray[np.float64], NDArray[np.float64],
                                        list[Fit | None]]]
# The checks after which a pair is retried with the other quads the closed loop found over
# it (Segmentation.alternatives): those an outline paired with a cover fails.
ALTERNATIVE_REASONS = ("tilted", "side on desk", "height", "texture height")


@dataclass(frozen=True)
class DetectConfig:
    """Settings of :func:`detect` (every field has a sensible default).

    Attributes
    ----------
    method : str
        Segmentation method, one of ``closed open auto-median auto-otsu lsd contour``.
    triangulation : {"dlt", "optimal"}
    use_marker : bool
        Look for the desk marker in each frame (ROI and desk plane). Not needed when the
        calibration is registered to the marker (``world_frame: marker``, what
        ``rovis register`` and ``rovis synth`` write): the desk is then z = 0 of the world.
    marker_id, marker_side : int, float
    workspace_x, workspace_y : (float, float)
        The workspace rectangle in the marker frame, metres.
    roi_height, roi_margin_px : float, int
        The ROI is the workspace up to this height above the desk (metres), grown by a margin.
    max_tilt_deg : float
        A book lies on the desk: a reconstructed cover tilted more than this against the desk
        plane is not a cover (e.g. the outline of a book with its page block) and is dropped.
    max_cover_side : float
        Metres. A reconstructed cover longer than this is no book (an atlas is ~0.4 m): two
        books end to end, or a cover and a line beyond it.
    min_cover_side : float
        Metres. A cover with a side shorter than this once the extent step is done is no
        book (a pocket book is ~0.1 × 0.075 m): a printed square, a label, a sticker.
    min_side_height : float
        Metres. A quad with a side whose midpoint is lower than this above the desk is
        dropped: that side is a line on the desk (a shadow's edge, a page block's foot).
    full_view : bool
        Undistort into an ideal frame that holds the raw images' whole field of view
        (:class:`rovis.undistort.IdealView`): with barrel distortion the raw image's border
        lies beyond the ideal image of its own size, and a cover near it loses a side.
    fit_rectangle : bool
        Replace the four separately triangulated corners by one 3D rectangle fitted to both
        images' corners (:func:`rovis.geometry.fit_rectangle`; beyond the paper).
    lift_foot : bool
        A pair that fails as tilted (or with a side on the desk) where no book is found
        by then, one side of it the foot of its page block in both images, is lifted to
        the cover's height (:func:`rovis.extent.lift_foot`; beyond the paper; needs the
        desk plane).
    flat_refit_px : float
        Pixels; 0 turns it off (and ``flat_refit_sides`` with it). A stereo pair that comes
        out tilted or with a side on the desk is refit as one rectangle parallel to the
        desk, kept where every corner of both images lies within this of it (beyond the
        paper; needs the desk plane). Twice this is also the margin ``flat_refit_sides``
        asks of the side it leaves out.
    flat_refit_sides : float
        Pixels; 0 turns it off (and ``stereo.pool_transfer_fit`` with its excused second
        try: the one-image search's fit of a candidate with a side unseen must lie within
        this of its sides). Where that
        refit misses, the rectangle is fitted to the pair's sides instead of its corners,
        one image's side left out: one that lies outside the fit by more than twice
        ``flat_refit_px`` (a page block's foot, the soft edge of the cover's shadow), the
        other seven sides within this of it
        (:meth:`Detector._side_fit`; beyond the paper). A segmentation pair gets it only
        after its alternatives (``stereo.alternatives``) made no book.
    unskew_deg, unskew_height, unskew_reach : float
        Degrees (0 turns it off), metres, a share. A cover whose corners make an angle
        further than ``unskew_deg`` from 90° has a side on a line of its print or a
        neighbour's edge: the cover is laid again from its other three sides, that one
        taken for unseen and looked for within ``complete.search`` of where it was (its
        middle), then, where that keeps no cover, ``unskew_reach`` of the difference of
        its neighbouring sides' lengths further (0.5: as far as its ends lie from its
        middle; 0 turns the wider search off), and kept within ``unskew_height`` of its
        height; one with every angle still that far off is dropped (``"skewed"``;
        :meth:`Detector._unskewed`; beyond the paper; needs the desk plane).
    segment, stereo, extent, complete, facing, sweep, side_height
        :class:`SegmentConfig`, :class:`StereoConfig`, :class:`ExtentConfig`,
        :class:`CompleteConfig`, :class:`FacingConfig`, :class:`SweepConfig`,
        :class:`SideHeightConfig`. ``side_height``: each cover moved to the height its
        sides' edges agree on, before the extent step
        (:func:`rovis.extent.height_from_sides`; beyond the paper; needs the desk plane).
        ``extent``: moving each cover's sides to its edges in both images
        (:mod:`rovis.extent`; beyond the paper; needs the desk plane). ``complete``: a
        pair of candidates with sides unseen, completed to a rectangle in 3D where
        refining each image alone gives no flat cover (:func:`rovis.extent.complete_open`;
        beyond the paper; needs the desk plane). ``facing``: a side facing the camera
        settled on the page-block edge both images share, before the extent step
        (:func:`rovis.extent.settle_facing_sides`), and, in a tilted pair's flat refit,
        a side one image saw on its page block's foot moved to the cover's height
        (``facing.block_sides``, :func:`rovis.extent.settle_block_sides`), and, after
        the steps that grow sides, a side both images took on its page block's foot, the
        cover flat at its height, moved to the cover's edge above it (``facing.feet``,
        :func:`rovis.extent.foot_side`; beyond the paper; need the desk plane). ``sweep``: each
        cover's height tested against its print, and a printed cover found in one image
        only placed in the other by its print (:mod:`rovis.sweep`; beyond the paper; needs
        the desk plane; the placing also ``stereo.transfer``).
    agreement
        :class:`rovis.agreement.AgreementConfig`: each book as reported checked against
        both images at the end of the frame, for its ``quality`` and
        ``reprojection_error_px`` (:mod:`rovis.agreement`; beyond the paper).
    heightmap, trim
        :class:`rovis.heightmap.HeightMapConfig`, :class:`rovis.trim.TrimConfig`:
        books that stand out of the desk in a height map; with the maps, a plain cover
        at the wrong height moved to theirs, a cover that takes in a lower neighbour
        cut back where the maps leave its height, and one cut short grown to where they
        do (beyond the paper; need the desk plane; switching the height map off switches
        these off too).
    """

    method: str = "closed"
    triangulation: Literal["dlt", "optimal"] = "dlt"
    use_marker: bool = True
    marker_id: int = marker.MARKER_ID
    marker_side: float = marker.MARKER_SIDE
    workspace_x: tuple[float, float] = marker.WORKSPACE_X
    workspace_y: tuple[float, float] = marker.WORKSPACE_Y
    roi_height: float = 0.10
    roi_margin_px: int = 8
    max_tilt_deg: float = 6.0
    min_side_height: float = 0.002
    max_cover_side: float = 0.45
    min_cover_side: float = 0.06
    fit_rectangle: bool = False
    lift_foot: bool = True
    flat_refit_px: float = 1.0
    flat_refit_sides: float = 1.0
    unskew_deg: float = 8.0
    unskew_height: float = 0.01
    unskew_reach: float = 0.5
    full_view: bool = True
    segment: SegmentConfig = field(default_factory=SegmentConfig)
    stereo: StereoConfig = field(default_factory=StereoConfig)
    extent: ExtentConfig = field(default_factory=ExtentConfig)
    complete: CompleteConfig = field(default_factory=CompleteConfig)
    facing: FacingConfig = field(default_factory=FacingConfig)
    sweep: SweepConfig = field(default_factory=SweepConfig)
    heightmap: HeightMapConfig = field(default_factory=HeightMapConfig)
    split: SplitConfig = field(default_factory=SplitConfig)
    trim: TrimConfig = field(default_factory=TrimConfig)
    side_height: SideHeightConfig = field(default_factory=SideHeightConfig)
    track: TrackConfig = field(default_factory=TrackConfig)
    agreement: AgreementConfig = field(default_factory=AgreementConfig)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {self.method!r}")
        if self.triangulation not in ("dlt", "optimal"):
            raise ValueError(f"triangulation: expected 'dlt' or 'optimal', got {self.triangulation!r}")


def with_settings(cfg: DetectConfig, settings: Sequence[str]) -> DetectConfig:
    """``cfg`` with fields replaced from ``"name=value"`` strings (the CLI's ``--set``).

    A name may reach into the nested settings with dots (``extent.grow=false``,
    ``segment.n_max=150``, ``stereo.min_ncc=0.3``, ``segment.quads.min_support=0.6``). The
    value is read as the field's current type: true/false, an integer, a number, text, or
    comma-separated numbers for a pair.

    Raises
    ------
    ValueError
        An unknown name or a value of the wrong type, naming both.
    """
    for item in settings:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"--set {item!r}: expected NAME=VALUE")
        cfg = _set(cfg, name.split("."), text.strip(), name)
    return cfg


def _set(obj: Any, path: list[str], text: str, name: str) -> Any:
    names = [f.name for f in fields(obj)]
    if path[0] not in names:
        raise ValueError(f"--set {name}: no setting {path[0]!r} here (expected one of "
                         f"{', '.join(names)})")
    current = getattr(obj, path[0])
    if len(path) > 1:
        if not is_dataclass(current):
            raise ValueError(f"--set {name}: {path[0]!r} has no settings inside it")
        return replace(obj, **{path[0]: _set(current, path[1:], text, name)})
    if is_dataclass(current):
        raise ValueError(f"--set {name}: a group of settings; name one inside it "
                         f"({', '.join(f.name for f in fields(current))})")
    try:
        value = _parse_like(current, text)
    except ValueError:
        raise ValueError(f"--set {name}={text}: expected {type(current).__name__} like "
                         f"{current!r}") from None
    return replace(obj, **{path[0]: value})  # runs the config's own checks


def _parse_like(current: Any, text: str) -> Any:
    if isinstance(current, bool):
        low = text.lower()
        if low in ("true", "yes", "on", "1"):
            return True
        if low in ("false", "no", "off", "0"):
            return False
        raise ValueError(text)
    if isinstance(current, int):
        return int(text)
    if isinstance(current, float):
        return float(text)
    if isinstance(current, tuple):
        parts = [p for p in text.split(",") if p.strip()]
        if len(parts) != len(current):
            raise ValueError(text)
        return tuple(_parse_like(c, p.strip()) for c, p in zip(current, parts))
    return text


@dataclass(eq=False)
class _Frame:
    """One stereo pair made ready for segmentation (:meth:`Detector._prepare`), and the
    frame's timing and warnings so far."""

    rig: StereoRig = None  # type: ignore[assignment]  # its Q_L, Q_R give ideal pixels
    raw_rig: StereoRig = None  # type: ignore[assignment]  # the raw images' rig
    desk_plane: NDArray[np.float64] | None = None
    ideal: dict[str, NDArray[np.uint8]] = field(default_factory=dict)
    grads: dict[str, Gradients] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)  # ms per stage
    clock: float = field(default_factory=time.perf_counter)

    def lap(self, stage: str) -> None:
        """Add the time since the last lap to ``stage``."""
        now = time.perf_counter()
        self.timing[stage] = self.timing.get(stage, 0.0) + 1e3 * (now - self.clock)
        self.clock = now


@dataclass(frozen=True, eq=False)
class Pair:
    """One cover's corners in both ideal images, the same physical corner at each index.

    ``transferred`` names the image the cover was segmented in when the other image's
    corners come from :func:`rovis.stereo.find_in_other_view` (None: segmented in both).
    """

    left: NDArray[np.float64]  # (4, 2)
    right: NDArray[np.float64]  # (4, 2)
    quality: float  # edge support of the segmented quad(s), 0-1
    error_px: float  # stereo match error (0 for a transferred cover)
    transferred: str | None = None
    alternative: bool = False  # from Segmentation.alternatives, after the first pair failed
    # BookDetection.source: "segmentation", or a cover neither image's segmentation kept,
    # from the candidate pools ("candidates", Detector._from_pool) or the height map
    # ("height map"); "one image" comes from ``transferred``
    source: str = "segmentation"
    three_sided: bool = False  # a segmented cover with its fourth side unseen (either image)
    # from a small candidate with sides unseen (SegmentConfig.small_open): kept only if no
    # side of the final book is under StereoConfig.small_open_min_side
    small_open: bool = False



def _on_cover_plane(rig: StereoRig, pair: Pair, desk_plane: NDArray[np.float64],
                    ) -> tuple[NDArray[np.float64], float]:
    """A pair's triangulated cover corners (4, 3) flattened onto the plane parallel to the
    desk through their mean, and that plane's height above the desk (metres)."""
    P = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
    height = float(np.mean(geometry.plane_distance(desk_plane, P)))
    up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
    return P - np.outer((P - P.mean(axis=0)) @ up, up), height

class Detector:
    """Detects books in stereo pairs from one calibrated rig.

    Parameters
    ----------
    rig : StereoRig
    cfg : DetectConfig, optional
    """

    def __init__(self, rig: StereoRig, cfg: DetectConfig | None = None) -> None:
        if rig.image_size is None:
            raise ValueError("calibration: image size unknown; give image_width/height")
        self.rig = rig
        self.cfg = cfg or DetectConfig()
        # Raw → ideal maps, computed once: for each ideal pixel, where to read the raw image.
        self._view = IdealView.of(rig, full=self.cfg.full_view)
        self._view_rigs: tuple[bytes, StereoRig] | None = None  # _view_rig's last
        self._rectification: tuple[bytes, Rectification] | None = None  # _rectified's last
        self._controllers = {cam: CascadeController(self.cfg.segment) for cam in ("left", "right")}
        # The last ROI per camera: a registered rig's (or a still marker's) is the same
        # every frame, so it is drawn once.
        self._masks: dict[str, tuple[bytes, NDArray[np.uint8]]] = {}
        # The last frame's books for track(): (pair, book, each side's edge evidence per
        # camera) each, and the segmentation info; None before a frame with the desk plane.
        self._tracks: tuple[list[tuple[Pair, BookDetection, dict[str, NDArray[np.float64]]]],
                            dict[str, SegmentationInfo]] | None = None

    def reset(self) -> None:
        """Start a new sequence: forget the controllers' previous optimum and the books
        :meth:`track` would follow."""
        for ctl in self._controllers.values():
            ctl.reset()
        self._tracks = None

    def detect(self, left: NDArray[np.generic], right: NDArray[np.generic]) -> FrameResult:
        """Find the books in one stereo pair of raw images.

        Parameters
        ----------
        left, right : ndarray, shape (H, W) or (H, W, 3); uint8 or uint16
            Raw camera images (colour and 16-bit are converted to 8-bit grey).

        Raises
        ------
        ValueError
            An image that is empty, of the wrong size, or of an unsupported type.
        """
        f = self._prepare(left, right)
        rig = f.rig
        desk_plane, ideal, grads = f.desk_plane, f.ideal, f.grads
        timing, warnings, lap = f.timing, f.warnings, f.lap

        # 3. segmentation per image
        segs: dict[str, Segmentation] = {}
        steps: dict[str, float] = {}  # the segmentation's own steps, both images
        for cam in ("left", "right"):
            segs[cam] = segment(ideal[cam], grads[cam], self.cfg.method,
                                controller=self._controllers[cam], cfg=self.cfg.segment,
                                timing=steps)
            lap("segmentation")
        timing.update({f"segmentation.{step}": ms for step, ms in steps.items()})
        if len(segs["left"]) == 0 or len(segs["right"]) == 0:
            warnings.append("no book cover found in the "
                            + " and ".join(c for c in ("left", "right") if len(segs[c]) == 0)
                            + " image")

        # 4. stereo correspondence, 5. triangulation and pose
        matches = match_quads(segs["left"].corners, segs["right"].corners, rig.Q_L, rig.Q_R,
                              desk_plane=desk_plane, gray_left=ideal["left"],
                              gray_right=ideal["right"], cfg=self.cfg.stereo)
        pairs = [Pair(segs["left"].corners[mt.left], mt.corners_right,
                      float(min(segs["left"].support[mt.left], segs["right"].support[mt.right])),
                      mt.error_px, three_sided=_three_sided(segs["left"], mt.left)
                      or _three_sided(segs["right"], mt.right)) for mt in matches]
        lap("stereo")
        # the print inside each cover, both images, for the height test (rovis.sweep)
        texture = (self._texture(ideal)
                   if (self.cfg.sweep.check or self.cfg.sweep.transfer) and desk_plane is not None
                   else None)
        books = [self._reconstruct_or_why(rig, pair, desk_plane, texture) for pair in pairs]
        books = self._with_flat_refits(rig, books, desk_plane, texture, sides=False)
        if self.cfg.stereo.alternatives:
            # beyond the paper: a pair that is no cover may be one with the other quads the
            # closed loop found over its quads (Segmentation.alternatives)
            for i, (mt, (pair, book, why)) in enumerate(zip(matches, books)):
                if book is None and why in ALTERNATIVE_REASONS:
                    others = [p.left for p, b, _ in books if b is not None]
                    books[i] = self._alternative(rig, segs, grads, ideal, mt, pair, why,
                                                 desk_plane, texture, others)
        # beyond the paper: a pair still tilted (its alternatives tried first: the other
        # quads may be the cover where this pair's are a frame printed inside it), fitted
        # flat to its sides with one image's side left out
        books = self._with_side_fits(rig, books, desk_plane, texture)
        lap("pose")
        if self.cfg.stereo.transfer:
            # A matched pair that is no flat cover often pairs a cover in one image with its
            # outline in the other: both quads are free again, for each to be looked for in
            # the other image on its own (without the desk plane, on the plane the quad's
            # rectangle implies: find_in_other_view).
            kept = [(mt, pair) for mt, (pair, book, _) in zip(matches, books) if book is not None]
            more = self._transfer(rig, segs, grads, ideal, kept, desk_plane, texture)
            lap("stereo")
            pairs += more
            books += self._with_flat_refits(
                rig, [self._reconstruct_or_why(rig, pair, desk_plane, texture) for pair in more],
                desk_plane, texture)
            lap("pose")
        found = [(pair, book) for pair, book, _ in books if book is not None]
        # each candidate quad of the pool refined once a frame (Detector._from_pool)
        refined: Refined = {}
        if desk_plane is None:
            # no height tells a cover from a rectangle printed on it: the cover is the one
            # around it, in its plane
            found, printed = self._without_prints(found)
            books += [(pair, None, "printed") for pair, _ in printed]
        if self.cfg.stereo.pool and desk_plane is not None:
            # beyond the paper: books among the candidates neither image's selection kept
            # (without the desk plane, nothing tells a book from a flat rectangle of a
            # pattern: on the real chessboard pairs, squares of the board)
            found += self._from_pool(rig, segs, grads, found, desk_plane, texture, refined)
            if any(np.all(seg.small_pool.lines >= 0, axis=1).any() for seg in segs.values()):
                # beyond the paper: then the candidates smaller than a cover of one image
                # (Segmentation.small_pool), in a pass of their own
                found += self._from_pool(rig, segs, grads, found, desk_plane, texture, refined,
                                         extra="small")
            lap("stereo")
        maps: list[tuple[HeightMap, NDArray[np.float64], HeightMapConfig, int]] = []
        if self.cfg.heightmap.enabled and desk_plane is not None:
            # beyond the paper: books that stand out of the desk in a height map
            if texture is None:
                texture = self._texture(ideal)
            maps = self._height_maps(rig, grads, desk_plane, texture, ideal)
            found += self._from_height_map(rig, grads, found, desk_plane, texture, maps)
            lap("heightmap")
        if self.cfg.lift_foot and desk_plane is not None:
            # beyond the paper: a pair that tilts because one side is its page block's
            # foot in both images, where nothing else found a book, lifted
            found += self._lifted(rig, grads, books, found, desk_plane, texture)
            lap("pose")
        if self.cfg.heightmap.dense and maps and desk_plane is not None:
            # beyond the paper: a cover of the desk's colour, or a plain one, that stands
            # out in a dense disparity map where nothing else found a book
            found += self._from_dense_map(rig, grads, ideal, found, desk_plane, texture, maps)
            lap("dense")
        if self.cfg.stereo.pool and desk_plane is not None and any(
                len(seg.late_pool) for seg in segs.values()):
            # beyond the paper: the candidates with sides unseen of the closed loop's other
            # T_H (Segmentation.late_pool), after the height maps, before the one-image search
            found += self._from_pool(rig, segs, grads, found, desk_plane, texture, refined,
                                     extra="late")
            lap("stereo")
        if self.cfg.stereo.pool_transfer and desk_plane is not None:
            # beyond the paper: one image's candidates looked for in the other, last
            found += self._from_pool_one_image(rig, segs, grads, ideal, found, desk_plane,
                                               texture, refined)
            lap("stereo")
        if self.cfg.stereo.pool and desk_plane is not None and any(
                np.any(seg.small_pool.lines < 0) for seg in segs.values()):
            # beyond the paper: the small candidates with sides unseen
            # (SegmentConfig.small_open), last: where nothing else found a book
            found += self._from_pool(rig, segs, grads, found, desk_plane, texture, refined,
                                     extra="small_open")
            lap("stereo")
        # a failed pair whose quad became a book through the one-image search is not lost
        # (a print lies inside the cover it was dropped for: it is always reported)
        dropped = [(why, pair.left, pair.right) for pair, book, why in books
                   if book is None and (why == "printed" or not any(
                       quad_overlap(pair.left, p.left) > self.cfg.stereo.transfer_max_overlap
                       for p, _ in found))]
        if dropped:
            count = Counter(why for why, _, _ in dropped)
            warnings.append(f"{len(dropped)} stereo pair(s) of quads dropped: no flat, book-sized "
                            "cover on the desk ("
                            + ", ".join(f"{why}: {n}" for why, n in count.most_common()) + ")")
        # beyond the paper: a cover that is no rectangle laid again from its three best
        # sides, or dropped where no corner is near a right angle
        if self.cfg.unskew_deg > 0 and desk_plane is not None:
            found, skewed = self._unskewed(rig, segs, grads, found, desk_plane, texture)
            if skewed:
                dropped += skewed
                warnings.append(f"{len(skewed)} cover(s) with no right angle dropped (skewed): "
                                "no book (a parallelogram of lines)")
            lap("unskew")
        # beyond the paper: each cover at the height its sides' edges give, then its sides
        # moved to its edges, seen in both images
        if self.cfg.side_height.enabled and desk_plane is not None:
            found = self._with_side_heights(rig, grads, found, desk_plane, texture)
            lap("side_height")
        read = [(hm, Q) for hm, Q, _, _ in maps]  # each map and the projection it is over
        if (self.cfg.extent.grow or self.cfg.extent.shrink) and desk_plane is not None:
            earlier = [pair.left for pair, _ in found]
            found = self._fit_extents(rig, segs, grads, found, desk_plane, texture, ideal, read)
            lap("extent")
            if self.cfg.stereo.pool and self.cfg.stereo.pool_again and any(
                    max((_shared(q, pair.left) for pair, _ in found), default=0.0) < 0.75
                    for q in earlier):
                # a quarter or more of a cover found before lies under none now (a pool
                # pair that was two books, cut back to one): the candidates looked at again
                more = self._from_pool(rig, segs, grads, found, desk_plane, texture, refined)
                if more:
                    found += self._fit_extents(rig, segs, grads, more, desk_plane, texture,
                                               ideal, read)
                lap("stereo")
        # a book from the small candidates with sides unseen that the extent step left under
        # its bound (stereo.small_open_min_side) is a piece of a cover cut short at a band of
        # its print, or a strip of desk: it goes now, before it keeps the steps below from
        # growing that cover (and again at the end, after them)
        found, narrow = self._without_small(found, small_open_only=True)
        # beyond the paper: two touching books taken for one cover, split at their seam
        # (after the extent step, which would grow each part over the other again)
        if self.cfg.split.enabled and desk_plane is not None:
            found = self._split_unions(rig, segs, grads, found, desk_plane, texture, read)
            lap("split")
        # beyond the paper: a plain cover at the wrong height, moved to the height map's
        if self.cfg.trim.map_height and read and desk_plane is not None:
            found = self._at_map_height(rig, segs, grads, found, desk_plane, texture, read)
            lap("trim")
        # beyond the paper: a cover that spans a neighbour at another height, cut back
        if self.cfg.trim.enabled and read and desk_plane is not None:
            found = self._trimmed(rig, segs, grads, found, desk_plane, texture, read)
            lap("trim")
        # ...and one that stops short of where the maps go on at its height, grown
        if self.cfg.trim.grow and read and desk_plane is not None:
            found = self._grown(rig, segs, grads, found, desk_plane, texture, read)
            lap("trim")
        # ...and one whose print goes on beyond a side, grown to the cover's edge
        if self.cfg.trim.print_grow and texture is not None and desk_plane is not None:
            found = self._grown_by_print(rig, segs, grads, found, desk_plane, texture)
            lap("trim")
        # beyond the paper: a side facing the camera that both images took on its page
        # block's foot, moved to the cover's edge above it (after the steps that grow sides)
        if self.cfg.facing.feet and desk_plane is not None:
            found = self._off_feet(rig, grads, found, desk_plane, texture)
            lap("feet")
        if self.cfg.heightmap.taken_px >= 0 and maps:
            # beyond the paper: two books of about one height side by side make one patch
            # in one slab of the maps, and one rectangle over both, which was turned down
            # where one of them was found: the maps cut again without the found covers'
            # pixels, once the steps above have grown each found cover to its edges
            more = self._from_height_map(rig, grads, found, desk_plane, texture, maps,
                                         without_found=True)
            if self.cfg.heightmap.wide_slab > 0 and len(maps) > 1:
                # ...and the smooth map in wide slabs: a cover whose heights it reads
                # spread wider than one slab. Cut without the covers found before only: a
                # piece of a cover just found, cut off from it, would be a book of its own
                # (the Table II renders' brick cover). A book over one just found is not
                # taken (by the rule a rectangle over a found quad is turned down with): in
                # the extent step beside it, it would move that book (build/t2b scene 54)
                smooth, Q_half, half, erode = maps[1]
                wide = replace(half, slab=self.cfg.heightmap.wide_slab)
                overlap = self.cfg.stereo.transfer_max_overlap
                more += [(pair, book) for pair, book in self._from_height_map(
                    rig, grads, found, desk_plane, texture, [(smooth, Q_half, wide, erode)],
                    without_found=True, above=half.raised,
                    min_ncc=self.cfg.heightmap.wide_min_ncc)
                    if not _over_any_of(pair, more, overlap)]
            lap("heightmap")
            if more:
                # each new book through the extent step, kept where it still lies over no
                # book found (as the pass asked of it: the extent step may grow it over one)
                for pair, book in self._fit_extents(rig, segs, grads, more, desk_plane, texture,
                                                    ideal, read):
                    if not _over_any_of(pair, found, self.cfg.heightmap.taken_overlap):
                        found.append((pair, book))
                lap("extent")
        # beyond the paper: one cover found as two books, cut at a printed band, joined
        # (after the steps that move each part's outer sides to the cover's edges)
        if self.cfg.split.join and desk_plane is not None:
            found = self._joined(rig, found, desk_plane, texture)
            lap("join")
        # last, since the extent step may grow a piece of a cover to the whole cover
        dropped_early = len(dropped)
        small_open = sum(pair.small_open for pair, _ in found)
        found, small = self._without_small(found)
        if small or narrow:
            # (a book from the small pass with sides unseen has a bound of its own)
            small_open += len(narrow) - sum(pair.small_open for pair, _ in found)
            small = narrow + small
            dropped += small
            also = (f" ({small_open} from small candidates with sides unseen, narrower than "
                    f"{self.cfg.stereo.small_open_min_side * 100:g} cm)" if small_open else "")
            warnings.append(f"{len(small)} cover(s) narrower than {self.cfg.min_cover_side * 100:g} "
                            f"cm dropped{also}: no book (a printed square, a label)")
        # beyond the paper: a cover another pass found over one both segmentations found
        # (after the small ones go: a label the segmentations found is no evidence)
        if self.cfg.stereo.over_segmented > 0 and desk_plane is not None:
            found, over = self._without_overlaps(found, rig, desk_plane, texture)
            if over:
                dropped += over
                warnings.append(f"{len(over)} cover(s) over a cover the segmentations found "
                                "dropped (overlaps)")
        # beyond the paper: two covers that overlap on the desk, the strip read at one's
        # height: the other cut back off it
        if self.cfg.stereo.height_cut > 0 and read and texture is not None \
                and desk_plane is not None:
            found = self._cut_by_height(rig, found, desk_plane, texture, read, grads,
                                        self._edge_strength(segs))
        freed = [quads for why, quads, _ in dropped[dropped_early:]
                 if why in ("too small", "overlaps")]
        if freed and self.cfg.stereo.pool and self.cfg.stereo.pool_freed \
                and desk_plane is not None:
            # beyond the paper: the candidates under a cover just dropped, free again
            found += self._over_freed(rig, segs, grads, found, freed, desk_plane, texture,
                                      ideal, read, refined)
        # beyond the paper: the desk between books, closed by plank seams and a book's edge,
        # or by books', sheets' and shadows' edges on all four sides (a sheet's text too)
        if (self.cfg.stereo.desk_unseen > 0 or self.cfg.stereo.desk_seen_ncc <= 1) \
                and texture is not None and desk_plane is not None:
            found, desk = self._without_desk(rig, segs, grads, found, desk_plane, texture)
            if desk:
                dropped += desk
                warnings.append(f"{len(desk)} cover(s) whose inside matches on the desk "
                                "dropped (the desk between books)")
        lap("overlaps")
        # beyond the paper: a cover whose near side a taller book in front hides, its side
        # moved out to straight under that book's (last: the steps above take each found
        # cover's quads for what both images show of it)
        if self.cfg.facing.under and desk_plane is not None:
            found = self._under_taller(rig, grads, found, desk_plane, texture)
            lap("under")
        # beyond the paper: each book as reported, checked against both images
        found = self._agreed(f, found, self._edge_strength(segs))
        lap("agreement")
        info = {cam: SegmentationInfo(T_H=segs[cam].T_H, T_HG=segs[cam].T_HG, y=segs[cam].y,
                                      iterations=segs[cam].iterations, n_quads=len(segs[cam]))
                for cam in ("left", "right")}
        self._remember(f, found, info)
        return self._result(f, found, info, lines={cam: segs[cam].lines for cam in segs},
                            covers={cam: segs[cam].corners for cam in segs}, dropped=dropped)

    def track(self, left: NDArray[np.generic], right: NDArray[np.generic]) -> FrameResult | None:
        """Follow the books of the previous frame into this one, or None where that fails.

        Beyond the paper, for a still camera's sequence (``rovis detect --track N``): each
        book the last :meth:`detect` (or :meth:`track`) returned is looked for where it
        was, each side of its cover refit to the gradient within
        ``TrackConfig.window_px`` in both images, and one rectangle parallel to the desk
        fitted to both images' corners where one fits (:func:`rovis.track.follow`). No
        segmentation runs, so a frame costs the undistortion, the gradients and a few side
        fits. It does not look for new books: the caller runs :meth:`detect` every few
        frames.

        Returns None (the caller then runs :meth:`detect`) when there is no previous frame,
        no book in it (a desk to watch for books put down), no desk plane, or any book is
        not where it was: a side that lost its edge, a corner whose sides no longer meet
        near it, or a cover that now fails the pose checks. A height-map book that cannot
        be followed is held where it was instead (``TrackConfig.hold_height_map``). Each
        book's ``quality`` and ``reprojection_error_px`` are this frame's
        (:mod:`rovis.agreement`; a followed book's error from the sides refit here).

        Raises
        ------
        ValueError
            As :meth:`detect`, for an image it cannot use.
        """
        if self._tracks is None or not self._tracks[0]:
            return None
        # the images are undistorted and differentiated only around the books followed:
        # a side is measured within window_px of where it was, a corner moves at most four
        # windows, and the smoothing and Sobel reach 4 px (edges.gradients' region); 16 px
        # to spare
        pad = 5 * self.cfg.track.window_px + 16
        w, h = self._view.size
        near: dict[str, tuple[int, int, int, int]] = {}
        for cam in ("left", "right"):
            px = np.concatenate([book.corners_left_px if cam == "left" else book.corners_right_px
                                 for _, book, _ in self._tracks[0]])
            x0, y0 = np.clip(np.floor(px.min(axis=0) - pad), 0, [w, h]).astype(int)
            x1, y1 = np.clip(np.ceil(px.max(axis=0) + pad), 0, [w, h]).astype(int)
            if x1 <= x0 or y1 <= y0:
                return None  # the books are out of view: detect afresh
            near[cam] = (int(x0), int(y0), int(x1), int(y1))
        f = self._prepare(left, right, near)
        if f.desk_plane is None:
            return None
        previous, info = self._tracks
        strength = self._edge_strength(info)
        thresholds = {cam: self.cfg.agreement.evidence * strength[cam] for cam in strength}
        found: list[tuple[Pair, BookDetection]] = []
        for pair, book, evidence in previous:
            moved = follow(f.grads, {"left": book.corners_left_px, "right": book.corners_right_px},
                           evidence, book.corners_world,
                           f.rig.Q_L, f.rig.Q_R, f.desk_plane, strength, self.cfg.track,
                           reach_px=self.cfg.agreement.reach_px)
            if moved is None and book.source == "height map" and self.cfg.track.hold_height_map:
                # nothing to follow it by: held where it was, checked against this frame
                found += self._agreed(f, [(pair, book)], strength)
                continue
            if moved is None:
                return None
            P, c_left, c_right, reproj = moved
            pose = geometry.pose_from_corners(P, f.desk_plane)
            pair = replace(pair, left=c_left, right=c_right)
            if self._pose_fails(pose, P, f.desk_plane, pair):
                return None
            # the book's quality measured as the detection measures it (rovis.agreement)
            quality, _ = edge_quality(f.grads, {"left": c_left, "right": c_right}, thresholds)
            found.append((pair, replace(book, pose=pose, corners_world=P, corners_left_px=c_left,
                                        corners_right_px=c_right, reprojection_error_px=reproj,
                                        quality=quality)))
        f.lap("track")
        info = {cam: replace(i, iterations=0) for cam, i in info.items()}
        self._tracks = ([(pair, book, evidence) for (pair, book), (_, _, evidence)
                         in zip(found, previous)], info)
        covers = {"left": [b.corners_left_px for _, b in found],
                  "right": [b.corners_right_px for _, b in found]}
        return self._result(f, found, info, tracked=True,
                            covers={cam: np.array(c).reshape(-1, 4, 2) for cam, c in covers.items()})

    def _prepare(self, left: NDArray[np.generic], right: NDArray[np.generic],
                 near: dict[str, tuple[int, int, int, int]] | None = None) -> _Frame:
        """Steps 1–2 of Fig. 2 and the gradients: the marker (world frame, desk plane, ROI),
        both images undistorted and their Sobel gradients inside the ROI; with ``near``,
        per camera a box (x0, y0, x1, y1) of ideal pixels, only in it (black, 0 beyond)."""
        f = _Frame()
        gray = {"left": to_gray_u8(left, "left image"), "right": to_gray_u8(right, "right image")}
        self._check_sizes(gray["left"], gray["right"])
        rig = self.rig

        # 1. marker → world frame, desk plane, ROI
        T_world_marker = None
        if rig.world_frame == "marker":
            # Registered (rovis register): the world is the marker's frame and the desk is
            # z = 0, known better than one frame's 10 cm marker can tell (~1° of tilt).
            T_world_marker = np.eye(4)
            f.desk_plane = marker.desk_plane_from_marker(T_world_marker)
        elif self.cfg.use_marker:
            T_world_marker = self._find_marker(gray, f.warnings)
            if T_world_marker is not None:
                if rig.world_frame == "left_camera":  # DESIGN §2: then the marker is the world
                    rig = rig.with_world(geometry.invert_transform(T_world_marker) @ rig.T_world_left,
                                         "marker")
                    T_world_marker = np.eye(4)
                f.desk_plane = marker.desk_plane_from_marker(T_world_marker)
        f.lap("marker")

        # 2. undistort, into a frame that holds the whole raw field of view (IdealView):
        # from here on pixels are that frame's, and ``f.rig`` the rig whose Q_L, Q_R give them
        view = self._view
        f.raw_rig, f.rig = rig, self._view_rig(rig)
        f.ideal = {cam: view.undistort(gray[cam], cam, None if near is None else near[cam])
                   for cam in gray}
        f.lap("undistort")
        for cam in ("left", "right"):
            mask = self._roi_mask(f.raw_rig, cam, T_world_marker)
            grad = gradients(f.ideal[cam], mask, region=None if near is None else near[cam])
            if view.grown:
                # the black beyond the raw image's border is no edge to refine onto, and a
                # side running there is out of view
                x0, y0, x1, y1 = (0, 0, *view.size) if near is None else near[cam]
                for g in (grad.dx, grad.dy):
                    g[y0:y1, x0:x1][view.valid[cam][y0:y1, x0:x1] == 0] = 0
                grad = replace(grad, seen=view.valid[cam])
            f.grads[cam] = grad
        f.lap("gradients")
        return f

    def _agreed(self, f: _Frame, found: list[tuple[Pair, BookDetection]],
                strength: dict[str, float]) -> list[tuple[Pair, BookDetection]]:
        """Each book with the ``quality`` and ``reprojection_error_px`` of its world corners
        against both images (:func:`rovis.agreement.agreement`): until here they were its
        pair's segmentation support and its corners' triangulation residual, which the
        steps that move sides leave stale."""
        cfg = self.cfg.agreement
        thresholds = {cam: cfg.evidence * strength[cam] for cam in strength}
        Q = {"left": f.rig.Q_L, "right": f.rig.Q_R}  # (each access builds the matrix)
        out = []
        for pair, book in found:
            if not np.all(np.isfinite(book.corners_world)):  # no cover to project: none seen
                out.append((pair, replace(book, quality=0.0, reprojection_error_px=cfg.reach_px)))
                continue
            quads = {cam: geometry.project(Q[cam], book.corners_world) for cam in Q}
            quality, error_px, _ = agreement(f.grads, quads, thresholds, reach_px=cfg.reach_px)
            out.append((pair, replace(book, quality=quality, reprojection_error_px=error_px)))
        return out

    def _remember(self, f: _Frame, found: list[tuple[Pair, BookDetection]],
                  info: dict[str, SegmentationInfo]) -> None:
        """Keep what :meth:`track` needs of this frame: each book's quads and the edge
        evidence along its sides in both images (None without the desk plane)."""
        if f.desk_plane is None:
            self._tracks = None
            return
        strength = self._edge_strength(info)
        self._tracks = ([(pair, book, {
            "left": side_evidence(f.grads["left"], book.corners_left_px,
                                  self.cfg.track.evidence * strength["left"]),
            "right": side_evidence(f.grads["right"], book.corners_right_px,
                                   self.cfg.track.evidence * strength["right"])})
            for pair, book in found], info)

    def _result(self, f: _Frame, found: list[tuple[Pair, BookDetection]],
                info: dict[str, SegmentationInfo], *, lines: dict[str, Lines] | None = None,
                covers: dict[str, NDArray[np.float64]] | None = None,
                dropped: Sequence[tuple[str, NDArray[np.float64], NDArray[np.float64]]] = (),
                tracked: bool = False) -> FrameResult:
        """The frame's result, corners back in the rig's ideal pixels and in the raw
        images' (DESIGN §3)."""
        view, raw_rig = self._view, f.raw_rig

        def raw(px: NDArray[np.float64], cam: Literal["left", "right"]) -> NDArray[np.float64]:
            return raw_rig.distort_points(view.to_rig_ideal(px), cam)

        objects = [replace(book, id=i, corners_left_px=raw(book.corners_left_px, "left"),
                           corners_right_px=raw(book.corners_right_px, "right"))
                   for i, (_, book) in enumerate(found)]
        return FrameResult(
            objects=objects, desk_plane=None if f.desk_plane is None else f.desk_plane.copy(),
            world_frame=f.rig.world_frame, segmentation=info, timing_ms=f.timing,
            warnings=f.warnings, T_world_left=f.rig.T_world_left.copy(),
            lines={cam: ls.shifted(-view.offset) for cam, ls in (lines or {}).items()},
            covers={cam: view.to_rig_ideal(c) for cam, c in (covers or {}).items()},
            dropped=[(why, view.to_rig_ideal(a), view.to_rig_ideal(b)) for why, a, b in dropped],
            tracked=tracked)

    # -- stages ---------------------------------------------------------------------------

    def _view_rig(self, rig: StereoRig) -> StereoRig:
        """``self._view.rig(rig)``, built once per world frame (a registered rig's, or a
        still marker's, is the same every frame)."""
        key = rig.T_world_left.tobytes() + rig.world_frame.encode()
        if self._view_rigs is None or self._view_rigs[0] != key:
            self._view_rigs = (key, self._view.rig(rig))
        return self._view_rigs[1]

    def _rectified(self, rig: StereoRig) -> Rectification:
        """The row-aligned pair of ``rig``'s ideal images (:class:`Rectification`), made
        once per rig (it does not depend on the world frame)."""
        size = self._view.size
        key = b"".join(np.asarray(a, np.float64).tobytes()
                       for a in (rig.K1, rig.K2, rig.R, rig.T, size))
        if self._rectification is None or self._rectification[0] != key:
            self._rectification = (key, Rectification.of(rig.K1, rig.K2, rig.R, rig.T, size))
        return self._rectification[1]

    def _texture(self, ideal: dict[str, NDArray[np.uint8]]) -> dict[str, NDArray[np.float32]]:
        """Each ideal image's print (:func:`rovis.sweep.high_pass`), none beyond the raw
        field of view (its black, and the step into it, are no print)."""
        out = {cam: high_pass(img, self.cfg.sweep.sigma_px) for cam, img in ideal.items()}
        if self._view.grown:
            for cam, tex in out.items():
                tex[self._view.valid[cam] == 0] = 0.0
        return out

    def check_input(self, left: NDArray[np.generic], right: NDArray[np.generic]) -> None:
        """Raise what :meth:`detect` raises for images it cannot take (empty, of an
        unsupported type, of different sizes or not the calibration's), without detecting.

        Raises
        ------
        ValueError
        """
        self._check_sizes(to_gray_u8(left, "left image"), to_gray_u8(right, "right image"))

    def _check_sizes(self, left: NDArray[np.uint8], right: NDArray[np.uint8]) -> None:
        if left.shape != right.shape:
            raise ValueError(f"image sizes differ: left {left.shape[1]}x{left.shape[0]}, "
                             f"right {right.shape[1]}x{right.shape[0]}")
        w, h = self.rig.image_size  # type: ignore[misc]
        if left.shape != (h, w):
            raise ValueError(f"image size {left.shape[1]}x{left.shape[0]} does not match the "
                             f"calibration's {w}x{h}")

    def _find_marker(self, gray: dict[str, NDArray[np.uint8]],
                     warnings: list[str]) -> NDArray[np.float64] | None:
        """``T_world_marker`` in the rig's world, or None (with a warning) if not seen."""
        rig = self.rig
        found = {cam: marker.detect_marker(gray[cam], marker_id=self.cfg.marker_id,
                                           intrinsics=rig.intrinsics(cam)) for cam in gray}
        if found["left"] is None or found["right"] is None:
            missing = " and ".join(c for c in ("left", "right") if found[c] is None)
            warnings.append(f"marker {self.cfg.marker_id} not found in the {missing} image: "
                            "whole image searched, desk plane unknown")
            return None
        try:
            T_left_marker = marker.marker_pose_stereo(rig, found["left"].corners_px,
                                                      found["right"].corners_px,
                                                      side=self.cfg.marker_side)
        except ValueError as exc:
            warnings.append(f"marker pose failed ({exc}): whole image searched")
            return None
        return rig.T_world_left @ T_left_marker

    def _roi_mask(self, rig: StereoRig, cam: Literal["left", "right"],
                  T_world_marker: NDArray[np.float64] | None) -> NDArray[np.uint8] | None:
        """The ROI in the ideal image (of :attr:`_view`) of ``rig`` (its raw frame): the
        workspace, or without the marker the raw image's field of view (None: all of it)."""
        if T_world_marker is None:
            return self._view.valid[cam] if self._view.grown else None
        key = np.asarray(T_world_marker, dtype=np.float64).tobytes() + rig.T_world_left.tobytes()
        if cam not in self._masks or self._masks[cam][0] != key:
            roi = roi_mask(rig, cam, T_world_marker, x=self.cfg.workspace_x,
                           y=self.cfg.workspace_y, height=self.cfg.roi_height,
                           margin_px=self.cfg.roi_margin_px, view=self._view)
            self._masks[cam] = (key, cv2.bitwise_and(roi, self._view.valid[cam]))
        return self._masks[cam][1]

    def _transfer(self, rig: StereoRig, segs: dict[str, Segmentation], grads: dict[str, Gradients],
                  ideal: dict[str, NDArray[np.uint8]], kept: list[tuple[Match, Pair]],
                  desk_plane: NDArray[np.float64] | None,
                  texture: dict[str, NDArray[np.float32]] | None = None) -> list[Pair]:
        """Covers found in one image only, looked for in the other (find_in_other_view;
        where that finds nothing, a printed cover by its print, :func:`rovis.sweep.find_by_print`;
        where neither finds anything, the same for the quad's first alternatives).

        ``kept``: the matched pairs that made books, each with the pair it became (its
        quads may be alternatives of the matched ones, or moved by the print test)."""
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        used = {"left": {mt.left for mt, _ in kept}, "right": {mt.right for mt, _ in kept}}
        taken = {"left": [pair.left for _, pair in kept], "right": [pair.right for _, pair in kept]}
        # Best-supported first: where the two images' segmentations disagree (a union of two
        # touching covers in one, one of them in the other), the cleaner quad wins. Without
        # the desk plane, the largest first: no height tells a cover from the rectangles
        # printed on it (on the real chessboard pairs, blocks of the board's squares), and
        # the cover is the one around them.
        def rank(src: str, k: int) -> float:
            if desk_plane is None:
                return float(abs(_shoelace(segs[src].corners[k][None])[0]))
            return float(segs[src].support[k])

        todo = sorted(((rank(src, k), src, dst, k)
                       for src, dst in (("left", "right"), ("right", "left"))
                       for k in range(len(segs[src])) if k not in used[src]), reverse=True)
        out = []
        n_alt = self.cfg.stereo.transfer_alternatives
        for _, src, dst, k in todo:
            quality = float(segs[src].support[k])
            if desk_plane is None and quality < self.cfg.stereo.free_transfer_support:
                continue  # the plane and depth come from the quad alone: a clean one only
            overlap = self.cfg.stereo.transfer_max_overlap
            if any(quad_overlap(segs[src].corners[k], q) > overlap for q in taken[src]):
                continue  # already a book, from the other image's quad
            # where the quad finds nothing, its first alternatives (the cover of an outline)
            alts = segs[src].alternatives[k][:n_alt] if k < len(segs[src].alternatives) else ()
            found = None
            for a, source in enumerate([segs[src].corners[k], *alts]):
                if a > 0:
                    source = order_corners(refine_quad(grads[src], source))
                    if any(quad_overlap(source, q) > overlap for q in taken[src]):
                        continue
                # the other image's Canny low threshold (LSD and contours set none: the open loop's)
                T_H = segs[dst].T_H or segs[src].T_H or self.cfg.segment.open_T_H
                found = find_in_other_view(source, Q[src], Q[dst], desk_plane, grads[dst],
                                           CANNY_LOW_RATIO * T_H, gray_from=ideal[src],
                                           gray_to=ideal[dst], cfg=self.cfg.stereo)
                if found is None and texture is not None and desk_plane is not None \
                        and self.cfg.sweep.transfer:
                    # no edges to refit there: a printed cover is placed by its print alone
                    placed = find_by_print(texture[src], texture[dst], Q[src], Q[dst], source,
                                           desk_plane, self.cfg.stereo.min_height, self.cfg.sweep)
                    found = None if placed is None else (placed,)
                if found is not None and not any(quad_overlap(found[0], q) > overlap
                                                 for q in taken[dst]):
                    break
                found = None
            if found is None:
                continue
            taken[src].append(source)
            taken[dst].append(found[0])
            c = {src: source, dst: found[0]}
            # keep eq. 1's order in the left image, the right's corners corresponding
            out.append(_in_eq1_order(Pair(c["left"], c["right"], quality, 0.0, transferred=src)))
        return out

    def _from_pool(self, rig: StereoRig, segs: dict[str, Segmentation],
                   grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                   desk_plane: NDArray[np.float64],
                   texture: dict[str, NDArray[np.float32]] | None,
                   refined: Refined | None = None, *,
                   extra: Literal["late", "small", "small_open"] | None = None,
                   ) -> list[tuple[Pair, BookDetection]]:
        """Books from the two images' candidate pools (:attr:`Segmentation.pool`, then
        :attr:`Segmentation.open_pool`) where no book is yet; with ``extra``, only the pairs
        with a quad of :attr:`Segmentation.small_pool` with every side seen (``"small"``:
        the candidates smaller than a cover of one image), of :attr:`Segmentation.late_pool`
        (``"late"``: the closed loop's other T_H), or of the small pool with sides unseen
        (``"small_open"``: ``SegmentConfig.small_open``; any other pool's quad may be the
        partner). The late and small_open passes' books must reproject within
        ``stereo.late_max_reprojection_px``; a small_open book must not be the desk between
        books found (two sides on their outlines), unless its print places it at its own
        height and no book whose outline holds one of its sides stands within
        ``stereo.small_open_apart`` of it (``stereo.small_open_between``), and is marked
        ``Pair.small_open`` (:meth:`_without_small`'s own bound).

        The pairs of Hough quads that roughly make a flat, book-sized rectangle
        (:func:`rovis.stereo.pool_pairs`) are refined in both images (Hough corners are
        too coarse for a height: 1 px of disparity is ~1.5 cm) and kept if the refined
        pair still matches and is one (:func:`rovis.stereo.flat_rectangle`, the pose
        checks' limits; failing that, refined without the inward search for the cover
        edge, :func:`rovis.segment.boundary.refine_quad`'s ``down``, in one image or
        both). The most edge pixels in both images first, each must pass the pose
        checks; a pair whose left quad holds two or more such pairs that fill it is taken
        for the union of touching books and gives way to them, and one whose book covers
        more than ``stereo.pool_taller_share`` of the desk footprint of a taller pair gives
        way to that pair, asked again after the other flat pairs. A pair with two sides
        unseen in either image (a two-sided candidate) must also show a step along each
        refined side in both images and have its corners at one height. A pair with a side
        neither image saw that fails those tests is completed in 3D instead
        (:func:`rovis.extent.complete_open`), after every pair that refined flat; one with
        every side seen is refit as one rectangle parallel to the desk (as
        :meth:`_flat_refit`, at most ``stereo.pool_flat_refits`` per pass), after those.
        """
        cfg = self.cfg
        overlap = cfg.stereo.transfer_max_overlap
        # the projections, made once for the pass (rig.Q_L makes its matrix again each time
        # it is read: flat reads both for every try of a pair)
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        up = desk_plane / np.linalg.norm(desk_plane[:3])
        on_desk, _, e1, e2 = _plane_frame(desk_plane)
        # the full candidates and those with one side unseen (Segmentation.open_pool),
        # then the small and the late pool: a refined quad is cached by its index in this
        # order, the same in every pass
        late = extra in ("late", "small_open")
        parts = {cam: [segs[cam].pool, segs[cam].open_pool, segs[cam].small_pool]
                 + ([segs[cam].late_pool] if late else []) for cam in ("left", "right")}
        pool = {cam: Quads.concat(parts[cam]) for cam in parts}
        # each quad's kind: 0 the full and open pools, 1 a small one with every side seen,
        # 2 a small one with sides unseen (SegmentConfig.small_open), 3 the late pool; the
        # kinds a pass may pair, and those each of its pairs must have one of
        kind = {cam: np.concatenate([
            np.zeros(len(parts[cam][0]) + len(parts[cam][1]), np.intp),
            np.where((parts[cam][2].lines < 0).any(axis=1), 2, 1) if len(parts[cam][2])
            else np.zeros(0, np.intp),
            np.full(len(pool[cam]) - sum(len(q) for q in parts[cam][:3]), 3, np.intp)])
            for cam in pool}
        usable, own = {None: ((0,), (0,)), "small": ((0, 1), (1,)), "late": ((0, 3), (3,)),
                       "small_open": ((0, 1, 2, 3), (2,))}[extra]
        taken = {"left": [p.left for p, _ in found], "right": [p.right for p, _ in found]}
        over = {cam: _over_any(pool[cam].corners, taken[cam], overlap) for cam in pool}
        index = {cam: np.flatnonzero(np.isin(kind[cam], usable) & ~over[cam]) for cam in pool}

        def pairs(at_left: NDArray[np.intp], at_right: NDArray[np.intp]) -> PoolPairs:
            # pool_pairs of the quads at those positions of `index`, as positions of `index`
            ql, qr = index["left"][at_left], index["right"][at_right]
            got = pool_pairs(pool["left"].corners[ql], pool["right"].corners[qr],
                             rig.Q_L, rig.Q_R, desk_plane=desk_plane,
                             side_range=(0.8 * cfg.min_cover_side, 1.1 * cfg.max_cover_side),
                             cfg=cfg.stereo, seen_left=pool["left"].lines[ql] >= 0,
                             seen_right=pool["right"].lines[qr] >= 0)
            return replace(got, left=at_left[got.left], right=at_right[got.right])

        every = {cam: np.arange(len(index[cam])) for cam in index}
        if extra is None:
            pp = pairs(every["left"], every["right"])
        else:
            # only the pairs with a quad of this pass's own (the others were tried before):
            # its own left ones with every right one, the other left ones with its own
            # right ones, in the order one call over all would give (pool_pairs judges
            # each pair alone)
            mine = {cam: np.isin(kind[cam][index[cam]], own) for cam in index}
            pp = PoolPairs.concat([pairs(every["left"][mine["left"]], every["right"]),
                                   pairs(every["left"][~mine["left"]],
                                         every["right"][mine["right"]])])
            pp = pp.take(np.lexsort((pp.right, pp.left)))
        if len(pp) == 0:
            return []
        i, j = index["left"][pp.left], index["right"][pp.right]
        # A candidate with two sides unseen (rovis.segment.quads.two_sided_quads) closes an
        # L where its two sides' edges end: between two books, or over a paper, that is
        # often no cover. Each of its refined sides must show a step across it at half
        # the Canny low threshold, along StereoConfig.two_sided_evidence of its length,
        # and its corners lie within StereoConfig.two_sided_flatness of one height.
        evidence = 0.5
        strength = self._edge_strength(segs)

        def two_open(quads: Quads, k: int) -> bool:
            return bool(np.count_nonzero(quads.lines[k] < 0) >= 2)

        # most two-sided candidates show no step anywhere near their guessed sides: those
        # are not worth a refinement (a coarse look first: within 3 px, along 30 %)
        plausible: dict[tuple[str, int], bool] = {}
        let_in: set[tuple[str, int]] = set()  # the candidates only the plain rule let in

        def worth(cam: str, k: int) -> bool:
            if (cam, k) not in plausible:
                quad = pool[cam].corners[k]
                ev = (side_evidence(grads[cam], quad, evidence * strength[cam], reach_px=3.0)
                      if two_open(pool[cam], k) else None)
                plausible[cam, k] = ev is None or ev.min() >= 0.3
                # ...but a plain one whose two sides are clear may be a cover of the desk's
                # tone, its far sides against the desk: completed where those sides end
                if not plausible[cam, k] and (
                        cfg.complete.enabled and cfg.complete.at_ends
                        and ev[pool[cam].lines[k] >= 0].min() >= 0.9
                        and strong_share(grads[cam], quad, strength[cam])
                        <= cfg.complete.plain_share):
                    plausible[cam, k] = True
                    let_in.add((cam, k))
            return plausible[cam, k]

        keep = np.flatnonzero([worth("left", a) and worth("right", b)
                               for a, b in zip(i.tolist(), j.tolist())])
        i, j, pp = i[keep], j[keep], pp.take(keep)
        if len(pp) == 0:
            return []
        # on busy texture (thousands of pairs of candidates) only those closest to their
        # epipolar segments are refined, which bounds the time
        most = (cfg.stereo.small_max_pairs if extra in ("small", "small_open")
                else cfg.stereo.pool_max_pairs)
        order = np.sort(np.argsort(pp.error_px, kind="stable")[:most])
        i, j, pp = i[order], j[order], pp.take(order)
        cache: Refined = {} if refined is None else refined

        def fitted(cam: str, k: int) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                              list[Fit | None]]:
            # with and without the inward search at once: most pairs are tried both ways
            key = (cam, pool[cam].corners[k].tobytes())
            if key not in cache:
                cache[key] = refine_quad_fits(grads[cam], pool[cam].corners[k])
            return cache[key]

        def sub_pixel(cam: str, k: int, inward: bool = True) -> NDArray[np.float64]:
            return fitted(cam, k)[0 if inward else 1]

        def flat(left: NDArray[np.float64], right: NDArray[np.float64]) -> NDArray[np.bool_]:
            P = geometry.triangulate_dlt(Q["left"], Q["right"], left.reshape(-1, 2),
                                         right.reshape(-1, 2)).reshape(-1, 4, 3)
            return flat_rectangle(P, desk_plane, side_range=(0.8 * cfg.min_cover_side,
                                                             cfg.max_cover_side),
                                  max_tilt_deg=cfg.max_tilt_deg,
                                  height_range=(cfg.stereo.min_height,
                                                cfg.stereo.max_cover_height))

        def refine_pairs(index: NDArray[np.intp], inward: tuple[bool, bool],
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
            left = np.array([sub_pixel("left", k, inward[0]) for k in i[index].tolist()])
            right = np.array([np.roll(sub_pixel("right", k, inward[1]), -s, axis=0)
                              for k, s in zip(j[index].tolist(), pp.shift[index].tolist())])
            return left.reshape(-1, 4, 2), right.reshape(-1, 4, 2)

        # Each pair is refined when its turn comes, not all up front: most pairs lie over a
        # book an earlier pair gave, and are passed over on their Hough quads alone.
        left, right = np.zeros((len(i), 4, 2)), np.zeros((len(i), 4, 2))
        ok, settled = np.zeros(len(i), bool), np.zeros(len(i), bool)
        as_refined = np.zeros((len(i), 4, 2))  # the left quads as refined (what a union is of)

        def settle(index: NDArray[np.intp]) -> None:
            index = index[~settled[index]]
            if len(index) == 0:
                return
            l1, r1 = refine_pairs(index, (True, True))
            good = flat(l1, r1)
            # whether the inward search moved a side of each pair's quad, per image: where
            # it did not, the quad without it is the same, and a try of the pair with that
            # quad is one made before (it failed: not made again, not asked of flat)
            moved = {cam: np.array([not np.array_equal(*fitted(cam, k)[:2])
                                    for k in ks.tolist()], bool)
                     for cam, ks in (("left", i[index]), ("right", j[index]))}
            # The refinement looks for a cover edge inside a side facing the camera (a page
            # block below it); a printed line there can pull one image's side inward and
            # tilt the cover. A pair that is no flat cover so is tried without that step,
            # in one image, then in both.
            for inward in ((False, True), (True, False), (False, False)):
                retry = np.flatnonzero(~good)
                if len(retry) == 0:
                    break
                for cam, search in zip(("left", "right"), inward):
                    if not search:
                        retry = retry[moved[cam][retry]]
                if len(retry) == 0:
                    continue
                l2, r2 = refine_pairs(index[retry], inward)
                better = flat(l2, r2)
                l1[retry[better]], r1[retry[better]] = l2[better], r2[better]
                good[retry[better]] = True
            left[index], right[index], ok[index], settled[index] = l1, r1, good, True
            as_refined[index] = l1

        # A pair with sides unseen whose refined guesses still make no flat cover: its
        # unseen sides placed in 3D instead, from the seen ones (rovis.extent.complete_open)
        completed = np.zeros(len(i), bool)
        side_fits: dict[tuple[str, int], list[Fit | None]] = {}

        def fits_of(cam: str, k: int) -> list[Fit | None]:
            # each candidate's seen sides fitted once, for every pair it is in (the fits
            # its refinement made: it is refined before it is completed)
            if (cam, k) not in side_fits:
                side_fits[cam, k] = [f if pool[cam].lines[k, s] >= 0 else None
                                     for s, f in enumerate(fitted(cam, k)[2])]
            return side_fits[cam, k]

        def seen(a: int) -> dict[str, NDArray[np.bool_]]:
            # which sides each image's candidate saw, in the left candidate's corner order
            return {"left": pool["left"].lines[i[a]] >= 0,
                    "right": np.roll(pool["right"].lines[j[a]] >= 0, -int(pp.shift[a]))}

        def all_seen(a: int) -> bool:  # every side seen in one image or the other
            sides = seen(a)
            return bool(np.all(sides["left"] | sides["right"]))

        def completable(a: int) -> bool:  # a side neither image saw
            return cfg.complete.enabled and not all_seen(a)

        def between_books(P: NDArray[np.float64]) -> bool:
            # the desk between books found: two sides of the rectangle (4, 3) theirs
            return any(_sides_on(geometry.project(Q[cam], P),
                                 _outlines(Q[cam], cam, found + out, up)).sum() >= 2
                       for cam in Q)

        def unseen_asked(a: int, P: NDArray[np.float64], height: float) -> list[int]:
            # the unseen sides of the completed cover P (4, 3) whose print is asked about:
            # not one along a book found taller, half of it within the strip's far bound of
            # that book's outline in the left image (complete.print_taller)
            sides_seen = seen(a)
            sides = np.flatnonzero(~(sides_seen["left"] | sides_seen["right"]))
            if not cfg.complete.print_taller or len(sides) == 0:
                return sides.tolist()
            taller = [(p, b) for p, b in found + out
                      if b.pose.size[2] >= height + cfg.complete.taller_by]
            if taller:
                beside = _sides_on(geometry.project(Q["left"], P),
                                   _outlines(Q["left"], "left", taller, up),
                                   tol_px=cfg.sweep.strip_px[1])
                sides = sides[~beside[sides]]
            return sides.tolist()

        def complete(a: int) -> bool:
            if not completable(a):
                return False
            shift = int(pp.shift[a])
            asked: list[float | None] = []  # the print's height, where complete_open asks

            def by_print() -> float | None:
                # the candidate's guessed sides may be off: the sweep's inset spares them
                assert texture is not None
                asked.append(print_height(texture["left"], texture["right"], Q["left"], Q["right"],
                                          pool["left"].corners[i[a]], desk_plane, cfg.sweep))
                return asked[-1]

            P = complete_open(
                {"left": pool["left"].corners[i[a]],
                 "right": np.roll(pool["right"].corners[j[a]], -shift, axis=0)},
                seen(a), Q, grads, strength, desk_plane,
                cfg.complete,
                height_range=(cfg.stereo.min_height, cfg.stereo.max_cover_height),
                side_range=(0.8 * cfg.min_cover_side, cfg.max_cover_side),
                fits={"left": fits_of("left", int(i[a])),
                      "right": [fits_of("right", int(j[a]))[(s + shift) % 4] for s in range(4)]},
                print_height=None if texture is None else by_print,
                ends_refused=between_books)
            if P is None or not flat(geometry.project(Q["left"], P)[None],
                                     geometry.project(Q["right"], P)[None])[0]:
                return False
            if texture is not None and asked and asked[0] is not None and print_goes_on(
                    texture["left"], texture["right"], Q["left"], Q["right"],
                    geometry.project(Q["left"], P), desk_plane, asked[0], cfg.sweep,
                    sides=unseen_asked(a, P, asked[0])):
                return False  # an unseen side placed on a band of the print
            if texture is not None and self._print_on_desk(rig, geometry.project(Q["left"], P),
                                                           desk_plane, texture):
                return False
            if ({("left", int(i[a])), ("right", int(j[a]))} & let_in) and between_books(P):
                return False
            left[a], right[a] = geometry.project(Q["left"], P), geometry.project(Q["right"], P)
            completed[a] = True
            return True

        # the pairs that refine to a flat cover, the most edge pixels first; then those
        # with sides unseen that did not, completed in 3D when their turn comes (most are
        # over a book found by then)
        score = pool["left"].n_f[i] + pool["right"].n_f[j]
        order = np.argsort(-score, kind="stable")
        coarse = {"left": pool["left"].corners[i], "right": pool["right"].corners[j]}
        coarse_area = np.array([cv2.contourArea(q.astype(np.float32)) for q in coarse["left"]])
        out: list[tuple[Pair, BookDetection]] = []

        def free(a: int) -> bool:
            return not (any(quad_overlap(left[a], t) > overlap for t in taken["left"])
                        or any(quad_overlap(right[a], t) > overlap for t in taken["right"]))

        def over_found(a: int) -> bool:
            # Hough quads over a book found by twice the share that makes a refined pair
            # not free. Refinement may move a side by up to a page-block strip (25 px), so
            # this is a measured rule, not a bound: on the development sets no pair whose
            # Hough quads overlapped a found book by more than that share came out free
            # once refined (docs/stereo.md, step 4; skipping them saves most of this step)
            return any(quad_overlap(coarse[cam][a], t) > 2 * overlap
                       for cam in ("left", "right") for t in taken[cam])

        def union(a: int) -> bool:
            # _is_union over the flat pairs whose left quads may lie inside this one (their
            # Hough quads overlap it by half), each refined if not yet. Of two parts 90 %
            # inside it, overlapping by at most `overlap` of the smaller, the smaller covers
            # at most 1 / (1.8 - overlap) of it (0.9 p1 + (0.9 - overlap) p2 <= 1, p2 <= p1;
            # 2/3 at 0.3): where no Hough quad inside is under 1.2 times that (a margin for
            # what refinement moves), there is no union and nothing to refine
            inside = np.array([b for b in order.tolist() if b != a
                               and quad_overlap(coarse["left"][b], as_refined[a]) > 0.5],
                              dtype=np.intp)
            a_area = cv2.contourArea(as_refined[a].astype(np.float32))
            if not np.any(coarse_area[inside] < 1.2 / (1.8 - overlap) * a_area):
                return False
            settle(inside)
            parts = np.concatenate([[a], inside[ok[inside]]])
            area = np.array([cv2.contourArea(q.astype(np.float32)) for q in as_refined[parts]])
            return _is_union(0, as_refined[parts], area, overlap)

        def as_pair(a: int) -> Pair:  # eq. 1 order, kept after refinement
            quality = float(min(pool["left"].support[i[a]].mean(),
                                pool["right"].support[j[a]].mean()))
            return _in_eq1_order(Pair(left[a], right[a], quality, float(pp.error_px[a]),
                                      source="candidates", small_open=extra == "small_open"))

        def own_between(book: BookDetection) -> bool:
            # A small cover between books found, its sides on theirs, is a book of its own
            # where its print matches between the images at its height, clearly better
            # than on the desk, and every book whose outline holds one of its sides
            # stands higher or lower: a piece of that book (cut at a band of its print,
            # flush with it) stands at its height, and the desk shows its own grain. The
            # sweep runs over the whole height range: a taller neighbour's print inside
            # the quad, matching best at its own height, refuses it too.
            sc = cfg.stereo
            if not sc.small_open_between or texture is None:
                return False
            P = book.corners_world
            height = float(book.pose.size[2])
            books = found + out  # (the neighbours first: no sweep where one refuses it)
            for cam in Q:
                quad = geometry.project(Q[cam], P)
                for (_, other), outline in zip(books, _outlines(Q[cam], cam, books, up)):
                    if (abs(float(other.pose.size[2]) - height) < sc.small_open_apart
                            and _sides_on(quad, [outline]).any()):
                        return False
            tol = max(sc.small_open_print_tol, 0.25 * height)
            top = max(cfg.sweep.max_height, height + 2 * tol)
            sweep = sweep_heights(texture["left"], texture["right"], Q["left"], Q["right"],
                                  geometry.project(Q["left"], P), desk_plane,
                                  np.arange(0.0, top + 1e-9, cfg.sweep.step),
                                  inset=cfg.sweep.inset, max_samples=cfg.sweep.max_samples)
            return not (sweep is None or abs(sweep.best_height - height) > tol
                        or sweep.best_ncc < sc.small_open_print_ncc
                        or sweep.best_ncc - sweep.ncc[0] < sc.small_open_print_gap)  # [0]: desk

        def kept_back(book: BookDetection) -> bool:
            # a book the pass does not take though the pose checks pass
            if late and book.reprojection_error_px > cfg.stereo.late_max_reprojection_px:
                return True
            # (small_open) the desk between books: its sides theirs; but not a book of its
            # own there (stereo.small_open_between)
            return extra == "small_open" and between_books(book.corners_world) \
                and not own_between(book)

        considered = np.zeros(len(i), bool)  # the pairs asked of consider so far
        hough_height: dict[int, float] = {}  # each pair's, on its Hough corners (gives_way)

        def gives_way(a: int, pair: Pair, book: BookDetection) -> bool:
            # Whether the book pair a makes reaches over a pool pair standing taller
            # (StereoConfig.pool_taller_share). Asked of the pairs not yet considered whose
            # Hough quads lie over the book's left quad, leave 40 % of it or more uncovered
            # (the book's own part; not its quad again, at another disparity: a mismatch),
            # stand higher than the book on their Hough corners and have one side unseen
            # at most (two guessed sides put a pair anywhere), each refined if not yet, and
            # reconstructed where it stands taller over the book's footprint
            share = cfg.stereo.pool_taller_share
            if share >= 1.0:
                return False
            height = float(book.pose.size[2])

            def higher(b: int) -> bool:  # on the Hough corners, a centimetre or so off
                if b not in hough_height:
                    right_b = np.roll(coarse["right"][b], -int(pp.shift[b]), axis=0)
                    P = geometry.triangulate_dlt(Q["left"], Q["right"], coarse["left"][b],
                                                 right_b)
                    hough_height[b] = float(np.mean(geometry.plane_distance(desk_plane, P)))
                return hough_height[b] > height

            near = np.array([b for b in order.tolist() if not considered[b]
                             and quad_overlap(coarse["left"][b], pair.left) > 0.1
                             and _shared(pair.left, coarse["left"][b]) <= 0.6
                             and not (two_open(pool["left"], i[b])
                                      or two_open(pool["right"], j[b]))
                             and not over_found(b) and higher(b)], dtype=np.intp)
            if len(near) == 0:
                return False
            settle(near)
            mine = _in_desk_plane(np.asarray(book.corners_world), on_desk, e1, e2)
            for b in near[ok[near]].tolist():
                P = geometry.triangulate_dlt(Q["left"], Q["right"], left[b], right[b])
                heights = geometry.plane_distance(desk_plane, P)
                # one height (a pair over two surfaces has none), and refined, still no
                # more than 60 % of the book's quad
                if (np.ptp(heights) > cfg.stereo.two_sided_flatness
                        or np.mean(heights) < height + cfg.complete.taller_by
                        or _shared(pair.left, left[b]) > 0.6):
                    continue
                theirs = _in_desk_plane(P, on_desk, e1, e2)
                inside, _ = cv2.intersectConvexConvex(mine, theirs)
                if inside <= share * cv2.contourArea(theirs):
                    continue
                # ...and it makes a book that tall, by the checks its own turn asks: a
                # mismatch over a printed cover is laid at the print's height or dropped
                _, taller, _ = self._reconstruct_or_why(rig, as_pair(b), desk_plane, texture)
                if taller is not None and not kept_back(taller) and \
                        float(taller.pose.size[2]) >= height + cfg.complete.taller_by:
                    return True
            return False

        gave_way: list[int] = []  # the pairs considered again, after the others

        def consider(a: int, again: bool = False) -> None:
            considered[a] = True
            if not free(a) or (ok[a] and union(a)):
                return
            if not ok[a] and not (complete(a) and free(a)):
                return
            if not completed[a] and (two_open(pool["left"], i[a]) or two_open(pool["right"], j[a])):
                # two sides guessed: each side must show a step in both images, and the
                # corners lie at one height (a guessed corner is off in depth)
                step = min(side_evidence(grads[cam], q, evidence * strength[cam]).min()
                           for cam, q in (("left", left[a]), ("right", right[a])))
                heights = geometry.plane_distance(
                    desk_plane, geometry.triangulate_dlt(Q["left"], Q["right"], left[a], right[a]))
                if (step < cfg.stereo.two_sided_evidence
                        or np.ptp(heights) > cfg.stereo.two_sided_flatness) and not (
                        complete(a) and free(a)):
                    return
            pair, book, _ = self._reconstruct_or_why(rig, as_pair(a), desk_plane, texture)
            if book is None or kept_back(book):
                return
            if ok[a] and not again and gives_way(a, pair, book):
                gave_way.append(a)
                return
            taken["left"].append(pair.left)
            taken["right"].append(pair.right)
            out.append((pair, book))

        deferred: list[int] = []
        unflat: list[int] = []
        for a in order.tolist():  # the flat pairs, as their turn comes
            if over_found(a):
                continue
            settle(np.array([a]))
            if ok[a]:
                consider(a)
            elif completable(a):
                deferred.append(a)
            elif all_seen(a):
                unflat.append(a)
        for a in gave_way:  # then those that gave way to a taller pair, if still free
            consider(a, again=True)
        for a in deferred:  # then the pairs to complete in 3D, in the same order
            consider(a)
        # Last, the pairs with every side seen that refined to no flat cover: far from the
        # camera a pixel of disparity is 2 cm, and the corners come out 1-3 cm apart in
        # height (build/t1b scene 23's 13 mm book, 1.3 m away: 4-14 mm). Each is refit as
        # one rectangle parallel to the desk (_flat_refit, a side on its page block's foot
        # in one image moved first; a least-squares fit and the pose checks, so at most
        # stereo.pool_flat_refits of them, of those still free).
        # After the completions: a refit pair may be a cover in one image and its outline
        # in the other, made flat too high.
        tries = cfg.stereo.pool_flat_refits if cfg.flat_refit_px > 0 else 0
        for a in unflat:
            if tries <= 0:
                break
            if over_found(a) or not free(a):
                continue
            tries -= 1
            refit = self._flat_refit(rig, Pair(left[a], right[a], 1.0, 0.0), desk_plane, None)
            if refit is not None:
                left[a], right[a], ok[a] = refit[0].left, refit[0].right, True
                consider(a, again=True)  # (every pair it might give way to had its turn)
        return out

    def _from_pool_one_image(self, rig: StereoRig, segs: dict[str, Segmentation],
                             grads: dict[str, Gradients], ideal: dict[str, NDArray[np.uint8]],
                             found: list[tuple[Pair, BookDetection]],
                             desk_plane: NDArray[np.float64],
                             texture: dict[str, NDArray[np.float32]] | None,
                             refined: Refined,
                             ) -> list[tuple[Pair, BookDetection]]:
        """Books where no book is yet from one image's candidate quads
        (:attr:`Segmentation.pool` and :attr:`Segmentation.open_pool`, then
        :attr:`Segmentation.late_pool`: ``StereoConfig.pool_transfer_late``), each looked
        for in the other image (:func:`rovis.stereo.find_in_other_view`).

        What this finds: two plain books end to end, of the desk's tone. Where one's end
        touches the other's no edge shows, in either image, so neither is a segmented cover
        and no pair of candidates makes one (the other image's Hough lines miss a faint
        side); but one image's candidate, refined, lies on the cover's edges, its end on
        the step where the two books' widths differ (a jog). Such a candidate, whose own
        image shows each side along ``StereoConfig.pool_transfer_seen`` of it, or all but
        one (that along ``pool_transfer_part`` at least), is looked for in the other image
        at each height, that side excused there too. The first
        ``StereoConfig.pool_transfer_max`` candidates per image that overlap no book and
        differ from those tried before (a corner more than 3 px away) are tried, the most
        edge pixels first (as many again of the late pool, after them), those that show two
        sides or more along less than ``pool_transfer_seen`` at a coarse look (within 3 px)
        not refined. None may have two
        sides on the outlines of books found by then (cover and page block), nor (with
        ``texture``) print inside that matches best on the desk: desk between books, its
        sides theirs. Each must pass the pose checks.

        A candidate with a side unseen is laid flat on its sides but, in the other image,
        that one and its opposite (:func:`_transferred_fit`; ``pool_transfer_fit``), or
        else reconstructed as it is. Only the fit makes a book of one from the late pool,
        or of one the other image shows only with a side along the epipolar lines short
        as well (``find_in_other_view``'s ``along_short``, asked after the strict look).
        Any other whose fit missed only its own image's unseen side, and of which no book
        came, is fitted again once every candidate of both images is tried, that side
        excused up to ``pool_transfer_excuse_px`` (a seam closes it askew), where it still
        lies over no book and has no two sides on the outlines of those found by then.
        """
        cfg = self.cfg.stereo
        overlap = cfg.transfer_max_overlap
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        taken = {"left": [p.left for p, _ in found], "right": [p.right for p, _ in found]}
        up = desk_plane / np.linalg.norm(desk_plane[:3])

        def meet(quads: NDArray[np.float64], cam: str) -> NDArray[np.bool_]:
            # (N, T): whether each quad's box meets each book's quad's box in the image
            if not taken[cam]:
                return np.zeros((len(quads), 0), bool)
            t = np.asarray(taken[cam])
            return ~np.any((t.min(axis=1)[None] > quads.max(axis=1)[:, None])
                           | (t.max(axis=1)[None] < quads.min(axis=1)[:, None]), axis=2)

        def over_taken(cam: str, q: NDArray[np.float64],
                       near: NDArray[np.bool_] | None = None) -> bool:
            # quad_overlap with the books' quads whose boxes meet q's (``near``: those
            # of the first len(near) books, known; the rest looked at)
            if near is None:
                near = meet(q[None], cam)[0]
            rest = np.arange(len(near), len(taken[cam]))
            return any(quad_overlap(q, taken[cam][t]) > overlap
                       for t in np.concatenate([np.flatnonzero(near), rest]))

        fit = (cfg.pool_transfer_fit and self.cfg.flat_refit_px > 0
               and self.cfg.flat_refit_sides > 0)
        out: list[tuple[Pair, BookDetection]] = []
        excused: list[tuple[Pair, str, int]] = []  # (pair, dst, unseen) to fit excused
        for src, dst in (("left", "right"), ("right", "left")):
            # the pool and open pool, then the late pool (Segmentation.late_pool: the other
            # T_H's candidates with sides unseen), each the most edge pixels first, the
            # first pool_transfer_max of each tried
            late = len(segs[src].pool) + len(segs[src].open_pool)
            extra = [segs[src].late_pool] if cfg.pool_transfer_late else []
            pool = Quads.concat([segs[src].pool, segs[src].open_pool] + extra)
            order = (np.argsort(-pool.n_f[:late], kind="stable").tolist()
                     + (late + np.argsort(-pool.n_f[late:], kind="stable")).tolist())
            around = _outlines(Q[src], src, found + out, up)
            tried: list[NDArray[np.float64]] = []
            count = [0, 0]  # tried of the pools, of the late pool
            near = meet(pool.corners, src)  # (a book found below is looked at in full)
            for k in order:
                if min(count) >= cfg.pool_transfer_max:
                    break
                if count[int(k >= late)] >= cfg.pool_transfer_max:
                    continue
                if over_taken(src, pool.corners[k], near[k]):
                    continue
                # the pool holds many variants of one quad (other Hough lines of its sides,
                # other T_H): one whose every corner is within 3 px of a tried one's adds
                # nothing (but variants further apart do: one fails the pose checks where
                # the next passes)
                if any(np.abs(pool.corners[k] - t).max() <= 3.0 for t in tried):
                    continue
                tried.append(pool.corners[k])
                count[int(k >= late)] += 1
                # a coarse look first (within 3 px): a candidate that shows two sides or
                # more along less than pool_transfer_seen is not worth a refinement
                coarse = side_evidence(grads[src], pool.corners[k], 0.5 * strength[src],
                                       reach_px=3.0)
                if np.sort(coarse)[1] < cfg.pool_transfer_seen:
                    continue
                key = (src, pool.corners[k].tobytes())
                quad = order_corners(refined[key][0] if key in refined
                                     else refine_quad(grads[src], pool.corners[k]))
                if over_taken(src, quad):
                    continue
                shown = side_evidence(grads[src], quad, 0.5 * strength[src])
                part = shown < cfg.pool_transfer_seen
                if part.sum() > 1 or shown.min() < cfg.pool_transfer_part:
                    continue
                if _sides_on(quad, around).sum() >= 2:
                    continue  # desk between found books: its sides are theirs
                unseen = int(np.argmin(shown)) if part.any() else None
                if unseen is not None and k >= late and not fit:
                    continue  # (only the fit makes a book of it)
                look = dict(gray_from=ideal[src], gray_to=ideal[dst], unseen=unseen, cfg=cfg)
                there = find_in_other_view(quad, Q[src], Q[dst], desk_plane, grads[dst],
                                           strength[dst], **look)
                # only the fit below makes a book of a late candidate with a side unseen
                # (the other T_H's candidates hold shadows and the desk's grain), or of one
                # whose other image shows a side along the epipolar lines short as well
                fit_only = unseen is not None and k >= late
                if there is None and unseen is not None and fit:
                    there = find_in_other_view(quad, Q[src], Q[dst], desk_plane, grads[dst],
                                               strength[dst], along_short=True, **look)
                    fit_only = True
                if there is None or over_taken(dst, there[0]):
                    continue
                c = {src: quad, dst: there[0]}
                if texture is not None and self._print_on_desk(rig, c["left"], desk_plane,
                                                               texture):
                    continue  # desk between books, its sides theirs
                raw = Pair(c["left"], c["right"], float(pool.support[k].mean()), 0.0,
                           transferred=src)
                book, P = None, None
                if unseen is not None and fit:
                    # the unseen side placed nothing in the other image: the cover laid
                    # flat on the sides that did (_transferred_fit), where that is a book
                    P = _transferred_fit(rig, raw, dst, unseen, desk_plane,
                                         self.cfg.flat_refit_sides)
                    if P is not None:
                        pair, book, _ = self._reconstruct_or_why(
                            rig, _in_eq1_order(_pair_at(rig, raw, P)), desk_plane, texture)
                if book is None and not fit_only:
                    pair, book, _ = self._reconstruct_or_why(rig, _in_eq1_order(raw),
                                                             desk_plane, texture)
                if book is None and P is None and unseen is not None and fit \
                        and not fit_only and cfg.pool_transfer_excuse_px > 0:
                    excused.append((raw, dst, unseen))  # (the fit may miss that side: below)
                if book is None:
                    continue
                taken["left"].append(pair.left)
                taken["right"].append(pair.right)
                around += _outlines(Q[src], src, [(pair, book)], up)
                out.append((pair, book))
        # last, where no book lies yet, the candidates of the strict look whose fit missed
        # their own image's unseen side: placed where the edges beside it end, at a seam
        # (two plain books end to end) it is a few pixels off and askew. Fitted again with
        # that side excused, up to pool_transfer_excuse_px; after every candidate of both
        # images, so that one which makes a book as it is comes first (on the nine sets:
        # the same books as in each candidate's turn)
        for raw, dst, unseen in excused:
            src = "left" if dst == "right" else "right"
            quad = getattr(raw, src)
            if over_taken(src, quad) or over_taken(dst, getattr(raw, dst)):
                continue
            if _sides_on(quad, _outlines(Q[src], src, found + out, up)).sum() >= 2:
                continue  # desk between books found since its turn
            P = _transferred_fit(rig, raw, dst, unseen, desk_plane, self.cfg.flat_refit_sides,
                                 excuse_px=cfg.pool_transfer_excuse_px)
            if P is None:
                continue
            pair, book, _ = self._reconstruct_or_why(
                rig, _in_eq1_order(_pair_at(rig, raw, P)), desk_plane, texture)
            if book is not None:
                taken["left"].append(pair.left)
                taken["right"].append(pair.right)
                out.append((pair, book))
        return out

    def _lifted(self, rig: StereoRig, grads: dict[str, Gradients],
                books: list[tuple[Pair, BookDetection | None, str]],
                found: list[tuple[Pair, BookDetection]], desk_plane: NDArray[np.float64],
                texture: dict[str, NDArray[np.float32]] | None,
                ) -> list[tuple[Pair, BookDetection]]:
        """Books from the pairs that failed as tilted, or with a side on the desk, where no
        book is yet: one side taken for the foot of its page block and lifted to the
        cover's height (:func:`rovis.extent.lift_foot`), the cover then passing every check."""
        overlap = self.cfg.stereo.transfer_max_overlap
        taken = {"left": [p.left for p, _ in found], "right": [p.right for p, _ in found]}

        def over_taken(pair: Pair) -> bool:  # over a book in either image
            return any(quad_overlap(getattr(pair, cam), t) > overlap
                       for cam in taken for t in taken[cam])

        out: list[tuple[Pair, BookDetection]] = []
        for pair, book, why in books:
            if book is not None or why not in ("tilted", "side on desk") or over_taken(pair):
                continue
            P = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right,
                                     method=self.cfg.triangulation)
            lifted = lift_foot({"left": pair.left, "right": pair.right},
                               {"left": rig.Q_L, "right": rig.Q_R}, grads, P, desk_plane,
                               min_height=self.cfg.stereo.min_height,
                               max_height=self.cfg.stereo.max_cover_height)
            if lifted is None:
                continue
            moved, made, _ = self._reconstruct_or_why(
                rig, _pair_at(rig, pair, lifted), desk_plane, texture)
            if made is None or over_taken(moved):
                continue
            taken["left"].append(moved.left)
            taken["right"].append(moved.right)
            out.append((moved, made))
        return out

    def _print_on_desk(self, rig: StereoRig, c_left: NDArray[np.float64],
                       desk_plane: NDArray[np.float64], texture: dict[str, NDArray[np.float32]],
                       plateau: float = 0.01) -> bool:
        """Whether the print inside the left quad ``c_left`` (4, 2) matches between the
        images best on the desk: one flat surface (best NCC ≥ ``sweep.min_ncc_to_move``)
        whose best heights (within ``plateau`` of the best NCC) centre below
        ``stereo.min_height``. A printed sheet's NCC is flat over the first millimetres, so
        the check of step 2 (a clear gap to the corners' height) lets a sheet completed a
        few millimetres up pass."""
        sweep, _ = texture_height(texture["left"], texture["right"], rig.Q_L, rig.Q_R, c_left,
                                  desk_plane, 0.0, self.cfg.sweep)
        if sweep is None or sweep.best_ncc < self.cfg.sweep.min_ncc_to_move:
            return False
        top = sweep.heights[sweep.ncc >= sweep.best_ncc - plateau]
        return float(top.mean()) < self.cfg.stereo.min_height

    def _height_maps(self, rig: StereoRig, grads: dict[str, Gradients],
                     desk_plane: NDArray[np.float64], texture: dict[str, NDArray[np.float32]],
                     ideal: dict[str, NDArray[np.uint8]],
                     ) -> list[tuple[HeightMap, NDArray[np.float64], HeightMapConfig, int]]:
        """The workspace's height maps (:mod:`rovis.heightmap`), finest first: each with
        the projection of the image it is over, the settings to cut covers from it with
        and the erosion of its patches (pixels)."""
        cfg = self.cfg.heightmap
        hm = height_map(texture["left"], texture["right"], rig.Q_L, rig.Q_R, desk_plane,
                        box=grads["left"].box, cfg=cfg)
        maps = [(hm, rig.Q_L, cfg, 0)]
        if cfg.smooth:  # then the covers without fine print
            smooth, Q_half, half = smooth_height_map(ideal["left"], ideal["right"], rig.Q_L,
                                                     rig.Q_R, desk_plane,
                                                     box=grads["left"].box, cfg=cfg)
            maps.append((smooth, Q_half, half, cfg.smooth_erode_px))
        return maps

    def _at_map_height(self, rig: StereoRig, segs: dict[str, Segmentation],
                       grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                       desk_plane: NDArray[np.float64],
                       texture: dict[str, NDArray[np.float32]] | None,
                       maps: list[tuple[HeightMap, NDArray[np.float64]]],
                       ) -> list[tuple[Pair, BookDetection]]:
        """Each book whose height the maps read clearly otherwise over its cover
        (:func:`rovis.trim.map_height`), laid at the maps' height (both images' quads on
        that plane, their mean; or, where they disagree, the one whose sides are edges in
        both images), its sides moved onto the edges both images show there. A book whose
        sides' edges hold it at its height (``TrimConfig.map_sides``) stays."""
        cfg = self.cfg.trim
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        # the sides facing away alone (side_height's three-sides fallback only answers a
        # centimetre off the corners' height)
        facing_away = replace(self.cfg.side_height, any_sides=0)
        out = []
        for pair, book in found:
            P = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
            height = float(np.mean(geometry.plane_distance(desk_plane, P)))
            h = map_height(P, maps, cfg) if book.source != "height map" else None
            if h is not None and cfg.map_sides > 0 and abs(h - height) >= cfg.min_height_move:
                # two or more of its sides that do not face the cameras, placed by stereo,
                # agree on the height it has, not on the maps': the maps' patch there is
                # another surface's (rt1 scene 67's book 2, 34 mm as both sides and the
                # truth say, moved to 47)
                sides = height_from_sides(P, Q, grads, desk_plane, facing_away)
                if (sides is not None and abs(sides - height) <= cfg.map_sides
                        and abs(sides - h) > cfg.map_sides):
                    h = None
            if h is not None and abs(h - height) >= cfg.min_height_move:
                trials = []
                laid = self._laid_at(rig, pair.left, pair.right, desk_plane, h)
                candidates = ([laid] if laid is not None else
                              [on_plane(rig.Q_L, pair.left, desk_plane, h),
                               on_plane(rig.Q_R, pair.right, desk_plane, h)])
                for C in candidates:
                    # ± snap_reach: the cover is moved whole, no side of it is known to be
                    # short (the trim's snap_inward is for a cut, which lands past the edge)
                    C = snap_sides(C, Q, grads, reach=cfg.snap_reach, inward=cfg.snap_reach)
                    edges = sum(_side_scores(C[None], s, (s + 1) % 4, Q, grads, strength,
                                             self.cfg.extent)[0][0] for s in range(4))
                    trials.append((edges, C))
                edges, C = max(trials, key=lambda t: t[0])
                if edges >= 3:
                    moved, fitted, _ = self._reconstruct_or_why(
                        rig, _pair_at(rig, pair, C), desk_plane, texture)
                    if fitted is not None:
                        pair, book = moved, fitted
            out.append((pair, book))
        return out

    def _trimmed(self, rig: StereoRig, segs: dict[str, Segmentation],
                 grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                 desk_plane: NDArray[np.float64],
                 texture: dict[str, NDArray[np.float32]] | None,
                 maps: list[tuple[HeightMap, NDArray[np.float64]]],
                 ) -> list[tuple[Pair, BookDetection]]:
        """Each cover that goes on beyond its own height, cut there (:mod:`rovis.trim`),
        the cut side moved onto the edge both images show (:func:`snap_sides`), and put
        through the pose checks again; a cover the maps found is left as it is. A cut
        cover is the rectangle laid flat at its corners' mean height, projected into both
        images: its other sides keep their place in 3D, not each image's own fit."""
        cfg = self.cfg.trim
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        out = []
        for pair, book in found:
            if book.source == "height map":
                out.append((pair, book))
                continue
            P, height = _on_cover_plane(rig, pair, desk_plane)
            moved = False
            for _ in range(2):  # a cover over two others, one along each axis
                cuts = []
                for axis in (0, 1):
                    profile = height_profile(P, axis, maps, cfg)
                    length = float(np.linalg.norm(P[axis + 1] - P[axis]))
                    c = trim_side(profile, height, cfg, strip=length / len(profile))
                    if c is not None:
                        cuts.append((c[2], axis, c[0], c[1]))
                cuts.sort(reverse=True)
                for score, axis, end, amount in cuts:  # the clearest step that is an edge
                    cut, side = cut_cover(P, axis, end, amount)
                    snapped = snap_sides(cut, Q, grads, reach=cfg.snap_reach,
                                         inward=cfg.snap_inward, sides=(side,))
                    # the cut side must be the cover's edge in both images (where the map
                    # is wrong, plain print matched at the desk's height, there is none),
                    # unless the step is clear: one desk-toned cover on another shows none
                    if _side_scores(snapped[None], side, (side + 1) % 4, Q, grads, strength,
                                    self.cfg.extent)[0][0]:
                        P, moved = snapped, True
                        break
                    if score >= cfg.min_score_unseen:
                        P, moved = cut, True
                        break
                else:
                    break
            if moved:
                new_pair, new_book, _ = self._reconstruct_or_why(rig, _pair_at(rig, pair, P),
                                                                 desk_plane, texture)
                # (a cut narrower than a book would be dropped at the end, the cover with it)
                if new_book is not None and min(new_book.pose.size[:2]) >= self.cfg.min_cover_side:
                    pair, book = new_pair, new_book
            out.append((pair, book))
        return out

    def _grown(self, rig: StereoRig, segs: dict[str, Segmentation],
               grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
               desk_plane: NDArray[np.float64],
               texture: dict[str, NDArray[np.float32]] | None,
               maps: list[tuple[HeightMap, NDArray[np.float64]]],
               ) -> list[tuple[Pair, BookDetection]]:
        """Each cover whose side stops short of where the maps go on at its height (a
        title band, a frame of print inside the cover), that side moved out to the edge
        both images show within that run (:func:`rovis.trim.grow_run`,
        :class:`rovis.trim.TrimConfig`'s grow settings), guarded as
        :meth:`_with_sides_grown` guards, the strip added over no more than
        ``trim.print_max_overlap`` of it of another book: a neighbour of the cover's height
        carries the maps on, and a faint line in its print may pass for the cover's edge
        (:func:`rovis.extent._grow_side`'s ``weak_support``). Where no edge shows within
        the run, the side is moved instead to where its neighbouring sides end
        (:func:`rovis.trim.lateral_grow`, ``trim.lateral_grow``). The maps' own books are
        grown too (measured with them)."""
        cfg = self.cfg.trim
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        extent = replace(self.cfg.extent, min_grow=cfg.grow_min)

        def move(P: NDArray[np.float64], s: int, height: float, below: float) -> float:
            limit = grow_run(P, s, height, maps, cfg)
            if limit <= 0:
                return 0.0
            moved = _grow_side(P, s, Q, grads, strength, _drop(P, desk_plane), extent,
                               limit=min(limit + cfg.grow_margin, below),
                               continuation=cfg.grow_continuation)
            if moved == 0.0 and cfg.lateral_grow and texture is not None:
                moved = lateral_grow(P, s, height, Q, grads, strength, texture, desk_plane,
                                     extent, cfg, limit=min(limit, below))
            return moved

        return self._with_sides_grown(rig, grads, strength, found, desk_plane, texture, move,
                                      strip_overlap=cfg.print_max_overlap)

    def _grown_by_print(self, rig: StereoRig, segs: dict[str, Segmentation],
                        grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                        desk_plane: NDArray[np.float64],
                        texture: dict[str, NDArray[np.float32]],
                        ) -> list[tuple[Pair, BookDetection]]:
        """Each cover whose print goes on, at its height, beyond a side (a title band or a
        printed frame taken for its edge), that side moved out to the cover's edge
        (:func:`rovis.trim.print_grow`), guarded as :meth:`_with_sides_grown` guards, and
        the strip added over no more than ``trim.print_max_overlap`` of it of another book
        (in the left image: a neighbour of the same height lines up there too)."""
        cfg = self.cfg.trim
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)

        def move(P: NDArray[np.float64], s: int, height: float, below: float) -> float:
            return print_grow(P, s, height, Q, grads, strength, texture, desk_plane,
                              self.cfg.extent, cfg, limit=below)

        return self._with_sides_grown(rig, grads, strength, found, desk_plane, texture, move,
                                      strip_overlap=cfg.print_max_overlap)

    def _with_sides_grown(self, rig: StereoRig, grads: dict[str, Gradients],
                          strength: dict[str, float], found: list[tuple[Pair, BookDetection]],
                          desk_plane: NDArray[np.float64],
                          texture: dict[str, NDArray[np.float32]] | None,
                          move: Callable[[NDArray[np.float64], int, float, float], float], *,
                          strip_overlap: float | None = None,
                          ) -> list[tuple[Pair, BookDetection]]:
        """``found`` with each cover's sides moved out by ``move(P, s, height, below)``
        metres (corners (4, 3) on the cover's plane, side ``s`` from corner ``s`` to ``s +
        1``; no farther than ``below``; 0: not moved), side after side. A new side stereo
        puts on the desk is not taken (:func:`rovis.extent._on_desk`, with
        ``extent.height_check``), nor one whose page block shows with no edge at its foot
        (``trim.grow_foot``), nor, with ``strip_overlap``, one whose added strip lies over
        more than that share of it of another book (left image): :meth:`_grow_refused`.
        A refused move is asked again up to ``trim.grow_retry`` short of it, for a nearer
        edge, ``trim.grow_tries`` asks in all; an answer within two offsets of its limit is
        the refused edge cut short there, and ends the asks. A grown cover over more than
        ``stereo.transfer_max_overlap`` of another book (of the smaller, left image) is
        not kept; the grown cover goes through the pose checks again. A book the added strip
        lies over that is a piece of the grown cover (:meth:`_pieces_of`) is no bar: the
        kept grown cover takes its place, and the list returned is shorter by it."""
        up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
        overlap = self.cfg.stereo.transfer_max_overlap
        out = list(found)
        gone: set[int] = set()  # the pieces grown covers took in
        for i, (pair, book) in enumerate(found):
            if i in gone:
                continue
            P, height = _on_cover_plane(rig, pair, desk_plane)
            drop = _drop(P, desk_plane)
            moved = False
            taken: set[int] = set()  # the pieces this cover's moves took in
            for s in range(4):
                below = np.inf
                for _ in range(self.cfg.trim.grow_tries):
                    d = move(P, s, height, below)
                    # an ask again that ends at its limit found the refused edge cut short
                    # (its run of offsets reaches the limit), not a nearer one
                    if d <= 0 or d >= below - 2 * self.cfg.extent.step:
                        break
                    grown = _moved(P, s, np.array([d]))[0]
                    pieces = self._pieces_of(out, i, grown, desk_plane, gone)
                    if self._grow_refused(rig, grads, strength, out, i, P, grown, s, drop, up,
                                          strip_overlap, gone | taken | pieces):
                        below = d - self.cfg.trim.grow_retry  # a nearer edge, if any
                        continue
                    P, moved = grown, True
                    taken |= pieces
                    break
            if not moved:
                continue
            left = geometry.project(rig.Q_L, P)
            if any(quad_overlap(left, p.left) > overlap for k, (p, _) in enumerate(out)
                   if k != i and k not in gone and k not in taken):
                continue
            trial = replace(pair, left=left, right=geometry.project(rig.Q_R, P))
            new_pair, new_book, _ = self._reconstruct_or_why(rig, trial, desk_plane, texture)
            if new_book is not None:
                out[i] = (new_pair, new_book)
                gone |= taken
        return [found_k for k, found_k in enumerate(out) if k not in gone]

    def _off_feet(self, rig: StereoRig, grads: dict[str, Gradients],
                  found: list[tuple[Pair, BookDetection]], desk_plane: NDArray[np.float64],
                  texture: dict[str, NDArray[np.float32]] | None,
                  ) -> list[tuple[Pair, BookDetection]]:
        """Each cover with its sides that both images took on the page block's foot moved
        in to the cover's edge above it (:func:`rovis.extent.foot_side`), kept where it
        passes the pose checks again and no side is shorter than ``min_cover_side``. The
        height map's books too: the move rests on stereo, not on the maps.

        A side on the foot pulls the corners' height down with it; where the other sides
        give another height (:func:`rovis.extent.height_off_feet`, ``facing.relay``), the
        feet are asked first with the cover laid there (each image's quad on that plane,
        their mean: the side on the foot keeps the two apart), then, where no side moves
        or the moved cover fails the checks, at the corners' height."""
        cfg = self.cfg.facing
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        out = []
        for pair, book in found:
            P, h = _on_cover_plane(rig, pair, desk_plane)
            starts = [P]
            h_sides = height_off_feet(P, Q, grads, desk_plane, cfg) if cfg.relay else None
            if h_sides is not None and abs(h_sides - h) > cfg.relay_min:
                starts.insert(0, 0.5 * (on_plane(rig.Q_L, pair.left, desk_plane, h_sides)
                                        + on_plane(rig.Q_R, pair.right, desk_plane, h_sides)))
            for P in starts:
                moved = False
                for s in range(4):
                    d = foot_side(P, s, Q, grads, desk_plane, cfg)
                    if d > 0:
                        P, moved = _moved(P, s, np.array([-d]))[0], True
                if not moved:
                    continue
                new_pair, new_book, _ = self._reconstruct_or_why(
                    rig, _pair_at(rig, pair, P), desk_plane, texture)
                if new_book is not None and min(new_book.pose.size[:2]) >= \
                        self.cfg.min_cover_side:
                    pair, book = new_pair, new_book
                    break
            out.append((pair, book))
        return out

    def _under_taller(self, rig: StereoRig, grads: dict[str, Gradients],
                      found: list[tuple[Pair, BookDetection]], desk_plane: NDArray[np.float64],
                      texture: dict[str, NDArray[np.float32]] | None,
                      ) -> list[tuple[Pair, BookDetection]]:
        """Each cover with a side facing the cameras that a taller book found in front
        hides, that side moved out to straight under the taller book's side
        (:func:`rovis.extent.under_taller`; with ``texture``, the high-passed images, also
        a side short of it where the strip between is the cover's print: None where
        neither the sweep nor the height map ran, and then not), kept where it passes the
        pose checks again.

        The cover's print height test (:mod:`rovis.sweep`) is not asked of the moved
        cover: beyond the taller book's edge, the strip the move adds shows that book's
        top, not this cover's print."""
        cfg = self.cfg.facing
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        # the covers as reported (a taller book's side is where its book says), each with
        # its height (NaN for a book with no cover to place)
        covers = [(book.corners_world, float(np.mean(geometry.plane_distance(
            desk_plane, book.corners_world)))) for _, book in found]
        out = []
        for i, (pair, book) in enumerate(found):
            P, h = covers[i]
            if not np.all(np.isfinite(P)):
                out.append((pair, book))
                continue
            taller = [PB for j, (PB, hB) in enumerate(covers)
                      if j != i and hB >= h + cfg.under_step]  # (NaN >= x is False)
            if not taller:
                out.append((pair, book))
                continue
            moved = False
            for s in range(4):
                if not _facing(P, s, Q):
                    continue
                d = under_taller(P, s, taller, Q, grads, desk_plane, cfg, texture=texture,
                                 sweep=self.cfg.sweep)
                if d > 0:
                    P, moved = _moved(P, s, np.array([d]))[0], True
            if moved:
                new_pair, new_book, _ = self._reconstruct_or_why(
                    rig, _pair_at(rig, pair, P), desk_plane)
                if new_book is not None:
                    pair, book = new_pair, new_book
            out.append((pair, book))
        return out

    def _pieces_of(self, out: list[tuple[Pair, BookDetection]], i: int,
                   grown: NDArray[np.float64], desk_plane: NDArray[np.float64],
                   gone: set[int]) -> set[int]:
        """The books of ``out`` but book ``i`` and ``gone`` that are pieces of the cover
        ``grown`` (4, 3), as :func:`rovis.split.piece_of` tells (``trim.grow_absorb``,
        ``split.join_step``; none where ``grow_absorb`` is 0)."""
        touch = self.cfg.trim.grow_absorb
        if touch <= 0:
            return set()
        return {k for k, (_, other) in enumerate(out) if k != i and k not in gone
                and piece_of(grown, other.corners_world, desk_plane, touch,
                             self.cfg.split.join_step)}

    def _grow_refused(self, rig: StereoRig, grads: dict[str, Gradients],
                      strength: dict[str, float], out: list[tuple[Pair, BookDetection]],
                      i: int, P: NDArray[np.float64], grown: NDArray[np.float64], s: int,
                      drop: NDArray[np.float64], up: NDArray[np.float64],
                      strip_overlap: float | None, ignore: set[int]) -> bool:
        """Whether :meth:`_with_sides_grown` refuses to move side ``s`` of book ``i``'s
        cover ``P`` (4, 3) out to ``grown``'s: its added strip over another book (not one
        of ``ignore``: the pieces of the grown cover, and those taken in before), the new
        side on the desk, or its page block's foot no edge."""
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        if strip_overlap is not None:
            added = geometry.project(rig.Q_L, np.array([P[s], P[(s + 1) % 4],
                                                        grown[(s + 1) % 4], grown[s]]))
            if any(_shared(added, p.left) > strip_overlap
                   for k, (p, _) in enumerate(out) if k != i and k not in ignore):
                return True
        if self.cfg.extent.height_check and _on_desk(grown, s, Q, grads, up, drop,
                                                      self.cfg.extent):
            return True
        return self.cfg.trim.grow_foot and not _foot_is_edge(grown, s, Q, grads, strength,
                                                              drop, self.cfg.extent)

    def _from_height_map(self, rig: StereoRig, grads: dict[str, Gradients],
                         found: list[tuple[Pair, BookDetection]], desk_plane: NDArray[np.float64],
                         texture: dict[str, NDArray[np.float32]],
                         maps: list[tuple[HeightMap, NDArray[np.float64], HeightMapConfig, int]],
                         refuse: Callable[[NDArray[np.float64]], bool] | None = None,
                         without_found: bool = False,
                         strip_maps: Sequence[tuple[HeightMap, NDArray[np.float64]]] = (),
                         above: float | None = None, min_ncc: float | None = None,
                         ) -> list[tuple[Pair, BookDetection]]:
        """Books where no book is yet, from the covers that stand out of the desk in a
        height map of the workspace (:mod:`rovis.heightmap`); ``refuse``, if given, turns
        down a rectangle (world corners, (4, 3)) before anything is done with it;
        ``without_found``: the maps cut without the pixels of ``found``'s covers
        (``HeightMapConfig.taken_px`` beyond them), each rectangle tried unsnapped too where
        the snapped one fails, and a book over a found one (``taken_overlap``) not taken;
        ``strip_maps``: other maps (with their projections) that bound each side's snap
        outward where they read a strip beyond it well below the cover
        (``HeightMapConfig.dense_snap_tol``, :func:`rovis.heightmap.snap_sides`);
        ``above``, if given: no slab reaching below this height is cut
        (:func:`rovis.heightmap.raised_covers`); ``min_ncc``, if given: a rectangle is taken
        only where its print answers the fine sweep within ``HeightMapConfig.step`` of its
        slab's height with an NCC this high.

        Each rectangle's height is refined by its print (a fine sweep), its sides are moved
        onto the edges both images show (:func:`rovis.heightmap.snap_sides`), and the
        rectangle, projected into both images and refined to their edges, is put through
        the pose checks; where the refined corners fail them (a pixel of disparity is a
        centimetre of height) the projected rectangle itself is.
        """
        cfg = self.cfg
        overlap = cfg.stereo.transfer_max_overlap
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        side_range = (0.8 * cfg.min_cover_side, cfg.max_cover_side)
        rects = [rect for hm, Q_map, map_cfg, erode in maps  # the fine map's first
                 for rect in raised_covers(
                     hm, Q_map, desk_plane, side_range=side_range, cfg=map_cfg, erode_px=erode,
                     exclude=(_footprints(hm, Q_map, found, cfg.heightmap.taken_px)
                              if without_found else None), above=above)]
        taken = {"left": [p.left for p, _ in found], "right": [p.right for p, _ in found]}
        out: list[tuple[Pair, BookDetection]] = []

        def kept(pair: Pair, book: BookDetection) -> bool:
            # the height map sees print, not covers: a patch narrower than most books is
            # more often a printed band across a cover than a whole one
            if min(book.pose.size[:2]) < cfg.heightmap.min_side:
                return False
            # the rest of a patch cut again (without_found) that lies over a found cover is
            # print of it, or of a book at its height beside it
            return not (without_found and _over_any_of(pair, found + out,
                                                        cfg.heightmap.taken_overlap))

        for P, height, fill in rects:
            if refuse is not None and refuse(P):
                continue
            # the corners in eq. 1's order in the left image
            left = geometry.project(rig.Q_L, P)
            order = [int(np.argmin(np.linalg.norm(left - c, axis=1))) for c in order_corners(left)]
            P, left = P[order], left[order]
            if any(quad_overlap(geometry.project(Q[cam], P), t) > overlap
                   for cam in Q for t in taken[cam]):
                continue
            step = cfg.heightmap.step
            near = np.arange(height - step, height + step + 1e-9, cfg.sweep.step)
            sweep = sweep_heights(texture["left"], texture["right"], rig.Q_L, rig.Q_R, left,
                                  desk_plane, near[near > 0], inset=cfg.sweep.inset,
                                  max_samples=cfg.sweep.max_samples)
            if min_ncc is not None and (sweep is None or sweep.best_ncc < min_ncc):
                continue
            if sweep is not None:
                height = sweep.best_height
                P = on_plane(rig.Q_L, left, desk_plane, height)
            pair, book = None, None
            snapped = snap_sides(P, Q, grads, reach=cfg.heightmap.snap_reach,
                                 inward=cfg.heightmap.snap_inward, maps=strip_maps,
                                 height=height, strip_tol=cfg.heightmap.dense_snap_tol,
                                 strip_read=cfg.heightmap.dense_snap_read)
            # the rest of a patch cut again (without_found) ends at its neighbour's edge, and
            # a faint side of it may snap in onto its print, or out over that neighbour: the
            # rectangle unsnapped where the snapped one fails
            for C in ((snapped, P) if without_found else (snapped,)):
                exact = Pair(geometry.project(rig.Q_L, C), geometry.project(rig.Q_R, C),
                             float(fill), 0.0, source="height map")
                refined = [refine_quad(grads[cam], getattr(exact, cam))
                           for cam in ("left", "right")]
                # eq. 1 order, kept after refinement
                refined = _in_eq1_order(replace(exact, left=refined[0], right=refined[1]))
                for trial in (refined, exact):
                    pair, book, _ = self._reconstruct_or_why(rig, trial, desk_plane, texture)
                    if book is not None:
                        break
                if book is not None and pair is not None and kept(pair, book):
                    break
            if book is None or pair is None or not kept(pair, book):
                continue
            taken["left"].append(pair.left)
            taken["right"].append(pair.right)
            out.append((pair, book))
        return out

    def _from_dense_map(self, rig: StereoRig, grads: dict[str, Gradients],
                        ideal: dict[str, NDArray[np.uint8]],
                        found: list[tuple[Pair, BookDetection]], desk_plane: NDArray[np.float64],
                        texture: dict[str, NDArray[np.float32]],
                        maps: list[tuple[HeightMap, NDArray[np.float64], HeightMapConfig, int]],
                        ) -> list[tuple[Pair, BookDetection]]:
        """Books where no book is yet, from the covers that stand out of the desk in the
        semi-global disparity map (:func:`rovis.heightmap.dense_height_map`), taken as
        the height map's are (:meth:`_from_height_map`), last.

        That map's smoothing carries a book's height on over a faint desk beside it and
        into a pocket of desk between books: a rectangle the plane sweeps (``maps``) read
        nothing over, or the desk, is no cover (:func:`rovis.heightmap.sweeps_confirm`).
        It also carries a plain cover's height on over a lower neighbour, whose print
        beyond the cover's faint edge draws the side's snap: the sweeps, which read that
        print at its own height, bound it (``strip_maps``).
        Its heights are a few millimetres noisier than the sweeps', so the later steps
        that read heights (``trim``) do not read it.
        """
        cfg = self.cfg.heightmap
        dense, Q_rect, dense_cfg = dense_height_map(
            ideal["left"], ideal["right"], self._rectified(rig), rig.T_left_world, desk_plane,
            mask=grads["left"].mask, cfg=cfg)
        sweeps = [(hm, Q) for hm, Q, _, _ in maps]
        return self._from_height_map(rig, grads, found, desk_plane, texture,
                                     [(dense, Q_rect, dense_cfg, cfg.dense_erode_px)],
                                     strip_maps=sweeps,
                                     refuse=lambda P: not sweeps_confirm(
                                         P, sweeps, max_desk=cfg.dense_max_desk,
                                         min_read=cfg.dense_min_read))

    def _alternative(self, rig: StereoRig, segs: dict[str, Segmentation],
                     grads: dict[str, Gradients], ideal: dict[str, NDArray[np.uint8]],
                     mt: Match, pair: Pair, why: str, desk_plane: NDArray[np.float64] | None,
                     texture: dict[str, NDArray[np.float32]] | None,
                     others: list[NDArray[np.float64]],
                     ) -> tuple[Pair, BookDetection | None, str]:
        """A matched pair that failed a pose check, retried with each image's quad
        refined without the inward search for the cover edge
        (``StereoConfig.plain_alternative``) and with the other quads each image's closed
        loop found over it (:attr:`Segmentation.alternatives`, refined):
        of the pairs that match and pass every check, the one with the smallest stereo
        error; the failed pair and its reason if none does."""
        most = self.cfg.stereo.max_alternatives
        quads: dict[str, list[NDArray[np.float64]]] = {}
        refined: dict[tuple[str, int], NDArray[np.float64]] = {}
        for cam, k in (("left", mt.left), ("right", mt.right)):
            alts = segs[cam].alternatives[k][:most] if k < len(segs[cam].alternatives) else ()
            quads[cam] = [segs[cam].corners[k]]
            if self.cfg.stereo.plain_alternative and k < len(segs[cam].coarse):
                # The same quad refined without the inward search for the cover edge
                # (refine_quad's ``down``): a light cover on a white page-block strip
                # 1-2 px wide shows a faint step at the cover's edge and a strong one at
                # the strip's foot; one image's search may step in to the first, the
                # other's not, and the 2-3 px of disparity between them tilt the cover.
                plain = order_corners(refine_quad_both(grads[cam], segs[cam].coarse[k])[1])
                if np.abs(plain - segs[cam].corners[k]).max() > 0.25:
                    refined[cam, len(quads[cam])] = plain
                    quads[cam].append(plain)
            quads[cam] += list(alts)

        def sub_pixel(cam: str, i: int) -> NDArray[np.float64]:
            # refit once, when first paired (it costs milliseconds)
            if i == 0:
                return quads[cam][0]
            if (cam, i) not in refined:
                refined[cam, i] = order_corners(refine_quad(grads[cam], quads[cam][i]))
            return refined[cam, i]

        overlap = self.cfg.stereo.transfer_max_overlap
        best: tuple[Pair, BookDetection | None, str] = (pair, None, why)
        for i in range(len(quads["left"])):
            if any(quad_overlap(quads["left"][i], q) > overlap for q in others):
                continue
            for j in range(len(quads["right"])):
                if (i, j) == (0, 0):
                    continue
                left, right = sub_pixel("left", i), sub_pixel("right", j)
                found = match_quads(left[None], right[None], rig.Q_L, rig.Q_R,
                                    desk_plane=desk_plane, gray_left=ideal["left"],
                                    gray_right=ideal["right"], cfg=self.cfg.stereo)
                if not found or (best[1] is not None and found[0].error_px >= best[0].error_px):
                    continue
                trial = self._reconstruct_or_why(
                    rig, Pair(left, found[0].corners_right, pair.quality, found[0].error_px,
                              alternative=True),
                    desk_plane, texture)
                # (too small, checked for the others after the extent step: a label)
                if trial[1] is not None and min(trial[1].pose.size[:2]) >= self.cfg.min_cover_side:
                    best = trial
        return best

    def _fit_extents(self, rig: StereoRig, segs: dict[str, Segmentation],
                     grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                     desk_plane: NDArray[np.float64],
                     texture: dict[str, NDArray[np.float32]] | None = None,
                     ideal: dict[str, NDArray[np.uint8]] | None = None,
                     maps: list[tuple[HeightMap, NDArray[np.float64]]] | None = None,
                     ) -> list[tuple[Pair, BookDetection]]:
        """Books whose cover stops at a printed line or reaches beyond its end, with their
        sides moved to the cover's edges (:mod:`rovis.extent`; the moved cover must pass the
        pose checks again, e.g. its size, and its print's height test). A book overlapping a
        moved cover (its other part) gives way to it, except that a cover found otherwise
        than by both segmentations, with every side seen, is not moved over one so found.
        The moved cover keeps its pair's ``quality`` and ``error_px``.

        With ``maps`` (each height map and the projection it is over) and
        ``extent.keep_print``, a side of a book the maps found is not pulled inward over a
        strip they read at the cover's height (:func:`rovis.trim.map_height`, within
        ``trim.tolerance``; the strip less ``extent.keep_print_margin`` next to the side's
        new place): the edges missing there are a gap in its picture, not the cover's end.
        (A book found by its edges may lie beside another of its height: the maps do not
        tell their covers apart.)"""
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        out, moved, before = [], [], {}
        read = maps if maps and self.cfg.extent.keep_print else None
        for pair, book in found:
            if self.cfg.facing.enabled:  # the page block's edge that is the cover's, in both
                settled = settle_facing_sides({"left": pair.left, "right": pair.right}, Q,
                                              grads, desk_plane, self.cfg.facing)
                if settled is not None:
                    trial, fitted, _ = self._reconstruct_or_why(
                        rig, replace(pair, left=settled["left"], right=settled["right"]),
                        desk_plane, texture)
                    if fitted is not None:
                        pair, book = trial, fitted
            new = fit_pair_extent({"left": pair.left, "right": pair.right}, Q, grads, strength,
                                  desk_plane, self.cfg.extent, gray=ideal,
                                  still_cover=_read_at(read, float(book.pose.size[2]),
                                                       self.cfg.trim)
                                  if read is not None and book.source == "height map" else None)
            if new is not None:
                bigger = _in_eq1_order(replace(pair, left=new["left"], right=new["right"]))
                bigger, fitted, _ = self._reconstruct_or_why(rig, bigger, desk_plane, texture)
                if fitted is not None:
                    before[len(out)] = (pair, book)
                    pair, book = bigger, fitted
                    moved.append(len(out))
            out.append((pair, book))
        # A cover found otherwise than by both segmentations is not moved over one they
        # found: two touching books of one height look like one cover cut by a printed
        # line, and the segmented cover has the better evidence.
        limit = self.cfg.stereo.transfer_max_overlap

        for i in list(moved):
            if not _segmented(*out[i]) and any(
                    k != i and k not in moved and _segmented(*out[k])
                    and quad_overlap(out[i][0].left, out[k][0].left) > limit
                    for k in range(len(out))):
                out[i] = before[i]
                moved.remove(i)
        drop = set()
        for i in sorted(moved, key=lambda k: -cv2.contourArea(out[k][0].left.astype(np.float32))):
            if i in drop:
                continue
            for k in range(len(out)):
                if k != i and k not in drop and quad_overlap(
                        out[i][0].left, out[k][0].left) > self.cfg.stereo.transfer_max_overlap:
                    drop.add(k)
        return [item for k, item in enumerate(out) if k not in drop]

    def _with_side_heights(self, rig: StereoRig, grads: dict[str, Gradients],
                           found: list[tuple[Pair, BookDetection]],
                           desk_plane: NDArray[np.float64],
                           texture: dict[str, NDArray[np.float32]] | None,
                           ) -> list[tuple[Pair, BookDetection]]:
        """Each book moved to the height its sides' edges agree on, where that lies
        ``side_height.min_move`` or more from its corners' (:func:`rovis.extent.height_from_sides`;
        beyond the paper). Each image's quad is laid on the cover's plane at that height;
        the two must agree (``sweep.max_spread``), their mean is the cover, and it must
        pass the pose checks again (its print's height test among them)."""
        cfg = self.cfg.side_height
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        out = []
        for pair, book in found:
            P = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
            h = (height_from_sides(P, Q, grads, desk_plane, cfg)
                 if np.all(np.isfinite(P)) else None)
            if h is not None and abs(h - float(book.pose.size[2])) >= cfg.min_move:
                laid = self._laid_at(rig, pair.left, pair.right, desk_plane, h)
                if laid is not None:
                    P = laid
                    moved, fitted, _ = self._reconstruct_or_why(
                        rig, _pair_at(rig, pair, P), desk_plane, texture)
                    if fitted is not None:
                        pair, book = moved, fitted
            out.append((pair, book))
        return out

    def _unskewed(self, rig: StereoRig, segs: dict[str, Segmentation],
                  grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                  desk_plane: NDArray[np.float64],
                  texture: dict[str, NDArray[np.float32]] | None,
                  ) -> tuple[list[tuple[Pair, BookDetection]],
                             list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]]:
        """Each book whose cover corners make an angle further than ``unskew_deg`` from 90°
        laid again without its worst side, and those with no angle within it as dropped
        pairs (``"skewed"``, left corners, right corners; beyond the paper).

        A cover is a rectangle; a quad with one side on a printed diagonal, or on a
        neighbour's edge, is none, and nothing else checks a segmented pair's angles. The
        side between the two worst angles is taken for unseen and the cover laid again as
        a rectangle parallel to the desk, its height and axes from the other three sides
        (:func:`rovis.extent.complete_open`; the unseen side where both images show a step
        within ``complete.search`` of where it was, or, where that keeps no cover (none,
        or one the pose checks or the height bound refuse), ``unskew_reach`` of the
        difference of its neighbouring sides' lengths further: a side on a desk line or a
        neighbour's edge may lie centimetres out at one end and more at the other,
        build/rt1 scene 66's book 4's 54 mm out at its middle, its neighbours 146 and 206
        mm long); the completed cover must pass the pose checks again and stay within
        ``unskew_height`` of the cover's height (a side on a taller neighbour's edge, or its
        print, gives that neighbour's height). Where that fails, the book stays as it was;
        one with every angle still that far off is a parallelogram of lines, no book
        (build/t2 scene 38: 43–45° off, a false positive)."""
        cfg = self.cfg
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        out, skewed = [], []
        for pair, book in found:
            off = _skew_deg(book.corners_world)  # at corner k, between sides k - 1 and k
            if off.max() <= cfg.unskew_deg:
                out.append((pair, book))
                continue
            s = int(np.argmax(off + np.roll(off, -1)))  # side s joins corners s and s + 1
            corners = {"left": pair.left, "right": pair.right}
            h = float(book.pose.size[2])
            # the other sides stay where they were refined (refit here, without the
            # segmentation's inward search, tests/test_pool.py's book's two sides facing
            # the camera moved 1-2 px off their edges: corners up to 5 mm off)
            fits = {cam: [None if k == s else (q[k], _unit(q[(k + 1) % 4] - q[k]))
                          for k in range(4)] for cam, q in corners.items()}
            # the side is looked for near where the images put it (its middle), then, where
            # that keeps no cover, as far again as its ends lie from its middle (half the
            # difference of its neighbouring sides' lengths; further first would let a
            # stronger edge out there win over the cover's own near its middle)
            C = book.corners_world
            spread = abs(float(np.linalg.norm(C[s] - C[(s - 1) % 4])
                               - np.linalg.norm(C[(s + 1) % 4] - C[(s + 2) % 4])))
            reach = cfg.unskew_reach * spread
            for search in [cfg.complete.search] + ([cfg.complete.search + reach]
                                                   if reach > cfg.complete.step else []):
                P = complete_open(corners, {cam: np.arange(4) != s for cam in Q}, Q, grads,
                                  strength, desk_plane,
                                  replace(cfg.complete, at_ends=False, search=search),
                                  height_range=(max(cfg.stereo.min_height,
                                                    h - cfg.unskew_height),
                                                min(cfg.stereo.max_cover_height,
                                                    h + cfg.unskew_height)),
                                  side_range=(0.8 * cfg.min_cover_side, cfg.max_cover_side),
                                  fits=fits)
                if P is None:
                    continue
                trial, fitted, _ = self._reconstruct_or_why(rig, _pair_at(rig, pair, P),
                                                            desk_plane, texture)
                # (its print's height test may move it: to a taller neighbour's print)
                if (fitted is not None
                        and abs(float(fitted.pose.size[2]) - h) <= cfg.unskew_height):
                    pair, book = trial, fitted
                    break
            if _skew_deg(book.corners_world).min() > cfg.unskew_deg:
                skewed.append(("skewed", pair.left, pair.right))
            else:
                out.append((pair, book))
        return out, skewed

    def _with_flat_refits(self, rig: StereoRig,
                          books: list[tuple[Pair, BookDetection | None, str]],
                          desk_plane: NDArray[np.float64] | None,
                          texture: dict[str, NDArray[np.float32]] | None, *,
                          sides: bool = True,
                          ) -> list[tuple[Pair, BookDetection | None, str]]:
        """``books`` (pair, book or None, why) with each pair that came out tilted or with
        a side on the desk replaced by its flat refit where that makes a book
        (:meth:`_flat_refit`, with or without the fit to its ``sides``; beyond the paper: a
        cover whose corners are each a pixel off in a different way comes out so, a pixel
        of disparity being a centimetre of height)."""
        if self.cfg.flat_refit_px <= 0 or desk_plane is None:
            return books
        return [(self._flat_refit(rig, pair, desk_plane, texture, sides=sides)
                 or (pair, book, why))
                if book is None and why in ("tilted", "side on desk") else (pair, book, why)
                for pair, book, why in books]

    def _with_side_fits(self, rig: StereoRig,
                        books: list[tuple[Pair, BookDetection | None, str]],
                        desk_plane: NDArray[np.float64] | None,
                        texture: dict[str, NDArray[np.float32]] | None,
                        ) -> list[tuple[Pair, BookDetection | None, str]]:
        """``books`` with each pair still tilted or with a side on the desk fitted to its
        sides (:meth:`_side_fit`), where that makes a book over no book found (its left
        quad overlapping none by more than ``stereo.transfer_max_overlap``: the
        alternatives ran before it and skipped what overlaps a book)."""
        if self.cfg.flat_refit_px <= 0 or self.cfg.flat_refit_sides <= 0 or desk_plane is None:
            return books
        overlap = self.cfg.stereo.transfer_max_overlap
        out = list(books)
        for k, (pair, book, why) in enumerate(books):
            if book is not None or why not in ("tilted", "side on desk"):
                continue
            fit = self._side_fit(rig, pair, desk_plane, texture)
            if fit is not None and not any(quad_overlap(fit[0].left, p.left) > overlap
                                           for p, b, _ in out if b is not None):
                out[k] = fit
        return out

    def _flat_refit(self, rig: StereoRig, pair: Pair, desk_plane: NDArray[np.float64],
                    texture: dict[str, NDArray[np.float32]] | None, *, sides: bool = True,
                    ) -> tuple[Pair, BookDetection, str] | None:
        """The pair as one rectangle parallel to the desk (:meth:`_flat_fit`), or None
        (for a pair that came out tilted or with a side on the desk, and the candidate
        pool's pairs, ``stereo.pool_flat_refits``).

        First, where one image saw a side on its page block's foot and the other on the
        cover's edge (a side end-on to the baseline: the tilt is that side's disparity),
        that image's side is moved to the cover's height the other sides give
        (:func:`rovis.extent.settle_block_sides`; ``facing.block_sides``), and the moved
        pair fitted flat, or else reconstructed as it is (one free rectangle); where
        neither makes a book, the pair as it came is fitted flat; where that misses, it is
        fitted to its sides with one image's side left out (:meth:`_side_fit`,
        ``flat_refit_sides``; ``sides`` turns that last one on or off)."""
        if self.cfg.facing.block_sides:
            settled = settle_block_sides({"left": pair.left, "right": pair.right},
                                         {"left": rig.Q_L, "right": rig.Q_R}, desk_plane,
                                         self.cfg.facing)
            if settled is not None:
                moved = replace(pair, left=settled["left"], right=settled["right"])
                out = self._flat_fit(rig, moved, desk_plane, texture)
                if out is None:
                    trial = self._reconstruct_or_why(rig, moved, desk_plane, texture)
                    out = trial if trial[1] is not None else None
                if out is not None:
                    return out
        out = self._flat_fit(rig, pair, desk_plane, texture)
        if out is None and sides and self.cfg.flat_refit_sides > 0:
            out = self._side_fit(rig, pair, desk_plane, texture)
        return out

    def _side_fit(self, rig: StereoRig, pair: Pair, desk_plane: NDArray[np.float64],
                  texture: dict[str, NDArray[np.float32]] | None,
                  ) -> tuple[Pair, BookDetection, str] | None:
        """The pair as one rectangle parallel to the desk fitted to its sides, one image's
        side left out (:func:`rovis.geometry.fit_rectangle_sides`), or None.

        A side one image saw on its page block's foot or on the soft edge of the cover's
        shadow lies outside the cover there, and the cover comes out tilted: fitted flat to
        the corners, it misses every corner by a pixel or two. Each side of either image
        whose line lies outside the fit to all eight (which spreads the error, up to half of
        it, over both images), by a fifth of the margin below at least, is left out in
        turn; the fit that brings the other seven closest, within ``flat_refit_sides``,
        with the left-out side more than twice ``flat_refit_px`` outside it (clear of the
        sides' own error), is kept if it passes the pose checks."""
        P0 = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
        if not np.all(np.isfinite(P0)):
            return None
        tol = self.cfg.flat_refit_px
        try:
            _, off = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pair.left, pair.right, P0,
                                                  desk_plane)
            best: tuple[float, NDArray[np.float64]] | None = None
            # a side that lies the margin (2 tol) outside the fit without it lies at least a
            # fifth of that outside the fit to all eight (which spreads a lone outlier over
            # both images, keeping a quarter to a half of it: tests/test_triangulation.py)
            for c, s in zip(*np.nonzero(off > 0.4 * tol)):
                use = np.ones((2, 4), bool)
                use[c, s] = False
                P, off_c = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pair.left,
                                                        pair.right, P0, desk_plane, use=use)
                worst = float(np.abs(off_c[use]).max())
                if (worst <= self.cfg.flat_refit_sides and off_c[c, s] > 2 * tol
                        and (best is None or worst < best[0])):
                    best = (worst, P)
        except ValueError:
            return None
        if best is None or not np.all(np.isfinite(best[1])):
            return None
        trial = self._reconstruct_or_why(rig, _pair_at(rig, pair, best[1]), desk_plane, texture)
        return trial if trial[1] is not None else None

    def _flat_fit(self, rig: StereoRig, pair: Pair, desk_plane: NDArray[np.float64],
                  texture: dict[str, NDArray[np.float32]] | None,
                  ) -> tuple[Pair, BookDetection, str] | None:
        """The pair as one rectangle parallel to the desk (:func:`rovis.geometry.fit_rectangle`
        with the desk plane), its corners projected into both images, if each image's
        corners lie within ``flat_refit_px`` of the rectangle's and it passes the pose
        checks; else None. A cover's outline with its page block, tilted in truth, fits
        no flat rectangle that well."""
        P0 = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
        if not np.all(np.isfinite(P0)):
            return None
        try:
            P = geometry.fit_rectangle(rig.Q_L, rig.Q_R, pair.left, pair.right, P0, desk_plane)
        except ValueError:
            return None
        flat = _pair_at(rig, pair, P)
        off = max(float(np.linalg.norm(flat.left - pair.left, axis=1).max()),
                  float(np.linalg.norm(flat.right - pair.right, axis=1).max()))
        if not np.isfinite(off) or off > self.cfg.flat_refit_px:
            return None
        trial = self._reconstruct_or_why(rig, flat, desk_plane, texture)
        return trial if trial[1] is not None else None

    def _edge_strength(self, segs: dict[str, Segmentation] | dict[str, SegmentationInfo],
                       ) -> dict[str, float]:
        """Per camera, the derivative across a line that counts as an edge: the Canny low
        threshold of the image's segmentation (LSD and contours set none: the open
        loop's). ``segs``: each image's segmentation, or what the result keeps of it."""
        return {cam: CANNY_LOW_RATIO * (seg.T_H or self.cfg.segment.open_T_H)
                for cam, seg in segs.items()}

    def _split_unions(self, rig: StereoRig, segs: dict[str, Segmentation],
                      grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                      desk_plane: NDArray[np.float64],
                      texture: dict[str, NDArray[np.float32]] | None = None,
                      maps: list[tuple[HeightMap, NDArray[np.float64]]] | None = None,
                      ) -> list[tuple[Pair, BookDetection]]:
        """Each book that is two touching books' outline replaced by the two
        (:func:`rovis.split.split_union_heights`), where both parts pass the pose checks and
        their heights differ by ``split.min_step`` or more (and, with ``maps`` and
        ``split.map_check``, the height maps do not read both parts less than that apart:
        :func:`rovis.trim.map_height`), or, split by the jog of a side
        (two books of one height), where both pass the pose checks, each side but the seam
        fitted within ``split.jog_reach_px``; the parts keep the pair's source, ``quality``
        and ``error_px``.

        Each part's sides are fitted to its own edges in each image first. Where both
        parts then pass the pose checks but lose the step or turn it round (one image's
        quad of the lower part still on the union's outline, at the taller book's
        disparity), each part is laid at the height its edges along the cut sides stand at
        (what split it) and its sides but the seam moved onto the edges both images show
        there (:func:`rovis.heightmap.snap_sides`).

        A book for which no split by a seam was kept (none found, or one refused), with
        ``maps`` and ``split.by_map``, is split where the maps read it at two heights across
        a line (:meth:`_split_by_map`): two books of one tone whose seam neither image
        shows."""
        Q = {"left": rig.Q_L, "right": rig.Q_R}
        strength = self._edge_strength(segs)
        out: list[tuple[Pair, BookDetection]] = []
        for pair, book in found:
            split = split_union_heights({"left": pair.left, "right": pair.right}, Q, grads,
                                        strength, desk_plane, self.cfg.split)
            if split is not None and not split.by_step:
                # split by the jog (two books of one height): both parts must be books,
                # each side but the seam fitted to its own edge, which may lie as far off
                # the union's outline as the jog was looked for (the narrower book's)
                made = []
                for part, seam in zip(split.parts, split.seams):
                    widths = [3.0 if s == seam else self.cfg.split.jog_reach_px
                              for s in range(4)]
                    made.append(self._fitted_part(rig, grads, pair, part, desk_plane,
                                                  texture, half_width=widths))
                if all(book is not None for _, book in made):
                    out += made  # type: ignore[arg-type]
                    continue
            elif split is not None and not (maps and self.cfg.split.map_check
                                            and self._one_height(rig, split, maps)):
                parts, heights, seams = split.parts, split.heights, split.seams
                made = [self._fitted_part(rig, grads, pair, part, desk_plane, texture)
                        for part in parts]
                # both parts are books, but not of the step that split them: laid there
                # (a part that is no book leaves the split in doubt, not its height)
                if (self.cfg.split.lay and all(book is not None for _, book in made)
                        and not self._keeps_step(made, heights)):
                    made = [self._laid_part(rig, grads, pair, part, h, seam, desk_plane,
                                            texture)
                            for part, h, seam in zip(parts, heights, seams)]
                if self._keeps_step(made, heights):
                    out += made  # type: ignore[arg-type]
                    continue
            if maps and self.cfg.split.by_map:  # no seam split it: the maps' step may
                others = [p.left for p, _ in found if p is not pair]
                by_map = self._split_by_map(rig, grads, pair, desk_plane, texture, maps,
                                            others)
                if by_map is not None:
                    out += by_map
                    continue
            out.append((pair, book))
        return out

    def _split_by_map(self, rig: StereoRig, grads: dict[str, Gradients], pair: Pair,
                      desk_plane: NDArray[np.float64],
                      texture: dict[str, NDArray[np.float32]] | None,
                      maps: list[tuple[HeightMap, NDArray[np.float64]]],
                      others: Sequence[NDArray[np.float64]] = (),
                      ) -> list[tuple[Pair, BookDetection]] | None:
        """The two books of a cover the height maps read at two heights across a line
        (:func:`rovis.split.map_step` on :func:`rovis.trim.height_profile` along either
        axis, the larger reduction), each part laid at its median height
        (:meth:`_laid_part`: its sides but the seam snapped to the edges both images show;
        the seam stays where the maps' strips put it, a strip or two off, for the trim and
        the grows to settle), or None where the maps read no step, a part lies over
        another found book (``others``, left quads: by more than
        ``stereo.transfer_max_overlap`` of the smaller; that part is that book, and a cover
        reaching over a lower one is the trim's) or the parts are not two books that keep
        the step (:meth:`_keeps_step`)."""
        P, _ = _on_cover_plane(rig, pair, desk_plane)
        steps = []
        for axis in (0, 1):
            profile = height_profile(P, axis, maps, self.cfg.trim)
            strip = float(np.linalg.norm(P[axis + 1] - P[axis])) / len(profile)
            step = map_step(profile, strip, self.cfg.split)
            if step is not None:
                steps.append((step.reduction, axis, step, strip, len(profile)))
        if not steps:
            return None
        _, axis, step, strip, n = max(steps, key=lambda s: s[0])
        # the part from the profile's start (its far end cut off) and the part after it
        parts = []
        for end, cut, height in ((1, (n - step.k) * strip, step.heights[0]),
                                 (0, step.k * strip, step.heights[1])):
            W, seam = cut_cover(P, axis, end, cut)
            part = {"left": geometry.project(rig.Q_L, W), "right": geometry.project(rig.Q_R, W)}
            parts.append((part, height, seam))
        limit = self.cfg.stereo.transfer_max_overlap
        if any(quad_overlap(part["left"], other) > limit
               for part, _, _ in parts for other in others):
            return None
        made = [self._laid_part(rig, grads, pair, part, height, seam, desk_plane, texture)
                for part, height, seam in parts]
        if not self._keeps_step(made, step.heights):
            return None
        return made  # type: ignore[return-value]

    def _one_height(self, rig: StereoRig, split: Split,
                    maps: list[tuple[HeightMap, NDArray[np.float64]]]) -> bool:
        """Whether the height maps read both parts of ``split`` (:func:`rovis.trim.map_height`)
        less than ``split.min_step`` apart: one cover, split at a line of its picture whose
        halves' edges stand at two heights."""
        h = [map_height(geometry.triangulate(rig.Q_L, rig.Q_R, part["left"], part["right"]),
                        maps, self.cfg.trim) for part in split.parts]
        return h[0] is not None and h[1] is not None and abs(h[0] - h[1]) < self.cfg.split.min_step

    def _keeps_step(self, made: list[tuple[Pair, BookDetection | None]],
                    heights: tuple[float, float]) -> bool:
        """Whether both parts of a split made books whose heights differ by
        ``split.min_step`` or more, the same way round as the ``heights`` (metres) that split
        them (each placed in 3D on its own, they keep that step)."""
        books = [book for _, book in made]
        if any(b is None for b in books):
            return False
        step = books[0].pose.size[2] - books[1].pose.size[2]  # type: ignore[union-attr]
        return abs(step) >= self.cfg.split.min_step and \
            np.sign(step) == np.sign(heights[0] - heights[1])

    def _fitted_part(self, rig: StereoRig, grads: dict[str, Gradients], pair: Pair,
                     part: dict[str, NDArray[np.float64]], desk_plane: NDArray[np.float64],
                     texture: dict[str, NDArray[np.float32]] | None, *,
                     half_width: float | Sequence[float] = 3.0,
                     ) -> tuple[Pair, BookDetection | None]:
        """One part of a split as a book: its sides fitted to its own edges in each image
        (the union's corners may come from a rectangle placed at one height, a candidate
        completed in 3D, off in one image for the lower part), within ``half_width`` px of
        the part's sides, one for all or per side
        (:func:`rovis.segment.boundary.refine_quad`), else as cut."""
        fitted = None
        for quads in ({cam: refine_quad(grads[cam], q, half_width=half_width)
                       for cam, q in part.items()}, part):
            trial = _in_eq1_order(replace(pair, left=quads["left"], right=quads["right"]))
            trial, fitted, _ = self._reconstruct_or_why(rig, trial, desk_plane, texture)
            if fitted is not None:
                break
        return trial, fitted

    def _laid_part(self, rig: StereoRig, grads: dict[str, Gradients], pair: Pair,
                   part: dict[str, NDArray[np.float64]], height: float, seam: int,
                   desk_plane: NDArray[np.float64],
                   texture: dict[str, NDArray[np.float32]] | None,
                   ) -> tuple[Pair, BookDetection | None]:
        """One part of a split as a book laid at ``height`` above the desk: the left
        image's quad on that plane (the right's lies on the union's outline there), its
        sides but side ``seam`` moved onto the edges both images show within
        ``split.lay_reach``. The seam stays where both images' fits put it: the taller
        book's top edge beside it is an edge on this plane too, a few millimetres on."""
        P = on_plane(rig.Q_L, part["left"], desk_plane, height)
        reach = self.cfg.split.lay_reach
        P = snap_sides(P, {"left": rig.Q_L, "right": rig.Q_R}, grads, reach=reach, inward=reach,
                       sides=tuple(s for s in range(4) if s != seam))
        trial, fitted, _ = self._reconstruct_or_why(rig, _in_eq1_order(_pair_at(rig, pair, P)),
                                                    desk_plane, texture)
        return trial, fitted

    def _joined(self, rig: StereoRig, found: list[tuple[Pair, BookDetection]],
                desk_plane: NDArray[np.float64],
                texture: dict[str, NDArray[np.float32]] | None = None,
                ) -> list[tuple[Pair, BookDetection]]:
        """The books with each two that are the halves of one cover
        (:func:`rovis.split.join_halves`) replaced by that cover, where it passes the pose
        checks as the less certain of the two would (a cover found in one image, among the
        alternatives or the candidates, or with a side unseen must stand higher); it takes
        that one's ``source``, the lower ``quality`` and the larger ``error_px``."""
        out = list(found)
        joined = True
        while joined:  # a cover cut twice is joined a half at a time
            joined = False
            for a, b in ((a, b) for a in range(len(out)) for b in range(a + 1, len(out))):
                U = join_halves(out[a][1].corners_world, out[b][1].corners_world, desk_plane,
                                self.cfg.split)
                if U is None:
                    continue
                first, second = out[a][0], out[b][0]
                trial = replace(
                    _pair_at(rig, first, U), quality=min(first.quality, second.quality),
                    error_px=max(first.error_px, second.error_px),
                    transferred=first.transferred or second.transferred,
                    alternative=first.alternative or second.alternative,
                    three_sided=first.three_sided or second.three_sided,
                    # (the joined cover is as wide as each half: the bound of
                    # small_open_min_side only where both came from the small pass)
                    small_open=first.small_open and second.small_open,
                    source=(first.source if first.source != "segmentation" else second.source))
                trial, book, _ = self._reconstruct_or_why(rig, _in_eq1_order(trial), desk_plane,
                                                          texture)
                if book is not None:
                    out[a] = (trial, book)
                    del out[b]
                    joined = True
                    break
        return out

    def _without_prints(self, found: list[tuple[Pair, BookDetection]], *, inside: float = 0.9,
                        max_off_plane: float = 0.005,
                        ) -> tuple[list[tuple[Pair, BookDetection]], list[tuple[Pair, BookDetection]]]:
        """The books not printed on another: a book whose left quad lies ``inside`` a larger
        book's, its corners within ``max_off_plane`` (metres) of that book's cover plane, is a
        print on that cover (for frames without the desk plane, where no height tells them
        apart). Returns the books kept and those dropped."""
        area = [abs(float(_shoelace(pair.left[None])[0])) for pair, _ in found]
        kept, printed = [], []
        for i, (pair, book) in enumerate(found):
            on = False
            for j, (outer, other) in enumerate(found):
                if j == i or area[j] <= area[i] or quad_overlap(pair.left, outer.left) < inside:
                    continue
                P = other.corners_world
                normal = np.cross(P[2] - P[0], P[3] - P[1])
                normal /= max(float(np.linalg.norm(normal)), 1e-12)
                if np.abs((book.corners_world - P.mean(axis=0)) @ normal).max() <= max_off_plane:
                    on = True
                    break
            (printed if on else kept).append((pair, book))
        return kept, printed

    def _without_desk(self, rig: StereoRig, segs: dict[str, Segmentation],
                      grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                      desk_plane: NDArray[np.float64], texture: dict[str, NDArray[np.float32]],
                      ) -> tuple[list[tuple[Pair, BookDetection]],
                                 list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]]:
        """The books, less each that is the desk between books; those as dropped pairs
        (``"desk"``, left corners, right corners).

        Two seams of the desk's planks and a book's edge make a quad whose fourth side
        closes where the seams' edges end, or is completed in 3D; it pairs into a flat,
        book-sized rectangle at the height stereo puts its sides at (the Table I renders'
        scene 80: 236 × 153 mm, 72 mm up, over bare desk). Such a cover has a side that is
        no step in either image (:func:`rovis.segment.boundary.side_evidence` under
        ``stereo.desk_unseen`` along it, at half the Canny low threshold), and its inside is
        the desk: the grain matches between the images (:func:`rovis.sweep.sweep_heights`,
        ``sweep``'s inset and samples) at the desk's height with an NCC of at least
        ``stereo.desk_ncc``, and no worse than at the cover's own. A book's print matches
        best at its own height; a plain cover (no texture, or an NCC under ``desk_ncc`` at
        the desk) tells nothing and stays, as does a cover whose four sides show unless its
        inside peaks clearly on the desk (below). A book of the height map stays too: the
        maps read it standing out of the desk, and a cover of the desk's grain matches no
        better at its own height than on the desk (tests/test_track.py's scene: a desk-toned
        cover 13 mm up, found 17 mm off, NCC 0.48 on the desk against 0.43 at its 14 mm).

        A quad of the desk may show all four sides too: the text block printed on a sheet of
        paper, or the desk between books closed by their edges, a sheet's and a shadow's
        (build/t1d scene 23: a sheet's text block, found as a book 196 × 142 mm and 7 mm up,
        matches with an NCC of 0.91 on the desk and 0.84 at 7 mm).
        Where the desk matches as well as above, a finer sweep asks it: from the desk to 5
        mm above the cover, every millimetre, the best NCC must lie at most
        ``stereo.desk_peak`` above the desk, be ``stereo.desk_seen_ncc`` at least and
        ``stereo.desk_margin`` more than at the cover's height. (The two heights alone would
        drop a book found too high: build/t1d scene 66's light cover, 17 mm high, found at
        28 mm, matches with 0.66 on the desk and 0.60 at 28 mm, but 0.68 at 7–15 mm.)"""
        cfg = self.cfg.stereo
        strength = self._edge_strength(segs)
        kept, desk = [], []
        for pair, book in found:
            if book.source == "height map":
                kept.append((pair, book))
                continue
            h = float(book.pose.size[2])
            sweep = sweep_heights(texture["left"], texture["right"], rig.Q_L, rig.Q_R,
                                  pair.left, desk_plane, [0.0, h], inset=self.cfg.sweep.inset,
                                  max_samples=self.cfg.sweep.max_samples)
            if sweep is None or sweep.ncc[0] < max(cfg.desk_ncc, sweep.ncc[1]):
                kept.append((pair, book))  # the inside matches better off the desk, or not
                continue
            unseen = np.full(4, cfg.desk_unseen > 0)
            for cam in ("left", "right"):
                if unseen.any():
                    unseen &= side_evidence(grads[cam], getattr(pair, cam),
                                            0.5 * strength[cam]) < cfg.desk_unseen
            if unseen.any() or self._desk_inside(rig, pair, h, desk_plane, texture,
                                                 float(sweep.ncc[1])):
                desk.append(("desk", pair.left, pair.right))
            else:
                kept.append((pair, book))
        return kept, desk

    def _desk_inside(self, rig: StereoRig, pair: Pair, height: float,
                     desk_plane: NDArray[np.float64], texture: dict[str, NDArray[np.float32]],
                     at_height: float) -> bool:
        """Whether a cover's inside matches between the images best at the desk (within
        ``stereo.desk_peak`` of it, NCC ``stereo.desk_seen_ncc`` at least) and by
        ``stereo.desk_margin`` better than at its ``height`` (metres; ``at_height``: the NCC
        there), swept every millimetre from the desk to 5 mm above it
        (:meth:`_without_desk`)."""
        cfg = self.cfg.stereo
        if cfg.desk_seen_ncc > 1:
            return False
        heights = np.arange(0.0, height + 0.005 + 1e-9, 0.001)
        sweep = sweep_heights(texture["left"], texture["right"], rig.Q_L, rig.Q_R, pair.left,
                              desk_plane, heights, inset=self.cfg.sweep.inset,
                              max_samples=self.cfg.sweep.max_samples)
        if sweep is None:
            return False
        best = int(np.argmax(sweep.ncc))
        return bool(heights[best] <= cfg.desk_peak + 1e-9 and sweep.ncc[best] >= cfg.desk_seen_ncc
                    and sweep.ncc[best] - at_height >= cfg.desk_margin)

    def _without_overlaps(self, found: list[tuple[Pair, BookDetection]],
                          rig: StereoRig | None = None,
                          desk_plane: NDArray[np.float64] | None = None,
                          texture: dict[str, NDArray[np.float32]] | None = None,
                          ) -> tuple[list[tuple[Pair, BookDetection]],
                                     list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]]:
        """The books, less each not found by both segmentations with every side seen that
        overlaps one so found by more than ``stereo.over_segmented`` of the smaller quad
        in each image; those as dropped pairs (``"overlaps"``, left corners, right
        corners).

        Two covers overlap in both images only where one lies over or in front of the
        other, and then by the strip the nearer one hides; a segmented cover is the better
        evidence (as in :meth:`_fit_extents`). On build/t2's scenes 56 and 58 a false
        "book" (294 × 141 and 131 × 164 mm) from the candidate pool lay over a book the
        segmentations found by 22 and 30 % of the smaller quad; the touching books found
        on the dev sets overlap by at most 12 % in one image.

        With ``stereo.over_cut``, a book from the height map over one such book only is cut
        back instead (:meth:`_cut_off`) and kept where it then passes the pose checks and
        lies over no other book found by that share: the maps' rectangle often runs on over
        a neighbour of about its height (one slab of the sweeps). Needs ``rig`` and
        ``desk_plane``."""
        limit = self.cfg.stereo.over_segmented
        kept, over = [], []

        def lying_over(pair: Pair, books: list[tuple[Pair, BookDetection]],
                       ) -> list[tuple[Pair, BookDetection]]:
            # the books of `books` that `pair` lies over by more than `limit` in both images
            return [(p, b) for p, b in books
                    if quad_overlap(pair.left, p.left) > limit
                    and quad_overlap(pair.right, p.right) > limit]

        segmented = [(p, b) for p, b in found if _segmented(p, b)]
        for pair, book in found:
            under = lying_over(pair, segmented) if not _segmented(pair, book) else []
            if not under:
                kept.append((pair, book))
                continue
            cut = (self._cut_off(rig, pair, book, under[0][1], desk_plane, texture)
                   if len(under) == 1 and book.source == "height map" and rig is not None
                   and desk_plane is not None and self.cfg.stereo.over_cut else None)
            if cut is not None and not lying_over(cut[0], [(p, b) for p, b in found
                                                           if p is not pair]):
                kept.append(cut)
            else:
                over.append(("overlaps", pair.left, pair.right))
        return kept, over

    def _cut_by_height(self, rig: StereoRig, found: list[tuple[Pair, BookDetection]],
                       desk_plane: NDArray[np.float64],
                       texture: dict[str, NDArray[np.float32]],
                       read: list[tuple[HeightMap, NDArray[np.float64]]],
                       grads: dict[str, Gradients], strength: dict[str, float],
                       ) -> list[tuple[Pair, BookDetection]]:
        """The books, each cut back off a neighbour it runs on over (:meth:`_cut_off`)
        where the strip between them is that neighbour's cover.

        Two books lie side by side, never one partly over the other: where two found
        covers overlap on the desk by a strip ``stereo.height_cut`` wide or more (metres,
        the narrower side of the overlap's smallest rectangle), the strip is one cover's.
        It is taken for book B's, and A is cut back off it, where:

        - the height maps read the strip (:func:`rovis.trim.map_height`), laid at B's
          height, within ``trim.tolerance`` of it, and laid at A's, at a height (not
          none) more than that from A's;
        - the print matches between the images (:func:`rovis.sweep.sweep_heights`, the
          whole strip) better at B's height than at A's by more than
          ``stereo.height_cut_gap``, with the strip laid at either height (a strip too
          thin to sweep is not cut);
        - B's side nearest the strip shows a step along ``stereo.height_cut_support`` or
          more of it in both images (:func:`rovis.segment.boundary.side_evidence`, half
          the Canny low threshold ``strength``): B's cover ends there.

        Each is read with the strip laid at each book's height, since a strip laid at one
        height falls in each image where that book would show it. The pairs are taken in
        the order of ``found``: a book is cut once at most, and not after it has owned a
        strip; the cut is kept where it passes the pose checks and no longer overlaps B by
        such a strip (else, or where no side of A is one B reaches across, A is kept as it
        was)."""
        cfg = self.cfg.stereo
        on_desk, up, e1, e2 = _plane_frame(desk_plane)
        tol = self.cfg.trim.tolerance
        out = list(found)
        cut: set[int] = set()
        owners: set[int] = set()

        def on_desk_2d(P: NDArray[np.float64]) -> NDArray[np.float32]:
            return _in_desk_plane(P, on_desk, e1, e2)

        def strip_of(A: BookDetection, B: BookDetection) -> NDArray[np.float64] | None:
            # the smallest rectangle (4, 2; desk coordinates, in order) around the two
            # covers' overlap on the desk, where its narrower side is height_cut or more
            area, poly = cv2.intersectConvexConvex(on_desk_2d(np.asarray(A.corners_world)),
                                                   on_desk_2d(np.asarray(B.corners_world)))
            if area <= 0 or poly is None:
                return None
            box = cv2.minAreaRect(poly.reshape(-1, 2))
            return cv2.boxPoints(box).astype(np.float64) if min(box[1]) >= cfg.height_cut \
                else None

        def owns(A: BookDetection, B: BookDetection, strip: NDArray[np.float64]) -> bool:
            # whether the strip is B's cover, not A's
            hA, hB = float(A.pose.size[2]), float(B.pose.size[2])
            laid = {h: on_desk + strip[:, :1] * e1 + strip[:, 1:] * e2 + h * up
                    for h in (hA, hB)}
            mA, mB = (map_height(laid[h], read, self.cfg.trim) for h in (hA, hB))
            if mB is None or abs(mB - hB) > tol or mA is None or abs(mA - hA) <= tol:
                return False
            for R in laid.values():
                sweep = sweep_heights(texture["left"], texture["right"], rig.Q_L, rig.Q_R,
                                      geometry.project(rig.Q_L, R), desk_plane, [hA, hB],
                                      inset=0.0)
                if sweep is None or sweep.ncc[1] <= sweep.ncc[0] + cfg.height_cut_gap:
                    return False
            # B's side nearest the strip's middle, seen as a step in both images
            corners = on_desk_2d(np.asarray(B.corners_world)).astype(np.float64)
            side = int(np.argmin(_point_segment_distance(strip.mean(axis=0), corners,
                                                         np.roll(corners, -1, axis=0))))
            return all(side_evidence(grads[cam], geometry.project(Q, B.corners_world),
                                     0.5 * strength[cam], reach_px=2.0)[side]
                       >= cfg.height_cut_support
                       for cam, Q in (("left", rig.Q_L), ("right", rig.Q_R)))

        for a in range(len(out)):
            for b in range(len(out)):
                if a == b or a in cut or a in owners or b in cut:
                    continue
                (pair, A), (_, B) = out[a], out[b]
                strip = strip_of(A, B)
                if strip is None or not owns(A, B, strip):
                    continue
                done = self._cut_off(rig, pair, A, B, desk_plane, texture)
                if done is not None and strip_of(done[1], B) is None:
                    out[a] = done
                    cut.add(a)
                    owners.add(b)
        return out

    def _cut_off(self, rig: StereoRig, pair: Pair, book: BookDetection, other: BookDetection,
                 desk_plane: NDArray[np.float64],
                 texture: dict[str, NDArray[np.float32]] | None,
                 ) -> tuple[Pair, BookDetection] | None:
        """``book`` with a side pulled in to where ``other``'s cover ends, seen from above
        (``other``'s corners measured in ``book``'s plane, along its sides), or None. Only
        a side ``other`` reaches across (some of its corners beyond the side, some inside:
        a neighbour the book ran on over, not a cover lying within it) is pulled; of those
        whose pull leaves ``min_cover_side`` or more, the shortest pull is tried, and kept
        where what is left passes the pose checks and is ``min_cover_side`` wide or more."""
        P = np.asarray(book.corners_world, dtype=np.float64)
        S = np.asarray(other.corners_world, dtype=np.float64)
        up = desk_plane[:3] / np.linalg.norm(desk_plane[:3])
        best = None
        for s in range(4):
            a, b = P[s], P[(s + 1) % 4]
            inward = P[(s + 2) % 4] - b  # along the neighbouring side, into the cover
            depth = float(np.linalg.norm(inward))
            inward = _unit(inward - (inward @ up) * up)  # level with the desk
            into = (S - a) @ inward  # each of its corners' depth into the cover
            reach = float(into.max())  # how far into the cover `other` goes
            if into.min() >= 0.0 or not 0.0 < reach < depth - self.cfg.min_cover_side:
                continue  # not across this side, or the pull leaves too little
            if best is None or reach < best[0]:
                best = (reach, s)
        if best is None:
            return None
        C = _moved(P, best[1], np.array([-best[0]]))[0]
        trial, fitted, _ = self._reconstruct_or_why(rig, _pair_at(rig, pair, C), desk_plane,
                                                    texture)
        if fitted is None or min(fitted.pose.size[:2]) < self.cfg.min_cover_side:
            return None
        return trial, fitted

    def _over_freed(self, rig: StereoRig, segs: dict[str, Segmentation],
                    grads: dict[str, Gradients], found: list[tuple[Pair, BookDetection]],
                    freed: list[NDArray[np.float64]], desk_plane: NDArray[np.float64],
                    texture: dict[str, NDArray[np.float32]] | None,
                    ideal: dict[str, NDArray[np.uint8]],
                    read: list[tuple[HeightMap, NDArray[np.float64]]],
                    refined: Refined) -> list[tuple[Pair, BookDetection]]:
        """Books of the candidate pool (:meth:`_from_pool`'s first pass) over the covers
        ``freed`` (left quads (4, 2)) that were dropped at the end: found before that pass,
        such a cover kept the candidates under it out of it (a piece of a cover cut at a
        band, dropped as narrower than a book, over the whole cover's pairs). Each new book
        lies over one by half or more of the smaller, goes through the extent step and must
        then be no narrower than a book (:meth:`_without_small`), lie over no found book
        by more than ``stereo.freed_overlap`` of the smaller quad in either image, and not
        beside one as the other part of its cover (:func:`rovis.split.beside`, within
        ``stereo.freed_touch`` and ``split.join_step``)."""
        more = [(pair, book) for pair, book
                in self._from_pool(rig, segs, grads, found, desk_plane, texture, refined)
                if any(quad_overlap(pair.left, q) > 0.5 for q in freed)]
        if not more:
            return []
        more = self._fit_extents(rig, segs, grads, more, desk_plane, texture, ideal, read)
        # a piece of a found cover (its print's other part, at its height, with two
        # corners on its outline) is no new book
        step, touch = self.cfg.split.join_step, self.cfg.stereo.freed_touch
        return [(pair, book) for pair, book in self._without_small(more)[0]
                if not _over_any_of(pair, found, self.cfg.stereo.freed_overlap)
                and not any(beside(book.corners_world, b.corners_world, desk_plane, touch, step)
                            for _, b in found)]

    def _without_small(self, found: list[tuple[Pair, BookDetection]], *,
                       small_open_only: bool = False,
                       ) -> tuple[list[tuple[Pair, BookDetection]],
                                  list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]]:
        """The books with no side shorter than ``min_cover_side`` (``stereo.small_open_min_side``
        for one from a small candidate with sides unseen; with ``small_open_only``, only
        those are looked at), and the others as dropped pairs (``"too small"``, left
        corners, right corners)."""
        kept, small = [], []
        for pair, book in found:
            least = (max(self.cfg.min_cover_side, self.cfg.stereo.small_open_min_side)
                     if pair.small_open else 0.0 if small_open_only else self.cfg.min_cover_side)
            if min(book.pose.size[0], book.pose.size[1]) < least:
                small.append(("too small", pair.left, pair.right))
            else:
                kept.append((pair, book))
        return kept, small

    def _pose_fails(self, pose: geometry.BookPose, P: NDArray[np.float64],
                    desk_plane: NDArray[np.float64] | None, pair: Pair) -> str:
        """The first pose check (:data:`DROP_REASONS`) the cover fails, or ``""``."""
        if max(pose.size[0], pose.size[1]) > self.cfg.max_cover_side:
            return "too long"  # two books end to end, or a cover and a line beyond it
        if desk_plane is None:
            # no extent step follows without the desk plane (it may grow a piece of a cover
            # to the whole cover): a piece is dropped now, and its quads stay free for the
            # one-image search (on the real chessboard pairs, strips of the board's squares
            # matched in both images kept the sheet from being looked for)
            if min(pose.size[0], pose.size[1]) < self.cfg.min_cover_side:
                return "too small"
            # found in one image, placed in the other on its rectangle's own plane: its
            # corners must make a rectangle (the quad's image was taken for one)
            if pair.transferred and not flat_rectangle(P, side_range=(0.0, np.inf))[0]:
                return "skewed"
            return ""
        if _tilt_deg(pose, desk_plane) > self.cfg.max_tilt_deg:
            return "tilted"
        # a cover found in one image only (or among the alternatives, the candidates or in
        # the height map, or with a side unseen) must stand as high as the search assumed:
        # a flat pattern on the desk (a sheet, a seam rectangle) is no book
        low = (self.cfg.stereo.min_height
               if pair.transferred or pair.alternative or pair.three_sided
               or pair.source != "segmentation" else 0.0)
        if not low < pose.size[2] <= self.cfg.stereo.max_height:
            return "height"
        # a side lying on the desk is a line on the desk (a shadow's edge, the page
        # block's foot), not the edge of a cover: the quad is no cover
        h = geometry.plane_distance(desk_plane, P)
        if np.any(0.5 * (h + np.roll(h, -1)) < self.cfg.min_side_height):  # side midpoints
            return "side on desk"
        return ""

    def _on_plane(self, rig: StereoRig, c_left: NDArray[np.float64], c_right: NDArray[np.float64],
                  desk_plane: NDArray[np.float64], sweep: Sweep) -> NDArray[np.float64] | None:
        """The cover moved to the height its print gives, (4, 3) world corners, or None.

        Only a print that matches nearly perfectly at one height is one flat surface: a
        weaker match (a quad over two books, over a cover and its neighbour) is no cover.
        Each image's quad is laid on that plane; the two must agree (a quad a few pixels
        off in one image is what moved the cover), and their mean is the cover.
        """
        if sweep.best_ncc < self.cfg.sweep.min_ncc_to_move:
            return None
        return self._laid_at(rig, c_left, c_right, desk_plane, sweep.best_height)

    def _laid_at(self, rig: StereoRig, c_left: NDArray[np.float64],
                 c_right: NDArray[np.float64], desk_plane: NDArray[np.float64],
                 height: float) -> NDArray[np.float64] | None:
        """The cover laid at ``height`` above the desk, (4, 3) world corners: each image's
        quad on that plane, their mean where they agree within ``sweep.max_spread`` at
        every corner, else None."""
        P_left = on_plane(rig.Q_L, c_left, desk_plane, height)
        P_right = on_plane(rig.Q_R, c_right, desk_plane, height)
        if np.max(np.linalg.norm(P_left - P_right, axis=1)) > self.cfg.sweep.max_spread:
            return None
        return 0.5 * (P_left + P_right)

    def _reconstruct_or_why(self, rig: StereoRig, pair: Pair,
                            desk_plane: NDArray[np.float64] | None,
                            texture: dict[str, NDArray[np.float32]] | None = None,
                            ) -> tuple[Pair, BookDetection | None, str]:
        """The pair, the book it makes, or None and the check it failed (one of
        :data:`DROP_REASONS`).

        ``texture``: both ideal images high-passed (:func:`rovis.sweep.high_pass`), for the
        height test of the cover's print. A cover the print moves comes back with a new
        pair: its corners in both images are the moved cover's, projected (so the later
        steps, e.g. :mod:`rovis.extent`, start from the cover where it is).
        """
        c_left, c_right = pair.left, pair.right
        P = geometry.triangulate(rig.Q_L, rig.Q_R, c_left, c_right, method=self.cfg.triangulation)
        if not np.all(np.isfinite(P)):
            return pair, None, "degenerate"
        if self.cfg.fit_rectangle:
            try:
                P = geometry.fit_rectangle(rig.Q_L, rig.Q_R, c_left, c_right, P)
            except ValueError:
                return pair, None, "degenerate"
        try:
            pose = geometry.pose_from_corners(P, desk_plane)
        except ValueError:
            return pair, None, "degenerate"
        why = self._pose_fails(pose, P, desk_plane, pair)
        if why:
            return pair, None, why
        if texture is not None and desk_plane is not None and self.cfg.sweep.check:
            # the cover's print against its corners' height (rovis.sweep)
            sweep, at_corners = texture_height(texture["left"], texture["right"], rig.Q_L,
                                               rig.Q_R, c_left, desk_plane, pose.size[2],
                                               self.cfg.sweep)
            # ...beyond its most textured quarter too, where it would move the cover up
            # (sweep.beyond_quarter: a taller neighbour's edge over one corner of a plain
            # cover; nothing lower shows through a cover: lower, the quad reaches beyond it)
            up = (sweep is not None and sweep.best_height > pose.size[2]
                  and sweep.best_ncc >= self.cfg.sweep.min_ncc_to_move)
            if sweep is not None and contradicts(sweep, at_corners, self.cfg.sweep) and (
                    not (up and self.cfg.sweep.beyond_quarter) or contradicts_beyond_quarter(
                        texture["left"], texture["right"], rig.Q_L, rig.Q_R, c_left,
                        desk_plane, sweep.best_height, pose.size[2], self.cfg.sweep)):
                P = self._on_plane(rig, c_left, c_right, desk_plane, sweep)
                if P is None:
                    return pair, None, "texture height"
                pair = _pair_at(rig, pair, P)
                c_left, c_right = pair.left, pair.right
                try:
                    pose = geometry.pose_from_corners(P, desk_plane)
                except ValueError:
                    return pair, None, "degenerate"
                why = self._pose_fails(pose, P, desk_plane, pair)  # e.g. a print on the desk
                if why:
                    return pair, None, why
        reproj = np.concatenate([
            np.linalg.norm(geometry.project(rig.Q_L, P) - c_left, axis=1),
            np.linalg.norm(geometry.project(rig.Q_R, P) - c_right, axis=1)])
        return pair, BookDetection(
            id=0, pose=pose, corners_world=P,
            corners_left_px=c_left, corners_right_px=c_right,  # ideal: made raw in detect
            reprojection_error_px=float(reproj.mean()),
            quality=pair.quality, stereo_error_px=pair.error_px,
            source="one image" if pair.transferred else pair.source), ""


def _segmented(pair: Pair, book: BookDetection) -> bool:
    """Whether a found book is a cover both images' segmentations found, every side seen
    (the better evidence where covers disagree: :meth:`Detector._fit_extents`,
    :meth:`Detector._without_overlaps`)."""
    return book.source == "segmentation" and not pair.three_sided


def _over_any_of(pair: Pair, found: list[tuple[Pair, BookDetection]], limit: float) -> bool:
    """Whether ``pair``'s quad lies over a quad of ``found``'s by more than ``limit`` of the
    smaller one (:func:`quad_overlap`) in either image (:func:`_over_any` in each)."""
    return any(bool(_over_any(getattr(pair, cam)[None], [getattr(p, cam) for p, _ in found],
                              limit)[0]) for cam in ("left", "right"))


def _read_at(maps: list[tuple[HeightMap, NDArray[np.float64]]], height: float,
             cfg: TrimConfig) -> Callable[[NDArray[np.float64]], bool]:
    """A test of a region of the desk (world corners (4, 3), in order around it): whether
    the height maps read it (:func:`rovis.trim.map_height`) within ``cfg.tolerance`` of
    ``height`` (metres above the desk)."""
    def reads_at(region: NDArray[np.float64]) -> bool:
        h = map_height(region, maps, cfg)
        return h is not None and abs(h - height) <= cfg.tolerance
    return reads_at


def _footprints(hm: HeightMap, Q: NDArray[np.float64], found: list[tuple[Pair, BookDetection]],
                margin_px: int) -> NDArray[np.bool_]:
    """The pixels of the map ``hm`` (over the image of projection ``Q``) that the covers of
    ``found`` take, and those within ``margin_px`` of them."""
    mask = np.zeros(hm.height.shape, np.uint8)
    for _, book in found:
        px = geometry.project(Q, np.asarray(book.corners_world))
        cv2.fillConvexPoly(mask, np.round(px * 16).astype(np.int32), 1, cv2.LINE_8, 4)
    if margin_px > 0:
        mask = cv2.dilate(mask, np.ones((2 * margin_px + 1,) * 2, np.uint8))
    return mask.astype(bool)


def _in_eq1_order(pair: Pair) -> Pair:
    """``pair`` with both images' corners rolled so the left image's top-left corner
    (smallest x + y) comes first: eq. 1's order there, the right's corners corresponding."""
    shift = int(np.argmin(pair.left.sum(axis=1)))
    return replace(pair, left=np.roll(pair.left, -shift, axis=0),
                   right=np.roll(pair.right, -shift, axis=0))


def _transferred_fit(rig: StereoRig, pair: Pair, dst: str, unseen: int,
                     desk_plane: NDArray[np.float64], max_off: float, *,
                     excuse_px: float = 0.0) -> NDArray[np.float64] | None:
    """The cover of a pair the one-image search made (:meth:`Detector._from_pool_one_image`)
    as one rectangle parallel to the desk (:func:`rovis.geometry.fit_rectangle_sides`),
    fitted to every side of the image it was found in and, in the other image ``dst``, to
    the two sides that run from the ``unseen`` side to its opposite only.

    The unseen side (a book's end against another's, end to end) showed no edge to place
    it. That leaves the opposite side (the other end) as the one across the epipolar lines
    that places the height, and refined in each image on its own it is a pixel or two off
    (a thick book's end face blurs it): laid on it, the cover comes out 10–20 mm off in
    height (Table II's two plain books end to end, docs/stereo.md). The two sides from end
    to end are refined along their whole length.

    Returns the corners (4, 3), world metres, in the pair's order, or None where the fit
    fails or misses a side it used by more than ``max_off`` pixels
    (``DetectConfig.flat_refit_sides``).

    With ``excuse_px`` > 0, the unseen side in the image the cover was found in, still
    fitted to, may be missed by up to that many pixels: there it was placed where the edges
    of the two sides beside it end, which at a seam is a few pixels off and askew (the Table
    II renders' plain book end to end with a taller one of its tone, scenes 9 and 17: missed
    by 3.7 and 4.4 px, where the other sides are missed by 0.8 px or less).
    """
    P0 = geometry.triangulate(rig.Q_L, rig.Q_R, pair.left, pair.right)
    if not np.all(np.isfinite(P0)):
        return None
    use = np.ones((2, 4), bool)
    use[0 if dst == "left" else 1, [unseen, (unseen + 2) % 4]] = False
    check = use.copy()
    own = (1 if dst == "left" else 0, unseen)  # the unseen side in its own image
    check[own] = excuse_px <= 0
    try:
        P, off = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pair.left, pair.right, P0,
                                              desk_plane, use=use)
    except ValueError:
        return None
    # the rectangle must lie on the sides it was fitted to: projected, any rectangle is a
    # flat cover, and the pose checks would pass a fit to sides that make none
    if not np.all(np.isfinite(P)) or np.abs(off[check]).max() > max_off:
        return None
    if excuse_px > 0 and abs(off[own]) > excuse_px:
        return None
    return P


def _pair_at(rig: StereoRig, pair: Pair, P: NDArray[np.float64]) -> Pair:
    """``pair`` with its corners moved to the projections of world corners ``P`` (4, 3) in
    both ideal images (a cover placed in 3D: its images agree exactly)."""
    return replace(pair, left=geometry.project(rig.Q_L, P), right=geometry.project(rig.Q_R, P))


def _in_desk_plane(P: NDArray[np.float64], on_desk: NDArray[np.float64],
                   e1: NDArray[np.float64], e2: NDArray[np.float64]) -> NDArray[np.float32]:
    """World points ``P`` (N, 3) as coordinates (N, 2) in the desk plane's frame
    (:func:`rovis.sweep._plane_frame`: its origin ``on_desk`` and axes ``e1``, ``e2``)."""
    d = P - on_desk
    return np.stack([d @ e1, d @ e2], axis=1).astype(np.float32)


def _shared(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """The share of convex quad ``a`` (4, 2) that quad ``b`` covers."""
    inter, _ = cv2.intersectConvexConvex(a.astype(np.float32), b.astype(np.float32))
    area = cv2.contourArea(a.astype(np.float32))
    return float(inter) / area if area > 0 else 1.0


def _over_any(quads: NDArray[np.float64], others: Sequence[NDArray[np.float64]],
              share: float) -> NDArray[np.bool_]:
    """Per quad of ``quads`` (N, 4, 2), whether one of ``others`` (each (4, 2)) overlaps it
    by more than ``share`` (:func:`quad_overlap`).

    The same as asking quad_overlap of every pair, which costs most of a pool's pass over
    thousands of pairs: it is asked only of the pairs whose boxes meet (in float32, the
    corners it reads), or with a quad of no area (an overlap of 1 to it). Two quads of
    area apart overlap by 0."""
    out = np.zeros(len(quads), bool)
    if len(quads) == 0 or len(others) == 0:
        return out
    q32, t32 = quads.astype(np.float32), np.asarray(others).astype(np.float32)
    ask = ~np.any((t32.min(axis=1)[None] > q32.max(axis=1)[:, None])
                  | (t32.max(axis=1)[None] < q32.min(axis=1)[:, None]), axis=2)  # (N, T)
    q_area = [cv2.contourArea(q) for q in q32]
    t_area = [cv2.contourArea(t) for t in t32]
    ask |= np.array([not a > 0 for a in q_area])[:, None]
    ask |= np.array([not a > 0 for a in t_area])[None, :]
    if share < 0:  # then 0 is over it too
        ask[:] = True
    for k, t in zip(*(i.tolist() for i in np.nonzero(ask))):
        if out[k]:
            continue
        # quad_overlap, its areas computed once per quad
        inter, _ = cv2.intersectConvexConvex(q32[k], t32[t])
        smaller = min(q_area[k], t_area[t])
        if (float(inter) / smaller if smaller > 0 else 1.0) > share:
            out[k] = True
    return out


def _outlines(Q: NDArray[np.float64], cam: str, books: list[tuple[Pair, BookDetection]],
              up: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """Each book's outline in camera ``cam`` (projection ``Q``): the convex hull (M, 2) of
    its cover and its foot (the cover dropped onto the desk, ``up`` its unit normal and
    offset), page block included."""
    out = []
    for p, b in books:
        foot = b.corners_world - np.outer(geometry.plane_distance(up, b.corners_world), up[:3])
        both = np.vstack([getattr(p, cam), geometry.project(Q, foot)])
        out.append(cv2.convexHull(both.astype(np.float32)).reshape(-1, 2))
    return out


def _sides_on(quad: NDArray[np.float64], regions: Sequence[NDArray[np.float64]], *,
              tol_px: float = 2.0, share: float = 0.5) -> NDArray[np.bool_]:
    """Which sides of ``quad`` (4, 2) lie on one of the convex ``regions`` (each (M, 2), a
    found book's outline in the image, its corners in order): at least ``share`` of the
    side's points (its middle 80 %) inside the region or within ``tol_px`` of it."""
    out = np.zeros(4, bool)
    t = np.linspace(0.1, 0.9, 17)[None, :, None]
    p = (quad[:, None] + t * (np.roll(quad, -1, axis=0) - quad)[:, None]).reshape(-1, 2)
    # the points' box, tol_px and a pixel more (a margin far above any rounding)
    low, high = p.min(axis=0) - (tol_px + 1.0), p.max(axis=0) + (tol_px + 1.0)
    for region in regions:
        a = np.asarray(region, dtype=np.float64)
        ab = np.roll(a, -1, axis=0) - a  # (M, 2) the outline's sides
        # A region with an area whose box misses that box holds none of the points and
        # lies more than tol_px from each: it changes nothing, and is not looked at (most
        # books are elsewhere). (A region with no area, a segment or a point, is: the
        # signs of the cross products below are all 0 along its line.)
        if ((np.any(a.min(axis=0) > high) or np.any(a.max(axis=0) < low))
                and abs(float(np.sum(a[:, 0] * ab[:, 1] - a[:, 1] * ab[:, 0]))) > 1.0):
            continue
        ap = p[:, None] - a[None]  # (N, M, 2)
        cross = ab[:, 0] * ap[..., 1] - ab[:, 1] * ap[..., 0]
        inside = np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)
        dist = _point_segment_distance(p[:, None], a[None], (a + ab)[None]).min(axis=1)
        out |= np.mean((inside | (dist <= tol_px)).reshape(4, -1), axis=1) >= share
    return out


def _three_sided(seg: Segmentation, k: int) -> bool:
    """Whether cover ``k`` of ``seg`` has its fourth side unseen
    (:attr:`Segmentation.three_sided`)."""
    return bool(k < len(seg.three_sided) and seg.three_sided[k])


def _is_union(a: int, quads: NDArray[np.float64], area: NDArray[np.float64],
              max_overlap: float, fill: float = 0.8) -> bool:
    """Whether quad ``a`` of ``quads`` (N, 4, 2) is filled by two or more smaller ones
    (each at least 90 % inside it, overlapping each other by at most ``max_overlap``) that
    cover at least ``fill`` of its area (``area``: (N,), px²): two touching books."""
    inner = [b for b in np.argsort(-area, kind="stable").tolist()
             if b != a and area[b] < 0.9 * area[a] and quad_overlap(quads[b], quads[a]) > 0.9]
    kept: list[int] = []
    for b in inner:
        if not any(quad_overlap(quads[b], quads[k]) > max_overlap for k in kept):
            kept.append(b)
    return len(kept) >= 2 and float(area[kept].sum()) >= fill * area[a]


def _skew_deg(P: NDArray[np.float64]) -> NDArray[np.float64]:
    """(4,): how far each corner's angle of a quad of world corners ``P`` (4, 3) lies from
    90° (degrees), corner k between side k - 1 and side k; 90° at both ends of a side of no
    length (:func:`rovis.stereo.side_lengths_and_corner_cos`, as :func:`flat_rectangle`
    asks)."""
    return np.degrees(np.arcsin(np.clip(side_lengths_and_corner_cos(P)[1], 0.0, 1.0)))


def _tilt_deg(pose: geometry.BookPose, desk_plane: NDArray[np.float64] | None) -> float:
    """Degrees between a cover's normal and the desk's (0 without a desk plane)."""
    if desk_plane is None:
        return 0.0
    return float(np.degrees(np.arccos(np.clip(pose.R[:, 2] @ desk_plane[:3], -1, 1))))


def roi_mask(rig: StereoRig, camera: Literal["left", "right"], T_world_marker: NDArray[np.float64], *,
             x: tuple[float, float] = marker.WORKSPACE_X, y: tuple[float, float] = marker.WORKSPACE_Y,
             height: float = 0.10, margin_px: int = 8,
             view: IdealView | None = None) -> NDArray[np.uint8]:
    """The workspace as a volume — desk to ``height`` above it — seen in the ideal image
    (the rig's, or ``view``'s).

    A cover lies above the desk: near the workspace's edge it is seen outside the desk-level
    rectangle. In ideal (undistorted) pixels the image of the prism is the convex hull of
    its two rectangles; it is grown by ``margin_px``.

    Returns
    -------
    ndarray, shape (H, W), uint8 — 255 inside.
    """
    pts = []
    for z in (0.0, height):
        lifted = T_world_marker @ geometry.make_transform(np.eye(3), [0.0, 0.0, z])
        raw = marker.workspace_polygon(rig, camera, T_world_marker=lifted, x=x, y=y)
        if len(raw) >= 3:
            ideal = rig.undistort_points(raw, camera)
            pts.append(ideal if view is None else view.from_rig_ideal(ideal))
    w, h = rig.image_size if view is None else view.size  # type: ignore[misc]
    mask = np.zeros((h, w), np.uint8)
    if pts:
        hull = cv2.convexHull(np.vstack(pts).astype(np.float32))
        cv2.fillConvexPoly(mask, np.rint(hull).astype(np.int32), 255)
        if margin_px > 0:
            k = 2 * margin_px + 1
            mask = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    return mask



def detect(left: NDArray[np.generic], right: NDArray[np.generic], rig: StereoRig, *,
           method: str = "closed", cfg: DetectConfig | None = None) -> FrameResult:
    """Find the books in one stereo pair (see :class:`Detector` for sequences).

    Parameters
    ----------
    left, right : ndarray, shape (H, W) or (H, W, 3)
        Raw images from the calibrated rig.
    rig : StereoRig
    method : str
        Segmentation method (closed loop by default).
    cfg : DetectConfig, optional
        Full settings; its ``method`` is replaced by ``method``.

    Returns
    -------
    FrameResult
        Books with pose, cuboid and pixel corners; the same content as the detection JSON.
    """
    cfg = replace(cfg or DetectConfig(), method=method)
    return Detector(rig, cfg).detect(left, right)
