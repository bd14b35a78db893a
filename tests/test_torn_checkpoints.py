"""A checkpoint torn by a crash mid-write is passed over when ``gymprecice train`` resumes.

A run killed while Stable-Baselines3 writes a checkpoint leaves the model zip cut before its
central directory, its replay buffer or ``VecNormalize`` pickle cut before its STOP opcode,
or the pickle not written at all. :func:`gymprecice_lab.envs.newest_checkpoint` (what a
resumed run, and ``evaluate`` on a training directory without a model, continues from)
must take the newest *intact* checkpoint and say in one line which file was torn and what
it uses instead. The files here have the layout SB3 writes (a zip with ``data``, pickles of
protocol 5 for the replay buffer and 4 for ``VecNormalize``), built without SB3 or torch.
Cost: under 0.1 s in all.
"""

from __future__ import annotations

import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest

from gymprecice_lab.common.wrapped_env import newest_checkpoint


def _checkpoint(directory: Path, steps: int, *, buffer: bool = True, stats: bool = True) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    model = directory / f"sac_{steps}_steps.zip"
    with zipfile.ZipFile(model, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("data", '{"policy_class": "SACPolicy"}')
        archive.writestr("policy.pth", np.random.default_rng(steps).bytes(50_000))
    if buffer:
        replay = {"observations": np.arange(20_000, dtype=np.float32), "pos": steps}
        (directory / f"sac_replay_buffer_{steps}_steps.pkl").write_bytes(
            pickle.dumps(replay, protocol=5)
        )
    if stats:
        (directory / f"sac_vecnormalize_{steps}_steps.pkl").write_bytes(
            pickle.dumps({"mean": np.zeros(4), "count": steps}, protocol=4)
        )
    return model


def _tear(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


@pytest.fixture
def checkpoints(tmp_path: Path) -> Path:
    directory = tmp_path / "train" / "checkpoints"
    for steps in (1000, 2000, 3000):
        _checkpoint(directory, steps)
    return directory


@pytest.mark.parametrize(
    ("torn", "says"),
    [
        ("sac_3000_steps.zip", "not a complete zip archive"),
        ("sac_replay_buffer_3000_steps.pkl", "sac_replay_buffer_3000_steps.pkl is cut short"),
        ("sac_vecnormalize_3000_steps.pkl", "sac_vecnormalize_3000_steps.pkl is cut short"),
    ],
)
def test_a_torn_newest_checkpoint_falls_back_to_the_one_before(checkpoints, capsys, torn, says):
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_3000_steps.zip", 3000)
    assert capsys.readouterr().err == ""  # intact: taken without a word
    _tear(checkpoints / torn)
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_2000_steps.zip", 2000)
    (line,) = capsys.readouterr().err.splitlines()
    assert line == (
        f"gymprecice: checkpoint {checkpoints / 'sac_3000_steps.zip'} is torn ({says}); "
        f"using {checkpoints / 'sac_2000_steps.zip'} instead"
    )


def test_a_pickle_the_crash_never_wrote_counts_as_torn(checkpoints, capsys):
    """The zip is written first: a crash right after it leaves no replay buffer, while the
    run's other checkpoints have theirs."""
    (checkpoints / "sac_replay_buffer_3000_steps.pkl").unlink()
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_2000_steps.zip", 2000)
    assert "sac_replay_buffer_3000_steps.pkl was never written" in capsys.readouterr().err


def test_a_zip_cut_by_a_few_bytes_or_with_a_bad_member_is_torn(checkpoints, capsys):
    model = checkpoints / "sac_3000_steps.zip"
    _tear(model, keep=0.999)
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_2000_steps.zip", 2000)
    data = bytearray((checkpoints / "sac_2000_steps.zip").read_bytes())
    data[200] ^= 0xFF  # inside policy.pth's compressed bytes: its CRC no longer matches
    (checkpoints / "sac_2000_steps.zip").write_bytes(bytes(data))
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_1000_steps.zip", 1000)
    assert capsys.readouterr().err.count("is torn") == 3


def test_every_checkpoint_torn_gives_none_and_says_so(tmp_path, capsys):
    directory = tmp_path / "checkpoints"
    _tear(_checkpoint(directory, 1000, buffer=False, stats=False))
    (directory / "sac_2000_steps.zip").write_bytes(b"")
    assert newest_checkpoint(directory) is None
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2 and all(line.endswith("no intact checkpoint is left") for line in lines)


def test_a_run_without_pickles_passes_over_a_torn_zip_only(tmp_path, capsys):
    """PPO without ``--normalize`` saves no pickle: none is missing, only the zip counts."""
    directory = tmp_path / "checkpoints"
    for steps in (1000, 2000):
        _checkpoint(directory, steps, buffer=False, stats=False)
    _tear(directory / "sac_2000_steps.zip")
    assert newest_checkpoint(directory) == (directory / "sac_1000_steps.zip", 1000)
    (line,) = capsys.readouterr().err.splitlines()
    assert "sac_2000_steps.zip is torn (not a complete zip archive)" in line
