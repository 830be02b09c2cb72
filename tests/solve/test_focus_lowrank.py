"""analysis.focus (the scan's --boundary embedded verdict) on branches from the low-rank path, whose eigenvectors
are LazyVectors computed when asked: it used to fail with a TypeError (`LazyVectors ** 2`), which stopped a 3D
`granstab track --scan` of the examples/track run. The focused codes equal those of the dense path's vectors."""
import numpy as np

import granstab
from granstab.analysis import focus
from granstab.mechanics.branches import RIGID
from granstab.model.packings import random_packing
from granstab.solve.lowrank import LazyVectors


def test_focus_takes_lazy_vectors_and_agrees_with_the_dense_path():
    scene = random_packing(2, 30, n_sliding=4, seed=2)
    lazy = granstab.analyze(scene, method="dense", lowrank=True, max_sliding=4)
    dense = granstab.analyze(scene, method="dense", lowrank=False, max_sliding=4)
    assert any(isinstance(b.stability_vectors, LazyVectors) for b in lazy.branches)
    inside = np.arange(10)
    a, b = focus(lazy, inside, 0.5), focus(dense, inside, 0.5)
    assert len(a.branches) == len(b.branches) == 2 ** 4
    for x, y in zip(a.branches, b.branches):
        assert np.array_equal(x.codes, y.codes)
    assert (a.verdict.verdict, a.verdict.consistent_negative) == (b.verdict.verdict, b.verdict.consistent_negative)
    # the share is taken on the vectors themselves: a share above 1 leaves every low (λ <= bound) mode out
    everything = focus(lazy, inside, 1.01)
    for x in everything.branches:
        assert np.all(x.codes[x.stability_eigenvalues <= x.accuracy] == RIGID)
