"""Videos of a recorded episode (``boids run --video``): GIF, or MP4 when imageio's ffmpeg
plugin (``imageio-ffmpeg``, the ``video`` extra) is installed.

Frames are drawn from the :class:`~boids_env.recording.Recording` (positions, the policy's
rule forces, the running V_*), not from the live env, so any recording makes a video (one of
``boids eval``'s trajectories, or a bag read back) and the episode's own time stays apart from
the encoding's. Frames are drawn and encoded one at a time, with a progress bar.
"""

from __future__ import annotations

import importlib.util
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import metrics, style
from boids_env.eval.progress import iterate
from boids_env.files import atomic_path
from boids_env.recording import Recording

VIDEO_FORMATS = ("gif", "mp4")
FRAME_EVERY = 2
"""Control steps per frame (a frame every 0.2 s of the episode)."""
SPEED = 2.0
"""Playback speed (times real time)."""
VIDEO_HINT = "MP4 needs imageio's ffmpeg plugin: pip install -e '.[video]'"


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`write_video` wrote."""

    path: Path
    frames: int
    seconds: float
    """Wall time of drawing and encoding (s)."""
    fps: float
    """Frames per second of playback."""


def check_format(fmt: str) -> None:
    """Raises ``ValueError`` for an unknown format, ``ImportError`` (naming the extra) for MP4
    without imageio-ffmpeg."""
    if fmt not in VIDEO_FORMATS:
        raise ValueError(f"video format must be one of {VIDEO_FORMATS}, got {fmt!r}")
    if fmt == "mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ImportError(VIDEO_HINT)


def running_status(recording: Recording) -> list[str]:
    """The HUD line of every sample: time and the V_* of the episode so far (as the env's
    own HUD shows them)."""
    cfg = recording.config
    flags = metrics.flags_for(cfg.metrics, recording.positions[1:], recording.commanded[1:],
                              None if recording.headings is None else recording.headings[1:])
    samples = np.arange(1, len(recording.time))
    lines = [f"t = {recording.time[0]:5.1f} s   V_sep 0.000   V_coh 0.000   V_align 0.000"]
    so_far = {key: np.cumsum(flags[name].sum(axis=1)) / samples
              for name, key in metrics.V_KEYS.items()}
    for s in samples:
        lines.append(f"t = {recording.time[s]:5.1f} s   V_sep {so_far['V_sep'][s - 1]:.3f}   "
                     f"V_coh {so_far['V_coh'][s - 1]:.3f}   "
                     f"V_align {so_far['V_align'][s - 1]:.3f}")
    return lines


def frames(recording: Recording, *, frame_every: int = FRAME_EVERY, view: str = "follow"
           ) -> Iterator[npt.NDArray[np.uint8]]:
    """Frames (H, W, 3) of every ``frame_every``-th sample and of the last one, drawn by the
    renderer (``view``: ``follow`` or ``arena``); the leader's trail covers every sample."""
    from boids_env.render import Frame, Renderer

    if isinstance(frame_every, bool) or not isinstance(frame_every, int) or frame_every < 1:
        raise ValueError(f"frame_every must be an integer >= 1, got {frame_every!r}")
    cfg = recording.config
    renderer = Renderer("rgb_array", cfg.scene, view=view)
    status = running_status(recording)
    last = len(recording.time) - 1
    try:
        for s in range(last + 1):
            overlays = {name: vec[s] for name, vec in (recording.forces or {}).items()}
            sc = cfg.scenario
            crowd = None if recording.pedestrians is None else recording.pedestrians[s]
            headings = None if recording.headings is None else recording.headings[s]
            scene = Frame(recording.positions[s], s, cfg.world.robot_radius, status[s],
                          cfg.observation.horizon, overlays, (),
                          sc.leader_radius, crowd,
                          sc.person_radius, headings)
            shown = s % frame_every == 0 or s == last
            if shown:
                image = renderer.draw(scene)
                assert image is not None
                yield image
            else:  # not drawn, but the leader's trail goes through it
                renderer.advance(scene)
    finally:
        renderer.close()


def frame_count(recording: Recording, frame_every: int = FRAME_EVERY) -> int:
    """How many frames :func:`frames` yields."""
    last = len(recording.time) - 1
    return last // frame_every + 1 + (last % frame_every != 0)


def write_video(recording: Recording, path: str | Path, *, frame_every: int = FRAME_EVERY,
                speed: float = SPEED, view: str = "follow", progress: bool = True
                ) -> VideoInfo:
    """Draws and encodes the episode to ``path`` (``.gif`` or ``.mp4``) atomically.

    Args:
        recording: the episode.
        path: the file; its suffix picks the format.
        frame_every: control steps per frame.
        speed: playback speed, times real time.
        view: ``follow`` (a camera on the flock, robots at true size, the arena as a map
            beside it) or ``arena`` (the whole arena).
        progress: show a progress bar (tqdm) while encoding, on a terminal.
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    check_format(fmt)
    if not speed > 0:
        raise ValueError(f"speed must be > 0 (times real time), got {speed!r}")
    fps = speed / (recording.config.world.dt * frame_every)
    total = frame_count(recording, frame_every)
    start = time.perf_counter()
    stream = iterate(frames(recording, frame_every=frame_every, view=view), total,
                     desc=f"encoding {path.name}", unit="frame", enabled=progress)
    with atomic_path(path) as tmp:
        if fmt == "gif":
            _write_gif(stream, tmp, fps)
        else:  # ffmpeg picks the container from the file name's suffix
            named = tmp.with_name(tmp.name + path.suffix)
            try:
                _write_mp4(stream, named, fps)
                os.replace(named, tmp)
            finally:
                named.unlink(missing_ok=True)
    return VideoInfo(path, total, time.perf_counter() - start, fps)


def _write_gif(stream: Iterator[npt.NDArray[np.uint8]], path: Path, fps: float) -> None:
    """One palette for all frames, no dithering (flat colours stay flat, nothing flickers):
    the first frame's colours and every colour of the style at a few opacities (arrows and
    contact rings may first appear later)."""
    from PIL import Image

    first = next(stream)
    palette = Image.fromarray(np.vstack([first, _swatch(first.shape[1])])).quantize(
        colors=128, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)

    def quantized() -> Iterator[Any]:
        for image in stream:
            yield Image.fromarray(image).quantize(palette=palette, dither=Image.Dither.NONE)

    head = Image.fromarray(first).quantize(palette=palette, dither=Image.Dither.NONE)
    head.save(path, format="GIF", save_all=True, append_images=quantized(),
              duration=round(1000 / fps), loop=0)


def _swatch(width: int) -> npt.NDArray[np.uint8]:
    """Blocks of every style colour over white at opacities 1, 0.7, 0.45 and 0.2."""
    colours = [style.LEADER, style.FOLLOWER, style.TRAIL, style.CONTACT,
               *style.RULE_COLOURS.values()]
    blocks = [np.full((24, 24, 3), np.round(a * np.array(c) + (1 - a) * 255), dtype=np.uint8)
              for c in colours for a in (1.0, 0.7, 0.45, 0.2)]
    row = np.hstack(blocks)[:, :width]
    return np.pad(row, ((0, 0), (0, width - row.shape[1]), (0, 0)), constant_values=255)


def _write_mp4(stream: Iterator[npt.NDArray[np.uint8]], path: Path, fps: float) -> None:
    import imageio.v2 as imageio

    writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                quality=8, pixelformat="yuv420p", macro_block_size=16)
    try:
        for image in stream:
            writer.append_data(image)
    finally:
        writer.close()
