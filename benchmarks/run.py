"""Run the benchmarks: ``python benchmarks/run.py [names...]`` (all when no name is given).

Every ``benchmarks/bench_*.py`` registers itself with :func:`_harness.register`; this
script imports them, runs the selected ones in order, prints each report (markdown)
and writes it, headed by the date, machine, library versions and BLAS, to
``benchmarks/results/<name>.md``.  It does not compare against stored numbers or
fail on slowness: peers are measured in the same run and ratios reported.  It exits
1 when a benchmark reports that a peer disagreed with coons (the run is then invalid).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _harness import RESULTS, discover, environment_markdown  # noqa: E402


def _load() -> str:
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except OSError:
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    registry = discover()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help=f"benchmarks to run (default all): {', '.join(registry)}")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    parser.add_argument("--no-write", action="store_true", help="print only; leave benchmarks/results/ alone")
    args = parser.parse_args(argv)
    if args.list:
        for b in registry.values():
            print(f"{b.name}: {b.description}")
        return 0
    unknown = [n for n in args.names if n not in registry]
    if unknown:
        parser.error(f"unknown benchmark(s) {', '.join(unknown)}; known: {', '.join(registry)}")
    status = 0
    for name in args.names or list(registry):
        bench = registry[name]
        header = environment_markdown(bench.versions)
        load0 = _load()
        t0 = time.perf_counter()
        report = bench.run()
        header += (
            f"\n- wall time {time.perf_counter() - t0:.0f} s; load average (1 min) {load0} at start, {_load()} at end"
            " (other work on the machine during the run makes every rate lower and noisier)"
        )
        text = report.markdown(header)
        print(text, flush=True)
        if not args.no_write:
            RESULTS.mkdir(parents=True, exist_ok=True)
            (RESULTS / f"{name}.md").write_text(text)
        status |= int(report.failed)
    return status


if __name__ == "__main__":
    sys.exit(main())
