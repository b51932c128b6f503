"""The Reynolds policy from observations equals a full-state reference, and it flocks."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.eval.episode import run_episode
from boids_env.observations import ObservationLayout, build_observations
from boids_env.policies import ReynoldsPolicy
from boids_env.policies.reynolds import reynolds_command, reynolds_forces
from boids_env.policies.reynolds_params import Timing, reynolds_params


def clip(x, limit):
    n = np.linalg.norm(x)
    return x * limit / n if n > limit else x


def reference(pos, vel, p, dt=0.1):
    """The study's controller written straight from full state, one follower at a time."""
    out = []
    for i in range(1, len(pos)):
        nbrs = [j for j in range(len(pos))
                if j != i and 0 < np.linalg.norm(pos[j] - pos[i]) <= p.horizon]
        coh = sep = ali = np.zeros(2)
        if nbrs:
            coh = (p.max_force / p.horizon) * np.mean([pos[j] - pos[i] for j in nbrs], axis=0)
            close = [j for j in nbrs if np.linalg.norm(pos[j] - pos[i]) < p.desired_separation]
            if close:
                s = np.mean([-(pos[j] - pos[i]) / np.linalg.norm(pos[j] - pos[i]) ** 3
                             for j in close], axis=0)
                sep = clip(s, 2 * p.max_force)
            u = np.sum([vel[j] for j in nbrs], axis=0)
            u = np.array([1.0, 0.0]) if np.linalg.norm(u) == 0 else u / np.linalg.norm(u)
            ali = clip(u * p.max_speed - vel[i], p.max_force)
        lead = pos[0] - pos[i]
        f = clip(p.cohesion_weight * coh + p.separation_weight * sep + p.alignment_weight * ali
                 + p.leader_weight * lead, p.max_force)
        out.append(clip(vel[i] + f / p.mass * dt, p.max_speed))
    return np.array(out)


@pytest.mark.parametrize("preset", ["paper", "boids_ros"])
@pytest.mark.parametrize("robots, leader_weight", [(7, 1.0), (13, 1.1), (19, 1.2)])
def test_from_observations_equals_full_state_reference(preset, robots, leader_weight):
    rng = np.random.default_rng(robots)
    p = reynolds_params(preset, leader_weight=leader_weight)
    layout = ObservationLayout(18)
    for trial in range(20):
        # Dyadic values are exact in float32, so the observation loses nothing.
        pos = np.round(rng.uniform(-1.2, 1.2, (robots, 2)) * 1024) / 1024
        vel = np.round(rng.uniform(-0.5, 0.5, (robots, 2)) * 1024) / 1024
        obs = build_observations(pos, vel, layout, 1.0, 3.0, 10.0)
        policy = ReynoldsPolicy(preset, leader_weight=leader_weight, timing=Timing(0.1, 0.0))
        got = policy.act_batch(obs).astype(np.float64)
        want = reference(pos, vel, p)
        assert np.abs(got - want.astype(np.float32)).max() <= 1e-9, f"trial {trial}"
        # and in float64, before the cast to the action's float32
        slots = layout.slots(obs.astype(np.float64))
        own = obs[:, layout.own_velocity].astype(np.float64)
        forces = reynolds_forces(layout.slot_position(slots), layout.slot_velocity(slots),
                                 layout.slot_valid(slots) > 0.5, own,
                                 obs[:, layout.leader_position].astype(np.float64), p)
        command, _ = reynolds_command(forces, own, p)
        assert np.abs(command - want).max() <= 1e-9, f"trial {trial}"


def test_holds_still_during_startup_then_moves():
    e = parallel_env(robots=7)
    pol = ReynoldsPolicy()
    obs, _ = e.reset(seed=0)
    pol.reset(0)
    for step in range(25):
        act = pol.act(obs)
        still = all(np.all(v == 0) for v in act.values())
        assert still == (step < 20), f"step {step}"
        obs, *_ = e.step(act)


def test_paper_flock_follows_the_leader_round_the_square():
    e = parallel_env()
    result = run_episode(e, ReynoldsPolicy(), seed=0)
    rec = result.recording
    dist = np.linalg.norm(rec.positions[1:, 1:] - rec.positions[1:, :1], axis=-1)
    mean_dist = dist.mean(axis=1)
    # measured (seed 0): mean distance under 2.25 m in 100% of samples, max final 1.6 m
    assert (mean_dist < 2.25).mean() > 0.9, (mean_dist < 2.25).mean()
    assert dist[-1].max() < 2.25, f"left behind at the end: {dist[-1].max():.2f} m"
    assert result.metrics["collisions"] <= 5, result.metrics["collisions"]
    assert result.metrics["min_distance"] > 2 * 0.036


@pytest.mark.slow
def test_leader_speed_trade_off_of_the_study():
    def v(speed):
        out = []
        for seed in range(5):
            m = run_episode(parallel_env(leader_speed=speed), ReynoldsPolicy(), seed=seed,
                            record=False).metrics
            out.append((m["V_sep"], m["V_coh"]))
        return np.mean(out, axis=0)

    slow, fast = v(0.5), v(0.6)
    assert slow[0] > fast[0], f"V_sep 0.5 m/s {slow[0]} vs 0.6 m/s {fast[0]}"
    assert fast[1] > slow[1], f"V_coh 0.6 m/s {fast[1]} vs 0.5 m/s {slow[1]}"


@pytest.mark.parametrize(("dt", "startup_time"), [(0.05, 2.0), (0.1, 3.0), (0.05, 0.5)])
def test_a_bound_policy_takes_dt_and_the_start_up_hold_from_the_env(dt, startup_time):
    # issue 39 item 7: bound to an env with dt=0.05 it integrated with 0.1 s; with
    # startup_time=3 it held its followers 2 s
    env = parallel_env(robots=7, dt=dt, startup_time=startup_time)
    policy = ReynoldsPolicy()
    obs, _ = env.reset(seed=0)
    from boids_env.eval.episode import bind_policy

    bind_policy(policy, env)  # as run_episode, the eval runner and the ROS controller do
    policy.reset(0)
    held = round(startup_time / dt)  # whole control periods of the hold
    for step in range(held + 3):
        snap = env.snapshot()
        act = policy.act(obs)
        got = np.array([act[a] for a in env.agents], dtype=np.float64)
        if step < held:
            assert not got.any(), f"step {step}: held until {startup_time} s"
        else:
            p = reynolds_params("paper")  # the study's controller at the env's period
            want = reference(snap.positions, snap.velocities, p, dt)
            assert np.abs(got - want).max() < 1e-5, (step, got.tolist(), want.tolist())
            assert got.any(), f"step {step}: moving after the hold"
        obs, *_ = env.step(act)


@pytest.mark.parametrize("given", [{"dt": 0.05}, {"startup_time": 0.0}])
def test_the_timing_is_the_envs_and_refused_as_a_controller_parameter(given):
    (name,) = given
    with pytest.raises(TypeError, match=rf"{name}: the env's timing, not a Reynolds parameter"):
        ReynoldsPolicy(**given)
    with pytest.raises(TypeError, match=rf"give {name} to the env"):
        reynolds_params("paper", **given)


@pytest.mark.parametrize(("given", "env_fields", "match"), [
    ({"max_speed": 0.4}, {"max_speed": 0.3}, r"max_speed=0.4 m/s .* the env's max_speed=0.3"),
    ({"horizon": 1.5}, {}, r"horizon=1.5 m .* the env's horizon=1 m"),
])
def test_a_policy_whose_timing_conflicts_with_the_env_is_refused(given, env_fields, match):
    policy = ReynoldsPolicy(**given)
    with pytest.raises(ValueError, match=match):
        policy.bind(parallel_env(robots=4, **env_fields))


def test_own_values_within_the_env_are_kept_and_the_rest_taken_from_it():
    env = parallel_env(robots=4, max_speed=0.4, horizon=1.5, dt=0.05, startup_time=1.0)
    policy = ReynoldsPolicy("boids_ros", max_speed=0.3)  # its own horizon 0.75, speed 0.3
    policy.bind(env)
    p = policy.params
    assert (*policy.timing, p.max_speed, p.horizon) == (0.05, 1.0, 0.3, 0.75)
    paper = ReynoldsPolicy()
    paper.bind(env)
    p = paper.params
    assert (*paper.timing, p.max_speed, p.horizon) == (0.05, 1.0, 0.4, 1.5)
