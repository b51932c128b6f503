"""The opt-in leader frame, and turned scenes (``path_rotation``, ``path_mirror``)."""

import math
from functools import partial

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.observations import Observer


def _turn(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _slot_order_free(layout, obs):
    """``obs`` with each neighbour-slot column sorted. The unjittered grid puts neighbours at
    equal distances: in a turned scene their distances differ in the last bit and either may
    take the first slot. Sorted, the slots are the same whatever that order (and close for
    close inputs)."""
    out = obs.copy()
    layout.slots(out)[:] = np.sort(layout.slots(obs), axis=0)
    return out


class LinearPolicy:
    """A fixed, deterministic function of the observation (random weights)."""

    def __init__(self, size, seed=0):
        rng = np.random.default_rng(seed)
        self.w1 = rng.normal(0, 0.3, (size, 16))
        self.w2 = rng.normal(0, 0.3, (16, 2))

    def __call__(self, obs):
        return 0.5 * np.tanh(np.tanh(obs @ self.w1) @ self.w2)


@pytest.mark.parametrize("deg", [30.0, 90.0, -135.0])
def test_observations_in_the_leader_frame_do_not_change_when_the_scene_turns(deg):
    rng = np.random.default_rng(4)
    pos = rng.uniform(-1.5, 1.5, (9, 2))
    vel = rng.uniform(-0.5, 0.5, (9, 2))
    vel[0] = [0.3, 0.4]  # the leader moves: its heading sets the frame
    config = EnvConfig.from_kwargs(robots=9, frame="leader")
    turn = _turn(deg)
    a, b = Observer(config), Observer(config)
    a.reset(None)
    b.reset(None)
    obs_a, obs_b = a(pos, vel), b(pos @ turn.T, vel @ turn.T)
    np.testing.assert_allclose(obs_b, obs_a, atol=1e-6)
    # the same frame actions are different world commands, turned by the same angle
    act = rng.uniform(-0.5, 0.5, (8, 2))
    np.testing.assert_allclose(b.to_world(act), a.to_world(act) @ turn.T, atol=1e-12)
    # and in the world frame the observations do turn
    world = EnvConfig.from_kwargs(robots=9)
    wa, wb = Observer(world), Observer(world)
    assert not np.allclose(wa(pos, vel), wb(pos @ turn.T, vel @ turn.T), atol=1e-3)


def test_a_turned_scene_turns_every_command_of_a_leader_frame_policy():
    deg = 30.0
    turn = _turn(deg)
    # path_size 1.47: no corner falls exactly on the 0.1 m arrival margin (a float tie)
    fields = dict(robots=7, path_size=1.47, init_jitter=0.0, frame="leader", max_cycles=80)
    plain, turned = parallel_env(**fields), parallel_env(**fields, path_rotation=deg)
    obs_p, _ = plain.reset(seed=0)
    obs_t, _ = turned.reset(seed=0)
    policy = LinearPolicy(plain.layout.size)
    slot_order_free = partial(_slot_order_free, plain.layout)
    for step in range(80):
        for agent in plain.agents:
            np.testing.assert_allclose(slot_order_free(obs_t[agent]),
                                       slot_order_free(obs_p[agent]), atol=1e-4,
                                       err_msg=f"step {step}, {agent}")
        act_p = {a: policy(slot_order_free(obs_p[a])) for a in plain.agents}
        act_t = {a: policy(slot_order_free(obs_t[a])) for a in turned.agents}
        obs_p, *_ = plain.step(act_p)
        obs_t, *_ = turned.step(act_t)
        sp, st = plain.snapshot(), turned.snapshot()
        np.testing.assert_allclose(st.commanded, sp.commanded @ turn.T, atol=1e-4,
                                   err_msg=f"step {step}")
        np.testing.assert_allclose(st.positions, sp.positions @ turn.T, atol=1e-4,
                                   err_msg=f"step {step}")
    assert np.abs(sp.commanded[1:]).max() > 0.05, "the policy commanded something"


def test_world_frame_is_the_default_and_actions_are_world_commands():
    env = parallel_env(robots=3, startup_time=100)
    env.reset(seed=0)
    env.step({"follower_1": np.array([0.3, -0.2]), "follower_2": np.array([0.0, 0.1])})
    np.testing.assert_array_equal(env.snapshot().commanded[1:], [[0.3, -0.2], [0.0, 0.1]])


def test_leader_frame_starts_along_the_first_move_and_follows_the_leader():
    env = parallel_env(robots=3, frame="leader", init_jitter=0.0)
    obs, _ = env.reset(seed=0)
    # at rest the frame faces the square's first leg (+y): the leader is ahead (+x in frame)
    rel = obs["follower_1"][env.layout.leader_position]
    world = np.array([0.5, 0.5])  # follower 1 sits at (-0.5, -0.5)
    np.testing.assert_allclose(rel, [world[1], -world[0]], atol=1e-6)
    mirrored = parallel_env(robots=3, frame="leader", path_mirror=True, path_rotation=90)
    mirrored.reset(seed=0)
    assert mirrored.leader.initial_heading == pytest.approx(math.pi)  # (0,1) turned by 90°


def test_turned_and_mirrored_squares_are_the_study_square_turned():
    base = parallel_env(robots=2, init_jitter=0.0)
    base.reset(seed=0)
    path = base.leader.reference_path()
    for deg, mirror in [(90.0, False), (0.0, True), (45.0, True)]:
        env = parallel_env(robots=2, init_jitter=0.0, path_rotation=deg, path_mirror=mirror,
                           path_size=3.0)
        env.reset(seed=0)
        m = np.diag([-1.0 if mirror else 1.0, 1.0])
        np.testing.assert_allclose(env.leader.reference_path(),
                                   path * 0.75 @ (_turn(deg) @ m).T, atol=1e-12)


def test_a_turned_square_that_leaves_the_arena_is_refused():
    with pytest.raises(ValueError, match="path_size"):
        parallel_env(path_rotation=45)  # corners at 5.66 m in a 5 m arena


def test_a_fast_leader_with_a_small_margin_still_finishes_its_path():
    env = parallel_env(robots=2, leader_speed=2.0, arrival_margin=0.01)
    env.reset(seed=0)
    steps = 0
    while env.agents:
        env.step({"follower_1": np.zeros(2)})
        steps += 1
    assert env.leader.finished, "the leader overshot its targets forever"
    assert steps < 400, steps


def test_relative_actions_add_the_observed_leader_velocity():
    # the leader's first leg runs +y at 0.55 m/s; a zero action commands what each follower
    # observes of it, a non-zero one is added to that (then the speed limit applies)
    env = parallel_env(robots=4, relative_actions=True, startup_time=0.0, max_cycles=30)
    obs, _ = env.reset(seed=0)
    assert env.action_space("follower_1").high[0] == pytest.approx(1.0)  # 2 × max_speed
    for _ in range(10):
        obs, *_ = env.step({a: np.zeros(2) for a in env.agents})
    seen = np.array([obs[a][env.layout.leader_velocity] for a in env.agents], dtype=np.float64)
    assert np.linalg.norm(seen, axis=1).min() > 0.4, "the leader is moving"
    offset = np.array([-0.2, 0.1])
    env.step({a: offset for a in env.agents})
    want = seen + offset
    speed = np.linalg.norm(want, axis=1, keepdims=True)
    want = want * np.minimum(1.0, 0.5 / speed)  # max_speed 0.5 in the world frame
    np.testing.assert_allclose(env.snapshot().commanded[1:], want, atol=1e-12)


def test_relative_actions_in_the_leader_frame_turn_with_the_scene():
    turn = _turn(30.0)
    fields = dict(robots=7, path_size=1.47, init_jitter=0.0, frame="leader",
                  relative_actions=True, max_cycles=60)
    plain, turned = parallel_env(**fields), parallel_env(**fields, path_rotation=30.0)
    obs_p, _ = plain.reset(seed=0)
    obs_t, _ = turned.reset(seed=0)
    policy = LinearPolicy(plain.layout.size, seed=1)
    slot_order_free = partial(_slot_order_free, plain.layout)
    for _ in range(60):
        obs_p, *_ = plain.step({a: policy(slot_order_free(obs_p[a])) for a in plain.agents})
        obs_t, *_ = turned.step({a: policy(slot_order_free(obs_t[a])) for a in turned.agents})
        np.testing.assert_allclose(turned.snapshot().commanded,
                                   plain.snapshot().commanded @ turn.T, atol=1e-4)


def test_relative_actions_is_a_flag():
    with pytest.raises(ValueError, match="relative_actions"):
        EnvConfig.from_kwargs(relative_actions="yes")


def test_times_matrix_is_the_matrix_product_rounded_as_two_products_and_a_sum():
    from boids_env.vectors import times_matrix

    rng = np.random.default_rng(2)
    v, m = rng.normal(size=(50, 3, 2)), _turn(33.0)
    out = times_matrix(v, m)
    np.testing.assert_allclose(out, v @ m, rtol=0, atol=1e-15)
    # each component rounded twice (product, then sum), never fused into one rounding
    x, y = v[..., 0], v[..., 1]
    assert np.array_equal(out[..., 0], np.add(np.multiply(x, m[0, 0]), np.multiply(y, m[1, 0])))
    assert np.array_equal(times_matrix([1.0, 2.0], m), times_matrix([[1.0, 2.0]], m)[0])


def test_sin_cos_is_within_two_ulp_of_the_c_library_and_keeps_the_symmetries():
    from boids_env.vectors import sin_cos

    phi = np.concatenate([np.linspace(-40.0, 40.0, 20001), [0.0, 1e-300, -2.5e-8]])
    sin, cos = sin_cos(phi)
    want_sin = np.array([math.sin(p) for p in phi.tolist()])
    want_cos = np.array([math.cos(p) for p in phi.tolist()])
    # absolute error within 2 ulp of 1 (the values are at most 1 in size)
    assert np.abs(sin - want_sin).max() <= 2 * np.spacing(1.0)
    assert np.abs(cos - want_cos).max() <= 2 * np.spacing(1.0)
    # relative accuracy near zero, where an absolute bound says little
    small = np.abs(phi) < 1e-3
    np.testing.assert_allclose(sin[small], want_sin[small], rtol=3e-16, atol=0)
    assert sin[phi == 0.0][0] == 0.0 and cos[phi == 0.0][0] == 1.0
    # odd and even, bit for bit
    minus_sin, minus_cos = sin_cos(-phi)
    assert np.array_equal(minus_sin, -sin) and np.array_equal(minus_cos, cos)
    assert np.all(sin * sin + cos * cos <= 1.0 + 4 * np.spacing(1.0))
