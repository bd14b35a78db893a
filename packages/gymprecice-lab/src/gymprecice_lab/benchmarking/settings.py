"""``benchmark.json``: the settings that decide a benchmark's numbers, locked on disk.

A benchmark is resumed by running the same command again (a seed already trained is
kept), so a rerun with other settings would mix two benchmarks in one table. The
settings are written before anything runs and compared on every resume: a difference
is refused (``--fresh`` starts over), except an algorithm added to the list, which
trains alone beside the finished ones. A ``benchmark.json`` written before a setting
existed is read with the value it ran with.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from gymprecice_lab.benchmarking.checks import BenchmarkError
from gymprecice_lab.benchmarking.command_settings import BenchmarkSettings
from gymprecice_lab.common.registered_env import LabEnv

__all__ = ["SETTINGS_NAME", "lock_settings", "settings_of"]

SETTINGS_NAME = "benchmark.json"


def settings_of(benchmark: BenchmarkSettings, env: LabEnv, algos: list[str], extra: dict) -> dict:
    """Everything that decides the benchmark's numbers (compared on a resume), of the
    command's settings (its feedback defaults filled in) and what its checks settled."""
    return {
        "env": env.name,
        "env_id": env.env_id,
        "algos": algos,
        "seeds": list(range(benchmark.seeds)),
        "timesteps": benchmark.timesteps,
        "n_envs": benchmark.n_envs,
        "train_args": extra,
        "episode_time": benchmark.episode_time,
        "eval_time": benchmark.eval_time,
        "env_kwargs": benchmark.env_kwargs or {},
        "double": bool(benchmark.double),
        "baselines": None
        if benchmark.no_baselines
        else {
            "constants": benchmark.constants,
            "amplitudes": benchmark.amplitudes,
            "frequencies": benchmark.frequencies,
            "centre": benchmark.centre,
            "feedback_gains": benchmark.feedback_gains,
            "feedback_delays": benchmark.feedback_delays,
            "feedback_signal": benchmark.feedback_signal,
            # only where the env has a law: a benchmark.json written before resumes
            **({"feedback_grid": benchmark.feedback_grid} if env.feedback_law else {}),
        },
        "bootstrap_reps": benchmark.bootstrap_reps,
    }


def lock_settings(out: Path, settings: dict[str, Any], fresh: bool) -> None:
    """Write ``benchmark.json``, or refuse a rerun whose settings differ from it."""
    path = out / SETTINGS_NAME
    if fresh and out.exists():
        for name in ("train", "eval", "baselines"):
            shutil.rmtree(out / name, ignore_errors=True)
        path.unlink(missing_ok=True)
    if path.is_file():
        original = _with_defaults(json.loads(path.read_text()))
        saved = _with_added_seeds(_with_added_algorithms(original, settings), settings)
        changed = [
            f"{key} is {json.dumps(settings.get(key))} now but {json.dumps(saved.get(key))} "
            f"in the benchmark being resumed"
            for key in sorted(set(saved) | set(settings))
            if json.dumps(saved.get(key), sort_keys=True)
            != json.dumps(settings.get(key), sort_keys=True)
        ]
        if changed:
            raise BenchmarkError(
                f"cannot resume {out} with other settings: {'; '.join(changed)}. Rerun with "
                f"the settings in {path}, choose another --out, or add --fresh to start over"
            )
        added = [a for a in settings["algos"] if a not in original["algos"]]
        if added:
            print(
                f"gymprecice benchmark: adding {', '.join(a.upper() for a in added)}; what "
                f"{', '.join(a.upper() for a in original['algos'])} finished is kept",
                flush=True,
            )
        seeds, old = settings.get("seeds") or [], original.get("seeds") or []
        if len(seeds) > len(old):
            print(
                f"gymprecice benchmark: adding seed(s) {', '.join(map(str, seeds[len(old) :]))}; "
                f"what seed(s) {', '.join(map(str, old))} finished is kept",
                flush=True,
            )
    out.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")  # a kill mid-write keeps the settings whole
    tmp.write_text(json.dumps(settings, indent=2) + "\n")
    os.replace(tmp, path)


def _with_defaults(saved: dict[str, Any]) -> dict[str, Any]:
    """``saved`` with the settings that a benchmark written before they existed ran with."""
    baselines = saved.get("baselines")
    if isinstance(baselines, dict) and "centre" not in baselines:
        saved = {**saved, "baselines": {**baselines, "centre": 0.5}}
    return saved


def _with_added_seeds(saved: dict[str, Any], settings: dict[str, Any]) -> dict[str, Any]:
    """``saved`` as if it had named the seeds that ``settings`` adds after its own: more
    seeds of the same benchmark keep every finished seed, evaluation and baseline (fewer
    would drop finished ones from the table: refused as another setting)."""
    seeds, old = settings.get("seeds") or [], saved.get("seeds") or []
    if len(seeds) <= len(old) or seeds[: len(old)] != old:
        return saved
    return {**saved, "seeds": seeds}


def _with_added_algorithms(saved: dict[str, Any], settings: dict[str, Any]) -> dict[str, Any]:
    """``saved`` as if it had named the algorithms that ``settings`` adds, with their
    training flags: adding an algorithm to a benchmark keeps every finished seed,
    evaluation and baseline of the others, whose settings must still match."""
    algos, old = settings.get("algos") or [], saved.get("algos") or []
    added = [a for a in algos if a not in old]
    if not added or algos[: len(old)] != old:
        return saved
    train_args = {**saved.get("train_args", {})}
    train_args.update({a: settings.get("train_args", {}).get(a) for a in added})
    return {**saved, "algos": algos, "train_args": train_args}
