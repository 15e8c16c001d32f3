"""Contact mechanics of the virtual DIGIT: normal force (N) -> indentation depth (mm).

Laws (E* in N/mm^2 = MPa, R and a in mm, d in mm):

- sphere, Hertz:          F = 4/3 E* sqrt(R) d^1.5
- flat shape, flat punch: F = 2 a E* d, a = sqrt(A / pi) the equivalent radius of the
  footprint area A that lies on the pad
- any other profile, per-pixel penalty (Winkler) model: pressure = k * penetration,
  F = k * sum(max(0, d - gap)) * pixel area, with k = 2 E* / (pi a_ref) so that a flat
  disc of radius a_ref obeys the flat-punch law exactly.

Object rigidity (the paper's Medium / High / Very High) enters twice: the gel and the
object are springs in series (1/E* = 1/E_gel + 1/E_obj; the gel takes the share
E_obj / (E_gel + E_obj) of the total indentation), and a soft object absorbs a fraction of
the force through its own conforming flanks. Two sensor effects are modelled on top: the gel
saturates (the force it can still turn into indentation flattens out from about 15 N), and
almost nothing is visible below about 1 N (``onset``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..checks import check_fields


@dataclass(frozen=True, slots=True)
class GelOptions:
    """Mechanical constants of the gel and the objects.

    gel_modulus_mpa: effective modulus E* of the gel on its rigid backing (MPa).
    object_modulus_mpa: E of each rigidity class (MPa; inf = rigid).
    absorbed_fraction: share of the force a soft object carries past the gel.
    saturation_knee_n / saturation_max_n: the gel force is F below the knee and approaches
    the max smoothly above it (tanh).
    onset_n: below about this force the visible deformation fades out (1 - exp(-(F/onset)^3)).
    penalty_ref_radius_mm: a_ref of the penalty stiffness k = 2 E* / (pi a_ref).
    """

    gel_modulus_mpa: float = 2.5
    object_modulus_mpa: dict = field(default_factory=lambda: {"medium": 2.5, "high": 25.0, "very_high": math.inf})
    absorbed_fraction: dict = field(default_factory=lambda: {"medium": 0.15, "high": 0.03, "very_high": 0.0})
    saturation_knee_n: float = 13.0
    saturation_max_n: float = 16.0
    onset_n: float = 1.2
    penalty_ref_radius_mm: float = 3.0

    def __post_init__(self) -> None:
        check_fields(self)

def _check_stiffness(options: GelOptions, stiffness: str) -> None:
    if stiffness not in options.object_modulus_mpa:
        raise ValueError(f"stiffness {stiffness!r}: expected one of {sorted(options.object_modulus_mpa)}")


def gel_force(force_n: float, stiffness: str, options: GelOptions) -> float:
    """Force (N) the gel turns into indentation: minus what a soft object absorbs, saturated."""
    _check_stiffness(options, stiffness)
    if not math.isfinite(force_n) or force_n < 0:
        raise ValueError(f"force_n: {force_n!r}; expected a finite force >= 0 N")
    f = force_n * (1.0 - options.absorbed_fraction[stiffness])
    knee, top = options.saturation_knee_n, options.saturation_max_n
    if f > knee:
        f = knee + (top - knee) * math.tanh((f - knee) / (top - knee))
    return f


def onset_visibility(force_n: float, options: GelOptions) -> float:
    """Fraction (0..1) of the indentation that shows in the image at gel force ``force_n``."""
    return 1.0 - math.exp(-((force_n / options.onset_n) ** 3))


def combined_modulus(stiffness: str, options: GelOptions) -> tuple[float, float]:
    """(E* of gel and object in series in MPa, the gel's share of the total indentation)."""
    _check_stiffness(options, stiffness)
    eg, eo = options.gel_modulus_mpa, options.object_modulus_mpa[stiffness]
    if math.isinf(eo):
        return eg, 1.0
    return 1.0 / (1.0 / eg + 1.0 / eo), eo / (eg + eo)


def hertz_depth(force_n: float, radius_mm: float, e_star: float) -> float:
    """Sphere indentation d (mm) from F = 4/3 E* sqrt(R) d^1.5."""
    return (3.0 * force_n / (4.0 * e_star * math.sqrt(radius_mm))) ** (2.0 / 3.0)


def hertz_force(depth_mm: float, radius_mm: float, e_star: float) -> float:
    """Sphere force (N) at indentation ``depth_mm`` (inverse of :func:`hertz_depth`)."""
    return 4.0 / 3.0 * e_star * math.sqrt(radius_mm) * max(depth_mm, 0.0) ** 1.5


def flat_punch_depth(force_n: float, area_mm2: float, e_star: float) -> float:
    """Flat punch indentation d (mm) from F = 2 a E* d with a = sqrt(A / pi)."""
    if area_mm2 <= 0:
        return 0.0
    return force_n / (2.0 * math.sqrt(area_mm2 / math.pi) * e_star)


def penalty_depth(force_n: float, gap_mm: np.ndarray, pixel_area_mm2: float, e_star: float,
                  options: GelOptions) -> float:
    """Depth d (mm) with k * sum(max(0, d - gap)) * pixel_area = F (exact, piecewise linear).

    gap_mm: finite gaps (mm, >= 0) of the pixels the body can touch.
    """
    g = np.sort(np.asarray(gap_mm, dtype=np.float64).ravel())
    if g.size == 0 or force_n <= 0:
        return 0.0
    k = 2.0 * e_star / (math.pi * options.penalty_ref_radius_mm)
    target = force_n / (k * pixel_area_mm2)  # = sum(max(0, d - g))
    csum = np.cumsum(g)
    n = np.arange(1, g.size + 1)
    at_knots = n * g - csum  # sum at d = g[j] over the first j+1 pixels
    j = int(np.searchsorted(at_knots, target, side="right")) - 1
    j = max(j, 0)
    return float((target + csum[j]) / (j + 1))
