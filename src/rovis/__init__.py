"""rovis: robust detection and 3D reconstruction of books on a desk with a stereo camera.

An implementation of Natarajan, Grigorescu, Mronga & Gräser, "Robust Detection and 3D
Reconstruction of Boundary Segmented Objects in a Robotic Library Scenario" (ROVIS/FRIEND).
"""

from rovis.calib import StereoRig, load_calibration, make_rig, save_calibration
from rovis.geometry import BookPose, pose_from_corners, triangulate
from rovis.pipeline import DetectConfig, Detector, detect
from rovis.results import BookDetection, FrameResult

__version__ = "0.1.0"

__all__ = ["BookDetection", "BookPose", "DetectConfig", "Detector", "FrameResult", "StereoRig",
           "detect", "load_calibration", "make_rig", "pose_from_corners", "save_calibration",
           "triangulate", "__version__"]
