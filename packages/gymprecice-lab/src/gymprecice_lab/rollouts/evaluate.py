"""``gymprecice evaluate | baseline | open-loop``: run a controller and record what happens.

The command's work; its parts: the controllers (:mod:`gymprecice_lab.rollouts.controllers`),
the loop (:mod:`gymprecice_lab.rollouts.rollout`) and the files and statistics
(:mod:`gymprecice_lab.rollouts.records`). Their public names are also reachable here, as at
the old path ``gymprecice_lab.evaluate``.

All three run whole episodes of one environment with a fixed controller and write the
same files, so ``gymprecice plot`` can put any of them side by side:

* ``history.csv``: one row per action: ``episode, step, start, time, reward``, the
  step's metrics, ``action_0..`` (``start``/``time``: coupling time at the action's start
  and end; metrics: the named scalars an env reports in ``info["metrics"]``, e.g. the
  cylinders' ``Cd``/``Cl`` averages the reward used, or the flap's tip displacement;
  actions in the env's own units);
* ``coefficients.csv``: every solver step's ``episode, time`` and the force coefficients
  among the env's ``info["metrics"]`` (the cylinders' ``Cd, Cl``, from each step's
  ``info["coefficients"]`` rows); not written for an env whose metrics have neither;
* ``summary.json``: per-episode return and the mean of each metric the env reports
  (``mean_<name>``: the cylinders' ``mean_Cd``, the flap's ``mean_mean_tip_displacement``,
  the heated plate's ``mean_tracking_error``), for an env with force coefficients (the
  cylinders) also the mean Cd and mean |Cl| over every solver step
  (``series_mean_Cd``, ``series_mean_abs_Cl``: what a drag-reduction claim is stated in;
  the per-action means differ where the reward averages over a window longer than an
  action), and over the episodes the mean and standard deviation of each
  (``over_episodes``) and, with ``--baseline RUN``, the % change of each mean against
  that run's;
* ``manifest.json``.

The controllers: ``evaluate`` is a trained PPO policy, deterministic by default (the mean
action: what one would deploy), over a horizon longer than the training episodes (10 s
by default against 2 s) to show that the control holds; ``baseline`` is the uncontrolled
flow that a controller is judged against (the zero action clipped into the action box,
in the env's own units: jets closed, cylinder at rest; with the card's ``uncontrolled``
env keywords where it declares them); ``open-loop`` is a sinusoid, the classic forcing a
learned controller should beat;
``feedback`` a classical feedback law (:mod:`gymprecice_lab.rollouts.feedback`).

A controller is ``controller(observation, time) -> action``; one with a ``reset()``
method has it called at every episode's start, one with ``observe(info)`` sees every
step's ``info`` (how a feedback law measures its signal). With ``--all-starts`` the
commands run one episode from each held-out start of the env
(:mod:`gymprecice_lab.common.starts`), episode k from held-out start k whatever the seed;
without it each episode's start is drawn from the held-out split by its seed, as before
(the documented results were made that way).

``--video [FILE]`` (any of the four) also writes a video of each episode, MP4 or GIF
(:mod:`gymprecice_lab.rollouts.video`; default ``episode.mp4`` in ``--out``), named in the
summary's episodes.

``evaluate --policy`` names the policy: a training directory or model file, a policy
shipped with the package by name, or ``shipped`` (the one shipped for the env). The env
is built with the action bound the policy was trained with, also on another env (a
transfer, said in one line); see :mod:`gymprecice_lab.policies.shipped` and
:mod:`gymprecice_lab.policies.fitted_env`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym

from gymprecice.plugin.card import FeedbackLaw
from gymprecice_lab.common.manifest import file_sha256, read_manifest, write_manifest
from gymprecice_lab.common.registered_env import (
    LabEnv,
    LabEnvError,
    default_frequency,
    default_out,
)
from gymprecice_lab.common.requirements import require_solvers
from gymprecice_lab.common.starts import (
    StartsError,
    evaluation_starts,
    held_out_starts,
    validation_starts,
)
from gymprecice_lab.common.wrapped_env import (
    load_model,
    load_normalizer,
    make_env_checked,
    vecnormalize_path,
)
from gymprecice_lab.common.wrapping import WrapError, wrap_spec
from gymprecice_lab.policies.fitted_env import check_policy_env, policy_env_kwargs
from gymprecice_lab.policies.policy import Policy, PolicyError
from gymprecice_lab.policies.shipped import resolve_policy, shipped_policies
from gymprecice_lab.rollouts.command_settings import RolloutSettings
from gymprecice_lab.rollouts.controllers import (
    Controller,
    law_point,
    sine_controller,
    zero_controller,
)
from gymprecice_lab.rollouts.feedback import FeedbackController
from gymprecice_lab.rollouts.records import (
    change_against,
    coefficient_columns,
    episodes_by_start,
    floor_metrics,
    over_episodes,
)
from gymprecice_lab.rollouts.rollout import rollout
from gymprecice_lab.rollouts.video import (
    DEFAULT_NAME,
    VideoError,
    check_renders,
    check_video_path,
)

__all__ = [
    "change_against",
    "coefficient_columns",
    "episodes_by_start",
    "floor_metrics",
    "law_point",
    "over_episodes",
    "rollout",
    "rollout_command",
    "sine_controller",
    "zero_controller",
]


def _policy(settings: RolloutSettings, env: LabEnv) -> Policy:
    """The policy to evaluate (``--policy``/``--model``, default ``runs/<env>/train``)."""
    spec = settings.policy
    try:
        policy = resolve_policy(
            spec if spec is not None else default_out(env, "train"),
            env,
            which=settings.model,
        )
    except PolicyError as exc:
        hint = ""
        if spec is None:
            names = ", ".join(shipped_policies()) or "none yet"
            hint = (
                f"; train one first (`gymprecice train {env.name}`) or pass --policy "
                f"NAME|PATH (shipped policies: {names})"
            )
        raise SystemExit(f"gymprecice evaluate: {exc}{hint}") from None
    for note in policy.notes:
        print(f"gymprecice evaluate: {note}")
    return policy


def _read_baseline(path: Path) -> dict[str, Any]:
    try:
        return json.loads((path / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        raise SystemExit(
            f"gymprecice: --baseline {path}: no readable summary.json ({exc}); run "
            f"`gymprecice baseline ENV --out {path}` first"
        ) from None


#: What the one-line report shows of an env with force coefficients (the cylinders): (summary
#: key, label, % change against a baseline?), their drag and lift over every solver step.
#: No % for the return or the lift: both are about zero uncontrolled (the reward offset is
#: the uncontrolled drag), so a relative change of them says nothing.
_SERIES_REPORTED = (
    ("return", "return", False),
    ("series_mean_Cd", "mean Cd", True),
    ("series_mean_abs_Cl", "mean |Cl|", True),
)


def _reported(stats: dict[str, Any], env_info: LabEnv) -> list[tuple[str, str, bool]]:
    """What the one-line report shows: the cylinders' force coefficients over every solver
    step where recorded, else the episode means of the env's own metrics (its card's
    objective, with its % change against a baseline, then its ``metrics``); then the
    fractions of its reference (a drag floor) where it declares one."""
    if "series_mean_Cd" in stats:
        shown = list(_SERIES_REPORTED)
    else:
        shown = [("return", "return", False)]
        objective = env_info.objective
        for name in env_info.episode_metrics:
            shown.append((f"mean_{name}", f"mean {name}", name == objective))
    if env_info.reference is not None:
        shown.append(("floor_fraction", f"fraction of the {env_info.reference.label}", False))
        shown.append(("settled_floor_fraction", "settled", False))
    return shown


def _report(command: str, summary: dict[str, Any], out: Path, env_info: LabEnv) -> str:
    """One line: mean ± std over the episodes of the return and the env's metrics (the
    cylinders: Cd and |Cl|), with the % change against a baseline where it means something."""
    stats = summary["over_episodes"]
    source = "series" if "series_mean_Cd" in stats else "actions"
    parts = []
    for key, label, relative in _reported(stats, env_info):
        if key in stats:
            part = f"{label} {stats[key]['mean']:.4f} ± {stats[key]['std']:.4f}"
            change = summary.get("change_percent", {}).get(key)
            if relative and change is not None:
                part += f" ({change:+.2f} % against the baseline)"
            parts.append(part)
    over = "over every solver step, " if source == "series" else ""
    return (
        f"gymprecice {command}: {len(summary['episodes'])} episode(s), "
        f"{', '.join(parts)} ({over}mean ± std over episodes); results in {out}"
    )


class _Unusable(Exception):
    """What the user typed cannot run: one line, exit status 2, nothing left running."""


def rollout_command(settings: RolloutSettings) -> int:
    """``gymprecice evaluate`` / ``baseline`` / ``open-loop`` / ``feedback`` (the
    settings' ``command``)."""
    try:
        return _rollout_command(settings.command, settings)
    except _Unusable as exc:
        print(f"gymprecice {settings.command}: {exc}", file=sys.stderr)
        return 2


def _rollout_command(command: str, settings: RolloutSettings) -> int:
    try:
        env_info = settings.lab_env
    except LabEnvError as exc:
        raise _Unusable(str(exc)) from None
    out = settings.run_dir
    kwargs = dict(settings.constructor_kwargs)  # added to below
    if command == "baseline":  # where the action cannot say "uncontrolled", a kwarg does
        kwargs = {**dict(env_info.baseline_kwargs), **kwargs}
    baseline = _read_baseline(settings.baseline) if settings.baseline else None
    video = _video(settings, env_info, out)
    if video is not None:
        kwargs["render_mode"] = "rgb_array"
    policy = _policy(settings, env_info) if command == "evaluate" else None
    applied = _policy_kwargs(policy, env_info, settings) if policy is not None else {}
    kwargs.update(applied)
    # what was typed is checked before the machine: a bad --law is the user's to fix anywhere
    own_law = _own_law(settings, env_info) if command == "feedback" else None
    if not settings.double:
        status = require_solvers(env_info, command, verbose=settings.require_solvers, kwargs=kwargs)
        if status:
            return status
    # the robustness wrappers' noise is seeded by each episode's reset seed
    try:
        robustness = wrap_spec(list(settings.wrap))
    except WrapError as exc:
        raise _Unusable(str(exc)) from None
    # The policy acts in [-1, 1] (training rescales); the fixed controllers act in the
    # env's own units, so that "zero" means jets closed.
    env = make_env_checked(
        env_info.name,
        env_info.env_id,
        0,
        kwargs,
        rescale=command == "evaluate",
        robustness=robustness,
    )
    try:
        episodes, starts = _episodes(command, settings, env, env_info)
        recorded: dict[str, Any] = {
            "robustness": robustness,
            "env_id": env_info.env_id,
            "env_kwargs": kwargs,
            "episodes": episodes,
            "starts": "validation" if settings.validation_starts else "held-out",
            "held_out_starts": (
                list(starts) if starts is not None and not settings.validation_starts else None
            ),
            "validation_starts": list(starts) if settings.validation_starts else None,
            "double": settings.double,
            "video": str(video) if video is not None else None,
        }
        controller, described = _controller(
            command, settings, env, env_info, (policy, applied) if policy else None, own_law
        )
        recorded.update(described)
        case_dir = getattr(getattr(env.unwrapped, "config", None), "case_dir", None)
        seed = settings.seed
        seeds = {"seed": seed, "episode_seeds": [seed + i for i in range(episodes)]}
        write_manifest(out, command=command, case_dir=case_dir, seeds=seeds, settings=recorded)
        summary = rollout(
            env,
            controller,
            out,
            episodes=episodes,
            seed=seed,
            every_start=starts is not None,
            starts="validation" if settings.validation_starts else "held-out",
            reference=env_info.reference,
            video=video,
        )
        if baseline is not None:
            summary["baseline"] = str(settings.baseline.resolve())
            summary["change_percent"] = change_against(summary, baseline)
            (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    finally:
        env.close()
    manifest = {"case_dir": case_dir, "seeds": seeds, "settings": recorded}
    solvers = read_manifest(out)["solvers"]  # as found before the rollout
    write_manifest(out, command=command, solvers=solvers, extra={"result": summary}, **manifest)
    print(_report(command, summary, out, env_info))
    return 0


def _video(settings: RolloutSettings, env_info: LabEnv, out: Path) -> Path | None:
    """``--video``'s file (None without it), refused before any solver starts: a format
    that cannot be written here, an env that cannot render."""
    video = settings.video
    if video is None:
        return None
    try:
        path = check_video_path(video or out / DEFAULT_NAME).resolve()
        check_renders(env_info.env_id)
    except VideoError as exc:
        raise _Unusable(str(exc)) from None
    return path


def _policy_kwargs(policy: Policy, env_info: LabEnv, settings: RolloutSettings) -> dict[str, Any]:
    """The env keyword arguments the policy needs: it acts in [-1, 1], so the env must
    have the action bound it was trained with (each change said in one line)."""
    try:
        applied, lines = policy_env_kwargs(policy, env_info, settings.env_kwargs)
    except PolicyError as exc:
        raise _Unusable(str(exc)) from None
    for line in lines:
        print(f"gymprecice evaluate: {line}")
    return applied


def _own_law(
    settings: RolloutSettings, env_info: LabEnv
) -> tuple[FeedbackLaw, dict[str, float]] | None:
    """``feedback``'s law: the env's own at ``--law`` (:func:`law_point`), else None for a
    signal fed back, refused where the env names no signal and ``--signal`` none."""
    try:
        own_law = law_point(env_info, settings.law)
    except ValueError as exc:
        raise _Unusable(str(exc)) from None
    if own_law is None and not (settings.signal or env_info.feedback_signal):
        raise _Unusable(
            f"{env_info.name} has no default signal; pass --signal "
            "NAME (one of the metrics its steps report in info['metrics']), or declare the "
            "lab card field 'feedback_signal' or 'feedback_law' (card=EnvCard(...) in "
            "register(), docs: Lab reference)"
        )
    return own_law


def _episodes(
    command: str, settings: RolloutSettings, env: gym.Env, env_info: LabEnv
) -> tuple[int, tuple[Any, ...] | None]:
    """How many episodes to run and, with ``--all-starts``, the starts they run from
    (None without it: each episode's start is drawn by its seed)."""
    if settings.validation_starts:
        try:
            labels = tuple(validation_starts(env))
        except StartsError as exc:
            raise _Unusable(str(exc)) from None
        return len(labels), labels
    if not settings.all_starts:
        return settings.episodes, None
    try:
        starts = tuple(evaluation_starts(env, settings.seed))
        held_out = held_out_starts(env)
    except StartsError as exc:
        raise _Unusable(str(exc)) from None
    if not held_out:
        print(
            f"gymprecice {command}: {env_info.name} has no held-out starts; its starts "
            f"are {starts[0]} to {starts[-1]} (lab card field "
            "'held_out_starts' and the env's held_out_starts property declare others)"
        )
    return len(starts), starts


def _controller(
    command: str,
    settings: RolloutSettings,
    env: gym.Env,
    env_info: LabEnv,
    policy: tuple[Policy, dict[str, Any]] | None,
    own_law: tuple[FeedbackLaw, dict[str, float]] | None,
) -> tuple[Controller, dict[str, Any]]:
    """The command's controller on ``env`` and what the manifest records of it
    (``policy``: evaluate's, with the env keyword arguments applied for it)."""
    if command == "evaluate":
        assert policy is not None
        return _policy_controller(*policy, settings, env, env_info)
    if command == "baseline":
        return zero_controller(env.action_space), {}
    if command == "feedback" and own_law is not None:
        law, point = own_law
        try:
            return law.build(env.action_space, point), {"law": env_info.feedback_law, **point}
        except ValueError as exc:
            raise _Unusable(str(exc)) from None
    if command == "feedback":
        signal = str(settings.signal or env_info.feedback_signal)
        try:
            feedback = FeedbackController(
                env.action_space, signal, settings.gain, settings.delay, settings.centre
            )
        except (TypeError, ValueError) as exc:
            raise _Unusable(str(exc)) from None
        return feedback, feedback.settings()
    amplitude, phase = settings.amplitude, settings.phase
    frequency = settings.frequency or env_info.open_loop_frequency or default_frequency(env)
    controller = sine_controller(env.action_space, amplitude, frequency, phase)
    return controller, {"amplitude": amplitude, "frequency": frequency, "phase": phase}


def _policy_controller(
    policy: Policy,
    applied: dict[str, Any],
    settings: RolloutSettings,
    env: gym.Env,
    env_info: LabEnv,
) -> tuple[Controller, dict[str, Any]]:
    """The trained policy as a controller (its mean action unless ``--stochastic``), its
    observations normalised as in training; refused if it does not fit ``env``."""
    model_path = policy.model
    model = load_model(model_path)
    try:
        check_policy_env(policy, model, env, env_info.name, applied)
    except PolicyError as exc:
        raise _Unusable(str(exc)) from None
    normalizer = load_normalizer(model_path)
    deterministic = not settings.stochastic

    def controller(obs: Any, t: float) -> Any:
        if normalizer is not None:
            obs = normalizer.normalize_obs(obs)
        action, _ = model.predict(obs, deterministic=deterministic)
        return action

    return controller, {
        "model": str(model_path.resolve()),
        "policy": policy.describe(),
        "model_sha256": file_sha256(model_path),
        "normalization": str(vecnormalize_path(model_path)) if normalizer else None,
        "deterministic": deterministic,
    }
