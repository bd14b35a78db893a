"""The environment exactly as ``gymprecice train`` wraps it, and a trained model loaded into it.

A policy trained by the command acts in ``[-1, 1]`` (``RescaleAction``) on observations
that may be normalised (``VecNormalize``). Run against a bare ``gym.make`` env it would
act in the wrong units and be clipped at the bound without a word; so the same wrapping
lives here, for the command and for users::

    from gymprecice_lab.common.wrapped_env import load_policy

    venv, model = load_policy("runs/quickstart/train", "quickstart", double=True)
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    obs, reward, done, info = venv.step(action)
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from gymprecice_lab.common.registered_env import find_lab_env

if TYPE_CHECKING:
    from gymprecice.plugin.card import Reference

__all__ = [
    "ACTION_RMS",
    "EPISODE_METRICS_KEY",
    "EpisodeMetrics",
    "episode_keywords",
    "find_model",
    "load_normalizer",
    "load_policy",
    "make_env",
    "make_env_checked",
    "vecnormalize_path",
]

#: the episode's action RMS (in the env's own units), recorded for every env
ACTION_RMS = "action_rms"
#: the final step's ``info`` entry where :class:`EpisodeMetrics` puts every episode mean
EPISODE_METRICS_KEY = "episode_metrics"

_CHECKPOINT = re.compile(r"^(?P<prefix>[a-z0-9]+)_(?P<steps>\d+)_steps\.zip$")


def episode_keywords(env_id: str) -> tuple[str, ...]:
    """The Monitor columns of ``env_id`` after ``r, l, t``: ``mean_<name>`` for each metric
    its lab card names (``objective``, then ``metrics``), then ``action_rms``.

    A CSV's columns are fixed when the file is opened, before any step says what the
    env reports, so they come from the card: the cylinders' (``metrics=("Cd", "Cl")``)
    give ``mean_Cd, mean_Cl, action_rms``; a flap judged on its tip displacement gives
    ``mean_mean_tip_displacement, action_rms``; an env without a card ``action_rms``
    alone. TensorBoard records every metric the env reports (:data:`EPISODE_METRICS_KEY`).
    """
    from gymprecice.plugin.card import CardError, EnvCard, card_for
    from gymprecice_lab.common.registered_env import LabEnv

    try:
        card = card_for(env_id)
    except CardError:  # refused: every command says so; the env itself still runs
        card = EnvCard()
    names = LabEnv(env_id, card).episode_metrics
    return (*(f"mean_{name}" for name in names), ACTION_RMS)


class EpisodeMetrics(gym.Wrapper):
    """Add the episode's mean of every metric and its action RMS to the final ``info``.

    The Monitor records only what the last ``info`` of an episode holds; envs report
    per-step scalars in ``info["metrics"]`` (the cylinders' force coefficients, the flap's
    tip displacement). At the episode's end each one's mean over the steps that reported
    it becomes ``info["mean_<name>"]``, and all of them, with ``action_rms``, also
    ``info["episode_metrics"]`` (what TensorBoard records). A name in ``declared`` (the
    Monitor's columns) that the env never reported is NaN, so every episode fills the
    same columns. The action RMS is taken in the env's own units (this wrapper sits
    inside ``RescaleAction``).
    """

    def __init__(self, env: gym.Env, declared: tuple[str, ...] = ()) -> None:
        super().__init__(env)
        self.declared = tuple(declared)
        self._sums: dict[str, float] = {}
        self._counts: dict[str, int] = {}
        self._steps = 0
        self._action_sq = 0.0

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self._sums, self._counts, self._steps, self._action_sq = {}, {}, 0, 0.0
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        for name, value in (info.get("metrics") or {}).items():
            number = _scalar(value)
            if number is not None:
                self._sums[name] = self._sums.get(name, 0.0) + number
                self._counts[name] = self._counts.get(name, 0) + 1
        applied = np.asarray(info.get("action", action), dtype=float).reshape(-1)
        self._action_sq += float(np.mean(applied**2)) if applied.size else 0.0
        if terminated or truncated:
            means = {f"mean_{n}": total / self._counts[n] for n, total in self._sums.items()}
            for key in self.declared:
                means.setdefault(key, float("nan"))
            means[ACTION_RMS] = float(np.sqrt(self._action_sq / self._steps))
            info.update(means)
            info[EPISODE_METRICS_KEY] = means
        return obs, reward, terminated, truncated, info


def _scalar(value: Any) -> float | None:
    """``value`` as a float when it is one number (a metric); ``None`` otherwise."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return float(array) if array.ndim == 0 else None


def make_env(
    env_id: str,
    idx: int,
    kwargs: Mapping[str, Any],
    *,
    monitor_file: str | None = None,
    rescale: bool = True,
    robustness: Mapping[str, Any] | None = None,
    held_out: bool = False,
    validation: tuple[int, int] | None = None,
    score: Reference | None = None,
) -> gym.Env:
    """One environment as training and evaluation see it (module level: picklable).

    ``rescale`` maps a bounded ``Box`` action space to ``[-1, 1]``; ``monitor_file`` records
    episode returns, lengths and the episode means of :func:`episode_keywords` with SB3's
    ``Monitor``.
    ``robustness`` (:mod:`gymprecice.robustness`: sensor and action noise, delay,
    dropout) sits between the policy and the rescaled env, so noise is in the policy's
    units; the vector env's ``seed`` seeds it. ``held_out`` makes every reset take the
    env's held-out starts in turn (:class:`gymprecice_lab.common.starts.HeldOutStarts`);
    ``validation=(part, parts)`` its share of the validation starts
    (:class:`gymprecice_lab.common.starts.ValidationStarts`: the envs that choose the model a
    training run keeps); ``score`` makes each episode's return the fraction of that
    reference's floor it reaches once settled
    (:class:`gymprecice_lab.common.settled_score.SettledFloorScore`).
    """
    import gymprecice  # noqa: F401  (registers the gymprecice/... ids in this process)

    env: gym.Env = gym.make(env_id, idx=idx, **dict(kwargs))
    if held_out:
        from gymprecice_lab.common.starts import HeldOutStarts

        env = HeldOutStarts(env)
    if validation is not None:
        from gymprecice_lab.common.starts import ValidationStarts

        env = ValidationStarts(env, *validation)
    if score is not None:  # inside the Monitor, whose returns SB3's evaluation reads
        from gymprecice_lab.common.settled_score import SettledFloorScore

        env = SettledFloorScore(env, score)
    keywords = episode_keywords(env_id)
    env = EpisodeMetrics(env, keywords[:-1])
    space = env.action_space
    if (
        rescale
        and isinstance(space, gym.spaces.Box)
        and np.all(np.isfinite(space.low))
        and np.all(np.isfinite(space.high))
    ):
        unit = np.ones(space.shape, dtype=space.dtype)
        env = gym.wrappers.RescaleAction(env, -unit, unit)
    if robustness:
        from gymprecice.learners.robustness import wrap

        env = wrap(env, robustness)
    if monitor_file is not None:
        env = _monitor(env, monitor_file, keywords)
    return env


def make_env_checked(
    name: str, env_id: str, idx: int, kwargs: Mapping[str, Any], **options: Any
) -> gym.Env:
    """:func:`make_env` for a command: a constructor that rejects the settings (a wrong
    ``--env-kwargs``) becomes one line naming the flag, not a chained traceback."""
    try:
        return make_env(env_id, idx, kwargs, **options)
    except (TypeError, ValueError) as exc:
        reason = str(exc).split(" was raised from the environment creator")[0]
        given = {k: v for k, v in kwargs.items() if k != "run_root"}
        raise SystemExit(
            f"gymprecice: {name} does not accept these settings ({json.dumps(given)}): "
            f"{reason}; fix --env-kwargs (see the env class's docstring for its arguments)"
        ) from None


def _monitor(env: gym.Env, monitor_file: str, keywords: tuple[str, ...]) -> gym.Env:
    """SB3's Monitor, appending to the file of a resumed run on the same time axis.

    SB3 writes a header (with ``t_start``) only into a new file and measures ``t`` from
    the process's start; a resumed run therefore takes the first header's ``t_start``, so
    that ``load_results`` (``t + t_start``) gives wall-clock times that keep increasing.
    """
    from stable_baselines3.common.monitor import Monitor

    path = Path(monitor_file if monitor_file.endswith(".csv") else f"{monitor_file}.monitor.csv")
    t_start = _header_t_start(path)
    if t_start is not None:
        _align_columns(path, ("r", "l", "t", *keywords))
    monitor = Monitor(
        env,
        filename=monitor_file,
        override_existing=t_start is None,
        info_keywords=keywords,
    )
    if t_start is not None:
        monitor.t_start = t_start
    return monitor


def _header_t_start(path: Path) -> float | None:
    """``t_start`` of an existing Monitor file's header (``None``: start a new file)."""
    if not path.is_file():
        return None
    with path.open() as handle:
        first = handle.readline()
    try:
        return float(json.loads(first[1:])["t_start"]) if first.startswith("#") else None
    except (ValueError, KeyError, TypeError):
        return None


def _align_columns(path: Path, columns: tuple[str, ...]) -> None:
    """Give a resumed Monitor file the columns this run writes, keeping every value.

    SB3 appends rows in the order of its own columns and never rewrites the header, so a
    run resumed with other info keywords (a newer gymprecice, another card) would append
    rows under the wrong names. The file is rewritten (atomically) with this run's columns
    first, and any column only the old rows have after them: old rows keep all their
    values, new rows leave the trailing columns empty.
    """
    import csv
    import os

    with path.open(newline="") as handle:
        first = handle.readline()
        if not first.startswith("#"):
            return
        reader = csv.DictReader(handle)
        if tuple(reader.fieldnames or ()) == columns:
            return
        rows = list(reader)
        old = tuple(reader.fieldnames or ())
    fieldnames = [*columns, *(c for c in old if c not in columns)]
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="\n") as handle:
        handle.write(first)
        writer = csv.DictWriter(handle, fieldnames=fieldnames, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


# -- trained models ------------------------------------------------------------------------


def vecnormalize_path(model: Path) -> Path:
    """Where the ``VecNormalize`` statistics of a saved model are.

    SB3's checkpoints name them ``<prefix>_vecnormalize_<steps>_steps.pkl``; any other
    ``NAME.zip`` (``model.zip``, ``best_model.zip``, a shipped policy) has
    ``NAME_vecnormalize.pkl`` beside it.
    """
    match = _CHECKPOINT.match(model.name)
    if match:
        return model.with_name(f"{match['prefix']}_vecnormalize_{match['steps']}_steps.pkl")
    return model.with_name(f"{model.stem}_vecnormalize.pkl")


def load_normalizer(model_path: Path) -> Any:
    """The frozen ``VecNormalize`` statistics saved with a model (``None`` if none were)."""
    import pickle

    path = vecnormalize_path(model_path)
    if not path.is_file():
        return None
    with path.open("rb") as handle:
        stats = pickle.load(handle)
    stats.training = False
    return stats


def find_model(path: Path, which: str = "kept") -> tuple[Path, str | None]:
    """The model file for ``path`` (a ``.zip`` or a training directory) and a note.

    A training directory gives its kept model (the best of its validations,
    :mod:`gymprecice_lab.common.kept_model`) with ``which="kept"``, else or failing that its
    ``model.zip``, and the note says which; a run stopped before writing either (killed,
    out of time) gives its newest checkpoint, with a note saying so.
    ``FileNotFoundError`` explains what was looked for.
    """
    from gymprecice_lab.common.kept_model import choose_model

    if path.is_file():
        return path, None
    if path.is_dir():
        chosen = choose_model(path, which)
        if chosen is not None:
            return chosen
        newest = newest_checkpoint(path / "checkpoints")
        if newest is not None:
            return newest[0], f"no model.zip in {path}; using its newest checkpoint {newest[0]}"
        raise FileNotFoundError(f"no model.zip and no checkpoints/*_steps.zip in {path}")
    raise FileNotFoundError(f"no trained model at {path}")


def newest_checkpoint(directory: Path) -> tuple[Path, int] | None:
    """The intact checkpoint with the most env steps in ``directory`` (``None``: none).

    A run killed while it wrote a checkpoint (SIGKILL, the OOM killer, a job's time limit,
    a full disk) leaves it torn: a zip cut before its central directory, a replay buffer or
    ``VecNormalize`` pickle cut before its end, or one of them never written. Resuming from
    it would fail, or silently train on without its replay buffer; so a torn checkpoint is
    passed over with one line on stderr naming the torn file and the checkpoint used instead.
    """
    import sys

    if not directory.is_dir():
        return None
    found = []
    for path in directory.iterdir():
        match = _CHECKPOINT.match(path.name)
        if match:
            found.append((int(match["steps"]), path))
    found.sort(key=lambda item: (-item[0], item[1].name))
    torn: list[str] = []
    chosen: tuple[Path, int] | None = None
    for steps, path in found:
        problem = _torn_checkpoint(path, steps, [p for s, p in found if s != steps])
        if problem is None:
            chosen = (path, steps)
            break
        torn.append(problem)
    instead = f"using {chosen[0]} instead" if chosen else "no intact checkpoint is left"
    for problem in torn:
        print(f"gymprecice: {problem}; {instead}", file=sys.stderr)
    return chosen


#: Pickles up to this size are checked opcode by opcode; larger ones by their last byte.
_WALKED_PICKLE_BYTES = 64 * 1024 * 1024


def _torn_checkpoint(path: Path, steps: int, others: list[Path]) -> str | None:
    """What is torn in the checkpoint ``path`` (``None``: it is intact).

    Its companions are its ``VecNormalize`` statistics and replay buffer: checked where
    they exist, and missing where another checkpoint has its own (a run saves the same
    files each time, the zip first).
    """
    if not _zip_intact(path):
        return f"checkpoint {path} is torn (not a complete zip archive)"
    prefix = path.name.split("_", 1)[0]
    for companion in (_replay_buffer_path, vecnormalize_path):
        extra = companion(path)
        if extra.is_file():
            if not _pickle_intact(extra):
                return f"checkpoint {path} is torn ({extra.name} is cut short)"
        elif any(companion(other).is_file() for other in others if other.name.startswith(prefix)):
            return f"checkpoint {path} is torn ({extra.name} was never written)"
    return None


def _replay_buffer_path(model: Path) -> Path:
    """``<algo>_replay_buffer_<steps>_steps.pkl`` beside a checkpoint (SB3's name)."""
    match = _CHECKPOINT.match(model.name)
    if not match:
        return model.with_name(f"{model.stem}_replay_buffer.pkl")
    return model.with_name(f"{match['prefix']}_replay_buffer_{match['steps']}_steps.pkl")


def _zip_intact(path: Path) -> bool:
    """A readable zip whose members all match their CRCs, with SB3's ``data`` in it."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            return "data" in archive.namelist() and archive.testzip() is None
    except (OSError, EOFError, zipfile.BadZipFile, ValueError, RuntimeError):
        return False


def _pickle_intact(path: Path) -> bool:
    """Whether a pickle reaches its STOP opcode, without building any object from it."""
    import pickletools

    try:
        size = path.stat().st_size
        with path.open("rb") as handle:
            if size < 2 or handle.read(1) != b"\x80":  # PROTO: protocol 2 or later
                return False
            if size > _WALKED_PICKLE_BYTES:
                handle.seek(-1, os.SEEK_END)
                return handle.read(1) == b"."
            handle.seek(0)
            for opcode, _, _ in pickletools.genops(handle):
                if opcode.name == "STOP":
                    return True
    except Exception:  # a cut opcode or argument: ValueError, struct.error, EOFError, ...
        return False
    return False


def load_model(path: Path, device: str = "cpu") -> Any:
    """A saved SB3 model of any algorithm ``gymprecice train`` offers (PPO, SAC, TD3,
    sb3-contrib's TQC), told apart by its policy's class."""
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(path, device=device, load_data=True)
    policy = str((data or {}).get("policy_class", "")).lower()
    if "tqc" in policy:
        from sb3_contrib import TQC

        return TQC.load(path, device=device)
    cls = SAC if "sac" in policy else TD3 if "td3" in policy else PPO
    return cls.load(path, device=device)


def load_policy(
    model: str | os.PathLike[str],
    env: str,
    *,
    idx: int = 0,
    device: str = "cpu",
    which: str = "kept",
    **env_kwargs: Any,
) -> tuple[Any, Any]:
    """``(vec_env, model)``: the env ``gymprecice train`` trained on, and the model in it.

    ``model`` is a ``.zip`` or a training directory (see :func:`find_model`: its kept
    model, or with ``which="final"`` its final one); ``env`` a
    registered id or short name; ``env_kwargs`` go to the env (e.g. ``double=True``,
    ``episode_time=10``). The vector env rescales actions like training did and, when the
    model was trained with ``--normalize``, normalises observations with the saved
    statistics (frozen: evaluation does not update them). A policy trained
    ``--shared-policy`` gets the vector env it trained in: one slot per agent of the joint
    env (:class:`~gymprecice.multiagent.sb3.SharedPolicyVecEnv`), each slot one agent's row.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from gymprecice_lab.training.shared_policy import per_row

    path, _ = find_model(Path(model), which)
    spec = find_lab_env(env)
    loaded = load_model(path, device=device)
    venv: Any = DummyVecEnv([lambda: make_env(spec.env_id, idx, env_kwargs)])
    if per_row(loaded.observation_space.shape, venv.observation_space.shape):
        from gymprecice.multiagent.sb3 import SharedPolicyVecEnv

        venv = SharedPolicyVecEnv(venv)
    stats = vecnormalize_path(path)
    if stats.is_file():
        venv = VecNormalize.load(str(stats), venv)
        venv.training = False
        venv.norm_reward = False
    return venv, loaded
