"""The contact gate's options: thresholds in grey levels and shares of the frame, validated
once where they enter (the gate, its background learning and the scene's ``[gate]`` table
read them)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..checks import check_fields
from ..errors import OptionsError
from ..typed_json import check


@dataclass
class GateOptions:
    """Gate settings. Areas are fractions of the frame area so one setting fits any size.

    background_frames: frames averaged into the background when it is learnt at start.
    blur: odd Gaussian kernel size in pixels at the working (downscaled) resolution.
    threshold: colour difference (0..255, max over B, G, R after the fitted per-channel gain
        and offset) above which a pixel counts as changed.
    on_area_frac / off_area_frac: hysteresis thresholds on the masked area.
    min_blob_frac: connected regions smaller than this are dropped (noise specks).
    downscale: integer factor the frame is shrunk by before the work (1 = full res; 4 = the
        80x60 a compact model sees).
    refresh_rate: per-frame weight of a no-contact frame in the background (0 = frozen).
    saturation_threshold / saturation_area_frac: a changed area (difference above
        saturation_threshold) covering this fraction of the frame reads as gel saturation.
    convex_hull: replace each kept blob by its convex hull (the contact patch of a convex
        indenter is convex). Off by default: a DIGIT grasps any shape. See :meth:`gelsight_mini`.
    open_px: side (working pixels) of a morphological opening of the changed-pixel mask
        before the blobs are found (0 = none: the blur and ``min_blob_frac`` remove specks).
    trust: judge mismatch / invalid frames (off: the plain gate; the gain/offset
        compensation runs either way).
    fit_tolerance: a thumbnail cell fits the background when its residual after the fit is
        below this (grey levels).
    step_level: mean brightness change (grey levels) implied by the fitted gain/offset above
        which the frame is a sudden photometric step (background_mismatch).
    fit_floor: below this fraction of fitting cells, a change that appeared at once (no
        contact was being tracked) is a background mismatch.
    motion_explained: share of the residual explained by a shift/rotation of the background
        above which the gel or camera moved.
    noise_factor: pixel-noise level (mean |frame - blurred frame|) above noise_factor x the
        background's + 1 grey level is a noise burst (invalid).
    relearn_frames: stable frames (no contact-like blob) before a mismatched background is
        re-learnt from the live frame; 0 = never (call :meth:`ContactGate.relearn`).
    stable_level: mean thumbnail change (grey levels) between frames under which a frame is stable.
    """

    background_frames: int = field(default=5, metadata=check(ge=1, le=10_000))
    blur: int = field(default=3, metadata=check(
        ge=1, le=99, expected="an odd integer in [1, 99] (Gaussian kernel, pixels)"))
    threshold: float = field(default=10.0, metadata=check(gt=0, lt=255))
    on_area_frac: float = field(default=0.006, metadata=check(ge=0, lt=1))
    off_area_frac: float = field(default=0.003, metadata=check(ge=0, lt=1))
    min_blob_frac: float = field(default=0.0015, metadata=check(ge=0, lt=1))
    downscale: int = field(default=4, metadata=check(ge=1, le=16))
    refresh_rate: float = field(default=0.02, metadata=check(ge=0, lt=1))
    saturation_threshold: float = field(default=60.0, metadata=check(gt=0))
    saturation_area_frac: float = field(default=0.25, metadata=check(gt=0, le=1))
    convex_hull: bool = False
    open_px: int = field(default=0, metadata=check(ge=0, le=50, expected="an integer in [0, 50] (0 = no opening)"))
    trust: bool = True
    fit_tolerance: float = field(default=8.0, metadata=check(gt=0))
    step_level: float = field(default=10.0, metadata=check(gt=0))
    fit_floor: float = field(default=0.35, metadata=check(gt=0, lt=1))
    motion_explained: float = field(default=0.35, metadata=check(gt=0, lt=1))
    noise_factor: float = field(default=2.2, metadata=check(gt=0))
    relearn_frames: int = field(default=30, metadata=check(ge=0, le=1_000_000,
                                                            expected="an integer in [0, 1000000] (0 = never)"))
    stable_level: float = field(default=2.0, metadata=check(gt=0))

    @classmethod
    def gelsight_mini(cls, **overrides: object) -> GateOptions:
        """Settings for a GelSight Mini (480x640): its LEDs make a stronger colour halo
        around the contact than a DIGIT's, so a higher threshold, convex hulls (ball and
        other convex indenters) and a finer working resolution (x2). On the 16 labelled ball
        presses (shared data): IoU with the contact circles mean 0.65 (see docs/runtime.md)."""
        base: dict[str, object] = {"threshold": 28.0, "convex_hull": True, "downscale": 2, "blur": 5, "open_px": 3}
        return cls(**{**base, **overrides})  # type: ignore[arg-type]

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`~.errors.ArgumentTypeError` (a TypeError) or :class:`~.errors.OptionsError`
        (a ValueError) naming the first bad field; run at construction, and again by
        :class:`ContactGate` (fields may have been changed since)."""
        check_fields(self)
        if self.blur % 2 == 0:
            raise OptionsError(f"GateOptions.blur={self.blur}: expected an odd integer >= 1 (Gaussian kernel, pixels)")
        if not self.off_area_frac <= self.on_area_frac:
            raise OptionsError(f"GateOptions.on_area_frac={self.on_area_frac}, off_area_frac={self.off_area_frac}: "
                               "expected 0 <= off_area_frac <= on_area_frac < 1")
