"""A policy's actions as the robots' commands, once: what the env does to the followers'
actions before the physics (:class:`~boids_env.environment.BoidsEnv`) and what the
controller node does to them before ``cmd_vel``
(:class:`~boids_env.eval.graph.controller.ControllerCore`).

Two steps, because the env does its own work between them (the crowd's walk, the leader's
command) and must refuse a NaN or inf before any of it: :func:`commands_from_actions` (the
robot's limits in the action's frame, then the start-up hold) and :func:`safe_commands` (the
opt-in safety filter against the robots, the scene and the people around).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from boids_env import kernels
from boids_env.config import EnvConfig
from boids_env.vectors import clip_speed_reference
from boids_env.world.safety import filter_commands, people_around
from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]


def native_actions(config: EnvConfig) -> bool:
    """Whether the actions are the robots' own (v, ω) (``action="unicycle"``) rather than
    velocities in the observation frame."""
    return config.observation.action == "unicycle"


def filtered(config: EnvConfig) -> bool:
    """Whether the safety filter acts on the commands of ``config``: ``safety_filter`` on, for
    velocity actions (native (v, ω) actions are never filtered)."""
    return config.safety.safety_filter and not native_actions(config)


def commands_from_actions(actions: FloatArray, config: EnvConfig,
                          to_world: Callable[[FloatArray], FloatArray], *, hold: bool,
                          limit: bool = True,
                          check: Callable[[FloatArray], None] | None = None) -> FloatArray:
    """The followers' commands (F, 2) from their actions (F, 2, float64).

    Native (v, ω) actions are clipped to the robot's top speed and turn rate; velocity
    actions are turned into the world frame by ``to_world`` and speed limited to
    ``max_speed`` (unless ``limit`` is False: a controller node of holonomic robots leaves
    the limit to the robot, or the simulator, which applies it once, as the env does).
    While ``hold`` (the start-up hold) every command is zero.

    Args:
        actions: the followers' actions, float64.
        config: the env config (the world's limits, the action space).
        to_world: the observation frame's actions in the world frame
            (:meth:`Observer.to_world <boids_env.observations.Observer.to_world>`).
        hold: the followers are held still.
        limit: speed limit the world-frame commands.
        check: called with ``actions`` wherever they may hold a NaN or inf (before the clip;
            where the speed limit's kernel met a speed that is not finite): the env's raises.
            None: such values pass on (a controller node sends those rows as a stop).
    """
    w = config.world
    if native_actions(config):
        if check is not None:
            check(actions)
        high = np.array([w.max_speed, w.max_turn_rate], dtype=np.float64)
        commands = np.clip(actions, -high, high)  # float64 limits, not the Box's float32
    else:
        commands = to_world(actions)
        if limit:
            commands = _speed_limited(commands, actions, w.max_speed, check)
    return np.zeros_like(commands) if hold else commands


def _speed_limited(commands: FloatArray, actions: FloatArray, max_speed: float,
                   check: Callable[[FloatArray], None] | None) -> FloatArray:
    """``commands`` speed limited: the kernel sees every speed, so the finite commands of a
    step cost no check of their own; ``check`` runs only where it met one that is not."""
    compiled = kernels.compiled()
    if compiled is not None and commands.flags.c_contiguous:
        status, out = compiled.clip_speed(commands, float(max_speed))
        if status != 2:  # 2: a speed that is not finite, from a NaN, inf or overflow
            return out
    if check is not None:
        check(actions)
    return clip_speed_reference(commands, max_speed)


def safe_commands(commands: FloatArray, config: EnvConfig, scene: Scene, positions: FloatArray,
                  velocities: FloatArray, leader_velocity: FloatArray,
                  pedestrians: FloatArray | None = None,
                  pedestrian_velocities: FloatArray | None = None) -> FloatArray:
    """The world-frame commands (F, 2) through the safety filter where ``config`` asks for
    it (:func:`filtered`; else unchanged), for the robots at ``positions`` moving at
    ``velocities`` (N, 2, the leader first) in ``scene``, the leader moving at
    ``leader_velocity`` (2,) and the crowd's pedestrians (P, 2) at theirs: a person
    leading and the pedestrians are kept off at their own width."""
    if not filtered(config):
        return commands
    w, sc = config.world, config.scenario
    people = people_around(positions[0], leader_velocity, pedestrians, pedestrian_velocities,
                           sc.person_radius, sc.leader_radius is not None)
    return filter_commands(commands, positions, velocities, leader_velocity, w.robot_radius,
                           w.max_speed, scene, config.safety, people)
