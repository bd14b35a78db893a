"""Shipping a training run: ``gymprecice ship-policy`` copies a trained model, with what it
was trained on and how, into the folder of shipped policies.

The model is stripped to what evaluation needs (:mod:`gymprecice_lab.policies.slim_model`), the
training env described by the keyword arguments that shape what the policy does
(:mod:`gymprecice_lab.policies.fitted_env`), and ``policy.json`` (:mod:`gymprecice_lab.policies.policy`)
records the training run: the algorithm and hyperparameters, the training command (without
the machine's directories: a policy ships to other machines), timesteps, wall-clock time,
source revision and the SHA-256 of the trained model file, the files' own checksums and,
with ``--evaluation RUN``, that evaluation's result. A policy directory is replaced whole
or not at all.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from gymprecice_lab.common.kept_model import KEPT_MODEL, read_kept
from gymprecice_lab.common.registered_env import LabEnv, LabEnvError, find_lab_env
from gymprecice_lab.policies.command_settings import ShipSettings
from gymprecice_lab.policies.fitted_env import MACHINE_KWARGS, describe_env
from gymprecice_lab.policies.policy import (
    FORMAT,
    METADATA_NAME,
    MODEL_NAME,
    POLICY_NAME,
    PolicyError,
    read_metadata,
)
from gymprecice_lab.policies.shipped import policies_dir
from gymprecice_lab.policies.slim_model import (
    check_same_actions,
    write_frozen_stats,
    write_slim_model,
)
from gymprecice_lab.training.shared_policy import per_row

__all__ = ["ship_command", "ship_policy"]

#: Names ``--policy`` reads as something else than a policy's name.
_RESERVED = ("shipped",)


def ship_policy(
    train_dir: str | os.PathLike[str],
    name: str | None = None,
    *,
    evaluation: str | os.PathLike[str] | None = None,
    directory: str | os.PathLike[str] | None = None,
    force: bool = False,
    checkpoint: str | None = None,
    which: str = "kept",
) -> Path:
    """Copy a training run's kept model into the shipped policies as ``name`` (default:
    the training env's name); return the policy's directory.

    ``train_dir`` is a ``gymprecice train`` output (its kept model, the best of its
    validations; ``which="final"``: its ``model.zip``; failing both, its newest
    checkpoint); ``checkpoint`` picks one of its checkpoints instead: ``"best"`` (the one
    with the highest mean training return, ``checkpoints/best.json``: chosen by training,
    never by an evaluation) or a step count. ``evaluation`` a ``gymprecice evaluate``
    output of that model, whose result ``policy.json`` then records. An existing policy of
    that name is replaced only with ``force``.
    """
    from gymprecice_lab.common.manifest import file_sha256
    from gymprecice_lab.common.wrapped_env import load_model, vecnormalize_path

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
    source = _source(train_dir, checkpoint, which)
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
    if not POLICY_NAME.match(name) or name in _RESERVED:
        raise PolicyError(
            f"policy name {name!r}: use lower-case letters, digits, '.', '_' and '-', "
            f"starting with a letter or digit (not {', '.join(_RESERVED)})"
        )
    return name


def _source(train_dir: Path, checkpoint: str | None, which: str = "kept") -> Path:
    """The model to ship: the checkpoint named, else the run's kept model (``which``
    ``"final"``: its final one; failing both, its newest checkpoint), said in one line."""
    from gymprecice_lab.common.wrapped_env import find_model

    if checkpoint is not None:
        return _checkpoint(train_dir, checkpoint)
    try:
        source, note = find_model(train_dir, which)
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
    from gymprecice_lab.common.manifest import file_sha256, package_versions

    root = dest.parent
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", dir=root))
    try:
        write_slim_model(model, tmp / MODEL_NAME)
        check_same_actions(model, tmp / MODEL_NAME)
        files = [MODEL_NAME]
        if stats.is_file():
            write_frozen_stats(stats, tmp / "model_vecnormalize.pkl")
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
    kwargs = {k: v for k, v in settings.get("env_kwargs", {}).items() if k not in MACHINE_KWARGS}
    model_sha = sha(source)
    kept = read_kept(train_dir) if source == train_dir / KEPT_MODEL else None
    # the checksum train recorded of this very file: the kept model's, or model.zip's
    recorded = (result.get("kept") or {}).get("model_sha256") if kept else None
    recorded = recorded or (None if kept else result.get("model_sha256"))
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
        # the kept model: the best of the run's validations, and what chose it
        "kept": (
            {k: kept.get(k) for k in ("timesteps", "mean_return", "score", "starts")}
            if kept
            else None
        ),
    }


def _checkpoint(train_dir: Path, which: str) -> Path:
    """``train_dir``'s checkpoint ``which``: ``best`` or a step count."""
    from gymprecice_lab.training.callbacks import BEST_NAME, read_best

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


# -- the command -----------------------------------------------------------------------------


def ship_command(settings: ShipSettings) -> int:
    """``gymprecice ship-policy TRAIN_DIR [--name NAME] [--evaluation RUN]``."""
    try:
        dest = ship_policy(
            settings.train_dir,
            settings.name,
            evaluation=settings.evaluation,
            directory=settings.into,
            force=settings.force,
            checkpoint=settings.checkpoint,
            which=settings.model,
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
