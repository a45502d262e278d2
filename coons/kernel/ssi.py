"""General surface–surface and curve–surface intersection by sampling, Newton correction and refinement.

:func:`march_intersection` finds the intersection curves of two surfaces of any kind (NURBS–NURBS,
quadric–NURBS, non-coaxial quadrics such as two crossing cylinders) inside two parameter boxes, as
cubic 3-D NURBS curves with p-curves on both surfaces in the same parameter; it is the fallback of
:func:`coons.kernel.intersect.intersect_surfaces` for the pairs that have no exact form.
:func:`intersect_curve_surface` finds the points where a curve crosses or touches a surface.  The
module deliberately does not trace intersection curves along which the two surfaces are tangent
(the signed distance does not change sign there: such a tangency is detected and logged; see
*Limitations*); exact analytic pairs are :mod:`coons.kernel.intersect`'s.

Notation: ``G`` is the *grid* surface, sampled on its box, ``F`` the *field* surface, whose signed
distance ``f = ±dist(G(u, v), F)`` is sampled on ``G``'s grid (the closed-form ``implicit`` of an
analytic surface, or a local projection onto a NURBS signed by its normal).  When only ``a`` is
analytic, ``b`` is the grid surface; results are always reported for ``(a, b)``.  A point of the
intersection is ``x = (u_G, v_G, u_F, v_F)`` with ``G(u_G, v_G) = F(u_F, v_F)``.

Steps (Cohen–Riesenfeld–Elber ch. 18; Patrikalakis–Maekawa §5.8, "lattice" methods, and §5.8.3 for
singular and tangential points):

1. *Sampling.*  ``f`` on a (slightly irregular, to avoid symmetric coincidences) grid over
   ``G``'s box; marching squares (saddle cells decided by the centre value) gives the crossings of
   ``f = 0`` with the grid edges and their connections into chains (open chains end on ``G``'s box
   boundary, closed chains are loops).  A chain whose samples all lie within ``tol.linear`` of
   each other is dropped: it is the sign flip of ``f`` around a vertex where the surfaces touch.
1b. *Small loops.*  A loop that meets no grid edge twice, or too few of them to be followed, is
   found through the critical points of ``f`` (Patrikalakis–Maekawa §5.8.3): inside a loop ``f``
   has an extremum of the other sign.  Newton's method on ``∇f = 0`` (difference quotients) from
   the grid vertices where ``|f|`` is locally smallest without a sign change nearby reaches it;
   the quadratic model there gives the loop's extent, and a local grid of :data:`_LOOP_CELLS`
   cells over twice that is marched like the main one (and doubled until its chains close).
   Loops of the main grid with fewer than :data:`_LOOP_MIN_SAMPLES` samples are marched again
   on such a local grid (a cubic through three or four samples of a loop folds back).
2. *Correction.*  Every crossing is moved onto the intersection by Newton's method on the 4 × 4
   system ``G(u_G, v_G) - F(u_F, v_F) = 0`` plus the grid line of its edge (``u_G`` or ``v_G``
   fixed), batched over all crossings.  Solutions are shifted by whole periods to the seed's
   (a sphere's ``v`` counts as 2π-periodic here; a sphere latitude that Newton carried over a
   pole and out of the box is reflected back, so that p-curves stay in the domain); a crossing
   whose Newton fails or leaves its edge keeps its seed, so that a wandering solution never marks
   a false exit from ``F``'s box.
3. *Singular points* (``n_G ∥ n_F``, where branches cross, e.g. two equal cylinders): local minima
   of ``|n_G × n_F|`` along the chains start a Gauss–Newton iteration on the 5 equations
   ``G - F = 0``, ``n_G · F_u = n_G · F_v = 0``; a converged solution splits every chain through it,
   so that the branches end there (a chain is taken to pass through the point when its nearest
   sample is within a step of it, or within the 3 × 3 grid cells around it with nearly parallel
   normals: next to a saddle contact, branches leaving through one edge are invisible and the
   chain turns a cell away; never at the point's image beyond ``G``'s seam).  A chain that ends a
   cell past the point at ``G``'s box edge, having turned in the point's cell from one arm onto
   another that runs back towards it, is split on its segment nearest the point instead.  The poles of a
   sphere and the apex of a cone that lie on the other surface split the chains in the same way
   (the p-curve on that surface jumps there; each side ends with the parameter of its own limit).
4. *Boxes.*  ``F``'s parameters are unwrapped along each chain; chains are cut where they leave
   ``F``'s box (or cross its seam when the box is a whole period), the cut point found by Newton
   with the boundary parameter fixed.  A loop cut only at a seam is one branch from one side of
   the box to the other, ``closed=True`` as in :mod:`coons.kernel.intersect` (its p-curve does not
   close, its 3-D curve does).
5. *Contacts.*  Grid vertices where ``|f|`` is locally smallest without a sign change nearby seed
   the same Gauss–Newton solve as singular points; a solution where the surfaces separate in every
   direction (the difference of their shape operators is definite) is an isolated contact point.
6. *Refinement and fit.*  Each piece is interpolated by a cubic in the chord length ``t`` of its
   samples (3-D curve and both p-curves, same ``t``; ``t1 - t0`` approximates but is not the arc
   length); the midpoints of all intervals are corrected by
   Newton in the plane normal to the fitted curve and inserted where any of the three curves misses
   them by more than half of ``tol.linear``, until none does.  The achieved ``tol`` of a branch is the
   largest distance measured between the three curves and the corrected points.  A parameter
   undetermined at a piece's end (a sphere's longitude at its pole, a cone's at its apex) is not
   measured by these distances (the whole pole is one point): at every fit it is extrapolated
   linearly in ``t`` from the two samples next to it (the limit along the branch, to second
   order), so the p-curve ends where its neighbourhood points instead of running along the pole.

Limitations: a loop smaller than a grid cell is found when the grid vertex nearest it is a local
minimum of ``|f|`` (step 1b): true when the surfaces approach each other over more than a cell
(the usual case, two nearly tangent surfaces cutting slightly: loops down to ``1e-3`` of the box
are tested), not when a feature narrower than a cell pokes through a surface that stays away
elsewhere (that needs the subdivision with normal cones of Sederberg's loop criterion, not done).
A piece shorter than a cell between two cuts is missed (a branch that leaves ``F``'s box and
crosses its seam within one cell, or the arms of a singular point closer than a cell to ``G``'s
periodic seam, which then end a cell short of it); surfaces tangent along a curve give no branch
(a warning is logged on ``logging.getLogger("coons")``).  A typical pair takes 0.05–0.3 s, mostly
in the Newton corrections and interpolations of the refinement.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, depth_first_order
from scipy.spatial import cKDTree

from coons.errors import InvalidInputError
from coons.kernel._common import interval_cuts
from coons.kernel.analytic import _Revolved, _surface_params
from coons.kernel.curve import NurbsCurve
from coons.kernel.onsurface import singular_parameters, surface_periods
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["march_intersection", "intersect_curve_surface"]

_log = logging.getLogger("coons")

#: Samples per direction of a NURBS field surface seeding the local projection, and its Gauss–Newton steps.
_FIELD_SAMPLES = 64
_FOOT_ITERATIONS = 8
#: Grid cells per direction of the sampling grid (the resolution of the search, not a tolerance:
#: loops narrower than a cell may be missed).
_GRID_CELLS = 48
#: Relative irregularity of the interior grid lines: moves them off symmetric positions (axes,
#: singular points of symmetric pairs) where f would vanish exactly at grid vertices.
_GRID_JITTER = 0.173
#: Newton iterations of the corrector; quadratic convergence needs far fewer from grid seeds.
_NEWTON_ITERATIONS = 24
#: Gauss–Newton iterations for singular points (linear convergence near a double point is possible).
_SINGULAR_ITERATIONS = 60
#: A singular-point candidate is dropped when its residual has not fallen below this fraction of
#: its best for this many Gauss–Newton steps (a solver strategy: the acceptance test decides).
_SINGULAR_GAIN = 0.9
_SINGULAR_PATIENCE = 5
#: Chain vertices whose normals make a sine below this start a singular-point search (a cheap
#: filter only: the Gauss–Newton solve decides).
_SINGULAR_SINE = 0.5
#: Refinement rounds of a branch (each at most doubles its samples) and the sample cap.
_REFINE_ROUNDS = 14
_MAX_BRANCH_SAMPLES = 1 << 13
#: Most samples added to one interval in one refinement round.
_MAX_SPLIT = 8
#: Curve samples per unit of a curve's parameter range in intersect_curve_surface (at least), and
#: per knot span of a NURBS curve.
_CURVE_SAMPLES = 128
_CURVE_SPAN_SAMPLES = 8


# ---------------------------------------------------------------------------- small helpers
def _resolve_box(surface, box, what: str) -> np.ndarray:
    if box is None:
        dom = np.array([surface.domain_u, surface.domain_v], dtype=np.float64)
        if not np.all(np.isfinite(dom)):
            raise InvalidInputError(
                f"{what}: the {type(surface).__name__} is unbounded, a box ((u0, u1), (v0, v1)) is required"
            )
        return dom
    try:
        b = np.array(box, dtype=np.float64)
    except (TypeError, ValueError):
        b = None
    if b is None or b.shape != (2, 2) or not np.all(np.isfinite(b)) or np.any(b[:, 0] >= b[:, 1]):
        raise InvalidInputError(f"{what}: box must be finite ((u0, u1), (v0, v1)) with u0 < u1, v0 < v1, got {box!r}")
    return b


def _one_period(box: np.ndarray, periods) -> np.ndarray:
    """A box at most one period long in periodic directions (a longer one would repeat branches).

    A face box enlarged past a whole period (``[-ε, 2π + ε]``) becomes ``[0, 2π]``: the seam goes to
    the middle of the doubly covered margin.
    """
    box = box.copy()
    for k, per in enumerate(periods):
        if per is not None and box[k, 1] - box[k, 0] > per:
            lo = 0.5 * (box[k, 0] + box[k, 1] - per)
            box[k] = lo, lo + per
    return box


def _in_domain(box: np.ndarray, surface, what: str) -> np.ndarray:
    """The part of ``box`` inside a NURBS domain (a face box may be enlarged past it); analytic: ``box``.

    Raises
    ------
    InvalidInputError
        The box does not meet the domain.
    """
    if not isinstance(surface, (NurbsSurface, _ClosedNurbs)):
        return box
    dom = np.array(surface.domain, dtype=np.float64)
    out = np.stack([np.maximum(box[:, 0], dom[:, 0]), np.minimum(box[:, 1], dom[:, 1])], axis=1)
    if np.any(out[:, 0] >= out[:, 1]):
        raise InvalidInputError(f"{what}: box {box.tolist()} does not meet the NURBS domain {dom.tolist()}")
    return out


def _clip(surface, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """NURBS parameters held in the domain (closed directions of a :class:`_ClosedNurbs` excepted)."""
    if isinstance(surface, NurbsSurface):
        (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
        return np.clip(u, u0, u1), np.clip(v, v0, v1)
    if isinstance(surface, _ClosedNurbs):
        (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
        return (u if surface.periodic_u else np.clip(u, u0, u1)), (v if surface.periodic_v else np.clip(v, v0, v1))
    return u, v


def _frame(surface, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points and first partials ``(m, 3)`` each (NURBS parameters clipped into the domain).

    A surface of revolution's three are formed here from its meridian with the same element-wise
    operations, in the same order, as its ``derivatives(u, v, 1)`` (bit for bit the same values):
    the marching corrector calls this every Newton step, and the general routine's stacking of
    all four partials costs more than the arithmetic.
    """
    if isinstance(surface, _Revolved):
        u, v = _surface_params(u, v)
        rho, h = surface._meridian(v, 1)
        X, Y, Z = surface._frame
        c, s = np.cos(u)[..., None], np.sin(u)[..., None]
        e0 = c * X + s * Y
        e1 = (-s) * X + c * Y
        S = (e0 * rho[0][..., None] + h[0][..., None] * Z) + surface._origin
        return S, e1 * rho[0][..., None], e0 * rho[1][..., None] + h[1][..., None] * Z
    d = np.asarray(surface.derivatives(*_clip(surface, u, v), 1))
    return d[..., 0, 0, :], d[..., 1, 0, :], d[..., 0, 1, :]


def _normals(surface, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.asarray(surface.normal(*_clip(surface, u, v)))


def _project(surface, points: np.ndarray, t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(m, 2)`` and signed distances ``(m,)`` of ``points`` relative to ``surface``.

    Closed form for analytic surfaces.  For NURBS a local projection: the nearest of
    :data:`_FIELD_SAMPLES`² surface samples (k-d tree) starts :data:`_FOOT_ITERATIONS` Gauss–Newton
    steps on ``(S - P) · S_u = (S - P) · S_v = 0`` kept in the domain, and the sign is that of
    ``(P - S) · n``.  This is a sampling of a signed distance for finding sign changes, cheaper than
    :func:`coons.kernel.projection.surface_closest_points`' global search; every point it gives is
    corrected by Newton afterwards, so a local rather than global foot only shifts a seed.
    """
    if hasattr(surface, "implicit") and not isinstance(surface, NurbsSurface):
        return np.asarray(surface.closest_parameters(points)), np.asarray(surface.implicit(points))
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    us, vs = np.linspace(u0, u1, _FIELD_SAMPLES), np.linspace(v0, v1, _FIELD_SAMPLES)
    grid = np.asarray(surface.evaluate_grid(us, vs)).reshape(-1, 3)
    _, nearest = cKDTree(grid).query(points)
    u, v = us[nearest // _FIELD_SAMPLES], vs[nearest % _FIELD_SAMPLES]
    for _ in range(_FOOT_ITERATIONS):
        S, Su, Sv = _frame(surface, u, v)
        r = S - points
        a, b, c = (Su * Su).sum(1), (Su * Sv).sum(1), (Sv * Sv).sum(1)
        gu, gv = (Su * r).sum(1), (Sv * r).sum(1)
        det = a * c - b * b
        safe = np.where(det > 0.0, det, 1.0)
        du = np.where(det > 0.0, (c * gu - b * gv) / safe, 0.0)
        dv = np.where(det > 0.0, (a * gv - b * gu) / safe, 0.0)
        u, v = np.clip(u - du, u0, u1), np.clip(v - dv, v0, v1)
    S = _frame(surface, u, v)[0]
    side = np.einsum("ij,ij->i", points - S, _normals(surface, u, v))
    return np.stack([u, v], axis=1), np.where(side < 0.0, -1.0, 1.0) * np.linalg.norm(points - S, axis=1)


class _ClosedNurbs:
    """A closed NURBS surface seen as periodic: parameters wrap into the domain in closed directions.

    Newton iterates and unwrapped branch parameters may cross the seam of a NURBS that closes on
    itself (a revolved or exact quadric NURBS); evaluating there must continue across the seam
    rather than clip.  Non-closed directions are clipped as for any NURBS.
    """

    def __init__(self, surface: NurbsSurface, periods) -> None:
        self.surface = surface
        self.periodic_u, self.periodic_v = periods[0] is not None, periods[1] is not None
        self.period_u, self.period_v = periods
        self.domain_u, self.domain_v = surface.domain_u, surface.domain_v
        self.domain = surface.domain

    def _map(self, u, v):
        (u0, u1), (v0, v1) = self.domain_u, self.domain_v
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        u = u0 + np.mod(u - u0, self.period_u) if self.periodic_u else u
        v = v0 + np.mod(v - v0, self.period_v) if self.periodic_v else v
        return np.clip(u, u0, u1), np.clip(v, v0, v1)

    def evaluate(self, u, v):
        return self.surface.evaluate(*self._map(u, v))

    def derivatives(self, u, v, order: int = 1):
        return self.surface.derivatives(*self._map(u, v), order)

    def normal(self, u, v):
        return self.surface.normal(*self._map(u, v))

    def evaluate_grid(self, us, vs):
        return self.surface.evaluate_grid(us, vs)


def _periodic_view(surface, t: Tolerance):
    """``surface``, or a :class:`_ClosedNurbs` view of a NURBS surface that closes on itself."""
    if not isinstance(surface, NurbsSurface):
        return surface
    periods = surface_periods(surface, t)
    return surface if periods == (None, None) else _ClosedNurbs(surface, periods)


def _correct(g, f, x: np.ndarray, fixed: np.ndarray, value: np.ndarray, plane: np.ndarray | None,
             t: Tolerance, boxes=(None, None)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton on ``G(x[:2]) - F(x[2:]) = 0`` plus one constraint per row, batched.

    The constraint is ``x[fixed] = value`` where ``fixed >= 0``, else the plane
    ``(G(x[:2]) - plane[:, :3]) · plane[:, 3:] = 0``.  Singular systems (near a singular point of
    the intersection) take pseudo-inverse steps, so those rows still move towards the curve.
    A sphere's latitude that ends beyond a pole and outside its box (``boxes``: G's and F's, or
    None) is brought back over the pole (:func:`_on_sphere_domain`).

    Returns
    -------
    x : (m, 4) corrected parameters
    points : (m, 3) ``G(x[:2])``
    ok : (m,) bool, ``|G - F| <= tol.linear / 10`` (a tenth of the budget: fitting adds its error)
    """
    x0 = np.asarray(x, dtype=np.float64)
    x = x0.copy()
    active = np.arange(x.shape[0])
    for _ in range(_NEWTON_ITERATIONS):
        if active.size == 0:
            break
        xa = x[active]
        m = active.size
        fix, val = fixed[active], value[active]
        has_fix = fix >= 0
        A, Au, Av = _frame(g, xa[:, 0], xa[:, 1])
        B, Bu, Bv = _frame(f, xa[:, 2], xa[:, 3])
        J = np.zeros((m, 4, 4))
        J[:, :3, 0], J[:, :3, 1], J[:, :3, 2], J[:, :3, 3] = Au, Av, -Bu, -Bv
        r = np.empty((m, 4))
        r[:, :3] = A - B
        J[np.flatnonzero(has_fix), 3, fix[has_fix]] = 1.0
        r[has_fix, 3] = xa[has_fix, fix[has_fix]] - val[has_fix]
        if plane is not None and not np.all(has_fix):
            pl = plane[active][~has_fix]
            n = pl[:, 3:]
            J[~has_fix, 3, 0] = np.einsum("ij,ij->i", Au[~has_fix], n)
            J[~has_fix, 3, 1] = np.einsum("ij,ij->i", Av[~has_fix], n)
            r[~has_fix, 3] = np.einsum("ij,ij->i", A[~has_fix] - pl[:, :3], n)
        step = _solve(J, r)
        xa = xa - step
        xa[:, 0], xa[:, 1] = _clip(g, xa[:, 0], xa[:, 1])
        xa[:, 2], xa[:, 3] = _clip(f, xa[:, 2], xa[:, 3])
        x[active] = xa
        moving = np.any(np.abs(step) > t.solver * np.maximum(1.0, np.abs(xa)), axis=1)
        active = active[moving]
    x[:, :2] = _on_sphere_domain(g, x[:, :2], x0[:, :2], boxes[0])
    x[:, 2:] = _on_sphere_domain(f, x[:, 2:], x0[:, 2:], boxes[1])
    A = _frame(g, x[:, 0], x[:, 1])[0]
    B = _frame(f, x[:, 2], x[:, 3])[0]
    return x, A, np.linalg.norm(A - B, axis=1) <= 0.1 * t.linear


def _on_sphere_domain(surface, uv: np.ndarray, seed: np.ndarray, box) -> np.ndarray:
    """A sphere's parameters ``(m, 2)`` with a latitude beyond a pole, and beyond ``box``, brought back.

    Newton's iterates may pass over a pole: ``(u, v)`` and ``(u + π, ±π - v)`` are the same point,
    and a latitude beyond the pole gives p-curves outside the surface's domain (their longitude
    then sweeps wildly).  Rows whose latitude lies outside ``[-π/2, π/2]`` and outside ``box``'s
    latitude range (a face box may reach a little past a pole: such points stay) are reflected;
    every longitude is shifted by whole turns to lie nearest the seed's.  Other surfaces, or
    ``box`` None: ``uv`` unchanged.
    """
    if (box is None or getattr(surface, "surface_type", None) != "sphere"
            or isinstance(surface, (NurbsSurface, _ClosedNurbs))):
        return uv
    uv = uv.copy()
    v = uv[:, 1]
    lo, hi = min(box[1][0], -0.5 * math.pi), max(box[1][1], 0.5 * math.pi)
    beyond = (v < lo) | (v > hi)
    w = np.mod(v + 0.5 * math.pi, 2.0 * math.pi)
    over = beyond & (w > math.pi)
    uv[beyond, 1] = np.where(over, 1.5 * math.pi - w, w - 0.5 * math.pi)[beyond]
    # Near a pole the longitude is nearly free and Newton's steps in it may be turns long.
    u = np.where(over, uv[:, 0] + math.pi, uv[:, 0])
    uv[:, 0] = u + 2.0 * math.pi * np.round((seed[:, 0] - u) / (2.0 * math.pi))
    return uv


def _solve(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``J⁺ r`` for a batch of square systems: LU where regular, the pseudo-inverse where singular."""
    cond_ok = np.abs(np.linalg.det(J)) > 0.0
    out = np.empty(r.shape)
    if np.any(cond_ok):
        try:
            out[cond_ok] = np.linalg.solve(J[cond_ok], r[cond_ok][..., None])[..., 0]
        except np.linalg.LinAlgError:
            cond_ok[:] = False
    if not np.all(cond_ok):
        out[~cond_ok] = np.einsum("mij,mj->mi", np.linalg.pinv(J[~cond_ok]), r[~cond_ok])
    bad = ~np.all(np.isfinite(out), axis=1)
    if np.any(bad):
        out[bad] = np.einsum("mij,mj->mi", np.linalg.pinv(J[bad]), r[bad])
    return out


def _singular_points(g, f, x0: np.ndarray, t: Tolerance) -> np.ndarray:
    """Gauss–Newton on ``G - F = 0, n_G · F_u = n_G · F_v = 0`` from ``x0`` ``(m, 4)``: the iterate of
    lowest residual of each row that reached ``0.1 tol.linear``.

    Central differences give the Jacobian (a step of ``sqrt(tol.solver)`` relative: truncation and
    round-off errors balance near ``tol.solver``).
    """
    x = np.array(x0, dtype=np.float64)

    def residual(xx: np.ndarray) -> np.ndarray:
        A, Au, Av = _frame(g, xx[:, 0], xx[:, 1])
        B, Bu, Bv = _frame(f, xx[:, 2], xx[:, 3])
        n = np.cross(Au, Av)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), np.finfo(float).tiny)
        return np.concatenate(
            [A - B, np.einsum("ij,ij->i", n, Bu)[:, None], np.einsum("ij,ij->i", n, Bv)[:, None]], axis=1
        )

    h = math.sqrt(t.solver)
    active = np.arange(x.shape[0])
    best = np.full(x.shape[0], np.inf)
    since = np.zeros(x.shape[0], dtype=np.int64)
    # The lowest-residual iterate of each row is the answer: at a pole of a parametrisation (a
    # sphere touching a plane at its pole) the steps can alternate between two states.
    lowest, x_low = np.full(x.shape[0], np.inf), x.copy()
    for _ in range(_SINGULAR_ITERATIONS):
        if active.size == 0:
            break
        xa = x[active]
        r = residual(xa)
        # A candidate that is no singular point (a mere local minimum of the normals' sine) sends
        # Gauss–Newton to a positive least-squares minimum: its residual stops shrinking.  Rows
        # whose residual has not fallen by _SINGULAR_GAIN for _SINGULAR_PATIENCE steps are
        # dropped (convergence to a true point, even linear, keeps shrinking it; a converged row
        # has its answer in x_low already).
        res = np.max(np.abs(r), axis=1)
        lower = res < lowest[active]
        lowest[active[lower]], x_low[active[lower]] = res[lower], xa[lower]
        gained = res < _SINGULAR_GAIN * best[active]
        best[active] = np.where(gained, res, best[active])
        since[active] = np.where(gained, 0, since[active] + 1)
        keep = since[active] < _SINGULAR_PATIENCE
        if not np.all(keep):
            active, xa, r = active[keep], xa[keep], r[keep]
            if active.size == 0:
                break
        J = np.empty((active.size, 5, 4))
        for k in range(4):
            hk = h * np.maximum(1.0, np.abs(xa[:, k]))
            xp, xm = xa.copy(), xa.copy()
            xp[:, k] += hk
            xm[:, k] -= hk
            J[:, :, k] = (residual(xp) - residual(xm)) / (2 * hk)[:, None]
        step = np.einsum("mij,mj->mi", np.linalg.pinv(J), r)
        x[active] = xa - step
        active = active[np.any(np.abs(step) > t.solver * np.maximum(1.0, np.abs(xa)), axis=1)]
    res = np.max(np.abs(residual(x)), axis=1)
    lower = res < lowest
    lowest[lower], x_low[lower] = res[lower], x[lower]
    return x_low[lowest <= 0.1 * t.linear]


# ---------------------------------------------------------------------------- sampling
def _grid_lines(lo: float, hi: float, n: int) -> np.ndarray:
    k = np.arange(n + 1, dtype=np.float64)
    s = (k + _GRID_JITTER * np.sin(2.399963 * k) * (k > 0) * (k < n)) / n
    return lo + (hi - lo) * s


def _marching_squares(f: np.ndarray, us: np.ndarray, vs: np.ndarray):
    """Crossings of ``f = 0`` with grid edges and the segments joining them (marching squares).

    Returns
    -------
    uv : (k, 2) crossing parameters (linear interpolation of f along the edge)
    fixed : (k,) 1 for edges along u (v fixed), 0 for edges along v (u fixed)
    edge : (k, 2) the range of the free parameter along each crossing's edge
    ends : (k, 2) flat grid indices of the edge's two vertices
    segments : (s, 2) int, pairs of crossing indices joined inside a cell
    """
    nu, nv = f.shape[0] - 1, f.shape[1] - 1
    pos = f >= 0.0
    cross_h = pos[:-1, :] != pos[1:, :]  # edges (i, j)-(i+1, j), shape (nu, nv+1)
    cross_v = pos[:, :-1] != pos[:, 1:]  # edges (i, j)-(i, j+1), shape (nu+1, nv)
    n_h = nu * (nv + 1)
    ids = np.full(n_h + (nu + 1) * nv, -1, np.int64)
    crossing = np.concatenate([cross_h.ravel(), cross_v.ravel()])
    ids[crossing] = np.arange(int(crossing.sum()))

    ih, jh = np.nonzero(cross_h)
    fh0, fh1 = f[ih, jh], f[ih + 1, jh]
    uh = us[ih] + (us[ih + 1] - us[ih]) * fh0 / (fh0 - fh1)
    iv, jv = np.nonzero(cross_v)
    fv0, fv1 = f[iv, jv], f[iv, jv + 1]
    vv = vs[jv] + (vs[jv + 1] - vs[jv]) * fv0 / (fv0 - fv1)
    uv = np.concatenate([np.stack([uh, vs[jh]], 1), np.stack([us[iv], vv], 1)])
    fixed = np.concatenate([np.ones(ih.size, np.int64), np.zeros(iv.size, np.int64)])
    edge = np.concatenate([np.stack([us[ih], us[ih + 1]], 1), np.stack([vs[jv], vs[jv + 1]], 1)])
    n1 = nv + 1
    ends = np.concatenate(
        [np.stack([ih * n1 + jh, (ih + 1) * n1 + jh], 1), np.stack([iv * n1 + jv, iv * n1 + jv + 1], 1)]
    )

    ci, cj = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    ci, cj = ci.ravel(), cj.ravel()
    # Cell edges: bottom H(i, j), top H(i, j+1), left V(i, j), right V(i+1, j).
    E = np.stack(
        [ids[ci * (nv + 1) + cj], ids[ci * (nv + 1) + cj + 1], ids[n_h + ci * nv + cj], ids[n_h + (ci + 1) * nv + cj]],
        axis=1,
    )
    count = (E >= 0).sum(axis=1)
    two = count == 2
    order = np.argsort(E[two] < 0, axis=1, kind="stable")[:, :2]
    seg2 = np.take_along_axis(E[two], order, axis=1)
    four = count == 4
    bottom, top, left, right = E[four].T
    i4, j4 = ci[four], cj[four]
    centre = f[i4, j4] + f[i4 + 1, j4] + f[i4, j4 + 1] + f[i4 + 1, j4 + 1]
    # If the centre has the sign of corner (i, j), that corner's region runs through the cell and
    # the segments cut off the two other corners.
    joined = (centre >= 0.0) == pos[ci[four], cj[four]]
    s1 = np.where(joined[:, None], np.stack([bottom, right], 1), np.stack([left, bottom], 1))
    s2 = np.where(joined[:, None], np.stack([left, top], 1), np.stack([top, right], 1))
    return uv, fixed, edge, ends, np.concatenate([seg2, s1, s2]).astype(np.int64)


def _chains(k: int, segments: np.ndarray) -> list[tuple[np.ndarray, bool]]:
    """Ordered vertex lists of the components of a graph of maximum degree 2, and whether each is a loop."""
    if k == 0:
        return []
    graph = coo_matrix((np.ones(len(segments)), (segments[:, 0], segments[:, 1])), shape=(k, k)).tocsr()
    graph = graph + graph.T
    degree = np.diff(graph.indptr)
    n_comp, label = connected_components(graph, directed=False)
    out = []
    for c in range(n_comp):
        members = np.flatnonzero(label == c)
        ends = members[degree[members] == 1]
        start = int(ends[0]) if ends.size else int(members[0])
        order = depth_first_order(graph, start, directed=False, return_predecessors=False)
        out.append((order, ends.size == 0 and members.size > 2))
    return out


# ---------------------------------------------------------------------------- box bookkeeping
class _FieldBox:
    """Inside tests and boundary values for the field surface's box (periodic directions modulo a period)."""

    def __init__(self, box: np.ndarray, periods, t: Tolerance, g_periods=(None, None)) -> None:
        self.box = box
        self.lo, self.hi = box[:, 0], box[:, 1]
        self.length = self.hi - self.lo
        self.periods = periods
        #: The grid surface's periods, for shifting inserted points next to their neighbours.
        self.g_periods = g_periods
        # Round-off of the caller's box arithmetic, as basis.check_parameters allows.
        self.slack = t.solver * np.maximum(1.0, self.length)

    def offset(self, y: np.ndarray, k: int) -> np.ndarray:
        """``w = y - lo`` reduced into ``[0, period)`` for periodic directions."""
        w = y - self.lo[k]
        per = self.periods[k]
        return np.mod(w, per) if per is not None else w

    def inside(self, y: np.ndarray) -> np.ndarray:
        ok = np.ones(y.shape[0], bool)
        for k in range(2):
            w = self.offset(y[:, k], k)
            per = self.periods[k]
            if per is not None and self.length[k] >= per - self.slack[k]:
                continue
            near_top = (w <= self.length[k] + self.slack[k])
            if per is not None:
                # Just below lo wraps to just below a period.
                near_top |= w >= per - self.slack[k]
                ok &= near_top
            else:
                ok &= (w >= -self.slack[k]) & near_top
        return ok

    def on_bound(self, y: np.ndarray) -> np.ndarray:
        """``(m,)`` bool: a non-periodic parameter is on (within round-off of) or beyond a bound of the box."""
        out = np.zeros(y.shape[0], bool)
        for k in range(2):
            if self.periods[k] is None:
                out |= (y[:, k] <= self.lo[k] + self.slack[k]) | (y[:, k] >= self.hi[k] - self.slack[k])
        return out

    def seam(self, y0: np.ndarray, y1: np.ndarray) -> np.ndarray:
        """(m, 2) unwrapped seam value ``lo + j period`` crossed between ``y0`` and ``y1``, NaN if none."""
        out = np.full(y0.shape, np.nan)
        for k in range(2):
            per = self.periods[k]
            if per is None or self.length[k] < per - self.slack[k]:
                continue
            j0 = np.floor((y0[:, k] - self.lo[k]) / per)
            j1 = np.floor((y1[:, k] - self.lo[k]) / per)
            out[:, k] = np.where(j0 != j1, self.lo[k] + per * np.maximum(j0, j1), np.nan)
        return out

    def exit(self, y_in: np.ndarray, y_out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direction index and unwrapped boundary value where ``y_in -> y_out`` leaves the box first."""
        frac = np.full(y_in.shape, np.inf)
        target = np.zeros(y_in.shape)
        for k in range(2):
            per = self.periods[k]
            w_in = self.offset(y_in[:, k], k)
            if per is not None and self.length[k] >= per - self.slack[k]:
                continue
            d = y_out[:, k] - y_in[:, k]
            up = y_in[:, k] + (self.length[k] - w_in)
            down = y_in[:, k] - w_in
            if per is None:
                val = np.where(d > 0, up, down)
                beyond = (y_out[:, k] >= self.hi[k] - self.slack[k]) | (y_out[:, k] <= self.lo[k] + self.slack[k])
            else:
                val = np.where(d > 0, up, down)
                beyond = ~self.inside(np.where(np.arange(2) == k, y_out, y_in))
            with np.errstate(divide="ignore", invalid="ignore"):
                fr = np.where(beyond & (d != 0), (val - y_in[:, k]) / d, np.inf)
            frac[:, k] = fr
            target[:, k] = val
        which = np.argmin(frac, axis=1)
        return which, target[np.arange(y_in.shape[0]), which]

    def shift(self, y: np.ndarray) -> np.ndarray:
        """Shift a piece's unwrapped parameters ``(m, 2)`` by whole periods into the box."""
        y = y.copy()
        for k in range(2):
            per = self.periods[k]
            if per is None:
                continue
            mid = 0.5 * (y[:, k].min() + y[:, k].max())
            y[:, k] -= per * np.floor((mid - self.lo[k]) / per)
        return y


# ---------------------------------------------------------------------------- public
def march_intersection(a, b, box_a=None, box_b=None, tol: Tolerance | None = None):
    """The intersection curves of two surfaces inside two parameter boxes (see the module docstring).

    Parameters
    ----------
    a, b : analytic surfaces of :mod:`coons.kernel.analytic` or NurbsSurface
    box_a, box_b : ((u0, u1), (v0, v1)), optional
        Required for unbounded surfaces; default the domain.
    tol : Tolerance, optional

    Returns
    -------
    SurfaceIntersection
        ``curves``: one :class:`~coons.kernel.intersect.IntersectionCurve` per branch piece, a cubic
        3-D NurbsCurve over its chord length ``[0, L]`` with cubic 2-D NURBS p-curves in the same
        parameter; ``points``, ``uv_a``, ``uv_b``: isolated contact points (the surfaces touch
        and separate in every direction around them) and their parameters.

    Raises
    ------
    InvalidInputError
        A missing box for an unbounded surface, a malformed box.

    Examples
    --------
    >>> from coons.kernel.analytic import CylindricalSurface
    >>> a = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    >>> b = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
    >>> r = march_intersection(a, b, ((np.pi / 2, 2.5 * np.pi), (-2, 2)), ((0, 2 * np.pi), (-2, 2)))
    >>> len(r.curves), all(c.tol <= 1e-7 for c in r.curves)
    (2, True)
    """
    from coons.kernel.intersect import IntersectionCurve, SurfaceIntersection

    t = resolve(tol)
    ba = _resolve_box(a, box_a, "march_intersection box_a")
    bb = _resolve_box(b, box_b, "march_intersection box_b")
    b_implicit = hasattr(b, "implicit") and not isinstance(b, NurbsSurface)
    a_implicit = hasattr(a, "implicit") and not isinstance(a, NurbsSurface)
    swap = a_implicit and not b_implicit
    g, f, bg, bf = (b, a, bb, ba) if swap else (a, b, ba, bb)
    g, f = _periodic_view(g, t), _periodic_view(f, t)
    bg, bf = _one_period(bg, surface_periods(g, t)), _one_period(bf, surface_periods(f, t))
    bg, bf = _in_domain(bg, g, "march_intersection"), _in_domain(bf, f, "march_intersection")

    pieces, contacts = _trace(g, f, bg, bf, t)
    curves = []
    for (X, closed), fitted in zip(pieces, _fit_branches(g, f, pieces, bg, bf, t)):
        if fitted is None:
            continue
        curve, pg, pf, length, achieved = fitted
        pa, pb = (pf, pg) if swap else (pg, pf)
        # As in coons.kernel.intersect: a loop cut only at a seam (its p-curve runs from one side of
        # the box to the other) is a closed branch too.
        ends = np.asarray(curve.evaluate(np.array([0.0, length])))
        closed = closed or bool(np.linalg.norm(ends[0] - ends[1]) <= t.linear)
        curves.append(IntersectionCurve(curve, 0.0, length, pa, pb, closed, achieved))
    points = _frame(g, contacts[:, 0], contacts[:, 1])[0] if contacts.shape[0] else np.zeros((0, 3))
    # Periodic parameters of each contact into the boxes, one point at a time (each is its own "piece").
    fbox = _FieldBox(bf, surface_periods(f, t), t)
    contacts = np.array([_shifted(x[None], fbox)[0] for x in contacts]).reshape(-1, 4)
    uv_a, uv_b = (contacts[:, 2:], contacts[:, :2]) if swap else (contacts[:, :2], contacts[:, 2:])
    return SurfaceIntersection(tuple(curves), points, uv_a, uv_b)


def _trace(g, f, bg: np.ndarray, bf: np.ndarray, t: Tolerance) -> tuple[list[tuple[np.ndarray, bool]], np.ndarray]:
    """Steps 1–5: corrected, ordered samples ``(m, 4)`` of every branch piece and whether it is a loop;
    and the parameters ``(k, 4)`` of isolated contact points."""
    us = _grid_lines(bg[0, 0], bg[0, 1], _GRID_CELLS)
    vs = _grid_lines(bg[1, 0], bg[1, 1], _GRID_CELLS)
    U, V = np.meshgrid(us, vs, indexing="ij")
    P = np.asarray(g.evaluate(*_clip(g, U, V))).reshape(-1, 3)
    _, dist = _project(f, P, t)
    fbox = _FieldBox(bf, surface_periods(f, t), t, surface_periods(g, t))
    chains = _coarse_loops(g, f, bg, us, vs, _grid_chains(g, f, us, vs, P, dist, fbox, t), fbox, t)
    seeds = _touch_seeds(dist.reshape(U.shape), P.reshape(U.shape + (3,)), t)
    chains += _small_loops(g, f, bg, us, vs, dist.reshape(U.shape), seeds, chains, fbox, t)
    crossings = _find_singular(g, f, chains, t)
    singular = np.concatenate([crossings, _degenerate_on(g, f, bg, bf, t)])
    return _cut(g, f, chains, singular, fbox, t, (us, vs)), _contacts(g, f, U, V, P, seeds, fbox, crossings, t)


def _grid_chains(g, f, us: np.ndarray, vs: np.ndarray, P: np.ndarray, dist: np.ndarray, fbox: "_FieldBox",
                 t: Tolerance) -> list[list]:
    """Steps 1–2 on one grid: the corrected chains ``[X (m, 4), points (m, 3), inside (m,), loop]``.

    ``P`` ``(nu * nv, 3)`` are ``G`` at the grid vertices ``us × vs`` and ``dist`` their signed
    distances to ``F``.
    """
    uv, fixed, edge, ends, segments = _marching_squares(dist.reshape(us.size, vs.size), us, vs)
    if uv.shape[0] == 0:
        return []
    # Seeds on F: the projections of the crossings.
    Pc = np.asarray(g.evaluate(*_clip(g, uv[:, 0], uv[:, 1])))
    uv_f, _ = _project(f, Pc, t)
    x0 = np.concatenate([uv, uv_f], axis=1)
    value = uv[np.arange(uv.shape[0]), fixed]
    # f is a signed distance (1-Lipschitz in space): a zero on the edge needs |f0| + |f1| <= the
    # edge's length.  Sign flips of a projected distance beyond a NURBS boundary fail this by far;
    # they are not corrected and mark where the branch leaves F (twice the chord covers the arc).
    plausible = np.abs(dist[ends]).sum(axis=1) <= 2.0 * np.linalg.norm(P[ends[:, 0]] - P[ends[:, 1]], axis=1)
    X, pts, ok = x0.copy(), Pc.copy(), np.zeros(uv.shape[0], bool)
    if np.any(plausible):
        X[plausible], pts[plausible], ok[plausible] = _correct(
            g, f, x0[plausible], fixed[plausible], value[plausible], None, t, (None, fbox.box)
        )
    # Newton may land on the same point with other parameters (a period away): back to the seed's.
    X = _near_seed(g, f, X, x0, fbox)
    # A crossing must stay on its edge (f changes sign there, so a root lies on it): where the curve
    # is nearly tangent to a grid line, Newton may reach the other of two close roots, which belongs
    # to a neighbouring edge.  1% of the edge is slack for round-off, far below such a jump.
    free = X[np.arange(X.shape[0]), 1 - fixed]
    margin = 0.01 * (edge[:, 1] - edge[:, 0])
    ok &= (free >= edge[:, 0] - margin) & (free <= edge[:, 1] + margin)
    # A failed crossing keeps its seed (the projection of the grid crossing), not where Newton
    # wandered: only the seed says whether the branch is inside F's box there.  A diverged
    # solution far outside the box would otherwise cut the branch in two.
    X[~ok], pts[~ok] = x0[~ok], Pc[~ok]

    chains = []
    for order, loop in _chains(uv.shape[0], segments):
        Xc, Pc_, okc = X[order], pts[order], ok[order]
        # Unwrap F's periodic parameters along the chain (steps far below half a period).
        for k, per in enumerate(fbox.periods):
            if per is not None:
                Xc[:, 2 + k] = np.unwrap(Xc[:, 2 + k], period=per)
        # A crossing whose Newton failed with F's parameters held on a bound of the box (a NURBS
        # domain clips them there) marks where the branch leaves F: it counts as outside.
        inside = fbox.inside(Xc[:, 2:]) & (okc | ~fbox.on_bound(Xc[:, 2:]))
        keep = okc | ~inside
        if not np.all(keep):
            _log.debug("march_intersection: %d grid crossings did not converge and were skipped", int((~keep).sum()))
        Xc, Pc_, okc, inside = Xc[keep], Pc_[keep], okc[keep], inside[keep] & okc[keep]
        # Coincident successive samples (a crossing at a grid vertex appears on two edges).
        if Xc.shape[0] > 1:
            step = np.linalg.norm(np.diff(Pc_, axis=0), axis=1)
            distinct = np.concatenate([[True], step > t.linear])
            Xc, Pc_, okc, inside = Xc[distinct], Pc_[distinct], okc[distinct], inside[distinct]
        # A sample at the point of the sample two before it: the chain went there and back.  Near a
        # branch's extreme in one parameter a grid line meets it twice within a cell, and Newton may
        # correct both crossings onto one root; the fit would then run the curve back and forth
        # (a trim loop that doubles on itself).  The repeat goes; the extreme's sample between stays.
        while Xc.shape[0] > 2:
            back = np.flatnonzero(np.linalg.norm(Pc_[2:] - Pc_[:-2], axis=1) <= t.linear)
            if back.size == 0:
                break
            keep = np.ones(Xc.shape[0], bool)
            keep[back[0] + 2] = False
            Xc, Pc_, okc, inside = Xc[keep], Pc_[keep], okc[keep], inside[keep]
        if loop and Xc.shape[0] > 2 and np.linalg.norm(Pc_[0] - Pc_[-1]) <= t.linear:
            Xc, Pc_, okc, inside = Xc[:-1], Pc_[:-1], okc[:-1], inside[:-1]
        if Xc.shape[0] > 1 and not np.all(inside):
            Xc, Pc_, inside = _densify_corners(g, f, Xc, Pc_, inside, fbox, t)
        if Xc.shape[0] == 0 or not np.any(inside):
            continue
        # A chain whose samples all lie within tol.linear of its first is no branch: sign flips
        # of f around a vertex where the surfaces touch (f = 0 there counts as positive); left
        # in, it would pass for a crossing and hide the contact point.
        if np.linalg.norm(Pc_ - Pc_[0], axis=1).max() <= t.linear:
            continue
        chains.append([Xc, Pc_, inside, loop and Xc.shape[0] > 2])
    return chains


def _touch_seeds(F: np.ndarray, Q: np.ndarray, t: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid vertices near which the surfaces may touch or cut a loop smaller than a cell: ``(i, j, reach)``.

    The vertices where ``|f|`` (``F`` ``(nu, nv)``) is not above any of their 8 neighbours, all of
    one sign, and no larger than the longest of their grid edges (a touching point or a small loop
    in the neighbouring cells is that close, ``f`` being a signed distance); ``reach`` ``(nu, nv)``
    is that longest edge at every vertex (``Q`` ``(nu, nv, 3)`` the grid points).
    """
    pad = np.pad(np.abs(F), 1, constant_values=np.inf)
    # Signs of the values beyond tol.linear (a vertex on the other surface has no side).
    pos = np.pad(F > t.linear, 1)
    neg = np.pad(F < -t.linear, 1)
    n0, n1 = F.shape
    lowest = np.ones(F.shape, bool)
    any_pos, any_neg = F > t.linear, F < -t.linear
    for di in (-1, 0, 1):  # the 8 neighbours
        for dj in (-1, 0, 1):
            if di == dj == 0:
                continue
            lowest &= np.abs(F) <= pad[1 + di : 1 + di + n0, 1 + dj : 1 + dj + n1]
            any_pos |= pos[1 + di : 1 + di + n0, 1 + dj : 1 + dj + n1]
            any_neg |= neg[1 + di : 1 + di + n0, 1 + dj : 1 + dj + n1]
    same = ~(any_pos & any_neg)
    reach = np.zeros(F.shape)
    du = np.linalg.norm(np.diff(Q, axis=0), axis=2)
    dv = np.linalg.norm(np.diff(Q, axis=1), axis=2)
    reach[:-1] = np.maximum(reach[:-1], du)
    reach[1:] = np.maximum(reach[1:], du)
    reach[:, :-1] = np.maximum(reach[:, :-1], dv)
    reach[:, 1:] = np.maximum(reach[:, 1:], dv)
    i, j = np.nonzero(lowest & same & (np.abs(F) <= reach))
    return i, j, reach


def _contacts(g, f, U, V, P: np.ndarray, seeds, fbox: _FieldBox, singular: np.ndarray,
              t: Tolerance) -> np.ndarray:
    """Isolated points where the surfaces touch without crossing, ``(k, 4)``.

    Seeds are those of :func:`_touch_seeds`.  The Gauss–Newton solve of :func:`_singular_points`
    decides; a solution is an isolated contact when the difference of the two second fundamental
    forms there is definite (the surfaces separate in every direction).  A semi-definite difference
    means the surfaces touch along a curve, which this module does not trace: it is logged.
    Contacts that coincide with singular points of the traced branches are not isolated.
    """
    i, j, reach = seeds
    if i.size == 0:
        return np.zeros((0, 4))
    Q = P.reshape(U.shape + (3,))
    seeds_g = np.stack([U[i, j], V[i, j]], axis=1)
    seeds_f, _ = _project(f, Q[i, j], t)
    xs = _singular_points(g, f, np.concatenate([seeds_g, seeds_f], axis=1), t)
    xs = xs[fbox.inside(xs[:, 2:])]
    if xs.shape[0] == 0:  # (none found, or none inside the boxes)
        return xs
    pts = _frame(g, xs[:, 0], xs[:, 1])[0]
    # Points closer than tol.linear are one point.
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    keep = np.unique(np.argmax(d <= t.linear, axis=1))
    xs, pts = xs[keep], pts[keep]
    if singular.shape[0]:
        sp = _frame(g, singular[:, 0], singular[:, 1])[0]
        far = np.linalg.norm(pts[:, None, :] - sp[None, :, :], axis=2).min(axis=1) > t.linear
        xs, pts = xs[far], pts[far]
    # Normals differenced over a thousandth of the median grid edge: truncation error ~1e-6 relative.
    definite = _separating(g, f, xs, 1e-3 * float(np.median(reach)), t)
    if np.any(~definite):
        _log.warning(
            "march_intersection: the surfaces touch along a curve (%d contact points found, the first at %s); "
            "tangential branches are not traced",
            int((~definite).sum()),
            np.round(pts[~definite][0], 6).tolist(),
        )
    return xs[definite]


# ---------------------------------------------------------------------------- small loops
#: Cells per direction of the local grid laid over a small loop (the loop spans about half of it).
_LOOP_CELLS = 16
#: Newton iterations for a critical point of the signed distance (quadratic convergence from a
#: seed within a cell; the cap only stops a seed that wanders).
_CRITICAL_ITERATIONS = 30
#: Local grids tried per loop, each twice the size of the previous, until its chains close.
_LOOP_ATTEMPTS = 3
#: Loops of the main grid with fewer samples are traced again on a local grid (a cubic through
#: fewer points of a closed curve cannot be trusted to follow it).
_LOOP_MIN_SAMPLES = 8
#: The 9-point stencil of the difference quotients of the signed distance.
_STENCIL = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], np.float64)


def _field_stencil(g, f, x: np.ndarray, h: np.ndarray, t: Tolerance):
    """Signed distance ``f`` of ``G(x)`` to ``F``, its gradient and Hessian in ``G``'s parameters.

    ``x``, ``h`` ``(m, 2)``: points and difference steps.  Central differences (truncation error
    ``O(h²)``) over the 9-point stencil, batched in one projection.  Returns ``(m,)``, ``(m, 2)``,
    ``(m, 2, 2)``.
    """
    q = x[:, None, :] + _STENCIL[None] * h[:, None, :]
    P = np.asarray(g.evaluate(*_clip(g, q[..., 0], q[..., 1]))).reshape(-1, 3)
    F = _project(f, P, t)[1].reshape(q.shape[:2])
    grad = np.stack([(F[:, 1] - F[:, 2]) / (2 * h[:, 0]), (F[:, 3] - F[:, 4]) / (2 * h[:, 1])], axis=1)
    H = np.empty((x.shape[0], 2, 2))
    H[:, 0, 0] = (F[:, 1] - 2 * F[:, 0] + F[:, 2]) / h[:, 0] ** 2
    H[:, 1, 1] = (F[:, 3] - 2 * F[:, 0] + F[:, 4]) / h[:, 1] ** 2
    H[:, 0, 1] = H[:, 1, 0] = (F[:, 5] - F[:, 6] - F[:, 7] + F[:, 8]) / (4 * h[:, 0] * h[:, 1])
    return F[:, 0], grad, H


def _loop_candidates(F: np.ndarray, us: np.ndarray, vs: np.ndarray, i: np.ndarray, j: np.ndarray,
                     t: Tolerance):
    """The seeds ``(i, j)`` where the Hessian of ``f`` from the 3 × 3 grid values is definite, of the
    sign of an extremum away from the other surface (a minimum where ``f > 0``), and not flat.

    A cheap filter for :func:`_small_loops`' Newton solves: surfaces parallel at a distance give
    every vertex as a seed (``|f|`` ties) and a flat ``f``.  Seeds on the grid's boundary are kept
    (no centred differences there).
    """
    nu, nv = F.shape[0] - 1, F.shape[1] - 1
    inner = (i > 0) & (i < nu) & (j > 0) & (j < nv)
    keep = ~inner
    a, b = i[inner], j[inner]
    if a.size:
        hp, hm = us[a + 1] - us[a], us[a] - us[a - 1]
        kp, km = vs[b + 1] - vs[b], vs[b] - vs[b - 1]
        f0 = F[a, b]
        huu = 2 * ((F[a + 1, b] - f0) / hp - (f0 - F[a - 1, b]) / hm) / (hp + hm)
        hvv = 2 * ((F[a, b + 1] - f0) / kp - (f0 - F[a, b - 1]) / km) / (kp + km)
        huv = (F[a + 1, b + 1] - F[a + 1, b - 1] - F[a - 1, b + 1] + F[a - 1, b - 1]) / ((hp + hm) * (kp + km))
        det = huu * hvv - huv**2
        big = 0.5 * np.abs(huu + hvv) + np.hypot(0.5 * (huu - hvv), huv)
        with np.errstate(divide="ignore", invalid="ignore"):
            small = np.where(big > 0, det / big, 0.0)
        # An extremum of f of the right kind (a minimum where f > 0) whose curvature moves f by more
        # than tol.linear across the seed's cells: round-off of a flat f does not.
        span = np.minimum(np.minimum(hp, hm), np.minimum(kp, km))
        keep[inner] = (det > 0) & (np.sign(huu) == np.sign(f0)) & (small * span**2 > t.linear)
    return i[keep], j[keep]


def _loop_extrema(g, f, bg: np.ndarray, x0: np.ndarray, sign: np.ndarray, cell: np.ndarray,
                  t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Extrema of ``f`` inside loops, from seeds ``x0`` ``(m, 2)`` where ``f`` has ``sign`` around them.

    Newton's method on ``∇f = 0`` (difference quotients of :func:`_field_stencil`, steps held
    within ``cell`` ``(2,)``).  An extremum of the other sign than ``sign``, beyond ``tol.linear``
    (a smaller one is a contact), within two cells of its seed, is a loop's: returns its parameters
    ``c`` ``(k, 2)`` and the half-size ``(k, 2)`` of a box twice the quadratic model's ellipse
    ``f(c) + ½ dᵀ H d = 0``, for loops that reach into ``bg``.
    """
    cell = np.broadcast_to(cell, x0.shape)
    # Difference steps a thousandth of a cell: truncation error ~1e-6 of the curvature terms, round-off
    # of f (~1e-15 of the coordinates) amplified by 1/h² stays far below it.
    h = 1e-3 * cell
    sign = np.array(sign, dtype=np.float64)
    x = np.array(x0, dtype=np.float64)
    active = np.flatnonzero(sign != 0)
    for _ in range(_CRITICAL_ITERATIONS):
        if active.size == 0:
            break
        _, grad, H = _field_stencil(g, f, x[active], h[active], t)
        det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] ** 2
        # The extremum sought has the Hessian's sign definite and that of a minimum where f > 0:
        # a seed whose Hessian is not so has no such extremum within reach of this model.
        good = (det > 0) & (np.sign(H[:, 0, 0]) == sign[active])
        safe = np.where(good, det, 1.0)
        step = np.stack([(H[:, 1, 1] * grad[:, 0] - H[:, 0, 1] * grad[:, 1]) / safe,
                         (H[:, 0, 0] * grad[:, 1] - H[:, 0, 1] * grad[:, 0]) / safe], axis=1)
        # Steps held within a cell (trust region of the quadratic model).
        scale = np.minimum(1.0, np.min(cell[active] / np.maximum(np.abs(step), np.finfo(float).tiny), axis=1))
        x[active] -= np.where(good[:, None], scale[:, None] * step, 0.0)
        moving = np.any(np.abs(step) > t.solver * np.maximum(1.0, np.abs(x[active])), axis=1)
        sign[active[~good]] = 0  # given up
        active = active[good & moving]
    found = np.flatnonzero(sign != 0)
    if found.size == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    value, _, H = _field_stencil(g, f, x[found], h[found], t)
    det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] ** 2
    # The extremum of a loop between the vertices lies in a cell next to its seed (the vertex of
    # least |f| around it); one more cell of slack.  Farther ones are other seeds' business.
    near = np.all(np.abs(x[found] - x0[found]) <= 2 * cell[found], axis=1)
    loop = near & (det > 0) & (value * sign[found] < 0) & (np.abs(value) > t.linear)
    c, d, H, det = x[found][loop], value[loop], H[loop], det[loop]
    # Extent of the ellipse f(c) + ½ dᵀ H d = 0 along each parameter: sqrt(2 |f(c)| |(H⁻¹)_kk|).
    inv_diag = np.stack([H[:, 1, 1], H[:, 0, 0]], axis=1) / det[:, None]
    half = 2.0 * np.sqrt(2.0 * np.abs(d)[:, None] * np.abs(inv_diag))
    # The extremum may lie just outside G's box while its loop reaches in (the local grid is
    # clipped to the box; its arcs end on the boundary): only loops clear of the box are dropped.
    meets = np.all((c - half < bg[:, 1]) & (c + half > bg[:, 0]), axis=1)
    return c[meets], half[meets]


def _small_loops(g, f, bg: np.ndarray, us: np.ndarray, vs: np.ndarray, F: np.ndarray, seeds, chains,
                 fbox: "_FieldBox", t: Tolerance) -> list[list]:
    """Chains of the closed loops that lie between the vertices of the grid (step 1b), as :func:`_grid_chains`'.

    Inside a loop the signed distance ``f`` has the other sign than around it, so it has an extremum
    there (a minimum where the grid sees ``f > 0``): near a vertex of :func:`_touch_seeds` (``|f|``
    locally smallest, no sign change around), Newton's method on ``∇f = 0`` (difference quotients,
    steps held within a grid cell) finds that critical point (Patrikalakis–Maekawa §5.8.3: loops
    are detected through the critical points of the distance).  An extremum of the other sign,
    beyond ``tol.linear`` (a smaller one is a contact, :func:`_contacts`' business), means a loop:
    the quadratic model ``f(c) + ½ dᵀ H d = 0`` gives its extent, a local grid of
    :data:`_LOOP_CELLS` cells over twice that is marched like the main one, and enlarged
    (:data:`_LOOP_ATTEMPTS` times) until its chains close.  Loops whose local grid meets a chain of
    the main grid are already traced.
    """
    i, j, _ = seeds
    i, j = _loop_candidates(F, us, vs, i, j, t)
    if i.size == 0:
        return []
    cell = np.array([np.diff(us).max(), np.diff(vs).max()])
    c, half = _loop_extrema(g, f, bg, np.stack([us[i], vs[j]], axis=1), np.sign(F[i, j]), cell, t)
    if c.shape[0] == 0:
        return []
    out: list[list] = []
    for k, found in enumerate(_local_loops(g, f, bg, c, half, chains, fbox, t)):  # loop over loops (a few)
        if found is None:
            _log.debug("march_intersection: no whole loop traced around the extremum of f at %s", c[k].tolist())
            continue
        out.extend(found)
    return out


def _local_loops(g, f, bg: np.ndarray, centre: np.ndarray, half: np.ndarray, chains, fbox: "_FieldBox",
                 t: Tolerance, own=None) -> list[list | None]:
    """Chains traced on local grids around ``centre`` ``(k, 2)`` of half-size ``half`` ``(k, 2)``; one list per centre.

    Each local grid (:data:`_LOOP_CELLS` cells per direction, clipped to ``bg``) is marched like the
    main one and doubled, up to :data:`_LOOP_ATTEMPTS` times, until every chain it finds closes or
    has both ends on ``bg``'s boundary (it is then whole).  ``None`` for a centre whose local grid
    holds samples of ``chains`` or of an earlier centre's (traced already, or too close to another
    branch to be marched alone), or whose chains never came out whole.  ``own`` (optional, one
    ``(m, 2)`` array per centre): samples of the coarse chain being replaced; an empty list for a
    centre whose samples all lie in an earlier centre's successful local grid (one loop that the
    main grid broke into two coarse chains was traced there whole).
    """
    done: list[tuple[np.ndarray, np.ndarray]] = []
    taken = np.concatenate([ch[0][:, :2] for ch in chains]) if chains else np.zeros((0, 2))
    # Round-off of the grid arithmetic: a chain end on a line of bg is on its boundary.
    slack = 1e-9 * (bg[:, 1] - bg[:, 0])

    def whole(ch) -> bool:
        if ch[3]:
            return True
        ends = ch[0][[0, -1], :2]
        return bool(np.all(np.any((np.abs(ends - bg[:, 0]) <= slack) | (np.abs(ends - bg[:, 1]) <= slack), axis=1)))

    half = half.copy()
    out: list[list | None] = []
    for k in range(centre.shape[0]):  # loop over small loops (a few per pair)
        if own is not None and any(np.all((own[k] >= lo) & (own[k] <= hi)) for lo, hi in done):
            out.append([])
            continue
        found = None
        for _attempt in range(_LOOP_ATTEMPTS):
            lo = np.maximum(centre[k] - half[k], bg[:, 0])
            hi = np.minimum(centre[k] + half[k], bg[:, 1])
            if np.any(np.all((taken >= lo) & (taken <= hi), axis=1)):
                break
            lus, lvs = _grid_lines(lo[0], hi[0], _LOOP_CELLS), _grid_lines(lo[1], hi[1], _LOOP_CELLS)
            LU, LV = np.meshgrid(lus, lvs, indexing="ij")
            P = np.asarray(g.evaluate(*_clip(g, LU, LV))).reshape(-1, 3)
            chains_k = _grid_chains(g, f, lus, lvs, P, _project(f, P, t)[1], fbox, t)
            if chains_k and all(whole(ch) for ch in chains_k):
                found = chains_k
                done.append((lo, hi))
                break
            half[k] *= 2.0
        out.append(found)
        if found:
            taken = np.concatenate([taken] + [ch[0][:, :2] for ch in found])
    return out


def _coarse_loops(g, f, bg: np.ndarray, us: np.ndarray, vs: np.ndarray, chains, fbox: "_FieldBox",
                  t: Tolerance) -> list[list]:
    """``chains`` with those of fewer than :data:`_LOOP_MIN_SAMPLES` samples traced again on local grids.

    A loop about one cell across, or an arc dipping into the box for a cell or two, meets few grid
    edges, and a crossing that fails its Newton correction leaves too few samples for the
    interpolation to follow it (the fit folds back, or the chain stops short of the boundary).
    Such a chain is marched again over its parameter box enlarged by a cell on every side; where
    that does not give whole chains (:func:`_local_loops`) the chain is kept as it was.
    """
    coarse = [k for k, ch in enumerate(chains) if ch[0].shape[0] < _LOOP_MIN_SAMPLES]
    if not coarse:
        return chains
    cell = np.array([np.diff(us).max(), np.diff(vs).max()])
    lo = np.array([chains[k][0][:, :2].min(axis=0) for k in coarse])
    hi = np.array([chains[k][0][:, :2].max(axis=0) for k in coarse])
    rest = [ch for k, ch in enumerate(chains) if k not in coarse]
    own = [chains[k][0][:, :2] for k in coarse]
    again = _local_loops(g, f, bg, 0.5 * (lo + hi), 0.5 * (hi - lo) + cell, rest, fbox, t, own)
    for k, found in zip(coarse, again):  # loop over coarse chains (a few)
        if found is None:
            # A loop smaller than the cells of its local grid too: sized by the extremum of f
            # inside it (either sign of f around it), as in _small_loops.
            mid = chains[k][0][:, :2].mean(axis=0)
            c, half = _loop_extrema(g, f, bg, np.array([mid, mid]), np.array([1.0, -1.0]), cell, t)
            if c.shape[0]:
                found = _local_loops(g, f, bg, c[:1], half[:1], rest, fbox, t)[0]
        rest.extend(found if found is not None else [chains[k]])
    return rest


def _separating(g, f, xs: np.ndarray, h: float, t: Tolerance) -> np.ndarray:
    """``(k,)`` bool: at contact points ``xs`` the surfaces separate in every direction.

    The shape operators of both surfaces in a common tangent frame ``(e1, e2)`` come from central
    differences of their normals at the projections of ``X ± h e_i`` (independent of the
    parametrisations, so poles and apexes are no exception); the contact is isolated when their
    difference ``H`` is definite: ``det H > sqrt(tol.angular) |H|²`` (the smaller principal value of
    ``H`` above ``sqrt(tol.angular)`` times the larger; a cylinder lying on a plane gives 0).
    """
    if xs.shape[0] == 0:
        return np.zeros(0, bool)
    X = _frame(g, xs[:, 0], xs[:, 1])[0]
    n = _normals(g, xs[:, 0], xs[:, 1])
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    frame = (e1, e2)
    shape = []
    for surface in (g, f):
        S = np.empty((xs.shape[0], 2, 2))
        for j, e in enumerate(frame):  # the two tangent directions
            Q = np.concatenate([X + h * e, X - h * e])
            uv, _ = _project(surface, Q, t)
            N = _normals(surface, uv[:, 0], uv[:, 1])
            N = N * np.sign(np.einsum("ij,ij->i", N, np.concatenate([n, n])))[:, None]
            dN = (N[: X.shape[0]] - N[X.shape[0] :]) / (2 * h)
            for i, ei in enumerate(frame):
                S[:, i, j] = np.einsum("ij,ij->i", dN, ei)
        shape.append(0.5 * (S + np.swapaxes(S, 1, 2)))
    H = shape[0] - shape[1]
    return np.linalg.det(H) > math.sqrt(t.angular) * np.einsum("kij,kij->k", H, H)


def _degenerate_points(surface) -> np.ndarray:
    """``(k, 3)`` points where the parametrisation of an analytic surface is singular (poles, apex)."""
    kind = getattr(surface, "surface_type", None)
    if kind == "sphere":
        return surface.center + np.array([[1.0], [-1.0]]) * surface.radius * surface.axis
    if kind == "cone":
        return surface.apex[None]
    return np.zeros((0, 3))


def _degenerate_on(g, f, bg: np.ndarray, bf: np.ndarray, t: Tolerance) -> np.ndarray:
    """Parameters ``(k, 4)`` of the degenerate points of either surface that lie on the other.

    A branch through a sphere's pole or a cone's apex is split there: its p-curve on that surface
    jumps (the pole's ``u`` is undetermined), so each side ends with its own limit.
    """
    pts = np.concatenate([_degenerate_points(g), _degenerate_points(f)])
    if pts.shape[0] == 0:
        return np.zeros((0, 4))
    uv_g, dg = _project(g, pts, t)
    uv_f, df = _project(f, pts, t)
    on = (np.abs(dg) <= t.linear) & (np.abs(df) <= t.linear)
    return np.concatenate([uv_g, uv_f], axis=1)[on]


def _find_singular(g, f, chains, t: Tolerance) -> np.ndarray:
    """Singular points ``(s, 4)`` near local minima of ``|n_G × n_F|`` along the chains."""
    cand = []
    for Xc, _, inside, loop in chains:
        n1 = _normals(g, Xc[:, 0], Xc[:, 1])
        n2 = _normals(f, Xc[:, 2], Xc[:, 3])
        s = np.linalg.norm(np.cross(n1, n2), axis=1)
        prev = np.roll(s, 1) if loop else np.concatenate([[np.inf], s[:-1]])
        nxt = np.roll(s, -1) if loop else np.concatenate([s[1:], [np.inf]])
        m = (s <= prev) & (s <= nxt) & (s < _SINGULAR_SINE) & inside
        cand.append(Xc[m])
    cand = np.concatenate(cand) if cand else np.zeros((0, 4))
    if cand.shape[0] == 0:
        return cand
    xs = _singular_points(g, f, cand, t)
    if xs.shape[0] == 0:
        return xs
    pts = _frame(g, xs[:, 0], xs[:, 1])[0]
    # Points closer than tol.linear are one point.
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    first = np.argmax(d <= t.linear, axis=1)
    return xs[np.unique(first)]


#: Bisections of a chain step that passes through F's box between two samples outside it.
_CORNER_BISECTIONS = 10
#: Points per chain step tested against F's box (linear in the parameters).
_CORNER_PROBES = 9


def _densify_corners(g, f, Xc, Pc, inside, fbox: "_FieldBox", t: Tolerance):
    """Samples added where a chain step, both ends outside ``F``'s box, passes through it.

    A branch may cross a corner of the box within one grid cell: no sample lands inside and the
    short piece would be lost (the neighbouring faces' branches then end apart).  Such steps
    (some of :data:`_CORNER_PROBES` points interpolated in ``F``'s parameters inside the box) are
    bisected by Newton in the plane through the chord's midpoint normal to it, up to
    :data:`_CORNER_BISECTIONS` times, until a sample falls inside or the step clears the box.
    """
    s = np.linspace(0.0, 1.0, _CORNER_PROBES)[1:-1]
    for _ in range(_CORNER_BISECTIONS):
        out = ~inside
        cand = np.flatnonzero(out[:-1] & out[1:])
        if cand.size == 0:
            break
        y0, y1 = Xc[cand, 2:], Xc[cand + 1, 2:]
        probes = y0[:, None, :] + s[None, :, None] * (y1 - y0)[:, None, :]
        hit = fbox.inside(probes.reshape(-1, 2)).reshape(cand.size, s.size).any(axis=1)
        cand = cand[hit]
        if cand.size == 0:
            break
        chord = Pc[cand + 1] - Pc[cand]
        if not np.all(np.linalg.norm(chord, axis=1) > t.linear):
            cand = cand[np.linalg.norm(chord, axis=1) > t.linear]
            chord = Pc[cand + 1] - Pc[cand]
            if cand.size == 0:
                break
        D = np.stack([0.5 * (Pc[cand] + Pc[cand + 1]), chord], axis=1)
        Xm, Pm, ok = _correct_on_planes(g, f, D, 0.5 * (Xc[cand] + Xc[cand + 1]), t)
        Xm = _near_seed(g, f, Xm, 0.5 * (Xc[cand] + Xc[cand + 1]), fbox)
        if not np.any(ok):
            break
        cand, Xm, Pm = cand[ok], Xm[ok], Pm[ok]
        Xc = np.insert(Xc, cand + 1, Xm, axis=0)
        Pc = np.insert(Pc, cand + 1, Pm, axis=0)
        inside = np.insert(inside, cand + 1, fbox.inside(Xm[:, 2:]))
    return Xc, Pc, inside


def _near_seed(g, f, X: np.ndarray, x0: np.ndarray, fbox: "_FieldBox") -> np.ndarray:
    """Corrected parameters ``X`` (m, 4) shifted by whole periods to lie nearest the seeds ``x0``.

    Besides the periodic directions of the boxes, a sphere's ``v`` is 2π-periodic as a formula
    (the same point): Newton from a seed near a pole may come back a turn away."""
    X = X.copy()
    per = list(fbox.g_periods + fbox.periods)
    for k, S in ((1, g), (3, f)):
        if getattr(S, "surface_type", None) == "sphere" and not isinstance(S, (NurbsSurface, _ClosedNurbs)):
            per[k] = 2.0 * math.pi
    for j, p in enumerate(per):
        if p is not None:
            X[:, j] += p * np.round((x0[:, j] - X[:, j]) / p)
    return X


def _near(x: np.ndarray, ref: np.ndarray, fbox: _FieldBox) -> np.ndarray:
    """``x`` with its periodic parameters (both surfaces) shifted by whole periods to lie nearest ``ref``."""
    x = x.copy()
    for j, per in enumerate(fbox.g_periods + fbox.periods):
        if per is not None:
            x[j] += per * np.round((ref[j] - x[j]) / per)
    return x


def _split_at_singular(g, f, Xc, Pc, inside, loop, singular, sing_pts, fbox, grid):
    """Replace the sample nearest each singular point on the chain by it; the samples, their flags
    (split there) and inside flags.

    A chain passes through a singular point when its nearest sample is within one chain step of
    it, or lies in the cell of the main grid (``grid = (us, vs)``) that holds the point or in one
    of its 8 neighbours, with nearly parallel normals there (sine below :data:`_SINGULAR_SINE`):
    the segments of a saddle cell may cut its corner, far from the crossing, and two branches
    leaving the point through one edge are invisible on it (no sign change), so the chain turns a
    cell away; a branch merely passing by has no reason to be nearly tangent.

    When that nearest sample ends an open chain a cell away from the point (a point within a cell
    of ``G``'s box boundary: the chain cut the saddle cell's corner from one arm onto another and
    then ran along the other arm back towards the point to the boundary), the chain passes the
    point on its segment nearest to it, not at its end: the point is inserted there, so that the
    arm before it ends at the point and the rest (the other arm, up to the boundary) starts there.
    Replacing the end would instead join the first arm to the point along the second.
    """
    split = np.zeros(Xc.shape[0], bool)
    if Xc.shape[0] < 2 or singular.shape[0] == 0:
        return Xc, split, inside
    seg = np.linalg.norm(np.diff(Pc, axis=0), axis=1)
    closing = float(np.linalg.norm(Pc[0] - Pc[-1])) if loop else 0.0
    before = np.concatenate([[closing], seg])
    after = np.concatenate([seg, [closing]])
    reach = np.maximum(before, after)
    sine = np.linalg.norm(np.cross(_normals(g, Xc[:, 0], Xc[:, 1]), _normals(f, Xc[:, 2], Xc[:, 3])), axis=1)
    Xc = Xc.copy()
    inserts: list[tuple[int, np.ndarray]] = []
    for s in range(singular.shape[0]):  # loop over singular points (a few)
        on_cell = sine < _SINGULAR_SINE
        for k, lines in enumerate(grid):  # the two parameters of G
            per = fbox.g_periods[k]
            y = singular[s, k] if per is None else lines[0] + np.mod(singular[s, k] - lines[0], per)
            i = int(np.clip(np.searchsorted(lines, y) - 1, 0, lines.size - 2))
            lo, width = lines[max(i - 1, 0)], lines[min(i + 2, lines.size - 1)] - lines[max(i - 1, 0)]
            # Round-off of the grid arithmetic (crossings lie on the lines up to it).  No wrapping
            # across a seam: the chain beyond it is another piece, which the point does not end.
            slack = 1e-9 * width
            w = Xc[:, k] - lo + slack
            on_cell &= (w >= 0.0) & (w <= width + 2 * slack)
        # A chain may pass a singular point more than once (it runs along two of its branches).
        d = np.linalg.norm(Pc - sing_pts[s], axis=1)
        prev = np.roll(d, 1) if loop else np.concatenate([[np.inf], d[:-1]])
        nxt = np.roll(d, -1) if loop else np.concatenate([d[1:], [np.inf]])
        for k in np.flatnonzero((d <= prev) & (d < nxt) & ((d <= reach) | on_cell) & inside):
            x = _near(singular[s], Xc[k], fbox)
            # The point's image a period beyond G's box (the chain ends at G's seam next to it)
            # is not on this piece: the piece on the other side of the seam runs through it.
            # (1e-9 of the box: round-off of the grid arithmetic, as above.)
            if not all(lines[0] - 1e-9 * (lines[-1] - lines[0]) <= x[j] <= lines[-1] + 1e-9 * (lines[-1] - lines[0])
                       for j, lines in enumerate(grid)):
                continue
            i = _passing_segment(Pc, sing_pts[s], k, inside) if not loop and d[k] > reach[k] else None
            if i is None:
                Xc[k], split[k] = x, True
            else:
                inserts.append((i + 1, _near(singular[s], Xc[i], fbox)))
    if inserts:
        at = np.array([i for i, _ in inserts])
        Xc = np.insert(Xc, at, np.array([x for _, x in inserts]), axis=0)
        split = np.insert(split, at, True)
        inside = np.insert(inside, at, True)
    return Xc, split, inside


def _passing_segment(Pc: np.ndarray, point: np.ndarray, k: int, inside: np.ndarray) -> int | None:
    """The segment ``(i, i + 1)`` of an open chain ``Pc`` on which it passes ``point``, when its sample
    ``k`` nearest the point is an end of the chain and the segment is not the one ending there (else None).

    The segment nearest the point among the run of segments from that end that pass it no farther than
    the end sample (the chain's approach to the point: a chain that also passes it elsewhere is split
    there separately), with both samples inside ``F``'s box.
    """
    n = Pc.shape[0]
    if k not in (0, n - 1) or n < 3:
        return None
    a, ab = Pc[:-1], np.diff(Pc, axis=0)
    s = np.clip(np.einsum("ij,ij->i", point - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), np.finfo(float).tiny),
                0.0, 1.0)
    dist = np.linalg.norm(a + s[:, None] * ab - point, axis=1)
    order = np.arange(n - 2, -1, -1) if k == n - 1 else np.arange(n - 1)
    # The segment at the end holds the end sample (its distance is the end's up to round-off).
    far = dist[order[1:]] > np.linalg.norm(Pc[k] - point)
    run = order[: 1 + (int(np.argmax(far)) if np.any(far) else far.size)]
    run = run[inside[run] & inside[run + 1]]
    if run.size == 0:
        return None
    i = int(run[np.argmin(dist[run])])
    return None if i == order[0] else i


def _cut(g, f, chains, singular: np.ndarray, fbox: _FieldBox, t: Tolerance,
         grid: tuple[np.ndarray, np.ndarray]) -> list[tuple[np.ndarray, bool]]:
    """Split chains at singular points and where they leave F's box; boundary points by Newton.

    ``grid``: the lines ``(us, vs)`` of the main grid (see :func:`_split_at_singular`).
    """
    sing_pts = _frame(g, singular[:, 0], singular[:, 1])[0] if singular.shape[0] else np.zeros((0, 3))
    pieces: list[tuple[np.ndarray, bool]] = []
    requests: list[tuple[int, str, np.ndarray, np.ndarray]] = []
    for Xc, Pc, inside, loop in chains:  # loop over branches
        Xc, split, inside = _split_at_singular(g, f, Xc, Pc, inside, loop, singular, sing_pts, fbox, grid)
        n = Xc.shape[0]
        virtual = False
        if loop:
            closing = _near(Xc[0], Xc[-1], fbox)
            ring = np.vstack([Xc, closing[None]])
            jump = np.any(np.isfinite(fbox.seam(ring[:-1, 2:], ring[1:, 2:])), axis=1)
            ins = np.append(inside, inside[0])
            cut = (jump & ins[:-1] & ins[1:]) | (ins[:-1] != ins[1:])
            if not np.any(cut) and not np.any(split):
                if np.all(inside):
                    pieces.append((Xc, True))
                continue
            if np.any(cut):
                start = (int(np.flatnonzero(cut)[0]) + 1) % n
                idx = np.concatenate([np.arange(start, n), np.arange(0, start)])
                virtual = True
            else:
                start = int(np.flatnonzero(split)[0])
                idx = np.concatenate([np.arange(start, n), np.arange(0, start + 1)])
            Xc, inside, split = Xc[idx], inside[idx], split[idx]
            for j, per in enumerate(fbox.periods):
                if per is not None:
                    Xc[:, 2 + j] = np.unwrap(Xc[:, 2 + j], period=per)
            n = Xc.shape[0]
        jump = np.any(np.isfinite(fbox.seam(Xc[:-1, 2:], Xc[1:, 2:])), axis=1) & inside[:-1] & inside[1:]
        cut = jump | (inside[:-1] != inside[1:])
        bounds = np.flatnonzero(cut)
        runs = np.stack([np.concatenate([[0], bounds + 1]), np.concatenate([bounds, [n - 1]])], axis=1)
        for r0, r1 in runs:  # loop over the pieces of this branch
            if not inside[r0]:
                continue
            run = np.arange(r0, r1 + 1)
            inner = np.flatnonzero(split[run][1:-1]) + 1 if run.size > 2 else np.zeros(0, np.int64)
            parts = np.split(run, inner)
            # The split sample ends one part and starts the next.
            parts = [np.append(p0, p1[0]) for p0, p1 in zip(parts[:-1], parts[1:])] + [parts[-1]]
            first, last = len(pieces), len(pieces) + len(parts) - 1
            pieces.extend((Xc[part], False) for part in parts)
            if r0 > 0:
                requests.append((first, "start", Xc[r0], Xc[r0 - 1]))
            elif virtual:
                requests.append((first, "start", Xc[0], _near(Xc[-1], Xc[0], fbox)))
            if r1 < n - 1:
                requests.append((last, "end", Xc[r1], Xc[r1 + 1]))
            elif virtual:
                requests.append((last, "end", Xc[-1], _near(Xc[0], Xc[-1], fbox)))
    if requests:
        _add_boundary_points(g, f, pieces, requests, fbox, t)
    return [(_shifted(X, fbox), closed) for X, closed in pieces if X.shape[0] >= 2 or closed]


def _shifted(X: np.ndarray, fbox: _FieldBox) -> np.ndarray:
    X = X.copy()
    X[:, 2:] = fbox.shift(X[:, 2:])
    return X


def _add_boundary_points(g, f, pieces, requests, fbox: _FieldBox, t: Tolerance) -> None:
    """Newton with F's boundary parameter fixed, from the inside sample towards the outside one."""
    m = len(requests)
    rows = np.arange(m)
    x_in = np.array([r[2] for r in requests])
    x_out = np.array([r[3] for r in requests])
    which, target = fbox.exit(x_in[:, 2:], x_out[:, 2:])
    seam = fbox.seam(x_in[:, 2:], x_out[:, 2:])
    has_seam = np.any(np.isfinite(seam), axis=1)
    seam_dir = np.argmax(np.isfinite(seam), axis=1)
    which = np.where(has_seam, seam_dir, which)
    target = np.where(has_seam, seam[rows, seam_dir], target)
    d = x_out[rows, 2 + which] - x_in[rows, 2 + which]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.clip(np.where(d != 0, (target - x_in[rows, 2 + which]) / d, 0.5), 0.0, 1.0)
    x0 = x_in + frac[:, None] * (x_out - x_in)
    X, _, ok = _correct(g, f, x0, 2 + which, target, None, t, (None, fbox.box))
    for i, (slot, end, *_rest) in enumerate(requests):  # loop over cut points (a few per branch)
        if not ok[i]:
            _log.debug("march_intersection: a box boundary point did not converge; the piece ends inside")
            continue
        Xp, closed = pieces[slot]
        Xp = np.vstack([X[i], Xp]) if end == "start" else np.vstack([Xp, X[i]])
        pieces[slot] = (Xp, closed)


# ---------------------------------------------------------------------------- refinement and fit
def _interp(P: np.ndarray, X: np.ndarray, s: np.ndarray) -> BSpline:
    """The 3-D curve and both p-curves interpolating ``P``, ``X[:, :2]``, ``X[:, 2:]`` at ``s``, as one spline of
    seven coordinates.

    One not-a-knot cubic spline interpolation of all seven coordinates (de Boor, *A Practical Guide
    to Splines*, ch. IX; scipy's banded solver), clamped over ``[s[0], s[-1]]``; the refinement
    evaluates it as it is (:func:`_curves` makes the NURBS curves of the accepted one).
    """
    return make_interp_spline(s, np.concatenate([P, X], axis=1), k=min(3, P.shape[0] - 1))


def _curves(c: BSpline) -> tuple[NurbsCurve, NurbsCurve, NurbsCurve]:
    """The 3-D curve and the p-curves on G and F of a spline of :func:`_interp`."""
    U, p = c.t, c.k
    Q = c.c[: U.size - p - 1]
    return NurbsCurve(Q[:, :3], U, p), NurbsCurve(Q[:, 3:5], U, p), NurbsCurve(Q[:, 5:], U, p)


def _points_tangents(c: BSpline, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(values (k, 7), D (k, 2, 3))``: a spline of :func:`_interp` at ``s`` (k,), and its 3-D curve's
    points and first derivatives."""
    values = c(s)
    return values, np.stack([values[:, :3], c(s, 1)[:, :3]], axis=1)


def _determined(g, f, X: np.ndarray, bg: np.ndarray, bf: np.ndarray, t: Tolerance
                ) -> tuple[np.ndarray, np.ndarray]:
    """Undetermined parameters (at a pole or apex) taken from the neighbouring samples of the piece, and
    its periodic parameters moved by whole periods so that the middle of the determined ones is in the box.

    Returns the samples and ``(2, 4)`` bool: the parameters undetermined at the first and the
    last sample (a piece through a singular point is split there, so it is one of its ends),
    which :meth:`_Branch.refit` extrapolates again from the refined samples next to it.
    """
    X = X.copy()
    s = np.arange(X.shape[0], dtype=np.float64)
    ends = np.zeros((2, 4), bool)
    for off, surface, box in ((0, g, bg), (2, f, bf)):
        free = singular_parameters(surface, X[:, off : off + 2], box, t)
        # A piece traced from a singular point (a branch from pole to pole of a sphere) took its turn from
        # the value Newton left for the free parameter there, which may be any: its periodic parameters go
        # by whole periods to where the middle of its determined samples lies in the box.
        for k, per in enumerate(surface_periods(surface, t)):
            lo, hi = (float(x) for x in box[k])
            det = ~free[:, k]
            if per is None or not det.any() or not (math.isfinite(lo) and math.isfinite(hi)):
                continue
            turns = round((0.5 * (lo + hi) - float(np.median(X[det, off + k]))) / per)
            if turns:
                X[:, off + k] += turns * per
        for k in range(2):
            bad = free[:, k]
            if np.any(bad) and not np.all(bad):
                X[bad, off + k] = np.interp(s[bad], s[~bad], X[~bad, off + k])
                ends[:, off + k] = bad[[0, -1]]
    return X, ends


#: Largest ratio of the end chord to the next one over which :meth:`_Branch.refit` extrapolates an
#: undetermined end parameter linearly (beyond it the slope of the next chord says too little).
_END_EXTRAPOLATION = 4.0


class _Branch:
    """Mutable refinement state of one branch piece: samples, their chord parameters and the interpolants."""

    def __init__(self, X: np.ndarray, closed: bool, free_ends: np.ndarray | None = None,
                 box: np.ndarray | None = None) -> None:
        self.X, self.closed = (np.vstack([X, X[:1]]) if closed else X), closed
        # (2, 4) bool: parameters undetermined at the first and last sample (a pole or apex there)
        self.free_ends = None if closed or free_ends is None or not free_ends.any() else free_ends
        # (2, 4) the parameter boxes of both surfaces (rows lo, hi), which extrapolated ends keep to
        self.box = box
        self.done = False
        self.fit = None
        self.err = np.zeros(0)
        self.ok = np.zeros(0, bool)

    def refit(self, g, f, t: Tolerance) -> bool:
        """Drop coincident samples, interpolate in chord length; False if fewer than 2 samples remain."""
        X = self.X
        P = 0.5 * (_frame(g, X[:, 0], X[:, 1])[0] + _frame(f, X[:, 2], X[:, 3])[0])
        step = np.linalg.norm(np.diff(P, axis=0), axis=1)
        keep = np.concatenate([[True], step > t.linear])
        if self.closed and X.shape[0] > 2 and step[-1] <= t.linear:
            keep[-2], keep[-1] = False, True
        X, P = X[keep], P[keep]
        if X.shape[0] < 2:
            return False
        if self.closed:
            P[-1] = P[0]
        if self.free_ends is not None and X.shape[0] >= 3:
            X = _extrapolated_ends(X, P, self.free_ends, self.box)
        self.X = X
        self.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        self.fit = _interp(P, X, self.s)
        return True


def _extrapolated_ends(X: np.ndarray, P: np.ndarray, free: np.ndarray, box: np.ndarray | None = None) -> np.ndarray:
    """Samples ``X`` (m, 4), m >= 3, with the parameters undetermined at an end (``free`` (2, 4), first
    and last sample) extrapolated linearly in chord length (``P`` (m, 3)) from the two samples next to it.

    At a sphere's pole the longitude of a branch through it has a limit, the longitude of the
    branch's tangent there, and the longitude of a sample at distance ``d`` differs from it by
    O(d): copying the nearest sample's value (:func:`_determined`) leaves an error of the size of
    the first chord, which the refinement never sees (in space the whole pole is one point) but
    which makes the p-curve run along the pole in the parameter plane over its last, tiny span
    (the face split then finds it overlapping the pole's segment and misorders the turn there).
    The linear extrapolation is second order; the two nearest samples are the refined ones.  Its
    value is kept in ``box`` (2, 4) (rows lo, hi of both surfaces' parameters, where finite): the limit
    often lies on the box's edge (a seam corner), and a second-order miss must not cross it.
    """
    X = X.copy()
    for row, e, n1, n2 in ((0, 0, 1, 2), (1, -1, -2, -3)):
        cols = np.flatnonzero(free[row])
        if cols.size == 0:
            continue
        d01 = float(np.linalg.norm(P[n1] - P[e]))
        d12 = float(np.linalg.norm(P[n2] - P[n1]))
        if d12 > 0.0 and d01 <= _END_EXTRAPOLATION * d12:
            X[e, cols] = X[n1, cols] + (X[n1, cols] - X[n2, cols]) * (d01 / d12)
            if box is not None:
                lo, hi = box[0, cols], box[1, cols]
                X[e, cols] = np.where(np.isfinite(lo), np.maximum(X[e, cols], lo), X[e, cols])
                X[e, cols] = np.where(np.isfinite(hi), np.minimum(X[e, cols], hi), X[e, cols])
        else:
            X[e, cols] = X[n1, cols]
    return X


def _fit_branches(g, f, pieces, bg: np.ndarray, bf: np.ndarray, t: Tolerance) -> list:
    """Step 6 for all pieces at once: refine by corrected samples until the interpolants agree to tol.linear / 2.

    An interval whose midpoint misses by ``e`` gets ``(2 e / tol.linear)^(1/4)`` new samples (the
    error of a cubic falls with the fourth power of the spacing), so few rounds are needed; the
    Newton corrections of all pieces run as one batch per round.

    Returns one ``(curve, pcurve_g, pcurve_f, length, achieved)`` or ``None`` per piece.
    """
    branches = []
    # rows lo, hi of the four parameters (g's u, v, then f's)
    box = np.array([[bg[0][0], bg[1][0], bf[0][0], bf[1][0]], [bg[0][1], bg[1][1], bf[0][1], bf[1][1]]], dtype=np.float64)
    for X, closed in pieces:
        Xd, ends = _determined(g, f, X, bg, bf, t)
        branches.append(_Branch(Xd, closed, ends, box))
    live = [br for br in branches if br.refit(g, f, t)]
    for br in branches:
        br.done = br.fit is None
    for _ in range(_REFINE_ROUNDS):
        work = [br for br in live if not br.done]
        if not work:
            break
        # Midpoints of every interval of every piece, corrected in one batch.
        sm = [0.5 * (br.s[:-1] + br.s[1:]) for br in work]
        evaluated = [_points_tangents(br.fit, m) for br, m in zip(work, sm)]
        values = np.concatenate([v for v, _ in evaluated])
        D = np.concatenate([d for _, d in evaluated])
        x0 = np.concatenate([0.5 * (br.X[:-1] + br.X[1:]) for br in work])
        Xm, Pm, okm = _correct_on_planes(g, f, D, x0, t, (bg, bf))
        Cm = D[:, 0]
        qg, qf = values[:, 3:5], values[:, 5:]
        Gm = _frame(g, qg[:, 0], qg[:, 1])[0]
        Fm = _frame(f, qf[:, 0], qf[:, 1])[0]
        err = np.max(np.stack([np.linalg.norm(Cm - Pm, axis=1), np.linalg.norm(Gm - Pm, axis=1),
                               np.linalg.norm(Fm - Pm, axis=1)]), axis=0)
        bounds = np.cumsum([0] + [m.size for m in sm])
        new_s, new_x0, new_D, owners = [], [], [], []
        for i, br in enumerate(work):  # loop over pieces
            e, ok = err[bounds[i] : bounds[i + 1]], okm[bounds[i] : bounds[i + 1]]
            br.err, br.ok = e, ok
            bad = ok & (e > 0.5 * t.linear)
            if not np.any(bad) or br.X.shape[0] + int(bad.sum()) > _MAX_BRANCH_SAMPLES:
                br.done = True
                continue
            idx = np.flatnonzero(bad)
            # (one cut more than _fitted_pcurve's ceil(r) - 1: a marched branch's samples are corrected
            # onto both surfaces, and fewer of them made later steps slower, not faster)
            count = np.minimum(np.ceil((e[idx] / (0.5 * t.linear)) ** 0.25), _MAX_SPLIT).astype(np.int64)
            owner, j = interval_cuts(idx, count)
            sn = br.s[owner] + j * (br.s[owner + 1] - br.s[owner])
            new_s.append(sn)
            new_x0.append(br.X[owner] + j[:, None] * (br.X[owner + 1] - br.X[owner]))
            new_D.append(_points_tangents(br.fit, sn)[1])
            owners.append((br, owner))
        if not owners:
            break
        Xn, _, okn = _correct_on_planes(g, f, np.concatenate(new_D), np.concatenate(new_x0), t, (bg, bf))
        nb = np.cumsum([0] + [o.size for _, o in owners])
        for i, (br, owner) in enumerate(owners):  # loop over pieces
            xs, oks = Xn[nb[i] : nb[i + 1]], okn[nb[i] : nb[i + 1]]
            br.X = np.insert(br.X, owner[oks] + 1, xs[oks], axis=0)
            if not br.refit(g, f, t):
                br.done, br.fit = True, None
    out = []
    for br in branches:
        if br.fit is None:
            out.append(None)
            continue
        X = br.X
        res = np.linalg.norm(_frame(g, X[:, 0], X[:, 1])[0] - _frame(f, X[:, 2], X[:, 3])[0], axis=1)
        measured = br.err[br.ok] if br.err.size == br.X.shape[0] - 1 else np.zeros(0)
        if np.any(~br.ok):
            _log.debug("march_intersection: %d branch midpoints did not converge", int((~br.ok).sum()))
        achieved = float(max(res.max(), measured.max() if measured.size else 0.0))
        curve, pg, pf = _curves(br.fit)
        out.append((curve, pg, pf, float(br.s[-1]), achieved))
    return out


def _correct_on_planes(g, f, D: np.ndarray, x0: np.ndarray, t: Tolerance, boxes=(None, None)):
    """Newton from ``x0`` in the planes through ``D[:, 0]`` normal to ``D[:, 1]`` (curve points and tangents)."""
    T = D[:, 1] / np.linalg.norm(D[:, 1], axis=1, keepdims=True)
    m = x0.shape[0]
    return _correct(g, f, x0, np.full(m, -1), np.zeros(m), np.concatenate([D[:, 0], T], 1), t, boxes)


# ---------------------------------------------------------------------------- curve–surface
def intersect_curve_surface(curve, t0: float, t1: float, surface, box=None, tol: Tolerance | None = None):
    """The points where ``curve([t0, t1])`` crosses or touches ``surface`` inside ``box``.

    Sign changes of the signed distance between curve samples, and local minima of its magnitude
    (touching), are refined by Newton's method on ``C(t) - S(u, v) = 0`` (3 × 3, pseudo-inverse steps
    so that touching points converge too); solutions farther than ``tol.linear`` apart are distinct
    (Cohen–Riesenfeld–Elber §18.2, sampling in place of subdivision).  Where the curve lies in the
    surface over a range (successive samples within ``tol.linear``), the ends of that range
    (to the sample spacing) are returned, not its inner points.

    Parameters
    ----------
    curve : 3-D curve with ``evaluate`` and ``derivatives`` (Line, Circle, Ellipse, NurbsCurve)
    t0, t1 : float, ``t0 < t1``
    surface : analytic surface or NurbsSurface
    box : ((u0, u1), (v0, v1)), optional; required for unbounded surfaces
    tol : Tolerance, optional

    Returns
    -------
    t : (k,) float64, increasing
    uv : (k, 2) float64, in ``box`` (periodic parameters shifted by whole periods)
    points : (k, 3) float64, ``curve(t)``

    Raises
    ------
    InvalidInputError
        ``t0 >= t1``, a missing or malformed box.

    Examples
    --------
    >>> from coons.kernel.analytic import Line, SphericalSurface
    >>> s = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    >>> t, uv, p = intersect_curve_surface(Line([-2, 0, 0], [1, 0, 0]), 0.0, 4.0, s)
    >>> np.allclose(t, [1.0, 3.0], rtol=0, atol=1e-12)
    True
    """
    tt = resolve(tol)
    a, b = float(t0), float(t1)
    if not (math.isfinite(a) and math.isfinite(b) and a < b):
        raise InvalidInputError(f"intersect_curve_surface: need finite t0 < t1, got t0={a!r}, t1={b!r}")
    bx = _resolve_box(surface, box, "intersect_curve_surface box")
    n = _CURVE_SAMPLES
    ts = np.linspace(a, b, n + 1)
    if isinstance(curve, NurbsCurve):
        kn = np.unique(curve.knots[(curve.knots > a) & (curve.knots < b)])
        extra = np.linspace(0, 1, _CURVE_SPAN_SAMPLES + 1)[1:-1]
        brk = np.concatenate([[a], kn, [b]])
        ts = np.unique(np.concatenate([ts, kn, (brk[:-1, None] + np.diff(brk)[:, None] * extra).ravel()]))
    P = np.asarray(curve.evaluate(ts))
    uv, dist = _project(surface, P, tt)
    pos = dist >= 0
    i = np.flatnonzero(pos[:-1] != pos[1:])
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = ts[i] + (ts[i + 1] - ts[i]) * dist[i] / (dist[i] - dist[i + 1])
    absd = np.abs(dist)
    prev = np.concatenate([[np.inf], absd[:-1]])
    nxt = np.concatenate([absd[1:], [np.inf]])
    # Where successive samples lie on the surface the curve runs in it: only the ends of such a
    # run are reported (the overlap's ends), not every sample of it.
    on = absd <= tt.linear
    inner = on & np.concatenate([[False], on[:-1]]) & np.concatenate([on[1:], [False]])
    touch = np.flatnonzero((absd <= prev) & (absd <= nxt) & ~inner)
    seeds_t = np.concatenate([tc[~(inner[i] | inner[i + 1])], ts[touch]])
    if seeds_t.size == 0:
        return np.zeros(0), np.zeros((0, 2)), np.zeros((0, 3))
    Ps = np.asarray(curve.evaluate(seeds_t))
    seeds_uv, _ = _project(surface, Ps, tt)
    y = np.concatenate([seeds_t[:, None], seeds_uv], axis=1)
    for _ in range(_NEWTON_ITERATIONS):
        D = np.asarray(curve.derivatives(np.clip(y[:, 0], a, b), 1))
        S, Su, Sv = _frame(surface, y[:, 1], y[:, 2])
        J = np.stack([D[:, 1], -Su, -Sv], axis=2)
        step = np.einsum("mij,mj->mi", np.linalg.pinv(J), D[:, 0] - S)
        y -= step
        y[:, 0] = np.clip(y[:, 0], a, b)
        y[:, 1], y[:, 2] = _clip(surface, y[:, 1], y[:, 2])
        if np.all(np.abs(step) <= tt.solver * np.maximum(1.0, np.abs(y))):
            break
    C = np.asarray(curve.evaluate(y[:, 0]))
    S = _frame(surface, y[:, 1], y[:, 2])[0]
    ok = np.linalg.norm(C - S, axis=1) <= tt.linear
    y, C = y[ok], C[ok]
    periods = surface_periods(surface, tt)
    bx = _one_period(bx, periods)
    fbox = _FieldBox(bx, periods, tt)
    uvs = y[:, 1:].copy()
    for k, per in enumerate(fbox.periods):
        if per is not None:
            uvs[:, k] = bx[k, 0] + fbox.offset(uvs[:, k], k)
    inside = fbox.inside(uvs)
    y, C, uvs = y[inside], C[inside], uvs[inside]
    order = np.argsort(y[:, 0], kind="stable")
    y, C, uvs = y[order], C[order], uvs[order]
    if y.shape[0] > 1:
        # Solutions closer than tol.linear are one point.
        distinct = np.concatenate([[True], np.linalg.norm(np.diff(C, axis=0), axis=1) > tt.linear])
        y, C, uvs = y[distinct], C[distinct], uvs[distinct]
    return y[:, 0], uvs, C
