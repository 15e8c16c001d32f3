"""Depth representation for the D / Dmod / RGBmod+D variants (numpy + OpenCV; SciPy's FFT
when installed): colour -> normal (paper MLP or our ball-press LUT), guarded gradients,
exact DST-I Poisson solve, the paper's 8-bit depth image, and the max-deformation baseline.
Conventions: see gradients.py and docs/depth.md."""

from .baseline import MaxDeformationBaseline, max_deformation
from .calibration import (
    AngleError,
    Circle,
    LUTOptions,
    NormalLUT,
    Press,
    cap_depth_px,
    detect_press_circle,
    evaluate_lut,
    fit_lut,
    sphere_normals,
)
from .gradients import GradientGuards, normals_to_gradients
from .normals import MappingError, PaperMLP, decode_paper_normals
from .poisson import PoissonSolver, forward_gradients
from .stage import DepthOptions, DepthResult, DepthStage

__all__ = [
    "AngleError", "Circle", "DepthOptions", "DepthResult", "DepthStage", "GradientGuards", "LUTOptions",
    "MappingError", "MaxDeformationBaseline", "NormalLUT", "PaperMLP", "PoissonSolver", "Press", "cap_depth_px",
    "decode_paper_normals", "detect_press_circle", "evaluate_lut", "fit_lut", "forward_gradients",
    "max_deformation", "normals_to_gradients", "sphere_normals",
]
