"""Trained policies that ship inside the package, so a user can evaluate one without training.

An env's package ships its policies in the folder its lab card's ``policies`` names
(``"package:folder"``; the tutorials' ``gymprecice_tutorials/policies/``), each a
directory ``<name>/``::

    model.zip                 the SB3 model, for evaluation only (no optimizer state)
    model_vecnormalize.pkl    the frozen VecNormalize statistics (when trained --normalize)
    policy.json               what it was trained on and how (see below)

The commands::

    gymprecice policies                                       # list the shipped ones
    gymprecice evaluate jet-cylinder-fast --policy shipped    # the one named after the env
    gymprecice evaluate jet-cylinder --policy jet-cylinder-fast   # by name, on another env
    gymprecice evaluate jet-cylinder-fast --policy runs/jet-cylinder-fast/train  # a path
    gymprecice ship-policy runs/jet-cylinder-fast/train --name jet-cylinder-fast \\
        --evaluation runs/jet-cylinder-fast/evaluate          # ship a training run

``--policy`` takes a shipped name, ``shipped`` (the policy named after the evaluated env, or
the one of its training case that the env's table entry names: ``heated-plate`` takes
``heated-plate-fast``)
or a path (a model ``.zip``, a training directory, a policy directory); a bare word that
names a shipped policy is that policy (write ``./NAME`` for a directory of that name).

**The action bound travels with the policy.** A policy acts in ``[-1, 1]`` and
``RescaleAction`` maps that onto the env's own bound; the same policy on an env with
another bound would act with other flow rates (JetCylinderFastEnv's jets are bounded by
2.5e-5 m³/s, JetCylinderEnv's by 2.5e-4: ten times as strong). So ``policy.json`` keeps
the keyword arguments that shape what the policy does (``env_kwargs``: the bound,
``max_flow_rate`` or ``max_omega``, and ``jet_width`` when training set it) and
evaluation rebuilds any env with them, saying so in one line when the env is not the one
the policy was trained on (a transfer). An env that does not take them, or whose
observation does not have the policy's shape, is refused in one line. A training
directory given as a path gets the same treatment from its ``manifest.json``.

``policy.json`` also records the training env (name, id), its action space and
observation shape, the algorithm and hyperparameters, the training command, timesteps,
wall-clock time, source revision and the SHA-256 of the trained model file, the files'
own checksums (checked when a shipped policy loads) and, with ``--evaluation RUN``, that
evaluation's result.

Shipping strips what evaluation does not need: the optimizer's moments (two thirds of a
PPO ``model.zip``), the value function's weights (zeroed, so that SB3 still loads the file
and the zeros deflate away), the last observations and episode statistics of training, and
the TensorBoard path; the archive is deflated. For the 512x512 MLP on 151 probes that is
8.2 MB trained, 1.3 MB shipped. The shipped model is checked to act exactly like the trained
one. ``PPO.load`` reads it as any SB3 model, but with a blank critic and fresh optimizer:
continue training from the training run's own checkpoint, not from a shipped policy.

``GYMPRECICE_POLICIES_DIR`` (or a ``directory`` argument) points all of this at another
directory than the packages': tests ship into a temporary one.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from gymprecice_lab.lab_env import LabEnv, LabEnvError, find_lab_env, lab_envs
from gymprecice_lab.shared import per_row

__all__ = [
    "METADATA_NAME",
    "POLICIES_DIR_ENV",
    "Policy",
    "PolicyController",
    "PolicyError",
    "check_policy_env",
    "load_shipped",
    "policies_dir",
    "policies_folder",
    "policy_env_kwargs",
    "policy_folders",
    "read_metadata",
    "resolve_policy",
    "ship_policy",
    "shipped_policies",
    "shipped_policy_dirs",
]

#: Environment variable naming another directory of shipped policies (tests use it).
POLICIES_DIR_ENV = "GYMPRECICE_POLICIES_DIR"
METADATA_NAME = "policy.json"
MODEL_NAME = "model.zip"
FORMAT = 1
#: The env attributes that bound the action (read from the built training env).
BOUND_ATTRS = ("max_flow_rate", "max_omega")
#: Keyword arguments that change the actuator, carried over when training set them.
ACTUATOR_KWARGS = ("jet_width",)
#: Training keyword arguments that belong to the machine, not to the policy.
_MACHINE_KWARGS = ("run_root", "options", "case_dir")
#: Saved attributes of an SB3 model that only training uses (left out of a shipped one).
_TRAINING_ONLY = (
    "_last_obs",
    "_last_original_obs",
    "_last_episode_starts",
    "ep_info_buffer",
    "ep_success_buffer",
)
_NAME = re.compile(r"^[a-z0-9][a-z0-9._-]*$")
_RESERVED = ("shipped",)


class PolicyError(ValueError):
    """A policy that cannot be found, shipped or run on an env; the message is one line."""


@dataclass
class Policy:
    """A policy to evaluate: its model file and, when known, what it was trained on."""

    model: Path
    #: the shipped name (``None`` for a path)
    name: str | None = None
    #: ``policy.json`` of a shipped policy, or the same fields from a training manifest
    metadata: dict[str, Any] | None = None
    #: a remark for the user (e.g. a training directory's newest checkpoint stands in)
    notes: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        return f"policy {self.name!r}" if self.name else f"policy {self.model}"

    @property
    def trained_on(self) -> str | None:
        return (self.metadata or {}).get("env", {}).get("name")

    def describe(self) -> dict[str, Any]:
        """What an evaluation's manifest records about the policy."""
        meta = self.metadata or {}
        return {
            "name": self.name,
            "source": "shipped" if self.name else "path",
            "trained_on": meta.get("env"),
            "env_kwargs": meta.get("env_kwargs"),
            "training_model_sha256": meta.get("training", {}).get("model_sha256"),
        }


# -- the shipped ones ----------------------------------------------------------------------


def policies_folder(spec: str) -> Path:
    """The folder a lab card's ``policies`` names: ``"package:folder"`` -> the folder
    ``folder`` inside the installed ``package``."""
    import importlib

    package, _, folder = spec.partition(":")
    try:
        module = importlib.import_module(package)
    except ImportError as exc:
        raise PolicyError(
            f"card field 'policies' names {spec!r}, which does not import: {exc}"
        ) from None
    return Path(str(module.__file__)).resolve().parent / folder


def policies_dir(
    directory: str | os.PathLike[str] | None = None, env: LabEnv | None = None
) -> Path | None:
    """Where ``env``'s shipped policies are (and where ``ship-policy`` puts one):
    ``directory``, else ``$GYMPRECICE_POLICIES_DIR``, else the folder its lab card's
    ``policies`` names (``None``: the card names none)."""
    if directory is not None:
        return Path(directory)
    override = os.environ.get(POLICIES_DIR_ENV)
    if override:
        return Path(override)
    if env is not None and env.card.policies:
        return policies_folder(env.card.policies)
    return None


def policy_folders(
    directory: str | os.PathLike[str] | None = None, env: LabEnv | None = None
) -> list[Path]:
    """Every folder a policy name is looked up in, ``env``'s own first: ``directory``, else
    ``$GYMPRECICE_POLICIES_DIR``, else the ``policies`` folders of every installed card."""
    own = policies_dir(directory, env)
    if directory is not None or os.environ.get(POLICIES_DIR_ENV):
        return [own] if own is not None else []
    folders = [own] if own is not None else []
    for spec in dict.fromkeys(e.card.policies for e in lab_envs() if e.card.policies):
        try:
            folder = policies_folder(str(spec))
        except PolicyError:
            continue
        if folder not in folders:
            folders.append(folder)
    return folders


def read_metadata(policy_dir: str | os.PathLike[str]) -> dict[str, Any]:
    return json.loads((Path(policy_dir) / METADATA_NAME).read_text())


def _policies_in(root: Path) -> dict[str, Path]:
    if not root.is_dir():
        return {}
    return {
        path.name: path
        for path in sorted(root.iterdir())
        if _NAME.match(path.name)
        and (path / METADATA_NAME).is_file()
        and (path / MODEL_NAME).is_file()
    }


def shipped_policy_dirs(
    directory: str | os.PathLike[str] | None = None, env: LabEnv | None = None
) -> dict[str, Path]:
    """``{name: its folder}`` of every shipped policy; a name found in two folders is the
    first's (``env``'s own folder first)."""
    found: dict[str, Path] = {}
    for root in policy_folders(directory, env):
        for name, path in _policies_in(root).items():
            found.setdefault(name, path)
    return dict(sorted(found.items()))


def shipped_policies(
    directory: str | os.PathLike[str] | None = None, env: LabEnv | None = None
) -> dict[str, dict[str, Any]]:
    """``{name: policy.json}`` of every shipped policy, sorted by name."""
    return {name: read_metadata(path) for name, path in shipped_policy_dirs(directory, env).items()}


def _names(directory: str | os.PathLike[str] | None, env: LabEnv | None = None) -> str:
    names = list(shipped_policy_dirs(directory, env))
    return ", ".join(names) if names else "none yet"


def resolve_policy(
    spec: str | os.PathLike[str],
    env: str | LabEnv | None = None,
    *,
    directory: str | os.PathLike[str] | None = None,
) -> Policy:
    """The policy ``--policy`` names: a shipped name, ``shipped`` (the one named after
    ``env``) or a path (model ``.zip``, training directory, policy directory)."""
    from gymprecice_lab.envs import find_model

    text = os.fspath(spec)
    bare = _NAME.match(text) is not None
    info = env if isinstance(env, LabEnv) or env is None else find_lab_env(env)
    shipped = shipped_policy_dirs(directory, info) if bare else {}
    if text == "shipped":
        if info is None:
            raise PolicyError("--policy shipped means the policy named after the env; name one")
        name = info.shipped_policy or info.name
        if name in shipped:
            return _shipped(shipped[name], name)
        raise PolicyError(
            f"no policy is shipped for {info.name} (shipped: {_names(directory, info)}); pass "
            "--policy NAME for one of those, or a model .zip or training directory"
        )
    if bare and text in shipped:
        return _shipped(shipped[text], text)
    path = Path(text).expanduser()
    if not path.exists():
        if bare:
            raise PolicyError(
                f"no shipped policy {text!r} and no file or directory of that name; "
                f"shipped policies: {_names(directory, info)}"
            )
        raise PolicyError(f"no policy at {path}: no such file or directory")
    try:
        model, note = find_model(path)
    except FileNotFoundError as exc:
        raise PolicyError(str(exc)) from None
    if (model.parent / METADATA_NAME).is_file():
        policy = Policy(model, None, read_metadata(model.parent))
    else:
        policy = Policy(model, None, _metadata_from_training(model))
    if note:
        policy.notes.append(note)
    return policy


def _shipped(directory: Path, name: str) -> Policy:
    """A shipped policy, its files checked against the checksums ``policy.json`` records."""
    from gymprecice_lab.manifest import file_sha256

    metadata = read_metadata(directory)
    for filename, record in metadata.get("files", {}).items():
        path = directory / filename
        if not path.is_file() or file_sha256(path) != record.get("sha256"):
            raise PolicyError(
                f"shipped policy {name!r}: {filename} is missing or not the file that was "
                f"shipped (SHA-256 differs from {METADATA_NAME}); ship it again"
            )
    return Policy(directory / MODEL_NAME, name, metadata)


def _metadata_from_training(model: Path) -> dict[str, Any] | None:
    """The env fields of ``policy.json`` for a model in a training directory (its
    ``manifest.json``, beside it or one up from ``checkpoints/``), ``None`` if unknown."""
    for directory in (model.parent, model.parent.parent):
        manifest = directory / "manifest.json"
        if not manifest.is_file():
            continue
        try:
            data = json.loads(manifest.read_text())
            if data.get("command") != "train":
                continue
            settings = data["settings"]
            return describe_env(find_lab_env(settings["env_id"]), settings["env_kwargs"])
        except Exception:  # an unreadable manifest: evaluate as before, without the bound
            return None
    return None


# -- an env for a policy -------------------------------------------------------------------


def describe_env(env: LabEnv, kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of ``policy.json`` that say what a policy trained on ``env`` (built with
    ``kwargs``) sees and does: env, the shaping ``env_kwargs``, action space, observation.

    Builds the env once without running it (on the test double where it has one, so no
    solver is needed; the spaces are the same), in a temporary run directory.
    """
    from gymprecice_lab.envs import make_env

    if any(k in kwargs for k in ("options", "case_dir")):
        raise PolicyError(
            "the run used a case of its own (--case); a policy must be trained on a packaged "
            "case to run elsewhere"
        )
    build = {k: v for k, v in kwargs.items() if k not in _MACHINE_KWARGS}
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
            shaping.update({k: kwargs[k] for k in ACTUATOR_KWARGS if k in kwargs})
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
                f"{policy.label} acts through {key}={value!r} (trained on "
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
        bound = ", ".join(f"{k}={v!r}" for k, v in applied.items()) or "its own bound"
        own = f" ({env.name}'s own: {env.action_bound:g})" if env.action_bound else ""
        lines.append(
            f"transfer: {policy.label} was trained on {trained_on}; running it on "
            f"{env.name} with {trained_on}'s action bound {bound}{own}"
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


def load_shipped(
    spec: str | os.PathLike[str],
    env: str,
    *,
    idx: int = 0,
    device: str = "cpu",
    directory: str | os.PathLike[str] | None = None,
    **env_kwargs: Any,
) -> tuple[Any, Any]:
    """``(vec_env, model)`` like :func:`gymprecice_lab.envs.load_policy`, for any
    ``--policy`` value; the env is built with the policy's action bound (``env_kwargs``
    given here win)::

        venv, model = load_shipped("jet-cylinder-fast", "jet-cylinder", double=True)
    """
    from gymprecice_lab.envs import load_policy

    info = find_lab_env(env)
    policy = resolve_policy(spec, info, directory=directory)
    applied, _ = policy_env_kwargs(policy, info, env_kwargs)
    venv, model = load_policy(
        policy.model, info.name, idx=idx, device=device, **{**applied, **env_kwargs}
    )
    try:
        check_policy_env(policy, model, venv.unwrapped.envs[0], info.name, applied)
    except PolicyError:
        venv.close()
        raise
    return venv, model


class PolicyController:
    """A trained policy as a controller ``controller(obs[, t]) -> action`` in the env's own
    units, acting as evaluation does: the observation normalised with the frozen statistics
    saved beside the model, the deterministic action mapped from ``[-1, 1]`` onto the
    action box ``bounds`` (``(low, high)``, as ``RescaleAction`` maps it in training).

    For scripts that drive an env themselves (a study of classical controllers beside a
    trained one); ``spec`` is any ``--policy`` value, ``env`` the env it names
    ``shipped`` for."""

    def __init__(self, spec: str, env: str, bounds: tuple[Any, Any]) -> None:
        import numpy as np

        from gymprecice_lab.envs import find_model, load_model, load_normalizer

        policy = resolve_policy(spec, env)
        path, _ = find_model(Path(policy.model))
        self.model = load_model(path)
        self.stats = load_normalizer(path)
        self.low, self.high = (np.asarray(b, dtype=float) for b in bounds)

    def __call__(self, obs: Any, t: float | None = None) -> Any:
        import numpy as np

        x = np.asarray(obs, dtype=np.float32)
        if self.stats is not None:
            x = self.stats.normalize_obs(x)
        action, _ = self.model.predict(x, deterministic=True)
        unit = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        # a shared policy acting on a joint env's rows answers one row per agent: keep
        # the box's shape, so scalar bounds still broadcast over a flat action
        unit = unit.reshape(self.low.shape if self.low.size == unit.size > 1 else -1)
        return (self.low + (unit + 1.0) * 0.5 * (self.high - self.low)).astype(np.float32)


# -- shipping --------------------------------------------------------------------------------


def ship_policy(
    train_dir: str | os.PathLike[str],
    name: str | None = None,
    *,
    evaluation: str | os.PathLike[str] | None = None,
    directory: str | os.PathLike[str] | None = None,
    force: bool = False,
    checkpoint: str | None = None,
) -> Path:
    """Copy a training run's final model into the shipped policies as ``name`` (default:
    the training env's name); return the policy's directory.

    ``train_dir`` is a ``gymprecice train`` output (its ``model.zip``, else its newest
    checkpoint); ``checkpoint`` picks one of its checkpoints instead: ``"best"`` (the one
    with the highest mean training return, ``checkpoints/best.json``: chosen by training,
    never by an evaluation) or a step count. ``evaluation`` a ``gymprecice evaluate``
    output of that model, whose result ``policy.json`` then records. An existing policy of
    that name is replaced only with ``force``.
    """
    from gymprecice_lab.envs import load_model, vecnormalize_path
    from gymprecice_lab.manifest import file_sha256

    train_dir = Path(train_dir)
    manifest, env = _training_run(train_dir)
    settings = manifest["settings"]
    name = _policy_name(name or env.name)
    root = policies_dir(directory, env)
    if root is None:
        raise PolicyError(
            f"{env.name}'s package ships no policies (lab card field 'policies', "
            "'package:folder'); pass --into DIR"
        )
    dest = root / name
    if dest.exists() and not force:
        raise PolicyError(
            f"a policy {name!r} is shipped already ({dest}); add --force to replace it"
        )
    source = _source(train_dir, checkpoint)
    described = describe_env(env, settings.get("env_kwargs", {}))
    model = load_model(source)
    obs_shape = tuple(model.observation_space.shape)
    env_shape = tuple(described["observation_shape"])
    shared = bool(settings.get("hyperparams", {}).get("shared_policy"))
    if obs_shape != env_shape and not (shared and per_row(obs_shape, env_shape)):
        raise PolicyError(
            f"{source} takes observations of shape {obs_shape}, but its training env "
            f"{env.name} gives {env_shape}"
        )
    stats = vecnormalize_path(source)
    normalize = bool(settings.get("hyperparams", {}).get("normalize"))
    if normalize and not stats.is_file():
        raise PolicyError(f"the run normalised observations but {stats} is missing")
    evaluated = _evaluation_record(Path(evaluation), file_sha256(source)) if evaluation else None
    metadata = {
        "format": FORMAT,
        "name": name,
        **described,
        "policy_actions": "in [-1, 1], rescaled onto action_space (gymnasium RescaleAction)",
        "normalize_observations": stats.is_file(),
        "algorithm": settings.get("hyperparams", {}).get("algo"),
        # a policy trained --shared-policy acts on each agent's row of the joint env
        **({"shared_by": list(env.card.agents)} if shared else {}),
        "hyperparams": settings.get("hyperparams"),
        "training": _training_record(manifest, train_dir, source, model, file_sha256),
        "evaluation": evaluated,
    }
    _write_policy(dest, model, stats, metadata)
    return dest


def _training_run(train_dir: Path) -> tuple[dict[str, Any], LabEnv]:
    """A ``gymprecice train`` output's manifest and the env it trained on."""
    try:
        manifest = json.loads((train_dir / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        raise PolicyError(
            f"{train_dir}: no readable manifest.json ({exc}); give a `gymprecice train` "
            "output directory"
        ) from None
    if manifest.get("command") != "train":
        raise PolicyError(f"{train_dir} is a `gymprecice {manifest.get('command')}` run, not train")
    try:
        return manifest, find_lab_env(manifest["settings"]["env_id"])
    except LabEnvError as exc:
        raise PolicyError(f"{train_dir}: {exc}") from None


def _policy_name(name: str) -> str:
    """``name``, refused unless it can name a policy (a directory, and ``--policy NAME``)."""
    if not _NAME.match(name) or name in _RESERVED:
        raise PolicyError(
            f"policy name {name!r}: use lower-case letters, digits, '.', '_' and '-', "
            f"starting with a letter or digit (not {', '.join(_RESERVED)})"
        )
    return name


def _source(train_dir: Path, checkpoint: str | None) -> Path:
    """The model to ship: the checkpoint named, else the run's final model (or its
    newest checkpoint, said in one line)."""
    from gymprecice_lab.envs import find_model

    if checkpoint is not None:
        return _checkpoint(train_dir, checkpoint)
    try:
        source, note = find_model(train_dir)
    except FileNotFoundError as exc:
        raise PolicyError(str(exc)) from None
    if note:
        print(f"gymprecice ship-policy: {note}")
    return source


#: the packages whose versions ``policy.json`` records
_RECORDED_PACKAGES = (
    "gymprecice-lab",
    "gymprecice-tutorials",
    "stable-baselines3",
    "torch",
    "gymnasium",
)


def _write_policy(dest: Path, model: Any, stats: Path, metadata: dict[str, Any]) -> None:
    """Write the slim model, its frozen statistics and ``policy.json`` (``metadata`` with
    the files' checksums and how it was shipped) into ``dest``, replacing it whole: a
    temporary directory beside it is renamed at the end, so a failure leaves nothing."""
    from gymprecice_lab.manifest import file_sha256, package_versions

    root = dest.parent
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", dir=root))
    try:
        _write_slim_model(model, tmp / MODEL_NAME)
        _check_same_actions(model, tmp / MODEL_NAME)
        files = [MODEL_NAME]
        if stats.is_file():
            _write_frozen_stats(stats, tmp / "model_vecnormalize.pkl")
            files.append("model_vecnormalize.pkl")
        metadata = {
            **metadata,
            "files": {
                f: {"sha256": file_sha256(tmp / f), "bytes": (tmp / f).stat().st_size}
                for f in files
            },
            "shipped": {
                "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                "left_out": "optimizer state, last observations and episode statistics of "
                "training, TensorBoard path",
                "packages": {
                    k: v for k, v in package_versions().items() if k in _RECORDED_PACKAGES
                },
            },
        }
        (tmp / METADATA_NAME).write_text(json.dumps(metadata, indent=2) + "\n")
        tmp.chmod(0o755)  # mkdtemp's 0700 would keep others from reading an install
        if dest.exists():
            shutil.rmtree(dest)
        tmp.rename(dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


#: Parameter names of the value function in SB3 policies: PPO's value branch and head,
#: SAC's and TD3's critics. Evaluation never reads them.
_CRITIC_PREFIXES = ("mlp_extractor.value_net.", "value_net.", "critic.", "critic_target.")


def _write_slim_model(model: Any, path: Path) -> None:
    """The model without what only training needs, in a deflated zip."""
    import torch

    optimizer = getattr(model.policy, "optimizer", None)
    if optimizer is not None:
        optimizer.state.clear()  # Adam's moments: twice the network; fresh state loads fine
    with torch.no_grad():
        # the value function (critics) only steers training: zeros keep the file loadable
        # by SB3 and deflate to nothing; the actions are checked unchanged afterwards
        for name, param in model.policy.named_parameters():
            if name.startswith(_CRITIC_PREFIXES):
                param.zero_()
    model.tensorboard_log = None
    stored = path.with_suffix(".stored.zip")
    model.save(stored, exclude=list(_TRAINING_ONLY))
    with (
        zipfile.ZipFile(stored) as src,
        zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as dst,
    ):
        for item in src.infolist():
            dst.writestr(item.filename, src.read(item.filename))
    stored.unlink()


def _check_same_actions(model: Any, path: Path) -> None:
    """The shipped file loads with SB3's own ``load`` and acts exactly like the original."""
    import numpy as np

    from gymprecice_lab.envs import load_model

    slim = load_model(path)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(8, *model.observation_space.shape)).astype(np.float32)
    ours, _ = slim.predict(obs, deterministic=True)
    theirs, _ = model.predict(obs, deterministic=True)
    if not np.array_equal(ours, theirs):
        raise PolicyError("the stripped model does not act like the trained one; not shipped")


def _write_frozen_stats(source: Path, path: Path) -> None:
    """The VecNormalize statistics, frozen, without training's last observations."""
    import pickle

    import numpy as np

    with source.open("rb") as handle:
        stats = pickle.load(handle)
    stats.training = False
    for attr in ("old_obs", "old_reward"):
        if hasattr(stats, attr):
            setattr(stats, attr, np.array([]))
    # what VecNormalize's own pickling drops, and unpickling did not restore
    stats.class_attributes, stats.returns = {}, np.array([])
    with path.open("wb") as handle:
        pickle.dump(stats, handle)


def _command_line(argv: list[str] | None, cwd: str | None = None) -> str | None:
    """The command as typed, without the machine's path to the ``gymprecice`` script (or
    ``python -m gymprecice``'s ``__main__.py``), and without the machine's directories: an
    absolute path is written relative to the directory the command ran in (``cwd``), or
    as its last component when it lies elsewhere (a policy ships to other machines)."""
    import shlex

    if not argv:
        return None

    def portable(arg: str) -> str:
        if not os.path.isabs(arg):
            return arg
        path = Path(arg)
        if cwd and path.is_relative_to(cwd) and path != Path(cwd):
            return path.relative_to(cwd).as_posix()
        return path.name or arg

    return shlex.join(["gymprecice", *(portable(a) for a in argv[1:])])


def _training_record(
    manifest: Mapping[str, Any], train_dir: Path, source: Path, model: Any, sha: Any
) -> dict[str, Any]:
    settings = manifest["settings"]
    segments = manifest.get("segments") or [
        {"argv": manifest.get("argv"), "result": manifest.get("result")}
    ]
    seconds = [float(s["result"]["seconds"]) for s in segments if s.get("result")]
    result = manifest.get("result") or {}
    kwargs = {k: v for k, v in settings.get("env_kwargs", {}).items() if k not in _MACHINE_KWARGS}
    model_sha = sha(source)
    recorded = result.get("model_sha256")
    return {
        "command": _command_line(
            segments[0].get("argv") or manifest.get("argv"), manifest.get("cwd")
        ),
        "segments": len(segments),
        "env_kwargs": kwargs,
        "double": bool(settings.get("double")),
        "n_envs": settings.get("n_envs"),
        "timesteps": int(model.num_timesteps),
        "timesteps_requested": settings.get("timesteps"),
        "interrupted": result.get("interrupted"),
        "wall_clock_seconds": round(sum(seconds), 1) if seconds else None,
        "recorded": manifest.get("created"),
        "source": (manifest.get("source") or {}).get("git"),
        "packages": manifest.get("packages"),
        "solvers_ok": (manifest.get("solvers") or {}).get("ok"),
        "model": source.relative_to(train_dir).as_posix(),
        "model_sha256": model_sha,
        "manifest_model_sha256_matches": (recorded == model_sha) if recorded else None,
    }


def _checkpoint(train_dir: Path, which: str) -> Path:
    """``train_dir``'s checkpoint ``which``: ``best`` or a step count."""
    from gymprecice_lab.callbacks import BEST_NAME, read_best

    directory = train_dir / "checkpoints"
    if which == "best":
        name = read_best(directory).get("name")
        if not name:
            raise PolicyError(
                f"{directory}: no readable {BEST_NAME}; train with checkpoints, or "
                "give --checkpoint STEPS"
            )
        path = directory / str(name)
    elif which.isdigit():
        found = sorted(directory.glob(f"*_{int(which)}_steps.zip"))
        path = found[0] if found else directory / f"ppo_{int(which)}_steps.zip"
    else:
        raise PolicyError(f"--checkpoint {which!r}: give 'best' or a step count")
    if not path.is_file():
        kept = sorted(p.name for p in directory.glob("*_steps.zip"))
        raise PolicyError(f"no checkpoint {path.name} in {directory}; kept: {', '.join(kept)}")
    return path


def _evaluation_record(run: Path, model_sha: str) -> dict[str, Any]:
    """An evaluation of the shipped model: its settings and result (no machine paths)."""
    try:
        summary = json.loads((run / "summary.json").read_text())
        manifest = json.loads((run / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        raise PolicyError(
            f"--evaluation {run}: no readable summary.json and manifest.json ({exc})"
        ) from None
    settings = manifest.get("settings", {})
    if manifest.get("command") != "evaluate":
        raise PolicyError(f"--evaluation {run} is a `gymprecice {manifest.get('command')}` run")
    if settings.get("model_sha256") != model_sha:
        raise PolicyError(
            f"--evaluation {run} evaluated another model (SHA-256 "
            f"{str(settings.get('model_sha256'))[:12]}..., this one {model_sha[:12]}...)"
        )
    kwargs = settings.get("env_kwargs", {})
    return {
        "command": _command_line(manifest.get("argv"), manifest.get("cwd")),
        "env_id": settings.get("env_id"),
        "episode_time": kwargs.get("episode_time"),
        "episodes": settings.get("episodes"),
        "double": settings.get("double"),
        "deterministic": settings.get("deterministic"),
        "source": (manifest.get("source") or {}).get("git"),
        "created": manifest.get("created"),
        "over_episodes": summary.get("over_episodes"),
        "change_percent": summary.get("change_percent"),
        "episodes_summary": summary.get("episodes"),
    }


# -- commands --------------------------------------------------------------------------------


def ship_command(args: argparse.Namespace) -> int:
    """``gymprecice ship-policy TRAIN_DIR [--name NAME] [--evaluation RUN]``."""
    try:
        dest = ship_policy(
            args.train_dir,
            args.name,
            evaluation=args.evaluation,
            directory=args.into,
            force=args.force,
            checkpoint=args.checkpoint,
        )
    except PolicyError as exc:
        print(f"gymprecice ship-policy: {exc}", file=sys.stderr)
        return 2
    meta = read_metadata(dest)
    sizes = ", ".join(f"{f} {r['bytes'] / 1e6:.2f} MB" for f, r in meta["files"].items())
    print(
        f"gymprecice ship-policy: shipped {meta['name']!r} (trained on {meta['env']['name']}, "
        f"{meta['training']['timesteps']:,} steps, {meta['env_kwargs']}) into {dest}: {sizes}"
    )
    return 0


def _objective(env_name: str) -> str | None:
    """The per-action metric an env is judged on (``None``: unknown env or none)."""
    try:
        return find_lab_env(env_name).objective
    except LabEnvError:
        return None


def list_command(args: argparse.Namespace) -> int:
    """``gymprecice policies``: one line per shipped policy."""
    policies = shipped_policies()
    if not policies:
        where = ", ".join(str(p) for p in policy_folders()) or "no installed package's card"
        print(f"gymprecice policies: none shipped in {where}")
        return 0
    for name, meta in policies.items():
        line = (
            f"{name}: trained on {meta['env']['name']} for {meta['training']['timesteps']:,} "
            f"steps, {meta['env_kwargs']}"
        )
        over = (meta.get("evaluation") or {}).get("over_episodes") or {}
        cd = over.get("mean_Cd")
        objective = _objective(meta["env"]["name"])
        if not cd and objective and over.get(f"mean_{objective}"):
            # an env judged on another metric than drag (the flap, the heated plate)
            value = over[f"mean_{objective}"]
            label = objective if objective.startswith("mean_") else f"mean {objective}"
            line += (
                f"; evaluated {label} {value['mean']:.4g} ± {value['std']:.2g} "
                f"over {value['n']} episodes"
            )
        if cd:
            line += f"; evaluated mean Cd {cd['mean']:.4f}"
            change = (meta["evaluation"].get("change_percent") or {}).get("mean_Cd")
            if change is not None:
                line += f" ({change:+.2f} % against the baseline)"
        print(line)
    return 0
