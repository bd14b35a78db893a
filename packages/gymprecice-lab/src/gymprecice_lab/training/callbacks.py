"""What ``gymprecice train`` adds to Stable-Baselines3's training loop, and why.

* :class:`RotatingCheckpoints`: SB3's ``CheckpointCallback`` keeps every checkpoint (8 MB
  each with a 512x512 net, a gigabyte over a long run); this keeps the newest ``keep`` and
  the best one (highest mean episode return when it was saved);
* :class:`EpisodeMetricsCallback`: the envs' episode means (of every metric they report in
  ``info["metrics"]``, and the action RMS) in TensorBoard and ``progress.csv``, next to the
  return;
* :func:`stop_signals_interrupt`: SIGTERM (SLURM preemption, ``timeout``), SIGHUP (a
  closed terminal) and Ctrl-C stop training, so the policy is saved, but never in the
  middle of a gradient update; around the save, :func:`hold_stop_signals` keeps a
  repeated signal from cutting it short;
* :func:`save_checkpoint`: every file of a checkpoint is written under a temporary name
  and renamed into place once whole, the model's zip last. A cluster sends SIGKILL a grace
  period after SIGTERM (SLURM: 30 s by default); a save it cuts short leaves only a
  temporary file (removed by the next run, :func:`remove_partial_saves`), never a torn
  checkpoint under a checkpoint's name, so the previous checkpoint stays the newest.
  SAC's save after SIGTERM with SB3's replay buffer of 100,000 transitions (122 MB of
  pickle for the jet cylinders' 151 probes) takes about a second on a local disk; a
  larger buffer on a slow shared file system can take longer than a grace period.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

from gymprecice_lab.common.wrapped_env import EPISODE_METRICS_KEY, vecnormalize_path

__all__ = [
    "BEST_NAME",
    "EpisodeMetricsCallback",
    "Interrupted",
    "RotatingCheckpoints",
    "StopOnSignal",
    "hold_stop_signals",
    "prune_checkpoints",
    "read_best",
    "remove_partial_saves",
    "save_checkpoint",
    "stop_signals_interrupt",
]

BEST_NAME = "best.json"
#: what a file being saved is called until it is whole: ``.<name>.partial`` beside it
PARTIAL_SUFFIX = ".partial"


class Interrupted(KeyboardInterrupt):
    """Training was stopped by a signal; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM, SIGHUP and Ctrl-C raise :class:`Interrupted`.

    Installed after the vector env's workers are started, so that they keep the default
    handlers and die with the job. Only the first one raises: a scheduler that preempts
    a job signals every process of it, and a batch script passes the signal on too, so a
    second SIGTERM often follows the first within milliseconds; raised again, it would
    cut short the unwinding that the first one started.

    A signal that lands inside a gradient update waits for the update to end, and
    :class:`StopOnSignal` raises it at the next env step: torch's optimizers write their
    state key by key (Adam: ``step``, then ``exp_avg``, then ``exp_avg_sq``), and a model
    saved between two keys cannot be resumed (``KeyError: 'exp_avg'`` at the first update
    after the resume). Waiting costs at most one update.
    """
    previous = {}
    received = _received
    received.clear()

    def handler(signum: int, frame: Any) -> None:
        if received:
            return  # a repeat of the stop signal being obeyed
        received.append(signum)
        if _inside_update(frame):
            return  # raised at the next env step, once the update is whole
        raise Interrupted(signum)

    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        received.clear()


#: where a gradient update runs: torch's optimizers, and the algorithms' ``train``
_UPDATE_PATHS = ("/torch/optim/", "/stable_baselines3/", "/sb3_contrib/")


def _inside_update(frame: Any) -> bool:
    """Whether the interrupted code is a gradient update (see :func:`stop_signals_interrupt`)."""
    while frame is not None:
        code = frame.f_code
        path = code.co_filename.replace(os.sep, "/")
        if _UPDATE_PATHS[0] in path:
            return True
        if code.co_name == "train" and any(part in path for part in _UPDATE_PATHS[1:]):
            return True
        frame = frame.f_back
    return False


#: the stop signal received inside the current :func:`stop_signals_interrupt` block
_received: list[int] = []


class StopOnSignal(BaseCallback):
    """Raise a received stop signal again at the next step.

    The handler's exception is lost where it lands in code that swallows exceptions: a
    finaliser, or logging's lock release ("Exception ignored in ..."). Training would then
    go on as if nothing was received, and only the first signal raises. Seen as a
    training that outlived its killed ``gymprecice tune``.
    """

    def _on_step(self) -> bool:
        if _received:
            raise Interrupted(_received[0])
        return True


@contextlib.contextmanager
def hold_stop_signals() -> Iterator[list[int]]:
    """Within the block, SIGTERM and SIGHUP are noted in the list it gives, not obeyed.

    Around what must finish once begun, the final save above all: a stop signal that
    arrives then (the repeat of one that stopped training, a scheduler's after the batch
    script's) would otherwise end the process mid-save with the default action; SIGKILL
    still ends it. A :func:`stop_signals_interrupt` block inside obeys them as usual.
    """
    held: list[int] = []
    previous = {
        sig: signal.signal(sig, lambda signum, frame: held.append(signum))
        for sig in (signal.SIGTERM, signal.SIGHUP)
    }
    try:
        yield held
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
        tmp = _partial(directory / BEST_NAME)  # whole or not at all, as the checkpoints
        tmp.write_text(json.dumps(record, indent=2) + "\n")
        os.replace(tmp, directory / BEST_NAME)


def _partial(path: Path) -> Path:
    """The temporary name ``path`` is written under until it is whole."""
    return path.with_name(f".{path.name}{PARTIAL_SUFFIX}")


def save_checkpoint(
    model: Any,
    path: Path,
    *,
    replay_buffer: Path | None = None,
    stats: Any = None,
    stats_path: Path | None = None,
) -> None:
    """Save ``model`` to ``path`` (a zip), its replay buffer to ``replay_buffer`` and the
    ``VecNormalize`` ``stats`` to ``stats_path``, each whole or not at all.

    Every file is written under a temporary name beside its own (``.<name>.partial``);
    once all are written they are renamed into place, the zip last. A kill at any moment
    (SIGKILL after a preemption's grace period, the OOM killer) leaves either the whole
    checkpoint or none of it under a checkpoint's name: what was there before (an
    earlier checkpoint, the same name saved before) stays whole. A save that fails
    removes its temporary files; one that is killed leaves them to
    :func:`remove_partial_saves`.
    """
    writes: list[tuple[Path, Any]] = []
    if stats is not None and stats_path is not None:
        writes.append((stats_path, lambda tmp: stats.save(str(tmp))))
    if replay_buffer is not None and getattr(model, "replay_buffer", None) is not None:
        writes.append((replay_buffer, model.save_replay_buffer))
    writes.append((path, model.save))  # renamed last: a checkpoint's zip means it is whole
    path.parent.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        for target, save in writes:
            written.append(_partial(target))
            save(written[-1])
        for (target, _), tmp in zip(writes, written):
            os.replace(tmp, target)
    finally:
        for tmp in written:
            tmp.unlink(missing_ok=True)  # what was not renamed: a save that failed


def remove_partial_saves(directory: Path, prefix: str | None = None) -> list[Path]:
    """Remove what saves killed mid-way left in ``directory``; return what was removed.

    Temporary files (``.<name>.partial``) of :func:`save_checkpoint`, and with ``prefix``
    the replay buffers and ``VecNormalize`` statistics whose checkpoint zip is missing (a
    kill between their rename and the zip's, or mid-way through
    :func:`prune_checkpoints`): hundreds of megabytes each, which nothing would read.
    """
    if not directory.is_dir():
        return []
    removed = [p for p in directory.glob(f".*{PARTIAL_SUFFIX}") if p.is_file()]
    if prefix is not None:
        for kind in ("replay_buffer", "vecnormalize"):
            for path in directory.glob(f"{prefix}_{kind}_*_steps.pkl"):
                steps = path.name[len(f"{prefix}_{kind}_") : -len("_steps.pkl")]
                if steps.isdigit() and not (directory / f"{prefix}_{steps}_steps.zip").exists():
                    removed.append(path)
    for path in removed:
        path.unlink(missing_ok=True)
    return removed


class RotatingCheckpoints(CheckpointCallback):
    """SB3's ``CheckpointCallback`` that keeps only the newest ``keep`` and the best, and
    saves each checkpoint whole or not at all (:func:`save_checkpoint`)."""

    def __init__(self, *args: Any, keep: int, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.keep = keep

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq == 0:
            directory = Path(self.save_path)
            path = Path(self._checkpoint_path(extension="zip"))
            save_checkpoint(
                self.model,
                path,
                replay_buffer=(
                    Path(self._checkpoint_path("replay_buffer_", extension="pkl"))
                    if self.save_replay_buffer
                    else None
                ),
                stats=self.model.get_vec_normalize_env() if self.save_vecnormalize else None,
                stats_path=Path(self._checkpoint_path("vecnormalize_", extension="pkl")),
            )
            record_checkpoint(directory, path, self.model)
            prune_checkpoints(directory, self.name_prefix, self.keep)
        return True


class EpisodeMetricsCallback(BaseCallback):
    """Log each finished episode's means (``env/mean_Cd``, ``env/mean_tip_displacement``,
    ..., ``env/action_rms``).

    :class:`~gymprecice_lab.common.wrapped_env.EpisodeMetrics` puts every metric the env reported, as
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
