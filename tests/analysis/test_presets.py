"""Every shipped preset loads and analyses with its identities at round-off; the shape presets give the verdicts
their comment blocks state."""

import pytest
from helpers import ROOT  # noqa: E402

import granstab

PRESETS = sorted((ROOT / "presets").glob("*.toml")) + sorted(
    (ROOT / "presets").glob("*.json"))


@pytest.mark.parametrize("path", PRESETS, ids=[p.name for p in PRESETS])
def test_preset_analyses_cleanly(path):
    text = path.read_text()
    if path.suffix == ".toml":
        assert text.startswith("#"), "every preset begins with a comment block saying what it shows"
    result = granstab.analyze(granstab.load_scene(path))
    for name, value in result.errors.items():
        assert value <= 1e-11, (name, value)
    assert result.summary["verdict"] in ("stable", "neutral", "unstable")


@pytest.mark.parametrize("name,verdict,n_contacts", [("ellipses_sharp", "unstable", 1), ("ellipses_flat", "stable", 1),
                                                     ("ellipsoid_trio", "unstable", 3)])
def test_shape_presets(name, verdict, n_contacts):
    scene = granstab.load_scene(ROOT / "presets" / f"{name}.toml")
    assert scene.n_contacts == n_contacts
    assert granstab.analyze(scene).summary["verdict"] == verdict
