"""What a validation scores: the fraction of the floor once settled, where an env has one.

A training run keeps the model best on its validation starts
(:mod:`gymprecice_lab.training.validation`). By default the score is the mean return of a
training-length episode. For an env whose lab card declares a physical ``reference`` (a
cylinder's drag floor) that is the wrong question: the benchmark and ``time-to-floor``
judge a controller by the reference's metric *once settled*, after the card's
``settle_time`` of transient, and the reward is not that metric (Rabault's reward charges
the lift too, and a 2 s training episode is mostly transient). On the jet cylinder, two
runs' checkpoints at 2,400 actions took 99.5 and 100.5 % of the drag floor once settled,
their final models 87 and 89 %: the last actions traded drag for less lift, as the
reward asks (docs/benchmark.md).

So for such an env every validation episode runs the transient and then one training
episode more (:func:`validation_episode_time`), and
:class:`~gymprecice_lab.common.settled_score.SettledFloorScore` makes the episode's return
the fraction of the floor that the settled mean of the metric reaches, the number
``time-to-floor`` reports, computed the same way. SB3's ``EvalCallback`` then keeps the
model best on that, unchanged.
"""

from __future__ import annotations

from gymprecice.plugin.card import EnvCard, Reference
from gymprecice_lab.common.kept_model import RETURN_SCORE

__all__ = ["score_name", "settled_reference", "validation_episode_time"]


def settled_reference(card: EnvCard) -> Reference | None:
    """The card's reference when validation can score it: declared, and either with no
    transient or on an env whose episode length can be set (``episode_time``)."""
    reference = card.reference
    if reference is None or (reference.settle_time > 0 and not card.episode_time):
        return None
    return reference


def validation_episode_time(reference: Reference, episode_time: float) -> float:
    """The transient the reference leaves out, then one training episode of settled flow."""
    return reference.settle_time + episode_time


def score_name(reference: Reference | None) -> str:
    """How the kept model's record names its score."""
    if reference is None:
        return RETURN_SCORE
    return f"settled fraction of the {reference.label}"
