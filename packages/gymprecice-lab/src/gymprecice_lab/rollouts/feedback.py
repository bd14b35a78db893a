"""The lab's classical feedback controllers: a signal fed back, or an env's own law.

:class:`FeedbackController` (:mod:`gymprecice.learners.feedback`, re-exported here)
feeds one of an env's ``info["metrics"]`` back to a bounded action, delayed and scaled:
the cylinders' lift on the jets or the spin. ``gymprecice feedback ENV --gain G --delay D``
runs one law; ``gymprecice sweep ENV --feedback-gains ... --feedback-delays ...`` tunes
it on the held-out starts beside the open-loop forcings.

Not every task's textbook controller is the lift fed back. An env names its own family
of classical controllers as a :class:`gymprecice.card.FeedbackLaw` (its lab card's
``feedback_law``: the heated plate's PID heater in the tutorials), with the grid of its
documented tuning; ``gymprecice sweep`` and ``benchmark`` then tune that family instead,
over ``--feedback-grid "kp=2,3;ki=25,50"`` or the law's own grid.
"""

from __future__ import annotations

from gymprecice.learners.feedback import FeedbackController
from gymprecice.plugin.card import FeedbackLaw, Grid, load_object

__all__ = ["FeedbackController", "own_law_grid"]


def own_law_grid(
    env_name: str, law_spec: str | None, gains: str | None, grid_text: str | None
) -> tuple[FeedbackLaw | None, Grid | None]:
    """The feedback law an env names (``law_spec``) and its grid to tune, from a command's
    ``--feedback-gains`` and ``--feedback-grid`` (``None``: not given, the law's documented
    grid; ``""``: no feedback baseline, grid ``None``). An env without a law of its own
    gives ``(None, None)``: its feedback is a signal fed back. The other kind's option is
    a ``ValueError`` rather than ignored."""
    if law_spec is None:
        if grid_text:
            raise ValueError(
                f"{env_name} has no feedback law of its own for --feedback-grid; its "
                "classical feedback is a signal fed back: --feedback-gains and "
                "--feedback-delays"
            )
        return None, None
    law = load_object(law_spec, "feedback_law")
    if gains:
        raise ValueError(
            f"{env_name}'s classical feedback is its {law.name} law "
            f"({', '.join(law.parameters)}), not a signal fed back: tune it with "
            f'--feedback-grid "{law.grid_text(law.default_grid())}" instead of '
            "--feedback-gains"
        )
    if grid_text == "":
        return law, None
    return law, law.parse_grid(grid_text or "")
