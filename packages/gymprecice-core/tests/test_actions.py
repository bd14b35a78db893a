from __future__ import annotations

import numpy as np
import pytest

from gymprecice.env.actions import ActionSchedule


def test_hold_repeats_the_action() -> None:
    schedule = ActionSchedule("hold", windows=3)
    schedule.start(np.zeros(1))
    values = schedule.spread(np.array([2.0]))
    assert [v.tolist() for v in values] == [[2.0], [2.0], [2.0]]


def test_ramp_goes_linearly_from_previous_to_new() -> None:
    schedule = ActionSchedule("ramp", windows=4)
    schedule.start(np.array([0.0]))
    assert np.allclose(np.concatenate(schedule.spread(np.array([4.0]))), [1, 2, 3, 4])
    assert np.allclose(np.concatenate(schedule.spread(np.array([0.0]))), [3, 2, 1, 0])


def test_ramp_cut_short_at_the_end_time_keeps_the_slope() -> None:
    schedule = ActionSchedule("ramp", windows=4)
    schedule.start(np.array([0.0]))
    assert np.allclose(np.concatenate(schedule.spread(np.array([4.0]), windows=2)), [1, 2])
    assert np.allclose(schedule.current, [2.0])


def test_cosine_eases_in_and_out_of_every_step() -> None:
    schedule = ActionSchedule("cosine", windows=4)
    schedule.start(np.array([0.0]))
    first = np.concatenate(schedule.spread(np.array([4.0])))
    assert np.allclose(first, 4 * (1 - np.cos(np.pi * np.array([1, 2, 3, 4]) / 4)) / 2)
    steps = np.diff(np.concatenate([[0.0], first]))
    assert steps[0] < steps[1] and steps[-1] < steps[-2]  # slow at both ends
    second = np.concatenate(schedule.spread(np.array([0.0])))
    assert np.allclose(second, 4 - first)  # from where the last step ended


def test_filter_is_first_order_and_continues_across_steps() -> None:
    schedule = ActionSchedule("filter", windows=2, filter_alpha=0.5)
    schedule.start(np.array([0.0]))
    assert np.allclose(np.concatenate(schedule.spread(np.array([8.0]))), [4, 6])
    assert np.allclose(np.concatenate(schedule.spread(np.array([8.0]))), [7, 7.5])


def test_vector_actions_and_validation() -> None:
    schedule = ActionSchedule("ramp", windows=2)
    schedule.start(np.zeros(2))
    values = schedule.spread(np.array([2.0, -2.0]))
    assert np.allclose(values[0], [1, -1]) and np.allclose(values[1], [2, -2])
    with pytest.raises(ValueError):
        ActionSchedule("smooth")
    with pytest.raises(ValueError):
        ActionSchedule("hold", windows=0)


def test_the_configuration_accepts_exactly_the_schemes() -> None:
    from typing import get_args

    from gymprecice.env.actions import SCHEMES
    from gymprecice.env.config import ActionsSection

    assert get_args(ActionsSection.model_fields["scheme"].annotation) == SCHEMES
