"""The environment models: small networks that predict the next observation and the reward.

Each member reads the last ``history`` observations and actions and predicts the change of
the observation and the reward of the newest action, in units of the data's own spread
(inputs and outputs are standardised: the probes' pressures and the reward differ by orders
of magnitude). Members differ in their initial weights and in which transitions they hold
out for validation, which is what makes their disagreement a measure of what the data does
not tell.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch as th
from numpy.lib.stride_tricks import sliding_window_view
from torch import nn

from gymprecice_lab.model_based.recorder import Segment
from gymprecice_lab.model_based.settings import EnsembleSettings

__all__ = ["EnvironmentEnsemble", "FitReport", "windows"]


@dataclass(frozen=True)
class FitReport:
    """What a fit did: the transitions used, and per member the epoch its kept weights come
    from (0: the previous fit's were not beaten) and their held-out loss."""

    transitions: int
    epochs: tuple[int, ...]
    validation_loss: tuple[float, ...]

    @property
    def mean_validation_loss(self) -> float:
        return float(np.mean(self.validation_loss))


def windows(segments: Sequence[Segment], history: int) -> tuple[np.ndarray, np.ndarray]:
    """Inputs and targets of every step with ``history`` steps behind it in its episode.

    Input: the ``history`` newest observations, then the ``history`` newest actions (the
    last being the action taken); target: the change of the observation, then the reward.
    """
    xs, ys = [], []
    for segment in segments:
        obs, actions, rewards = segment.arrays()
        steps = len(actions)
        if steps < history:
            continue
        # windows[k] covers steps k .. k+history-1; the step predicted is t = k+history-1
        obs_windows = sliding_window_view(obs[:steps], history, axis=0)  # [n, d, H]
        act_windows = sliding_window_view(actions, history, axis=0)  # [n, a, H]
        n = obs_windows.shape[0]
        x = np.concatenate(
            [
                obs_windows.transpose(0, 2, 1).reshape(n, -1),
                act_windows.transpose(0, 2, 1).reshape(n, -1),
            ],
            axis=1,
        )
        t = np.arange(history - 1, steps)
        y = np.concatenate([obs[t + 1] - obs[t], rewards[t, None]], axis=1)
        xs.append(x)
        ys.append(y)
    if not xs:
        return np.empty((0, 0), np.float32), np.empty((0, 0), np.float32)
    return np.concatenate(xs).astype(np.float32), np.concatenate(ys).astype(np.float32)


class _Members(nn.Module):
    """All members' layers stacked: one batched matrix product per layer trains them all
    at once (small networks are bound by Python's per-call cost, not by arithmetic)."""

    def __init__(self, members: int, sizes: Sequence[int], generator: th.Generator) -> None:
        super().__init__()
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for fan_in, fan_out in itertools.pairwise(sizes):
            bound = 1.0 / np.sqrt(fan_in)  # PyTorch's default for nn.Linear
            w = th.empty(members, fan_in, fan_out).uniform_(-bound, bound, generator=generator)
            b = th.empty(members, 1, fan_out).uniform_(-bound, bound, generator=generator)
            self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(b))

    def forward(self, x: th.Tensor) -> th.Tensor:
        """``x``: ``[members, batch, in]`` -> ``[members, batch, out]``."""
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            x = th.baddbmm(b, x, w)
            if k < last:
                x = nn.functional.silu(x)
        return x


class EnvironmentEnsemble:
    """``settings.members`` networks, fitted together on the same transitions."""

    def __init__(self, settings: EnsembleSettings, obs_dim: int, act_dim: int, seed: int) -> None:
        self.settings = settings
        self.obs_dim = obs_dim
        self.act_dim = act_dim
        self._rng = np.random.default_rng(seed)
        in_dim = settings.history * (obs_dim + act_dim)
        sizes = [in_dim, *settings.hidden, obs_dim + 1]
        self.net = _Members(settings.members, sizes, th.Generator().manual_seed(seed))
        self._optimizer = th.optim.Adam(self.net.parameters(), lr=settings.learning_rate)
        self._x_mean = np.zeros(in_dim, np.float32)
        self._x_std = np.ones(in_dim, np.float32)
        self._y_mean = np.zeros(obs_dim + 1, np.float32)
        self._y_std = np.ones(obs_dim + 1, np.float32)
        self.fitted = False

    @property
    def members(self) -> int:
        return self.settings.members

    def fit(self, segments: Sequence[Segment]) -> FitReport:
        """Fit every member on ``segments`` (continuing from its weights), early-stopped.

        Each member holds out its own random ``validation`` share and keeps the weights of
        its best epoch on it; the fit stops when no member improved for ``patience`` epochs.
        """
        s = self.settings
        x, y = windows(segments, s.history)
        if len(x) < 2:
            raise ValueError(
                f"the ensemble needs at least 2 transitions with {s.history} steps of history"
            )
        self._x_mean, self._x_std = x.mean(0), _spread(x)
        self._y_mean, self._y_std = y.mean(0), _spread(y)
        xt = th.as_tensor((x - self._x_mean) / self._x_std)
        yt = th.as_tensor((y - self._y_mean) / self._y_std)
        held_out = max(1, round(s.validation * len(x)))
        orders = np.stack([self._rng.permutation(len(x)) for _ in range(s.members)])
        val = th.as_tensor(orders[:, :held_out])
        train = orders[:, held_out:] if len(x) > held_out else orders
        batches = max(1, train.shape[1] // s.batch_size)

        best = self._losses(xt, yt, val)
        best_state = [p.detach().clone() for p in self.net.parameters()]
        best_epoch = np.zeros(s.members, np.int64)
        since = 0
        for epoch in range(1, s.epochs + 1):
            self.net.train()
            shuffled = np.take_along_axis(train, self._rng.random(train.shape).argsort(1), 1)
            for batch in np.array_split(shuffled, batches, axis=1):
                index = th.as_tensor(batch)
                self._optimizer.zero_grad()
                loss = nn.functional.mse_loss(self.net(xt[index]), yt[index])
                loss.backward()
                self._optimizer.step()
            losses = self._losses(xt, yt, val)
            improved = losses < best
            if improved.any():
                since = 0
                with th.no_grad():
                    for kept, now in zip(best_state, self.net.parameters()):
                        kept[improved] = now[improved]
                best = np.where(improved, losses, best)
                best_epoch[improved] = epoch
            else:
                since += 1
                if since >= s.patience:
                    break
        with th.no_grad():
            for now, kept in zip(self.net.parameters(), best_state):
                now.copy_(kept)
        self.fitted = True
        return FitReport(len(x), tuple(int(e) for e in best_epoch), tuple(float(v) for v in best))

    def _losses(self, x: th.Tensor, y: th.Tensor, index: th.Tensor) -> np.ndarray:
        """Each member's mean squared error on its own rows ``index[m]``."""
        self.net.eval()
        with th.no_grad():
            err = (self.net(x[index]) - y[index]) ** 2
        return err.mean(dim=(1, 2)).numpy()

    def predict(
        self, members: np.ndarray, obs_history: np.ndarray, action_history: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Next observations and rewards; row ``i`` follows member ``members[i]``.

        ``obs_history`` is ``[n, history, obs_dim]`` (oldest first), ``action_history``
        ``[n, history, act_dim]`` (the last row the action now taken).
        """
        n = len(members)
        x = np.concatenate([obs_history.reshape(n, -1), action_history.reshape(n, -1)], axis=1)
        xt = th.as_tensor(((x - self._x_mean) / self._x_std).astype(np.float32))
        self.net.eval()
        with th.no_grad():
            every = self.net(xt.expand(self.members, n, -1))  # each member on every row
        out = every[th.as_tensor(members), th.arange(n)].numpy()
        out = out * self._y_std + self._y_mean
        return obs_history[:, -1, :] + out[:, :-1], out[:, -1]


def _spread(values: np.ndarray) -> np.ndarray:
    """Standard deviation per column, 1 where a column is constant (nothing to scale)."""
    std = values.std(0)
    return np.where(std > 1e-8, std, 1.0).astype(np.float32)
