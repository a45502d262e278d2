"""The array helpers of coons.kernel._common agree with the numpy expressions they replace."""

from __future__ import annotations

import numpy as np

from coons.kernel._common import column_max, column_min, next_corners, sorted_contains


def test_next_corners_is_the_rotated_ravel():
    T = np.random.default_rng(0).integers(0, 50, (40, 3))
    np.testing.assert_array_equal(next_corners(T), T[:, [1, 2, 0]].ravel())
    np.testing.assert_array_equal(next_corners(T[::-1, ::-1]), T[::-1, ::-1][:, [1, 2, 0]].ravel())
    assert next_corners(np.zeros((0, 3), dtype=np.int64)).shape == (0,)


def test_column_reductions_and_sorted_membership():
    rng = np.random.default_rng(1)
    P = rng.normal(size=(30, 3))
    np.testing.assert_array_equal(column_min(P), P.min(axis=0))
    np.testing.assert_array_equal(column_max(P), P.max(axis=0))
    keys = np.sort(rng.integers(0, 100, 40))
    q = rng.integers(-5, 110, 60)
    np.testing.assert_array_equal(sorted_contains(keys, q), np.isin(q, keys))
    assert not sorted_contains(np.zeros(0, dtype=np.int64), q).any()
