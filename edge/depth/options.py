"""The depth stage's options (:class:`DepthOptions`, validated where they enter) and the frame
reducer to its grid; edge/depth/stage.py runs them."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from ..checks import check_fields
from ..errors import OptionsError
from ..frames import FRAME_COLS, FRAME_ROWS, FRAME_SHAPE
from ..typed_json import check
from .gradients import GradientGuards

MODES = ("exact", "paper")



def frame_reducer(downscale: int, reduction: str = ""):
    """The :class:`~tactile_force.edge.gate.reduce.FrameReducer` of full-resolution 320x240x3 frames
    to the depth grid: ``reduction`` a :class:`~tactile_force.edge.bundle.manifest.Reduction` value
    ('' = the package's default for that factor, :func:`~tactile_force.edge.gate.reduce.default_reduction`)."""
    from ..bundle.manifest import FrameReduction, Reduction
    from ..gate.reduce import FrameReducer, default_reduction

    red = FrameReduction(Reduction(reduction), downscale) if reduction else default_reduction(downscale)
    red.check()
    return FrameReducer(red, FRAME_SHAPE)


@dataclass(slots=True)
class DepthOptions:
    """mapping: path of the paper MLP .npz or of a ``calibrate-depth`` .npz;
    mode: 'exact' (decoded normals, guarded gradients, exact DST-I solve, heights in px)
    or 'paper' (the authors' pipeline; needs the paper MLP and a reference);
    levels_per_px: exact-mode 8-bit levels per pixel of indentation (255/20: 20 px -> 255);
    paper_scale: paper-mode levels per metre of the authors' map (their x255 times 1000);
    gel_width_m / gel_height_m: the authors' gel size for their gradient units (AUROVA DIGIT);
    guards: n_z floor and slope clamp; saturated_fraction: share of mask pixels with a
    channel at 255 above which the frame is flagged 'saturated'; solver_dtype: float32/64;
    mapping_step: exact mode evaluates the colour->normal mapping on every pixel of the
    mask (1) or on every 2nd row and column of it (2: a quarter of the work, each pixel
    takes the value of the evaluated pixel at its even row and column; the error against
    1 is in docs/benchmarks/latency.md); paper_dilation_px: paper mode evaluates the MLP
    only inside the contact mask dilated by this many pixels, elsewhere the gradients are
    the reference frames' (None, the default: on every pixel, as the authors did, so their
    checkpoints see their depth images; the masked variant's error is in latency.md);
    downscale: the depth grid is the frame reduced by this integer factor k (1: the full
    320 x 240 frame, paper mode and the authors' checkpoints; 4: 80 x 60, the compact
    bundles' network input); reduction: how a full-resolution frame handed to the stage is
    reduced to that grid, a :class:`~tactile_force.edge.bundle.manifest.Reduction` value ('area',
    'area-2x-steps'; '' = the package default for the factor; a bundle's depth record names it).

    Notes
    -----
    Units at ``downscale = k``: the grid pitch is k full-resolution pixels. Normals are
    unitless, so the slope ``-n_x / n_z`` is the same at every resolution; per *grid*
    pixel the height changes by ``k`` times that slope. The stage feeds the solver
    ``g = k * slope`` (forward differences along the grid, ``g[i, j] = h[i, j+1] - h[i, j]``
    with ``h`` in full-resolution pixels), so the solved height is in full-resolution
    pixels of indentation whatever ``k`` is, and ``levels_per_px`` keeps its meaning
    (255/48: 48 full-resolution pixels of indentation = 255). A calibration's
    ``px_per_mm`` (full resolution) converts heights to mm unchanged: ``h_mm = h / px_per_mm``;
    on the grid, lateral distances are ``k / px_per_mm`` mm per grid pixel. The guards
    (``max_slope``) act on the unitless slope, before the factor k.

    At k > 1 the slope of each forward difference is the mean of its two end pixels'
    slopes, ``g[i, j] = k (s[i, j] + s[i, j+1]) / 2`` (the slope half way between them; 0
    beyond the frame), not the slope at ``[i, j]`` alone: at a 4-pixel pitch using the
    pixel's own slope shifts the surface by half a grid pixel (2 px) and its error on a
    spherical cap is 3x larger (tests/edge/depth/test_depth_network_resolution.py). Full
    resolution (k = 1) keeps the pixel's own slope, as the authors' pipeline and every
    depth image made before.
    """

    mapping: str | os.PathLike = field(metadata=check(
        nonempty=True, expected="a path to the colour->normal .npz (str or os.PathLike)"))
    mode: str = field(default="exact", metadata=check(choices=MODES))
    levels_per_px: float = field(default=255.0 / 20.0, metadata=check(gt=0))
    paper_scale: float = field(default=255.0 * 1000.0, metadata=check(gt=0))
    gel_width_m: float = field(default=0.01832, metadata=check(gt=0))
    gel_height_m: float = field(default=0.02505, metadata=check(gt=0))
    guards: GradientGuards = field(default_factory=GradientGuards)
    saturated_fraction: float = field(default=0.5, metadata=check(ge=0, le=1))
    solver_dtype: str = field(default="float32", metadata=check(choices=("float32", "float64")))
    mapping_step: int = field(default=1, metadata=check(choices=(1, 2), expected="1 (every pixel) or 2"))
    paper_dilation_px: int | None = field(default=None, metadata=check(
        ge=0, expected="pixels >= 0 or None (evaluate everywhere)"))
    downscale: int = field(default=1, metadata=check(ge=1))
    reduction: str = ""

    def __post_init__(self) -> None:
        check_fields(self)
        k = self.downscale
        if FRAME_ROWS % k or FRAME_COLS % k:
            raise OptionsError(f"DepthOptions.downscale={k!r}: expected an integer k >= 1 dividing "
                               f"{FRAME_ROWS} and {FRAME_COLS} (1, 2, 4, 5, 8, ...)")
        if k > 1 and (FRAME_ROWS // k < 2 or FRAME_COLS // k < 2):
            raise OptionsError(f"DepthOptions.downscale={k}: the depth grid needs at least 2 x 2 pixels")
        if k > 1 and self.mode == "paper":
            raise OptionsError(f"DepthOptions.downscale={k}: paper mode runs at full resolution (downscale=1), "
                               "as the authors' checkpoints were trained")
        if k > 1 and self.mapping_step != 1:
            raise OptionsError(f"DepthOptions.mapping_step={self.mapping_step} with downscale={k}: at the network "
                               "resolution the mapping runs on every grid pixel (mapping_step=1)")
        if k > 1:
            try:
                frame_reducer(k, self.reduction)
            except ValueError as exc:
                raise OptionsError(f"DepthOptions.reduction={self.reduction!r} with downscale={k}: {exc}") from None
