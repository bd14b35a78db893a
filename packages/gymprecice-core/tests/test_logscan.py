"""A failed solver's error message shows the solver's own error lines, not only the tail."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter
from gymprecice.env.processes import read_tail
from gymprecice.plugin.errors import SolverCrashedError
from gymprecice.plugin.logscan import error_lines

STUBS = Path(__file__).parent / "stubs"
#: what preCICE 3's default formatter prints for an error (colours included)
PRECICE_ERROR = (
    "(0) 10:41:07 [impl::ParticipantImpl]:231 in configure: \x1b[31mERROR: \x1b[0m"
    'The participant "Fluidd" is not defined in the configuration.'
)
BACKTRACE = "\n".join(f"#{i} 0x7f00 in Foam::error::printStack(Foam::Ostream&)" for i in range(60))


def test_precice_error_line_far_above_the_tail_is_found(tmp_path: Path) -> None:
    log = tmp_path / "log.pimpleFoam"
    log.write_text(f"Starting\n{PRECICE_ERROR}\n{BACKTRACE}\n")
    assert error_lines(log) == [
        "(0) 10:41:07 [impl::ParticipantImpl]:231 in configure: ERROR: The participant "
        '"Fluidd" is not defined in the configuration.'
    ]
    tail = read_tail(log, 40)
    assert "Fluidd" not in tail
    err = SolverCrashedError("env 0: solver 'fluid' exited", log_tail=tail, log_file=str(log))
    assert "error lines in the log:" in str(err) and '"Fluidd" is not defined' in str(err)
    again = pickle.loads(pickle.dumps(err))
    assert again.error_lines == err.error_lines and str(again) == str(err)


def test_openfoam_fatal_error_keeps_the_message_below_the_banner(tmp_path: Path) -> None:
    log = tmp_path / "log"
    log.write_text(
        "Create time\n\n--> FOAM FATAL IO ERROR: \n\nkeyword patches is undefined in dictionary "
        '"system/preciceDict/interfaces/Jet1"\n\nfile: system/preciceDict\n' + BACKTRACE
    )
    lines = error_lines(log)
    assert lines[0] == "--> FOAM FATAL IO ERROR:"
    assert any("keyword patches is undefined" in line for line in lines)


def test_a_clean_log_and_a_missing_log_have_no_error_lines(tmp_path: Path) -> None:
    (tmp_path / "log").write_text("Time = 0.1\nExecutionTime = 1 s\n")
    assert error_lines(tmp_path / "log") == []
    assert error_lines(tmp_path / "absent") == []
    assert error_lines(None) == []


class _Env(Adapter):
    def __init__(self, options, idx=0, **kwargs):
        super().__init__(options, idx, **kwargs)
        self.set_interface_vertices("jet1", [[0.0, 1.0]])
        self.set_interface_vertices("jet2", [[1.0, 1.0]])
        self.set_interface_vertices("probe", [[5.0, 0.0]])
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        return {"jet1": [[0.0, 0.0]], "jet2": [[0.0, 0.0]]}

    def _get_observation(self, read_data, read_var_list):
        return np.asarray(read_data["probe"], dtype=np.float32)

    def _get_reward(self):
        return 0.0

    def _close_external_resources(self):
        pass


def test_a_solver_abort_shows_its_error_line_not_only_the_backtrace(
    make_case, base_config, tmp_path, monkeypatch
) -> None:
    monkeypatch.setenv("PYTHONPATH", f"{STUBS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    monkeypatch.setenv("GYMPRECICE_PRECICE_LIBRARY", "stub_precice")
    monkeypatch.setenv("STUB_PRECICE_LOG", str(tmp_path / "writes.log"))
    monkeypatch.setenv("STUB_PRECICE_BLOCK_AT", "init")
    abort = (
        "import sys\n"
        f"print({PRECICE_ERROR!r})\n"
        "for i in range(80): print(f'#{i} 0x7f00 in Foam::error::printStack', flush=True)\n"
        "sys.exit(1)"
    )
    config = base_config()
    config["physics_simulation_engine"]["solvers"]["fluid"]["options"]["argv"] = [
        "{python}",
        "-c",
        abort,
    ]
    config["timeouts"] = {"progress": 5, "kill_grace": 0.5, "finalize": 2}
    env = _Env(make_case(tmp_path / "case", config), 0, run_root=tmp_path / "runs")
    with pytest.raises(SolverCrashedError) as info:
        env.reset()
    env.close()
    assert "Fluidd" not in info.value.log_tail
    assert '"Fluidd" is not defined in the configuration.' in str(info.value)


def test_a_crash_report_s_log_tail_has_no_colour_codes(tmp_path) -> None:
    """preCICE colours its log levels: a tail shown to a person must not carry the codes."""
    from gymprecice.plugin.errors import SolverCrashedError
    from gymprecice.plugin.logscan import without_colours

    tail = "---[precice] \x1b[31mERROR:\x1b[0m the partner is gone\n\x1b[1;33mwarning\x1b[0m\n"
    error = SolverCrashedError("solver 'fluid' exited", solver="fluid", log_tail=tail)
    assert "\x1b" not in str(error) and "\x1b" not in error.log_tail
    assert "---[precice] ERROR: the partner is gone" in str(error)
    assert without_colours("\x1b[?25l\x1b[2Kdone\x1b(B") == "done\x1b(B"  # CSI only
