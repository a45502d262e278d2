"""Hunt for chains of curved B-rep Booleans in special position that fail (issue 5); not a benchmark.

``python benchmarks/hunt_boolean_chains.py --seed 1 --chains 40`` draws chains of 2–4 Booleans
(``+``, ``-``, ``&``) of cylinders, boxes (some turned 30° or 45° about z) and spheres whose
centres lie on a 0.25 grid and whose caps often share the planes ``z = ±1, ±2`` — coplanar caps,
rims crossing at vertices, walls through sphere poles: the special positions where kernels fail.
Each chain runs in coons and in OCCT (build123d on its own primitives); a chain is reported when
coons raises, returns a solid whose ``check`` is not clean, or whose volume differs from OCCT's
(``BRepGProp`` with eps 1e-10) by more than 1e-6 relative.  A difference is refereed by Monte
Carlo on the exact CSG (4e7 points): the verdict says which engine is off by how many standard
errors.  Chains OCCT cannot build (an empty intermediate result) are skipped.  Non-manifold
results raise by design (``"shared by 4 edges"``, ``"not a manifold"``) and are counted apart.
``--chain K`` runs one chain of the seed and prints its recipe.  The fixed cases live in
``tests/booleans/test_solid_regressions.py``.  It is not registered with ``benchmarks/run.py``
(it measures correctness, not speed).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import coons  # noqa: E402
from coons.errors import CoonsError  # noqa: E402

#: One solid of a chain: (kind, size a, height b, x, y, z, turn in degrees about z).
Spec = tuple[str, float, float, float, float, float, float]


def draw(rng: np.random.Generator) -> tuple[list[Spec], list[str]]:
    """One chain: its solids and its operators (one fewer)."""
    n = int(rng.integers(2, 5))
    specs = []
    for _ in range(n):
        kind = str(rng.choice(["cyl", "cyl", "box", "sph"]))
        a = float(rng.choice([1.0, 1.5, 2.0]))
        b = float(rng.choice([2.0, 4.0]))
        x, y = (rng.integers(-4, 5, 2) * 0.25).tolist()
        z = float(rng.choice([0.0, 0.0, 1.0, -1.0]))
        turn = float(rng.choice([0.0, 0.0, 45.0, 30.0])) if kind == "box" else 0.0
        specs.append((kind, a, b, x, y, z, turn))
    return specs, rng.choice(["+", "-", "&"], n - 1).tolist()


def _coons(spec: Spec):
    kind, a, b, x, y, z, turn = spec
    s = coons.Cylinder(a, b) if kind == "cyl" else coons.Box(a, a, b) if kind == "box" else coons.Sphere(a)
    if turn:
        s = s.rotate((0, 0, 0), (0, 0, 1), turn)
    return s.translate((x, y, z))


def _occt(spec: Spec):
    import build123d as bd

    kind, a, b, x, y, z, turn = spec
    s = bd.Cylinder(a, b) if kind == "cyl" else bd.Box(a, a, b) if kind == "box" else bd.Sphere(a)
    return bd.Pos(x, y, z) * bd.Rot(0, 0, turn) * s


def _apply(op: str, a, b):
    return a + b if op == "+" else a - b if op == "-" else a & b


def occt_volume(shape) -> float | None:
    """OCCT's volume (eps 1e-10) of a build123d result, None when it is empty."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    w = getattr(shape, "_wrapped", None)
    if w is None or w.IsNull() or not TopExp_Explorer(w, TopAbs_FACE).More():
        return None
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(w, props, 1e-10)
    return float(props.Mass())


def _inside(spec: Spec, P: np.ndarray) -> np.ndarray:
    kind, a, b, x, y, z, turn = spec
    Q = P - np.array([x, y, z])
    if kind == "sph":
        return (Q * Q).sum(axis=1) <= a * a
    if kind == "cyl":
        return (Q[:, 0] ** 2 + Q[:, 1] ** 2 <= a * a) & (np.abs(Q[:, 2]) <= b / 2)
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    u, v = c * Q[:, 0] + s * Q[:, 1], -s * Q[:, 0] + c * Q[:, 1]
    return (np.abs(u) <= a / 2) & (np.abs(v) <= a / 2) & (np.abs(Q[:, 2]) <= b / 2)


def referee(specs: list[Spec], ops: list[str], points: int = 40_000_000, seed: int = 0) -> tuple[float, float]:
    """Monte Carlo volume of the exact CSG and its standard error (points in the box [-5, 5]² × [-3, 3])."""
    lo, hi = np.array([-5.0, -5.0, -3.0]), np.array([5.0, 5.0, 3.0])
    rng = np.random.default_rng(seed)
    hits, done, batch = 0, 0, 4_000_000
    while done < points:
        P = lo + (hi - lo) * rng.random((batch, 3))
        m = _inside(specs[0], P)
        for op, spec in zip(ops, specs[1:]):
            o = _inside(spec, P)
            m = m | o if op == "+" else m & ~o if op == "-" else m & o
        hits += int(m.sum())
        done += batch
    box, p = float(np.prod(hi - lo)), hits / done
    # (no hit, or all: the standard error is below one point's volume, which stands in for it)
    return box * p, max(box * math.sqrt(p * (1 - p) / done), box / done)


def run_chain(specs: list[Spec], ops: list[str]) -> tuple[str, str]:
    """``(verdict, detail)``: verdict "ok", "skipped", "non-manifold", "raised", "crashed" (an exception
    that is not a coons error), "invalid" or "differs"."""
    c, o = _coons(specs[0]), _occt(specs[0])
    try:
        for op, spec in zip(ops, specs[1:]):
            c = _apply(op, c, _coons(spec))
    except CoonsError as exc:
        text = str(exc)
        if "shared by 4 edges" in text or "not a manifold" in text:
            return "non-manifold", text[:160]
        return "raised", f"{type(exc).__name__}: {text[:300]}"
    except Exception as exc:  # not a coons error: a bug (the hunt goes on and names the chain)
        return "crashed", f"{type(exc).__name__}: {str(exc)[:300]}"
    try:
        for op, spec in zip(ops, specs[1:]):
            o = _apply(op, o, _occt(spec))
        vo = occt_volume(o)
    except Exception as exc:  # build123d on an empty intermediate result
        return "skipped", f"OCCT: {type(exc).__name__}"
    if not c.check().ok:
        return "invalid", c.check().summary()
    vc = 0.0 if c.is_empty else c.volume
    vo = 0.0 if vo is None else vo
    if abs(vc - vo) <= 1e-6 * max(1.0, abs(vo)):
        return "ok", f"{vc:.9g}"
    mc, se = referee(specs, ops)
    return "differs", f"coons {vc:.9g} ({abs(vc - mc) / se:.1f} σ), OCCT {vo:.9g} ({abs(vo - mc) / se:.1f} σ), Monte Carlo {mc:.6g} ± {se:.2g}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--chains", type=int, default=40)
    ap.add_argument("--chain", type=int, default=None, help="run only this chain of the seed and print its recipe")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    counts: dict[str, int] = {}
    for k in range(args.chains):
        specs, ops = draw(rng)
        if args.chain is not None and k != args.chain:
            continue
        verdict, detail = run_chain(specs, ops)
        counts[verdict] = counts.get(verdict, 0) + 1
        if verdict != "ok" or args.chain is not None:
            print(f"seed {args.seed} chain {k} {verdict}: ops {ops} solids {specs}\n    {detail}")
    print(", ".join(f"{v} {n}" for v, n in sorted(counts.items())))
    return 1 if counts.get("raised") or counts.get("invalid") or counts.get("crashed") else 0


if __name__ == "__main__":
    sys.exit(main())
