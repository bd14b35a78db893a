"""The docs' flow pictures: a still from a video, and an env's field snapshot.

``scripts/make_docs_pictures.sh`` calls it; each picture on the site names the command
that made it, so it can be made again:

* ``python scripts/docs_pictures.py still VIDEO PNG [--stack N]`` writes the last frame of
  ``VIDEO`` (the state the controller reached) as ``PNG``: the page shows the still, the
  video is one click away. ``--stack N`` takes a frame of ``N`` panels side by side
  (``gymprecice compare --video``) and puts them one above the other, each cut to its
  label, its title and its plot (:func:`stacked`): a wide, flat domain such as the jet
  cylinder's channel is then drawn larger in a page's column;
* ``python scripts/docs_pictures.py snapshot ENV PNG [--steps N] [--double]`` makes the
  env with ``render_mode="rgb_array"``, resets it (seed 0), takes ``N`` actions at the
  top of the action box (so the actuator's state is visible) and writes ``env.render()``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def still(video: Path, png: Path, stack: int = 0) -> Path:
    """Write the last frame of ``video`` to ``png`` (its ``stack`` panels stacked)."""
    import imageio.v2 as imageio

    reader = imageio.get_reader(video)
    try:
        frame = None
        for frame in reader:  # noqa: B007  (the last one is kept)
            pass
    finally:
        reader.close()
    if frame is None:
        raise SystemExit(f"{video}: no frame in this video")
    frame = np.asarray(frame)[:, :, :3]
    if stack > 1:
        frame = stacked(frame, stack)
    png.parent.mkdir(parents=True, exist_ok=True)
    imageio.imwrite(png, frame)
    return png


#: a pixel this close to white (sum of RGB) counts as background
_WHITE = 3 * 250
#: white runs longer than this (pixels) between a panel's parts are cut to ``_GAP``
_GAP = 6


def _plot_right(panel: np.ndarray) -> int:
    """The column of the right spine of a panel's plot (drawn by gymprecice's renderer).

    The spines are a frame's longest dark lines: the top and bottom ones are the rows more
    than half dark; of the columns dark all along the plot's height, the first run is the
    left spine and the second the right one (the colour bars come after it).
    """
    dark = panel.sum(axis=2) < 150
    rows = np.flatnonzero(dark.mean(axis=1) > 0.5)
    columns = (
        np.flatnonzero(dark[rows[0] : rows[-1] + 1].mean(axis=0) > 0.95) if len(rows) > 1 else []
    )
    runs = np.split(columns, np.flatnonzero(np.diff(columns) > 1) + 1) if len(columns) else []
    if len(runs) < 2:
        raise SystemExit("still --stack: no plot frame (axes) found in a panel")
    return int(runs[1][-1])


def stacked(frame: np.ndarray, panels: int) -> np.ndarray:
    """``frame``'s ``panels`` equal-width panels one above the other, without colour bars.

    Each panel is cut right of its plot (dropping its colour bars) and its long white
    bands (between the title and the plot) are cut to a few pixels.
    """
    width = frame.shape[1] // panels
    parts = []
    for k in range(panels):
        panel = frame[:, k * width : (k + 1) * width, :3]
        right = _plot_right(panel)
        panel = panel[:, : min(right + 8, width)]
        filled = (panel.astype(int).sum(axis=2) < _WHITE).any(axis=1)
        keep = filled.copy()
        run = 0
        for row in range(len(filled)):  # keep the first _GAP rows of every white run
            run = 0 if filled[row] else run + 1
            keep[row] = filled[row] or run <= _GAP
        parts.append(panel[keep])
    widest = max(part.shape[1] for part in parts)
    padded = [
        np.pad(part, ((0, 0), (0, widest - part.shape[1]), (0, 0)), constant_values=255)
        for part in parts
    ]
    return np.concatenate(padded)


def snapshot(env_id: str, png: Path, steps: int, double: bool) -> Path:
    """Render ``env_id`` after ``steps`` actions at the top of its action box."""
    import tempfile

    import gymnasium as gym
    import imageio.v2 as imageio

    import gymprecice  # noqa: F401  (registers the environments)

    if not env_id.startswith("gymprecice/"):
        env_id = f"gymprecice/{env_id}"
    with tempfile.TemporaryDirectory(prefix="gymprecice-snapshot-") as runs:
        kwargs = {"run_root": runs, "render_mode": "rgb_array"}
        if double:
            kwargs["double"] = True
        env = gym.make(env_id, **kwargs)
        try:
            env.reset(seed=0)
            action = np.asarray(env.action_space.high, dtype=env.action_space.dtype)
            for _ in range(steps):
                *_, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    break
            frame = env.render()
        finally:
            env.close()
    png.parent.mkdir(parents=True, exist_ok=True)
    imageio.imwrite(png, frame)
    return png


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    cmd = commands.add_parser("still", help="the last frame of a video as a PNG")
    cmd.add_argument("video", type=Path)
    cmd.add_argument("png", type=Path)
    cmd.add_argument("--stack", type=int, default=0, help="panels to stack (compare's video)")
    cmd = commands.add_parser("snapshot", help="an env's env.render() as a PNG")
    cmd.add_argument("env", help="a registered id, e.g. gymprecice/HeatedPlateFast-v0")
    cmd.add_argument("png", type=Path)
    cmd.add_argument("--steps", type=int, default=4, help="actions before the frame")
    cmd.add_argument("--double", action="store_true", help="on the test double")
    args = parser.parse_args(argv)
    if args.command == "still":
        print(still(args.video, args.png, args.stack))
    else:
        print(snapshot(args.env, args.png, args.steps, args.double))


if __name__ == "__main__":
    main()
