"""Test-wide settings for every test directory of the repository, and the suite's own checks.

The variables below are what ``scripts/test.sh`` and CI set (docs/contributing/test-suite.md):

* ``GYMPRECICE_REQUIRE_REAL=1``: a real-stack test that skips fails instead.
* ``GYMPRECICE_TIER=fast`` runs only the tests that need neither the real stack nor much
  time (run before the stack is built, so that a broken change fails in minutes);
  ``GYMPRECICE_TIER=rest`` runs the others, and again every test that skipped in the fast
  tier (listed in the file ``GYMPRECICE_TIER_SKIPPED``): together the two are the whole suite.
  The rest splits in two that run side by side: ``GYMPRECICE_TIER=waiting``, the tests
  that mostly wait (those that start a Ray cluster, for nodes, heartbeats and restarted
  actors; those marked ``waits``, for timeouts and signals), and ``GYMPRECICE_TIER=local``,
  all the others.
* ``GYMPRECICE_DURATIONS=<file>``: the session's wall-clock and every test's time (set-up,
  call and tear-down; wall and CPU seconds) are written there as JSON, slowest first, for
  ``scripts/suite_report.py``'s budget check.

And a rule for every real-stack test: its docstring states what it costs (``Cost: about
20 s (...)``). A real test that passes without one fails, so that a new one cannot slip into
the suite's budget unnoticed.
"""

from __future__ import annotations

import json
import os
import re
import resource
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Set to 1 (CI does) to turn a skipped real-stack test into a failure: where the set-up
#: builds preCICE and the adapters, a ``precice``/``openfoam``/``dealii``/``fenics`` test that skips
#: proves nothing and hides a broken set-up.
REQUIRE_REAL_ENV = "GYMPRECICE_REQUIRE_REAL"
REAL_MARKERS = ("precice", "openfoam", "dealii", "fenics")
#: ``fast`` or ``rest`` (or the rest's two parts, ``waiting`` and ``local``): which tier of the
#: suite this session runs (unset: all of it).
TIER_ENV = "GYMPRECICE_TIER"
#: The file the fast tier lists its skipped tests in, and the rest tier runs them from.
TIER_SKIPPED_ENV = "GYMPRECICE_TIER_SKIPPED"
#: Markers that keep a test out of the fast tier, besides the real-stack ones.
SLOW_MARKERS = ("slow",)
#: A file to write the session's durations to (JSON).
DURATIONS_ENV = "GYMPRECICE_DURATIONS"
#: What a real-stack test's docstring says about its cost: ``Cost: about 40 s (pimpleFoam)``.
COST_LINE = re.compile(r"\bCost:\s*\S")
#: How ``pytest -n N --dist loadgroup`` (scripts/test.sh; a scheduler of pytest-xdist's
#: ``loadgroup`` kind, below, since its own does not see groups with pytest 9) shares the
#: tests between its workers: the tests that start a Ray cluster on one worker (two clusters
#: at once would compete for the same ports and cores); a test that uses a module- or
#: class-wide fixture with its module, so that the fixture is made once; every other test,
#: the real solvers' among them, on its own, to whichever worker is free. A coupled run
#: keeps about one core busy (its participants take turns), and most tests wait more than
#: they compute, so the workers, not a group, bound how many solvers run at once.
RAY_GROUP = "ray"
RAY_FIXTURES = ("ray_cluster",)
RAY_MODULES = ("tests/test_ray.py",)
#: A test using a fixture of one of these scopes stays with its module's other tests.
SHARED_SCOPES = ("module", "class", "package")

#: This session's tier settings, taken out of the environment at start-up (a test that runs
#: pytest in a subprocess must not inherit them: it would overwrite this session's files).
_settings: dict[str, str] = {}
_SETTING_NAMES = (TIER_ENV, TIER_SKIPPED_ENV, DURATIONS_ENV)


def pytest_configure(config: pytest.Config) -> None:
    taken = {name: os.environ.pop(name) for name in _SETTING_NAMES if name in os.environ}
    worker = getattr(config, "workerinput", None)
    _settings.clear()
    _settings.update(worker.get("gymprecice_suite", {}) if worker is not None else taken)
    xdist = worker is None and config.pluginmanager.has_plugin("xdist")
    if xdist and config.getoption("dist") == "loadgroup" and config.getoption("numprocesses"):
        _settings[GROUPS_KEY] = _groups_file(config)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node) -> None:
    """Hand this session's tier settings to a pytest-xdist worker."""
    handed = {k: v for k, v in _settings.items() if k != DURATIONS_ENV}  # the controller writes
    node.workerinput["gymprecice_suite"] = handed


@pytest.fixture(scope="session", autouse=True)
def _session_prerun_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """One OpenFOAM pre-run cache for the session, never the user's.

    A pre-run is stored under a hash of everything it depends on (the case's files, the
    times, the application, the installation), so tests with the same case share it instead
    of each paying for it again; a test with another case gets its own entry. Set for the
    whole session, before any module's fixture pre-runs. With pytest-xdist the workers share
    it (an entry is locked while it is made and renamed into place). A test about the cache
    itself points ``GYMPRECICE_CACHE_DIR`` at a directory of its own.
    """
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's directory, above each worker's own
    directory = root / "gymprecice-cache"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("GYMPRECICE_CACHE_DIR", str(directory))
        # Stable-Baselines3 makes a folder in the system's temporary directory for every
        # learn() whose logger it configures itself; the session's temporary folder takes
        # them, so a test run leaves nothing in /tmp.
        patch.setenv("SB3_LOGDIR", str(tmp_path_factory.getbasetemp() / "sb3-logs"))
        yield directory


def _real_markers(item: pytest.Item) -> list[str]:
    return [m for m in REAL_MARKERS if item.get_closest_marker(m) is not None]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()
    report.user_properties.append(("cpu_s", _cpu_since(item)))
    markers = _real_markers(item)
    if not markers:
        return
    if report.when == "call" and report.passed and not states_cost(item):
        report.outcome = "failed"
        report.longrepr = (
            f"this {'/'.join(markers)} test does not state its cost: a real-stack test says in "
            "its docstring what it adds to the suite's time, such as `Cost: about 20 s (one "
            "pimpleFoam, 0.05 s simulated)`; measure it (`pytest --durations=0 TEST`) and "
            "say so (docs/contributing/test-suite.md)"
        )
        return
    if not report.skipped or os.environ.get(REQUIRE_REAL_ENV, "0") in ("", "0"):
        return
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    report.outcome = "failed"
    report.longrepr = (
        f"{REQUIRE_REAL_ENV}=1 and this {'/'.join(markers)} test was skipped ({reason}); "
        "the set-up did not provide the real stack: see `gymprecice doctor` and "
        "`gymprecice install --list`"
    )


def states_cost(item: pytest.Item) -> bool:
    """Whether the test's docstring, or its class's (a class of tests that share one
    fixture), says ``Cost: ...``."""
    docs = [getattr(getattr(item, "function", None), "__doc__", None)]
    cls = getattr(item, "cls", None)
    if cls is not None:
        docs.append(cls.__doc__)
    return any(COST_LINE.search(doc) for doc in docs if doc)


# -- tiers ---------------------------------------------------------------------------------------


def xdist_group(item: pytest.Item) -> str:
    """The group of a test, run on one pytest-xdist worker (see ``RAY_GROUP``)."""
    module = item.nodeid.split("::", 1)[0]
    if module in RAY_MODULES or any(f in RAY_FIXTURES for f in getattr(item, "fixturenames", ())):
        return RAY_GROUP
    fixtures = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
    if any(d.scope in SHARED_SCOPES for defs in fixtures.values() for d in defs):
        return module  # its module- or class-wide fixture is made once
    return item.nodeid


def in_fast_tier(item: pytest.Item) -> bool:
    """A test that needs neither the real stack nor much time (nor a Ray cluster, whose
    start-up alone takes tens of seconds)."""
    if any(item.get_closest_marker(m) for m in (*REAL_MARKERS, *SLOW_MARKERS)):
        return False
    return xdist_group(item) != RAY_GROUP


def mostly_waits(item: pytest.Item) -> bool:
    """A test of the rest that mostly waits, run beside the others (``scripts/test.sh``):
    one that starts a Ray cluster, or one marked ``waits``."""
    return xdist_group(item) == RAY_GROUP or item.get_closest_marker("waits") is not None


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    _select_tier(config, items)
    if GROUPS_KEY in _settings:  # a pytest-xdist worker: tell the scheduler the groups
        groups = json.dumps({item.nodeid: xdist_group(item) for item in items})
        partial = Path(f"{_settings[GROUPS_KEY]}.{os.getpid()}")
        partial.write_text(groups)
        partial.replace(_settings[GROUPS_KEY])


#: The values of ``GYMPRECICE_TIER``: ``rest`` is ``waiting`` and ``local`` together.
TIERS = ("fast", "rest", "waiting", "local")


def _select_tier(config: pytest.Config, items: list[pytest.Item]) -> None:
    tier = _settings.get(TIER_ENV, "")
    if not tier:
        return
    if tier not in TIERS:
        raise pytest.UsageError(
            f"{TIER_ENV}={tier!r}: use fast, rest (or its parts waiting and local), or leave it "
            "unset"
        )
    again: set[str] = set()
    listed = _settings.get(TIER_SKIPPED_ENV)
    if tier != "fast" and listed and Path(listed).is_file():
        again = set(Path(listed).read_text().split())
    kept, deselected = [], []
    for item in items:
        fast = in_fast_tier(item)
        keep = fast if tier == "fast" else (not fast or item.nodeid in again)
        if keep and tier in ("waiting", "local"):
            keep = mostly_waits(item) == (tier == "waiting")
        (kept if keep else deselected).append(item)
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = kept


#: The key of ``_settings`` naming the file in which pytest-xdist's workers write each
#: test's group, for the controller's scheduler.
GROUPS_KEY = "groups_file"


def _groups_file(config: pytest.Config) -> str:
    fd, name = tempfile.mkstemp(prefix="gymprecice-xdist-groups-", suffix=".json")
    os.close(fd)
    config.add_cleanup(lambda: Path(name).unlink(missing_ok=True))
    return name


@pytest.hookimpl(optionalhook=True, tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """``--dist loadgroup`` by :func:`xdist_group`: each group is one unit of work, the
    biggest first, handed to whichever worker is nearly out of work."""
    if GROUPS_KEY not in _settings:
        return None
    from xdist.scheduler import LoadScopeScheduling

    path = Path(_settings[GROUPS_KEY])

    class GroupScheduling(LoadScopeScheduling):
        groups: dict[str, str] | None = None

        def _split_scope(self, nodeid: str) -> str:
            if self.groups is None:  # written by the workers before they report collection
                self.groups = json.loads(path.read_text() or "{}")
            return self.groups.get(nodeid, nodeid)

    return GroupScheduling(config, log)


# -- the session's time: the durations file ------------------------------------------------------

_cpu_mark = pytest.StashKey[float]()


def _cpu_now() -> float:
    """CPU seconds of this process and of its children that have been waited for (solvers,
    partners, ``gymprecice`` commands): unlike wall-clock, barely changed by a busy machine."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _cpu_since(item: pytest.Item) -> float:
    """CPU seconds since the previous phase of ``item`` (set-up, call, tear-down) ended."""
    now = _cpu_now()
    spent = now - item.stash.get(_cpu_mark, now)
    item.stash[_cpu_mark] = now
    return spent


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item) -> None:
    item.stash[_cpu_mark] = _cpu_now()


class _SessionClock:
    """The session's wall-clock and each test's time, in the process that reports them
    (with pytest-xdist: the controller, which receives every worker's reports)."""

    def __init__(self) -> None:
        self.started = self.written = time.monotonic()
        self.started_at = time.time()
        self.tests: dict[str, dict] = {}

    def add(self, report: pytest.TestReport) -> None:
        nodeid = report.nodeid
        entry = self.tests.setdefault(nodeid, {"seconds": 0.0, "cpu_s": 0.0, "outcome": "passed"})
        entry["seconds"] += report.duration
        entry["cpu_s"] += dict(report.user_properties).get("cpu_s", 0.0)
        if report.failed or (report.skipped and entry["outcome"] == "passed"):
            entry["outcome"] = report.outcome
        if report.when == "call" and hasattr(report, "worker_id"):
            entry["worker"] = report.worker_id


_clock = _SessionClock()


def pytest_sessionstart(session: pytest.Session) -> None:
    _clock.__init__()


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _clock.add(report)
    # Now and then during the session too: a run stopped by a CI time limit still shows
    # where its time went.
    if report.when == "teardown" and time.monotonic() - _clock.written > _REWRITE_S:
        _write_durations(finished=False)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Write the durations file and, in the fast tier, the list of its skipped tests."""
    if hasattr(session.config, "workerinput"):  # an xdist worker: the controller writes
        return
    _write_durations(finished=True)
    listed = _settings.get(TIER_SKIPPED_ENV)
    if listed and _settings.get(TIER_ENV) == "fast":
        skipped = sorted(n for n, e in _clock.tests.items() if e["outcome"] == "skipped")
        _write(Path(listed), "".join(f"{nodeid}\n" for nodeid in skipped))


#: How often (seconds) a running session rewrites its durations file.
_REWRITE_S = 30.0


def _write_durations(*, finished: bool) -> None:
    target = _settings.get(DURATIONS_ENV)
    _clock.written = time.monotonic()
    if not target:
        return
    slowest = sorted(_clock.tests.items(), key=lambda kv: -kv[1]["seconds"])
    tests = [
        {
            "nodeid": nodeid,
            **entry,
            "seconds": round(entry["seconds"], 2),
            "cpu_s": round(entry["cpu_s"], 2),
        }
        for nodeid, entry in slowest
    ]
    summary = {
        "tier": _settings.get(TIER_ENV) or "all",
        # when it started (seconds since the epoch): sessions run side by side overlap
        "started_at": round(_clock.started_at, 3),
        "wall_s": round(time.monotonic() - _clock.started, 3),
        "finished": finished,
    }
    _write(Path(target), json.dumps({**summary, "tests": tests}, indent=1) + "\n")


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
