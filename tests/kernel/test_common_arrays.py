"""The array helpers of coons.kernel._common agree with the numpy expressions they replace."""

from __future__ import annotations

import numpy as np

import pytest

from coons.errors import InvalidInputError
from coons.kernel._common import (
    column_max,
    column_min,
    interleaved_columns,
    next_corners,
    prev_corners,
    row_pointers,
    sorted_contains,
    used_ids,
)


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


def test_used_ids_is_the_unique_of_the_non_negative_ids():
    rng = np.random.default_rng(2)
    idx = rng.integers(-1, 12, (50, 2))
    np.testing.assert_array_equal(used_ids(idx, 12), np.unique(idx[idx >= 0]))
    assert used_ids(np.full(7, -1), 3).shape == (0,)
    assert used_ids(np.zeros(0, dtype=np.int64), 0).dtype == np.int64


def test_used_ids_rejects_an_id_beyond_the_table():
    with pytest.raises(InvalidInputError, match="id 5 is out of range; expected ids below 5"):
        used_ids(np.array([0, 5, -1]), 5)


def test_row_pointers_are_the_searchsorted_of_the_row_range():
    ids = np.sort(np.random.default_rng(3).integers(0, 20, 70))
    np.testing.assert_array_equal(row_pointers(ids, 20), np.searchsorted(ids, np.arange(21)))
    np.testing.assert_array_equal(row_pointers(ids[ids < 5], 25), np.searchsorted(ids[ids < 5], np.arange(26)))
    np.testing.assert_array_equal(row_pointers(np.zeros(0, dtype=np.int64), 4), np.zeros(5, dtype=np.int64))


def test_row_pointers_reject_ids_outside_the_rows():
    with pytest.raises(InvalidInputError, match=r"row ids must lie in 0..3, got 1..4"):
        row_pointers(np.array([1, 2, 4]), 4)
    with pytest.raises(InvalidInputError, match=r"row ids must lie in 0..3, got -1..2"):
        row_pointers(np.array([-1, 2]), 4)


def test_interleaved_columns_are_the_fancy_ravel():
    W = np.random.default_rng(4).integers(0, 99, (25, 4))
    for i, j in ((1, 3), (0, 2), (3, 0)):
        out = interleaved_columns(W, i, j)
        np.testing.assert_array_equal(out, W[:, [i, j]].ravel())
        assert out.flags.c_contiguous and out.flags.writeable
    np.testing.assert_array_equal(interleaved_columns(W[:, :2], 1, 0), W[:, 1::-1].ravel())
    assert interleaved_columns(np.zeros((0, 2)), 0, 1).shape == (0,)


def test_prev_corners_are_the_other_rotated_ravel():
    T = np.random.default_rng(6).integers(0, 50, (40, 3))
    np.testing.assert_array_equal(prev_corners(T), T[:, [2, 0, 1]].ravel())
    np.testing.assert_array_equal(prev_corners(T[::-1, ::-1]), T[::-1, ::-1][:, [2, 0, 1]].ravel())
    assert prev_corners(np.zeros((0, 3), dtype=np.int64)).shape == (0,)


def test_interval_cuts_spread_count_samples_evenly_inside_each_interval():
    from coons.kernel._common import interval_cuts

    rng = np.random.default_rng(4)
    intervals = np.sort(rng.choice(50, 12, replace=False))
    count = rng.integers(0, 6, 12)
    owner, frac = interval_cuts(intervals, count)
    expect_owner = np.concatenate([[i] * c for i, c in zip(intervals.tolist(), count.tolist())]).astype(np.int64)
    expect_frac = np.concatenate([np.arange(1, c + 1) / (c + 1) for c in count.tolist()])
    np.testing.assert_array_equal(owner, expect_owner)
    np.testing.assert_array_equal(frac, expect_frac)
    assert interval_cuts(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))[0].size == 0
