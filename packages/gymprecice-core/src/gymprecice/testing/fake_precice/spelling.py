"""The "did you mean ..." of preCICE's messages about unknown meshes and data."""

from __future__ import annotations

from collections.abc import Iterable


def edit_distance(a: str, b: str) -> int:
    row = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, cb in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (ca != cb))
    return row[-1]


def best_match(given: str, candidates: Iterable[str]) -> tuple[int, str] | None:
    scored = sorted((edit_distance(given, c), c) for c in candidates)
    return scored[0] if scored else None
