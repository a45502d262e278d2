"""Validation and small array helpers shared by curves and surfaces (bookkeeping, no geometry)."""

from __future__ import annotations

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError

#: Points evaluated per chunk in batched paths: bounds the temporary gathers to a few MB.
CHUNK = 1 << 15


def as_points(values, *, ndim: int, what: str) -> np.ndarray:
    """Control points as a read-only float64 array with ``ndim`` axes, the last of size 2 or 3 (or more).

    Raises
    ------
    InvalidGeometryError
        Wrong number of axes, fewer than 2 coordinates, NaN or inf coordinates.
    """
    a = np.array(values, dtype=np.float64)
    if a.ndim != ndim:
        raise InvalidGeometryError(f"{what}: expected an array with {ndim} axes, got shape {a.shape}")
    if a.shape[-1] < 2:
        raise InvalidGeometryError(f"{what}: points need at least 2 coordinates, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise InvalidGeometryError(f"{what}: coordinate at index {tuple(int(i) for i in bad)} is not finite")
    a.setflags(write=False)
    return a


def as_weights(values, shape: tuple[int, ...], *, what: str) -> np.ndarray:
    """Weights as a read-only float64 array of ``shape``; ``None`` gives ones.

    Raises
    ------
    InvalidGeometryError
        Wrong shape, NaN/inf or non-positive weights.
    """
    if values is None:
        w = np.ones(shape)
    else:
        w = np.array(values, dtype=np.float64)
        if w.shape != shape:
            raise InvalidGeometryError(f"{what}: expected weights of shape {shape}, got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise InvalidGeometryError(f"{what}: weights must be finite")
        if np.any(w <= 0):
            bad = np.argwhere(w <= 0)[0]
            raise InvalidGeometryError(
                f"{what}: weights must be positive, weight at index {tuple(int(i) for i in bad)} is {w[tuple(bad)]!r}"
            )
    w.setflags(write=False)
    return w


def as_degree(value, *, what: str) -> int:
    """A degree as a Python int >= 1.

    Raises
    ------
    InvalidGeometryError
        Not an integer, or below 1.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidGeometryError(f"{what}: degree must be an integer, got {value!r}")
    if value < 1:
        raise InvalidGeometryError(f"{what}: degree must be >= 1, got {value}")
    return int(value)


def as_transform(matrix) -> np.ndarray:
    """A 4×4 affine (or 3×3 linear) transform as a 4×4 float64 array.

    Raises
    ------
    InvalidInputError
        Wrong shape, non-finite entries or a projective last row.
    """
    T = np.asarray(matrix, dtype=np.float64)
    if T.shape == (3, 3):
        T4 = np.eye(4)
        T4[:3, :3] = T
        T = T4
    if T.shape != (4, 4):
        raise InvalidInputError(f"transform must be 3x3 or 4x4, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise InvalidInputError("transform has non-finite entries")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=0.0):
        raise InvalidInputError(f"transform must be affine (last row 0 0 0 1), got {T[3].tolist()}")
    return T


def similarity_parts(matrix, angular_tol: float) -> tuple[np.ndarray, float, bool]:
    """Split a similarity ``T = [s Q | t]`` (``Q`` orthogonal): ``(T as 4×4, s, det Q < 0)``.

    ``M^T M / s^2 - I`` is dimensionless (cosines between the images of orthogonal axes and
    relative stretches); beyond ``angular_tol`` circles would map to ellipses.

    Raises
    ------
    InvalidInputError
        A malformed, non-finite, projective or singular matrix, or one that is not a similarity
        (the message gives the deviation).
    """
    T = as_transform(matrix)
    M = T[:3, :3]
    det = float(np.linalg.det(M))
    if det == 0.0:
        raise InvalidInputError("transform is singular (determinant 0)")
    s = abs(det) ** (1.0 / 3.0)
    deviation = float(np.max(np.abs(M.T @ M / s**2 - np.eye(3))))
    if deviation > angular_tol:
        raise InvalidInputError(
            "transform must be a similarity (rotation, reflection, uniform scale, translation): "
            f"max |M^T M / s^2 - I| = {deviation:.3g}, expected <= angular tolerance {angular_tol:g}"
        )
    return T, s, det < 0.0


def binomials(n: int) -> np.ndarray:
    """Pascal's triangle ``C[k, i] = k choose i`` for ``0 <= i <= k <= n``."""
    C = np.zeros((n + 1, n + 1))
    for k in range(n + 1):
        C[k, 0] = 1.0
        for i in range(1, k + 1):
            C[k, i] = C[k - 1, i - 1] + (C[k - 1, i] if i <= k - 1 else 0.0)
    return C


def next_corners(T: np.ndarray) -> np.ndarray:
    """``T[:, [1, 2, 0]].ravel()`` for a C-contiguous ``(m, 3)`` array: the end of each directed edge
    ``3 t + k`` (from ``T[t, k]`` to ``T[t, (k + 1) % 3]``), as a new ``(3 m,)`` array.

    The fancy-indexed form returns a Fortran-ordered array whose ``ravel`` is a strided copy: 20 to
    30 times slower at 1e5 rows (numpy 2.4) than these two contiguous slice copies.
    """
    r = np.ascontiguousarray(T).ravel()
    d = np.empty_like(r)
    d[:-1] = r[1:]
    d[2::3] = r[0::3]
    return d


def prev_corners(T: np.ndarray) -> np.ndarray:
    """``T[:, [2, 0, 1]].ravel()`` for an ``(m, 3)`` array: the corner before each corner, i.e. the vertex
    opposite each directed edge ``3 t + k`` (from ``T[t, k]`` to ``T[t, (k + 1) % 3]``); two contiguous
    slice copies, as :func:`next_corners`."""
    r = np.ascontiguousarray(T).ravel()
    d = np.empty_like(r)
    d[1:] = r[:-1]
    d[0::3] = r[2::3]
    return d


def interleaved_columns(A: np.ndarray, i: int, j: int) -> np.ndarray:
    """``A[:, [i, j]].ravel()`` of a 2-D array as a new ``(2 n,)`` array: two strided column copies.

    The fancy-indexed form makes a Fortran-ordered copy and then a strided ravel: 20 to 40 times
    slower at 1e5 rows (numpy 2.4).
    """
    out = np.empty(2 * A.shape[0], dtype=A.dtype)
    out[0::2] = A[:, i]
    out[1::2] = A[:, j]
    return out


def column_min(A: np.ndarray) -> np.ndarray:
    """``A.min(axis=0)`` of an ``(n, k)`` array (small ``k``), one contiguous reduction per column: an
    axis-0 reduction over rows of three is 10-20 times slower (numpy 2.4)."""
    return np.array([A[:, j].min() for j in range(A.shape[1])], dtype=A.dtype)


def column_max(A: np.ndarray) -> np.ndarray:
    """``A.max(axis=0)`` of an ``(n, k)`` array (small ``k``); see :func:`column_min`."""
    return np.array([A[:, j].max() for j in range(A.shape[1])], dtype=A.dtype)


def row_norms(X: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(X, axis=-1)`` for a last axis of 2 or 3, written out: the same floats (its
    sum of squares runs left to right too), without numpy's row-by-row reduction of a short axis."""
    S = X[..., 0] * X[..., 0] + X[..., 1] * X[..., 1]
    if X.shape[-1] == 3:
        S += X[..., 2] * X[..., 2]
    return np.sqrt(S)


def linspace_rows(start, stop, num: int) -> np.ndarray:
    """``np.linspace(start, stop, num, axis=1)`` of sequences ``start, stop`` of ``k`` floats (``num >= 2``), ``(k, num)``:
    the same floats (``start + i * step``, ``step = (stop - start) / (num - 1)``, or ``start + i / (num - 1) * delta``
    where a step underflows to zero, the last column ``stop``), as a C-ordered array, without numpy's
    general set-up (about a third of the cost on a few rows, numpy 2.4)."""
    a = np.asarray(start, dtype=np.float64)[:, None]
    b = np.asarray(stop, dtype=np.float64)[:, None]
    div = num - 1
    delta = b - a
    step = delta / div
    y = np.arange(num, dtype=np.float64)
    y = (y / div) * delta if (step == 0).any() else y * step
    y += a
    y[:, -1] = b[:, 0]
    return y


def row_pointers(sorted_ids: np.ndarray, n: int) -> np.ndarray:
    """``np.searchsorted(sorted_ids, np.arange(n + 1))``: the CSR row pointers ``(n + 1,)`` int64 of
    increasing row ids ``0 <= sorted_ids < n``, by counting (``n`` binary searches cost several
    times more at 1e5 rows).

    Raises
    ------
    InvalidInputError
        An id outside ``0 .. n - 1``.
    """
    ids = np.asarray(sorted_ids).reshape(-1)
    out = np.zeros(n + 1, dtype=np.int64)
    if ids.size == 0:
        return out
    if int(ids[0]) < 0 or int(ids[-1]) >= n:
        raise InvalidInputError(f"row ids must lie in 0..{n - 1}, got {int(ids[0])}..{int(ids[-1])}")
    np.cumsum(np.bincount(ids, minlength=n), out=out[1:])
    return out


def used_ids(idx: np.ndarray, n: int) -> np.ndarray:
    """``np.unique(idx[idx >= 0])`` for int ids below ``n`` (-1 for none), by one scatter: no sort.

    ``np.unique`` sorts (about 3 ms per 1e5 ids with numpy 2.4, even when every id is -1); here a
    ``(n,)`` mask is marked, which is linear in ``idx.size + n``.

    Raises
    ------
    InvalidInputError
        An id of ``n`` or more (the caller's table is shorter than its references).
    """
    idx = np.asarray(idx).reshape(-1)
    idx = idx[idx >= 0]
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    if int(idx.max()) >= n:
        raise InvalidInputError(f"id {int(idx.max())} is out of range; expected ids below {n}")
    mask = np.zeros(n, dtype=bool)
    mask[idx] = True
    return np.flatnonzero(mask)


def sorted_contains(sorted_keys: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``np.isin(q, sorted_keys)`` for an already sorted 1-D ``sorted_keys`` (binary search; ``np.isin``
    would sort both arrays again)."""
    if sorted_keys.size == 0:
        return np.zeros(q.shape, dtype=bool)
    pos = np.searchsorted(sorted_keys, q)
    np.minimum(pos, sorted_keys.size - 1, out=pos)
    return sorted_keys[pos] == q


def interval_cuts(intervals: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where to put ``count[k]`` evenly spaced new samples inside interval ``intervals[k]``: the owner
    interval ``(m,)`` of each new sample and its fraction ``(m,)`` of the way along (``x[i] + f (x[i+1] - x[i])``).

    The refinements of fits (p-curve fits, intersection branches) cut each interval that misses the
    tolerance into ``count + 1`` equal parts at once: an interpolant's error falls with a power of
    the spacing, so one round usually suffices where halving took several.
    """
    count = np.asarray(count, dtype=np.int64)
    owner = np.repeat(np.asarray(intervals, dtype=np.int64), count)
    if owner.size == 0:
        return owner, np.zeros(0)
    # 1, 2, ..., c for each interval: a running index minus the start of its interval's run
    first = np.repeat(np.cumsum(count) - count, count)
    step = np.arange(owner.size) - first + 1
    return owner, step / np.repeat(count + 1, count)


def row_groups(*cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows equal in every column of ``cols`` (``(k,)`` each) as groups numbered in the order of their first
    row: ``first (g,)`` the first row of each group and ``of (k,)`` each row's group.  One sort of the rows
    (floats compare as Python's do: ``0.0 == -0.0``, as in a dict of key tuples; to tell floats apart bit
    for bit, pass them viewed as int64), or for a few rows that dict itself."""
    k = cols[0].size
    if k <= _ROW_GROUPS_BY_DICT:
        # (a few rows: a dict of Python key tuples, which compare as the sort below does, costs less)
        seen: dict[tuple, int] = {}
        first_l: list[int] = []
        of_l: list[int] = []
        for i, key in enumerate(zip(*[c.tolist() for c in cols])):
            g = seen.setdefault(key, len(first_l))
            if g == len(first_l):
                first_l.append(i)
            of_l.append(g)
        return np.array(first_l, dtype=np.int64), np.array(of_l, dtype=np.int64)
    order = np.lexsort(cols[::-1])
    same = np.ones(max(k - 1, 0), dtype=bool)  # (each sorted row equal to the one before)
    for col in cols:
        c = col[order]
        same &= c[1:] == c[:-1]
    group = np.empty(k, dtype=np.int64)
    start = np.concatenate([[True], ~same])[:k]
    group[order] = np.cumsum(start) - 1
    first = order[start]  # (the sort is stable: a run's first row is its group's smallest)
    rank = np.argsort(first, kind="stable")  # the groups in the order of their first row
    renumber = np.empty(rank.size, dtype=np.int64)
    renumber[rank] = np.arange(rank.size)
    return first[rank], renumber[group]


#: Up to this many rows :func:`row_groups` groups them by a dict.
_ROW_GROUPS_BY_DICT = 64
