"""``gymprecice plot``'s training figure: a mean band over seeds, never over algorithms."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gymprecice_lab import plots


def _run(root: Path, name: str, algo: str, offset: float) -> Path:
    run = root / name
    (run / "monitor").mkdir(parents=True)
    rows = "\n".join(f"{-50 + k + offset},20,{k}" for k in range(40))
    (run / "monitor" / "env_0.monitor.csv").write_text('#{"t_start": 0}\nr,l,t\n' + rows + "\n")
    (run / "hyperparams.json").write_text(json.dumps({"algo": algo}))
    return run


@pytest.mark.parametrize(("algos", "band"), [(("sac", "sac"), True), (("sac", "ppo"), False)])
def test_the_mean_band_is_drawn_over_seeds_of_one_algorithm_only(
    tmp_path: Path, monkeypatch, algos: tuple[str, str], band: bool
) -> None:
    runs = [_run(tmp_path, f"run{k}", algo, k) for k, algo in enumerate(algos)]
    labels: list[str] = []
    original = plots._save

    def spy(fig, plt, target):
        labels.extend(t.get_text() for t in fig.axes[0].get_legend().get_texts())
        return original(fig, plt, target)

    monkeypatch.setattr(plots, "_save", spy)
    assert plots.plot_reward(runs, tmp_path / "out") is not None
    assert any(label.startswith("mean of 2 runs") for label in labels) is band, labels
