"""The paper's classical baseline (Shukrullo et al., as the paper reimplements it): the
maximum deformation of the depth image, mapped to force in N by a 3rd-order polynomial
fitted on labelled frames."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import check_fields
from ..errors import OptionsError
from ..typed_json import check


def max_deformation(depth: np.ndarray) -> float:
    """Maximum of a depth image (H x W or H x W x 1, 8-bit levels or float); 0 if empty."""
    d = np.asarray(depth, dtype=np.float64)
    finite = d[np.isfinite(d)]
    return float(finite.max()) if finite.size else 0.0


@dataclass(slots=True)
class MaxDeformationBaseline:
    """force_n = polyval(coeffs, max_deformation(depth)); coeffs highest power first."""

    coeffs: tuple[float, ...] = field(metadata=check(nonempty=True, expected="polynomial coefficients (numbers, "
                                                                             "highest power first)"))
    degree: int = field(default=3, metadata=check(ge=0))

    def __post_init__(self) -> None:
        check_fields(self)
        if len(self.coeffs) != self.degree + 1:
            raise OptionsError(f"MaxDeformationBaseline.coeffs: {len(self.coeffs)} coefficients; expected degree + 1 "
                               f"= {self.degree + 1}")

    @classmethod
    def fit(cls, depths, forces_n, degree: int = 3) -> MaxDeformationBaseline:
        """Least-squares fit on depth images and their forces (N); needs > degree frames."""
        x = np.array([max_deformation(d) for d in depths], dtype=np.float64)
        y = np.asarray(forces_n, dtype=np.float64)
        if x.size != y.size:
            raise ValueError(f"fit: {x.size} depth images but {y.size} forces")
        if x.size <= degree or np.unique(x).size <= degree:
            raise ValueError(f"fit: {np.unique(x).size} distinct deformations; a degree-{degree} polynomial needs more")
        if not np.all(np.isfinite(y)):
            raise ValueError("fit: forces hold NaN or inf")
        return cls(tuple(float(c) for c in np.polyfit(x, y, degree)), degree)

    def predict(self, depth: np.ndarray) -> float:
        """Force in N for one depth image."""
        return float(np.polyval(self.coeffs, max_deformation(depth)))

    def save(self, path: str | os.PathLike) -> Path:
        p = Path(path)
        p.write_text(json.dumps({"model": "max_deformation_poly", "degree": self.degree, "coeffs": list(self.coeffs)}))
        return p

    @classmethod
    def load(cls, path: str | os.PathLike) -> MaxDeformationBaseline:
        rec = json.loads(Path(path).read_text())
        if rec.get("model") != "max_deformation_poly":
            raise ValueError(f"{path}: not a max-deformation baseline (model={rec.get('model')!r})")
        return cls(tuple(float(c) for c in rec["coeffs"]), int(rec["degree"]))
