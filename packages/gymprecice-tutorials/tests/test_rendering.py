"""Every tutorial env renders on the test double: ``gymnasium.make(id, render_mode=...)``.

The doubles' scripted flows hand over the same field names as the real solvers' plugins
(``U`` of the fluids, the flap's ``displacement``, the plate's ``T``), so the frame, the
overlay and the video machinery run here exactly as on the real stack. The two flaps' id
is the joint (single-controller) view of a multi-agent env: it renders its frame.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import gymprecice  # noqa: F401  (registers the ids)

#: a frame that shows a field has far more pixel variance than a blank or one-colour one
VARIANCE_FLOOR = 100.0
#: every tutorial env that has a test double, with the simulated seconds of a test
#: episode (a few actions); the flap's full case has none: its training case stands in
DOUBLES = {
    "gymprecice/JetCylinder-v0": 0.1,
    "gymprecice/RotatingCylinder-v0": 0.1,
    "gymprecice/JetCylinderFast-v0": 0.1,
    "gymprecice/RotatingCylinderFast-v0": 0.1,
    "gymprecice/Quickstart-v0": 0.1,
    "gymprecice/PerpendicularFlapFast-v0": 0.3,
    "gymprecice/HeatedPlate-v0": 0.5,
    "gymprecice/HeatedPlateFast-v0": 0.5,
    "gymprecice/TwoFlapsFast-v0": 0.3,
}
#: tutorial envs with no test double: the flap's full case, and FSI3 (tests/test_fsi3_real.py
#: renders it on the real solvers)
WITHOUT_DOUBLE = {"gymprecice/PerpendicularFlap-v0", "gymprecice/TurekHronFSI3-v0"}


def _make(env_id: str, tmp_path: Path) -> gym.Env:
    return gym.make(
        env_id,
        double=True,
        run_root=str(tmp_path / "runs"),
        episode_time=DOUBLES[env_id],
        render_mode="rgb_array",
    )


@pytest.mark.parametrize("env_id", sorted(DOUBLES))
def test_every_tutorial_env_renders_a_changing_frame(env_id, tmp_path):
    env = _make(env_id, tmp_path)
    try:
        assert env.metadata["render_fps"] > 0
        assert env.unwrapped.render_mode == "rgb_array"
        env.reset(seed=0)
        first = env.render()
        width, _ = env.unwrapped.render_size  # the height follows the domain
        assert first.shape[1:] == (width, 3) and first.dtype == np.uint8
        assert first.shape[0] % 16 == 0
        assert first.var() > VARIANCE_FLOOR
        high = env.action_space.high
        env.step(np.asarray(high, dtype=env.action_space.dtype))
        env.step(np.asarray(high, dtype=env.action_space.dtype))
        second = env.render()
        assert second.shape == first.shape
        assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
    finally:
        env.close()


def test_every_tutorial_env_is_covered():
    tutorials = {
        env_id
        for env_id, spec in gym.registry.items()
        if str(spec.entry_point).startswith("gymprecice_tutorials")
    }
    assert tutorials == set(DOUBLES) | WITHOUT_DOUBLE


def test_record_video_of_a_tutorial_env(tmp_path):
    pytest.importorskip("moviepy", reason="the render extra: gymprecice-core[render]")
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="gymprecice-core[render]")
    env = _make("gymprecice/JetCylinderFast-v0", tmp_path)
    videos = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(videos), episode_trigger=lambda _: True)
    env.reset(seed=0)
    done = False
    while not done:
        *_, terminated, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
        done = terminated or truncated
    env.close()
    (video,) = videos.glob("*.mp4")
    reader = imageio_ffmpeg.read_frames(str(video))
    # the jet's channel (2.2 m x 0.41 m): a wide frame, its height whole macro blocks
    width, height = next(reader)["size"]
    assert width == 640 and height % 16 == 0 and height < 320
    assert len(list(reader)) >= 2
