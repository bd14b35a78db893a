"""``gymprecice.plugin.choose_start``: a reset's pick among saved starts, for every plugin."""

from __future__ import annotations

import numpy as np
import pytest

from gymprecice.plugin import ConfigError, choose_start

POOLS = {"train": ["b", "a", "d"], "eval": ["c"]}
EVERYTHING = ["b", "a", "d", "c"]


@pytest.mark.parametrize(
    ("split", "start", "expected"),
    [(None, 0, "b"), ("train", 2, "d"), ("eval", 0, "c"), ("all", 3, "c")],
)
def test_a_start_index_takes_the_splits_start_in_the_order_given(split, start, expected) -> None:
    assert choose_start(POOLS, EVERYTHING, None, split, start) == expected


def test_a_sort_key_orders_the_index_but_not_the_draw() -> None:
    pools = {"train": ["4.9", "4.7", "4.8"]}
    by_index = [
        choose_start(pools, pools["train"], None, "train", k, order=float) for k in range(3)
    ]
    assert by_index == ["4.7", "4.8", "4.9"]
    drawn = choose_start(pools, pools["train"], np.random.default_rng(3), "train", order=float)
    assert drawn == pools["train"][int(np.random.default_rng(3).integers(3))]


def test_without_an_index_the_start_is_drawn_with_the_generator() -> None:
    for seed in range(10):
        expected = POOLS["train"][int(np.random.default_rng(seed).integers(3))]
        assert choose_start(POOLS, EVERYTHING, np.random.default_rng(seed), None) == expected


def test_a_split_the_pools_lack_falls_back_to_every_start() -> None:
    assert choose_start({}, EVERYTHING, None, "eval", 3) == "c"


@pytest.mark.parametrize(
    ("split", "start", "message"),
    [
        ("validation", None, "keeps no validation starts; add one"),
        ("test", None, "use 'train' \\(default\\), 'eval', 'validation' or 'all'"),
        ("eval", 1, "split 'eval' has 1 start\\(s\\) \\(c\\); use 0 to 0"),
        ("eval", True, "must be an integer index"),
    ],
)
def test_a_wrong_reset_option_is_refused_with_the_fix(split, start, message) -> None:
    with pytest.raises(ConfigError, match=message):
        choose_start(POOLS, EVERYTHING, None, split, start, what="start", validation_hint="add one")


def test_nothing_to_start_from_is_refused() -> None:
    with pytest.raises(ConfigError, match="no snapshot to start from"):
        choose_start({}, [], None, None)
