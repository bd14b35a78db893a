"""``gymprecice plot``: PNG figures of training and control runs.

* ``reward.png``: episode return against environment steps during training, one faint line
  per env and the running mean over all of them, from SB3's monitor files
  (``<run>/monitor/*.monitor.csv``); a run without them (e.g. monitors deleted) falls back
  to the ``rollout/ep_rew_mean`` curve of its TensorBoard logs (``<run>/tb``);
* ``actions.png``: the action history of each evaluate / baseline / open-loop run;
* ``coefficients.png``: drag and lift coefficients of each run against time, with the
  baseline (``--baseline``) drawn as a reference: the figure of Rabault et al. that shows
  whether the controller reduced drag;
* ``objective.png``: for environments that name an objective (the flap's mean tip
  displacement), that metric per action of each run against time.

matplotlib runs with the non-interactive Agg backend: plotting must work on a headless
machine and never open a window.
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_lab.rollouts.command_settings import PlotSettings

__all__ = [
    "load_coefficients",
    "load_history",
    "load_training_curve",
    "plot_actions",
    "plot_coefficients",
    "plot_command",
    "plot_reward",
]


# -- reading runs --------------------------------------------------------------------------


def _read_csv(
    path: Path, *, skip_comment: bool = False, fieldnames: Sequence[str] | None = None
) -> list[dict[str, str]]:
    """Rows of a CSV file; ``fieldnames`` are used when the file has no header line."""
    with path.open(newline="") as handle:
        lines = [line for line in handle if not (skip_comment and line.startswith("#"))]
    if fieldnames and lines and not set(lines[0].strip().split(",")) & set(fieldnames):
        return list(csv.DictReader(lines, fieldnames=list(fieldnames)))
    return list(csv.DictReader(lines))


def load_training_curve(run: Path) -> dict[str, Any] | None:
    """Episode returns of a training run: ``{"per_env": [(steps, returns)], "source": ...}``.

    Monitor files give every episode of every env: ``l`` (its length) summed over an env's
    episodes is that env's step count; the global step of an episode is about ``n_envs``
    times it, since the envs step together.
    """
    monitors = sorted((run / "monitor").glob("*.monitor.csv"))
    per_env = []
    for path in monitors:
        rows = _read_csv(path, skip_comment=True, fieldnames=("r", "l", "t"))
        if not rows:
            continue
        lengths = np.array([float(r["l"]) for r in rows])
        returns = np.array([float(r["r"]) for r in rows])
        per_env.append((np.cumsum(lengths) * len(monitors), returns))
    if per_env:
        return {"per_env": per_env, "source": "monitor"}
    scalars = _tensorboard_scalars(run / "tb", "rollout/ep_rew_mean")
    if scalars is not None:
        return {"per_env": [scalars], "source": "tensorboard"}
    return None


def _tensorboard_scalars(directory: Path, tag: str) -> tuple[np.ndarray, np.ndarray] | None:
    if not directory.is_dir():
        return None
    try:
        from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    except ImportError:
        return None
    steps: list[float] = []
    values: list[float] = []
    for events in sorted(directory.rglob("events.out.tfevents.*")):
        acc = EventAccumulator(str(events), size_guidance={"scalars": 0})
        acc.Reload()
        if tag not in acc.Tags().get("scalars", []):
            continue
        for event in acc.Scalars(tag):
            steps.append(event.step)
            values.append(event.value)
    if not steps:
        return None
    order = np.argsort(steps, kind="stable")
    return np.asarray(steps)[order], np.asarray(values)[order]


def _load_columns(path: Path) -> dict[str, np.ndarray] | None:
    """A rollout CSV as columns (``None`` when the file is missing or empty)."""
    if not path.is_file():
        return None
    rows = _read_csv(path)
    if not rows:
        return None
    return {key: np.array([_float(r[key]) for r in rows]) for key in rows[0]}


def load_history(run: Path) -> dict[str, np.ndarray] | None:
    """``history.csv`` of a rollout run as columns (``None`` when the run has none)."""
    return _load_columns(run / "history.csv")


def load_coefficients(run: Path) -> dict[str, np.ndarray] | None:
    """``coefficients.csv`` of a rollout run as columns (``None`` when empty or missing)."""
    return _load_columns(run / "coefficients.csv")


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return float("nan")


# -- figures -------------------------------------------------------------------------------


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    # text stays text in SVG and PDF: editable and searchable in a paper's figures
    matplotlib.rcParams.update({"svg.fonttype": "none", "pdf.fonttype": 42})
    import matplotlib.pyplot as plt

    return plt


@dataclass
class Style:
    """How figures are written: ``gymprecice plot --format/--dpi/--labels/--episode``."""

    fmt: str = "png"
    dpi: int = 120
    labels: dict[Path, str] = field(default_factory=dict)
    #: the episode drawn of rollout runs (``None``: the first each run has)
    episode: int | None = None


STYLE = Style()


def _label(run: Path) -> str:
    given = STYLE.labels.get(run.resolve())
    if given:
        return given
    return f"{run.parent.name}/{run.name}" if run.parent.name else run.name


def _episode_mask(episodes: np.ndarray) -> tuple[np.ndarray, int]:
    """Rows of the episode to draw and its number (``--episode``, else the first)."""
    wanted = int(episodes.min()) if STYLE.episode is None else STYLE.episode
    mask = episodes == wanted
    if not mask.any():
        raise SystemExit(
            f"gymprecice plot: --episode {wanted}: the run has episodes "
            f"{', '.join(str(int(e)) for e in np.unique(episodes))}"
        )
    return mask, wanted


def _run_env(run: Path) -> Any:
    """The environment a run was made with (from its manifest), if known."""
    from gymprecice_lab.common.registered_env import find_lab_env

    # a controller's directory inside a `gymprecice sweep` output has the sweep's manifest
    for directory in (run, run.parent):
        try:
            manifest = json.loads((directory / "manifest.json").read_text())
            return find_lab_env(manifest["settings"]["env_id"])
        except (OSError, ValueError, KeyError):
            continue
    return None


def _action_scheme(run: Path) -> tuple[str, int]:
    """The case's action scheme and windows per action (``hold``, 1 when unknown).

    One window per action whose written data preCICE interpolates (a ``waveform-degree``
    of 1 or more on the controller's write data in the case's preCICE configuration)
    reaches the solver as a ramp, whatever core writes.
    """
    from gymprecice.plugin.errors import ConfigError
    from gymprecice.plugin.precice_xml import load_precice_config

    try:
        manifest = json.loads((run / "manifest.json").read_text())
        case = Path(manifest["case_dir"])
        if not case.is_dir():  # the run directory was moved: its own copy of the case
            case = run / "envs" / "cases" / case.name
        config = json.loads((case / "gymprecice-config.json").read_text())
        actions = config.get("actions", {})
        scheme, windows = str(actions.get("scheme", "hold")), int(actions.get("windows", 1))
        if windows == 1:
            precice = load_precice_config(
                case / str(config.get("precice", {}).get("config_file", "precice-config.xml"))
            )
            controller = str(config.get("controller", {}).get("participant", "Controller"))
            written = precice.participant(controller).write_data
            if any((precice.data[name].waveform_degree or 0) >= 1 for name, _ in written):
                scheme = "ramp"
        return scheme, windows
    except (OSError, ValueError, KeyError, TypeError, ConfigError):
        return "hold", 1


def applied_action(
    start: np.ndarray, end: np.ndarray, values: np.ndarray, scheme: str, windows: int
) -> tuple[np.ndarray, np.ndarray]:
    """Time and value of an action signal as the env applied it, window by window.

    Core's :class:`~gymprecice.actions.ActionSchedule` spreads each action over the step's
    preCICE windows (``ramp``: a line from the previous action; ``hold``: a step). The
    episode starts from rest (zero).
    """
    from gymprecice.env.actions import ActionSchedule

    schedule = ActionSchedule(scheme=scheme, windows=max(1, windows))
    schedule.start(np.zeros(1))
    times, out = [float(start[0])], [0.0 if scheme != "hold" else float(values[0])]
    for t0, t1, value in zip(start, end, values):
        per_window = schedule.spread(np.array([value]))
        edges = np.linspace(t0, t1, len(per_window) + 1)[1:]
        times += [float(t) for t in edges]
        out += [float(np.asarray(v).reshape(-1)[0]) for v in per_window]
    return np.array(times), np.array(out)


def _algorithm(run: Path) -> str | None:
    """The learning algorithm a training run recorded (``None`` when it recorded none)."""
    try:
        return json.loads((Path(run) / "hyperparams.json").read_text()).get("algo")
    except (OSError, ValueError, AttributeError):
        return None


def plot_reward(runs: Sequence[Path], target: Path) -> Path | None:
    """``reward.png`` from every run that has training logs; ``None`` if none has."""
    curves = [(run, load_training_curve(run)) for run in runs]
    curves = [(run, c) for run, c in curves if c is not None]
    if not curves:
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    smoothed: list[tuple[np.ndarray, np.ndarray]] = []
    for k, (run, curve) in enumerate(curves):
        colour = f"C{k}"
        if curve["source"] == "monitor":
            steps = np.concatenate([s for s, _ in curve["per_env"]])
            returns = np.concatenate([r for _, r in curve["per_env"]])
            for s, r in curve["per_env"]:
                ax.plot(s, r, color=colour, alpha=0.25, lw=0.8)
            # mean over the envs' episodes ending at the same step, then a running mean
            unique, inverse = np.unique(steps, return_inverse=True)
            means = np.bincount(inverse, weights=returns) / np.bincount(inverse)
            window = max(1, min(len(unique) // 5, 20))
            smooth = np.convolve(means, np.ones(window) / window, mode="valid")
            label = f"{_label(run)} (running mean of {window} episode ends)"
            ax.plot(unique[window - 1 :], smooth, color=colour, lw=2, label=label)
            smoothed.append((unique[window - 1 :], smooth))
        else:
            s, r = curve["per_env"][0]
            ax.plot(s, r, color=colour, lw=2, label=f"{_label(run)} (TensorBoard)")
    algorithms = {_algorithm(run) for run, _ in curves}
    # Several seeds of one algorithm: their mean and spread on a common axis (runs of
    # different algorithms are not seeds of one experiment: no mean of them).
    if len(smoothed) >= 2 and len(algorithms) == 1:
        lo = max(s[0] for s, _ in smoothed)
        hi = min(s[-1] for s, _ in smoothed)
        if hi > lo:
            grid = np.linspace(lo, hi, 200)
            stack = np.array([np.interp(grid, s, v) for s, v in smoothed])
            mean, std = stack.mean(axis=0), stack.std(axis=0)
            ax.plot(grid, mean, "k", lw=1.5, label=f"mean of {len(smoothed)} runs")
            ax.fill_between(grid, mean - std, mean + std, color="k", alpha=0.15, label="± std")
    ax.set_xlabel("environment steps (actions)")
    ax.set_ylabel("episode return (reward, dimensionless)")
    ax.set_title("Training")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return _save(fig, plt, target / "reward")


def plot_actions(runs: Sequence[Path], target: Path, baseline: Path | None = None) -> Path | None:
    """``actions``: each rollout's action as applied, one panel per unit, bounds dotted."""
    series = [(run, load_history(run)) for run in [*runs, *([baseline] if baseline else [])]]
    series = [(run, h) for run, h in series if h is not None]
    if not series:
        return None
    by_unit: dict[str, list[tuple[int, Path, dict[str, np.ndarray]]]] = {}
    for k, (run, history) in enumerate(series):
        env = _run_env(run)
        by_unit.setdefault(env.action_unit if env else "", []).append((k, run, history))
    plt = _pyplot()
    fig, axes = plt.subplots(len(by_unit), 1, figsize=(7, 3.5 * len(by_unit)), squeeze=False)
    episodes = set()
    for ax, (unit, members) in zip(axes[:, 0], by_unit.items()):
        bounds = set()
        for k, run, history in members:
            env = _run_env(run)
            if env is not None and env.action_bound:
                bounds.add(env.action_bound)
            mask, episode = _episode_mask(history["episode"])
            episodes.add(episode)
            scheme, windows = _action_scheme(run)
            start = history.get("start", history["time"])[mask]
            keys = sorted(key for key in history if key.startswith("action_"))
            for key in keys:
                t, v = applied_action(
                    start, history["time"][mask], history[key][mask], scheme, windows
                )
                label = _label(run) + (f" {key}" if len(keys) > 1 else "") + f" ({scheme})"
                ax.plot(t, v, color=f"C{k}", label=label)
        for bound in sorted(bounds):
            for sign in (-1, 1):
                ax.axhline(sign * bound, color="grey", ls=":", lw=1)
        ax.set_ylabel(f"action ({unit})" if unit else "action")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].set_title(f"Actions as applied (episode {', '.join(map(str, sorted(episodes)))})")
    return _save(fig, plt, target / "actions")


def plot_coefficients(
    runs: Sequence[Path], target: Path, baseline: Path | None = None
) -> Path | None:
    """``coefficients.png``: Cd and Cl of every run, the baseline dashed in black."""
    series = [(run, load_coefficients(run)) for run in runs]
    series = [(run, c) for run, c in series if c is not None]
    reference = load_coefficients(baseline) if baseline is not None else None
    if not series and reference is None:
        return None
    plt = _pyplot()
    fig, (ax_d, ax_l) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    ref_cd = None
    episodes = set()
    if reference is not None:
        assert baseline is not None
        first, episode = _episode_mask(reference["episode"])
        episodes.add(episode)
        ref_cd = float(np.mean(reference["Cd"][first]))
        label = f"baseline (mean Cd {ref_cd:.4f})"
        ax_d.plot(reference["time"][first], reference["Cd"][first], "k--", lw=1, label=label)
        ax_l.plot(reference["time"][first], reference["Cl"][first], "k--", lw=1, label="baseline")
    for k, (run, coeffs) in enumerate(series):
        if baseline is not None and run.resolve() == baseline.resolve():
            continue
        first, episode = _episode_mask(coeffs["episode"])
        episodes.add(episode)
        mean_cd = float(np.mean(coeffs["Cd"][first]))
        note = f"mean Cd {mean_cd:.4f}"
        if ref_cd:
            note += f", {100 * (mean_cd - ref_cd) / abs(ref_cd):+.1f} % vs baseline"
        ax_d.plot(
            coeffs["time"][first],
            coeffs["Cd"][first],
            color=f"C{k}",
            label=f"{_label(run)} ({note})",
        )
        ax_l.plot(coeffs["time"][first], coeffs["Cl"][first], color=f"C{k}", label=_label(run))
    ax_d.set_ylabel("drag coefficient Cd (-)")
    ax_l.set_ylabel("lift coefficient Cl (-)")
    ax_l.set_xlabel("time (s)")
    ax_d.set_title(f"Force coefficients (episode {', '.join(map(str, sorted(episodes)))})")
    for ax in (ax_d, ax_l):
        ax.grid(alpha=0.3)
    ax_d.legend(loc="best", fontsize="small")
    return _save(fig, plt, target / "coefficients")


def plot_objective(runs: Sequence[Path], target: Path, baseline: Path | None = None) -> Path | None:
    """``objective.png``: the env's objective per action (its lab card's ``objective``, e.g.
    the flap's mean tip displacement) of every run, the baseline dashed in black; the
    legend gives each run's mean over the drawn episode."""
    members = [*runs, *([baseline] if baseline else [])]
    drawn = []
    for run in members:
        env, history = _run_env(run), load_history(run)
        if env is None or not env.objective or history is None or env.objective not in history:
            continue
        drawn.append((run, env.objective, history))
    if not drawn:
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 3.8))
    episodes = set()
    for k, (run, objective, history) in enumerate(drawn):
        mask, episode = _episode_mask(history["episode"])
        episodes.add(episode)
        values = history[objective][mask]
        is_baseline = baseline is not None and run.resolve() == baseline.resolve()
        style = {"color": "k", "ls": "--", "lw": 1} if is_baseline else {"color": f"C{k}"}
        label = f"{'baseline' if is_baseline else _label(run)} (mean {np.mean(values):.4g})"
        ax.plot(history["time"][mask], values, label=label, **style)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(drawn[0][1].replace("_", " ") + " per action")
    ax.set_title(f"Objective, lower is better (episode {', '.join(map(str, sorted(episodes)))})")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return _save(fig, plt, target / "objective")


def _save(fig: Any, plt: Any, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    path = path.with_suffix(f".{STYLE.fmt}")
    fig.savefig(path, dpi=STYLE.dpi)
    plt.close(fig)
    return path


def plot_command(settings: PlotSettings) -> int:
    """``gymprecice plot RUN... [--baseline RUN] [--out DIR]``."""
    runs: list[Path] = list(settings.runs)
    baseline = settings.baseline
    missing = [str(r) for r in [*runs, *([baseline] if baseline else [])] if not r.is_dir()]
    if missing:
        print(f"gymprecice plot: no such run directory: {', '.join(missing)}", file=sys.stderr)
        return 1
    labels = [s.strip() for s in settings.labels.split(",")] if settings.labels else []
    if labels and len(labels) != len(runs):
        print(
            f"gymprecice plot: --labels has {len(labels)} names for {len(runs)} runs; "
            f"give one per RUN, comma-separated",
            file=sys.stderr,
        )
        return 2
    STYLE.fmt, STYLE.dpi, STYLE.episode = settings.format, settings.dpi, settings.episode
    STYLE.labels = {run.resolve(): label for run, label in zip(runs, labels)}
    target = settings.out or runs[0] / "plots"
    written = [
        plot_reward(runs, target),
        plot_actions(runs, target, baseline),
        plot_coefficients(runs, target, baseline),
        plot_objective(runs, target, baseline),
    ]
    written_paths = [p for p in written if p is not None]
    if not written_paths:
        print(
            "gymprecice plot: nothing to draw: the runs have no monitor/TensorBoard logs "
            "(train) and no history.csv / coefficients.csv (evaluate, baseline, open-loop)",
            file=sys.stderr,
        )
        return 1
    for path in written_paths:
        print(path)
    return 0
