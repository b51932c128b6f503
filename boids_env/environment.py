"""``BoidsEnv``: the leader-following flock of the study as a PettingZoo ``ParallelEnv``."""

from __future__ import annotations

import copy
import warnings
from collections.abc import Mapping
from dataclasses import fields
from operator import attrgetter
from typing import Any, ClassVar, NamedTuple

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from boids_env import kernels, metrics, proxemics
from boids_env.commands import commands_from_actions, native_actions, safe_commands
from boids_env.config import EnvConfig
from boids_env.fused import Fused
from boids_env.observations import Crowd, Observer
from boids_env.vectors import as_velocities
from boids_env.world import scenario
from boids_env.world.leader import ExternalLeader, Leader, make_leader, preview_path, redraw_clear
from boids_env.world.person import make_person
from boids_env.world.realism import Realism
from boids_env.world.robots import RobotModel, odometry_velocities
from boids_env.world.scenario import ScenarioConfig
from boids_env.world.space import Snapshot, World

AgentID = str


class ArrayStep(NamedTuple):
    """What :meth:`BoidsEnv.step_arrays` returns, one row (or column) per follower."""

    observations: npt.NDArray[np.float32]
    """(F, D) the next observations."""
    rewards: npt.NDArray[np.float64]
    """(F,) the rewards (the sum of ``terms``)."""
    terms: npt.NDArray[np.float64]
    """(9, F) the reward terms in ``REWARD_INFO_KEYS`` order."""
    truncated: bool
    """The episode ended (all followers are truncated together; there is no termination)."""

class _Plan(NamedTuple):
    """A step's commands, between :meth:`BoidsEnv._before_physics` and the physics."""

    full: npt.NDArray[np.float64]
    """(N, 2) the leader's command then the followers' (native (v, ω) with ``native``)."""
    crowd: npt.NDArray[np.float64] | None
    """(P, 2) the crowd's velocities, or None without one."""
    native: bool
    """``action="unicycle"``: ``full`` holds the drivers' own commands."""


REWARD_INFO_KEYS = ("reward_separation", "reward_cohesion", "reward_alignment",
                    "reward_proximity", "reward_contact", "reward_wall", "reward_gap",
                    "reward_intrusion", "reward_parked")
"""The per-term rewards every follower's info holds, after reset and after every step: the
study's three, then the safety terms (0 unless ``reward="safe"`` or their weights are set),
then the cohesion gap (0 unless ``reward_gap`` is set), the intrusion into the leader's or a
pedestrian's personal space (0 unless ``reward_intrusion`` is set) and the parked term (0
unless ``reward_parked`` is set)."""
RESET_OPTIONS = (*(f.name for f in fields(ScenarioConfig) if f.name not in ("robots", "crowd")),
                 "obs_noise")
"""Fields that ``reset(options=...)`` may change for one episode: the scenario's (not
``robots``, which fixes the agents, nor ``crowd``, which fixes the observations' pedestrian
slots) and the sensing noise."""


class BoidsEnv(ParallelEnv[AgentID, np.ndarray, np.ndarray]):
    """A leader-following boids flock of Sphero robots (Akgun's ROS study), on pymunk.

    ## Description
    Robot 0, the leader, drives a scripted path (by default the study's square at 0.55 m/s);
    the followers ``follower_1`` … ``follower_{N-1}`` are the agents. They should keep the
    study's three rules *against the leader*: not closer than 0.7 m (separation), not farther
    than 2.25 m (cohesion), heading within 45° of the leader's command (alignment).

    ## Action Space
    Per follower ``Box(-max_speed, max_speed, (2,), float32)``: the commanded velocity (vx, vy)
    in m/s, world frame. The speed (the vector's norm) is clipped to ``max_speed`` (0.5 m/s);
    the robot tracks the command with a force of at most ``drive_force`` (1 N). With the
    opt-in ``relative_actions`` the action is relative to the leader velocity the follower
    observes, within ±2·max_speed; with ``frame="leader"`` it is in the leader's frame. A
    robot with a heading (``robot="turtlebot3_burger"``, any ``drive="unicycle"``) turns the
    command into (v, ω) with its driver's law; with ``action="unicycle"`` the action is (v, ω)
    itself, within ±max_speed m/s and ±max_turn_rate rad/s (:mod:`boids_env.world.robots`).

    ## Observation Space
    Per follower ``Box`` of size 6 + 5·K, float32 (see :mod:`boids_env.observations`):

    | slice | content | unit | bound |
    |---|---|---|---|
    | 0:2 | own velocity | m/s | ±velocity_bound |
    | 2:4 | leader position relative to self | m | ±2·arena_half_size |
    | 4:6 | leader velocity | m/s | ±velocity_bound |
    | 6+5k : 11+5k | slot k: relative position, velocity, valid | m, m/s, 1 | ±horizon, ±vb, [0,1] |

    Slots hold the robots within ``horizon`` (the leader included), nearest first. Opt-in
    blocks follow (:attr:`layout`): static slots, lidar rays and, with a crowd, pedestrian
    slots (relative position, velocity, valid flag of the nearest pedestrians). Robots with a
    heading add ``own_heading`` (2), ``leader_heading`` (2) and ``neighbour_headings`` (2·K)
    after these: unit vectors (cos, sin), zero in an empty slot.

    ## A person as the leader (opt-in)
    ``leader="person"``: robot 0 is a pedestrian walked by JuPedSim (the ``people`` extra)
    to the corners of its path with a varying gait and pauses, a 0.22 m, 70 kg body the robots
    cannot push; ``leader="trajectory"`` replays a recorded walk (``leader_trajectory``, a
    CSV of t, x, y); ``crowd=N`` adds pedestrians walking to random goals. The episode's
    metrics then include the proxemics of :mod:`boids_env.proxemics`.

    ## Rewards
    Per follower and step: −(w_sep·[sep] + w_coh·[coh] + w_ali·[ali]) · dt, the flags of
    :mod:`boids_env.metrics`; each term is in ``infos[agent]`` as ``reward_separation``,
    ``reward_cohesion``, ``reward_alignment``. Summed over followers and the episode, the
    return is −(V_sep + V_coh + V_align) · T (the default ``reward="study"``).
    ``reward="safe"`` adds −w·[flag]·dt per follower for ``reward_proximity`` (closer than
    ``safety_distance``, 0.3 m, to any other robot, the leader included), ``reward_contact``
    (touching a robot) and ``reward_wall`` (centre within ``wall_distance``, 0.15 m, of a
    wall); these keys are always in the infos (0 under the study's reward). The opt-in
    ``reward_gap`` weight adds −w·(distance to the leader − 2.25 m)₊·dt, a dense cohesion
    signal (info key ``reward_gap``; with ``route_leader``, for a follower that does not see
    the leader, the distance is the route's length: behind a wall it is as far as its way
    round). The opt-in ``reward_intrusion`` weight adds −w·dt while a follower is within
    ``intrusion_distance`` (1.2 m, Hall's personal zone) of the leader or a pedestrian (info
    key ``reward_intrusion``), for following a person. The opt-in ``reward_parked`` weight
    adds −w·speed·dt while the leader has stood still for more than ``parked_after`` (info
    key ``reward_parked``; with ``parked_within`` only for followers near the leader):
    followers park around a leader who stops.

    ## Starting State
    Leader at (0, 0), followers on the study's 0.5 m grid behind it with a seeded jitter of
    ±``init_jitter`` (0.05 m); everything at rest. The leader waits ``startup_time`` (2 s).

    ## Episode End
    No termination. All followers are truncated ``tail_time`` (0.5 s) after the leader finishes
    its path (74.6 s in the study's case), or at ``max_cycles`` steps.

    ## Arguments
    ``BoidsEnv(config=None, render_mode=None, **fields)``: any field of
    :class:`~boids_env.config.EnvConfig` by its flat name, e.g. ``robots=19`` (group size with
    the leader), ``leader_speed=0.6``, ``path="circle"``, ``max_cycles=500``.
    ``reset(options=...)`` may change scenario fields (not ``robots``) for one episode.

    ## Version History
    - v0: first release.
    """

    _flags: tuple[dict[AgentID, bool], dict[AgentID, bool]] | None = None
    """The step's all-False and all-True dicts of the live agents (copied each step)."""
    _codes: npt.NDArray[np.intp] | None = None
    """The last step's violation flags as bits when a kernel computed them (the fused call
    or :meth:`_terms`'s; else None): they pick each agent's info dict (:meth:`_infos`)."""
    _templates: tuple[npt.NDArray[np.float64], list[dict[str, float]]] | None = None

    metadata: ClassVar[dict[str, Any]] = {
        "name": "boids_leader_v0", "render_modes": ["human", "rgb_array"], "render_fps": 10,
        "is_parallelizable": True}

    def __init__(self, config: EnvConfig | None = None, render_mode: str | None = None,
                 **kwargs: Any) -> None:
        if config is not None and not isinstance(config, EnvConfig):
            raise TypeError(f"config must be an EnvConfig, got {type(config).__name__}")
        base = config if config is not None else EnvConfig()
        self.config = base.replace(**kwargs) if kwargs else base
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or "
                             f"None, got {render_mode!r}")
        self.render_mode = render_mode
        obs_cfg = self.config.observation
        n = self.config.scenario.robots
        self.possible_agents: list[AgentID] = [f"follower_{i}" for i in range(1, n)]
        # every follower lives until the episode ends (no agent leaves early): a step's
        # actions must name exactly these
        self._live = frozenset(self.possible_agents)
        self.agents: list[AgentID] = []
        self._observer = Observer(self.config)
        self.layout = self._observer.layout
        # one Box object per agent (seeding one agent's space must not reseed the others')
        self.observation_spaces = {a: self._observer.make_space() for a in self.possible_agents}
        self.action_spaces = {a: self._action_box() for a in self.possible_agents}
        x0, y0, x1, y1 = self.config.scene.bounds
        vb = obs_cfg.velocity_bound
        self.state_space = spaces.Box(
            np.concatenate([np.tile([x0, y0], n), np.full(2 * n, -vb)]).astype(np.float32),
            np.concatenate([np.tile([x1, y1], n), np.full(2 * n, vb)]).astype(np.float32),
            dtype=np.float32)
        self._rng: np.random.Generator | None = None
        self._world: World | None = None
        self._leader: Leader | None = None
        self._people: Any = None
        self._renderer: Any = None
        self._fused: Fused | None = None
        self.episode_config = self.config
        self.overlays: dict[str, npt.NDArray[np.float64]] = {}
        """Per-follower vectors (F, 2) the renderer draws as arrows (e.g. rule forces)."""
        self.hud_text: list[str] = []
        """Extra lines the renderer writes over the arena (e.g. the live window's controls)."""

    # ----------------------------------------------------------------------------- spaces
    def _action_box(self) -> spaces.Box:
        """One follower's action Box: (vx, vy) within ±max_speed (±2·max_speed relative to
        the leader's), or (v, ω) within the robot's limits (``action="unicycle"``)."""
        world, obs_cfg = self.config.world, self.config.observation
        if obs_cfg.action == "unicycle":
            assert world.max_turn_rate is not None
            high = np.array([world.max_speed, world.max_turn_rate], dtype=np.float32)
            return spaces.Box(-high, high, (2,), np.float32)
        bound = world.max_speed * (2.0 if obs_cfg.relative_actions else 1.0)
        return spaces.Box(-bound, bound, (2,), np.float32)

    def observation_space(self, agent: AgentID) -> spaces.Box:
        return self.observation_spaces[self._known(agent)]

    def action_space(self, agent: AgentID) -> spaces.Box:
        return self.action_spaces[self._known(agent)]

    def _known(self, agent: AgentID) -> AgentID:
        if agent not in self.observation_spaces:
            raise KeyError(f"unknown agent {agent!r}; agents are follower_1 … "
                           f"follower_{len(self.possible_agents)}")
        return agent

    # ------------------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[AgentID, np.ndarray], dict[AgentID, dict[str, Any]]]:
        obs = self.reset_arrays(seed, options)
        # The same info keys as step()'s, so clients that build their spec from reset
        # (TorchRL, BenchMARL) keep the reward terms.
        zero = dict.fromkeys(REWARD_INFO_KEYS, 0.0)
        return dict(zip(self.agents, obs, strict=True)), {a: dict(zero) for a in self.agents}

    def reset_arrays(self, seed: int | None = None, options: dict[str, Any] | None = None
                     ) -> npt.NDArray[np.float32]:
        """:meth:`reset` without dicts: the observations (F, D), one row per follower in
        ``possible_agents`` order. Same state, same seeding, same checks.

        The new episode is built aside and swapped in whole: a refused reset (a bad option,
        random waypoints that never clear the scene, no room for the crowd, ...) raises and
        leaves the env exactly as it was, its episode in progress, config, leader, world and
        random stream untouched."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                                 or seed < 0):
            raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
        episode = self._episode_config(options)  # validated before any state changes
        if seed is not None:
            rng = np.random.default_rng(int(seed))
        else:  # an unseeded reset goes on drawing from the env's stream
            rng = self._rng if self._rng is not None else np.random.default_rng()
        drawn = rng.bit_generator.state
        try:
            state = self._new_episode(episode, rng, seed)
        except BaseException:
            rng.bit_generator.state = drawn  # a refused reset draws nothing from the stream
            raise
        self._rng = rng
        self.episode_config = episode
        self.__dict__.update(state)
        self.agents = list(self.possible_agents)
        self.overlays = {}
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs

    def _new_episode(self, episode: EnvConfig, rng: np.random.Generator, seed: int | None
                     ) -> dict[str, Any]:
        """The state of a new episode of ``episode``, drawn from ``rng``, by attribute name;
        nothing of the env is changed (:meth:`reset_arrays` swaps it in)."""
        sc, wc = episode.scenario, episode.world
        scene = episode.scene
        initial = scenario.initial_positions(
            sc, rng, scenario.layout_heading(sc, wc.scene, preview_path(sc, wc.dt)))
        leader = make_leader(sc, rng, wc.dt)
        if sc.path == "random_waypoints" and not scene.is_empty_box:
            leader = redraw_clear(sc, scene, wc.robot_radius, leader, rng, wc.dt)
        # the person and the crowd draw from the stream only when asked for: defaults unchanged
        leader, people = make_person(sc, scene, leader, initial, rng, wc.dt)
        headings = (np.full(sc.robots, leader.initial_heading)
                    if wc.drive == "unicycle" else None)
        observer = Observer(episode)
        reward_scale = metrics.reward_scale(episode.metrics, wc.dt)
        safety_scale = -np.array(episode.metrics.safety_weights)[:, None] * wc.dt
        state: dict[str, Any] = {
            "_initial_positions": initial, "_leader": leader, "_people": people,
            "_initial_headings": headings, "_scene": scene,
            "_world": _build_world(episode, initial, headings, people),
            "_step_limit": scenario.step_limit(sc, leader.nominal_duration, wc.dt),
            "_tail_steps": round(sc.tail_time / wc.dt), "_finish_step": None,
            # (commanded, executed, crowd, native) of every step, replayed by __setstate__
            "_history": [],
            "_counts": np.zeros((3, len(self.possible_agents)), dtype=np.int64),
            "_observer": observer, "_realism": None,
            "_reward_scale": reward_scale,
            "_safety_scale": safety_scale,
            "_safety_on": bool(safety_scale.any()),
            "_violation_scale": np.ascontiguousarray(reward_scale[:, 0]),  # the kernel's
            "_gap_scale": -episode.metrics.reward_gap * wc.dt,
            "_intrusion_scale": -episode.metrics.reward_intrusion * wc.dt,
            "_parked_scale": -episode.metrics.reward_parked * wc.dt,
            "_parked_steps": round(episode.metrics.parked_after / wc.dt),
            "_still_steps": 0}
        observer.reset(rng, leader.initial_heading)
        if episode.realism.active:  # its own stream, drawn only when on: defaults unchanged
            realism_rng = np.random.default_rng(rng.integers(2**63))
            # stale observations draw from a stream of the episode seed alone (a ROS
            # controller node draws the same); without a seed, from the env's stream
            stale_seed = 0
            if episode.realism.resolved()["stale_observations"] > 0:
                stale_seed = int(seed) if seed is not None else int(rng.integers(2**63))
            state["_realism"] = Realism(episode.realism, sc.robots, wc.dt, sc.startup_time,
                                        wc.robot_radius, wc.max_speed, realism_rng, stale_seed)
        return state

    def _new_world(self) -> World:
        """The current episode's world at its start (rebuilt on unpickling)."""
        return _build_world(self.episode_config, self._initial_positions,
                            self._initial_headings, self._people)

    def _episode_config(self, options: Mapping[str, Any] | None) -> EnvConfig:
        if options is None:
            return self.config
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
        return self.config.replace(**known) if known else self.config

    # ------------------------------------------------------------------------------- step
    def step(self, actions: Mapping[AgentID, npt.ArrayLike]) -> tuple[
            dict[AgentID, np.ndarray], dict[AgentID, float], dict[AgentID, bool],
            dict[AgentID, bool], dict[AgentID, dict[str, Any]]]:
        """Applies every live follower's velocity command and advances 0.1 s."""
        if self._world is None:
            raise RuntimeError("step() called before reset(); call reset() first")
        if not self.agents:
            if actions:
                raise RuntimeError("the episode has ended (every follower is truncated); call "
                                   "reset() before stepping again")
            return {}, {}, {}, {}, {}
        agents = self.agents
        result = self._advance(self._parse_actions(actions))
        flags = self._flags
        if flags is None or len(flags[0]) != len(agents):  # built once (copies are cheaper)
            flags = self._flags = (dict.fromkeys(agents, False), dict.fromkeys(agents, True))
        return (dict(zip(agents, result.observations, strict=True)),
                dict(zip(agents, result.rewards.tolist(), strict=True)),
                flags[0].copy(), flags[result.truncated].copy(),
                self._infos(agents, result.terms))

    def _infos(self, agents: list[AgentID], terms: npt.NDArray[np.float64]
               ) -> dict[AgentID, dict[str, Any]]:
        """Each agent's info dict: its reward terms (9, F) by ``REWARD_INFO_KEYS``."""
        k0, k1, k2, k3, k4, k5, k6, k7, k8 = REWARD_INFO_KEYS
        if not (self._safety_on or self._gap_scale or self._intrusion_scale
                or self._parked_scale):
            codes = self._codes
            if codes is not None and len(codes) == len(agents):
                # the fused call's flags (bits 1, 2, 4) pick one of 8 dicts of the same
                # floats (scale × 1.0 or × 0.0, as the kernel multiplies), copied per agent
                return dict(zip(agents, map(dict.copy, map(self._info_templates().__getitem__,
                                                           codes.tolist())), strict=True))
            # the opt-in rows are the zeros they started as: a copy of the zero dict with
            # the study's three terms set (a third cheaper than a literal per agent)
            t0, t1, t2 = terms[:3].tolist()
            copy = dict.fromkeys(REWARD_INFO_KEYS, 0.0).copy
            infos = {}
            for a, c0, c1, c2 in zip(agents, t0, t1, t2, strict=True):
                info = infos[a] = copy()
                info[k0], info[k1], info[k2] = c0, c1, c2
            return infos
        # a literal per agent: 4× faster than dict(zip(...)) (1 ms a step at 1000 robots)
        return {a: {k0: c0, k1: c1, k2: c2, k3: c3, k4: c4, k5: c5, k6: c6, k7: c7, k8: c8}
                for a, (c0, c1, c2, c3, c4, c5, c6, c7, c8) in zip(
                    agents, terms.T.tolist(), strict=True)}

    def _info_templates(self) -> list[dict[str, float]]:
        """The 8 info dicts of the study's reward (no opt-in term), by the flags' bits
        (separation 1, cohesion 2, alignment 4): each term ``scale × 1.0`` or ``× 0.0``,
        the products the kernel's terms are (−0.0 for an unflagged term), built once per
        episode's scales."""
        scale = self._violation_scale
        cached = self._templates
        if cached is not None and cached[0] is scale:
            return cached[1]
        values = scale.tolist()
        templates = []
        for code in range(8):
            info = dict.fromkeys(REWARD_INFO_KEYS, 0.0)
            for row in range(3):
                info[REWARD_INFO_KEYS[row]] = values[row] * (1.0 if code >> row & 1 else 0.0)
            templates.append(info)
        self._templates = (scale, templates)
        return templates

    def step_arrays(self, actions: npt.ArrayLike) -> ArrayStep:
        """:meth:`step` without dicts, for vectorised trainers: ``actions`` (F, 2), one row per
        follower in ``possible_agents`` order. The same code as :meth:`step` underneath (the
        results are bit-identical); the same checks (a clear error for a wrong shape, dtype or
        a NaN/inf, and after the episode ended), and the same state afterwards."""
        if self._world is None:
            raise RuntimeError("step_arrays() called before reset(); call reset() first")
        if not self.agents:
            raise RuntimeError("the episode has ended (every follower is truncated); call "
                               "reset() before stepping again")
        arr = np.asarray(actions)
        shape = (len(self.agents), 2)
        if arr.dtype.kind not in "iuf" or arr.shape != shape:
            raise ValueError(f"actions must be a real array of shape {shape} (vx, vy per "
                             f"follower, m/s), got dtype {arr.dtype} and shape {arr.shape}")
        # a NaN or inf is refused by the speed limit, before anything moves
        # (:meth:`_before_physics`)
        return self._advance(arr.astype(np.float64))

    def _advance(self, actions: npt.NDArray[np.float64]) -> ArrayStep:
        """One control step from checked actions (F, 2) in the observation frame: their speed
        limited in the world frame (as a simulator receiving world-frame commands limits
        it, so that a policy in another frame gets the same commands bit for bit), the
        physics, the metrics and rewards, the episode's end, the next observations.

        Parts which :class:`~boids_env.batch.EnvBatch` also calls (computing the third for
        all its copies at once): :meth:`_before_physics`, :meth:`_physics`, the reward
        terms and observations (:meth:`_outcome`), the episode's end (:meth:`_end_step`).
        """
        self._physics(self._before_physics(actions))
        terms, observations = self._outcome()
        # add.reduce: terms.sum's own call without its Python wrapper (the same bits)
        return ArrayStep(observations, np.add.reduce(terms, axis=0), terms, self._end_step())

    def _outcome(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float32]]:
        """The step's reward terms (9, F) and next observations after the physics: in one
        compiled call where the layout allows (:mod:`boids_env.fused`; the same bits),
        else :meth:`_terms` and :meth:`_observe`."""
        compiled = kernels.loaded()
        if compiled is not None:
            followers = len(self.possible_agents)
            plan = self._fused
            if plan is None or plan.keys[0][0] is not self.episode_config or \
                    plan.keys[0][1] is not self._counts:  # Fused.current for one env
                plan = self._fused = Fused([self], [0, followers])
            if plan.index:
                obs = np.empty((followers, self._observer.layout.size), dtype=np.float32)
                terms = np.zeros((len(REWARD_INFO_KEYS), followers))
                plan.run(compiled, obs, terms)
                self._codes = plan.codes
                return terms, obs
        world = self._world
        assert world is not None
        self._codes = None  # _terms sets them when its kernel runs
        return self._terms(world), self._observe()

    def _before_physics(self, actions: npt.NDArray[np.float64]) -> _Plan:
        """The step's commands from the checked actions (:mod:`boids_env.commands`: the
        robot's limits, the start-up hold, a NaN or inf refused before anything moves), the
        crowd's walk, the leader's command, the safety filter (nothing stepped yet)."""
        world, leader = self._world, self._leader
        assert world is not None and leader is not None
        cfg = self.episode_config
        sc = cfg.scenario
        time = world.time
        commands = commands_from_actions(
            actions, cfg, self._observer.to_world, check=self._finite,
            hold=sc.startup_hold and scenario.holding(time, sc.startup_time))
        crowd = None
        if self._people is not None:
            self._people.advance(time)
            crowd = (self._people.pedestrians - world.pedestrian_positions) / cfg.world.dt
        full = np.empty((len(commands) + 1, 2))
        full[0] = leader.command(time, world.positions[0])
        commands = safe_commands(commands, cfg, self._scene, world.positions, world.velocities,
                                 full[0], None if crowd is None else world.pedestrian_positions,
                                 crowd)
        x, y = full[0].tolist()  # the stored command (two floats, one call)
        self._still_steps = 0 if x != 0.0 or y != 0.0 else self._still_steps + 1
        native = native_actions(cfg)
        if native:  # the followers' (v, ω) as they come; the leader's driver makes its own
            full[0] = world.model.native(full[:1], world.heading_vectors[:1])[0]
        full[1:] = commands
        return _Plan(full, crowd, native)

    def _physics(self, plan: _Plan) -> None:
        """Steps the world with the planned commands (realism between, if on) and records
        them for replay."""
        world = self._world
        assert world is not None
        full, crowd = plan.full, plan.crowd
        if plan.native:
            world.step(None, native=full)
            self._history.append((None, None, crowd, full))
        elif self._realism is None:
            world.step(full, None, crowd)
            self._history.append((full, None, crowd, None))
        else:
            executed = self._realism.executed(full, world.positions, world.time)
            world.step(full, executed, crowd)
            self._history.append((full, executed, crowd, None))

    def _end_step(self) -> bool:
        """Whether the episode ended with this step (the leader's finish and tail, the step
        limit; the agents leave then), after rendering it in ``human`` mode."""
        world, leader = self._world, self._leader
        assert world is not None and leader is not None
        if self._finish_step is None and leader.finished:
            self._finish_step = world.steps
        done = world.steps >= self._step_limit or (
            self._finish_step is not None and world.steps >= self._finish_step + self._tail_steps)
        if done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return bool(done)

    def _terms(self, world: World) -> npt.NDArray[np.float64]:
        """The step's reward terms (9, F) in ``REWARD_INFO_KEYS`` order: the study's three
        (−weight · flag · dt, as ``metrics.reward_terms``; their flags counted for the
        episode's V_*), then the opt-in ones, which stay zero rows unless their weight is set
        (nothing is computed for them then)."""
        terms = np.zeros((len(REWARD_INFO_KEYS), len(world.positions) - 1))
        mc = self.episode_config.metrics
        compiled = kernels.compiled()
        if compiled is not None and mc.alignment_source == "command":
            # the same bits in one loop; the angles from numpy's arctan2 (boids_env.kernels)
            cmd = world.commanded
            codes = np.empty(len(world.positions) - 1, dtype=np.intp)
            compiled.violations(world.positions, cmd, np.arctan2(cmd[:, 1], cmd[:, 0]),
                                mc.separation_threshold, mc.cohesion_threshold,
                                mc.alignment_threshold_deg, mc.wrap_alignment,
                                self._violation_scale, self._counts, codes, terms)
            self._codes = codes  # the flags' bits: they pick the info dicts (_infos)
        else:
            flags = metrics.flags_for(mc, world.positions, world.commanded, world.headings)
            stacked = np.stack([flags[name] for name in metrics.VIOLATIONS])
            self._counts += stacked
            np.multiply(self._reward_scale, stacked, out=terms[:3])
        if (compiled is not None and (self._safety_on or self._gap_scale)
                and not self.episode_config.observation.route_leader
                and len(world.positions) < metrics.KD_TREE_MIN_ROBOTS):
            self._safety_gap_compiled(compiled, world.positions, terms)
        else:
            if self._safety_on:
                terms[3:6] = self._safety_terms(world.positions)
            if self._gap_scale:
                terms[6:7] = self._gap_term(world.positions)
        if self._intrusion_scale:
            terms[7:8] = self._intrusion_term(world)
        if self._parked_scale:
            terms[8:9] = self._parked_term(world.velocities)
        return terms

    def _safety_terms(self, positions: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The safety reward terms (3, F): −weight · flag · dt (called when a weight is set)."""
        scale = self._safety_scale
        cfg = self.episode_config
        flags = metrics.safety_flags(positions, cfg.world.robot_radius,
                                     cfg.metrics.safety_distance,
                                     cfg.scene.within(positions[1:], self._wall_reach()))
        return scale * np.stack([flags[name] for name in metrics.SAFETY_FLAGS])

    def _wall_reach(self) -> float:
        """How near static geometry a follower's centre is flagged at a wall: the metrics'
        ``wall_distance``, at least touching (the robot's radius and the contact tolerance)."""
        cfg = self.episode_config
        return max(cfg.metrics.wall_distance, cfg.world.robot_radius + metrics.CONTACT_TOLERANCE)

    def _safety_gap_compiled(self, compiled: Any, positions: npt.NDArray[np.float64],
                             terms: npt.NDArray[np.float64]) -> None:
        """:meth:`_safety_terms` and :meth:`_gap_term` (the straight distance) into
        ``terms`` in one compiled call, the same bits (below the KD-tree's size)."""
        cfg = self.episode_config
        safety = self._safety_on
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        if safety:
            near = np.ascontiguousarray(self._scene.within(pos[1:], self._wall_reach()),
                                        dtype=np.bool_)
        else:
            near = np.zeros(len(pos) - 1, dtype=np.bool_)
        compiled.safety_gap_terms(
            pos, near, np.ascontiguousarray(self._safety_scale[:, 0]),
            float(cfg.metrics.safety_distance),
            2 * cfg.world.robot_radius + metrics.CONTACT_TOLERANCE, safety,
            float(self._gap_scale), float(cfg.metrics.cohesion_threshold),
            bool(self._gap_scale), terms)

    def _gap_term(self, positions: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The cohesion-gap reward term (1, F): −weight · metres beyond the cohesion threshold
        · dt (called when its weight is set)."""
        threshold = self.episode_config.metrics.cohesion_threshold
        gap = np.maximum(self._leader_distances(positions) - threshold, 0.0)
        return self._gap_scale * gap[None]

    def _leader_distances(self, positions: npt.NDArray[np.float64]
                          ) -> npt.NDArray[np.float64]:
        """Each follower's distance to the leader (F,): the straight line, or with
        ``route_leader`` the route's length for a follower that does not see the leader."""
        cfg = self.episode_config
        distance = metrics.leader_distance(positions)
        if cfg.observation.route_leader:
            from boids_env.world.route import leader_in_sight, route_grid, sense_route

            grid = route_grid(cfg.scene, cfg.world.robot_radius, cfg.observation.route_cell)
            hidden = ~leader_in_sight(grid, positions)
            if hidden.any():
                distance = np.where(hidden, sense_route(grid, positions)[1], distance)
        return distance

    def _intrusion_term(self, world: World) -> npt.NDArray[np.float64]:
        """The intrusion reward term (1, F): −weight · dt while a follower's centre is within
        ``intrusion_distance`` of the leader's (a person's personal space) or of a
        pedestrian's (called when its weight is set)."""
        flags = proxemics.intrusion_flags(world.positions, world.pedestrian_positions,
                                        self.episode_config.metrics.intrusion_distance)
        return self._intrusion_scale * flags[None]

    def _parked_term(self, velocities: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The parked reward term (1, F): −weight · follower speed · dt once the leader's
        command has been zero for more than ``parked_after``, zeros before (called when its
        weight is set)."""
        if self._still_steps <= self._parked_steps:
            return np.zeros((1, len(velocities) - 1))
        speed = np.sqrt(np.einsum("fd,fd->f", velocities[1:], velocities[1:]))
        within = self.episode_config.metrics.parked_within
        if within > 0:  # only the followers already around the leader park
            world = self._world
            assert world is not None
            speed = np.where(self._leader_distances(world.positions) <= within, speed, 0.0)
        return self._parked_scale * speed[None]

    def _parse_actions(self, actions: Mapping[AgentID, npt.ArrayLike]
                       ) -> npt.NDArray[np.float64]:
        if type(actions) is not dict and not isinstance(actions, Mapping):  # ABC check: slow
            raise TypeError(f"actions must be a dict of agent -> (vx, vy), got "
                            f"{type(actions).__name__}")
        agents = self.agents
        if len(actions) != len(agents) or (
                actions.keys() != self._live if type(actions) is dict  # one set comparison
                else not all(a in actions for a in agents)):
            unknown = sorted(str(a) for a in actions if a not in self.agents)
            missing = [a for a in self.agents if a not in actions]
            raise KeyError(f"actions must hold exactly the live agents; unknown: {unknown}, "
                           f"missing: {missing}")
        values = list(map(actions.__getitem__, agents))
        arr = _real_pairs(values)  # the common case: what policies return (a NaN or inf
        if arr is None:            # is refused by the speed limit, before anything moves)
            return np.stack([as_velocities(v, f"action of {a}", (2,))
                             for a, v in zip(self.agents, values, strict=True)])
        return arr

    def _finite(self, actions: npt.NDArray[np.float64]) -> None:
        """Raises the clear error for a NaN or inf in the checked actions (F, 2), naming
        the followers that sent one (:func:`~boids_env.commands.commands_from_actions`
        calls it where the actions may hold one)."""
        if not np.isfinite(actions).all():
            bad = [a for a, row in zip(self.agents, actions, strict=True)
                   if not np.isfinite(row).all()]
            raise ValueError(f"actions must be finite; NaN or inf from {bad}")

    def _observe(self) -> npt.NDArray[np.float32]:
        world = self._world
        assert world is not None
        crowd = self.crowd
        headings = world.heading_vectors
        velocities = world.velocities
        if headings is not None:  # what a controller reads from odometry (REP 105)
            velocities = odometry_velocities(velocities, headings)
        obs = self._observer(world.positions, velocities, crowd, headings)
        # a stale row keeps the sight it was seen with (the observer's leader_hidden)
        return obs if self._realism is None else self._realism.observations(obs,
                                                                           self._observer)

    # -------------------------------------------------------------------------- queries
    @property
    def np_random(self) -> np.random.Generator:
        """The env's random generator (seeded by ``reset(seed=...)``), as Gymnasium and
        PettingZoo's own envs expose it (SuperSuit's wrappers read it)."""
        if self._rng is None:
            self._rng = np.random.default_rng()
        return self._rng

    def state(self) -> np.ndarray:
        """Global state: positions (N·2) then velocities (N·2), the leader first, float32.
        Positions are exact (the physics keeps every robot inside the arena); velocities are
        clipped to ±velocity_bound like the observations'."""
        world = self._require_world()
        vb = self.episode_config.observation.velocity_bound
        return np.concatenate([world.positions.ravel(),
                               np.clip(world.velocities, -vb, vb).ravel()]).astype(np.float32)

    def __copy__(self) -> BoidsEnv:
        """An independent copy (as :func:`copy.deepcopy`): a copy sharing the source's
        world, random stream or counters would corrupt both."""
        return copy.deepcopy(self)

    def snapshot(self) -> Snapshot:
        """The world's current arrays (copies): positions, velocities, commands, contacts."""
        return self._require_world().snapshot()

    def episode_metrics(self) -> dict[str, Any]:
        """The study's V_* and per-follower counts of the episode so far."""
        world = self._require_world()
        steps = max(world.steps, 1)
        out: dict[str, Any] = {}
        for row, name in enumerate(metrics.VIOLATIONS):
            out[metrics.V_KEYS[name]] = float(self._counts[row].sum() / steps)
            out[metrics.COUNT_KEYS[name]] = self._counts[row].tolist()
        out["steps"] = world.steps
        out["duration"] = world.time
        return out

    @property
    def crowd(self) -> Crowd | None:
        """The crowd's pedestrians now (positions and velocities, world frame) as the
        followers observe them, or None without a crowd."""
        world = self._require_world()
        return Crowd(world.pedestrian_positions, world.pedestrian_velocities) if world.p else None

    @property
    def leader_hidden(self) -> npt.NDArray[np.bool_] | None:
        """With ``route_leader``: which followers (F,, in agent order) did not see the leader
        through free space at the last observation, so read it along their route (a
        policy that switches on it: :class:`~boids_env.policies.sight_switch.SightSwitch`);
        None without ``route_leader``."""
        return self._observer.leader_hidden

    @property
    def leader(self) -> Leader:
        """The current episode's leader (e.g. an ExternalLeader to steer)."""
        if self._leader is None:
            raise RuntimeError("no episode yet; call reset() first")
        return self._leader

    @property
    def robot_model(self) -> RobotModel:
        """The episode's robot model (:mod:`boids_env.world.robots`); ``robot_model.native``
        is its driver's law, world-frame velocities -> the native command."""
        return self._require_world().model

    def set_leader_command(self, velocity: npt.ArrayLike) -> None:
        """Velocity (m/s) for an ``external`` leader, used from the next step on."""
        if not isinstance(self.leader, ExternalLeader):
            raise RuntimeError(f"set_leader_command needs path='external', this episode's "
                               f"path is {self.episode_config.scenario.path!r}")
        self.leader.set_command(velocity)

    def _require_world(self) -> World:
        if self._world is None:
            raise RuntimeError("no episode yet; call reset() first")
        return self._world

    # ------------------------------------------------------------------------- rendering
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            warnings.warn("render() called without a render_mode; pass render_mode='human' or "
                          "'rgb_array' to the constructor", UserWarning, stacklevel=2)
            return None
        if self._world is None:
            raise RuntimeError("render() called before reset()")
        from boids_env.render import Frame, Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, self.config.scene)
            self._renderer.fps = self.metadata["render_fps"]
        world = self._world
        m = self.episode_metrics()
        status = (f"t = {m['duration']:5.1f} s   V_sep {m['V_sep']:.3f}   V_coh {m['V_coh']:.3f}"
                  f"   V_align {m['V_align']:.3f}")
        sc = self.episode_config.scenario
        frame = Frame(world.positions, world.steps, self.episode_config.world.robot_radius,
                      status, self.episode_config.observation.horizon, dict(self.overlays),
                      tuple(self.hud_text), None if sc.leader == "robot" else sc.person_radius,
                      world.pedestrian_positions if world.p else None, sc.person_radius,
                      world.headings)
        return self._renderer.draw(frame)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # --------------------------------------------------------------------------- pickle
    def __getstate__(self) -> dict[str, Any]:
        # pymunk cannot serialise its contact cache, so a copied space diverges after a
        # contact. The world is rebuilt from the initial positions and the commands replayed,
        # which is bit-exact because the physics is deterministic.
        state = self.__dict__.copy()
        state["_world"] = None
        state["_renderer"] = None
        state["_fused"] = None  # rebuilt on use: its counts are views of the env's
        state["_codes"] = None
        state["_replay"] = self._world is not None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        replay = state.pop("_replay", False)
        self.__dict__.update(state)
        if replay:
            self._world = self._new_world()
            for command, executed, crowd, native in self._history:
                self._world.step(command, executed, crowd, native=native)


_DTYPE = attrgetter("dtype")


def _real_pairs(values: list[Any]) -> npt.NDArray[np.float64] | None:
    """``values`` stacked (F, 2) as float64 if every one is an array of shape (2,) with an
    integer or float dtype, else None (the caller parses each value with its error
    messages). The checks are three C calls, not a Python test per value: the set of
    dtypes (a value without one, a list or a float, is not an array), their kinds, and the
    stacked shape, which is (F, 2) only if every value has shape (2,) (a numpy scalar, of
    shape (), or a value of any other shape gives another, or no stack at all)."""
    try:
        dtypes = set(map(_DTYPE, values))
        real = (dtypes.pop().kind in "iuf" if len(dtypes) == 1  # the common case
                else all(dtype.kind in "iuf" for dtype in dtypes))
    except (AttributeError, TypeError):  # no dtype, or not numpy's (a tensor's)
        return None
    if not real:
        return None
    try:
        arr = np.array(values, dtype=np.float64)
    except (ValueError, TypeError):  # shapes that differ; an object that cannot convert
        return None
    return arr if arr.shape == (len(values), 2) else None


def _build_world(cfg: EnvConfig, initial: npt.NDArray[np.float64],
                 headings: npt.NDArray[np.float64] | None, people: Any) -> World:
    """An episode's world at its start: a person leader and the crowd as kinematic bodies
    when the scenario has them."""
    sc = cfg.scenario
    return World(cfg.world, initial, cfg.scene, headings,
                 leader_radius=None if sc.leader == "robot" else sc.person_radius,
                 pedestrians=None if people is None else people.start_pedestrians,
                 pedestrian_radius=sc.person_radius,
                 leader_kinematic=sc.leader == "trajectory" and sc.crowd > 0)


def parallel_env(render_mode: str | None = None, **kwargs: Any) -> BoidsEnv:
    """The parallel env; keyword arguments are config fields by flat name (``robots=19``)."""
    return BoidsEnv(render_mode=render_mode, **kwargs)


class BoidsAECWrapper(parallel_to_aec_wrapper):
    """PettingZoo's parallel-to-AEC conversion, checking each action when it is given: the
    conversion caches actions until the last agent's, so a bad one would otherwise stay cached
    (and fail every later step) after the error."""

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        live = not (self.terminations.get(agent) or self.truncations.get(agent))
        if live:
            as_velocities(action, f"action of {agent}", (2,))
        super().step(action)


def raw_env(render_mode: str | None = None, **kwargs: Any) -> Any:
    """The AEC version of :func:`parallel_env` without PettingZoo's order-enforcing wrapper."""
    return BoidsAECWrapper(parallel_env(render_mode=render_mode, **kwargs))


def env(render_mode: str | None = None, **kwargs: Any) -> Any:
    """The AEC version (PettingZoo's order-enforcing wrapper over :func:`raw_env`)."""
    return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **kwargs))


__all__ = ["REWARD_INFO_KEYS", "ArrayStep", "BoidsAECWrapper", "BoidsEnv", "env", "parallel_env",
           "raw_env"]
