from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rovis import geometry
from rovis.calib import StereoRig, make_rig

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data" / "bumblebee2"


def pytest_report_header(config: pytest.Config) -> str:
    """The OpenCV under test beside the one constraints.txt pins: the synthetic scenes'
    pixels, and so the tests that pin down one rendered scene, depend on its release."""
    import cv2

    constraints = REPO / "constraints.txt"
    lines = constraints.read_text().splitlines() if constraints.exists() else []
    pinned = next((line.split("==", 1)[1].strip() for line in lines
                   if line.startswith("opencv-python-headless==")), "none")
    return f"rovis: OpenCV {cv2.__version__} (constraints.txt pins opencv-python-headless {pinned})"


def nearest_book(result, centre, on_desk: bool = False):  # type: ignore[no-untyped-def]
    """The book of detection ``result`` (:class:`rovis.results.FrameResult`) whose centre
    lies nearest ``centre`` (3,) (a true book's, metres), and how far (m): in space, or with
    ``on_desk`` over the desk (x, y alone)."""
    c = np.asarray(centre, dtype=np.float64)
    axes = slice(0, 2) if on_desk else slice(0, 3)
    book = min(result.objects, key=lambda o: np.linalg.norm(o.pose.center[axes] - c[axes]))
    return book, float(np.linalg.norm(book.pose.center[axes] - c[axes]))


@pytest.fixture
def rig() -> StereoRig:
    """A Bumblebee2-like rig 1.1 m above a desk, looking down 55°, world = desk frame."""
    target = np.array([0.45, 0.35, 0.0])
    eye = target + 1.1 * np.array([0.0, -np.cos(np.radians(55)), np.sin(np.radians(55))])
    return make_rig(T_world_left=geometry.look_at(eye, target), world_frame="marker")


@pytest.fixture
def bumblebee_dir() -> Path:
    if not (SHARED_DATA / "chess" / "stereo.yaml").exists():
        pytest.skip(f"real Bumblebee2 data not found at {SHARED_DATA}")
    return SHARED_DATA


def ideal_images(rig: StereoRig, rendering) -> dict[str, np.ndarray]:  # type: ignore[no-untyped-def]
    """Both raw images of a synthetic rendering, undistorted (ideal pixels, as the
    pipeline segments them)."""
    import cv2

    out = {}
    for cam, raw in (("left", rendering.left), ("right", rendering.right)):
        K, D = rig.intrinsics(cam)
        maps = cv2.initUndistortRectifyMap(K, D, None, K, rig.image_size, cv2.CV_16SC2)
        out[cam] = cv2.remap(raw, *maps, cv2.INTER_LINEAR)
    return out
