"""``BoidsEnv``: the leader-following flock of the study as a PettingZoo ``ParallelEnv``."""

from __future__ import annotations

import copy
import warnings
from collections.abc import Mapping
from operator import attrgetter
from typing import Any, ClassVar, NamedTuple

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from boids_env import kernels, metrics
from boids_env.commands import commands_from_actions, native_actions, safe_commands
from boids_env.config import EnvConfig
from boids_env.dict_api import BoidsAECWrapper, parse_actions
from boids_env.episode_state import Episode, episode_config
from boids_env.fused import Fused
from boids_env.observations import Crowd, Observer
from boids_env.rewards import REWARD_INFO_KEYS
from boids_env.world import scenario
from boids_env.world.leader import ExternalLeader, Leader
from boids_env.world.robots import RobotModel, odometry_velocities
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
        observer = Observer(self.config)
        self.layout = observer.layout
        # one Box object per agent (seeding one agent's space must not reseed the others')
        self.observation_spaces = {a: observer.make_space() for a in self.possible_agents}
        self.action_spaces = {a: self._action_box() for a in self.possible_agents}
        x0, y0, x1, y1 = self.config.scene.bounds
        vb = obs_cfg.velocity_bound
        self.state_space = spaces.Box(
            np.concatenate([np.tile([x0, y0], n), np.full(2 * n, -vb)]).astype(np.float32),
            np.concatenate([np.tile([x1, y1], n), np.full(2 * n, vb)]).astype(np.float32),
            dtype=np.float32)
        self._rng: np.random.Generator | None = None
        self._episode: Episode | None = None
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
        config = episode_config(self.config, options)  # validated before anything changes
        if seed is not None:
            rng = np.random.default_rng(int(seed))
        else:  # an unseeded reset goes on drawing from the env's stream
            rng = self._rng if self._rng is not None else np.random.default_rng()
        drawn = rng.bit_generator.state
        try:
            episode = Episode.start(config, rng, seed)
        except BaseException:
            rng.bit_generator.state = drawn  # a refused reset draws nothing from the stream
            raise
        self._rng = rng
        self.episode_config = config
        self._episode = episode
        self.agents = list(self.possible_agents)
        self.overlays = {}
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs

    # ------------------------------------------------------------------------------- step
    def step(self, actions: Mapping[AgentID, npt.ArrayLike]) -> tuple[
            dict[AgentID, np.ndarray], dict[AgentID, float], dict[AgentID, bool],
            dict[AgentID, bool], dict[AgentID, dict[str, Any]]]:
        """Applies every live follower's velocity command and advances 0.1 s."""
        episode = self._episode
        if episode is None:
            raise RuntimeError("step() called before reset(); call reset() first")
        if not self.agents:
            if actions:
                raise RuntimeError("the episode has ended (every follower is truncated); call "
                                   "reset() before stepping again")
            return {}, {}, {}, {}, {}
        agents = self.agents
        result = self._advance(parse_actions(actions, agents, self._live))
        flags = self._flags
        if flags is None or len(flags[0]) != len(agents):  # built once (copies are cheaper)
            flags = self._flags = (dict.fromkeys(agents, False), dict.fromkeys(agents, True))
        return (dict(zip(agents, result.observations, strict=True)),
                dict(zip(agents, result.rewards.tolist(), strict=True)),
                flags[0].copy(), flags[result.truncated].copy(),
                episode.rewards.infos(agents, result.terms))

    def step_arrays(self, actions: npt.ArrayLike) -> ArrayStep:
        """:meth:`step` without dicts, for vectorised trainers: ``actions`` (F, 2), one row per
        follower in ``possible_agents`` order. The same code as :meth:`step` underneath (the
        results are bit-identical); the same checks (a clear error for a wrong shape, dtype or
        a NaN/inf, and after the episode ended), and the same state afterwards."""
        if self._episode is None:
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
        else the episode's :meth:`Rewards.terms <boids_env.rewards.Rewards.terms>` and
        :meth:`_observe`."""
        episode = self._episode
        assert episode is not None
        compiled = kernels.loaded()
        if compiled is not None:
            plan = self._fused
            if plan is None or plan.keys[0][0] is not episode or \
                    plan.keys[0][1] is not episode.rewards.counts:  # Fused.current, one env
                plan = self._fused = Fused([self], [0, len(self.possible_agents)])
            if plan.index:
                followers = len(self.possible_agents)
                obs = np.empty((followers, episode.observer.layout.size), dtype=np.float32)
                terms = np.zeros((len(REWARD_INFO_KEYS), followers))
                plan.run(compiled, obs, terms)
                episode.rewards.codes = plan.codes
                return terms, obs
        return episode.rewards.terms(episode.world), self._observe()

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
            crowd = self._people.walk(time, world)
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
        episode = self._episode
        assert episode is not None
        world, realism, full, crowd = episode.world, episode.realism, plan.full, plan.crowd
        if plan.native:
            world.step(None, native=full)
            episode.history.append((None, None, crowd, full))
        elif realism is None:
            world.step(full, None, crowd)
            episode.history.append((full, None, crowd, None))
        else:
            executed = realism.executed(full, world.positions, world.time)
            world.step(full, executed, crowd)
            episode.history.append((full, executed, crowd, None))

    def _end_step(self) -> bool:
        """Whether the episode ended with this step (the leader's finish and tail, the step
        limit; the agents leave then), after rendering it in ``human`` mode."""
        episode = self._episode
        assert episode is not None
        steps = episode.world.steps
        if episode.finish_step is None and episode.leader.finished:
            episode.finish_step = steps
        done = steps >= episode.step_limit or (
            episode.finish_step is not None and steps >= episode.finish_step + episode.tail_steps)
        if done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return bool(done)

    def _finite(self, actions: npt.NDArray[np.float64]) -> None:
        """Raises the clear error for a NaN or inf in the checked actions (F, 2), naming
        the followers that sent one (:func:`~boids_env.commands.commands_from_actions`
        calls it where the actions may hold one)."""
        if not np.isfinite(actions).all():
            bad = [a for a, row in zip(self.agents, actions, strict=True)
                   if not np.isfinite(row).all()]
            raise ValueError(f"actions must be finite; NaN or inf from {bad}")

    def _observe(self) -> npt.NDArray[np.float32]:
        episode = self._episode
        assert episode is not None
        world, observer = episode.world, episode.observer
        crowd = self.crowd
        headings = world.heading_vectors
        velocities = world.velocities
        if headings is not None:  # what a controller reads from odometry (REP 105)
            velocities = odometry_velocities(velocities, headings)
        obs = observer(world.positions, velocities, crowd, headings)
        # a stale row keeps the sight it was seen with (the observer's leader_hidden)
        return obs if episode.realism is None else episode.realism.observations(obs, observer)

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
        episode = self._require_episode()
        world, counts = episode.world, episode.rewards.counts
        steps = max(world.steps, 1)
        out: dict[str, Any] = {}
        for row, name in enumerate(metrics.VIOLATIONS):
            out[metrics.V_KEYS[name]] = float(counts[row].sum() / steps)
            out[metrics.COUNT_KEYS[name]] = counts[row].tolist()
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
        return None if self._episode is None else self._episode.observer.leader_hidden

    @property
    def leader(self) -> Leader:
        """The current episode's leader (e.g. an ExternalLeader to steer)."""
        return self._require_episode().leader

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

    @property
    def episode(self) -> Episode | None:
        """The live episode's parts (:class:`~boids_env.episode_state.Episode`: its world,
        leader, observer, rewards, ...), None before the first reset; what the batch and
        fused paths read. Read it, change nothing in it."""
        return self._episode

    def _require_episode(self) -> Episode:
        if self._episode is None:
            raise RuntimeError("no episode yet; call reset() first")
        return self._episode

    def _require_world(self) -> World:
        return self._require_episode().world

    # The live episode's parts by the names the step's commands read (_before_physics,
    # _speed_limited; the leader's still steps feed the parked reward term), after a reset.
    _world = property(attrgetter("_episode.world"))
    _leader = property(attrgetter("_episode.leader"))
    _people = property(attrgetter("_episode.people"))
    _scene = property(attrgetter("_episode.scene"))
    _observer = property(attrgetter("_episode.observer"))
    _still_steps = property(attrgetter("_episode.rewards.still_steps"),
                            lambda self, steps: setattr(self._episode.rewards, "still_steps",
                                                        steps))

    # ------------------------------------------------------------------------- rendering
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            warnings.warn("render() called without a render_mode; pass render_mode='human' or "
                          "'rgb_array' to the constructor", UserWarning, stacklevel=2)
            return None
        if self._episode is None:
            raise RuntimeError("render() called before reset()")
        from boids_env.render import Frame, Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, self.config.scene)
            self._renderer.fps = self.metadata["render_fps"]
        world = self._episode.world
        m = self.episode_metrics()
        status = (f"t = {m['duration']:5.1f} s   V_sep {m['V_sep']:.3f}   V_coh {m['V_coh']:.3f}"
                  f"   V_align {m['V_align']:.3f}")
        sc = self.episode_config.scenario
        frame = Frame(world.positions, world.steps, self.episode_config.world.robot_radius,
                      status, self.episode_config.observation.horizon, dict(self.overlays),
                      tuple(self.hud_text), sc.leader_radius,
                      world.pedestrian_positions if world.p else None, sc.person_radius,
                      world.headings)
        return self._renderer.draw(frame)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # --------------------------------------------------------------------------- pickle
    def __getstate__(self) -> dict[str, Any]:
        # the episode's world is rebuilt and its commands replayed (Episode.__setstate__)
        state = self.__dict__.copy()
        state["_renderer"] = None
        state["_fused"] = None  # rebuilt on use: its counts are views of the episode's
        return state


def parallel_env(render_mode: str | None = None, **kwargs: Any) -> BoidsEnv:
    """The parallel env; keyword arguments are config fields by flat name (``robots=19``)."""
    return BoidsEnv(render_mode=render_mode, **kwargs)


def raw_env(render_mode: str | None = None, **kwargs: Any) -> Any:
    """The AEC version of :func:`parallel_env` without PettingZoo's order-enforcing wrapper."""
    return BoidsAECWrapper(parallel_env(render_mode=render_mode, **kwargs))


def env(render_mode: str | None = None, **kwargs: Any) -> Any:
    """The AEC version (PettingZoo's order-enforcing wrapper over :func:`raw_env`)."""
    return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **kwargs))


__all__ = ["REWARD_INFO_KEYS", "ArrayStep", "BoidsAECWrapper", "BoidsEnv", "env", "parallel_env",
           "raw_env"]
