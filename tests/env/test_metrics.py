"""Violation metrics on hand-computed cases, and the reward/metric identity in the env."""

import numpy as np
import pytest

from boids_env import metrics, parallel_env
from boids_env.config import MetricsConfig


def flags(leader_pos, follower_pos, leader_cmd, follower_cmd, **kw):
    pos = np.array([leader_pos, *follower_pos], dtype=float)
    cmd = np.array([leader_cmd, *follower_cmd], dtype=float)
    return metrics.violation_flags(pos, cmd, **kw)


def test_separation_and_cohesion_thresholds_against_the_leader():
    f = flags([1, 1], [[1, 1.69], [1, 1.71], [1, 3.25], [1, 3.26]], [0, 0], [[0, 0]] * 4)
    assert f["separation"].tolist() == [True, False, False, False]
    assert f["cohesion"].tolist() == [False, False, False, True]


def test_alignment_uses_commanded_directions():
    # leader heading 0°; followers at 45° (not > 45), 46°, 90°, zero command (0°)
    c = [[1, 1], [np.cos(np.radians(46)), np.sin(np.radians(46))], [0, 1], [0, 0]]
    f = flags([0, 0], [[1, 0]] * 4, [0.5, 0], c)
    assert f["alignment"].tolist() == [False, True, True, False]


def test_wrapped_and_unwrapped_alignment_differ_at_179_vs_minus_179():
    lead = [np.cos(np.radians(179)), np.sin(np.radians(179))]
    foll = [np.cos(np.radians(-179)), np.sin(np.radians(-179))]
    wrapped = flags([0, 0], [[1, 0]], lead, [foll])["alignment"]
    unwrapped = flags([0, 0], [[1, 0]], lead, [foll], wrap_alignment=False)["alignment"]
    assert wrapped.tolist() == [False]  # 2° apart
    assert unwrapped.tolist() == [True]  # |179 − (−179)| = 358° > 45°
    assert metrics.angle_difference_deg(np.array(179.0), np.array(-179.0)) == pytest.approx(2)


def test_episode_violations_sum_over_followers():
    # 4 samples, 2 followers: follower 1 violates separation twice, follower 2 once.
    sep = np.array([[1, 0], [1, 1], [0, 0], [0, 0]], dtype=bool)
    zero = np.zeros_like(sep)
    v = metrics.episode_violations({"separation": sep, "cohesion": zero, "alignment": zero})
    assert v == {"V_sep": 0.75, "V_coh": 0.0, "V_align": 0.0}  # (2 + 1) · 0.1 s / 0.4 s
    counts = metrics.violation_counts({"separation": sep, "cohesion": zero, "alignment": zero})
    assert counts["count_sep"].tolist() == [2, 1]


def test_extra_metrics_on_hand_made_trajectory():
    pos = np.array([[[0, 0], [1, 0], [3, 0]], [[0, 0], [0.07, 0], [3, 0]],
                    [[0, 0], [0.5, 0], [3, 0]], [[0, 0], [0.07, 0], [3, 0]]], dtype=float)
    nearest = [metrics.safety_metrics(p[None], 0.036)["min_distance"] for p in pos]
    assert nearest == pytest.approx([1, 0.07, 0.5, 0.07])
    safety = metrics.safety_metrics(pos, radius=0.036)
    assert safety["contacts_follower"] + safety["contacts_leader"] == 2  # two separate touches
    vel = np.array([[1, 0], [1, 0], [0, 1]], dtype=float)
    assert metrics.polarization(vel) == pytest.approx(np.hypot(2, 1) / 3)
    assert metrics.polarization(np.zeros((3, 2))) == 0.0
    assert metrics.leader_distance(pos[0]).tolist() == [1, 3]


def test_summed_episode_reward_equals_minus_total_violation_times_T():
    e = parallel_env(robots=7, leader_speed=0.6)
    rng = np.random.default_rng(1)
    e.reset(seed=1)
    total = 0.0
    terms = {"reward_separation": 0.0, "reward_cohesion": 0.0, "reward_alignment": 0.0}
    while e.agents:
        _, rew, _, _, info = e.step({a: rng.uniform(-0.5, 0.5, 2) for a in e.agents})
        total += sum(rew.values())
        for a in info:
            for k in terms:
                terms[k] += info[a][k]
    m = e.episode_metrics()
    T = m["duration"]
    assert m["V_sep"] + m["V_coh"] + m["V_align"] > 0
    assert total == pytest.approx(-(m["V_sep"] + m["V_coh"] + m["V_align"]) * T, rel=1e-12)
    assert terms["reward_separation"] == pytest.approx(-m["V_sep"] * T)
    assert terms["reward_alignment"] == pytest.approx(-m["V_align"] * T)


def test_reward_weights_scale_terms():
    f = {"separation": np.array([True]), "cohesion": np.array([True]),
         "alignment": np.array([False])}
    cfg = MetricsConfig(reward_separation=2.0, reward_cohesion=0.5)
    # the env's terms: the (3, 1) scale times the flags stacked in VIOLATIONS order
    t = metrics.reward_scale(cfg, 0.1) * np.stack([f[n] for n in metrics.VIOLATIONS])
    assert t[0].tolist() == [pytest.approx(-0.2)]
    assert t[1].tolist() == [pytest.approx(-0.05)]
    assert t[2].tolist() == [0.0]


def test_safety_metrics_on_a_hand_made_trajectory():
    r = 0.036
    touch = 2 * r  # centre distance of two touching robots
    # 4 samples, leader + 2 followers. Sample 1: followers touch; sample 2: leader touches
    # follower 1 and follower 2 sits on the wall at x = 5 - r; sample 3: nobody touches.
    pos = np.array([
        [[0, 0], [1, 0], [2, 0]],
        [[0, 0], [1, 0], [1 + touch, 0]],
        [[0, 0], [touch, 0], [5 - r, 0]],
        [[0, 0], [1, 0], [3, 0]],
    ], dtype=float)
    wall = np.abs(pos).max(axis=2) >= 5 - r - metrics.CONTACT_TOLERANCE  # (T, N), by hand
    clearance = 5 - np.abs(pos).max(axis=2)
    sight = np.array([[True, True], [True, False], [True, True], [False, False]])
    s = metrics.safety_metrics(pos, r, wall, leader_path=np.array([[0.0, -1], [0, 1]]),
                               clearance=clearance, sight=sight)
    assert s["touching_fraction"] == 0.5
    assert s["mean_contact_pairs"] == 0.5
    assert s["contacts_follower"] == 1 and s["contacts_leader"] == 1
    assert s["wall_fraction"] == 0.25
    assert s["min_clearance"] == pytest.approx(0.0), "follower 2 touches the wall at 5 - r"
    assert s["no_sight_fraction"] == 3 / 8
    nn = [np.mean([1, 1, 1]), np.mean([1, touch, touch]), np.mean([touch, touch, 5 - r - touch]),
          np.mean([1, 1, 2])]
    assert s["mean_nn_distance"] == pytest.approx(np.mean(nn))
    assert s["min_distance"] == pytest.approx(touch)
    assert s["leader_path_deviation"] == 0.0 and s["leader_path_deviation_max"] == 0.0
    bare = metrics.safety_metrics(pos, r)
    assert np.isnan(bare["leader_path_deviation"]) and np.isnan(bare["wall_fraction"])


def test_safety_metrics_of_large_groups_match_brute_force():
    rng = np.random.default_rng(3)
    pos = np.cumsum(rng.normal(0, 0.02, (60, 70, 2)), axis=0) + rng.uniform(-1, 1, (1, 70, 2))
    big = metrics.safety_metrics(pos, 0.036)  # 70 robots: the KD-tree path
    # compared with the definitions computed by brute force
    small = {}
    diff = pos[:, :, None] - pos[:, None]
    dist = np.linalg.norm(diff, axis=-1) + np.where(np.eye(70, dtype=bool), np.inf, 0)
    touching = np.triu(dist < 2 * 0.036 + metrics.CONTACT_TOLERANCE, 1)
    small["touching_fraction"] = touching.any(axis=(1, 2)).mean()
    small["mean_contact_pairs"] = touching.sum(axis=(1, 2)).mean()
    onset = touching & ~np.concatenate([np.zeros_like(touching[:1]), touching[:-1]])
    small["contacts_leader"] = onset[:, 0].sum()
    small["contacts_follower"] = onset[:, 1:].sum()
    small["mean_nn_distance"] = dist.min(axis=2).mean()
    for key, value in small.items():
        assert big[key] == pytest.approx(value), key
    assert big["touching_fraction"] > 0 and big["contacts_follower"] > 0


def test_path_deviation_to_a_polyline():
    path = np.array([[0.0, 0], [4, 0], [4, 4]])
    pts = np.array([[2.0, 1], [5, 2], [4, 5], [-1, 0]])
    assert metrics.path_deviation(pts, path).tolist() == pytest.approx([1, 1, 1, 1])


def test_safe_reward_terms_follow_the_flags():
    e = parallel_env(robots=3, reward="safe", init_jitter=0.0, layout_spacing=0.2,
                     startup_time=100)
    e.reset(seed=0)
    # push follower 2 onto follower 1 (cells (-0.2,-0.2) and (0.2,-0.2)): they get closer than
    # the 0.3 m safety distance and finally touch
    seen = set()
    for _ in range(20):
        _, rew, _, _, info = e.step({"follower_1": np.array([0.0, 0.0]),
                                     "follower_2": np.array([-0.5, 0.0])})
        i = info["follower_2"]
        for key in ("reward_proximity", "reward_contact", "reward_wall"):
            if i[key]:
                seen.add(key)
        assert rew["follower_2"] == pytest.approx(sum(i.values()))
    assert seen == {"reward_proximity", "reward_contact"}
    from boids_env.config import SAFE_WEIGHTS

    assert i["reward_contact"] == pytest.approx(-SAFE_WEIGHTS["reward_contact"] * 0.1)
    study = parallel_env(robots=3, init_jitter=0.0, layout_spacing=0.2, startup_time=100)
    study.reset(seed=0)
    for _ in range(20):
        _, _, _, _, info = study.step({"follower_1": np.array([0.0, 0.0]),
                                       "follower_2": np.array([-0.5, 0.0])})
        assert info["follower_2"]["reward_contact"] == 0.0


def test_the_cohesion_gap_is_the_leader_distance_beyond_the_threshold():
    """The gap the ``reward_gap`` term pays for, (leader distance − 2.25 m)₊, as the env
    computes it from :func:`metrics.leader_distance`."""
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, -2.25], [3.0, 4.0]])
    gap = np.maximum(metrics.leader_distance(pos) - 2.25, 0.0)
    assert gap.tolist() == pytest.approx([0.0, 0.0, 2.75])
    batch = np.stack([pos, pos + np.array([1.0, 0.0])])  # (T, N, 2): a shift changes nothing
    np.testing.assert_allclose(np.maximum(metrics.leader_distance(batch) - 2.25, 0.0),
                               [[0, 0, 2.75]] * 2)


def test_gap_reward_pays_per_metre_beyond_the_cohesion_threshold():
    """The opt-in reward_gap term: −w · (d − 2.25 m)₊ · dt for each follower, in the infos and
    the reward; zero for followers within the threshold and when the weight is 0."""
    fields = dict(robots=3, init_jitter=0.0, startup_time=100)
    env = parallel_env(reward_gap=4.0, **fields)
    _, infos = env.reset(seed=0)
    assert all(i["reward_gap"] == 0.0 for i in infos.values())
    still = {a: np.zeros(2) for a in env.agents}
    _, rew, _, _, info = env.step(still)
    pos = env.snapshot().positions
    d = np.linalg.norm(pos[1:] - pos[0], axis=1)
    assert (d < 2.25).all(), d  # the study's grid: every follower within the threshold
    assert all(i["reward_gap"] == 0.0 for i in info.values()), info
    far = parallel_env(reward_gap=4.0, **fields)
    far.reset(seed=0)
    for _ in range(60):  # follower_2 drives away from the waiting leader for 6 s
        _, rew, _, _, info = far.step({"follower_1": np.zeros(2),
                                       "follower_2": np.array([0.5, -0.5])})
    pos = far.snapshot().positions
    excess = np.linalg.norm(pos[2] - pos[0]) - 2.25
    assert excess > 0.5, excess
    i = info["follower_2"]
    assert i["reward_gap"] == pytest.approx(-4.0 * excess * 0.1), (i, excess)
    assert i["reward_cohesion"] == pytest.approx(-0.1)
    assert rew["follower_2"] == pytest.approx(sum(i.values()))
    assert info["follower_1"]["reward_gap"] == 0.0
    off = parallel_env(**fields)  # the default weight 0: the term is zero even far away
    off.reset(seed=0)
    for _ in range(60):
        _, _, _, _, info = off.step({"follower_1": np.zeros(2),
                                     "follower_2": np.array([0.5, -0.5])})
    assert info["follower_2"]["reward_gap"] == 0.0
    assert info["follower_2"]["reward_cohesion"] == pytest.approx(-0.1)


def test_parked_reward_pays_for_speed_once_the_leader_has_stood_still():
    """reward_parked=3, parked_after=2 s: −3 · speed · dt per follower from the 21st step of a
    leader standing still (here its 2 s start-up plus a 10 s pause at once), zero before, and
    zero with the default weight."""
    fields = dict(robots=3, init_jitter=0.0, leader_pauses=((0.0, 10.0),))
    env = parallel_env(reward_parked=3.0, parked_after=2.0, **fields)
    _, infos = env.reset(seed=0)
    assert all(i["reward_parked"] == 0.0 for i in infos.values())
    command = {"follower_1": np.array([0.2, 0.0]), "follower_2": np.zeros(2)}
    for step in range(1, 26):
        _, rew, _, _, info = env.step(command)
        speed = np.linalg.norm(env.snapshot().velocities[1:], axis=1)
        expected = -3.0 * speed * 0.1 if step > 20 else np.zeros(2)
        got = [info["follower_1"]["reward_parked"], info["follower_2"]["reward_parked"]]
        np.testing.assert_allclose(got, expected, rtol=1e-12, err_msg=f"step {step}")
        assert rew["follower_1"] == pytest.approx(sum(info["follower_1"].values()))
    assert speed[0] == pytest.approx(0.2, abs=1e-6) and got[0] < 0
    off = parallel_env(**fields)
    off.reset(seed=0)
    for _ in range(25):
        _, _, _, _, info = off.step(command)
    assert info["follower_1"]["reward_parked"] == 0.0


def test_still_time_and_parked_metrics_on_hand_computed_samples():
    from boids_env.metrics import parked_metrics, still_time

    cmd = np.array([[0, 0], [0, 0], [1, 0], [0, 0], [0, 0], [0.005, 0]], dtype=float)
    np.testing.assert_allclose(still_time(cmd, 0.5), [0.5, 1.0, 0.0, 0.5, 1.0, 1.5])
    # 8 samples, dt = 1 s, the leader still throughout: samples 6-8 (stood > 5 s) count
    t = 8
    commanded = np.zeros((t, 3, 2))
    positions = np.zeros((t, 3, 2))
    positions[:, 1] = [1.0, 0.0]
    positions[:, 2] = [0.0, 2.0]
    positions[6, 2] = [0.0, 2.5]
    velocities = np.zeros((t, 3, 2))
    velocities[5:, 1] = [[0.3, 0.4], [0.0, 0.0], [0.0, 0.0]]  # speeds 0.5, 0, 0
    velocities[5:, 2] = [[0.0, 0.1], [0.1, 0.0], [0.0, 0.0]]  # speeds 0.1, 0.1, 0
    velocities[0, 1] = [9.0, 9.0]  # before 5 s of standstill: not counted
    out = parked_metrics(positions, velocities, commanded, 1.0)
    assert out == pytest.approx({"parked_speed": 0.7 / 6, "parked_distance_max": 2.5,
                                 "parked_time": 3.0})
    commanded[4, 0] = [0.2, 0.0]  # the leader moved at sample 5: 3 still samples after it
    assert parked_metrics(positions, velocities, commanded, 1.0) == {}


def test_lost_followers_counts_those_beyond_3_m_at_the_end():
    # leader at the origin; followers at 1, 2.9, 3.1 and 4 m at the last sample (2.9 m before)
    last = np.array([[0, 0], [1, 0], [0, 2.9], [-3.1, 0], [0, -4]], dtype=float)
    positions = np.stack([last * 0.5, last])
    still = np.zeros_like(positions)
    out = metrics.episode_metrics(positions, still, still, MetricsConfig(), 0.1, 0.036)
    assert out["lost_followers"] == 2, out["lost_followers"]
