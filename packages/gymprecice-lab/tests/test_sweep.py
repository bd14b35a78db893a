"""``gymprecice sweep`` on the test double: every controller on every held-out start, the
table, the best of each kind and the figure; bad grids are refused before anything runs."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gymnasium.spaces import Box

from gymprecice.plugin.card import CardError, load_object
from gymprecice.tools.cli import main
from gymprecice_lab import evaluate
from gymprecice_lab.rollouts.sweep import SweepResult, best, constant_controller, parse_grid
from gymprecice_tutorials.heated_plate.pid import PID_LAW

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", "sweep", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.timeout(300)
def test_sweep_runs_every_controller_on_every_start_and_names_the_best(tmp_path: Path) -> None:
    proc = _cli(
        tmp_path,
        "quickstart",
        "--double",
        "--episode-time",
        "0.1",
        "--constants",
        "3",
        "--amplitudes",
        "0.5,1",
        "--frequencies",
        "3",
        "--episodes",
        "2",
        "--out",
        "sweep",
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = tmp_path / "sweep"
    with (out / "sweep.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [r["kind"] for r in rows] == ["uncontrolled"] + ["constant"] * 3 + ["sinusoid"] * 2
    assert [float(r["action"]) for r in rows if r["kind"] == "constant"] == pytest.approx(
        [-2.5e-4, 0.0, 2.5e-4]
    )
    for row in rows:
        starts = [float(row["start_0"]), float(row["start_1"])]
        assert float(row["mean"]) == pytest.approx(np.mean(starts))
        assert float(row["spread"]) == pytest.approx(max(starts) - min(starts))
        assert (out / row["label"] / "history.csv").is_file()
    summary = json.loads((out / "sweep.json").read_text())
    constants = [r for r in rows if r["kind"] == "constant"]
    assert (
        summary["best_constant"]["label"] == min(constants, key=lambda r: float(r["mean"]))["label"]
    )
    assert summary["best_sinusoid"]["kind"] == "sinusoid"
    assert (out / "sweep.png").read_bytes().startswith(PNG_SIGNATURE)
    assert "best constant" in proc.stdout and "best sinusoid" in proc.stdout


@pytest.mark.timeout(300)
def test_an_env_with_a_feedback_law_of_its_own_is_tuned_over_that_laws_grid(
    tmp_path: Path,
) -> None:
    """The heated plate's classical feedback is a PID heater, not a signal fed back: the
    sweep runs every point of ``--feedback-grid`` on the held-out starts, and the tuned
    PID tracks the setpoint far better than the uncontrolled plate or any open loop."""
    proc = _cli(
        tmp_path,
        "heated-plate",
        "--double",
        "--constants",
        "2",
        "--amplitudes",
        "0.5",
        "--frequencies",
        "0.5",
        "--feedback-grid",
        "kp=3;ki=25,50",
        "--out",
        "sweep",
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = tmp_path / "sweep"
    with (out / "sweep.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    pid = [r for r in rows if r["kind"] == "feedback"]
    # kd keeps the law's documented values (0 and 1)
    assert [r["label"] for r in pid] == [
        "feedback-pid-kp3-ki25-kd0",
        "feedback-pid-kp3-ki25-kd1",
        "feedback-pid-kp3-ki50-kd0",
        "feedback-pid-kp3-ki50-kd1",
    ]
    assert [(float(r["kp"]), float(r["ki"]), float(r["kd"])) for r in pid][1] == (3, 25, 1)
    summary = json.loads((out / "sweep.json").read_text())
    best_pid = summary["best_feedback"]
    assert best_pid["label"] == min(pid, key=lambda r: float(r["mean"]))["label"]
    others = [r for r in rows if r["kind"] != "feedback"]
    assert best_pid["mean"] < 0.5 * min(float(r["mean"]) for r in others), rows
    manifest = json.loads((out / "manifest.json").read_text())["settings"]
    assert manifest["feedback_law"] == "gymprecice_tutorials.heated_plate.pid:PID_LAW"
    assert len(manifest["feedback_grid"]) == 4
    # the best point, run alone by `gymprecice feedback --law`, scores what the sweep says
    point = {k: best_pid[k] for k in ("kp", "ki", "kd")}
    law = ";".join(f"{k}={v:g}" for k, v in point.items())
    command = ["feedback", "heated-plate", "--double", "--law", law, "--all-starts"]
    alone = subprocess.run(
        [sys.executable, "-m", "gymprecice", *command, "--episodes", "3", "--out", "alone"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert alone.returncode == 0, alone.stdout + alone.stderr
    summary = json.loads((tmp_path / "alone" / "summary.json").read_text())
    errors = [e["mean_tracking_error"] for e in summary["episodes"]]
    # within 0.1 % (a fresh env's first episode differs from the sweep's reused env in the
    # fifth digit); the grid's neighbours differ by several per cent
    assert errors == pytest.approx([best_pid[f"start_{i}"] for i in range(3)], rel=1e-3)
    settings = json.loads((tmp_path / "alone" / "manifest.json").read_text())["settings"]
    assert {k: settings[k] for k in point} == point


@pytest.mark.timeout(300)
def test_a_sweep_on_the_validation_starts_tunes_without_a_held_out_start(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """``--starts validation``: every controller from the env's validation starts (those
    that choose a trained model), none from a held-out one; ``--amplitudes=``: no
    sinusoids. Such a sweep says so, and ``compare`` refuses it beside held-out runs.
    Cost: about 10 s (2 controllers x 3 episodes on the lumped-plate double)."""
    from gymprecice_tutorials.heated_plate.environment import HeatedPlateEnv

    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "heated-plate", "--double", "--starts", "validation", "--constants", "0"]
    argv += ["--amplitudes=", "--feedback-grid=kp=3;ki=50;kd=1", "--out", "tune"]
    assert main(argv) == 0, capsys.readouterr()
    assert "2 controller(s) x 3 validation start(s)" in capsys.readouterr().out
    out = tmp_path / "tune"
    env = HeatedPlateEnv(double=True, run_root=tmp_path / "probe")
    try:
        validation, held_out = env.validation_starts, env.held_out_starts
    finally:
        env.close()
    for label in ("uncontrolled", "feedback-pid-kp3-ki50-kd1"):
        episodes = json.loads((out / label / "summary.json").read_text())["episodes"]
        assert [e["start_label"] for e in episodes] == list(validation)
        assert not {e["start_label"] for e in episodes} & set(held_out)
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["starts"] == "validation"
    assert [r["kind"] for r in summary["controllers"]] == ["uncontrolled", "feedback"]
    assert json.loads((out / "manifest.json").read_text())["settings"]["starts"] == "validation"
    with pytest.raises(SystemExit, match="ran on the env's validation starts"):
        main(["compare", "tune"])


def test_a_sweep_on_the_validation_starts_runs_each_of_them_once(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """The jet cylinder has two validation starts: without ``--episodes`` each runs once
    (not three episodes, the first start twice). About 5 s on the double."""
    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "jet-cylinder-fast", "--double", "--episode-time", "0.1"]
    argv += ["--starts", "validation", "--constants", "0", "--amplitudes=", "--out", "tune"]
    assert main(argv) == 0, capsys.readouterr()
    assert "1 controller(s) x 2 validation start(s)" in capsys.readouterr().out
    episodes = json.loads((tmp_path / "tune" / "uncontrolled" / "summary.json").read_text())
    labels = [e["start_label"] for e in episodes["episodes"]]
    assert labels == ["t = 4.74 s", "t = 4.9 s"]


def test_the_plate_pid_module_runs_the_labs_commands(tmp_path: Path, monkeypatch, capsys) -> None:
    """``python -m gymprecice_tutorials.heated_plate.pid``, as the docs gave it, runs the
    lab's commands: a tuning sweep on validation starts, then the held-out sweep of its
    best point with the constants, one evaluate per policy, compare and plot; each is
    printed, and each is one the ``gymprecice`` parser takes."""
    from gymprecice.tools import cli
    from gymprecice.tools.cli import build_parser
    from gymprecice_tutorials.heated_plate import pid

    ran: list[list[str]] = []

    def gymprecice(argv: list[str]) -> int:
        build_parser().parse_args(argv)  # a command the lab's parser takes
        ran.append(argv)
        if argv[0] == "sweep" and "validation" in argv:  # the tuning sweep's result
            best = {"label": "feedback-pid-kp3-ki50-kd1", "kp": 3.0, "ki": 50.0, "kd": 1.0}
            (tmp_path / "out" / "tune").mkdir(parents=True)
            (tmp_path / "out" / "tune" / "sweep.json").write_text(
                json.dumps({"best_feedback": best})
            )
        return 0

    monkeypatch.setattr(cli, "main", gymprecice)
    out = str(tmp_path / "out")
    argv = ["--sweep-on", "fast", "--kp", "2,3", "--ki", "25,50", "--kd", "0,1"]
    argv += ["--seeds", "0,1,2", "--constants", "315", "--policy", "runs/plate/sac"]
    assert pid.main([*argv, "--policy", "shipped", "--solid", "fenics", "--out", out]) == 0
    fenics = ["--env-kwargs", '{"solid": "fenics"}']
    tune = ["--starts", "validation", "--episodes", "3", "--constants", "0", "--amplitudes="]
    tune += ["--feedback-grid=kp=2,3;ki=25,50;kd=0,1", "--out", f"{out}/tune"]
    held_out = ["--feedback-grid=kp=3;ki=50;kd=1", "--constants", "9", "--amplitudes="]
    policies = [f"{out}/policy-sac", f"{out}/policy-shipped"]
    evaluate = ["evaluate", "heated-plate", "--policy"]
    plot = ["--baseline", f"{out}/sweep/uncontrolled", "--out", f"{out}/plots"]
    assert ran == [
        ["sweep", "heated-plate-fast", *tune],
        ["sweep", "heated-plate", *held_out, "--out", f"{out}/sweep", *fenics],
        [*evaluate, "runs/plate/sac", "--all-starts", "--out", policies[0], *fenics],
        [*evaluate, "shipped", "--all-starts", "--out", policies[1], *fenics],
        ["compare", f"{out}/sweep", *policies, "--out", out],
        ["plot", f"{out}/sweep/feedback-pid-kp3-ki50-kd1", *policies, *plot],
    ]
    printed = [line for line in capsys.readouterr().out.splitlines() if line.startswith("$ ")]
    assert printed[0].startswith("$ gymprecice sweep heated-plate-fast --starts validation")
    assert len(printed) == len(ran)


@pytest.mark.parametrize(
    ("env", "extra", "message"),
    [
        ("heated-plate", [], 'pass --law with one value of each parameter, e.g. --law "kp=2;'),
        ("heated-plate", ["--law", "kp=3,4"], "give kp, ki, kd one value each"),
        ("heated-plate", ["--law", "kx=3"], "--law takes NAME=V1,V2,... for the pid law's"),
        ("quickstart", ["--law", "kp=3"], "quickstart has no feedback law of its own"),
        ("perpendicular-flap-fast", [], "has no default signal; pass --signal"),
    ],
)
def test_feedback_without_what_its_env_needs_is_refused_leaving_nothing(
    tmp_path: Path, gymprecice_refused, env, extra, message
) -> None:
    argv = ["feedback", env, "--double", *extra, "--out", "run"]
    status, err = gymprecice_refused(tmp_path, *argv)
    assert status == 2 and message in err, err
    assert not (tmp_path / "run").exists()


def test_a_bad_law_is_reported_before_missing_solvers(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(evaluate, "require_solvers", lambda *a, **k: 3)  # no solvers here
    assert main(["feedback", "heated-plate", "--law", "kx=3", "--out", "run"]) == 2
    assert "--law takes NAME=V1,V2,... for the pid law's" in capsys.readouterr().err
    assert main(["feedback", "heated-plate", "--law", "kp=3;ki=50;kd=1", "--out", "run"]) == 3
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("env", "flag", "value", "message"),
    [
        ("quickstart", "--amplitudes", "0.5,x", "--amplitudes takes comma-separated numbers"),
        ("quickstart", "--frequencies", "0,1", "--frequencies must be positive"),
        ("quickstart", "--amplitudes", ",", "--amplitudes needs at least one finite number"),
        ("quickstart", "--feedback-grid", "kp=1", "has no feedback law of its own"),
        ("heated-plate", "--feedback-gains", "1", "tune it with --feedback-grid"),
        ("heated-plate", "--feedback-grid", "kx=1", "parameters (kp, ki, kd); got 'kx=1'"),
        ("heated-plate", "--feedback-grid", "ki=5,y", "ki= needs comma-separated finite"),
    ],
)
def test_bad_grids_are_refused_naming_the_flag(
    tmp_path: Path, gymprecice_refused, env, flag, value, message
) -> None:
    argv = ["sweep", env, "--double", f"{flag}={value}", "--out", "sweep"]
    status, err = gymprecice_refused(tmp_path, *argv)
    assert status != 0 and message in err, err
    assert not (tmp_path / "sweep").exists()


def test_a_feedback_law_parses_its_grid_and_names_its_points() -> None:
    law = PID_LAW
    assert law.parameters == ("kp", "ki", "kd")
    assert len(law.points(law.default_grid())) == 40  # the documented tuning sweep
    grid = law.parse_grid("kp=2, 3; ki=50 kd=1")
    assert grid == {"kp": [2.0, 3.0], "ki": [50.0], "kd": [1.0]}
    assert law.points(grid) == [
        {"kp": 2.0, "ki": 50.0, "kd": 1.0},
        {"kp": 3.0, "ki": 50.0, "kd": 1.0},
    ]
    assert law.label({"kp": 3.0, "ki": 50.0, "kd": 1.0}) == "pid-kp3-ki50-kd1"
    assert law.parse_grid(law.grid_text(grid)) == grid
    assert load_object("gymprecice_tutorials.heated_plate.pid:PID_LAW", "feedback_law") is law
    with pytest.raises(CardError, match="not a gymprecice\\.card\\.FeedbackLaw"):
        load_object("gymprecice_tutorials.heated_plate.pid:PIDController", "feedback_law")
    heater = law.build(Box(300.0, 340.0, shape=(1,)), {"kp": 3, "ki": 0, "kd": 0})
    assert heater(np.array([1.0, 0.0, 0.0, 0.0]), 0.0)[0] == pytest.approx(307.0)
    with pytest.raises(ValueError, match="heater's range"):
        law.build(Box(-1.0, 1.0, shape=(1,)), {"kp": 3, "ki": 0, "kd": 0})


def test_parse_grid_and_constant_controller() -> None:
    assert parse_grid("0.25, 0.5,1", "amplitudes") == [0.25, 0.5, 1.0]
    act = constant_controller(Box(1.0, 3.0, shape=(1,)), 0.25)
    assert act(None, 0.0)[0] == pytest.approx(1.5)
    with pytest.raises(TypeError, match="bounded Box"):
        constant_controller(Box(-np.inf, np.inf, shape=(1,)), 0.5)


def test_best_takes_the_lowest_mean_of_a_kind() -> None:
    results = [
        SweepResult("a", "constant", objectives=[0.3, 0.1]),
        SweepResult("b", "constant", objectives=[0.15, 0.15]),
        SweepResult("c", "sinusoid", objectives=[0.01, 0.01]),
    ]
    assert best(results, "constant").label == "b"
    assert best(results, "uncontrolled") is None


@pytest.mark.timeout(300)
def test_two_workers_give_the_one_worker_table_and_a_rerun_keeps_finished_controllers(
    tmp_path: Path,
) -> None:
    grid = ["jet-cylinder-fast", "--double", "--episode-time", "0.1", "--constants", "2"]
    grid += ["--amplitudes", "1", "--frequencies", "3", "--episodes", "2"]
    grid += ["--feedback-gains=-1,1"]
    one = _cli(tmp_path, *grid, "--out", "one")
    two = _cli(tmp_path, *grid, "--workers", "2", "--out", "two")
    assert one.returncode == 0, one.stdout + one.stderr
    assert two.returncode == 0, two.stdout + two.stderr
    assert "6 controller(s) x 2 held-out start(s) on 2 worker(s)" in two.stdout
    tables = [json.loads((tmp_path / d / "sweep.json").read_text()) for d in ("one", "two")]
    assert tables[0]["controllers"] == tables[1]["controllers"]
    # each worker ran in its own env directory
    assert {p.name for p in (tmp_path / "two/envs").iterdir()} >= {"env_0", "env_1"}

    # a sweep cut short: one controller never finished; the rerun runs only that one
    unfinished = tmp_path / "two" / tables[1]["controllers"][3]["label"] / "summary.json"
    unfinished.unlink()
    again = _cli(tmp_path, *grid, "--workers", "2", "--out", "two")
    assert again.returncode == 0, again.stdout + again.stderr
    assert "5 of 6 controllers were finished by an earlier run of this sweep: kept" in again.stdout
    assert "1 controller(s) x 2 held-out start(s) on 1 worker(s)" in again.stdout
    assert json.loads((tmp_path / "two/sweep.json").read_text()) == tables[1]

    # other rollouts (another episode length) keep nothing, not even the three controllers
    # this smaller grid shares with the finished sweep (a feedback gain among them, so that
    # the feedback signal, which the rollouts also depend on, is the finished sweep's)
    other_grid = [*grid[:3], "0.15", "--constants", "0", "--amplitudes", "1"]
    other_grid += ["--frequencies", "3", "--episodes", "2", "--feedback-gains=1"]
    other = _cli(tmp_path, *other_grid, "--out", "two")
    assert other.returncode == 0, other.stdout + other.stderr
    assert "kept" not in other.stdout
    assert "3 controller(s) x 2 held-out start(s) on 1 worker(s)" in other.stdout


@pytest.mark.timeout(300)
def test_sigterm_stops_every_worker_of_a_parallel_sweep_and_its_solvers(tmp_path: Path) -> None:
    import os
    import signal
    import time

    proc = subprocess.Popen(
        [
            *(sys.executable, "-m", "gymprecice", "sweep", "jet-cylinder-fast", "--double"),
            *("--episode-time", "50", "--constants", "2", "--episodes", "2", "--workers", "2"),
            *("--amplitudes", "1", "--frequencies", "3", "--out", "sweep"),
        ],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its own process group: what is left of it can be found
    )
    try:
        deadline = time.monotonic() + 120
        # both workers running an episode: each has its env's directory
        while not all((tmp_path / "sweep/envs" / f"env_{w}").is_dir() for w in (0, 1)):
            assert proc.poll() is None, proc.communicate()[0]
            assert time.monotonic() < deadline, "the workers never started"
            time.sleep(0.5)
        time.sleep(2)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
        deadline = time.monotonic() + 30
        while True:  # every process of the group (workers, fake solvers) gone
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            assert time.monotonic() < deadline, "a worker or solver outlived the sweep"
            time.sleep(0.5)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode != 0
    assert not (tmp_path / "sweep/sweep.json").exists()
