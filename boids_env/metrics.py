"""The study's violation metrics and the extra flock metrics, as pure functions on arrays.

One source for the env's rewards, for recordings and for the evaluation suite (DESIGN
section 4). Arrays put robots on the second-to-last axis with the leader first: positions
``(..., N, 2)``; a leading time axis ``T`` makes the same functions work on whole episodes.

- separation violation: |p_leader − p_i| < separation_threshold (0.7 m)
- cohesion violation: |p_leader − p_i| > cohesion_threshold (2.25 m)
- alignment violation: the angle between the leader's and follower i's *commanded* velocity
  directions exceeds alignment_threshold_deg (45°); a zero command has direction 0°.
- V_x = Σ_i (violating samples of i · dt) / T, summed over followers, T = samples · dt.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from boids_env.config import MetricsConfig

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

VIOLATIONS = ("separation", "cohesion", "alignment")
V_KEYS = {"separation": "V_sep", "cohesion": "V_coh", "alignment": "V_align"}
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
    offset = positions[..., 1:, :] - positions[..., :1, :]
    distance = np.sqrt(np.einsum("...d,...d->...", offset, offset))
    heading = heading_deg(commanded)
    turn = angle_difference_deg(heading[..., :1], heading[..., 1:], wrap=wrap_alignment)
    return {
        "separation": distance < separation_threshold,
        "cohesion": distance > cohesion_threshold,
        "alignment": turn > alignment_threshold_deg,
    }


def flags_for(config: MetricsConfig, positions: FloatArray, commanded: FloatArray
              ) -> dict[str, BoolArray]:
    """:func:`violation_flags` with the thresholds of a :class:`MetricsConfig`."""
    return violation_flags(positions, commanded,
                           separation_threshold=config.separation_threshold,
                           cohesion_threshold=config.cohesion_threshold,
                           alignment_threshold_deg=config.alignment_threshold_deg,
                           wrap_alignment=config.wrap_alignment)


def reward_scale(config: MetricsConfig, dt: float) -> FloatArray:
    """−weight · dt per violation, in VIOLATIONS order, shaped (3, 1) to scale stacked flags."""
    weights = np.array([config.reward_separation, config.reward_cohesion,
                        config.reward_alignment])
    return (-weights * dt)[:, None]


def reward_terms(flags: dict[str, BoolArray], config: MetricsConfig, dt: float
                 ) -> dict[str, FloatArray]:
    """Per-follower reward terms −weight · flag · dt (DESIGN section 4)."""
    scale = reward_scale(config, dt)[:, 0]
    return {name: scale[i] * flags[name].astype(float) for i, name in enumerate(VIOLATIONS)}


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


def pairwise_min_distance(positions: FloatArray) -> FloatArray:
    """Smallest centre distance between any two robots at each time: (T, N, 2) -> (T,)."""
    n = positions.shape[-2]
    if n < 2:
        return np.full(positions.shape[0], np.inf)
    if n <= 64:
        diff = positions[:, :, None, :] - positions[:, None, :, :]
        dist = np.sqrt(np.einsum("tijd,tijd->tij", diff, diff))
        dist[:, np.arange(n), np.arange(n)] = np.inf
        return dist.min(axis=(1, 2))
    return np.array([cKDTree(p).query(p, k=2)[0][:, 1].min() for p in positions])


def contact_pairs(positions: FloatArray, distance: float) -> set[tuple[int, int]]:
    """Pairs (i < j) of robots closer than ``distance`` at one instant: (N, 2) -> set."""
    pairs = cKDTree(positions).query_pairs(distance, output_type="ndarray")
    return {(int(i), int(j)) for i, j in pairs}


def collision_count(positions: FloatArray, radius: float, tolerance: float = 0.001) -> int:
    """Number of contact onsets between robots over an episode (T, N, 2): a pair that starts
    touching (closer than 2·radius + tolerance) after not touching counts once."""
    touching: set[tuple[int, int]] = set()
    onsets = 0
    for p in positions:
        now = contact_pairs(p, 2 * radius + tolerance)
        onsets += len(now - touching)
        touching = now
    return onsets


def polarization(velocities: FloatArray) -> FloatArray:
    """|mean unit velocity| of the robots that move: (..., N, 2) -> (...); 0 when none move."""
    speed = np.linalg.norm(velocities, axis=-1, keepdims=True)
    moving = speed[..., 0] > 1e-6
    unit = np.divide(velocities, speed, out=np.zeros_like(velocities), where=speed > 1e-6)
    count = moving.sum(axis=-1)
    total = np.linalg.norm(unit.sum(axis=-2), axis=-1)
    return np.divide(total, count, out=np.zeros_like(total), where=count > 0)


def leader_distance(positions: FloatArray) -> FloatArray:
    """Distance of every follower to the leader: (..., N, 2) -> (..., N-1)."""
    return np.linalg.norm(positions[..., 1:, :] - positions[..., :1, :], axis=-1)


def episode_metrics(positions: FloatArray, velocities: FloatArray, commanded: FloatArray,
                    config: MetricsConfig, dt: float, robot_radius: float) -> dict[str, object]:
    """Everything reported for one episode, from its sampled arrays.

    Args:
        positions, velocities, commanded: (T, N, 2) samples after every control step, the
            leader first (the initial state is not a sample).
        config: thresholds and flags.
        dt: sampling period (s).
        robot_radius: for contacts (m).

    Returns:
        ``V_sep``, ``V_coh``, ``V_align``, the per-follower ``count_*`` lists,
        ``V_align_unwrapped`` and ``count_align_unwrapped`` (the study's unwrapped rule),
        ``duration`` (T, s), ``steps``, ``min_distance`` (m), ``collisions``,
        ``polarization`` (episode mean) and ``mean_leader_distance`` (m).
    """
    flags = flags_for(config, positions, commanded)
    out: dict[str, object] = dict(episode_violations(flags))
    out.update({k: v.tolist() for k, v in violation_counts(flags).items()})
    # The study's own (unwrapped) alignment rule beside the configured one, for comparisons.
    study = flags_for(replace(config, wrap_alignment=False), positions, commanded)["alignment"]
    out["V_align_unwrapped"] = float(study.sum() / study.shape[0]) if study.shape[0] else 0.0
    out["count_align_unwrapped"] = study.sum(axis=0).astype(np.int64).tolist()
    out["steps"] = int(positions.shape[0])
    out["duration"] = float(positions.shape[0] * dt)
    out["min_distance"] = float(pairwise_min_distance(positions).min())
    out["collisions"] = collision_count(positions, robot_radius)
    out["polarization"] = float(polarization(velocities).mean())
    out["mean_leader_distance"] = float(leader_distance(positions).mean())
    return out
