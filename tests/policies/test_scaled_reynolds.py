"""Reynolds sized for the robot (preset ``scaled``, issue 38): the study's distances are free
gaps between Spheros; bound to a larger robot they keep those gaps, and the flock follows the
route and clears the leader's path."""

import dataclasses
import math

import numpy as np
import pytest

from boids_env.environment import BoidsEnv
from boids_env.eval.episode import env_fields_for, run_episode
from boids_env.policies.reynolds import ReynoldsPolicy, sized_params
from boids_env.policies.reynolds_params import PRESETS, ReynoldsParams, reynolds_params


def _bound(preset, robot):
    policy = ReynoldsPolicy(preset)
    env = BoidsEnv(**env_fields_for(policy, {"robot": robot}))
    env.reset(seed=0)
    policy.bind(env)
    return policy, env


def test_the_scaled_preset_follows_the_route_and_clears_the_leaders_path():
    p = reynolds_params("scaled")
    assert p.scale_to_robot and p.follow_route
    assert p.robot_avoidance == 0.15 and p.personal_space == 0.56
    assert p.obstacle_lookahead == 1.0  # a holonomic Sphero's; sized for a turning robot
    assert (p.path_width, p.path_flee, p.walls_first) == (0.3, 0.5, True)
    assert PRESETS["paper"] == ReynoldsParams()  # the study's preset is untouched
    assert not reynolds_params("route").scale_to_robot


def test_distances_keep_the_spheros_free_gaps_on_a_turtlebot():
    # TurtleBot3 Burger: r = 0.105 m, 0.069 m more than the Sphero's 0.036 m
    # (its top speed 0.22 m/s bound from the env, a quarter turn in 1.5 s)
    p = sized_params(dataclasses.replace(reynolds_params("scaled"), max_speed=0.22), 0.105,
                     1.5)
    assert p.desired_separation == pytest.approx(0.7 + 2 * 0.069, abs=1e-12)  # 0.838
    # the free gap, plus the way a leader at 0.22 m/s comes while the follower turns
    assert p.personal_space == pytest.approx(0.56 + 2 * 0.069 + 0.22 * 1.5, abs=1e-12)
    assert p.obstacle_distance == pytest.approx(0.4 + 0.069, abs=1e-12)  # 0.469
    assert p.obstacle_lookahead == pytest.approx(2.5, abs=1e-12)  # 1 s + 1.5 s to turn
    assert p.path_time == pytest.approx(3.5, abs=1e-12)  # 2 s of the leader's path + 1.5 s
    assert p.path_width == pytest.approx(0.3 + 2 * 0.069, abs=1e-12)  # centre to centre
    assert p.robot_avoidance == 0.15  # a surface gap already
    # a Sphero's are the preset's own; a preset without a personal space keeps none
    sphero = reynolds_params("scaled")
    assert sized_params(sphero, 0.036) is sphero
    assert sized_params(reynolds_params("route"), 0.105).personal_space == 0.0


def test_binding_sizes_once_for_the_env_robot():
    policy, env = _bound("scaled", "turtlebot3_burger")
    first = policy.params
    assert first.desired_separation == pytest.approx(0.838, abs=1e-12)
    # a quarter turn at 2.84 rad/s after the ramp to it at 3.2 rad/s²
    turn = math.pi / 2 / 2.84 + 2.84 / 3.2
    assert first.obstacle_lookahead == pytest.approx(1.0 + turn, abs=1e-12)
    assert first.personal_space == pytest.approx(0.698 + 0.22 * turn, abs=1e-12)
    policy.bind(env)  # every episode binds again: the distances do not grow
    assert policy.params == first
    other = BoidsEnv(**env_fields_for(policy, {"robot": "gritsbot"}))
    other.reset(seed=0)
    policy.bind(other)  # GRITSbot: r = 0.055 m, 3.64 rad/s at once
    assert policy.params.desired_separation == pytest.approx(0.7 + 2 * 0.019, abs=1e-12)
    grits_turn = math.pi / 2 / (0.4 / 0.11)
    assert policy.params.obstacle_lookahead == pytest.approx(1.0 + grits_turn, abs=1e-12)
    # sized from the preset's own values, not from the TurtleBot3's (its 0.22 m/s)
    assert policy.params.personal_space == pytest.approx(0.56 + 2 * 0.019 + 0.2 * grits_turn,
                                                         abs=1e-12)
    sphero, _ = _bound("scaled", "sphero")
    assert sphero.params == dataclasses.replace(reynolds_params("scaled"), max_speed=0.5)
    paper, _ = _bound("paper", "turtlebot3_burger")
    assert paper.params.desired_separation == 0.7  # only scale_to_robot sizes


def test_along_the_route_the_leader_term_seeks_the_ring_and_pushes_out_of_the_path():
    from boids_env.policies.reynolds import path_push, ring_force

    # route 2 m east; the personal space 0.5 m: seek the point 1.5 m east
    assert np.allclose(ring_force(np.array([[2.0, 0.0]]), 0.5), [[1.5, 0.0]])
    # the leader 1 m east walking west at 0.5 m/s; the follower 0.1 m south of its line:
    # in the strip ahead (1 m <= 2 s x 0.5 + 0.5), pushed 0.5 - 0.1 = 0.4 m further south
    push = path_push(np.array([[1.0, 0.1]]), np.array([[-0.5, 0.0]]), 0.5)
    assert np.allclose(push, [[0.0, -0.4]])
    # behind the walking leader: no push
    assert np.allclose(path_push(np.array([[-1.0, 0.1]]), np.array([[-0.5, 0.0]]), 0.5), 0)


@pytest.mark.slow
def test_a_scaled_turtlebot_flock_never_touches_where_the_studys_packs():
    def run(preset):
        policy = ReynoldsPolicy(preset)
        env = BoidsEnv(**env_fields_for(policy, {"robot": "turtlebot3_burger",
                                                 "max_cycles": 600}))
        return run_episode(env, policy, seed=0).metrics

    paper, scaled = run("paper"), run("scaled")
    assert paper["touching_fraction"] > 0.3, paper["touching_fraction"]
    assert scaled["touching_fraction"] == 0.0, scaled["touching_fraction"]
    assert scaled["lost_followers"] == 0


def test_scale_to_robot_is_validated():
    with pytest.raises((TypeError, ValueError), match="scale_to_robot"):
        dataclasses.replace(ReynoldsParams(), scale_to_robot="yes")


def _one_follower_obs(policy, env, leader_at, leader_velocity, leader_heading):
    """One TurtleBot3 follower at rest heading east, alone but for the leader at
    ``leader_at`` (m, relative), straight route to it (an open floor)."""
    obs = np.zeros((1, env.layout.size))
    layout = env.layout
    obs[0, layout.leader_position] = leader_at
    obs[0, layout.leader_velocity] = leader_velocity
    obs[0, layout.block("leader_heading")] = leader_heading
    obs[0, layout.block("own_heading")] = (1.0, 0.0)
    distance = math.hypot(*leader_at)
    obs[0, layout.block("route")] = (leader_at[0] / distance, leader_at[1] / distance,
                                     distance, 1.0)
    policy._steps = 10**6  # past the start-up hold
    return obs


@pytest.mark.parametrize(("leader_velocity", "case"), [
    ((-0.242, 0.0), "backing out towards the follower at 1.1 x its top speed"),
    ((0.0, 0.0), "turned round towards the follower, about to drive"),
])
def test_a_turtlebot_follower_leaves_the_path_of_a_leader_coming_back(leader_velocity, case):
    # The leader 1.2 m east of a TurtleBot3 follower, 5 cm north of its line, heading west
    # (towards it). A follower that must turn a quarter turn (1.4 s) before it moves sideways
    # needs to start now: it must not be pulled towards the leader's ring, and it must be
    # pushed out of the leader's way (south: it is on the south side of the leader's line).
    policy = ReynoldsPolicy("scaled")
    env = BoidsEnv(**env_fields_for(policy, {"robot": "turtlebot3_burger", "robots": 2}))
    env.reset(seed=0)
    policy.bind(env)
    obs = _one_follower_obs(policy, env, (1.2, 0.05), leader_velocity, (-1.0, 0.0))
    policy.act_batch(obs)
    lead = policy.forces["leader"][0]
    assert lead[0] <= 0.0, (case, lead)  # never towards the oncoming leader
    assert lead[1] < -0.1, (case, lead)  # out of its path, to the follower's side


def test_behind_a_leader_driving_away_the_turtlebot_still_follows():
    policy = ReynoldsPolicy("scaled")
    env = BoidsEnv(**env_fields_for(policy, {"robot": "turtlebot3_burger", "robots": 2}))
    env.reset(seed=0)
    policy.bind(env)
    obs = _one_follower_obs(policy, env, (1.5, 0.05), (0.242, 0.0), (1.0, 0.0))
    policy.act_batch(obs)
    lead = policy.forces["leader"][0]
    assert lead[0] > 0.0  # pulled after it


def test_a_neighbour_does_not_hold_a_follower_against_a_wall():
    from boids_env.policies.reynolds import WALL_YIELD, walls_then_robots

    # the wall pushes south at 0.1 N, a neighbour north at 0.1 N: summed they cancel (the
    # follower stays pressed to the wall); walls first, the neighbour's push against the wall
    # loses WALL_YIELD of itself
    out = walls_then_robots(np.array([[0.0, -0.1]]), np.array([[0.05, 0.1]]), 0.23)
    assert np.allclose(out, [[0.05, -0.1 + 0.1 * (1 - WALL_YIELD)]])
    assert out[0, 1] < 0  # off the wall
    # a push along the wall or away from it is kept, within what the wall leaves
    assert np.allclose(walls_then_robots(np.array([[0.0, -0.2]]), np.array([[0.0, -0.2]]),
                                         0.23), [[0.0, -0.23]])


@pytest.mark.parametrize(("name", "value"), [("path_width", -0.1), ("path_flee", -1.0),
                                             ("path_time", 61.0), ("path_speed", 0.0),
                                             ("walls_first", "yes")])
def test_the_path_clearing_parameters_are_validated(name, value):
    with pytest.raises(ValueError, match=f"{name} must be .*, got"):
        dataclasses.replace(ReynoldsParams(), **{name: value})


def test_the_scaled_preset_senses_and_avoids_the_arena_walls_too():
    # the study's arena has no static slots by default; the scaled preset asks for them
    assert ReynoldsPolicy("scaled").env_fields == {"route_sensing": True, "static_slots": 4}
    assert ReynoldsPolicy("route").env_fields == {"route_sensing": True}  # unchanged
    policy, env = _bound("scaled", "turtlebot3_burger")
    assert env.config.world.scene == "arena" and policy.avoid
