"""Closest points on curves and surfaces, and point inversion, for many points at once.

For every query point this module finds the parameter of the nearest point of a
curve or surface: global seeding from a dense sample of the geometry (a few samples
per knot span, more where they lie far apart, listed through a k-d tree), then one
batched, safeguarded Newton iteration on all seeds of all points at once (The NURBS
Book §6.1; the sampling plays the role of the subdivision of Cohen–Riesenfeld–Elber
ch. 16), with the domain ends of a curve and the four boundary curves of a surface
as further candidates.  Inversion is the same search followed by a check that every
point lies on the geometry.  It deliberately does not project onto trimmed faces,
B-reps or meshes, returns only the nearest of several local minima (between
candidates at equal distance the choice is arbitrary), and treats a periodic knot
vector like any other: parameters stay inside the domain, and seeds on both sides
of a seam make the seam harmless.  A fold of the geometry narrower than the sample
spacing can hide a closer local minimum from the seeding (see :class:`_Sampling`).

Notation: ``P`` a query point, ``C(u)`` the curve, ``S(u, v)`` the surface,
``r = C - P`` (or ``S - P``) the residual.  The distance is stationary where
``f(u) = C'(u) · r = 0`` (curves) or ``Su · r = Sv · r = 0`` (surfaces).

*Cells.*  Knots where the geometry is only C0 (multiplicity >= degree) are
*creases*; they cut the domain into cells on which the geometry is smooth.  Every
iterate lives in one cell and is evaluated with that cell's polynomial piece (one
ulp inside at its upper bound); a seed on a crease starts once in each adjacent
cell; an iterate that stops on a crease with descent into the neighbouring cell
moves there.

*Steps* are Newton's; where the Hessian of the squared distance is not positive
definite they are Gauss–Newton's (curves) or use the Hessian with its eigenvalues
made positive (surfaces).  The trial point follows the projection of the step onto
the cell and the step is halved until the distance does not grow by more than its
round-off ``tol.solver * scale``.

*Convergence* of an iterate (any one suffices):

* coincidence: ``|r| <= tol.solver * scale`` (``scale``: the size and position
  magnitude of the sampled geometry, the reference of its round-off);
* zero cosine: ``|C' · r| <= tol.angular |C'| |r|`` in every direction not held
  at a bound;
* a step below ``tol.solver`` times the domain length in every parameter, or whose
  image ``|Δu Su + Δv Sv|`` is below ``tol.solver * scale`` (the distance is
  stationary to round-off);
* at a cell bound with the descent direction leaving the cell (an active set),
  and no descent into the neighbouring cell.

Points whose nearest candidate did not converge within :data:`MAX_ITERATIONS`
iterations raise :class:`~coons.errors.ConvergenceError` naming their indices;
nothing is returned silently unconverged.

The functions use a duck-typed interface so that analytic curves and surfaces can
call them: curves need ``domain`` and ``derivatives(u, order)``
(``np.shape(u) + (order + 1, d)``), surfaces ``domain_u``, ``domain_v`` and
``derivatives(u, v, order)`` (``shape + (order + 1, order + 1, d)``); ``knots``,
``degree`` (``knots_u``, ``degree_u``, ... for surfaces) and ``weights`` refine the
sampling and give the creases when present; ``evaluate_grid`` speeds up sampling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from coons.errors import ConvergenceError, InvalidInputError
from coons.kernel._common import CHUNK
from coons.tolerance import Tolerance, resolve

__all__ = [
    "ClosestPoints",
    "curve_closest_parameters",
    "curve_closest_points",
    "curve_invert",
    "surface_closest_parameters",
    "surface_closest_points",
    "surface_invert",
    "MAX_ITERATIONS",
]

#: Newton iterations allowed per seed before its point is reported as not converged.
MAX_ITERATIONS = 64
#: Step halvings per line search; 2**-60 of any step is far below the solver tolerance.
_MAX_HALVINGS = 60
#: Most seeds per point: nearest discrete local minima of its sampled distance (as many on a surface's boundary).
_SEEDS = 16
#: Curve samples per knot span per (degree + 1); twice that for rational curves.
_CURVE_SAMPLES = 4
#: Surface samples per knot span per (degree + 1), in each direction; twice that if rational.
_SURFACE_SAMPLES = 2
#: Intervals are refined until consecutive samples are about 1/_CURVE_RESOLUTION of the curve's size apart
#: (at most _CURVE_CAP samples in all) ...
_CURVE_RESOLUTION = 256
_CURVE_CAP = 4096
#: ... or 1/_SURFACE_RESOLUTION of the surface's size, in each direction (at most _SURFACE_CAP per direction) ...
_SURFACE_RESOLUTION = 64
_SURFACE_CAP = 256
#: ... cutting an interval into at most this many pieces per round, in at most _REFINE_ROUNDS rounds.
_MAX_REFINE = 16
_REFINE_ROUNDS = 2
#: Samples of a geometry without knots (analytic types), per direction.
_PLAIN_SAMPLES = 64
#: Inversion's local searches: samples within each reach times the distance found (in space), and
#: +-_WINDOW of the domain, around the first answer (_WINDOW_SAMPLES on curves, _WINDOW_SAMPLES / 4 + 1
#: per direction on surfaces).
_WINDOW_REACHES = (8.0, 32.0, 128.0)
_WINDOW = 1 / 4
_WINDOW_SAMPLES = 256
#: Samples listed per point by the k-d tree before falling back to a search over all samples.
_BALL = 64
#: Distances computed at once in that fallback (bounds its temporaries to a few MB).
_BRUTE_BUDGET = CHUNK * 16
#: Query points per batch: each carries up to 2 * _SEEDS Newton iterates (more on creases).
_POINTS_PER_BATCH = max(1, CHUNK // (2 * _SEEDS))


@dataclass(frozen=True, eq=False)
class ClosestPoints:
    """Closest points of a batch of query points on a curve or surface.

    Attributes
    ----------
    parameters : (...,) float64 for curves, (..., 2) float64 ``(u, v)`` for surfaces
    points : (..., d) float64
        The geometry evaluated at ``parameters``.
    distances : (...,) float64
        Euclidean distances from the query points to ``points``.

    ``...`` is the batch shape of the query points.  The arrays are read-only.
    """

    parameters: np.ndarray
    points: np.ndarray
    distances: np.ndarray

    def __post_init__(self) -> None:
        for name in ("parameters", "points", "distances"):
            a = np.array(getattr(self, name), dtype=np.float64)
            a.setflags(write=False)
            object.__setattr__(self, name, a)


# ---------------------------------------------------------------------- public: curves
def curve_closest_parameters(curve, points, tol: Tolerance | None = None) -> np.ndarray:
    """Parameters of the points of ``curve`` nearest to ``points``.

    Parameters
    ----------
    curve : NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    points : (..., d) array_like
        Query points, ``d`` the dimension of the curve.
    tol : Tolerance, optional

    Returns
    -------
    (...,) float64
        Parameters in ``curve.domain``.

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        Some points did not converge; ``.indices`` are flat indices into
        ``points.reshape(-1, d)``, ``.residuals`` their orthogonality cosines.
    """
    return curve_closest_points(curve, points, tol).parameters


def curve_closest_points(curve, points, tol: Tolerance | None = None) -> ClosestPoints:
    """Closest points, their parameters and distances on ``curve`` (The NURBS Book §6.1).

    Seeds: ``4 (p + 1)`` samples per knot span (twice as many if rational; more in
    intervals whose samples are farther apart than 1/:data:`_CURVE_RESOLUTION` of
    the curve's size); each point starts Newton
    from up to :data:`_SEEDS` discrete local minima of its
    sampled distance (see :class:`_Sampling`), and the two domain ends are further
    candidates.  See the module docstring for the iteration and its convergence.

    Parameters
    ----------
    curve : NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    points : (..., d) array_like

    Returns
    -------
    ClosestPoints
        ``parameters (...,)``, ``points (..., d)``, ``distances (...,)``.

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        As in :func:`curve_closest_parameters`.
    """
    t = resolve(tol)
    lo, hi = (float(x) for x in curve.domain)
    breaks, counts = _spans(curve, "knots", "degree", (lo, hi), _CURVE_SAMPLES)
    params = _expand(breaks, counts)
    samples = _curve_points(curve, params)
    # Intervals whose samples lie far apart (fast or strongly weighted pieces) get more samples.
    target = _diagonal(samples) / _CURVE_RESOLUTION
    for _ in range(_REFINE_ROUNDS):
        refined = _subdivided(params, np.linalg.norm(np.diff(samples, axis=0), axis=1), target, _CURVE_CAP)
        if refined.size == params.size:
            break
        params = refined
        samples = _curve_points(curve, params)
    P, batch = _as_query_points(points, samples.shape[-1])
    crease_values = _crease_values(curve, "knots", "degree", (lo, hi))
    creases = _Creases([crease_values])
    sample, cell_of, nbr = _axis(params, crease_values)
    sampling = _Sampling(samples[sample], nbr)
    ends = _curve_points(curve, np.array([lo, hi]))

    def ders(u: np.ndarray, items: np.ndarray) -> np.ndarray:
        return np.asarray(curve.derivatives(u, 2), dtype=np.float64)

    u_out = np.empty(P.shape[0])
    C_out = np.empty_like(P)
    failed: list[np.ndarray] = []
    residuals: list[np.ndarray] = []
    for s in range(0, P.shape[0], _POINTS_PER_BATCH):
        Q = P[s : s + _POINTS_PER_BATCH]
        m = Q.shape[0]
        owner, idx = sampling.seeds(Q, _SEEDS)
        u0, cell = params[sample[idx]], cell_of[idx]
        which = np.zeros(u0.shape, np.int64)
        u, C, ok, cos = _descend_1d(ders, u0, which, cell, Q[owner], creases, t, sampling.scale)
        # The domain ends are candidates of every point.
        owner = np.concatenate([owner, np.repeat(np.arange(m), 2)])
        u = np.concatenate([u, np.tile([lo, hi], m)])
        C = np.concatenate([C, np.tile(ends, (m, 1))])
        ok = np.concatenate([ok, np.ones(2 * m, bool)])
        cos = np.concatenate([cos, np.zeros(2 * m)])
        best, bad, res = _pick(owner, C, ok, cos, Q, t)
        u_out[s : s + m] = u[best]
        C_out[s : s + m] = C[best]
        failed.append(s + np.flatnonzero(bad))
        residuals.append(res[bad])
    _raise_unconverged("curve_closest_points", failed, residuals, P.shape[0])
    dist = np.linalg.norm(C_out - P, axis=1)
    return ClosestPoints(u_out.reshape(batch), C_out.reshape(batch + (P.shape[1],)), dist.reshape(batch))


def curve_invert(curve, points, tol: Tolerance | None = None) -> np.ndarray:
    """Parameters of points that lie on ``curve`` (point inversion, The NURBS Book §6.1).

    The closest-point search of :func:`curve_closest_points`; points it leaves
    farther than ``tol.linear`` get local searches (Newton from the nearest of dense
    samples in windows of :data:`_WINDOW_REACHES` times the distance found around
    the answer: a point can sit behind a fold narrower than the global sampling)
    before the function raises.

    Parameters
    ----------
    curve : NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    points : (..., d) array_like
        Points expected on the curve within ``tol.linear``.

    Returns
    -------
    (...,) float64

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        Some points are farther than ``tol.linear`` from the curve (``.indices``:
        flat indices into ``points.reshape(-1, d)``, ``.residuals``: their
        distances), or the closest-point search did not converge.
    """
    t = resolve(tol)
    cp = curve_closest_points(curve, points, t)
    P = np.asarray(points, dtype=np.float64).reshape(-1, cp.points.shape[-1])
    u, dist = cp.parameters.ravel().copy(), cp.distances.ravel().copy()
    # Second, local searches before giving up: a point on the curve may sit behind a fold
    # narrower than the global sampling (see _Sampling).
    for reach in _WINDOW_REACHES:
        off = np.flatnonzero(dist > t.linear)
        if off.size == 0:
            break
        _search_curve_window(curve, P, u, dist, off, reach, t)
    _raise_off(dist, t, "curve")
    return u.reshape(cp.parameters.shape)


# ---------------------------------------------------------------------- public: surfaces
def surface_closest_parameters(surface, points, tol: Tolerance | None = None) -> np.ndarray:
    """Parameters ``(u, v)`` of the points of ``surface`` nearest to ``points``.

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    points : (..., d) array_like

    Returns
    -------
    (..., 2) float64

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        Some points did not converge; ``.indices`` are flat indices into
        ``points.reshape(-1, d)``, ``.residuals`` their orthogonality cosines.
    """
    return surface_closest_points(surface, points, tol).parameters


def surface_closest_points(surface, points, tol: Tolerance | None = None) -> ClosestPoints:
    """Closest points, their parameters and distances on ``surface`` (The NURBS Book §6.1).

    Seeds: a tensor grid of ``2 (p + 1)`` samples per knot span in each direction
    (twice as many if rational; more in intervals whose samples are farther apart than
    1/:data:`_SURFACE_RESOLUTION` of the surface's size, at most
    :data:`_SURFACE_CAP` per direction); each point starts the 2×2 Newton iteration from up
    to :data:`_SEEDS` discrete local minima of its sampled distance on the grid, and
    the 1-D iteration along the four boundary iso-curves from up to :data:`_SEEDS`
    local minima of its distance to the boundary samples; the nearest converged
    candidate wins.  Seeds on a collapsed edge (a pole) take their parameter along
    the edge from the nearest samples of the adjacent row, since Newton cannot move
    it there (the derivative along the edge vanishes).

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    points : (..., d) array_like

    Returns
    -------
    ClosestPoints
        ``parameters (..., 2)``, ``points (..., d)``, ``distances (...,)``.

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        As in :func:`surface_closest_parameters`.
    """
    t = resolve(tol)
    (ulo, uhi), (vlo, vhi) = ((float(a), float(b)) for a, b in (surface.domain_u, surface.domain_v))
    breaks_u, counts_u = _spans(surface, "knots_u", "degree_u", (ulo, uhi), _SURFACE_SAMPLES)
    breaks_v, counts_v = _spans(surface, "knots_v", "degree_v", (vlo, vhi), _SURFACE_SAMPLES)
    us, vs = _expand(breaks_u, counts_u), _expand(breaks_v, counts_v)
    grid = _surface_grid(surface, us, vs)  # (a, b, d)
    # Rows and columns of intervals whose samples lie far apart get more samples.
    target = _diagonal(grid.reshape(-1, grid.shape[-1])) / _SURFACE_RESOLUTION
    for _ in range(_REFINE_ROUNDS):
        refined_u = _subdivided(us, np.linalg.norm(np.diff(grid, axis=0), axis=2).max(axis=1), target, _SURFACE_CAP)
        refined_v = _subdivided(vs, np.linalg.norm(np.diff(grid, axis=1), axis=2).max(axis=0), target, _SURFACE_CAP)
        if refined_u.size == us.size and refined_v.size == vs.size:
            break
        us, vs = refined_u, refined_v
        grid = _surface_grid(surface, us, vs)
    a, b, d = grid.shape
    P, batch = _as_query_points(points, d)
    values_u = _crease_values(surface, "knots_u", "degree_u", (ulo, uhi))
    values_v = _crease_values(surface, "knots_v", "degree_v", (vlo, vhi))
    creases_u, creases_v = _Creases([values_u]), _Creases([values_v])
    su, cell_u, nbr_u = _axis(us, values_u)
    sv, cell_v, nbr_v = _axis(vs, values_v)
    # Virtual grid: every (u-sample, cell) × (v-sample, cell) pair, row-major over the two axes.
    ka, kb = su.size, sv.size
    vi, vj = np.unravel_index(np.arange(ka * kb), (ka, kb))
    inner = _Sampling(
        grid[su[vi], sv[vj]],
        np.stack(
            [nbr_u[vi, 0] * kb + vj, nbr_u[vi, 1] * kb + vj, vi * kb + nbr_v[vj, 0], vi * kb + nbr_v[vj, 1]], axis=1
        ),
    )
    scale = inner.scale

    # Edges 0: u = ulo (parameter v), 1: u = uhi, 2: v = vlo (parameter u), 3: v = vhi, with their
    # real samples, the adjacent row, and which virtual grid samples lie on them.
    edges = [
        (grid[0], grid[min(1, a - 1)], su[vi] == 0),
        (grid[-1], grid[max(a - 2, 0)], su[vi] == a - 1),
        (grid[:, 0], grid[:, min(1, b - 1)], sv[vj] == 0),
        (grid[:, -1], grid[:, max(b - 2, 0)], sv[vj] == b - 1),
    ]
    # A collapsed edge (all its samples within tol.linear of one point, e.g. a sphere's pole) is no
    # boundary curve, and a seed on it takes its free parameter from the adjacent row (see below).
    collapsed = [bool(np.max(np.linalg.norm(row - row[0], axis=1)) <= t.linear) for row, _, _ in edges]
    open_edges = [e for e in range(4) if not collapsed[e]]
    edge_axis = [(sv, nbr_v, cell_v, vs), (sv, nbr_v, cell_v, vs), (su, nbr_u, cell_u, us), (su, nbr_u, cell_u, us)]
    boundary = None
    if open_edges:
        sizes = [edge_axis[e][0].size for e in open_edges]
        offsets = np.cumsum([0] + sizes[:-1])
        boundary = _Sampling(
            np.concatenate([edges[e][0][edge_axis[e][0]] for e in open_edges]),
            np.concatenate([edge_axis[e][1] + o for e, o in zip(open_edges, offsets)]),
        )
        b_edge = np.repeat(open_edges, sizes)
        b_par = np.concatenate([edge_axis[e][3][edge_axis[e][0]] for e in open_edges])
        b_cell = np.concatenate([edge_axis[e][2] for e in open_edges])
    fixed = np.array([ulo, uhi, vlo, vhi])
    edge_creases = _Creases([values_v, values_u])  # set 0: edges along v, set 1: edges along u

    uv_out = np.empty((P.shape[0], 2))
    S_out = np.empty_like(P)
    failed: list[np.ndarray] = []
    residuals: list[np.ndarray] = []
    for s in range(0, P.shape[0], _POINTS_PER_BATCH):
        Q = P[s : s + _POINTS_PER_BATCH]
        m = Q.shape[0]

        owner, idx = inner.seeds(Q, _SEEDS)
        u0, v0 = us[su[vi[idx]]], vs[sv[vj[idx]]]
        cu, cv = cell_u[vi[idx]], cell_v[vj[idx]]
        # Seeds on a collapsed edge all sit on the same point with an arbitrary free parameter,
        # which Newton cannot correct there (the derivative along the edge vanishes): the k-th
        # seed of a point takes the k-th nearest sample of the adjacent row instead.
        for e in range(4):
            at = np.flatnonzero(edges[e][2][idx]) if collapsed[e] else np.empty(0, np.int64)
            if at.size == 0:
                continue
            rank = np.arange(at.size) - np.searchsorted(owner[at], owner[at], side="left")
            adjacent = edges[e][1]
            near = np.argsort(cdist(Q[owner[at]], adjacent), axis=1)
            near = near[np.arange(at.size), np.minimum(rank, adjacent.shape[0] - 1)]
            zero = np.zeros(at.size, np.int64)
            if e >= 2:
                u0[at] = us[near]
                cu[at] = creases_u.cell(u0[at], zero)
            else:
                v0[at] = vs[near]
                cv[at] = creases_v.cell(v0[at], zero)
        uv, S, ok, cos = _descend_2d(surface, u0, v0, cu, cv, Q[owner], creases_u, creases_v, t, scale)

        if boundary is None:
            best, bad, res = _pick(owner, S, ok, cos, Q, t)
            uv_out[s : s + m], S_out[s : s + m] = uv[best], S[best]
            failed.append(s + np.flatnonzero(bad))
            residuals.append(res[bad])
            continue
        b_owner, jdx = boundary.seeds(Q, _SEEDS)
        edge, w0, cell = b_edge[jdx], b_par[jdx], b_cell[jdx]
        along_v = edge < 2
        which = np.where(along_v, 0, 1)

        def ders(w: np.ndarray, items: np.ndarray, edge=edge, along_v=along_v) -> np.ndarray:
            e, av = edge[items], along_v[items]
            D = np.asarray(
                surface.derivatives(np.where(av, fixed[e], w), np.where(av, w, fixed[e]), 2), dtype=np.float64
            )
            return np.where(av[:, None, None], D[:, 0, :3, :], D[:, :3, 0, :])

        w, Sb, okb, cosb = _descend_1d(ders, w0, which, cell, Q[b_owner], edge_creases, t, scale)
        uvb = np.stack([np.where(along_v, fixed[edge], w), np.where(along_v, w, fixed[edge])], axis=1)

        owner = np.concatenate([owner, b_owner])
        uv = np.concatenate([uv, uvb])
        S = np.concatenate([S, Sb])
        best, bad, res = _pick(owner, S, np.concatenate([ok, okb]), np.concatenate([cos, cosb]), Q, t)
        uv_out[s : s + m] = uv[best]
        S_out[s : s + m] = S[best]
        failed.append(s + np.flatnonzero(bad))
        residuals.append(res[bad])
    _raise_unconverged("surface_closest_points", failed, residuals, P.shape[0])
    dist = np.linalg.norm(S_out - P, axis=1)
    return ClosestPoints(uv_out.reshape(batch + (2,)), S_out.reshape(batch + (d,)), dist.reshape(batch))


def surface_invert(surface, points, tol: Tolerance | None = None) -> np.ndarray:
    """Parameters ``(u, v)`` of points that lie on ``surface`` (The NURBS Book §6.1).

    The closest-point search of :func:`surface_closest_points`, followed for points
    left farther than ``tol.linear`` by local searches as in :func:`curve_invert`.

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    points : (..., d) array_like
        Points expected on the surface within ``tol.linear``.

    Returns
    -------
    (..., 2) float64

    Raises
    ------
    InvalidInputError
        ``points`` of the wrong dimension or not finite; an unbounded domain.
    ConvergenceError
        Some points are farther than ``tol.linear`` from the surface (``.indices``:
        flat indices into ``points.reshape(-1, d)``, ``.residuals``: their
        distances), or the closest-point search did not converge.
    """
    t = resolve(tol)
    cp = surface_closest_points(surface, points, t)
    P = np.asarray(points, dtype=np.float64).reshape(-1, cp.points.shape[-1])
    uv, dist = cp.parameters.reshape(-1, 2).copy(), cp.distances.ravel().copy()
    # Second, local searches before giving up: a point on the surface may sit behind a fold
    # narrower than the global sampling (see _Sampling).
    for reach in _WINDOW_REACHES:
        off = np.flatnonzero(dist > t.linear)
        if off.size == 0:
            break
        _search_surface_window(surface, P, uv, dist, off, reach, t)
    _raise_off(dist, t, "surface")
    return uv.reshape(cp.parameters.shape)


# ---------------------------------------------------------------------- sampling and seeds (bookkeeping)
class _Sampling:
    """Samples of a curve, a surface grid or a surface boundary, and the seeds they give.

    ``neighbours`` ``(S, k)`` lists each sample's neighbours in the sampling (the
    sample itself where one is missing).  :meth:`seeds` returns, per query point,
    the nearest *discrete local minima* of its distance to the samples (samples no
    farther than any neighbour) among the samples within ``d0 + h`` of it, where
    ``d0`` is the nearest sample's distance and ``h`` the largest gap between
    neighbouring samples.  The sample nearest to the global closest point ``X*`` is
    within ``h`` of it, so its distance is at most ``d* + h <= d0 + h``, and a
    discrete descent from it ends at a local minimum inside that ball: one seed lies
    in the basin of the global minimum even when several local minima are nearly
    equidistant, where the plain nearest samples would all cluster in one basin.
    (Two minima closer together than the sample spacing share one seed, and Newton
    finds one of them: a fold narrower than the spacing can hide the closer one.)
    The ball is listed with k-d tree queries of :data:`_BALL` then ``8 * _BALL``
    neighbours; points whose ball holds more fall back to a chunked search over
    all samples.
    """

    def __init__(self, samples: np.ndarray, neighbours: np.ndarray) -> None:
        self.samples = samples
        self.neighbours = neighbours
        self.tree = cKDTree(samples)
        self.scale = _scale(samples)
        self.gap = float(np.max(np.linalg.norm(samples[neighbours] - samples[:, None, :], axis=-1)))

    def seeds(self, Q: np.ndarray, n_seeds: int) -> tuple[np.ndarray, np.ndarray]:
        """Seeds of the query points ``Q (m, d)``: ``owner (q,)`` (row of ``Q``) and sample index ``(q,)``."""
        S, m = self.samples.shape[0], Q.shape[0]
        n = min(n_seeds, S)
        d0, _ = self.tree.query(Q, k=1)
        bound = np.nextafter(np.asarray(d0, dtype=np.float64).reshape(m) + self.gap, np.inf)
        score = np.full((m, n), np.inf)
        index = np.zeros((m, n), np.int64)
        rows = np.arange(m)
        for K in (_BALL, _BALL * 8):
            K = min(K, S)
            sc, ix, full = self._seeds_ball(Q[rows], bound[rows], K, n)
            score[rows], index[rows] = sc, ix
            rows = rows[full]
            if rows.size == 0 or K == S:
                rows = rows[:0]
                break
        if rows.size:
            score[rows], index[rows] = self._seeds_all(Q[rows], n)
        keep = np.isfinite(score)
        return np.broadcast_to(np.arange(m)[:, None], score.shape)[keep], index[keep]

    def _local(self, dist: np.ndarray, Q: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """True where sample ``idx`` (``dist`` from its row's query point) is no farther than its neighbours."""
        nbr = self.neighbours[idx]
        local = np.ones(idx.shape, bool)
        for j in range(nbr.shape[-1]):
            local &= dist <= np.linalg.norm(self.samples[nbr[..., j]] - Q[:, None, :], axis=-1)
        return local

    def _seeds_ball(self, Q: np.ndarray, bound: np.ndarray, K: int, n: int):
        """Nearest ``n`` local minima among the ``K`` nearest samples in each ball; ``full``: the ball holds more."""
        m = Q.shape[0]
        dK = np.empty((m, K))
        iK = np.empty((m, K), np.int64)
        for rows, radius in _bound_groups(bound):
            dist, ind = self.tree.query(Q[rows], k=K, distance_upper_bound=radius)
            dK[rows], iK[rows] = np.reshape(dist, (-1, K)), np.reshape(ind, (-1, K))
        inside = dK <= bound[:, None]
        iK = np.where(inside, iK, 0)
        score = np.where(inside & self._local(dK, Q, iK), dK, np.inf)
        order = np.argsort(score, axis=1, kind="stable")[:, :n]
        full = inside[:, -1] & (K < self.samples.shape[0])
        return np.take_along_axis(score, order, axis=1), np.take_along_axis(iK, order, axis=1), full

    def _seeds_all(self, Q: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Nearest ``n`` discrete local minima over all samples: scores ``(r, n)`` and indices ``(r, n)``."""
        X, nbr = self.samples, self.neighbours
        S = X.shape[0]
        score = np.empty((Q.shape[0], n))
        index = np.empty((Q.shape[0], n), np.int64)
        step = max(1, _BRUTE_BUDGET // S)
        for s in range(0, Q.shape[0], step):
            D = cdist(Q[s : s + step], X)
            local = np.ones(D.shape, bool)
            for j in range(nbr.shape[1]):
                local &= D <= D[:, nbr[:, j]]
            sc = np.where(local, D, np.inf)
            part = np.argpartition(sc, n - 1, axis=1)[:, :n] if n < S else np.broadcast_to(np.arange(S), sc.shape)
            score[s : s + step] = np.take_along_axis(sc, part, axis=1)
            index[s : s + step] = part
        return score, index


def _bound_groups(bound: np.ndarray) -> Iterator[tuple[np.ndarray, float]]:
    """Rows grouped by ball radius (within a factor 2), each group with its largest radius.

    The k-d tree takes one scalar distance bound per query; a group's largest
    radius lists a superset of every member's ball, trimmed afterwards.
    """
    order = np.argsort(bound)
    b = bound[order]
    start = 0
    while start < b.size:
        stop = max(int(np.searchsorted(b, 2.0 * b[start], side="right")), start + 1)
        yield order[start:stop], float(b[stop - 1])
        start = stop


def _axis(params: np.ndarray, creases: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples of one parameter axis split into cells: a sample on an interior crease appears once per side.

    Parameters
    ----------
    params : (n,) sorted sample parameters
    creases : sorted crease values, domain ends included

    Returns
    -------
    sample (k,) int
        Index into ``params`` of each virtual sample, ordered by cell then parameter.
    cell (k,) int
        Its cell.
    neighbours (k, 2) int
        Previous and next virtual sample in the same cell (itself where there is none).
    """
    last = creases.size - 2
    right = np.clip(np.searchsorted(creases, params, side="right") - 1, 0, last)
    on = np.flatnonzero((right > 0) & (params == creases[right]))
    sample = np.concatenate([np.arange(params.size), on])
    cell = np.concatenate([right, right[on] - 1])
    order = np.lexsort((sample, cell))
    sample, cell = sample[order], cell[order]
    k = np.arange(sample.size)
    prev = np.where((k > 0) & (cell[np.maximum(k - 1, 0)] == cell), k - 1, k)
    nxt = np.where((k < k.size - 1) & (cell[np.minimum(k + 1, k.size - 1)] == cell), k + 1, k)
    return sample, cell, np.stack([prev, nxt], axis=1)


class _Creases:
    """One or more sorted crease vectors (domain ends included) and the cells they define.

    Set ``k`` is ``values[k]``; an item with ``which == k`` and ``cell == c`` lives in
    ``[values[k][c], values[k][c + 1]]``.
    """

    def __init__(self, values: list[np.ndarray]) -> None:
        self.values = values
        width = max(v.size for v in values)
        self.table = np.full((len(values), width), np.nan)
        for k, vals in enumerate(values):
            self.table[k, : vals.size] = vals
        self.last = np.array([v.size - 2 for v in values])  # index of the last cell of each set

    def cell(self, u: np.ndarray, which: np.ndarray) -> np.ndarray:
        """Cell of each parameter, the right one on a crease (the last one at the domain end)."""
        c = np.empty(u.shape, np.int64)
        for k, vals in enumerate(self.values):
            sel = which == k
            c[sel] = np.clip(np.searchsorted(vals, u[sel], side="right") - 1, 0, self.last[k])
        return c

    def bounds(self, which: np.ndarray, cell: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.table[which, cell], self.table[which, cell + 1]

    def on_crease(self, u: np.ndarray, which: np.ndarray, cell: np.ndarray) -> np.ndarray:
        """Parameters on an interior crease that is the lower bound of their cell."""
        return (cell > 0) & (u == self.table[which, cell])


def _crease_values(geom: Any, knots_attr: str, degree_attr: str, domain) -> np.ndarray:
    """Knots inside ``domain`` where the geometry is only C0 (multiplicity >= degree), with the domain ends."""
    lo, hi = domain
    knots = getattr(geom, knots_attr, None)
    degree = getattr(geom, degree_attr, None)
    inner = np.empty(0)
    if knots is not None and degree is not None:
        vals, counts = np.unique(np.asarray(knots, dtype=np.float64), return_counts=True)
        inner = vals[(counts >= int(degree)) & (vals > lo) & (vals < hi)]
    return np.concatenate([[lo], inner, [hi]])


def _as_query_points(points, d: int) -> tuple[np.ndarray, tuple[int, ...]]:
    """Query points as a contiguous ``(m, d)`` float64 array and their batch shape."""
    P = np.asarray(points, dtype=np.float64)
    if P.ndim == 0 or P.shape[-1] != d:
        raise InvalidInputError(f"points must have shape (..., {d}) to match the geometry, got shape {P.shape}")
    if not np.all(np.isfinite(P)):
        bad = np.argwhere(~np.isfinite(P))[0]
        raise InvalidInputError(f"points must be finite, coordinate at index {tuple(int(i) for i in bad)} is not")
    return np.ascontiguousarray(P.reshape(-1, d)), P.shape[:-1]


def _spans(geom: Any, knots_attr: str, degree_attr: str, domain, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """Sampling plan of one axis: span breaks ``(s + 1,)`` and samples per span ``(s,)``.

    ``factor (p + 1)`` samples per non-empty knot span, doubled if rational; a
    geometry without knots gets :data:`_PLAIN_SAMPLES` over its domain.
    """
    lo, hi = domain
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InvalidInputError(f"closest points need a bounded parameter domain, got [{lo!r}, {hi!r}]")
    knots = getattr(geom, knots_attr, None)
    degree = getattr(geom, degree_attr, None)
    if knots is None or degree is None:
        return np.array([lo, hi]), np.array([_PLAIN_SAMPLES])
    weights = getattr(geom, "weights", None)
    weights = np.asarray(weights if weights is not None else [1.0], dtype=np.float64)
    rational = bool(np.any(weights != weights.flat[0]))
    breaks = np.unique(np.asarray(knots, dtype=np.float64))
    breaks = np.concatenate([[lo], breaks[(breaks > lo) & (breaks < hi)], [hi]])
    per_span = factor * (int(degree) + 1) * (2 if rational else 1)
    return breaks, np.full(breaks.size - 1, per_span)


def _expand(breaks: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Sample parameters ``(N + 1,)`` of a sampling plan: ``counts[i]`` per span, ends included."""
    span = np.repeat(np.arange(counts.size), counts)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(span.size) - start[span]) / counts[span]
    params = breaks[span] + (breaks[span + 1] - breaks[span]) * frac
    return np.append(params, breaks[-1])


def _subdivided(params: np.ndarray, gaps: np.ndarray, target: float, cap: int) -> np.ndarray:
    """Sample parameters with every interval whose 3-D gap exceeds ``target`` cut into equal pieces.

    ``gaps (N,)`` are the 3-D distances between consecutive samples (the largest over
    the other direction of a surface).  An interval is cut into at most
    :data:`_MAX_REFINE` pieces, and the target is relaxed until the axis holds at
    most ``cap`` samples (or as many as it had).
    """
    pieces = np.ones(gaps.size, np.int64)
    while target > 0:
        pieces = np.clip(np.ceil(gaps / target), 1, _MAX_REFINE).astype(np.int64)
        if pieces.sum() + 1 <= max(cap, params.size):
            break
        target *= 1.25
    if np.all(pieces == 1):
        return params
    return _expand(params, pieces)


def _search_curve_window(
    curve: Any, P: np.ndarray, u: np.ndarray, dist: np.ndarray, off: np.ndarray, reach: float, t: Tolerance
) -> None:
    """Inversion's local search: Newton from the nearest of dense samples around ``u[off]``; updates ``u, dist``.

    The window spans about ``reach`` times the distance found, in space, on each side
    (at most :data:`_WINDOW` of the domain), with :data:`_WINDOW_SAMPLES` samples.
    """
    lo, hi = (float(x) for x in curve.domain)
    speed = np.linalg.norm(np.asarray(curve.derivatives(u[off], 1), dtype=np.float64)[:, 1], axis=1)
    half = _window(dist[off], speed, hi - lo, reach)
    window = np.clip(u[off, None] + half[:, None] * np.linspace(-1, 1, _WINDOW_SAMPLES), lo, hi)
    X = np.asarray(curve.derivatives(window, 0), dtype=np.float64)[..., 0, :]
    u0 = window[np.arange(off.size), np.argmin(np.linalg.norm(X - P[off, None, :], axis=2), axis=1)]
    creases = _Creases([_crease_values(curve, "knots", "degree", (lo, hi))])
    which = np.zeros(off.size, np.int64)

    def ders(w: np.ndarray, items: np.ndarray) -> np.ndarray:
        return np.asarray(curve.derivatives(w, 2), dtype=np.float64)

    scale = _scale(X.reshape(-1, X.shape[-1]))
    u1, C1, ok, _ = _descend_1d(ders, u0, which, creases.cell(u0, which), P[off], creases, t, scale)
    d1 = np.linalg.norm(C1 - P[off], axis=1)
    better = ok & (d1 < dist[off])
    u[off[better]], dist[off[better]] = u1[better], d1[better]


def _search_surface_window(
    surface: Any, P: np.ndarray, uv: np.ndarray, dist: np.ndarray, off: np.ndarray, reach: float, t: Tolerance
) -> None:
    """:func:`_search_curve_window` on a surface, ``(_WINDOW_SAMPLES / 4 + 1)²`` samples; updates ``uv, dist``."""
    (ulo, uhi), (vlo, vhi) = ((float(a), float(b)) for a, b in (surface.domain_u, surface.domain_v))
    D = np.asarray(surface.derivatives(uv[off, 0], uv[off, 1], 1), dtype=np.float64)
    half_u = _window(dist[off], np.linalg.norm(D[:, 1, 0], axis=1), uhi - ulo, reach)
    half_v = _window(dist[off], np.linalg.norm(D[:, 0, 1], axis=1), vhi - vlo, reach)
    s = np.linspace(-1, 1, _WINDOW_SAMPLES // 4 + 1)
    wu = np.clip(uv[off, 0, None] + half_u[:, None] * s, ulo, uhi)[:, :, None]
    wv = np.clip(uv[off, 1, None] + half_v[:, None] * s, vlo, vhi)[:, None, :]
    X = np.asarray(surface.derivatives(wu, wv, 0), dtype=np.float64)[..., 0, 0, :].reshape(off.size, -1, P.shape[1])
    i, j = np.unravel_index(np.argmin(np.linalg.norm(X - P[off, None, :], axis=2), axis=1), (s.size, s.size))
    u0, v0 = wu[np.arange(off.size), i, 0], wv[np.arange(off.size), 0, j]
    creases_u = _Creases([_crease_values(surface, "knots_u", "degree_u", (ulo, uhi))])
    creases_v = _Creases([_crease_values(surface, "knots_v", "degree_v", (vlo, vhi))])
    zero = np.zeros(off.size, np.int64)
    cu, cv = creases_u.cell(u0, zero), creases_v.cell(v0, zero)
    uv1, S1, ok, _ = _descend_2d(
        surface, u0, v0, cu, cv, P[off], creases_u, creases_v, t, _scale(X.reshape(-1, X.shape[-1]))
    )
    d1 = np.linalg.norm(S1 - P[off], axis=1)
    better = ok & (d1 < dist[off])
    uv[off[better]], dist[off[better]] = uv1[better], d1[better]


def _window(dist: np.ndarray, speed: np.ndarray, length: float, reach: float) -> np.ndarray:
    """Half-widths in one parameter spanning ``reach`` times ``dist`` in space (``speed`` = ``|∂S|``),
    at most :data:`_WINDOW` of the domain ``length``."""
    with np.errstate(divide="ignore"):
        half = np.where(speed > 0, reach * dist / speed, np.inf)
    return np.minimum(half, _WINDOW * length)


def _scale(samples: np.ndarray) -> float:
    """Reference magnitude of the geometry's round-off: its size or its distance from the origin."""
    return float(max(_diagonal(samples), np.max(np.abs(samples))))


def _diagonal(samples: np.ndarray) -> float:
    return float(np.linalg.norm(samples.max(axis=0) - samples.min(axis=0)))


def _curve_points(curve: Any, u: np.ndarray) -> np.ndarray:
    return np.asarray(curve.derivatives(u, 0), dtype=np.float64)[:, 0, :]


def _surface_grid(surface: Any, us: np.ndarray, vs: np.ndarray) -> np.ndarray:
    if hasattr(surface, "evaluate_grid"):
        return np.asarray(surface.evaluate_grid(us, vs), dtype=np.float64)
    D = np.asarray(surface.derivatives(us[:, None], vs[None, :], 0), dtype=np.float64)
    return D[..., 0, 0, :]


# ---------------------------------------------------------------------- Newton (formulas)
def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _inside(u: np.ndarray, hi: np.ndarray, interior: np.ndarray) -> np.ndarray:
    """``u``, moved one ulp below ``hi`` where it sits on an interior upper crease (the cell's own piece)."""
    return np.where((u >= hi) & interior, np.nextafter(hi, -np.inf), u)


def _descend_1d(
    ders: Callable[[np.ndarray, np.ndarray], np.ndarray],
    u: np.ndarray,
    which: np.ndarray,
    cell: np.ndarray,
    P: np.ndarray,
    creases: _Creases,
    tol: Tolerance,
    scale: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Safeguarded Newton on ``f(u) = C'(u) · (C(u) - P) = 0`` for a batch of seeds (The NURBS Book eq. 6.3).

    Parameters
    ----------
    ders : callable ``(u (n,), items (n,) int) -> (n, 3, d)``
        Point, first and second derivative at ``u`` for the batch items ``items``.
    u : (n,) seeds; which, cell : (n,) crease set and cell of each seed; P : (n, d) query points.

    Returns
    -------
    u (n,), points (n, d), converged (n,) bool, cosine (n,) ``|f| / (|C'| |r|)`` at the end.
    """
    n = u.shape[0]
    cell = cell.copy()
    first, last = creases.table[which, 0], creases.table[which, creases.last[which] + 1]
    lo, hi = creases.bounds(which, cell)
    u = np.clip(u.astype(np.float64, copy=True), lo, hi)

    def at(uu: np.ndarray, items: np.ndarray, c: np.ndarray) -> np.ndarray:
        return ders(_inside(uu, creases.table[which[items], c + 1], c < creases.last[which[items]]), items)

    D = at(u, np.arange(n), cell)
    converged = np.zeros(n, bool)
    # A step this small (parameter or image) is round-off of the solver's relative accuracy.
    step_u = tol.solver * (last - first)
    step_x = tol.solver * scale
    active = np.arange(n)
    for _ in range(MAX_ITERATIONS):
        if active.size == 0:
            break
        ua, Pa, Da, ca = u[active], P[active], D[active], cell[active]
        lo, hi = creases.bounds(which[active], ca)
        r = Da[:, 0] - Pa
        d1, d2 = Da[:, 1], Da[:, 2]
        f = _dot(d1, r)
        dist = np.linalg.norm(r, axis=1)
        speed = np.linalg.norm(d1, axis=1)
        low, high = (ua <= lo) & (f > 0), (ua >= hi) & (f < 0)
        done = (dist <= step_x) | (np.abs(f) <= tol.angular * speed * dist) | low | high
        # Stopped on a crease: move to the neighbouring cell if its one-sided derivative descends into it.
        try_ = np.flatnonzero(done & (dist > step_x) & ((low & (ca > 0)) | (high & (ca < creases.last[which[active]]))))
        moved = np.zeros(active.size, bool)
        if try_.size:
            items = active[try_]
            nc = np.where(low[try_], ca[try_] - 1, ca[try_] + 1)
            Dn = at(u[items], items, nc)
            slope = _dot(Dn[:, 1], Dn[:, 0] - P[items])
            go = np.where(low[try_], slope > 0, slope < 0)
            cell[items[go]], D[items[go]] = nc[go], Dn[go]
            moved[try_[go]] = True
        converged[active[done & ~moved]] = True
        step = ~done
        active, ua, Pa, ca, lo, hi, f, dist, speed, r, d2 = (
            x[step] for x in (active, ua, Pa, ca, lo, hi, f, dist, speed, r, d2)
        )
        # Newton on f; where f' <= 0 (near a distance maximum) Gauss–Newton's |C'|^2, a descent direction.
        fp = _dot(d2, r) + speed * speed
        denom = np.where(fp > 0, fp, speed * speed)
        with np.errstate(divide="ignore", invalid="ignore"):
            du = np.where(denom > 0, -f / denom, 0.0)
        du = np.clip(ua + du, lo, hi) - ua
        pending = np.arange(active.size)
        for _ in range(_MAX_HALVINGS):
            if pending.size == 0:
                break
            items = active[pending]
            trial = np.clip(ua[pending] + du[pending], lo[pending], hi[pending])
            Dt = at(trial, items, ca[pending])
            # Not farther, up to the round-off of the distance itself (else steps at the minimum would halve forever).
            better = np.linalg.norm(Dt[:, 0] - Pa[pending], axis=1) <= dist[pending] + step_x
            size = np.abs(du[pending])
            small = (size <= step_u[items]) | (size * speed[pending] <= step_x)
            u[items[better]], D[items[better]] = trial[better], Dt[better]
            # A tiny step ends the iteration, accepted or not: the distance is stationary to round-off.
            converged[items[small]] = True
            pending = pending[~better & ~small]
            du[pending] *= 0.5
        # Items that moved to another cell did not step this round and stay active.
        active = np.flatnonzero(~converged)
    r = D[:, 0] - P
    cos = _cosine(_dot(D[:, 1], r), np.linalg.norm(D[:, 1], axis=1), np.linalg.norm(r, axis=1))
    return u, D[:, 0].copy(), converged, cos


def _descend_2d(
    surface: Any,
    u: np.ndarray,
    v: np.ndarray,
    cu: np.ndarray,
    cv: np.ndarray,
    P: np.ndarray,
    creases_u: _Creases,
    creases_v: _Creases,
    tol: Tolerance,
    scale: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Safeguarded Newton on ``Su · r = Sv · r = 0`` for a batch of seeds (The NURBS Book eqs. 6.6–6.8).

    Each iterate stays in its cell with an active set at the cell's bounds: a
    parameter at a bound whose descent direction leaves the cell is frozen and the
    iteration runs in the other one (projected Newton).

    Parameters
    ----------
    u, v : (n,) seeds; cu, cv : (n,) their cells; P : (n, d) query points.

    Returns
    -------
    uv (n, 2), points (n, d), converged (n,) bool, cosine (n,) (larger of the two directions).
    """
    n = u.shape[0]
    cu, cv = cu.copy(), cv.copy()
    Tu, Tv = creases_u.table[0], creases_v.table[0]
    last_u, last_v = int(creases_u.last[0]), int(creases_v.last[0])
    ulo, uhi, vlo, vhi = Tu[0], Tu[last_u + 1], Tv[0], Tv[last_v + 1]
    u = np.clip(u.astype(np.float64, copy=True), Tu[cu], Tu[cu + 1])
    v = np.clip(v.astype(np.float64, copy=True), Tv[cv], Tv[cv + 1])

    def at(uu: np.ndarray, vv: np.ndarray, cu: np.ndarray, cv: np.ndarray) -> np.ndarray:
        D = np.asarray(
            surface.derivatives(_inside(uu, Tu[cu + 1], cu < last_u), _inside(vv, Tv[cv + 1], cv < last_v), 2),
            dtype=np.float64,
        )
        # S, Su, Sv, Suu, Suv, Svv
        return np.stack([D[:, 0, 0], D[:, 1, 0], D[:, 0, 1], D[:, 2, 0], D[:, 1, 1], D[:, 0, 2]], axis=1)

    D = at(u, v, cu, cv)
    converged = np.zeros(n, bool)
    # Steps this small (parameters or image) are round-off of the solver's relative accuracy.
    step_u = tol.solver * (uhi - ulo)
    step_v = tol.solver * (vhi - vlo)
    step_x = tol.solver * scale
    active = np.arange(n)
    for _ in range(MAX_ITERATIONS):
        if active.size == 0:
            break
        ua, va, Pa, Da = u[active], v[active], P[active], D[active]
        lo_u, hi_u = Tu[cu[active]], Tu[cu[active] + 1]
        lo_v, hi_v = Tv[cv[active]], Tv[cv[active] + 1]
        r = Da[:, 0] - Pa
        Su, Sv, Suu, Suv, Svv = Da[:, 1], Da[:, 2], Da[:, 3], Da[:, 4], Da[:, 5]
        f, g = _dot(Su, r), _dot(Sv, r)
        dist = np.linalg.norm(r, axis=1)
        nu, nv = np.linalg.norm(Su, axis=1), np.linalg.norm(Sv, axis=1)
        low_u, high_u = (ua <= lo_u) & (f > 0), (ua >= hi_u) & (f < 0)
        low_v, high_v = (va <= lo_v) & (g > 0), (va >= hi_v) & (g < 0)
        out_u, out_v = low_u | high_u, low_v | high_v
        ok_u = out_u | (np.abs(f) <= tol.angular * nu * dist)
        ok_v = out_v | (np.abs(g) <= tol.angular * nv * dist)
        done = (dist <= step_x) | (ok_u & ok_v)
        # Stopped on a crease: move to the neighbouring cell if its one-sided derivative descends into it.
        moved = np.zeros(active.size, bool)
        for low, high, cells, last, along_u in ((low_u, high_u, cu, last_u, True), (low_v, high_v, cv, last_v, False)):
            c = cells[active]
            try_ = np.flatnonzero(done & ~moved & (dist > step_x) & ((low & (c > 0)) | (high & (c < last))))
            if not try_.size:
                continue
            items = active[try_]
            nc = np.where(low[try_], c[try_] - 1, c[try_] + 1)
            Dn = at(u[items], v[items], nc if along_u else cu[items], cv[items] if along_u else nc)
            slope = _dot(Dn[:, 1 if along_u else 2], Dn[:, 0] - P[items])
            go = np.where(low[try_], slope > 0, slope < 0)
            cells[items[go]], D[items[go]] = nc[go], Dn[go]
            moved[try_[go]] = True
        converged[active[done & ~moved]] = True
        step = ~done
        state = (active, ua, va, Pa, r, Su, Sv, Suu, Suv, Svv, f, g, dist, nu, nv, out_u, out_v, lo_u, hi_u, lo_v, hi_v)
        active, ua, va, Pa, r, Su, Sv, Suu, Suv, Svv, f, g, dist, nu, nv, out_u, out_v, lo_u, hi_u, lo_v, hi_v = (
            x[step] for x in state
        )
        # Hessian H of |r|^2 / 2.  The step solves |H| δ = -∇ with |H| the Hessian with its
        # eigenvalues made positive ("saddle-free" Newton): Newton's step where H is positive
        # definite, a descent step scaled by the curvature elsewhere.  Eigenvalues are floored
        # at tol.solver relative to |Su|^2 + |Sv|^2, which keeps |H| invertible at a pole.
        a, b, c = nu * nu + _dot(r, Suu), _dot(Su, Sv) + _dot(r, Suv), nv * nv + _dot(r, Svv)
        floor = tol.solver * (nu * nu + nv * nv)
        mean, radius = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
        theta = 0.5 * np.arctan2(2.0 * b, a - c)
        c1, s1 = np.cos(theta), np.sin(theta)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = np.where(floor > 0, -(c1 * f + s1 * g) / np.maximum(np.abs(mean + radius), floor), 0.0)
            t2 = np.where(floor > 0, -(c1 * g - s1 * f) / np.maximum(np.abs(mean - radius), floor), 0.0)
            du_only = np.where(floor > 0, -f / np.maximum(np.abs(a), floor), 0.0)
            dv_only = np.where(floor > 0, -g / np.maximum(np.abs(c), floor), 0.0)
        du_both, dv_both = c1 * t1 - s1 * t2, s1 * t1 + c1 * t2
        du = np.where(out_u, 0.0, np.where(out_v, du_only, du_both))
        dv = np.where(out_v, 0.0, np.where(out_u, dv_only, dv_both))
        # The first trial goes at most a cell's width in each parameter; shrinking the whole step
        # keeps its direction, a descent direction, which clipping each parameter would not.
        with np.errstate(divide="ignore"):
            shrink = np.minimum(1.0, np.minimum((hi_u - lo_u) / np.abs(du), (hi_v - lo_v) / np.abs(dv)))
        du, dv = du * shrink, dv * shrink
        pending = np.arange(active.size)
        for _ in range(_MAX_HALVINGS):
            if pending.size == 0:
                break
            items = active[pending]
            # Along the projection arc: the trial point is clipped into the cell, the direction is not.
            tu = np.clip(ua[pending] + du[pending], lo_u[pending], hi_u[pending])
            tv = np.clip(va[pending] + dv[pending], lo_v[pending], hi_v[pending])
            Dt = at(tu, tv, cu[items], cv[items])
            # Not farther, up to the round-off of the distance itself (else steps at the minimum would halve forever).
            better = np.linalg.norm(Dt[:, 0] - Pa[pending], axis=1) <= dist[pending] + step_x
            su, sv = tu - ua[pending], tv - va[pending]
            image = np.linalg.norm(su[:, None] * Su[pending] + sv[:, None] * Sv[pending], axis=1)
            small = ((np.abs(su) <= step_u) & (np.abs(sv) <= step_v)) | (image <= step_x)
            u[items[better]], v[items[better]], D[items[better]] = tu[better], tv[better], Dt[better]
            # A tiny step ends the iteration, accepted or not: the distance is stationary to round-off.
            converged[items[small]] = True
            pending = pending[~better & ~small]
            du[pending] *= 0.5
            dv[pending] *= 0.5
        # Items that moved to another cell did not step this round and stay active.
        active = np.flatnonzero(~converged)
    r = D[:, 0] - P
    dist = np.linalg.norm(r, axis=1)
    cos = np.maximum(
        _cosine(_dot(D[:, 1], r), np.linalg.norm(D[:, 1], axis=1), dist),
        _cosine(_dot(D[:, 2], r), np.linalg.norm(D[:, 2], axis=1), dist),
    )
    return np.stack([u, v], axis=1), D[:, 0].copy(), converged, cos


def _cosine(f: np.ndarray, speed: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """``|f| / (speed * dist)``, 0 where the denominator vanishes (a coincident point or a stationary parameter)."""
    den = speed * dist
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, np.abs(f) / den, 0.0)


# ---------------------------------------------------------------------- choosing and reporting
def _pick(
    owner: np.ndarray, cand: np.ndarray, ok: np.ndarray, cos: np.ndarray, Q: np.ndarray, tol: Tolerance
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best candidate of every query point: its nearest converged one.

    Parameters
    ----------
    owner : (c,) row of ``Q`` each candidate belongs to (every row has one)
    cand : (c, d) candidate points; ok : (c,) converged; cos : (c,) residual cosines
    Q : (m, d) query points

    A point fails when none of its candidates converged, or when an unconverged one
    is nearer than the best converged one by more than ``tol.linear`` (the answer
    might then not be the closest point).

    Returns
    -------
    best (m,) index into the candidates, bad (m,) bool, residual cosine (m,) of the nearest candidate.
    """
    m = Q.shape[0]
    dist = np.linalg.norm(cand - Q[owner], axis=1)
    d_ok = np.where(ok, dist, np.inf)
    nearest = _first_per_owner(owner, dist, m)
    best = _first_per_owner(owner, d_ok, m)
    found = np.isfinite(d_ok[best])
    bad = ~found | (dist[nearest] < d_ok[best] - tol.linear)
    return np.where(found, best, nearest), bad, cos[nearest]


def _first_per_owner(owner: np.ndarray, key: np.ndarray, m: int) -> np.ndarray:
    """Index of the smallest ``key`` of each owner ``0 .. m-1``."""
    order = np.lexsort((key, owner))
    starts = np.searchsorted(owner[order], np.arange(m))
    return order[starts]


def _raise_unconverged(where: str, failed: list[np.ndarray], residuals: list[np.ndarray], m: int) -> None:
    idx = np.concatenate(failed) if failed else np.empty(0, np.int64)
    if idx.size:
        res = np.concatenate(residuals)
        raise ConvergenceError(
            f"{where}: {idx.size} of {m} points did not converge within {MAX_ITERATIONS} Newton iterations "
            f"(first at index {int(idx[0])}, orthogonality cosine {float(res[0]):.3g})",
            indices=idx,
            residuals=res,
        )


def _raise_off(distances: np.ndarray, tol: Tolerance, what: str) -> None:
    d = np.asarray(distances).ravel()
    off = np.flatnonzero(d > tol.linear)
    if off.size:
        worst = int(off[np.argmax(d[off])])
        raise ConvergenceError(
            f"{what} inversion: {off.size} of {d.size} points are farther than tol.linear = {tol.linear:g} "
            f"from the {what}; the worst is index {worst} at distance {float(d[worst]):.6g}",
            indices=off,
            residuals=d[off],
        )
