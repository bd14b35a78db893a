"""scripts/robustness_study.py: runs only what is missing, then tabulates and draws."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "robustness_study.py"


@pytest.fixture
def study():
    spec = importlib.util.spec_from_file_location("robustness_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _summary(run: Path, cd: float, cl: float) -> None:
    run.mkdir(parents=True)
    change = {"series_mean_Cd": cd, "series_mean_abs_Cl": cl}
    (run / "summary.json").write_text(json.dumps({"change_percent": change}))


def test_a_finished_study_is_reused_and_drawn(study, tmp_path: Path, monkeypatch) -> None:
    _summary(tmp_path / "baseline", 0.0, 0.0)
    _summary(tmp_path / "sensor-noise-0", -6.86, -70.5)
    _summary(tmp_path / "sensor-noise-0.1", -6.92, -68.7)
    monkeypatch.setattr(study, "_gymprecice", lambda *a: pytest.fail(f"ran {a}"))
    assert study.main(["--out", str(tmp_path), "--levels", "0", "0.1"]) == 0
    rows = json.loads((tmp_path / "study.json").read_text())
    assert [r["std"] for r in rows] == [0.0, 0.1]
    assert rows[1]["mean_Cd_change_percent"] == -6.92
    assert (tmp_path / "figure.png").stat().st_size > 0


def test_a_missing_level_is_evaluated_with_its_wrapper(study, tmp_path: Path, monkeypatch) -> None:
    _summary(tmp_path / "baseline", 0.0, 0.0)
    ran = []

    def fake(*args: str) -> None:
        ran.append(args)
        _summary(Path(args[args.index("--out") + 1]), -6.0, -60.0)

    monkeypatch.setattr(study, "_gymprecice", fake)
    study.study("jet-cylinder-fast", "shipped", [0.2], tmp_path, seed=0)
    [args] = ran
    assert args[:2] == ("evaluate", "jet-cylinder-fast")
    assert "sensor_noise:std=0.2,mode=relative" in args


def test_negative_levels_are_refused(study, tmp_path: Path) -> None:
    with pytest.raises(SystemExit):
        study.main(["--out", str(tmp_path), "--levels", "-0.1"])
