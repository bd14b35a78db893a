"""``reset(options={"split": "eval", "start": k})`` takes the k-th held-out snapshot: an
evaluation runs every held-out start once instead of drawing them (no OpenFOAM needed)."""

from __future__ import annotations

import numpy as np
import pytest

from gymprecice.plugin.errors import ConfigError
from gymprecice_openfoam.case import PreparedCase, choose_start, split_snapshots

TIMES = ["4.7", "4.74", "4.78", "4.82", "4.86", "4.9", "4.94", "4.98"]


def _state() -> PreparedCase:
    return PreparedCase(
        application="pimpleFoam",
        np=1,
        initial_time="4.98",
        snapshots=list(TIMES),
        split=split_snapshots(list(TIMES), {}),
    )


def test_every_fourth_snapshot_is_held_out() -> None:
    assert split_snapshots(list(TIMES), {})["eval"] == ["4.82", "4.98"]


def test_start_index_takes_each_held_out_snapshot_whatever_the_seed() -> None:
    state = _state()
    for seed in range(3):
        rng = np.random.default_rng(seed)
        assert [choose_start(state, rng, "eval", k) for k in (0, 1)] == ["4.82", "4.98"]


def test_without_a_start_index_the_snapshot_is_drawn_from_the_split() -> None:
    drawn = {choose_start(_state(), np.random.default_rng(s), "eval") for s in range(20)}
    assert drawn == {"4.82", "4.98"}


@pytest.mark.parametrize(
    ("start", "message"), [(2, "use 0 to 1"), (-1, "use 0 to 1"), ("a", "integer")]
)
def test_a_start_index_out_of_range_is_refused_naming_the_range(
    start: object, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        choose_start(_state(), None, "eval", start)  # type: ignore[arg-type]
