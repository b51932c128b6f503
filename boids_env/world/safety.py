"""The opt-in safety filter: between any policy and the robots, it changes each follower's
velocity command as little as it must so that the command does not drive the robot into
static geometry or into another robot.

A control-barrier filter for velocity-controlled (single-integrator) robots, solved for all
followers at once. For each surface point of walls and obstacles within ``safety_range`` (the
nearest ones in up to four directions, as the static slots find them) and each robot within
it, with n the unit vector towards it and gap h its edge distance minus ``safety_margin``, the
command v must satisfy one half-plane:

- a surface point: n·v ≤ α·h (the follower alone keeps its distance);
- another follower: n·v ≤ s + α·h/2, s the smaller of the two robots' measured speeds along
  n (both are filtered, each takes half, and the pair's rows add up to n·(v_i − v_j) ≤
  s_i∧s_j − s_i∨s_j + α·h ≤ α·h: the reciprocal split of ORCA; a flock moving together is
  not slowed, and a robot never pushes one that has stopped in front of it);
- the leader, which is never filtered: n·v ≤ α·h + n·v_leader (its command this step);
- a person leading and the nearest pedestrians, as the leader at their own width or at the
  distance asked (:func:`people_constraints`), and optionally the strip ahead of a walking
  person (``safety_person_path``, :func:`person_path_constraints`): with e its walking
  direction and l a follower's offset across it, σ·e⊥·(v − v_person) ≥ −α·(σ·l − w).

α is ``safety_gain`` (1/s): a robot closes on anything at most α times its gap per second, so
the gap decays at most exponentially and never reaches zero (h ≥ 0 is kept forward
invariant, up to the physics' discretisation). The filtered command is the point of the
constraints' intersection nearest the policy's command, found exactly in 2-D: the command
itself if it is allowed, else the nearest of its projections onto each constraint's line and
of the lines' pairwise crossings that satisfies them all. Where they cannot all hold (a robot
squeezed between the leader or a wall and other followers), the walls and the leader come
first: of the candidates that keep off them, the one that violates the followers' rows least
(they also yield); if none does, the one whose worst violation is least. Its
arithmetic is elementwise (no matrix products, whose summation order may vary between CPUs),
so it is the same on every CPU.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from boids_env import kernels
from boids_env.checks import flag as _flag
from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set
from boids_env.proxemics import CUT_IN_MIN_SPEED
from boids_env.vectors import clip_speed

if TYPE_CHECKING:
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

PEOPLE_ROWS = 4
"""People (a person leading, pedestrians) that constrain each follower: the nearest ones
within reach."""
PATH_MIN_SPEED = CUT_IN_MIN_SPEED
"""A person leading walks (and its path is kept clear, ``safety_person_path``) from this
speed (m/s) on: the cut-in metric's threshold."""
STATIC_POINTS = 4
"""Surface points of static geometry per follower: the nearest in up to four directions
more than 45° apart (a corridor's two walls, a corner's two sides)."""
_FREE = 1e9
"""The bound of an unused constraint (always satisfied)."""
_TOLERANCE = 1e-9
"""A candidate satisfies a constraint within this (m/s)."""
COMPILED_BELOW = 96
"""Below this group size the compiled filter (:mod:`boids_env.kernels`) finds each follower's
robots by all pairs and runs the whole filter in one loop; from it on, the numpy code's
KD-tree."""


@dataclass(frozen=True)
class SafetyConfig:
    """The opt-in safety filter between the policy and the robots (:mod:`~boids_env.world.
    safety`). Off by default: the study's controller ran without one."""

    safety_filter: bool = False
    """Filter every follower's command so that it does not drive the robot into static
    geometry or another robot (a control-barrier filter; see the module). Opt-in."""
    safety_margin: float = 0.03
    """Edge-to-edge (or edge-to-wall) distance (m) the filter keeps as the barrier's zero."""
    safety_gain: float = 2.0
    """α (1/s): a robot may close on a wall or robot at most α × its gap (beyond the margin)
    per second."""
    safety_range: float = 0.5
    """Centre distance (m) within which walls, obstacles and robots constrain a command."""
    safety_neighbours: int = 6
    """The nearest robots within ``safety_range`` that constrain a follower (the leader
    included)."""
    safety_person_distance: float = 0.0
    """Centre distance (m) the filter keeps (plus ``safety_margin``) between a follower and
    a person leading where it exceeds their bodies' (``person_radius`` + the robot's
    radius): 0.45 keeps robots out of the person's intimate zone (Hall) as far as they can
    (a person who walks at one still gets there). 0: their bodies, as for robots."""
    safety_pedestrian_distance: float = 0.0
    """The same for each pedestrian of a crowd (0: their bodies)."""
    safety_person_path: float = 0.0
    """Seconds of a walking person's path ahead that the filter keeps clear (0: off). A
    follower ahead of a person leading who walks (from 0.2 m/s), within the distance the
    person covers in this time plus the distance kept from it, keeps its centre at least
    that kept distance to the side of the person's line of walking: one stepping into the
    strip is held back, one inside it steps out sideways. A robot straight ahead of a
    person walking as fast as it can drive cannot keep its distance by backing away; out
    of the way it can. Its rows yield to the walls, the leader's and the people's rows
    where they cannot all hold."""

    def __post_init__(self) -> None:
        _set(self, "safety_filter", _flag("safety_filter", self.safety_filter))
        _set(self, "safety_margin", _number("safety_margin", self.safety_margin, 0.0, 1.0,
                                            unit="m"))
        _set(self, "safety_gain", _number("safety_gain", self.safety_gain, 0.0, 100,
                                          lo_open=True, unit="1/s"))
        _set(self, "safety_range", _number("safety_range", self.safety_range, 0.0, 10,
                                           lo_open=True, unit="m"))
        _set(self, "safety_neighbours", _integer("safety_neighbours", self.safety_neighbours,
                                                 0, 64))
        for name in ("safety_person_distance", "safety_pedestrian_distance"):
            _set(self, name, _number(name, getattr(self, name), 0.0, 3.0, unit="m"))
        _set(self, "safety_person_path", _number("safety_person_path",
                                                 self.safety_person_path, 0.0, 10.0,
                                                 unit="s"))


def barrier_constraints(positions: FloatArray, velocities: FloatArray,
                        leader_velocity: FloatArray, radius: float, config: SafetyConfig,
                        surfaces: FloatArray, surface_valid: npt.NDArray[np.bool_],
                        leader_row: bool = True,
                        ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """The half-planes a·v ≤ b of every follower's command.

    Args:
        positions: (N, 2) robot positions, the leader first.
        velocities: (N, 2) their measured velocities (m/s).
        leader_velocity: (2,) the leader's command this step (m/s).
        radius: the robots' radius (m).
        config: the filter's parameters.
        surfaces: (F, M, 2) offsets from each follower to surface points (m).
        surface_valid: (F, M) which of them exist.
        leader_row: whether the leader is a robot row (False: a person leads, whose wider
            row :func:`people_constraints` gives).

    Returns:
        ``(a (F, K, 2), b (F, K), hard (F, K))``: unit normals towards each obstacle or robot,
        the bounds (unused rows have a = 0 and b = a large number), and which rows are hard
        (static geometry and the leader; the other followers' rows are soft: they yield too).
    """
    alpha, margin = config.safety_gain, config.safety_margin
    dist_s = np.sqrt(surfaces[..., 0] ** 2 + surfaces[..., 1] ** 2)
    ok_s = np.asarray(surface_valid, dtype=bool) & (dist_s > 0.0)
    safe_d = np.where(ok_s, dist_s, 1.0)
    a_s = np.where(ok_s[..., None], surfaces / safe_d[..., None], 0.0)
    b_s = np.where(ok_s, alpha * (dist_s - radius - margin), _FREE)

    index, dist_r = _neighbours(positions, config.safety_range, config.safety_neighbours)
    ok_r = index >= 0 if leader_row else index > 0
    other = positions[np.where(ok_r, index, 0)]
    offset = other - positions[1:, None, :]
    safe_r = np.where(ok_r, dist_r, 1.0)
    a_r = np.where(ok_r[..., None], offset / safe_r[..., None], 0.0)
    gap = alpha * (dist_r - 2.0 * radius - margin)
    lead = leader_velocity[0] * a_r[..., 0] + leader_velocity[1] * a_r[..., 1]
    own = velocities[1:, None, :]
    theirs = velocities[np.where(ok_r, index, 0)]
    shared = np.minimum(own[..., 0] * a_r[..., 0] + own[..., 1] * a_r[..., 1],
                        theirs[..., 0] * a_r[..., 0] + theirs[..., 1] * a_r[..., 1])
    b_r = np.where(index == 0, gap + lead, 0.5 * gap + shared)
    b_r = np.where(ok_r, b_r, _FREE)
    hard = np.concatenate([np.ones(b_s.shape, dtype=bool), index == 0], axis=1)
    return (np.concatenate([a_s, a_r], axis=1), np.concatenate([b_s, b_r], axis=1), hard)


def _neighbours(positions: FloatArray, reach: float, k: int
                ) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """The ``k`` nearest other robots within ``reach`` of each follower: indices (F, k),
    nearest first, -1 where none, and their distances (inf where none)."""
    followers = len(positions) - 1
    if k == 0 or followers == 0:
        return np.full((followers, k), -1, dtype=np.intp), np.full((followers, k), np.inf)
    width = min(k + 1, len(positions))
    dist, index = cKDTree(positions).query(positions[1:], k=width, distance_upper_bound=reach)
    dist = np.asarray(dist, dtype=float).reshape(followers, width)
    index = np.asarray(index).reshape(followers, width)
    # each row starts with the follower itself at distance 0 (or a robot exactly on it,
    # which cannot be steered away from either): drop those
    keep = (dist > 0.0) & np.isfinite(dist)
    order = np.argsort(~keep, axis=1, kind="stable")[:, :k]
    dist = np.take_along_axis(np.where(keep, dist, np.inf), order, axis=1)
    index = np.take_along_axis(np.where(keep, index, -1), order, axis=1)
    out_d = np.full((followers, k), np.inf)
    out_i = np.full((followers, k), -1, dtype=np.intp)
    out_d[:, :dist.shape[1]], out_i[:, :index.shape[1]] = dist, index
    return out_i, out_d


def nearest_allowed(commands: FloatArray, a: FloatArray, b: FloatArray,
                    hard: npt.NDArray[np.bool_] | None = None) -> FloatArray:
    """The velocity nearest each command that satisfies its half-planes a·v ≤ b, exactly
    (2-D: the command, its projections onto each line and the lines' pairwise crossings are
    the candidates); where no candidate satisfies them all, of those satisfying the ``hard``
    rows the one whose worst soft violation is least, else the one whose worst violation is
    least.

    Args:
        commands: (F, 2) the policy's commands (m/s).
        a: (F, K, 2) unit normals (zero rows: unused).
        b: (F, K) bounds.
        hard: (F, K) rows served first when not all can hold (None: all).

    Returns:
        (F, 2) the filtered commands.
    """
    out = np.array(commands, dtype=float)
    excess = a[..., 0] * out[:, None, 0] + a[..., 1] * out[:, None, 1] - b
    active = (excess > _TOLERANCE).any(axis=1) if b.shape[1] else np.zeros(len(b), dtype=bool)
    if active.any():  # most commands are allowed as they are: solve for the others only
        hard_rows = None if hard is None else hard[active]
        out[active] = _solve(out[active], a[active], b[active], excess[active], hard_rows)
    return out


def _solve(commands: FloatArray, a: FloatArray, b: FloatArray, excess: FloatArray,
           hard: npt.NDArray[np.bool_] | None) -> FloatArray:
    """:func:`nearest_allowed` for rows whose command violates a constraint."""
    f, k = b.shape
    used = (a[..., 0] != 0.0) | (a[..., 1] != 0.0)
    # projections onto each line: v − (a·v − b)·a (|a| = 1)
    proj = commands[:, None, :] - excess[..., None] * a
    # crossings of lines i < j: solve a_i·v = b_i, a_j·v = b_j (Cramer's rule)
    i, j = np.triu_indices(k, 1)
    ai, aj, bi, bj = a[:, i], a[:, j], b[:, i], b[:, j]
    det = ai[..., 0] * aj[..., 1] - ai[..., 1] * aj[..., 0]
    crossing = np.abs(det) > 1e-9
    safe = np.where(crossing, det, 1.0)
    cross = np.stack([(bi * aj[..., 1] - bj * ai[..., 1]) / safe,
                      (ai[..., 0] * bj - aj[..., 0] * bi) / safe], axis=-1)
    candidates = np.concatenate([commands[:, None, :], proj, cross], axis=1)  # (F, C, 2)
    real = np.concatenate([np.ones((f, 1), dtype=bool), used,
                           crossing & used[:, i] & used[:, j]], axis=1)
    violation = (a[:, None, :, 0] * candidates[:, :, None, 0]
                 + a[:, None, :, 1] * candidates[:, :, None, 1] - b[:, None, :])  # (F, C, K)
    violation = np.where(used[:, None, :], violation, -np.inf)
    worst = np.where(real, violation.max(axis=2), np.inf)
    diff = candidates - commands[:, None, :]
    distance = np.where(real, diff[..., 0] ** 2 + diff[..., 1] ** 2, np.inf)
    feasible = worst <= _TOLERANCE
    best = np.argmin(np.where(feasible, distance, np.inf), axis=1)
    # squeezed: keep off walls and the leader, violate the followers' rows least
    hard = np.ones((f, k), dtype=bool) if hard is None else hard
    worst_hard = np.where(real, np.where(hard[:, None, :], violation, -np.inf).max(axis=2),
                          np.inf)
    worst_soft = np.where(hard[:, None, :], -np.inf, violation).max(axis=2)
    keeps = worst_hard <= _TOLERANCE
    soft_pick = np.argmin(np.where(keeps, worst_soft, np.inf), axis=1)
    fallback = np.where(keeps.any(axis=1), soft_pick, np.argmin(worst, axis=1))
    pick = np.where(feasible.any(axis=1), best, fallback)
    return candidates[np.arange(f), pick]


@dataclass(frozen=True)
class People:
    """The people the filter keeps the followers off: positions (P, 2), their velocities
    this step (P, 2, m/s) and their body radius (m). A person leading is one of them (first)
    and then not a robot row."""

    positions: FloatArray
    velocities: FloatArray
    radius: float
    person_leads: bool = False


def people_around(leader_position: FloatArray, leader_velocity: FloatArray,
                  pedestrians: FloatArray | None, pedestrian_velocities: FloatArray | None,
                  radius: float, person_leads: bool) -> People | None:
    """The :class:`People` of a step (None: neither a person leading nor pedestrians): the
    leader (2,) when a person leads, moving at ``leader_velocity``, then the pedestrians
    (P, 2) at theirs."""
    crowd = pedestrians is not None and pedestrian_velocities is not None \
        and len(pedestrians) > 0
    if not person_leads and not crowd:
        return None
    positions = [np.reshape(leader_position, (1, 2))] if person_leads else []
    velocities = [np.reshape(leader_velocity, (1, 2))] if person_leads else []
    if crowd:
        positions.append(np.asarray(pedestrians, dtype=np.float64))
        velocities.append(np.asarray(pedestrian_velocities, dtype=np.float64))
    return People(np.concatenate(positions), np.concatenate(velocities), radius, person_leads)


def _person_keep(people: People, radius: float, config: SafetyConfig) -> float:
    """The centre distance the filter keeps from a person leading: ``safety_margin`` beyond
    the larger of their bodies' and ``safety_person_distance``."""
    return max(config.safety_person_distance, people.radius + radius) + config.safety_margin


def people_constraints(followers: FloatArray, people: People, radius: float,
                       config: SafetyConfig) -> tuple[FloatArray, FloatArray]:
    """The half-planes of the :data:`PEOPLE_ROWS` nearest people within reach of each
    follower (F, 2): n·v ≤ α·(d − keep) + n·v_person, keep ``safety_margin`` beyond the
    larger of the bodies' centre distance and ``safety_person_distance`` (a person leading)
    or ``safety_pedestrian_distance`` (a pedestrian), reach ``safety_range`` plus what keep
    adds to a robot pair's. ``(a (F, R, 2), b (F, R))``."""
    keep = np.full(len(people.positions), max(config.safety_pedestrian_distance,
                                              people.radius + radius) + config.safety_margin)
    if people.person_leads and len(keep):
        keep[0] = _person_keep(people, radius, config)
    f, k = len(followers), PEOPLE_ROWS
    a, b = np.zeros((f, k, 2)), np.full((f, k), _FREE)
    if not len(people.positions) or not f:
        return a, b
    offset = people.positions[None, :, :] - followers[:, None, :]
    dist = np.sqrt(offset[..., 0] ** 2 + offset[..., 1] ** 2)
    order = np.argsort(dist, axis=1, kind="stable")[:, :k]
    dist = np.take_along_axis(dist, order, axis=1)
    offset = np.take_along_axis(offset, order[..., None], axis=1)
    velocity, kept = people.velocities[order], keep[order]
    reach = config.safety_range + kept - 2.0 * radius - config.safety_margin
    ok = (dist > 0.0) & (dist <= reach)
    safe = np.where(ok, dist, 1.0)
    n = np.where(ok[..., None], offset / safe[..., None], 0.0)
    bound = config.safety_gain * (dist - kept) + n[..., 0] * velocity[..., 0] \
        + n[..., 1] * velocity[..., 1]
    used = order.shape[1]
    a[:, :used], b[:, :used] = n, np.where(ok, bound, _FREE)
    return a, b


def person_path_constraints(followers: FloatArray, people: People, radius: float,
                            config: SafetyConfig) -> tuple[FloatArray, FloatArray]:
    """The half-plane that keeps each follower (F, 2) out of a walking person's path
    (``safety_person_path``; :class:`SafetyConfig`): with e the person's walking direction,
    l a follower's signed offset across it and w the distance kept from the person, a
    follower ahead of the person within its speed × ``safety_person_path`` + w satisfies
    σ·e⊥·(v − v_person) ≥ −α·(σ·l − w), σ the side it is on (the left where l = 0): the
    barrier of the strip of half-width w, which moves it sideways out of the strip at up to
    α times its depth. ``(a (F, 1, 2), b (F, 1))``; rows off (a = 0) elsewhere."""
    f = len(followers)
    a, b = np.zeros((f, 1, 2)), np.full((f, 1), _FREE)
    if not (people.person_leads and config.safety_person_path > 0.0 and f):
        return a, b
    velocity = people.velocities[0]
    speed = float(np.sqrt(velocity[0] ** 2 + velocity[1] ** 2))
    if speed < PATH_MIN_SPEED:
        return a, b
    keep = _person_keep(people, radius, config)
    ex, ey = velocity[0] / speed, velocity[1] / speed
    rel = followers - people.positions[0]
    along = rel[:, 0] * ex + rel[:, 1] * ey
    across = rel[:, 1] * ex - rel[:, 0] * ey  # along e⊥ = (−e_y, e_x)
    side = np.where(across < 0.0, -1.0, 1.0)
    depth = side * across - keep
    on = (along > 0.0) & (along <= speed * config.safety_person_path + keep) \
        & (depth <= config.safety_range)
    across_velocity = velocity[1] * ex - velocity[0] * ey  # 0 up to rounding
    a[:, 0, 0] = np.where(on, side * ey, 0.0)
    a[:, 0, 1] = np.where(on, -side * ex, 0.0)
    b[:, 0] = np.where(on, config.safety_gain * depth - side * across_velocity, _FREE)
    return a, b


def filter_commands(commands: FloatArray, positions: FloatArray, velocities: FloatArray,
                    leader_velocity: FloatArray, radius: float, max_speed: float, scene: Scene,
                    config: SafetyConfig, people: People | None = None) -> FloatArray:
    """The followers' commands (F, 2, world frame, m/s) filtered for the robots at
    ``positions`` moving at ``velocities`` (N, 2, the leader first) in ``scene``, with the
    leader commanding ``leader_velocity`` (2,) this step; speeds stay within
    ``max_speed``. ``people``: a person leading and pedestrians, kept off as wider discs
    (:func:`people_constraints`); the leader is then not a robot row."""
    surfaces, valid = scene.nearest_points(positions[1:], STATIC_POINTS,
                                           config.safety_range)
    compiled = kernels.compiled()
    if compiled is not None and len(positions) < COMPILED_BELOW and people is None:
        # the same bits in one loop; it declines (status 1) where the KD-tree's order on
        # exact ties or its bound decide, and the numpy code below runs
        status, out = compiled.safety_filter(
            np.ascontiguousarray(commands, dtype=np.float64),
            np.ascontiguousarray(positions, dtype=np.float64),
            np.ascontiguousarray(velocities, dtype=np.float64),
            np.ascontiguousarray(leader_velocity, dtype=np.float64), float(radius),
            config.safety_gain, config.safety_margin, config.safety_range,
            config.safety_neighbours, surfaces, valid)
        if status == 0:
            return clip_speed(out, max_speed)
    leads = people is not None and people.person_leads
    a, b, hard = barrier_constraints(positions, velocities,
                                     np.asarray(leader_velocity, dtype=float), radius, config,
                                     surfaces, valid, leader_row=not leads)
    if people is not None:  # the people's rows are hard, the path's soft
        blocks = [(a, b, hard)]
        a_p, b_p = people_constraints(positions[1:], people, radius, config)
        blocks.append((a_p, b_p, np.ones(b_p.shape, dtype=bool)))
        if leads and config.safety_person_path > 0.0:
            a_w, b_w = person_path_constraints(positions[1:], people, radius, config)
            blocks.append((a_w, b_w, np.zeros(b_w.shape, dtype=bool)))
        a, b, hard = (np.concatenate(rows, axis=1) for rows in zip(*blocks, strict=True))
    return clip_speed(nearest_allowed(np.asarray(commands, dtype=float), a, b, hard),
                      max_speed)
