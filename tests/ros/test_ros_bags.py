"""Bags of a live graph (commands answer the odometry) read back into the simulator's own
samples and metrics; no ROS needed (``rosbags`` writes and reads the bags)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

from boids_env.environment import BoidsEnv
from boids_env.policies import ReynoldsPolicy
from boids_env.recording import Recorder, Recording

pytest.importorskip("rosbags")


@dataclass
class Episode:
    recording: Recording
    metrics: dict
    answers: np.ndarray
    """(T, F, 2) the policy's raw actions, as a controller node publishes them."""


@pytest.fixture(scope="module")
def episode() -> Episode:
    env = BoidsEnv(robots=7, max_cycles=80)
    policy = ReynoldsPolicy()
    obs, _ = env.reset(seed=2)
    policy.reset(2)
    recorder = Recorder()
    recorder.capture(env)
    answers = []
    while env.agents:
        actions = policy.act(obs)
        answers.append(np.array([actions[a] for a in env.agents], dtype=np.float64))
        obs, *_ = env.step(actions)
        recorder.capture(env)
    recording = recorder.recording(env, seed=2)
    return Episode(recording, recording.metrics(), np.array(answers))


def _live_bag(episode: Episode, path, last_answer=(0.3, -0.2)) -> None:
    """A bag as ``rosbag record`` writes it of a live graph: the k-th command of each robot
    is the one published in answer to the k-th odometry (the leader's as the simulator
    publishes it, the followers' raw from the policy), i.e. the command of sample k+1; the
    answer to the last odometry is never executed."""
    from boids_env.rosbag import write_bag

    rec = episode.recording
    published = np.empty_like(rec.commanded)
    published[:-1, 0] = rec.commanded[1:, 0]
    published[:-1, 1:] = episode.answers
    published[-1] = last_answer
    write_bag(Recording(rec.config, rec.time + 1.0, rec.positions, rec.velocities, published),
              path)


def test_a_live_bag_reads_back_into_the_simulators_samples(episode, tmp_path):
    from boids_env.eval.ros.bags import read_live_bag

    bag = tmp_path / "live.bag"
    _live_bag(episode, bag)
    back = read_live_bag(bag, episode.recording.config)
    for name in ("time", "positions", "velocities", "commanded"):
        assert np.array_equal(getattr(back, name), getattr(episode.recording, name)), name
    assert json.dumps(back.metrics(), sort_keys=True) == json.dumps(episode.metrics,
                                                                    sort_keys=True)


def test_read_bag_alone_gets_the_positions_right_and_the_commands_one_tick_early(
        episode, tmp_path):
    from boids_env.rosbag import read_bag

    bag = tmp_path / "live.bag"
    _live_bag(episode, bag)
    plain = read_bag(bag, episode.recording.config)
    assert np.array_equal(plain.positions, episode.recording.positions)
    assert np.array_equal(plain.commanded[:-1, 0], episode.recording.commanded[1:, 0])
    metrics = plain.metrics()
    assert (metrics["V_sep"], metrics["V_coh"]) == (episode.metrics["V_sep"],
                                                    episode.metrics["V_coh"])


def _copy_without(src, dst, topic: str, count: int) -> None:
    """``src`` without the first ``count`` messages of ``topic`` (a recorder that subscribed
    late)."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(src) as reader, Writer(dst) as writer:
        # each connection's own message definition (tf2_msgs and others are not in every
        # typestore)
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data,
                                             md5sum=c.digest)
                 for c in reader.connections}
        skipped = 0
        for conn, stamp, raw in reader.messages():
            if conn.topic == topic and skipped < count:
                skipped += 1
                continue
            writer.write(conns[conn.id], stamp, raw)


@pytest.mark.parametrize(("topic", "count", "error"), [
    ("/robot_0/odom", 1, "odometry counts differ"),
    # one command fewer than samples is fine (the last tick's answer may never be recorded)
    ("/robot_3/cmd_vel", 2, r"fewer than 80 commands .*\{3: 79\}")])
def test_a_bag_missing_a_tick_is_refused(episode, tmp_path, topic, count, error):
    from boids_env.eval.ros.bags import read_live_bag

    full = tmp_path / "full.bag"
    _live_bag(episode, full)
    short = tmp_path / "short.bag"
    _copy_without(full, short, topic, count)
    with pytest.raises(ValueError, match=error):
        read_live_bag(short, episode.recording.config)


def test_boids_ros_metrics_prints_the_table_and_writes_the_files(episode, tmp_path):
    bag = tmp_path / "live.bag"
    _live_bag(episode, bag)
    config = tmp_path / "config.json"
    config.write_text(json.dumps({"env": episode.recording.config.to_dict()}))
    out = tmp_path / "metrics"
    proc = subprocess.run([sys.executable, "-m", "boids_env.train.cli", "ros", "metrics",
                           str(bag), "--config", str(config), "--out", str(out)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert f"{episode.metrics['V_align']:.4f}" in proc.stdout, proc.stdout
    written = json.loads((out / "metrics.json").read_text())
    assert written["V_align"] == episode.metrics["V_align"]
    assert Recording.from_parquet(out / "trajectory.parquet").positions.shape == (
        episode.recording.positions.shape)
    shutil.rmtree(out)
