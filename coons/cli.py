"""The ``coons`` command line.

Subcommands:

``coons demo [--out DIR]``
    Builds exact NURBS geometry (a rational circle, an interpolated space curve,
    a bicubic patch, an exact rational torus), checks a few closed forms, and writes
    ``DIR/kernel.png`` (a plot of the curves and surfaces), ``DIR/torus.stl`` and, from the
    B-rep layer, ``DIR/plate.stl``: an extruded plate with holes, checked and measured exactly.

``coons validate [CASES...] [--report DIR] [--jobs N] [--scheduler ADDR] [--list] [--timeout S] [--json FILE]``
    Runs reference cases (:mod:`coons.validation`) through coons, OCCT (build123d) and
    manifold3d, prints a table, optionally writes an HTML report with pictures.  Case names may be
    glob patterns; none means the whole catalogue.  Exit status 1 when coons is wrong or invalid
    on some case (or raised an untyped exception, or hung or crashed while running).

``coons convert IN OUT``
    STEP or STL in, STEP or STL out (by file suffix).  An STL is read as a closed triangle mesh
    (coplanar neighbours merged into polygon faces).

``coons info FILE``
    Volume, area, bounding box, counts and validity of each solid of a STEP or STL file.

Usage errors (a bad argument, an unknown case, a file that cannot be read) print one line
``coons: error: ...`` on stderr and exit with status 2.  Reference engines, matplotlib and
Dask are imported lazily, only by the subcommands that need them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from coons.errors import CoonsError

__all__ = ["main"]


def _grid_mesh(points, closed_u: bool, closed_v: bool):
    """Triangles of a sampled surface grid ``(a, b, 3)``, welding the last row/column onto the first when closed."""
    import numpy as np

    a, b = points.shape[:2]
    na = a - 1 if closed_u else a
    nb = b - 1 if closed_v else b
    V = points[:na, :nb].reshape(-1, 3)
    i, j = np.meshgrid(np.arange(a - 1), np.arange(b - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()

    def vid(ii, jj):
        return (ii % na) * nb + (jj % nb)

    v00, v10, v01, v11 = vid(i, j), vid(i + 1, j), vid(i, j + 1), vid(i + 1, j + 1)
    T = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return V, T


def _demo(out: Path) -> int:
    import numpy as np

    from coons.io.stl import export_stl
    from coons.kernel import conics, fitting
    from coons.kernel.surface import NurbsSurface

    out.mkdir(parents=True, exist_ok=True)
    circle = conics.nurbs_circle([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 2.0)
    t = np.linspace(0.0, 4.0 * np.pi, 25)
    helix_pts = np.stack([np.cos(t), np.sin(t), 0.15 * t], axis=1)
    helix = fitting.interpolate_curve(helix_pts, degree=3)
    rng = np.random.default_rng(7)
    xs = np.linspace(-3.0, 3.0, 6)
    net = np.stack(np.meshgrid(xs, xs, indexing="ij"), axis=-1)
    net = np.concatenate([net, rng.uniform(-0.6, 0.6, (6, 6, 1))], axis=-1)
    knots = [0, 0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1, 1]
    patch = NurbsSurface(net, knots, knots, 3, 3)
    torus = conics.nurbs_torus([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 3.0, 1.0)

    # Closed forms the demo checks before it draws anything.
    s = np.linspace(*circle.domain, 721)
    radius_error = float(np.abs(np.linalg.norm(circle.evaluate(s), axis=1) - 2.0).max())
    us = np.linspace(*torus.domain_u, 121)
    vs = np.linspace(*torus.domain_v, 61)
    T = torus.evaluate_grid(us, vs)
    rho = np.hypot(T[..., 0], T[..., 1])
    torus_error = float(np.abs(np.hypot(rho - 3.0, T[..., 2]) - 1.0).max())
    helix_error = float(np.abs(helix.evaluate(fitting.parametrize(helix_pts)) - helix_pts).max())
    print(f"circle radius error {radius_error:.2e}, torus distance error {torus_error:.2e}, "
          f"helix interpolation error {helix_error:.2e}")

    V, F = _grid_mesh(T, closed_u=True, closed_v=True)
    stl = export_stl((V, F), out / "torus.stl")

    # A B-rep part: a plate with four round holes, exact faces, checked, measured, meshed.
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude
    from coons.topology.tessellate import tessellate

    plate = Profile.rectangle(8.0, 6.0)
    for cx, cy in ((-2.5, -1.5), (2.5, -1.5), (-2.5, 1.5), (2.5, 1.5)):
        plate = plate.with_hole(Profile.circle(0.8, center=(cx, cy)))
    part = extrude(plate, 1.5)
    exact_volume = (8.0 * 6.0 - 4 * np.pi * 0.8**2) * 1.5
    report = part.check()
    print(f"plate with holes: {len(part.faces())} faces, valid={report.ok}, volume {part.volume:.12f} "
          f"(exact {exact_volume:.12f}, relative error {abs(part.volume / exact_volume - 1):.1e})")
    mesh = tessellate(part, deflection=0.01)
    part_stl = export_stl(mesh, out / "plate.stl")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - matplotlib ships with the dev extra
        print("matplotlib is not installed: skipping kernel.png (pip install 'coons[plot]')")
        print(f"wrote {stl} and {part_stl}")
        return 0
    fig = plt.figure(figsize=(16, 4.5))
    ax = fig.add_subplot(1, 4, 1, projection="3d")
    c = circle.evaluate(s)
    h = helix.evaluate(np.linspace(*helix.domain, 400))
    ax.plot(c[:, 0], c[:, 1], c[:, 2], label="rational circle")
    ax.plot(h[:, 0], h[:, 1], h[:, 2], label="interpolated helix")
    ax.scatter(*helix_pts.T, s=6, c="k")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title("curves")
    ax = fig.add_subplot(1, 4, 2, projection="3d")
    g = np.linspace(0.0, 1.0, 40)
    P = patch.evaluate_grid(g, g)
    ax.plot_surface(P[..., 0], P[..., 1], P[..., 2], cmap="viridis", linewidth=0)
    ax.plot_wireframe(net[..., 0], net[..., 1], net[..., 2], color="k", linewidth=0.4)
    ax.set_title("bicubic patch and control net")
    ax = fig.add_subplot(1, 4, 3, projection="3d")
    ax.plot_surface(T[..., 0], T[..., 1], T[..., 2], cmap="plasma", linewidth=0)
    ax.set_box_aspect((1, 1, 0.35))
    ax.set_zticks([-1, 0, 1])
    ax.set_title("exact rational torus")
    ax = fig.add_subplot(1, 4, 4, projection="3d")
    mv = mesh.vertices
    ax.plot_trisurf(mv[:, 0], mv[:, 1], mv[:, 2], triangles=mesh.triangles, color="#9db4d0", shade=True,
                    linewidth=0.0)
    ax.set_box_aspect((8, 6, 1.5))
    ax.set_zticks([0, 1.5])
    ax.set_title(f"B-rep plate, {len(part.faces())} exact faces, watertight mesh")
    fig.tight_layout()
    png = out / "kernel.png"
    fig.savefig(png, dpi=110)
    print(f"wrote {png}, {stl} and {part_stl}")
    return 0


# ============================================================================ validate
def _validate(args) -> int:
    from coons.validation.cases import recipe_text, select_cases
    from coons.validation.report import exit_status, format_table, write_html
    from coons.validation.runner import RunOptions, options_dict, run_cases

    cases = select_cases(args.cases)
    if args.list:
        for c in cases:
            print(f"{c.name:34s} {','.join(c.tags):34s} {recipe_text(c.recipe)}")
        return 0
    options = RunOptions(render=args.report is not None)
    t0 = time.perf_counter()
    results = run_cases(cases, options=options, jobs=args.jobs, timeout=args.timeout, scheduler=args.scheduler)
    seconds = time.perf_counter() - t0
    print(format_table(results, seconds))
    if args.report is not None:
        where = "Dask " + args.scheduler if args.scheduler else f"{args.jobs or os.cpu_count()} local processes"
        index = write_html(results, args.report, seconds=seconds,
                           options={**options_dict(options), "timeout": args.timeout, "run on": where})
        print(f"wrote {index}")
    if args.json is not None:
        import json

        plain = [{k: v for k, v in r.items() if k != "images"} for r in results]
        args.json.write_text(json.dumps(plain, indent=1, default=str))
        print(f"wrote {args.json}")
    return exit_status(results)


# ============================================================================ convert / info
_STEP = (".step", ".stp")


def _read_solids(path: Path) -> list:
    """The solids of a STEP or STL file (by suffix)."""
    from coons.errors import InvalidInputError

    if not path.is_file():
        raise InvalidInputError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in _STEP:
        from coons.io.step.reader import import_step

        got = import_step(path)
        return list(got) if isinstance(got, (list, tuple)) else [got]
    if suffix == ".stl":
        from coons.io.stl import import_stl
        from coons.topology.from_mesh import from_mesh

        V, T = import_stl(path)
        return [from_mesh(V, T, merge_coplanar=True)]
    raise InvalidInputError(f"{path}: unknown file type {suffix!r}, expected .step, .stp or .stl")


def _convert(src: Path, dst: Path) -> int:
    from coons.errors import InvalidInputError

    suffix = dst.suffix.lower()
    if suffix not in _STEP + (".stl",):
        raise InvalidInputError(f"{dst}: unknown output type {suffix!r}, expected .step, .stp or .stl")
    solids = _read_solids(src)
    if suffix == ".stl":
        import numpy as np

        from coons.io.stl import export_stl
        from coons.topology.tessellate import tessellate

        meshes = [tessellate(s) for s in solids if not s.is_empty]
        if not meshes:
            raise InvalidInputError(f"{src}: no solid to write")
        offsets = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
        V = np.concatenate([m.vertices for m in meshes])
        T = np.concatenate([m.triangles + o for m, o in zip(meshes, offsets)])
        out = export_stl((V, T), dst)
    else:
        from coons.io.step.writer import export_step

        if len(solids) != 1:
            raise InvalidInputError(f"{src}: holds {len(solids)} solids; STEP output takes exactly 1")
        out = export_step(solids[0], dst)
    print(f"wrote {out} ({len(solids)} solid{'s' if len(solids) != 1 else ''})")
    return 0


def _info(path: Path) -> int:
    solids = _read_solids(path)
    print(f"{path}: {len(solids)} solid{'s' if len(solids) != 1 else ''}")
    for i, s in enumerate(solids):
        b = s.brep
        report = s.check()
        print(f"solid {i}: volume {s.volume:.12g}, area {s.area:.12g}")
        if not s.is_empty:
            lo, hi = s.bounding_box()
            print(f"  bbox [{', '.join(f'{x:.9g}' for x in lo)}] .. [{', '.join(f'{x:.9g}' for x in hi)}]")
        print(f"  lumps {b.n_solids}, shells {b.n_shells}, faces {b.n_faces}, edges {b.n_edges}, "
              f"vertices {b.n_vertices}; surfaces {sorted(set(s.surface_types()))}")
        print(f"  valid: {report.ok}" + ("" if report.ok else f" ({report.summary(limit=5)})"))
    return 0


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {n}")
    return n


def _positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}") from None
    if not (x > 0 and x != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}")
    return x


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line error of the other subcommands (``coons: error: ...``, exit status 2)."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"coons: error: {message} (see `{self.prog} --help`)\n")


def main(argv: list[str] | None = None) -> int:
    parser = _Parser(prog="coons", description="coons solid modeling kernel")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="build exact NURBS geometry and write a PNG plot and an STL")
    demo.add_argument("--out", type=Path, default=Path("demo-output"), help="output folder (default: demo-output)")
    val = sub.add_parser("validate", help="compare coons with OCCT and manifold3d on the reference cases")
    val.add_argument("cases", nargs="*", help="case names or glob patterns (default: the whole catalogue)")
    val.add_argument("--report", type=Path, metavar="DIR", help="write DIR/index.html with pictures")
    val.add_argument("--jobs", type=_positive_int, metavar="N", help="case processes at a time (default: cores)")
    val.add_argument("--scheduler", metavar="ADDR", help="run on a Dask cluster (tcp://host:port)")
    val.add_argument("--list", action="store_true", help="list the selected cases and exit")
    val.add_argument("--timeout", type=_positive_float, default=120.0, metavar="S",
                     help="seconds per case (default 120)")
    val.add_argument("--json", type=Path, metavar="FILE", help="also write the results as JSON")
    conv = sub.add_parser("convert", help="convert between STEP and STL (by file suffix)")
    conv.add_argument("input", type=Path)
    conv.add_argument("output", type=Path)
    info = sub.add_parser("info", help="volume, area, bounding box, counts and validity of a STEP/STL file")
    info.add_argument("file", type=Path)
    args = parser.parse_args(argv)
    try:
        if args.command == "demo":
            return _demo(args.out)
        if args.command == "validate":
            return _validate(args)
        if args.command == "convert":
            return _convert(args.input, args.output)
        if args.command == "info":
            return _info(args.file)
    except BrokenPipeError:  # the reader of stdout went away (``coons validate --list | head``)
        sys.stderr.close()
        return 0
    except (CoonsError, OSError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"coons: error: {msg}", file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f"coons: error: a module this command needs is missing: {exc}", file=sys.stderr)
        return 2
    return 1  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
