"""prepare / reset / launch of an OpenFOAM run directory, with real OpenFOAM runs.

The contract checked here: after any episode, reset leaves the run directory exactly as
prepare left it (every file hash), and the source case is never touched.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from foamlib import FoamFile

from gymprecice.plugin.errors import CaseError, ConfigError
from gymprecice.plugin.solver import SolverContext
from gymprecice_openfoam import case, checks, control, installation, testing


def _episode(
    foam, solver: SolverContext, extra: list[str] | None = None, *, adapter: str = "drop"
) -> Path:
    """Run the launch spec as core would, uncoupled: without a preCICE partner.

    The adapter's function object is taken out of controlDict for the run (where the
    adapter is installed it would wait for the controller) and the file's bytes put back;
    ``adapter="unloadable"`` keeps it but names a library that does not exist, which is
    what a machine without the adapter sees.
    """
    spec = case.launch_spec(solver)
    env = foam.environ()
    env.update(spec.env)
    log = Path(spec.cwd) / spec.log_name
    control_dict = control.control_dict_path(solver.run_dir)
    original = control_dict.read_bytes()
    try:
        with FoamFile(control_dict) as ctl:
            for name in control.adapter_entries(solver.run_dir):
                if adapter == "drop":
                    del ctl["functions", name]
                else:
                    ctl["functions", name, "libs"] = [MISSING_LIBRARY]
        with log.open("wb") as handle:
            proc = subprocess.run(
                [*spec.argv, *(extra or [])],
                cwd=spec.cwd,
                env=env,
                stdout=handle,
                stderr=subprocess.STDOUT,
                timeout=120,
                check=False,
            )
    finally:
        control_dict.write_bytes(original)
    assert proc.returncode == 0, log.read_text()[-3000:]
    return log


MISSING_LIBRARY = "libpreciceAdapterFunctionObjectNowhere.so"


def _litter(run_dir: Path, initial: str) -> None:
    """What a coupled episode and a careless user leave behind."""
    (run_dir / "precice-Fluid-iterations.log").write_text("1 2 3\n")
    (run_dir / "precice-Fluid-events.json").write_text("{}")
    (run_dir / "precice-run").mkdir()
    (run_dir / "precice-run" / "Fluid-Controller.address").write_text("x")
    (run_dir / "precice-profiling").mkdir()
    with (run_dir / initial / "U").open("a") as handle:
        handle.write("// changed\n")
    (run_dir / initial / "p").unlink()
    (run_dir / initial / "extra").write_text("not from prepare")


@pytest.mark.openfoam
def test_prepare_then_reset_restores_the_prepared_tree(foam, cylinder_case, solver_for, digest):
    """Cost: about 1 s (blockMesh, a 0.01 s pre-run and two 0.008 s pimpleFoam episodes of the
    small cylinder).
    """
    source = cylinder_case("fluid", end_time=0.03, delta_t=0.002, write_interval=0.004)
    source_before = digest(source)
    solver = solver_for(source, prerun_end_time=0.01)
    state = case.prepare_case(solver)
    run_dir = solver.run_dir

    assert state.initial_time == "0.01" and state.np == 1
    assert (run_dir / "constant" / "polyMesh" / "faces").is_file()  # made by blockMesh
    assert (run_dir / "log.blockMesh").is_file()
    prerun_log = (run_dir / "log.prerun.pimpleFoam").read_text()
    assert "Time = 0.01" in prerun_log and "End" in prerun_log
    assert "preciceAdapterFunctionObject" not in prerun_log  # the adapter was taken out
    assert control.adapter_entries(run_dir) == ["preCICE_Adapter"]  # ... and put back
    ctl = FoamFile(run_dir / "system" / "controlDict")
    assert ctl["startFrom"] == "startTime" and ctl["startTime"] == 0.01
    assert (run_dir / case.PRERUN_OUTPUT / "probes" / "0" / "p").is_file()
    assert not (run_dir / "postProcessing").exists()
    after_prepare = digest(run_dir)

    for _ in range(2):
        log = _episode(foam, solver)
        assert (run_dir / "0.018").is_dir()
        assert (run_dir / "postProcessing" / "probes" / "0.01" / "p").is_file()
        _litter(run_dir, "0.01")
        assert case.reset_case(solver) == "0.01"
        assert digest(run_dir) == after_prepare
        assert not log.exists()
    assert digest(source) == source_before


@pytest.mark.openfoam
def test_check_solver_reports_the_uncoupled_run(foam, cylinder_case, solver_for):
    """Without a loadable adapter OpenFOAM only warns and runs uncoupled: we must not.

    Cost: under a second (blockMesh and a few pimpleFoam steps).
    """
    solver = solver_for(cylinder_case("fluid", end_time=0.004))
    case.prepare_case(solver)
    log = _episode(foam, solver, adapter="unloadable")
    text = log.read_text()
    assert f'Could not load "{MISSING_LIBRARY}"' in text
    message = checks.check_solver(solver, text[-2000:], log.name)
    assert message is not None
    assert str(log) in message and "UNCOUPLED" in message and "FOAM_USER_LIBBIN" in message
    assert "Unknown function type preciceAdapterFunctionObject" in message


V1912_WARNING = """Starting time loop

--> FOAM Warning :
    From function void* Foam::dlLibraryTable::openLibrary(const Foam::fileName&, bool)
    in file db/dynamicLibrary/dlLibraryTable/dlLibraryTable.C at line 65
    Could not load "libpreciceAdapterFunctionObject.so"
libpreciceAdapterFunctionObject.so: cannot open shared object file: No such file or directory
--> FOAM Warning :
Unknown function type preciceAdapterFunctionObject
--> while loading function object 'preCICE_Adapter'
"""


def test_check_log_cases(tmp_path):
    run_dir = tmp_path / "fluid"
    (run_dir / "system").mkdir(parents=True)
    ctl = run_dir / "system" / "controlDict"
    ctl.write_text(testing.control_dict(adapter=True))
    log = run_dir / "log.pimpleFoam"
    log.write_text(V1912_WARNING + "Time = 0.001\n" * 5)
    message = checks.check_log(run_dir, log, "Time = 0.002\n")
    assert message.startswith(str(log)) and "Could not load" in message
    assert "'libpreciceAdapterFunctionObject.so', as written in controlDict" in message
    # A misspelled library: the message names it as written, and the right name.
    ctl.write_text(
        testing.control_dict(adapter=True).replace(
            '"libpreciceAdapterFunctionObject.so"', '"libpreciceAdapterFunctionObjekt.so"'
        )
    )
    log.write_text(V1912_WARNING.replace("FunctionObject.so", "FunctionObjekt.so"))
    message = checks.check_log(run_dir, log, "")
    assert "'libpreciceAdapterFunctionObjekt.so', as written in controlDict" in message
    assert "named 'libpreciceAdapterFunctionObject.so': fix 'libs' there" in message
    ctl.write_text(testing.control_dict(adapter=True))
    # A loaded adapter that fails its configuration.
    log.write_text("\x1b[31mError in the preCICE adapter: \x1b[0m\nPatch 'jet3' does not exist.\n")
    message = checks.check_log(run_dir, log, "")
    assert "reported an error" in message and "jet3" in message and "preciceDict" in message
    # Nothing wrong (yet).
    log.write_text("---[preciceAdapter] Loaded the OpenFOAM-preCICE adapter - v1.3.1.\n")
    assert checks.check_log(run_dir, log, "") is None
    # A controlDict without the adapter: the fix is the snippet.
    ctl.write_text(testing.control_dict(adapter=False) + "// preciceAdapterFunctionObject\n")
    message = checks.check_log(run_dir, None, "")
    assert str(ctl) in message and control.ADAPTER_SNIPPET in message
    # The adapter pulled in with #include is still found.
    (run_dir / "system" / "preciceFO").write_text(
        'preCICE_Adapter { type preciceAdapterFunctionObject; libs ("x"); }\n'
    )
    ctl.write_text(testing.control_dict(adapter=False) + '#include "preciceFO"\n')
    assert checks.check_log(run_dir, None, "") is None


@pytest.mark.openfoam
def test_snapshots_draw_starts_from_a_fixed_split(foam, cylinder_case, solver_for, digest):
    """Cost: about 2 s (blockMesh and a pre-run writing the snapshots)."""
    solver = solver_for(
        cylinder_case("fluid", end_time=0.03, write_interval=0.004),
        prerun_end_time=0.016,
        snapshots=[0.004, 0.008, 0.012, 0.016],
        eval_fraction=0.5,
    )
    state = case.prepare_case(solver)
    assert state.split == {"train": ["0.004", "0.012"], "eval": ["0.008", "0.016"]}
    run_dir = solver.run_dir
    # Snapshots the pre-run wrote live in the store, not among the case's times.
    assert sorted(case.time_names(run_dir), key=float) == ["0", "0.016"]
    stored = run_dir / case.STORE / "times" / "case"

    def starts(seed: int, split: str | None, n: int = 8) -> list[str]:
        solver.rng = np.random.default_rng(seed)
        solver.reset_options = {} if split is None else {"split": split}
        out = []
        for _ in range(n):
            start = case.reset_case(solver)
            out.append(start)
            assert FoamFile(run_dir / "system" / "controlDict")["startTime"] == float(start)
            assert digest(run_dir / start) == digest(stored / start)
            later = [t for t in case.time_names(run_dir) if float(t) > float(start)]
            assert later in ([], ["0.016"])  # only the prepared initial state may be later
        return out

    train = starts(1, None)
    assert set(train) == {"0.004", "0.012"}
    assert starts(1, None) == train  # same seed, same starts
    assert set(starts(2, "eval")) == {"0.008", "0.016"}
    assert set(starts(3, "all", 20)) == {"0.004", "0.008", "0.012", "0.016"}
    # An episode from a snapshot, then a reset to another one.
    solver.rng = np.random.default_rng(5)
    solver.reset_options = {"split": "eval"}
    start = case.reset_case(solver)
    _episode(foam, solver, ["-noFunctionObjects"])
    assert any(float(t) > float(start) + 1e-9 for t in case.time_names(run_dir) if t != "0.016")
    again = case.reset_case(solver)
    assert digest(run_dir / again) == digest(stored / again)
    with pytest.raises(ConfigError, match="split"):
        solver.reset_options = {"split": "test"}
        case.reset_case(solver)
    # Preparing the same directory again finds the snapshots it had put away.
    again = case.prepare_case(solver)
    assert again.snapshots == state.snapshots and again.split == state.split
    assert sorted(case.time_names(run_dir), key=float) == ["0", "0.016"]


@pytest.mark.openfoam
def test_parallel_case_prepares_launches_and_resets(foam, cylinder_case, solver_for, digest):
    """Cost: about 2 s (blockMesh, decomposePar and a two-rank pre-run)."""
    if foam.which("mpirun") is None:
        pytest.skip("mpirun not available")
    solver = solver_for(
        cylinder_case("fluid", end_time=0.012, write_interval=0.002, decompose=2, split=(1, 2, 1)),
        prerun_end_time=0.006,
    )
    state = case.prepare_case(solver)
    run_dir = solver.run_dir
    assert state.np == 2
    for proc in ("processor0", "processor1"):
        assert sorted(case.time_names(run_dir / proc), key=float) == ["0", "0.006"]
    spec = case.launch_spec(solver)
    assert Path(spec.argv[0]).name == "mpirun" and spec.argv[1:3] == ["-np", "2"]
    assert spec.argv[-1] == "-parallel" and Path(spec.argv[-2]).name == "pimpleFoam"
    after_prepare = digest(run_dir)
    _episode(foam, solver)
    assert (run_dir / "processor1" / "0.012").is_dir()
    _litter(run_dir, "processor0/0.006")
    case.reset_case(solver)
    assert digest(run_dir) == after_prepare


def test_bad_cases_are_clear_errors(tmp_path, monkeypatch, solver_for):
    source = tmp_path / "src"
    (source / "system").mkdir(parents=True)
    solver = solver_for(source)
    with pytest.raises(CaseError, match=r"system/controlDict: missing"):
        case.prepare_case(solver)
    same = SolverContext(
        name="f", kind="openfoam", run_dir=source, source_dir=source, env_dir=tmp_path
    )
    with pytest.raises(CaseError, match="is the source case"):
        case.prepare_case(same)
    with pytest.raises(CaseError, match="was not prepared"):
        case.reset_case(solver)
    (solver.run_dir / "system" / "controlDict").write_text(testing.control_dict())
    (solver.run_dir / "system" / "decomposeParDict").write_text("numberOfSubdomains 4;\n")
    with pytest.raises(CaseError, match="numberOfSubdomains is 4 but the solver option np=2"):
        case.decide_np(solver.run_dir, {"np": 2})
    assert case.decide_np(solver.run_dir, {"np": 1}) == 1


def test_openfoam_missing_is_a_clear_error(tmp_path, monkeypatch, solver_for):
    empty = tmp_path / "bin"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    monkeypatch.delenv("WM_PROJECT_DIR", raising=False)
    monkeypatch.delenv(installation.BASHRC_ENV, raising=False)
    monkeypatch.setattr(installation, "_BASHRC_GLOBS", ())
    with pytest.raises(CaseError, match="OpenFOAM not found") as err:
        installation.find_openfoam()
    assert "etc/bashrc" in str(err.value)
    source = tmp_path / "src"
    (source / "system").mkdir(parents=True)
    (source / "system" / "controlDict").write_text(testing.control_dict())
    with pytest.raises(CaseError, match="OpenFOAM not found"):
        case.prepare_case(solver_for(source))
    # A WM_PROJECT_DIR that is not an installation is named in the message.
    monkeypatch.setenv("WM_PROJECT_DIR", str(tmp_path))
    with pytest.raises(CaseError, match=f"WM_PROJECT_DIR={tmp_path} has no etc/controlDict"):
        installation.find_openfoam()


def test_debian_layout_is_recognised(tmp_path, monkeypatch):
    """Programs in <prefix>/bin, etc in <prefix>/share/openfoam (the Debian package)."""
    prefix = tmp_path / "usr"
    (prefix / "bin").mkdir(parents=True)
    (prefix / "share" / "openfoam" / "etc").mkdir(parents=True)
    (prefix / "share" / "openfoam" / "etc" / "controlDict").write_text("")
    (prefix / "share" / "openfoam" / "etc" / "bashrc").write_text(
        "export WM_PROJECT_VERSION=v1912\n"
    )
    tool = prefix / "bin" / "blockMesh"
    tool.write_text("#!/bin/sh\n")
    tool.chmod(0o755)
    inst = installation.find_openfoam({"PATH": str(prefix / "bin")})
    assert inst.layout == "debian" and inst.version == "v1912"
    assert inst.env == {"WM_PROJECT_DIR": str(prefix / "share" / "openfoam")}


@pytest.mark.openfoam
def test_failed_prerun_names_its_log_and_restores_control_dict(cylinder_case, solver_for):
    """Cost: under a second (blockMesh and a pimpleFoam that fails at once)."""
    solver = solver_for(cylinder_case("fluid"), prerun_end_time=0.004)
    (solver.run_dir / "system" / "fvSolution").write_text(
        testing.HEADER.format(cls="dictionary", obj="fvSolution") + "solvers {}\n"
    )
    ctl = solver.run_dir / "system" / "controlDict"
    original = ctl.read_bytes()
    with pytest.raises(CaseError, match=r"log\.prerun\.pimpleFoam") as err:
        case.prepare_case(solver)
    assert "FOAM FATAL" in str(err.value)  # the log's tail is quoted
    assert ctl.read_bytes() == original


def test_case_without_mesh_or_recipe(tmp_path):
    (tmp_path / "system").mkdir()
    inst = installation.OpenFOAMInstallation(project_dir=tmp_path, layout="sourced")
    with pytest.raises(CaseError, match=r"no mesh and no recipe \(system/blockMeshDict"):
        case.ensure_mesh(tmp_path, inst, {})


@pytest.mark.openfoam
def test_envs_share_one_prerun_through_the_cache(cylinder_case, solver_for, tmp_path, monkeypatch):
    """Identical cases pre-run once: the others copy the result, even when concurrent.

    Cost: about 1 s (six blockMesh, three 0.01 s and one 0.02 s pre-run of the small
    cylinder).
    """
    import threading

    # a cache of its own: the session's may hold this case's pre-run already
    monkeypatch.setenv("GYMPRECICE_CACHE_DIR", str(tmp_path / "own-session-cache"))

    sources = [cylinder_case(f"fluid{i}", end_time=0.03, delta_t=0.002) for i in range(3)]
    solvers = [solver_for(s, prerun_end_time=0.01) for s in sources]
    threads = [threading.Thread(target=case.prepare_case, args=(s,)) for s in solvers]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    logs = [(s.run_dir / "log.prerun.pimpleFoam").read_text() for s in solvers]
    restored = [log.startswith("// gymprecice: pre-run restored") for log in logs]
    assert sorted(restored) == [False, True, True], "exactly one env ran the pre-run"
    fields = [(s.run_dir / "0.01" / "U").read_bytes() for s in solvers]
    assert fields[0] == fields[1] == fields[2]
    assert all(s.state["openfoam"].initial_time == "0.01" for s in solvers)

    # A case whose episodes are longer (another endTime in controlDict, which a pre-run
    # overrides) takes the same pre-run: a training's validation env with longer episodes.
    later = solver_for(cylinder_case("later", end_time=0.05, delta_t=0.002), prerun_end_time=0.01)
    case.prepare_case(later)
    assert (later.run_dir / "log.prerun.pimpleFoam").read_text().startswith("// gymprecice")
    assert (later.run_dir / "0.01" / "U").read_bytes() == fields[0]

    # Another input (here the pre-run's end) is another entry; false turns sharing off.
    longer = solver_for(cylinder_case("longer", end_time=0.03, delta_t=0.002), prerun_end_time=0.02)
    case.prepare_case(longer)
    assert not (longer.run_dir / "log.prerun.pimpleFoam").read_text().startswith("//")
    private = solver_for(
        cylinder_case("private", end_time=0.03, delta_t=0.002),
        prerun_end_time=0.01,
        prerun_cache=False,
    )
    case.prepare_case(private)
    assert not (private.run_dir / "log.prerun.pimpleFoam").read_text().startswith("//")
    own = tmp_path / "own-cache"
    elsewhere = solver_for(
        cylinder_case("elsewhere", end_time=0.03, delta_t=0.002),
        prerun_end_time=0.01,
        prerun_cache=str(own),
    )
    case.prepare_case(elsewhere)
    assert len([p for p in own.iterdir() if p.is_dir()]) == 1


def test_the_pre_run_cache_reads_controldict_without_what_a_pre_run_overrides() -> None:
    from gymprecice_openfoam.control import as_a_prerun_reads_it

    case = b"application pimpleFoam;\nstartFrom startTime;\nstartTime 0;\nendTime 6;\n" \
        b"deltaT 0.001;\nwriteInterval 6;\nfunctions\n{\n    endTime 3;\n}\n"  # fmt: skip
    longer = case.replace(b"endTime 6;", b"endTime 15;").replace(
        b"writeInterval 6", b"writeInterval 9"
    )
    finer = case.replace(b"deltaT 0.001", b"deltaT 0.0005")
    assert as_a_prerun_reads_it(case) == as_a_prerun_reads_it(longer)
    assert as_a_prerun_reads_it(case) != as_a_prerun_reads_it(finer)
    # an entry of a sub-dictionary is not the run's span: kept
    nested = case.replace(b"    endTime 3;", b"    endTime 4;")
    assert as_a_prerun_reads_it(case) != as_a_prerun_reads_it(nested)


def test_prerun_cache_option_is_checked() -> None:
    from gymprecice_openfoam import prerun_cache

    with pytest.raises(ConfigError, match="prerun_cache=3"):
        prerun_cache.cache_dir({"prerun_cache": 3})
    assert prerun_cache.cache_dir({"prerun_cache": False}) is None
