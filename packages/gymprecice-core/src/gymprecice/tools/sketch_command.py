"""``gymprecice sketch ENV --out FILE``: a picture of an environment's case, from its files.

ENV is a registered environment (its id or its card's short name) or a case directory
(or its ``gymprecice-config.json``). A registered env is made with its run root in a
temporary directory, so a packaged case is written there, read and removed with it; no
episode starts, no solver runs (a plugin may run a mesher in a temporary directory of its
own). Each solver's plugin reads its case (``gymprecice_sketch_case``), core reads the
coupling from the preCICE configuration (:mod:`gymprecice.case_sketch`) and draws
(:mod:`gymprecice.sketch_drawing`). Only the output file is written.

Bad input is refused before anything is made, in one line naming the fix, with exit
status 2: an unknown env, an output that cannot be written or is neither PNG nor SVG, an
env none of whose solvers an installed plugin can sketch.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

from gymprecice.plugin.sketch import FORMATS

__all__ = [
    "SketchRefused",
    "add_sketch_parser",
    "cmd_sketch",
    "config_of",
    "env_layer",
    "load_case",
    "output_path",
    "parse_env_kwargs",
]


class SketchRefused(ValueError):
    """Input ``gymprecice sketch`` cannot use: said in one line, exit status 2."""


def add_sketch_parser(sub: Any) -> None:
    """Add ``gymprecice sketch`` to the command line's sub-parsers."""
    p = sub.add_parser(
        "sketch",
        help="draw an environment's case (domain, patches, actuators, sensors) as PNG or SVG",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
    )
    p.add_argument(
        "env",
        metavar="ENV",
        help="a registered environment (id or short name, e.g. jet-cylinder-fast) or a case "
        "directory holding gymprecice-config.json",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="FILE",
        help="the picture, .png or .svg (default: sketch-<env>.png here)",
    )
    p.add_argument(
        "--env-kwargs",
        default=None,
        metavar="JSON",
        help='keyword arguments for the environment, e.g. \'{"solid": "fenics"}\'',
    )
    p.add_argument("--title", default=None, help="the picture's title (default: the env's id)")
    p.set_defaults(func=cmd_sketch)


def output_path(out: Path) -> Path:
    """``out`` if a sketch can be written there, else :class:`SketchRefused` saying why."""
    if out.is_dir():
        raise SketchRefused(
            f"--out {out}: is a directory; give a file in it (--out {out / 'sketch.png'})"
        )
    if out.suffix.lower() not in FORMATS:
        raise SketchRefused(
            f"--out {out}: a sketch is a .png or .svg file; name it so (e.g. --out "
            f"{out.with_suffix('.png')})"
        )
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise SketchRefused(
            f"--out {out}: the directory {parent} does not exist; create it or write elsewhere"
        )
    if not os.access(parent, os.W_OK | os.X_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise SketchRefused(
            f"--out {out}: {'the file' if out.exists() else 'the directory ' + str(parent)} is "
            "not writable; write elsewhere or fix its permissions"
        )
    return out


def parse_env_kwargs(text: str | None) -> dict[str, Any]:
    """``--env-kwargs``'s JSON object ({} when not given), or :class:`SketchRefused`."""
    if not text:
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SketchRefused(f"--env-kwargs: not JSON ({exc.msg}); give an object") from None
    if not isinstance(value, dict):
        raise SketchRefused('--env-kwargs: give a JSON object, e.g. \'{"solid": "fenics"}\'')
    return value


def env_layer(env: Any, holds: Any) -> Any:
    """The first of the env's layers (through wrappers and joint envs) for which
    ``holds(layer)`` is true, or ``None``."""
    seen = getattr(env, "unwrapped", env)
    for _ in range(8):
        if holds(seen):
            return seen
        seen = getattr(seen, "env", None)  # a JointEnv holds its multi-agent env
        if seen is None:
            return None
    return None


def config_of(env: Any) -> Any:
    """The env's :class:`~gymprecice.config.GymPreciceConfig` (through wrappers and joint
    envs), or ``None``."""
    from gymprecice.env.config import GymPreciceConfig

    layer = env_layer(env, lambda seen: isinstance(getattr(seen, "config", None), GymPreciceConfig))
    return None if layer is None else layer.config


def load_case(name: str, run_root: str, kwargs: dict[str, Any]) -> tuple[Any, str, Any]:
    """(configuration, title, env to close or None) of ENV."""
    from gymprecice.env.config import load_config

    path = Path(name)
    if path.exists():
        if kwargs:
            raise SketchRefused("--env-kwargs: only a registered environment takes them")
        config = load_config(path)
        return config, config.case_dir.name, None
    import gymnasium

    from gymprecice.plugin.card import find_env

    try:
        env_id, card = find_env(name)
    except KeyError as exc:
        raise SketchRefused(f"{exc.args[0]}; or give a case directory") from None
    env = gymnasium.make(env_id, run_root=run_root, disable_env_checker=True, **kwargs)
    config = config_of(env)
    if config is None:
        env.close()
        raise SketchRefused(
            f"{env_id}: the environment holds no gymprecice configuration (.config) to sketch; "
            "give its case directory instead"
        )
    title = f"{env_id} ({card.name})" if card.name else env_id
    return config, title, env


def _slug(name: str) -> str:
    tail = Path(name).name if Path(name).exists() else name.split("/")[-1]
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", tail).strip("-") or "case"


def cmd_sketch(args: argparse.Namespace) -> int:
    from gymprecice.tools.case_sketch import sketch_case, solver_sketches

    try:
        out = output_path(args.out or Path(f"sketch-{_slug(args.env)}.png"))
        kwargs = parse_env_kwargs(args.env_kwargs)
        with tempfile.TemporaryDirectory(prefix="gymprecice-sketch-") as run_root:
            config, title, env = load_case(args.env, run_root, kwargs)
            try:
                answers = solver_sketches(config)
            finally:
                if env is not None:
                    env.close()
            if all(answer is None for answer in answers.values()):
                kinds = ", ".join(f"{s.name}: {s.kind}" for s in config.solvers.values())
                raise SketchRefused(
                    f"{args.env}: no installed plugin sketches its solvers ({kinds}); a solver "
                    "plugin answers gymprecice_sketch_case (gymprecice-openfoam does for "
                    "kind openfoam): sketch an env with such a solver"
                )
            sketch = sketch_case(config, args.title or title, answers)
        from gymprecice.env.rendering import MissingRenderDependency
        from gymprecice.tools.sketch_drawing import draw_sketch

        try:
            draw_sketch(sketch, out)
        except MissingRenderDependency as exc:
            raise SketchRefused(str(exc)) from None
        except OSError as exc:
            raise SketchRefused(f"--out {out}: cannot be written ({exc.strerror})") from None
    except SketchRefused as exc:
        print(f"gymprecice sketch: error: {exc}", file=sys.stderr)
        return 2
    for note in sketch.notes:
        print(note)
    if sketch.undrawn:
        print(f"not drawn (their plugin draws no sketch): {', '.join(sketch.undrawn)}")
    print(out)
    return 0
