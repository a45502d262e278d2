"""Basis functions: partition of unity, agreement with scipy's B-splines, knot-vector validation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import basis as b
from coons.tolerance import DEFAULT_TOLERANCE

from .strategies import random_knots

RTOL = 1e-12


@st.composite
def knot_setups(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    p = draw(st.integers(1, 6))
    n = draw(st.integers(p + 1, p + 10))
    U = random_knots(rng, n, p, draw(st.booleans()))
    u = np.concatenate([rng.random(200), [0.0, 1.0], np.unique(U[(U >= 0) & (U <= 1)])])
    return U, p, n, u


@given(knot_setups())
def test_partition_of_unity_and_non_negativity(setup):
    U, p, n, u = setup
    B = b.basis_matrix(b.as_knot_vector(U, p, n), p, u).toarray()
    np.testing.assert_allclose(B.sum(axis=1), 1.0, rtol=0, atol=1e-13)
    assert B.min() >= -1e-15
    # Local support: at most p + 1 non-zero functions per parameter.
    assert np.all((np.abs(B) > 0).sum(axis=1) <= p + 1)


@given(knot_setups())
def test_basis_and_derivatives_match_scipy(setup):
    U, p, n, u = setup
    U = b.as_knot_vector(U, p, n)
    spans = b.find_spans(U, p, u)
    ders = b.basis_derivatives(U, p, spans, u, p + 1)
    N = b.basis_functions(U, p, spans, u)
    np.testing.assert_allclose(ders[:, 0, :], N, rtol=0, atol=1e-13)
    # Reference: scipy's BSpline with unit coefficient vectors (its own recursion).
    cols = spans[:, None] - p + np.arange(p + 1)
    inside = u < U[n]  # scipy evaluates the last span half-open differently at u = U[n]
    for k in range(p + 1):
        ref = BSpline(U, np.eye(n), p, extrapolate=False)(u, nu=k)
        ours = np.zeros_like(ref)
        np.put_along_axis(ours, cols, ders[:, k, :], axis=1)
        scale = np.abs(ref[inside]).max() + 1.0
        np.testing.assert_allclose(ours[inside], ref[inside], rtol=0, atol=1e-10 * scale)
    # Derivatives of order above p vanish.
    np.testing.assert_array_equal(ders[:, p + 1, :], 0.0)


def test_find_spans_closed_last_span_and_repeated_knots():
    U = b.as_knot_vector([0, 0, 0, 0.5, 0.5, 1, 1, 1], 2, 5)
    spans = b.find_spans(U, 2, np.array([0.0, 0.25, 0.5, 0.75, 1.0]))
    assert spans.tolist() == [2, 2, 4, 4, 4]


def test_knot_vector_errors():
    with pytest.raises(InvalidGeometryError, match="expected 7 knots"):
        b.as_knot_vector([0, 0, 0, 1, 1, 1], 2, 4)
    with pytest.raises(InvalidGeometryError, match="non-decreasing"):
        b.as_knot_vector([0, 0, 0, 0.6, 0.4, 1, 1, 1], 2, 5)
    with pytest.raises(InvalidGeometryError, match="not finite"):
        b.as_knot_vector([0, 0, 0, np.nan, 1, 1, 1], 2, 4)
    with pytest.raises(InvalidGeometryError, match="empty domain"):
        b.as_knot_vector([0, 0, 0, 0, 0, 0], 2, 3)
    with pytest.raises(InvalidGeometryError, match="multiplicity 3"):
        b.as_knot_vector([0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1], 2, 6)
    with pytest.raises(InvalidGeometryError, match="degree must be an integer >= 1"):
        b.as_knot_vector([0, 1], 0, 2)


def test_parameter_checks():
    tol = DEFAULT_TOLERANCE
    np.testing.assert_array_equal(b.check_parameters([1.0 + 1e-15, -1e-16], (0.0, 1.0), tol), [1.0, 0.0])
    with pytest.raises(InvalidInputError, match="outside the domain"):
        b.check_parameters([0.5, 1.001], (0.0, 1.0), tol)
    with pytest.raises(InvalidInputError, match="finite"):
        b.check_parameters([np.nan], (0.0, 1.0), tol)


def test_uniform_knot_helpers():
    U = b.clamped_uniform_knots(6, 3, (2.0, 5.0))
    assert b.domain_of(U, 3) == (2.0, 5.0)
    assert U.tolist() == [2, 2, 2, 2, 3, 4, 5, 5, 5, 5]
    V = b.periodic_uniform_knots(6, 3, (0.0, 1.0))
    assert b.domain_of(V, 3) == (0.0, 1.0)
    np.testing.assert_allclose(np.diff(V), 1 / 3)
    with pytest.raises(InvalidGeometryError, match="at least 4 control points"):
        b.clamped_uniform_knots(3, 3)
