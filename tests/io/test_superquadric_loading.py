"""The superquadric loading run of docs/shapes.md (examples/liggghts_superquadric/in.load, dumps committed under
tests/data/liggghts_superquadric/load): four frames, the settled packing then 2, 4 and 8 times its weight (the
density raised, gravity the script's). Each frame is read alone; its grains balance contacts and m g with the
frame's own masses (a reader that kept the first frame's masses would leave the heavier frames' weight unbalanced:
a residual of order 1), and its first frame is the one-frame packing of in.settle."""

import numpy as np
from helpers import DATA  # noqa: E402

import granstab.io

D = DATA / "liggghts_superquadric"
LAW = {"k": 677.0, "alpha": 0.8235, "mu": 0.5}


def test_the_loading_run_is_four_balanced_frames_from_the_settled_packing():
    source = granstab.io.open([D / "load" / "atoms.dump", D / "load" / "contacts.dump", D / "in.settle"], **LAW)
    assert source.frames == [40000, 45000, 50000, 55000] and source.warnings == []
    settled = granstab.io.load([D / "atoms.dump", D / "contacts.dump", D / "in.settle"], **LAW).scene
    masses = []
    for frame in source.frames:
        loaded = source.read(frame)
        imb = loaded.report["imbalance"]
        # quasi-static (kinetic energy < 1e-7 J): per grain |Σf + m g| / Σ|f| has median 1.0e-3 … 2.8e-3 over the
        # frames (measured), the grains at the walls (their wall force not dumped) left out
        assert imb["particles"] >= 120 and imb["force"]["median"] <= 0.01 and imb["moment"]["median"] <= 0.01
        masses.append(loaded.scene.mass)
        if frame == 40000:
            order = np.argsort(np.array(loaded.scene.names, int))
            ref = np.argsort(np.array(settled.names, int))
            np.testing.assert_allclose(loaded.scene.x[order], settled.x[ref], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.array(masses) / masses[0], np.array([1, 2, 4, 8])[:, None] + 0 * masses[0],
                               rtol=1e-9)
