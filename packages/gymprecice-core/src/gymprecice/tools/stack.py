"""Build the real coupling stack (preCICE, pyprecice, solver adapters) from release sources.

preCICE, pyprecice's C++ side and the solvers' preCICE adapters are in no binary package
registry, and building them by hand is what preCICE users struggle with most. This module is
the machinery of ``gymprecice install``: each piece is an :class:`InstallStep` (core owns
preCICE and pyprecice, each solver plugin contributes the step for its own adapter through
``gymprecice_install_steps``), and :func:`install` runs them in order.

Why it is shaped like this:

* **One per-user prefix** (``$GYMPRECICE_STACK_PREFIX``, default
  ``~/.local/share/gymprecice/stack``) outside every checkout, so that each clone, venv and CI
  run reuses the libraries built once. Only pyprecice lives in the venv (it is a Python
  package), linked to the prefix by an RPATH, so nobody sources anything.
* **Sources** come from a directory named by ``$GYMPRECICE_SOURCES`` (an offline mirror of the
  release archives) or, where the machine reaches GitHub, from the release archive itself.
  Every archive is checked against the checksum pinned here: a corrupt or different archive
  is refused before anything is built.
* **Stamps**: a step is done when its stamp (version and archive checksum) matches and what
  it built is still there, so a second run takes seconds. The stamp is written last, after a
  successful build; a failed or interrupted build leaves no stamp, and the next run builds
  again. One lock serialises concurrent set-ups of the same prefix; inside one, the steps
  that need nothing of each other may build side by side (``--at-once``).
* **Prerequisites first**: each step lists what it needs on the machine (a compiler, CMake,
  Boost, a solver; see :mod:`gymprecice.prerequisites`). Before anything is built, every step
  that would be built is probed, and all that is missing is named at once with the packages
  that provide it; a step that lacks something is not started (``missing``).
* **Logs**: each step logs to ``<prefix>/logs/<step>.log``; a failure prints the log's tail,
  the lines that look like errors, and what to do.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tarfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

from gymprecice.plugin.errors import GymPreciceError
from gymprecice.tools.prerequisites import Prerequisite, command_output, describe_missing

__all__ = [
    "PREFIX_ENV",
    "SOURCES_ENV",
    "BuildContext",
    "BuildError",
    "InstallStep",
    "SourceArchive",
    "command_output",
    "install",
    "solver_environment",
    "stack_prefix",
    "stack_which",
    "stamp_of",
]

PREFIX_ENV = "GYMPRECICE_STACK_PREFIX"
SOURCES_ENV = "GYMPRECICE_SOURCES"
#: Set to ``0`` to never download (a machine that must build from the mirror only).
DOWNLOAD_ENV = "GYMPRECICE_DOWNLOAD"


class BuildError(GymPreciceError):
    """A step of ``gymprecice install`` failed; the message says which, why and what to do."""


def stack_prefix() -> Path:
    """Where ``gymprecice install`` puts what it builds (one per user, shared by checkouts)."""
    explicit = os.environ.get(PREFIX_ENV)
    if explicit:
        return Path(explicit).expanduser().resolve()
    data = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data).expanduser() / "gymprecice" / "stack"


def solver_environment(
    environ: Mapping[str, str] | None = None, prefix: Path | None = None
) -> dict[str, str]:
    """Variables that let a solver process find the stack built by ``gymprecice install``.

    The OpenFOAM-preCICE adapter is a function object that OpenFOAM ``dlopen``s by bare name,
    so its directory must be on ``LD_LIBRARY_PATH``; ``elasticity`` must be on ``PATH``.
    Plugins add these to the environment of the solvers they launch. Returns only the
    variables that change, and nothing when the stack was never built.
    """
    environ = os.environ if environ is None else environ
    prefix = stack_prefix() if prefix is None else prefix
    changes: dict[str, str] = {}
    for var, sub in (("LD_LIBRARY_PATH", "lib"), ("PATH", "bin")):
        folder = prefix / sub
        if not folder.is_dir():
            continue
        parts = [p for p in environ.get(var, "").split(os.pathsep) if p]
        if str(folder) not in parts:
            changes[var] = os.pathsep.join([*parts, str(folder)])
    return changes


def stack_which(program: str, environ: Mapping[str, str] | None = None) -> str | None:
    """:func:`shutil.which` that also looks in the stack's ``bin`` (after ``PATH``)."""
    environ = os.environ if environ is None else environ
    path = environ.get("PATH", os.defpath)
    extra = solver_environment(environ).get("PATH")
    return shutil.which(program, path=extra or path)


# -- sources -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SourceArchive:
    """A release source archive, pinned by its checksum."""

    filename: str
    sha256: str
    url: str = ""  # where it is published (used only where the machine reaches it)
    top: str = ""  # the single top directory inside the archive

    def locate(self, log: Callable[[str], None]) -> Path:
        """The archive on disk: from ``$GYMPRECICE_SOURCES``, or downloaded; checksum verified."""
        sources = os.environ.get(SOURCES_ENV)
        if sources:
            candidate = Path(sources).expanduser() / self.filename
            if candidate.is_file():
                self.verify(candidate)
                return candidate
        cached = stack_prefix() / "sources" / self.filename
        if cached.is_file():
            self.verify(cached)
            return cached
        where = f"${SOURCES_ENV}={sources}" if sources else f"${SOURCES_ENV} is not set"
        if not self.url or os.environ.get(DOWNLOAD_ENV, "1") == "0":
            raise BuildError(
                f"{self.filename}: not found ({where}) and downloading is off; put the release "
                f"archive in a directory and set {SOURCES_ENV} to it"
            )
        # Imported here: every importer of gymprecice.plugin (a solver partner too) loads
        # this module, and only a download needs urllib's HTTP stack.
        import urllib.request

        log(f"downloading {self.url}")
        cached.parent.mkdir(parents=True, exist_ok=True)
        partial = cached.with_name(cached.name + ".part")
        try:
            with urllib.request.urlopen(self.url, timeout=60) as response, partial.open("wb") as f:
                shutil.copyfileobj(response, f)
        except OSError as exc:
            partial.unlink(missing_ok=True)
            raise BuildError(
                f"{self.filename}: not found ({where}) and the download from {self.url} failed "
                f"({exc}); on a machine without internet, put the release archive in a "
                f"directory and set {SOURCES_ENV} to it"
            ) from None
        self.verify(partial)
        partial.rename(cached)
        return cached

    def verify(self, path: Path) -> None:
        digest = hashlib.sha256()
        with path.open("rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        if digest.hexdigest() != self.sha256:
            raise BuildError(
                f"{path}: checksum mismatch (sha256 {digest.hexdigest()}, expected "
                f"{self.sha256}); the archive is corrupt or not the pinned release: replace it "
                f"with the original {self.filename}"
            )


# -- steps -------------------------------------------------------------------------------------


@dataclass
class BuildContext:
    """What a step's ``build`` gets: where to install, a scratch directory, a logged runner."""

    step: InstallStep
    prefix: Path
    work: Path
    log_path: Path
    jobs: int
    say: Callable[[str], None] = print

    def run(self, argv: Sequence[str], cwd: Path, env: Mapping[str, str] | None = None) -> None:
        """Run a build command; its output goes to the step's log, a failure raises."""
        full_env = {**os.environ, **(env or {})}
        with self.log_path.open("a") as log:
            log.write(f"\n$ (cd {cwd} && {' '.join(map(str, argv))})\n")
            log.flush()
            try:
                proc = subprocess.run(
                    [str(a) for a in argv],
                    cwd=cwd,
                    env=full_env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL,
                )
            except FileNotFoundError:
                raise BuildError(
                    f"{self.step.title}: `{argv[0]}` is not installed; {self.step.needs}"
                ) from None
        if proc.returncode != 0:
            raise BuildError(
                f"{self.step.title}: `{Path(str(argv[0])).name}` failed "
                f"(exit status {proc.returncode})"
            )

    def unpack(self, archive: SourceArchive) -> Path:
        """Extract a verified archive into the scratch directory; returns its top directory."""
        path = archive.locate(self.say)
        with tarfile.open(path) as tar:
            tar.extractall(self.work, filter="tar")
        return self.work / archive.top if archive.top else self.work

    def pkg_config_env(self) -> dict[str, str]:
        """Environment in which ``pkg-config`` and CMake find the stack's preCICE."""
        pc = [str(self.prefix / "lib" / "pkgconfig")]
        if os.environ.get("PKG_CONFIG_PATH"):
            pc.append(os.environ["PKG_CONFIG_PATH"])
        return {
            "PKG_CONFIG_PATH": os.pathsep.join(pc),
            "CMAKE_PREFIX_PATH": os.pathsep.join(
                p for p in (str(self.prefix), os.environ.get("CMAKE_PREFIX_PATH", "")) if p
            ),
            **solver_environment(prefix=self.prefix),
        }


#: :attr:`InstallStep.needs` by default: the advice when a build program is missing
BUILD_TOOLS_ADVICE = "install the build tools (a C++ compiler, make, CMake) and run it again"


@dataclass
class InstallStep:
    """One piece of the stack: how to tell it is there, and how to build it.

    ``found`` returns a description of a usable installation that this step did not build
    (e.g. a preCICE that ``pkg-config`` finds), in which case nothing is built. ``built``
    returns the path of what this step's own build produced, or ``None`` once it is gone.
    ``key`` changes whenever a rebuild is needed (version, archive checksum, build options).
    ``prerequisites`` are probed before the build starts (:mod:`gymprecice.prerequisites`);
    ``needs`` is the advice when a build program turns out to be missing all the same.
    """

    name: str
    title: str
    version: str
    build: Callable[[BuildContext], None]
    built: Callable[[Path], Path | None]
    found: Callable[[], str | None] = lambda: None
    archive: SourceArchive | None = None
    requires: tuple[str, ...] = ()
    needs: str = BUILD_TOOLS_ADVICE
    key_extra: str = ""
    per_environment: bool = False  # built into the running Python environment, not the prefix
    prerequisites: tuple[Prerequisite, ...] = ()
    #: roughly how long its build takes on a 2-core machine: of the steps ready to build
    #: side by side, the longest start first, and the shorter ones fill in beside them
    about_seconds: float = 60.0

    def missing_prerequisites(self) -> list[Prerequisite]:
        """The prerequisites whose probe finds nothing on this machine."""
        return [p for p in dict.fromkeys(self.prerequisites) if not p.present()]

    @property
    def key(self) -> str:
        checksum = self.archive.sha256 if self.archive else ""
        scope = sys.prefix if self.per_environment else ""
        return "|".join((self.version, checksum, self.key_extra, scope))


def stamp_path(step: InstallStep, prefix: Path) -> Path:
    scope = hashlib.sha256(sys.prefix.encode()).hexdigest()[:12] if step.per_environment else ""
    return prefix / "stamps" / (f"{step.name}-{scope}.json" if scope else f"{step.name}.json")


def stamp_of(step: InstallStep, prefix: Path | None = None) -> dict | None:
    """The stamp of a finished build of ``step`` whose product still exists, else ``None``."""
    prefix = stack_prefix() if prefix is None else prefix
    path = stamp_path(step, prefix)
    try:
        stamp = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if stamp.get("key") != step.key or step.built(prefix) is None:
        return None
    return stamp


@contextlib.contextmanager
def _locked(prefix: Path) -> Iterator[None]:
    prefix.mkdir(parents=True, exist_ok=True)
    with (prefix / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def order_steps(
    steps: Sequence[InstallStep], wanted: Sequence[str], skip: Sequence[str] = ()
) -> list[InstallStep]:
    """``wanted`` (or all, for ``"all"``) with what they require first, in dependency order.

    ``skip`` leaves steps out of what is wanted (a set-up that opts out of one solver, e.g.
    ``--skip fenics``); a skipped step that a wanted one requires is still built, and a name
    no installed plugin offers is ignored (opting out of what is not there is no error).
    """
    by_name = {s.name: s for s in steps}
    unknown = [w for w in wanted if w != "all" and w not in by_name]
    if unknown:
        raise BuildError(
            f"unknown install step {', '.join(unknown)}; known: all, {', '.join(by_name)}"
        )
    names = list(by_name) if "all" in wanted or not wanted else list(wanted)
    names = [n for n in names if n not in skip]
    ordered: list[InstallStep] = []

    def visit(name: str, chain: tuple[str, ...]) -> None:
        if name in chain:
            raise BuildError(f"install steps require each other: {' -> '.join([*chain, name])}")
        step = by_name.get(name)
        if step is None or step in ordered:
            return
        for req in step.requires:
            visit(req, (*chain, name))
        ordered.append(step)

    for name in names:
        visit(name, ())
    return ordered


@dataclass
class StepResult:
    step: InstallStep
    status: str  # "built", "done", "found", "missing" (prerequisites), "failed", "skipped"
    detail: str = ""
    seconds: float = 0.0
    log: Path | None = None
    failure: str = field(default="", repr=False)


def install(
    steps: Sequence[InstallStep],
    *,
    force: bool = False,
    jobs: int | None = None,
    prefix: Path | None = None,
    say: Callable[[str], None] = print,
    at_once: int = 1,
) -> list[StepResult]:
    """Build every step that is not done yet; a failed step skips the steps that require it.

    First, for every step that would be built, its prerequisites are probed and everything
    missing is said at once; such a step is not started (``missing``).

    With ``at_once`` above 1, steps whose requirements are settled build side by side, that
    many at a time: after preCICE, its adapters and pyprecice need nothing of each other,
    and much of each build runs on one core (CMake's configuring, unpacking, pip,
    pyprecice's one translation unit). One at a time is the default until a
    quiet machine has shown what building side by side saves. The results come in the
    order of ``steps``.
    """
    prefix = stack_prefix() if prefix is None else prefix
    jobs = jobs or max(1, len(os.sched_getaffinity(0)))
    lock = threading.Lock()

    def said(line: str) -> None:  # whole lines, whichever build says them
        with lock:
            say(line)

    with _locked(prefix):
        plan = _plan(steps, prefix, force=force)
        lacking = {step.name: absent for step, _, _, absent in plan if absent}
        if lacking:
            said(missing_prerequisites_message(steps, lacking))
        planned = {step.name for step, *_ in plan}
        results: dict[str, StepResult] = {}
        failed: set[str] = set()
        built: set[str] = set()
        pending = list(plan)
        running: dict[Future[StepResult], str] = {}
        with ThreadPoolExecutor(max_workers=max(1, at_once)) as pool:
            while pending or running:
                # longest first: after preCICE, its two adapters side by side, then pyprecice
                # and FEniCS's environment as each frees a slot (the listed order ran those
                # two one after the other beside the deal.II adapter, and the OpenFOAM
                # adapter only after them)
                ready = sorted(pending, key=lambda entry: -entry[0].about_seconds)
                for entry in ready:
                    step = entry[0]
                    if any(r in planned and r not in results for r in step.requires):
                        continue  # what it requires is still being built
                    pending.remove(entry)
                    settled, stamp, elsewhere = _judge(
                        entry, prefix, failed, built, force=force, say=said
                    )
                    if settled is not None:
                        results[step.name] = settled
                        continue
                    future = pool.submit(
                        _run_step, step, prefix, stamp, elsewhere, jobs=jobs, say=said
                    )
                    running[future] = step.name
                if not running:
                    continue
                finished, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in finished:
                    name = running.pop(future)
                    results[name] = future.result()
                    if results[name].status == "failed":
                        failed.add(name)
                    elif results[name].status == "built":
                        built.add(name)
    return [results[step.name] for step, *_ in plan]


def _judge(
    entry: tuple[InstallStep, dict | None, str | None, list[Prerequisite]],
    prefix: Path,
    failed: set[str],
    built: set[str],
    *,
    force: bool,
    say: Callable[[str], None],
) -> tuple[StepResult | None, dict | None, str | None]:
    """A step whose requirements are settled: its result when it is not to be built
    (``skipped``, ``missing``), else None; and its stamp and an installation found elsewhere,
    judged again when what it requires was just rebuilt."""
    step, stamp, elsewhere, absent = entry
    blocked = [r for r in step.requires if r in failed]
    if blocked:
        failed.add(step.name)
        say(f"[install] {step.title}: skipped (needs {', '.join(blocked)})")
        return StepResult(step, "skipped", f"needs {', '.join(blocked)}"), None, None
    if not force and any(r in built for r in step.requires):
        # what it requires was just rebuilt: judge the step now, not before that
        stamp = stamp_of(step, prefix)
        elsewhere = None if stamp is not None else step.found()
        if stamp is None and not elsewhere:
            absent = step.missing_prerequisites()
    if absent:
        failed.add(step.name)
        say(f"[install] {step.title}: not built, missing {describe_missing(absent)}")
        return StepResult(step, "missing", describe_missing(absent)), None, None
    return None, stamp, elsewhere


def _plan(
    steps: Sequence[InstallStep], prefix: Path, *, force: bool
) -> list[tuple[InstallStep, dict | None, str | None, list[Prerequisite]]]:
    """Per step: its stamp, an installation found elsewhere, and what a build would lack."""
    plan = []
    for step in steps:
        stamp = None if force else stamp_of(step, prefix)
        elsewhere = None if force or stamp is not None else step.found()
        build = stamp is None and not elsewhere
        plan.append((step, stamp, elsewhere, step.missing_prerequisites() if build else []))
    return plan


def missing_prerequisites_message(
    steps: Sequence[InstallStep], lacking: Mapping[str, Sequence[Prerequisite]]
) -> str:
    """What each step lacks, and one ``apt-get install`` line for all of it."""
    lines = ["[install] missing on this machine (nothing of these steps is built):"]
    everything: list[Prerequisite] = []
    for step in steps:
        absent = lacking.get(step.name)
        if absent:
            lines.append(f"  {step.name}: {', '.join(p.title for p in absent)}")
            everything.extend(absent)
    packages = list(dict.fromkeys(d for p in everything for d in p.debian))
    if packages:
        lines.append(f"  Debian/Ubuntu: sudo apt-get install {' '.join(packages)}")
    lines.append(
        "  Install them and run `gymprecice install` again (`--skip STEP` leaves a step out)."
    )
    return "\n".join(lines)


def _run_step(
    step: InstallStep,
    prefix: Path,
    stamp: dict | None,
    elsewhere: str | None,
    *,
    jobs: int,
    say: Callable[[str], None],
) -> StepResult:
    if stamp is not None:
        say(f"[install] {step.title}: done ({stamp.get('path')})")
        return StepResult(step, "done", str(stamp.get("path")))
    if elsewhere:
        say(f"[install] {step.title}: found {elsewhere}, not built")
        return StepResult(step, "found", elsewhere)
    log_path = prefix / "logs" / f"{step.name}.log"
    log_path.parent.mkdir(parents=True, exist_ok=True)
    log_path.write_text(f"gymprecice install {step.name}: {step.title}\n")
    stamp_path(step, prefix).unlink(missing_ok=True)
    say(f"[install] {step.title}: building (log: {log_path})")
    work = prefix / "build" / step.name
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    started = time.monotonic()
    try:
        # its progress lines name it: other steps may be building beside it
        def step_say(line: str) -> None:
            say(line.replace("[install]   ", f"[install]   {step.name}: ", 1))

        step.build(BuildContext(step, prefix, work, log_path, jobs, step_say))
        product = step.built(prefix)
        if product is None:
            raise BuildError(f"{step.title}: the build finished but produced nothing usable")
    except (BuildError, OSError, tarfile.TarError) as exc:
        seconds = time.monotonic() - started
        message = _failure_message(step, exc, log_path)
        say(message)
        return StepResult(step, "failed", str(exc), seconds, log_path, message)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    seconds = time.monotonic() - started
    stamp = {"key": step.key, "version": step.version, "path": str(product), "seconds": seconds}
    stamp_path(step, prefix).parent.mkdir(parents=True, exist_ok=True)
    stamp_path(step, prefix).write_text(json.dumps(stamp, indent=1) + "\n")
    say(f"[install] {step.title}: built in {_minutes(seconds)} ({product})")
    return StepResult(step, "built", str(product), seconds, log_path)


def _failure_message(step: InstallStep, exc: BaseException, log_path: Path) -> str:
    try:
        lines = log_path.read_text(errors="replace").splitlines()
    except OSError:
        lines = []
    errors = [ln for ln in lines if "error" in ln.lower() and "-Werror" not in ln][-8:]
    tail = lines[-15:]
    shown = [*errors, "  ...", *tail] if errors else tail
    body = "\n".join(f"    {ln}" for ln in shown)
    return (
        f"[install] {step.title}: FAILED: {exc}\n"
        f"  from {log_path}:\n{body}\n"
        f"  Nothing of {step.name} is marked installed; fix the cause and run "
        f"`gymprecice install {step.name}` again."
    )


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:.0f} s" if seconds >= 60 else f"{seconds:.1f} s"
