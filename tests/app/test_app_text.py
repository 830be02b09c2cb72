"""The explorer's page text as pure functions (app/text.py), read without viser or a server (issue 40)."""
from __future__ import annotations

from types import SimpleNamespace

import pytest
from helpers import ROOT  # noqa: E402

from granstab_app.text import (
    VERDICT_COLOR,
    badge,
    field_note,
    headline_html,
    legend_markdown,
    lowest_mode,
    metric_row,
    mode_counts,
    mode_text,
)


def test_headline_is_coloured_by_its_verdict_and_escapes_the_title():
    text = headline_html("unstable", "a <b> pair", "it rolls", 7)
    assert f"background:{VERDICT_COLOR['unstable']}" in text and 'data-revision="7"' in text
    assert "a &lt;b&gt; pair" in text and "UNSTABLE" in text and "it rolls" in text
    assert 'data-verdict="not-analysed"' in headline_html("not analysed", "", "", 1)


def test_mode_counts_say_the_per_branch_count_only_where_it_differs():
    assert mode_counts({"negative": 1, "zero": 0, "positive": 3}, (3, 0, 1)) == "1 negative · 0 zero · 3 positive"
    assert "over the branches: 2 · 0 · 6" in mode_counts({"negative": 1, "zero": 0, "positive": 3}, (6, 0, 2))


def test_metric_row_follows_the_check():
    assert "checking L/10, L and 10L and inertia" in metric_row("L", None, 3, True, True, 2.0)
    assert metric_row("L", {"revision": 2, "robust": True, "metrics": []}, 3, False, False, 1).startswith("L only")
    rows = [{"metric": "L/10", "verdict": "stable", "consistent_negative": 0},
            {"metric": "10L", "verdict": "unstable", "consistent_negative": 1}]
    assert metric_row("L", {"revision": 3, "robust": False, "metrics": rows}, 3, False, False, 1) == \
        "L/10: stable (0 negative) · 10L: unstable (1 negative)"


def test_legend_names_only_what_is_drawn():
    scene = SimpleNamespace(n_contacts=3, n_particles=4)
    on = {"forces": True, "normals": False, "osculating": True}
    text = legend_markdown(scene, on, {"max_force": 2.0, "arrow": 0.5}, False, 5000, 400)
    assert "arrows" in text and "largest |f| = 2" in text and "normals" not in text and "osculating" in text
    off = legend_markdown(scene, {"forces": False, "normals": False, "osculating": False},
                          {"max_force": 2.0, "arrow": 0.5}, True, 5000, 400)
    assert "off above 5,000 contacts" in off and "arrows" not in off


def test_field_note_and_mode_text():
    assert field_note(0.5, 0.0, 1e-9).endswith("(λ⁽⁶⁾/k = 0 within the zero tolerance 1e-09).")
    assert field_note(0.5, -0.25, 1e-9).endswith("(λ⁽⁶⁾/k = -0.25).") and "**rolling** mode only" in field_note(1, 0, 0)
    assert "unstable through another mode (sliding)" in field_note(0.5, 0.25, 1e-9, "sliding")
    import numpy as np
    m = SimpleNamespace(shares={"normal": 0.0, "rolling": 1.0}, code=0, label="rolling", eigenvalue=-0.5, branch=1,
                        hinges=False, consistent=True)
    text = mode_text(m, np.array([1, -1, 0]), coloured=True)
    assert "1 sliding, 1 unloading contact(s)" in text and "rolling 100%" in text and "normal" not in text
    assert "dark red" in text and "dark blue" in mode_text(SimpleNamespace(**{**vars(m), "eigenvalue": 0.5}),
                                                           np.zeros(3), coloured=True)


@pytest.mark.parametrize("rho, f, verdict, words", [
    (0.5, 0.01, "unstable", "The grains can roll apart: the contact is sharper than a circle (ρ/r = 0.5 < 1)"),
    (1.0, 0.01, "neutral", "exactly as curved as a circle (ρ/r = 1)"),
    (1.5, 0.01, "stable", "The grains rock back when rolled: the contact is flatter than a circle (ρ/r = 1.5 > 1)"),
    (1.5, -0.002, "unstable", "flatter than a circle (ρ/r = 1.5 > 1) and the force pulls (cohesive)")])
def test_the_plain_sentence_follows_the_pair(rho, f, verdict, words):
    """Under the badge one plain sentence: what the grains do and why (the curvature against a circle's, the
    force's sign: λ⁽⁶⁾ = f(ρ − r)); none of the research words of the technical reason."""
    from granstab_app.state import Session
    s = Session("two_particle")
    s.set_params(rho_r=rho, f_kr=f)
    verdict_now, _, sentence = badge(s)
    assert verdict_now == verdict and words in sentence
    assert not any(w in sentence for w in ("eq:", "sym(", "𝓗", "b0 #")) and "eq:" in s.report()["reason"]


def test_modes_are_named_by_what_they_do():
    from granstab_app.state import Session
    s = Session("four_disk")
    keys = [m.key for m in s.modes()]
    assert len(set(keys)) == len(keys) and not any("#" in k for k in keys)
    assert any(k.startswith("sliding at contact") for k in keys) and any(k.startswith("gear") for k in keys)
    assert lowest_mode(s.modes()).eigenvalue < 0 and lowest_mode(s.modes()).consistent


def test_every_preset_has_a_title_and_one_line():

    from granstab_app.state import Session
    from granstab_app.text import PRESETS, info_markdown
    stems = {p.stem for p in (ROOT / "presets").iterdir()}
    assert stems == set(PRESETS) and all(title and line.count(".") <= 2 for title, line in PRESETS.values())
    s = Session("four_disk")
    assert info_markdown(s, s.verdict).startswith("**Four disks (the paper's Sec. 4.2)** — All four contacts sliding")


def test_a_preset_menu_entry_names_its_title_and_its_stem():
    """The menu shows the title a student reads and the stem the docs, links and --preset use."""
    from granstab_app.text import PRESETS, preset_label
    assert preset_label("four_disk") == f"{PRESETS['four_disk'][0]} (four_disk)"
    assert preset_label("my_scene") == "my_scene"                      # not a preset: its own name
    labels = [preset_label(k) for k in PRESETS]
    assert len(set(labels)) == len(labels)
