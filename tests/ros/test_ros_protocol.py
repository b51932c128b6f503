"""The nodes' shared logic as plain Python (no ROS needed): the simulator's command board, the
controller's tick assembly, stamps, episodes, the dynamic_reconfigure description."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from boids_env.eval.graph.protocol import (
    CommandBoard,
    EpisodeInfo,
    TickAssembler,
    is_continuation,
    stamp_ns,
)
from boids_env.eval.ros import reconfigure
from boids_env.policies.reynolds_params import ReynoldsParams, reynolds_params


def test_lockstep_board_counts_only_answers_to_the_current_tick():
    board = CommandBoard(3)
    board.open_tick(new_episode=True)
    board.post(0, 0.1, 0.2, now=0.0)
    board.post(2, 0.3, 0.0, now=0.0)
    assert board.missing() == [1] and not board.wait_all(0.01)
    board.post(1, -0.1, 0.0, now=0.0)
    assert board.wait_all(0.01)
    assert np.array_equal(board.current(), [[0.1, 0.2], [-0.1, 0.0], [0.3, 0.0]])
    board.open_tick()  # the next tick: last tick's answers no longer count
    assert board.missing() == [0, 1, 2]
    assert np.array_equal(board.current(), np.zeros((3, 2)))


def test_a_second_answer_in_one_tick_is_counted_and_the_latest_kept():
    board = CommandBoard(1)
    board.open_tick()
    board.post(0, 0.1, 0.0, now=0.0)
    board.post(0, 0.2, 0.0, now=0.0)
    assert board.extra == 1 and np.array_equal(board.current(), [[0.2, 0.0]])


def test_real_time_board_zeroes_a_command_older_than_the_timeout():
    board = CommandBoard(2, timeout=0.5)
    board.open_tick(new_episode=True)
    board.post(0, 0.4, 0.0, now=10.0)
    board.open_tick()
    board.post(1, 0.0, 0.3, now=10.3)
    commands, timed_out, stale = board.latest(now=10.5)
    assert np.array_equal(commands, [[0.4, 0.0], [0.0, 0.3]]) and not timed_out.any()
    assert stale.tolist() == [True, False], "follower 0 did not answer the last tick"
    commands, timed_out, stale = board.latest(now=10.51)  # follower 0's is 0.51 s old
    assert np.array_equal(commands, [[0.0, 0.0], [0.0, 0.3]]), commands
    assert timed_out.tolist() == [True, False] and not stale.any()


def test_commands_from_before_an_episode_are_stale_in_it():
    board = CommandBoard(1, timeout=5.0)
    board.open_tick(new_episode=True)
    board.post(0, 0.4, 0.0, now=1.0)
    board.open_tick(new_episode=True)
    commands, timed_out, _ = board.latest(now=1.1)
    assert np.array_equal(commands, [[0.0, 0.0]]) and timed_out.all()


def test_non_finite_commands_are_dropped_and_counted():
    board = CommandBoard(1)
    board.open_tick()
    assert not board.post(0, float("nan"), 0.0, now=0.0)
    assert board.rejected == 1 and board.missing() == [0]


def test_board_wakes_a_waiting_simulator_from_another_thread():
    board = CommandBoard(2)
    board.open_tick()
    poster = threading.Timer(0.05, lambda: [board.post(i, 0.1, 0.0, 0.0) for i in range(2)])
    poster.start()
    assert board.wait_all(5.0)
    poster.join()


@pytest.mark.parametrize(("followers", "timeout"), [(0, 0.5), (2, 0.0), (2, 61.0)])
def test_board_rejects_bad_arguments(followers, timeout):
    with pytest.raises(ValueError, match=r"followers|timeout"):
        CommandBoard(followers, timeout)


def test_a_tick_completes_when_every_robot_reported_its_stamp():
    asm = TickAssembler(3)
    assert asm.add(2, 100, 2.0, 0.0, 0.2, 0.0) is None
    assert asm.add(0, 100, 0.0, 0.0, 0.0, 0.1) is None
    assert asm.add(0, 200, 0.0, 0.1, 0.0, 0.1) is None  # the next tick starts arriving
    tick = asm.add(1, 100, 1.0, 0.5, 0.0, 0.0)
    assert tick is not None and tick.stamp_ns == 100
    assert np.array_equal(tick.positions, [[0, 0], [1, 0.5], [2, 0]])
    assert np.array_equal(tick.velocities, [[0, 0.1], [0, 0], [0.2, 0]])
    assert asm.add(1, 100, 1.0, 0.5, 0.0, 0.0) is None, "a tick is returned once"


def test_a_tick_with_a_crowd_waits_for_every_pedestrian_and_carries_them_apart():
    asm = TickAssembler(2, pedestrians=2)  # sources 2 and 3 are the pedestrians
    asm.add(0, 100, 0.0, 0.0, 1.0, 0.0)
    asm.add(1, 100, 1.0, 0.0, 0.0, 0.0)
    assert asm.add(3, 100, 5.0, 6.0, 0.5, -0.5) is None, "pedestrian 0 still missing"
    tick = asm.add(2, 100, 3.0, 4.0, 0.0, 1.0)
    assert tick is not None
    assert np.array_equal(tick.positions, [[0, 0], [1, 0]])
    assert np.array_equal(tick.crowd_positions, [[3, 4], [5, 6]])
    assert np.array_equal(tick.crowd_velocities, [[0, 1], [0.5, -0.5]])
    assert TickAssembler(2).add(1, 1, 0, 0, 0, 0) is None
    lone = TickAssembler(2)
    lone.add(0, 1, 0, 0, 0, 0)
    assert lone.add(1, 1, 0, 0, 0, 0).crowd_positions is None  # no crowd: none


@pytest.mark.parametrize("pedestrians", [-1, 1.5, True, "2"])
def test_tick_assembler_refuses_a_bad_crowd_size(pedestrians):
    with pytest.raises(ValueError, match=r"pedestrians must be a non-negative integer"):
        TickAssembler(2, pedestrians)


def test_ticks_come_in_order_and_a_passed_over_stamp_never_completes():
    asm = TickAssembler(2)
    asm.add(0, 100, 0, 0, 0, 0)
    asm.add(0, 200, 0, 0, 0, 0)
    assert asm.add(1, 200, 1, 0, 0, 0).stamp_ns == 200
    assert asm.add(1, 100, 1, 0, 0, 0) is None  # robot 1's time went back: a restart...
    assert asm.add(0, 100, 0, 0, 0, 0).stamp_ns == 100  # ...so its stamps count again


def test_snapshot_waits_for_every_robot_then_gives_the_latest():
    asm = TickAssembler(2)
    asm.add(0, 100, 0, 0, 0, 0)
    assert asm.snapshot() is None
    asm.add(1, 105, 1, 1, 0, 0)
    asm.add(0, 200, 0.5, 0, 0, 0)
    snap = asm.snapshot()
    assert snap.stamp_ns == 200 and np.array_equal(snap.positions, [[0.5, 0], [1, 1]])


def test_stamps_are_exact_multiples_of_the_period():
    start = stamp_ns(1_000_000_000, 0, 0.1)
    assert stamp_ns(start, 746, 0.1) - start == 74_600_000_000
    assert is_continuation(start, start + 100_000_000, 0.1)
    assert not is_continuation(None, start, 0.1)
    assert not is_continuation(start, start + 1_100_000_000, 0.1)  # a new episode's gap
    assert not is_continuation(start, start - 100_000_000, 0.1)


def test_episode_info_round_trips_and_refuses_anything_else():
    info = EpisodeInfo(2, 7, 81_600_000_000, 1.5707963267948966)
    assert EpisodeInfo.from_json(info.to_json()) == info
    with pytest.raises(ValueError, match="/boids/episode"):
        EpisodeInfo.from_json('{"index": 1}')


def test_reconfigure_description_has_the_generated_modules_shape():
    cfg = reconfigure.config_type(reynolds_params("boids_ros"), sensing_horizon=1.0)
    names = [p["name"] for p in cfg.config_description["parameters"]]
    assert names == list(reconfigure.TUNABLE)
    assert cfg.defaults["horizon"] == 0.75 and cfg.max["horizon"] == 1.0
    assert cfg.defaults["desired_separation"] == 0.45
    assert all(cfg.type[n] == "double" for n in names)
    levels = sorted(cfg.level.values())
    assert levels == [1 << i for i in range(len(names))] and cfg.all_level == sum(levels)
    for name in names:
        assert cfg.min[name] <= cfg.defaults[name] <= cfg.max[name], name


def test_reconfigure_applies_valid_values_and_refuses_invalid_ones():
    params = ReynoldsParams()
    changed, error = reconfigure.apply(params, {"leader_weight": 1.2, "groups": {}})
    assert error is None and changed.leader_weight == 1.2 and changed.horizon == 1.0
    same, error = reconfigure.apply(params, {"horizon": 0.0})
    assert same is params and "horizon must be" in error
    assert reconfigure.values(changed)["leader_weight"] == 1.2


def test_the_description_encodes_as_dynamic_reconfigure_does():
    from boids_env.eval.ros.rospy_path import MissingRosError, import_rospy

    try:
        import_rospy()
        from dynamic_reconfigure.encoding import encode_description, extract_params
    except (MissingRosError, ImportError) as exc:
        pytest.skip(f"dynamic_reconfigure is not installed: {exc}")
    cfg = reconfigure.config_type(ReynoldsParams(), sensing_horizon=2.0)
    msg = encode_description(cfg)
    assert [p.name for p in msg.groups[0].parameters] == list(reconfigure.TUNABLE)
    assert {d.name: d.value for d in msg.max.doubles}["horizon"] == 2.0
    assert len(extract_params(cfg.config_description)) == len(reconfigure.TUNABLE)


def test_reconfigure_assignments_are_parsed_with_clear_errors():
    assert reconfigure.parse_assignments(["leader_weight=1.2", "horizon=0.8"]) == {
        "leader_weight": 1.2, "horizon": 0.8}
    with pytest.raises(ValueError, match="name=value"):
        reconfigure.parse_assignments(["mass=1"])
    with pytest.raises(ValueError, match="leader_weight must be a number"):
        reconfigure.parse_assignments(["leader_weight=heavy"])


def test_ticks_carry_the_orientation_of_robots_with_a_heading():
    assembler = TickAssembler(2)
    assert assembler.add(0, 100, 1.0, 2.0, 0.2, 0.0, 0.6, 0.8) is None
    tick = assembler.add(1, 100, 3.0, 4.0, 0.1, 0.0)
    assert tick.quaternions.tolist() == [[0.6, 0.8], [0.0, 1.0]]
    assert tick.velocities.tolist() == [[0.2, 0.0], [0.1, 0.0]]


@pytest.mark.parametrize(("fields", "message"), [
    ({"robot": "turtlebot3_burger", "path": "external"}, "external leader"),
    ({"robot": "gritsbot", "realism": "ros"}, "leave --realism out"),
])
def test_the_sim_refuses_what_body_frame_commands_cannot_carry(fields, message):
    from boids_env.eval.ros.sim import SimNode, SimOptions

    with pytest.raises(ValueError, match=message):
        SimNode(SimOptions(env_fields=fields))  # before any ROS call
