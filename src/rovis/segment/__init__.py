"""Boundary segmentation of book covers (paper §3): edges, lines, quads, eq. 2, control."""

from rovis.segment.boundary import Evaluation, SegmentConfig, Segmentation, evaluate, finish
from rovis.segment.control import CascadeController
from rovis.segment.edges import Gradients, canny, gradients
from rovis.segment.lines import Lines, hough_lines
from rovis.segment.quads import QuadConfig, order_corners
from rovis.segment.quality import quality

__all__ = ["CascadeController", "Evaluation", "Gradients", "Lines", "QuadConfig", "SegmentConfig",
           "Segmentation", "canny", "evaluate", "finish", "gradients", "hough_lines",
           "order_corners", "quality"]
