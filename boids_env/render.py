"""pygame renderer: the scene (the arena's walls, obstacles, a map's cells) with a 1 m grid,
robots, contacts, the leader trail, horizon circles and rule-force arrows, and beside it a
panel with the HUD (time, V_*, touching pairs), a legend, a 1 m scale bar, the live window's
controls and its messages.

The only module that knows pixels; it draws a plain-data :class:`Frame` (the env builds it)
over a static :class:`~boids_env.world.scene.Scene` and imports no env. Works headless:
``rgb_array`` draws on an off-screen surface; ``human`` opens a window, and where there is no
display warns and draws it off-screen (as Gymnasium's envs do); :func:`require_display` raises
:class:`NoDisplayError` there instead (the live window's check; set ``SDL_VIDEODRIVER=dummy``
to run a window invisibly on purpose, e.g. in tests).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import style
from boids_env.drawing import (
    ARENA,
    BACKGROUND,
    GRID,
    GRID_LABEL,
    HEIGHT,
    HORIZON,
    MARGIN,
    MESSAGE,
    MIN_RADIUS,
    MUTED,
    OUTSIDE,
    PANEL,
    PANEL_BACKGROUND,
    TEXT,
    WALL,
    WIDTH,
    NoDisplayError,
    blend,
    darker,
    draw_arrow,
    grid_step,
    open_window,
    pygame,
    require_display,
    wrap_text,
)
from boids_env.metrics import CONTACT_TOLERANCE, contact_pairs
from boids_env.world.scene import Scene

__all__ = ["VIEWS", "Frame", "NoDisplayError", "Renderer", "require_display"]

OBSTACLE = (95, 95, 92)
"""Obstacles and a map's occupied cells."""
UNKNOWN = (200, 200, 194)
"""A map's unknown cells."""


@dataclass(frozen=True)
class Frame:
    """What one frame shows, as plain data (the env builds it; this module knows no env)."""

    positions: npt.NDArray[np.float64]
    """(N, 2) robot positions (m), the leader first."""
    steps: int
    """Control steps since reset (a smaller number than the last frame's clears the trail)."""
    robot_radius: float
    """Robot radius (m)."""
    status: str = ""
    """The HUD's numbers (``"t = 1.0 s   V_sep 0.000 …"``: items apart by 3+ spaces, one
    panel line each)."""
    horizon: float = 1.0
    """Neighbour radius (m), drawn around followers when the renderer shows horizons."""
    overlays: dict[str, npt.NDArray[np.float64]] = field(default_factory=dict)
    """Per-follower vectors (F, 2) drawn as arrows, by rule name."""
    hud_lines: tuple[str, ...] = ()
    """Extra text for the panel (e.g. the live window's controls), wrapped to its width."""
    leader_radius: float | None = None
    """A person leads: its body's radius (m); drawn as a person, with its personal space."""
    pedestrians: npt.NDArray[np.float64] | None = None
    """(P, 2) the crowd's positions (m), drawn as grey people (None: no crowd)."""
    pedestrian_radius: float = 0.22
    """The pedestrians' radius (m)."""
    headings: npt.NDArray[np.float64] | None = None
    """(N,) headings (rad) of robots that have one, drawn as a mark from the centre to the
    rim; None for the study's holonomic robots."""


VIEWS = ("arena", "follow")
"""``arena``: the whole scene; ``follow``: a camera that follows the flock, zoomed so the
robots show at their true size, with the whole scene as a map in the panel."""
MIN_VIEW = 1.6
"""Smallest half-width (m) of the ``follow`` view."""


class Renderer:
    """Draws :class:`Frame` s of one env (created by the env on its first render) or of a
    recording (:mod:`boids_env.eval.video`).

    Args:
        mode: ``human`` (a window) or ``rgb_array`` (returns the frames).
        scene: the static scene (a number: the study's empty arena of that half size, m).
        show_horizon: draw each follower's neighbour radius.
        trail_length: control steps of the leader's trail that stay drawn.
        view: one of :data:`VIEWS`.
    """

    def __init__(self, mode: str, scene: Scene | float, *, show_horizon: bool = False,
                 trail_length: int = 2000, view: str = "arena") -> None:
        if view not in VIEWS:
            raise ValueError(f"view must be one of {VIEWS}, got {view!r}")
        if not isinstance(scene, Scene):
            from boids_env.world.scenes import arena

            scene = arena(float(scene))
        self.mode = mode
        self.view = view
        self.static = scene
        x0, y0, x1, y1 = scene.bounds
        self.bounds = np.array([[x0, y0], [x1, y1]])
        self.middle = self.bounds.mean(axis=0)
        """The scene's centre (m)."""
        self.half = max(x1 - x0, y1 - y0) / 2
        """Half the side of the square that holds the scene (m)."""
        self.centre = self.middle.copy()
        """The middle of the drawn area (m); the scene's centre in the ``arena`` view."""
        self.view_half = self.half
        """Half the side of the drawn area (m)."""
        self.scale = (ARENA - 2 * MARGIN) / (2 * self.half)
        """Pixels per metre of the arena drawing."""
        self.show_horizon = show_horizon
        self.trail_length = trail_length
        self._trail: list[npt.NDArray[np.float64]] = []
        self._last_steps = -1
        self._camera_steps = -1
        self._gliding = False
        self.arrow_scale = style.ARROW_SCALE * (2 if view == "arena" else 1)
        """Metres drawn per unit of an overlay vector (twice the style's in the zoomed-out
        ``arena`` view)."""
        self.arrow_max = style.ARROW_MAX * (1.6 if view == "arena" else 1)
        """Longest arrow drawn (m)."""
        self.message = ""
        """A transient message shown at the bottom of the panel (the live window's)."""
        self.message_opacity = 1.0
        """Its opacity, 0 (gone) to 1, so that it can fade."""
        pygame.font.init()
        self._fonts = {size: pygame.font.Font(None, size) for size in (16, 19, 21, 26)}
        self._window: Any = None
        self._clock: Any = None
        self.fps: float = 10.0
        """Frames per second of the human window (10 = real time; 0 = as fast as possible)."""
        if mode == "human":
            self._window = open_window((WIDTH, HEIGHT), "boids-env")
            self._clock = pygame.time.Clock()
        self._canvas = pygame.Surface((WIDTH, HEIGHT))
        self._background = self._draw_background() if view == "arena" else None

    def to_px(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
        """World metres (..., 2) to pixel coordinates (y up in the world, down on screen)."""
        points = np.asarray(points, dtype=float)
        px = np.empty(points.shape, dtype=np.int64)
        px[..., 0] = np.rint(ARENA / 2 + (points[..., 0] - self.centre[0]) * self.scale)
        px[..., 1] = np.rint(HEIGHT / 2 - (points[..., 1] - self.centre[1]) * self.scale)
        return px

    def robot_radius_px(self, robot_radius: float, robots: int) -> int:
        """Drawn radius (px): the true one, or :data:`MIN_RADIUS` (3 px above 200 robots)."""
        least = MIN_RADIUS if robots <= 200 else 3
        return max(least, round(robot_radius * self.scale))

    def advance(self, scene: Frame) -> None:
        """Takes in a frame that is not drawn (a video's skipped step): the leader's trail
        still passes through it."""
        self._update_trail(scene.steps, np.asarray(scene.positions[0], dtype=float))

    def draw(self, scene: Frame) -> npt.NDArray[np.uint8] | None:
        """Draws one frame; returns an (H, W, 3) image in ``rgb_array`` mode."""
        canvas = self._canvas
        positions = np.asarray(scene.positions, dtype=float)
        self._update_trail(scene.steps, positions[0])
        if self._background is not None:
            canvas.blit(self._background, (0, 0))
        else:
            self._update_camera(positions, reset=scene.steps == 0)
            self._draw_grid(canvas)
        canvas.set_clip(pygame.Rect(0, 0, ARENA - 1, HEIGHT))  # nothing spills into the panel
        pos = self.to_px(positions)
        if len(self._trail) > 1:
            pygame.draw.lines(canvas, style.TRAIL, False,
                              [tuple(p) for p in self.to_px(np.array(self._trail))], 2)
        if self.show_horizon:
            r = int(scene.horizon * self.scale)
            for x, y in pos[1:]:
                pygame.draw.circle(canvas, HORIZON, (int(x), int(y)), r, 1)
        touching = sorted(contact_pairs(positions, 2 * scene.robot_radius + CONTACT_TOLERANCE)
                          ) if len(pos) > 1 else []
        self._draw_people(canvas, scene)
        self._draw_robots(canvas, pos, scene.robot_radius, {k for p in touching for k in p},
                          person=scene.leader_radius is not None)
        if scene.headings is not None:
            self._draw_headings(canvas, positions, np.asarray(scene.headings, dtype=float),
                                scene.robot_radius)
        self._draw_arrows(canvas, positions[1:], scene.overlays)
        if self._background is None:  # the margins, over what was drawn beyond the view
            self._draw_margins(canvas)
        canvas.set_clip(None)
        self._draw_panel(canvas, scene, len(touching))
        if self.mode == "human":
            self._window.blit(canvas, (0, 0))
            pygame.event.pump()
            pygame.display.flip()
            self._clock.tick(self.fps)
            return None
        return np.ascontiguousarray(np.transpose(pygame.surfarray.array3d(canvas), (1, 0, 2)))

    # ----------------------------------------------------------------------------- arena
    def _update_camera(self, positions: npt.NDArray[np.float64], reset: bool) -> None:
        """Follows the flock lazily: the view stays put while the flock is near its middle,
        glides after it when it drifts off (or snaps, on the first frame), widens at once
        when a robot would leave it and narrows slowly; it moves in whole pixels, so a still
        frame is the same image (small GIFs)."""
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        target = (lo + hi) / 2
        need = max(MIN_VIEW, 0.6 * float(np.max(hi - lo)) + 0.5)
        if reset or self._camera_steps < 0:
            self.centre, self.view_half = target, need
            self._gliding = False
        else:
            off = float(np.max(np.abs(target - self.centre)))
            self._gliding = off > (0.02 if self._gliding else 0.2) * self.view_half
            if self._gliding:
                self.centre = self.centre + 0.15 * (target - self.centre)
            if need > self.view_half:
                self.view_half += 0.3 * (need - self.view_half)
            elif need < 0.75 * self.view_half:
                self.view_half += 0.05 * (need - self.view_half)
        reach = float(np.max(np.abs(positions - self.centre))) + 0.25
        self.view_half = min(max(self.view_half, reach), self.half + 0.5)
        # the view stays within 0.5 m of the scene's edges
        room = np.maximum(self.bounds[1] - self.middle + 0.5 - self.view_half, 0.0)
        self.scale = round((ARENA - 2 * MARGIN) / (2 * self.view_half), 1)
        centre = np.clip(self.centre, self.middle - room, self.middle + room)
        self.centre = np.round(centre * self.scale) / self.scale
        self._camera_steps = 0

    def _draw_background(self) -> Any:
        """The static part of the ``arena`` view: grid with labels, walls, panel."""
        surface = pygame.Surface((WIDTH, HEIGHT))
        self._draw_grid(surface)
        self._draw_margins(surface)
        return surface

    def _draw_margins(self, surface: Any) -> None:
        for rect in ((0, 0, ARENA, MARGIN), (0, HEIGHT - MARGIN, ARENA, MARGIN),
                     (0, 0, MARGIN, HEIGHT), (ARENA - MARGIN, 0, MARGIN, HEIGHT)):
            surface.fill(BACKGROUND, rect)
        self._draw_tick_labels(surface)

    def _ticks(self, axis: int) -> npt.NDArray[np.float64]:
        step = grid_step(self.view_half, self.scale)
        lo = max(float(self.bounds[0, axis]), float(self.centre[axis]) - self.view_half)
        hi = min(float(self.bounds[1, axis]), float(self.centre[axis]) + self.view_half)
        return np.arange(np.ceil(lo / step), np.floor(hi / step) + 1) * step

    def _draw_grid(self, surface: Any) -> None:
        surface.fill(OUTSIDE)
        pygame.draw.rect(surface, PANEL_BACKGROUND, (ARENA, 0, PANEL, HEIGHT))
        pygame.draw.line(surface, (205, 205, 200), (ARENA, 0), (ARENA, HEIGHT), 1)
        surface.set_clip(pygame.Rect(0, 0, ARENA - 1, HEIGHT))
        low, high = self.to_px(self.bounds[0]), self.to_px(self.bounds[1])
        surface.fill(BACKGROUND, (int(low[0]), int(high[1]), int(high[0] - low[0]),
                                  int(low[1] - high[1])))
        for t in self._ticks(0):
            x = int(self.to_px(np.array([t, 0.0]))[0])
            pygame.draw.line(surface, GRID, (x, int(high[1])), (x, int(low[1])), 1)
        for t in self._ticks(1):
            y = int(self.to_px(np.array([0.0, t]))[1])
            pygame.draw.line(surface, GRID, (int(low[0]), y), (int(high[0]), y), 1)
        self._draw_static(surface, self.to_px, self.scale)
        if self.static.box is not None:
            width, height = int(high[0] - low[0]), int(low[1] - high[1])
            pygame.draw.rect(surface, WALL, (int(low[0]), int(high[1]), width + 1, height + 1), 2)
        surface.set_clip(None)

    def _draw_static(self, surface: Any, to_px: Any, scale: float) -> None:
        """The scene's obstacles: a map's cells as an image, capsules as thick round-ended
        lines (pillars as discs), blocks as filled polygons."""
        scene = self.static
        grid = scene.grid
        if grid is not None and grid.origin[2] == 0.0:
            self._draw_cells(surface, to_px, scale)
        else:
            for a, b, r in zip(scene.a, scene.b, scene.radius, strict=True):
                pa, pb = to_px(a), to_px(b)
                width = max(1, round(2 * r * scale))
                if np.any(pa != pb):
                    pygame.draw.line(surface, OBSTACLE, tuple(pa), tuple(pb), width)
                for end in (pa, pb):
                    pygame.draw.circle(surface, OBSTACLE, tuple(end), max(1, round(r * scale)))
        for poly in scene.polygons:
            pygame.draw.polygon(surface, OBSTACLE, [tuple(p) for p in to_px(poly)])

    def _draw_cells(self, surface: Any, to_px: Any, scale: float) -> None:
        grid = self.static.grid
        assert grid is not None
        h, w = grid.cells.shape
        rgb = np.empty((w, h, 3), dtype=np.uint8)  # pygame arrays are (x, y)
        rgb[...] = BACKGROUND
        cells = grid.cells[::-1].T  # image rows from the top
        rgb[cells == 100] = OBSTACLE
        rgb[cells == -1] = UNKNOWN
        x0, y0, _ = grid.origin
        top_left = to_px(np.array([x0, y0 + h * grid.resolution]))
        size = (max(1, round(w * grid.resolution * scale)), max(1, round(h * grid.resolution
                                                                         * scale)))
        image = pygame.transform.scale(pygame.surfarray.make_surface(rgb), size)
        surface.blit(image, (int(top_left[0]), int(top_left[1])))

    @property
    def axis_caption(self) -> str:
        """What the grid's numbers are, drawn in the top margin (the last tick, which once
        carried the unit, is often outside the view)."""
        return f"x, y in m (world frame); grid {grid_step(self.view_half, self.scale):g} m"

    def _draw_tick_labels(self, surface: Any) -> None:
        """Grid values (m) in the margins: x along the bottom, y along the left, and what
        they are along the top."""
        font = self._fonts[16]
        xs, ys = self._ticks(0), self._ticks(1)
        for t in np.union1d(xs, ys):
            x, y = self.to_px(np.array([t, t]))
            if t not in xs:
                x = -1
            if t not in ys:
                y = -1
            label = font.render(f"{t:g}", True, GRID_LABEL)
            if MARGIN <= x <= ARENA - MARGIN:
                surface.blit(label, (int(x) - label.get_width() // 2, HEIGHT - MARGIN + 5))
            if MARGIN <= y <= HEIGHT - MARGIN:
                surface.blit(label, (MARGIN - label.get_width() - 4,
                                     int(y) - label.get_height() // 2))
        caption = font.render(self.axis_caption, True, GRID_LABEL)
        surface.blit(caption, (MARGIN, (MARGIN - caption.get_height()) // 2))

    def _update_trail(self, steps: int, leader: npt.NDArray[np.float64]) -> None:
        if steps < self._last_steps or steps == 0:
            self._trail = []
        if steps != self._last_steps:
            self._trail.append(np.array(leader, dtype=float))
            self._trail = self._trail[-self.trail_length:]
        self._last_steps = steps

    def _draw_people(self, canvas: Any, scene: Frame) -> None:
        """The crowd's pedestrians and a person leader (body at its true size, a ring for its
        personal space), under the robots."""
        if scene.pedestrians is not None and len(scene.pedestrians):
            r = max(2, round(scene.pedestrian_radius * self.scale))
            for x, y in self.to_px(np.asarray(scene.pedestrians, dtype=float)):
                pygame.draw.circle(canvas, style.PEDESTRIAN, (int(x), int(y)), r)
                pygame.draw.circle(canvas, darker(style.PEDESTRIAN), (int(x), int(y)), r, 1)
        if scene.leader_radius is not None:
            x, y = self.to_px(np.asarray(scene.positions, dtype=float)[:1])[0]
            centre = (int(x), int(y))
            ring = round(style.PERSONAL_SPACE_RADIUS * self.scale)
            pygame.draw.circle(canvas, style.PERSONAL_SPACE, centre, ring, 1)
            body = max(3, round(scene.leader_radius * self.scale))
            pygame.draw.circle(canvas, style.PERSON, centre, body)
            pygame.draw.circle(canvas, darker(style.PERSON), centre, body, 2)

    def _draw_robots(self, canvas: Any, pos: npt.NDArray[np.int64], robot_radius: float,
                     touching: set[int], *, person: bool = False) -> None:
        drawn = self.robot_radius_px(robot_radius, len(pos))
        true = robot_radius * self.scale
        for k in range(len(pos) - 1, 0 if person else -1, -1):  # the leader last, on top
            centre = (int(pos[k, 0]), int(pos[k, 1]))
            radius = drawn + 1 if k == 0 and drawn > true + 0.5 else drawn
            colour = style.LEADER if k == 0 else style.FOLLOWER
            pygame.draw.circle(canvas, colour, centre, radius)
            if true < radius - 1.5:  # the true size, as a dark core
                pygame.draw.circle(canvas, darker(colour), centre, max(1, round(true)))
            if k in touching:
                pygame.draw.circle(canvas, style.CONTACT, centre, radius + 2, 2)

    def _draw_headings(self, canvas: Any, positions: npt.NDArray[np.float64],
                       headings: npt.NDArray[np.float64], robot_radius: float) -> None:
        """A heading mark per robot: a line from its centre to its rim (as drawn)."""
        reach = self.robot_radius_px(robot_radius, len(positions)) / self.scale
        tips = positions + reach * np.stack([np.cos(headings), np.sin(headings)], axis=1)
        width = 2 if reach * self.scale >= 6 else 1
        for (x0, y0), (x1, y1) in zip(self.to_px(positions), self.to_px(tips), strict=True):
            pygame.draw.line(canvas, style.HEADING, (int(x0), int(y0)), (int(x1), int(y1)),
                             width)

    def _draw_arrows(self, canvas: Any, followers: npt.NDArray[np.float64],
                     overlays: dict[str, npt.NDArray[np.float64]]) -> None:
        for name, vectors in overlays.items():
            colour = style.RULE_COLOURS.get(name, style.OTHER_ARROW)
            vec = style.arrow_vectors(vectors, self.arrow_scale, self.arrow_max)
            start = self.to_px(followers)
            end = self.to_px(followers + vec)
            for a, b in zip(start, end, strict=True):
                draw_arrow(canvas, colour, a, b)

    # ----------------------------------------------------------------------------- panel
    def _draw_panel(self, canvas: Any, scene: Frame, touching: int) -> None:
        left, width = ARENA + 14, PANEL - 26
        y = 12
        y = self._text(canvas, "boids-env", (left, y), 26, TEXT) + 6
        status = re.sub(r"=\s+", "= ", scene.status.strip())  # "t =   4.5 s" is one item
        for item in [s for s in re.split(r"\s{3,}", status) if s]:
            y = self._text(canvas, item, (left, y), 21, TEXT)
        y = self._text(canvas, f"touching pairs {touching}", (left, y), 21,
                       TEXT if touching == 0 else (170, 60, 0)) + 10
        y = self._legend(canvas, scene, left, y) + 8
        if self.view == "follow":
            self._draw_map(canvas, np.asarray(scene.positions, dtype=float), left,
                           max(y, HEIGHT - 12 - width), width)
        for line in scene.hud_lines:
            for part in wrap_text(line, self._fonts[19], width):
                y = self._text(canvas, part, (left, y), 19, MUTED)
        if self.message and self.message_opacity > 0:
            lines = wrap_text(self.message, self._fonts[19], width)
            y = HEIGHT - 10 - 17 * len(lines)
            colour = blend(MESSAGE, PANEL_BACKGROUND, self.message_opacity)
            for part in lines:
                y = self._text(canvas, part, (left, y), 19, colour)

    def _draw_map(self, canvas: Any, positions: npt.NDArray[np.float64], left: int, top: int,
                  side: int) -> None:
        """The whole scene, small: its obstacles, the leader's trail, the robots and the
        zoomed view."""
        side = min(side, HEIGHT - 8 - top)
        k = (side - 2) / (2 * self.half)
        cx, cy = self.middle

        def to_map(points: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
            p = np.asarray(points, dtype=float)
            out = np.empty(p.shape, dtype=np.int64)
            out[..., 0] = np.rint(left + 1 + (p[..., 0] - cx + self.half) * k)
            out[..., 1] = np.rint(top + 1 + (self.half - p[..., 1] + cy) * k)
            return out

        def px(points: npt.NDArray[np.float64]) -> list[tuple[int, int]]:
            return [tuple(p) for p in to_map(np.atleast_2d(points)).tolist()]

        pygame.draw.rect(canvas, OUTSIDE, (left, top, side, side))
        (bx0, by0), (bx1, by1) = px(self.bounds)
        pygame.draw.rect(canvas, BACKGROUND, (bx0, by1, bx1 - bx0, by0 - by1))
        canvas.set_clip(pygame.Rect(left, top, side, side))
        self._draw_static(canvas, to_map, k)
        canvas.set_clip(None)
        pygame.draw.rect(canvas, WALL, (left, top, side, side), 1)
        if len(self._trail) > 1:
            pygame.draw.lines(canvas, style.TRAIL, False, px(np.array(self._trail)), 2)
        for i, centre in enumerate(px(positions)[::-1]):
            leader = i == len(positions) - 1
            pygame.draw.circle(canvas, style.LEADER if leader else style.FOLLOWER, centre,
                               3 if leader else 2)
        (x0, y0), (x1, y1) = px(np.array([self.centre - self.view_half,
                                          self.centre + self.view_half]))
        rect = pygame.Rect(x0, y1, x1 - x0, y0 - y1).clip(pygame.Rect(left, top, side, side))
        pygame.draw.rect(canvas, MUTED, rect, 1)
        self._text(canvas, "whole scene (box: view)", (left + 4, top + 3), 16, MUTED)

    def _legend(self, canvas: Any, scene: Frame, left: int, y: int) -> int:
        radius = self.robot_radius_px(scene.robot_radius, len(scene.positions))
        person = scene.leader_radius is not None
        rows: list[tuple[str, Any]] = [
            ("person (the leader)" if person else "leader (robot 0)",
             lambda c: pygame.draw.circle(canvas, style.PERSON if person else style.LEADER, c,
                                          7 if person else radius + 1)),
            ("follower", lambda c: pygame.draw.circle(canvas, style.FOLLOWER, c, radius)),
            ("touching a robot", lambda c: (
                pygame.draw.circle(canvas, style.FOLLOWER, c, radius),
                pygame.draw.circle(canvas, style.CONTACT, c, radius + 2, 2))),
            ("leader trail", lambda c: pygame.draw.line(canvas, style.TRAIL, (c[0] - 10, c[1]),
                                                        (c[0] + 10, c[1]), 2))]
        if person:
            rows.append(("personal space (1.2 m)", lambda c: pygame.draw.circle(
                canvas, style.PERSONAL_SPACE, c, 8, 1)))
        if scene.pedestrians is not None and len(scene.pedestrians):
            rows.append(("pedestrian", lambda c: pygame.draw.circle(canvas, style.PEDESTRIAN,
                                                                    c, 7)))
        for name in scene.overlays:
            colour = style.RULE_COLOURS.get(name, style.OTHER_ARROW)
            rows.append((style.RULE_LABELS.get(name, name), lambda c, colour=colour: draw_arrow(
                canvas, colour, np.array([c[0] - 11, c[1]]), np.array([c[0] + 11, c[1]]))))
        for label, icon in rows:
            icon((left + 11, y + 8))
            y = self._text(canvas, label, (left + 30, y), 19, TEXT)
        # 1 m scale bar at the arena's scale
        bar = round(self.scale)
        y += 8
        pygame.draw.line(canvas, TEXT, (left, y + 6), (left + bar, y + 6), 2)
        for x in (left, left + bar):
            pygame.draw.line(canvas, TEXT, (x, y + 1), (x, y + 11), 2)
        y = self._text(canvas, "1 m", (left + bar + 8, y), 19, TEXT) + 2
        true_mm = 1000 * scene.robot_radius
        if radius > scene.robot_radius * self.scale + 1:
            factor = radius / (scene.robot_radius * self.scale)
            note = (f"robots drawn {factor:.1f}x true size; dark core: true size "
                    f"(r {true_mm:.0f} mm)")
        else:
            note = f"robots at true size (r {true_mm:.0f} mm)"
        if scene.overlays:
            note += f"; arrows {self.arrow_scale:g} m per N, at most {self.arrow_max:g} m"
        for part in wrap_text(note, self._fonts[16], PANEL - 26):
            y = self._text(canvas, part, (left, y), 16, MUTED)
        return y

    def _text(self, canvas: Any, text: str, at: tuple[int, int], size: int,
              colour: tuple[int, int, int]) -> int:
        surface = self._fonts[size].render(text, True, colour)
        canvas.blit(surface, at)
        return at[1] + surface.get_height() + 1

    def close(self) -> None:
        if self._window is not None:
            pygame.display.quit()
            self._window = None
