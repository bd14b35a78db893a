"""``ModelEnsemblePPO``: SB3's PPO, with model-based updates after each CFD update.

After every CFD rollout and its PPO update (SB3's own ``train``), the ensemble is fitted on
every CFD transition recorded so far, then up to ``updates`` times: each member predicts one
trajectory under the current policy, and PPO updates on them. The counters that the run's
clock, checkpoints and ``--timesteps`` read (``num_timesteps``, the CFD env's last
observation) are put back afterwards, so only CFD actions count.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from gymprecice_lab.model_based.ensemble import EnvironmentEnsemble
from gymprecice_lab.model_based.model_env import ModelVecEnv
from gymprecice_lab.model_based.recorder import TransitionRecorder
from gymprecice_lab.model_based.settings import TRANSITIONS_FILE, EnsembleSettings

__all__ = ["TRANSITIONS_FILE", "ModelEnsemblePPO"]


class _Quiet(BaseCallback):
    """The callback of model-based rollouts: checkpoints and episode logs count CFD only."""

    def _on_step(self) -> bool:
        return True


class ModelEnsemblePPO(PPO):
    """PPO that also learns from an ensemble of environment models (see the package doc).

    Built and loaded like :class:`~stable_baselines3.PPO`; :meth:`attach` then gives it the
    settings, the recorder under the CFD env and the file that keeps the transitions. Its
    saved models are PPO's (the ensemble is not saved: it is refitted from the transitions).
    """

    _settings: EnsembleSettings | None = None
    _recorder: TransitionRecorder | None = None
    _transitions_file: Path | None = None
    _ensemble: EnvironmentEnsemble | None = None
    _model_env: ModelVecEnv | None = None
    _cfd_rollouts: int = 0

    def attach(
        self, settings: EnsembleSettings, recorder: TransitionRecorder, transitions_file: Path
    ) -> int:
        """Use ``settings`` and ``recorder``; reload transitions kept by an earlier segment.

        Raises ``ValueError`` for an env the models cannot predict: they read and write
        flat ``Box`` observations and actions.
        """
        for name, space in (("observation", self.observation_space), ("action", self.action_space)):
            if not isinstance(space, spaces.Box) or len(space.shape) != 1:
                raise ValueError(
                    f"model_ensemble needs a flat Box {name} space (its models predict "
                    f"vectors); this env's is {space}: drop model_ensemble for this env"
                )
        self._settings = settings
        self._recorder = recorder
        self._transitions_file = transitions_file
        restored = recorder.load(transitions_file)
        # a resume has its data already: no warm-up again
        self._cfd_rollouts = settings.warmup_rollouts if restored else 0
        return restored

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "_settings",
            "_recorder",
            "_transitions_file",
            "_ensemble",
            "_model_env",
            "_cfd_rollouts",
        ]

    def train(self) -> None:
        super().train()
        if self._settings is None or self._recorder is None:
            return
        self._cfd_rollouts += 1
        if self._transitions_file is not None:
            self._recorder.save(self._transitions_file)
        if self._cfd_rollouts <= self._settings.warmup_rollouts or self._settings.updates == 0:
            return
        self._model_based_updates()

    def _model_based_updates(self) -> None:
        settings, recorder = self._settings, self._recorder
        assert settings is not None and recorder is not None
        segments = recorder.segments()
        ensemble = self._ensemble_for(segments)
        report = ensemble.fit(segments)
        model_env = self._model_env_for(ensemble)
        model_env.use(segments)
        env = self._normalized(model_env)

        saved = (
            self.num_timesteps,
            self._last_obs,
            self._last_episode_starts,
            self.rollout_buffer,
        )
        self.rollout_buffer = self.rollout_buffer_class(
            self.n_steps,
            self.observation_space,
            self.action_space,
            device=self.device,
            gamma=self.gamma,
            gae_lambda=self.gae_lambda,
            n_envs=model_env.num_envs,
            **self.rollout_buffer_kwargs,
        )
        callback = _Quiet()
        callback.init_callback(self)
        # train/ keeps the CFD update's losses (the model-based ones would overwrite them);
        # train/n_updates counts every update
        cfd_losses = {
            k: v
            for k, v in self.logger.name_to_value.items()
            if k.startswith("train/") and k != "train/n_updates"
        }
        done, previous, improving = 0, None, 1.0
        try:
            while done < settings.updates:
                self._last_obs = env.reset()  # the same starts each time (ModelVecEnv.use)
                self._last_episode_starts = np.ones(model_env.num_envs, dtype=bool)
                self.collect_rollouts(env, callback, self.rollout_buffer, self.n_steps)
                per_env = _mean_reward_per_env(self.rollout_buffer.rewards)
                per_member = per_env.reshape(-1, ensemble.members).mean(axis=0)
                if previous is not None:
                    improving = float(np.mean(per_member > previous))
                    if improving < settings.quorum:
                        break
                previous = per_member
                PPO.train(self)
                done += 1
        finally:
            self.num_timesteps, self._last_obs, self._last_episode_starts = saved[:3]
            self.rollout_buffer = saved[3]
            for key, value in cfd_losses.items():
                self.logger.record(key, value)
        self.logger.record("model/transitions", report.transitions)
        self.logger.record("model/validation_loss", report.mean_validation_loss)
        self.logger.record("model/fit_epochs", float(np.mean(report.epochs)))
        self.logger.record("model/updates", done)
        self.logger.record("model/improving_share", improving)

    def _ensemble_for(self, segments: list[Any]) -> EnvironmentEnsemble:
        if self._ensemble is None:
            assert self._settings is not None
            obs, actions, _ = segments[0].arrays()
            self._ensemble = EnvironmentEnsemble(
                self._settings, obs.shape[1], actions.shape[1], seed=self.seed or 0
            )
        return self._ensemble

    def _model_env_for(self, ensemble: EnvironmentEnsemble) -> ModelVecEnv:
        if self._model_env is None:
            self._model_env = ModelVecEnv(
                ensemble,
                self.observation_space,  # type: ignore[arg-type]
                self.action_space,  # type: ignore[arg-type]
                horizon=self.n_steps,
                seed=(self.seed or 0) + 1,
                trajectories=self._settings.trajectories if self._settings else 1,
            )
        return self._model_env

    def _normalized(self, model_env: ModelVecEnv) -> VecEnv:
        """The model env seen through the CFD env's normalisation (frozen), if it has one."""
        cfd = self.env
        if not isinstance(cfd, VecNormalize):
            return model_env
        env = VecNormalize(
            model_env,
            training=False,
            norm_obs=cfd.norm_obs,
            norm_reward=cfd.norm_reward,
            clip_obs=cfd.clip_obs,
            clip_reward=cfd.clip_reward,
            gamma=cfd.gamma,
            epsilon=cfd.epsilon,
        )
        env.obs_rms, env.ret_rms = cfd.obs_rms, cfd.ret_rms
        return env


def _mean_reward_per_env(rewards: np.ndarray) -> np.ndarray:
    """Each env's mean reward of a rollout, leaving out the last step when there are more:
    PPO added the bootstrapped value of the truncated episode's end to it."""
    return (rewards[:-1] if len(rewards) > 1 else rewards).mean(axis=0)
