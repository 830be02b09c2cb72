"""What a session reads from its analysis: the report (once per revision), the modes and their motions, the
particles' shares of a mode, the pair's λ⁽⁶⁾, and the exports. A base of app/state.py's Session, which holds the
inputs (model, params, scene, analysis, revision); pure Python (no viser).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import granstab
from granstab.mechanics.branches import BOTH, MINUS, PLUS, RIGID
from granstab.mechanics.verdicts import frequencies_and_growth

from .field import Field, field_png, lambda6_field
from .modes import label_modes, mode_offsets, rotation_matrix
from .pools import attributed, metric_family
from .scenes import Body, ShapeModel

CONSISTENT = (PLUS, MINUS, BOTH)
SAME_MODE = 0.999          # |cos| of two unit motions above which they are one mode (distinct_modes)


@dataclass(frozen=True)
class Mode:
    """One eigenpair of sym(𝓗^i) of branch `branch`: what the spectrum panel lists and the animation plays."""

    branch: int
    index: int
    eigenvalue: float
    code: int                  # granstab.mechanics.branches: PLUS, MINUS, BOTH (consistent), INCONSISTENT, RIGID
    label: str
    shares: dict
    hinges: bool
    name: str = ""             # the menu's name: what it does, λ, and which case (Readings.modes; unique)

    @property
    def consistent(self) -> bool:
        return self.code in CONSISTENT

    @property
    def key(self) -> str:
        return self.name or f"{self.label}, λ = {self.eigenvalue:.4g}"


def mode_names(modes: list, scene, masks: list) -> list[str]:
    """Unique plain names of `modes`, by what they do ("rolling", "gear", "sliding at contact 3 (top–left)"), their
    λ and ✓/✗ (consistent or not); the case (branch) where a scene has several, a count where two still agree."""
    names, seen = [], {}
    for m in modes:
        what = m.label
        if m.label == "sliding":
            at = np.flatnonzero(masks[m.branch] == 1)
            what = "sliding at contact" + ("s " if len(at) > 1 else " ") + ", ".join(
                f"{c + 1} ({scene.names[scene.p[c]]}–{scene.names[scene.q[c]]})" for c in at[:3]) + ("…" if len(at) > 3 else "")
        mark = "" if m.code == RIGID else " ✓" if m.consistent else " ✗"
        name = f"{what}, λ = {m.eigenvalue:.4g}{mark}" + (f" · case {m.branch + 1} of {len(masks)}"
                                                          if len(masks) > 1 else "")
        seen[name] = seen.get(name, 0) + 1
        names.append(name if seen[name] == 1 else f"{name} ({seen[name]})")
    return names


class Readings:
    """The readings of a Session's current analysis (its attributes: scene, analysis, params, revision, error, …)."""

    def headline(self) -> tuple[str | None, str]:
        """The verdict word and the reason under it, in one voice: the core's reason may call a neutral verdict whose
        zero is resolved only within its accuracy "NOT DETERMINED"; the page says the verdict once and that it is not
        proven (the table below says why)."""
        r = self.report()
        if r["verdict"] is None:
            return None, ""
        reason = r["reason"].replace("NOT DETERMINED:", "not proven:")
        if not r["sufficient"] and "not proven" not in reason:
            reason += " — not proven"
        return r["verdict"], reason

    def distinct_modes(self) -> dict:
        """Consistent modes by sign, each counted once: the same motion in several branches (a rolling mode that no
        sliding contact takes part in) is one mode. Two unit motions are the same where |cos| ≥ SAME_MODE.
        Returns {"negative": n, "zero": n, "positive": n}; the core's counts (report()["counts"]) are per branch."""
        names = ("negative", "zero", "positive")
        if self.analysis is None:
            return dict.fromkeys(names, 0)
        groups = {name: [] for name in names}          # consistent unit motions by sign, in (branch, index) order
        for i, b in enumerate(self.analysis.branches):
            lam, U = b.stability_eigenvalues, self.motions(i)
            sign = np.where(lam < -b.zero_tol, 0, np.where(lam > b.zero_tol, 2, 1))
            for s, name in enumerate(names):
                groups[name].append(U[:, np.isin(b.codes, CONSISTENT) & (sign == s)])
        out = {}
        for name, parts in groups.items():
            W = np.concatenate(parts, axis=1) if parts else np.zeros((0, 0))     # (no branch: nothing counted)
            same = np.abs(W.T @ W) >= SAME_MODE
            kept: list[int] = []
            for j in range(W.shape[1]):                # a motion counts unless an earlier counted one is the same
                if not same[j, kept].any():
                    kept.append(j)
            out[name] = len(kept)
        return out

    def motions(self, branch: int) -> np.ndarray:
        """The unit physical motions (n_dof, K) of every eigenvector of a branch (Analysis.motion, all at once;
        cached per analysis)."""
        if self._motions[0] != self.revision:
            self._motions = (self.revision, {})
        cache = self._motions[1]
        if branch not in cache:
            cache[branch] = self.analysis.motion(self.analysis.branches[branch].stability_vectors)
        return cache[branch]

    def dynamics(self) -> dict | None:
        """Inertia metric only (λ = ω², eq:Hm's 𝓗 in the kinetic-energy metric): the lowest frequencies ω = √λ and the
        largest growth rates √(−λ) of the branch with the lowest eigenvalue, eigenvalues resolved by their accuracy."""
        if self.analysis is None or self.metric != "inertia":
            return None
        b = min(self.analysis.branches, key=lambda b: b.stability_eigenvalues.min())
        frequencies, growth = frequencies_and_growth(b.stability_eigenvalues, b.accuracy)
        return {"frequencies": np.sort(frequencies)[:4], "growth_rates": -np.sort(-growth)[:3], "branch": b.mask}

    def report(self) -> dict:
        """What the verdict panel shows: verdict, reason, flags, counts, the largest error estimate, times.
        Computed once per revision (its Type-1 check solves the load response): a refresh reads it several times."""
        key = (self.revision, id(self.analysis), self.error, self.notice, self.metric, self.elapsed,
               self.analysis is not None and self.analysis.attribution is not None)
        if self._report[0] != key:
            self._report = (key, self._compute_report())
        return self._report[1]

    def _compute_report(self) -> dict:
        if self.analysis is None:
            return {"verdict": None, "error": self.error, "elapsed": self.elapsed}
        a, s = self.analysis, self.analysis.verdict
        worst = max(a.errors.items(), key=lambda kv: kv[1]) if a.errors else ("", 0.0)
        return {
            "verdict": s.verdict, "reason": s.reason, "sufficient": s.sufficient,
            "type2": s.type2_nonuniqueness, "type1": self._type1(),
            "hinges": s.hinges_on_tolerance, "n_branches": s.n_branches,
            "counts": (s.consistent_positive, s.consistent_zero, s.consistent_negative),
            "n_particles": self.scene.n_particles, "n_contacts": self.scene.n_contacts,
            "n_sliding": int(np.sum(self.scene.at_yield())), "worst_error": worst, "errors": a.errors,
            "analysis_time": a.timings.get("total", 0.0), "elapsed": self.elapsed, "warnings": a.warnings,
            "error": self.error, "notice": self.notice, "metric": self.metric, "dynamics": self.dynamics(),
            "attribution": None if a.attribution is None else a.attribution.line(),
        }

    def _type1(self) -> str:
        """type1, once per analysis (a report made again when the attribution arrives does not solve it again)."""
        if self._type1_of[0] is not self.analysis:
            self._type1_of = (self.analysis, self.type1())
        return self._type1_of[1]

    def attribute(self) -> bool:
        """Why the verdict is unstable (pools.attributed), for an analysis made without it; whether it changed."""
        return self.analysis is not None and attributed(self.analysis)

    def type1(self) -> str:
        """Type-1 non-uniqueness (Sec. 3.1) under a proportional load increment d𝕓 = current load.

        It needs two branches, i.e. a potentially sliding contact; the core's `verdicts.load_response` decides."""
        if self.analysis is None or len(self.analysis.branches) < 2:
            return "no (a single branch: no contact at yield)"
        from granstab.mechanics.verdicts import load_response
        s = self.scene
        if s.fixed is not None:
            return "not evaluated (a scene held by fixed particles)"
        db = np.concatenate([s.load, s.load_moment], axis=1).reshape(-1)
        if not np.any(db):
            return "not evaluated (no load to increment)"
        res = load_response(self.analysis, db)
        return "yes (proportional loading)" if res["type1_nonuniqueness"] else "no (proportional loading)"

    def modes(self) -> list[Mode]:
        """Every eigenpair of every branch, labelled by what its motion does (cached per analysis)."""
        if self._modes[0] == self.revision:
            return self._modes[1]
        out = []
        if self.analysis is not None:
            a = self.analysis
            for i, b in enumerate(a.branches):
                labels = label_modes(self.scene, self.motions(i), b.mask, a.length, b.codes == RIGID)
                out += [Mode(i, j, float(lam), int(code), lab.label, lab.shares, bool(b.hinges[j]))
                        for j, (lam, code, lab) in enumerate(zip(b.stability_eigenvalues, b.codes, labels))]
            names = mode_names(out, self.scene, [b.mask for b in a.branches])
            out = [replace(m, name=name) for m, name in zip(out, names)]
        self._modes = (self.revision, out)
        return out

    def mode(self, key: str) -> Mode | None:
        return next((m for m in self.modes() if m.key == key), None)

    def particle_shares(self, mode: Mode) -> np.ndarray:
        """Where the mode lives: each particle's |motion| √(|du|² + (size·|dθ|)²) over the largest one (N,), in [0, 1]."""
        b = self.analysis.branches[mode.branch]
        du, dth = mode_offsets(self.scene, self.analysis.motion(b.stability_vectors[:, mode.index]), self.size)
        share = np.sqrt(np.sum(du ** 2, axis=1) + self.size ** 2 * np.sum(dth ** 2, axis=1))
        return share / max(float(share.max()), 1e-300)

    def mode_bodies(self, mode: Mode, amplitude: float, phase: float) -> list[Body]:
        """Bodies displaced along `mode` at `phase` (radians): x + A s du, R(A s dθ) R with s the phase factor.

        A consistent-one-way mode (PLUS/MINUS) only moves in its consistent direction (s = ±|sin|)."""
        b = self.analysis.branches[mode.branch]
        U = self.analysis.motion(b.stability_vectors[:, mode.index])
        du, dth = mode_offsets(self.scene, U, self.size)
        s = np.sin(phase)
        s = abs(s) if mode.code == PLUS else -abs(s) if mode.code == MINUS else s
        index = {name: i for i, name in enumerate(self.scene.names)}
        out = []
        for body in self.bodies():
            i = index[body.name]
            dR = rotation_matrix(self.scene.dim, amplitude * s * dth[i])
            out.append(replace(body, x=body.x + amplitude * s * du[i], R=dR @ body.R))   # its shape kept
        return out

    def rolling_eigenvalue(self) -> float | None:
        """λ⁽⁶⁾ of the current analysis in units of k: the rolling-labelled eigenvalue of the first branch,
        0 exactly when |λ⁽⁶⁾| is within the branch's zero tolerance (`zero_tolerance()`)."""
        rolling = [m for m in self.modes() if m.branch == 0 and m.label == "rolling"]
        if not rolling:
            return None
        lam = rolling[0].eigenvalue
        return 0.0 if abs(lam) <= self.analysis.branches[0].zero_tol else lam / self.params["k"]

    def zero_tolerance(self) -> float | None:
        """The eigenvalue zero tolerance of the first branch in units of k (what "λ = 0" means here)."""
        if self.analysis is None or not self.analysis.branches:
            return None
        return self.analysis.branches[0].zero_tol / self.params["k"]

    def export_scene(self) -> tuple[str, bytes]:
        """The current scene as a scene file that reloads to the same analysis (shape or contact format, JSON)."""
        if isinstance(self.model, ShapeModel):
            data = self.model.to_dict(self.params)
        elif self.scene is not None:
            data = granstab.scene_to_dict(self.scene)
        else:
            raise ValueError("no scene to export")
        return f"{Path(str(self.preset)).stem}-scene.json", json.dumps(data, indent=1, default=_json).encode()

    def export_analysis(self) -> tuple[str, bytes]:
        """The analysis as JSON (`granstab analyze --json` object) with the app's parameters and mode labels."""
        if self.analysis is None:
            raise ValueError(f"no analysis to export: {self.error}")
        data = self.analysis.to_dict()
        data["app"] = {"preset": self.preset, "kind": self.kind,
                       "params": {k: self.params[k] for k in self.used_params},
                       "modes": [{"branch": m.branch, "index": m.index, "eigenvalue": m.eigenvalue,
                                  "consistent": m.consistent, "label": m.label} for m in self.modes()]}
        return f"{Path(str(self.preset)).stem}-analysis.json", json.dumps(data, indent=1, default=_json).encode()

    def export_contour(self) -> tuple[str, bytes]:
        field = self.field()
        if field is None:
            raise ValueError("the λ⁽⁶⁾ contour exists for the two-particle pair only")
        return "lambda6-contour.png", field_png(field, (self.params["rho_r"], self.params["f_kr"]))

    def check_metrics(self) -> dict | None:
        """The verdict in every metric of the family (L/10, L, 10L, inertia where masses are known), on request:
        the page shows the single-metric verdict first and runs this only when asked (it costs ~3× the analysis).
        Returns {"robust": bool, "metrics": [per-metric verdict and counts], "time": s} (None without a scene)."""
        if self.scene is None or self.analysis is None:
            return None
        return self.keep_metrics(metric_family(self.scene), self.revision)

    def keep_metrics(self, metrics: dict, revision: int) -> dict | None:
        """Keep a family check computed (metric_family, off the lock) for `revision`; one for an older scene or older
        parameters is dropped (None): the next move superseded it."""
        if revision != self.revision:
            return None
        self.metrics = {**metrics, "revision": revision}
        return self.metrics

    def family_estimate(self) -> float:
        """Seconds the family check should take here: three analyses in L's time (four with masses)."""
        return (4 if self.scene is not None and self.scene.mass is not None else 3) * self.elapsed

    @property
    def verdict(self) -> str | None:
        return None if self.analysis is None else self.analysis.verdict.verdict

    def field(self) -> Field | None:
        """The λ⁽⁶⁾ field for the pair (None for other scenes: no work for a panel that is not shown)."""
        if self.kind != "two_particle":
            return None
        return lambda6_field(self.params["alpha"], self.params["rolling"])

    @property
    def field_scale(self) -> float:
        """The length the λ⁽⁶⁾ surface is laid out in: the pair's r (fixed, unlike the particle size, which grows
        with ρ/r — the surface is cached, so the current-state marker must be placed on the same scale)."""
        return float(self.model.field_scale())


def _json(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
