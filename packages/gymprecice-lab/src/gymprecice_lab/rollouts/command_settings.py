"""The rollout commands' options, typed, built once: ``evaluate``, ``baseline``,
``open-loop``, ``feedback``, ``sweep``, ``compare`` and ``plot``.

One frozen dataclass per kind of command (why frozen dataclasses, and why one module per
family: :mod:`gymprecice_lab.common.command_settings`). The four commands that run one
fixed controller share :class:`RolloutSettings`: they differ only in the controller, so
each controller's options are a group of fields that the other commands leave at
"not asked for" (their parsers have no such option).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from gymprecice_lab.common.command_settings import EnvSettings

__all__ = ["CompareSettings", "PlotSettings", "RolloutSettings", "SweepSettings"]


@dataclass(frozen=True, kw_only=True)
class RolloutSettings(EnvSettings):
    """``gymprecice evaluate | baseline | open-loop | feedback`` (``command`` says which):
    the environment family (:class:`EnvSettings`), the episodes, then each controller's
    options."""

    # -- the episodes (every rollout command) ---------------------------------------------
    #: ``--episodes``
    episodes: int
    #: ``--all-starts``: one episode from every held-out start (overrides ``episodes``)
    all_starts: bool
    #: ``--validation-starts``: one episode from every validation start instead
    validation_starts: bool = False
    #: ``--video [FILE]``: None without it, "" for the default file in the output
    video: str | None

    # -- what a controller is compared with (evaluate, open-loop, feedback) -------------
    #: ``--baseline RUN``: a baseline run whose summary the means are compared with
    baseline: Path | None = None

    # -- evaluate's policy ----------------------------------------------------------------
    #: ``--policy NAME|PATH`` (None: ``runs/<env>/train``)
    policy: str | None = None
    #: ``--model kept|final``: which model of a training run
    model: str = "kept"
    #: ``--stochastic``: sample actions instead of the mean
    stochastic: bool = False

    # -- open-loop's sinusoid -------------------------------------------------------------
    #: ``--amplitude``: a fraction of the action bound
    amplitude: float | None = None
    #: ``--frequency`` in Hz (None: the card's, else a tenth of the action rate)
    frequency: float | None = None
    #: ``--phase`` in radians
    phase: float | None = None

    # -- feedback's law: a signal fed back, or the env's own law --------------------------
    gain: float | None = None
    #: ``--delay``: whole actions between the signal and the action it sets
    delay: int | None = None
    #: ``--signal``: the metric fed back (None: the card's feedback_signal)
    signal: str | None = None
    #: ``--centre``: the action without signal, a fraction of the action box
    centre: float | None = None
    #: ``--law NAME=V;...``: one point of the env's own law
    law: str | None = None


@dataclass(frozen=True, kw_only=True)
class SweepSettings(EnvSettings):
    """``gymprecice sweep``: the environment family (:class:`EnvSettings`), the grid of
    controllers, and how the rollouts run. The grids are kept as typed (comma-separated
    text); the sweep parses and checks them."""

    # -- the grid: constants, sinusoids, classical feedback ----------------------------
    #: ``--constants``: constant actions from low to high (0: none)
    constants: int
    #: ``--amplitudes``, fractions of the half range, comma-separated
    amplitudes: str
    #: ``--frequencies`` (Hz), comma-separated
    frequencies: str
    #: ``--centre``: the sinusoids' centre, a fraction of the action box
    centre: float
    #: ``--feedback-gains``, comma-separated ("": no feedback)
    feedback_gains: str
    #: ``--feedback-delays`` in whole actions, comma-separated
    feedback_delays: str
    #: ``--feedback-signal`` (None: the card's feedback_signal)
    feedback_signal: str | None
    #: ``--feedback-grid NAME=V1,V2;...``: the env's own law's points (None: its grid)
    feedback_grid: str | None

    # -- the rollouts ---------------------------------------------------------------------
    #: ``--episodes``: starts per controller (None: three on the held-out starts, each
    #: validation start once with ``--starts validation``)
    episodes: int | None
    #: ``--workers``: controllers run at once
    workers: int
    #: ``--starts``: the env's held-out starts, or its validation starts (to tune a law)
    starts: str = "held-out"


@dataclass(frozen=True, kw_only=True)
class CompareSettings:
    """``gymprecice compare``: the runs read, where the tables go, the side-by-side video."""

    #: RUN...: sweep outputs and evaluate / baseline / open-loop outputs
    runs: tuple[Path, ...]
    #: ``--out`` (None: beside the first RUN)
    out: Path | None
    #: ``--video FILE``: the uncontrolled and the controlled envs side by side
    video: Path | None


@dataclass(frozen=True, kw_only=True)
class PlotSettings:
    """``gymprecice plot``: the runs drawn, and how the figures look."""

    # -- what is drawn ----------------------------------------------------------------
    #: RUN...: train, evaluate, baseline, open-loop, feedback outputs
    runs: tuple[Path, ...]
    #: ``--baseline RUN``: drawn as the reference
    baseline: Path | None
    #: ``--episode``: the rollouts' episode drawn (None: each run's first)
    episode: int | None
    #: ``--labels``: legend names, comma-separated, one per RUN
    labels: str | None

    # -- where and how ------------------------------------------------------------------
    #: ``--out`` (None: ``<first RUN>/plots``)
    out: Path | None
    #: ``--format``: png, pdf or svg
    format: str
    #: ``--dpi``: the PNGs' resolution
    dpi: int
