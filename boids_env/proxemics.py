"""Proxemics and social-navigation metrics of robots around a person and a crowd, as pure
functions on arrays (no physics).

Distances are between centres, as HuNavSim's evaluator and CrowdNav measure them. Arrays put
robots on the second-to-last axis with the person (the leader) first: positions
``(T, N, 2)``; pedestrians ``(T, P, 2)``.

- Hall's zones (Hall 1966, *The Hidden Dimension*; reported as time fractions by HuNavSim,
  Pérez-Higueras et al. 2023): intimate below 0.45 m, personal 0.45-1.2 m, social 1.2-3.6 m,
  public beyond.
- Contacts: a robot's disc within ``tolerance`` of the person's (or a pedestrian's); an onset
  counts once, as the flock's contact counts do.
- Cut in front (this project's definition): the person walks (at least ``CUT_IN_MIN_SPEED``)
  and the robot's centre lies in the strip the person's body sweeps in the next
  ``CUT_IN_TIME`` seconds at its current velocity (ahead of it, within person_radius +
  robot_radius of its line of walking): the robot is in the person's way.
- Intrusions into a pedestrian's personal space: a follower's centre within 1.2 m (Hall's
  personal zone) or 0.45 m (intimate) of some pedestrian's.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

HALL_ZONES = (("intimate", 0.45), ("personal", 1.2), ("social", 3.6), ("public", np.inf))
"""Hall's proxemic zones around a person, each up to its outer centre distance (m)."""
CUT_IN_TIME = 2.0
"""How far ahead (s of the person's walking) a robot counts as in the person's path."""
CUT_IN_MIN_SPEED = 0.2
"""The person counts as walking from this speed (m/s) on."""
PERSON_KEYS = ("intimate_fraction", "personal_fraction", "social_fraction", "public_fraction",
               "min_person_distance", "person_contacts", "person_contact_fraction",
               "cut_in_fraction")
"""The person metrics of :func:`person_metrics`, in report order (present when the leader is a
person)."""
CROWD_KEYS = ("pedestrian_intimate_fraction", "pedestrian_personal_fraction",
              "min_pedestrian_distance", "pedestrian_contacts")
"""The crowd metrics of :func:`crowd_metrics` (present with a crowd)."""


def distances_to(points: FloatArray, others: FloatArray) -> FloatArray:
    """Centre distances (..., F, P) from each point (..., F, 2) to each other (..., P, 2)."""
    diff = points[..., :, None, :] - others[..., None, :, :]
    return np.sqrt(diff[..., 0] * diff[..., 0] + diff[..., 1] * diff[..., 1])


def person_distance(positions: FloatArray) -> FloatArray:
    """Each follower's centre distance to the person (robot 0): (..., N, 2) -> (..., N-1)."""
    rel = positions[..., 1:, :] - positions[..., :1, :]
    return np.sqrt(rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1])


def zone_fractions(distance: FloatArray) -> dict[str, FloatArray]:
    """The fraction of samples each follower spends in each of Hall's zones.

    Args:
        distance: (T, F) centre distances to the person (m).

    Returns:
        ``{"intimate", "personal", "social", "public"}`` -> (F,) fractions summing to 1.
    """
    out = {}
    lower = 0.0
    for name, upper in HALL_ZONES:
        inside = (distance >= lower) & (distance < upper)
        out[name] = inside.mean(axis=0) if len(distance) else np.zeros(distance.shape[1:])
        lower = upper
    return out


def onsets(flags: BoolArray) -> int:
    """Starts of True runs along the first axis of ``flags`` (T, ...), a run already True in
    the first sample included."""
    f = np.asarray(flags, dtype=bool)
    if not len(f):
        return 0
    before = np.concatenate([np.zeros_like(f[:1]), f[:-1]])
    return int((f & ~before).sum())


def cut_in_flags(positions: FloatArray, person_velocity: FloatArray, robot_radius: float,
                 person_radius: float, horizon: float = CUT_IN_TIME,
                 min_speed: float = CUT_IN_MIN_SPEED) -> BoolArray:
    """Whether each follower is in the person's path (see the module docstring).

    Args:
        positions: (T, N, 2) positions, the person first.
        person_velocity: (T, 2) the person's velocity (m/s).
        robot_radius, person_radius: the discs' radii (m).
        horizon: seconds of walking ahead that count.
        min_speed: the person walks from this speed on (m/s).

    Returns:
        (T, F) flags.
    """
    vx, vy = person_velocity[:, 0], person_velocity[:, 1]
    speed = np.sqrt(vx * vx + vy * vy)
    walking = speed >= min_speed
    ux = np.divide(vx, speed, out=np.zeros_like(vx), where=walking)[:, None]
    uy = np.divide(vy, speed, out=np.zeros_like(vy), where=walking)[:, None]
    rel = positions[:, 1:, :] - positions[:, :1, :]
    along = rel[..., 0] * ux + rel[..., 1] * uy
    across = np.abs(rel[..., 1] * ux - rel[..., 0] * uy)
    reach = (speed * horizon)[:, None] + person_radius
    return walking[:, None] & (along > 0) & (along <= reach) & (
        across < person_radius + robot_radius)


def intrusion_flags(positions: FloatArray, pedestrians: FloatArray, distance: float
                    ) -> BoolArray:
    """Whether each follower's centre is within ``distance`` of the leader's or of a
    pedestrian's at one instant: positions (N, 2), pedestrians (P, 2) -> (N-1,)."""
    near = person_distance(positions) < distance
    if len(pedestrians):
        near |= distances_to(positions[1:], pedestrians).min(axis=-1) < distance
    return near


def person_metrics(positions: FloatArray, person_velocity: FloatArray, robot_radius: float,
                   person_radius: float, tolerance: float = 0.001) -> dict[str, object]:
    """The proxemics of an episode's samples.

    Args:
        positions: (T, N, 2) samples, the person first.
        person_velocity: (T, 2) the person's velocity (m/s).
        robot_radius: the robots' radius (m).
        person_radius: the person's radius (m).
        tolerance: contact tolerance (m).

    Returns:
        ``intimate_fraction`` … ``public_fraction``: the followers' mean fraction of time in
        each of Hall's zones around the person; ``personal_space`` (per follower, a list): the
        fraction of time inside 1.2 m (intimate or personal); ``min_person_distance``: the
        smallest robot-person centre distance (m); ``person_contacts``: robot-person contact
        onsets; ``person_contact_fraction``: fraction of samples in which some robot touches
        the person; ``cut_in_fraction``: the followers' mean fraction of time in the person's
        path.
    """
    pos = np.asarray(positions, dtype=float)
    nan = float("nan")
    if not len(pos) or pos.shape[1] < 2:
        return dict.fromkeys(PERSON_KEYS, nan)
    dist = person_distance(pos)
    zones = zone_fractions(dist)
    out: dict[str, object] = {f"{name}_fraction": float(zones[name].mean())
                              for name, _ in HALL_ZONES}
    out["personal_space"] = (zones["intimate"] + zones["personal"]).tolist()
    out["min_person_distance"] = float(dist.min())
    touch = dist < person_radius + robot_radius + tolerance
    out["person_contacts"] = onsets(touch)
    out["person_contact_fraction"] = float(touch.any(axis=1).mean())
    cut = cut_in_flags(pos, np.asarray(person_velocity, dtype=float), robot_radius,
                       person_radius)
    out["cut_in_fraction"] = float(cut.mean())
    return out


def crowd_metrics(positions: FloatArray, pedestrians: FloatArray, robot_radius: float,
                  pedestrian_radius: float, tolerance: float = 0.001) -> dict[str, float]:
    """The followers among the crowd.

    Args:
        positions: (T, N, 2) samples, the leader first (not counted).
        pedestrians: (T, P, 2) the crowd's positions, P >= 1.
        robot_radius, pedestrian_radius: the discs' radii (m).
        tolerance: contact tolerance (m).

    Returns:
        ``pedestrian_intimate_fraction`` / ``pedestrian_personal_fraction``: the followers'
        mean fraction of time within 0.45 m / 1.2 m of some pedestrian;
        ``min_pedestrian_distance``: the smallest follower-pedestrian centre distance (m);
        ``pedestrian_contacts``: follower-pedestrian contact onsets.
    """
    pos = np.asarray(positions, dtype=float)
    near = distances_to(pos[:, 1:], np.asarray(pedestrians, dtype=float))  # (T, F, P)
    nearest = near.min(axis=2)
    return {"pedestrian_intimate_fraction": float((nearest < HALL_ZONES[0][1]).mean()),
            "pedestrian_personal_fraction": float((nearest < HALL_ZONES[1][1]).mean()),
            "min_pedestrian_distance": float(nearest.min()),
            "pedestrian_contacts": float(onsets(
                near < pedestrian_radius + robot_radius + tolerance))}
