"""Recordings: Parquet round trip gives the live env's metrics exactly."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.recording import Recording


def test_parquet_round_trip_reproduces_metrics(tmp_path):
    env = parallel_env(robots=7, leader_speed=0.6, max_cycles=300)
    result = run_episode(env, ReynoldsPolicy(), seed=2)
    live = env.episode_metrics()
    rec = result.recording
    for key in ("V_sep", "V_coh", "V_align", "count_sep", "count_coh", "count_align"):
        assert rec.metrics()[key] == live[key], key
    rec.to_parquet(tmp_path / "t.parquet")
    back = Recording.from_parquet(tmp_path / "t.parquet")
    assert back.config == env.config
    for name in ("time", "positions", "velocities", "commanded"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    assert back.metrics() == rec.metrics()
    np.testing.assert_array_equal(back.leader_path, rec.leader_path)
    assert back.extra == {"seed": 2}
    # the policy's rule forces behind every command (zero at reset), for videos and markers
    assert set(rec.forces) == {"separation", "cohesion", "alignment", "leader"}
    assert rec.forces["leader"].shape == (len(rec.time), 6, 2)
    assert not rec.forces["leader"][0].any() and rec.forces["leader"][-1].any()
    for name, vec in rec.forces.items():
        assert np.array_equal(back.forces[name], vec), name


@pytest.mark.parametrize("fmt, name", [("ros1", "ep.bag"), ("mcap", "ep_mcap")])
def test_ros_bag_round_trip_reproduces_metrics(tmp_path, fmt, name):
    from boids_env.rosbag import read_bag, write_bag

    env = parallel_env(robots=7, max_cycles=150)
    rec = run_episode(env, ReynoldsPolicy(), seed=1).recording
    write_bag(rec, tmp_path / name, format=fmt)
    if fmt == "mcap":
        assert list((tmp_path / name).glob("*.mcap")), "a ROS 2 bag folder with MCAP storage"
    back = read_bag(tmp_path / name)
    assert back.positions.shape == rec.positions.shape
    assert np.array_equal(back.positions, rec.positions)
    assert np.array_equal(back.commanded, rec.commanded)
    assert np.allclose(back.time, rec.time, atol=1e-9)
    np.testing.assert_array_equal(back.leader_path, rec.leader_path)  # from /leader/path
    got, want = back.metrics(), rec.metrics()
    assert got.keys() == want.keys()
    for key in want:  # every metric, exactly (the leader's path deviation included)
        assert got[key] == want[key], (key, got[key], want[key])


def test_unreadable_bag(tmp_path):
    from boids_env.rosbag import read_bag, write_bag

    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\nnot really")
    with pytest.raises(ValueError, match="cannot read ROS bag"):
        read_bag(junk)
    with pytest.raises(FileNotFoundError, match="bag not found"):
        read_bag(tmp_path / "missing.bag")
    rec = run_episode(parallel_env(robots=3, max_cycles=5), ReynoldsPolicy(), seed=0).recording
    with pytest.raises(ValueError, match="format must be one of"):
        write_bag(rec, tmp_path / "x", format="ros3")
