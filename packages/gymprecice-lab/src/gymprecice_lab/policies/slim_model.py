"""A trained SB3 model stripped to what evaluation needs, so that a shipped policy is small.

Shipping strips the optimizer's moments (two thirds of a PPO ``model.zip``), the value
function's weights (zeroed, so that SB3 still loads the file and the zeros deflate away),
the last observations and episode statistics of training, and the TensorBoard path; the
archive is deflated. For the 512x512 MLP on 151 probes that is 8.2 MB trained, 1.3 MB
shipped. The shipped model is checked to act exactly like the trained one. ``PPO.load``
reads it as any SB3 model, but with a blank critic and fresh optimizer: continue training
from the training run's own checkpoint, not from a shipped policy.

The VecNormalize statistics beside it are frozen and lose training's last observations.
:mod:`gymprecice_lab.policies.ship` writes both into a policy's directory.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

from gymprecice_lab.policies.policy import PolicyError

__all__ = ["check_same_actions", "write_frozen_stats", "write_slim_model"]

#: Saved attributes of an SB3 model that only training uses (left out of a shipped one).
_TRAINING_ONLY = (
    "_last_obs",
    "_last_original_obs",
    "_last_episode_starts",
    "ep_info_buffer",
    "ep_success_buffer",
)
#: Parameter names of the value function in SB3 policies: PPO's value branch and head,
#: SAC's and TD3's critics. Evaluation never reads them.
_CRITIC_PREFIXES = ("mlp_extractor.value_net.", "value_net.", "critic.", "critic_target.")


def write_slim_model(model: Any, path: Path) -> None:
    """The model without what only training needs, in a deflated zip."""
    import torch

    optimizer = getattr(model.policy, "optimizer", None)
    if optimizer is not None:
        optimizer.state.clear()  # Adam's moments: twice the network; fresh state loads fine
    with torch.no_grad():
        # the value function (critics) only steers training: zeros keep the file loadable
        # by SB3 and deflate to nothing; the actions are checked unchanged afterwards
        for name, param in model.policy.named_parameters():
            if name.startswith(_CRITIC_PREFIXES):
                param.zero_()
    model.tensorboard_log = None
    stored = path.with_suffix(".stored.zip")
    model.save(stored, exclude=list(_TRAINING_ONLY))
    with (
        zipfile.ZipFile(stored) as src,
        zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as dst,
    ):
        for item in src.infolist():
            dst.writestr(item.filename, src.read(item.filename))
    stored.unlink()


def check_same_actions(model: Any, path: Path) -> None:
    """The shipped file loads with SB3's own ``load`` and acts exactly like the original."""
    import numpy as np

    from gymprecice_lab.common.wrapped_env import load_model

    slim = load_model(path)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(8, *model.observation_space.shape)).astype(np.float32)
    ours, _ = slim.predict(obs, deterministic=True)
    theirs, _ = model.predict(obs, deterministic=True)
    if not np.array_equal(ours, theirs):
        raise PolicyError("the stripped model does not act like the trained one; not shipped")


def write_frozen_stats(source: Path, path: Path) -> None:
    """The VecNormalize statistics, frozen, without training's last observations."""
    import pickle

    import numpy as np

    with source.open("rb") as handle:
        stats = pickle.load(handle)
    stats.training = False
    for attr in ("old_obs", "old_reward"):
        if hasattr(stats, attr):
            setattr(stats, attr, np.array([]))
    # what VecNormalize's own pickling drops, and unpickling did not restore
    stats.class_attributes, stats.returns = {}, np.array([])
    with path.open("wb") as handle:
        pickle.dump(stats, handle)
