"""pygame drawing primitives and the frame's layout and colours, for :mod:`boids_env.render`.

Pixels only; no env, no scene.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import numpy as np
import numpy.typing as npt

try:
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError("rendering needs pygame-ce: pip install -e '.[render]'") from exc

ARENA = 640
"""Side of the arena drawing (px), its margin included."""
PANEL = 272
"""Width of the panel beside the arena (px)."""
WIDTH, HEIGHT = ARENA + PANEL, ARENA
"""Frame size (px): both multiples of 16, as video encoders want."""
MARGIN = 24
"""Space around the arena's walls (px), where the grid's labels go."""
MIN_RADIUS = 5
"""Smallest drawn robot radius (px): a 36 mm robot is 2 px at the default scale, so it is
drawn larger (the panel says by how much) with its true size as a dark core."""
BACKGROUND = (255, 255, 255)
OUTSIDE = (236, 236, 233)
"""Beyond the walls."""
PANEL_BACKGROUND = (241, 241, 237)
GRID = (226, 226, 222)
GRID_LABEL = (150, 150, 150)
WALL = (40, 40, 40)
TEXT = (25, 25, 25)
MUTED = (95, 95, 95)
HORIZON = (200, 215, 235)
MESSAGE = (160, 30, 30)


def grid_step(half: float, scale: float) -> float:
    """Grid spacing (m): 1 m, or the smallest of 2, 5, 10 … m whose lines are 28 px apart."""
    for step in (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0):
        if step * scale >= 28:
            return step
    return 2 * half


def draw_arrow(canvas: Any, colour: tuple[int, int, int], start: npt.ArrayLike,
               end: npt.ArrayLike, width: int = 2, head: float = 7.0) -> None:
    """An arrow from ``start`` to ``end`` (px) with a filled head; nothing if shorter than
    1 px, no head below 4 px."""
    a, b = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    d = b - a
    length = float(np.hypot(*d))
    if length < 1:
        return
    u = d / length
    size = min(head, 0.6 * length)
    base = b - u * size
    pygame.draw.line(canvas, colour, a.round(), (base + u).round(), width)
    if length >= 4:
        n = np.array([-u[1], u[0]]) * size * 0.55
        pygame.draw.polygon(canvas, colour, [b.round(), (base + n).round(),
                                             (base - n).round()])


def wrap_text(text: str, font: Any, width: int) -> list[str]:
    """``text`` broken at spaces into lines no wider than ``width`` px (a longer word gets a
    line of its own)."""
    lines: list[str] = []
    current = ""
    for word in text.split():
        trial = f"{current} {word}" if current else word
        if current and font.size(trial)[0] > width:
            lines.append(current)
            current = word
        else:
            current = trial
    if current:
        lines.append(current)
    return lines


def darker(colour: tuple[int, int, int]) -> tuple[int, int, int]:
    r, g, b = colour
    return (int(r * 0.45), int(g * 0.45), int(b * 0.45))


def blend(colour: tuple[int, int, int], background: tuple[int, int, int], opacity: float
           ) -> tuple[int, int, int]:
    o = min(max(opacity, 0.0), 1.0)
    r, g, b = (round(o * c + (1 - o) * k) for c, k in zip(colour, background, strict=True))
    return (r, g, b)


class NoDisplayError(RuntimeError):
    """A window was asked for where there is no display."""


def display_missing() -> str | None:
    """Why no window would be seen (SDL found no display and fell back, unasked, to its
    off-screen driver), or None where a window can be shown or the invisible driver was asked
    for (``SDL_VIDEODRIVER=dummy``)."""
    pygame.display.init()
    driver = pygame.display.get_driver()
    if driver not in ("offscreen", "dummy") or os.environ.get("SDL_VIDEODRIVER"):
        return None
    return (f"no display (DISPLAY is "
            f"{os.environ.get('DISPLAY') or 'not set'}, WAYLAND_DISPLAY is "
            f"{os.environ.get('WAYLAND_DISPLAY') or 'not set'}; SDL could only open its "
            f"{driver!r} driver)")


def require_display() -> None:
    """Raises :class:`NoDisplayError` where a window would not be seen: the live window's
    check (``boids run --render human``), made before anything runs."""
    reason = display_missing()
    if reason is not None:
        pygame.display.quit()
        raise NoDisplayError(
            f"{reason.replace('no display', 'no display for the live window', 1)}. Run it on "
            f"a desktop (or ssh -X), or write a video instead: boids run --video; set "
            f"SDL_VIDEODRIVER=dummy to run the window invisibly on purpose.")


def open_window(size: tuple[int, int], caption: str) -> Any:
    """Opens the pygame window. Where there is no display it warns once and draws on SDL's
    off-screen window, as Gymnasium's own envs do headless (so that ``check_env``, which opens
    every declared render mode, passes); :func:`require_display` is the strict check."""
    reason = display_missing()
    if reason is not None:
        warnings.warn(f"render_mode='human': {reason}; the frames are drawn off-screen, unseen "
                      f"(render_mode='rgb_array' returns them)", UserWarning, stacklevel=4)
    window = pygame.display.set_mode(size)
    pygame.display.set_caption(caption)
    return window
