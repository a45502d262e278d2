"""Running reference cases: one case in-process, many in parallel processes, or on a Dask cluster.

:func:`run_case` builds one :class:`~coons.validation.cases.Case` with the three engines of
:mod:`coons.validation.engines`, measures the Hausdorff distance between coons's and OCCT's
meshes, judges it (:func:`coons.validation.compare.judge`) and, when asked, renders its pictures
(:mod:`coons.validation.report`); it returns plain data (a ``dict``), so results cross process
and network boundaries and can be written as JSON.

:func:`run_cases` runs many cases:

* locally, each case in **its own process**, at most ``jobs`` at a time.  The processes are forked
  from a ``multiprocessing`` *forkserver* that imported coons and the engines the run needs
  (build123d, manifold3d, matplotlib) once, so a child starts in ~50 ms instead of ~4 s.  A
  crash (a segfault in a reference engine) or a hang (past ``timeout`` seconds the child is
  killed) costs one case, which is recorded with the engine it was running, never the run.
  (``concurrent.futures.ProcessPoolExecutor`` was not used: a crashing worker breaks the whole
  pool, and before Python 3.14 a hung worker cannot be killed through its public API.)
* on a Dask distributed cluster when ``scheduler="tcp://host:port"`` is given
  (``distributed.Client(address).submit``; the workers import coons and run :func:`run_case` in
  their own processes, pictures come back as PNG bytes).  Dask cannot kill one running task, so
  there ``timeout`` bounds the whole run: ``timeout × ceil(cases / worker threads)`` plus a
  minute for the workers' imports; unfinished cases are cancelled and recorded as timed out.

A progress bar is drawn on stderr when it is a terminal.  The module never decides a verdict
itself except ``timeout`` and ``crashed``.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time
import uuid
from dataclasses import asdict, dataclass
from typing import Any, Callable, Sequence

import numpy as np

from coons.errors import InvalidInputError
from coons.validation.cases import Case, recipe_text

__all__ = ["RunOptions", "run_case", "run_cases", "recipe_scale", "failed_result", "Progress"]

#: Modules the forkserver imports once, so that every case process starts warm (plus build123d,
#: manifold3d and matplotlib when the run needs them).
PRELOAD = ["coons", "coons.validation.runner", "coons.validation.compare", "coons.validation.engines"]


@dataclass(frozen=True)
class RunOptions:
    """How to run a case.

    Attributes
    ----------
    relative_deflection : float
        Tessellation deflection as a fraction of the diagonal of the operands' bounding box.
    engines : tuple of str
        References to run besides coons: ``"occt"``, ``"manifold"``.
    render : bool
        Render the pictures of the report (PNG bytes in the result).
    samples : int
        Sample points per mesh for the Hausdorff distance.
    """

    relative_deflection: float = 1e-3
    engines: tuple[str, ...] = ("occt", "manifold")
    render: bool = False
    samples: int = 8000

    def __post_init__(self) -> None:
        if not (isinstance(self.relative_deflection, (int, float)) and 0 < self.relative_deflection < 1):
            raise InvalidInputError(f"relative_deflection must be in (0, 1), got {self.relative_deflection!r}")
        unknown = set(self.engines) - {"occt", "manifold"}
        if unknown:
            raise InvalidInputError(f"unknown reference engines {sorted(unknown)}, expected 'occt' and/or 'manifold'")


def recipe_scale(node: tuple) -> float:
    """Diagonal of the bounding box of all placed leaves of a recipe (exact coons boxes).

    The case's tessellation deflection is a fraction of it, the same for every engine and known
    before any Boolean runs.
    """
    from coons.validation.engines import _coons_leaf, _placement

    corners: list[np.ndarray] = []

    def walk(n: tuple, M: np.ndarray) -> None:
        kind = n[0]
        if kind in ("pos", "rot"):
            walk(n[2], M @ _placement(n).matrix)
        elif kind in ("union", "difference", "intersection"):
            walk(n[1], M)
            walk(n[2], M)
        else:
            b = np.asarray(_coons_leaf(n).bounding_box(), float)
            C = np.array(np.meshgrid(*b.T, indexing="ij")).reshape(3, -1).T
            corners.append(C @ M[:3, :3].T + M[:3, 3])

    walk(node, np.eye(4))
    P = np.concatenate(corners)
    return float(np.linalg.norm(P.max(0) - P.min(0)))


def failed_result(case: Case, kind: str, reason: str, stage: str | None, seconds: float) -> dict:
    """The result of a case that produced none: ``kind`` is ``"timeout"`` or ``"crashed"``.

    It counts as a coons failure only when coons was the engine running (``stage == "coons"``).
    """
    return {
        "name": case.name, "description": case.description, "recipe": recipe_text(case.recipe),
        "tags": list(case.tags), "expect_volume": case.expect_volume,
        "verdict": {"kind": kind, "reasons": [reason], "measures": [], "failed_references": {},
                    "coons_bug": stage == "coons"},
        "engines": {}, "hausdorff": None, "deflection": None, "seconds": seconds, "images": {}, "stage": stage,
    }


def run_case(case: Case, options: RunOptions = RunOptions(), stage: Callable[[str], None] | None = None) -> dict:
    """Run one case in this process (module docstring).

    Parameters
    ----------
    case : Case
    options : RunOptions
    stage : callable, optional
        Called with ``"coons"``, ``"occt"``, ``"manifold"``, ``"compare"``, ``"render"`` as each starts.

    Returns
    -------
    dict
        ``name``, ``description``, ``recipe``, ``tags``, ``expect_volume``, ``verdict`` (a
        :class:`~coons.validation.compare.Verdict` as a dict), ``engines`` (each
        :class:`~coons.validation.engines.EngineResult` as a dict), ``hausdorff``, ``deflection``,
        ``seconds`` and ``images`` (``{"coons": png bytes, "deviation": png bytes}`` when rendered).
    """
    from coons.validation import compare, engines

    note = stage or (lambda s: None)
    t0 = time.perf_counter()
    note("coons")
    deflection = options.relative_deflection * recipe_scale(case.recipe)
    want_mesh = "occt" in options.engines or options.render
    res_c, _ = engines.run_coons(case, deflection, mesh=want_mesh)
    results: dict[str, Any] = {"coons": res_c}
    if "occt" in options.engines:
        note("occt")
        results["occt"] = engines.run_occt(case, deflection, mesh=True)
    if "manifold" in options.engines:
        note("manifold")
        results["manifold"] = engines.run_manifold(case, deflection)
    note("compare")
    h, vdist = None, None
    o = results.get("occt")
    if res_c.mesh is not None and o is not None and o.mesh is not None and len(o.mesh[1]) and len(res_c.mesh[1]):
        h, vdist = compare.hausdorff(res_c.mesh, o.mesh, samples=options.samples)
    verdict = compare.judge(case, results, deflection=deflection, hausdorff_distance=h)
    images: dict[str, bytes] = {}
    if options.render and res_c.mesh is not None and len(res_c.mesh[1]):
        note("render")
        from coons.validation import report

        images["coons"] = report.render_mesh_png(res_c.mesh, title=f"{case.name}: coons")
        if vdist is not None and verdict.kind in ("disagree", "reference-failed"):
            images["deviation"] = report.render_mesh_png(
                res_c.mesh, values=vdist, title=f"{case.name}: distance of coons's mesh to OCCT's")
    return {
        "name": case.name, "description": case.description, "recipe": recipe_text(case.recipe),
        "tags": list(case.tags), "expect_volume": case.expect_volume,
        "verdict": verdict.to_dict(), "engines": {k: v.to_dict() for k, v in results.items()},
        "hausdorff": h, "deflection": deflection, "seconds": time.perf_counter() - t0, "images": images,
        "stage": None,
    }


# ============================================================================ progress
class Progress:
    """A one-line progress bar on a stream (stderr), drawn only when the stream is a terminal."""

    def __init__(self, total: int, stream=None, enabled: bool | None = None, width: int = 30) -> None:
        self.total, self.done, self.width = total, 0, width
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", lambda: False)
        self.enabled = bool(isatty()) if enabled is None else enabled
        self.t0 = time.perf_counter()

    def update(self, name: str, verdict: str) -> None:
        self.done += 1
        if not self.enabled:
            return
        k = int(self.width * self.done / max(self.total, 1))
        bar = "#" * k + "-" * (self.width - k)
        el = time.perf_counter() - self.t0
        self.stream.write(f"\r[{bar}] {self.done}/{self.total} {el:5.0f}s {name[:28]:28s} {verdict:16s}")
        if self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


# ============================================================================ local processes
def _child(conn, target, case: Case, options: RunOptions) -> None:
    """Body of a case process: report each stage, then the result, through the pipe."""
    try:
        result = target(case, options, lambda s: conn.send(("stage", s)))
        conn.send(("result", result))
    except BaseException as exc:  # noqa: BLE001 - the parent records it
        conn.send(("error", f"{type(exc).__name__}: {exc}"[:500]))
    finally:
        conn.close()


def _context(options: RunOptions):
    """The forkserver context, preloading what the options need (the first run of a process decides)."""
    ctx = multiprocessing.get_context("forkserver" if "forkserver" in multiprocessing.get_all_start_methods()
                                      else "spawn")
    if ctx.get_start_method() == "forkserver":
        extra = (["build123d"] if "occt" in options.engines else []) + \
                (["manifold3d"] if "manifold" in options.engines else []) + \
                (["coons.validation.report", "matplotlib.pyplot"] if options.render else [])
        ctx.set_forkserver_preload(PRELOAD + extra)
    return ctx


def _run_local(cases: Sequence[Case], options: RunOptions, jobs: int, timeout: float, target, progress) -> list[dict]:
    from multiprocessing.connection import wait

    ctx = _context(options)
    pending = list(enumerate(cases))[::-1]
    running: dict[Any, dict] = {}  # connection -> {proc, case, index, start, stage}
    out: list[dict | None] = [None] * len(cases)

    def finish(conn, result: dict) -> None:
        info = running.pop(conn)
        out[info["index"]] = result
        try:
            conn.close()
        except OSError:  # pragma: no cover
            pass
        info["proc"].join(timeout=5)
        progress.update(info["case"].name, result["verdict"]["kind"])

    while pending or running:
        while pending and len(running) < jobs:
            i, case = pending.pop()
            r, w = ctx.Pipe(duplex=False)
            p = ctx.Process(target=_child, args=(w, target, case, options), daemon=True)
            p.start()
            w.close()
            running[r] = {"proc": p, "case": case, "index": i, "start": time.monotonic(), "stage": None}
        now = time.monotonic()
        wait_for = min(info["start"] + timeout for info in running.values()) - now
        ready = wait(list(running), timeout=max(0.0, wait_for))
        for conn in ready:
            info = running[conn]
            try:
                kind, payload = conn.recv()
            except (EOFError, OSError):
                info["proc"].join(timeout=5)
                code = info["proc"].exitcode
                finish(conn, failed_result(info["case"], "crashed",
                                           f"the case process died (exit code {code}) while running {info['stage']}",
                                           info["stage"], time.monotonic() - info["start"]))
                continue
            if kind == "stage":
                info["stage"] = payload
            elif kind == "result":
                finish(conn, payload)
            else:
                finish(conn, failed_result(info["case"], "crashed",
                                           f"the harness failed while running {info['stage']}: {payload}",
                                           info["stage"], time.monotonic() - info["start"]))
        now = time.monotonic()
        for conn, info in list(running.items()):
            if now - info["start"] > timeout:
                info["proc"].kill()
                finish(conn, failed_result(info["case"], "timeout",
                                           f"no result after {timeout:g} s (killed while running {info['stage']})",
                                           info["stage"], now - info["start"]))
    return out  # type: ignore[return-value]


# ============================================================================ Dask
def _run_dask(cases: Sequence[Case], options: RunOptions, scheduler: str, timeout: float, target,
              progress) -> list[dict]:
    from distributed import Client, as_completed

    try:
        client = Client(scheduler, timeout=10)
    except OSError as exc:
        raise InvalidInputError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from exc
    try:
        threads = max(1, sum(client.nthreads().values()))
        budget = timeout * math.ceil(len(cases) / threads) + 60.0
        run = uuid.uuid4().hex[:8]
        futures = [client.submit(target, c, options, pure=False, key=f"coons-validate-{c.name}-{run}") for c in cases]
        index = {f.key: i for i, f in enumerate(futures)}
        out: list[dict | None] = [None] * len(cases)
        t0 = time.monotonic()
        try:
            for fut in as_completed(futures, timeout=budget):
                i = index[fut.key]
                if fut.status == "finished":
                    out[i] = fut.result()
                else:
                    err = fut.exception()
                    out[i] = failed_result(cases[i], "crashed", f"the Dask task failed: {type(err).__name__}: {err}",
                                           None, time.monotonic() - t0)
                progress.update(cases[i].name, out[i]["verdict"]["kind"])
        except TimeoutError:
            pass  # the unfinished cases are recorded below
        finally:
            for i, f in enumerate(futures):
                if out[i] is None:
                    f.cancel()
                    out[i] = failed_result(cases[i], "timeout", f"no result within the run's budget of {budget:g} s "
                                           f"on the Dask cluster", None, time.monotonic() - t0)
                    progress.update(cases[i].name, "timeout")
        return out  # type: ignore[return-value]
    finally:
        client.close()


def run_cases(cases: Sequence[Case], *, options: RunOptions = RunOptions(), jobs: int | None = None,
              timeout: float = 120.0, scheduler: str | None = None, target: Callable | None = None,
              progress: Progress | None = None) -> list[dict]:
    """Run cases in parallel (module docstring) and return their results in the order given.

    Parameters
    ----------
    cases : sequence of Case
    options : RunOptions
    jobs : int, optional
        Concurrent case processes (default: the number of cores); ignored with ``scheduler``.
    timeout : float
        Seconds per case (> 0).
    scheduler : str, optional
        A Dask scheduler address (``tcp://host:port``).
    target : callable, optional
        ``target(case, options, stage)``, default :func:`run_case` (tests substitute one that hangs).
    progress : Progress, optional
        Default: a bar on stderr when it is a terminal.

    Returns
    -------
    list of dict
        :func:`run_case`'s results, or :func:`failed_result`'s for cases that timed out or crashed.

    Raises
    ------
    InvalidInputError
        ``jobs < 1``, ``timeout <= 0``, or an unreachable scheduler.
    """
    if jobs is None:
        jobs = os.cpu_count() or 1
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InvalidInputError(f"jobs must be an integer >= 1, got {jobs!r}")
    if not (isinstance(timeout, (int, float)) and timeout > 0 and math.isfinite(timeout)):
        raise InvalidInputError(f"timeout must be a finite number of seconds > 0, got {timeout!r}")
    target = run_case if target is None else target
    progress = Progress(len(cases)) if progress is None else progress
    if not cases:
        return []
    if scheduler:
        return _run_dask(cases, options, scheduler, timeout, target, progress)
    return _run_local(cases, options, jobs, float(timeout), target, progress)


def options_dict(options: RunOptions) -> dict:
    """The options as plain data (for the report)."""
    return asdict(options)
