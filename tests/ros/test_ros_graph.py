"""The study's ROS graph for real: ``boids ros sim`` and ``boids ros controller`` as nodes on a
real roscore (one per test, on a free port), against ``boids run`` in-process."""

from __future__ import annotations

import json
import signal
import time

import numpy as np
import pytest
from graph_support import assert_same_recording

from boids_env.eval.run import run
from boids_env.recording import Recording

pytestmark = pytest.mark.slow

REAL_TIME_TOLERANCE = 0.3
"""Largest |ΔV_x| allowed between a real-time graph and the in-process run of the same 15 s
case: four ticks' worth of every follower flipping a violation flag (0.08 each). A command that
misses its 0.1 s tick is applied one tick late, and one that is 0.5 s late is replaced by
zero; on an idle machine none is late and the runs are identical."""
REAL_TIME_DRIFT = 0.5
"""Largest position difference (m) allowed between the real-time and in-process runs."""


def _in_process(policy: str = "reynolds", seed: int = 0, **fields):
    return run(policy, out=None, seed=seed, env_fields=fields, quiet=True)


def _run_lockstep(ros, *sim_args: str, policy: str = "reynolds", recorder: bool = False):
    """sim --lockstep + controller (+ rosbag record -a); returns the sim's output folder."""
    out = ros.folder / "sim_out"
    wait = ["--wait-for", "/recorder"] if recorder else []
    sim = ros.boids("sim", "ros", "sim", "--lockstep", "--out", str(out), *wait, *sim_args)
    if recorder:
        bag = ros.spawn("recorder", "rosbag", "record", "-a", "-O", str(ros.folder / "run.bag"),
                        "__name:=recorder")
    controller = ros.boids("controller", "ros", "controller", "--policy", policy)
    assert sim.wait(240) == 0, sim.output()
    controller.stop()
    if recorder:
        bag.stop(timeout=120)  # SIGINT: rosbag writes what it has queued, closes the bag
        assert (ros.folder / "run.bag").exists(), bag.output()
    return out, sim


def test_lockstep_graph_reproduces_boids_run_exactly_on_the_default_case(ros):
    out, sim = _run_lockstep(ros)
    reference = _in_process()
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "lockstep graph vs boids run")
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)
    assert metrics["steps"] == 746 and metrics["duration"] == pytest.approx(74.6)
    config = json.loads((out / "config.json").read_text())
    assert config["ros"]["controllers"] == ["/reynolds_controller"], config["ros"]
    assert config["ros"]["extra_commands"] == 0, config["ros"]
    text = sim.output()
    assert "V_sep" in text and f"{reference.metrics['V_sep']:.4f}" in text, text[-2000:]
    assert ros.param("/use_sim_time") is True


def test_rosbag_record_of_a_lockstep_run_gives_the_sims_metrics(ros):
    from boids_env.config import EnvConfig
    from boids_env.eval.ros.bags import read_live_bag
    from boids_env.rosbag import read_bag

    out, _ = _run_lockstep(ros, "--max-cycles", "300", "--leader-speed", "0.6",
                           recorder=True)
    bag = ros.folder / "run.bag"
    ours = Recording.from_parquet(out / "trajectory.parquet")
    sim_metrics = json.loads((out / "metrics.json").read_text())
    config = EnvConfig.from_dict(json.loads((out / "config.json").read_text())["env"])
    live = read_live_bag(bag, config)
    assert_same_recording(live, ours, "bag (read_bag + live alignment) vs sim")
    from_bag = live.metrics()
    for key in ("V_sep", "V_coh", "V_align", "V_align_unwrapped", "leader_path_deviation",
                "min_distance", "polarization"):
        assert from_bag[key] == sim_metrics[key], f"{key}: bag {from_bag[key]} vs sim " \
                                                  f"{sim_metrics[key]}"
    # read_bag alone pairs the k-th command with the k-th odometry: the positions, and so
    # V_sep and V_coh, are the sim's exactly; V_align is the same series one tick later
    plain = read_bag(bag, config).metrics()
    assert (plain["V_sep"], plain["V_coh"]) == (sim_metrics["V_sep"], sim_metrics["V_coh"])
    followers = config.scenario.robots - 1
    assert abs(plain["V_align"] - sim_metrics["V_align"]) <= 2 * followers / 300, (
        plain["V_align"], sim_metrics["V_align"])


def test_a_turtlebot3_graph_speaks_body_frame_and_equals_boids_run_exactly(ros):
    """A robot with a heading on the graph as a TurtleBot3 speaks: body-frame cmd_vel
    (linear.x, angular.z) from the controller, oriented odometry with the twist in the
    robot's frame (REP 105); the lockstep run equals boids run bit for bit."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out, _ = _run_lockstep(ros, "--robot", "turtlebot3_burger", "--max-cycles", "150",
                           "--robots", "7", recorder=True)
    reference = _in_process(robot="turtlebot3_burger", max_cycles=150, robots=7)
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "turtlebot graph vs boids run")
    for name in ("headings", "angular_velocities", "native"):
        assert np.array_equal(getattr(ours, name), getattr(reference.recording, name)), name
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)
    assert json.loads((out / "config.json").read_text())["env"]["world"]["robot"] == \
        "turtlebot3_burger"
    cmd, odom = {}, {}
    with AnyReader([ros.folder / "run.bag"],
                   default_typestore=get_typestore(Stores.ROS1_NOETIC)) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic.endswith("/cmd_vel"):
                cmd.setdefault(conn.topic, []).append((msg.linear.x, msg.linear.y,
                                                       msg.angular.z))
            elif conn.topic.endswith("/odom"):
                odom.setdefault(conn.topic, []).append(
                    (msg.twist.twist.linear.y, msg.twist.twist.angular.z,
                     msg.pose.pose.orientation.z, msg.pose.pose.orientation.w))
    assert len(cmd) == 7 and len(odom) == 7
    commands = np.array([c for k in range(1, 7) for c in cmd[f"/robot_{k}/cmd_vel"]])
    assert np.all(commands[:, 1] == 0.0), "body-frame cmd_vel: linear.y is zero"
    assert np.abs(commands[:, 2]).max() > 0.5, "body-frame cmd_vel: angular.z turns"
    assert np.all(commands[:, 0] >= 0.0) and commands[:, 0].max() <= 0.22
    # the k-th command answers the k-th odometry: it is the next sample's (v, ω)
    np.testing.assert_array_equal(commands.reshape(6, -1, 3)[:, :150, [0, 2]],
                                  ours.native[1:, 1:].transpose(1, 0, 2))
    twists = np.array([o for k in range(7) for o in odom[f"/robot_{k}/odom"]])
    assert np.abs(twists[:, 0]).max() < 0.01, "the twist is in the robot's frame"
    assert np.abs(twists[:, 1]).max() > 0.5 and np.abs(twists[:, 2]).max() > 0.5
    # boids ros metrics of the bag: the sim's numbers
    from boids_env.config import EnvConfig
    from boids_env.eval.ros.bags import read_live_bag

    config = EnvConfig.from_dict(json.loads((out / "config.json").read_text())["env"])
    live = read_live_bag(ros.folder / "run.bag", config)
    assert np.array_equal(live.positions, ours.positions)
    assert np.array_equal(live.native, ours.native)
    from_bag = live.metrics()
    for key in ("V_sep", "V_coh", "V_align", "V_align_heading", "touching_fraction"):
        assert from_bag[key] == metrics[key], (key, from_bag[key], metrics[key])


@pytest.mark.parametrize("policy", ["learned", "boids_env.policies.random_policy:RandomPolicy"])
def test_any_policy_runs_as_the_controller_node(ros, policy):
    out, _ = _run_lockstep(ros, "--max-cycles", "120", "--robots", "7", "--seed", "3",
                           policy=policy)
    ours = Recording.from_parquet(out / "trajectory.parquet")
    if policy == "learned":
        reference = _in_process("learned", seed=3, robots=7, max_cycles=120)
        assert_same_recording(ours, reference.recording, "learned policy graph vs boids run")
    else:  # random: the same seeded draws as in-process (the controller resets it with the seed)
        reference = _in_process(policy, seed=3, robots=7, max_cycles=120)
        assert_same_recording(ours, reference.recording, "random policy graph vs boids run")


def test_several_episodes_reset_the_controller_each_time(ros):
    out, _ = _run_lockstep(ros, "--episodes", "2", "--max-cycles", "60", "--seed", "5")
    for index, seed in enumerate((5, 6)):
        ours = Recording.from_parquet(out / f"episode_{index:03d}" / "trajectory.parquet")
        reference = _in_process(seed=seed, max_cycles=60)
        assert_same_recording(ours, reference.recording, f"episode {index} (seed {seed})")


def test_a_walking_person_and_a_crowd_on_the_ros1_graph_equal_boids_run(ros):
    """A person walked by JuPedSim leads through a doorway with a crowd of 3: the sim
    publishes every /pedestrian_k/odom with each tick, the controller waits for them and
    observes them, and the lockstep run equals boids run bit for bit."""
    out, _ = _run_lockstep(ros, "--scene", "doorway", "--leader", "person", "--crowd", "3",
                           "--robots", "4", "--max-cycles", "150")
    reference = _in_process(scene="doorway", leader="person", crowd=3, robots=4,
                            max_cycles=150)
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "person and crowd graph vs boids run")
    assert np.array_equal(ours.pedestrians, reference.recording.pedestrians)
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)


def test_real_time_graph_stays_within_tolerance_of_boids_run(ros):
    out = ros.folder / "rt"
    sim = ros.boids("sim", "ros", "sim", "--max-cycles", "150", "--out", str(out))
    controller = ros.boids("controller", "ros", "controller")
    assert sim.wait(120) == 0, sim.output()
    controller.stop()
    reference = _in_process(max_cycles=150)
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("V_sep", "V_coh", "V_align"):
        assert abs(metrics[key] - reference.metrics[key]) <= REAL_TIME_TOLERANCE, (
            key, metrics[key], reference.metrics[key])
    ours = Recording.from_parquet(out / "trajectory.parquet")
    gap = np.abs(ours.positions - reference.recording.positions).max()
    assert gap < REAL_TIME_DRIFT, f"real-time positions drift {gap:.3f} m from in-process"
    stats = json.loads((out / "config.json").read_text())["ros"]
    assert stats["mode"] == "real time" and 14.9 <= stats["wall_time"] <= 25, stats
    if stats["late_ticks"] == 0 and stats["timed_out"] == 0 and stats["stale"] == 0:
        # every answer arrived within its tick: the real-time run is the lockstep one
        assert_same_recording(ours, reference.recording, "punctual real-time graph")


def test_killing_the_controller_stops_the_robots_after_the_timeout(ros):
    out = ros.folder / "kill"
    sim = ros.boids("sim", "ros", "sim", "--max-cycles", "90", "--out", str(out))
    controller = ros.boids("controller", "ros", "controller")
    controller.wait_for_line("new episode", 60)
    time.sleep(4.5)  # past the 2 s start-up hold: the followers are moving
    controller.stop(signal.SIGKILL)
    killed_at = time.monotonic()
    assert sim.wait(60) == 0, sim.output()
    rec = Recording.from_parquet(out / "trajectory.parquet")
    commands = rec.commanded[:, 1:]  # (samples, followers, 2)
    moving = np.flatnonzero(np.abs(commands).max(axis=(1, 2)) > 0)
    assert len(moving) > 10, "the followers never moved before the kill"
    last = moving[-1]
    assert last <= 84, f"last non-zero command at sample {last}: no stop after the kill"
    assert np.all(commands[last + 1:] == 0) and len(commands) - last > 10
    # the silent controller's last commands are kept for the timeout (0.5 s = 5 ticks),
    # not longer: then (0, 0), as a robot driver's safety stop
    held = 1
    while np.array_equal(commands[last - held], commands[last]):
        held += 1
    assert held <= 6, f"the last command was applied {held} ticks (timeout 0.5 s)"
    speeds = np.hypot(*rec.velocities[-1, 1:].T)
    assert speeds.max() < 0.01, f"followers still moving at {speeds.max():.3f} m/s"
    stats = json.loads((out / "config.json").read_text())["ros"]
    assert stats["timed_out"] >= 12 * (len(commands) - 1 - last), stats
    assert time.monotonic() - killed_at < 60


def test_a_policy_node_drives_a_bare_odometry_source_and_is_reconfigured_live(ros):
    out = ros.folder / "fake.json"
    controller = ros.boids("controller", "ros", "controller", "--robots", "4")
    robots = ros.node("fake", "fake_robots.py", "--robots", "4", "--ticks", "60", "--out",
                      str(out), "--reconfigure-at", "35", "--leader-weight", "0.3")
    assert robots.wait(90) == 0, robots.output() + controller.output()
    tool = ros.boids("reconfigure", "ros", "reconfigure", "max_force=0.3", "horizon=5")
    assert tool.wait(60) == 0, tool.output()
    # the server clamps the horizon to the sensing horizon (the observations' 1 m)
    assert "max_force = 0.3" in tool.output() and "horizon = 1\n" in tool.output(), \
        tool.output()
    assert ros.param("/reynolds_controller/max_force") == 0.3
    controller.stop()
    log = json.loads(out.read_text())
    # every tick answered once, for every follower
    assert log["received"][1:] == [60] * 3, log["received"]
    positions = np.array(log["positions"])  # (ticks, robots, 2)
    # the Reynolds start-up hold (2 s), then the followers close in on the leader
    assert np.allclose(positions[20, 1:], positions[0, 1:]), "followers moved during start-up"
    before = np.linalg.norm(positions[20, 1:] - positions[20, 0], axis=1)
    after = np.linalg.norm(positions[-1, 1:] - positions[-1, 0], axis=1)
    assert np.all(after < before), (before, after)
    # the markers carry each rule's weighted force as every picture of the flock draws it
    # (boids_env.style): the leader term w · (p_leader - p_i), 0.5 m a metre, at most 0.25 m
    # long; with the weight reconfigured to 0.3 its arrow is short of that cap
    from boids_env import style

    assert log["reconfigured"] == {"tick": 35, "leader_weight": 0.3, "param": 0.3}
    stamps = {s: i for i, s in enumerate(log["stamps"])}
    checked = {1.0: 0, 0.3: 0}
    for entry in log["markers"]:
        tick = stamps[entry["stamp"]]
        assert set(entry["arrows"]) == {"separation", "cohesion", "alignment", "leader"}
        offset = positions[tick, 0] - positions[tick, 1]
        if tick < 20 or 35 <= tick <= 37 or np.linalg.norm(offset) <= 0.1:
            continue  # the start-up hold, the switch
        weight = 1.0 if tick < 35 else 0.3
        drawn = style.arrow_vectors(np.array([weight * offset]))[0]
        assert np.allclose(entry["arrows"]["leader"]["1"], drawn, atol=1e-4), (
            tick, weight, entry["arrows"]["leader"]["1"], drawn)
        checked[weight] += 1
    assert checked[1.0] and checked[0.3], checked


def test_unsynchronised_odometry_is_answered_at_the_control_rate(ros):
    out = ros.folder / "fake.json"
    controller = ros.boids("controller", "ros", "controller", "--robots", "3", "--sync",
                           "rate")
    robots = ros.node("fake", "fake_robots.py", "--robots", "3", "--ticks", "40", "--out",
                      str(out), "--unsynced")
    assert robots.wait(90) == 0, robots.output() + controller.output()
    controller.stop()
    log = json.loads(out.read_text())
    # about one command per tick (rate mode runs on its own 0.1 s clock)
    assert all(30 <= n <= 45 for n in log["received"][1:]), log["received"]
    positions = np.array(log["positions"])
    assert np.linalg.norm(positions[-1, 1:] - positions[0, 1:], axis=1).min() > 0.05


def test_external_leader_follows_robot_0_cmd_vel_and_lone_followers_stay(ros):
    out = ros.folder / "ext"
    sim = ros.boids("sim", "ros", "sim", "--path", "external", "--robots", "4",
                    "--max-cycles", "45", "--no-wait", "--out", str(out))
    teleop = ros.spawn("teleop", "rostopic", "pub", "-r", "20", "/robot_0/cmd_vel",
                       "geometry_msgs/Twist", "{linear: {x: 0.3, y: 0.0}}")
    assert sim.wait(60) == 0, sim.output()
    teleop.stop()
    rec = Recording.from_parquet(out / "trajectory.parquet")
    leader = rec.positions[:, 0]
    assert leader[-1, 0] > 0.2 and abs(leader[-1, 1]) < 1e-6, leader[-1]
    assert np.all(rec.positions[:, 0][:20, 0] == 0.0), "the leader moved during start-up"
    # no controller: every follower gets the zero command and stays where it started
    assert np.all(rec.commanded[:, 1:] == 0)
    assert np.allclose(rec.positions[-1, 1:], rec.positions[0, 1:])


def test_lockstep_graph_with_ros_realism_reproduces_boids_run_with_it(ros):
    out, _ = _run_lockstep(ros, "--max-cycles", "150", "--seed", "4", "--realism", "ros")
    ours = Recording.from_parquet(out / "trajectory.parquet")
    reference = _in_process(seed=4, max_cycles=150, realism="ros")
    assert_same_recording(ours, reference.recording, "realism ros graph vs boids run")
    ideal = _in_process(seed=4, max_cycles=150)
    assert not np.array_equal(ideal.recording.positions, ours.positions)  # realism acted
