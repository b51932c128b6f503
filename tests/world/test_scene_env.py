"""Scenes in the env: rigid walls and obstacles, the scene's own path and start, sensing,
the Reynolds policy's obstacle avoidance, drawing, determinism."""

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.eval.episode import run_episode
from boids_env.observations import ObservationLayout, Observer
from boids_env.policies import ReynoldsPolicy
from boids_env.world.scenes import BUILTIN

SCENES = sorted(BUILTIN)


@pytest.mark.parametrize("name", SCENES)
def test_no_robot_sinks_into_static_geometry_under_random_full_speed_commands(name):
    # a still leader; every follower drives at full speed in a random direction that it
    # keeps for about 2 s, so the flock runs into walls and obstacles again and again
    env = parallel_env(scene=name, path="external", max_cycles=1000)
    rng = np.random.default_rng(7)
    env.reset(seed=7)
    radius = env.config.world.robot_radius
    worst, step = 0.0, 0
    angle = rng.uniform(0, 2 * np.pi, len(env.agents))
    while env.agents:
        turn = rng.random(len(angle)) < 0.05
        angle = np.where(turn, rng.uniform(0, 2 * np.pi, len(angle)), angle)
        speed = env.config.world.max_speed
        env.step_arrays(np.stack([np.cos(angle), np.sin(angle)], axis=1) * speed)
        step += 1
        depth = radius - env.config.scene.clearance(env.snapshot().positions)
        worst = max(worst, float(depth.max()))
    assert step == 1000
    assert env.snapshot().wall_contacts.size or worst > -0.01, "the test reaches the walls"
    assert worst <= 0.005, f"{name}: a robot sank {worst * 1000:.1f} mm into static geometry"


@pytest.mark.parametrize("seed", range(3))
def test_reynolds_avoids_the_walls_of_a_small_room_by_itself(seed):
    result = run_episode(parallel_env(scene="small_room"), ReynoldsPolicy(), seed=seed)
    assert result.metrics["wall_fraction"] <= 0.01, result.metrics["wall_fraction"]
    assert "obstacle" in result.recording.forces, "its force is recorded like the others'"


def test_without_avoidance_the_small_room_flock_comes_closer_to_the_walls():
    on = run_episode(parallel_env(scene="small_room"), ReynoldsPolicy(), seed=0).metrics
    off = run_episode(parallel_env(scene="small_room"),
                      ReynoldsPolicy(obstacle_avoidance=False), seed=0).metrics
    assert off["min_clearance"] < on["min_clearance"] - 0.1, (off["min_clearance"],
                                                              on["min_clearance"])


def test_avoidance_is_off_in_the_arena_even_with_a_wall_slot():
    env = parallel_env(sense_walls=True)
    policy = ReynoldsPolicy()
    run_episode(env, policy, seed=0)
    assert not policy.avoid and "obstacle" not in policy.forces
    forced = ReynoldsPolicy(obstacle_avoidance=True)
    run_episode(parallel_env(sense_walls=True), forced, seed=0)
    assert forced.avoid, "asked for explicitly, it runs on the wall slot"


def test_a_scene_sets_its_path_and_start_unless_given():
    cfg = EnvConfig.from_kwargs(scene="doorway")
    assert cfg.scenario.path == "waypoints" and cfg.scenario.start == (-4.0, 0.0)
    assert cfg.static_slots == 4, "any scene but the arena senses its obstacles"
    slow = EnvConfig.from_kwargs(scene="small_room", leader_speed=0.4)
    assert slow.scenario.path_size == 2.0 and slow.scenario.leader_speed == 0.4
    back = cfg.replace(scene="arena")
    assert back.scenario == EnvConfig().scenario and back.static_slots == 0
    from boids_env.world.scenes import LAB_PATH

    mine = EnvConfig.from_kwargs(map=str(BUILTIN_LAB), path="waypoints", waypoints=LAB_PATH,
                                 start=(-3.5, -2.5))
    assert mine.world.scene == str(BUILTIN_LAB) and mine.scenario.start_heading is None
    with pytest.raises(ValueError, match=r"leader path 'square' of scene 'doorway': leg 1 "
                       r"from \(-4\.00, 0\.00\) to \(-4\.00, 4\.00\)|reaches .* north wall"):
        EnvConfig.from_kwargs(scene="doorway", path="square")
    with pytest.raises(ValueError, match=r"scene must be one of .*arena.*doorway"):
        EnvConfig.from_kwargs(scene="moon")
    with pytest.raises(TypeError, match="scene or the map, not both"):
        EnvConfig.from_kwargs(scene="lab", map="x.yaml")


BUILTIN_LAB = __import__("boids_env.world.scenes", fromlist=["DATA"]).DATA / "lab.yaml"


@pytest.mark.parametrize("name", SCENES)
def test_observations_stay_in_their_space_with_static_slots_and_lidar(name):
    env = parallel_env(scene=name, lidar_rays=16, max_cycles=150)
    obs, _ = env.reset(seed=1)
    blocks = [b for b, _ in env.layout.blocks]
    assert blocks[-2:] == (["neighbours", "lidar"] if name == "arena" else ["static", "lidar"])
    rng = np.random.default_rng(1)
    step = 0
    while env.agents:
        for agent, o in obs.items():
            assert env.observation_space(agent).contains(o), (name, step, agent)
        obs, *_ = env.step({a: rng.uniform(-0.5, 0.5, 2) for a in env.agents})
        step += 1
    assert ObservationLayout.from_blocks(env.layout.blocks) == env.layout


def test_the_lidar_reads_walls_and_robots_at_hand_computed_ranges():
    config = EnvConfig.from_kwargs(scene="small_room", robots=3, lidar_rays=4,
                                   lidar_range=3.0)
    observer = Observer(config)
    observer.reset(None)
    # walls at ±2.5; follower 1 at (1.5, 0) sees the east wall 1.0 m away (+x ray), follower
    # 2 at (-1.5, 0) 2.0 m to its east along +x... the leader at (0, 0) is in the way
    pos = np.array([[0.0, 0.0], [1.5, 0.0], [-1.5, -2.0]])
    obs = observer(pos, np.zeros((3, 2)))
    lidar = obs[:, observer.layout.block("lidar")]
    r = config.world.robot_radius
    np.testing.assert_allclose(lidar[0], [1.0, 2.5, 1.5 - r, 2.5], atol=1e-6)
    np.testing.assert_allclose(lidar[1], [3.0, 3.0, 1.0, 0.5], atol=1e-6)
    static = obs[:, observer.layout.block("static")].reshape(2, 4, 3)
    np.testing.assert_allclose(static[1, 0], [0.0, -0.5, 1.0], atol=1e-6)
    np.testing.assert_allclose(static[1, 1], [-1.0, 0.0, 1.0], atol=1e-6)


def test_random_waypoints_in_a_pillar_field_keep_clear_of_the_pillars():
    env = parallel_env(scene="pillars", path="random_waypoints", path_size=3.5)
    scene = env.config.scene
    for seed in range(5):
        env.reset(seed=seed)
        path = env.leader.reference_path()
        blocked, _ = scene.blocked(path[:-1], path[1:], env.config.world.robot_radius)
        assert not blocked.any(), f"seed {seed}"


def test_scene_episodes_are_deterministic():
    def run():
        env = parallel_env(scene="lab", lidar_rays=8, obs_noise=0.01, max_cycles=120)
        result = run_episode(env, ReynoldsPolicy(), seed=3)
        return result.recording.positions, result.metrics

    (a, ma), (b, mb) = run(), run()
    assert np.array_equal(a, b) and ma == mb


def test_frames_draw_the_scenes_obstacles():
    from boids_env import style
    from boids_env.render import OBSTACLE

    env = parallel_env(scene="pillars", render_mode="rgb_array", max_cycles=5)
    env.reset(seed=0)
    image = env.render()
    renderer = env._renderer
    x, y = renderer.to_px(env.config.scene.a[0])
    assert tuple(image[y, x]) == OBSTACLE, "a pillar's centre is drawn as an obstacle"
    cx, cy = renderer.to_px(np.array([0.0, 0.0]))
    assert tuple(image[cy, cx]) != OBSTACLE
    assert style.RULE_COLOURS["obstacle"] != OBSTACLE
