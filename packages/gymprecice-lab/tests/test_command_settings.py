"""Each lab command's settings: the parsed command line, typed and frozen, built once.

The ``argparse.Namespace`` stops at the command line (:mod:`gymprecice_lab.cli.settings`);
what a command computes from its options (the env, its constructor keyword arguments)
is computed once.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from gymprecice.tools.cli import build_parser, main
from gymprecice_lab.cli.settings import SETTINGS, from_argv, from_namespace

LAB = Path(__file__).resolve().parents[1] / "src" / "gymprecice_lab"

#: A command line of each lab command that has options (the least it takes).
ARGV = {
    "train": ["train", "quickstart", "--wrap", "delay:steps=1"],
    "tune": ["tune", "quickstart", "--params", "gamma,learning_rate"],
    "evaluate": ["evaluate", "quickstart"],
    "baseline": ["baseline", "quickstart"],
    "open-loop": ["open-loop", "quickstart"],
    "feedback": ["feedback", "quickstart"],
    "sweep": ["sweep", "quickstart"],
    "compare": ["compare", "a", "b"],
    "plot": ["plot", "a"],
    "benchmark": ["benchmark", "quickstart", "--train-args", "--gamma 0.9"],
    "time-to-floor": ["time-to-floor", "a"],
    "ship-policy": ["ship-policy", "a"],
}


def namespace_parameters(root: Path) -> list[str]:
    """Every function parameter annotated ``argparse.Namespace`` (or ``Namespace``) in
    the modules under ``root`` outside its ``cli/`` (``path:line function(parameter)``)."""
    found = []
    for path in sorted(root.rglob("*.py")):
        relative = path.relative_to(root)
        if relative.parts[0] == "cli":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            arguments = node.args
            for arg in (
                *arguments.posonlyargs,
                *arguments.args,
                *arguments.kwonlyargs,
                *(a for a in (arguments.vararg, arguments.kwarg) if a is not None),
            ):
                annotation = ast.unparse(arg.annotation) if arg.annotation is not None else ""
                if annotation.split(".")[-1].strip("'\"") == "Namespace":
                    name = getattr(node, "name", "<lambda>")
                    found.append(f"{relative}:{node.lineno} {name}({arg.arg})")
    return found


def test_no_lab_module_outside_the_cli_takes_a_namespace() -> None:
    assert namespace_parameters(LAB) == []


def test_the_namespace_check_can_fail(tmp_path: Path) -> None:
    (tmp_path / "cli").mkdir()
    (tmp_path / "cli" / "parse.py").write_text(
        "import argparse\ndef run(ns: argparse.Namespace) -> int: ...\n"
    )
    (tmp_path / "work.py").write_text(
        "import argparse\nfrom argparse import Namespace\n"
        "def one(args: argparse.Namespace) -> int: ...\n"
        "def two(x: int, *, ns: 'Namespace') -> int: ...\n"
        "def three(args) -> int: ...\n"
    )
    assert namespace_parameters(tmp_path) == ["work.py:3 one(args)", "work.py:4 two(ns)"]


def test_every_lab_command_with_options_has_settings() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    runs = {name: p.get_default("func") for name, p in sub.choices.items()}
    lab = {
        name
        for name, run in runs.items()
        if "gymprecice_lab" in getattr(run, "func", run).__module__
    }
    assert lab == {*SETTINGS, "policies"}
    assert set(ARGV) == set(SETTINGS)


@pytest.mark.parametrize("command", sorted(ARGV))
def test_every_option_is_a_typed_field_of_a_frozen_settings(command: str) -> None:
    ns = build_parser().parse_args(ARGV[command])
    settings = from_namespace(command, ns)
    fields = {f.name for f in dataclasses.fields(settings)}
    options = set(vars(ns)) - {"func", "command"}
    assert options <= fields, options - fields
    for name in options:
        value = getattr(ns, name)
        assert getattr(settings, name) == (tuple(value) if isinstance(value, list) else value)
    if "command" in fields:
        assert settings.command == command
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(settings, next(iter(options)), None)


def test_lists_become_tuples() -> None:
    wrap = from_argv(ARGV["train"]).wrap
    assert isinstance(wrap, tuple) and len(wrap) == 1
    assert from_argv(ARGV["tune"]).params == ("gamma", "learning_rate")
    assert from_argv(ARGV["benchmark"]).train_args == ("--gamma 0.9",)
    assert from_argv(ARGV["compare"]).runs == (Path("a"), Path("b"))


def test_an_option_without_a_field_is_refused_at_once() -> None:
    ns = build_parser().parse_args(ARGV["plot"])
    ns.colour = "red"
    with pytest.raises(TypeError, match="PlotSettings has no field for the option"):
        from_namespace("plot", ns)
    del ns.colour
    del ns.dpi
    with pytest.raises(TypeError, match="dpi"):
        from_namespace("plot", ns)


def test_a_rollout_command_leaves_the_other_controllers_options_unasked() -> None:
    baseline = from_argv(["baseline", "quickstart", "--episodes", "2"])
    assert (baseline.policy, baseline.model, baseline.amplitude, baseline.law) == (
        None,
        "kept",
        None,
        None,
    )
    assert from_argv(["open-loop", "quickstart", "--phase", "1"]).phase == 1.0


def test_derived_values_are_computed_once(tmp_path: Path, monkeypatch) -> None:
    from gymprecice_lab.common import command_settings

    calls = []
    build = command_settings.build_env_kwargs

    def counted(*args: Any) -> dict[str, Any]:
        calls.append(args)
        return build(*args)

    monkeypatch.setattr(command_settings, "build_env_kwargs", counted)
    settings = from_argv(["sweep", "quickstart", "--double", "--out", str(tmp_path / "s")])
    assert settings.run_dir == (tmp_path / "s").resolve()
    assert settings.lab_env is settings.lab_env
    kwargs = settings.constructor_kwargs
    assert settings.constructor_kwargs is kwargs and len(calls) == 1
    assert kwargs["double"] is True and kwargs["episode_time"] == 2.0  # the rollout horizon
    assert kwargs["run_root"] == str((tmp_path / "s" / "envs").resolve())


def test_train_builds_the_env_kwargs_once(tmp_path: Path, monkeypatch) -> None:
    """The env's keyword arguments are built once: checked, probed, recorded and trained
    with the same ones (train used to build them twice)."""
    from gymprecice_lab.common import command_settings
    from gymprecice_lab.training import train

    calls = []
    build = command_settings.build_env_kwargs
    monkeypatch.setattr(
        command_settings, "build_env_kwargs", lambda *a: calls.append(a) or build(*a)
    )
    trained_with = []

    def no_training(env: Any, out: Path, kwargs: dict[str, Any], *a: Any, **k: Any) -> dict:
        trained_with.append(kwargs)
        return {"interrupted": None, "timesteps": 0, "model": str(out / "model.zip")}

    monkeypatch.setattr(train, "train", no_training)
    out = tmp_path / "train"
    argv = ["train", "quickstart", "--double", "--episode-time", "0.1", "--out", str(out)]
    assert main(argv) == 0
    assert len(calls) == 1
    manifest = json.loads((out / "manifest.json").read_text())
    assert trained_with == [manifest["settings"]["env_kwargs"]]
    assert manifest["settings"]["env_kwargs"]["episode_time"] == 0.1


def test_the_benchmark_fills_in_its_feedback_defaults_in_new_settings() -> None:
    from gymprecice_lab.benchmarking.checks import DEFAULT_FEEDBACK_GAINS, resolve_feedback
    from gymprecice_lab.common.registered_env import find_lab_env

    given = from_argv(["benchmark", "jet-cylinder-fast", "--double"])
    resolved = resolve_feedback(given, find_lab_env("jet-cylinder-fast"))
    assert given.feedback_gains is None  # as typed
    assert resolved.feedback_gains == DEFAULT_FEEDBACK_GAINS
    assert dataclasses.replace(resolved, feedback_gains=None) == given
