"""The live state of one episode of :class:`~boids_env.environment.BoidsEnv`, as one typed
record: what a reset builds aside (the options' :func:`episode_config`, then
:meth:`Episode.start`) and swaps in whole, so that a refused reset leaves the env's record as
it was; what each step reads and writes; and what pickling keeps (the world is rebuilt and
its commands replayed)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from boids_env.config import fastest_speed
from boids_env.observations import Observer
from boids_env.rewards import Rewards
from boids_env.world import scenario
from boids_env.world.leader import make_leader, preview_path, redraw_clear
from boids_env.world.person import make_person
from boids_env.world.realism import Realism
from boids_env.world.scenario import ScenarioConfig
from boids_env.world.space import World

if TYPE_CHECKING:
    from boids_env.config import EnvConfig
    from boids_env.world.crowd_replay import ReplayedCrowd
    from boids_env.world.leader import Leader
    from boids_env.world.people import People
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

RESET_OPTIONS = (*(f.name for f in fields(ScenarioConfig)
                   if f.name not in ("robots", "crowd", "crowd_file")), "obs_noise")
"""Fields that ``reset(options=...)`` may change for one episode: the scenario's (not
``robots``, which fixes the agents, nor ``crowd`` and ``crowd_file``, which fix the
observations' pedestrian slots) and the sensing noise."""


def episode_config(config: EnvConfig, options: Mapping[str, Any] | None) -> EnvConfig:
    """The config of an episode that ``reset(options=...)`` asks of an env of ``config``
    (:data:`RESET_OPTIONS` changed, others ignored with a warning; ``robots`` refused)."""
    if options is None:
        return config
    if not isinstance(options, Mapping):
        raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
    if "robots" in options:
        raise ValueError("options cannot change robots (the group size fixes "
                         "possible_agents); make a new env with robots=...")
    unknown = sorted(k for k in options if k not in RESET_OPTIONS)
    if unknown:
        warnings.warn(f"reset ignores unknown option(s) {unknown}; it accepts "
                      f"{list(RESET_OPTIONS)}", UserWarning, stacklevel=3)
    known = {k: v for k, v in options.items() if k in RESET_OPTIONS}
    return config.replace(**known) if known else config


@dataclass(eq=False)
class Episode:
    """One episode's parts (:attr:`BoidsEnv.episode <boids_env.environment.BoidsEnv.episode>`).

    The env's batch and fused paths (:mod:`boids_env.batch`, :mod:`boids_env.fused`) read it;
    anything else should read the env's own queries (``snapshot``, ``episode_metrics``,
    ``leader``, ``crowd``) and leave the record to the env.
    """

    config: EnvConfig
    """The episode's config (the env's ``episode_config``)."""
    leader: Leader
    """The leader (robot 0's path, a person, an external command)."""
    people: People | ReplayedCrowd | None
    """The pedestrian simulation (a walking person, a crowd) or a replayed crowd, or None."""
    scene: Scene
    """The episode's static geometry."""
    world: World
    """The physics; rebuilt and replayed from :attr:`history` on unpickling."""
    observer: Observer
    """The followers' sensing (its frame, noise stream, the leader velocity it last saw)."""
    realism: Realism | None
    """Latency, dropped commands and stale observations, or None when off."""
    rewards: Rewards
    """The reward terms' scales, the violation counts and the info dicts."""
    initial_positions: FloatArray
    """(N, 2) the robots' start (the world is rebuilt from it on unpickling)."""
    initial_headings: FloatArray | None
    """(N,) the start headings of robots with one, else None."""
    step_limit: int
    """The step at which the episode is truncated whatever the leader does."""
    tail_steps: int
    """Steps the episode goes on after the leader finishes its path."""
    finish_step: int | None = None
    """The step at which the leader finished, once it has."""
    history: list[tuple[Any, Any, Any, Any]] = field(default_factory=list)
    """(commanded, executed, crowd, native) of every step, replayed on unpickling."""

    @classmethod
    def start(cls, config: EnvConfig, rng: np.random.Generator, seed: int | None) -> Episode:
        """A new episode of ``config``, drawn from ``rng`` (``seed``: the reset's, which the
        stale observations' stream takes); raises where the episode is refused (a path
        that never clears the scene, no room for the crowd, ...)."""
        sc, wc = config.scenario, config.world
        scene = config.scene
        initial = scenario.initial_positions(
            sc, rng, scenario.layout_heading(sc, wc.scene, preview_path(sc, wc.dt)))
        leader = make_leader(sc, rng, wc.dt)
        if sc.path == "random_waypoints" and not scene.is_empty_box:
            leader = redraw_clear(sc, scene, wc.robot_radius, leader, rng, wc.dt)
        # the person and the crowd draw from the stream only when asked for: defaults unchanged
        leader, people = make_person(sc, scene, leader, initial, rng, wc.dt, wc.robot_radius)
        headings = (np.full(sc.robots, leader.initial_heading)
                    if wc.has_heading else None)
        observer = Observer(config)
        world = build_world(config, initial, headings, people)
        observer.reset(rng, leader.initial_heading)
        realism = None
        if config.realism.active:  # its own stream, drawn only when on: defaults unchanged
            realism_rng = np.random.default_rng(rng.integers(2**63))
            # stale observations draw from a stream of the episode seed alone (a ROS
            # controller node draws the same); without a seed, from the env's stream
            stale_seed = 0
            if config.realism.resolved()["stale_observations"] > 0:
                stale_seed = int(seed) if seed is not None else int(rng.integers(2**63))
            realism = Realism(config.realism, sc.robots, wc.dt, sc.startup_time,
                              wc.robot_radius, wc.max_speed, realism_rng, stale_seed)
        return cls(config, leader, people, scene, world, observer, realism,
                   Rewards(config, sc.robots - 1), initial, headings,
                   scenario.step_limit(sc, leader.nominal_duration, wc.dt),
                   round(sc.tail_time / wc.dt))

    def __getstate__(self) -> dict[str, Any]:
        # pymunk cannot serialise its contact cache, so a copied space diverges after a
        # contact: the world stays behind and __setstate__ rebuilds it
        return {name: value for name, value in self.__dict__.items() if name != "world"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        # the world from the start with every step's commands replayed: bit-exact, the
        # physics being deterministic
        self.world = build_world(self.config, self.initial_positions, self.initial_headings,
                                 self.people)
        for command, executed, crowd, native in self.history:
            self.world.step(command, executed, crowd, native=native)


def build_world(config: EnvConfig, initial: FloatArray, headings: FloatArray | None,
                people: People | ReplayedCrowd | None) -> World:
    """An episode's world at its start: a person leader and the crowd as kinematic bodies
    when the scenario has them (a replayed crowd's placements made by the world)."""
    from boids_env.world.crowd_replay import ReplayedCrowd

    sc = config.scenario
    return World(config.world, initial, config.scene, headings,
                 leader_radius=sc.leader_radius,
                 pedestrians=None if people is None else people.start_pedestrians,
                 pedestrian_radius=sc.person_radius,
                 leader_kinematic=sc.leader_kind.kinematic(sc),
                 people_speed=fastest_speed(config)[0],
                 stage=people if isinstance(people, ReplayedCrowd) else None)
