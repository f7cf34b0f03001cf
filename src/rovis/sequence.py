"""Stereo pairs from files: pairing left/right images and running one Detector over them.

``rovis detect`` takes a left and a right *source*: two image files (one frame), or two
folders or quoted glob patterns (a sequence). A sequence keeps one :class:`Detector`, so the
controllers start each frame from the previous frame's optimum, and a bad frame (missing,
unreadable or truncated image, wrong size…) becomes a result with an ``error``, never the end
of the run.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rovis.imageio import read_gray
from rovis.pipeline import Detector
from rovis.results import FrameResult

IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm", ".ppm", ".bmp",
                            ".pnm", ".webp"})
# Words that say which camera a file is from; removed to get the name both files share.
_SIDE = re.compile(r"left|right", re.IGNORECASE)


@dataclass(frozen=True)
class FramePair:
    """One stereo pair of files; either may be None when its partner has no match."""

    index: int
    left: Path | None
    right: Path | None


@dataclass(frozen=True, eq=False)
class FrameOutcome:
    """What became of one pair: a result, or the reason there is none."""

    pair: FramePair
    result: FrameResult | None = None
    error: str | None = None
    left_image: np.ndarray | None = None
    right_image: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        return self.result is not None

    def to_dict(self) -> dict[str, object]:
        """The detection JSON of DESIGN §3 with ``frame``, ``left``, ``right`` first; for a
        bad frame those three and ``error``."""
        names = {"frame": self.pair.index,
                 "left": None if self.pair.left is None else str(self.pair.left),
                 "right": None if self.pair.right is None else str(self.pair.right)}
        if self.result is None:
            return {**names, "error": self.error}
        return self.result.to_dict(**names)


def is_sequence_source(source: str) -> bool:
    """True for a folder or a glob pattern, False for a single file (existing or not)."""
    return glob.has_magic(source) or Path(source).is_dir()


def list_images(source: str, what: str, side: str | None = None) -> list[Path]:
    """The image files of a folder (sorted, image suffixes only) or a glob pattern (sorted).

    With ``side`` ("left" or "right"), a folder holding files named after that side (one
    folder with ``left01.png``, ``right01.png``…) gives only those.

    Raises
    ------
    ValueError
        When nothing matches, naming ``what`` and ``source``.
    """
    if Path(source).is_dir():
        paths = sorted(p for p in Path(source).iterdir()
                       if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
        if side is not None:
            named = [p for p in paths if side in p.name.lower()]
            paths = named or paths
        if not paths:
            raise ValueError(f"{what}: no image files in folder {source}")
        return paths
    paths = sorted(Path(p) for p in glob.glob(source) if not Path(p).is_dir())
    if not paths:
        if not glob.has_magic(source):
            raise ValueError(f"{what}: {source}: image file not found")
        raise ValueError(f"{what}: no file matches {source!r}")
    return paths


def _keys(paths: list[Path]) -> list[str]:
    """Each path relative to the paths' common folder, without suffix and without the words
    left/right: ``0003/left.png`` → ``0003/``, ``left01.jpg`` → ``01``."""
    parents = [str(p.parent) for p in paths]
    base = Path(os.path.commonpath(parents)) if parents else Path(".")
    out = []
    for p in paths:
        rel = p.relative_to(base) if p.is_relative_to(base) else p
        out.append(_SIDE.sub("", str(rel.with_suffix(""))).lower())
    return out


def pair_images(left: list[Path], right: list[Path]) -> list[FramePair]:
    """Pair left and right image files.

    By the name they share once the words left/right, the suffix and each side's common
    folder are removed (``left01.jpg``/``right01.jpg``; ``0000/left.png``/``0000/right.png``;
    ``L/img3.png``/``R/img3.png``) when that pairs at least one file and is one-to-one; a file
    without a partner then becomes a pair with a missing side (reported as a bad frame).
    Otherwise, with as many left as right files, in sorted order.

    Raises
    ------
    ValueError
        Different numbers of files whose names do not pair up.
    """
    kl, kr = _keys(left), _keys(right)
    unique = len(set(kl)) == len(kl) and len(set(kr)) == len(kr)
    common = set(kl) & set(kr)
    if unique and common:
        by_key_r = dict(zip(kr, right))
        by_key_l = dict(zip(kl, left))
        keys = sorted(set(kl) | set(kr),
                      key=lambda k: str(by_key_l.get(k) or by_key_r.get(k)))
        return [FramePair(i, by_key_l.get(k), by_key_r.get(k)) for i, k in enumerate(keys)]
    if len(left) != len(right):
        raise ValueError(f"{len(left)} left images but {len(right)} right images, and their "
                         "names do not pair up (expected names like left01.png/right01.png)")
    return [FramePair(i, l_, r_) for i, (l_, r_) in enumerate(zip(left, right))]


def run_pair(detector: Detector, pair: FramePair, *, keep_images: bool = False,
             track: bool = False) -> FrameOutcome:
    """Read one pair and detect; every expected failure becomes the outcome's ``error``.

    ``track``: follow the previous frame's books (:meth:`Detector.track`) and detect only
    where that fails."""
    if pair.left is None or pair.right is None:
        have = pair.left or pair.right
        side = "right" if pair.right is None else "left"
        return FrameOutcome(pair, error=f"{have}: no {side} image pairs with it")
    try:
        left = read_gray(pair.left)
        right = read_gray(pair.right)
        result = detector.track(left, right) if track else None
        if result is None:
            result = detector.detect(left, right)
    except (ValueError, OSError, cv2.error) as exc:  # this frame's input, not the run's
        return FrameOutcome(pair, error=" ".join(str(exc).split()))
    if keep_images:
        return FrameOutcome(pair, result=result, left_image=left, right_image=right)
    return FrameOutcome(pair, result=result)


def run_sequence(detector: Detector, pairs: list[FramePair], *, keep_images: bool = False,
                 track_every: int = 0,
                 on_frame: Callable[[FrameOutcome], None] | None = None) -> Iterator[FrameOutcome]:
    """Detect in each pair in order with one detector (warm-started controllers).

    ``track_every`` > 1: a still camera's sequence; detect in the first frame and every
    ``track_every``-th, and in the frames between follow the books already found
    (:meth:`Detector.track`, a few tens of milliseconds), detecting afresh in any frame
    where a book is not where it was. New books are found at the next detection.

    Yields each :class:`FrameOutcome` as it is done; ``on_frame`` is called with it first.
    """
    if track_every < 0:
        raise ValueError(f"track_every: expected 0 (off) or a positive number of frames, "
                         f"got {track_every}")
    detector.reset()
    for k, pair in enumerate(pairs):
        track = track_every > 1 and k % track_every != 0
        outcome = run_pair(detector, pair, keep_images=keep_images, track=track)
        if on_frame is not None:
            on_frame(outcome)
        yield outcome
