"""The live window (``boids run --render human``): the flock at real time in a pygame window,
the leader driven by the arrow keys (``--path external``), and the Reynolds parameters tuned
from the keyboard while it runs, as the original did with its dynamic-reconfigure panel.

:class:`LiveControls` holds all the key handling as plain logic on key names (pygame's
``pygame.key.name``), so it is unit-tested without a display; :func:`run_live` is the loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.config import ReynoldsParams

TUNABLE = (("1", "separation_weight", 0.1), ("2", "cohesion_weight", 0.1),
           ("3", "alignment_weight", 0.1), ("4", "leader_weight", 0.1),
           ("5", "horizon", 0.05), ("6", "desired_separation", 0.05))
"""(key, Reynolds parameter, step) of what the keyboard tunes."""
MAX_HORIZON = 2.0
"""Sensing radius of the live env (m): the tuned horizon can grow up to it."""
ARROWS = {"up": (0.0, 1.0), "down": (0.0, -1.0), "left": (-1.0, 0.0), "right": (1.0, 0.0)}
HELP = ("arrows: drive leader (--path external)  1-6: pick  +/-: change  "
        "space: pause  f: fast  r: restart  q: quit")


@dataclass
class LiveControls:
    """Keyboard state of the live window: held arrows, the parameter being tuned, flags."""

    params: ReynoldsParams | None
    """The Reynolds parameters being tuned (None for a policy without them)."""
    leader_speed: float = 0.55
    selected: str = "separation_weight"
    paused: bool = False
    fast: bool = False
    quit: bool = False
    restart: bool = False
    message: str = ""
    held: set[str] = field(default_factory=set)

    def key_down(self, key: str) -> None:
        """Handles a key press (a pygame key name: ``up``, ``1``, ``+``, ``space`` …)."""
        key = key.lower()
        if key in ARROWS:
            self.held.add(key)
        elif key in ("q", "escape"):
            self.quit = True
        elif key == "space":
            self.paused = not self.paused
        elif key == "f":
            self.fast = not self.fast
        elif key == "r":
            self.restart = True
        elif key in {k for k, _, _ in TUNABLE}:
            self.selected = next(name for k, name, _ in TUNABLE if k == key)
        elif key in ("+", "=", "[+]", "up_plus"):
            self.adjust(+1)
        elif key in ("-", "[-]", "_"):
            self.adjust(-1)

    def key_up(self, key: str) -> None:
        self.held.discard(key.lower())

    def adjust(self, direction: int) -> None:
        """Changes the selected parameter by one step; invalid values are refused, shown in
        :attr:`message`, and leave the parameters unchanged."""
        if self.params is None:
            self.message = "this policy has no Reynolds parameters"
            return
        step = next(s for _, name, s in TUNABLE if name == self.selected)
        value = round(getattr(self.params, self.selected) + direction * step, 6)
        if self.selected == "horizon" and value > MAX_HORIZON:
            self.message = f"horizon must be <= {MAX_HORIZON} m (the live sensing radius)"
            return
        try:
            self.params = replace(self.params, **{self.selected: value})
        except ValueError as exc:
            self.message = str(exc)
            return
        self.message = f"{self.selected} = {value:g}"

    def leader_command(self) -> npt.NDArray[np.float64]:
        """The leader's velocity from the held arrow keys, at ``leader_speed``."""
        direction = np.sum([ARROWS[k] for k in self.held if k in ARROWS] or [(0.0, 0.0)],
                           axis=0)
        norm = float(np.hypot(*direction))
        return direction / norm * self.leader_speed if norm > 0 else np.zeros(2)

    def hud_lines(self) -> list[str]:
        """The on-screen text: the parameters (selected one marked) and the key help."""
        lines = []
        if self.params is not None:
            for key, name, _ in TUNABLE:
                mark = ">" if name == self.selected else " "
                lines.append(f"{mark}{key} {name} {getattr(self.params, name):.2f}")
        state = " ".join(s for s, on in (("PAUSED", self.paused), ("FAST", self.fast)) if on)
        if state:
            lines.append(state)
        if self.message:
            lines.append(self.message)
        lines.append(HELP)
        return lines


def run_live(policy_spec: str = "reynolds", *, preset: str = "paper", seed: int = 0,
             fast_factor: float = 4.0, env_fields: dict[str, Any] | None = None,
             leader_weight: float | None = None) -> tuple[LiveControls, dict[str, Any]]:
    """Opens the window and runs episodes until ``q``; returns the final controls (the tuned
    parameters) and the last episode's metrics (with the leader's final position)."""
    import pygame

    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for
    from boids_env.policies.registry import load_policy

    overrides = {} if leader_weight is None else {"leader_weight": leader_weight}
    policy = load_policy(policy_spec, preset=preset, **overrides)
    fields = dict(env_fields or {})
    if getattr(policy, "params", None) is not None:
        fields.setdefault("horizon", MAX_HORIZON)  # room to raise the tuned horizon
    env = BoidsEnv(render_mode="human", **env_fields_for(policy, fields))
    controls = LiveControls(getattr(policy, "params", None),
                            leader_speed=env.config.scenario.leader_speed)
    external = env.config.scenario.path == "external"
    obs, _ = env.reset(seed=seed)
    policy.reset(seed)
    env.render()
    renderer = env._renderer
    try:
        while not controls.quit:
            for event in pygame.event.get():
                if event.type == pygame.QUIT:
                    controls.quit = True
                elif event.type == pygame.KEYDOWN:
                    controls.key_down(pygame.key.name(event.key))
                elif event.type == pygame.KEYUP:
                    controls.key_up(pygame.key.name(event.key))
            if controls.quit:
                break
            if controls.params is not None:
                policy.params = controls.params  # type: ignore[attr-defined]
            renderer.fps = env.metadata["render_fps"] * (fast_factor if controls.fast else 1)
            env.hud_text = controls.hud_lines()
            if controls.restart or not env.agents:
                controls.restart = False
                obs, _ = env.reset(seed=seed)
                policy.reset(seed)
            if controls.paused:
                env.render()
                continue
            if external:
                env.set_leader_command(controls.leader_command())
            actions = policy.act(obs)
            env.overlays = getattr(policy, "forces", {}) or {}
            obs, *_ = env.step(actions)
    finally:
        metrics = env.episode_metrics()
        metrics["leader_position"] = env.snapshot().positions[0].tolist()
        env.close()
    return controls, metrics
