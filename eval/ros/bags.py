"""The study's metrics from a bag that ``rosbag record`` wrote of a live graph.

A live graph publishes a robot's command *in answer to* its odometry: the k-th
``/robot_k/cmd_vel`` message is the command for the control period that *starts* at the k-th
odometry sample, so it is the commanded velocity of sample k+1. Bags written by
:func:`boids_env.rosbag.write_bag` (and read by :func:`boids_env.rosbag.read_bag`) pair the
k-th command with the k-th odometry instead. :func:`read_live_bag` reads a bag with
``read_bag`` and moves every robot's commands one sample later (sample 0, the reset state,
gets the zero command), so that the recording, and every metric of it, equals the simulator's
own. Its positions and velocities are ``read_bag``'s unchanged (V_sep and V_coh do not depend
on the commands at all).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from boids_env.config import EnvConfig
from boids_env.recording import Recording
from boids_env.vectors import clip_speed
from boids_env.world.leader import make_leader


def topic_counts(path: str | Path) -> dict[str, int]:
    """Messages per topic of a bag (ROS 1 file or ROS 2 folder)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    store = get_typestore(Stores.ROS1_NOETIC if path.is_file() else Stores.ROS2_HUMBLE)
    counts: dict[str, int] = {}
    with AnyReader([path], default_typestore=store) as reader:
        for conn in reader.connections:
            counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
    return counts


def read_live_bag(path: str | Path, config: EnvConfig | None = None) -> Recording:
    """A bag recorded from a live graph as a :class:`~boids_env.recording.Recording` with the
    simulator's own sample convention.

    Args:
        path: the bag.
        config: the run's env config (thresholds, dt, group size): the simulator's
            ``config.json``; default: ``read_bag``'s (the study's, robots from the bag).

    Raises:
        ValueError: the bag misses commands or odometry (its ``/robot_k/*`` counts differ:
            e.g. the recorder subscribed after the first tick; start it before the run, with
            ``boids ros sim --wait-for``).
    """
    from boids_env.rosbag import read_bag

    counts = topic_counts(path)
    robots = sum(1 for t in counts if t.startswith("/robot_") and t.endswith("/odom"))
    odom = [counts.get(f"/robot_{k}/odom", 0) for k in range(robots)]
    if len(set(odom)) > 1:
        raise ValueError(f"{path}: the robots' odometry counts differ ({odom}): the bag "
                         f"does not hold every tick of every robot")
    samples = odom[0] if odom else 0
    short = {k: n for k in range(robots)
             if (n := counts.get(f"/robot_{k}/cmd_vel", 0)) < samples - 1}
    if short:
        raise ValueError(f"{path}: {len(short)} robot(s) have fewer than {samples - 1} "
                         f"commands (one per tick): {short}; record from before tick 0")
    # each command answers an odometry sample: it is the next sample's command
    recording = read_bag(path, config, answers=True)
    samples = recording.positions.shape[0]
    commanded = recording.commanded.copy()
    # what the robots executed: the followers' speed limited as the simulator limits it
    commanded[:, 1:] = clip_speed(commanded[:, 1:], recording.config.world.max_speed)
    time = np.arange(samples) * recording.config.world.dt
    return Recording(recording.config, time, recording.positions, recording.velocities,
                     commanded, {**recording.extra, "source": f"rosbag {Path(path).name}"},
                     scripted_path(config) if config is not None else None,
                     headings=recording.headings,
                     angular_velocities=recording.angular_velocities, native=recording.native)


def scripted_path(config: EnvConfig) -> np.ndarray | None:
    """The leader's scripted path of ``config`` (for its path deviation), or None where a bag
    cannot tell it: an external leader, or random waypoints (drawn from the run's seed)."""
    if config.scenario.path in ("external", "random_waypoints"):
        return None
    path = make_leader(config.scenario, np.random.default_rng(0),
                       config.world.dt).reference_path()
    return None if path is None else np.asarray(path, dtype=float)
