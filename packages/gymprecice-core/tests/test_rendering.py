"""``render_mode="rgb_array"``: fields from the solvers' plugins, drawn by core.

Runs the fake cylinder (the scripted partner on the preCICE test double), whose flow
writes a pressure field when core asks for one, and checks the Gymnasium conventions:
the frame's shape, that it shows something and changes, RecordVideo, the bad inputs, and
that an env without ``render_mode`` makes its solver write nothing more.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter
from gymprecice.env.rendering import FrameRenderer, hole_mask
from gymprecice.plugin.errors import ConfigError, SolverCrashedError
from gymprecice.plugin.fields import Field, Overlay, grid_points, read_field_file, write_field_file
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import temporary_plugin
from gymprecice.testing import case_config
from gymprecice.testing.flows import place_jets

DOUBLE = "gymprecice.testing.fake_precice"
#: a frame that shows a field has far more pixel variance than a blank or one-colour one
VARIANCE_FLOOR = 100.0


class RenderingCylinderEnv(Adapter):
    render_fields = {"fluid": "p"}

    def __init__(self, options, idx=0, **kwargs):
        super().__init__(options, idx, **kwargs)
        place_jets(self)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(32,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        q = float(np.asarray(action).ravel()[0])
        return {
            name: np.tile([0.0, sign * q], (len(self.interface_geometry[name].coordinates), 1))
            for name, sign in (("jet1", 1.0), ("jet2", -1.0))
        }

    def _get_observation(self, read_data, read_var_list):
        return np.asarray(read_data["cylinder"], dtype=np.float32)

    def _get_reward(self):
        return 0.0

    def _render_overlay(self):
        q = float(np.asarray(self.last_action).ravel()[0])
        return Overlay(text=[f"Q = {q:+.2f}"], arrows=[(0.0, 0.05, 0.0, 0.1 * q)])


def _case(tmp_path: Path, max_time: float = 0.05) -> Path:
    case = tmp_path / "case"
    (case / "fluid").mkdir(parents=True, exist_ok=True)
    case_config("fake_cylinder", case, max_time=max_time)
    argv = ["{python}", "-m", "gymprecice.testing.partner", "--config", "{precice_config}"]
    argv += ["--participant", "Fluid", "--library", DOUBLE]
    config = {
        "precice": {"library": DOUBLE},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "command",
                    "path": "fluid",
                    "participant": "Fluid",
                    "options": {"argv": argv},
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"cylinder": "Pressure"},
        },
        "timeouts": {"progress": 10, "reset": 60, "kill_grace": 0.5, "finalize": 5},
    }
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    return case


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def test_frames_have_the_shape_show_the_field_and_change(tmp_path):
    env = RenderingCylinderEnv(_case(tmp_path), run_root=tmp_path / "runs", render_mode="rgb_array")
    assert env.metadata["render_fps"] > 0 and "rgb_array" in env.metadata["render_modes"]
    env.reset(seed=0)
    first = env.render()
    width, height = env.render_size
    assert height is None  # the domain decides: a wide channel, a short frame
    assert first.shape[1:] == (width, 3) and first.dtype == np.uint8
    assert first.shape[0] % 16 == 0 and first.shape[0] < 400
    assert first.var() > VARIANCE_FLOOR
    env.step(np.array([1.0], dtype=np.float32))
    env.step(np.array([1.0], dtype=np.float32))
    second = env.render()
    assert second.shape == first.shape
    assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
    env.close()


def test_without_render_mode_the_solver_writes_nothing_more(tmp_path):
    case = _case(tmp_path)
    plain = RenderingCylinderEnv(case, run_root=tmp_path / "plain")
    rendering = RenderingCylinderEnv(case, run_root=tmp_path / "rendering", render_mode="rgb_array")
    for env in (plain, rendering):
        env.reset(seed=0)
        truncated = False
        while not truncated:
            *_, truncated, _ = env.step(np.array([0.5], dtype=np.float32))
        env.close()
    without = _files(plain.run_dir)
    with_render = _files(rendering.run_dir)
    assert not any("gymprecice-fields" in name for name in without)
    assert with_render - without == {"fluid/gymprecice-fields/p.npz"}
    assert plain.render() is None  # Gymnasium's convention: a warning, no frame


def test_record_video_writes_a_playable_file(tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="gymprecice-core[render]")
    pytest.importorskip("moviepy", reason="the render extra: gymprecice-core[render]")
    env = RenderingCylinderEnv(_case(tmp_path), run_root=tmp_path / "runs", render_mode="rgb_array")
    videos = tmp_path / "videos"
    recorder = gym.wrappers.RecordVideo(env, str(videos), episode_trigger=lambda _: True)
    recorder.reset(seed=0)
    truncated = False
    while not truncated:
        *_, truncated, _ = recorder.step(np.array([0.3], dtype=np.float32))
    recorder.close()
    files = sorted(videos.glob("*.mp4"))
    assert files, f"no video in {sorted(videos.iterdir())}"
    reader = imageio_ffmpeg.read_frames(str(files[0]))  # decodes it: a playable file
    meta = next(reader)
    frames = list(reader)
    width, height = meta["size"]  # the frame's, kept for the episode
    assert width == 640 and height % 16 == 0 and height < 400
    assert len(frames) == 6  # reset + 5 actions


def test_an_unsupported_render_mode_names_the_supported_ones(tmp_path):
    with pytest.raises(ValueError, match=r"render_mode='human'.*\['rgb_array'\]"):
        RenderingCylinderEnv(_case(tmp_path), run_root=tmp_path / "runs", render_mode="human")


def test_a_field_the_solver_does_not_write_is_named(tmp_path):
    env = RenderingCylinderEnv(_case(tmp_path), run_root=tmp_path / "runs", render_mode="rgb_array")
    env.render_fields = {"fluid": "vorticity"}
    with pytest.raises(SolverCrashedError, match=r"'vorticity'.*writes \['p'\]"):
        env.reset(seed=0)
    env.close()


def test_a_solver_not_in_the_configuration_is_named(tmp_path):
    env = RenderingCylinderEnv(_case(tmp_path), run_root=tmp_path / "runs", render_mode="rgb_array")
    env.render_fields = {"solid": "d"}
    with pytest.raises(ConfigError, match=r"solver 'solid'.*\['fluid'\]"):
        env.reset(seed=0)
    env.close()


def test_a_plugin_without_the_field_hook_is_named(tmp_path):
    class Silent:
        """A plugin of its own kind that launches the partner but reads no fields."""

        @hookimpl
        def gymprecice_solver_kinds(self):
            return {"silent": "a solver without fields"}

        @hookimpl
        def gymprecice_reset_case(self, solver):
            return True if solver.kind == "silent" else None

        @hookimpl
        def gymprecice_launch_solver(self, solver):
            if solver.kind != "silent":
                return None
            from gymprecice.plugin.solver import LaunchSpec
            from gymprecice.testing import partner

            argv = partner.command(solver.precice_config_file, "Fluid", library=DOUBLE)
            return LaunchSpec(argv=argv, cwd=solver.run_dir)

    case = _case(tmp_path)
    config = json.loads((case / "gymprecice-config.json").read_text())
    config["physics_simulation_engine"]["solvers"]["fluid"] = {
        "kind": "silent",
        "path": "fluid",
        "participant": "Fluid",
    }
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    with temporary_plugin(Silent(), "silent-plugin"):
        env = RenderingCylinderEnv(case, run_root=tmp_path / "runs", render_mode="rgb_array")
        env.reset(seed=0)
        with pytest.raises(ConfigError, match=r"plugin 'silent-plugin'.*gymprecice_read_field"):
            env.render()
        env.close()


def test_a_frame_missing_after_the_last_step_is_an_error_at_once_not_a_wait(tmp_path):
    """After the truncating step the solvers have exited: a frame not written by then never
    will be. render() looks once and names it, where it used to wait the progress timeout
    and then blame a hung solver."""
    from gymprecice.plugin.errors import SolverError, SolverTimeoutError
    from gymprecice.plugin.solver import LaunchSpec
    from gymprecice.testing import partner

    points, triangles = grid_points([0.0, 1.0], [0.0, 1.0])

    class Stale:
        """A plugin whose solver writes its field at the start only."""

        @hookimpl
        def gymprecice_solver_kinds(self):
            return {"stale": "a solver that writes its field once"}

        @hookimpl
        def gymprecice_reset_case(self, solver):
            return True if solver.kind == "stale" else None

        @hookimpl
        def gymprecice_launch_solver(self, solver):
            if solver.kind != "stale":
                return None
            argv = partner.command(solver.precice_config_file, "Fluid", library=DOUBLE)
            return LaunchSpec(argv=argv, cwd=solver.run_dir)

        @hookimpl
        def gymprecice_read_field(self, solver, name, time):
            if solver.kind != "stale":
                return None
            return Field(name, 0.0, points, np.ones(len(points)), triangles=triangles)

    case = _case(tmp_path)
    config = json.loads((case / "gymprecice-config.json").read_text())
    config["physics_simulation_engine"]["solvers"]["fluid"]["kind"] = "stale"
    config["timeouts"]["progress"] = 30
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    with temporary_plugin(Stale(), "stale-plugin"):
        env = RenderingCylinderEnv(case, run_root=tmp_path / "runs", render_mode="rgb_array")
        try:
            env.reset(seed=0)
            env.render()  # the start's frame is there
            truncated = False
            while not truncated:
                *_, truncated, _ = env.step(np.array([0.5], dtype=np.float32))
            with pytest.raises(SolverError, match=r"'p' at t=0\.05.*exited.*t=0\)") as raised:
                env.render()
            assert not isinstance(raised.value, SolverTimeoutError)
            assert raised.value.solver == "fluid"
        finally:
            env.close()


def test_vector_env_renders_every_env(tmp_path):
    from gymprecice.vector import ResilientVectorEnv

    case = _case(tmp_path)
    fns = [
        (
            lambda i=i: RenderingCylinderEnv(
                case, i, run_root=tmp_path / "runs", render_mode="rgb_array"
            )
        )
        for i in range(2)
    ]
    envs = ResilientVectorEnv(fns)
    try:
        assert envs.render_mode == "rgb_array"
        envs.reset(seed=0)
        frames = envs.render()
        assert len(frames) == 2
        assert all(f.shape == frames[0].shape and f.var() > VARIANCE_FLOOR for f in frames)
        assert frames[0].shape[1] == 640
    finally:
        envs.close()


def test_field_files_round_trip_and_are_checked(tmp_path):
    points, triangles = grid_points([0.0, 1.0, 2.0], [0.0, 1.0])
    field = Field("T", 0.5, points, np.arange(6.0), triangles=triangles, label="T [K]")
    back = read_field_file(write_field_file(tmp_path, field))
    assert back.time == 0.5 and back.label == "T [K]"
    assert np.array_equal(back.triangles, triangles) and np.array_equal(back.values, field.values)
    with pytest.raises(ValueError, match="field 'T': values must have one row per point"):
        Field("T", 0.0, points, np.zeros(4))


def test_delaunay_is_made_once_and_holes_are_masked():
    # points around a hole of radius 1: Delaunay bridges it, the mask removes the bridge
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    rings = [r * np.stack([np.cos(angles), np.sin(angles)], 1) for r in (1.0, 1.1, 1.2, 1.3)]
    points = np.concatenate(rings)
    renderer = FrameRenderer(320, 240)
    field = Field("p", 0.0, points, points[:, 0])
    tri = renderer.triangulation("fluid/p", field)
    kept = renderer._meshes["fluid/p"]
    assert tri.mask is not None and tri.mask.any()
    centroids = points[tri.triangles[~tri.mask]].mean(axis=1)
    assert np.linalg.norm(centroids, axis=1).min() > 0.8  # nothing drawn across the hole
    renderer.triangulation("fluid/p", Field("p", 1.0, points, points[:, 1]))
    assert renderer._meshes["fluid/p"] is kept  # same points: the triangulation is reused
    assert hole_mask(*grid_points([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])) is None
    frame = renderer.draw([("fluid/p", field)], Overlay(text=["hello"]), "title")
    assert frame.shape == (240, 320, 3) and frame.var() > VARIANCE_FLOOR


# -- several agents in one frame: gymprecice.multiagent -------------------------------------


def _two_jets(case: Path, tmp_path: Path, **kwargs):
    """The fake cylinder with one agent per jet (MultiAgentAdapter), drawing its pressure."""
    pytest.importorskip("pettingzoo", reason="gymprecice-core[multiagent]")
    from gymprecice.multiagent import MultiAgentAdapter

    class RenderingTwoJets(MultiAgentAdapter):
        agent_data = {"upper": ["jet1"], "lower": ["jet2"]}
        render_fields = {"fluid": "p"}

        def __init__(self, options, idx=0, **kw):
            super().__init__(options, idx, **kw)
            place_jets(self)
            box = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
            self.action_spaces = dict.fromkeys(self.possible_agents, box)
            self.observation_spaces = {
                agent: gym.spaces.Box(-np.inf, np.inf, shape=(32,), dtype=np.float32)
                for agent in self.possible_agents
            }

        def _get_agent_action(self, agent, action, write_var_list):
            (ref,) = write_var_list
            n = len(self.interface_geometry[ref.interface].coordinates)
            sign = 1.0 if agent == "upper" else -1.0
            return {ref: np.tile([0.0, sign * float(action[0])], (n, 1))}

        def _get_observations(self, read_data, read_var_list):
            pressure = np.asarray(read_data["cylinder"], dtype=np.float32)
            return dict.fromkeys(self.agents, pressure)

        def _get_rewards(self):
            return dict.fromkeys(self.agents, 0.0)

    return RenderingTwoJets(case, run_root=tmp_path, **kwargs)


def test_a_multi_agent_env_renders_every_agent_in_one_frame(tmp_path):
    env = _two_jets(_case(tmp_path), tmp_path / "runs", render_mode="rgb_array")
    try:
        assert env.render_mode == "rgb_array" and env.metadata["render_fps"] > 0
        env.reset(seed=0)
        first = env.render()
        width, _ = env.render_size  # the height follows the domain
        assert first.shape[1:] == (width, 3) and first.dtype == np.uint8
        assert first.var() > VARIANCE_FLOOR
        env.step({"upper": np.array([1.0], np.float32), "lower": np.array([-0.5], np.float32)})
        assert env._render_overlay().text == ["upper: [1.0]", "lower: [-0.5]"]
        env.step({"upper": np.array([1.0], np.float32), "lower": np.array([-0.5], np.float32)})
        second = env.render()
        assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
    finally:
        env.close()


def test_a_multi_agent_env_without_render_mode_writes_nothing_more(tmp_path):
    case = _case(tmp_path)
    plain = _two_jets(case, tmp_path / "plain")
    rendering = _two_jets(case, tmp_path / "rendering", render_mode="rgb_array")
    for env in (plain, rendering):
        env.reset(seed=0)
        while env.agents:
            env.step({agent: np.array([0.5], np.float32) for agent in env.agents})
        env.close()
    without = _files(plain.run_dir)
    assert _files(rendering.run_dir) - without == {"fluid/gymprecice-fields/p.npz"}
    with pytest.warns(UserWarning, match=r"RenderingTwoJets.render\(\) called without"):
        assert plain.render() is None


def test_a_multi_agent_env_refuses_a_render_mode_it_lacks_and_names_itself(tmp_path):
    case = _case(tmp_path)
    with pytest.raises(ValueError, match=r"RenderingTwoJets.*render_mode='human'.*rgb_array"):
        _two_jets(case, tmp_path / "runs", render_mode="human")
    env = _two_jets(case, tmp_path / "runs", render_mode="rgb_array")
    env.render_fields = {"solid": "d"}
    try:
        with pytest.raises(ConfigError, match=r"RenderingTwoJets.render_fields.*'solid'"):
            env.reset(seed=0)
    finally:
        env.close()


def test_the_joint_env_records_a_video_of_the_multi_agent_frame(tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="gymprecice-core[render]")
    pytest.importorskip("moviepy", reason="the render extra: gymprecice-core[render]")
    from gymprecice.multiagent import JointEnv

    env = JointEnv(_two_jets(_case(tmp_path), tmp_path / "runs", render_mode="rgb_array"))
    assert env.render_mode == "rgb_array"
    videos = tmp_path / "videos"
    recorder = gym.wrappers.RecordVideo(env, str(videos), episode_trigger=lambda _: True)
    recorder.reset(seed=0)
    truncated = False
    while not truncated:
        *_, truncated, _ = recorder.step(np.full((2, 1), 0.3, np.float32))
    recorder.close()
    (video,) = videos.glob("*.mp4")
    reader = imageio_ffmpeg.read_frames(str(video))  # decodes it: a playable file
    width, height = next(reader)["size"]
    assert width == env.render_size[0] and height % 16 == 0
    assert len(list(reader)) == 6  # reset + 5 actions


def test_the_same_quantity_of_two_solvers_is_one_layer_with_one_colour_bar():
    from gymprecice.env.frames import shared_layers

    points, triangles = grid_points([0.0, 0.1], [0.0, 0.5, 1.0])
    moved = np.tile([0.01, 0.0], (len(points), 1))
    flap = Field("d", 0.2, points, moved, triangles=triangles, displacement=moved, label="|u|")
    other = Field(
        "d", 0.2, points + np.array([2.0, 0.0]), moved * 2, triangles=triangles, label="|u|"
    )
    fluid = Field("U", 0.2, points * 10, np.ones(len(points)), label="|U|")
    layers = shared_layers([("fluid/U", fluid), ("up/d", flap), ("down/d", other)])
    assert [label for label, _ in layers] == ["fluid/U", "up+down/d"]
    joined = layers[1][1]
    assert joined.label == "|u|" and len(joined.points) == 2 * len(points)
    assert np.array_equal(joined.triangles[len(triangles) :], triangles + len(points))
    assert np.array_equal(joined.displacement[len(points) :], np.zeros_like(points))
    # without triangles (one Delaunay would bridge them) they stay apart, named by solver
    loose = [
        ("a/p", Field("p", 0, points, np.ones(6), label="p")),
        ("b/p", Field("p", 0, points, 2.0 * np.ones(6), label="p")),
    ]
    assert [f.label for _, f in shared_layers(loose)] == ["a p", "b p"]
