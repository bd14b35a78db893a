"""The lab runs on an environment that is not a tutorial: examples/gymprecice-heated-rod.

The example is a third-party environment package: it depends on gymprecice-core alone,
registers ``heatedrod/HeatedRod-v0`` and its lab card through the ``gymprecice`` entry
point, and ships its own case (a Python solver, run by core's ``command`` kind). Here it is
installed with pip as a user would (built from a copy of its folder, not editable) into a
virtual environment of its own that sees the set-up's ``.venv``, and every command is the
``gymprecice`` command of that environment, run from an empty directory. On the test double
(``--double``) the commands need no preCICE; the ``precice`` test runs the same package on
the real stack.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "gymprecice-heated-rod"
ENV_ID = "heatedrod/HeatedRod-v0"
#: seconds any one command may take before the test fails instead of hanging (a command
#: here takes 5 to 45 s on two idle cores, several times that on a loaded machine)
COMMAND_TIMEOUT = 480
#: PPO's smallest sensible run on the rod: one rollout of two episodes, a small network
TINY_PPO = ["--n-steps", "40", "--batch-size", "40", "--net", "64,64", "--no-progress-bar"]

# Tens of seconds each (not the fast tier), on one xdist worker: they share the venv and
# the training run that the fixtures make once.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("heated-rod")]


@pytest.fixture(scope="session")
def rod_python(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The interpreter of a virtual environment with the example installed. Cost: about 5 s.

    ``venv --system-site-packages`` would reach the base interpreter's packages, not the
    set-up's ``.venv`` this test runs in, so a ``.pth`` line adds ``.venv``'s site-packages
    (with its editable installs) behind the environment's own. pip installs the example
    from a copy of its folder (setuptools writes ``build/`` and ``*.egg-info`` next to the
    sources), without dependencies or an index: everything it needs is in ``.venv``.
    """
    root = tmp_path_factory.mktemp("heated-rod")
    source = root / "gymprecice-heated-rod"
    shutil.copytree(
        EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__")
    )
    env_dir = root / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    own = _run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"])
    outer = sysconfig.get_paths()["purelib"]
    (Path(own.stdout.strip()) / "_setup_venv.pth").write_text(
        f"import site; site.addsitedir({outer!r})\n"
    )
    _run(
        [python, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--no-index",
         "--no-deps", "--no-build-isolation", str(source)],
        env={**_clean_env(), "PIP_CONFIG_FILE": os.devnull},
        cwd=root,
    )  # fmt: skip
    where = _run([python, "-c", "import gymprecice_heated_rod as m; print(m.__file__)"], cwd=root)
    assert Path(where.stdout.strip()).is_relative_to(env_dir), where.stdout  # not the sources
    return python


def _clean_env() -> dict[str, str]:
    """The environment a user's shell gives: no test-suite switches, no PYTHONPATH."""
    drop = ("PYTHONPATH", "VIRTUAL_ENV", "GYMPRECICE_DISABLE_PLUGINS", "GYMPRECICE_REQUIRE_REAL")
    return {k: v for k, v in os.environ.items() if k not in drop}


def _run(argv: list, *, cwd: Path | None = None, env: dict | None = None, check: bool = True):
    result = subprocess.run(
        [str(a) for a in argv],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env or _clean_env(),
        timeout=COMMAND_TIMEOUT,
    )
    if check and result.returncode != 0:
        pytest.fail(
            f"{' '.join(map(str, argv[:6]))} ... exited {result.returncode}\n"
            f"stdout:\n{result.stdout[-3000:]}\nstderr:\n{result.stderr[-3000:]}"
        )
    return result


def gymprecice(python: Path, *args: object, cwd: Path, check: bool = True):
    """``gymprecice ARGS`` of the example's environment, run in ``cwd``."""
    return _run([python, "-m", "gymprecice", *args], cwd=cwd, check=check)


def _python(python: Path, code: str, cwd: Path):
    return _run([python, "-c", textwrap.dedent(code)], cwd=cwd)


def _real_precice_importable() -> str | None:
    """Why ``import precice`` fails in a child process (``None``: it imports)."""
    probe = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True, text=True)
    return None if probe.returncode == 0 else (probe.stderr.strip().splitlines() or ["?"])[-1]


# -- the package as installed ----------------------------------------------------------------


def test_the_installed_package_registers_its_env_and_card(rod_python: Path, tmp_path) -> None:
    """``import gymprecice`` registers the id and the card from the entry point, the
    installed case passes ``gymprecice check``, and the env passes Gymnasium's checker on
    the test double. Cost: about 12 s (three double episodes)."""
    _python(
        rod_python,
        f"""
        import warnings
        import gymnasium
        from gymnasium.utils.env_checker import check_env
        from gymprecice.plugin.card import card_for, find_env
        from gymprecice.tools.cli import main
        from gymprecice.plugin.registration import registered_environments
        from gymprecice_heated_rod.env import CASE_DIR

        assert registered_environments()[{ENV_ID!r}] == "heated-rod", registered_environments()
        card = card_for({ENV_ID!r})
        assert find_env("heated-rod") == ({ENV_ID!r}, card)
        assert card.objective == "tracking_error" and card.held_out_starts and card.double
        assert card.feedback_law == "gymprecice_heated_rod.control:PI_LAW"
        assert main(["check", str(CASE_DIR)]) == 0  # the case as installed
        env = gymnasium.make({ENV_ID!r}, double=True).unwrapped
        try:
            assert len(env.held_out_starts) == 3
            with warnings.catch_warnings():
                # the checker advises [-1, 1] action boxes and finite observation bounds;
                # the heaters' K/s are deliberate (the lab's learners rescale actions)
                warnings.simplefilter("ignore")
                check_env(env, skip_render_check=True)
        finally:
            env.close()
        """,
        tmp_path,
    )


# -- the lab on the test double ---------------------------------------------------------------


@pytest.fixture(scope="module")
def trained(rod_python: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``gymprecice train heated-rod --double``: one PPO rollout of 40 actions. Cost: about
    12 s."""
    work = tmp_path_factory.mktemp("train")
    gymprecice(rod_python, "train", "heated-rod", "--double", "--timesteps", 40, *TINY_PPO,
               "--out", "run", cwd=work)  # fmt: skip
    return work / "run"


@pytest.fixture(scope="module")
def swept(rod_python: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """``gymprecice sweep heated-rod --double``: the uncontrolled rod, one sinusoid and two
    PI controllers of the card's law, from the three held-out starts. Cost: about 25 s (12
    episodes)."""
    work = tmp_path_factory.mktemp("sweep")
    gymprecice(rod_python, "sweep", "heated-rod", "--double", "--constants", 0,
               "--amplitudes", 0.5, "--frequencies", 2, "--feedback-grid", "kp=100,300;ki=1500",
               "--out", "sweep", cwd=work)  # fmt: skip
    assert (work / "sweep" / "sweep.csv").is_file() and (work / "sweep" / "sweep.png").is_file()
    return json.loads((work / "sweep" / "sweep.json").read_text())


def test_train_on_the_double(trained: Path) -> None:
    """A model, a checkpoint and a manifest of the installed package's case (the training
    itself is the ``trained`` fixture's 15 s)."""
    assert (trained / "model.zip").is_file() and list((trained / "checkpoints").glob("*.zip"))
    manifest = json.loads((trained / "manifest.json").read_text())
    assert manifest["command"] == "train"
    assert "site-packages" in manifest["case_dir"]  # the installed copy, not the sources
    assert manifest["case_dir"].endswith("gymprecice_heated_rod/case")


def test_evaluate_all_starts_on_the_double(rod_python: Path, trained: Path, tmp_path) -> None:
    """One episode from each held-out start, labelled with the env's own start labels, and
    the card's metrics in the summary. Cost: about 10 s (three episodes)."""
    gymprecice(rod_python, "evaluate", "heated-rod", "--double", "--policy", trained,
               "--all-starts", "--out", "eval", cwd=tmp_path)  # fmt: skip
    episodes = json.loads((tmp_path / "eval" / "summary.json").read_text())["episodes"]
    assert [e["start"] for e in episodes] == [0, 1, 2]
    assert [e["start_label"].split(",")[0] for e in episodes] == [
        "setpoint 0.13 K",
        "setpoint 0.17 K",
        "setpoint 0.11 K",
    ]
    for episode in episodes:
        assert episode["steps"] == 20 and episode["end_time"] == pytest.approx(1.0)
        assert 0 < episode["mean_tracking_error"] < 0.5 and episode["mean_heat"] > 0
    history = (tmp_path / "eval" / "history.csv").read_text().splitlines()
    assert history[0].split(",")[4:9] == [
        "reward", "tracking_error", "error", "mean_temperature", "heat",
    ]  # fmt: skip


def test_baseline_is_the_cards_uncontrolled_setting(rod_python: Path, swept, tmp_path) -> None:
    """``baseline --all-starts`` runs the card's ``uncontrolled={"uncontrolled": True}``
    (every heater at 24 K/s), not the zero action clipped into the box (no heat): its
    tracking errors are the sweep's uncontrolled row, start by start. Cost: about 10 s
    (three episodes)."""
    gymprecice(rod_python, "baseline", "heated-rod", "--double", "--all-starts",
               "--out", "baseline", cwd=tmp_path)  # fmt: skip
    episodes = json.loads((tmp_path / "baseline" / "summary.json").read_text())["episodes"]
    errors = [e["mean_tracking_error"] for e in episodes]
    uncontrolled = next(c for c in swept["controllers"] if c["label"] == "uncontrolled")
    assert errors == pytest.approx([uncontrolled[f"start_{k}"] for k in range(3)], rel=1e-9)
    assert all(e["mean_heat"] == pytest.approx(24.0) for e in episodes)


def test_sweep_tunes_the_cards_feedback_law(swept: dict) -> None:
    """The sweep runs the env's own PI law (the card's ``feedback_law``) beside the open
    loop, and the tuned PI holds the setpoint better than the uncontrolled rod from every
    held-out start (the sweep itself is the ``swept`` fixture's 25 s)."""
    labels = [c["label"] for c in swept["controllers"]]
    assert labels == [
        "uncontrolled",
        "sine-c0.5-a0.5-f2",
        "feedback-pi-kp100-ki1500",
        "feedback-pi-kp300-ki1500",
    ]
    by_label = {c["label"]: c for c in swept["controllers"]}
    for k in range(3):
        pi = by_label["feedback-pi-kp300-ki1500"][f"start_{k}"]
        assert pi < by_label["uncontrolled"][f"start_{k}"], k


@pytest.mark.timeout(900)  # a loaded machine: several times the cost below
def test_benchmark_two_seeds_on_the_double(rod_python: Path, tmp_path) -> None:
    """``benchmark --seeds 2``: two PPO seeds of one rollout each, evaluated from the three
    held-out starts beside the uncontrolled rod, the best constant, the best sinusoid and
    the card's PI law, with intervals, the table and both figures. Cost: about 60 s."""
    gymprecice(rod_python, "benchmark", "heated-rod", "--double", "--seeds", 2,
               "--timesteps", 40, "--train-args", " ".join(TINY_PPO), "--constants", 1, "--amplitudes", 0.5, "--frequencies", 2,
               "--feedback-grid", "kp=300;ki=1500", "--bootstrap-reps", 200,
               "--out", "bench", cwd=tmp_path)  # fmt: skip
    out = tmp_path / "bench"
    results = json.loads((out / "results.json").read_text())
    assert results["env"] == ENV_ID and len(results["held_out_starts"]) == 3
    controllers = {c["label"].split(":")[0]: c for c in results["controllers"]}
    assert set(controllers) == {
        "PPO", "uncontrolled", "best constant", "best sinusoid", "best feedback",
    }  # fmt: skip
    assert controllers["PPO"]["runs"] == 2
    assert controllers["best feedback"]["label"].endswith("feedback-pi-kp300-ki1500")
    for controller in controllers.values():
        scores = controller["metrics"]["objective"]["scores"]
        assert all(len(run) == 3 for run in scores) and len(scores) == controller["runs"]
    table = (out / "results.md").read_text()
    assert "## objective: tracking_error (lower is better)" in table
    for figure in ("return_wallclock.png", "objective_per_start.png"):
        assert (out / figure).stat().st_size > 10_000, figure
    assert (out / "results.csv").read_text().startswith("controller,kind,runs,starts,")


# -- bad input: one line, exit 2, nothing on disk ----------------------------------------------


def _refused(result, *phrases: str) -> str:
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    return lines[0]


def test_an_id_no_package_registers(rod_python: Path, tmp_path) -> None:
    """The message lists the registered ids, the example's among them. Cost: about 4 s."""
    result = gymprecice(rod_python, "train", "heatedrod/NoSuchRod-v0", "--double",
                        cwd=tmp_path, check=False)  # fmt: skip
    _refused(result, "'heatedrod/NoSuchRod-v0'", "heated-rod (heatedrod/HeatedRod-v0)")
    assert not list(tmp_path.iterdir())


def test_a_command_that_needs_a_field_the_card_lacks(rod_python, trained, tmp_path) -> None:
    """time-to-floor needs a physical ``reference``, which the rod's card does not declare:
    refused naming the field and how to declare it, before any evaluation. Cost: about 4 s."""
    before = sorted(p.relative_to(trained) for p in trained.rglob("*"))
    result = gymprecice(rod_python, "time-to-floor", trained, "--env", "heated-rod", "--double",
                        cwd=tmp_path, check=False)  # fmt: skip
    _refused(result, "'reference'", ENV_ID, "EnvCard(reference=...)")
    assert not list(tmp_path.iterdir())
    assert sorted(p.relative_to(trained) for p in trained.rglob("*")) == before


_BAD_PLUGIN = """
import sys
import warnings

from gymprecice.plugin.card import CardError, EnvCard, card_for
from gymprecice.tools.cli import main
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import PluginWarning, register_plugin
from gymprecice.plugin.registration import register_environments

FORM = sys.argv[1]


class BadCard:
    @hookimpl
    def gymprecice_register_environments(self, register):
        card = {"name": "bad-rod", "double": "yes"}  # a str where a bool belongs
        register(
            "badlab/BadRod-v0",
            "gymprecice_heated_rod.env:HeatedRodEnv",
            card=card if FORM == "mapping" else EnvCard(**card),
        )


register_plugin(BadCard(), "bad-card-package")
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    register_environments()
(warning,) = [w for w in caught if issubclass(w.category, PluginWarning)]
print(warning.message, file=sys.stderr)
if FORM == "mapping":
    try:
        card_for("badlab/BadRod-v0")
    except CardError:
        pass
    else:
        raise AssertionError("a malformed card was accepted")
    sys.exit(main(["evaluate", "badlab/BadRod-v0", "--double", "--out", "never"]))
"""


@pytest.mark.parametrize("form", ["mapping", "EnvCard"])
def test_a_malformed_card_names_the_package_and_the_field(rod_python, tmp_path, form) -> None:
    """A second plugin registered in-process declares ``double="yes"``. As a mapping, the
    card is refused at load (a warning naming the package and the field) and the command
    on its id repeats the refusal in one line; written as ``EnvCard(...)`` in the hook, the
    card's own check stops the hook, and the load warning names both. Cost: about 4 s each."""
    script = tmp_path / "bad_card.py"
    script.write_text(_BAD_PLUGIN)
    result = _run([rod_python, script, form], cwd=tmp_path, check=False)
    loaded, *refusal = result.stderr.strip().splitlines()
    assert "'bad-card-package'" in loaded and "'double'" in loaded, loaded
    if form == "mapping":
        result.stderr = "\n".join(refusal)
        _refused(result, "badlab/BadRod-v0", "'bad-card-package'", "'double'", "str 'yes'")
    else:
        assert result.returncode == 0 and not refusal, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad_card.py"]


# -- the real stack ----------------------------------------------------------------------------


@pytest.mark.precice
@pytest.mark.timeout(900)
def test_train_and_evaluate_on_real_precice(rod_python: Path, tmp_path) -> None:
    """The same commands without ``--double``: the rod couples through real preCICE (its log
    says so), and the policy's tracking errors from the held-out starts are those of the
    same policy on the double, start by start: the double is faithful on this case.

    Cost: about 35 s (40 training actions, then two evaluations of three episodes).
    """
    why = _real_precice_importable()
    if why is not None:
        pytest.skip(f"cannot import pyprecice (preCICE): {why}")
    gymprecice(rod_python, "train", "heated-rod", "--timesteps", 40, *TINY_PPO,
               "--out", "run", cwd=tmp_path)  # fmt: skip
    solver_log = tmp_path / "run" / "envs" / "env_0" / "rod" / "solver.log"
    assert "This is preCICE version 3" in solver_log.read_text()
    errors = {}
    for where, flags in (("real", []), ("double", ["--double"])):
        gymprecice(rod_python, "evaluate", "heated-rod", *flags, "--policy", "run",
                   "--all-starts", "--out", where, cwd=tmp_path)  # fmt: skip
        summary = json.loads((tmp_path / where / "summary.json").read_text())
        errors[where] = [e["mean_tracking_error"] for e in summary["episodes"]]
    assert len(errors["real"]) == 3
    assert errors["real"] == pytest.approx(errors["double"], rel=1e-6)
