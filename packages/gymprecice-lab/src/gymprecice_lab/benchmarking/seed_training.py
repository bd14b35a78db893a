"""One seed's training, kept when finished, re-run when it fails.

A seed is never silently dropped from the aggregate: a training that fails (an exit
status, a crash) is reported and re-run up to ``--retries`` times, each rerun resuming
from the newest checkpoint; one that still fails stops the benchmark. Every failed
attempt is recorded in the seed's ``benchmark-failures.json`` as it fails, across reruns
of the benchmark; with the envs its vector env re-created (a lost Ray node, a crashed or
hung solver: ``workers/failures.jsonl``) they are the seed's restarts that the results
report (:func:`restarts`). A training stopped by a signal is the user's and is not
retried. A seed already trained to ``--timesteps`` is kept.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from gymprecice_lab.benchmarking.checks import BenchmarkError
from gymprecice_lab.common.command_runs import exit_status_of, parse_command

__all__ = ["restarts", "train_seed", "trained", "training_record", "worker_train_seed"]

#: a seed's failed training attempts (a JSON list, one line of text each)
FAILURES_FILE = "benchmark-failures.json"


def trained(run: Path, timesteps: int, stop_at: float | None = None) -> bool:
    """Whether ``run`` holds a finished training: of at least ``timesteps`` steps, or
    stopped by a ``--stop-at`` whose kept model scores ``stop_at`` too (a run stopped at
    0.95 is not finished for a benchmark that now stops at 0.97: it trains on)."""
    try:
        result = json.loads((run / "manifest.json").read_text()).get("result") or {}
    except (OSError, ValueError):
        return False
    stopped = result.get("stopped_at") or {}
    reached = bool(stopped) and (
        stop_at is None or float(stopped.get("value") or float("-inf")) >= stop_at
    )
    return (
        (run / "model.zip").is_file()
        and not result.get("interrupted")
        and (int(result.get("timesteps") or 0) >= timesteps or reached)
    )


def _train_once(argv: list[str]) -> int:
    """One ``gymprecice train`` (its exit status); an exception is a failed training."""
    ns = parse_command(argv)
    return int(ns.func(ns) or 0)


def train_seed(argv: list[str], run: Path, label: str, retries: int) -> None:
    """Train one seed, re-running a failed attempt up to ``retries`` times (a rerun
    resumes from the attempt's newest checkpoint)."""
    failures: list[str] = []
    for attempt in range(retries + 1):
        try:
            status = _train_once(argv)
        except Exception as exc:  # a crashed training: report, then run it again
            status, reason = 1, f"{type(exc).__name__}: {exc}"
        else:
            reason = f"exit status {status}"
        if status == 0:
            return
        if status > 128:  # stopped by a signal (Ctrl-C, SIGTERM): the user's, not a failure
            raise BenchmarkError(
                f"{label}: training stopped by a signal ({reason}); run the same command "
                "again to resume",
                status,
            )
        failures.append(f"attempt {attempt + 1}: {reason}")
        _record_failure(run, failures[-1])
        print(
            f"gymprecice benchmark: {label}: training failed ({reason})"
            + ("; running it again" if attempt < retries else ""),
            file=sys.stderr,
            flush=True,
        )
    raise BenchmarkError(
        f"{label}: training failed {len(failures)} time(s) ({'; '.join(failures)}); no table "
        f"is written without it (see {run}); fix the cause and run the same command again "
        "(finished seeds are kept)",
        1,
    )


def _record_failure(run: Path, failure: str) -> None:
    """Add a failed attempt to the seed's record (kept across reruns of the benchmark)."""
    run.mkdir(parents=True, exist_ok=True)
    path = run / FAILURES_FILE
    try:
        earlier = json.loads(path.read_text())
    except (OSError, ValueError):
        earlier = []
    path.write_text(json.dumps([*earlier, failure], indent=2) + "\n")


def restarts(run: Path) -> dict[str, int]:
    """How often the training in ``run`` was restarted: ``"env_restarts"``, envs its
    vector env re-created (each line of its ``workers/failures.jsonl``: a lost Ray node, a
    crashed or hung solver), and ``"training_reruns"``, times it was re-run from its
    newest checkpoint after it failed."""
    from gymprecice.vector.pool import FAILURES_FILE as ENV_FAILURES

    def count(path: Path, read) -> int:
        try:
            return len(read(path.read_text()))
        except (OSError, ValueError):
            return 0

    return {
        "env_restarts": count(run / "workers" / ENV_FAILURES, str.splitlines),
        "training_reruns": count(run / FAILURES_FILE, json.loads),
    }


def training_record(run: Path) -> dict[str, Any]:
    """What a seed's training cost and kept: its steps and its training time (over its
    segments, the gaps between them left out), its validations (each step and the mean
    score over the validation starts: whether the budget was enough), and the kept
    model's step, validation score and training time at its save (``kept`` ``None``: it
    kept none)."""
    from gymprecice_lab.common.kept_model import RETURN_SCORE, read_kept
    from gymprecice_lab.common.manifest import read_manifest
    from gymprecice_lab.common.training_clock import total_training_seconds, training_seconds

    try:
        manifest = read_manifest(run)
        written = (run / "manifest.json").stat().st_mtime  # its last write: the run's end
    except (OSError, ValueError):
        manifest, written = {}, None
    segments = manifest.get("segments") or []
    total = total_training_seconds(segments, written)
    record: dict[str, Any] = {
        "timesteps": (manifest.get("result") or {}).get("timesteps"),
        "segments": len(segments),
        "training_seconds": None if total is None else round(total, 1),
        "validations": _validations(run),
        "kept": None,
    }
    kept = read_kept(run)
    if kept is not None:
        seconds = kept.get("seconds_of_training")
        if seconds is None and kept.get("saved_at") is not None:  # recorded before it
            seconds = training_seconds(segments, float(kept["saved_at"]))
        record["kept"] = {
            "timesteps": kept.get("timesteps"),
            "score": kept.get("score") or RETURN_SCORE,
            "value": kept.get("mean_return"),
            "training_seconds": None if seconds is None else round(float(seconds), 1),
        }
    return record


def _validations(run: Path) -> list[list[float]]:
    """``[[step, mean score], ...]`` of the run's validations (``eval/evaluations.npz``,
    SB3's record, kept across resumes); none for a run trained without them."""
    import numpy as np

    try:
        with np.load(run / "eval" / "evaluations.npz") as data:
            steps, results = data["timesteps"], data["results"]
    except (OSError, ValueError, KeyError):
        return []
    return [
        [int(step), round(float(np.mean(row)), 6)] for step, row in zip(steps, results, strict=True)
    ]


def worker_train_seed(argv: list[str], run: str, label: str, retries: int) -> int:
    """:func:`train_seed` in a pool's worker (0: trained)."""
    return exit_status_of(train_seed, argv, Path(run), label, retries)
