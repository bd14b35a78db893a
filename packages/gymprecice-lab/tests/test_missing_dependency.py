"""A lab command in an environment that lacks one of its modules: one line, nothing written.

pip installs the lab with Stable-Baselines3, torch and PyYAML, but an environment can still
lose one (a manual uninstall, a broken upgrade). The command must then say what to install,
exit 2 and leave no output directory, instead of a traceback after ``runs/`` was made.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from gymprecice.tools.cli import main


@pytest.mark.parametrize(
    ("command", "module"),
    [
        ("train", "yaml"),
        ("train", "torch"),
        ("evaluate", "stable_baselines3"),
    ],
)
def test_a_missing_module_is_one_line_and_nothing_is_written(
    command: str, module: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, module, None)  # `import module` now fails
    out = tmp_path / "out"
    argv = [command, "jet-cylinder-fast", "--double", "--out", str(out)]
    if command == "evaluate":
        argv += ["--policy", "shipped"]
    status = main(argv)
    captured = capsys.readouterr()
    assert status == 2, captured
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith(f"gymprecice {command}: error: {module} is not installed: ")
    assert "pip install '" in captured.err
    assert list(tmp_path.iterdir()) == []  # no --out, no runs/, no gymprecice-runs/
