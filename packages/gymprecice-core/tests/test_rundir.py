from __future__ import annotations

from pathlib import Path

import pytest

from gymprecice.env import rundir
from gymprecice.env.config import load_config
from gymprecice.env.rundir import create_run_directory
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import load_precice_config


def test_each_env_gets_real_copies_and_its_own_exchange_dir(case_dir: Path, tmp_path: Path) -> None:
    cfg = load_config(case_dir)
    runs = [create_run_directory(cfg, i, tmp_path / "runs") for i in range(2)]
    assert runs[0].root != runs[1].root
    for run in runs:
        copied = run.root / "fluid" / "input.txt"
        assert copied.read_text() == "pristine\n" and not copied.is_symlink()
        xml = load_precice_config(run.precice_config_file)
        assert xml.m2n[0].exchange_directory == str(run.exchange_dir)
        assert run.exchange_dir.is_dir()
    (runs[0].root / "fluid" / "input.txt").write_text("changed\n")
    assert (case_dir / "fluid" / "input.txt").read_text() == "pristine\n"
    assert 'exchange-directory=""' in (case_dir / "precice-config.xml").read_text()


def test_recreating_replaces_only_gymprecice_dirs(case_dir: Path, tmp_path: Path) -> None:
    cfg = load_config(case_dir)
    run = create_run_directory(cfg, 0, tmp_path / "runs")
    (run.root / "stale").write_text("old episode")
    run = create_run_directory(cfg, 0, tmp_path / "runs")
    assert not (run.root / "stale").exists()
    foreign = tmp_path / "other" / "env_0"
    foreign.mkdir(parents=True)
    (foreign / "thesis.tex").write_text("precious")
    with pytest.raises(ConfigError, match="not made by gymprecice"):
        create_run_directory(cfg, 0, tmp_path / "other")
    assert (foreign / "thesis.tex").read_text() == "precious"


def test_run_root_inside_the_case_is_not_copied_recursively(case_dir: Path) -> None:
    cfg = load_config(case_dir)
    first = create_run_directory(cfg, 0, case_dir / "runs")
    second = create_run_directory(cfg, 1, case_dir / "runs")
    assert not (second.root / "runs").exists()
    assert (first.root / "fluid").is_dir()


def test_a_copy_cut_short_leaves_no_run_directory_and_the_next_run_makes_it(
    case_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A command killed while it copies the case (the sweep of a benchmark killed with
    SIGKILL) must leave nothing the next run would refuse as foreign."""
    cfg = load_config(case_dir)
    old = create_run_directory(cfg, 0, tmp_path / "runs")

    def killed(*args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(rundir, "write_with_exchange_directory", killed)
    with pytest.raises(KeyboardInterrupt):
        create_run_directory(cfg, 0, tmp_path / "runs")
    assert not old.root.exists()
    assert (tmp_path / "runs" / ".env_0.new" / "fluid").is_dir()  # the half-made copy
    monkeypatch.undo()
    run = create_run_directory(cfg, 0, tmp_path / "runs")
    assert (run.root / "fluid" / "input.txt").read_text() == "pristine\n"
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["env_0"]
