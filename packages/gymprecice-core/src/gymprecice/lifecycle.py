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

from typing import Any

from gymprecice.errors import CaseError
from gymprecice.solver import LaunchSpec, SolverContext

__all__ = ["launch_spec", "prepare_case", "reset_case"]


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
