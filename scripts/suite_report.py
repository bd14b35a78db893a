"""Where the test suite's time went, and whether it stayed inside its budget.

    python scripts/suite_report.py [--budget SECONDS] [--setup-times FILE] DURATIONS.json...

Reads the durations files the sessions of ``scripts/test.sh`` wrote (``GYMPRECICE_DURATIONS``,
see conftest.py), prints the set-up's time split (when given), each session's wall-clock, the
suite's (sessions that ran side by side count once) and its slowest tests; exits 1 when the
suite's wall-clock is over ``--budget``, naming the slowest tests: whoever pushes the suite
past its budget sees which tests to make cheaper. Standard library only: it runs before
anything is installed too.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

#: How many of the slowest tests are listed.
SLOWEST = 30


def minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:02.0f} s"


def load(paths: list[Path]) -> list[dict]:
    sessions = []
    for path in paths:
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise SystemExit(
                f"suite_report: cannot read {path} ({exc}); was the session run?"
            ) from None
        data.setdefault("tier", path.stem)
        sessions.append(data)
    return sessions


def suite_wall(sessions: list[dict]) -> float:
    """The suite's wall-clock: the sessions' sum, but time that sessions run side by side
    (``scripts/test.sh`` runs the rest tier's two parts at once) counts once. Sessions of
    files without a start time are taken as one after another."""
    if not all("started_at" in s for s in sessions):
        return sum(s["wall_s"] for s in sessions)
    spans = sorted((s["started_at"], s["started_at"] + s["wall_s"]) for s in sessions)
    total, end = 0.0, float("-inf")
    for start, stop in spans:
        total += max(0.0, stop - max(start, end))
        end = max(end, stop)
    return total


def report(sessions: list[dict], budget: float | None, setup_times: str = "") -> tuple[str, bool]:
    """The report's text, and whether the suite is inside its budget."""
    lines: list[str] = []
    if setup_times.strip():
        lines += ["== set-up ==", setup_times.rstrip()]
    lines.append("== test suite ==")
    wall = suite_wall(sessions)
    for s in sessions:
        tests = s["tests"]
        cpu = sum(t.get("cpu_s", 0.0) for t in tests)
        lines.append(
            f"  {s['tier']:<12} {minutes(s['wall_s']):>14}  ({len(tests)} tests, "
            f"{cpu / 60:.1f} CPU-min)"
        )
    budget_text = f" (budget {minutes(budget)})" if budget is not None else ""
    total = sum(s["wall_s"] for s in sessions)
    overlap = f" ({minutes(total)} of sessions, some side by side)" if total - wall > 1 else ""
    lines.append(f"  {'suite':<12} {minutes(wall):>14}{budget_text}{overlap}")
    tests = sorted(
        (t for s in sessions for t in s["tests"]), key=lambda t: -float(t.get("seconds", 0.0))
    )
    lines.append(f"== the {min(SLOWEST, len(tests))} slowest tests (wall, CPU) ==")
    for t in tests[:SLOWEST]:
        lines.append(f"  {t['seconds']:7.1f} s {t.get('cpu_s', 0.0):7.1f} s  {t['nodeid']}")
    inside = budget is None or wall <= budget
    if not inside:
        lines.append(
            f"FAILED: the test suite took {minutes(wall)}, over its budget of {minutes(budget)}. "
            "Make the slowest tests above cheaper (share their cases and pre-runs, shorten "
            "simulated time their assertions do not need; docs/contributing/test-suite.md) "
            "rather than raising the budget."
        )
    return "\n".join(lines), inside


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("durations", nargs="+", type=Path, help="durations files (JSON)")
    parser.add_argument("--budget", type=float, default=None, help="the suite's budget, s")
    parser.add_argument("--setup-times", type=Path, default=None, help="the set-up's split")
    args = parser.parse_args(argv)
    setup = ""
    if args.setup_times is not None and args.setup_times.is_file():
        setup = args.setup_times.read_text()
    text, inside = report(load(args.durations), args.budget, setup)
    print(text)
    return 0 if inside else 1


if __name__ == "__main__":
    sys.exit(main())
