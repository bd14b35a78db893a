"""The lab's command-line options, each declared once, grouped in families.

A command's parser is composed from these (:mod:`gymprecice_lab.cli`): the environment
family (ENV, ``--out``, ``--double``, ``--episode-time``, ...), the rollout family
(``--episodes``, ``--all-starts``, ``--baseline``), the policy, open-loop and feedback
families, the sweep's grid, the training family shared with ``benchmark`` and
``--workers``. Where a command gives an option another meaning (``benchmark``'s
``--algo`` takes several algorithms; its ``--episode-time`` is the training episode's),
it takes the declared option and changes only what differs (:meth:`Option.but`), so that
a flag's name, type and checks stay in one place. An option that one command alone takes
(``train``'s hyperparameters, ``plot``'s ``--dpi``) is declared with that command.

Building these costs nothing: ``gymprecice --help`` never loads torch or matplotlib.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from gymprecice_lab.common.registered_env import lab_envs
from gymprecice_lab.common.wrapping import parse_wrap_argument
from gymprecice_lab.training.hyperparams import ALGORITHMS

__all__ = [
    "ALGO",
    "ALL_STARTS",
    "BASELINE",
    "CASE",
    "DOUBLE",
    "ENV_KWARGS",
    "EPISODES",
    "EPISODE_TIME",
    "FEEDBACK",
    "FRESH",
    "N_ENVS",
    "OPEN_LOOP",
    "OUT",
    "MODEL",
    "POLICY",
    "RAY",
    "REQUIRE_SOLVERS",
    "SEED",
    "STOCHASTIC",
    "SWEEP_GRID",
    "TIMESTEPS",
    "VIDEO",
    "WRAP",
    "Option",
    "adapted",
    "defaults",
    "env_argument",
    "env_options",
    "json_object",
    "non_negative_int",
    "option",
    "positive_float",
    "positive_int",
    "runs_argument",
    "workers_option",
]


# -- value types -------------------------------------------------------------------------------


def json_object(text: str) -> dict[str, Any]:
    """A JSON object given on the command line (``--env-kwargs``)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object, e.g. '{\"lift_penalty\": 0.1}'")
    return value


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {value}")
    return value


def positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


# -- an option, declared once --------------------------------------------------------------


class Option(NamedTuple):
    """One ``add_argument`` call: its flags (a positional's name) and settings; without
    flags, the parser defaults it sets (``set_defaults``)."""

    flags: tuple[str, ...]
    settings: dict[str, Any]

    @property
    def dest(self) -> str:
        """The attribute it sets: ``--feedback-gains`` -> ``feedback_gains``."""
        if "dest" in self.settings:
            return str(self.settings["dest"])
        long = next((f for f in self.flags if f.startswith("--")), self.flags[0])
        return long.lstrip("-").replace("-", "_")

    def but(self, **changes: Any) -> Option:
        """The same option with ``changes`` to its settings (a command's own help)."""
        return Option(self.flags, {**self.settings, **changes})

    def add_to(self, parser: argparse.ArgumentParser) -> None:
        if self.flags:
            parser.add_argument(*self.flags, **self.settings)
        else:
            parser.set_defaults(**self.settings)


def option(*flags: str, **settings: Any) -> Option:
    return Option(flags, settings)


def adapted(family: Sequence[Option], **changes: Mapping[str, Any]) -> tuple[Option, ...]:
    """``family`` with the options named (by their dest) changed: a command's own
    defaults and help, e.g. ``adapted(SWEEP_GRID, constants={"default": 3})``."""
    unknown = set(changes) - {o.dest for o in family if o.flags}
    if unknown:
        raise KeyError(f"no option {', '.join(sorted(unknown))} in the family")
    return tuple(o.but(**changes[o.dest]) if o.flags and o.dest in changes else o for o in family)


def defaults(**values: Any) -> Option:
    """Parser defaults that no flag sets (``rollout``: what ``--episode-time`` means)."""
    return Option((), values)


# -- the environment family: every command that runs an env ----------------------------------


def env_argument(more: str = "") -> Option:
    """ENV: a registered id or short name (listed when the parser is built)."""
    names = ", ".join(env.name for env in lab_envs())
    return option(
        "env",
        metavar="ENV",
        help=f"environment: a registered id or short name ({names or 'none installed'})" + more,
    )


OUT = option("--out", type=Path, default=None, help="output directory (None: runs/<env>/<command>)")
DOUBLE = option(
    "--double",
    action="store_true",
    help="run against gymprecice's preCICE test double with a scripted fake flow "
    "(no preCICE, no OpenFOAM; the whole pipeline in minutes, and for tests)",
)
REQUIRE_SOLVERS = option(
    "--require-solvers",
    action="store_true",
    help="print `gymprecice doctor`'s whole report when preCICE or a solver this "
    "environment needs is missing (without it: one line)",
)
CASE = option("--case", type=Path, help="a case directory of your own instead of the recipe")
SEED = option("--seed", type=int, default=0, help="random seed")
EPISODE_TIME = option(
    "--episode-time",
    type=positive_float,
    default=None,
    metavar="SECONDS",
    help="simulated seconds per episode, for an env whose card declares episode_time "
    "(None: the case's training episode)",
)
WRAP = option(
    "--wrap",
    action="append",
    type=parse_wrap_argument,
    default=[],
    metavar="NAME:KEY=VALUE,...",
    help="a robustness wrapper between the policy and the env (repeatable): "
    "sensor_noise:std=0.05[,mode=absolute], action_noise:std=0.1, delay:steps=2, "
    "dropout:p=0.1[,fill=0]; train also reads them from the hyperparameter file's "
    "'robustness' key",
)
ENV_KWARGS = option(
    "--env-kwargs",
    type=json_object,
    default={},
    metavar="JSON",
    help="extra keyword arguments of the environment, e.g. '{\"lift_penalty\": 0.1}'",
)


def env_options(*, rollout: bool) -> tuple[Option, ...]:
    """ENV and how to build it. ``rollout``: a command that runs a fixed controller over
    the card's ``rollout_time`` (evaluate, sweep, ...), not a training episode."""
    episode_time = EPISODE_TIME
    if rollout:
        horizons = ", ".join(f"{e.name} {e.rollout_time:g} s" for e in lab_envs() if e.rollout_time)
        episode_time = EPISODE_TIME.but(
            help="simulated seconds per episode, for an env whose card declares episode_time "
            f"(None: the card's rollout_time ({horizons}), else the case's)"
        )
    return (
        env_argument(),
        OUT,
        DOUBLE,
        REQUIRE_SOLVERS,
        CASE,
        SEED,
        episode_time,
        defaults(rollout=rollout),
        WRAP,
        ENV_KWARGS,
    )


# -- the rollout family: evaluate, baseline, open-loop, feedback -----------------------------

EPISODES = option("--episodes", type=positive_int, default=1, help="episodes to run")
ALL_STARTS = option(
    "--all-starts",
    action="store_true",
    help="one episode from every held-out start of the env (overrides --episodes; an env "
    "whose lab card declares no held-out starts: one from each of its first five seeds)",
)
VALIDATION_STARTS = option(
    "--validation-starts",
    action="store_true",
    help="one episode from every validation start of the env instead (the starts that "
    "choose a trained model, never the held-out ones that judge it): how a kept model "
    "or a law does there, over episodes as long as the evaluation's",
)
BASELINE = option(
    "--baseline",
    type=Path,
    default=None,
    metavar="RUN",
    help="a baseline run directory (its summary.json): report the %% change of each mean",
)

VIDEO = option(
    "--video",
    nargs="?",
    const="",
    default=None,
    type=str,
    metavar="FILE",
    help="also write a video of each episode, FILE.mp4 or FILE.gif (several episodes: "
    "FILE-episode-K.mp4; FILE left out: episode.mp4 in --out); the env renders "
    "(render_mode='rgb_array'), which costs a frame per action",
)

# -- the policy family: evaluate ---------------------------------------------------------------

POLICY = option(
    "--policy",
    dest="policy",
    metavar="NAME|PATH",
    default=None,
    help="the policy: a model .zip, a training directory (its kept model, else its "
    "model.zip, else its newest checkpoint: --model says which), the name of a policy "
    "shipped with the package (`gymprecice policies` lists them; ./NAME for a directory "
    "of that name) or `shipped` (the one shipped for ENV). On another env than its "
    "training env a policy keeps its training action bound (None: runs/<env>/train)",
)


class _ModelAction(argparse.Action):
    """``--model kept|final``; any other value is a policy, as ``--model PATH`` always
    was (the older spelling of ``--policy PATH``)."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None) -> None:
        from gymprecice_lab.common.kept_model import MODEL_CHOICES

        if values in MODEL_CHOICES:
            namespace.model = values
        elif hasattr(namespace, "policy"):
            namespace.policy = values
        else:
            parser.error(f"{option_string} takes {' or '.join(MODEL_CHOICES)}, got {values!r}")


MODEL = option(
    "--model",
    dest="model",
    action=_ModelAction,
    default="kept",
    metavar="kept|final",
    help="which model of a training run: the kept one (the best of the run's validations, "
    "on starts disjoint from the held-out ones) or the final one; the line printed says "
    "which was taken (a path here is taken as --policy)",
)
STOCHASTIC = option("--stochastic", action="store_true", help="sample actions instead")

# -- the open-loop family: one sinusoid ------------------------------------------------------

OPEN_LOOP = (
    option(
        "--amplitude",
        type=float,
        default=0.5,
        help="amplitude as a fraction of the action bound",
    ),
    option(
        "--frequency",
        type=positive_float,
        default=None,
        help="frequency in Hz (None: the card's open_loop_frequency, else a tenth of the "
        "action rate)",
    ),
    option("--phase", type=float, default=0.0, help="phase in radians"),
)

# -- the feedback family: one classical feedback law -----------------------------------------

FEEDBACK_SIGNAL_HELP = "the info['metrics'] entry fed back (None: the card's feedback_signal)"
FEEDBACK = (
    option(
        "--gain",
        type=float,
        default=1.0,
        help="fraction of the action's half range per unit of the signal",
    ),
    option(
        "--delay",
        type=non_negative_int,
        default=0,
        help="whole actions between the signal and the action it sets (the phase shift)",
    ),
    option("--signal", default=None, help=FEEDBACK_SIGNAL_HELP),
    option(
        "--centre",
        type=float,
        default=0.5,
        help="the action without signal as a fraction of the action box (0.5: its middle)",
    ),
    option(
        "--law",
        default=None,
        metavar="NAME=V;...",
        help="for an env with a feedback law of its own (the heated plate's PID), one value "
        "of each of its parameters, e.g. 'kp=3;ki=50;kd=1' (instead of --signal, --gain, "
        "--delay)",
    ),
)

# -- the sweep's grid: sweep, and benchmark's baselines --------------------------------------

SWEEP_GRID = (
    option(
        "--constants",
        type=non_negative_int,
        default=9,
        help="constant actions, evenly from low to high (0: none)",
    ),
    option(
        "--amplitudes",
        default="0.25,0.5,1",
        help="sinusoid amplitudes, fractions of the half range, comma-separated (empty: "
        "no sinusoids)",
    ),
    option(
        "--frequencies",
        default="0.3,0.6,1.2,2.4",
        help="sinusoid frequencies (Hz), comma-separated",
    ),
    option(
        "--centre",
        type=float,
        default=0.5,
        help="the sinusoids' centre as a fraction of the action box (0.5: its middle)",
    ),
    option(
        "--feedback-gains",
        default="",
        help="gains of the classical feedback law to sweep, comma-separated (empty: none; "
        "see `gymprecice feedback`), e.g. -2,-1,-0.5,0.5,1,2",
    ),
    option(
        "--feedback-delays",
        default="0",
        help="its delays in whole actions, comma-separated",
    ),
    option("--feedback-signal", default=None, help=FEEDBACK_SIGNAL_HELP),
    option(
        "--feedback-grid",
        default=None,
        metavar="NAME=V1,V2;...",
        help="for an env with a feedback law of its own (the heated plate's PID: kp, ki, kd), "
        "the values of its parameters to tune, e.g. 'kp=2,3;ki=25,50;kd=0' (unnamed "
        "parameters keep the law's documented grid; default: that grid; empty: none)",
    ),
)


# -- the training family: train, and benchmark's seeds -----------------------------------------

ALGO = option("--algo", choices=ALGORITHMS, default="ppo", help="learning algorithm")
TIMESTEPS = option(
    "--timesteps",
    type=positive_int,
    default=100_000,
    help="total actions (env steps), rounded up to whole rollouts; 100,000 is about "
    "21 hours on the real jet cylinder on 2 cores",
)
N_ENVS = option("--n-envs", type=positive_int, default=1, help="parallel environments")
FRESH = option("--fresh", action="store_true", help="start over even if --out has checkpoints")
RAY = option(
    "--ray",
    metavar="auto|ADDRESS",
    default=None,
    help="run the envs as Ray actors on a Ray cluster (auto: the one this machine "
    "joined); needs gymprecice-core[ray], see docs/cluster.md",
)

# -- the others ------------------------------------------------------------------------------


def workers_option(what: str) -> Option:
    """``--workers``: how many of ``what`` at once, each on its own core."""
    return option(
        "--workers",
        type=positive_int,
        default=1,
        help=f"{what} (a solver runs on one core: at most the machine's cores)",
    )


def runs_argument(what: str) -> Option:
    """RUN...: the output directories a command reads."""
    return option("runs", nargs="+", type=Path, metavar="RUN", help=what)
