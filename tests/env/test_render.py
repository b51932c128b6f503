"""The renderer on hand-made scenes: sizes, contacts, arrows, text wrapping, no display."""

import os
import subprocess
import sys

import numpy as np
import pytest

from boids_env import style
from boids_env.drawing import (
    ARENA,
    BACKGROUND,
    HEIGHT,
    MARGIN,
    MIN_RADIUS,
    WIDTH,
    draw_arrow,
    wrap_text,
)
from boids_env.render import Frame, Renderer

RADIUS = 0.036


def _count(image, colour, tol=10):
    return int((np.abs(image.astype(int) - colour).max(axis=-1) <= tol).sum())


def _scene(positions, **kwargs):
    return Frame(np.asarray(positions, dtype=float), 5, RADIUS,
                 "t =   0.5 s   V_sep 0.100   V_coh 0.000   V_align 0.200", **kwargs)


@pytest.mark.parametrize("view", ["arena", "follow"])
def test_robots_are_discs_of_at_least_the_minimum_radius(view):
    r = Renderer("rgb_array", 5.0, view=view)
    image = r.draw(_scene([[0, 0], [1, 0], [-1, 0], [0, 1]]))
    assert image.shape == (HEIGHT, WIDTH, 3)
    drawn = r.robot_radius_px(RADIUS, 4)
    assert drawn >= MIN_RADIUS and drawn >= round(RADIUS * r.scale)
    for k, (x, y) in enumerate(r.to_px(np.array([[1, 0], [-1, 0], [0, 1]]))):
        patch = image[y - drawn - 1:y + drawn + 2, x - drawn - 1:x + drawn + 2]
        area = _count(patch, style.FOLLOWER)
        assert area >= 0.5 * np.pi * drawn**2, f"follower {k + 1}: {area} px of blue"
    if view == "follow":
        assert r.scale > 100, f"the camera zooms onto the flock: {r.scale:.0f} px/m"
        assert drawn == round(RADIUS * r.scale), "robots at their true size when zoomed"


@pytest.mark.parametrize("view", ["arena", "follow"])
def test_the_axes_say_their_unit(view):
    """The GIF's grid numbers had no unit: the one tick that carried "m" was often out of
    view. A caption in the top margin says what they are."""
    r = Renderer("rgb_array", 5.0, view=view)
    image = r.draw(_scene([[0, 0], [-0.5, 0], [0, -0.5]]))
    top = image[:MARGIN, MARGIN:ARENA // 2]
    ink = int((np.abs(top.astype(int) - BACKGROUND).max(axis=-1) > 40).sum())
    assert ink > 150, f"the caption is drawn in the top margin ({ink} px of text)"
    assert r.axis_caption == "x, y in m (world frame); grid 1 m", r.axis_caption


def test_touching_robots_are_ringed_and_counted():
    r = Renderer("rgb_array", 5.0)
    apart = r.draw(_scene([[0, 0], [2, 0], [2.5, 0]]))
    touching = r.draw(_scene([[0, 0], [2, 0], [2 + 2 * RADIUS, 0]]))
    ring = style.CONTACT
    assert _count(touching[:, :ARENA], ring) > _count(apart[:, :ARENA], ring) + 20, \
        "a dark ring around each touching robot"
    assert not np.array_equal(touching[:, ARENA:], apart[:, ARENA:]), "the HUD count changes"


def test_arrows_have_heads_and_the_legend_names_each_rule():
    r = Renderer("rgb_array", 5.0, view="follow")
    overlays = {name: np.array([[0.3, 0.0], [0.0, 0.3]]) for name in style.RULE_COLOURS}
    overlays["leader"] = np.array([[5.0, 0.0], [0.0, 5.0]])  # raw metres: drawn shortened
    image = r.draw(_scene([[0, 0], [-1, 0], [0, -1]], overlays=overlays))
    for name, colour in style.RULE_COLOURS.items():
        assert _count(image[:, ARENA:], colour) > 10, f"legend entry for {name}"
    # the leader term is shortened to the longest arrow (0.25 m), not 5 m long
    start = r.to_px(np.array([-1.0, 0.0]))
    length = r.arrow_max * r.scale
    row = image[start[1] - 4:start[1] + 5, :ARENA]
    xs = np.nonzero((np.abs(row.astype(int) - style.RULE_COLOURS["leader"]).max(-1) <= 10)
                    .any(axis=0))[0]
    assert xs.max() - start[0] == pytest.approx(length, abs=3), (xs.max(), start, length)


def test_an_arrow_head_is_wider_than_its_shaft():
    import pygame

    surface = pygame.Surface((60, 30))
    surface.fill((255, 255, 255))
    draw_arrow(surface, (0, 0, 0), (5, 15), (55, 15))
    image = np.transpose(pygame.surfarray.array3d(surface), (1, 0, 2))
    dark = (image.max(axis=-1) < 128)
    assert dark[:, 20].sum() <= 3 and dark[:, 51].sum() >= 5, "a 2 px shaft and a head"


def test_wrapped_text_fits_the_panel():
    import pygame

    pygame.font.init()
    font = pygame.font.Font(None, 19)
    text = "arrows: drive the leader (--path external) · 1-6: pick · +/-: change · quit"
    lines = wrap_text(text, font, 120)
    assert len(lines) > 2 and all(font.size(line)[0] <= 120 for line in lines), lines
    assert " ".join(lines) == text


def test_a_fading_message_blends_into_the_panel():
    r = Renderer("rgb_array", 5.0)
    r.message = "leader_weight = 1.1"
    r.message_opacity = 1.0
    shown = r.draw(_scene([[0, 0], [1, 0]]))
    r.message_opacity = 0.0
    gone = r.draw(_scene([[0, 0], [1, 0]]))
    bottom = slice(HEIGHT - 40, HEIGHT)
    assert _count(shown[bottom, ARENA:], (160, 30, 30), tol=40) > 20
    assert _count(gone[bottom, ARENA:], (160, 30, 30), tol=40) == 0


def _headless() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ("SDL_VIDEODRIVER", "DISPLAY", "WAYLAND_DISPLAY")}


def test_no_display_is_a_clear_error_for_the_live_window():
    code = ("from boids_env.render import require_display, NoDisplayError\n"
            "try:\n    require_display()\nexcept NoDisplayError as e:\n    print(e)\n"
            "else:\n    print('opened')\n")
    out = subprocess.run([sys.executable, "-c", code], env=_headless(), capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert "no display for the live window" in out and "DISPLAY" in out and "--video" in out, out
    # asked for explicitly (as the tests do), the invisible driver is fine
    out = subprocess.run([sys.executable, "-c", code],
                         env={**_headless(), "SDL_VIDEODRIVER": "dummy"},
                         capture_output=True, text=True, timeout=120, check=True).stdout
    assert out.strip() == "opened", out


def test_the_human_mode_without_a_display_warns_and_draws_off_screen():
    """As Gymnasium's own envs do headless: ``check_env`` opens every declared render mode."""
    code = ("import warnings\nfrom boids_env.render import Renderer\n"
            "with warnings.catch_warnings(record=True) as caught:\n"
            "    warnings.simplefilter('always')\n    r = Renderer('human', 5.0)\n"
            "print(r.mode, '|'.join(str(w.message) for w in caught))\n")
    out = subprocess.run([sys.executable, "-c", code], env=_headless(), capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert out.startswith("human ") and "no display" in out and "rgb_array" in out, out
