"""The learning algorithm and its hyperparameters, as ``gymprecice train`` resolves them.

Precedence, as in RL Zoo: the algorithm's defaults here, then ``--hyperparams FILE.yaml``,
then the flags typed on the command line. The resolved set is written to
``<out>/hyperparams.json`` when a run starts; a resumed run must resolve to the same set,
because SB3 keeps a saved model's values and would otherwise silently train with other
hyperparameters than the ones recorded.

The command's side lives here too: :func:`hyperparameters` reads the file and the flags of
its settings (:class:`~gymprecice_lab.training.command_settings.TrainSettings`), :func:`with_robustness` adds ``--wrap``, :func:`refuse_changed_resume` and
:func:`keep_hyperparameters` hold a resume to the recorded set, and
:func:`adjust_batch_size` clamps PPO's mini-batch to its rollout buffer.
"""

from __future__ import annotations

import inspect
import json
import math
import shutil
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.wrapping import wrap_spec
from gymprecice_lab.model_based.settings import ENSEMBLE_KEY, EnsembleSettings
from gymprecice_lab.training.command_settings import TrainSettings

#: the key that overlaps SAC's and TD3's updates with the solvers (gymprecice_lab.training.overlap)
OVERLAP_KEY = "overlap_updates"
#: the key that caps the learner's CPU threads (torch.set_num_threads)
THREADS_KEY = "torch_threads"
#: the key that trains one policy shared by a joint env's agents (gymprecice_lab.training.shared_policy)
SHARED_KEY = "shared_policy"

__all__ = [
    "ALGORITHMS",
    "OFF_POLICY",
    "DEFAULTS",
    "FLAGS",
    "HYPERPARAMS_NAME",
    "adjust_batch_size",
    "algorithm_class",
    "changed_on_resume",
    "hyperparameters",
    "keep_hyperparameters",
    "load_hyperparams_file",
    "model_kwargs",
    "refuse_changed_resume",
    "resolve",
    "with_robustness",
]

ALGORITHMS = ("ppo", "sac", "td3", "tqc")
#: the off-policy algorithms (a replay buffer, SB3's ``gradient_steps``, overlap_updates)
OFF_POLICY = ("sac", "td3", "tqc")
HYPERPARAMS_NAME = "hyperparams.json"

#: Defaults per algorithm. PPO's ``n_steps`` of 80 is one jet-cylinder episode; SAC/TD3
#: keep SB3's defaults except a replay buffer that fits expensive CFD (few samples).
DEFAULTS: dict[str, dict[str, Any]] = {
    "ppo": {
        "n_steps": 80,
        "batch_size": 80,
        "n_epochs": 10,
        "learning_rate": 3e-4,
        "gamma": 0.99,
        "net": [512, 512],
        "normalize": False,
    },
    "sac": {
        "batch_size": 256,
        "learning_rate": 3e-4,
        "gamma": 0.99,
        "net": [256, 256],
        "buffer_size": 100_000,
        "learning_starts": 100,
        "normalize": False,
    },
    "td3": {
        "batch_size": 256,
        "learning_rate": 1e-3,
        "gamma": 0.99,
        "net": [256, 256],
        "buffer_size": 100_000,
        "learning_starts": 100,
        "normalize": False,
        # TD3's policy is deterministic: without action noise it explores only during
        # learning_starts. Gaussian noise of 0.1 of the (rescaled, [-1, 1]) action range is
        # the TD3 paper's choice and RL Zoo's; SB3's own default is none.
        "noise_type": "normal",
        "noise_std": 0.1,
    },
}
# sb3-contrib's TQC (Truncated Quantile Critics, Kuznetsov et al. 2020): SAC with
# distributional critics whose top quantiles are dropped against overestimation; SAC's
# defaults here, sb3-contrib's otherwise (5 critics of 25 quantiles, 2 dropped per critic)
DEFAULTS["tqc"] = dict(DEFAULTS["sac"])

#: Hyperparameter -> the ``gymprecice train`` flag that sets it (for error messages).
FLAGS = {
    "n_steps": "--n-steps",
    "batch_size": "--batch-size",
    "n_epochs": "--n-epochs",
    "learning_rate": "--learning-rate",
    "gamma": "--gamma",
    "net": "--net",
    "normalize": "--normalize",
    "algo": "--algo",
    SHARED_KEY: "--shared-policy",
}

#: Keys of a hyperparameter file that are not constructor arguments of the algorithm.
_OWN_KEYS = {
    "net",
    "normalize",
    "robustness",
    ENSEMBLE_KEY,
    OVERLAP_KEY,
    THREADS_KEY,
    SHARED_KEY,
    "noise_type",
    "noise_std",
}
#: RL Zoo's names of the exploration noise of SAC and TD3 (``noise_type``).
NOISE_TYPES = ("normal", "ornstein-uhlenbeck")
#: RL Zoo keys accepted in a file and ignored (the command line or the env decides them).
_IGNORED_KEYS = {"policy", "n_timesteps", "n_envs", "env_wrapper", "normalize_kwargs"}


def algorithm_class(algo: str, params: Mapping[str, Any] | None = None) -> type:
    """The Stable-Baselines3 class of ``algo`` (imported here: SB3 loads torch).

    With a ``model_ensemble`` key in ``params``, PPO is
    :class:`~gymprecice_lab.model_based.ppo.ModelEnsemblePPO`; with
    ``overlap_updates: true``, SAC and TD3 run their updates while the solvers compute
    (:mod:`gymprecice_lab.training.overlap`). Saved models are the plain algorithm's, so
    evaluation loads them as such.
    """
    from stable_baselines3 import PPO, SAC, TD3

    if algo == "ppo" and params is not None and params.get(ENSEMBLE_KEY) is not None:
        from gymprecice_lab.model_based.ppo import ModelEnsemblePPO

        return ModelEnsemblePPO
    if algo == "tqc":
        from sb3_contrib import TQC

        cls: type = TQC
    else:
        cls = {"ppo": PPO, "sac": SAC, "td3": TD3}[algo]
    if algo != "ppo" and params is not None and params.get(OVERLAP_KEY):
        from gymprecice_lab.training.overlap import overlapping

        return overlapping(cls)
    return cls


def load_hyperparams_file(path: Path, algo: str, env_keys: tuple[str, ...]) -> dict[str, Any]:
    """The hyperparameters of a YAML file, flat or RL-Zoo style (keyed by env id or name).

    Raises ``SystemExit`` with one line naming the file and the fix when the file cannot
    be read or names something ``algo`` does not have.
    """
    import yaml

    where = f"gymprecice train: --hyperparams {path}"
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise SystemExit(f"{where}: cannot read it ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise SystemExit(f"{where}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SystemExit(f"{where}: must be a mapping of hyperparameter names to values")
    for key in env_keys:
        if isinstance(data.get(key), dict):
            data = data[key]
            break
    allowed = set(inspect.signature(algorithm_class(algo).__init__).parameters) - {
        "self",
        "policy",
        "env",
    }
    out: dict[str, Any] = {}
    for key, value in data.items():
        if key in _IGNORED_KEYS:
            continue
        if key not in allowed and key not in _OWN_KEYS:
            raise SystemExit(
                f"{where}: {algo.upper()} has no hyperparameter {key!r}; "
                f"choose from {', '.join(sorted(allowed | _OWN_KEYS))}"
            )
        if key == "noise_type" and value not in (*NOISE_TYPES, None):
            raise SystemExit(
                f"{where}: noise_type {value!r} is not one of {', '.join(NOISE_TYPES)}"
            )
        if key == "noise_type" and algo == "ppo":
            raise SystemExit(
                f"{where}: noise_type is the action noise of SAC and TD3; PPO explores with "
                "its own policy's spread (set policy_kwargs: log_std_init instead)"
            )
        if key == THREADS_KEY and (
            isinstance(value, bool) or not isinstance(value, int) or value < 1
        ):
            raise SystemExit(f"{where}: {THREADS_KEY} is a whole number of threads, 1 or more")
        if key == OVERLAP_KEY:
            if not isinstance(value, bool):
                raise SystemExit(f"{where}: {OVERLAP_KEY} is true or false, not {value!r}")
            if algo == "ppo" and value:
                raise SystemExit(
                    f"{where}: {OVERLAP_KEY} overlaps SAC's and TD3's gradient steps with the "
                    "solvers; PPO updates once per rollout (use --algo sac or td3, or drop "
                    "the key)"
                )
        if key == SHARED_KEY and not isinstance(value, bool):
            raise SystemExit(f"{where}: {SHARED_KEY} is true or false, not {value!r}")
        if key == ENSEMBLE_KEY:
            if algo != "ppo":
                raise SystemExit(
                    f"{where}: {ENSEMBLE_KEY} is model-ensemble PPO's; {algo.upper()} has "
                    "none (use --algo ppo, or drop the key)"
                )
            value = EnsembleSettings.from_value(value, where).to_json()
        out[key] = list(value) if key == "net" else value
    return out


def resolve(
    algo: str, from_file: Mapping[str, Any], from_flags: Mapping[str, Any]
) -> dict[str, Any]:
    """Defaults, overridden by the file, overridden by flags that were typed (not ``None``).

    ``n_steps``/``n_epochs`` are PPO's; typed for SAC or TD3 they are refused, not ignored.
    """
    params = {"algo": algo, **DEFAULTS[algo], **dict(from_file)}
    for key, value in from_flags.items():
        if value is None:
            continue
        if algo != "ppo" and key in ("n_steps", "n_epochs"):
            raise SystemExit(
                f"gymprecice train: {FLAGS[key]} is a PPO setting; {algo.upper()} has none "
                f"(drop it, or use --algo ppo)"
            )
        params[key] = value
    return params


def model_kwargs(params: Mapping[str, Any], action_dim: int = 1) -> dict[str, Any]:
    """Constructor keyword arguments of the SB3 algorithm for resolved ``params``.

    ``noise_type``/``noise_std`` (RL Zoo's keys) become SB3's ``action_noise`` for an
    action of ``action_dim`` numbers.
    """
    kwargs = {k: v for k, v in params.items() if k not in _OWN_KEYS and k != "algo"}
    if params.get("noise_type"):
        kwargs["action_noise"] = _action_noise(
            str(params["noise_type"]), float(params.get("noise_std", 0.1)), action_dim
        )
    net = list(params["net"])
    critic = "vf" if params["algo"] == "ppo" else "qf"
    policy_kwargs = dict(kwargs.pop("policy_kwargs", None) or {})
    policy_kwargs.setdefault("net_arch", {"pi": net, critic: net})
    kwargs["policy_kwargs"] = policy_kwargs
    return kwargs


def _action_noise(kind: str, std: float, action_dim: int) -> Any:
    import numpy as np
    from stable_baselines3.common.noise import (
        NormalActionNoise,
        OrnsteinUhlenbeckActionNoise,
    )

    cls = NormalActionNoise if kind == "normal" else OrnsteinUhlenbeckActionNoise
    return cls(mean=np.zeros(action_dim), sigma=std * np.ones(action_dim))


def changed_on_resume(saved: Mapping[str, Any], now: Mapping[str, Any]) -> list[str]:
    """One line per hyperparameter that differs from the run being resumed, naming its flag."""
    lines = []
    for key in sorted(set(saved) | set(now)):
        before, after = saved.get(key), now.get(key)
        if _same(before, after):
            continue
        flag = FLAGS.get(key, f"hyperparameter {key!r} (--hyperparams)")
        lines.append(f"{flag} is {_show(after)} now but {_show(before)} in the run being resumed")
    return lines


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)
    return json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)


def _show(value: Any) -> str:
    if isinstance(value, list):
        return ",".join(str(v) for v in value)
    return "unset" if value is None else str(value)


# -- the command's hyperparameters ---------------------------------------------------------


def hyperparameters(settings: TrainSettings, env: LabEnv) -> dict[str, Any]:
    """The run's resolved hyperparameters: the defaults, ``--hyperparams``, then the flags
    (``env``: the one the file's sections are looked up by).

    (:func:`keep_hyperparameters` copies ``--hyperparams`` into the run.)"""
    from_file: dict[str, Any] = {}
    if settings.hyperparams is not None:
        keys = tuple(dict.fromkeys((env.env_id, env.name, env.env_id.split("/", 1)[-1])))
        from_file = load_hyperparams_file(settings.hyperparams, settings.algo, keys)
    flags = {
        "n_steps": settings.n_steps,
        "batch_size": settings.batch_size,
        "n_epochs": settings.n_epochs,
        "learning_rate": settings.learning_rate,
        "gamma": settings.gamma,
        "net": _net(settings.net) if settings.net is not None else None,
        "normalize": True if settings.normalize else None,
        SHARED_KEY: True if settings.shared_policy else None,
    }
    return resolve(settings.algo, from_file, flags)


def _net(text: str) -> list[int]:
    """``--net 512,512``: the hidden layers' sizes."""
    try:
        sizes = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1:
        raise SystemExit(f"gymprecice train: --net must be sizes like 512,512, got {text!r}")
    return sizes


def with_robustness(params: dict[str, Any], wrap: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """``params`` with the robustness wrappers of the file and ``--wrap`` (``wrap``)
    together (a ``WrapError`` for a malformed one), none left where there are none."""
    robustness = wrap_spec(params.get("robustness"), list(wrap))
    if robustness:
        params["robustness"] = robustness
    else:
        params.pop("robustness", None)
    return params


def refuse_changed_resume(out: Path, params: Mapping[str, Any]) -> None:
    """Refuse to resume the run in ``out`` with hyperparameters other than its own."""
    saved_path = out / HYPERPARAMS_NAME
    if not saved_path.is_file():
        return
    changed = changed_on_resume(json.loads(saved_path.read_text()), params)
    if changed:
        raise SystemExit(
            f"gymprecice train: cannot resume {out} with other hyperparameters: "
            f"{'; '.join(changed)} (SB3 would keep the saved values); rerun with the run's "
            f"values (see {saved_path.name}) or add --fresh to start over"
        )


def keep_hyperparameters(
    hyperparams_file: Path | None, out: Path, params: Mapping[str, Any], *, resumed: bool
) -> None:
    """Write the run's hyperparameters (a resume keeps the first run's) and a copy of
    ``--hyperparams`` (``hyperparams_file``) into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    if not resumed:
        (out / HYPERPARAMS_NAME).write_text(json.dumps(params, indent=2) + "\n")
    if hyperparams_file is not None and hyperparams_file.resolve() != (out / "hyperparams.yaml"):
        shutil.copyfile(hyperparams_file, out / "hyperparams.yaml")


def adjust_batch_size(params: dict[str, Any], slots: int) -> list[str]:
    """PPO's mini-batch cannot exceed its rollout buffer: clamp it, say so, record it.

    ``slots`` is the learner's steps per env step: ``--n-envs``, times the agents with
    ``--shared-policy``."""
    if params["algo"] != "ppo":
        return []
    buffer = int(params["n_steps"]) * slots
    if int(params["batch_size"]) <= buffer:
        return []
    note = (
        f"--batch-size {params['batch_size']} is larger than the rollout buffer "
        f"(--n-steps {params['n_steps']} x {slots} learner slots = {buffer}); training "
        f"with batch size {buffer}"
    )
    params["batch_size"] = buffer
    print(f"gymprecice train: warning: {note}", file=sys.stderr)
    return [note]
