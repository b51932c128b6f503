"""The study's violation metrics and the extra flock metrics, as pure functions on arrays.

One source for the env's rewards, for recordings and for the evaluation suite (the study's
definitions). Arrays put robots on the second-to-last axis with the leader first: positions
``(..., N, 2)``; a leading time axis ``T`` makes the same functions work on whole episodes.

- separation violation: |p_leader − p_i| < separation_threshold (0.7 m)
- cohesion violation: |p_leader − p_i| > cohesion_threshold (2.25 m)
- alignment violation: the angle between the leader's and follower i's *commanded* velocity
  directions exceeds alignment_threshold_deg (45°); a zero command has direction 0°.
- V_x = Σ_i (violating samples of i · dt) / T, summed over followers, T = samples · dt.

Safety (beyond the study, which measures only against the leader, so a flock can score well
while its robots touch all the time): robot–robot and robot–leader contact, wall contact,
nearest-neighbour spacing and the leader's deviation from its scripted path; see
:func:`safety_metrics` and, per step, :func:`safety_flags`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from boids_env import kernels

if TYPE_CHECKING:
    from boids_env.config import MetricsConfig
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

VIOLATIONS = ("separation", "cohesion", "alignment")
CONTACT_TOLERANCE = 0.001
"""Two robots (or a robot and a wall) closer than touching + this (m) count as in contact:
pymunk's collision slop lets rigid contacts overlap by about ``collision_slop``."""
SAFETY_KEYS = ("touching_fraction", "mean_contact_pairs", "contacts_follower",
               "contacts_leader", "wall_fraction", "min_clearance", "no_sight_fraction",
               "mean_nn_distance", "leader_path_deviation", "leader_path_deviation_max")
"""The safety metrics of :func:`safety_metrics`, in report order."""
SAFETY_FLAGS = ("proximity", "contact", "wall")
"""Per-follower, per-step safety flags (:func:`safety_flags`), in reward order."""
V_KEYS = {"separation": "V_sep", "cohesion": "V_coh", "alignment": "V_align"}
KD_TREE_MIN_ROBOTS = 96
"""From this group size on, the safety flags find each follower's nearest robot with a
KD-tree; below it, all pairs in a compiled loop (:mod:`boids_env.kernels`)."""
COUNT_KEYS = {"separation": "count_sep", "cohesion": "count_coh", "alignment": "count_align"}


def heading_deg(velocity: FloatArray) -> FloatArray:
    """Direction of each velocity ``(..., 2)`` in degrees in (−180, 180]; 0° for zero."""
    angle = np.degrees(np.arctan2(velocity[..., 1], velocity[..., 0]))
    still = (velocity[..., 0] == 0) & (velocity[..., 1] == 0)
    return np.where(still, 0.0, angle)


def angle_difference_deg(a: FloatArray, b: FloatArray, *, wrap: bool = True) -> FloatArray:
    """|a − b| in degrees; wrapped into [0°, 180°] unless ``wrap`` is False (the study's rule)."""
    diff = np.abs(a - b)
    return np.minimum(diff, 360.0 - diff) if wrap else diff


def violation_flags(positions: FloatArray, commanded: FloatArray, *,
                    separation_threshold: float = 0.7, cohesion_threshold: float = 2.25,
                    alignment_threshold_deg: float = 45.0, wrap_alignment: bool = True
                    ) -> dict[str, BoolArray]:
    """Per-follower violation flags against the leader.

    Args:
        positions: (..., N, 2) positions, the leader first.
        commanded: (..., N, 2) commanded velocities, the leader first.

    Returns:
        ``{"separation", "cohesion", "alignment"}`` -> bool arrays (..., N-1).
    """
    # x and y apart (a trailing axis of 2 makes numpy's inner loops short); the squares are
    # summed in einsum's order, so the distances are the same bits
    ox = positions[..., 1:, 0] - positions[..., :1, 0]
    oy = positions[..., 1:, 1] - positions[..., :1, 1]
    distance = ox * ox
    distance += oy * oy
    np.sqrt(distance, out=distance)
    heading = heading_deg(commanded)
    turn = angle_difference_deg(heading[..., :1], heading[..., 1:], wrap=wrap_alignment)
    return {
        "separation": distance < separation_threshold,
        "cohesion": distance > cohesion_threshold,
        "alignment": turn > alignment_threshold_deg,
    }


def flags_for(config: MetricsConfig, positions: FloatArray, commanded: FloatArray,
              headings: FloatArray | None = None) -> dict[str, BoolArray]:
    """:func:`violation_flags` with the thresholds of a :class:`MetricsConfig`; with
    ``alignment_source="heading"`` the alignment flag compares the measured ``headings``
    (..., N) (rad) instead of the commands."""
    flags = violation_flags(positions, commanded,
                            separation_threshold=config.separation_threshold,
                            cohesion_threshold=config.cohesion_threshold,
                            alignment_threshold_deg=config.alignment_threshold_deg,
                            wrap_alignment=config.wrap_alignment)
    if config.alignment_source == "heading":
        if headings is None:
            raise ValueError("alignment_source='heading' needs the robots' headings (robots "
                             "with a heading: drive='unicycle')")
        flags["alignment"] = heading_misalignment(headings, config)
    return flags


def heading_misalignment(headings: FloatArray, config: MetricsConfig) -> BoolArray:
    """Alignment violations on measured headings: the angle between the leader's heading and
    each follower's exceeds ``alignment_threshold_deg`` (wrapped unless ``wrap_alignment`` is
    False, as the study's rule): (..., N) rad -> (..., N-1). Every robot with a heading has
    one, moving or not, so the study's "zero command points at 0°" plays no part."""
    deg = np.degrees(np.asarray(headings, dtype=float))
    turn = angle_difference_deg(deg[..., :1], deg[..., 1:], wrap=config.wrap_alignment)
    return turn > config.alignment_threshold_deg


def reward_scale(config: MetricsConfig, dt: float) -> FloatArray:
    """−weight · dt per violation, in VIOLATIONS order, shaped (3, 1) to scale stacked flags."""
    weights = np.array([config.reward_separation, config.reward_cohesion,
                        config.reward_alignment])
    return (-weights * dt)[:, None]


def episode_violations(flags: dict[str, BoolArray]) -> dict[str, float]:
    """The study's V_sep, V_coh, V_align from an episode's flags ``(T, F)``.

    V = Σ_i count_i · dt / (T · dt) = Σ_i count_i / T: summed over followers, not averaged.
    """
    out = {}
    for name in VIOLATIONS:
        f = np.asarray(flags[name])
        out[V_KEYS[name]] = float(f.sum() / f.shape[0]) if f.shape[0] else 0.0
    return out


def violation_counts(flags: dict[str, BoolArray]) -> dict[str, npt.NDArray[np.int64]]:
    """Per-follower counts of violating samples ``(F,)`` (the study's group-size measure)."""
    return {COUNT_KEYS[name]: np.asarray(flags[name]).sum(axis=0).astype(np.int64)
            for name in VIOLATIONS}


def contact_pairs(positions: FloatArray, distance: float) -> set[tuple[int, int]]:
    """Pairs (i < j) of robots closer than ``distance`` at one instant: (N, 2) -> set."""
    pairs = cKDTree(positions).query_pairs(distance, output_type="ndarray")
    return {(int(i), int(j)) for i, j in pairs}


def _pair_stats(pos: FloatArray, touch: float) -> dict[str, float]:
    """Contact counts, onsets (leader pairs apart), nearest-neighbour mean and the minimum
    distance of samples (T, N, 2) with N >= 2: all pairs in chunks for small groups, a KD-tree
    per sample for large ones."""
    steps, n = pos.shape[:2]
    stats = {"touching": 0.0, "pairs": 0.0, "onset_leader": 0.0, "onset_follower": 0.0,
             "nn": 0.0, "min": float("inf")}
    if n <= 64:
        iu, ju = np.triu_indices(n, 1)
        leader_pair = iu == 0
        before = np.zeros(len(iu), dtype=bool)
        chunk = max(1, 2_000_000 // (n * n))
        for start in range(0, steps, chunk):
            p = pos[start:start + chunk]
            diff = p[:, :, None, :] - p[:, None, :, :]
            dist = np.sqrt(np.einsum("tijd,tijd->tij", diff, diff))
            dist[:, np.arange(n), np.arange(n)] = np.inf
            stats["nn"] += float(dist.min(axis=2).mean(axis=1).sum())
            stats["min"] = min(stats["min"], float(dist.min()))
            touching = dist[:, iu, ju] < touch  # (t, P)
            onset = touching & ~np.vstack([before[None], touching[:-1]])
            stats["onset_leader"] += float(onset[:, leader_pair].sum())
            stats["onset_follower"] += float(onset[:, ~leader_pair].sum())
            stats["touching"] += float(touching.any(axis=1).sum())
            stats["pairs"] += float(touching.sum())
            before = touching[-1]
        return stats
    previous: set[tuple[int, int]] = set()
    for p in pos:
        tree = cKDTree(p)
        nearest = tree.query(p, k=2)[0][:, 1]
        stats["nn"] += float(nearest.mean())
        stats["min"] = min(stats["min"], float(nearest.min()))
        now = {(int(i), int(j)) for i, j in tree.query_pairs(touch, output_type="ndarray")}
        stats["touching"] += bool(now)
        stats["pairs"] += len(now)
        for i, _ in now - previous:
            stats["onset_leader" if i == 0 else "onset_follower"] += 1
        previous = now
    return stats


def safety_metrics(positions: FloatArray, radius: float,
                   static_contact: BoolArray | None = None,
                   leader_path: FloatArray | None = None,
                   tolerance: float = CONTACT_TOLERANCE, *,
                   clearance: FloatArray | None = None,
                   sight: BoolArray | None = None) -> dict[str, float]:
    """Safety of an episode's samples (T, N, 2), the leader first.

    Args:
        positions: (T, N, 2) samples.
        radius: the robots' radius (m).
        static_contact: (T, N) whether each robot touches static geometry (walls or
            obstacles); None: no wall metrics.
        leader_path: the leader's scripted path as a polyline (M, 2).
        tolerance: contact tolerance (m).
        clearance: (T, N) distance (m) from each robot's centre to static geometry.
        sight: (T, N-1) whether each follower sees the leader (no static geometry between).

    Returns:
        ``touching_fraction``: fraction of samples in which some pair of robots (the leader
        included) is in contact; ``mean_contact_pairs``: pairs in contact per sample;
        ``contacts_follower`` / ``contacts_leader``: contact onsets between two followers /
        between the leader and a follower (a pair that starts touching counts once, a pair
        touching in the first sample included); ``wall_fraction``: fraction of samples in which
        some robot touches static geometry; ``min_clearance``: the smallest distance (m) from
        any robot's edge to static geometry over the episode; ``no_sight_fraction``: the
        followers' mean fraction of samples with a wall or obstacle between them and the
        leader; ``mean_nn_distance``: centre distance (m) from each robot to its nearest other
        robot, averaged over robots and samples; ``min_distance``: the smallest centre
        distance between two robots (m); ``leader_path_deviation`` / ``_max``: the leader's
        mean / largest distance (m) from its scripted path ``leader_path`` (NaN when not
        given).
    """
    pos = np.asarray(positions, dtype=float)
    steps, n = pos.shape[:2]
    nan = float("nan")
    out: dict[str, float] = dict.fromkeys(SAFETY_KEYS, nan)
    out["min_distance"] = nan
    if steps == 0:
        return out
    if static_contact is not None:
        out["wall_fraction"] = float(np.any(static_contact, axis=1).mean())
    if clearance is not None:
        out["min_clearance"] = float(np.min(clearance) - radius)
    if sight is not None and sight.size:
        out["no_sight_fraction"] = float((~np.asarray(sight)).mean())
    if n > 1:
        stats = _pair_stats(pos, 2 * radius + tolerance)
        out.update(touching_fraction=stats["touching"] / steps,
                   mean_contact_pairs=stats["pairs"] / steps,
                   contacts_follower=stats["onset_follower"],
                   contacts_leader=stats["onset_leader"],
                   mean_nn_distance=stats["nn"] / steps, min_distance=stats["min"])
    if leader_path is not None and len(leader_path):
        dev = path_deviation(pos[:, 0], np.asarray(leader_path, dtype=float))
        out["leader_path_deviation"] = float(dev.mean())
        out["leader_path_deviation_max"] = float(dev.max())
    return out


def path_deviation(points: FloatArray, path: FloatArray) -> FloatArray:
    """Distance (m) from each point (T, 2) to the polyline ``path`` (M, 2): (T,)."""
    if len(path) == 1:
        return np.linalg.norm(points - path[0], axis=-1)
    a, b = path[:-1], path[1:]  # (S, 2) segments
    ab = b - a
    length2 = np.einsum("sd,sd->s", ab, ab)
    best = np.full(len(points), np.inf)
    for start in range(0, len(a), 512):  # chunks bound the (T, S) temporaries
        sa, sab, sl = a[start:start + 512], ab[start:start + 512], length2[start:start + 512]
        rel = points[:, None, :] - sa[None]
        t = np.clip(np.einsum("tsd,sd->ts", rel, sab) / np.where(sl > 0, sl, 1.0), 0.0, 1.0)
        closest = sa[None] + t[..., None] * sab[None]
        d = np.linalg.norm(points[:, None, :] - closest, axis=-1).min(axis=1)
        best = np.minimum(best, d)
    return best


def safety_flags(positions: FloatArray, radius: float, safety_distance: float,
                 near_static: BoolArray, tolerance: float = CONTACT_TOLERANCE
                 ) -> dict[str, BoolArray]:
    """Per-follower safety flags at one instant (N, 2), the leader first: ``proximity``
    (centre distance to some other robot, the leader included, below ``safety_distance``),
    ``contact`` (touching some other robot) and ``wall`` (``near_static``: the follower's
    centre near static geometry, as the caller measured it); each (N-1,)."""
    pos = np.asarray(positions, dtype=float)
    n = len(pos)
    compiled = kernels.compiled()
    if 1 < n < KD_TREE_MIN_ROBOTS and compiled is not None:  # the same bits in one loop
        nearest = compiled.nearest_other(np.ascontiguousarray(pos))
    elif n > 1:
        nearest = cKDTree(pos).query(pos[1:], k=2)[0][:, 1]
    else:  # pragma: no cover - an env always has a follower
        nearest = np.zeros(0)
    return {"proximity": nearest < safety_distance,
            "contact": nearest < 2 * radius + tolerance,
            "wall": np.asarray(near_static, dtype=bool)}


PARKED_AFTER = 5.0
"""Seconds the leader must have stood still before its followers count as parked (the
parked-formation metrics; issue 26's measure)."""
STILL_SPEED = 0.01
"""A leader commanding less than this (m/s) stands still."""


def still_time(commanded_leader: FloatArray, dt: float) -> FloatArray:
    """How long (s) the leader has stood still at each sample: (T, 2) -> (T,). A sample whose
    command is below :data:`STILL_SPEED` adds dt to the run of still samples before it; a
    moving one resets it to 0."""
    cmd = np.asarray(commanded_leader, dtype=float)
    still = np.sqrt(np.einsum("td,td->t", cmd, cmd)) < STILL_SPEED
    index = np.arange(len(still))
    last_moving = np.maximum.accumulate(np.where(still, -1, index))  # -1: none yet
    return np.where(still, (index - last_moving) * dt, 0.0)


def parked_metrics(positions: FloatArray, velocities: FloatArray, commanded: FloatArray,
                   dt: float, after: float = PARKED_AFTER) -> dict[str, float]:
    """How the followers wait for a leader who stands still, over the samples where it has
    stood for more than ``after`` seconds.

    Args:
        positions, velocities, commanded: (T, N, 2) samples, the leader first.
        dt: sampling period (s).
        after: seconds of standstill before a sample counts (default 5 s).

    Returns:
        ``parked_speed``: the followers' mean speed (m/s) over those samples;
        ``parked_distance_max``: the farthest any follower was from the leader then (m);
        ``parked_time``: how long (s) those samples last. Empty when there are none.
    """
    waited = still_time(np.asarray(commanded)[:, 0], dt) > after + 1e-9
    if not waited.any() or np.asarray(positions).shape[1] < 2:
        return {}
    vel = np.asarray(velocities, dtype=float)[waited, 1:]
    speed = np.sqrt(np.einsum("tfd,tfd->tf", vel, vel))
    return {"parked_speed": float(speed.mean()),
            "parked_distance_max": float(leader_distance(np.asarray(positions)[waited]).max()),
            "parked_time": float(waited.sum() * dt)}


def polarization(velocities: FloatArray) -> FloatArray:
    """|mean unit velocity| of the robots that move: (..., N, 2) -> (...); 0 when none move."""
    speed = np.linalg.norm(velocities, axis=-1, keepdims=True)
    moving = speed[..., 0] > 1e-6
    unit = np.divide(velocities, speed, out=np.zeros_like(velocities), where=speed > 1e-6)
    count = moving.sum(axis=-1)
    total = np.linalg.norm(unit.sum(axis=-2), axis=-1)
    return np.divide(total, count, out=np.zeros_like(total), where=count > 0)


LOST_DISTANCE = 3.0
"""A follower farther than this from the leader at an episode's end (m) counts as lost
(issue 36's bar: stranded behind a wall or left in another room)."""


def leader_distance(positions: FloatArray) -> FloatArray:
    """Distance of every follower to the leader: (..., N, 2) -> (..., N-1)."""
    return np.linalg.norm(positions[..., 1:, :] - positions[..., :1, :], axis=-1)


def episode_metrics(positions: FloatArray, velocities: FloatArray, commanded: FloatArray,
                    config: MetricsConfig, dt: float, robot_radius: float,
                    scene: Scene | None = None, leader_path: FloatArray | None = None, *,
                    person_radius: float | None = None, pedestrians: FloatArray | None = None,
                    pedestrian_radius: float = 0.22, headings: FloatArray | None = None
                    ) -> dict[str, object]:
    """Everything reported for one episode, from its sampled arrays.

    Args:
        positions, velocities, commanded: (T, N, 2) samples after every control step, the
            leader first (the initial state is not a sample).
        config: thresholds and flags.
        dt: sampling period (s).
        robot_radius: for contacts (m).
        scene: the static scene, for wall contact, clearance and line of sight (None: the
            study's 10 m arena).
        leader_path: the leader's scripted path as a polyline (M, 2), for its deviation.
        person_radius: the leader is a person of this radius (m): adds the proxemics of
            :func:`boids_env.proxemics.person_metrics` (None: a robot leads, no such keys).
        pedestrians: (T, P, 2) the crowd's positions, for the crowd's proxemics.
        pedestrian_radius: the pedestrians' radius (m).
        headings: (T, N) measured headings (rad) of robots that have one.

    Returns:
        ``V_sep`` / ``V_coh`` / ``V_align``: the study's violation metrics, the followers'
        summed violating time over the episode's duration (the module docstring's V_x);
        ``count_sep`` / ``count_coh`` / ``count_align``: each follower's violating samples
        (a list); ``V_align_unwrapped`` / ``count_align_unwrapped``: alignment by the study's
        unwrapped rule; ``steps``: the samples T; ``duration``: T · dt (s);
        ``min_distance``: the smallest centre distance between two robots (m);
        ``collisions``: contact onsets, follower-follower and leader-follower;
        ``polarization``: the episode mean of |mean unit velocity| of the moving robots;
        ``mean_leader_distance``: the followers' mean distance to the leader (m);
        ``final_leader_distance_max``: the farthest any follower is from the leader at the
        last sample (m: a follower left behind); ``lost_followers``: how many followers
        end farther than :data:`LOST_DISTANCE` from the leader; ``no_sight``: each follower's
        fraction of time without line of sight to the leader (a list); the safety metrics of
        :func:`safety_metrics` (``SAFETY_KEYS``); when the leader stood still for more than
        5 s, :func:`parked_metrics`; with a person leading, the proxemics of
        :func:`boids_env.proxemics.person_metrics`; with a crowd,
        :func:`boids_env.proxemics.crowd_metrics`; for robots with a heading
        ``V_align_heading`` / ``count_align_heading``: alignment on the measured headings;
        ``V_align_command``: alignment on the commands (the study's rule). ``V_align`` is
        the one ``alignment_source`` names.
    """
    if scene is None:
        from boids_env.world.scenes import arena

        scene = arena()
    flags = flags_for(config, positions, commanded, headings)
    out: dict[str, object] = dict(episode_violations(flags))
    out.update({k: v.tolist() for k, v in violation_counts(flags).items()})
    out.update(_other_alignments(flags, config, positions, commanded, headings))
    out["steps"] = int(positions.shape[0])
    out["duration"] = float(positions.shape[0] * dt)
    out["polarization"] = float(polarization(velocities).mean())
    out.update(_leader_distances(positions))
    pos = np.asarray(positions, dtype=float)
    sight = line_of_sight(pos, scene)
    safety = safety_metrics(pos, robot_radius, scene.within(pos, robot_radius,
                                                            CONTACT_TOLERANCE),
                            leader_path, clearance=scene.clearance(pos), sight=sight)
    out["min_distance"] = safety.pop("min_distance")
    # every contact onset, follower-follower and leader-follower
    out["collisions"] = int(safety["contacts_follower"] + safety["contacts_leader"])
    out.update(safety)
    out["no_sight"] = (~sight).mean(axis=0).tolist() if sight.size else []
    if person_radius is not None:
        _add_person(out, pos, velocities, robot_radius, person_radius)
    if pedestrians is not None and np.asarray(pedestrians).shape[1]:
        from boids_env.proxemics import crowd_metrics

        out.update(crowd_metrics(pos, pedestrians, robot_radius, pedestrian_radius))
    out.update(parked_metrics(pos, velocities, commanded, dt))
    return out


def _other_alignments(flags: dict[str, BoolArray], config: MetricsConfig,
                      positions: FloatArray, commanded: FloatArray,
                      headings: FloatArray | None) -> dict[str, object]:
    """:func:`episode_metrics`' alignment by the rules other than the configured one (whose
    ``flags`` are ``V_align``'s): the study's unwrapped rule, for comparisons, and for robots
    with a heading both the headings' and the commands'."""
    study = flags_for(replace(config, wrap_alignment=False), positions, commanded,
                      headings)["alignment"]
    out: dict[str, object] = {
        "V_align_unwrapped": float(study.sum() / study.shape[0]) if study.shape[0] else 0.0,
        "count_align_unwrapped": study.sum(axis=0).astype(np.int64).tolist()}
    if headings is not None:
        steps = max(int(positions.shape[0]), 1)
        # the configured source's flags are V_align's: only the other one is computed
        by_heading = config.alignment_source == "heading"
        on_heading = flags["alignment"] if by_heading else heading_misalignment(headings, config)
        on_command = flags_for(replace(config, alignment_source="command"), positions,
                               commanded)["alignment"] if by_heading else flags["alignment"]
        out["V_align_heading"] = float(on_heading.sum() / steps)
        out["count_align_heading"] = on_heading.sum(axis=0).astype(np.int64).tolist()
        out["V_align_command"] = float(on_command.sum() / steps)
    return out


def _leader_distances(positions: FloatArray) -> dict[str, object]:
    """:func:`episode_metrics`' followers' distances to the leader: the mean, the farthest
    at the end, and how many end lost."""
    distances = leader_distance(positions)  # (T, N-1)
    return {"mean_leader_distance": float(distances.mean()),
            "final_leader_distance_max": float(distances[-1].max()) if distances.size else 0.0,
            "lost_followers": int((distances[-1] > LOST_DISTANCE).sum())
            if distances.size else 0}


def _add_person(out: dict[str, object], pos: FloatArray, velocities: FloatArray,
                robot_radius: float, person_radius: float) -> None:
    """Adds a leading person's proxemics to ``out``, whose leader contacts (and so its
    collisions) become those with the person's body, not a robot's."""
    from boids_env.proxemics import person_metrics

    out.update(person_metrics(pos, np.asarray(velocities, dtype=float)[:, 0], robot_radius,
                              person_radius))
    # out holds values of several types; these are counts (numbers)
    out["contacts_leader"] = leader = float(cast(float, out["person_contacts"]))
    out["collisions"] = int(cast(float, out["contacts_follower"]) + leader)


def line_of_sight(positions: FloatArray, scene: Scene) -> BoolArray:
    """Whether each follower sees the leader at each sample (no wall or obstacle crosses the
    segment between their centres): (T, N, 2) -> (T, N-1). The box's walls never block."""
    pos = np.asarray(positions, dtype=float)
    steps, n = pos.shape[:2]
    if scene.is_empty_box or n < 2:
        return np.ones((steps, max(n - 1, 0)), dtype=bool)
    leader = np.broadcast_to(pos[:, :1], pos[:, 1:].shape).reshape(-1, 2)
    blocked, _ = scene.blocked(leader, pos[:, 1:].reshape(-1, 2), use_grid=False)
    return ~blocked.reshape(steps, n - 1)
