"""The study's reference controller: three Reynolds rules plus leader following.

Computed from observations only, through the named layout, for all followers in one numpy pass.
Per follower, with neighbours j (0 < |r_j| ≤ horizon, the leader included), r_j relative
position, v_j their velocity, v own velocity and clip(x, L) = x·L/|x| when |x| > L:

- cohesion   F_coh = (max_force / horizon) · mean_j r_j                (0 without neighbours)
- separation F_sep = clip(mean_{|r_j| < d_sep} (−r_j / |r_j|³), 2·max_force)   (0 if none)
- alignment  F_ali = clip(u − v, max_force), u = Σ_j v_j rescaled to max_speed (direction +x
  when the sum is zero, as the original; 0 without neighbours)
- leader     F_lead = p_leader − p_i (metres, unscaled)
- F = clip(Σ w·F, max_force);  command = clip(v + F / mass · dt, max_speed)
- zero command for the first ``startup_time`` seconds after reset.

Beyond the study, preset ``route`` (``follow_route``): the leader term aims along the route
through free space (the observation's ``route`` block, :mod:`boids_env.world.route`),
F_lead = d·L with d the route's unit direction and L its length, so a follower behind a wall
seeks the door rather than the wall (the straight line where no free route exists).

Beyond the study, preset ``scaled`` (issue 38) sizes the controller for the robot
(``scale_to_robot``, :func:`sized_params`: the study's distances kept as free gaps between
bodies) and follows the route with the proxemic leader term along it: F_lead = r − s·r/|r|
with r the route term above, plus the push out of the leader's path ahead (below), so a
follower steps aside for a leader backing out of a dead end instead of fleeing before it.
For a robot with a heading (it must turn before it moves; ``path_width`` > 0,
:func:`clear_path`) the strip ahead is ``path_width`` wide (sized), ``path_time`` grown by
the quarter-turn time long, lies along the leader's heading while it stands or turns in
place, and inside it the ring's pull is dropped and a push ``path_flee``·(length − a) along
the leader's travel is added; the ring's radius grows by ``max_speed`` × the quarter-turn
time; and with ``walls_first`` the walls' push is served before the other robots'
(:func:`walls_then_robots`).

Beyond the study (on in any scene but the study's empty arena, see ``obstacle_avoidance``):
- obstacle   F_obs = −max_force · Σ_m s_m · n_m over the static slots m (n_m the unit vector
  towards the surface point at distance d_m, u_m = max(0, v·n_m) the approach speed),
  s_m = clip(1 − (d_m − u_m·lookahead) / obstacle_distance, 0, 1)
- served first: a = clip(w_obs·F_obs, max_force), F = a + clip(Σ w·F, max_force − |a|)
  (Reynolds' prioritised acceleration allocation: near a wall, avoiding it wins).
- pedestrians (with a crowd's pedestrian slots): the nearest point of each pedestrian's body
  is one more obstacle point of F_obs, so followers steer around people as around walls.

A person as the leader: the study's leader term seeks the leader's centre, so out of the box
the flock follows a person as it follows a robot, as close as separation lets it (the
person is one more neighbour its separation pushes from below 0.7 m). The opt-in
proxemics-aware variant (``personal_space`` s > 0, preset ``proxemic``: 1.2 m, Hall's personal
zone) replaces it with
- leader     F_lead = r − s·r/|r| (r = p_leader − p_i): it seeks the circle of radius s
  around the person, pulling in from outside and pushing out from inside, plus, while the
  person walks (speed u ≥ 0.2 m/s, direction e), a sideways push (s − |c|)·sign(c)·n out of
  the strip ahead of it (0 < a ≤ 2 s·u + s, |c| < s, with a and c the follower's position
  along e and across it, n the unit normal on the follower's side).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.observations import ObservationLayout
from boids_env.policies import kernels
from boids_env.policies.base import BatchPolicy
from boids_env.policies.reynolds_params import (
    DEFAULT_TIMING,
    ENV_OWNED,
    PRESETS,
    ReynoldsParams,
    Timing,
    bound_params,
    reynolds_params,
    sized_params,
    turn_time,
    within,
)
from boids_env.world.scenario import holding

FloatArray = npt.NDArray[np.float64]
RULES = ("separation", "cohesion", "alignment", "leader")
"""The study's rules, in the order their forces are summed."""
OBSTACLE = "obstacle"
"""The obstacle-avoidance rule (beyond the study): its force is served first."""


def clip_norm(x: FloatArray, limit: float) -> FloatArray:
    """Scales rows of ``x`` (..., 2) whose norm exceeds ``limit`` down to ``limit``."""
    norm = np.sqrt(x[..., 0] * x[..., 0] + x[..., 1] * x[..., 1])
    # min(1, limit / norm) is exactly 1 where the norm is within the limit (or zero)
    scale = np.minimum(1.0, limit / np.maximum(norm, 1e-300))
    return x * scale[..., None]


def reynolds_forces(rel: FloatArray, vel: FloatArray, valid: npt.NDArray[np.bool_],
                    own_velocity: FloatArray, leader_offset: FloatArray, p: ReynoldsParams
                    ) -> dict[str, FloatArray]:
    """The four unweighted rule forces (F, 2) from neighbour arrays.

    Args:
        rel: (F, K, 2) neighbour positions relative to each follower (m).
        vel: (F, K, 2) neighbour velocities (m/s).
        valid: (F, K) which slots hold a neighbour.
        own_velocity: (F, 2) each follower's velocity.
        leader_offset: (F, 2) leader position relative to each follower.
        p: controller parameters.
    """
    dist = np.sqrt(np.einsum("fkd,fkd->fk", rel, rel))
    near = valid & (dist > 0) & (dist <= p.horizon)
    nearf = near.astype(float)
    count = nearf.sum(axis=1)[:, None]
    has = count > 0
    # Sums over the neighbour slots as (F, K) x (F, K, 2) contractions.
    mean_rel = np.einsum("fk,fkd->fd", nearf, rel) / np.maximum(count, 1)
    cohesion = (p.max_force / p.horizon) * mean_rel

    close = near & (dist < p.desired_separation)
    n_close = close.sum(axis=1)[:, None]
    inv_cube = np.divide(1.0, dist * dist * dist, out=np.zeros_like(dist), where=close)
    push = -np.einsum("fk,fkd->fd", inv_cube, rel) / np.maximum(n_close, 1)
    separation = clip_norm(push, 2 * p.max_force)

    total = np.einsum("fk,fkd->fd", nearf, vel)
    norm = np.sqrt(np.einsum("fd,fd->f", total, total))[:, None]
    direction = np.where(norm > 0, total / np.where(norm > 0, norm, 1.0), [1.0, 0.0])
    alignment = clip_norm(direction * p.max_speed - own_velocity, p.max_force) * has
    return {"separation": separation, "cohesion": cohesion, "alignment": alignment,
            "leader": np.array(leader_offset, dtype=float)}


PATH_TIME = 2.0
"""The proxemics-aware leader term keeps this many seconds of the person's walking clear."""
WALKING_SPEED = 0.2
"""The person counts as walking from this speed (m/s) on."""


def proxemic_leader_force(leader_offset: FloatArray, leader_velocity: FloatArray,
                          space: float) -> FloatArray:
    """The proxemics-aware leader term (F, 2) in metres: towards the circle of radius
    ``space`` around the person, and sideways out of its path ahead (see the module
    docstring).

    Args:
        leader_offset: (F, 2) the person's position relative to each follower (m).
        leader_velocity: (F, 2) the person's velocity as each follower observes it (m/s).
        space: the personal space's radius s (m).
    """
    return ring_force(leader_offset, space) + path_push(leader_offset, leader_velocity, space)


def ring_force(offset: FloatArray, space: float) -> FloatArray:
    """``offset`` (F, 2) shortened by ``space`` along itself: towards the circle of radius
    ``space`` around its end (from inside: away from it)."""
    rx, ry = offset[:, 0], offset[:, 1]
    dist = np.sqrt(rx * rx + ry * ry)
    scale = np.where(dist > 0, 1.0 - space / np.where(dist > 0, dist, 1.0), 0.0)
    return offset * scale[:, None]


def path_push(leader_offset: FloatArray, leader_velocity: FloatArray, space: float
              ) -> FloatArray:
    """The sideways push (F, 2) out of the strip of half-width ``space`` ahead of a walking
    leader (the proxemics-aware leader term's second part, module docstring)."""
    rx, ry = leader_offset[:, 0], leader_offset[:, 1]
    vx, vy = leader_velocity[:, 0], leader_velocity[:, 1]
    speed = np.sqrt(vx * vx + vy * vy)
    walking = speed >= WALKING_SPEED
    ex = np.where(walking, vx / np.where(walking, speed, 1.0), 0.0)
    ey = np.where(walking, vy / np.where(walking, speed, 1.0), 0.0)
    along = -(rx * ex + ry * ey)  # the follower relative to the person, along its walk
    across = -(ry * ex - rx * ey)  # … and to its left (+) or right (−)
    ahead = walking & (along > 0) & (along <= PATH_TIME * speed + space) & (
        np.abs(across) < space)
    side = np.where(across >= 0, 1.0, -1.0)
    push = np.where(ahead, (space - np.abs(across)) * side, 0.0)
    return np.stack([-ey * push, ex * push], axis=1)


WALL_YIELD = 0.25
"""With ``walls_first``: the fraction of a neighbour's push against a wall's push that is
dropped (all of it squeezes robots into each other, none holds them against the wall)."""


def clear_path(route: FloatArray, leader_offset: FloatArray, leader_velocity: FloatArray,
               leader_heading: FloatArray, p: ReynoldsParams) -> FloatArray:
    """The leader term (F, 2, in m) along the route for robots that turn before they move
    (``path_width`` > 0, robots with a heading): the ring of radius ``personal_space`` round
    the leader, except inside the strip ahead of it, which is pushed clear sideways (to
    ``path_width`` from its line) and forwards (``path_flee`` × the strip left ahead).

    The strip lies along the leader's velocity while it moves (from ``path_speed``), along
    its heading while it stands or turns in place (it drives off along it), and reaches
    ``path_time`` × max(its speed, ``max_speed``) + ``personal_space`` ahead of it.

    Args:
        route: (F, 2) the route term (direction × length to the leader along the route).
        leader_offset: (F, 2) the leader relative to each follower (m, straight line).
        leader_velocity: (F, 2) the leader's velocity (m/s).
        leader_heading: (F, 2) the leader's heading (unit vectors).
        p: controller parameters (sized for the robot).
    """
    rx, ry = leader_offset[:, 0], leader_offset[:, 1]
    vx, vy = leader_velocity[:, 0], leader_velocity[:, 1]
    speed = np.sqrt(vx * vx + vy * vy)
    moving = speed >= p.path_speed
    ex = np.where(moving, vx / np.where(moving, speed, 1.0), leader_heading[:, 0])
    ey = np.where(moving, vy / np.where(moving, speed, 1.0), leader_heading[:, 1])
    along = -(rx * ex + ry * ey)  # the follower relative to the leader, along its travel
    across = -(ry * ex - rx * ey)  # … and to its left (+) or right (−)
    length = p.path_time * np.maximum(speed, p.max_speed) + p.personal_space
    ahead = (along > 0) & (along <= length) & (np.abs(across) < p.path_width)
    side = np.where(across >= 0, 1.0, -1.0)
    sideways = np.where(ahead, (p.path_width - np.abs(across)) * side, 0.0)
    forwards = np.where(ahead, p.path_flee * (length - along), 0.0)
    ring = np.where(ahead[:, None], 0.0, ring_force(route, p.personal_space))
    return ring + np.stack([-ey * sideways + ex * forwards, ex * sideways + ey * forwards],
                           axis=1)


def pedestrian_points(slots: FloatArray, radius: float) -> tuple[FloatArray,
                                                                 npt.NDArray[np.bool_]]:
    """The nearest point of each pedestrian's body (F, P, 2) and which slots hold one, from
    pedestrian slots (F, P, 5) (a follower inside a body gets its centre)."""
    rel, valid = slots[..., 0:2], slots[..., 4] > 0.5
    dist = np.sqrt(rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1])
    scale = np.maximum(dist - radius, 0.0) / np.where(dist > 0, dist, 1.0)
    return rel * scale[..., None], valid


def obstacle_force(offsets: FloatArray, valid: npt.NDArray[np.bool_], own_velocity: FloatArray,
                   p: ReynoldsParams) -> FloatArray:
    """The unweighted obstacle-avoidance force (F, 2) from the static slots.

    Args:
        offsets: (F, M, 2) offsets from each follower to the nearest surface points (m).
        valid: (F, M) which slots hold a point.
        own_velocity: (F, 2) each follower's velocity, or (F, M, 2) its velocity relative to
            each point (a pedestrian's moves).
        p: controller parameters.
    """
    dist = np.sqrt(np.einsum("fmd,fmd->fm", offsets, offsets))
    towards = np.divide(offsets, dist[..., None], out=np.zeros_like(offsets),
                        where=(dist > 0)[..., None])
    closing = (np.einsum("fmd,fmd->fm", towards, own_velocity) if own_velocity.ndim == 3
               else np.einsum("fmd,fd->fm", towards, own_velocity))
    approach = np.maximum(closing, 0.0)
    effective = dist - approach * p.obstacle_lookahead
    strength = np.clip(1.0 - effective / p.obstacle_distance, 0.0, 1.0) * valid
    return -p.max_force * np.einsum("fm,fmd->fd", strength, towards)


def walls_then_robots(walls: FloatArray, robots: FloatArray, limit: float) -> FloatArray:
    """The obstacle force (F, 2) with walls served before robots: ``walls`` clipped to
    ``limit``, then ``robots`` without its part against the walls' push (a neighbour never
    pushes a follower into a wall), within what is left of ``limit``."""
    first = clip_norm(walls, limit)
    norm = np.sqrt(first[:, 0] * first[:, 0] + first[:, 1] * first[:, 1])
    unit = first / np.where(norm > 0, norm, 1.0)[:, None]
    against = np.minimum(np.einsum("fd,fd->f", robots, unit), 0.0) * WALL_YIELD
    rest = robots - against[:, None] * unit
    return first + clip_norm_each(rest, limit - norm)


def reynolds_command(forces: dict[str, FloatArray], own_velocity: FloatArray,
                     p: ReynoldsParams, robots: FloatArray | None = None,
                     dt: float = DEFAULT_TIMING.dt) -> tuple[FloatArray, dict[str, FloatArray]]:
    """Combines the rule forces into the commanded velocity, integrated over the control
    period ``dt`` (s); returns it and weighted forces. An ``obstacle`` force, when given, is
    served first (the others share the rest of ``max_force``); ``robots`` (other robots as
    obstacle points, ``walls_first``) after the walls' and people's part of it."""
    weights = {"separation": p.separation_weight, "cohesion": p.cohesion_weight,
               "alignment": p.alignment_weight, "leader": p.leader_weight}
    weighted = {name: weights[name] * forces[name] for name in RULES}
    total = clip_norm(sum(weighted.values()), p.max_force)
    if OBSTACLE in forces:
        weighted[OBSTACLE] = p.obstacle_weight * forces[OBSTACLE]
        first = clip_norm(weighted[OBSTACLE], p.max_force)
        if robots is not None:
            first = walls_then_robots(weighted[OBSTACLE], p.obstacle_weight * robots,
                                      p.max_force)
            weighted[OBSTACLE] = first
        left = p.max_force - np.sqrt(first[:, 0] * first[:, 0] + first[:, 1] * first[:, 1])
        rest = clip_norm_each(sum(weighted[name] for name in RULES), left)
        pushed = np.any(first != 0.0, axis=1)[:, None]
        total = np.where(pushed, first + rest, total)  # untouched rows: the study's sum
    command = clip_norm(own_velocity + total / p.mass * dt, p.max_speed)
    return command, weighted


def robot_avoidance_force(slots: FloatArray, own_velocity: FloatArray, radius: float,
                          p: ReynoldsParams) -> FloatArray:
    """Other robots as obstacle points (F, 2): each neighbour's nearest surface point pushes
    as an obstacle does, within ``robot_avoidance`` instead of ``obstacle_distance`` and with
    the speed closing on it (``robot_avoidance``, preset ``route``).

    Args:
        slots: (F, K, 5) neighbour slots.
        own_velocity: (F, 2) each follower's velocity.
        radius: the robots' radius (m).
        p: controller parameters.
    """
    rel, vel = slots[..., 0:2], slots[..., 2:4]
    dist = np.sqrt(rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1])
    valid = (slots[..., 4] > 0.5) & (dist > 0)
    surface = rel * (np.maximum(dist - 2 * radius, 1e-6) / np.where(dist > 0, dist, 1.0))[
        ..., None]
    closing = own_velocity[:, None, :] - vel
    return obstacle_force(surface, valid, closing, within(p, p.robot_avoidance))


def route_leader_force(obs: FloatArray, layout: ObservationLayout) -> FloatArray:
    """The leader term along the route (F, 2): the route block's direction × its length (the
    straight line's where no free route exists, which the block already holds)."""
    if not layout.route:
        raise ValueError("follow_route needs the observations' route block: make the env with "
                         "route_sensing=True (the policy's env_fields)")
    route = obs[:, layout.block("route")]
    return route[:, 0:2] * route[:, 2:3]


def clip_norm_each(x: FloatArray, limits: FloatArray) -> FloatArray:
    """Rows of ``x`` (F, 2) scaled down to their own ``limits`` (F,) where longer."""
    norm = np.sqrt(x[..., 0] * x[..., 0] + x[..., 1] * x[..., 1])
    scale = np.minimum(1.0, limits / np.maximum(norm, 1e-300))
    return x * scale[..., None]


ARENA_STATIC_SLOTS = 4
"""Static slots a route-following preset that always avoids obstacles (``scaled``) asks
the env for, so that it senses the study's arena walls too (any other scene has 4)."""
class ReynoldsPolicy(BatchPolicy):
    """Reynolds + leader controller of the study, reading observations only.

    ``ReynoldsPolicy(preset="paper", **overrides)``: the ``paper`` (Table IV) or ``boids_ros``
    (original code) parameters, any
    :class:`~boids_env.policies.reynolds_params.ReynoldsParams` field
    overridden (``leader_weight=1.2``). After each :meth:`act`, :attr:`forces` holds each
    rule's weighted force per follower (for drawing).

    :meth:`bind` tells it the env's observation layout and scene (``run_episode``, the eval
    runner and the ROS controller do): then it reads static slots and range sensing, and
    avoids obstacles in any scene but the study's arena, and it takes the env's control
    period, start-up time, robots' top speed and sensing horizon (see :meth:`bind`). Unbound,
    it reads the study-era layouts (neighbour slots, at most a wall slot) from the
    observation's size, its own parameters and ``timing``.
    """

    def __init__(self, preset: str = "paper", *, layout: ObservationLayout | None = None,
                 timing: Timing = DEFAULT_TIMING, **overrides: Any) -> None:
        self.params = reynolds_params(preset, **overrides)
        # the parameters before sizing for the robot (scale_to_robot sizes these at each bind)
        self._unsized = self.params
        defaults = ReynoldsParams()
        # the values the controller itself sets (given, or its preset's own): kept when bound
        # where the env allows them, the rest taken from the env
        self._own = frozenset(overrides) | {
            name for name in ENV_OWNED
            if getattr(PRESETS[preset], name) != getattr(defaults, name)}
        self.preset = preset
        self.forces: dict[str, FloatArray] = {}
        self.layout = layout
        self.avoid = bool(self.params.obstacle_avoidance) and bool(layout and layout.static)
        self.pedestrian_radius = 0.22
        self.robot_radius = 0.036
        self.timing = Timing(*timing)
        """The control period and start-up hold it acts on: the env's, read at :meth:`bind`;
        unbound, ``timing`` (the study's 10 Hz and 2 s unless given)."""
        self._steps = 0
        if self.params.follow_route:  # the route preset reads the env's route sensing
            self.env_fields = {"route_sensing": True}
            if self.params.obstacle_avoidance:  # walls sensed in the study's arena too
                self.env_fields["static_slots"] = ARENA_STATIC_SLOTS

    def bind(self, env: Any) -> None:
        """Reads ``env``'s observation layout, whether its scene is the study's arena (any
        object with ``layout`` and ``config``/``episode_config``: a BoidsEnv, the ROS
        controller), its timing (:attr:`timing`: the control period ``dt`` and the
        ``startup_time``) and the quantities the env owns
        (:data:`~boids_env.policies.reynolds_params.ENV_OWNED`): the robots' top speed
        ``max_speed`` and the sensing ``horizon`` unless the controller sets its own (given,
        or the preset's: ``boids_ros``' 0.75 m), which may not exceed the env's. The study's
        case: the same values either way."""
        self.layout = env.layout
        config = getattr(env, "episode_config", None) or env.config
        auto = config.world.scene != "arena"
        wanted = self.params.obstacle_avoidance
        self.avoid = bool(self.layout.static) and (auto if wanted is None else wanted)
        self.pedestrian_radius = config.scenario.person_radius
        self.robot_radius = config.world.robot_radius
        self.timing = Timing.of(config)
        self._unsized = bound_params(self._unsized, self._own, config)
        self.params = self._unsized
        if self.params.scale_to_robot:
            self.params = sized_params(self.params, self.robot_radius, turn_time(config.world))

    def reset(self, seed: int | None = None) -> None:
        self._steps = 0
        self.forces = {}

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        obs = np.asarray(obs, dtype=np.float64)
        layout = self.layout if self.layout is not None else ObservationLayout.for_size(
            obs.shape[1])
        if obs.ndim != 2 or obs.shape[1] != layout.size:
            raise ValueError(f"observations of size {obs.shape[1:]} do not fit the bound layout "
                             f"({layout.size} values); bind the policy to this env")
        p = self.params
        dt, startup_time = self.timing
        held = holding(self._steps * dt, startup_time)
        self._steps += 1
        people = bool(layout.pedestrians)
        crowding = p.robot_avoidance > 0
        rules = (*RULES, OBSTACLE) if self.avoid or people or crowding else RULES
        if held:
            self.forces = {name: np.zeros((len(obs), 2)) for name in rules}
            return np.zeros((len(obs), 2), dtype=np.float32)
        slots = layout.slots(obs)
        own = obs[:, layout.own_velocity]
        compiled = kernels.compiled()
        if compiled is not None:  # the same bits in one loop (policies.kernels)
            forces = dict(zip(("separation", "cohesion", "alignment"), compiled.reynolds_forces(
                np.ascontiguousarray(obs), layout.neighbours_start, layout.neighbours,
                p.horizon, p.desired_separation, p.max_force, p.max_speed), strict=True))
            forces["leader"] = np.array(obs[:, layout.leader_position], dtype=float)
        else:
            forces = reynolds_forces(layout.slot_position(slots), layout.slot_velocity(slots),
                                     layout.slot_valid(slots) > 0.5, own,
                                     obs[:, layout.leader_position], p)
        if p.personal_space > 0:
            forces["leader"] = proxemic_leader_force(obs[:, layout.leader_position],
                                                     obs[:, layout.leader_velocity],
                                                     p.personal_space)
        if p.follow_route:
            forces["leader"] = route_leader_force(obs, layout)
            if p.personal_space > 0 and p.path_width > 0 and layout.headings:
                # a robot that turns before it moves: the path cleared earlier and wider
                forces["leader"] = clear_path(forces["leader"], obs[:, layout.leader_position],
                                              obs[:, layout.leader_velocity],
                                              obs[:, layout.block("leader_heading")], p)
            elif p.personal_space > 0:  # the ring and the clear path ahead, along the route
                forces["leader"] = ring_force(forces["leader"], p.personal_space) + path_push(
                    obs[:, layout.leader_position], obs[:, layout.leader_velocity],
                    p.personal_space)
        if self.avoid or people:
            static = layout.static_slots(obs) if self.avoid else np.zeros((len(obs), 0, 3))
            points, valid, moving = static[..., :2], static[..., 2] > 0.5, own
            if people:
                slots = layout.pedestrian_slots(obs)
                walkers, near = pedestrian_points(slots, self.pedestrian_radius)
                points = np.concatenate([points, walkers], axis=1)
                valid = np.concatenate([valid, near], axis=1)
                relative = own[:, None, :] - layout.slot_velocity(slots)  # closing on people
                moving = np.concatenate([np.broadcast_to(own[:, None, :], static[..., :2].shape),
                                         relative], axis=1)
            forces[OBSTACLE] = obstacle_force(points, valid, moving, p)
        robots = None
        if crowding:
            push = robot_avoidance_force(layout.slots(obs), own, self.robot_radius, p)
            if p.walls_first and OBSTACLE in forces and layout.headings:
                robots = push
            else:
                forces[OBSTACLE] = forces[OBSTACLE] + push if OBSTACLE in forces else push
        command, self.forces = reynolds_command(forces, own, p, robots, dt)
        return command.astype(np.float32)
