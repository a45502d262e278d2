"""Mass properties of curved Boolean results (fitted NURBS p-curves), and the adaptive quadrature's
round-off floor (coons/topology/mass.py, ``_adaptive``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coons.errors import ConvergenceError
from coons.topology import mass
from coons.topology.primitives import Cone


def _frustum_pair():
    """Two frustums whose intersection is a 0.003 sliver (seeded; the draw of a random-Boolean run)."""
    rng = np.random.default_rng(52)

    def cone():
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        c = rng.uniform(-2, 2, 3)
        return Cone(rng.uniform(1, 3), rng.uniform(0, 1), rng.uniform(3, 8), direction=d).translate(c)

    # Replay the generator's draws up to the pair (kinds 3/2, 1/0, 3/2 consume these numbers).
    for kinds in ((3, 2), (1, 0), (3, 2)):
        rng.integers(0, 4, 2)
        for k in kinds:
            rng.normal(size=3), rng.uniform(-2, 2, 3)
            rng.uniform(size={0: 2, 1: 1, 2: 3, 3: 3}[k])
    assert rng.integers(0, 4, 2).tolist() == [2, 2]
    return cone(), cone()


def test_cone_cone_sliver_volume_converges():
    """The intersection's cone face made the quadrature stall at its round-off floor (estimated
    2.3e-12 against 1e-12, 1.3 million pieces, ConvergenceError after a minute)."""
    from coons.booleans.solid import difference, intersection, union

    A, B = _frustum_pair()
    I, U, D = intersection(A, B), union(A, B), difference(A, B)
    vi = I.volume
    assert 0.003 < vi < 0.0031
    # Inclusion–exclusion against the closed-form frustum volumes, and OCCT's 0.0030177907 (to its accuracy).
    assert abs(U.volume + vi - A.volume - B.volume) <= 1e-9 * (A.volume + B.volume)
    assert abs(D.volume + vi - A.volume) <= 1e-9 * A.volume
    assert vi == pytest.approx(0.003017790727810715, rel=1e-5)


def test_round_off_floor_is_accepted_but_real_error_is_not(monkeypatch):
    """A smooth integrand with 1e-14 relative noise converges (its estimate stalls at the noise); with 1e-7
    noise the estimate stalls far above the target and the quadrature still raises."""
    def noisy(level):
        def fn(item, t):
            noise = level * np.sign(np.sin(1e13 * t))  # deterministic, unresolved at any piece size reached
            f = np.cos(t) * (1 + noise)
            return np.stack([f, f], axis=1)
        return fn

    item = np.zeros(4, dtype=np.int64)
    lo, hi = np.linspace(0, 1, 5)[:-1], np.linspace(0, 1, 5)[1:]
    got = mass._adaptive(item, lo, hi, item, 1, noisy(1e-14), 2, 1e-15, np.zeros(1), np.zeros(1, np.int64))
    np.testing.assert_allclose(got[0], math.sin(1.0), rtol=1e-13)
    monkeypatch.setattr(mass, "_MAX_PIECES", 1 << 12)  # give up early: the noise is never resolved
    with pytest.raises(ConvergenceError, match="did not reach relative accuracy"):
        mass._adaptive(item, lo, hi, item, 1, noisy(1e-7), 2, 1e-15, np.zeros(1), np.zeros(1, np.int64))
