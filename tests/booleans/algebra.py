"""Shared assertion of the curved-Boolean tests: the three results are valid and obey the volume algebra."""

from __future__ import annotations

#: Relative tolerance of the algebra identities (coons alone).
RTOL_ALGEBRA = 1e-9


def assert_valid_and_algebraic(name: str, a, b, results: dict) -> None:
    """Each of ``results`` (``{"union" | "intersection" | "difference": Shape}``) passes ``check``, and
    ``vol(A ∪ B) + vol(A ∩ B) = vol(A) + vol(B)``, ``vol(A − B) = vol(A) − vol(A ∩ B)`` to :data:`RTOL_ALGEBRA`."""
    for op, res in results.items():
        rep = res.check()
        assert rep.ok, f"{name} {op}: {rep.summary()}"
    u, i, d = (results[op].volume for op in ("union", "intersection", "difference"))
    assert abs(u + i - a.volume - b.volume) <= RTOL_ALGEBRA * (a.volume + b.volume)
    assert abs(d - a.volume + i) <= RTOL_ALGEBRA * a.volume
