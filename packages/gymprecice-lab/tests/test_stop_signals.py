"""A stop signal (SIGTERM, SIGHUP, Ctrl-C) stops training at once, except inside a
gradient update, which it lets finish: a model saved in the middle of Adam's first step
held a parameter with a ``step`` but no ``exp_avg``, and its resume died with
``KeyError: 'exp_avg'`` (seen as an intermittent failure of the SLURM preemption test)."""

from __future__ import annotations

import os
import signal

import pytest
import torch

from gymprecice_lab.training.callbacks import Interrupted, StopOnSignal, stop_signals_interrupt


def _model_and_adam() -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    torch.manual_seed(0)
    model = torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.Linear(4, 1))
    return model, torch.optim.Adam(model.parameters(), lr=1e-3)


def _first_step(model: torch.nn.Module, optimizer: torch.optim.Optimizer) -> None:
    optimizer.zero_grad()
    model(torch.ones(2, 3)).sum().backward()
    optimizer.step()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_inside_an_update_waits_for_it_and_stops_at_the_next_step(signum) -> None:
    model, optimizer = _model_and_adam()

    def signal_mid_step(optimizer: torch.optim.Optimizer, args: object, kwargs: object) -> None:
        os.kill(os.getpid(), signum)  # delivered inside torch's step, before the state

    optimizer.register_step_pre_hook(signal_mid_step)
    before = signal.getsignal(signum)
    with stop_signals_interrupt():
        try:
            _first_step(model, optimizer)
        except Interrupted:
            pytest.fail("the signal cut the optimizer's step short")
        state = [optimizer.state[p] for p in model.parameters()]
        assert all({"step", "exp_avg", "exp_avg_sq"} <= set(s) for s in state)
        with pytest.raises(Interrupted) as stopped:
            StopOnSignal()._on_step()  # the next env step
    assert stopped.value.signum == signum
    assert signal.getsignal(signum) is before  # the block's handler is gone


def test_a_signal_outside_an_update_stops_at_once_and_a_repeat_is_ignored() -> None:
    with pytest.raises(Interrupted) as stopped, stop_signals_interrupt():
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(10**6):  # the handler runs at the next bytecode
            pass
        pytest.fail("SIGTERM outside an update did not stop at once")
    assert stopped.value.signum == signal.SIGTERM
    with stop_signals_interrupt():
        with pytest.raises(Interrupted):
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(10**6):
                pass
        os.kill(os.getpid(), signal.SIGTERM)  # the repeat of the one being obeyed
        for _ in range(10**6):
            pass
