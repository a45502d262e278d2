"""Fuzzing the STEP reader: corrupted files give a StepError or a valid solid, never anything else, never a hang.

Mutations (seeded, reproducible): byte flips, truncations, deleted and duplicated lines, swapped
references, random numbers in place of references, random numbers in place of numbers.  Inputs
are the corpus files (tests/data) and a hand-written box with a void (tests/io/step_samples.py).
The small file goes through the whole reader (parse, schema, faces, sewing, check) for two inputs
in three; the corpus files through the parser and the schema in the default run (speed) and the
whole reader in the slow run (except the screw, see ``SLOW``).  Each input runs under a wall-clock
alarm of ``TIME_LIMIT`` seconds.
"""

from __future__ import annotations

import random
import re
import signal
import time
from pathlib import Path

import pytest

from coons.errors import StepError
from coons.io.step.p21 import parse
from coons.io.step.reader import solids_from_p21
from coons.io.step.schema import StepModel
from coons.topology.shape import Solid
from tests.io.step_samples import box_mesh, polyhedron_step

DATA = Path(__file__).resolve().parents[1] / "data"
CORPUS = {p.name: p.read_bytes() for p in sorted(DATA.glob("*.step"))}
SMALL = polyhedron_step(*box_mesh((0, 0, 0), (10, 20, 30)), unit="inch",
                        voids=[box_mesh((2, 2, 2), (5, 5, 5))]).encode()

#: Corpus files read through parser + schema only even in the slow run: the screw's NURBS faces take
#: ~15 s to project and check, so a thousand of its mutants would take hours.
SLOW = {"occt-screw.step"}
#: Wall-clock bound per input (the largest corpus file reads in ~0.3 s on an idle machine).
TIME_LIMIT = 20.0

_REF = re.compile(rb"(?<==|,|\()\s*#(\d+)")
_NUM = re.compile(rb"(?<=[,(])-?\d+\.\d*(?:E[+-]?\d+)?")
_NUMBERS = [b"0", b"-1", b"1.E308", b"-0.", b"1.E-300", b"99999999999", b"3", b"2.5", b"#0", b"$", b"*", b".T."]


def mutate(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """One random corruption of ``data`` and its description."""
    kind = rng.randrange(7)
    n = len(data)
    if kind == 0:
        k = rng.randrange(n)
        b = rng.choice([rng.randrange(256), rng.choice(b"#();,'.$*=0123456789E-")])
        return data[:k] + bytes([b]) + data[k + 1:], f"byte {k} -> {b}"
    if kind == 1:
        k = rng.randrange(n)
        return data[:k], f"truncated at {k}"
    lines = data.split(b"\n")
    if kind == 2:
        k = rng.randrange(len(lines))
        return b"\n".join(lines[:k] + lines[k + 1:]), f"line {k + 1} deleted"
    if kind == 3:
        k = rng.randrange(len(lines))
        return b"\n".join(lines[:k + 1] + lines[k:]), f"line {k + 1} duplicated"
    refs = list(_REF.finditer(data))
    if kind == 4 and len(refs) > 1:
        a, b = sorted(rng.sample(range(len(refs)), 2))
        ra, rb = refs[a], refs[b]
        out = (data[:ra.start(1)] + rb.group(1) + data[ra.end(1):rb.start(1)] + ra.group(1) + data[rb.end(1):])
        return out, f"references {ra.group(1).decode()} and {rb.group(1).decode()} swapped"
    if kind == 5 and refs:
        r = rng.choice(refs)
        new = rng.choice([str(rng.randrange(1, 2 * len(refs) + 10)).encode(), str(rng.randrange(10**9)).encode()])
        return data[:r.start(1)] + new + data[r.end(1):], f"reference #{r.group(1).decode()} -> #{new.decode()}"
    nums = list(_NUM.finditer(data))
    if nums:
        m = rng.choice(nums)
        new = rng.choice(_NUMBERS)
        return data[:m.start()] + new + data[m.end():], f"number {m.group().decode()} -> {new.decode()}"
    return data[: n // 2], "halved"


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def _read(data: bytes, full: bool) -> None:
    """Run the reader; only StepError (raised) or valid solids may come out."""
    f = parse(data)
    if full:
        for s in solids_from_p21(f):
            assert isinstance(s, Solid) and s.check().ok
    else:
        StepModel(f).solids()


def run_fuzz(count: int, full_corpus: bool, seed: int = 2026) -> dict:
    rng = random.Random(seed)
    names = list(CORPUS)
    stats = {"inputs": 0, "step_error": 0, "valid": 0, "worst_seconds": 0.0}
    failures = []
    old = signal.signal(signal.SIGALRM, _alarm)
    try:
        for i in range(count):
            # per 4 inputs: two small files through the whole reader, one through parser + schema,
            # one corpus file (whole reader in the slow run)
            small = i % 4 != 3
            name = "small" if small else names[(i // 4) % len(names)]
            base = SMALL if small else CORPUS[name]
            data, what = mutate(base, rng)
            t0 = time.perf_counter()
            signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT)
            try:
                _read(data, full=(small and (i % 4 != 2 or full_corpus)) or (not small and full_corpus and name not in SLOW))
                stats["valid"] += 1
            except StepError as exc:
                if not str(exc):
                    failures.append((i, name, what, "StepError without a message"))
            except _Timeout:
                failures.append((i, name, what, f"no result within {TIME_LIMIT} s"))
            except Exception as exc:  # noqa: BLE001 - the point of the test is to catch anything else
                failures.append((i, name, what, f"{type(exc).__name__}: {exc}"[:300]))
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0.0)
            stats["worst_seconds"] = max(stats["worst_seconds"], time.perf_counter() - t0)
            stats["inputs"] += 1
    finally:
        signal.signal(signal.SIGALRM, old)
    stats["step_error"] = stats["inputs"] - stats["valid"] - len(failures)
    stats["failures"] = failures
    return stats


def test_fuzz_default():
    stats = run_fuzz(2000, full_corpus=False)
    assert stats["failures"] == [], stats["failures"][:5]
    assert stats["step_error"] > 500 and stats["valid"] > 100  # both outcomes are exercised


@pytest.mark.slow
def test_fuzz_full():
    stats = run_fuzz(10000, full_corpus=True, seed=7)
    assert stats["failures"] == [], stats["failures"][:5]
