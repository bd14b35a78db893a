"""FSI3's starts from the swinging state: the library, and the case of episodes from it.

The library is built by a coupled run (tests/test_fsi3_real.py runs the smoke size);
here a library is laid out by hand, as :func:`gymprecice_tutorials.turek_hron.build_starts.build`
leaves one, and what an env makes of it is checked without solvers.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from gymprecice_tutorials.turek_hron import starts
from gymprecice_tutorials.turek_hron.case import case_files
from gymprecice_tutorials.turek_hron.environment import START_FILE, TurekHronEnv

TIMES = ["6", "6.02", "6.04", "6.06", "6.08", "6.1", "6.12", "6.14"]


def _library(root: Path, times: list[str] = TIMES, **case: object) -> Path:
    """A library as ``build`` leaves one, with placeholder states."""
    for name in times:
        fluid = root / "fluid" / name
        (fluid / "polyMesh").mkdir(parents=True)
        (fluid / "U").write_text(f"U at {name}\n")
        (fluid / "polyMesh" / "points").write_text(f"points at {name}\n")
        (root / "solid").mkdir(exist_ok=True)
        (root / "solid" / f"state-{name}.npz").write_bytes(b"state")
    index = {"resolution": "coarse", "time_step": 0.002, "degree": 2, "times": times}
    index.update(case)
    index["split"] = starts.split(times)
    (root / starts.INDEX).write_text(json.dumps(index))
    return root


def test_start_times_are_evenly_spaced_from_the_first_and_bad_ones_are_refused() -> None:
    assert starts.start_times(6.0, 3, 0.02) == [6.0, 6.02, 6.04]
    for bad in ((6.0, 0, 0.02), (6.0, 3, 0.0), (-1.0, 3, 0.02)):
        with pytest.raises(ValueError, match="count >= 1"):
            starts.start_times(*bad)


def test_a_library_splits_its_starts_into_held_out_validation_and_training(tmp_path) -> None:
    library = starts.load(_library(tmp_path / "lib"))
    split = library.split
    assert sorted(split) == ["eval", "train", "validation"]
    every = [name for names in split.values() for name in names]
    assert sorted(every, key=float) == TIMES  # each start in exactly one split
    assert split["eval"] and split["validation"] and split["train"]


def test_a_missing_or_incomplete_library_names_the_command_that_builds_one(tmp_path) -> None:
    with pytest.raises(
        FileNotFoundError, match=r"gymprecice_tutorials\.turek_hron\.build_starts --out"
    ):
        starts.load(tmp_path / "nowhere")
    root = _library(tmp_path / "lib")
    (root / "solid" / "state-6.04.npz").unlink()
    with pytest.raises(FileNotFoundError, match=r"state-6\.04\.npz"):
        starts.load(root)


def test_a_library_of_another_case_is_refused_naming_how_to_build_this_ones(tmp_path) -> None:
    library = starts.load(_library(tmp_path / "lib", resolution="medium"))
    with pytest.raises(ValueError, match=r"--resolution coarse --time-step 0\.002 --degree 2"):
        library.check("coarse", 0.002, 2)
    library.check("medium", 0.002, 2)  # its own case passes


def test_a_case_from_starts_holds_every_fluid_state_and_hands_both_solvers_one_split(
    tmp_path,
) -> None:
    library = starts.load(_library(tmp_path / "lib"))
    files = TurekHronEnv._files_from_starts(library, "coarse", 0.002, 0.5, 2, 0.02, "fenics")
    for name in TIMES:
        assert files[f"fluid-openfoam/{name}/U"] == f"U at {name}\n"
        assert files[f"fluid-openfoam/{name}/polyMesh/points"] == f"points at {name}\n"
    solvers = json.loads(files["gymprecice-config.json"])["physics_simulation_engine"]["solvers"]
    snapshots = solvers["fluid"]["options"]["snapshots"]
    states = solvers["solid"]["options"]["starts"]
    assert solvers["solid"]["kind"] == "fenics"
    assert solvers["solid"]["options"]["start_file"] == START_FILE
    assert set(snapshots) == set(states) == set(library.split)
    for split, names in library.split.items():
        # the k-th start of a split is the same time for the fluid and the bar
        assert snapshots[split] == [float(n) for n in names]
        assert [Path(p).name for p in states[split]] == [f"state-{n}.npz" for n in names]
    bar = json.loads(files["solid-fenics/solid.json"])
    assert bar["start_state"] == START_FILE
    # the fluid restarts on its deformed mesh, but gives preCICE the bar's surface at rest,
    # where the FEniCS bar's own mesh is (the adapter's default kicks a deformed start)
    assert re.search(
        r"^\s*restartFromDeformed\s+false;", files["fluid-openfoam/system/preciceDict"], re.M
    )
    # the first iterate from a saved state is not relaxed towards the zeros preCICE keeps
    # as its previous iterate (the packaged 0.1 threw a swinging bar back towards rest)
    assert files["precice-config.xml"].count('<initial-relaxation value="1" />') == 1
    assert 'initial-relaxation value="0.1"' in case_files("coarse")["precice-config.xml"]
    # an episode lasts episode_time from its start: the coupling's max-time
    assert files["precice-config.xml"].count('<max-time value="0.5" />') == 2


def test_starts_with_the_dealii_solid_are_refused_before_any_case_is_written(tmp_path) -> None:
    library = starts.load(_library(tmp_path / "lib"))
    with pytest.raises(ValueError, match="solid='fenics'"):
        TurekHronEnv._files_from_starts(library, "coarse", 0.002, 0.5, 2, 0.02, "dealii")
    with pytest.raises(ValueError, match="solid='fenics'"):
        TurekHronEnv(starts=library.path, solid="dealii", run_root=tmp_path / "runs")
    assert not (tmp_path / "runs").exists()


def test_the_build_runs_save_the_states_a_library_needs() -> None:
    """What build asks of the case: the bar saves its state at the start times and the
    fluid writes every spacing, keeping the last starts (and one more)."""
    files = case_files(
        "coarse",
        0.002,
        6.14,
        2,
        0.02,
        "fenics",
        solid_settings={"save_dir": "states", "save_times": [6.0, 6.02]},
        fluid_writes=(0.02, 9),
    )
    bar = json.loads(files["solid-fenics/solid.json"])
    assert bar["save_dir"] == "states" and bar["save_times"] == [6.0, 6.02]
    control = files["fluid-openfoam/system/controlDict"]
    assert "writeInterval   0.02;" in control and "purgeWrite      9;" in control
    with pytest.raises(ValueError, match="FEniCS bar"):
        case_files("coarse", solid="dealii", solid_settings={"save_dir": "states"})


def test_the_build_checkpoints_on_the_starts_grid_before_the_first_start() -> None:
    from gymprecice_tutorials.turek_hron.build_starts import checkpoint_times

    assert checkpoint_times(6.0, 1.0, 0.02) == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert checkpoint_times(6.5, 1.0, 0.02) == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    assert checkpoint_times(0.02, 0.01, 0.01) == [0.01]  # --smoke
    assert checkpoint_times(6.0, 0.0, 0.02) == []  # none asked for
    with pytest.raises(ValueError, match="whole number of --spacing"):
        checkpoint_times(6.0, 0.25, 0.02)


def test_each_solver_is_told_the_start_by_the_split_that_holds_it(tmp_path, monkeypatch) -> None:
    """The env chooses the start and hands both solvers its own split and index, so that
    'all' (in time order for the fluid, in the splits' order for the bar) and a drawn
    start mean one time for both."""
    from gymprecice.env.core import Adapter

    library = starts.load(_library(tmp_path / "lib"))
    told: list[dict] = []

    def reset(self, *, seed=None, options=None):
        told.append(dict(options))
        return np.zeros(2, np.float32), {}

    monkeypatch.setattr(Adapter, "reset", reset)
    env = TurekHronEnv(starts=library.path, run_root=tmp_path / "runs")
    for k, name in enumerate(TIMES):
        _, info = env.reset(options={"split": "all", "start": k})
        own = told[-1]
        assert library.split[own["split"]][own["start"]] == name
        assert info["start"] == {"split": "all", "index": k, "time": name}
    _, info = env.reset(seed=7)  # a training start, drawn from the seed
    assert told[-1]["split"] == "train" and info["start"]["time"] in library.split["train"]
    assert env.reset(seed=7)[1]["start"] == info["start"]  # the same seed, the same start
    assert env.held_out_starts == tuple(f"t = {n} s" for n in library.split["eval"])
    with pytest.raises(ValueError, match="use 0 to"):
        env.reset(options={"split": "eval", "start": 99})
    with pytest.raises(ValueError, match="splits"):
        env.reset(options={"split": "test"})


def test_the_build_refuses_a_folder_in_use_before_running_anything(tmp_path) -> None:
    from gymprecice_tutorials.turek_hron.build_starts import build

    library = _library(tmp_path / "lib")
    with pytest.raises(FileExistsError, match="a library is already there"):
        build(library)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(FileExistsError, match="not empty"):
        build(tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
    assert not (tmp_path / ".mine-run").exists()
