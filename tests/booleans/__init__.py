"""Tests of coons.booleans (mirrors the package)."""
