"""Observation layout, neighbour search (all pairs and KD-tree) and bounds."""

import numpy as np
import pytest

from boids_env import observations as ob
from boids_env import parallel_env
from boids_env.observations import sensing


def brute_neighbours(pos, horizon, k):
    rows = []
    for i in range(1, len(pos)):
        d = np.linalg.norm(pos - pos[i], axis=1)
        cand = [j for j in range(len(pos)) if j != i and 0 < d[j] <= horizon]
        cand.sort(key=lambda j: (d[j], j))
        rows.append((cand[:k] + [-1] * k)[:k])
    return np.array(rows)


@pytest.mark.parametrize("n", [5, 40, 150])
def test_neighbours_match_brute_force(n):
    rng = np.random.default_rng(n)
    pos = rng.uniform(-2, 2, (n, 2))
    index, dist = ob.nearest_neighbours(pos, horizon=1.0, k=6)
    assert np.array_equal(index, brute_neighbours(pos, 1.0, 6))
    assert np.all(np.diff(dist, axis=1)[np.isfinite(dist[:, 1:])] >= 0), "nearest first"


def test_kdtree_skips_robots_on_top_of_each_other_like_all_pairs(monkeypatch):
    pos = np.random.default_rng(1).uniform(-1, 1, (30, 2))
    pos[5] = pos[3]  # two followers at the same point: neither is the other's neighbour
    pos[7] = pos[3]
    a = ob.nearest_neighbours(pos, 0.6, 25)  # more slots than neighbours in reach
    monkeypatch.setattr(sensing, "KD_TREE_MIN_ROBOTS", 2)
    b = ob.nearest_neighbours(pos, 0.6, 25)
    np.testing.assert_array_equal(a[0], brute_neighbours(pos, 0.6, 25))
    # the same neighbours at the same distances (robots 3, 5, 7 tie: the KD-tree may order
    # exact ties differently)
    np.testing.assert_allclose(a[1], b[1])
    assert [sorted(r) for r in a[0]] == [sorted(r) for r in b[0]]
    for i in (3, 5, 7):
        assert not {3, 5, 7} - {i} & set(b[0][i - 1]), f"robot {i} sees a robot on top of it"


def test_kdtree_and_all_pairs_agree(monkeypatch):
    pos = np.random.default_rng(0).uniform(-3, 3, (60, 2))
    a = ob.nearest_neighbours(pos, 1.0, 10)
    monkeypatch.setattr(sensing, "KD_TREE_MIN_ROBOTS", 2)
    b = ob.nearest_neighbours(pos, 1.0, 10)
    assert np.array_equal(a[0], b[0])
    assert np.allclose(a[1], b[1])


def test_observation_layout_contents():
    pos = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.9], [3.0, 3.0]])
    vel = np.array([[0.1, 0.2], [0.0, 0.3], [-0.1, 0.0], [0.2, 0.2]])
    layout = ob.ObservationLayout(3)
    obs = ob.build_observations(pos, vel, layout, horizon=1.0, velocity_bound=3.0, reach=10.0)
    assert obs.shape == (3, 6 + 15) and obs.dtype == np.float32
    f1 = obs[0]
    assert f1[layout.own_velocity].tolist() == pytest.approx([0.0, 0.3])
    assert f1[layout.leader_position].tolist() == pytest.approx([-0.5, 0.0])
    assert f1[layout.leader_velocity].tolist() == pytest.approx([0.1, 0.2])
    slots = layout.slots(obs)
    # follower 1: leader at 0.5 m, then robot 2 at 0.9 m; robot 3 out of range
    assert layout.slot_valid(slots[0]).tolist() == [1, 1, 0]
    assert layout.slot_position(slots[0])[0].tolist() == pytest.approx([-0.5, 0.0])
    assert layout.slot_position(slots[0])[1].tolist() == pytest.approx([0.0, 0.9])
    assert layout.slot_velocity(slots[0])[1].tolist() == pytest.approx([-0.1, 0.0])
    assert slots[0, 2].tolist() == [0, 0, 0, 0, 0]
    assert layout.slot_valid(slots[2]).tolist() == [0, 0, 0], "robot 3 is alone"


def test_observations_stay_in_space_along_random_rollouts():
    e = parallel_env(robots=19, neighbours=8)
    rng = np.random.default_rng(0)
    obs, _ = e.reset(seed=0)
    step = 0
    while e.agents and step < 400:
        for a, o in obs.items():
            assert e.observation_space(a).contains(o), f"step {step}, {a}: {o}"
        obs, *_ = e.step({a: rng.uniform(-1, 1, 2) for a in e.agents})
        step += 1
    assert e.state_space.contains(e.state())


def test_wall_slot_points_at_the_nearest_wall_within_the_horizon():
    from boids_env import EnvConfig

    config = EnvConfig.from_kwargs(robots=4, sense_walls=True)
    observer = ob.Observer(config)
    observer.reset(None)
    pos = np.array([[0.0, 0.0], [4.5, 1.0], [-1.0, -4.2], [0.5, 0.5]])
    obs = observer(pos, np.zeros((4, 2)))
    wall = obs[:, observer.layout.wall]
    np.testing.assert_allclose(wall, [[0.5, 0.0, 1.0], [0.0, -0.8, 1.0], [0.0, 0.0, 0.0]],
                               atol=1e-6)
    assert obs.shape[1] == observer.layout.size == 6 + 5 * 18 + 3
    assert ob.ObservationLayout.for_size(obs.shape[1]) == observer.layout
    assert obs[0] in parallel_env(robots=4, sense_walls=True).observation_space("follower_1")
    # the Reynolds policy reads such observations too (it ignores the wall slot)
    from boids_env.policies import ReynoldsPolicy
    from boids_env.policies.reynolds_params import Timing

    plain = EnvConfig.from_kwargs(robots=4)
    without = ob.Observer(plain)
    without.reset(None)
    policy, twin = (ReynoldsPolicy(timing=Timing(0.1, 0.0)) for _ in range(2))
    np.testing.assert_array_equal(policy.act_batch(obs), twin.act_batch(without(pos,
                                                                                np.zeros((4, 2)))))


def test_layout_for_size_refuses_impossible_sizes():
    with pytest.raises(ValueError, match="no study-era observation layout has size 8"):
        ob.ObservationLayout.for_size(8)


@pytest.mark.parametrize("fields", [
    {"robots": 4, "neighbours": 6, "scene": "lab", "static_slots": 2, "static_range": 20.0},
    {"robots": 5, "neighbours": 6, "robot": "turtlebot3_burger"},
    {"robots": 5, "leader": "person", "crowd": 2, "pedestrian_slots": 3},
])
def test_sensing_noise_spares_flags_and_empty_slots(fields):
    """obs_noise perturbs what is sensed and nothing else: every valid flag stays exactly 0
    or 1, and an empty slot (a flag of 0) stays all zeros, its heading too."""
    env = parallel_env(obs_noise=0.3, max_cycles=30, **fields)
    env.reset_arrays(seed=3)
    layout = env._observer.layout
    obs = np.concatenate([env.step_arrays(np.zeros((len(env.agents), 2))).observations
                          for _ in range(20)])
    groups = [(layout.slots(obs), 4, [0, 1, 2, 3])]  # (slots, flag column, sensed columns)
    if layout.static:
        groups.append((layout.static_slots(obs), 2, [0, 1]))
    if layout.pedestrians:
        groups.append((layout.pedestrian_slots(obs), 4, [0, 1, 2, 3]))
    for slots, flag, sensed in groups:
        valid = slots[..., flag]
        assert set(np.unique(valid)) <= {0.0, 1.0}
        empty = valid == 0.0
        assert (slots[..., sensed][empty] == 0.0).all()
        # the noise reached what is sensed: a real slot's values are not round numbers
        assert (~empty).any() and (slots[..., sensed][~empty] != 0.0).mean() > 0.9
    assert (layout.slots(obs)[..., 4] == 0.0).any()  # 6 slots, at most 4 robots to fill them
    if layout.headings:
        empty = layout.slots(obs)[..., 4] == 0.0
        assert (layout.neighbour_headings(obs)[empty] == 0.0).all()
    env.close()


# ------------------------------------------------------------------ the block table
def test_the_study_blocks_lead_the_table_at_their_fixed_indices():
    layout = ob.ObservationLayout(4, 2, 3, pedestrians=1, headings=True, route=True)
    assert [s.name for s in ob.specs()][:4] == ["own_velocity", "leader_position",
                                                "leader_velocity", "neighbours"]
    assert layout.block("own_velocity") == layout.own_velocity
    assert layout.block("leader_position") == layout.leader_position
    assert layout.block("leader_velocity") == layout.leader_velocity
    assert layout.block("neighbours").start == layout.neighbours_start
    assert [s.name for s in ob.specs()] == list(ob.BLOCKS)


def test_every_spec_bounds_and_masks_its_own_columns():
    ranges = ob.Ranges(10.0, 1.0, 3.0, 2.0, 4.0, 5.0)
    names = [s.name for s in ob.specs()]
    for spec in ob.specs():
        low, high = spec.bounds(ranges)
        assert len(low) == len(high) == spec.width, spec.name
        assert all(lo <= hi for lo, hi in zip(low, high, strict=True)), spec.name
        assert set(spec.masked) <= set(range(spec.width)) and spec.doc, spec.name
        assert spec.flag is None or 0 <= spec.flag < spec.width, spec.name
        owner = spec.masked_by or spec.name
        assert not spec.masked or ob.specs()[names.index(owner)].flag is not None, spec.name


def test_the_shipped_models_saved_layouts_read_back_block_for_block():
    from pathlib import Path

    from boids_env.policies.sb3_policy import read_meta

    zips = sorted((Path(__file__).resolve().parents[2] / "policies" / "models").glob("*.zip"))
    assert zips
    for path in zips:
        meta = read_meta(path)
        for saved in (meta.get("observation_layout"), (meta.get("card") or {}).get("observation")):
            if saved is not None:
                layout = ob.ObservationLayout.from_blocks(saved)
                assert [list(b) for b in layout.blocks] == [list(b) for b in saved], path.name


def test_a_layout_is_a_frozen_value_named_by_its_parameters():
    import pickle

    layout = ob.ObservationLayout(6, 1, pedestrians=2, route=True)
    assert layout == ob.ObservationLayout(neighbours=6, static=1, lidar=0, pedestrians=2,
                                          headings=False, route=True)
    assert hash(layout) == hash(pickle.loads(pickle.dumps(layout)))
    assert pickle.loads(pickle.dumps(layout)) == layout and layout != ob.ObservationLayout(6)
    assert layout.parameters == {"neighbours": 6, "static": 1, "lidar": 0, "pedestrians": 2,
                                 "headings": False, "route": True}
    assert repr(layout).startswith("ObservationLayout(neighbours=6, static=1, lidar=0,")
    with pytest.raises(AttributeError):
        layout.neighbours = 3
    with pytest.raises(TypeError, match="no parameter 'sonar'"):
        ob.ObservationLayout(6, sonar=2)
    with pytest.raises(ValueError, match="static must be a non-negative integer, got -1"):
        ob.ObservationLayout(6, -1)
    with pytest.raises(ValueError, match="route must be True or False, got 1"):
        ob.ObservationLayout(6, route=1)
    with pytest.raises(ValueError, match="not an observation layout"):
        ob.ObservationLayout.from_blocks([["own_velocity", 2], ["route", 4]])


def test_study_only_is_the_layout_without_a_block_of_its_own_fill():
    for fields in ({}, {"lidar": 2}, {"static": 1}, {"pedestrians": 1}, {"headings": True},
                   {"route": True}, {"neighbours": 0}):
        layout = ob.ObservationLayout(**{"neighbours": 5, **fields})
        assert layout.study_only == (not (layout.static or layout.lidar or layout.pedestrians
                                          or layout.headings or layout.route)), fields
