"""Model-ensemble PPO: policy updates on flow predicted by learned models between CFD rollouts.

Each action of the real case costs seconds of CFD; a small network's prediction of the next
probe readings costs microseconds. drlFoam's model-ensemble PPO (Weiner and Geise, "Model-
based deep reinforcement learning for accelerated learning from flow simulations",
Meccanica 2024) trains an ensemble of such networks on every CFD transition seen so far and
lets PPO learn from trajectories the ensemble predicts between the CFD rollouts; its authors
report up to 85 % less training time (the fluidic pinball; above 65 % on the cylinder). The
ensemble, rather than one network, keeps the policy from exploiting one model's errors:
every member predicts its own trajectory, and the policy goes back to the CFD as soon as
fewer than a quorum of members see it improve.

The parts, one per module:

* :mod:`.settings`: the ``model_ensemble`` key of a hyperparameter file, checked;
* :mod:`.recorder`: a vector-env wrapper that keeps every CFD transition, raw (before
  ``VecNormalize``), and saves them beside the run so that a resume keeps them;
* :mod:`.ensemble`: the networks and their fit;
* :mod:`.model_env`: a vector env whose steps are the ensemble's predictions;
* :mod:`.ppo`: :class:`~.ppo.ModelEnsemblePPO`, SB3's PPO with the model-based updates
  after each CFD update.

Only the CFD actions count: ``num_timesteps``, the checkpoints and ``--timesteps`` are the
real case's actions, so a model-ensemble run is compared with PPO action for action and
second for second.
"""

from gymprecice_lab.model_based.settings import ENSEMBLE_KEY, EnsembleSettings

__all__ = ["ENSEMBLE_KEY", "EnsembleSettings"]
