"""Kernel benchmark: NURBS surface evaluation speed of coons against OCCT, splipy and geomdl.

Two surfaces — (a) a bicubic polynomial B-spline with a 20 × 20 net and clamped uniform
knots, (b) the exact rational torus (biquadratic, 9 × 9 net, knots
``[0,0,0,.25,.25,.5,.5,.75,.75,1,1,1]`` each way, built here from the 9-point circle
with weights ``1, √2/2`` alternating; The NURBS Book §7.5, A8.1) — are evaluated on a
1000 × 1000 tensor grid and at 10^6 scattered random parameters, as points and as
points with both first partials, by

* coons: ``NurbsSurface.evaluate_grid``, ``.derivatives_grid(order=1)`` (or, in a
  coons without it, ``.derivatives`` with broadcast ``u[:, None]``, ``v[None, :]``),
  ``.evaluate`` and ``.derivatives(order=1)``, after an untimed warm-up;
* OCCT 8 through OCP: a ``Geom_BSplineSurface`` built from the same poles, weights,
  knots and multiplicities, evaluated point by point from Python; several per-point
  entry points are probed and the fastest one is timed (OCCT 8's ``GeomGridEval``
  batch evaluator is compiled into TKG3d but has no binding in OCP, see the report);
* splipy: ``Surface(u, v)`` / ``.derivative`` on tensor grids, and with
  ``tensor=False`` for scattered parameters (splipy evaluates the parameter pairs in
  one vectorised call; a per-point loop would be far slower);
* geomdl: its grid evaluator (``Surface.evaluate`` with sample sizes) for grid points,
  ``evaluate_single`` / ``derivatives`` per point otherwise.

Before its rate is reported, every peer's output of the timed run is compared with
coons's at the same parameters (points to 1e-9, derivatives to 1e-9 relative to their
largest magnitude); a disagreement is shown in the table instead of a rate.  The
module does not assert speed, test coons (tests/ does), or tune anything: it measures.
"""

from __future__ import annotations

import math
import time

import numpy as np

from _harness import Report, markdown_table, matmul_gflops, measure, register
from coons.kernel.basis import clamped_uniform_knots
from coons.kernel.surface import NurbsSurface

GRID = 1000  # grid is GRID x GRID
SCATTERED = 1_000_000
WARMUP = 50_000  # points of the untimed first calls
POINT_ATOL = 1e-9  # agreement demanded of every peer, absolute, on O(1) coordinates
DERIV_RTOL = 1e-9  # derivatives: relative to the largest derivative magnitude of the case
TORUS_RADII = (2.0, 0.5)  # major R, minor r
PEERS = ("coons", "OCCT", "splipy", "geomdl")
# The targets, reported (never asserted): coons/OCCT >= 20 everywhere; coons/splipy
# >= 1 on grids and "far ahead" on scattered parameters, read here as >= 10.
TARGET_OCCT = 20.0
TARGET_SPLIPY = {"grid": 1.0, "scattered": 10.0}
CASES = (("grid", 0), ("grid", 1), ("scattered", 0), ("scattered", 1))


# ---------------------------------------------------------------------------- surfaces
def bicubic_surface(n: int = 20, seed: int = 7) -> NurbsSurface:
    """A wavy bicubic B-spline over ``[0, 1]^2``: a regular ``n × n`` net lifted by random heights."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    P = np.stack([x, y, 0.2 * rng.standard_normal((n, n))], axis=-1)
    K = clamped_uniform_knots(n, 3)
    return NurbsSurface(P, K, K, 3, 3)


def torus_surface(R: float = TORUS_RADII[0], r: float = TORUS_RADII[1]) -> NurbsSurface:
    """Exact NURBS torus about the z axis: the 9-point circle revolved by the 9-point circle.

    ``u`` runs round the axis (major radius ``R``), ``v`` round the tube (minor radius ``r``);
    The NURBS Book §7.5 (circle) and A8.1 (surface of revolution).
    """
    s = math.sqrt(0.5)
    c = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float)
    w = np.array([1, s, 1, s, 1, s, 1, s, 1])
    rho = R + r * c[:, 0]  # profile: distance from the axis, height
    z = r * c[:, 1]
    P = np.empty((9, 9, 3))
    P[..., 0] = c[:, None, 0] * rho[None, :]
    P[..., 1] = c[:, None, 1] * rho[None, :]
    P[..., 2] = z[None, :]
    K = np.array([0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1], float)
    return NurbsSurface(P, K, K, 2, 2, np.outer(w, w))


class Problem:
    """A surface and its parameters: ``us, vs`` for the grid, ``u, v`` scattered (seeded)."""

    def __init__(self, name: str, surface: NurbsSurface, seed: int = 11):
        self.name = name
        self.surface = surface
        (u0, u1), (v0, v1) = surface.domain
        self.us = np.linspace(u0, u1, GRID)
        self.vs = np.linspace(v0, v1, GRID)
        rng = np.random.default_rng(seed)
        self.u = rng.uniform(u0, u1, SCATTERED)
        self.v = rng.uniform(v0, v1, SCATTERED)

    def grid_params(self, rows: int) -> tuple[np.ndarray, np.ndarray]:
        """Flat ``u, v`` of the first ``rows`` grid rows, row-major (u outer, v inner)."""
        return np.repeat(self.us[:rows], self.vs.size), np.tile(self.vs, rows)


# ---------------------------------------------------------------------------- runners
class Runner:
    """One peer's way to evaluate one case.

    ``fn(units)`` evaluates the first ``units`` units and returns its raw result;
    ``normalise(raw)`` turns it into ``(N, 3)`` points or ``(N, 3, 3)`` rows ``[S, Su, Sv]``;
    ``options`` go to :func:`_harness.measure`; ``note`` says how the path was chosen.
    """

    def __init__(self, path: str, fn, normalise=lambda x: np.asarray(x, float), note: str = "", **options):
        self.path, self.fn, self.normalise, self.note, self.options = path, fn, normalise, note, options


def _coons_d1(raw: np.ndarray) -> np.ndarray:
    A = raw.reshape(-1, 2, 2, raw.shape[-1])
    return np.stack([A[:, 0, 0], A[:, 1, 0], A[:, 0, 1]], axis=1)


def coons_runners(pb: Problem) -> dict:
    s, us, vs, u, v = pb.surface, pb.us, pb.vs, pb.u, pb.v
    full = {"full_budget": math.inf}
    # Untimed warm-up at a batch size that takes every path coons has (a JIT compiles on first use).
    s.evaluate(u[:WARMUP], v[:WARMUP])
    s.derivatives(u[:WARMUP], v[:WARMUP], 1)
    s.evaluate_grid(us[:16], vs)
    if hasattr(s, "derivatives_grid"):
        grid_d1 = Runner("NurbsSurface.derivatives_grid(us, vs, 1)",
                         lambda k: s.derivatives_grid(us[:k], vs, 1), _coons_d1, **full)
    else:  # coons before derivatives_grid: broadcast parameters through the scattered path
        grid_d1 = Runner("NurbsSurface.derivatives(u[:, None], v[None, :], 1)",
                         lambda k: s.derivatives(us[:k, None], vs[None, :], 1), _coons_d1, **full)
    return {
        ("grid", 0): Runner("NurbsSurface.evaluate_grid", lambda k: s.evaluate_grid(us[:k], vs),
                            lambda x: x.reshape(-1, x.shape[-1]), **full),
        ("grid", 1): grid_d1,
        ("scattered", 0): Runner("NurbsSurface.evaluate", lambda n: s.evaluate(u[:n], v[:n]), **full),
        ("scattered", 1): Runner("NurbsSurface.derivatives(u, v, 1)",
                                 lambda n: s.derivatives(u[:n], v[:n], 1), _coons_d1, **full),
    }


def to_occt(surface: NurbsSurface):
    """``Geom_BSplineSurface`` with the same poles, weights, knots and multiplicities (not timed)."""
    from OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    nu, nv = surface.shape
    poles = Array2_gp_Pnt(1, nu, 1, nv)
    weights = Array2_double(1, nu, 1, nv)
    for i in range(nu):
        for j in range(nv):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*map(float, surface.control_points[i, j])))
            weights.SetValue(i + 1, j + 1, float(surface.weights[i, j]))

    def knots(U):
        vals, mults = np.unique(U, return_counts=True)
        K, M = Array1_double(1, len(vals)), Array1_int(1, len(vals))
        for i, (k, m) in enumerate(zip(vals, mults)):
            K.SetValue(i + 1, float(k))
            M.SetValue(i + 1, int(m))
        return K, M

    Ku, Mu = knots(surface.knots_u)
    Kv, Mv = knots(surface.knots_v)
    if surface.is_rational:
        return Geom_BSplineSurface(poles, weights, Ku, Kv, Mu, Mv, surface.degree_u, surface.degree_v)
    return Geom_BSplineSurface(poles, Ku, Kv, Mu, Mv, surface.degree_u, surface.degree_v)


def _occt_d0(method):
    from OCP.gp import gp_Pnt

    def run(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        p = gp_Pnt()
        coord = p.Coord

        def one(a, b):
            method(a, b, p)
            return coord()

        return np.array(list(map(one, u.tolist(), v.tolist())))

    return run


def _occt_value(method):
    def run(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.array([p.Coord() for p in map(method, u.tolist(), v.tolist())])

    return run


def _occt_d1(method):
    from OCP.gp import gp_Pnt, gp_Vec

    def run(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
        cp, cu, cv = p.Coord, du.Coord, dv.Coord

        def one(a, b):
            method(a, b, p, du, dv)
            return cp(), cu(), cv()

        return np.array(list(map(one, u.tolist(), v.tolist())))

    return run


def occt_variants(pb: Problem) -> dict[int, dict[str, object]]:
    """Per-point OCCT entry points by derivative order: name -> ``run(u, v) -> array``."""
    from OCP.GeomAdaptor import GeomAdaptor_Surface

    g = to_occt(pb.surface)
    a = GeomAdaptor_Surface(g)
    return {
        0: {
            "Geom_BSplineSurface.D0 (reused gp_Pnt)": _occt_d0(g.D0),
            "Geom_BSplineSurface.EvalD0": _occt_value(g.EvalD0),
            "Geom_BSplineSurface.Value": _occt_value(g.Value),
            "GeomAdaptor_Surface.D0 (span cache, reused gp_Pnt)": _occt_d0(a.D0),
        },
        1: {
            "Geom_BSplineSurface.D1 (reused gp_Pnt/gp_Vec)": _occt_d1(g.D1),
            "GeomAdaptor_Surface.D1 (span cache, reused gp_Pnt/gp_Vec)": _occt_d1(a.D1),
        },
    }


def occt_runners(pb: Problem) -> dict:
    variants = occt_variants(pb)
    out = {}
    for layout, order in CASES:
        if layout == "grid":
            fns = {name: (lambda k, f=f: f(*pb.grid_params(k))) for name, f in variants[order].items()}
            probe = max(1, 20_000 // GRID)
        else:
            fns = {name: (lambda n, f=f: f(pb.u[:n], pb.v[:n])) for name, f in variants[order].items()}
            probe = 20_000
        # The fastest per-point entry point on a probe of ~2e4 points (best of 2) is the one timed.
        times = {}
        for name, fn in fns.items():
            best = math.inf
            for _ in range(2):
                t0 = time.perf_counter()
                fn(probe)
                best = min(best, time.perf_counter() - t0)
            times[name] = best
        name = min(times, key=times.get)
        per_point = probe * (GRID if layout == "grid" else 1)
        note = ", ".join(f"{k.split(' (')[0]} {1e9 * t / per_point:.0f}"
                         for k, t in sorted(times.items(), key=lambda kv: kv[1]))
        runner = Runner(name, fns[name], note=f"OCCT entry points probed, ns per point: {note}")
        out[(layout, order)] = runner
    return out


def to_splipy(surface: NurbsSurface):
    from splipy import BSplineBasis, Surface

    bu = BSplineBasis(order=surface.degree_u + 1, knots=surface.knots_u.tolist())
    bv = BSplineBasis(order=surface.degree_v + 1, knots=surface.knots_v.tolist())
    net = surface.homogeneous if surface.is_rational else surface.control_points
    # splipy reads a flat list of control points with the first direction varying fastest.
    cps = np.ascontiguousarray(net.transpose(1, 0, 2)).reshape(-1, net.shape[2])
    return Surface(bu, bv, cps, rational=surface.is_rational)


def splipy_runners(pb: Problem) -> dict:
    sp = to_splipy(pb.surface)
    us, vs, u, v = pb.us, pb.vs, pb.u, pb.v

    def d1(a, b, tensor):
        return np.stack(
            [sp(a, b, tensor=tensor), sp.derivative(a, b, d=(1, 0), tensor=tensor),
             sp.derivative(a, b, d=(0, 1), tensor=tensor)],
            axis=-2,
        )

    flat = lambda x: x.reshape(-1, x.shape[-1])  # noqa: E731
    flat_d1 = lambda x: x.reshape(-1, 3, x.shape[-1])  # noqa: E731
    return {
        ("grid", 0): Runner("Surface(us, vs) (tensor)", lambda k: sp(us[:k], vs), flat),
        ("grid", 1): Runner("Surface(us, vs) + .derivative(d=(1,0)), (0,1) (tensor)",
                            lambda k: d1(us[:k], vs, True), flat_d1),
        ("scattered", 0): Runner("Surface(u, v, tensor=False)", lambda n: sp(u[:n], v[:n], tensor=False), flat),
        ("scattered", 1): Runner("Surface(u, v, tensor=False) + .derivative(..., tensor=False) x2",
                                 lambda n: d1(u[:n], v[:n], False), flat_d1),
    }


def to_geomdl(surface: NurbsSurface):
    from geomdl import BSpline, NURBS

    nu, nv = surface.shape
    if surface.is_rational:
        g = NURBS.Surface()
        pts = surface.homogeneous  # geomdl's NURBS takes weighted points [w x, w y, w z, w]
    else:
        g = BSpline.Surface()
        pts = surface.control_points
    g.degree_u, g.degree_v = surface.degree_u, surface.degree_v
    g.set_ctrlpts(pts.reshape(-1, pts.shape[2]).tolist(), nu, nv)  # v varies fastest
    g.knotvector_u = surface.knots_u.tolist()
    g.knotvector_v = surface.knots_v.tolist()
    return g


def geomdl_runners(pb: Problem) -> dict:
    g = to_geomdl(pb.surface)

    def grid_points(k: int) -> np.ndarray:
        g.sample_size_u, g.sample_size_v = k, pb.vs.size
        g.evaluate(start_u=pb.us[0], stop_u=pb.us[k - 1], start_v=pb.vs[0], stop_v=pb.vs[-1])
        return np.array(g.evalpts)

    def points(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.array([g.evaluate_single(t) for t in zip(u.tolist(), v.tolist())])

    def d1(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = []
        for a, b in zip(u.tolist(), v.tolist()):
            S = g.derivatives(a, b, order=1)
            out.append((S[0][0], S[1][0], S[0][1]))
        return np.array(out)

    # geomdl's grid evaluator needs two rows at least (one row collapses its linspace).
    return {
        ("grid", 0): Runner("Surface.evaluate (its grid evaluator)", grid_points, probe_points=2 * GRID),
        ("grid", 1): Runner("Surface.derivatives per point", lambda k: d1(*pb.grid_params(k))),
        ("scattered", 0): Runner("Surface.evaluate_single per point", lambda n: points(pb.u[:n], pb.v[:n])),
        ("scattered", 1): Runner("Surface.derivatives per point", lambda n: d1(pb.u[:n], pb.v[:n])),
    }


# ---------------------------------------------------------------------------- the run
def _agreement(got: np.ndarray, ref: np.ndarray, order: int) -> float:
    """Max abs difference, scaled for derivatives by their largest magnitude (1 at least)."""
    if got.shape != ref.shape:
        return math.inf
    err = np.abs(got - ref)
    if order == 0:
        return float(err.max())
    return float(err.max() / max(1.0, float(np.abs(ref[:, 1:]).max())))


def _gemm_flops(pb: Problem) -> float:
    """Flops of the two-stage grid contraction, counting the v stage as dense (as the brief does)."""
    nu, nv = pb.surface.shape
    D = pb.surface.dimension + (1 if pb.surface.is_rational else 0)
    a, b = pb.us.size, pb.vs.size
    return 2.0 * nv * nu * b * D + 2.0 * a * nu * b * D


def _case_label(pb: Problem, layout: str, order: int) -> str:
    where = f"grid {GRID}×{GRID}" if layout == "grid" else f"scattered {SCATTERED:.0e}".replace("+0", "")
    return f"{pb.name}, {where}, {'points + D1' if order else 'points'}"


def _fmt(x: float) -> str:
    if not math.isfinite(x):
        return "–"
    return f"{x:.3g}" if x < 1000 else f"{x:.0f}"


def _torus_residual(pts: np.ndarray, R: float, r: float) -> float:
    """Largest distance of ``(N, 3)`` points from the torus of radii ``R, r`` about the z axis."""
    rho = np.hypot(pts[:, 0], pts[:, 1])
    return float(np.abs(np.hypot(rho - R, pts[:, 2]) - r).max())


def _coons_compiled_path() -> str:
    """Whether coons's optional compiled kernels (numba) serve large scattered batches in this run."""
    try:
        from coons.kernel import _accel
    except ImportError:
        return "none in this coons (numpy only)."
    if getattr(_accel, "AVAILABLE", False):
        return (f"numba kernels for scattered batches of ≥ {getattr(_accel, 'THRESHOLD', '?')} points "
                "(set COONS_NO_NUMBA=1 to time the numpy path); grids stay on numpy/BLAS.")
    return "numba not available or disabled (COONS_NO_NUMBA): numpy only."


def _measure_case(pb: Problem, runners: dict, layout: str, order: int, gflops: float) -> dict:
    """Time every peer on one case, gate it on agreement with coons, and collect the report lines."""
    label = _case_label(pb, layout, order)
    units_full, ppu = (GRID, GRID) if layout == "grid" else (SCATTERED, 1)
    out = {"rates": {}, "details": [], "notes": [], "failures": [], "missed": []}
    ref = None
    for peer in PEERS:
        rn = runners[peer][(layout, order)]
        m, raw, _ = measure(rn.fn, units_full, ppu, path=rn.path, **rn.options)
        got = rn.normalise(raw)
        del raw
        if peer == "coons":
            ref, err = got, 0.0
            if pb.surface.is_rational and order == 0:
                res = _torus_residual(got, *TORUS_RADII)
                out["notes"].append(f"{label}: coons points lie on the torus to {res:.1e}.")
            if (layout, order) == ("grid", 0):
                flops = _gemm_flops(pb)
                achieved = flops / m.seconds / 1e9
                out["notes"].append(
                    f"{label}: coons reaches {achieved:.1f} GFLOP/s on the two-stage contraction "
                    f"({flops / 1e6:.0f} Mflop, v stage counted dense), "
                    f"{100 * achieved / gflops:.0f} % of this machine's matmul rate."
                )
        else:
            err = _agreement(got, ref[: got.shape[0]], order)
        del got
        if rn.note:
            out["notes"].append(f"{label}: {rn.note}.")
        ok = err <= (POINT_ATOL if order == 0 else DERIV_RTOL)
        if not ok:
            out["failures"].append(f"{label}: {peer} disagrees with coons by {err:.2e}")
        out["rates"][peer] = m.mpoints_per_s if ok else math.nan
        out["details"].append([
            label, peer, m.path, f"{m.points:,}" + ("" if m.full else " (subsample)"), str(m.reps),
            f"{m.seconds:.4g}", "reference" if peer == "coons" else f"{err:.1e}",
        ])
    rates = out["rates"]
    c = rates["coons"]
    for peer, target in (("OCCT", TARGET_OCCT), ("splipy", TARGET_SPLIPY[layout])):
        ratio = c / rates[peer]
        if not ratio >= target:
            out["missed"].append(f"{label}: coons/{peer} = {_fmt(ratio)} (target ≥ {target:g})")
    out["row"] = (
        [label]
        + [_fmt(rates[p]) if math.isfinite(rates[p]) else "mismatch" for p in PEERS]
        + [_fmt(c / rates["OCCT"]), _fmt(c / rates["splipy"])]
    )
    return out


@register(
    "kernel",
    "NURBS surface evaluation (grid / scattered, points / D1): coons vs OCCT, splipy, geomdl",
    versions=("cadquery-ocp-novtk", "splipy", "geomdl", "threadpoolctl", "numba"),
)
def run() -> Report:
    problems = [Problem("bicubic 20×20", bicubic_surface()), Problem("rational torus 9×9", torus_surface())]
    gflops = matmul_gflops()
    results = []
    for pb in problems:
        runners = {
            "coons": coons_runners(pb),
            "OCCT": occt_runners(pb),
            "splipy": splipy_runners(pb),
            "geomdl": geomdl_runners(pb),
        }
        results += [_measure_case(pb, runners, layout, order, gflops) for layout, order in CASES]
    collect = lambda key: [x for r in results for x in r[key]]  # noqa: E731
    failures, missed = collect("failures"), collect("missed")

    main = "Rates in Mpoints/s (a point with D1 counts once); higher is better.\n\n" + markdown_table(
        ["case", "coons", "OCCT", "splipy", "geomdl", "coons/OCCT", "coons/splipy"], [r["row"] for r in results]
    )
    targets = (
        f"## Against the targets\n\nTargets: coons/OCCT ≥ {TARGET_OCCT:g}; coons/splipy ≥ "
        f"{TARGET_SPLIPY['grid']:g} on grids and ≥ {TARGET_SPLIPY['scattered']:g} on scattered parameters. "
        + ("Missed:\n\n" + "\n".join(f"- {m}" for m in missed) if missed else "All met.")
    )
    ctx = [
        f"- numpy matmul 2000×2000 float64: {gflops:.1f} GFLOP/s (best of 3).",
        f"- coons compiled path: {_coons_compiled_path()}",
        "- coons: a grid with D1 goes through `derivatives_grid` (or, in a coons without it, "
        "`derivatives` on broadcast parameters).",
        "- OCCT: per-point calls from Python into OCP, coordinates collected into a numpy array "
        "(inputs converted with .tolist(), output with np.array, both timed). OCCT 8.0.1 ships "
        "`GeomGridEval_*` batch evaluators in TKG3d, but OCP 8.0.1.1 binds no `GeomGridEval` module "
        "(and `EvalD1` returns an unbound `Geom_Surface::ResD1`), so the fastest path reachable "
        "from Python is the fastest per-point entry point, picked per case on a probe of 2e4 points.",
        "- splipy: `tensor=False` evaluates parameter pairs in one vectorised call; "
        "D1 is three calls (point, ∂u, ∂v).",
        "- geomdl: pure Python; grid points use its own grid evaluator, everything else per point.",
        "- Full problems: best of ≥ 3 runs (more, up to 20, while they add up to about 1 s). "
        "Subsamples: a peer whose full problem would take > 1.5 s is timed on the first grid rows "
        "or scattered points, grown until its best of 2 runs takes ≥ 0.5 s.",
        f"- Agreement gate: points within {POINT_ATOL:g} of coons's, derivatives within {DERIV_RTOL:g} "
        "relative to the case's largest derivative.",
        *[f"- {n}" for n in collect("notes")],
    ]
    detail = "## How each number was taken\n\n" + markdown_table(
        ["case", "peer", "path", "points timed", "runs (best of)", "best s", "max Δ vs coons"], collect("details")
    )
    sections = [main, targets, "## Context\n\n" + "\n".join(ctx), detail]
    if failures:
        sections.insert(
            1, "## Disagreements (these cells carry no rate)\n\n" + "\n".join(f"- {f}" for f in failures)
        )
    return Report("Kernel benchmark: NURBS surface evaluation", sections, failed=bool(failures))
