"""Core overheads, printed side by side with a bare preCICE loop in one run.

    python benchmarks/bench_core.py [--windows 300] [--concurrent 2]

For each available library (the test double always; real pyprecice when importable):

* step: one ``Adapter.step()`` per time window against a bare read/write/advance loop of
  the same library, same meshes, same data and the same null partner process. The adapter
  overhead is the difference (goal: <= 100 us through the double, <= 1.2x with real preCICE).
* reset: ``Adapter.reset()`` against a bare start (launch the partner, create the
  participant, initialize).
* concurrent resets: N envs resetting at once (each in its own process, as under a vector
  env) against one reset (goal: <= 1.2x).

Figures depend on the machine's load; run it on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, wait
from pathlib import Path

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter
from gymprecice.env.pidregistry import kill_recorded_groups
from gymprecice.testing import case_config
from gymprecice.testing.flows import fake_cylinder_geometry

DOUBLE = "gymprecice.testing.fake_precice"
PARTNER = ["-m", "gymprecice.testing.partner", "--flow", "gymprecice.testing.flows:NullFlow"]


class BenchEnv(Adapter):
    def __init__(self, options, idx=0, **kwargs):
        super().__init__(options, idx, **kwargs)
        geometry = fake_cylinder_geometry()
        self._coords = {name: geometry[name].coordinates for name in ("jet1", "jet2")}
        for name, coords in self._coords.items():
            self.set_interface_vertices(name, coords)
        self._zero = {name: np.zeros_like(c) for name, c in self._coords.items()}
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        return self._zero

    def _get_observation(self, read_data, read_var_list):
        return read_data["cylinder"]

    def _get_reward(self):
        return 0.0


def make_case(root: Path, library: str, windows: int) -> Path:
    case = root / "case"
    (case / "fluid").mkdir(parents=True, exist_ok=True)
    case_config("fake_cylinder", case, max_time=0.01 * windows)
    argv = ["{python}", *PARTNER, "--config", "{precice_config}", "--participant", "Fluid"]
    config = {
        "precice": {"library": library},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "command",
                    "participant": "Fluid",
                    "options": {"argv": [*argv, "--library", library]},
                }
            }
        },
        "controller": {
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"cylinder": "Pressure"},
        },
        # A loaded machine slows everything down; a hang must still end in an error.
        "timeouts": {"reset": 120, "progress": 60},
    }
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    return case


def adapter_run(case: Path, run_root: Path) -> tuple[float, list[float]]:
    env = BenchEnv(case, 0, run_root=run_root)
    started = time.perf_counter()
    env.reset(seed=0)
    reset_s = time.perf_counter() - started
    steps, truncated = [], False
    action = np.zeros(1, dtype=np.float32)
    while not truncated:
        t0 = time.perf_counter()
        _, _, _, truncated, _ = env.step(action)
        steps.append(time.perf_counter() - t0)
    env.close()
    return reset_s, steps[:-1]  # the last step also ends the episode (finalize, exits)


def bare_run(case: Path, library: str, work: Path) -> tuple[float, list[float]]:
    """The same coupling without gymprecice: partner launched by hand, loop in-process."""
    import importlib

    precice = importlib.import_module(library)
    work.mkdir(parents=True, exist_ok=True)
    config = case_config("fake_cylinder", work, max_time=None, exchange_directory=work / "x")
    xml = (case / "precice-config.xml").read_text()
    max_time = xml.split('<max-time value="')[1].split('"')[0]
    config.write_text(
        config.read_text().replace('<max-time value="1.0"', f'<max-time value="{max_time}"')
    )
    started = time.perf_counter()
    partner = subprocess.Popen(
        [
            sys.executable,
            *PARTNER,
            "--config",
            str(config),
            "--participant",
            "Fluid",
            "--library",
            library,
        ],
        cwd=work,
        stdout=subprocess.DEVNULL,
    )
    here = os.getcwd()
    os.chdir(work)  # preCICE writes its profiling files into the working directory
    participant = precice.Participant("Controller", str(config), 0, 1)
    geometry = fake_cylinder_geometry()
    ids = {}
    for name in ("jet1", "jet2"):
        ids[name] = participant.set_mesh_vertices(
            f"Controller-Mesh-{name}", geometry[name].coordinates
        )
    participant.set_mesh_access_region("Fluid-Mesh-cylinder", np.array([-1e300, 1e300] * 2))
    participant.initialize()
    cyl_ids, _ = participant.get_mesh_vertex_ids_and_coordinates("Fluid-Mesh-cylinder")
    reset_s = time.perf_counter() - started
    zero = {name: np.zeros((len(ids[name]), 2)) for name in ids}
    steps = []
    while participant.is_coupling_ongoing():
        t0 = time.perf_counter()
        dt = participant.get_max_time_step_size()
        for name in ids:
            participant.write_data(f"Controller-Mesh-{name}", "Velocity", ids[name], zero[name])
        participant.advance(dt)
        participant.read_data("Fluid-Mesh-cylinder", "Pressure", cyl_ids, 0.0)
        steps.append(time.perf_counter() - t0)
    participant.finalize()
    os.chdir(here)
    partner.wait(timeout=30)
    return reset_s, steps[:-1]


def _reset_once(args: tuple[str, str, int]) -> float:
    case, run_root, idx = args
    env = BenchEnv(case, idx, run_root=run_root)
    env.run_dir  # noqa: B018 - prepare outside the timed reset, as a vector env does at start-up
    started = time.perf_counter()
    env.reset(seed=idx)
    elapsed = time.perf_counter() - started
    env.close()
    return elapsed


#: the longest the concurrent resets may take, whatever the load (each reset has its own
#: timeouts in the case's config; this bounds the pool around them)
CONCURRENT_DEADLINE_S = 300.0


def _reset_in_processes(jobs: list[tuple[str, str, int]]) -> list[float]:
    """Run ``_reset_once`` for each job in its own process, with a deadline.

    ``multiprocessing.Pool.map`` waits forever for the result of a worker that died (the
    OOM killer on a loaded machine, a signal): the benchmark then hangs instead of
    failing. ``ProcessPoolExecutor`` reports a dead worker (``BrokenProcessPool``), and
    the wait below has a deadline.
    """
    ctx = mp.get_context("forkserver")
    pool = ProcessPoolExecutor(len(jobs), mp_context=ctx)
    try:
        futures = [pool.submit(_reset_once, job) for job in jobs]
        _, pending = wait(futures, timeout=CONCURRENT_DEADLINE_S)
        if pending:
            raise SystemExit(
                f"bench_core: {len(pending)} of {len(jobs)} concurrent resets did not finish "
                f"within {CONCURRENT_DEADLINE_S:g} s"
            )
        return [f.result() for f in futures]
    finally:
        for process in list(getattr(pool, "_processes", {}).values()):
            if process.is_alive():
                process.kill()  # a reset still running
        pool.shutdown(wait=False, cancel_futures=True)
        for _, run_root, idx in jobs:  # what the killed resets had started
            kill_recorded_groups(Path(run_root) / f"env_{idx}", grace=0.5)


def concurrent_resets(case: Path, run_root: Path, n: int) -> tuple[float, float]:
    [one] = _reset_in_processes([(str(case), str(run_root / "one"), 0)])
    started = time.perf_counter()
    _reset_in_processes([(str(case), str(run_root / "many"), i) for i in range(n)])
    many = time.perf_counter() - started
    return one, many


def _us(values: list[float]) -> str:
    return f"{statistics.median(values) * 1e6:9.1f} us (median of {len(values)})"


def real_precice_available() -> bool:
    probe = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True)
    return probe.returncode == 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=300)
    parser.add_argument("--concurrent", type=int, default=os.cpu_count() or 2)
    args = parser.parse_args()
    libraries = [DOUBLE] + (["precice"] if real_precice_available() else [])
    if len(libraries) == 1:
        print("real pyprecice not importable: only the test double is measured")
    for library in libraries:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            case = make_case(root, library, args.windows)
            a_reset, a_steps = adapter_run(case, root / "runs")
            b_reset, b_steps = bare_run(case, library, root / "bare")
            overhead = statistics.median(a_steps) - statistics.median(b_steps)
            print(f"\n== {library} ({args.windows} windows, null partner)")
            print(f"  step   adapter {_us(a_steps)}   bare loop {_us(b_steps)}")
            print(
                f"         adapter overhead {overhead * 1e6:8.1f} us per step, "
                f"ratio {statistics.median(a_steps) / statistics.median(b_steps):.2f}x"
            )
            print(
                f"  reset  adapter {a_reset * 1e3:8.1f} ms          bare start {b_reset * 1e3:8.1f} ms"
            )
            if library == DOUBLE:
                one, many = concurrent_resets(case, root / "conc", args.concurrent)
                print(
                    f"  {args.concurrent} concurrent resets {many * 1e3:8.1f} ms vs one reset "
                    f"{one * 1e3:8.1f} ms: {many / one:.2f}x"
                )


if __name__ == "__main__":
    main()
