"""What core does with the answers of the per-solver case hooks, in one place.

Core (:class:`gymprecice.core.Adapter`) and the plugin conformance suite
(:mod:`gymprecice.testing.conformance`) both go through these functions, so a plugin that
passes the suite behaves the same in an env. Each hook's ``None`` means one thing: *this
plugin gives no answer for this solver* (usually: not its kind). What core then does is
stated here and in each hook's spec:

* ``gymprecice_prepare_case``: nobody prepares, so core's own preparation stands: the
  pristine case already copied into the env's run directory. A solver that needs nothing
  beyond its case files needs no prepare hook.
* ``gymprecice_reset_case`` and ``gymprecice_launch_solver``: nobody answers, so the solver
  cannot run: a :class:`~gymprecice.errors.CaseError` names the hook to implement.

Any other answer than the documented ones (``False``, a string) is a plugin bug and is
refused with the hook's name, rather than read as "handled".
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from typing import Any

from gymprecice.plugin.errors import CaseError, ConfigError, SolverError, SolverTimeoutError
from gymprecice.plugin.fields import Field
from gymprecice.plugin.solver import LaunchSpec, SolverContext

__all__ = ["launch_spec", "prepare_case", "read_field", "reset_case"]

#: seconds between two looks for a field snapshot the solver has not written yet
FIELD_POLL_S = 0.05


def _bad_answer(hook: str, ctx: SolverContext, answer: Any, expected: str) -> CaseError:
    return CaseError(
        f"{ctx.describe()}: {hook} returned {answer!r}; it must return {expected}. "
        f"Fix the plugin that handles kind {ctx.kind!r} (raise CaseError with the file and the "
        "fix when the case is bad, instead of returning a false value)"
    )


def prepare_case(hook: Any, ctx: SolverContext) -> bool:
    """Call ``gymprecice_prepare_case``; ``None`` keeps core's copy of the case as it is.

    Returns whether a plugin prepared the solver (``False``: core's copy is all there is).
    """
    answer = hook.gymprecice_prepare_case(solver=ctx)
    if answer is None:
        return False
    if answer is not True:
        raise _bad_answer(
            "gymprecice_prepare_case",
            ctx,
            answer,
            "True (prepared) or None (nothing to do beyond core's copy of the case)",
        )
    return True


def reset_case(hook: Any, ctx: SolverContext) -> None:
    """Call ``gymprecice_reset_case``; a solver nobody resets cannot start an episode."""
    answer = hook.gymprecice_reset_case(solver=ctx)
    if answer is None:
        raise CaseError(
            f"{ctx.describe()}: no installed plugin resets this kind: every hook "
            f"gymprecice_reset_case returned None for kind {ctx.kind!r}. The plugin that "
            "declares the kind must implement it and return True (with an empty body when "
            "the solver needs no reset)"
        )
    if answer is not True:
        raise _bad_answer("gymprecice_reset_case", ctx, answer, "True (reset) or None (not mine)")


def launch_spec(hook: Any, ctx: SolverContext) -> LaunchSpec:
    """Call ``gymprecice_launch_solver``; a solver nobody launches cannot run."""
    spec = hook.gymprecice_launch_solver(solver=ctx)
    if spec is None:
        raise CaseError(
            f"{ctx.describe()}: no installed plugin launches this kind: every hook "
            f"gymprecice_launch_solver returned None for kind {ctx.kind!r}. The plugin that "
            "declares the kind must implement it and return a LaunchSpec"
        )
    if not isinstance(spec, LaunchSpec):
        raise _bad_answer("gymprecice_launch_solver", ctx, spec, "a LaunchSpec or None (not mine)")
    return spec


def read_field(
    hook: Any,
    ctx: SolverContext,
    name: str,
    time: float,
    *,
    tolerance: float,
    timeout: float,
    alive: Callable[[], None] | None = None,
    plugin: str | None = None,
    exited: bool = False,
) -> Field:
    """Call ``gymprecice_read_field`` until the solver's snapshot reaches ``time``.

    The solver may write a moment after the coupling returned, so an older snapshot (or
    none yet) means "ask again": every :data:`FIELD_POLL_S` seconds, with ``alive()``
    raising if a solver died, until ``timeout``. Once the solver has ``exited`` (the
    episode is over: a render after its last step) nothing more will be written: one
    look, and a missing snapshot is a :class:`SolverError` at once, not a wait. No plugin
    answering at all is an error naming the solver's plugin (``plugin``) and the hook.
    """
    deadline = _time.monotonic() + (0.0 if exited else max(0.0, timeout))
    answered = None
    while True:
        answered = hook.gymprecice_read_field(solver=ctx, name=name, time=time)
        if answered is None and plugin is not None:
            # No snapshot yet, or a plugin that reads no fields at all: tell them apart.
            impls = [impl.plugin_name for impl in hook.gymprecice_read_field.get_hookimpls()]
            if plugin not in impls:
                raise ConfigError(
                    f"{ctx.describe()}: cannot render field {name!r}: plugin {plugin!r}, which "
                    f"handles kind {ctx.kind!r}, does not implement the hook "
                    "gymprecice_read_field; render without this solver (leave it out of the "
                    "env's render_fields) or add the hook to the plugin"
                )
        if answered is not None:
            if not isinstance(answered, Field):
                raise _bad_answer(
                    "gymprecice_read_field", ctx, answered, "a gymprecice.fields.Field or None"
                )
            if answered.time >= time - tolerance:
                return answered
        if _time.monotonic() >= deadline:
            have = "none" if answered is None else f"the latest at t={answered.time:g}"
            if exited:
                raise SolverError(
                    f"{ctx.describe()}: field {name!r} at t={time:g} was not written before "
                    f"the solver exited at the episode's end ({have}); its plugin must make "
                    "it write the fields at the coupling's last step too",
                    env_index=ctx.env_index,
                    solver=ctx.name,
                )
            raise SolverTimeoutError(
                f"{ctx.describe()}: field {name!r} at t={time:g} was not written within "
                f"{timeout:g} s ({have}); check that the solver writes it at every action",
                env_index=ctx.env_index,
                solver=ctx.name,
            )
        if alive is not None:
            alive()
        _time.sleep(FIELD_POLL_S)
