"""``gymprecice train``: PPO (Stable-Baselines3) on N parallel tutorial environments.

What a long training run on a shared machine needs, and how it is met:

* **parallel simulations that do not take training down**: the envs run in subprocesses
  through :class:`gymprecice.sb3.ResilientSubprocVecEnv` (a crashed or hung solver costs
  one episode, not the run) when it is installed, else SB3's ``SubprocVecEnv``;
* **resumable**: checkpoints go to ``<out>/checkpoints/ppo_<steps>_steps.zip`` every
  ``--checkpoint-every`` env steps and at the end; a rerun of the same command continues
  from the newest one (``--fresh`` starts over);
* **observable**: a progress bar, TensorBoard logs in ``<out>/tb``, per-env episode
  returns in ``<out>/monitor/env_<i>.monitor.csv`` (what ``gymprecice plot`` draws);
* **traceable**: ``<out>/manifest.json`` (versions, solver checks, case hashes, seeds);
* **fails fast**: ``--require-solvers`` runs ``gymprecice doctor``'s checks first and stops
  with their explanation when preCICE or a solver the env needs is missing.

Actions are rescaled to ``[-1, 1]`` for the policy (``RescaleAction``): PPO's Gaussian
policy starts with unit standard deviation, which against a ``±2.5e-4`` box would only
ever produce the bounds.
"""

from __future__ import annotations

import argparse
import functools
import io
import re
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice_tutorials.manifest import read_manifest, write_manifest
from gymprecice_tutorials.plugin import ENVIRONMENTS, TutorialEnv, find_environment

__all__ = [
    "CHECKPOINT_PREFIX",
    "build_env_kwargs",
    "doctor_text",
    "latest_checkpoint",
    "make_env",
    "missing_requirements",
    "require_solvers",
    "train",
    "train_command",
]

CHECKPOINT_PREFIX = "ppo"
_CHECKPOINT = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")

#: ``gymprecice doctor`` checks each environment needs: a check counts when its name, in
#: lower case, starts with one of these (``openfoam`` covers OpenFOAM itself and the
#: OpenFOAM-preCICE adapter, without which OpenFOAM runs uncoupled and the controller waits
#: forever). The two-process cylinder cases also need decomposePar and mpirun.
_NEEDS: dict[str, tuple[str, ...]] = {
    "jet-cylinder": ("pyprecice", "openfoam", "blockmesh", "decomposepar", "mpirun"),
    "rotating-cylinder": ("pyprecice", "openfoam", "blockmesh", "decomposepar", "mpirun"),
    "quickstart": ("pyprecice", "openfoam", "blockmesh"),
    "perpendicular-flap": ("pyprecice", "openfoam", "deal.ii", "elasticity"),
}


# -- solver requirements -------------------------------------------------------------------


def missing_requirements(report: Mapping[str, Any], env: TutorialEnv) -> list[dict[str, Any]]:
    """The failed doctor checks that ``env`` needs to run on real solvers.

    Every failed *required* check counts, plus the checks the env itself needs
    (``_NEEDS``): the doctor marks only Python and pyprecice as required for everyone.
    """
    needs = _NEEDS.get(env.name, ("pyprecice",))
    missing = []
    for check in report["checks"]:
        if check["ok"]:
            continue
        name = str(check["name"]).lower()
        if check.get("required") or name.startswith(needs):
            missing.append(dict(check))
    return missing


def doctor_text(report: Mapping[str, Any]) -> str:
    """The doctor report as ``gymprecice doctor`` prints it."""
    out = io.StringIO()
    for check in report["checks"]:
        mark = "[ok]     " if check["ok"] else "[MISSING]" if check["required"] else "[--]     "
        required = " (required)" if check["required"] else ""
        source = "" if check["source"] == "core" else f" [{check['source']}]"
        print(f"{mark} {check['name']}{required}{source}: {check['detail']}", file=out)
        if not check["ok"] and check.get("advice"):
            print(f"          -> {check['advice']}", file=out)
    return out.getvalue()


def require_solvers(env: TutorialEnv, command: str = "train") -> int:
    """0 when this machine can run ``env`` on real solvers; else explain and return 1."""
    from gymprecice.cli import doctor_report

    report = doctor_report()
    missing = missing_requirements(report, env)
    if not missing:
        return 0
    names = ", ".join(
        "pyprecice (the preCICE library and its Python bindings)"
        if c["name"] == "pyprecice"
        else str(c["name"])
        for c in missing
    )
    print(
        f"gymprecice {command}: {env.name} cannot run on real solvers on this machine; "
        f"missing: {names}.\n\n{doctor_text(report)}\n"
        f"Install what is missing (see the advice above and the README's 'Real preCICE'), "
        f"or add --double to run against gymprecice's preCICE test double.",
        file=sys.stderr,
    )
    return 1


# -- environments --------------------------------------------------------------------------


def build_env_kwargs(args: argparse.Namespace, env: TutorialEnv, out: Path) -> dict[str, Any]:
    """Constructor keyword arguments of the environment from the command's options."""
    kwargs: dict[str, Any] = {"run_root": str((out / "envs").resolve())}
    episode_time = getattr(args, "episode_time", None)
    if args.double:
        if not env.double:
            raise SystemExit(
                f"gymprecice: {env.name} has no scripted fake flow for --double; run it on real "
                f"solvers (choose one of "
                f"{', '.join(e.name for e in ENVIRONMENTS.values() if e.double)} for --double)"
            )
        if args.case is not None:
            raise SystemExit("gymprecice: --double runs a packaged case; drop --case")
        kwargs["double"] = True
    if args.case is not None:
        if episode_time is not None:
            raise SystemExit(
                "gymprecice: --episode-time shapes a packaged case; with --case set the "
                "coupling's max-time in your precice-config.xml instead"
            )
        kwargs["options"] = str(args.case.resolve())
    elif episode_time is not None:
        if not env.recipe:
            raise SystemExit(
                f"gymprecice: {env.name} has a fixed case; --episode-time does not apply "
                "(its episode length is the coupling's max-time)"
            )
        kwargs["episode_time"] = float(episode_time)
    elif getattr(args, "default_episode_time", None) and env.recipe:
        kwargs["episode_time"] = float(args.default_episode_time)
    kwargs.update(args.env_kwargs or {})
    return kwargs


def make_env(
    env_id: str,
    idx: int,
    kwargs: Mapping[str, Any],
    *,
    monitor_file: str | None = None,
    rescale: bool = True,
) -> gym.Env:
    """One environment as training and evaluation see it (module level: picklable).

    ``rescale`` maps a bounded ``Box`` action space to ``[-1, 1]``; ``monitor_file`` records
    episode returns and lengths with SB3's ``Monitor`` (appending on resume).
    """
    import gymprecice  # noqa: F401  (registers the gymprecice/... ids in this process)

    env = gym.make(env_id, idx=idx, **dict(kwargs))
    space = env.action_space
    if (
        rescale
        and isinstance(space, gym.spaces.Box)
        and np.all(np.isfinite(space.low))
        and np.all(np.isfinite(space.high))
    ):
        unit = np.ones(space.shape, dtype=space.dtype)
        env = gym.wrappers.RescaleAction(env, -unit, unit)
    if monitor_file is not None:
        from stable_baselines3.common.monitor import Monitor

        # A resumed run appends to its monitor file (SB3 writes the header only into a
        # new file, so a new file must be started with override_existing=True).
        exists = Path(
            monitor_file if monitor_file.endswith(".csv") else f"{monitor_file}.monitor.csv"
        )
        env = Monitor(env, filename=monitor_file, override_existing=not exists.is_file())
    return env


def _vec_env(fns: Sequence[Callable[[], gym.Env]], kind: str, log_dir: Path) -> Any:
    """The vector env of kind ``kind`` (see ``gymprecice train --vec-env``).

    The resilient env gets no reset deadline of its own: an env's first reset includes
    the case's pre-run (minutes to hours of CFD), which has its own timeout in the
    solver plugin, and the Adapter's ``timeouts`` already catch hung couplings.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if kind == "dummy":
        return DummyVecEnv(list(fns))
    if kind in ("auto", "resilient"):
        try:
            from gymprecice.sb3 import ResilientSubprocVecEnv
        except ImportError:
            if kind == "resilient":
                raise SystemExit(
                    "gymprecice: --vec-env resilient needs gymprecice.sb3, which this "
                    "installation of gymprecice-core does not have"
                ) from None
        else:
            return ResilientSubprocVecEnv(list(fns), reset_timeout=None, log_dir=str(log_dir))
    return SubprocVecEnv(list(fns))


# -- checkpoints ---------------------------------------------------------------------------


def latest_checkpoint(directory: Path) -> tuple[Path, int] | None:
    """The checkpoint with the most env steps in ``directory`` (``None`` if there is none)."""
    best: tuple[Path, int] | None = None
    if not directory.is_dir():
        return None
    for path in directory.iterdir():
        match = _CHECKPOINT.match(path.name)
        if match and (best is None or int(match.group(1)) > best[1]):
            best = (path, int(match.group(1)))
    return best


# -- training ------------------------------------------------------------------------------


def train(
    env: TutorialEnv,
    out: Path,
    env_kwargs: Mapping[str, Any],
    *,
    n_envs: int = 1,
    timesteps: int = 100_000,
    n_steps: int = 80,
    batch_size: int = 80,
    n_epochs: int = 10,
    learning_rate: float = 3e-4,
    gamma: float = 0.99,
    net: Sequence[int] = (512, 512),
    checkpoint_every: int | None = None,
    fresh: bool = False,
    vec_env: str = "auto",
    progress_bar: bool = True,
    device: str = "cpu",
    seed: int = 0,
) -> dict[str, Any]:
    """Train (or resume training) and return a summary; see the module docstring."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

    out.mkdir(parents=True, exist_ok=True)
    checkpoints = out / "checkpoints"
    monitor = out / "monitor"
    monitor.mkdir(exist_ok=True)
    if fresh:
        for old in list(checkpoints.glob(f"{CHECKPOINT_PREFIX}_*_steps.zip")) + list(
            monitor.glob("*.monitor.csv")
        ):
            old.unlink()
    fns = [
        functools.partial(
            make_env,
            env.env_id,
            i,
            dict(env_kwargs),
            monitor_file=str(monitor / f"env_{i}"),
        )
        for i in range(n_envs)
    ]
    vec = _vec_env(fns, vec_env, out / "workers")
    try:
        vec.seed(seed)
        resume = None if fresh else latest_checkpoint(checkpoints)
        if resume is not None:
            model = PPO.load(
                resume[0], env=vec, device=device, tensorboard_log=str(out / "tb"), seed=seed
            )
            print(f"gymprecice train: resuming from {resume[0]} ({model.num_timesteps} steps)")
        else:
            if batch_size > n_steps * n_envs:
                batch_size = n_steps * n_envs
            model = PPO(
                "MlpPolicy",
                vec,
                n_steps=n_steps,
                batch_size=batch_size,
                n_epochs=n_epochs,
                learning_rate=learning_rate,
                gamma=gamma,
                policy_kwargs={"net_arch": {"pi": list(net), "vf": list(net)}},
                tensorboard_log=str(out / "tb"),
                seed=seed,
                device=device,
                verbose=0,
            )
        done_before = int(model.num_timesteps)
        remaining = timesteps - done_before
        every = checkpoint_every or 10 * model.n_steps * n_envs
        callbacks: list[Any] = [
            CheckpointCallback(
                save_freq=max(1, every // n_envs),
                save_path=str(checkpoints),
                name_prefix=CHECKPOINT_PREFIX,
            )
        ]
        callbacks += _telemetry_callbacks(vec)
        started = time.monotonic()
        interrupted = False
        if remaining > 0:
            try:
                model.learn(
                    total_timesteps=remaining,
                    callback=CallbackList(callbacks),
                    tb_log_name=CHECKPOINT_PREFIX,
                    reset_num_timesteps=resume is None,
                    progress_bar=progress_bar,
                )
            except KeyboardInterrupt:
                # Ctrl-C: keep what was learnt (the policy lives in this process); the
                # same command resumes from the checkpoint written below.
                interrupted = True
        else:
            print(f"gymprecice train: already trained for {done_before} >= {timesteps} steps")
        checkpoints.mkdir(parents=True, exist_ok=True)
        final = checkpoints / f"{CHECKPOINT_PREFIX}_{model.num_timesteps}_steps.zip"
        model.save(final)
        model.save(out / "model.zip")
        return {
            "timesteps": int(model.num_timesteps),
            "resumed_from": str(resume[0]) if resume else None,
            "steps_this_run": int(model.num_timesteps) - done_before,
            "seconds": round(time.monotonic() - started, 3),
            "model": str(out / "model.zip"),
            "interrupted": interrupted,
        }
    finally:
        vec.close()


def _telemetry_callbacks(vec: Any) -> list[Any]:
    """gymprecice's telemetry callback (time in solvers vs env vs learner, failures) in
    TensorBoard, for the resilient vector env that measures it."""
    try:
        from gymprecice.sb3 import ResilientSubprocVecEnv, TelemetryCallback
    except ImportError:
        return []
    return [TelemetryCallback()] if isinstance(vec, ResilientSubprocVecEnv) else []


def _net(text: str) -> list[int]:
    try:
        sizes = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1:
        raise SystemExit(f"gymprecice train: --net must be sizes like 512,512, got {text!r}")
    return sizes


def default_out(env: TutorialEnv, command: str) -> Path:
    return Path("runs") / env.name / command


def train_command(args: argparse.Namespace) -> int:
    """``gymprecice train``."""
    try:
        env = find_environment(args.env)
    except KeyError as exc:
        print(f"gymprecice train: {exc.args[0]}", file=sys.stderr)
        return 2
    if args.require_solvers and not args.double:
        status = require_solvers(env, "train")
        if status:
            return status
    out = (args.out or default_out(env, "train")).resolve()
    kwargs = build_env_kwargs(args, env, out)
    case_dir = _case_dir(env, kwargs)
    settings = {
        key: getattr(args, key)
        for key in (
            "n_envs",
            "timesteps",
            "n_steps",
            "batch_size",
            "n_epochs",
            "learning_rate",
            "gamma",
            "net",
            "checkpoint_every",
            "fresh",
            "vec_env",
            "device",
            "double",
        )
    }
    settings.update({"env_id": env.env_id, "env_kwargs": kwargs})
    seeds = {"seed": args.seed, "env_seeds": [args.seed + i for i in range(args.n_envs)]}
    write_manifest(out, command="train", case_dir=case_dir, seeds=seeds, settings=settings)
    result = train(
        env,
        out,
        kwargs,
        n_envs=args.n_envs,
        timesteps=args.timesteps,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        n_epochs=args.n_epochs,
        learning_rate=args.learning_rate,
        gamma=args.gamma,
        net=_net(args.net),
        checkpoint_every=args.checkpoint_every,
        fresh=args.fresh,
        vec_env=args.vec_env,
        progress_bar=not args.no_progress_bar,
        device=args.device,
        seed=args.seed,
    )
    write_manifest(
        out,
        command="train",
        case_dir=case_dir,
        seeds=seeds,
        settings=settings,
        solvers=read_manifest(out)["solvers"],
        extra={"result": result},
    )
    if result["interrupted"]:
        print(
            f"gymprecice train: interrupted after {result['timesteps']} steps; saved "
            f"{result['model']} and a checkpoint; run the same command again to resume",
            file=sys.stderr,
        )
        return 130
    print(
        f"gymprecice train: {result['timesteps']} steps; model {result['model']}; "
        f"TensorBoard: tensorboard --logdir {out / 'tb'}"
    )
    return 0


def _case_dir(env: TutorialEnv, kwargs: Mapping[str, Any]) -> Path | None:
    """The case the envs will run (materialised now, once, for all of them).

    Building one env here (no solver starts before ``reset``) writes the recipe's case, so
    the N env processes find it ready, and gives its directory for the manifest.
    """
    probe = make_env(env.env_id, 0, kwargs, rescale=False)
    try:
        config = getattr(probe.unwrapped, "config", None)
        return Path(config.case_dir) if config is not None else None
    finally:
        probe.close()
