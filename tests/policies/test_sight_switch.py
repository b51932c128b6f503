"""``learned-buildings`` and any ``SEEN+HIDDEN`` pair: one model for the followers that see the
leader, another for those that do not (policies/sight_switch.py)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from boids_env import BoidsEnv
from boids_env.eval.episode import bind_policy, env_fields_for
from boids_env.eval.runner import PolicySpec
from boids_env.policies.registry import (
    BUILDINGS_MODEL,
    MODELS,
    SCENES_MODEL,
    load_policy,
    model_path,
    switch_parts,
)
from boids_env.policies.sb3_policy import load_model_policy
from boids_env.policies.sight_switch import SightSwitch


def _env(policy, **fields):
    env = BoidsEnv(**env_fields_for(policy, fields))
    bind_policy(policy, env)
    return env


def test_the_env_marks_the_followers_that_do_not_see_the_leader():
    # doorway: a wall at x = 0 with a 1 m door at y = 0; the leader east of it
    env = BoidsEnv(scene="doorway", robots=3, route_sensing=True, route_leader=True)
    env.reset(seed=0)
    assert env.leader_hidden is not None and env.leader_hidden.shape == (2,)
    positions = np.array([[1.0, -2.0], [-1.0, -2.0], [2.0, -1.0]])
    env._observer(positions, np.zeros_like(positions))
    assert env.leader_hidden.tolist() == [True, False]
    plain = BoidsEnv(scene="doorway", robots=3, route_sensing=True)
    plain.reset(seed=0)
    assert plain.leader_hidden is None


def test_learned_buildings_is_learned_scenes_in_sight_and_the_route_model_out_of_sight():
    policy = load_policy("learned-buildings")
    assert isinstance(policy, SightSwitch)
    assert switch_parts("learned-buildings") == (SCENES_MODEL, BUILDINGS_MODEL)
    scenes, route = load_model_policy(SCENES_MODEL), load_model_policy(BUILDINGS_MODEL)
    env = _env(policy, scene="floorplan:1016", robots=13, leader_speed=0.55)
    obs = env.reset_arrays(seed=3)
    policy.reset(3)
    mixed = 0
    for _ in range(400):
        hidden = env.leader_hidden.copy()
        actions = policy.act_batch(obs)
        seen_actions = scenes.act_batch(np.ascontiguousarray(obs[:, :-4]))
        route_actions = route.act_batch(obs)
        np.testing.assert_array_equal(actions[~hidden], seen_actions[~hidden])
        np.testing.assert_array_equal(actions[hidden], route_actions[hidden])
        mixed += bool(hidden.any() and not hidden.all())
        obs = env.step_arrays(actions).observations
    assert mixed > 20  # both models acted side by side in this plan's rooms


def test_on_open_floor_learned_buildings_acts_as_learned_scenes_bit_for_bit():
    runs = {}
    for name in ("learned-buildings", "learned-scenes"):
        policy = load_policy(name)
        env = _env(policy, max_cycles=200)
        obs, _ = env.reset(seed=1)
        policy.reset(1)
        while env.agents:
            obs, *_ = env.step(policy.act(obs))
        runs[name] = (env.snapshot().positions, env.episode_metrics())
    np.testing.assert_array_equal(runs["learned-buildings"][0], runs["learned-scenes"][0])
    assert runs["learned-buildings"][1] == runs["learned-scenes"][1]


def test_any_two_models_pair_by_name_or_zip():
    pair = f"learned-scenes+{BUILDINGS_MODEL}"
    assert switch_parts(pair) == (SCENES_MODEL, BUILDINGS_MODEL)
    assert model_path(pair) == BUILDINGS_MODEL == model_path("learned-buildings")
    assert model_path("learned-scenes") == SCENES_MODEL
    assert switch_parts("learned-scenes") is None
    assert switch_parts("reynolds+random") is None  # not models: no pair
    assert isinstance(load_policy(pair), SightSwitch)
    assert PolicySpec.parse(pair).label == "ppo_scenes+ppo_buildings"
    assert PolicySpec.parse("learned-buildings").label == "learned-buildings"


def test_the_fingerprint_of_a_pair_covers_both_models(tmp_path):
    import shutil

    seen = tmp_path / "seen.zip"
    shutil.copy(SCENES_MODEL, seen)
    before = PolicySpec.parse(f"{seen}+{BUILDINGS_MODEL}").fingerprint
    shutil.copy(MODELS["learned"], seen)  # another in-sight model, the same path
    after = PolicySpec.parse(f"{seen}+{BUILDINGS_MODEL}").fingerprint
    assert before != after


def _fake(fields, size):
    return SimpleNamespace(env_fields=fields, obs_size=size, reset=lambda seed=None: None)


def test_a_pair_that_cannot_switch_is_refused_with_the_reason():
    scenes, route = load_model_policy(SCENES_MODEL), load_model_policy(BUILDINGS_MODEL)
    with pytest.raises(ValueError, match="out-of-sight model must be trained with route"):
        SightSwitch(scenes, scenes)
    with pytest.raises(ValueError, match="in-sight model must be a learned model trained "
                                         "without route sensing"):
        SightSwitch(route, route)
    other = _fake({**scenes.env_fields, "frame": "world"}, scenes.obs_size)
    with pytest.raises(ValueError, match="different envs: frame='world' against 'leader'"):
        SightSwitch(other, route)
    with pytest.raises(ValueError, match=r"different envs: safety_filter='\(unset\)' "
                                         r"against True"):
        load_policy(f"learned+{BUILDINGS_MODEL}")  # trained without the safety filter
    with pytest.raises(ValueError, match=r"without its 4 route inputs \(sizes 10 and"):
        SightSwitch(_fake(dict(scenes.env_fields), 10), route)
    with pytest.raises(ValueError, match="out-of-sight model must be trained with "
                                         "route_sensing and route_leader"):
        load_policy(f"learned-buildings+{SCENES_MODEL}")  # the pair the wrong way round


def test_the_switch_needs_an_env_with_route_sensing_and_its_rows():
    policy = load_policy("learned-buildings")
    obs = np.zeros((12, policy.obs_size), dtype=np.float32)
    with pytest.raises(RuntimeError, match="bind it to the env first"):
        policy.act_batch(obs)
    with pytest.raises(ValueError, match="route_sensing"):
        bind_policy(policy, BoidsEnv(robots=13))
    env = _env(policy, robots=13)
    with pytest.raises(ValueError, match="12 observation rows, but the bound env's last "
                                         "observation marked none"):
        policy.act_batch(obs)  # not reset yet
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"3 observation rows, .* marked 12"):
        policy.act_batch(obs[:3])


def _seen_as(flags):
    """An observer whose last call marked these followers as not seeing the leader."""
    return SimpleNamespace(leader_hidden=np.array(flags))


def test_a_stale_observation_keeps_the_sight_it_was_seen_with():
    # ROS realism repeats a follower's previous observation now and then: the switch must
    # then read that observation's sight flag too, not the current one
    from boids_env.world.realism import StaleObservations

    stale = StaleObservations(1.0, seed=0)  # every row stale after the first call
    first = np.zeros((3, 2), dtype=np.float32)
    stale(first, _seen_as([True, False, True]))
    out = stale(first + 1, _seen_as([False, True, False]))
    np.testing.assert_array_equal(out, first)
    assert stale.hidden.tolist() == [True, False, True]
    fresh = StaleObservations(0.0, seed=0)
    fresh(first, _seen_as([True, False, True]))
    fresh(first + 1, _seen_as([False, True, False]))
    assert fresh.hidden.tolist() == [False, True, False]


def test_the_env_under_ros_realism_marks_the_sight_of_the_rows_it_delivers():
    env = BoidsEnv(scene="floorplan:1002", robots=13, route_sensing=True, route_leader=True,
                   realism="ros", startup_time=0.0)
    env.reset_arrays(seed=0)
    rng = np.random.default_rng(0)
    differed = 0
    for _ in range(300):
        env.step_arrays(rng.uniform(-0.5, 0.5, (12, 2)))
        delivered = env.leader_hidden
        assert env.episode.realism.stale.hidden is delivered
        differed += int((delivered != ~leader_in_sight_now(env)).any())
    assert differed > 0  # some rows went stale with another sight than the current one


def leader_in_sight_now(env):
    from boids_env.world.route import leader_in_sight, route_grid

    cfg = env.episode_config
    grid = route_grid(cfg.scene, cfg.world.robot_radius, cfg.observation.route_cell)
    return leader_in_sight(grid, env._world.positions)


def test_boids_eval_runs_a_pair_named_by_its_two_models(tmp_path):
    import pandas as pd

    from boids_env.train.cli import main

    suite = tmp_path / "one.toml"
    suite.write_text('name = "one"\nseeds = 1\n[[case]]\nname = "door"\ngroup = "g"\n'
                     'scene = "doorway"\nrobots = 4\nmax_cycles = 40\n')
    pair = f"learned-scenes+{BUILDINGS_MODEL}"
    out = tmp_path / "out"
    assert main(["eval", "--suite", str(suite), "--policy", pair, "--policy",
                 "learned-buildings", "--workers", "1", "--no-progress", "--out",
                 str(out)]) == 0
    rows = pd.read_parquet(out / "results.parquet").set_index("policy")
    assert sorted(rows.index) == ["learned-buildings", "ppo_scenes+ppo_buildings"]
    # the same two models: the same episode
    assert rows.loc["learned-buildings", "V_sep"] == rows.loc["ppo_scenes+ppo_buildings",
                                                            "V_sep"]
    assert rows.loc["learned-buildings", "steps"] == 40
