"""The vector package's rooms import in one direction: no module imports its importer.

The pool makes backends (it imports them, lazily); the backends and the pool read the
contract (``Reply``, ``CRASH``, ``TIMEOUT``, the ``Backend`` and ``Host`` protocols) from
``vector/contract.py``, which imports neither. Checked on the source, at every level of
the file (an import inside a function is still a dependency).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

VECTOR = Path(__file__).resolve().parents[1] / "src" / "gymprecice" / "vector"


def imported_modules(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


@pytest.mark.parametrize("backend", ["local.py", "ray.py"])
def test_backends_read_the_contract_not_the_pool(backend: str) -> None:
    imports = imported_modules(VECTOR / backend)
    assert "gymprecice.vector.pool" not in imports
    assert "gymprecice.vector.contract" in imports


def test_the_contract_imports_neither_the_pool_nor_a_backend() -> None:
    imports = imported_modules(VECTOR / "contract.py")
    for room in ("pool", "local", "ray", "gymnasium", "host"):
        assert f"gymprecice.vector.{room}" not in imports


def test_the_pool_makes_backends_and_reads_the_contract() -> None:
    """The other direction is there (so the checks above read real imports)."""
    pool = imported_modules(VECTOR / "pool.py")
    assert "gymprecice.vector.local" in pool  # the pool makes the local backend
    assert "gymprecice.vector.contract" in pool
