"""Plugin manager (discovery, laziness, disabling, failures), every hook, env registration."""

from __future__ import annotations

import importlib.metadata
import json
import os
import subprocess
import sys
import textwrap
import uuid
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest

from gymprecice import default_plugin, plugins, registration
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import (
    DISABLE_ENV_VAR,
    PluginWarning,
    get_plugin_manager,
    list_plugins,
    plugin_failures,
    register_plugin,
    solver_kinds,
    temporary_plugin,
    unregister_plugin,
)
from gymprecice.plugin.solver import DoctorCheck, InterfaceGeometry, LaunchSpec, SolverContext

# -- helpers ------------------------------------------------------------------------------------


@pytest.fixture
def fresh(monkeypatch: pytest.MonkeyPatch):
    """A not-yet-loaded plugin manager; the process-wide one comes back afterwards."""
    monkeypatch.setattr(plugins, "_manager", None)
    monkeypatch.delenv(DISABLE_ENV_VAR, raising=False)
    return monkeypatch


@pytest.fixture
def distribution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Factory: install a tiny distribution (dist-info + modules) on a temporary sys.path."""
    created: list[str] = []

    def make(
        dist: str,
        entry_points: dict[str, str],
        modules: dict[str, str],
        version: str = "1.2.3",
        environments: dict[str, str] | None = None,
    ) -> Path:
        root = tmp_path / f"site-{uuid.uuid4().hex[:8]}"
        info = root / f"{dist.replace('-', '_')}-{version}.dist-info"
        info.mkdir(parents=True)
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
        lines = "".join(f"{name} = {target}\n" for name, target in entry_points.items())
        text = f"[gymprecice]\n{lines}"
        if environments:  # ids declared in the metadata
            text += "\n[gymprecice.environments]\n"
            text += "".join(f"{env_id} = {target}\n" for env_id, target in environments.items())
        (info / "entry_points.txt").write_text(text)
        for module, source in modules.items():
            (root / f"{module}.py").write_text(textwrap.dedent(source))
            created.append(module)
        monkeypatch.syspath_prepend(str(root))
        return root

    yield make
    for module in created:
        sys.modules.pop(module, None)


def _unique(prefix: str) -> str:
    return f"{prefix}_{uuid.uuid4().hex[:8]}"


TOY_PLUGIN = """
from gymprecice.plugin.hookspecs import hookimpl

@hookimpl
def gymprecice_solver_kinds():
    return {"toy": "a toy solver"}
"""


def _solver(tmp_path: Path, kind: str) -> SolverContext:
    run_dir = tmp_path / "env_0" / "toy"
    run_dir.mkdir(parents=True, exist_ok=True)
    return SolverContext(
        name="toy", kind=kind, run_dir=run_dir, source_dir=tmp_path, env_dir=run_dir.parent
    )


class ToyPlugin:
    """Answers every hook for kind "toy" only, as the hook contract asks."""

    class Reader:
        def read_new(self):
            return [1.0]

        def close(self):
            pass

    @hookimpl
    def gymprecice_solver_kinds(self):
        return {"toy": "a toy solver"}

    @hookimpl
    def gymprecice_prepare_case(self, solver):
        if solver.kind != "toy":
            return None
        solver.state["prepared"] = True
        return True

    @hookimpl
    def gymprecice_reset_case(self, solver):
        if solver.kind != "toy":
            return None
        solver.state["resets"] = solver.state.get("resets", 0) + 1
        return True

    @hookimpl
    def gymprecice_launch_solver(self, solver):
        if solver.kind != "toy":
            return None
        return LaunchSpec(argv=["toy-solver"], cwd=solver.run_dir)

    @hookimpl
    def gymprecice_check_solver(self, solver, log_text):
        if solver.kind != "toy":
            return None
        return "toy adapter not loaded" if "uncoupled" in log_text else None

    @hookimpl
    def gymprecice_interface_geometry(self, solver, interface, mesh):
        if solver.kind != "toy" or mesh != "Toy-Mesh":
            return None
        return InterfaceGeometry(np.zeros((3, 2)))

    @hookimpl
    def gymprecice_open_output(self, solver, name, options):
        if solver.kind != "toy" or name != "probes":
            return None
        return self.Reader()

    @hookimpl
    def gymprecice_doctor_checks(self):
        return [DoctorCheck("toy-solver", ok=False, advice="install toy", required=False)]


# -- discovery ----------------------------------------------------------------------------------


def test_entry_point_plugins_are_discovered_with_their_distribution(fresh, distribution) -> None:
    module = _unique("toy_plugin")
    distribution("toy-dist", {"toy": module}, {module: TOY_PLUGIN}, version="4.5.6")
    pm = get_plugin_manager()
    assert pm.has_plugin("toy")
    (info,) = [p for p in list_plugins() if p.name == "toy"]
    assert (info.distribution, info.version, info.module) == ("toy-dist", "4.5.6", module)
    assert info.hooks == ("gymprecice_solver_kinds",)
    assert solver_kinds()["toy"] == ("a toy solver", "toy")


def test_loading_is_lazy_and_happens_once(fresh, distribution) -> None:
    module = _unique("counted_plugin")
    distribution(
        "counted",
        {"counted": module},
        {
            module: TOY_PLUGIN
            + "\nimport builtins\nbuiltins._gp_loads = getattr(builtins, '_gp_loads', 0) + 1\n"
        },
    )
    calls = []
    real = importlib.metadata.distributions
    fresh.setattr(importlib.metadata, "distributions", lambda: calls.append(1) or real())
    import builtins

    builtins._gp_loads = 0
    assert plugins._manager is None and calls == []  # nothing loaded before the first call
    first = get_plugin_manager()
    second = get_plugin_manager()
    assert first is second
    assert calls == [1] and builtins._gp_loads == 1
    # Loading again by hand registers nothing twice and raises nothing.
    assert first.load_plugins() == 0
    assert [n for n, p in first.list_name_plugin() if p is first.get_plugin("counted")] == [
        "counted"
    ]
    del builtins._gp_loads


def test_default_plugin_is_registered_like_a_third_party_one(fresh) -> None:
    pm = get_plugin_manager()
    assert pm.get_plugin("script") is default_plugin
    # Core's metadata is often visible twice (dist-info + source tree egg-info): once only.
    assert [n for n, p in pm.list_name_plugin() if p is default_plugin] == ["script"]
    (info,) = [p for p in list_plugins() if p.name == "script"]
    assert info.distribution == "gymprecice-core"
    assert {"script", "command"} <= set(solver_kinds())


def test_default_plugin_without_distribution_metadata(fresh) -> None:
    fresh.setattr(importlib.metadata, "distributions", lambda: [])
    pm = get_plugin_manager()
    assert pm.get_plugin("script") is default_plugin
    (info,) = list_plugins()
    assert (info.name, info.distribution) == ("script", "gymprecice-core")
    assert solver_kinds()["command"].plugin == "script"


def test_default_plugin_declared_twice_is_registered_once(fresh, distribution) -> None:
    distribution("repackaged-core", {"core-again": "gymprecice.default_plugin"}, {})
    pm = get_plugin_manager()
    names = [n for n, p in pm.list_name_plugin() if p is default_plugin]
    assert len(names) == 1
    assert not plugin_failures()


def test_disable_all_keeps_only_the_default_plugin(fresh, distribution) -> None:
    module = _unique("toy_plugin")
    distribution("toy-dist", {"toy": module}, {module: TOY_PLUGIN})
    fresh.setenv(DISABLE_ENV_VAR, "1")
    assert [p.name for p in list_plugins()] == ["script"]
    assert set(solver_kinds()) == {"script", "command"}


@pytest.mark.parametrize("value", ["toy", "toy-dist", "other, Toy_Dist", "script,toy"])
def test_disable_by_name_or_distribution(fresh, distribution, value: str) -> None:
    toy, keep = _unique("toy_plugin"), _unique("kept_plugin")
    distribution("toy-dist", {"toy": toy}, {toy: TOY_PLUGIN})
    distribution("kept-dist", {"kept": keep}, {keep: "x = 1\n"})
    fresh.setenv(DISABLE_ENV_VAR, value)
    pm = get_plugin_manager()
    assert not pm.has_plugin("toy")
    assert pm.has_plugin("kept")
    assert pm.get_plugin("script") is default_plugin  # core's kinds cannot be disabled


@pytest.mark.parametrize("value", ["", "0", "false"])
def test_disable_off_values(fresh, distribution, value: str) -> None:
    toy = _unique("toy_plugin")
    distribution("toy-dist", {"toy": toy}, {toy: TOY_PLUGIN})
    fresh.setenv(DISABLE_ENV_VAR, value)
    assert get_plugin_manager().has_plugin("toy")


def test_broken_plugin_is_warned_about_and_skipped(fresh, distribution) -> None:
    good, bad = _unique("good_plugin"), _unique("bad_plugin")
    distribution("good-dist", {"good": good}, {good: TOY_PLUGIN})
    distribution("bad-dist", {"bad": bad}, {bad: "raise ImportError('needs libfoo.so')\n"})
    with pytest.warns(PluginWarning, match=r"'bad' \(from bad-dist 1\.2\.3\).*libfoo\.so"):
        pm = get_plugin_manager()
    assert pm.has_plugin("good") and not pm.has_plugin("bad")
    (failure,) = plugin_failures()
    assert (failure.name, failure.distribution) == ("bad", "bad-dist")
    assert "libfoo.so" in failure.error


def test_plugin_failing_validation_leaves_no_trace(fresh, distribution) -> None:
    module = _unique("invalid_plugin")
    source = """
    from gymprecice.plugin.hookspecs import hookimpl

    @hookimpl
    def gymprecice_launch_solver(solver, not_an_argument):
        return None
    """
    distribution("invalid-dist", {"invalid": module}, {module: source})
    with pytest.warns(PluginWarning, match="not_an_argument"):
        pm = get_plugin_manager()
    assert not pm.has_plugin("invalid")
    assert all(i.plugin_name != "invalid" for i in pm.hook.gymprecice_launch_solver.get_hookimpls())


def test_plugin_importing_the_manager_while_loading(fresh, distribution) -> None:
    module = _unique("reentrant_plugin")
    source = TOY_PLUGIN + (
        "\nfrom gymprecice.plugins import get_plugin_manager\nSEEN = get_plugin_manager()\n"
    )
    distribution("reentrant", {"reentrant": module}, {module: source})
    pm = get_plugin_manager()
    assert sys.modules[module].SEEN is pm
    assert pm.has_plugin("reentrant")


def test_misspelt_hook_is_named(fresh) -> None:
    class Typo:
        @hookimpl
        def gymprecice_solver_kind(self):
            return {"x": "y"}

    with pytest.warns(PluginWarning, match="did you mean 'gymprecice_solver_kinds'"):
        register_plugin(Typo(), "typo")


def test_register_unregister_and_temporary_plugin(fresh) -> None:
    plugin = ToyPlugin()
    with temporary_plugin(plugin, "toy") as pm:
        assert pm.get_plugin("toy") is plugin
        assert solver_kinds()["toy"].plugin == "toy"
        with pytest.raises(ValueError):
            register_plugin(plugin, "toy-again")
    assert not get_plugin_manager().has_plugin("toy")
    assert "toy" not in solver_kinds()

    name = register_plugin(plugin, "toy")
    assert unregister_plugin(name) is plugin
    assert unregister_plugin(plugin) is None
    assert unregister_plugin("never-registered") is None


def test_duplicate_kind_is_warned_and_first_consulted_plugin_wins(fresh) -> None:
    class Other:
        @hookimpl
        def gymprecice_solver_kinds(self):
            return {"toy": "another toy"}

    with (
        temporary_plugin(ToyPlugin(), "toy"),
        temporary_plugin(Other(), "other"),
        pytest.warns(PluginWarning, match="'toy' is claimed by plugins 'other' and 'toy'"),
    ):
        kinds = solver_kinds()
    assert kinds["toy"] == ("another toy", "other")


def test_failing_solver_kinds_costs_only_that_plugin(fresh) -> None:
    class Broken:
        @hookimpl
        def gymprecice_solver_kinds(self):
            raise RuntimeError("boom")

    with temporary_plugin(Broken(), "broken"), pytest.warns(PluginWarning, match="'broken'.*boom"):
        kinds = solver_kinds()
    assert {"script", "command"} <= set(kinds)


# -- every hook through the manager -------------------------------------------------------------


def test_firstresult_hooks_reach_the_plugin_of_the_kind(fresh, tmp_path: Path) -> None:
    with temporary_plugin(ToyPlugin(), "toy") as pm:
        hook = pm.hook
        toy = _solver(tmp_path, "toy")
        assert hook.gymprecice_prepare_case(solver=toy) is True
        assert hook.gymprecice_reset_case(solver=toy) is True
        assert toy.state == {"prepared": True, "resets": 1}
        assert hook.gymprecice_launch_solver(solver=toy).argv == ["toy-solver"]
        assert hook.gymprecice_check_solver(solver=toy, log_text="ran uncoupled") == (
            "toy adapter not loaded"
        )
        assert hook.gymprecice_check_solver(solver=toy, log_text="fine") is None
        geometry = hook.gymprecice_interface_geometry(solver=toy, interface="jet", mesh="Toy-Mesh")
        assert geometry.coordinates.shape == (3, 2)
        assert hook.gymprecice_interface_geometry(solver=toy, interface="j", mesh="Other") is None
        reader = hook.gymprecice_open_output(solver=toy, name="probes", options={})
        assert reader.read_new() == [1.0]

        # A kind of another plugin (core's "command") never reaches the toy plugin.
        other = _solver(tmp_path, "command")
        other.options = {"argv": ["{python}", "-c", "pass"]}
        spec = hook.gymprecice_launch_solver(solver=other)
        assert list(spec.argv) == [sys.executable, "-c", "pass"]
        assert "prepared" not in other.state
        assert hook.gymprecice_open_output(solver=other, name="probes", options={}) is None


def test_doctor_checks_hook_collects_every_plugin(fresh) -> None:
    with temporary_plugin(ToyPlugin(), "toy") as pm:
        names = [c.name for answer in pm.hook.gymprecice_doctor_checks() for c in answer]
    assert "toy-solver" in names and "bash" in names


def test_solver_kinds_hook_collects_every_plugin(fresh) -> None:
    with temporary_plugin(ToyPlugin(), "toy") as pm:
        merged = {k for answer in pm.hook.gymprecice_solver_kinds() for k in answer}
    assert {"toy", "script", "command"} <= merged


# -- Gymnasium environment registration ---------------------------------------------------------


class DummyEnv(gymnasium.Env):
    observation_space = gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def __init__(self, size: int = 2) -> None:
        self.size = size

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action):
        return np.zeros(2, np.float32), 1.0, True, False, {}


@pytest.fixture
def env_ids():
    """Ids registered during a test are removed from Gymnasium's registry afterwards."""
    ids: list[str] = []
    yield ids
    for env_id in ids:
        gymnasium.registry.pop(env_id, None)
        registration._registered.pop(env_id, None)


def test_plugin_environments_are_registered(fresh, env_ids) -> None:
    env_id = f"gymprecice/Dummy{uuid.uuid4().hex[:6]}-v0"
    env_ids.append(env_id)

    class Envs:
        @hookimpl
        def gymprecice_register_environments(self, register):
            register(env_id, entry_point=DummyEnv, kwargs={"size": 5}, max_episode_steps=3)

    with temporary_plugin(Envs(), "envs"):
        assert registration.register_environments() == [env_id]
        assert registration.register_environments() == []  # idempotent
    assert registration.registered_environments()[env_id] == "envs"
    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (2,) and env.unwrapped.size == 5
    assert env.spec.max_episode_steps == 3
    env.close()


def test_existing_ids_are_left_alone(fresh, env_ids) -> None:
    env_id = f"gymprecice/Mine{uuid.uuid4().hex[:6]}-v0"
    env_ids.append(env_id)
    gymnasium.register(env_id, entry_point=DummyEnv, kwargs={"size": 1})

    class Envs:
        @hookimpl
        def gymprecice_register_environments(self, register):
            register(env_id, entry_point=DummyEnv, kwargs={"size": 9})

    with temporary_plugin(Envs(), "envs"):
        assert registration.register_environments() == []
    assert gymnasium.spec(env_id).kwargs == {"size": 1}


def test_broken_environment_plugin_does_not_stop_the_others(fresh, env_ids) -> None:
    good_id = f"gymprecice/Good{uuid.uuid4().hex[:6]}-v0"
    env_ids.append(good_id)

    class Broken:
        @hookimpl
        def gymprecice_register_environments(self, register):
            raise RuntimeError("cannot find my cases")

    class Good:
        @hookimpl
        def gymprecice_register_environments(self, register):
            register(good_id, entry_point=DummyEnv)

    with (
        temporary_plugin(Good(), "good"),
        temporary_plugin(Broken(), "broken"),
        pytest.warns(PluginWarning, match="'broken' failed to register.*cannot find my cases"),
    ):
        added = registration.register_environments()
    assert added == [good_id]


#: an env module whose reset observes 0.5 (a plugin's environment, in a subprocess)
ONE_NUMBER_ENV = """
import gymnasium, numpy as np

class Env(gymnasium.Env):
    observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.full(1, 0.5, np.float32), {}

    def step(self, action):
        return np.zeros(1, np.float32), 0.0, True, False, {}
"""


def _run_with(root: Path, code: str, disable: str | None = None) -> dict:
    """``code`` in a fresh interpreter with the distribution at ``root`` installed and
    every plugin enabled (but ``disable``); the JSON of its last line."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), *sys.path]))
    env.pop(DISABLE_ENV_VAR, None)
    if disable is not None:
        env[DISABLE_ENV_VAR] = disable
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


IMPORT_CHECK = """
import json, sys, warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    import gymprecice
import gymnasium
lazy_before_make = "{impl}" not in sys.modules
env = gymnasium.make("{env_id}")
print(json.dumps({{
    "warnings": [str(w.message) for w in caught],
    "lazy_before_make": lazy_before_make,
    "obs": env.reset(seed=0)[0].tolist(),
    "heavy": [m for m in ("torch", "matplotlib", "stable_baselines3", "precice") if m in sys.modules],
}}))
"""


def test_import_gymprecice_registers_lazily_and_survives_a_broken_plugin(distribution) -> None:
    plugin, impl, bad = _unique("envs_plugin"), _unique("envs_impl"), _unique("bad_plugin")
    env_id = f"gymprecice/Lazy{uuid.uuid4().hex[:6]}-v0"
    root = distribution(
        "envs-dist",
        {"envs": plugin, "bad": bad},
        {
            plugin: f"""
            from gymprecice.plugin.hookspecs import hookimpl

            @hookimpl
            def gymprecice_register_environments(register):
                register("{env_id}", entry_point="{impl}:Env")
            """,
            impl: ONE_NUMBER_ENV,
            bad: "raise RuntimeError('plugin exploded')\n",
        },
    )
    result = _run_with(root, IMPORT_CHECK.format(impl=impl, env_id=env_id))
    assert any("'bad'" in w and "plugin exploded" in w for w in result["warnings"])
    assert result["lazy_before_make"] is True
    assert result["obs"] == [0.5]
    assert result["heavy"] == []


def test_import_gymprecice_registers_nothing_twice() -> None:
    # The package already registered at import: doing it again adds nothing.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PluginWarning)
        assert registration.register_environments() == []


FIRST_IMPORT_CHECK = """
import json
import {plugin}  # the plugin module first: it imports gymprecice at its top
from gymprecice.plugin.manager import solver_kinds
kinds = solver_kinds()
import gymnasium
env = gymnasium.make("{env_id}")
print(json.dumps({{"kinds": sorted(kinds), "obs": env.reset(seed=0)[0].tolist()}}))
"""


def test_a_plugin_module_imported_before_gymprecice_keeps_its_hooks(distribution) -> None:
    """A plugin module that imports gymprecice at its top, imported first, is half imported
    while gymprecice loads the plugins: it is registered once its import has finished,
    with every hook and its environments, at the next use of the plugin manager (pluggy
    would otherwise have registered it without hooks, for good)."""
    plugin, impl = _unique("early_plugin"), _unique("early_impl")
    env_id = f"early/Early{uuid.uuid4().hex[:6]}-v0"
    root = distribution(
        "early-dist",
        {"early": plugin},
        {
            plugin: f"""
            from gymprecice.plugin.hookspecs import hookimpl

            @hookimpl
            def gymprecice_solver_kinds():
                return {{"early-kind": "a kind from a plugin imported first"}}

            @hookimpl
            def gymprecice_register_environments(register):
                register("{env_id}", entry_point="{impl}:Env")
            """,
            impl: ONE_NUMBER_ENV,
        },
    )
    result = _run_with(root, FIRST_IMPORT_CHECK.format(plugin=plugin, env_id=env_id))
    assert "early-kind" in result["kinds"]
    assert result["obs"] == [0.5]


SIBLING_FIRST_CHECK = """
import json, warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    from {package}.helpers import KIND  # a module of the plugin's package first
    from gymprecice.plugin.manager import solver_kinds
    kinds = solver_kinds()
print(json.dumps({{"kinds": sorted(kinds), "warnings": [str(w.message) for w in caught]}}))
"""


def test_a_plugin_whose_package_is_imported_first_is_loaded_once_it_has_finished(
    distribution,
) -> None:
    """A module of the plugin's own package imported first, which imports gymprecice at
    its top: the plugin module, importing a name that module has not defined yet, fails
    while gymprecice loads the plugins. It is loaded again at the next use of the plugin
    manager, with its hooks and no warning (before, the plugin was skipped for the
    process, as gymprecice-fenics was when ``gymprecice_fenics.solver_env`` came first)."""
    package = _unique("sibling_pkg")
    root = distribution("sibling-dist", {"sibling": f"{package}.plugin"}, {})
    (root / package).mkdir()
    (root / package / "__init__.py").write_text("")
    (root / package / "helpers.py").write_text(
        "from gymprecice.plugin import hookimpl  # imports gymprecice, which loads plugins\n"
        "KIND = 'sibling-kind'\n"
    )
    (root / package / "plugin.py").write_text(
        textwrap.dedent(
            f"""
            from gymprecice.plugin import hookimpl
            from {package}.helpers import KIND

            @hookimpl
            def gymprecice_solver_kinds():
                return {{KIND: "a kind from a plugin whose package came first"}}
            """
        )
    )
    result = _run_with(root, SIBLING_FIRST_CHECK.format(package=package))
    assert "sibling-kind" in result["kinds"]
    assert not [w for w in result["warnings"] if "sibling" in w], result["warnings"]


DECLARED_CHECK = """
import json
import gymnasium
# the user's own registration of a declared id, before gymprecice: it stays
gymnasium.register("{user_id}", entry_point="{impl}:Env", max_episode_steps=3)
import {plugin}  # the plugin module first: it imports gymprecice at its top
known = {{i: gymnasium.spec(i).max_episode_steps for i in ("{env_id}", "{user_id}")}}
obs = gymnasium.make("{env_id}").reset(seed=0)[0].tolist()
from gymprecice.plugin.manager import get_plugin_manager
get_plugin_manager()  # the next use: the hook registers its ids, with their kwargs
after = {{i: gymnasium.spec(i).max_episode_steps for i in ("{env_id}", "{user_id}")}}
print(json.dumps({{"known": known, "obs": obs, "after": after}}))
"""

DISABLED_CHECK = """
import json, gymnasium, gymprecice
print(json.dumps({{"known": "{env_id}" in gymnasium.registry}}))
"""


def test_ids_declared_in_metadata_are_known_before_the_plugin_module_has_loaded(
    distribution,
) -> None:
    """A distribution's ``gymprecice.environments`` entry points register its ids from the
    metadata, on ``import gymprecice``: ``gymnasium.make`` works even while the plugin
    module imported first is still half imported. Its hook's registration then takes the
    declared one's place; a user's own registration stays; a disabled plugin's ids are not
    registered."""
    plugin, impl = _unique("declared_plugin"), _unique("declared_impl")
    env_id = f"declared/Declared{uuid.uuid4().hex[:6]}-v0"
    user_id = f"declared/Users{uuid.uuid4().hex[:6]}-v0"
    root = distribution(
        "declared-dist",
        {"declared": plugin},
        {
            plugin: f"""
            from gymprecice.plugin import hookimpl

            @hookimpl
            def gymprecice_register_environments(register):
                register("{env_id}", entry_point="{impl}:Env", max_episode_steps=9)
                register("{user_id}", entry_point="{impl}:Env", max_episode_steps=9)
            """,
            impl: ONE_NUMBER_ENV,
        },
        environments={env_id: f"{impl}:Env", user_id: f"{impl}:Env"},
    )
    result = _run_with(
        root, DECLARED_CHECK.format(plugin=plugin, impl=impl, env_id=env_id, user_id=user_id)
    )
    assert result["known"] == {env_id: None, user_id: 3}
    assert result["obs"] == [0.5]
    assert result["after"] == {env_id: 9, user_id: 3}
    for disable in ("declared", "declared-dist", "1"):
        assert _run_with(root, DISABLED_CHECK.format(env_id=env_id), disable) == {"known": False}
