"""The *Force uncertainty* and *Position uncertainty* controls of the Verdict tab (issue 42): a relative band ±x % on
every contact force and a band of ±y % of a radius on every contact and reference point, and one plain sentence
saying whether the verdict holds under them, depends on the data (a counter-example's forces shown, and whether it
moved the positions) or is undecided. 0 on both (the default) runs nothing. `robust_sentence` and `robustness`
are pure of viser (tests/app/test_app_uncertainty.py); granstab.uncertainty.data_robustness does the work
(docs/uncertainty.md: the position band's bound is rigorous, mechanics/nonaffine.py)."""
from __future__ import annotations

import numpy as np

from granstab.mechanics.uncertainty import Band
from granstab.uncertainty import data_robustness

MOST = 50          # the force slider's largest band, %
MOST_POSITION = 10  # the position slider's largest band, % of a radius


def radius(scene) -> float:
    """The scene's length unit for the position band: the mean contact arm |r^pq|, |r^qp| (a particle's radius)."""
    return float(np.mean(np.linalg.norm(np.concatenate([scene.r_pq, scene.r_qp]), axis=1)))


def robustness(s):
    """data_robustness of session `s`'s verdict under ±s.force_band % on the forces and ±s.position_band % of a
    radius on the positions (None at 0 on both, without an analysis, or on a map), computed once per (revision,
    bands): the session's own analysis is reused where its metric is L."""
    if not (s.force_band or s.position_band) or s.analysis is None or s.scene is None or s.on_map:
        return None
    key = (s.revision, s.force_band, s.position_band)
    if s.robust[0] != key:
        metric = "inertia" if s.analysis.length is None else "L"
        reuse = s.analysis if metric == "L" and len(s.analysis.branches) == s.analysis.verdict.n_branches else None
        band = Band(rel=s.force_band / 100, position=s.position_band / 100 * radius(s.scene))
        s.robust = (key, data_robustness(s.scene, band, metric=metric, rotation_length=s.analysis.length,
                                         analysis=reuse))
    return s.robust[1]


def _bands(percent: float, position: float) -> tuple[str, str]:
    """(the band as a heading, the sentence's "within …" words) for forces ±percent % and positions ±position %."""
    forces, places = f"±{percent:g} %", f"±{position:g} % of a radius"
    if not position:
        return forces, f"contact forces within {forces} of the measured ones"
    if not percent:
        return f"{places} in the positions", f"contact positions within {places} of the measured ones"
    return (f"{forces} in the forces and {places} in the positions",
            f"contact forces within {forces} and positions within {places} of the measured ones")


def robust_sentence(robust, percent: float, names=None, position: float = 0.0) -> str:
    """The plain-words line under the verdict table ("" at 0 on both or without a result). `names`: the contacts'
    labels (default c0, c1, …) for the counter-example's forces; `position`: the position band, % of a radius."""
    if robust is None or not (percent or position):
        return ""
    band, within = _bands(percent, position)
    if robust.robust == "holds":
        return (f"**Holds under {band}:** every set of {within} gives the same verdict ({robust.verdict}) — proven, "
                "not sampled.")
    if robust.robust == "depends":
        forces = np.asarray(robust.counterexample["forces"])
        labels = names or [f"c{i}" for i in range(len(forces))]
        shown = ", ".join(f"{n}: ({', '.join(f'{v:.4g}' for v in f)})" for n, f in zip(labels, forces))
        kept = (" (at moved positions)" if "x" in robust.counterexample else " (positions as measured)") if position \
            else ""
        return (f"**Depends on the data:** a force set within {band} makes it "
                f"{robust.counterexample['verdict']} instead of {robust.verdict}. Counter-example forces{kept}: "
                f"{shown}.")
    proven = f"proven for {robust.margin:.2g}× the band only" if np.isfinite(robust.margin) else "no bound applies"
    return (f"**Undecided at {band}:** neither proven to hold ({proven}) nor shown to change by a set of "
            f"{within}.")


class BandControl:
    """The two sliders and their sentence, in the Verdict tab (panel/verdict.py builds and writes it)."""

    def __init__(self, ui, gui):
        self.ui = ui
        self.slider = gui.add_slider("Force uncertainty ± %", min=0, max=MOST, step=1, initial_value=0,
                                     hint="each contact force within this percentage of its value: does the verdict "
                                          "hold for all of them? 0: not asked (nothing extra is computed)")
        self.slider.on_update(lambda _: ui.run(self._set))
        self.position = gui.add_slider("Position uncertainty ± % of a radius", min=0, max=MOST_POSITION, step=0.1,
                                       initial_value=0)     # no hint: it would cover the force box above
        self.position.on_update(lambda _: ui.run(self._set))
        self.text = gui.add_markdown("")

    def _set(self) -> None:
        s = self.ui.session
        s.force_band, s.position_band = float(self.slider.value), float(self.position.value)
        self.ui.write_verdict()

    def write(self, s) -> None:
        """The sentence, sent only when it changes (an unchanged write is a message to the page all the same)."""
        text = robust_sentence(robustness(s), s.force_band, position=s.position_band)
        if text != self.text.content:
            self.text.content = text
