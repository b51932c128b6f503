"""A refused ``reset()`` leaves the env exactly as it was (issue 39 item 4): the episode in
progress goes on bit for bit as in a twin env that was never asked, its config, leader,
world and random stream untouched, whatever refused the new episode."""

import numpy as np
import pytest

from boids_env import parallel_env


def _bad_world(*args, **kwargs):
    raise RuntimeError("the physics refused the world")


# (env fields, refused reset options, a patch of reset's last stage or None, the error)
REFUSALS = {
    "random waypoints never clear the scene": (
        {"scene": "pillars"}, {"path": "random_waypoints", "random_waypoint_count": 50}, None,
        "random_waypoints: no path"),
    "no room for the crowd": (
        {"scene": "small_room", "crowd": 12}, {"person_radius": 0.4}, None,
        "crowd must be at most"),
    "a bad option value": ({}, {"leader_speed": -1.0}, None, "leader_speed"),
    "the world cannot be built": ({}, {"leader_speed": 0.6}, "World", "the physics refused"),
}


def _actions(env, rng):
    return {a: rng.uniform(-0.3, 0.3, 2) for a in env.agents}


def _assert_same(env, twin, where):
    a, b = env.snapshot(), twin.snapshot()
    for name in ("positions", "velocities", "commands"):
        if hasattr(a, name):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (where, name)
    assert a.time == b.time, where
    assert env.episode_config == twin.episode_config, where
    assert env.agents == twin.agents, where
    assert type(env.leader) is type(twin.leader), where
    assert np.array_equal(env.leader.reference_path(), twin.leader.reference_path()), where


@pytest.mark.parametrize("seed", [7, None])
@pytest.mark.parametrize("kind", list(REFUSALS))
def test_a_refused_reset_leaves_the_env_as_it_was(kind, seed, monkeypatch):
    fields, options, patch, error = REFUSALS[kind]
    env = parallel_env(max_cycles=40, robots=5, **fields)
    twin = parallel_env(max_cycles=40, robots=5, **fields)
    env.reset(seed=0)
    twin.reset(seed=0)
    acts = np.random.default_rng(1)
    for _ in range(5):
        step = _actions(env, acts)
        env.step(step)
        twin.step(step)
    with monkeypatch.context() as m:
        if patch is not None:
            m.setattr("boids_env.episode_state.World", _bad_world)
        with pytest.raises((ValueError, RuntimeError), match=error):
            env.reset(seed=seed, options=options)
    _assert_same(env, twin, f"{kind}: just after the refused reset")
    while env.agents:  # the episode in progress goes on as the twin's
        step = _actions(env, acts)
        out, ref = env.step(step), twin.step(step)
        for k, (x, y) in enumerate(zip(out, ref, strict=True)):
            assert x.keys() == y.keys(), (kind, k)
            for agent in x:
                assert np.array_equal(np.asarray(x[agent]), np.asarray(y[agent])), (
                    kind, env.snapshot().time, k, agent)
    _assert_same(env, twin, f"{kind}: at the episode's end")
    # the random stream was not drawn from: an unseeded reset continues it as the twin's
    first, second = env.reset(), twin.reset()
    for agent in first[0]:
        assert np.array_equal(first[0][agent], second[0][agent]), (kind, agent)
