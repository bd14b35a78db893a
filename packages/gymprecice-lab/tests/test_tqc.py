"""sb3-contrib's TQC beside SB3's algorithms: trained, overlapped, resumed, evaluated, tuned.

TQC (Truncated Quantile Critics) is SAC with distributional critics whose top quantiles
are dropped against the critics' overestimation; ``--algo tqc`` takes it wherever
``--algo sac`` goes. On the test double, seconds.
"""

from __future__ import annotations

import json

import optuna

from gymprecice_lab.common.wrapped_env import load_model
from gymprecice_lab.training.tune_spaces import DEFAULTS, sample, space_names


def _train(tmp_path, *extra):
    from gymprecice.tools.cli import main

    (tmp_path / "tqc.yml").write_text(
        "gymprecice/Quickstart-v0:\n  learning_starts: 4\n  batch_size: 8\n  net: [16, 16]\n"
        "  top_quantiles_to_drop_per_net: 1\n  overlap_updates: true\n  torch_threads: 1\n"
    )
    return main(
        [
            "train",
            "quickstart",
            "--double",
            "--episode-time",
            "0.1",
            "--algo",
            "tqc",
            "--hyperparams",
            str(tmp_path / "tqc.yml"),
            "--checkpoint-every",
            "8",
            "--vec-env",
            "dummy",
            "--no-progress-bar",
            "--out",
            str(tmp_path / "run"),
            *extra,
        ]
    )


def test_tqc_trains_overlapped_resumes_and_loads_as_tqc(tmp_path):
    from sb3_contrib import TQC

    assert _train(tmp_path, "--timesteps", "16") == 0
    model = load_model(tmp_path / "run" / "model.zip")
    assert isinstance(model, TQC) and model.top_quantiles_to_drop_per_net == 1
    assert (tmp_path / "run" / "checkpoints" / "tqc_replay_buffer_16_steps.pkl").is_file()
    assert _train(tmp_path, "--timesteps", "24") == 0  # resumes from 16 with its buffer
    assert load_model(tmp_path / "run" / "model.zip").num_timesteps == 24
    kept = json.loads((tmp_path / "run" / "eval" / "best.json").read_text())
    assert kept["timesteps"] in (8, 16, 24)


def test_tqc_searches_sacs_space_and_the_quantiles_it_drops():
    assert space_names("tqc") == (*space_names("sac"), "top_quantiles_to_drop_per_net")
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    params = sample(study.ask(), "tqc", 1000, 2, {}, None)
    assert params["top_quantiles_to_drop_per_net"] in (0, 1, 2, 3, 5)
    kept = sample(study.ask(), "tqc", 1000, 2, {}, ["learning_rate"])
    assert kept["top_quantiles_to_drop_per_net"] == DEFAULTS["tqc"]["top_quantiles_to_drop_per_net"]
