"""model/vec.py's row norms: np.linalg.norm(a, axis=1) bit for bit, so that reading a scene gives the same numbers
as before they were introduced (issue 41: the import of 10⁶ contacts)."""
import numpy as np
import pytest

from granstab.model.vec import norms


@pytest.mark.parametrize("k", range(1, 10))
def test_norms_are_numpys_bit_for_bit(k):
    rng = np.random.default_rng(k)
    a = rng.standard_normal((5000, k)) * 10.0 ** rng.uniform(-150, 150, (5000, 1))   # rows of any magnitude
    assert np.array_equal(norms(a), np.linalg.norm(a, axis=1))
    assert np.array_equal(norms(a[::3]), np.linalg.norm(a[::3], axis=1))          # a strided view


def test_norms_of_integers_and_no_rows():
    assert np.array_equal(norms(np.array([[3, 4], [0, 0]])), [5.0, 0.0])
    assert norms(np.zeros((0, 3))).shape == (0,)
