"""``gymprecice benchmark`` on the test double: seeds trained and resumed, every held-out
start evaluated, baselines on the same starts, intervals, tables and figures; bad input
refused before anything trains; a failed seed re-run, never dropped."""

from __future__ import annotations

import csv
import json
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.spaces import Box, Discrete

from gymprecice.tools.cli import main
from gymprecice_lab import benchmark, benchmark_training
from gymprecice_lab.benchmarking.checks import (
    BenchmarkError,
    check_algorithm_fits,
    parse_algorithms,
)
from gymprecice_lab.benchmarking.stats import estimate, iqm
from gymprecice_lab.common.command_runs import CommandFailed, run_commands
from gymprecice_lab.common.manifest import file_sha256
from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_lab.rollouts.feedback import FeedbackController

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: two PPO seeds of 16 actions on the test double: what every tiny benchmark here trains
TINY_TRAINING = [
    "--double",
    "--seeds",
    "2",
    "--algo",
    "ppo",
    "--timesteps",
    "16",
    "--train-args",
    "--n-steps 8 --batch-size 8 --net 8,8 --vec-env dummy",
    "--bootstrap-reps",
    "200",
]
TINY = [
    "jet-cylinder-fast",
    *TINY_TRAINING,
    "--episode-time",
    "0.1",
    "--eval-time",
    "0.15",
    "--constants",
    "2",
    "--amplitudes",
    "1",
    "--frequencies",
    "3",
    "--feedback-gains=-1,1",
    "--feedback-delays",
    "0,3",
    # evaluations and baselines in two worker processes, as the docs' command runs them
    "--workers",
    "2",
]


#: one PPO seed: for what an env brings of its own (its objective, its feedback law); that
#: every seed is trained and evaluated from every start, the benchmark of ``bench`` shows
ONE_SEED_TRAINING = [*TINY_TRAINING]
ONE_SEED_TRAINING[ONE_SEED_TRAINING.index("--seeds") + 1] = "1"


def _no_training(argv: list[str]) -> int:
    raise AssertionError(f"nothing may train here, but train ran: {argv}")


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One benchmark whose seed 1 fails its first training attempt."""
    out = tmp_path_factory.mktemp("bench") / "run"
    real = benchmark_training._train_once
    calls: list[str] = []

    def flaky(argv: list[str]) -> int:
        seed = argv[argv.index("--seed") + 1]
        calls.append(seed)
        if seed == "1" and calls.count("1") == 1:
            raise RuntimeError("solver crashed (injected)")
        return real(argv)

    patch = pytest.MonkeyPatch()
    patch.setattr(benchmark_training, "_train_once", flaky)
    try:
        status = main(["benchmark", *TINY, "--out", str(out)])
    finally:
        patch.undo()
    return {"out": out, "status": status, "calls": calls}


@pytest.mark.timeout(600)
def test_every_seed_trains_with_its_manifest_and_a_failed_seed_is_run_again(bench) -> None:
    assert bench["status"] == 0
    # seed 1 failed once and was run again; nothing was dropped
    assert bench["calls"] == ["0", "1", "1"]
    for seed in (0, 1):
        manifest = json.loads((bench["out"] / f"train/ppo/seed_{seed}/manifest.json").read_text())
        assert manifest["seeds"]["seed"] == seed
        assert manifest["result"]["timesteps"] >= 16
    results = json.loads((bench["out"] / "results.json").read_text())
    ppo = next(c for c in results["controllers"] if c["label"] == "PPO")
    assert ppo["runs"] == 2
    assert np.asarray(ppo["metrics"]["objective"]["scores"]).shape == (2, 2)


def test_every_policy_is_evaluated_from_every_held_out_start(bench) -> None:
    results = json.loads((bench["out"] / "results.json").read_text())
    assert results["held_out_starts"] == ["t = 4.82 s", "t = 4.98 s"]
    for seed in (0, 1):
        summary = json.loads((bench["out"] / f"eval/ppo/seed_{seed}/summary.json").read_text())
        assert [e["start"] for e in summary["episodes"]] == [0, 1]
        assert [e["start_label"] for e in summary["episodes"]] == results["held_out_starts"]


def test_baselines_run_on_the_same_starts_and_the_best_of_each_kind_is_reported(bench) -> None:
    results = json.loads((bench["out"] / "results.json").read_text())
    kinds = [c["kind"] for c in results["controllers"]]
    assert kinds == ["learned", "uncontrolled", "constant", "sinusoid", "feedback"]
    sweep = json.loads((bench["out"] / "baselines/sweep.json").read_text())
    feedback = [r for r in sweep["controllers"] if r["kind"] == "feedback"]
    assert len(feedback) == 4  # gains x delays
    best = min(feedback, key=lambda r: r["mean"])
    entry = results["controllers"][-1]
    assert entry["label"] == f"best feedback: {best['label']}"
    assert entry["metrics"]["objective"]["mean"]["value"] == pytest.approx(best["mean"])
    for c in results["controllers"][1:]:
        assert c["runs"] == 1 and len(c["metrics"]["objective"]["scores"][0]) == 2


def test_intervals_contain_their_estimate_and_the_tables_agree(bench) -> None:
    results = json.loads((bench["out"] / "results.json").read_text())
    with (bench["out"] / "results.csv").open() as handle:
        rows = {r["controller"]: r for r in csv.DictReader(handle)}
    markdown = (bench["out"] / "results.md").read_text()
    for c in results["controllers"]:
        for metric, stats in c["metrics"].items():
            scores = np.asarray(stats["scores"])
            assert stats["mean"]["value"] == pytest.approx(scores.mean())
            assert stats["iqm"]["value"] == pytest.approx(float(iqm(scores.reshape(-1))))
            assert stats["median"]["value"] == pytest.approx(float(np.median(scores)))
            for s in ("mean", "median", "iqm"):
                assert stats[s]["low"] <= stats[s]["value"] <= stats[s]["high"]
                assert float(rows[c["label"]][f"{metric}_{s}"]) == pytest.approx(stats[s]["value"])
        assert f"| {c['label']} | {c['kind']} | {c['runs']} |" in markdown
    assert float(rows["PPO"]["mean_Cd_iqm"]) > 0  # the cylinders' mean Cd, beside the objective
    # the fraction of the drag floor that every controller reaches, from the same drag
    floor = find_lab_env("jet-cylinder-fast").reference
    for c in results["controllers"]:
        fraction, cd = c["metrics"]["floor_fraction"], c["metrics"]["mean_Cd"]
        assert np.asarray(fraction["scores"]) == pytest.approx(
            (floor.uncontrolled - np.asarray(cd["scores"])) / (floor.uncontrolled - floor.floor)
        )
    assert (
        "## floor_fraction" in markdown
        and "| controller | kind | runs | mean | median | iqm |" in markdown
    )


def test_figures_are_written(bench) -> None:
    for name in ("return_wallclock.png", "objective_per_start.png"):
        assert (bench["out"] / name).read_bytes().startswith(PNG_SIGNATURE)


def test_the_flap_is_benchmarked_on_its_own_objective(tmp_path) -> None:
    """An env without a drag floor or a feedback law: its seed from each of its three
    held-out gusts, scored by the flap's mean tip displacement, against the open-loop
    baselines."""
    env, objective, starts = "perpendicular-flap-fast", "mean_tip_displacement", 3
    out = tmp_path / "run"
    argv = [
        env,
        *ONE_SEED_TRAINING,
        "--constants",
        "1",  # one of each kind: choosing the best of a kind, the benchmark of bench shows
        "--amplitudes",
        "1",
        "--frequencies",
        "0.5",
        "--centre",
        "0.875",  # where the flap's best open loop swings
        "--feedback-gains=",
    ]
    assert main(["benchmark", *argv, "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert len(results["held_out_starts"]) == starts
    assert [c["kind"] for c in results["controllers"]] == [
        "learned",
        "uncontrolled",
        "constant",
        "sinusoid",
    ]
    ppo = results["controllers"][0]
    assert np.asarray(ppo["metrics"]["objective"]["scores"]).shape == (1, starts)
    assert "floor_fraction" not in ppo["metrics"]  # no drag floor off the cylinders
    summary = json.loads((out / "eval/ppo/seed_0/summary.json").read_text())
    assert [e["start"] for e in summary["episodes"]] == list(range(starts))
    assert ppo["metrics"]["objective"]["scores"][0] == pytest.approx(
        [e[f"mean_{objective}"] for e in summary["episodes"]]
    )
    assert objective in (out / "results.md").read_text()
    sweep = json.loads((out / "baselines" / "manifest.json").read_text())
    assert sweep["settings"]["centre"] == 0.875
    assert results["controllers"][3]["label"].startswith("best sinusoid: sine-c0.875-")


@pytest.mark.slow
def test_a_shared_policy_is_benchmarked_on_the_two_flaps_joint_env(tmp_path) -> None:
    """``--train-args "--shared-policy"``: every seed trains one policy both flaps share
    (a step per agent), is evaluated on both rows of the joint env from the three held-out
    gusts, and is named as a shared policy in the table."""
    out = tmp_path / "run"
    training = [*ONE_SEED_TRAINING]
    training[training.index("--timesteps") + 1] = "60"  # one 30-action episode, two agents
    training[training.index("--train-args") + 1] = (
        "--shared-policy --n-steps 30 --batch-size 30 --n-epochs 1 --net 8,8 --vec-env dummy"
    )
    argv = ["two-flaps-fast", *training, "--no-baselines"]
    assert main(["benchmark", *argv, "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    (learned,) = results["controllers"]
    assert learned["label"] == "PPO, shared policy"
    assert np.asarray(learned["metrics"]["objective"]["scores"]).shape == (1, 3)
    manifest = json.loads((out / "train/ppo/seed_0/manifest.json").read_text())
    assert manifest["settings"]["hyperparams"]["shared_policy"] is True
    assert manifest["result"]["timesteps"] == 60
    summary = json.loads((out / "eval/ppo/seed_0/summary.json").read_text())
    assert [e["start"] for e in summary["episodes"]] == [0, 1, 2]
    assert "PPO, shared policy" in (out / "results.md").read_text()


def test_the_heated_plate_is_benchmarked_against_its_own_feedback_law(tmp_path) -> None:
    """An env that names its classical feedback (the plate's PID heater): the baselines'
    feedback is the best point of that law's grid, recorded in benchmark.json, run on the
    same held-out starts as every policy."""
    out = tmp_path / "run"
    argv = [
        "heated-plate-fast",
        *ONE_SEED_TRAINING,
        "--constants",
        "1",
        "--amplitudes",
        "0.5",
        "--frequencies",
        "0.5",
        "--feedback-grid",
        "kp=3;ki=25,50;kd=1",
    ]
    assert main(["benchmark", *argv, "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    kinds = [c["kind"] for c in results["controllers"]]
    assert kinds == ["learned", "uncontrolled", "constant", "sinusoid", "feedback"]
    pid = results["controllers"][4]
    assert pid["label"].startswith("best feedback: feedback-pid-kp3-ki")
    assert np.asarray(pid["metrics"]["objective"]["scores"]).shape == (1, 3)
    uncontrolled = results["controllers"][1]["metrics"]["objective"]["mean"]["value"]
    assert pid["metrics"]["objective"]["mean"]["value"] < uncontrolled
    settings = json.loads((out / "benchmark.json").read_text())["baselines"]
    assert settings["feedback_grid"] == "kp=3;ki=25,50;kd=1"
    assert settings["feedback_gains"] == ""
    sweep = json.loads((out / "baselines" / "sweep.json").read_text())
    assert [r["label"] for r in sweep["controllers"] if r["kind"] == "feedback"] == [
        "feedback-pid-kp3-ki25-kd1",
        "feedback-pid-kp3-ki50-kd1",
    ]


@pytest.mark.parametrize(
    ("env", "flag", "message"),
    [
        ("heated-plate-fast", "--feedback-gains=1", "tune it with --feedback-grid"),
        ("heated-plate-fast", "--feedback-grid=kp=x", "kp= needs comma-separated finite"),
        ("jet-cylinder-fast", "--feedback-grid=kp=1", "has no feedback law of its own"),
    ],
)
def test_the_other_kinds_feedback_options_are_refused_before_training(
    tmp_path, monkeypatch, capsys, env, flag, message
) -> None:
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", env, "--double", flag, "--out", str(tmp_path / "b")])
    assert message in capsys.readouterr().err + str(exc.value.code)
    assert not (tmp_path / "b").exists()


def test_a_resumed_benchmark_keeps_finished_seeds(bench, monkeypatch, capsys) -> None:
    before = (bench["out"] / "results.json").read_text()
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    assert main(["benchmark", *TINY, "--out", str(bench["out"])]) == 0
    assert "ppo seed 1: trained already, kept" in capsys.readouterr().out
    assert json.loads((bench["out"] / "results.json").read_text()) == json.loads(before)


def test_a_benchmark_written_before_the_sinusoids_had_a_centre_resumes(
    bench, tmp_path, monkeypatch, capsys
) -> None:
    import shutil

    out = tmp_path / "run"
    shutil.copytree(bench["out"], out)
    settings = json.loads((out / "benchmark.json").read_text())
    del settings["baselines"]["centre"]
    (out / "benchmark.json").write_text(json.dumps(settings))
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    assert main(["benchmark", *TINY, "--out", str(out)]) == 0
    assert json.loads((out / "benchmark.json").read_text())["baselines"]["centre"] == 0.5
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *TINY, "--centre", "0.875", "--out", str(out)])
    assert '"centre": 0.875' in capsys.readouterr().err and exc.value.code == 2


def test_a_resumed_benchmark_with_other_settings_is_refused(bench, monkeypatch, capsys) -> None:
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    changed = [*TINY, "--out", str(bench["out"])]
    changed[changed.index("--timesteps") + 1] = "32"
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *changed])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "cannot resume" in err and "timesteps is 32 now but 16" in err and "--fresh" in err


def _with_algorithms(algos: str, ppo_args: str, sac_args: str) -> list[str]:
    argv = [*TINY]
    argv[argv.index("--algo") + 1] = algos
    argv[argv.index("--train-args") + 1] = f"ppo: {ppo_args}"
    return [*argv, "--train-args", f"sac: {sac_args}"]


def test_an_algorithm_added_to_a_benchmark_trains_alone_and_joins_the_table(
    bench, tmp_path, monkeypatch, capsys
) -> None:
    import shutil

    out = tmp_path / "run"
    shutil.copytree(bench["out"], out)
    real, trained = benchmark_training._train_once, []

    def recording(argv: list[str]) -> int:
        trained.append((argv[argv.index("--algo") + 1], argv[argv.index("--seed") + 1]))
        return real(argv)

    monkeypatch.setattr(benchmark_training, "_train_once", recording)
    ppo_args = TINY[TINY.index("--train-args") + 1]
    sac_args = "--net 8,8 --vec-env dummy"
    added = _with_algorithms("ppo,sac", ppo_args, sac_args)
    assert main(["benchmark", *added, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "adding SAC; what PPO finished is kept" in said
    assert trained == [("sac", "0"), ("sac", "1")]  # PPO's seeds are not trained again
    labels = [c["label"] for c in json.loads((out / "results.json").read_text())["controllers"]]
    assert labels[:2] == ["PPO", "SAC"] and labels[2] == "uncontrolled"
    assert json.loads((out / "benchmark.json").read_text())["algos"] == ["ppo", "sac"]

    # the algorithm already there may not change on the way
    changed = _with_algorithms("ppo,sac", ppo_args.replace("8,8", "16,16"), sac_args)
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *changed, "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "cannot resume" in err and "train_args is" in err and "16,16" in err


def test_seeds_added_to_a_benchmark_train_alone_and_join_the_table(
    bench, tmp_path, monkeypatch, capsys
) -> None:
    """``--seeds 3`` on a benchmark of two: seed 2 trains, seeds 0 and 1 and the baselines
    are kept; fewer seeds than were run is another setting, refused."""
    import shutil

    out = tmp_path / "run"
    shutil.copytree(bench["out"], out)
    real, trained = benchmark_training._train_once, []

    def recording(argv: list[str]) -> int:
        trained.append(argv[argv.index("--seed") + 1])
        return real(argv)

    monkeypatch.setattr(benchmark_training, "_train_once", recording)
    more = [*TINY]
    more[more.index("--seeds") + 1] = "3"
    assert main(["benchmark", *more, "--out", str(out)]) == 0
    assert "adding seed(s) 2; what seed(s) 0, 1 finished is kept" in capsys.readouterr().out
    assert trained == ["2"]
    learned = json.loads((out / "results.json").read_text())["controllers"][0]
    assert learned["runs"] == 3
    assert json.loads((out / "benchmark.json").read_text())["seeds"] == [0, 1, 2]

    fewer = [*TINY]
    fewer[fewer.index("--seeds") + 1] = "1"
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *fewer, "--out", str(out)])
    assert exc.value.code == 2
    assert "cannot resume" in capsys.readouterr().err


def test_a_seed_that_keeps_failing_stops_the_benchmark_without_a_table(
    tmp_path, monkeypatch, capsys
) -> None:
    def broken(argv: list[str]) -> int:
        raise RuntimeError("solver crashed (injected)")

    monkeypatch.setattr(benchmark_training, "_train_once", broken)
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *TINY, "--retries", "2", "--out", str(tmp_path / "b")])
    assert exc.value.code == 1
    err = capsys.readouterr().err
    assert err.count("ppo seed 0: training failed") == 4  # 3 reports, then the verdict
    assert "no table is written" in err
    assert not (tmp_path / "b/results.md").exists()
    failures = json.loads((tmp_path / "b/train/ppo/seed_0/benchmark-failures.json").read_text())
    assert len(failures) == 3


# -- bad input, refused before anything trains ------------------------------------------------


@pytest.mark.timeout(600)
def test_zero_seeds_run_the_classical_baselines_alone(tmp_path, monkeypatch, capsys) -> None:
    """``--seeds 0``: the classical baselines on the held-out starts, in the same results
    files as a whole benchmark, with nothing trained."""
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    out = tmp_path / "run"
    argv = ["heated-plate-fast", "--double", "--seeds", "0", "--bootstrap-reps", "200"]
    argv += ["--constants", "1", "--amplitudes", "0.5", "--frequencies", "0.5"]
    assert main(["benchmark", *argv, "--feedback-grid", "kp=3;ki=25;kd=1", "--out", str(out)]) == 0
    assert "the classical baselines alone from 3 held-out start" in capsys.readouterr().out
    results = json.loads((out / "results.json").read_text())
    kinds = [c["kind"] for c in results["controllers"]]
    assert kinds == ["uncontrolled", "constant", "sinusoid", "feedback"]
    for controller in results["controllers"]:
        assert np.asarray(controller["metrics"]["objective"]["scores"]).shape == (1, 3)
    assert (out / "objective_per_start.png").read_bytes().startswith(PNG_SIGNATURE)
    assert not (out / "train").exists() and not (out / "return_wallclock.png").exists()


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--seeds", "-1"], "--seeds: must be at least 0, got -1"),
        (["--seeds", "0", "--no-baselines"], "--seeds 0 --no-baselines leaves nothing to run"),
        (["--seeds", "0", "--train-args", "--net 8,8"], "--train-args would be ignored"),
    ],
)
def test_nothing_to_run_is_refused(tmp_path, capsys, flags, message) -> None:
    out = tmp_path / "b"
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", "jet-cylinder-fast", "--double", *flags, "--out", str(out)])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err + str(exc.value.code)
    assert not out.exists()


class _Planned(Exception):
    """Raised where the benchmark would start training: the plan was made."""


def test_an_env_without_held_out_starts_is_benchmarked_from_seeds(tmp_path, monkeypatch) -> None:
    """quickstart names no held-out starts: its starts are the seeds that stand for them
    (the lab card's default), recorded in benchmark.json before anything trains."""

    def planned(args, plan) -> None:
        raise _Planned(plan.starts)

    monkeypatch.setattr(benchmark, "_train_seeds", planned)
    with pytest.raises(_Planned) as exc:
        main(["benchmark", "quickstart", "--double", "--out", str(tmp_path / "b")])
    seeds = [f"seed {k}" for k in range(5)]
    assert exc.value.args[0] == seeds
    settings = json.loads((tmp_path / "b" / "benchmark.json").read_text())
    assert settings["held_out_starts"] == seeds
    assert not (tmp_path / "b/train").exists()


def test_evaluate_all_starts_on_an_env_without_them_runs_its_seeds(tmp_path, capsys) -> None:
    argv = ["baseline", "quickstart", "--double", "--all-starts", "--episode-time", "0.05"]
    assert main([*argv, "--seed", "3", "--out", str(tmp_path / "b")]) == 0
    assert "quickstart has no held-out starts; its starts are seed 3 to seed 7" in (
        capsys.readouterr().out
    )
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert [e["start_label"] for e in summary["episodes"]] == [f"seed {k}" for k in range(3, 8)]


@pytest.mark.parametrize(
    ("algo", "space", "message"),
    [
        ("sac", Discrete(3), "SAC acts only in a continuous Box"),
        ("td3", Box(-np.inf, np.inf, (1,)), "unbounded"),
        ("tqc", Discrete(3), "TQC acts only in a continuous Box"),
    ],
)
def test_an_algorithm_that_does_not_fit_the_action_space_is_refused(
    algo, space, message, capsys
) -> None:
    with pytest.raises(BenchmarkError):
        check_algorithm_fits(algo, space)
    assert message in capsys.readouterr().err


def test_an_algorithm_that_fits_passes() -> None:
    for algo in ("ppo", "sac", "td3", "tqc"):
        check_algorithm_fits(algo, Box(-1.0, 1.0, (1,)))
    check_algorithm_fits("ppo", Discrete(3))


def test_an_unknown_algorithm_is_refused_naming_the_choices(capsys) -> None:
    with pytest.raises(BenchmarkError):
        parse_algorithms("ppo,dqn")
    assert "unknown dqn; choose from ppo, sac, td3, tqc" in capsys.readouterr().err


def test_a_training_flag_the_algorithm_lacks_is_refused_before_training(
    tmp_path, monkeypatch
) -> None:
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    argv = ["benchmark", "jet-cylinder-fast", "--double", "--algo", "ppo,sac"]
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--train-args", "--n-steps 8", "--out", str(tmp_path / "b")])
    assert "--n-steps is a PPO setting; SAC has none" in str(exc.value.code)
    assert not (tmp_path / "b/train").exists()


@pytest.mark.parametrize(
    ("flag", "message"),
    [
        ("--frequencies=0,3", "--frequencies must be positive"),
        ("--feedback-delays=1.5", "--feedback-delays are whole numbers"),
        ("--amplitudes=x", "--amplitudes takes comma-separated numbers"),
        ("--centre=1.5", "--centre is a fraction of the action box, 0 to 1; got 1.5"),
    ],
)
def test_a_bad_baseline_grid_is_refused_before_training(
    tmp_path, monkeypatch, capsys, flag, message
) -> None:
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", "jet-cylinder-fast", "--double", flag, "--out", str(tmp_path / "b")])
    assert message in capsys.readouterr().err + str(exc.value.code)
    assert not (tmp_path / "b/train").exists()


# -- the statistics and the feedback law ------------------------------------------------------


def test_the_bootstrap_is_stratified_by_start() -> None:
    # start 0 scores about 0, start 1 about 10: resampling seeds within each start keeps
    # one of each in every resample, so the mean never strays far from 5
    rng = np.random.default_rng(0)
    scores = np.column_stack([rng.normal(0, 0.1, 5), rng.normal(10, 0.1, 5)])
    for statistic in ("mean", "iqm"):
        e = estimate(scores, statistic, reps=500)
        assert 4.8 < e.low <= e.value <= e.high < 5.2


def test_a_controller_run_once_has_no_interval_and_nan_is_refused() -> None:
    e = estimate(np.array([[1.0, 2.0, 3.0]]), "mean")
    assert (e.value, e.low, e.high, e.runs) == (2.0, 2.0, 2.0, 1)
    with pytest.raises(ValueError, match="NaN"):
        estimate(np.array([[1.0, np.nan], [1.0, 2.0]]), "iqm")


def test_iqm_is_the_mean_of_the_middle_half() -> None:
    assert float(iqm(np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 100.0]))) == pytest.approx(3.5)


def test_feedback_acts_on_the_signal_of_delay_actions_ago() -> None:
    law = FeedbackController(Box(-2.0, 2.0, (1,)), "Cl", gain=0.5, delay=2)
    actions = []
    for cl in (1.0, -1.0, 4.0, 0.0):
        actions.append(float(law(None, 0.0)[0]))
        law.observe({"metrics": {"Cl": cl}})
    # delay 0 would feed back the last action's Cl; delay 2 the one two actions before:
    # nothing measured that long ago for the first three actions, then -0.5 * 2 * Cl
    assert actions == pytest.approx([0.0, 0.0, 0.0, -1.0])
    assert float(law(None, 0.0)[0]) == pytest.approx(1.0)  # Cl = -1 two actions back
    law.observe({"metrics": {"Cl": 0.0}})
    assert float(law(None, 0.0)[0]) == pytest.approx(-2.0)  # Cl = 4: -4 clipped to the bound
    law.reset()
    assert float(law(None, 0.0)[0]) == 0.0


def test_feedback_refuses_a_signal_the_env_does_not_report() -> None:
    law = FeedbackController(Box(-1.0, 1.0, (1,)), "lift", gain=1.0)
    with pytest.raises(KeyError, match=r"'lift' is not among this env's metrics \(Cd, Cl\)"):
        law.observe({"metrics": {"Cd": 3.0, "Cl": 0.1}})
    with pytest.raises(TypeError, match="bounded Box"):
        FeedbackController(Discrete(2), "Cl", gain=1.0)


# -- held-out starts ---------------------------------------------------------------------------


@pytest.mark.parametrize("double", [False, True])
def test_the_fast_cylinders_hold_out_every_fourth_snapshot(tmp_path, double) -> None:
    from gymprecice_tutorials.fast_cases import JetCylinderFastEnv

    env = JetCylinderFastEnv(run_root=tmp_path, double=double)
    try:
        assert env.held_out_starts == ("t = 4.82 s", "t = 4.98 s")
    finally:
        env.close()


def test_an_openfoam_case_with_an_explicit_split_holds_out_its_eval_snapshots(tmp_path) -> None:
    from gymprecice_tutorials.fast_cases import RotatingCylinderFastEnv

    env = RotatingCylinderFastEnv(run_root=tmp_path)
    try:
        env.config.solvers[env.fluid].options["snapshots"] = {"train": [4.7], "eval": [4.9, 4.8]}
        assert env.held_out_starts == ("t = 4.8 s", "t = 4.9 s")
    finally:
        env.close()


def test_the_quickstart_has_no_held_out_starts(tmp_path) -> None:
    from gymprecice_tutorials.quickstart.environment import QuickstartEnv

    env = QuickstartEnv(run_root=tmp_path, double=True)
    try:
        assert env.held_out_starts == ()
    finally:
        env.close()


class _Starts(gym.Env):
    """An env with two held-out starts that records the options of every reset."""

    observation_space = Box(-1.0, 1.0, (1,))
    action_space = Box(-1.0, 1.0, (1,))
    held_out_starts = ("a", "b")

    def __init__(self) -> None:
        self.options: list[dict] = []

    def reset(self, *, seed=None, options=None):
        self.options.append(dict(options or {}))
        return np.zeros(1, np.float32), {}


def test_the_eval_freq_env_takes_the_held_out_starts_in_turn() -> None:
    from gymprecice_lab.common.starts import HeldOutStarts

    inner = _Starts()
    env = HeldOutStarts(inner)
    for _ in range(3):
        env.reset()  # what SB3's EvalCallback does: no options
    env.reset(options={"split": "train"})  # a caller's options win
    assert [o.get("start") for o in inner.options] == [0, 1, 0, 1]
    assert [o["split"] for o in inner.options] == ["eval", "eval", "eval", "train"]


def test_evaluations_npz_survives_a_resume(tmp_path) -> None:
    from types import SimpleNamespace

    from gymprecice_lab.training.validation import _keep_evaluations

    path = tmp_path / "evaluations.npz"
    np.savez(
        path, timesteps=[40, 80], results=[[1.0, 2.0], [3.0, 4.0]], ep_lengths=[[5, 5], [5, 5]]
    )
    callback = SimpleNamespace(
        evaluations_timesteps=[], evaluations_results=[], evaluations_length=[]
    )
    _keep_evaluations(callback, path)  # type: ignore[arg-type]
    assert callback.evaluations_timesteps == [40, 80]
    assert callback.evaluations_results == [[1.0, 2.0], [3.0, 4.0]]
    assert callback.evaluations_length == [[5, 5], [5, 5]]


@pytest.mark.timeout(300)
def test_commands_failing_in_worker_processes_are_all_reported_not_waited_for(
    tmp_path, capsys
) -> None:
    missing = [
        (
            [
                *("evaluate", "jet-cylinder-fast", "--double"),
                *("--policy", str(tmp_path / f"no-{k}"), "--out", str(tmp_path / f"eval-{k}")),
            ],
            f"evaluating seed {k}",
        )
        for k in range(3)
    ]
    with pytest.raises(CommandFailed) as exc:
        run_commands(missing, 2)
    assert exc.value.code == 1
    message = capsys.readouterr().err
    assert all(f"evaluating seed {k}: exit status 1" in message for k in range(3))
    assert "run the same command again" in message


# -- --ray: a real Ray cluster on this machine ------------------------------------------------


@pytest.mark.timeout(600)
def test_with_ray_every_seed_trains_evaluates_and_the_sweep_runs_on_the_cluster(
    ray_cluster, tmp_path, capsys, monkeypatch
) -> None:
    out, nodes = tmp_path / "bench", tmp_path / "nodes"
    monkeypatch.setenv("GYMPRECICE_NODE_DIR", str(nodes))  # where actors and tasks work
    address = ray_cluster.address
    assert main(["benchmark", *TINY, "--ray", address, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert (
        f"training 2 seed(s) at once, their envs as Ray actors on the cluster at {address}" in said
    )
    workers = {node.node_id for node in ray_cluster.worker_nodes}
    for seed in range(2):
        train, run = out / "train" / "ppo" / f"seed_{seed}", out / "eval" / "ppo" / f"seed_{seed}"
        assert (train / "model.zip").is_file()
        assert f"evaluating ppo seed {seed}: done on" in said
        # evaluated on a worker node (the head has no CPU), its output brought back here
        # with the paths of this machine, the env runs left behind but their logs kept
        remote = json.loads((run / "remote.json").read_text())
        assert remote["node_id"] in workers and remote["status"] == 0
        summary = json.loads((run / "summary.json").read_text())
        assert len(summary["episodes"]) == 2
        manifest = (run / "manifest.json").read_text()
        assert str(train) in manifest and "gymprecice-command-" not in manifest
        # the kept model's evaluation is the kept model's, the final one's the final's
        for which, model in (("eval", "best_model.zip"), ("eval-final", "model.zip")):
            recorded = json.loads(
                (out / which / "ppo" / f"seed_{seed}" / "manifest.json").read_text()
            )
            assert recorded["settings"]["model_sha256"] == file_sha256(train / model), which
        kept = [p for p in (run / "envs").rglob("*") if p.is_file()]
        assert kept and all(p.name.startswith("log.") or p.suffix == ".log" for p in kept)
    sweep = json.loads((out / "baselines" / "remote.json").read_text())
    assert sweep["node_id"] in workers and (out / "baselines" / "sweep.json").is_file()
    rows = json.loads((out / "results.json").read_text())["controllers"]
    assert [c["label"] for c in rows][:2] == ["PPO", "uncontrolled"]
    # one env per seed, each an actor that worked in its node directory; every task's
    # scratch directory is gone
    actors = sorted(p.name.split("-")[0] for p in (nodes / "gymprecice-ray").iterdir())
    assert actors == ["env_0", "env_0"]
    assert not list(nodes.glob("gymprecice-command-*"))

    # a rerun keeps everything: nothing trains, nothing is sent to the cluster again
    monkeypatch.setattr(benchmark_training, "_train_once", _no_training)
    assert main(["benchmark", *TINY, "--ray", address, "--out", str(out)]) == 0
    assert "done on" not in capsys.readouterr().out


def test_with_ray_a_sweep_no_node_can_hold_is_refused_before_training(
    ray_cluster, tmp_path, capsys
) -> None:
    out = tmp_path / "bench"
    argv = ["benchmark", *TINY, "--workers", "3", "--ray", ray_cluster.address]
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--out", str(out)])
    assert exc.value.code == 2
    assert (
        "the baselines' sweep (--workers 3) needs 3 CPUs on one node, but the cluster's "
        "largest node has 2" in capsys.readouterr().err
    )
    assert not (out / "train").exists()


def test_with_ray_a_cluster_that_does_not_answer_is_refused_before_training(
    tmp_path, capsys
) -> None:
    pytest.importorskip("ray", reason="benchmark --ray needs gymprecice-core[ray]")
    out = tmp_path / "bench"
    with pytest.raises(SystemExit) as exc:
        main(["benchmark", *TINY, "--ray", "127.0.0.1:1", "--out", str(out)])
    assert exc.value.code == 2
    assert "--ray 127.0.0.1:1: no Ray cluster answers there" in capsys.readouterr().err
    assert not (out / "train").exists()
