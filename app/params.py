"""The quantities the sliders set: key, label, range, step and what each means (plain data, no viser).

Forces and stiffnesses are dimensionless where the paper makes them so: f/(kr) and ρ/r for the pair,
rolling stiffness in units of k r². k itself only scales every eigenvalue (the verdict never depends on it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Param:
    key: str
    label: str
    lo: float
    hi: float
    step: float
    default: float
    hint: str

    def clean(self, value) -> float:
        """Clip to the range and round to the step's decimals (slider values carry float noise: 0.30000000000000004)."""
        value = float(value)
        if math.isnan(value):
            raise ValueError(f"{self.label}: not a number")
        decimals = max(0, len(f"{self.step:.10f}".rstrip("0").split(".")[1]))
        return round(min(max(value, self.lo), self.hi), decimals + 2)


PARAMS: dict[str, Param] = {p.key: p for p in (
    Param("rho_r", "ρ/r", 0.2, 3.0, 0.01, 0.5,
          "tip radius of curvature over radius: < 1 sharp, 1 circle, > 1 flat"),
    Param("f_kr", "f/(kr)", -0.005, 0.02, 0.0005, 0.01,
          "normal contact force over k·r: > 0 compressive, < 0 cohesive (tensile)"),
    Param("mu", "μ", 0.0, 1.5, 0.01, 0.5, "Coulomb friction coefficient"),
    Param("mobilised", "mobilised friction", 0.0, 1.0, 0.01, 0.0,
          "tangential force as a fraction of the Coulomb limit μ|f_n| (1 = sliding)"),
    Param("alpha", "α", 0.05, 2.0, 0.05, 1.0, "tangential over normal contact stiffness"),
    Param("k", "k", 0.1, 10.0, 0.1, 1.0, "normal contact stiffness (scales every eigenvalue)"),
    Param("rolling", "rolling stiffness/(kr²)", 0.0, 0.5, 0.005, 0.0, "contact moment stiffness M^pq"),
)}


def defaults() -> dict[str, float]:
    return {key: p.default for key, p in PARAMS.items()}
