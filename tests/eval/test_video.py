"""Videos of a recording: frames a person can read (robot size, legend, arrows, HUD), GIF
and MP4 encoding with progress."""

import importlib.util
import io
import sys

import numpy as np
import pytest

from boids_env import parallel_env, style
from boids_env.drawing import ARENA, HEIGHT, MIN_RADIUS, WIDTH
from boids_env.eval.episode import run_episode
from boids_env.eval.video import check_format, frame_count, frames, running_status, write_video
from boids_env.policies import ReynoldsPolicy


@pytest.fixture(scope="module")
def recording():
    env = parallel_env(robots=7, max_cycles=60)
    return run_episode(env, ReynoldsPolicy(), seed=0).recording


def _has(image, colour, tol=12):
    return int((np.abs(image.astype(int) - colour).max(axis=-1) <= tol).sum())


def test_frames_show_robots_at_a_visible_size_and_every_arrow_colour(recording):
    images = list(frames(recording))
    assert len(images) == frame_count(recording) == 31, len(images)
    last = images[-1]
    assert last.shape == (HEIGHT, WIDTH, 3) and WIDTH % 16 == 0 and HEIGHT % 16 == 0
    arena, panel = last[:, :ARENA], last[:, ARENA:]
    disc = np.pi * MIN_RADIUS**2
    assert _has(arena, style.LEADER) >= 0.6 * disc, "the leader is a visible red disc"
    assert _has(arena, style.FOLLOWER) >= 6 * 0.6 * disc, "six visible blue followers"
    for name in ("separation", "cohesion", "alignment", "leader"):  # the study's rules
        assert _has(panel, style.RULE_COLOURS[name]) > 10, f"the legend shows {name}"
    assert _has(panel, style.RULE_COLOURS["obstacle"]) == 0, "no obstacle force in the arena"
    for name in ("separation", "leader"):  # the rules with large forces in this episode
        assert _has(arena, style.RULE_COLOURS[name]) > 20, f"{name} arrows are drawn"
    for a, b in ((style.LEADER, style.RULE_COLOURS["leader"]),
                 (style.FOLLOWER, style.RULE_COLOURS["alignment"])):
        assert np.abs(np.subtract(a, b)).sum() > 120, f"{a} and {b} are told apart"


def test_the_arena_view_shows_the_whole_arena(recording):
    image = list(frames(recording, view="arena"))[-1]
    assert _has(image[:, :ARENA], style.FOLLOWER) > 6 * 40, "six followers drawn"


def test_the_hud_runs_the_episodes_v_to_its_final_numbers(recording):
    lines = running_status(recording)
    assert len(lines) == len(recording.time)
    m = recording.metrics()
    assert lines[0].startswith("t =   0.0 s")
    assert (f"V_sep {m['V_sep']:.3f}" in lines[-1] and f"V_coh {m['V_coh']:.3f}" in lines[-1]
            and f"V_align {m['V_align']:.3f}" in lines[-1]), (lines[-1], m)


def test_gif_keeps_every_frame_and_the_arrow_colours(recording, tmp_path):
    from PIL import Image

    info = write_video(recording, tmp_path / "e.gif", progress=True)
    assert info.frames == 31 and info.fps == pytest.approx(10.0) and info.seconds > 0
    gif = Image.open(tmp_path / "e.gif")
    assert gif.n_frames == 31 and gif.info["duration"] == 100, "2x real time"
    gif.seek(30)
    last = np.asarray(gif.convert("RGB"))
    assert _has(last[:, :ARENA], style.RULE_COLOURS["separation"], tol=20) > 20, \
        "the shared palette keeps the arrow colours that the first frame lacks"
    assert [p.name for p in tmp_path.iterdir()] == ["e.gif"], "no temporary file left"


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_the_encoding_bar_shows_on_a_terminal_only(recording, tmp_path, monkeypatch):
    """A bar's redraws would fill a piped log with half lines; on a terminal it shows."""
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    write_video(recording, tmp_path / "a.gif", progress=True)
    assert "encoding a.gif" in terminal.getvalue() and "/31" in terminal.getvalue()
    piped = io.StringIO()
    monkeypatch.setattr(sys, "stderr", piped)
    write_video(recording, tmp_path / "b.gif", progress=True)
    assert piped.getvalue() == "", "no bar in a piped log"


def test_the_render_extra_installs_the_encoding_bar():
    """The README's first command installs the render extra only: tqdm was in eval and train,
    so the bar was silently skipped there."""
    import tomllib
    from pathlib import Path

    from boids_env.extras import EXTRAS

    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    for extra in ("render", "video"):
        wants = project["project"]["optional-dependencies"][extra]
        assert any(r.startswith("tqdm") for r in wants), (extra, wants)
        assert "tqdm" in EXTRAS[extra], extra


@pytest.mark.skipif(importlib.util.find_spec("imageio_ffmpeg") is None,
                    reason="imageio-ffmpeg (the video extra) is not installed")
def test_mp4(recording, tmp_path):
    import imageio.v2 as imageio

    info = write_video(recording, tmp_path / "e.mp4", progress=False)
    reader = imageio.get_reader(tmp_path / "e.mp4", format="FFMPEG")
    first = reader.get_data(0)
    assert first.shape == (HEIGHT, WIDTH, 3)
    assert reader.count_frames() == info.frames == 31
    assert [p.name for p in tmp_path.iterdir()] == ["e.mp4"]


def test_bad_format_and_missing_ffmpeg_are_clear(monkeypatch, recording, tmp_path):
    with pytest.raises(ValueError, match="video format must be one of"):
        write_video(recording, tmp_path / "e.avi")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "imageio_ffmpeg" else real(name, *a))
    with pytest.raises(ImportError, match=r"-e '\.\[video\]'"):
        check_format("mp4")
