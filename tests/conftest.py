from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rovis import geometry
from rovis.calib import StereoRig, make_rig

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data" / "bumblebee2"


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
