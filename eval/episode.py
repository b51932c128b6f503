"""One episode of a policy in the env, with optional recording and video frames."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.config import ObservationConfig
from boids_env.environment import BoidsEnv
from boids_env.policies.base import Policy
from boids_env.recording import Recorder, Recording


@dataclass
class EpisodeResult:
    """What one episode produced."""

    metrics: dict[str, Any]
    """V_*, per-follower counts and the extra flock metrics (see boids_env.metrics)."""
    recording: Recording | None
    frames: list[npt.NDArray[np.uint8]] = field(default_factory=list)
    wall_time: float = 0.0
    """Seconds the episode took (stepping, policy and recording; not the video encoding)."""
    reward_total: float = 0.0
    """The env's rewards summed over followers and steps (its configured reward)."""


def env_fields_for(policy: Policy, fields: dict[str, Any] | None = None) -> dict[str, Any]:
    """Env config fields for running ``policy``: those its observations need (a trained model's
    ``env_fields``, e.g. its number of neighbour slots), then ``fields``; for a policy with
    Reynolds parameters the sensing horizon covers its neighbour radius unless given."""
    out = {**getattr(policy, "env_fields", {}), **(fields or {})}
    params = getattr(policy, "params", None)
    if params is not None and "horizon" not in out:
        out["horizon"] = max(params.horizon, ObservationConfig().horizon)
    return out


def bind_policy(policy: Policy, env: BoidsEnv) -> None:
    """Tells a policy that reads the env's layout (``bind``, e.g. the Reynolds policy: static
    slots, range sensing, obstacle avoidance in scenes) which env it acts in."""
    saved = getattr(policy, "observation_layout", None)
    if saved is not None and saved != env.layout:
        raise ValueError(f"the policy reads observations laid out as {list(saved.blocks)}, the "
                         f"env gives {list(env.layout.blocks)}: make the env with the policy's "
                         f"env_fields {getattr(policy, 'env_fields', {})}")
    bind = getattr(policy, "bind", None)
    if callable(bind):
        bind(env)


def run_episode(env: BoidsEnv, policy: Policy, seed: int | None = None, *,
                options: dict[str, Any] | None = None, record: bool = True,
                frame_every: int = 0,
                on_step: Callable[[BoidsEnv, int], None] | None = None) -> EpisodeResult:
    """Runs ``policy`` for one whole episode of ``env``.

    Args:
        env: the environment (``render_mode="rgb_array"`` if frames are wanted).
        policy: any Policy; if it exposes ``forces`` (the Reynolds policy does), they are drawn.
        seed: episode seed, passed to both ``env.reset`` and ``policy.reset``.
        options: reset options (scenario fields for this episode).
        record: keep the trajectory (needed for the extra flock metrics).
        frame_every: keep a rendered frame every this many steps (0: none).
        on_step: called with the env and the step count after the reset (0) and after every
            step (a live view); it must not change the env.
    """
    start = time.perf_counter()
    obs, _ = env.reset(seed=seed, options=options)
    bind_policy(policy, env)
    policy.reset(seed)
    recorder = Recorder() if record else None
    frames: list[npt.NDArray[np.uint8]] = []
    if recorder:
        recorder.capture(env)
    if on_step is not None:
        on_step(env, 0)
    step = 0
    reward_total = 0.0
    while env.agents:
        actions = policy.act(obs)
        forces = getattr(policy, "forces", None)
        if forces:
            env.overlays = forces
        if frame_every and step % frame_every == 0:
            frames.append(env.render())
        obs, rewards, *_ = env.step(actions)
        reward_total += sum(rewards.values())
        step += 1
        if recorder:
            recorder.capture(env)
        if on_step is not None:
            on_step(env, step)
    if frame_every:
        frames.append(env.render())
    recording = recorder.recording(env, seed=seed) if recorder else None
    metrics = recording.metrics() if recording else env.episode_metrics()
    return EpisodeResult(metrics, recording, frames, time.perf_counter() - start, reward_total)
