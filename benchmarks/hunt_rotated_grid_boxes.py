"""Hunt for polyhedral Booleans of rotated grid-box pairs that fail (issue 4); not a benchmark.

``python benchmarks/hunt_rotated_grid_boxes.py --pairs 1000 --seed 1`` draws random pairs of
grid boxes ``g = (lo, size)`` (integer corners in ``[0, 4)``, sizes in ``[1, 4)``) turned by the
same random rigid motion — the draw of ``test_a_fixed_batch_of_rotated_grid_boxes_all_succeed``
in ``tests/booleans/test_polyhedral_coincident.py`` — runs union, intersection and difference on
each, and reports every Boolean that raised, returned a solid whose ``check`` is not clean, or
whose volume is off the closed form by more than ``1e-9`` of the pair's volume scale.  The union
of boxes touching only along an edge or at a corner is non-manifold and must raise (``"not a
manifold"``); those refusals are counted apart, not as failures.  Each failure is printed as
``(g1, g2, q, t, op)`` ready to paste into ``REGRESSIONS``; the summary also counts the Booleans in which
:func:`coons.booleans._mesh_arrangement.snap` gave up and left the operands unsnapped (its debug
message on ``logging.getLogger("coons")``).  It is not registered with ``benchmarks/run.py`` (it
measures correctness, not speed).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "booleans"))

import coons.booleans.polyhedral as poly  # noqa: E402
from coons.errors import BooleanError  # noqa: E402
from test_polyhedral_coincident import ROTATED_RTOL, draw_rotated_pair, grid_pair, touch_only  # noqa: E402


def run_one(g1, g2, q, t, op) -> str | None:
    """``None`` when the Boolean is right (or a required non-manifold refusal), else the reason."""
    a, b, vols = grid_pair(g1, g2, q, t)
    try:
        r = poly.boolean(a, b, op)
    except BooleanError as exc:
        if op == "union" and touch_only(g1, g2) and "not a manifold" in str(exc):
            return None
        return f"BooleanError({exc.stage}): {str(exc)[:120]}"
    except Exception as exc:  # noqa: BLE001 - the hunt records every kind of failure
        return f"{type(exc).__name__}: {str(exc)[:120]}"
    if op == "union" and touch_only(g1, g2):
        return "non-manifold union returned a solid"
    report = r.check()
    if not report.ok:
        return "check: " + report.summary()[:120]
    vol = 0.0 if r.is_empty else r.volume
    scale = sum(vols.values())
    if abs(vol - vols[op]) > ROTATED_RTOL * scale:
        return f"volume {vol!r}, expected {vols[op]!r}"
    return None


class _SnapGiveUps(logging.Handler):
    """Counts the snap's "operands left as they are" messages."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.count = 0

    def emit(self, record: logging.LogRecord) -> None:
        if record.getMessage().startswith("snap: operands left"):
            self.count += 1


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    log = logging.getLogger("coons")
    give_ups = _SnapGiveUps()
    log.addHandler(give_ups)
    log.setLevel(logging.DEBUG)
    tried = refused = 0
    failures = []
    t0 = time.perf_counter()
    for k in range(args.pairs):
        g1, g2, q, t = draw_rotated_pair(rng)
        for op in ("union", "intersection", "difference"):
            why = run_one(g1, g2, q, t, op)
            if op == "union" and touch_only(g1, g2):
                refused += 1
                if why is None:
                    continue
            else:
                tried += 1
            if why is not None:
                case = (g1.tolist(), g2.tolist(), q.tolist(), t.tolist(), op)
                failures.append((k, case, why))
                print(f"pair {k}: {why}\n    {case!r},", flush=True)
    rate = len(failures) / max(tried, 1)
    print(f"seed {args.seed}: {len(failures)} failures in {tried} Booleans with a manifold exact result "
          f"({100 * rate:.2f} %), plus {refused} required refusals; the snap gave up {give_ups.count} times; "
          f"{time.perf_counter() - t0:.0f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
