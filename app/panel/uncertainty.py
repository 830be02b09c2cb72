"""The *Force uncertainty* control of the Verdict tab (issue 42): a relative band ±x % on every contact force, and
one plain sentence saying whether the verdict holds under it, depends on the data (a counter-example's forces
shown) or is undecided. 0 % (the default) runs nothing. `robust_sentence` and `robustness` are pure of viser
(tests/app/test_app_uncertainty.py); granstab.uncertainty.data_robustness does the work (docs/uncertainty.md)."""
from __future__ import annotations

import numpy as np

from granstab.mechanics.uncertainty import Band
from granstab.uncertainty import data_robustness

MOST = 50          # the slider's largest band, %


def robustness(s):
    """data_robustness of session `s`'s verdict under ±s.force_band % (None at 0 %, without an analysis, or on a
    map), computed once per (revision, band): the session's own analysis is reused where its metric is L."""
    if not s.force_band or s.analysis is None or s.scene is None or s.on_map:
        return None
    key = (s.revision, s.force_band)
    if s.robust[0] != key:
        metric = "inertia" if s.analysis.length is None else "L"
        reuse = s.analysis if metric == "L" and len(s.analysis.branches) == s.analysis.verdict.n_branches else None
        s.robust = (key, data_robustness(s.scene, Band(rel=s.force_band / 100), metric=metric,
                                         rotation_length=s.analysis.length, analysis=reuse))
    return s.robust[1]


def robust_sentence(robust, percent: float, names=None) -> str:
    """The plain-words line under the verdict table ("" at 0 % or without a result). `names`: the contacts' labels
    (default c0, c1, …) for the counter-example's forces."""
    if robust is None or not percent:
        return ""
    band = f"±{percent:g} %"
    if robust.robust == "holds":
        return (f"**Holds under {band}:** every set of contact forces within {band} of the measured ones gives the "
                f"same verdict ({robust.verdict}) — proven, not sampled.")
    if robust.robust == "depends":
        forces = np.asarray(robust.counterexample["forces"])
        labels = names or [f"c{i}" for i in range(len(forces))]
        shown = ", ".join(f"{n}: ({', '.join(f'{v:.4g}' for v in f)})" for n, f in zip(labels, forces))
        return (f"**Depends on the data:** a force set within {band} makes it "
                f"{robust.counterexample['verdict']} instead of {robust.verdict}. Counter-example forces: {shown}.")
    proven = f"proven for {robust.margin:.2g}× the band only" if np.isfinite(robust.margin) else "no bound applies"
    return (f"**Undecided at {band}:** neither proven to hold ({proven}) nor shown to change by a force set "
            "within the band.")


class BandControl:
    """The slider and its sentence, in the Verdict tab (panel/verdict.py builds and writes it)."""

    def __init__(self, ui, gui):
        self.ui = ui
        self.slider = gui.add_slider("Force uncertainty ± %", min=0, max=MOST, step=1, initial_value=0,
                                     hint="each contact force within this percentage of its value: does the verdict "
                                          "hold for all of them? 0: not asked (nothing extra is computed)")
        self.slider.on_update(lambda _: ui.run(self._set))
        self.text = gui.add_markdown("")

    def _set(self) -> None:
        self.ui.session.force_band = float(self.slider.value)
        self.ui.write_verdict()

    def write(self, s) -> None:
        """The sentence, sent only when it changes (an unchanged write is a message to the page all the same)."""
        text = robust_sentence(robustness(s), s.force_band)
        if text != self.text.content:
            self.text.content = text
