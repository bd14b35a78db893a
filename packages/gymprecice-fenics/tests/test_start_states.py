"""Option ``starts``: every reset puts the episode's saved solid state at ``start_file``.

The start is chosen as the OpenFOAM plugin chooses its snapshot (same split, same index,
same draw for the same seed), so a solid restarting from a saved state starts from the
fluid's snapshot's moment. No FEniCS needed: the hooks only copy files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import ConfigError
from gymprecice_fenics import plugin

#: The fluid's snapshot times, in time order, and the solid state saved at each.
TIMES = ["4.7", "4.74", "4.78", "4.82", "4.86", "4.9"]
TRAIN = ["4.7", "4.74", "4.78", "4.86"]
EVAL = ["4.82", "4.9"]


def _file(time: str) -> str:
    return f"starts/state-{time}.npz"


def _write_states(case: Path) -> None:
    folder = case / "solid-fenics" / "starts"
    folder.mkdir()
    for time in TIMES:
        (folder / f"state-{time}.npz").write_text(time)


def _starts(validation: list[str] | None = None) -> dict[str, list[str]]:
    starts = {"train": [_file(t) for t in TRAIN], "eval": [_file(t) for t in EVAL]}
    if validation is not None:
        starts["validation"] = [_file(t) for t in validation]
    return starts


def _reset(solver, seed: int = 0, **reset_options) -> str:
    solver.rng = np.random.default_rng(seed)
    solver.reset_options = dict(reset_options)
    assert plugin.gymprecice_reset_case(solver) is True
    start_file = solver.options.get("start_file", "start-state.npz")
    return (solver.run_dir / start_file).read_text()


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({"split": "eval", "start": 0}, "4.82"),
        ({"split": "eval", "start": 1}, "4.9"),
        ({"start": 2}, "4.78"),  # no split: the train split
        ({"split": "train", "start": 3}, "4.86"),
        ({"split": "validation", "start": 0}, "4.74"),
        ({"split": "all", "start": 4}, "4.82"),  # train's, then eval's, in the order given
    ],
)
def test_reset_copies_the_start_of_the_split_and_index_asked_for(
    make_fenics_solver, case: Path, options: dict, expected: str
) -> None:
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts(validation=["4.74"])})
    assert plugin.gymprecice_validate_case(solver) == []
    assert _reset(solver, **options) == expected


def test_each_reset_replaces_the_last_episodes_start_without_writing_through_a_link(
    make_fenics_solver, case: Path
) -> None:
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts(), "start_file": "restart/state.npz"})
    assert _reset(solver, split="eval", start=0) == "4.82"
    target = solver.run_dir / "restart" / "state.npz"
    target.unlink()
    pristine = case / "solid-fenics" / _file("4.7")
    target.symlink_to(pristine)
    assert _reset(solver, split="eval", start=1) == "4.9"
    assert not target.is_symlink() and pristine.read_text() == "4.7"
    assert sorted(p.name for p in target.parent.iterdir()) == ["state.npz"]


def test_an_absolute_start_file_is_taken_as_it_is(make_fenics_solver, tmp_path: Path) -> None:
    saved = tmp_path / "elsewhere.npz"
    saved.write_text("elsewhere")
    solver = make_fenics_solver(options={"starts": {"train": [str(saved)], "eval": [str(saved)]}})
    assert plugin.gymprecice_validate_case(solver) == []
    assert _reset(solver) == "elsewhere"


def test_without_a_start_index_the_start_is_drawn_with_the_solvers_rng(
    make_fenics_solver, case: Path
) -> None:
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts()})
    drawn = set()
    for seed in range(20):
        expected = EVAL[int(np.random.default_rng(seed).integers(len(EVAL)))]
        chosen = _reset(solver, seed, split="eval")
        assert chosen == expected
        drawn.add(chosen)
    assert drawn == set(EVAL)


@pytest.mark.parametrize("split", [None, "train", "eval", "all"])
def test_the_start_is_the_openfoam_plugins_snapshot_for_the_same_seed(
    make_fenics_solver, case: Path, split: str | None
) -> None:
    """A fluid's snapshots and the solid's states given in the same (time) order: both
    solvers, seeded alike by core, start every episode from the same moment."""
    openfoam = pytest.importorskip("gymprecice_openfoam.case")
    state = openfoam.PreparedCase(
        application="pimpleFoam",
        np=1,
        initial_time="4.9",
        snapshots=[*TRAIN, *EVAL],
        split={"train": list(TRAIN), "eval": list(EVAL)},
    )
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts()})
    for seed in range(12):
        fluid = openfoam.choose_start(state, np.random.default_rng(seed), split)
        assert _reset(solver, seed, split=split) == fluid
    if split == "all":
        return  # an index over all counts train's files, then eval's (OpenFOAM: time order)
    pool = {None: TRAIN, "train": TRAIN, "eval": EVAL}[split]
    for k in range(len(pool)):
        fluid = openfoam.choose_start(state, None, split, k)
        assert _reset(solver, split=split, start=k) == fluid


def test_without_starts_reset_writes_no_start_file(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    solver.reset_options = {"split": "eval", "start": 0}
    assert plugin.gymprecice_reset_case(solver) is True
    assert not (solver.run_dir / "start-state.npz").exists()


def test_a_missing_start_file_is_named_with_the_option_and_the_fix(
    make_fenics_solver, case: Path
) -> None:
    _write_states(case)
    starts = _starts()
    starts["eval"][1] = "starts/state-9.npz"
    solver = make_fenics_solver(options={"starts": starts})
    [problem] = plugin.gymprecice_validate_case(solver)
    assert "options.starts['eval'][1]" in problem
    assert str(case / "solid-fenics" / "starts" / "state-9.npz") in problem
    assert "relative to it) or give its absolute path" in problem
    with pytest.raises(ConfigError, match=r"starts\['eval'\]\[1\]"):
        plugin.gymprecice_prepare_case(solver)


@pytest.mark.parametrize(
    ("starts", "start_file", "message"),
    [
        (["a.npz"], None, "options.starts must be"),
        ({"train": ["a.npz"]}, None, r"missing or empty \['eval'\]"),
        ({"train": ["a.npz"], "eval": ["a.npz"], "test": []}, None, r"unknown \['test'\]"),
        ({"train": "a.npz", "eval": ["a.npz"]}, None, "must be a list of files"),
        (None, "../outside.npz", "start_file must be a file name relative to the run"),
        (None, "/tmp/x.npz", "start_file must be a file name relative to the run"),
    ],
)
def test_a_malformed_starts_option_is_refused(
    make_fenics_solver, case: Path, starts, start_file, message: str
) -> None:
    (case / "solid-fenics" / "a.npz").write_text("a")
    options: dict = {"starts": starts}
    if start_file is not None:
        options["start_file"] = start_file
    solver = make_fenics_solver(options=options)
    [problem] = plugin.gymprecice_validate_case(solver)
    assert "solid" in problem
    with pytest.raises(ConfigError, match=message):
        plugin.gymprecice_reset_case(solver)


def test_a_start_index_out_of_range_is_refused_naming_the_range(
    make_fenics_solver, case: Path
) -> None:
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts()})
    for start in (2, -1):
        solver.reset_options = {"split": "eval", "start": start}
        with pytest.raises(ConfigError, match=r"split 'eval' has 2 start\(s\).*use 0 to 1"):
            plugin.gymprecice_reset_case(solver)
    solver.reset_options = {"split": "eval", "start": "first"}
    with pytest.raises(ConfigError, match="must be an integer index"):
        plugin.gymprecice_reset_case(solver)
    assert not (solver.run_dir / "start-state.npz").exists()


def test_a_validation_split_the_starts_do_not_have_is_refused_with_the_fix(
    make_fenics_solver, case: Path
) -> None:
    _write_states(case)
    solver = make_fenics_solver(options={"starts": _starts()})
    solver.reset_options = {"split": "validation"}
    with pytest.raises(ConfigError, match=r"no validation starts; give .*'validation' list"):
        plugin.gymprecice_reset_case(solver)
