"""``python -m gymprecice_tutorials.turek_hron.check_starts``: the comparison of an episode
from a start with the uncontrolled series, the swing's figures, and bad input refused in
one line before anything runs. (The episode itself needs the real stack and a full
library: docs/validation.md has the run; tests/test_fsi3_real.py restarts one from the
smoke library.)"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gymprecice_tutorials.turek_hron import check_starts, starts


def _series(start: float, seconds: float, shift: float = 0.0) -> dict[str, np.ndarray]:
    """A swing at 5.3 Hz sampled every 2 ms, ``shift`` seconds late."""
    time = np.round(np.arange(0.0, seconds + 1e-9, 0.002), 6) + start
    phase = 2 * np.pi * 5.3 * (time - shift)
    return {
        "time": time,
        "tip_dx": -0.0027 + 0.0025 * np.cos(2 * phase),
        "tip_dy": 0.032 * np.sin(phase),
        "drag": 457.0 + 22.0 * np.cos(2 * phase),
        "lift": 150.0 * np.sin(phase),
    }


def test_an_episode_that_repeats_the_series_passes_and_a_kicked_one_misses() -> None:
    series = _series(6.0, 0.22)
    # the same swing, its times counted from the start at 6 s
    time = series["time"][:101] - 6.0
    episode = {"time": time}
    for name in ("tip_dx", "tip_dy", "drag", "lift"):
        episode[name] = np.interp(time + 6.0, series["time"], series[name])
    figures = check_starts.compare_with_series(episode, series, 6.0)
    assert all(f["ok"] for f in figures.values()), figures
    # time 0 is left out: an episode's forces begin at its first window's end
    episode["lift"][0] += 1e3
    assert check_starts.compare_with_series(episode, series, 6.0)["lift"]["ok"]
    # a restart that throws the bar back towards rest, for a few windows
    kicked = {k: v.copy() for k, v in episode.items()}
    kicked["tip_dy"][1:4] *= 0.1
    figures = check_starts.compare_with_series(kicked, series, 6.0)
    assert not figures["tip_dy"]["ok"]
    assert figures["tip_dy"]["max_departure"] == pytest.approx(
        np.max(np.abs(0.9 * episode["tip_dy"][1:4]))
    )


def test_the_swing_s_range_and_up_crossings_over_a_span() -> None:
    late = _series(5.9, 0.4, shift=0.0126)
    swing = check_starts.swing_of(late["time"], late["tip_dy"], (6.0, 6.22))
    assert swing["tip_dy_max"] == pytest.approx(0.032, rel=1e-2)
    assert swing["tip_dy_min"] == pytest.approx(-0.032, rel=1e-2)
    # sin crosses upwards at whole periods after the shift: 6.0504 and 6.2391 s
    expected = [0.0126 + k / 5.3 for k in range(40) if 6.0 <= 0.0126 + k / 5.3 <= 6.22]
    assert swing["up_crossings"] == pytest.approx(expected, abs=1e-4)


def _library(root: Path, end: float = 6.22) -> Path:
    times = ["6", "6.02", "6.04", "6.06"]
    for name in times:
        (root / "fluid" / name).mkdir(parents=True)
        (root / "solid").mkdir(exist_ok=True)
        (root / "solid" / f"state-{name}.npz").write_bytes(b"state")
    index = {"resolution": "coarse", "time_step": 0.002, "degree": 2, "times": times}
    index["split"] = starts.split(times)
    (root / starts.INDEX).write_text(json.dumps(index))
    np.savez(root / starts.UNCONTROLLED, **_series(6.0, end - 6.0))
    return root


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--start", "6.05"], "no start at 6.05 s in"),
        (["--start", "6.06", "--time", "0.2"], "goes past it; give a shorter --time"),
        (["--against", "{tmp}/nowhere"], "no watch point log of the FEniCS bar; run `python -m"),
    ],
)
def test_bad_input_is_refused_in_one_line_before_any_solver_starts(
    tmp_path, capsys, args, message
) -> None:
    library = _library(tmp_path / "lib")
    out = tmp_path / "runs"
    argv = ["--starts", str(library), "--out", str(out)]
    argv += [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert check_starts.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists()


def test_a_missing_library_names_the_command_that_builds_one(tmp_path, capsys) -> None:
    assert check_starts.main(["--starts", str(tmp_path / "none")]) == 2
    assert "build_starts --out" in capsys.readouterr().err
