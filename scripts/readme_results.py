"""Write the README's results table from the benchmarks' result files, or check it.

The README is read on the repository's page, where no macro runs, so its table is
written here from docs/results/ (scripts/docs_macros.py's ``results_table``, the same
figures docs/benchmark.md quotes) between two marker lines:

    python scripts/readme_results.py          # rewrite the table
    python scripts/readme_results.py --check  # exit 1 when the README's table differs

tests/test_docs_figures.py runs the check, so a figure typed by hand, or a result file
replaced without rewriting the table, fails the tests.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
START = "<!-- results table: written by scripts/readme_results.py -->"
END = "<!-- end of results table -->"


def _macros():
    spec = importlib.util.spec_from_file_location(
        "docs_macros", Path(__file__).with_name("docs_macros.py")
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)
    spec.loader.exec_module(module)
    return module


def with_table(text: str, table: str) -> str:
    """``text`` with the block between the markers replaced by ``table``."""
    try:
        head, rest = text.split(START + "\n", 1)
        _, tail = rest.split(END, 1)
    except ValueError:
        raise SystemExit(f"README.md: the marker lines {START!r} and {END!r} are missing") from None
    return f"{head}{START}\n{table}\n{END}{tail}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check; exit 1 when it differs")
    args = parser.parse_args(argv)
    text = README.read_text()
    wanted = with_table(text, _macros().results_table())
    if args.check:
        if wanted != text:
            print(
                "README.md: the results table differs from docs/results/; run "
                "python scripts/readme_results.py",
                file=sys.stderr,
            )
            return 1
        return 0
    README.write_text(wanted)
    return 0


if __name__ == "__main__":
    sys.exit(main())
