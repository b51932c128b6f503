"""One episode's rewards: the scales of its terms, each step's terms (9, F) and the agents'
info dicts.

A follower's reward is the sum of nine terms, in :data:`REWARD_INFO_KEYS` order: the study's
three (−weight · flag · dt of the violation flags of :mod:`boids_env.metrics`, the flags also
counted for the episode's V_*), then the opt-in ones, which stay zero rows unless their weight
is set (nothing is computed for them then). :class:`Rewards` holds one episode's scales and
counts; :class:`~boids_env.environment.BoidsEnv` makes one per episode, and the fused path
(:mod:`boids_env.fused`) reads its scales and counts in its place where the kernels compute
the study's terms of many copies at once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from boids_env import kernels, metrics, proxemics

if TYPE_CHECKING:
    from boids_env.config import EnvConfig
    from boids_env.world.space import World

FloatArray = npt.NDArray[np.float64]

REWARD_INFO_KEYS = ("reward_separation", "reward_cohesion", "reward_alignment",
                    "reward_proximity", "reward_contact", "reward_wall", "reward_gap",
                    "reward_intrusion", "reward_parked")
"""The per-term rewards every follower's info holds, after reset and after every step: the
study's three, then the safety terms (0 unless ``reward="safe"`` or their weights are set),
then the cohesion gap (0 unless ``reward_gap`` is set), the intrusion into the leader's or a
pedestrian's personal space (0 unless ``reward_intrusion`` is set) and the parked term (0
unless ``reward_parked`` is set)."""


class Rewards:
    """The reward of one episode of ``config`` for ``followers`` followers.

    Args:
        config: the episode's config (its metrics' weights and thresholds, ``dt``).
        followers: the number of followers (the columns of :attr:`counts`).
    """

    def __init__(self, config: EnvConfig, followers: int) -> None:
        mc, wc = config.metrics, config.world
        self.config = config
        self._metrics = mc
        self._scene = config.scene
        self.scale = metrics.reward_scale(mc, wc.dt)
        """(3, 1) −weight · dt of the study's three flags."""
        self.violation_scale = np.ascontiguousarray(self.scale[:, 0])
        """(3,) the same, as the kernels take it."""
        self.safety_scale = -np.array(mc.safety_weights)[:, None] * wc.dt
        """(3, 1) −weight · dt of the proximity, contact and wall flags."""
        self.safety_on = bool(self.safety_scale.any())
        self.gap_scale = -mc.reward_gap * wc.dt
        self.intrusion_scale = -mc.reward_intrusion * wc.dt
        self.parked_scale = -mc.reward_parked * wc.dt
        self.parked_steps = round(mc.parked_after / wc.dt)
        """Steps the leader stands still before the parked term counts."""
        self.study_only = not (self.safety_on or self.gap_scale or self.intrusion_scale
                               or self.parked_scale)
        """No opt-in term is on: rows 3..8 stay zero."""
        self.wall_reach = max(mc.wall_distance, wc.robot_radius + metrics.CONTACT_TOLERANCE)
        """How near static geometry a follower's centre is flagged at a wall: the metrics'
        ``wall_distance``, at least touching (the robot's radius and the contact tolerance)."""
        self._contact = 2 * wc.robot_radius + metrics.CONTACT_TOLERANCE
        self._radius = wc.robot_radius
        self.counts = np.zeros((3, followers), dtype=np.int64)
        """(3, F) each follower's violating steps so far, in ``metrics.VIOLATIONS`` order (the
        episode's V_*); the fused path may rebind it to a view of its own counts."""
        self.codes: npt.NDArray[np.intp] | None = None
        """The last step's violation flags as bits (separation 1, cohesion 2, alignment 4)
        where a kernel computed them (:meth:`terms`'s or the fused call's; else None): they
        pick each agent's info dict (:meth:`infos`)."""
        self.still_steps = 0
        """Steps the leader's command has been zero (counted by the env's step)."""
        self._templates: list[dict[str, float]] | None = None

    def terms(self, world: World) -> FloatArray:
        """The step's reward terms (9, F) in :data:`REWARD_INFO_KEYS` order after the
        physics of ``world``; adds the study's flags to :attr:`counts`."""
        positions = world.positions
        terms = np.zeros((len(REWARD_INFO_KEYS), len(positions) - 1))
        mc = self._metrics
        compiled = kernels.compiled()
        self.codes = None
        if compiled is not None and mc.alignment_source == "command":
            # the same bits in one loop; the angles from numpy's arctan2 (boids_env.kernels)
            cmd = world.commanded
            codes = np.empty(len(positions) - 1, dtype=np.intp)
            compiled.violations(positions, cmd, np.arctan2(cmd[:, 1], cmd[:, 0]),
                                mc.separation_threshold, mc.cohesion_threshold,
                                mc.alignment_threshold_deg, mc.wrap_alignment,
                                self.violation_scale, self.counts, codes, terms)
            self.codes = codes  # the flags' bits: they pick the info dicts (infos)
        else:
            flags = metrics.flags_for(mc, positions, world.commanded, world.headings)
            stacked = np.stack([flags[name] for name in metrics.VIOLATIONS])
            self.counts += stacked
            np.multiply(self.scale, stacked, out=terms[:3])
        if (compiled is not None and (self.safety_on or self.gap_scale)
                and not self.config.observation.route_leader
                and len(positions) < metrics.KD_TREE_MIN_ROBOTS):
            self._safety_gap_compiled(compiled, positions, terms)
        else:
            if self.safety_on:
                terms[3:6] = self.safety_terms(positions)
            if self.gap_scale:
                terms[6:7] = self.gap_term(positions)
        if self.intrusion_scale:
            terms[7:8] = self.intrusion_term(positions, world.pedestrian_positions)
        if self.parked_scale:
            terms[8:9] = self.parked_term(positions, world.velocities)
        return terms

    def safety_terms(self, positions: FloatArray) -> FloatArray:
        """The safety reward terms (3, F): −weight · flag · dt (called when a weight is set)."""
        flags = metrics.safety_flags(positions, self._radius, self._metrics.safety_distance,
                                     self._scene.within(positions[1:], self.wall_reach))
        return self.safety_scale * np.stack([flags[name] for name in metrics.SAFETY_FLAGS])

    def _safety_gap_compiled(self, compiled: Any, positions: FloatArray,
                             terms: FloatArray) -> None:
        """:meth:`safety_terms` and :meth:`gap_term` (the straight distance) into ``terms``
        in one compiled call, the same bits (below the KD-tree's size)."""
        mc = self._metrics
        safety = self.safety_on
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        if safety:
            near = np.ascontiguousarray(self._scene.within(pos[1:], self.wall_reach),
                                        dtype=np.bool_)
        else:
            near = np.zeros(len(pos) - 1, dtype=np.bool_)
        compiled.safety_gap_terms(
            pos, near, np.ascontiguousarray(self.safety_scale[:, 0]),
            float(mc.safety_distance), self._contact, safety, float(self.gap_scale),
            float(mc.cohesion_threshold), bool(self.gap_scale), terms)

    def gap_term(self, positions: FloatArray) -> FloatArray:
        """The cohesion-gap reward term (1, F): −weight · metres beyond the cohesion threshold
        · dt (called when its weight is set)."""
        threshold = self._metrics.cohesion_threshold
        gap = np.maximum(self.leader_distances(positions) - threshold, 0.0)
        return self.gap_scale * gap[None]

    def leader_distances(self, positions: FloatArray) -> FloatArray:
        """Each follower's distance to the leader (F,): the straight line, or with
        ``route_leader`` the route's length for a follower that does not see the leader."""
        cfg = self.config
        distance = metrics.leader_distance(positions)
        if cfg.observation.route_leader:
            from boids_env.world.route import leader_in_sight, route_grid, sense_route

            grid = route_grid(cfg.scene, cfg.world.robot_radius, cfg.observation.route_cell)
            hidden = ~leader_in_sight(grid, positions)
            if hidden.any():
                distance = np.where(hidden, sense_route(grid, positions)[1], distance)
        return distance

    def intrusion_term(self, positions: FloatArray, pedestrians: FloatArray) -> FloatArray:
        """The intrusion reward term (1, F): −weight · dt while a follower's centre is within
        ``intrusion_distance`` of the leader's (a person's personal space) or of a
        pedestrian's (called when its weight is set)."""
        flags = proxemics.intrusion_flags(positions, pedestrians,
                                          self._metrics.intrusion_distance)
        # a float times a bool array is float64 (numpy's stubs say only "floating")
        return cast("FloatArray", self.intrusion_scale * flags[None])

    def parked_term(self, positions: FloatArray, velocities: FloatArray) -> FloatArray:
        """The parked reward term (1, F): −weight · follower speed · dt once the leader's
        command has been zero for more than ``parked_after``, zeros before (called when its
        weight is set)."""
        if self.still_steps <= self.parked_steps:
            return np.zeros((1, len(velocities) - 1))
        speed = np.sqrt(np.einsum("fd,fd->f", velocities[1:], velocities[1:]))
        within = self._metrics.parked_within
        if within > 0:  # only the followers already around the leader park
            speed = np.where(self.leader_distances(positions) <= within, speed, 0.0)
        return self.parked_scale * speed[None]

    def infos(self, agents: list[str], terms: FloatArray) -> dict[str, dict[str, Any]]:
        """Each agent's info dict: its reward terms (9, F) by :data:`REWARD_INFO_KEYS`."""
        k0, k1, k2, k3, k4, k5, k6, k7, k8 = REWARD_INFO_KEYS
        if self.study_only:
            codes = self.codes
            if codes is not None and len(codes) == len(agents):
                # the kernel's flags (bits 1, 2, 4) pick one of 8 dicts of the same floats
                # (scale × 1.0 or × 0.0, as the kernel multiplies), copied per agent
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
        the products the kernel's terms are (−0.0 for an unflagged term), built once."""
        if self._templates is None:
            values = self.violation_scale.tolist()
            templates = []
            for code in range(8):
                info = dict.fromkeys(REWARD_INFO_KEYS, 0.0)
                for row in range(3):
                    info[REWARD_INFO_KEYS[row]] = values[row] * (1.0 if code >> row & 1 else 0.0)
                templates.append(info)
            self._templates = templates
        return self._templates

    def __getstate__(self) -> dict[str, Any]:
        # the codes may be a view of a fused call's array: the next step writes them anew
        return {**self.__dict__, "codes": None}
