"""TwoFlapsFast: damp both flaps' swing after a gust, the two flaps' training case.

The task
--------
The flaps (0.1 x 1, E = 4 MPa, rho = 3000 kg/m³) swing with a period of about 1.6 s in
the 5 m/s flow (nu = 1e-3 m²/s), and the fluid barely damps them: after the impulsive start
the upstream tip swings between 0 and 0.035 m, the downstream one, in its wake, between
-0.03 and 0.02 m, for seconds. Each agent's slot moves its flap's load by about ±20 % at
full blowing or suction (10 m/s), so a constant setting only moves the centre of a swing;
taking energy out of it means sucking while the tip moves downstream and blowing while it
comes back (a load against the motion), which needs the tip's state: the classical law
that does it (:mod:`.feedback`) takes a fifth off the uncontrolled swing. The objective
is each flap's own mean tip displacement; the agents share a policy.

What a start is
---------------
Fluid and solids run from rest at t = 0 (the tutorial's impulsive start), coupled from the
first window. Each ``reset()`` then drives the coupled case for ``settle_time`` seconds
(not part of the episode) with a *gust*: each slot held at one setting and switched to
another at one random instant. The episode begins at ``settle_time`` with the flaps
swinging at amplitudes and phases that the start and the gust set. Training draws its
gusts from the episode seed; ``reset(options={"split": "eval"})`` takes the held-out gusts
of :data:`EVAL_GUSTS` (``seed % 3``, or ``"start": k``), whose settings (multiples of
:data:`GUST_STEP`) no training draw (odd multiples of half a step) reproduces.

The training case
-----------------
The packaged case (preCICE's multiple-perpendicular-flaps tutorial with the slots) with
these edits (:mod:`.training_case`), measured in docs/tutorials/two-flaps.md:

* fluid mesh of 1,208 cells instead of 4,650 (half the cells in each direction);
* preCICE time window 0.05 s instead of 0.01 s, fluid time step 0.025 s (two per window),
  the solids' step the window; two windows per action (10 actions per second, as the
  packaged case's ten windows of 0.01 s);
* solid elements of degree 2 instead of 4;
* the multi coupling's relative convergence limit 1e-3 instead of 1e-4;
* the coupling's max-time: ``settle_time + episode_time``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.multiagent import JointEnv
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.episodes import episode_timing, fixed_start, read_split
from gymprecice_tutorials.two_flaps import double as flaps_double
from gymprecice_tutorials.two_flaps.environment import FLAPS, TwoFlapsEnv
from gymprecice_tutorials.two_flaps.training_case import ACTION_TIME, fast_case_files

__all__ = [
    "EVAL_GUSTS",
    "GUST_STEP",
    "VALIDATION_GUSTS",
    "Gust",
    "TwoFlapsFastEnv",
    "TwoFlapsJointEnv",
    "gust",
]

#: grid of gust settings (fractions of the slot's full velocity): training draws
#: ``-1 + GUST_STEP * (k + 0.5)``, evaluation uses multiples of ``GUST_STEP``
GUST_STEP = 0.1


class Gust(tuple):
    """A start: slot settings ``first`` until ``switch`` seconds, then ``second``.

    ``first`` and ``second`` hold one setting per agent, in :data:`FLAPS` order.
    """

    __slots__ = ()

    def __new__(cls, first: tuple[float, ...], second: tuple[float, ...], switch: float) -> Gust:
        return super().__new__(
            cls, (tuple(map(float, first)), tuple(map(float, second)), float(switch))
        )

    first = property(lambda self: self[0])
    second = property(lambda self: self[1])
    switch = property(lambda self: self[2])

    def settings(self, time: float) -> dict[str, float]:
        """Each agent's slot setting the gust asks for at ``time`` (s since the run began)."""
        values = self.first if time < self.switch - 1e-9 else self.second
        return {flap.agent: value for flap, value in zip(FLAPS, values, strict=True)}


#: The held-out starts: both slots from full blowing to full suction (and back, the other
#: way for the downstream flap), the reverse, and a small change of another phase.
EVAL_GUSTS: tuple[Gust, ...] = (
    Gust((1.0, -1.0), (-1.0, 1.0), 0.5),
    Gust((-1.0, 1.0), (1.0, -1.0), 0.3),
    Gust((0.0, 0.0), (0.5, 0.5), 0.7),
)

#: The validation starts, which choose the model a training run keeps: whole-step
#: settings like the held-out gusts (so no training draw meets them), none of them.
VALIDATION_GUSTS: tuple[Gust, ...] = (
    Gust((0.5, -0.5), (-0.5, 0.5), 0.4),
    Gust((-0.5, 0.0), (1.0, 0.5), 0.6),
    Gust((1.0, 1.0), (0.0, -1.0), 0.5),
)


def gust(rng: np.random.Generator, settle_time: float) -> Gust:
    """A training start drawn from ``rng``: two settings per slot and a switch time.

    Settings lie on the half-step grid ``-1 + GUST_STEP * (k + 0.5)``, which never meets
    the whole-step settings of :data:`EVAL_GUSTS`; the switch is a whole action in
    ``[ACTION_TIME, settle_time - ACTION_TIME]``.
    """
    slots = round(2.0 / GUST_STEP)
    values = -1.0 + GUST_STEP * (rng.integers(0, slots, size=(2, len(FLAPS))) + 0.5)
    actions = max(1, round(settle_time / ACTION_TIME))
    switch = ACTION_TIME * int(rng.integers(1, max(2, actions)))
    return Gust(tuple(values[0]), tuple(values[1]), switch)


class TwoFlapsFastEnv(TwoFlapsEnv):
    """Damp both flaps after a gust, on the two flaps' training case (module docstring).

    * **Agents, actions, observations, rewards**: :class:`TwoFlapsEnv`'s.
    * **Episode**: ``episode_time`` seconds (default 3: 30 actions) after a
      ``settle_time`` gust (default 1 s); every agent truncated at the end.
    * ``uncontrolled=True``: after the gust both slots are closed (the tutorial's plain
      floor) whatever the actions: the run a controller is judged against.
    * ``base_damping=KV`` (s/m): each slot is the classical damping law's setting,
      ``-KV vx`` of its flap's tip velocity, plus the agent's action, clipped to the
      slot's range: a policy that learns a residual on top of the textbook controller
      starts from it (an action of 0 is the law). 0, the default: the action alone.
    * ``double=True``: the same env against gymprecice's preCICE test double and two
      scripted flaps (:mod:`gymprecice_tutorials.two_flaps.double`), no solvers needed.
    """

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = 0,
        *,
        episode_time: float = 3.0,
        settle_time: float = 1.0,
        uncontrolled: bool = False,
        base_damping: float = 0.0,
        double: bool = False,
        run_root: str | Path | None = None,
        **kwargs: Any,
    ) -> None:
        self.episode_time, self.settle_time = episode_timing(ACTION_TIME, episode_time, settle_time)
        end_time = self.settle_time + self.episode_time
        if options is None and double:
            options = write_case_files(
                "two-flaps-fast-double", flaps_double.double_case_files(end_time), run_root
            )
        elif options is None:
            options = write_case_files("two-flaps-fast", fast_case_files(end_time), run_root)
        elif double:
            raise ValueError(
                "double=True runs the packaged training case on the test double; with a case "
                "of your own (options) leave double out"
            )
        super().__init__(options, idx, run_root=run_root, **kwargs)
        if not any(solver.kind == "openfoam" for solver in self.config.solvers.values()):
            # No fluid mesh a plugin could read (the test double's scripted flaps): give
            # the controller the training case's slot faces.
            for jet, faces in flaps_double.training_slots().items():
                self.set_interface_vertices(jet, faces.coordinates)
        self.uncontrolled = bool(uncontrolled)
        if not (np.isfinite(base_damping) and base_damping >= 0):
            raise ValueError(f"base_damping is a gain >= 0 (s/m), got {base_damping}")
        self.base_damping = float(base_damping)
        self.start: Gust | None = None
        self._split: str = "train"
        self._split_seed: int | None = None

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        """Start the coupled run, drive it through this episode's gust, return the state.

        ``options={"split": "eval"}`` takes :data:`EVAL_GUSTS` ``[seed % 3]`` (``seed``
        0 when none is given), or ``[k]`` with ``"start": k``; ``"validation"`` likewise
        :data:`VALIDATION_GUSTS`; ``"train"`` draws a training gust from the seed.
        """
        self._split, self._split_seed = read_split(
            options, seed, len(EVAL_GUSTS), "gusts", len(VALIDATION_GUSTS)
        )
        obs, infos = super().reset(seed=seed, options=options)  # draws self.start
        assert self.start is not None
        while self.time < self.settle_time - 1e-9:
            actions = {
                agent: np.array([value], np.float32)
                for agent, value in self.start.settings(self.time).items()
            }
            obs, _, _, _, infos = super().step(actions)
            info = next(iter(infos.values()), {})
            if "diverged" in info:
                self.close()
                raise RuntimeError(
                    f"solver {info['diverged']['solver']!r} diverged at t = {self.time:g} s "
                    f"during the {self.settle_time} s gust, before the agents acted: "
                    f"{info['diverged']['evidence']}"
                )
            if not self.agents:
                self.close()
                raise RuntimeError(
                    f"the coupled run ended at t = {self.time:g} s during the "
                    f"{self.settle_time} s gust; the case's max-time must exceed settle_time"
                )
        start_info = {
            "gust": [list(self.start.first), list(self.start.second)],
            "split": self._split,
        }
        infos = {agent: {**info, "start": start_info} for agent, info in infos.items()}
        for info in infos.values():
            info.pop("metrics", None)
            info.pop("action", None)
        return obs, infos

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        """The held-out gusts, in the order ``reset(options={"split": "eval", "start": k})``
        takes them."""
        return tuple(
            f"slots {_pair(g.first)} -> {_pair(g.second)} at {g.switch:g} s" for g in EVAL_GUSTS
        )

    @property
    def validation_starts(self) -> tuple[str, ...]:
        """The validation gusts, in the order ``reset(options={"split": "validation",
        "start": k})`` takes them."""
        return tuple(
            f"slots {_pair(g.first)} -> {_pair(g.second)} at {g.switch:g} s"
            for g in VALIDATION_GUSTS
        )

    def _slot_mean_velocity(self, agent: str, action: np.ndarray) -> float:
        """The slot's setting: the gust's before ``settle_time``; after it, the agent's
        action, on top of the classical damping law's where ``base_damping`` is set (a
        residual policy: the law's ``-base_damping * vx`` of the flap's tip, plus the
        action, clipped to the slot's range), or closed where uncontrolled."""
        controlled = self.time >= self.settle_time - 1e-9
        if self.uncontrolled and controlled:
            return 0.0
        if self.base_damping and controlled and agent in self.tip_state:
            law = -self.base_damping * float(self.tip_state[agent][2])
            action = np.asarray(action, dtype=float).reshape(-1)[:1] + law
        return super()._slot_mean_velocity(agent, action)

    def _initial_actions(self) -> dict[str, np.ndarray]:
        """Choose this episode's start; the run's first window is the gust's first setting.

        Core calls it during ``reset()`` once the seed is applied and the solvers run.
        """
        fixed = fixed_start(self._split, self._split_seed, EVAL_GUSTS, VALIDATION_GUSTS)
        self.start = fixed or gust(self.np_random, self.settle_time)
        return {
            agent: np.array([value], dtype=np.float32)
            for agent, value in self.start.settings(0.0).items()
        }


def _pair(values: tuple[float, ...]) -> str:
    return "(" + ", ".join(f"{v:+g}" for v in values) + ")"


class TwoFlapsJointEnv(JointEnv):
    """TwoFlapsFast as one ``gymnasium.Env``: one controller that sees and drives both slots.

    What ``gymprecice/TwoFlapsFast-v0`` makes, for Gymnasium and the single-agent lab
    commands, and the baseline a shared policy is compared with. Observation ``(2, 9)`` and
    action ``(2, 1)``, one row per flap (upstream first); reward the mean of the two
    agents' rewards. ``info["metrics"]`` holds ``mean_tip_displacement``, the mean of
    both flaps' (the negated reward), and each flap's own; ``info["action"]`` both slots'
    mean velocities (m/s). Keyword arguments are :class:`TwoFlapsFastEnv`'s
    (``render_mode`` among them: the frame is the multi-agent env's).
    """

    #: what ``gymnasium.make`` and the lab's ``--video`` read before building the env
    metadata: dict[str, Any] = dict(TwoFlapsFastEnv.metadata)

    def __init__(self, options: Any = None, idx: int | None = 0, **kwargs: Any) -> None:
        super().__init__(TwoFlapsFastEnv(options, idx, **kwargs))

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        live = list(self.env.agents)
        obs, reward, terminated, truncated, info = super().step(action)
        if "diverged" not in info:
            env = self.env
            per_flap = {agent: env.mean_tip_displacement(agent) for agent in live}
            info["metrics"] = {
                "mean_tip_displacement": float(np.mean(list(per_flap.values()))),
                **{f"{agent}_tip_displacement": value for agent, value in per_flap.items()},
            }
            info["action"] = [env.jet_velocity[agent] for agent in self.agents]
        return obs, reward, terminated, truncated, info

    @property
    def held_out_starts(self) -> tuple[str, ...]:
        return self.env.held_out_starts

    @property
    def validation_starts(self) -> tuple[str, ...]:
        return self.env.validation_starts
