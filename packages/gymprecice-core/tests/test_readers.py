"""The rows of one step: the cut every reader makes at the step's end (gymprecice.readers)."""

from __future__ import annotations

import numpy as np

from gymprecice.plugin.readers import rows_through


def test_the_step_ends_with_the_row_at_its_time() -> None:
    assert rows_through([0.1, 0.2, 0.3, 0.4], 0.2) == 2
    assert rows_through(np.array([0.1, 0.2, 0.3]), 0.3) == 3
    assert rows_through([], 0.2) == 0


def test_a_time_printed_a_little_off_is_still_the_step_s_last_row() -> None:
    assert rows_through([0.1, 0.20000000001, 0.3], 0.2, 1e-9) == 2
    assert rows_through([0.1, 0.19999999999, 0.3], 0.2, 1e-9) == 2
    assert rows_through([0.1, 0.2000001, 0.3], 0.2, 1e-9) == 2  # none at 0.2: the next closes


def test_every_coupling_iteration_s_rows_belong_to_the_step() -> None:
    # an implicitly coupled solver writes the window's times again on each iteration
    times = [0.05, 0.1, 0.05, 0.1, 0.15, 0.2]
    assert rows_through(times, 0.1) == 4


def test_an_output_without_a_row_at_the_time_ends_the_step_with_the_next_row() -> None:
    assert rows_through([0.15, 0.25, 0.35], 0.2) == 2
    assert rows_through([0.25, 0.35], 0.2) == 1


def test_no_row_joins_a_step_whose_last_row_went_out_already() -> None:
    assert rows_through([0.3, 0.4], 0.2, handed_out=0.2) == 0
    assert rows_through([0.3, 0.4], 0.2, handed_out=0.1) == 1
