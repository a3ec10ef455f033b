"""geometry.arrays.unique: np.unique's result, by a sort."""

import numpy as np
import pytest

from baker.geometry.arrays import unique


@pytest.mark.parametrize("dtype", [np.int8, np.int32, np.int64, np.uint16])
@pytest.mark.parametrize("n", [0, 1, 2, 3, 50, 5000])
def test_unique_matches_numpy(dtype, n):
    a = np.random.default_rng(n).integers(0, 40, size=n).astype(dtype)
    got = unique(a)
    assert got.dtype == np.unique(a).dtype
    assert np.array_equal(got, np.unique(a))


def test_unique_flattens():
    a = np.array([[3, 1, 3], [2, 1, 0]])
    assert unique(a).tolist() == [0, 1, 2, 3]
