"""Shared machinery of the benchmarks: registry, adaptive timing, environment header, markdown.

This module registers benchmark modules (``bench_*.py`` beside it register themselves
on import), times callables under one written policy, describes the machine and its
BLAS, and formats markdown.  It deliberately knows nothing about geometry or about any
peer library, decides nothing about what is fast enough, and asserts nothing: speed is
reported as rates and ratios measured in the same run, never turned into a pass/fail.

Timing policy (:func:`measure`)
-------------------------------
A case is a callable ``fn(units)`` that evaluates the first ``units`` units of a problem
(a unit is a scattered point, or a grid row of many points).  A small probe sizes the
run; the full problem is timed, best of ``reps`` (more for runs of a few ms, since the
minimum of a shared machine's timings needs many draws), when its estimated time fits
``full_budget`` seconds; otherwise (a slow peer) a subsample is grown until its best of
``subsample_reps`` runs takes at least ``min_seconds``, and the rate is reported with
the subsample size.
"""

from __future__ import annotations

import datetime as _dt
import gc
import importlib
import importlib.metadata as _md
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"

__all__ = [
    "Benchmark",
    "Measurement",
    "REGISTRY",
    "Report",
    "discover",
    "environment_markdown",
    "markdown_table",
    "matmul_gflops",
    "measure",
    "register",
]


# ---------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class Report:
    """What one benchmark returns: a title and markdown sections, the first being the main table."""

    title: str
    sections: list[str]
    #: True when a peer disagreed with coons: the affected cells carry no rate and run.py exits 1.
    failed: bool = False

    def markdown(self, header: str) -> str:
        return "\n\n".join([f"# {self.title}", header, *self.sections]) + "\n"


@dataclass(frozen=True)
class Benchmark:
    name: str
    description: str
    run: Callable[[], Report]
    #: Distributions whose versions the results header records, beyond numpy and scipy.
    versions: tuple[str, ...] = ()


#: name -> Benchmark, filled by :func:`register` when ``bench_*.py`` modules are imported.
REGISTRY: dict[str, Benchmark] = {}


def register(
    name: str, description: str, versions: tuple[str, ...] = ()
) -> Callable[[Callable[[], Report]], Callable[[], Report]]:
    """Decorator: register ``fn() -> Report`` as benchmark ``name`` (results in ``results/<name>.md``).

    ``versions`` names the distributions (peers) whose versions the results header records.
    """

    def deco(fn: Callable[[], Report]) -> Callable[[], Report]:
        if name in REGISTRY and REGISTRY[name].run is not fn:
            raise ValueError(f"benchmark name {name!r} registered twice")
        REGISTRY[name] = Benchmark(name, description, fn, tuple(versions))
        return fn

    return deco


def discover() -> dict[str, Benchmark]:
    """Import every ``bench_*.py`` beside this file (each registers itself) and return the registry."""
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    for path in sorted(HERE.glob("bench_*.py")):
        importlib.import_module(path.stem)
    return REGISTRY


# ---------------------------------------------------------------------------- timing
@dataclass(frozen=True)
class Measurement:
    """Best wall time of ``reps`` runs over ``points`` evaluations.

    ``full`` is False when a subsample of the problem was timed (a slow path).
    """

    seconds: float
    points: int
    reps: int
    full: bool
    path: str = ""

    @property
    def mpoints_per_s(self) -> float:
        return self.points / self.seconds / 1e6


def forget_coons_caches() -> None:
    """Forget everything coons remembers between operations (meshes, mass integrals, Boolean
    carry-overs, per-object memos of sewing, checking and the kernel).

    Benchmarks reuse their operands across repetitions; a warm cache would time a reuse of the
    operands' tessellations and integrals, not the operation.  Call this before each coons
    repetition (untimed, or inside the timing: it costs microseconds).
    """
    from coons.booleans.solid import _forget_caches

    _forget_caches()


def _timed(fn: Callable[[int], object], units: int) -> tuple[float, object]:
    gc.collect()
    t0 = time.perf_counter()
    out = fn(units)
    return time.perf_counter() - t0, out


def measure(
    fn: Callable[[int], object],
    units_full: int,
    points_per_unit: int = 1,
    *,
    path: str = "",
    reps: int = 3,
    max_reps: int = 20,
    fast_seconds: float = 1.0,
    subsample_reps: int = 2,
    min_seconds: float = 0.5,
    full_budget: float = 1.5,
    probe_points: int = 2000,
) -> tuple[Measurement, object, int]:
    """Time ``fn(units)`` under the module's policy.

    Parameters
    ----------
    fn : callable ``units -> result``
        Evaluates the first ``units`` units of the problem and returns its result.
    units_full : int
        Units in the whole problem.
    points_per_unit : int
        Evaluated points per unit (grid row length, or 1).
    reps, max_reps, fast_seconds : int, int, float
        The full problem is timed best of ``reps`` runs, or of more (up to ``max_reps``)
        while they add up to about ``fast_seconds``.
    subsample_reps : int
        Runs of a subsample, each of at least ``min_seconds`` (grown until the best one is).
    full_budget : float
        Largest estimated time (s) of one full run for which the full problem is timed;
        ``math.inf`` always times the full problem.

    Returns
    -------
    (Measurement, result of the last run, units of the last run)
    """
    units = max(1, min(units_full, math.ceil(probe_points / points_per_unit)))
    t, out = _timed(fn, units)
    while units < units_full:
        t = max(t, 1e-6)  # a probe faster than the clock still sizes the next run
        if t * units_full / units <= full_budget:
            units = units_full
        elif t >= min_seconds:
            break
        else:
            # Aim 30 % past min_seconds; at most x16 per step, since small probes time overheads.
            units = min(units_full, math.ceil(units * min(16.0, 1.3 * min_seconds / t)))
        t, out = _timed(fn, units)
    while True:
        full = units == units_full
        n_reps = subsample_reps
        if full:
            # Fast paths are cheap to repeat, and on a shared 2-core VM the minimum needs many draws.
            n_reps = max(reps, min(max_reps, math.ceil(fast_seconds / max(t, 1e-6))))
        best = t
        for _ in range(n_reps - 1):
            t, out = _timed(fn, units)
            best = min(best, t)
        if full or best >= min_seconds:
            break
        # A repetition ran faster than the sizing run: a subsample must take min_seconds in its best run.
        units = min(units_full, math.ceil(units * 1.3 * min_seconds / best))
        t, out = _timed(fn, units)
    m = Measurement(best, units * points_per_unit, n_reps, full, path)
    return m, out, units


def matmul_gflops(n: int = 2000, reps: int = 3) -> float:
    """GFLOP/s of an ``n × n`` float64 matmul (``2 n^3`` flops), best of ``reps``."""
    rng = np.random.default_rng(0)
    A = rng.random((n, n))
    B = rng.random((n, n))
    A @ B  # warm the BLAS thread pool
    best = math.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        A @ B
        best = min(best, time.perf_counter() - t0)
    return 2.0 * n**3 / best / 1e9


# ---------------------------------------------------------------------------- environment
def _version(dist: str) -> str:
    try:
        return _md.version(dist)
    except _md.PackageNotFoundError:
        return "not installed"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _blas_summary() -> list[str]:
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        cfg = np.show_config(mode="dicts")
        blas = cfg.get("Build Dependencies", {}).get("blas", {})
        return [f"numpy BLAS (numpy.show_config): {blas.get('name', '?')} {blas.get('version', '')}".strip()]
    lines = []
    for info in threadpool_info():
        owner = Path(info.get("filepath", "")).parent.name
        lines.append(
            f"{info.get('internal_api')} {info.get('version') or ''} ({info.get('prefix')}, from {owner}): "
            f"{info.get('num_threads')} threads"
            + (f", kernel {info['architecture']}" if info.get("architecture") else "")
            + (f", {info['threading_layer']}" if info.get("threading_layer") else "")
        )
    return lines


def environment_markdown(extra_versions: tuple[str, ...] = ()) -> str:
    """Markdown header: date, machine, Python and library versions, BLAS, OPENBLAS_* variables."""
    versions = ["numpy", "scipy", *extra_versions]
    vs = ", ".join(f"{d} {_version(d)}" for d in versions)
    env = {
        k: v
        for k, v in sorted(os.environ.items())
        if k.startswith(("OPENBLAS_", "NUMBA_", "COONS_")) or k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
    }
    nproc = len(os.sched_getaffinity(0))
    env_text = ", ".join(f"{k}={v}" for k, v in env.items()) or "no OPENBLAS_*/NUMBA_*/COONS_*/OMP_NUM_THREADS set"
    lines = [
        f"- date: {_dt.datetime.now().astimezone().isoformat(timespec='seconds')}",
        f"- machine: {os.cpu_count()} CPUs (nproc {nproc}), {_cpu_model()}, {platform.machine()}, "
        f"Linux {platform.release()}",
        f"- python {platform.python_version()}; {vs}",
        "- BLAS (threadpoolctl): " + "; ".join(_blas_summary()),
        f"- environment: {env_text} (left as found)",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- markdown
def markdown_table(headers: list[str], rows: list[list[str]]) -> str:
    """A GitHub markdown table with right-aligned columns after the first."""
    align = [":--"] + ["--:"] * (len(headers) - 1)
    out = ["| " + " | ".join(headers) + " |", "| " + " | ".join(align) + " |"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)
