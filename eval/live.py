"""The live window (``boids run --render human``): the flock at real time in a pygame window,
the leader driven by the arrow keys (``--path external``), and the Reynolds parameters tuned
from the keyboard while it runs, as the original did with its dynamic-reconfigure panel.

:class:`LiveControls` holds all the key handling as plain logic on key names (pygame's
``pygame.key.name``), so it is unit-tested without a display; :func:`run_live` is the loop.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.policies.reynolds_params import TUNABLE, ReynoldsParams

KEYS = tuple((t.key, name, t.step) for name, t in TUNABLE.items() if t.key is not None)
"""(key, Reynolds parameter, step) of what the keyboard tunes (the tunables with a key)."""
MAX_HORIZON = 2.0
"""Sensing radius of the live env (m): the tuned horizon can grow up to it."""
ARROWS = {"up": (0.0, 1.0), "down": (0.0, -1.0), "left": (-1.0, 0.0), "right": (1.0, 0.0)}
HELP = ("arrows: drive the leader (--path external) · 1-6: pick · +/-: change · "
        "space: pause · f: fast · r: restart · q: quit")
MESSAGE_SECONDS = 3.0
"""How long a message stays fully visible (s) before it fades."""
FADE_SECONDS = 1.0
"""How long it takes to fade out (s)."""


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
    """The last message (a changed value, a refused one); it fades after a few seconds."""
    held: set[str] = field(default_factory=set)
    clock: Callable[[], float] = time.monotonic
    """Seconds, for the messages' age (tests pass their own)."""
    message_time: float = float("-inf")
    """When :attr:`message` was set (``clock`` seconds)."""

    def say(self, text: str) -> None:
        """Shows ``text`` as the message, from now."""
        self.message = text
        self.message_time = self.clock()

    def message_opacity(self) -> float:
        """1 while the message is fresh, then down to 0 over :data:`FADE_SECONDS`."""
        if not self.message:
            return 0.0
        age = self.clock() - self.message_time
        return float(min(1.0, max(0.0, 1.0 - (age - MESSAGE_SECONDS) / FADE_SECONDS)))

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
        elif key in {k for k, _, _ in KEYS}:
            self.selected = next(name for k, name, _ in KEYS if k == key)
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
            self.say("this policy has no Reynolds parameters")
            return
        step = next(s for _, name, s in KEYS if name == self.selected)
        value = round(getattr(self.params, self.selected) + direction * step, 6)
        if self.selected == "horizon" and value > MAX_HORIZON:
            self.say(f"horizon must be <= {MAX_HORIZON} m (the live sensing radius)")
            return
        try:
            self.params = replace(self.params, **{self.selected: value})
        except ValueError as exc:
            self.say(str(exc))
            return
        self.say(f"{self.selected} = {value:g}")

    def leader_command(self) -> npt.NDArray[np.float64]:
        """The leader's velocity from the held arrow keys, at ``leader_speed``."""
        direction = np.sum([ARROWS[k] for k in self.held if k in ARROWS] or [(0.0, 0.0)],
                           axis=0)
        norm = float(np.hypot(*direction))
        return direction / norm * self.leader_speed if norm > 0 else np.zeros(2)

    def hud_lines(self) -> list[str]:
        """The panel's text: the parameters (selected one marked), the state and the key help
        (the message is shown apart, fading: :meth:`message_opacity`)."""
        lines = []
        if self.params is not None:
            for key, name, _ in KEYS:
                mark = ">" if name == self.selected else " "
                lines.append(f"{mark}{key} {name} {getattr(self.params, name):.2f}")
        state = " ".join(s for s, on in (("PAUSED", self.paused), ("FAST", self.fast)) if on)
        if state:
            lines.append(state)
        lines.append(HELP)
        return lines


def run_live(policy_spec: str = "reynolds", *, preset: str = "paper", seed: int = 0,
             fast_factor: float = 4.0, env_fields: dict[str, Any] | None = None,
             leader_weight: float | None = None, trust_model: bool = False
             ) -> tuple[LiveControls, dict[str, Any]]:
    """Opens the window and runs episodes until ``q``; returns the final controls (the tuned
    parameters) and the last episode's metrics, the safety metrics included (with the
    leader's final position). Raises :class:`~boids_env.render.NoDisplayError` where there
    is no display. ``trust_model``: see :func:`~boids_env.policies.registry.load_policy`'s
    ``trust``."""
    from boids_env.checks import number
    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import bind_policy, env_fields_for, warn_outside_card
    from boids_env.policies.registry import load_policy, split_preset
    from boids_env.policies.reynolds_params import reynolds_params
    from boids_env.recording import Recorder
    from boids_env.render import require_display

    number("fast_factor", fast_factor, 0.0, 1000.0, lo_open=True, unit="times real time")
    require_display()  # the env's own human mode only warns; an unseen live window is refused
    overrides: dict[str, Any] = {} if leader_weight is None else {"leader_weight": leader_weight}
    name, chosen = split_preset(policy_spec, preset)
    if name == "reynolds":  # the rule radius is the controller's own here, tuned live within
        overrides["horizon"] = reynolds_params(chosen).horizon  # the wider sensing radius
    policy = load_policy(policy_spec, preset=preset, trust=trust_model, **overrides)
    fields = dict(env_fields or {})
    if getattr(policy, "params", None) is not None:
        fields.setdefault("horizon", MAX_HORIZON)  # room to raise the tuned horizon
    env = BoidsEnv(render_mode="human", **env_fields_for(policy, fields))
    external = env.config.scenario.path == "external"
    obs, _ = env.reset(seed=seed)
    bind_policy(policy, env)  # its layout and scene, the env's timing and top speed
    warn_outside_card(policy, {"": env.config}, name=policy_spec)  # one line, as boids run
    policy.reset(seed)
    # the bound parameters (the env's dt, start-up and top speed) are the ones tuned
    controls = LiveControls(getattr(policy, "params", None),
                            leader_speed=env.config.scenario.leader_speed)
    env.render()
    renderer = env._renderer
    recorder = Recorder()
    recorder.capture(env)
    try:
        while not controls.quit:
            _handle_events(controls)
            if controls.quit:
                break
            if controls.params is not None:
                policy.params = controls.params  # type: ignore[attr-defined]
            renderer.fps = env.metadata["render_fps"] * (fast_factor if controls.fast else 1)
            env.hud_text = controls.hud_lines()
            renderer.message, renderer.message_opacity = (controls.message,
                                                          controls.message_opacity())
            if controls.restart or not env.agents:
                controls.restart = False
                obs, _ = env.reset(seed=seed)
                policy.reset(seed)
                recorder = Recorder()
                recorder.capture(env)
            if controls.paused:
                env.render()
                continue
            if external:
                env.set_leader_command(controls.leader_command())
            actions = policy.act(obs)
            env.overlays = getattr(policy, "forces", {}) or {}
            obs, *_ = env.step(actions)
            recorder.capture(env)
    finally:
        metrics = env.episode_metrics()
        if metrics.get("steps", 0):
            metrics = recorder.recording(env, seed=seed).metrics()
        metrics["leader_position"] = env.snapshot().positions[0].tolist()
        env.close()
    return controls, metrics


def _handle_events(controls: LiveControls) -> None:
    """Passes the window's pending key events (and its close button) to ``controls``."""
    import pygame

    for event in pygame.event.get():
        if event.type == pygame.QUIT:
            controls.quit = True
        elif event.type == pygame.KEYDOWN:
            controls.key_down(pygame.key.name(event.key))
        elif event.type == pygame.KEYUP:
            controls.key_up(pygame.key.name(event.key))
