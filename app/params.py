"""The quantities the sliders set: key, label, range, step and what each means (plain data, no viser).

Forces and stiffnesses are dimensionless where the paper makes them so: f/(kr) and ρ/r for the pair,
rolling stiffness in units of k r². k itself only scales every eigenvalue (the verdict never depends on it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Param:
    key: str
    label: str
    lo: float
    hi: float
    step: float
    default: float
    hint: str
    scale: bool = False       # only scales the answer: its range follows the scene's value (around)

    def clean(self, value) -> float:
        """Clip to the range and round to the step's decimals (slider values carry float noise: 0.30000000000000004)."""
        value = float(value)
        if math.isnan(value):
            raise ValueError(f"{self.label}: not a number")
        decimals = max(0, len(f"{self.step:.10f}".rstrip("0").split(".")[1]))
        return round(min(max(value, self.lo), self.hi), decimals + 2)

    def snap(self, value) -> float:
        """The nearest slider step to `value` (what the slider shows for a value picked elsewhere: the λ⁽⁶⁾ surface)."""
        value = self.clean(value)
        return self.clean(self.lo + round((value - self.lo) / self.step) * self.step)

    def around(self, value: float) -> Param:
        """The slider for a scene whose start value is `value`: a scale (k, which only scales every eigenvalue)
        outside the range moves its range, step and default by whole decades to hold it (a LAMMPS run's k = 10³
        on the 0.1-10 slider: clipped to 10 at the first move, while the box showed 1000); others are unchanged."""
        if not self.scale or value <= 0 or self.lo <= value <= self.hi:
            return self
        f = 10.0 ** round(math.log10(value / math.sqrt(self.lo * self.hi)))
        return replace(self, lo=self.lo * f, hi=self.hi * f, step=self.step * f, default=self.default * f)


PARAMS: dict[str, Param] = {p.key: p for p in (
    Param("rho_r", "ρ/r", 0.2, 3.0, 0.01, 0.5,
          "tip radius of curvature over radius: < 1 sharp, 1 circle, > 1 flat"),
    Param("f_kr", "f/(kr)", -0.005, 0.02, 0.0005, 0.01,
          "normal contact force over k·r: > 0 compressive, < 0 cohesive (tensile)"),
    Param("mu", "μ", 0.0, 1.5, 0.01, 0.5, "Coulomb friction coefficient"),
    Param("mobilised", "mobilised friction", 0.0, 1.0, 0.01, 0.0,
          "tangential force as a fraction of the Coulomb limit μ|f_n| (1 = sliding)"),
    Param("alpha", "α", 0.05, 2.0, 0.05, 1.0, "tangential over normal contact stiffness"),
    Param("k", "k", 0.1, 10.0, 0.1, 1.0, "normal contact stiffness (scales every eigenvalue)", scale=True),
    Param("rolling", "rolling stiffness/(kr²)", 0.0, 0.5, 0.005, 0.0, "contact moment stiffness M^pq"),
)}


def defaults() -> dict[str, float]:
    return {key: p.default for key, p in PARAMS.items()}
