"""The controller node's logic, transport-free: any policy answering ticks of odometry with
the followers' commands, as the study's ``reynolds_controller`` node.

Each follower's observation is built with :class:`~boids_env.observations.Observer` (the
env's own builder, with the env's config: the same observations as in-process). Robots with a
heading (e.g. a TurtleBot3) read REP 105 odometry (oriented, the twist in the robot's frame)
and are answered with their own (linear.x, angular.z) from their driver's law, as a real
TurtleBot3 takes it. ``boids ros controller`` (ROS 1) and ``boids ros2 controller`` (ROS 2
over Zenoh) are this class under two transports (:class:`ControllerTransport`): they
subscribe to the odometry (:meth:`ControllerCore.odometry`) and publish the answers, and
:meth:`ControllerCore.spin` runs the loop.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from boids_env.commands import commands_from_actions, filtered, native_actions, safe_commands
from boids_env.config import EnvConfig
from boids_env.eval.episode import bind_policy, env_fields_for
from boids_env.eval.graph.protocol import (
    EpisodeInfo,
    Tick,
    TickAssembler,
    finite_commands,
    is_continuation,
)
from boids_env.observations import INITIAL_HEADING, Crowd, Observer
from boids_env.policies.base import Policy
from boids_env.policies.registry import load_policy, split_preset
from boids_env.world.realism import StaleObservations
from boids_env.world.robots import make_model, quaternion_headings, to_world
from boids_env.world.scenario import holding

SYNC_MODES = ("stamp", "rate")


@dataclass(frozen=True)
class ControllerOptions:
    """How the controller node runs."""

    policy: str = "reynolds"
    """A policy spec of :func:`~boids_env.policies.registry.load_policy`."""
    preset: str = "paper"
    """Reynolds parameter preset (unless ``policy`` names one)."""
    leader_weight: float | None = None
    """Reynolds leader weight override."""
    env_fields: Mapping[str, Any] = field(default_factory=dict)
    """Env config fields (``robots`` …) of the odometry source. Empty: the simulator's config
    (announced on the graph), waited for up to ``config_wait`` seconds."""
    sync: str = "stamp"
    """``stamp``: answer a tick once every robot's odometry with that stamp arrived (each
    tick exactly once, in order: what lockstep relies on); ``rate``: every ``dt`` of wall
    time from each robot's latest odometry (robots not stamped together)."""
    seed: int = 0
    """Seed for ``policy.reset`` when the simulator announces no episode."""
    config_wait: float = 30.0
    """Seconds to wait for the simulator's config."""
    max_ticks: int | None = None
    """Stop after answering this many ticks (None: run until shut down)."""
    idle_exit: float = 30.0
    """Exit once no tick has come for this many seconds after the first (the simulator
    ended, or every robot's odometry stopped); 0: run until shut down."""
    markers: bool = True
    """Publish the rule-force markers when the policy has forces."""
    quiet: bool = False
    node_name: str = "reynolds_controller"
    trust_model: bool = False
    """A model zip may load through SB3's own load, which runs code stored in the file."""

    def __post_init__(self) -> None:
        if self.sync not in SYNC_MODES:
            raise ValueError(f"sync must be one of {SYNC_MODES}, got {self.sync!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not (isinstance(self.config_wait, int | float) and 0 <= self.config_wait <= 3600):
            raise ValueError(f"config_wait must be in [0, 3600] s, got {self.config_wait!r}")
        if self.max_ticks is not None and (isinstance(self.max_ticks, bool) or not isinstance(
                self.max_ticks, int) or self.max_ticks < 1):
            raise ValueError(f"max_ticks must be a positive integer or None, got "
                             f"{self.max_ticks!r}")
        if isinstance(self.idle_exit, bool) or not (
                isinstance(self.idle_exit, int | float) and 0 <= self.idle_exit <= 86400):
            raise ValueError(f"idle_exit must be in [0, 86400] s (0: never), got "
                             f"{self.idle_exit!r}")
        if not isinstance(self.trust_model, bool):
            raise TypeError(f"trust_model must be True or False, got {self.trust_model!r}")
        split_preset(self.policy, self.preset)  # a bad spec or preset fails before ROS starts


class ControllerTransport(Protocol):
    """What a middleware provides to :meth:`ControllerCore.spin`."""

    def stopped(self) -> bool:
        """Whether the node is shutting down."""

    def answer(self, tick: Tick) -> Any:
        """Publishes the followers' commands for one tick (:meth:`ControllerCore.answer`'s),
        and whatever goes with them (the force markers)."""


def base_config(options: ControllerOptions, name: str, read: Callable[[], str | None],
                stopped: Callable[[], bool], *, source: str, command: str, poll: float,
                where: str = "") -> EnvConfig:
    """The odometry source's env config: ``options.env_fields``, else the simulator's, its
    JSON as ``read`` returns it (None until it is there), waited for up to
    ``options.config_wait`` seconds in steps of ``poll``.

    Args:
        options: how the node runs.
        name: the node's name, for messages.
        read: the simulator's config JSON, or None while there is none.
        stopped: whether the node is shutting down (stops the wait).
        source: what holds the config (``/boids/env_config parameter``), for messages.
        command: the simulator's command (``boids ros sim``), for messages.
        poll: seconds between two reads.
        where: said after the wait in the error (the network looked at).

    Raises:
        ValueError: no config within ``config_wait`` seconds.
    """
    if options.env_fields:
        return EnvConfig().replace(**dict(options.env_fields))
    waited, announced = 0.0, False
    while True:
        text = read()
        if text is not None:
            return EnvConfig.from_dict(json.loads(text))
        if waited >= options.config_wait or stopped():
            raise ValueError(f"no {source} after {options.config_wait:g} s{where}: start "
                             f"{command} first, or give the robots of another odometry "
                             f"source (--robots N)")
        if not announced and not options.quiet:
            print(f"{name}: waiting for {source} ({command})", flush=True)
            announced = True
        time.sleep(poll)
        waited += poll


def controller_policy(options: ControllerOptions) -> Policy:
    """The policy the node runs (loaded before the node touches a middleware)."""
    overrides = {} if options.leader_weight is None else {
        "leader_weight": options.leader_weight}
    spec, preset = split_preset(options.policy, options.preset)
    return load_policy(spec, preset=preset, trust=options.trust_model, **overrides)


class ControllerCore:
    """A policy answering ticks: :meth:`answer` turns one tick of odometry into every
    follower's command, resetting the policy at each new episode.

    Args:
        options: how to run.
        policy: the loaded policy (:func:`controller_policy`).
        base: the odometry source's env config (the simulator's).
        name: the node's name, for messages.
        episode: given the stamp (ns) of a tick that does not continue the last one, returns
            the episode the simulator announced last (or None).
    """

    def __init__(self, options: ControllerOptions, policy: Policy, base: EnvConfig,
                 name: str, episode: Callable[[int], EpisodeInfo | None]) -> None:
        self.options = options
        self.policy = policy
        self.name = name
        self._episode_info = episode
        self.config = base.replace(**env_fields_for(policy, {}))
        self.observer = Observer(self.config)
        self.layout = self.observer.layout
        bind_policy(policy, self)  # the layout, the scene, the robots' top speed: as an env
        self.model = make_model(self.config.world)
        """The robots' model: for robots with a heading, the driver's law the env applies
        in-process is applied here, and (v, ω) goes out on cmd_vel."""
        self.stale: StaleObservations | None = None
        self.robots = self.config.scenario.robots
        self.pedestrians = self.config.scenario.crowd
        """The crowd's size: each tick waits for every pedestrian's odometry too."""
        self.dt = self.config.world.dt
        self.agents = [f"follower_{i}" for i in range(1, self.robots)]
        self.episode: EpisodeInfo | None = None
        self._episode_start: int | None = None
        self._last_stamp: int | None = None
        self.answered = 0
        self.nonfinite = 0
        """Commands sent as a stop because they were not finite (non-finite odometry)."""
        self.assembler = TickAssembler(self.robots, self.pedestrians)
        """The odometry's ticks: the robots', then the crowd's pedestrians' sources."""
        self.ticks: queue.Queue[Tick] = queue.Queue()
        """Complete ticks not answered yet (``sync="stamp"``)."""

    def odometry(self, source: int, stamp: int, x: float, y: float, vx: float, vy: float,
                 qz: float = 0.0, qw: float = 1.0) -> None:
        """Takes one odometry message (any thread): robot ``source``'s, or pedestrian
        ``source - robots``'s; with ``sync="stamp"`` a tick it completes is queued for
        :meth:`spin`."""
        tick = self.assembler.add(source, stamp, x, y, vx, vy, qz, qw)
        if tick is not None and self.options.sync == "stamp":
            self.ticks.put(tick)

    def spin(self, transport: ControllerTransport) -> int:
        """Answers ticks through ``transport`` until it stops or ``max_ticks`` are answered;
        returns how many were. ``sync="stamp"``: each complete tick once, in order;
        ``"rate"``: every ``dt`` of wall time, the latest odometry of every robot."""
        limit, idle = self.options.max_ticks, self.options.idle_exit
        deadline = answered_at = time.monotonic()
        last: int | None = None
        while not transport.stopped() and (limit is None or self.answered < limit):
            if idle and self.answered and time.monotonic() - answered_at > idle:
                if not self.options.quiet:
                    print(f"controller: no tick for {idle:g} s (the simulator ended or the "
                          f"odometry stopped); exiting after {self.answered} ticks", flush=True)
                break
            if self.options.sync == "stamp":
                try:
                    tick = self.ticks.get(timeout=0.1)
                except queue.Empty:
                    continue
            else:
                deadline += self.dt
                time.sleep(max(0.0, deadline - time.monotonic()))
                snap = self.assembler.snapshot()
                if snap is None or snap.stamp_ns == last:
                    continue
                tick, last = snap, snap.stamp_ns
            transport.answer(tick)
            answered_at = time.monotonic()
        return self.answered

    @property
    def leader_hidden(self) -> npt.NDArray[np.bool_] | None:
        """Which followers did not see the leader at the last tick (``route_leader``; as
        :attr:`BoidsEnv.leader_hidden <boids_env.environment.BoidsEnv.leader_hidden>`)."""
        return self.observer.leader_hidden

    @property
    def heading(self) -> bool:
        """Whether the robots have a heading (commands are (v, ω) in their own frame)."""
        return bool(self.model.has_heading)

    def maybe_reset(self, stamp: int) -> None:
        """Resets the policy (and the observer) at the first tick of every episode."""
        if is_continuation(self._last_stamp, stamp, self.dt):
            return
        info = self._episode_info(stamp)
        if self._last_stamp is None:
            fresh = True
        elif info is not None:
            fresh = self.episode is None or info.index != self.episode.index
        else:
            fresh = stamp < self._last_stamp  # the source's clock restarted
        if not fresh:
            return
        if info is not None and info.start_ns > stamp:
            info = None  # announced for a later tick: not this episode's
        self.episode = info
        self._episode_start = info.start_ns if info is not None else stamp
        seed = info.seed if info is not None else self.options.seed
        self.policy.reset(seed)
        self.observer.reset(np.random.default_rng(seed),
                            info.initial_heading if info is not None else INITIAL_HEADING)
        p = self.config.realism.resolved()["stale_observations"]
        self.stale = StaleObservations(p, seed) if p > 0 else None  # as the env draws them
        if not self.options.quiet:
            which = f"episode {info.index}, seed {seed}" if info else f"seed {seed}"
            print(f"{self.name}: new episode ({which}) at stamp {stamp / 1e9:.1f} s",
                  flush=True)

    def _holding(self, stamp: int) -> bool:
        """Whether the followers are held still at ``stamp``: the first ``startup_time``
        seconds of an episode when the config (a learned model's env fields) asks for
        ``startup_hold``, as the env holds them in-process."""
        sc = self.config.scenario
        if not sc.startup_hold or self._episode_start is None:
            return False
        return holding((stamp - self._episode_start) / 1e9, sc.startup_time)

    def answer(self, tick: Tick) -> np.ndarray:
        """The commands (F, 2) for one tick: world-frame (vx, vy), or (v, ω) for robots
        with a heading."""
        self.maybe_reset(tick.stamp_ns)
        self._last_stamp = tick.stamp_ns
        velocities, headings = tick.velocities, None
        if self.heading:  # REP 105 odometry, read back as the env observes it
            assert tick.quaternions is not None
            headings = quaternion_headings(tick.quaternions[:, 0], tick.quaternions[:, 1])
            velocities = to_world(velocities, headings)
        crowd = None
        if tick.crowd_positions is not None and tick.crowd_velocities is not None:
            crowd = Crowd(tick.crowd_positions, tick.crowd_velocities)
        obs = self.observer(tick.positions, velocities, crowd, headings)
        if self.stale is not None:
            obs = self.stale(obs, self.observer)  # its sight flags stale with their rows
        actions = self.policy.act(dict(zip(self.agents, obs, strict=True)))
        raw = np.array([actions[a] for a in self.agents], dtype=np.float64)
        cfg = self.config
        # As the env turns actions into commands (boids_env.commands). Holonomic robots
        # without the filter get no speed limit here: the robot, or the simulator, limits
        # the speed once, as the env does; the filter and a driver's law need it first.
        commands = commands_from_actions(raw, cfg, self.observer.to_world,
                                         hold=self._holding(tick.stamp_ns),
                                         limit=headings is not None or filtered(cfg))
        # The leader's odometry velocity stands for the leader's command, which the
        # in-process env knows and a controller node does not; the people are kept off at
        # their odometry velocities (the env uses their commands).
        commands = safe_commands(commands, cfg, cfg.scene, tick.positions, velocities,
                                 velocities[0], tick.crowd_positions, tick.crowd_velocities)
        if headings is not None and not native_actions(cfg):
            commands = self.model.native(commands, headings[1:])  # the robot driver's law
        # a non-finite odometry poisons its neighbours' commands: they go out as a stop
        commands, bad = finite_commands(commands)
        self.nonfinite += bad
        self.answered += 1
        return commands

    def world_forces(self) -> dict[str, np.ndarray]:
        """The policy's rule forces of the last answer in the world frame (empty for a policy
        without them), for the markers."""
        forces = getattr(self.policy, "forces", None) or {}
        return {rule: self.observer.to_world(np.asarray(f, dtype=np.float64))
                for rule, f in forces.items()}

    @staticmethod
    def twist_fields(command: np.ndarray, heading: bool) -> tuple[float, float, float]:
        """One command as ``cmd_vel``'s (linear.x, linear.y, angular.z)."""
        a, b = float(command[0]), float(command[1])
        return (a, 0.0, b) if heading else (a, b, 0.0)
