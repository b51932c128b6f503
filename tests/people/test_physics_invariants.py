"""People never break the physics: over long crowded episodes no body gets into a wall, no
pedestrian walks faster than the crowd's fastest speed, no robot moves faster than a walking
person can push it, and the guard that checks this on every step
(boids_env.world.invariants) says so when it is violated."""

import warnings

import numpy as np
import pytest

from boids_env import BoidsEnv
from boids_env.eval.episode import bind_policy, env_fields_for
from boids_env.policies.registry import load_policy
from boids_env.world.invariants import PhysicsGuard, PhysicsWarning
from boids_env.world.scenes import load_scene


def test_the_guard_counts_a_body_in_a_wall_and_one_too_fast_and_warns_once():
    scene = load_scene("corridor")
    x0, y0, x1, y1 = scene.bounds
    grid = np.stack(np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41)), -1)
    free = grid.reshape(-1, 2)[np.argmax(scene.clearance(grid.reshape(-1, 2)))]
    assert scene.clearance(free[None])[0] > 0.5
    guard = PhysicsGuard(scene, 0.036, 0.22, robot_speed=0.5, person_speed=1.2)
    inside = np.array([[x0 - 0.001, (y0 + y1) / 2], free])
    with pytest.warns(PhysicsWarning, match="step 3: robot 0 .* inside static geometry"):
        guard.check(3, inside, np.zeros((2, 2)), np.zeros((0, 2)), np.zeros((0, 2)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per world
        guard.check(4, inside[1:], np.array([[0.6, 0.0]]), inside[1:], np.array([[0.0, 1.3]]))
    assert guard.counts == {"robots_in_walls": 1, "people_in_walls": 0, "robots_too_fast": 1,
                            "people_too_fast": 1}


CROWDED = [
    ("corridor", {"scene": "corridor", "leader": "person", "crowd": 8}, "reynolds"),
    ("floorplan", {"scene": "floorplan:7", "leader": "person", "crowd": 8}, "random"),
    ("doorway walk", {"scene": "doorway", "leader_trajectory": "doorway_walk",
                      "leader": "trajectory", "crowd": 6}, "reynolds"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "fields", "policy"), CROWDED, ids=[c[0] for c in CROWDED])
def test_a_long_crowded_episode_keeps_every_body_out_of_walls_and_within_its_speed(
        name, fields, policy):
    pol = load_policy(policy)
    env = BoidsEnv(**env_fields_for(pol, {**fields, "max_cycles": 700}))
    obs, _ = env.reset(seed=11)
    bind_policy(pol, env)
    pol.reset(11)
    world, people = env.episode.world, env.episode.people
    scene, r = env.config.scene, env.config.world.robot_radius
    robot_limit = max(env.config.world.max_speed, world.guard.limits[1])
    sc = env.config.scenario
    leader_speed = max((v for v, _ in sc.leader_kind.top_speeds(sc)), default=0.0)
    step = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", PhysicsWarning)
        while env.agents:
            obs, *_ = env.step(pol.act(obs))
            step += 1
            robots = world.positions[1:] if world.person_leader else world.positions
            clear = scene.clearance(robots)
            assert clear.min() > r / 2, (name, step, float(clear.min()))
            speed = np.hypot(*world.velocities.T)
            assert speed.max() <= robot_limit, (name, step, float(speed.max()))
            walking = np.hypot(*world.pedestrian_velocities.T)
            # within the fastest walk configured (a pedestrian's own speed, or the
            # leader's: a body nudged by another stays within theirs)
            fastest = max(people.speeds.max(), leader_speed)
            assert walking.max() <= 1.01 * fastest, (name, step, float(walking.max()))
    assert step >= 300, (name, step)
    assert world.guard.counts == dict.fromkeys(world.guard.counts, 0), world.guard.counts
