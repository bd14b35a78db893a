"""``--video FILE``: an episode's frames (``env.render()``) as an MP4 or a GIF.

``gymprecice evaluate`` / ``baseline`` / ``open-loop`` / ``feedback`` with ``--video``
build the env with ``render_mode="rgb_array"`` and write one video per episode: ``FILE``
itself for one episode, ``FILE`` with ``-episode-K`` before its suffix for several. The
frames are those of Gymnasium's ``RecordVideo``: one after ``reset()`` and one after every
step, at the env's ``metadata["render_fps"]``. The episode's summary names its video, so
``gymprecice compare --video`` can put the uncontrolled and the controlled flow from the
same start side by side (:func:`side_by_side`).

The writers are imageio's: MP4 through imageio-ffmpeg (which brings its own ffmpeg
binary, no system one), GIF through Pillow. A format whose writer is not installed is
refused before any solver starts, naming the package to install.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "FORMATS",
    "VideoError",
    "VideoFile",
    "check_renders",
    "check_video_path",
    "episode_video_path",
    "read_frames",
    "side_by_side",
    "video_fps",
    "write_video",
]

#: suffix -> (what writes it, the Python modules it needs, the install hint)
FORMATS: dict[str, tuple[str, tuple[str, ...], str]] = {
    ".mp4": (
        "imageio with imageio-ffmpeg",
        ("imageio", "imageio_ffmpeg"),
        "pip install imageio imageio-ffmpeg (or 'gymprecice-core[render]')",
    ),
    ".gif": (
        "imageio with Pillow",
        ("imageio", "PIL"),
        "pip install imageio pillow (or 'gymprecice-core[render]')",
    ),
}
#: name of a video when no FILE is given (``--video`` alone): in the command's --out
DEFAULT_NAME = "episode.mp4"


class VideoError(ValueError):
    """``--video`` cannot be written: an unknown format or a writer not installed."""


def check_video_path(path: str | Path) -> Path:
    """``path`` if its format can be written here; else :class:`VideoError` with the fix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise VideoError(
            f"--video {path}: cannot write {suffix or 'a file without a suffix'}; name an "
            f"{' or '.join(s.lstrip('.').upper() for s in FORMATS)} file ({', '.join(FORMATS)})"
        )
    writer, modules, hint = FORMATS[suffix]
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise VideoError(
            f"--video {path}: writing {suffix.lstrip('.').upper()} needs {writer}, and "
            f"{', '.join(missing)} is not installed; {hint}"
        )
    return path


def episode_video_path(path: Path, episode: int, episodes: int) -> Path:
    """Where episode ``episode`` of ``episodes`` goes: ``path``, or ``path-episode-K``."""
    if episodes == 1:
        return path
    return path.with_name(f"{path.stem}-episode-{episode}{path.suffix}")


class VideoFile:
    """A video being written, frame by frame (an episode's frames are never all in memory).

    Use as a context manager; the parent directory is made. A video that received no
    frame is removed and refused.
    """

    def __init__(self, path: Path, fps: float) -> None:
        import imageio.v2 as imageio

        self.path, self.frames = Path(path), 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.suffix.lower() == ".mp4":
            # libx264 in yuv420p (what every player plays) needs even sizes: pad by 1 at most
            self._writer = imageio.get_writer(
                self.path,
                format="FFMPEG",
                fps=fps,
                codec="libx264",
                pixelformat="yuv420p",
                macro_block_size=2,
            )
        else:
            self._writer = imageio.get_writer(self.path, mode="I", duration=1000.0 / fps, loop=0)

    def add(self, frame: np.ndarray) -> None:
        self._writer.append_data(np.asarray(frame, dtype=np.uint8))
        self.frames += 1

    def __enter__(self) -> VideoFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()
        if not self.frames:
            self.path.unlink(missing_ok=True)
            if exc[0] is None:
                raise VideoError(f"--video {self.path}: the episode rendered no frame")


def write_video(path: Path, frames: Sequence[np.ndarray], fps: float) -> Path:
    """Write ``frames`` (``HxWx3`` uint8) to ``path``."""
    with VideoFile(path, fps) as video:
        for frame in frames:
            video.add(frame)
    return path


def check_renders(env_id: str) -> None:
    """Refuse an env whose class does not list ``rgb_array`` in its ``render_modes``.

    Checked from the registration, before anything is built (an env registered through a
    factory function has no metadata to read, and is left to its constructor).
    """
    import gymnasium as gym
    from gymnasium.envs.registration import load_env_creator

    entry = gym.spec(env_id).entry_point
    creator = load_env_creator(entry) if isinstance(entry, str) else entry
    metadata = getattr(creator, "metadata", None)
    if isinstance(creator, type) and isinstance(metadata, dict):
        modes = list(metadata.get("render_modes", []))
        if "rgb_array" not in modes:
            raise VideoError(
                f"--video: {env_id} does not render (its metadata['render_modes'] is "
                f"{modes}); a video needs an env that supports render_mode='rgb_array' "
                "(render_fields and the render_modes metadata, docs: Rendering)"
            )


def read_frames(path: Path) -> Iterator[np.ndarray]:
    """The frames of a video written by :func:`write_video` (RGB, ``HxWx3`` uint8)."""
    import imageio.v2 as imageio

    reader = imageio.get_reader(path)
    try:
        for frame in reader:
            yield np.asarray(frame)[:, :, :3]
    finally:
        reader.close()


def _label(text: str, width: int, height: int = 24) -> np.ndarray:
    """A white strip of ``width`` pixels with ``text`` centred on it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100
    figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(figure)
    figure.text(0.5, 0.5, text, ha="center", va="center", fontsize=10, weight="bold")
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()


def video_fps(path: Path) -> float:
    """The frame rate a video was written at (MP4: its fps; GIF: 1000 / frame duration)."""
    import imageio.v2 as imageio

    reader = imageio.get_reader(path)
    try:
        meta = reader.get_meta_data()
    finally:
        reader.close()
    if meta.get("fps"):
        return float(meta["fps"])
    return 1000.0 / float(meta.get("duration") or 250.0)


def side_by_side(out: Path, videos: Sequence[Path], labels: Sequence[str]) -> Path:
    """One video of ``videos`` next to each other, each under its label, at the first's rate.

    The shorter ones hold their last frame until the longest ends; frames of different
    heights are padded white at the bottom.
    """
    streams = [read_frames(v) for v in videos]
    last: list[np.ndarray | None] = [None] * len(videos)
    strips: dict[int, np.ndarray] = {}
    frames = []
    while True:
        ended = 0
        for k, stream in enumerate(streams):
            frame = next(stream, None)
            if frame is None:
                ended += 1
                if last[k] is None:
                    raise VideoError(f"{videos[k]}: no frame in this video")
            else:
                last[k] = frame
        if ended == len(streams):
            break
        shown = [f for f in last if f is not None]
        height = max(f.shape[0] for f in shown)
        panels = []
        for k, frame in enumerate(shown):
            if frame.shape[0] < height:
                pad = np.full((height - frame.shape[0], *frame.shape[1:]), 255, np.uint8)
                frame = np.concatenate([frame, pad])
            if k not in strips:
                strips[k] = _label(labels[k], frame.shape[1])
            panels.append(np.concatenate([strips[k], frame]))
        frames.append(np.concatenate(panels, axis=1))
    return write_video(out, frames, video_fps(videos[0]))
