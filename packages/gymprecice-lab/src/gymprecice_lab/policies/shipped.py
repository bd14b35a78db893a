"""Trained policies that ship inside a package, so a user can evaluate one without training:
where they are, which one ``--policy`` names, and loading one to run.

An env's package ships its policies in the folder its lab card's ``policies`` names
(``"package:folder"``; the tutorials' ``gymprecice_tutorials/policies/``), each a
directory ``<name>/`` (its files: :mod:`gymprecice_lab.policies.policy`).

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
The env a policy runs on is built with the policy's action bound
(:mod:`gymprecice_lab.policies.fitted_env`); shipping a training run is
:mod:`gymprecice_lab.policies.ship`.

``GYMPRECICE_POLICIES_DIR`` (or a ``directory`` argument) points all of this at another
directory than the packages': tests ship into a temporary one.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv, LabEnvError, find_lab_env, lab_envs
from gymprecice_lab.policies.fitted_env import check_policy_env, describe_env, policy_env_kwargs
from gymprecice_lab.policies.policy import (
    METADATA_NAME,
    MODEL_NAME,
    POLICY_NAME,
    Policy,
    PolicyError,
    read_metadata,
)

__all__ = [
    "POLICIES_DIR_ENV",
    "PolicyController",
    "load_shipped",
    "policies_dir",
    "policies_folder",
    "policy_folders",
    "resolve_policy",
    "shipped_policies",
    "shipped_policy_dirs",
]

#: Environment variable naming another directory of shipped policies (tests use it).
POLICIES_DIR_ENV = "GYMPRECICE_POLICIES_DIR"


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


def _policies_in(root: Path) -> dict[str, Path]:
    if not root.is_dir():
        return {}
    return {
        path.name: path
        for path in sorted(root.iterdir())
        if POLICY_NAME.match(path.name)
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
    which: str = "kept",
) -> Policy:
    """The policy ``--policy`` names: a shipped name, ``shipped`` (the one named after
    ``env``) or a path (model ``.zip``, training directory, policy directory); of a
    training directory its kept model, or with ``which="final"`` its final one."""
    from gymprecice_lab.common.wrapped_env import find_model

    text = os.fspath(spec)
    bare = POLICY_NAME.match(text) is not None
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
        model, note = find_model(path, which)
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
    from gymprecice_lab.common.manifest import file_sha256

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


# -- running one ----------------------------------------------------------------------------


def load_shipped(
    spec: str | os.PathLike[str],
    env: str,
    *,
    idx: int = 0,
    device: str = "cpu",
    directory: str | os.PathLike[str] | None = None,
    **env_kwargs: Any,
) -> tuple[Any, Any]:
    """``(vec_env, model)`` like :func:`gymprecice_lab.common.wrapped_env.load_policy`, for any
    ``--policy`` value; the env is built with the policy's action bound (``env_kwargs``
    given here win)::

        venv, model = load_shipped("jet-cylinder-fast", "jet-cylinder", double=True)
    """
    from gymprecice_lab.common.wrapped_env import load_policy

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

        from gymprecice_lab.common.wrapped_env import find_model, load_model, load_normalizer

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


# -- the command -----------------------------------------------------------------------------


def _objective(env_name: str) -> str | None:
    """The per-action metric an env is judged on (``None``: unknown env or none)."""
    try:
        return find_lab_env(env_name).objective
    except LabEnvError:
        return None


def list_command() -> int:
    """``gymprecice policies`` (it takes no option): one line per shipped policy."""
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
        if meta.get("shared_by"):  # trained --shared-policy: one policy every agent runs
            line += f"; one policy shared by {', '.join(meta['shared_by'])}"
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
