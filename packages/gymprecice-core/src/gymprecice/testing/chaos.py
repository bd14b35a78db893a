"""A fake-cylinder gymprecice case whose solver fails on request, and its env.

Tests of fault tolerance (and benchmarks of the vector env) need a complete gymprecice
environment, Adapter, coupling worker, preCICE (the double) and a solver process, whose
solver can be made to fail in every way real CFD solvers fail, at a chosen moment, once:

* :func:`write_case` writes a case directory: ``gymprecice-config.json`` (explicit form,
  one solver ``fluid`` of kind ``command``), a preCICE configuration, and ``fluid/`` with
  a small mesh description (``mesh/boundary``, the patches the reset step checks);
* the solver is ``python chaos_solver.py run -- <partner args>`` (a copy of
  :mod:`gymprecice.testing.chaos_solver` in the solver directory), a launcher that applies
  a pending fault and then becomes (``exec``) the scripted partner
  ``python -m gymprecice.testing.partner``; the case's reset step is
  ``python chaos_solver.py reset``, which checks the mesh like a real reset script would;
* :func:`inject` arms a fault for env ``i``, consumed by the next launch (``"run"``) or
  reset step (``"reset"``) of that env only, so the env's next episode is healthy again;
* :class:`CylinderEnv` is an :class:`~gymprecice.core.Adapter` for this case. Its
  observation is the probe pressures, the drag coefficient read from the solver's
  ``forceCoeffs`` output file, and the time; the reward is minus the drag.

Faults (``inject(faults_dir, index, phase, fault, **params)``):

``kill`` (run)
    the solver dies by SIGKILL at window ``window`` (0: before it connects).
``stop`` (run)
    the solver stops itself with SIGSTOP before connecting (a hung solver at reset).
    Mid-episode, stop it from outside: ``os.killpg(solver_group, SIGSTOP)``.
``exit`` (run)
    the solver prints ``FOAM FATAL ERROR`` and exits with ``code`` at window ``window``.
``corrupt-output`` (run)
    the solver's ``forceCoeffs`` file is garbage when the episode starts, so the env's
    first read fails. Mid-episode, overwrite the file from outside (:func:`corrupt_output`).
``disk-full`` (run)
    the solver may write only ``headroom`` more bytes to any file (RLIMIT_FSIZE, SIGXFSZ
    ignored): once its log or outputs reach the limit, every write fails with EFBIG as
    writes on a full disk fail with ENOSPC. A real tiny filesystem would need privileges
    (mounting a tmpfs) that test machines rarely grant, and a read-only directory does not
    stop root; the file-size limit is enforced by the kernel for any user.
``diverge`` (run)
    the solver diverges at window ``window``: its log shows a blown-up Courant number and
    a ``Floating point exception`` (the case's ``divergence_patterns``), and it exits with
    status 136. An episode outcome, not a fault: the step terminates with the penalty.
``bad-case`` (reset)
    the reset step finds patch ``patch`` (default ``jet1``) missing from the env's copy of
    ``mesh/boundary`` and fails like a solver utility does.
"""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.core import Adapter
from gymprecice.env.pidregistry import PidRegistry, process_starttime
from gymprecice.testing import chaos_solver
from gymprecice.testing.chaos_solver import (
    COEFFICIENTS,
    FAULTS_VARIABLE,
    PATCHES,
    corrupt_output,
    fault_path,
)
from gymprecice.testing.flows import place_jets
from gymprecice.testing.partner import DEFAULT_LIBRARY

__all__ = [
    "FAULTS_VARIABLE",
    "PRECICE_XML",
    "CylinderEnv",
    "ProcessWatcher",
    "corrupt_output",
    "describe_processes",
    "inject",
    "is_mpi_singleton_daemon",
    "is_owner_watchdog",
    "left_behind",
    "pid_alive",
    "process_family",
    "env_processes",
    "process_table",
    "processes_with_environment",
    "solver_groups",
    "survivors",
    "write_case",
]


#: The launcher's file name in the case's solver directory.
LAUNCHER = "chaos_solver.py"

#: Controller + Fluid, parallel-explicit; the controller reads pressure on its own probe
#: mesh (nearest-neighbour from the fluid's), writes jet velocities.
PRECICE_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<precice-configuration>
  <data:vector name="Velocity" />
  <data:scalar name="Pressure" />
  <mesh name="Controller-Mesh-jet1" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Controller-Mesh-jet2" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Controller-Mesh-probe" dimensions="2"><use-data name="Pressure" /></mesh>
  <mesh name="Fluid-Mesh-jet1" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Fluid-Mesh-jet2" dimensions="2"><use-data name="Velocity" /></mesh>
  <mesh name="Fluid-Mesh-probe" dimensions="2"><use-data name="Pressure" /></mesh>
  <participant name="Controller">
    <provide-mesh name="Controller-Mesh-jet1" />
    <provide-mesh name="Controller-Mesh-jet2" />
    <provide-mesh name="Controller-Mesh-probe" />
    <receive-mesh name="Fluid-Mesh-probe" from="Fluid" />
    <write-data name="Velocity" mesh="Controller-Mesh-jet1" />
    <write-data name="Velocity" mesh="Controller-Mesh-jet2" />
    <read-data name="Pressure" mesh="Controller-Mesh-probe" />
    <mapping:nearest-neighbor direction="read" from="Fluid-Mesh-probe" to="Controller-Mesh-probe" constraint="consistent" />
  </participant>
  <participant name="Fluid">
    <provide-mesh name="Fluid-Mesh-jet1" />
    <provide-mesh name="Fluid-Mesh-jet2" />
    <provide-mesh name="Fluid-Mesh-probe" />
    <receive-mesh name="Controller-Mesh-jet1" from="Controller" />
    <receive-mesh name="Controller-Mesh-jet2" from="Controller" />
    <read-data name="Velocity" mesh="Fluid-Mesh-jet1" />
    <read-data name="Velocity" mesh="Fluid-Mesh-jet2" />
    <write-data name="Pressure" mesh="Fluid-Mesh-probe" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-jet1" to="Fluid-Mesh-jet1" constraint="consistent" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-jet2" to="Fluid-Mesh-jet2" constraint="consistent" />
  </participant>
  <m2n:sockets acceptor="Controller" connector="Fluid" exchange-directory="" />
  <coupling-scheme:parallel-explicit>
    <participants first="Controller" second="Fluid" />
    <max-time value="{end_time!r}" />
    <time-window-size value="{window!r}" />
    <exchange data="Velocity" mesh="Controller-Mesh-jet1" from="Controller" to="Fluid" />
    <exchange data="Velocity" mesh="Controller-Mesh-jet2" from="Controller" to="Fluid" />
    <exchange data="Pressure" mesh="Fluid-Mesh-probe" from="Fluid" to="Controller" />
  </coupling-scheme:parallel-explicit>
</precice-configuration>
"""

#: Controller probe vertices (x, y), downstream of the cylinder.
PROBES = np.array([[0.2, 0.0], [0.4, 0.05], [0.6, -0.05]])


def write_case(
    root: str | os.PathLike[str],
    faults_dir: str | os.PathLike[str],
    *,
    end_time: float = 0.2,
    window: float = 0.01,
    windows_per_step: int = 2,
    step_sleep: float = 0.0,
    flow: str | None = None,
    write_outputs: bool = True,
    timeouts: Mapping[str, float] | None = None,
    run_root: str | os.PathLike[str] | None = None,
    library: str = DEFAULT_LIBRARY,
) -> Path:
    """Write the case into ``root`` (made if needed); returns ``root``.

    ``faults_dir`` is where :func:`inject` arms faults for this case's envs. An episode
    lasts ``end_time / window`` time windows, ``windows_per_step`` of them per env step;
    the solver sleeps ``step_sleep`` seconds per time step (the cost of a CFD step).
    ``timeouts`` go to the configuration's ``timeouts`` section. ``library`` is the module
    imported as ``precice`` by both the env's coupling worker (``precice.library``) and the
    solver (the partner's ``--library``): the double by default, ``"precice"`` for real
    preCICE. The env's ``GYMPRECICE_PRECICE_LIBRARY`` overrides the env's side only, so
    leave it unset when running this case.
    """
    root = Path(root)
    (root / "fluid" / "mesh").mkdir(parents=True, exist_ok=True)
    (root / "precice-config.xml").write_text(PRECICE_XML.format(end_time=end_time, window=window))
    (root / "fluid" / "mesh" / "boundary").write_text(
        "".join(f"{patch}\n{{\n    type patch;\n}}\n" for patch in PATCHES)
    )
    partner = ["--config", "{precice_config}", "--participant", "Fluid", "--library", library]
    partner += ["--option", "probes=3"]  # small output files: predictable disk use
    if flow:
        partner += ["--flow", flow]
    if step_sleep:
        partner += ["--step-sleep", repr(step_sleep)]
    if write_outputs:
        partner += ["--write-outputs", "."]
    # The launcher is copied into the case and run as a file: ``-m`` would import the
    # gymprecice package (and its plugin registration) in every solver start.
    shutil.copyfile(chaos_solver.__file__, root / "fluid" / LAUNCHER)
    launcher = ["{python}", LAUNCHER]
    config: dict[str, Any] = {
        "environment": {"name": "chaos-cylinder"},
        "precice": {
            "config_file": "precice-config.xml",
            "library": library,
        },
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "command",
                    "path": "fluid",
                    "participant": "Fluid",
                    "options": {
                        "argv": [*launcher, "run", "--", *partner],
                        "reset_argv": [*launcher, "reset"],
                        "reset_timeout": 30,
                        "divergence_patterns": ["Floating point exception"],
                        # the partner needs no plugin: skip loading them at every start
                        "env": {
                            FAULTS_VARIABLE: str(Path(faults_dir).resolve()),
                            "GYMPRECICE_DISABLE_PLUGINS": "1",
                        },
                    },
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"probe": "Pressure"},
        },
        "actions": {"windows": windows_per_step, "scheme": "hold"},
        "timeouts": {"reset": 30, "progress": 3, "finalize": 2, "kill_grace": 0.5},
    }
    if run_root is not None:
        config["environment"]["run_root"] = str(Path(run_root).resolve())
    config["timeouts"].update(timeouts or {})
    (root / "gymprecice-config.json").write_text(json.dumps(config, indent=2) + "\n")
    Path(faults_dir).mkdir(parents=True, exist_ok=True)
    return root


def inject(
    faults_dir: str | os.PathLike[str], env_index: int, phase: str, fault: str, **params: Any
) -> Path:
    """Arm ``fault`` for the next ``phase`` (``"run"`` or ``"reset"``) of env ``env_index``."""
    if phase not in ("run", "reset"):
        raise ValueError(f"phase must be 'run' or 'reset', got {phase!r}")
    path = fault_path(faults_dir, env_index, phase)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"fault": fault, **params}))
    os.replace(tmp, path)
    return path


def solver_groups(env_dir: str | os.PathLike[str]) -> list[int]:
    """Process groups of this case's solver recorded for an env (not the coupling worker)."""
    groups = []
    for pgid in PidRegistry(env_dir).pgids():
        try:
            cmdline = Path(f"/proc/{pgid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"gymprecice.testing.partner" in cmdline or LAUNCHER.encode() in cmdline:
            groups.append(pgid)
    return groups


# -- process inspection (Linux /proc) ---------------------------------------------------------


def _stat_fields(pid: int | str) -> list[bytes] | None:
    try:
        data = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return data[data.rfind(b")") + 2 :].split()


def pid_alive(pid: int | None) -> bool:
    """Whether ``pid`` is a live process (zombies count as dead: they hold nothing)."""
    if pid is None:
        return False
    fields = _stat_fields(pid)
    return fields is not None and fields[0] not in (b"Z", b"X")


def is_mpi_singleton_daemon(pid: int) -> bool:
    """Whether ``pid`` is the ``orted`` an Open MPI 4 singleton started for itself.

    pyprecice imports mpi4py, so every process that imports real ``precice`` (the coupling
    worker, a Python solver) initialises an MPI singleton, and Open MPI 4 forks an
    ``orted --set-sid ... --singleton-died-pipe N`` for it: in a session of its own, so
    outside the process groups gymprecice records and kills. It exits by itself as soon as
    its singleton is gone (the pipe closes), a moment after the singleton died.
    """
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return bool(argv) and argv[0].endswith(b"orted") and b"--singleton-died-pipe" in argv


def is_owner_watchdog(pid: int) -> bool:
    """Whether ``pid`` is the watchdog of a process that launched solvers.

    It outlives its owner by design (:mod:`gymprecice.owner_watchdog`): once the owner is
    gone it stops what the owner left and exits, a moment later (longer on a busy machine).
    """
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return b"gymprecice.owner_watchdog" in argv[:4]


def survivors(pids: Iterable[int], keep: Iterable[int] = (), mpi_grace: float = 10.0) -> list[int]:
    """The live ``pids`` except ``keep``, once MPI singleton daemons and owner watchdogs
    among them had time to exit.

    Any other live process is returned at once; while the live ones are all Open MPI
    singleton daemons (:func:`is_mpi_singleton_daemon`), watchdogs of owners that are gone
    (:func:`is_owner_watchdog`) or processes already exiting (their memory released: an
    empty command line, e.g. an ``orted`` in uninterruptible exit), wait up to
    ``mpi_grace`` seconds for them to go, so that one still there after the grace counts as
    leaked.
    """
    allowed = set(keep)
    candidates = [p for p in set(pids) if p not in allowed]
    daemons = {p for p in candidates if is_mpi_singleton_daemon(p) or is_owner_watchdog(p)}
    deadline = time.monotonic() + mpi_grace
    while True:
        alive = sorted(p for p in candidates if pid_alive(p))
        lingering = [p for p in alive if p in daemons or _exiting(p)]
        if not lingering or len(lingering) < len(alive) or time.monotonic() >= deadline:
            return alive
        time.sleep(0.05)


def _exiting(pid: int) -> bool:
    try:
        return not Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return True


def describe_processes(pids: Iterable[int]) -> list[str]:
    """``"pid state ppid pgid: command line"`` of each pid (for assertion messages)."""
    out = []
    for pid in pids:
        fields = _stat_fields(pid)
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").strip()
        except OSError:
            argv = b"?"
        head = " ".join(f.decode() for f in fields[:3]) if fields else "gone"
        out.append(f"{pid} {head}: {argv.decode(errors='replace')[:200]}")
    return out


def process_table() -> dict[int, tuple[int, int]]:
    """``pid -> (ppid, pgid)`` of every live process."""
    table = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        fields = _stat_fields(entry.name)
        if fields is None or fields[0] in (b"Z", b"X"):
            continue
        table[int(entry.name)] = (int(fields[1]), int(fields[2]))
    return table


def process_family(
    root: int | None,
    groups: Iterable[int] = (),
    table: Mapping[int, tuple[int, int]] | None = None,
) -> set[int]:
    """``root`` with all its descendants, plus every member of the process ``groups``."""
    table = process_table() if table is None else table
    wanted = set(groups)
    found = {pid for pid, (_, pgid) in table.items() if pgid in wanted}
    if root is None or root not in table:
        return found
    children: dict[int, list[int]] = {}
    for pid, (ppid, _) in table.items():
        children.setdefault(ppid, []).append(pid)
    todo = [root]
    while todo:
        pid = todo.pop()
        found.add(pid)
        todo += children.get(pid, [])
    return found


def processes_with_environment(name: str, value: str) -> list[int]:
    """Live processes whose environment has ``name=value`` (those readable to us)."""
    needle = f"{name}={value}".encode()
    found = []
    for pid in process_table():
        try:
            environ = Path(f"/proc/{pid}/environ").read_bytes()
        except OSError:
            continue
        if needle in environ.split(b"\0"):
            found.append(pid)
    return found


def env_processes(pool: Any, index: int) -> set[int]:
    """Processes of env ``index`` of an :class:`~gymprecice.vector.EnvPool` right now.

    Its worker with everything descending from it (coupling worker, solvers and their
    children), plus every member of the process groups recorded in its run directory.
    """
    run_dir = pool.run_dirs[index]
    groups = PidRegistry(run_dir).pgids() if run_dir else []
    return process_family(pool.worker_pids[index], groups)


class ProcessWatcher:
    """Remember every process ``sample()`` returns, sampled every ``interval`` seconds.

    Processes of a failing env come and go within seconds; sampling in a thread while the
    test drives the env catches them, so that the test can check afterwards that every one
    of them is gone (``leaked()``). Each is remembered with its start time: a pid that a
    later process took (pids wrap at 32,768 on many machines) is not the one seen.
    """

    def __init__(self, sample: Callable[[], set[int]], interval: float = 0.05) -> None:
        self.sample = sample
        self.interval = interval
        self.seen: set[int] = set()
        self._started: dict[int, int | None] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="process-watcher", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                for pid in self.sample() - self.seen:
                    self._started[pid] = process_starttime(pid)
                    self.seen.add(pid)
            except Exception:  # a racing exit while reading /proc
                pass
            self._stop.wait(self.interval)

    def stop(self) -> set[int]:
        """Stop sampling; return every pid seen."""
        self._stop.set()
        self._thread.join()
        return self.seen

    def leaked(self, keep: Iterable[int] = (), within: float = 0.0) -> list[int]:
        """Processes seen that are still alive, except ``keep`` (e.g. the current
        incarnation), waiting up to ``within`` seconds for them to exit (a process that
        is ending, such as an owner's watchdog that saw its owner go, takes a moment)."""
        allowed = set(keep)

        def alive() -> list[int]:
            return sorted(
                p
                for p in self.seen
                if p not in allowed
                and pid_alive(p)
                and process_starttime(p) == self._started.get(p)
            )

        deadline = time.monotonic() + within
        left = alive()
        while left and time.monotonic() < deadline:
            time.sleep(0.05)
            left = alive()
        return left


# -- the env ------------------------------------------------------------------------------


class CylinderEnv(Adapter):
    """Jet control of the fake cylinder (see the module docstring).

    Observation: the 3 probe pressures, the latest drag coefficient from the solver's
    ``forceCoeffs`` file (0 before the first window), and the time. Action: the jet
    flow rate in [-1, 1] (jet1 blows what jet2 sucks). Reward: minus the drag. Set
    ``read_outputs=False`` to skip the output file (benchmarks of the bare coupling).
    """

    def __init__(
        self,
        options: Any = None,
        idx: int = 0,
        *,
        read_outputs: bool = True,
        **kwargs: Any,
    ) -> None:
        super().__init__(options, idx, **kwargs)
        place_jets(self)
        self.set_interface_vertices("probe", PROBES)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(5,), dtype=np.float32)
        self.read_outputs = read_outputs
        self._drag = 0.0

    def _get_action(self, action: Any, write_var_list: Any) -> dict[str, np.ndarray]:
        q = float(np.asarray(action, dtype=float).ravel()[0])
        out = {}
        for name, sign in (("jet1", 1.0), ("jet2", -1.0)):
            n = len(self.interface_geometry[name].coordinates)
            out[name] = np.tile([0.0, sign * q], (n, 1))
        return out

    def _get_observation(self, read_data: Any, read_var_list: Any) -> np.ndarray:
        self._drag = self._read_drag() if self.read_outputs else 0.0
        pressure = np.asarray(read_data["probe"], dtype=float).ravel()
        return np.array([*pressure, self._drag, self.time], dtype=np.float32)

    def _get_reward(self) -> float:
        return -self._drag

    def _read_drag(self) -> float:
        path = self.solver_dirs["fluid"] / COEFFICIENTS
        try:
            text = path.read_bytes()
        except FileNotFoundError:
            return 0.0
        if not text.startswith(b"# Force coefficients"):
            raise ValueError(f"{path}: corrupt forceCoeffs output (no header)")
        rows = [line for line in text.decode().splitlines() if not line.startswith("#")]
        if not rows:
            return 0.0
        try:
            return float(rows[-1].split()[1])
        except (IndexError, ValueError):
            raise ValueError(f"{path}: corrupt forceCoeffs row {rows[-1]!r}") from None


def left_behind(root: Path) -> set[int]:
    """Live processes started for the commands a test ran in ``root``: ``XDG_STATE_HOME``
    under ``root`` in their environment, or their working directory under ``root``
    (never found by name)."""
    needle = f"XDG_STATE_HOME={root / 'state'}".encode()
    found = set()
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = Path(entry.path, "environ").read_bytes().split(b"\0")
            cwd = Path(os.readlink(Path(entry.path, "cwd")))
        except OSError:
            continue
        if (needle in environ or cwd.is_relative_to(root)) and pid_alive(int(entry.name)):
            found.add(int(entry.name))
    return found
