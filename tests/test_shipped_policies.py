"""Trained policies shipped inside gymprecice-tutorials: they load, run, keep their bound.

* every policy in the package's ``policies/`` loads (``PPO.load`` on the stripped model,
  checksums as shipped) and runs a short deterministic episode on the preCICE test double
  of the env it was trained on;
* the round trip on the double: a policy trained in seconds (with an action bound of its
  own, 1e-5 m³/s against the env's 2.5e-4) is shipped into a temporary directory
  (``GYMPRECICE_POLICIES_DIR``), found by name and as ``shipped``, evaluated through the
  command line, transferred to another env with its training bound, and refused where it
  cannot run;
* on the real stack (``precice``/``openfoam``): the shipped jet-cylinder-fast policy
  lowers the mean drag of 2 s from a held-out snapshot below the uncontrolled flow's.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import gymprecice_tutorials
from gymprecice_lab.common.manifest import file_sha256
from gymprecice_lab.policies.policy import PolicyError, read_metadata
from gymprecice_lab.policies.ship import ship_policy
from gymprecice_lab.policies.shipped import (
    POLICIES_DIR_ENV,
    load_shipped,
    resolve_policy,
    shipped_policies,
)

#: The package's own policies (not a ``GYMPRECICE_POLICIES_DIR`` of the environment).
PACKAGE_POLICIES = Path(gymprecice_tutorials.__file__).resolve().parent / "policies"
SHIPPED = list(shipped_policies(PACKAGE_POLICIES))
#: What a shipped policy may weigh (the 512x512 PPO of the cylinders: about 1.3 MB).
MAX_BYTES = 1_500_000
#: The tiny policy's own bound, a tenth of the jet cylinders' default 2.5e-4.
BOUND = 1e-5


def _cli(cwd: Path, *args: str, policies: Path | None = None, timeout: float = 240) -> Any:
    env = dict(os.environ)
    env.pop(POLICIES_DIR_ENV, None)
    if policies is not None:
        env[POLICIES_DIR_ENV] = str(policies)
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _ok(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout + proc.stderr


def _fails(proc: subprocess.CompletedProcess[str]) -> str:
    """The one line a refused command prints."""
    assert proc.returncode != 0, proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


def _refused_here(cwd: Path, *args: str, policies: Path | None = None, monkeypatch, capsys) -> str:
    """:func:`_fails` for a command refused before it runs anything, run in this process
    (a process of its own would spend seconds importing PyTorch to print one line); the
    exit status a process would have is the one checked."""
    from gymprecice.tools.cli import main

    monkeypatch.chdir(cwd)
    monkeypatch.delenv(POLICIES_DIR_ENV, raising=False)
    if policies is not None:
        monkeypatch.setenv(POLICIES_DIR_ENV, str(policies))
    capsys.readouterr()
    try:
        status, message = main(list(args)), ""
    except SystemExit as exc:
        code = exc.code
        status, message = (code, "") if isinstance(code, int) else (1, f"{code}\n")
    captured = capsys.readouterr()
    assert status != 0, captured.out
    lines = (captured.err + message).strip().splitlines()
    assert len(lines) == 1, captured.err + message
    return lines[0]


def _actions(run: Path) -> np.ndarray:
    with (run / "history.csv").open() as handle:
        return np.array([float(r["action_0"]) for r in csv.DictReader(handle)])


# -- the policies in the package ----------------------------------------------------------


def test_a_policy_is_shipped():
    """Fails until a trained policy is shipped (`gymprecice ship-policy TRAIN_DIR`)."""
    assert SHIPPED, (
        f"no policy in {PACKAGE_POLICIES}; ship the jet-cylinder-fast run with "
        "`gymprecice ship-policy runs/jet-cylinder-fast/train --name jet-cylinder-fast "
        "--evaluation runs/jet-cylinder-fast/evaluate`"
    )


@pytest.mark.timeout(180)
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_policy_loads_and_runs_on_its_training_env_double(name: str, tmp_path: Path):
    meta = shipped_policies(PACKAGE_POLICIES)[name]
    for filename, record in meta["files"].items():
        assert (PACKAGE_POLICIES / name / filename).stat().st_size == record["bytes"]
    assert sum(r["bytes"] for r in meta["files"].values()) < MAX_BYTES
    assert meta["env"]["name"] and meta["training"]["timesteps"] > 0
    assert isinstance(meta["env_kwargs"], dict)  # the bound, where the env has one
    venv, model = load_shipped(
        name,
        meta["env"]["name"],
        directory=PACKAGE_POLICIES,
        double=True,
        episode_time=0.1,
        run_root=str(tmp_path),
    )
    # a shared policy runs in one vector-env slot per agent, each slot one agent's row
    shared = bool(meta.get("shared_by"))
    try:
        assert type(model).__name__.lower() == meta["algorithm"]
        assert list(venv.observation_space.shape) == meta["observation_shape"][shared:]
        assert venv.num_envs == (len(meta["shared_by"]) if shared else 1)
        inner = venv.unwrapped.envs[0].unwrapped
        for key, value in meta["env_kwargs"].items():
            assert getattr(inner, key) == pytest.approx(value)
        obs = venv.reset()
        bound = max(abs(v) for v in meta["action_space"]["high"] + meta["action_space"]["low"])
        for _ in range(200):
            action, _ = model.predict(obs, deterministic=True)
            obs, _, done, infos = venv.step(action)
            assert np.isfinite(obs).all()
            if not shared:  # the two flaps report slot velocities in m/s: their own test
                applied = np.asarray(infos[0]["action"], dtype=float)
                assert np.all(np.abs(applied) <= bound * (1 + 1e-6))
            if done[0]:
                break
        else:
            pytest.fail("the episode did not end")
    finally:
        venv.close()


# -- the round trip on the double ---------------------------------------------------------


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A policy trained for seconds on the double with its own bound, evaluated, shipped
    as ``tiny`` and as ``quickstart`` (the one ``--policy shipped`` finds)."""
    root = tmp_path_factory.mktemp("shipped")
    policies = root / "policies"
    _ok(
        _cli(
            root,
            "train",
            "quickstart",
            "--double",
            "--normalize",
            "--net",
            "16,16",
            "--n-steps",
            "8",
            "--batch-size",
            "8",
            "--n-epochs",
            "1",
            "--timesteps",
            "16",
            "--checkpoint-every",
            "8",
            "--episode-time",
            "0.1",
            "--env-kwargs",
            json.dumps({"max_flow_rate": BOUND}),
            "--no-progress-bar",
            "--out",
            "train",
        )
    )
    common = ["quickstart", "--double", "--episode-time", "0.1"]
    _ok(_cli(root, "evaluate", *common, "--policy", "train", "--out", "evaluate"))
    out = _ok(
        _cli(
            root,
            "ship-policy",
            "train",
            "--name",
            "tiny",
            "--evaluation",
            "evaluate",
            policies=policies,
        )
    )
    assert "shipped 'tiny'" in out
    # named after its env (here, not by a second command: the first ran the command line)
    ship_policy(root / "train", directory=policies)
    return {"root": root, "policies": policies}


def test_shipping_keeps_what_evaluation_needs_and_the_record(tiny):
    from stable_baselines3 import PPO

    root, policies = tiny["root"], tiny["policies"]
    assert set(shipped_policies(policies)) == {"quickstart", "tiny"}
    policy = resolve_policy("tiny", directory=policies)
    assert policy.model == policies / "tiny" / "model.zip"
    meta = policy.metadata
    assert meta["env"] == {"name": "quickstart", "id": "gymprecice/Quickstart-v0"}
    assert meta["env_kwargs"] == {"max_flow_rate": BOUND}
    assert meta["action_space"]["high"] == [BOUND] and meta["observation_shape"] == [151]
    training = meta["training"]
    assert training["command"].startswith("gymprecice train quickstart --double")
    # the run's kept model ships: the best of its validations, with what chose it
    kept = training["kept"]
    assert training["timesteps"] == kept["timesteps"] and kept["timesteps"] in (8, 16)
    assert training["timesteps_requested"] == 16 and training["wall_clock_seconds"] > 0
    assert kept["score"] == "mean validation return" and len(kept["starts"]) == 3
    assert training["model"] == "best_model.zip"
    assert training["model_sha256"] == file_sha256(root / "train" / "best_model.zip")
    assert training["manifest_model_sha256_matches"] is True
    assert training["source"] is None or isinstance(training["source"], str)
    evaluation = meta["evaluation"]
    assert evaluation["episode_time"] == 0.1 and "mean_Cd" in evaluation["over_episodes"]
    text = (policies / "tiny" / "policy.json").read_text()
    assert str(root) not in text  # no machine paths in what ships
    files = {p.name for p in (policies / "tiny").iterdir()}
    assert files == {"model.zip", "model_vecnormalize.pkl", "policy.json"}
    # SB3's own loader reads it; no optimizer moments; acts exactly like the trained model
    slim = PPO.load(policies / "tiny" / "model.zip", device="cpu")
    trained = PPO.load(root / "train" / "best_model.zip", device="cpu")  # the kept model
    final = PPO.load(root / "train" / "model.zip", device="cpu")
    assert not slim.policy.optimizer.state_dict()["state"]
    assert final.policy.optimizer.state_dict()["state"]  # what shipping strips
    # the value function is blank (only training reads it), the actor untouched
    for (name, ours), (_, theirs) in zip(
        slim.policy.named_parameters(), trained.policy.named_parameters(), strict=True
    ):
        if name.startswith(("mlp_extractor.value_net.", "value_net.")):
            assert not ours.any(), name  # blank whatever the kept model's (weights: not)
            assert theirs.any() or name.endswith("bias"), name
        else:
            assert ours.equal(theirs), name
    obs = np.random.default_rng(1).normal(size=(5, 151)).astype(np.float32)
    assert np.array_equal(
        slim.predict(obs, deterministic=True)[0], trained.predict(obs, deterministic=True)[0]
    )
    assert (policies / "tiny" / "model.zip").stat().st_size < (
        root / "train" / "model.zip"
    ).stat().st_size


def test_a_shipped_command_names_no_directory_of_the_training_machine():
    """Absolute paths in a recorded command become relative to where it ran, or their
    last component where they lie elsewhere: a policy ships to other machines."""
    from gymprecice_lab.policies.ship import _command_line

    argv = ["/opt/env/bin/gymprecice", "train", "two-flaps-fast", "--out", "/home/u/w/runs/a"]
    assert _command_line(argv, "/home/u/w") == "gymprecice train two-flaps-fast --out runs/a"
    assert _command_line(argv, "/elsewhere") == "gymprecice train two-flaps-fast --out a"
    assert _command_line([*argv[:3], "--out", "runs/a"], None).endswith("--out runs/a")
    assert _command_line(None) is None


def test_a_checkpoint_ships_best_by_training_return_or_by_steps(tiny, tmp_path):
    """--checkpoint best takes checkpoints/best.json's model (chosen by training return,
    never by an evaluation), --checkpoint STEPS that step's; others are refused."""
    train = tiny["root"] / "train"
    checkpoints = sorted((train / "checkpoints").glob("*_steps.zip"))
    assert checkpoints, "the tiny run keeps checkpoints"
    first = checkpoints[0]
    steps = int(first.stem.split("_")[-2])
    # point best.json at the first checkpoint: best is whatever it names, not the newest
    best = json.loads((train / "checkpoints" / "best.json").read_text())
    (train / "checkpoints" / "best.json").write_text(json.dumps({**best, "name": first.name}))
    try:
        dest = ship_policy(train, "best", directory=tmp_path, checkpoint="best")
        meta = read_metadata(dest)
        assert meta["training"]["model"] == f"checkpoints/{first.name}"
        assert meta["training"]["model_sha256"] == file_sha256(first)
        dest = ship_policy(train, "by-steps", directory=tmp_path, checkpoint=str(steps))
        assert read_metadata(dest)["training"]["model"] == f"checkpoints/{first.name}"
        for bad in ("latest", "999999"):
            with pytest.raises(PolicyError, match="checkpoint"):
                ship_policy(train, "bad", directory=tmp_path, checkpoint=bad)
    finally:
        (train / "checkpoints" / "best.json").write_text(json.dumps(best))


def test_evaluate_by_name_and_as_shipped_acts_like_the_training_run(tiny):
    root, policies = tiny["root"], tiny["policies"]
    common = ["quickstart", "--double", "--episode-time", "0.1"]
    _ok(_cli(root, "evaluate", *common, "--policy", "tiny", "--out", "by-name", policies=policies))
    out = _ok(
        _cli(
            root,
            "evaluate",
            *common,
            "--policy",
            "shipped",
            "--out",
            "as-shipped",
            policies=policies,
        )
    )
    assert "transfer" not in out
    for run in ("by-name", "as-shipped"):
        summary = json.loads((root / run / "summary.json").read_text())
        assert summary["episodes"][0]["steps"] == 4
        actions = _actions(root / run)
        assert np.all(np.abs(actions) <= BOUND * (1 + 1e-6)) and np.any(actions != 0)
        assert np.allclose(actions, _actions(root / "evaluate"), rtol=1e-6, atol=0)
    settings = json.loads((root / "by-name" / "manifest.json").read_text())["settings"]
    assert settings["policy"]["name"] == "tiny" and settings["policy"]["source"] == "shipped"
    assert settings["env_kwargs"]["max_flow_rate"] == BOUND
    # --model still takes a path (here the kept model, the one shipped)
    _ok(_cli(root, "evaluate", *common, "--model", "train/best_model.zip", "--out", "model"))
    assert np.allclose(_actions(root / "model"), _actions(root / "evaluate"), rtol=1e-6, atol=0)


def test_a_policy_trained_to_see_more_ships_what_it_sees(tmp_path: Path):
    """A plate policy trained with ``observation="state"`` takes four numbers, not the
    default five: it ships that keyword and runs by name without being told it again."""
    policies = tmp_path / "policies"
    kwargs = json.dumps({"observation": "state"})
    train = ["heated-plate-fast", "--double", "--env-kwargs", kwargs, "--net", "8,8"]
    ppo = ["--n-steps", "8", "--batch-size", "8", "--n-epochs", "1", "--timesteps", "8"]
    quick = ["--no-validation", "--no-progress-bar"]
    _ok(_cli(tmp_path, "train", *train, *ppo, *quick, "--out", "train"))
    ship = ["train", "--model", "final", "--name", "sees-more"]
    _ok(_cli(tmp_path, "ship-policy", *ship, policies=policies))
    meta = read_metadata(policies / "sees-more")
    assert meta["env_kwargs"]["observation"] == "state"
    assert meta["observation_shape"] == [4]
    common = ["heated-plate-fast", "--double", "--episodes", "1"]
    _ok(
        _cli(
            tmp_path, "evaluate", *common, "--policy", "sees-more", "--out", "ev", policies=policies
        )
    )
    settings = json.loads((tmp_path / "ev" / "manifest.json").read_text())["settings"]
    assert settings["env_kwargs"]["observation"] == "state"


def test_a_policy_trained_on_a_feedback_law_runs_on_it_wherever_it_is_evaluated(
    tmp_path: Path,
):
    """``base_feedback`` puts the classical law under the policy, whose action is added
    to the law's: evaluated from its training directory (as ``time-to-floor`` and
    ``scripts/train.sh`` do) or shipped, without ``--env-kwargs``, it runs on the law."""
    policies = tmp_path / "policies"
    law = {"gain": -1, "delay": 6}
    train = ["jet-cylinder-fast", "--double", "--episode-time", "0.1", "--net", "8,8"]
    train += ["--env-kwargs", json.dumps({"base_feedback": law})]
    ppo = ["--n-steps", "8", "--batch-size", "8", "--n-epochs", "1", "--timesteps", "8"]
    quick = ["--no-validation", "--no-progress-bar"]
    _ok(_cli(tmp_path, "train", *train, *ppo, *quick, "--out", "train"))
    common = ["jet-cylinder-fast", "--double", "--episode-time", "0.1"]
    _ok(_cli(tmp_path, "evaluate", *common, "--policy", "train", "--model", "final", "--out", "ev"))
    settings = json.loads((tmp_path / "ev" / "manifest.json").read_text())["settings"]
    assert settings["env_kwargs"]["base_feedback"] == law
    _ok(
        _cli(
            tmp_path,
            "ship-policy",
            "train",
            "--model",
            "final",
            "--name",
            "on-law",
            policies=policies,
        )
    )
    assert read_metadata(policies / "on-law")["env_kwargs"]["base_feedback"] == law


def test_transfer_to_another_env_keeps_the_training_bound(tiny, tmp_path):
    root, policies = tiny["root"], tiny["policies"]
    out = _ok(
        _cli(
            root,
            "evaluate",
            "jet-cylinder",
            "--double",
            "--episode-time",
            "0.1",
            "--policy",
            "tiny",
            "--out",
            "transfer",
            policies=policies,
        )
    )
    line = next(x for x in out.splitlines() if "transfer" in x)
    assert "trained on quickstart" in line and "jet-cylinder" in line
    assert "max_flow_rate=1e-05" in line
    actions = _actions(root / "transfer")
    assert np.all(np.abs(actions) <= BOUND * (1 + 1e-6)) and np.any(actions != 0)
    settings = json.loads((root / "transfer" / "manifest.json").read_text())["settings"]
    assert settings["env_id"] == "gymprecice/JetCylinder-v0"
    assert settings["env_kwargs"]["max_flow_rate"] == BOUND
    # the same from Python
    venv, _ = load_shipped(
        "tiny", "jet-cylinder", directory=policies, double=True, run_root=str(tmp_path)
    )
    try:
        assert venv.unwrapped.envs[0].unwrapped.max_flow_rate == BOUND
    finally:
        venv.close()


def test_unknown_names_other_actuators_and_wrong_shapes_are_refused(
    tiny, tmp_path, monkeypatch, capsys
):
    from stable_baselines3 import PPO

    root, policies = tiny["root"], tiny["policies"]
    common = ["--double", "--episode-time", "0.1", "--out", str(tmp_path / "x")]
    line = _fails(  # as typed: one line from a process of its own
        _cli(root, "evaluate", "quickstart", *common, "--policy", "nope", policies=policies)
    )
    assert "no shipped policy 'nope'" in line and "quickstart, tiny" in line
    here = {"policies": policies, "monkeypatch": monkeypatch, "capsys": capsys}
    line = _refused_here(
        root, "evaluate", "rotating-cylinder", *common, "--policy", "shipped", **here
    )
    assert "no policy is shipped for rotating-cylinder" in line and "tiny" in line
    line = _refused_here(root, "evaluate", "rotating-cylinder", *common, "--policy", "tiny", **here)
    assert "has no max_flow_rate" in line
    # a model of another observation: refused at evaluation and at shipping
    other = tmp_path / "other"
    other.mkdir()
    PPO("MlpPolicy", "Pendulum-v1", policy_kwargs={"net_arch": [8]}, device="cpu").save(
        other / "model.zip"
    )
    line = _refused_here(
        root,
        "evaluate",
        "quickstart",
        *common,
        "--policy",
        str(other / "model.zip"),
        monkeypatch=monkeypatch,
        capsys=capsys,
    )
    assert "observations of shape (3,)" in line and "(151,)" in line
    shutil.copy(root / "train" / "manifest.json", other / "manifest.json")
    with pytest.raises(PolicyError, match=r"shape \(3,\)"):
        ship_policy(other, "other", directory=tmp_path / "policies")
    # names, replacing, an evaluation of another model, a file changed after shipping
    with pytest.raises(PolicyError, match="shipped already"):
        ship_policy(root / "train", "tiny", directory=policies)
    with pytest.raises(PolicyError, match="policy name"):
        ship_policy(root / "train", "shipped", directory=tmp_path / "policies")
    elsewhere = tmp_path / "evaluate-elsewhere"
    shutil.copytree(root / "evaluate", elsewhere)
    manifest = json.loads((elsewhere / "manifest.json").read_text())
    manifest["settings"]["model_sha256"] = "0" * 64
    (elsewhere / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(PolicyError, match="evaluated another model"):
        ship_policy(root / "train", "x", evaluation=elsewhere, directory=tmp_path / "p")
    copy = tmp_path / "copied"
    shutil.copytree(policies, copy)
    with (copy / "tiny" / "model_vecnormalize.pkl").open("ab") as handle:
        handle.write(b"\0")
    with pytest.raises(PolicyError, match="not the file that was shipped"):
        resolve_policy("tiny", directory=copy)


# -- on the real stack ----------------------------------------------------------------------


def _missing() -> list[str]:
    """What the real stack lacks here (empty when preCICE, OpenFOAM and the adapter are)."""
    from gymprecice_openfoam.testing import missing_coupled_stack

    return missing_coupled_stack("pimpleFoam")


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_shipped_jet_cylinder_fast_policy_lowers_the_drag_on_openfoam(tmp_path: Path):
    """2 s from the same held-out snapshot: the shipped policy's mean Cd is below the
    uncontrolled flow's (pre-run and snapshots first: tens of minutes on 2 cores).

    Cost: a few minutes on 2 cores, one of the suite's heaviest: blockMesh and the 5 s pre-run with
    its snapshots (about 50 s; the second command restores it from the pre-run cache), then two
    coupled 2 s episodes.
    """
    missing = _missing()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    if "jet-cylinder-fast" not in SHIPPED:
        pytest.skip("no jet-cylinder-fast policy shipped yet (gymprecice ship-policy)")
    common = ["jet-cylinder-fast", "--episode-time", "2", "--seed", "0"]
    _ok(_cli(tmp_path, "baseline", *common, "--out", "baseline", timeout=3000))
    out = _ok(
        _cli(
            tmp_path,
            "evaluate",
            *common,
            "--policy",
            "shipped",
            "--baseline",
            "baseline",
            "--out",
            "controlled",
            timeout=3000,
        )
    )
    assert "transfer" not in out
    summaries = {
        run: json.loads((tmp_path / run / "summary.json").read_text())
        for run in ("baseline", "controlled")
    }
    for run in ("baseline", "controlled"):
        manifest = json.loads((tmp_path / run / "manifest.json").read_text())
        assert manifest["settings"]["double"] is False
        assert manifest["settings"]["env_kwargs"]["episode_time"] == 2.0
    with (
        (tmp_path / "baseline" / "history.csv").open() as a,
        (tmp_path / "controlled" / "history.csv").open() as b,
    ):
        first = next(csv.DictReader(a)), next(csv.DictReader(b))
    assert first[0]["start"] == first[1]["start"]  # the same held-out snapshot
    cd = {run: s["over_episodes"]["mean_Cd"]["mean"] for run, s in summaries.items()}
    assert cd["controlled"] < cd["baseline"], cd
    bound = shipped_policies(PACKAGE_POLICIES)["jet-cylinder-fast"]["env_kwargs"]
    assert np.all(np.abs(_actions(tmp_path / "controlled")) <= bound["max_flow_rate"] * (1 + 1e-6))


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_shipped_flap_policy_beats_the_uncontrolled_flap_on_the_real_stack(tmp_path: Path):
    """From the first held-out gust, 1.5 s of the three-participant FSI (OpenFOAM, deal.II,
    the controller): the shipped policy's mean tip displacement is below the uncontrolled
    flap's, and its jet stays on the inlet.

    Cost: a few minutes on 2 cores: two 1.5 s runs of the three-participant FSI (pimpleFoam,
    elasticity, the controller).
    """
    from gymprecice.tools.stack import stack_which

    missing = _missing() + ([] if stack_which("elasticity") else ["the deal.II adapter"])
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    common = ["perpendicular-flap-fast", "--seed", "0", "--env-kwargs", '{"episode_time": 1.5}']
    _ok(_cli(tmp_path, "baseline", *common, "--out", "baseline", timeout=600))
    _ok(
        _cli(
            tmp_path, "evaluate", *common, "--policy", "shipped", "--out", "controlled", timeout=600
        )
    )
    objective = {
        run: json.loads((tmp_path / run / "summary.json").read_text())["episodes"][0][
            "mean_mean_tip_displacement"
        ]
        for run in ("baseline", "controlled")
    }
    assert objective["controlled"] < objective["baseline"], objective
    centres = _actions(tmp_path / "controlled")
    assert len(centres) == 15 and np.all((centres >= 1.0) & (centres <= 3.0))


# -- the two flaps' shared policy -----------------------------------------------------------


def _tip_displacements(run: Path) -> list[float]:
    """Each episode's mean tip displacement of both flaps (the two flaps' objective)."""
    summary = json.loads((run / "summary.json").read_text())
    return [e["mean_mean_tip_displacement"] for e in summary["episodes"]]


def _two_flaps_against_uncontrolled(tmp_path: Path, *starts: str, timeout: float) -> None:
    """Run the uncontrolled flaps and the shipped shared policy from the same starts and
    assert the policy damps both flaps more, start by start, each slot within its bound."""
    for command, out, extra in (
        ("baseline", "uncontrolled", []),
        ("evaluate", "shared", ["--policy", "shipped"]),
    ):
        _ok(
            _cli(
                tmp_path, command, "two-flaps-fast", *starts, *extra, "--out", out, timeout=timeout
            )
        )
    uncontrolled = _tip_displacements(tmp_path / "uncontrolled")
    shared = _tip_displacements(tmp_path / "shared")
    assert len(shared) == len(uncontrolled) > 0
    assert all(s < u for s, u in zip(shared, uncontrolled)), (shared, uncontrolled)
    with (tmp_path / "shared" / "history.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    # each slot's mean velocity (m/s): within the env's 10 m/s, and following its flap
    slots = np.array([[float(r["action_0"]), float(r["action_1"])] for r in rows])
    assert np.all(np.abs(slots) <= 10.0 * (1 + 1e-6)) and np.ptp(slots, axis=0).min() > 0


def test_the_two_flaps_ship_one_policy_both_flaps_share(monkeypatch, capsys):
    """The two flaps' policy was trained --shared-policy: it takes one flap's row and
    says which agents share it, in the order of the env's card, as `gymprecice policies`
    tells."""
    from gymprecice.plugin.card import card_for
    from gymprecice.tools.cli import main

    monkeypatch.delenv(POLICIES_DIR_ENV, raising=False)
    assert main(["policies"]) == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if x.startswith("two-flaps")]
    assert "one policy shared by upstream, downstream" in line

    meta = shipped_policies(PACKAGE_POLICIES)["two-flaps-fast"]
    assert meta["shared_by"] == list(card_for("gymprecice/TwoFlapsFast-v0").agents)
    assert meta["observation_shape"] == [2, 9] and meta["action_space"]["shape"] == [2, 1]
    assert meta["hyperparams"]["shared_policy"] is True
    assert "--shared-policy" in meta["training"]["command"]
    assert "/" not in meta["training"]["command"].split("--out ")[1].split()[0]


@pytest.mark.timeout(300)
def test_shipped_two_flaps_policy_beats_the_uncontrolled_flaps_on_the_double(tmp_path: Path):
    """On the test double, from each of the three held-out gusts, the shipped shared
    policy leaves less tip displacement than the uncontrolled flaps (by about 2 %)."""
    _two_flaps_against_uncontrolled(tmp_path, "--double", "--all-starts", timeout=240)


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_shipped_two_flaps_policy_beats_the_uncontrolled_flaps_on_the_real_stack(tmp_path: Path):
    """From the first held-out gust, one whole episode of the four participants (OpenFOAM,
    two deal.II flaps, the controller): the shipped shared policy's mean tip displacement
    of both flaps is below the uncontrolled flaps' (by 8 % in its evaluation).

    Cost: about a minute on 2 cores: two 3 s episodes of the four-participant FSI.
    """
    from gymprecice.tools.stack import stack_which

    missing = _missing() + ([] if stack_which("elasticity") else ["the deal.II adapter"])
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _two_flaps_against_uncontrolled(tmp_path, "--seed", "0", timeout=600)
