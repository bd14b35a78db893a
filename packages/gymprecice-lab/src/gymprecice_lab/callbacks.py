"""What ``gymprecice train`` adds to Stable-Baselines3's training loop, and why.

* :class:`RotatingCheckpoints`: SB3's ``CheckpointCallback`` keeps every checkpoint (8 MB
  each with a 512x512 net, a gigabyte over a long run); this keeps the newest ``keep`` and
  the best one (highest mean episode return when it was saved);
* :class:`EpisodeMetricsCallback`: the envs' episode means (of every metric they report in
  ``info["metrics"]``, and the action RMS) in TensorBoard and ``progress.csv``, next to the
  return;
* :func:`stop_signals_interrupt`: SIGTERM (SLURM preemption, ``timeout``) and SIGHUP (a
  closed terminal) stop training the way Ctrl-C does, so the policy is saved.
"""

from __future__ import annotations

import contextlib
import json
import math
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

from gymprecice_lab.envs import EPISODE_METRICS_KEY, vecnormalize_path

__all__ = [
    "BEST_NAME",
    "EpisodeMetricsCallback",
    "Interrupted",
    "RotatingCheckpoints",
    "prune_checkpoints",
    "read_best",
    "stop_signals_interrupt",
]

BEST_NAME = "best.json"


class Interrupted(KeyboardInterrupt):
    """Training was stopped by a signal; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Interrupted` like Ctrl-C would.

    Installed after the vector env's workers are started, so that they keep the default
    handlers and die with the job.
    """
    previous = {}

    def handler(signum: int, frame: Any) -> None:
        raise Interrupted(signum)

    for sig in (signal.SIGTERM, signal.SIGHUP):
        previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _mean_return(model: Any) -> float | None:
    episodes = [float(e["r"]) for e in getattr(model, "ep_info_buffer", None) or []]
    return float(np.mean(episodes)) if episodes else None


def prune_checkpoints(directory: Path, prefix: str, keep: int) -> list[Path]:
    """Delete all but the newest ``keep`` checkpoints and the best one; return the deleted.

    Each checkpoint's ``VecNormalize`` statistics and replay buffer go with it.
    """
    best = read_best(directory).get("name")
    found = []
    for path in directory.glob(f"{prefix}_*_steps.zip"):
        steps = path.name[len(prefix) + 1 : -len("_steps.zip")]
        if steps.isdigit():
            found.append((int(steps), path))
    found.sort()
    deleted = []
    for steps, path in found[: max(0, len(found) - keep)]:
        if path.name == best:
            continue
        for extra in (
            path,
            vecnormalize_path(path),
            path.with_name(f"{prefix}_replay_buffer_{steps}_steps.pkl"),
        ):
            extra.unlink(missing_ok=True)
        deleted.append(path)
    return deleted


def read_best(directory: Path) -> dict[str, Any]:
    """The best checkpoint's record in ``directory`` (``name``, ``timesteps``, ``mean_return``);
    empty when there is none or it cannot be read."""
    try:
        return json.loads((directory / BEST_NAME).read_text())
    except (OSError, ValueError):
        return {}


def record_checkpoint(directory: Path, path: Path, model: Any) -> None:
    """Make ``path`` the best checkpoint if its mean episode return beats the recorded one."""
    score = _mean_return(model)
    if score is None or not math.isfinite(score):
        return
    best = read_best(directory)
    if best.get("mean_return") is None or score > float(best["mean_return"]):
        record = {"name": path.name, "timesteps": int(model.num_timesteps), "mean_return": score}
        (directory / BEST_NAME).write_text(json.dumps(record, indent=2) + "\n")


class RotatingCheckpoints(CheckpointCallback):
    """SB3's ``CheckpointCallback`` that keeps only the newest ``keep`` and the best."""

    def __init__(self, *args: Any, keep: int, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.keep = keep

    def _on_step(self) -> bool:
        result = super()._on_step()
        if self.n_calls % self.save_freq == 0:
            directory = Path(self.save_path)
            record_checkpoint(directory, Path(self._checkpoint_path(extension="zip")), self.model)
            prune_checkpoints(directory, self.name_prefix, self.keep)
        return result


class EpisodeMetricsCallback(BaseCallback):
    """Log each finished episode's means (``env/mean_Cd``, ``env/mean_tip_displacement``,
    ..., ``env/action_rms``).

    :class:`~gymprecice_lab.envs.EpisodeMetrics` puts every metric the env reported, as
    its episode mean, into the final step's ``info["episode_metrics"]``: whatever the env
    is, its own metrics are logged (SB3 itself logs only the return and length). A metric
    that is NaN (declared by the card, never reported) is left out.
    """

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", []):
            means = info.get(EPISODE_METRICS_KEY)
            if not means:
                continue
            for key, value in means.items():
                if value is not None and math.isfinite(float(value)):
                    self.logger.record_mean(f"env/{key}", float(value))
        return True
