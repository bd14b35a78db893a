"""An env fitted to a policy: what a policy was trained on, and the env it may run on.

**The action bound travels with the policy.** A policy acts in ``[-1, 1]`` and
``RescaleAction`` maps that onto the env's own bound; the same policy on an env with
another bound would act with other flow rates (JetCylinderFastEnv's jets are bounded by
2.5e-5 m³/s, JetCylinderEnv's by 2.5e-4: ten times as strong). So ``policy.json`` keeps
the keyword arguments that shape what the policy does (``env_kwargs``: the bound,
``max_flow_rate`` or ``max_omega``, ``jet_width`` when training set it, and the
``observation`` it was trained to see, and a classical law run under it such as
``base_feedback``, when training chose them) and
evaluation rebuilds any env with them, saying so in one line when the env is not the one
the policy was trained on (a transfer). An env that does not take them, or whose
observation does not have the policy's shape, is refused in one line. A training
directory given as a path gets the same treatment from its ``manifest.json``.

Shipping (:mod:`gymprecice_lab.policies.ship`) and looking up a training directory
(:mod:`gymprecice_lab.policies.shipped`) describe the training env here; evaluation and
:func:`gymprecice_lab.policies.shipped.load_shipped` fit the env they build to the policy.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.policies.policy import Policy, PolicyError
from gymprecice_lab.training.shared_policy import per_row

__all__ = [
    "ACTUATOR_KWARGS",
    "BASE_LAW_KWARGS",
    "BOUND_ATTRS",
    "MACHINE_KWARGS",
    "OBSERVATION_KWARGS",
    "check_policy_env",
    "describe_env",
    "policy_env_kwargs",
]

#: The env attributes that bound the action (read from the built training env).
BOUND_ATTRS = ("max_flow_rate", "max_omega")
#: Keyword arguments that change the actuator, carried over when training set them.
ACTUATOR_KWARGS = ("jet_width",)
#: Keyword arguments that change what the policy sees, carried over when training set them:
#: a plate policy trained with ``observation="integral"`` takes five numbers, not the
#: default four, and must get them wherever it runs.
OBSERVATION_KWARGS = ("observation",)
#: Keyword arguments that run a classical law under the policy, carried over when training
#: set them: a policy trained on ``base_feedback`` learnt what to add to the feedback law,
#: and without the law under it, it is not the controller that was trained.
BASE_LAW_KWARGS = ("base_feedback", "base_damping")
#: Training keyword arguments that belong to the machine, not to the policy.
MACHINE_KWARGS = ("run_root", "options", "case_dir")


def describe_env(env: LabEnv, kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of ``policy.json`` that say what a policy trained on ``env`` (built with
    ``kwargs``) sees and does: env, the shaping ``env_kwargs``, action space, observation.

    Builds the env once without running it (on the test double where it has one, so no
    solver is needed; the spaces are the same), in a temporary run directory.
    """
    from gymprecice_lab.common.wrapped_env import make_env

    if any(k in kwargs for k in ("options", "case_dir")):
        raise PolicyError(
            "the run used a case of its own (--case); a policy must be trained on a packaged "
            "case to run elsewhere"
        )
    build = {k: v for k, v in kwargs.items() if k not in MACHINE_KWARGS}
    if env.double:
        build["double"] = True
    with tempfile.TemporaryDirectory(prefix="gymprecice-policy-") as tmp:
        built = make_env(env.env_id, 0, {**build, "run_root": tmp}, rescale=False)
        try:
            inner = built.unwrapped
            space = inner.action_space
            shaping: dict[str, Any] = {
                k: float(getattr(inner, k)) for k in BOUND_ATTRS if hasattr(inner, k)
            }
            carried = (*ACTUATOR_KWARGS, *BASE_LAW_KWARGS, *OBSERVATION_KWARGS)
            shaping.update({k: kwargs[k] for k in carried if k in kwargs})
            return {
                "env": {"name": env.name, "id": env.env_id},
                "env_kwargs": shaping,
                "action_space": {
                    "shape": list(space.shape),
                    # float32 bounds as written (2.5e-05, not 2.500000063e-05)
                    "low": [float(str(v)) for v in space.low.reshape(-1)],
                    "high": [float(str(v)) for v in space.high.reshape(-1)],
                    "unit": env.action_unit,
                },
                "observation_shape": list(built.observation_space.shape),
            }
        finally:
            built.close()


def policy_env_kwargs(
    policy: Policy, env: LabEnv, given: Mapping[str, Any]
) -> tuple[dict[str, Any], list[str]]:
    """The env keyword arguments the policy needs on ``env``, and lines to print.

    ``given`` are the command's own (``--env-kwargs``): one of them that sets a shaping
    argument to another value wins, with a warning. Off its training env a policy runs
    with the training env's bound (a transfer, said in one line).
    """
    meta = policy.metadata
    if not meta:
        return {}, []
    shaping = dict(meta.get("env_kwargs", {}))
    lines = []
    applied = {}
    for key, value in shaping.items():
        if not _accepts(env, key):
            raise PolicyError(
                f"{policy.label} was trained with {key}={value!r} (on "
                f"{policy.trained_on}); {env.name} has no {key}, it cannot run there"
            )
        if key in given and given[key] != value:
            lines.append(
                f"warning: --env-kwargs sets {key}={given[key]!r}; {policy.label} was trained "
                f"with {key}={value!r}, its actions scale with it"
            )
        else:
            applied[key] = value
    trained_on = policy.trained_on
    if trained_on and trained_on != env.name:
        acting = {k: v for k, v in applied.items() if k not in OBSERVATION_KWARGS}
        seeing = {k: v for k, v in applied.items() if k in OBSERVATION_KWARGS}
        own = f" ({env.name}'s own: {env.action_bound:g})" if env.action_bound else ""
        bound = ", ".join(f"{k}={v!r}" for k, v in acting.items())
        parts = [f"{trained_on}'s action bound {bound}{own}"] if acting else []
        parts += [f"{k}={v!r}" for k, v in seeing.items()]
        lines.append(
            f"transfer: {policy.label} was trained on {trained_on}; running it on "
            f"{env.name} with {' and '.join(parts) or 'its own action bound'}"
        )
    return applied, lines


def check_policy_env(
    policy: Policy, model: Any, env: Any, env_name: str, applied: Mapping[str, Any]
) -> None:
    """Refuse (:class:`PolicyError`) an env whose observation or action shape is not the
    policy's, or whose action bound is not the one the policy was trained with (unless
    ``--env-kwargs`` changed it on purpose: ``applied`` lacks one of the policy's)."""
    import numpy as np

    obs, want = tuple(env.observation_space.shape), tuple(model.observation_space.shape)
    act, want_act = tuple(env.action_space.shape), tuple(model.action_space.shape)
    if per_row(want, obs) and per_row(want_act, act):
        # a shared policy (train --shared-policy) acts on each agent's row of its joint env
        obs, act = obs[1:], act[1:]
    if obs != want:
        raise PolicyError(
            f"{policy.label} takes observations of shape {want}, {env_name} gives {obs}; "
            "it cannot run there"
        )
    want = want_act
    if act != want:
        raise PolicyError(
            f"{policy.label} gives actions of shape {want}, {env_name} takes {act}; "
            "it cannot run there"
        )
    meta = policy.metadata or {}
    space = meta.get("action_space")
    if not space or dict(applied) != meta.get("env_kwargs", {}):
        return
    inner = env.unwrapped.action_space
    low, high = np.asarray(space["low"], float), np.asarray(space["high"], float)
    if inner.low.size != low.size or not (
        np.allclose(inner.low.reshape(-1), low, rtol=1e-6)
        and np.allclose(inner.high.reshape(-1), high, rtol=1e-6)
    ):
        raise PolicyError(
            f"{policy.label} was trained with actions in [{low.min():g}, {high.max():g}] "
            f"{space.get('unit') or ''}; {env_name} has [{float(inner.low.min()):g}, "
            f"{float(inner.high.max()):g}] with the same settings; it cannot run there"
        )


def _accepts(env: LabEnv, key: str) -> bool:
    """Whether ``env``'s class (or a parent it passes keywords to) takes ``key``."""
    import importlib
    import inspect

    entry = env.entry_point
    if isinstance(entry, str):
        module, _, name = entry.partition(":")
        cls = getattr(importlib.import_module(module), name)
    else:
        cls = entry
    if not isinstance(cls, type):  # a factory function: its own parameters
        return key in inspect.signature(cls).parameters
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is not None and key in inspect.signature(init).parameters:
            return True
    return False
