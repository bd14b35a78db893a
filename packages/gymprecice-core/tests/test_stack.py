"""``gymprecice install``'s machinery: sources, checksums, stamps, failures, order.

Steps here build nothing real: they write a file (or run a tiny shell command), so the
tests exercise what every real step relies on: a checksum mismatch refuses the archive, a
failed build leaves no stamp and skips what requires it, a second run takes the stamp.
The real builds run in the set-up (``scripts/setup.sh``) and the ``precice`` tests use them.
"""

from __future__ import annotations

import hashlib
import io
import subprocess
import sys
import tarfile
import threading
from pathlib import Path

import pytest

from gymprecice import stack
from gymprecice.tools.install_command import install_steps, stack_checks
from gymprecice.tools.stack import (
    BuildContext,
    BuildError,
    InstallStep,
    SourceArchive,
    install,
    order_steps,
    solver_environment,
    stamp_of,
)


@pytest.fixture
def prefix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "stack"
    monkeypatch.setenv(stack.PREFIX_ENV, str(root))
    monkeypatch.setenv(stack.DOWNLOAD_ENV, "0")
    monkeypatch.delenv(stack.SOURCES_ENV, raising=False)
    return root


def make_archive(folder: Path, name: str = "demo-1.0") -> SourceArchive:
    """A release-like archive ``<name>.tar.gz`` with one file, and its pinned description."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.tar.gz"
    data = b"int main() { return 0; }\n"
    with tarfile.open(path, "w:gz") as tar:
        info = tarfile.TarInfo(f"{name}/main.c")
        info.size = len(data)
        tar.addfile(info, io.BytesIO(data))
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return SourceArchive(filename=path.name, sha256=digest, url="", top=name)


def copying_step(archive: SourceArchive, name: str = "demo", **kwargs) -> InstallStep:
    """A step that 'builds' by copying the archive's file into <prefix>/lib."""
    calls: list[int] = []

    def build(ctx: BuildContext) -> None:
        calls.append(1)
        source = ctx.unpack(archive)
        (ctx.prefix / "lib").mkdir(parents=True, exist_ok=True)
        ctx.run(["cp", source / "main.c", ctx.prefix / "lib" / f"{name}.c"], cwd=ctx.work)

    step = InstallStep(
        name=name,
        title=f"{name} 1.0",
        version="1.0",
        archive=archive,
        build=build,
        built=lambda p: (p / "lib" / f"{name}.c") if (p / "lib" / f"{name}.c").exists() else None,
        **kwargs,
    )
    step.calls = calls  # type: ignore[attr-defined]
    return step


def test_builds_once_then_a_second_run_takes_the_stamp(prefix, tmp_path, monkeypatch):
    archive = make_archive(tmp_path / "mirror")
    monkeypatch.setenv(stack.SOURCES_ENV, str(tmp_path / "mirror"))
    step = copying_step(archive)
    lines: list[str] = []
    first = install([step], say=lines.append)
    assert [r.status for r in first] == ["built"]
    assert stamp_of(step) is not None
    assert (prefix / "logs" / "demo.log").is_file()
    assert any("building" in line for line in lines) and any("built in" in line for line in lines)
    second = install([step], say=lines.append)
    assert [r.status for r in second] == ["done"] and step.calls == [1]
    # what was built disappears: the stamp no longer counts, the step builds again
    (prefix / "lib" / "demo.c").unlink()
    assert stamp_of(step) is None
    assert [r.status for r in install([step], say=lines.append)] == ["built"]


def test_corrupt_archive_is_refused_and_nothing_is_marked_installed(prefix, tmp_path, monkeypatch):
    archive = make_archive(tmp_path / "mirror")
    (tmp_path / "mirror" / archive.filename).write_bytes(b"not the release")
    monkeypatch.setenv(stack.SOURCES_ENV, str(tmp_path / "mirror"))
    step = copying_step(archive)
    lines: list[str] = []
    [result] = install([step], say=lines.append)
    assert result.status == "failed"
    assert "checksum mismatch" in result.failure and archive.filename in result.failure
    assert "replace it" in result.failure
    assert stamp_of(step) is None and not (prefix / "stamps" / "demo.json").exists()
    assert not (prefix / "build" / "demo").exists()  # scratch removed


def test_missing_sources_without_download_name_the_variable(prefix, tmp_path):
    archive = make_archive(tmp_path / "elsewhere")
    [result] = install([copying_step(archive)], say=lambda _line: None)
    assert result.status == "failed"
    assert archive.filename in result.failure and stack.SOURCES_ENV in result.failure


def test_missing_tool_names_the_piece_and_the_fix(prefix, tmp_path):
    def build(ctx: BuildContext) -> None:
        ctx.run(["no-such-compiler-xyz", "--version"], cwd=ctx.work)

    step = InstallStep(
        name="tool",
        title="tool 1.0",
        version="1.0",
        build=build,
        built=lambda p: None,
        needs="install the compiler (apt-get install g++)",
    )
    [result] = install([step], say=lambda _line: None)
    assert result.status == "failed"
    assert "no-such-compiler-xyz" in result.failure and "apt-get install g++" in result.failure


def test_failed_build_shows_the_error_lines_and_skips_what_requires_it(prefix, tmp_path):
    def build(ctx: BuildContext) -> None:
        script = "echo compiling; echo 'main.c:3: error: expected ;'; seq 1 40; exit 2"
        ctx.run(["sh", "-c", script], cwd=ctx.work)

    broken = InstallStep(name="base", title="base 1.0", version="1.0", build=build,
                         built=lambda p: None)  # fmt: skip
    archive = make_archive(tmp_path / "mirror")
    dependent = copying_step(archive, name="child", requires=("base",))
    results = install([broken, dependent], say=lambda _line: None)
    assert [r.status for r in results] == ["failed", "skipped"]
    assert "main.c:3: error: expected ;" in results[0].failure  # far above the tail
    assert "exit status 2" in results[0].failure
    assert "gymprecice install base" in results[0].failure
    assert dependent.calls == [] and stamp_of(broken) is None


def test_steps_that_need_nothing_of_each_other_build_side_by_side(prefix, tmp_path):
    """After what they require, independent steps build at once (two meet inside their
    builds, which one at a time never do), each one's lines name it, and the results keep
    the steps' order; by default they build one after the other."""
    events: list[str] = []

    def step(name: str, meet: threading.Barrier | None, *requires: str) -> InstallStep:
        def build(ctx: BuildContext) -> None:
            events.append(f"start {name}")
            ctx.say("[install]   compiling")
            if meet is not None:
                meet.wait(timeout=10)  # BrokenBarrierError: the other one never came
            (ctx.prefix / "lib").mkdir(parents=True, exist_ok=True)
            (ctx.prefix / "lib" / name).touch()
            events.append(f"end {name}")

        def built(p: Path) -> Path | None:
            return p / "lib" / name if (p / "lib" / name).exists() else None

        return InstallStep(name, f"{name} 1.0", "1.0", build, built, requires=requires)

    meet = threading.Barrier(2)
    steps = [step("lib", None), step("left", meet, "lib"), step("right", meet, "lib")]
    lines: list[str] = []
    results = install(steps, jobs=2, at_once=2, say=lines.append)
    assert [(r.step.name, r.status) for r in results] == [
        ("lib", "built"),
        ("left", "built"),
        ("right", "built"),
    ]
    assert events[:2] == ["start lib", "end lib"]  # what they require comes first
    assert set(events[2:4]) == {"start left", "start right"}  # then both at once
    assert "[install]   left: compiling" in lines and "[install]   right: compiling" in lines

    events.clear()
    one_at_a_time = [step("lib2", None), step("a", None, "lib2"), step("b", None, "lib2")]
    install(one_at_a_time, jobs=2, say=lambda _line: None)
    assert events == ["start lib2", "end lib2", "start a", "end a", "start b", "end b"]


def test_the_longest_ready_steps_start_first_and_the_short_ones_fill_in(prefix, tmp_path):
    """Two slots, four steps after ``lib``: the two longest (by ``about_seconds``) start
    together whatever the listed order; each short one starts only when a slot frees."""
    events: list[str] = []
    lock = threading.Lock()
    long_ones = threading.Barrier(2)

    def step(name: str, about: float, *requires: str) -> InstallStep:
        def build(ctx: BuildContext) -> None:
            with lock:
                events.append(f"start {name}")
            if name in ("big", "large"):
                long_ones.wait(timeout=10)  # BrokenBarrierError: they did not run together
            (ctx.prefix / "lib").mkdir(parents=True, exist_ok=True)
            (ctx.prefix / "lib" / name).touch()
            with lock:
                events.append(f"end {name}")

        def built(p: Path) -> Path | None:
            return p / "lib" / name if (p / "lib" / name).exists() else None

        return InstallStep(
            name, f"{name} 1.0", "1.0", build, built, requires=requires, about_seconds=about
        )

    steps = [
        step("lib", 150),
        step("small", 45, "lib"),
        step("tiny", 40, "lib"),
        step("big", 100, "lib"),
        step("large", 90, "lib"),
    ]
    results = install(steps, jobs=2, at_once=2, say=lambda _line: None)
    assert [r.step.name for r in results] == ["lib", "small", "tiny", "big", "large"]
    assert all(r.status == "built" for r in results)
    assert set(events[2:4]) == {"start big", "start large"}
    assert events.index("start small") > min(events.index("end big"), events.index("end large"))


def test_found_elsewhere_is_used_not_rebuilt(prefix, tmp_path):
    archive = make_archive(tmp_path / "mirror")
    step = copying_step(archive, found=lambda: "/opt/demo (pkg-config)")
    [result] = install([step], say=lambda _line: None)
    assert result.status == "found" and step.calls == []


def test_order_puts_requirements_first_and_refuses_unknown_steps():
    def step(name: str, *requires: str) -> InstallStep:
        return InstallStep(name, name, "1", lambda c: None, lambda p: None, requires=requires)

    steps = [step("adapter", "lib"), step("lib"), step("other")]
    assert [s.name for s in order_steps(steps, ["adapter"])] == ["lib", "adapter"]
    assert [s.name for s in order_steps(steps, ["all"])] == ["lib", "adapter", "other"]
    with pytest.raises(BuildError, match="unknown install step nope; known: all, adapter"):
        order_steps(steps, ["nope"])


def test_skip_leaves_a_step_out_unless_a_wanted_one_requires_it():
    def step(name: str, *requires: str) -> InstallStep:
        return InstallStep(name, name, "1", lambda c: None, lambda p: None, requires=requires)

    steps = [step("adapter", "lib"), step("lib"), step("other")]
    assert [s.name for s in order_steps(steps, ["all"], skip=["other"])] == ["lib", "adapter"]
    assert [s.name for s in order_steps(steps, ["all"], skip=["lib"])] == [
        "lib",
        "adapter",
        "other",
    ]
    assert [s.name for s in order_steps(steps, ["all"], skip=["absent"])] == [
        "lib",
        "adapter",
        "other",
    ]


def test_solver_environment_adds_the_stack_once(prefix):
    assert solver_environment({"PATH": "/usr/bin"}) == {}  # nothing built: nothing added
    (prefix / "lib").mkdir(parents=True)
    (prefix / "bin").mkdir()
    env = solver_environment({"PATH": "/usr/bin", "LD_LIBRARY_PATH": "/opt/lib"})
    assert env["PATH"].split(":") == ["/usr/bin", str(prefix / "bin")]
    assert env["LD_LIBRARY_PATH"].split(":") == ["/opt/lib", str(prefix / "lib")]
    assert solver_environment(env) == {}


def test_every_installed_plugin_contributes_its_step():
    names = [s.name for s in install_steps()]
    assert names[:2] == ["precice", "pyprecice"]
    assert {"openfoam-adapter", "dealii-adapter"} <= set(names)
    assert all(s.archive is None or len(s.archive.sha256) == 64 for s in install_steps())


def test_doctor_lines_say_what_to_run(prefix):
    step = InstallStep("demo", "demo 1.0", "1.0", lambda c: None, lambda p: None)
    [check] = stack_checks([step])
    assert not check.ok and check.advice == "run `gymprecice install demo`"


def test_install_command_lists_and_refuses_unknown_steps(prefix):
    run = [sys.executable, "-m", "gymprecice", "install"]
    listed = subprocess.run([*run, "--list"], capture_output=True, text=True, timeout=120)
    assert listed.returncode == 0 and "openfoam-adapter" in listed.stdout
    wrong = subprocess.run([*run, "precise"], capture_output=True, text=True, timeout=120)
    assert wrong.returncode == 2 and "unknown install step precise" in wrong.stdout


def test_doctor_says_what_is_wrong_when_pyprecice_cannot_load_libprecice(prefix):
    from gymprecice.tools.cli import _pyprecice_advice

    (prefix / "lib").mkdir(parents=True)
    (prefix / "lib" / "libprecice.so.3").write_bytes(b"")
    error = "ImportError: libprecice.so.3: cannot open shared object file: No such file"
    advice = _pyprecice_advice(error)
    assert "does not find libprecice" in advice and str(prefix / "lib") in advice
    assert "gymprecice install pyprecice --force" in advice and "LD_LIBRARY_PATH" in advice
    assert "gymprecice install" in _pyprecice_advice(
        "ModuleNotFoundError: No module named 'precice'"
    )


# -- prerequisites: probed before anything is built ---------------------------------------------


def test_missing_prerequisites_are_named_at_once_and_nothing_of_that_step_builds(prefix, tmp_path):
    from gymprecice.tools.prerequisites import Prerequisite, program

    archive = make_archive(tmp_path / "mirror")
    absent = program("CMake", "no-such-cmake-xyz", debian=("cmake",))
    eigen = Prerequisite("Eigen 3", lambda: False, ("libeigen3-dev",))
    there = Prerequisite("make", lambda: True, ("make",))
    lib = copying_step(archive, name="lib", prerequisites=(absent, eigen, there))
    adapter = copying_step(archive, name="adapter", requires=("lib",))
    other = copying_step(archive, name="other", prerequisites=(there,))
    lines: list[str] = []
    results = install([lib, adapter, other], say=lines.append)
    assert [r.status for r in results] == ["missing", "skipped", "failed"]  # other: no sources
    # said first, before any step starts: what each lacks and one apt-get line for all
    assert lines[0].startswith("[install] missing on this machine")
    assert "lib: CMake, Eigen 3" in lines[0] and "make" not in lines[0].split("\n")[1]
    assert "sudo apt-get install cmake libeigen3-dev" in lines[0]
    assert "CMake, Eigen 3" in results[0].detail
    assert lib.calls == [] and adapter.calls == []
    assert not (prefix / "logs" / "lib.log").exists()


def test_a_step_found_elsewhere_or_done_needs_no_prerequisites(prefix, tmp_path):
    from gymprecice.tools.prerequisites import Prerequisite

    never = Prerequisite("a compiler", lambda: False)
    archive = make_archive(tmp_path / "mirror")
    step = copying_step(archive, found=lambda: "/opt/demo", prerequisites=(never,))
    lines: list[str] = []
    [result] = install([step], say=lines.append)
    assert result.status == "found" and not any("missing" in line for line in lines)


def test_prerequisite_probes_look_where_the_compiler_looks(tmp_path, monkeypatch):
    from gymprecice import prerequisites as pre

    include, lib, bin_ = tmp_path / "include", tmp_path / "lib", tmp_path / "bin"
    for folder in (include / "toymath" / "Toy", lib, bin_):
        folder.mkdir(parents=True)
    monkeypatch.setenv("PATH", str(bin_))
    monkeypatch.setenv("CPATH", str(include))
    monkeypatch.setenv("LIBRARY_PATH", str(lib))
    tool = pre.program("toy tool", "toy-tool-xyz", debian=("toy",))
    head = pre.header("toy headers", "toy/toy.h")
    libs = pre.library("toy libraries", "toy_a", "toy_b")
    eigen = pre.pkg_config("toy math", "no-such-module-xyz", "toymath/Toy/Core")
    assert pre.missing([tool, head, libs, eigen]) == [tool, head, libs, eigen]
    script = bin_ / "toy-tool-xyz"
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    (include / "toy").mkdir()
    (include / "toy" / "toy.h").write_text("")
    (include / "toymath" / "Toy" / "Core").write_text("")
    (lib / "libtoy_a.so.1").write_text("")
    assert pre.missing([tool, head, libs, eigen]) == [libs]  # libtoy_b is still missing
    (lib / "libtoy_b.so").write_text("")
    assert pre.missing([tool, head, libs, eigen]) == []
    assert pre.describe_missing([tool]) == "toy tool (Debian/Ubuntu: sudo apt-get install toy)"


def test_install_help_states_the_build_prerequisites():
    proc = subprocess.run(
        [sys.executable, "-m", "gymprecice", "install", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    for piece in ("C++ compiler", "CMake", "pkg-config", "Boost", "Eigen", "libxml2"):
        assert piece in proc.stdout, piece
    assert "sudo apt-get install g++ make cmake pkg-config" in proc.stdout
    assert "setup.sh" not in proc.stdout


def test_core_steps_declare_what_precice_needs():
    from gymprecice.tools.precice_install import core_install_steps

    precice, pyprecice = core_install_steps()
    titles = " ".join(p.title for p in precice.prerequisites)
    for piece in ("C++ compiler", "CMake", "pkg-config", "Boost", "Eigen", "libxml2", "make"):
        assert piece in titles, piece
    assert any("Python.h" in p.title for p in pyprecice.prerequisites)
