"""pyprecice is compiled once per preCICE build and Python, then installed from its wheel.

Every new virtual environment (a fresh clone's ``.venv``) needs pyprecice, and compiling it
takes most of a minute: ``gymprecice install`` keeps the wheel it built in the stack prefix,
keyed by preCICE's build record, and installs later environments from it. Here the build's
commands are recorded instead of run.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pytest

from gymprecice.tools import precice_install
from gymprecice.tools.stack import BuildContext, BuildError


def _prefix(tmp_path: Path, record: str = "3.4.1|sha|-DCMAKE_BUILD_TYPE=Release") -> Path:
    prefix = tmp_path / "stack"
    (prefix / "lib" / "pkgconfig").mkdir(parents=True)
    (prefix / "lib" / "libprecice.so").write_bytes(b"")
    (prefix / "lib" / "pkgconfig" / "libprecice.pc").write_text("")
    (prefix / "stamps").mkdir()
    (prefix / "stamps" / "precice.json").write_text(json.dumps({"key": record}))
    return prefix


class Recorder:
    """Stands for the build's subprocesses: `pip wheel` writes a wheel, the rest is noted."""

    def __init__(self) -> None:
        self.commands: list[list[str]] = []

    def __call__(self, ctx: BuildContext, argv, cwd, env=None) -> None:
        argv = [str(a) for a in argv]
        self.commands.append(argv)
        if "wheel" in argv:
            out = Path(argv[argv.index("--wheel-dir") + 1])
            out.mkdir(parents=True, exist_ok=True)
            (out / "pyprecice-3.4.0-cp311-cp311-linux_x86_64.whl").write_bytes(b"wheel")

    def compiled(self) -> bool:
        return any("--no-binary" in c for c in self.commands)


def _build(prefix: Path, tmp_path: Path, monkeypatch, recorder: Recorder, imports=True) -> None:
    step = next(s for s in precice_install.core_install_steps() if s.name == "pyprecice")
    work = Path(tempfile.mkdtemp(dir=tmp_path))
    ctx = BuildContext(step, prefix, work, tmp_path / "log", jobs=2, say=lambda _: None)
    monkeypatch.setattr(BuildContext, "run", lambda self, *args, **kw: recorder(self, *args, **kw))
    monkeypatch.setattr(precice_install.importlib.util, "find_spec", lambda name: object())
    answers = imports if isinstance(imports, list) else [imports] * 3
    replies = iter(answers)
    monkeypatch.setattr(
        precice_install,
        "probe_pyprecice",
        lambda python=None: (
            ("precice/__init__.py", "3.4.1")
            if next(replies)
            else (None, "ImportError: undefined symbol")
        ),
    )
    precice_install._build_pyprecice(ctx)


def test_the_second_environment_installs_the_wheel_the_first_compiled(tmp_path, monkeypatch):
    prefix = _prefix(tmp_path)
    first = Recorder()
    _build(prefix, tmp_path, monkeypatch, first)
    assert first.compiled()
    wheel_dir = precice_install._wheel_dir(prefix)
    assert [p.name for p in wheel_dir.iterdir()] == ["pyprecice-3.4.0-cp311-cp311-linux_x86_64.whl"]
    second = Recorder()
    _build(prefix, tmp_path, monkeypatch, second)
    assert not second.compiled()
    (install,) = second.commands
    assert install[-1] == str(wheel_dir / "pyprecice-3.4.0-cp311-cp311-linux_x86_64.whl")


def test_another_precice_build_gets_its_own_wheel(tmp_path):
    one = precice_install._wheel_dir(_prefix(tmp_path / "a"))
    other = precice_install._wheel_dir(_prefix(tmp_path / "b", record="3.4.1|sha|-DOTHER=ON"))
    assert one.name != other.name


def test_a_kept_wheel_that_does_not_import_is_compiled_afresh(tmp_path, monkeypatch):
    prefix = _prefix(tmp_path)
    _build(prefix, tmp_path, monkeypatch, Recorder())
    again = Recorder()
    _build(prefix, tmp_path, monkeypatch, again, imports=[False, True])
    assert again.compiled()
    assert len(list(precice_install._wheel_dir(prefix).glob("*.whl"))) == 1


def test_without_a_record_of_the_precice_build_nothing_is_kept(tmp_path, monkeypatch):
    prefix = _prefix(tmp_path)
    (prefix / "stamps" / "precice.json").unlink()
    recorder = Recorder()
    _build(prefix, tmp_path, monkeypatch, recorder)
    assert recorder.compiled()
    assert not (prefix / "wheels").exists()


def test_a_wheel_that_imports_nowhere_fails_the_step(tmp_path, monkeypatch):
    prefix = _prefix(tmp_path)
    with pytest.raises(BuildError, match="does not import"):
        _build(prefix, tmp_path, monkeypatch, Recorder(), imports=False)
