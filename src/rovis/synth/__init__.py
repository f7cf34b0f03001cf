"""Synthetic library-desk stereo scenes with physically grounded light (DESIGN §4).

``sample_scene`` draws what is on the desk and how it is lit, ``render`` turns a scene into a
stereo pair plus ground truth, ``write_dataset`` writes DESIGN §3's dataset layout
(``rovis synth``).
"""

from rovis.synth.dataset import PROTOCOLS, contact_sheet, write_dataset
from rovis.synth.render import Rendering, render, scene_truth
from rovis.synth.scene import Light, Scene, sample_light, sample_rig, sample_scene

__all__ = ["PROTOCOLS", "Light", "Rendering", "Scene", "contact_sheet", "render",
           "sample_light", "sample_rig", "sample_scene", "scene_truth", "write_dataset"]
