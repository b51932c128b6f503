"""The pymunk world: velocity tracking, contacts, walls, finiteness."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.config import WorldConfig
from boids_env.world.space import World


def test_robot_reaches_commanded_speed_within_0_2_s_and_holds_it():
    w = World(WorldConfig(), [[0.0, 0.0]])
    speeds = []
    for _ in range(30):
        w.step(np.array([[0.3, 0.4]]))  # 0.5 m/s, diagonal
        speeds.append(np.linalg.norm(w.velocities[0]))
    assert abs(speeds[1] - 0.5) < 1e-6, f"speed at 0.2 s: {speeds[1]}"
    assert np.allclose(speeds[1:], 0.5, atol=1e-6), f"speeds: {speeds}"
    assert np.allclose(w.velocities[0], [0.3, 0.4], atol=1e-6)


def test_pushed_together_robots_do_not_overlap_more_than_5_mm():
    cfg = WorldConfig()
    start = np.array([[x, y] for x in np.linspace(-0.5, 0.5, 4) for y in np.linspace(-0.5, 0.5, 4)])
    w = World(cfg, start)
    worst = 0.0
    for _ in range(100):
        w.step(np.clip(-w.positions, -0.5, 0.5))  # everybody drives at the centre
        d = np.linalg.norm(w.positions[:, None] - w.positions[None], axis=-1)
        d[np.diag_indices(len(d))] = np.inf
        worst = max(worst, 2 * cfg.robot_radius - d.min())
    assert worst <= 0.005, f"overlap {worst * 1000:.2f} mm"
    assert len(w.snapshot().contacts) > 0, "the crowd should be touching"


def test_long_random_full_speed_run_stays_in_arena_and_finite():
    e = parallel_env(robots=19, path="external", max_cycles=3000)
    rng = np.random.default_rng(0)
    e.reset(seed=0)
    half = e.config.world.arena_half_size
    radius = e.config.world.robot_radius
    step = 0
    while e.agents:
        # Mostly pushing outwards at full speed, to press robots into the walls.
        actions = {a: rng.normal(size=2) for a in e.agents}
        e.step(actions)
        snap = e.snapshot()
        assert np.isfinite(snap.positions).all() and np.isfinite(snap.velocities).all(), step
        assert np.abs(snap.positions).max() <= half - radius + 0.003, (
            f"step {step}: robot at {np.abs(snap.positions).max()}")
        assert np.isfinite(e.state()).all()
        step += 1
    assert step == 3000


def test_walls_stop_a_robot():
    w = World(WorldConfig(), [[4.5, 0.0]])
    for _ in range(40):
        w.step(np.array([[0.5, 0.0]]))
    assert 4.9 < w.positions[0, 0] <= 5.0 - 0.036 + 0.002
    assert list(w.snapshot().wall_contacts) == [0]


def test_snapshot_shapes_leader_first():
    e = parallel_env(robots=7)
    e.reset(seed=0)
    s = e.snapshot()
    assert s.positions.shape == (7, 2) and s.velocities.shape == (7, 2)
    assert s.commanded.shape == (7, 2)
    assert np.array_equal(s.positions[0], [0.0, 0.0])
    s.positions[:] = 99  # a copy: the env is unaffected
    assert e.snapshot().positions[0, 0] == 0.0


def test_a_flock_of_1000_runs_renders_and_stays_physical():
    """Scale: N = 1000 in a ±14 m arena with the Reynolds policy in the loop."""
    from scipy.spatial.distance import pdist

    from boids_env.policies import ReynoldsPolicy

    e = parallel_env(robots=1000, arena_half_size=14.0, render_mode="rgb_array")
    policy = ReynoldsPolicy()
    obs, _ = e.reset(seed=0)
    policy.reset(0)
    radius, half = e.config.world.robot_radius, e.config.world.arena_half_size
    worst = 0.0
    for _ in range(60):  # start-up hold, then 4 s of flocking
        obs, *_ = e.step(policy.act(obs))
        snap = e.snapshot()
        assert np.isfinite(snap.positions).all() and np.isfinite(snap.velocities).all()
        assert np.all(np.abs(snap.positions) <= half - radius + 0.005)
        worst = max(worst, 2 * radius - float(pdist(snap.positions).min()))
    assert worst <= 0.005, f"overlap {worst * 1000:.2f} mm"
    moved = np.linalg.norm(snap.velocities[1:], axis=1)
    assert (moved > 0.05).mean() > 0.5, "most followers should be moving after the start-up"
    frame = e.render()
    assert frame.shape[2] == 3 and frame.std() > 0
    assert all(np.isfinite(o).all() for o in obs.values())


@pytest.mark.parametrize("seed", [0, 1])
def test_random_full_speed_commands_overlap_at_most_5_mm(seed):
    """19 robots, every one commanded full speed in a random direction each step, 1000
    steps: contacts never sink more than 5 mm (the study's robots are 72 mm wide)."""
    from scipy.spatial.distance import pdist

    e = parallel_env(robots=19, path="external", startup_time=0.0, max_cycles=10**6)
    e.reset(seed=seed)
    rng = np.random.default_rng(seed)
    radius = e.config.world.robot_radius
    worst, half = 0.0, e.config.world.arena_half_size
    for step in range(1000):
        angle = rng.uniform(0, 2 * np.pi, 19)
        unit = np.stack([np.cos(angle), np.sin(angle)], axis=1) * 0.5
        e.set_leader_command(unit[0])
        e.step(dict(zip(e.agents, unit[1:], strict=True)))
        pos = e.snapshot().positions
        worst = max(worst, 2 * radius - float(pdist(pos).min()))
        assert np.abs(pos).max() < half, f"step {step}"
    assert worst <= 0.005, f"overlap {worst * 1000:.2f} mm"
