"""``--video``: the lab's rollouts write each episode's frames, and ``compare`` puts the
uncontrolled and the controlled flow side by side, on the test double.

The commands run as a user runs them (``python -m gymprecice ...``), on the jet cylinder's
training case coupled through the preCICE test double to its scripted flow.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import imageio.v3 as iio
import numpy as np
import pytest

import gymprecice  # noqa: F401  (registers the ids)
from gymprecice_lab import video as video_module
from gymprecice_lab.rollouts.video import VideoError, check_renders, check_video_path

ROLLOUT = ("jet-cylinder-fast", "--double", "--episode-time", "0.1")


def _cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _ok(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An uncontrolled and a controlled run of one episode from the same start, with videos."""
    root = tmp_path_factory.mktemp("videos")
    _ok(_cli(root, "baseline", *ROLLOUT, "--out", "baseline", "--video", "baseline.mp4"))
    _ok(_cli(root, "evaluate", *ROLLOUT, "--policy", "shipped", "--out", "evaluate", "--video"))
    return root


def _steps(run: Path) -> int:
    return json.loads((run / "summary.json").read_text())["episodes"][0]["steps"]


def test_each_episode_is_a_playable_video_of_a_frame_per_action(runs: Path) -> None:
    for run, path in (
        (runs / "baseline", runs / "baseline.mp4"),
        (runs / "evaluate", runs / "evaluate" / "episode.mp4"),  # --video without FILE
    ):
        frames = iio.imread(path, plugin="pyav") if _has_pyav() else _ffmpeg_frames(path)
        # the state after reset, then one per action, all of one size: the env's width and
        # a height from the jet's wide channel (whole macro blocks)
        assert frames.shape[0] == _steps(run) + 1 and frames.shape[2:] == (640, 3)
        assert frames.shape[1] % 16 == 0 and frames.shape[1] < 400
        assert frames[-1].var() > 100.0
        assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).sum() > 0
        episode = json.loads((run / "summary.json").read_text())["episodes"][0]
        assert Path(episode["video"]) == path.resolve()


def test_compare_puts_uncontrolled_and_controlled_side_by_side(runs: Path) -> None:
    out = _ok(_cli(runs, "compare", "baseline", "evaluate", "--video", "side.gif"))
    assert "side.gif" in out
    frames = iio.imread(runs / "side.gif")
    # each half a whole frame under its label strip, as many frames as the longer episode
    assert frames.shape[0] == max(_steps(runs / "baseline"), _steps(runs / "evaluate")) + 1
    height = next(video_module.read_frames(runs / "baseline.mp4")).shape[0]  # one frame's
    assert frames.shape[1] == height + 24 and frames.shape[2] == 2 * 640
    left, right = frames[-1][24:, :640], frames[-1][24:, 640:]
    assert left.var() > 100.0 and right.var() > 100.0
    # the shipped policy's jets differ from closed ones: the halves differ
    assert np.abs(left.astype(int) - right.astype(int)).sum() > 0


def test_compare_without_an_uncontrolled_video_names_the_command(runs: Path) -> None:
    proc = _cli(runs, "compare", "evaluate", "--video", "alone.mp4")
    assert proc.returncode == 2
    assert "no" in proc.stderr and "gymprecice baseline ENV --video" in proc.stderr
    assert not (runs / "alone.mp4").exists()


def test_a_format_without_a_writer_is_refused_before_anything_runs(tmp_path: Path) -> None:
    proc = _cli(tmp_path, "baseline", *ROLLOUT, "--out", "run", "--video", "episode.avi")
    assert proc.returncode == 2
    assert "cannot write .avi; name an MP4 or GIF file" in proc.stderr
    assert not (tmp_path / "run").exists()


def test_a_writer_not_installed_is_named_with_the_fix(monkeypatch: pytest.MonkeyPatch) -> None:
    find_spec = importlib.util.find_spec

    def without_ffmpeg(name: str, *args: object):
        return None if name == "imageio_ffmpeg" else find_spec(name, *args)

    monkeypatch.setattr(video_module.importlib.util, "find_spec", without_ffmpeg)
    with pytest.raises(VideoError, match=r"imageio_ffmpeg is not installed; pip install imageio"):
        check_video_path("wake.mp4")
    assert check_video_path("wake.gif").name == "wake.gif"  # GIF needs no ffmpeg


class _Blind(gym.Env):
    metadata = {"render_modes": []}


def test_an_env_that_does_not_render_is_refused() -> None:
    gym.register("test-video/Blind-v0", entry_point=_Blind)
    try:
        with pytest.raises(VideoError, match=r"does not render.*render_modes'\] is \[\]"):
            check_renders("test-video/Blind-v0")
    finally:
        del gym.registry["test-video/Blind-v0"]
    check_renders("gymprecice/JetCylinderFast-v0")  # a tutorial env renders


def _has_pyav() -> bool:
    return importlib.util.find_spec("av") is not None


def _ffmpeg_frames(path: Path) -> np.ndarray:
    return np.stack(list(video_module.read_frames(path)))
