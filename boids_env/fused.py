"""The study's after-physics work of one env or many in one compiled call.

After the physics, a step computes every follower's violation flags and reward terms and
its next observation. For the common layouts that is three kernels of
:mod:`boids_env._compiled.study` (the neighbour search, the observation blocks, the flags)
with a few numpy calls between; :class:`Fused` makes them one call (``batch_after``), for
one env (:meth:`BoidsEnv._outcome <boids_env.environment.BoidsEnv._outcome>`) or for K
copies at once (:class:`boids_env.batch.EnvBatch`): the same kernels, copy by copy, in one
loop, so the bits are each env's own. It reads each env's live episode
(:attr:`BoidsEnv.episode <boids_env.environment.BoidsEnv.episode>`): its world, observer and
:class:`~boids_env.rewards.Rewards` (the scales, and the counts it adds to).

A copy is fused when its step needs nothing else (:func:`fusable`): holonomic robots below
``KD_TREE_MIN_ROBOTS``, the study's blocks only (any number of neighbour slots, the world or
the leader frame, relative actions or not), no sensing noise, realism or crowd, the
alignment rule on the commands, and none of the opt-in reward terms (the safety terms, the
gap, intrusion and parked terms). Any other env computes them with its own code.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from boids_env.observations import KD_TREE_MIN_ROBOTS, rotation

if TYPE_CHECKING:
    from boids_env.episode_state import Episode


def fusable(env: Any) -> bool:
    """Whether ``env``'s (a :class:`~boids_env.environment.BoidsEnv` with a live episode)
    observations, flags and reward terms after its physics are what ``batch_after``
    computes (the module doc's list)."""
    cfg, episode = env.episode_config, env.episode
    obs, lay = cfg.observation, episode.observer.layout
    return (not cfg.world.has_heading and cfg.scenario.robots < KD_TREE_MIN_ROBOTS
            and lay.study_only
            and obs.obs_noise == 0 and not obs.route_leader and obs.frame in ("world", "leader")
            and cfg.metrics.alignment_source == "command" and episode.realism is None
            and episode.people is None and episode.rewards.study_only)


class Fused:
    """The constants of one fused call: which copies, where their rows go, their
    thresholds, bounds and reward scales, and one counts array whose column blocks are the
    fused copies' own :attr:`Rewards.counts <boids_env.rewards.Rewards.counts>` (rebound to
    views of it, their values kept).

    Build it with :meth:`current`, which keeps it while no copy was reset."""

    def __init__(self, envs: list[Any], bounds: list[int]) -> None:
        self.member = np.array([fusable(env) for env in envs], dtype=bool)
        self.index = np.flatnonzero(self.member).tolist()
        self.chosen = [envs[i] for i in self.index]
        self.episodes: list[Episode] = [env.episode for env in self.chosen]
        """The fused copies' live episodes (their worlds, observers and rewards)."""
        cfgs = [env.episode_config for env in self.chosen]
        robots = np.cumsum([0, *(c.scenario.robots for c in cfgs)])
        layouts = [ep.observer.layout for ep in self.episodes]
        self.ints = np.array([[robots[j], robots[j + 1], bounds[i],
                               c.observation.frame == "leader", lay.neighbours,
                               lay.neighbours_start]
                              for j, (i, c, lay) in enumerate(zip(self.index, cfgs, layouts,
                                                                  strict=True))],
                             dtype=np.intp).reshape(-1, 6)
        self.params = np.array([
            [c.observation.horizon, c.observation.velocity_bound, ep.observer.reach,
             c.metrics.separation_threshold, c.metrics.cohesion_threshold,
             c.metrics.alignment_threshold_deg, float(c.metrics.wrap_alignment),
             *ep.rewards.violation_scale, 0.0, 0.0, 0.0, 0.0]
            for ep, c in zip(self.episodes, cfgs, strict=True)], dtype=np.float64).reshape(-1, 14)
        size = layouts[0].size if layouts else 0
        self.bounds = np.array([[ep.observer.space.low, ep.observer.space.high]
                                for ep in self.episodes], dtype=np.float32)
        self.bounds = self.bounds.reshape(len(self.chosen), 2, size)
        self.rotating = np.flatnonzero(self.ints[:, 3]).tolist()
        self.relative = [j for j, c in enumerate(cfgs) if c.observation.relative_actions]
        self.counts = np.zeros((3, bounds[-1]), dtype=np.int64)
        self.codes = np.zeros(bounds[-1], dtype=np.intp)
        """Each row's three violation flags as bits (1, 2, 4), rewritten by every run."""
        for i in self.index:
            rewards = envs[i].episode.rewards
            self.counts[:, bounds[i]:bounds[i + 1]] = rewards.counts
            rewards.counts = self.counts[:, bounds[i]:bounds[i + 1]]
        self.keys = [(env.episode, env.episode.rewards.counts) for env in envs]
        """Each copy's episode and counts as the plan was built (another plan may rebind
        the counts since: then this one no longer adds to them)."""

    @classmethod
    def current(cls, plan: Fused | None, envs: list[Any], bounds: list[int]) -> Fused:
        """``plan`` if every copy has the episode and counts it was built with (no reset,
        no other plan since), else a new one."""
        if plan is not None and all(
                episode is env.episode and counts is episode.rewards.counts
                for (episode, counts), env in zip(plan.keys, envs, strict=True)):
            return plan
        return cls(envs, bounds)

    def run(self, compiled: Any, observations: npt.NDArray[np.float32],
            terms: npt.NDArray[np.float64]) -> None:
        """Fills the fused copies' rows of ``observations`` (rows, D) and ``terms``
        (9, rows), and adds to their counts, in one compiled call; the leader frames turn
        first, and relative actions keep the leader velocity each follower observed."""
        episodes = self.episodes
        for j in self.rotating:
            observer = episodes[j].observer
            observer.follow(episodes[j].world.velocities)
            self.params[j, 10:14] = rotation(observer.heading).ravel()
        if len(episodes) == 1:
            world = episodes[0].world
            positions, velocities, commanded = world.positions, world.velocities, \
                world.commanded
            angle = np.arctan2(commanded[:, 1], commanded[:, 0])
        else:
            worlds = [ep.world for ep in episodes]
            commands = [w.commanded for w in worlds]
            positions = np.concatenate([w.positions for w in worlds])
            velocities = np.concatenate([w.velocities for w in worlds])
            commanded = np.concatenate(commands)
            # numpy's arctan2 copy by copy, as each env calls it alone (its SIMD loop's
            # bits then never depend on a row's place in a longer array)
            angle = np.concatenate([np.arctan2(c[:, 1], c[:, 0]) for c in commands])
        compiled.batch_after(positions, velocities, commanded, angle, self.ints, self.params,
                             self.bounds, self.counts, self.codes, observations, terms)
        for j in self.relative:
            start, observer = self.ints[j, 2], episodes[j].observer
            block = observations[start:start + len(self.chosen[j].possible_agents)]
            observer._leader_velocity = block[:, observer.layout.leader_velocity].astype(
                np.float64)
