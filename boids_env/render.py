"""pygame renderer: arena, robots, leader trail, horizon circles, force arrows and a HUD.

The only module that knows pixels. Works headless: ``rgb_array`` draws on an off-screen
surface; ``human`` opens a window (set ``SDL_VIDEODRIVER=dummy`` where there is no display).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

try:
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError("rendering needs pygame-ce: pip install 'boids-env[render]'") from exc

SIZE = 640
"""Side of the arena drawing (px); the HUD strip sits below it."""
HUD_HEIGHT = 28
BACKGROUND = (250, 250, 247)
WALL = (40, 40, 40)
LEADER = (214, 39, 40)
FOLLOWER = (31, 119, 180)
TRAIL = (240, 160, 160)
HORIZON = (200, 215, 235)
ARROW_COLOURS = {  # as the original RViz view
    "alignment": (0, 0, 255),
    "cohesion": (0, 170, 0),
    "separation": (230, 0, 0),
    "leader": (120, 200, 255),
}
ARROW_SCALE = 1.0
"""Metres drawn per unit of an overlay vector (newton for forces, metre for the leader term)."""
ARROW_MAX = 0.4
"""Longest arrow drawn (m), so that the raw leader vector does not cover the arena."""


@dataclass(frozen=True)
class Scene:
    """What one frame shows, as plain data (the env builds it; this module knows no env)."""

    positions: npt.NDArray[np.float64]
    """(N, 2) robot positions (m), the leader first."""
    steps: int
    """Control steps since reset (a smaller number than the last frame's clears the trail)."""
    robot_radius: float
    """Robot radius (m)."""
    status: str = ""
    """The HUD line under the arena (time, V_*)."""
    horizon: float = 1.0
    """Neighbour radius (m), drawn around followers when the renderer shows horizons."""
    overlays: dict[str, npt.NDArray[np.float64]] = field(default_factory=dict)
    """Per-follower vectors (F, 2) drawn as arrows, by rule name."""
    hud_lines: tuple[str, ...] = ()
    """Extra text lines (e.g. the live window's controls)."""


class Renderer:
    """Draws :class:`Scene` frames of one env; created by the env on its first render."""

    def __init__(self, mode: str, arena_half_size: float, *, show_horizon: bool = False,
                 trail_length: int = 2000) -> None:
        self.mode = mode
        self.half = arena_half_size
        self.scale = (SIZE - 20) / (2 * arena_half_size)  # px per metre, 10 px margin
        self.show_horizon = show_horizon
        self.trail_length = trail_length
        self._trail: list[tuple[int, int]] = []
        self._last_steps = -1
        pygame.font.init()
        self._font = pygame.font.Font(None, 22)
        self._window: Any = None
        self._clock: Any = None
        self.fps: float = 10.0
        """Frames per second of the human window (10 = real time; 0 = as fast as possible)."""
        if mode == "human":
            pygame.display.init()
            self._window = pygame.display.set_mode((SIZE, SIZE + HUD_HEIGHT))
            pygame.display.set_caption("boids-env")
            self._clock = pygame.time.Clock()
        self._canvas = pygame.Surface((SIZE, SIZE + HUD_HEIGHT))

    def to_px(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
        """World metres (..., 2) to pixel coordinates (y up in the world, down on screen)."""
        px = np.empty(points.shape, dtype=np.int64)
        px[..., 0] = np.rint(SIZE / 2 + points[..., 0] * self.scale)
        px[..., 1] = np.rint(SIZE / 2 - points[..., 1] * self.scale)
        return px

    def draw(self, scene: Scene) -> npt.NDArray[np.uint8] | None:
        """Draws one frame; returns an (H, W, 3) image in ``rgb_array`` mode."""
        canvas = self._canvas
        canvas.fill(BACKGROUND)
        corner = self.to_px(np.array([-self.half, self.half]))
        side = round(2 * self.half * self.scale)
        pygame.draw.rect(canvas, WALL, (int(corner[0]), int(corner[1]), side, side), 2)
        pos = self.to_px(scene.positions)
        if scene.steps < self._last_steps or scene.steps == 0:
            self._trail = []
        if scene.steps != self._last_steps:
            self._trail.append((int(pos[0, 0]), int(pos[0, 1])))
            self._trail = self._trail[-self.trail_length:]
        self._last_steps = scene.steps
        if len(self._trail) > 1:
            pygame.draw.lines(canvas, TRAIL, False, self._trail, 2)
        if self.show_horizon:
            r = int(scene.horizon * self.scale)
            for x, y in pos[1:]:
                pygame.draw.circle(canvas, HORIZON, (int(x), int(y)), r, 1)
        radius = max(3, round(scene.robot_radius * self.scale))
        for x, y in pos[1:]:
            pygame.draw.circle(canvas, FOLLOWER, (int(x), int(y)), radius)
        pygame.draw.circle(canvas, LEADER, (int(pos[0, 0]), int(pos[0, 1])), radius + 1)
        self._draw_arrows(canvas, scene.positions[1:], scene.overlays)
        self._draw_hud(canvas, scene)
        if self.mode == "human":
            self._window.blit(canvas, (0, 0))
            pygame.event.pump()
            pygame.display.flip()
            self._clock.tick(self.fps)
            return None
        return np.ascontiguousarray(np.transpose(pygame.surfarray.array3d(canvas), (1, 0, 2)))

    def _draw_arrows(self, canvas: Any, followers: npt.NDArray[np.float64],
                     overlays: dict[str, npt.NDArray[np.float64]]) -> None:
        for name, vectors in overlays.items():
            colour = ARROW_COLOURS.get(name, (90, 90, 90))
            start = self.to_px(followers)
            vec = ARROW_SCALE * np.asarray(vectors, dtype=float)
            length = np.linalg.norm(vec, axis=-1, keepdims=True)
            vec = np.where(length > ARROW_MAX, vec * ARROW_MAX / np.maximum(length, 1e-12), vec)
            end = self.to_px(followers + vec)
            for a, b in zip(start, end, strict=True):
                if tuple(a) != tuple(b):
                    pygame.draw.line(canvas, colour, (int(a[0]), int(a[1])),
                                     (int(b[0]), int(b[1])), 2)

    def _draw_hud(self, canvas: Any, scene: Scene) -> None:
        pygame.draw.rect(canvas, (235, 235, 230), (0, SIZE, SIZE, HUD_HEIGHT))
        canvas.blit(self._font.render(scene.status, True, (20, 20, 20)), (8, SIZE + 6))
        for i, line in enumerate(scene.hud_lines):
            canvas.blit(self._font.render(line, True, (60, 60, 60)), (14, 14 + 17 * i))

    def close(self) -> None:
        if self._window is not None:
            pygame.display.quit()
            self._window = None
