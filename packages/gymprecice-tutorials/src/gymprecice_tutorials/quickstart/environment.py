"""Quickstart-v0: the jet cylinder made cheap enough to try on a laptop.

The jet cylinder on the recipe's coarse mesh (a few thousand cells, one process), with a
5 s pre-run and 20-action (0.5 s) episodes: an episode takes seconds once the pre-run is
cached, so the whole pipeline (pre-run, coupling, training, plots) can be seen working
before committing hours to :class:`~gymprecice_tutorials.jet_cylinder.environment.JetCylinderEnv`.
The coarse mesh's uncontrolled drag differs from the fine one's, so ``reward_offset``
(3.205, the fine mesh's value) no longer makes "no control" score exactly zero; compare
against ``gymprecice baseline quickstart`` instead.
"""

from __future__ import annotations

from typing import ClassVar

from gymprecice_tutorials.jet_cylinder.environment import JetCylinderEnv

__all__ = ["QuickstartEnv"]


class QuickstartEnv(JetCylinderEnv):
    """:class:`JetCylinderEnv` on the ``quickstart`` recipe; the same keyword arguments."""

    recipe: ClassVar[str] = "quickstart"
