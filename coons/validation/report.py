"""Reports of ``coons validate``: a text table, an HTML page with pictures, and the exit status.

:func:`format_table` prints one line per case (verdict, volumes of the three engines, the
Hausdorff distance, time) and a summary; :func:`write_html` writes ``DIR/index.html``, a
self-contained page (inline CSS, no script, no network) with per case the figures of each
engine, the count convention, the verdict and its reasons, and the PNG pictures written next to
it: coons's result rendered with simple Lambert shading (matplotlib Agg,
``mpl_toolkits.mplot3d.art3d.Poly3DCollection``) and, where engines disagree, coons's mesh
coloured by its distance to OCCT's.  :func:`render_mesh_png` makes those pictures (it runs in
the case processes).  :func:`exit_status` is 1 when coons is wrong or invalid on a case (or
raised an untyped exception, or hung or crashed while coons was running), else 0.

The module imports matplotlib only inside :func:`render_mesh_png`; it does not run cases.
"""

from __future__ import annotations

import html
import io
import os
from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["render_mesh_png", "format_table", "write_html", "exit_status", "summary_counts", "COUNT_RULE"]

COUNT_RULE = (
    "Counts: coons has no seam and no degenerate edges and splits closed faces (a cylinder's side is two "
    "half-cylinders, a sphere two hemispheres, a torus four quarters); OCCT has seam edges, degenerate edges at "
    "poles and apexes, and whole closed faces; on planar faces coons may keep 2-valent vertices on straight "
    "edges. χ = V − E + F − R (R inner loops, OCCT's degenerate edges left out) equals 2 (shells − genus) in "
    "both conventions and must agree; for all-planar cases F and V − E must agree too. manifold3d counts "
    "triangles."
)


def render_mesh_png(mesh, *, values=None, title: str = "", size: tuple[float, float] = (5.0, 4.2),
                    dpi: int = 90) -> bytes:
    """A PNG picture of a triangle mesh: Lambert-shaded, or coloured by per-vertex ``values`` with a colour bar.

    Parameters
    ----------
    mesh : tuple of ``(V (n, 3) float64, T (m, 3) int64)``
    values : (n,) float64, optional
        Per-vertex values (distances); each triangle takes the largest of its vertices'.
    title : str

    Returns
    -------
    bytes
        The PNG file.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    V, T = np.asarray(mesh[0], float), np.asarray(mesh[1], np.int64)
    tri = V[T]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    light = np.array([0.4, -0.5, 0.77])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.clip(n @ light, 0.0, 1.0)
    fig = plt.figure(figsize=size, dpi=dpi)
    ax = fig.add_subplot(projection="3d")
    if values is None:
        base = np.array([0.55, 0.68, 0.85])
        colors = np.clip(shade[:, None] * base, 0, 1)
    else:
        vals = np.asarray(values, float)[T].max(axis=1)
        vmax = float(vals.max()) if len(vals) and vals.max() > 0 else 1.0
        cmap = plt.get_cmap("inferno")
        colors = cmap(vals / vmax)[:, :3] * (0.6 + 0.4 * shade[:, None])
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0.0, vmax))
        fig.colorbar(sm, ax=ax, shrink=0.7, label="distance to OCCT's mesh")
    ax.add_collection3d(Poly3DCollection(tri, facecolors=colors, edgecolors="none", linewidths=0))
    lo, hi = V.min(0), V.max(0)
    c, r = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9)
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=25, azim=-55)
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=6)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


# ============================================================================ text
def _fmt(x, spec: str = ".6g") -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return format(x, spec)
    return str(x)


def _volume(result: dict, engine: str) -> str:
    e = result.get("engines", {}).get(engine)
    if not e:
        return "-"
    if e["status"] != "ok":
        return "raised"
    return _fmt(e["volume"], ".8g")


def summary_counts(results: Sequence[dict]) -> dict[str, int]:
    """Number of cases per verdict kind."""
    out: dict[str, int] = {}
    for r in results:
        k = r["verdict"]["kind"]
        out[k] = out.get(k, 0) + 1
    return out


def exit_status(results: Sequence[dict]) -> int:
    """1 when some case shows coons wrong, invalid, buggy (untyped exception) or hung/crashed in coons; else 0."""
    return int(any(r["verdict"]["kind"] == "disagree" or r["verdict"].get("coons_bug") for r in results))


def format_table(results: Sequence[dict], seconds: float | None = None) -> str:
    """The stdout table: one line per case, then a summary line."""
    head = f"{'case':34s} {'verdict':17s} {'coons volume':>15s} {'OCCT volume':>15s} {'manifold vol.':>15s} " \
           f"{'Hausdorff':>10s} {'time':>6s}  note"
    lines = [head, "-" * len(head)]
    for r in results:
        v = r["verdict"]
        note = v["reasons"][0] if v["reasons"] else ""
        lines.append(f"{r['name'][:34]:34s} {v['kind']:17s} {_volume(r, 'coons'):>15s} {_volume(r, 'occt'):>15s} "
                     f"{_volume(r, 'manifold'):>15s} {_fmt(r.get('hausdorff'), '.2e'):>10s} "
                     f"{r.get('seconds') or 0:5.1f}s  {note[:110]}")
    counts = summary_counts(results)
    summ = ", ".join(f"{counts[k]} {k}" for k in sorted(counts))
    tail = f"{len(results)} cases: {summ}"
    if seconds is not None:
        tail += f" in {seconds:.1f} s"
    lines += ["-" * len(head), tail]
    return "\n".join(lines)


# ============================================================================ HTML
_CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}
th{background:#eee}td.l{text-align:left}.agree{background:#d9f2d9}.disagree{background:#f8c8c8}
.coons-raised{background:#fbe7b5}.reference-failed{background:#d6e4f7}.timeout,.crashed{background:#e4d0f0}
section{border-top:2px solid #999;margin-top:1.5em;padding-top:.5em}img{max-width:46%;margin-right:1%}
.small{font-size:12px;color:#555}
"""

_FIELDS = (("status", "status"), ("volume", "volume"), ("area", "area"), ("bbox", "bounding box"),
           ("counts", "V / E / F / R"), ("euler", "χ"), ("shells", "shells / lumps"), ("valid", "valid"),
           ("seconds", "seconds"))


def _engine_cell(e: dict | None, key: str) -> str:
    if not e:
        return "-"
    if key == "status":
        return e["status"] if e["status"] == "ok" else f"raised: {e.get('error')}"
    if e["status"] != "ok":
        return "-"
    if key == "bbox":
        b = e.get("bbox")
        return "-" if b is None else " ".join(f"[{', '.join(f'{x:.6g}' for x in row)}]" for row in b)
    if key == "counts":
        c = e.get("counts") or {}
        s = f"{c.get('vertices')} / {c.get('edges')} / {c.get('faces')} / {c.get('inner_loops')}"
        if "seam_edges" in c:
            s += f" (seams {c['seam_edges']}, degenerate {c['degenerate_edges']})"
        return s
    if key == "shells":
        c = e.get("counts") or {}
        return f"{c.get('shells')} / {c.get('solids')}"
    if key == "valid":
        return f"{e.get('valid')} ({e.get('validity', '')[:120]})"
    x = e.get(key)
    return _fmt(x, ".12g") if key in ("volume", "area") else _fmt(x, ".3g")


def write_html(results: Sequence[dict], directory, *, title: str = "coons validate",
               seconds: float | None = None, options: dict | None = None) -> Path:
    """Write ``directory/index.html`` and the pictures (``<case>.png``, ``<case>-deviation.png``).

    Parameters
    ----------
    results : sequence of dict
        :func:`coons.validation.runner.run_case` results (with ``images`` when rendered).
    directory : str or Path
        Created if needed; files are written atomically (temporary name, then ``os.replace``).

    Returns
    -------
    Path
        The index file.
    """
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    esc = html.escape
    counts = summary_counts(results)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{esc(title)}</title>"
             f"<style>{_CSS}</style></head><body><h1>{esc(title)}</h1>"]
    summ = ", ".join(f"{counts[k]} {esc(k)}" for k in sorted(counts))
    parts.append(f"<p>{len(results)} cases: {summ}" + (f", {seconds:.1f} s" if seconds is not None else "")
                 + f". Exit status {exit_status(results)}.</p>")
    if options:
        parts.append(f"<p class='small'>Options: {esc(str(options))}</p>")
    parts.append(f"<p class='small'>{esc(COUNT_RULE)}</p>")
    parts.append("<table><tr><th>case</th><th>verdict</th><th>coons volume</th><th>OCCT volume</th>"
                 "<th>manifold volume</th><th>Hausdorff</th><th>reason</th></tr>")
    for r in results:
        k = r["verdict"]["kind"]
        reason = r["verdict"]["reasons"][0] if r["verdict"]["reasons"] else ""
        parts.append(f"<tr class='{esc(k)}'><td class='l'><a href='#{esc(r['name'])}'>{esc(r['name'])}</a></td>"
                     f"<td class='l'>{esc(k)}</td><td>{_volume(r, 'coons')}</td><td>{_volume(r, 'occt')}</td>"
                     f"<td>{_volume(r, 'manifold')}</td><td>{_fmt(r.get('hausdorff'), '.2e')}</td>"
                     f"<td class='l'>{esc(reason[:160])}</td></tr>")
    parts.append("</table>")
    for r in results:
        name = r["name"]
        v = r["verdict"]
        parts.append(f"<section id='{esc(name)}'><h2>{esc(name)} — <span class='{esc(v['kind'])}'>"
                     f"{esc(v['kind'])}</span></h2><p>{esc(r.get('description', ''))}<br><code>"
                     f"{esc(r.get('recipe', ''))}</code></p>")
        if r.get("expect_volume") is not None:
            parts.append(f"<p>closed-form volume {r['expect_volume']:.12g}</p>")
        if v["reasons"]:
            parts.append("<ul>" + "".join(f"<li>{esc(x)}</li>" for x in v["reasons"]) + "</ul>")
        engines = r.get("engines", {})
        if engines:
            names = [n for n in ("coons", "occt", "manifold") if n in engines]
            parts.append("<table><tr><th></th>" + "".join(f"<th>{n}</th>" for n in names) + "</tr>")
            for key, label in _FIELDS:
                parts.append(f"<tr><th>{esc(label)}</th>"
                             + "".join(f"<td class='l'>{esc(_engine_cell(engines[n], key))}</td>" for n in names)
                             + "</tr>")
            parts.append("</table>")
            parts.append(f"<p class='small'>deflection {_fmt(r.get('deflection'), '.3g')}, Hausdorff distance "
                         f"coons–OCCT {_fmt(r.get('hausdorff'), '.3g')}, {r.get('seconds') or 0:.2f} s</p>")
        bad = [m for m in v.get("measures", []) if not m["ok"]]
        if bad:
            parts.append("<table><tr><th>measure</th><th>reference</th><th>deviation</th><th>tolerance</th></tr>"
                         + "".join(f"<tr><td class='l'>{esc(m['name'])}</td><td class='l'>{esc(m['reference'])}</td>"
                                   f"<td>{m['deviation']:.3g}</td><td>{m['tolerance']:.3g}</td></tr>" for m in bad)
                         + "</table>")
        imgs = r.get("images") or {}
        for key, suffix in (("coons", ""), ("deviation", "-deviation")):
            if imgs.get(key):
                fname = f"{name}{suffix}.png"
                _write_atomic(d / fname, imgs[key])
                parts.append(f"<img src='{esc(fname)}' alt='{esc(name)} {key}'>")
        parts.append("</section>")
    parts.append("</body></html>")
    index = d / "index.html"
    _write_atomic(index, "\n".join(parts).encode("utf-8"))
    return index


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)
