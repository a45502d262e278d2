"""The ``coons`` command line.

Subcommands:

``coons demo [--out DIR]``
    Builds exact NURBS geometry (a rational circle, an interpolated space curve,
    a bicubic patch, an exact rational torus), checks a few closed forms, and writes
    ``DIR/kernel.png`` (a plot of the curves and surfaces), ``DIR/torus.stl`` and, from the
    B-rep layer, ``DIR/plate.stl``: an extruded plate with holes, checked and measured exactly.

Later issues add ``validate``, ``convert`` and ``info``.  Reference engines and
matplotlib are imported lazily, only by the subcommands that need them.
"""

from __future__ import annotations

import argparse
import sys
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="coons", description="coons solid modeling kernel")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="build exact NURBS geometry and write a PNG plot and an STL")
    demo.add_argument("--out", type=Path, default=Path("demo-output"), help="output folder (default: demo-output)")
    args = parser.parse_args(argv)
    try:
        if args.command == "demo":
            return _demo(args.out)
    except CoonsError as exc:
        print(f"coons: error: {exc}", file=sys.stderr)
        return 2
    return 1  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
