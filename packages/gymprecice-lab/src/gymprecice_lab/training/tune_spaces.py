"""The hyperparameters ``gymprecice tune`` searches, per algorithm, as RL Zoo samples them.

RL Zoo's spaces (``rl_zoo3/hyperparams_opt.py``) are sized for millions of cheap steps;
a coupled simulation gives thousands. So the spaces here keep RL Zoo's parameters and
their log-uniform learning rate, and scale what depends on the budget to the trial's
``timesteps``: SAC's, TQC's and TD3's ``learning_starts`` are fractions of it, PPO's rollout
lengths stay a few episodes. Each sampler returns hyperparameters under the names a
``--hyperparams`` file takes (:mod:`gymprecice_lab.training.hyperparams`), so the best trial's
are written as such a file.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["DEFAULTS", "NETS", "SPACES", "sample", "space_names"]

#: the network shapes a trial chooses between (name -> hidden layers)
NETS = {"small": [64, 64], "medium": [256, 256], "large": [400, 300], "wide": [512, 512]}


def _ppo(trial: Any, timesteps: int, n_envs: int) -> dict[str, Any]:
    n_steps = trial.suggest_categorical("n_steps", [20, 40, 80, 160])
    # mini-batches that divide the rollout (n_steps x n_envs): a fraction of it
    split = trial.suggest_categorical("minibatches", [1, 2, 4])
    return {
        "n_steps": n_steps,
        "batch_size": max(1, n_steps * n_envs // split),
        "n_epochs": trial.suggest_categorical("n_epochs", [5, 10, 20]),
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 3e-3, log=True),
        "gamma": trial.suggest_categorical("gamma", [0.95, 0.98, 0.99, 0.995]),
        "gae_lambda": trial.suggest_categorical("gae_lambda", [0.9, 0.95, 0.98]),
        "clip_range": trial.suggest_categorical("clip_range", [0.1, 0.2, 0.3]),
        "net": NETS[trial.suggest_categorical("net", list(NETS))],
    }


def _off_policy(trial: Any, timesteps: int, n_envs: int) -> dict[str, Any]:
    fraction = trial.suggest_categorical("learning_starts_fraction", [0.02, 0.05, 0.1])
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True),
        "gamma": trial.suggest_categorical("gamma", [0.95, 0.98, 0.99]),
        "batch_size": trial.suggest_categorical("batch_size", [64, 128, 256]),
        "learning_starts": max(n_envs, round(fraction * timesteps)),
        "gradient_steps": trial.suggest_categorical("gradient_steps", [1, 2, 4, 8]),
        "tau": trial.suggest_categorical("tau", [0.005, 0.01, 0.02]),
        "net": NETS[trial.suggest_categorical("net", list(NETS))],
    }


def _tqc(trial: Any, timesteps: int, n_envs: int) -> dict[str, Any]:
    # RL Zoo's TQC space: SAC's, and how many of each critic's 25 quantiles to drop
    return {
        **_off_policy(trial, timesteps, n_envs),
        "top_quantiles_to_drop_per_net": trial.suggest_categorical(
            "top_quantiles_to_drop_per_net", [0, 1, 2, 3, 5]
        ),
    }


def _td3(trial: Any, timesteps: int, n_envs: int) -> dict[str, Any]:
    return {
        **_off_policy(trial, timesteps, n_envs),
        "noise_std": trial.suggest_categorical("noise_std", [0.05, 0.1, 0.2, 0.3]),
    }


#: the parameters each sampler suggests, in order
_OFF_POLICY_NAMES = (
    "learning_rate",
    "gamma",
    "batch_size",
    "learning_starts_fraction",
    "gradient_steps",
    "tau",
    "net",
)
_PPO_NAMES = (
    "n_steps",
    "minibatches",
    "n_epochs",
    "learning_rate",
    "gamma",
    "gae_lambda",
    "clip_range",
    "net",
)

#: algorithm -> its sampler and the names of the parameters it suggests
SPACES: dict[str, tuple[Callable[[Any, int, int], dict[str, Any]], tuple[str, ...]]] = {
    "ppo": (_ppo, _PPO_NAMES),
    "sac": (_off_policy, _OFF_POLICY_NAMES),
    "td3": (_td3, (*_OFF_POLICY_NAMES, "noise_std")),
    "tqc": (_tqc, (*_OFF_POLICY_NAMES, "top_quantiles_to_drop_per_net")),
}


#: the value a parameter keeps when ``--params`` leaves it out of the search: the lab's
#: default where it has one (:data:`gymprecice_lab.training.hyperparams.DEFAULTS`), else SB3's
DEFAULTS: dict[str, dict[str, Any]] = {
    "ppo": {
        "n_steps": 80,
        "minibatches": 1,
        "n_epochs": 10,
        "learning_rate": 3e-4,
        "gamma": 0.99,
        "gae_lambda": 0.95,
        "clip_range": 0.2,
        "net": "wide",
    },
    "sac": {
        "learning_rate": 3e-4,
        "gamma": 0.99,
        "batch_size": 256,
        "learning_starts_fraction": 0.02,
        "gradient_steps": 1,
        "tau": 0.005,
        "net": "medium",
    },
}
DEFAULTS["td3"] = {**DEFAULTS["sac"], "learning_rate": 1e-3, "noise_std": 0.1}
DEFAULTS["tqc"] = {**DEFAULTS["sac"], "top_quantiles_to_drop_per_net": 2}


class _Subset:
    """A trial that samples only ``names``; every other parameter keeps its default."""

    def __init__(self, trial: Any, names: set[str], defaults: Mapping[str, Any]) -> None:
        self.trial, self.names, self.defaults = trial, names, defaults

    def suggest_categorical(self, name: str, choices: list[Any]) -> Any:
        if name in self.names:
            return self.trial.suggest_categorical(name, choices)
        return self.defaults[name]

    def suggest_float(self, name: str, low: float, high: float, *, log: bool = False) -> float:
        if name in self.names:
            return self.trial.suggest_float(name, low, high, log=log)
        return self.defaults[name]


def space_names(algo: str) -> tuple[str, ...]:
    """The parameters ``algo``'s space suggests, in order."""
    return SPACES[algo][1]


def sample(
    trial: Any,
    algo: str,
    timesteps: int,
    n_envs: int,
    fixed: Mapping[str, Any],
    names: list[str] | None = None,
) -> dict[str, Any]:
    """A trial's hyperparameters: what the trial samples (of ``names`` only, when given:
    the others keep :data:`DEFAULTS`), overridden by ``fixed`` (``--hyperparams``)."""
    if names is not None:
        trial = _Subset(trial, set(names), DEFAULTS[algo])
    sampled = SPACES[algo][0](trial, timesteps, n_envs)
    return {**sampled, **dict(fixed)}
