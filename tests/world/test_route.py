"""Route sensing on hand-made scenes: the way to the leader goes through the door."""

import math

import numpy as np
import pytest

from boids_env.config import EnvConfig
from boids_env.environment import BoidsEnv
from boids_env.observations import ObservationLayout
from boids_env.world.route import route_grid, sense_route
from boids_env.world.scene import Scene

RADIUS = 0.036


def two_rooms(door: float) -> Scene:
    """A 6 m × 4 m box cut at x = 0 by a wall (10 cm thick) with a door of clear width
    ``door`` centred at y = 1."""
    jamb = door / 2 + 0.05
    return Scene("two rooms", box=(-3.0, -2.0, 3.0, 2.0),
                 a=np.array([[0.0, 1.0 + jamb], [0.0, 1.0 - jamb]]),
                 b=np.array([[0.0, 3.0], [0.0, -3.0]]), radius=np.full(2, 0.05))


def test_the_direction_points_at_the_door_not_through_the_wall():
    scene = two_rooms(1.0)
    leader, follower = np.array([2.0, -1.0]), np.array([-2.0, -1.0])
    direction, length, valid = sense_route(route_grid(scene, RADIUS),
                                           np.stack([leader, follower]))
    assert valid.tolist() == [True]
    to_door = np.array([0.0, 1.0]) - follower
    cosine = float(direction[0] @ to_door / np.linalg.norm(to_door))
    # straight at the leader would be (1, 0): 45° off the door's bearing (cos 0.707)
    assert cosine > 0.95, (direction, cosine)
    assert abs(np.linalg.norm(direction[0]) - 1.0) < 1e-12
    via_door = 2 * math.hypot(2.0, 2.0)  # 5.66 m, against 4 m straight through the wall
    assert via_door - 0.1 <= length[0] <= 3 * via_door, length


def test_a_door_narrower_than_a_robot_is_no_way_through():
    scene = two_rooms(0.06)  # narrower than the robot's 0.072 m diameter
    leader, follower = np.array([2.0, -1.0]), np.array([-2.0, -1.0])
    direction, length, valid = sense_route(route_grid(scene, RADIUS),
                                           np.stack([leader, follower]))
    # stated fallback: valid flag 0, the straight line's direction and distance
    assert valid.tolist() == [False]
    np.testing.assert_allclose(direction[0], [1.0, 0.0])
    np.testing.assert_allclose(length, [4.0])



def test_a_door_passes_a_robot_narrower_than_it_and_stops_a_wider_one():
    scene = two_rooms(0.3)
    pos = np.array([[2.0, -1.0], [-2.0, -1.0]])
    assert sense_route(route_grid(scene, 0.08), pos)[2].tolist() == [True]  # 0.16 m wide
    assert sense_route(route_grid(scene, 0.2), pos)[2].tolist() == [False]  # 0.4 m wide


def test_in_the_open_the_route_is_the_straight_line():
    scene = two_rooms(1.0)
    pos = np.array([[-1.0, -1.0], [-2.5, -1.0], [-1.0, 0.2], [-1.3, -1.3]])
    direction, length, valid = sense_route(route_grid(scene, RADIUS), pos)
    straight = pos[0] - pos[1:]
    cos = (direction * straight).sum(1) / np.linalg.norm(straight, axis=1)
    assert valid.all() and (cos > 0.97).all(), cos
    assert (length >= np.linalg.norm(straight, axis=1) - 0.15).all(), length


def test_a_follower_touching_a_wall_reads_its_nearest_free_cell():
    scene = two_rooms(1.0)
    pos = np.array([[2.0, -1.0], [-0.08, -1.0]])  # 3 cm from the wall's face
    direction, _, valid = sense_route(route_grid(scene, RADIUS), pos)
    assert valid.tolist() == [True]
    # off the wall (−x) and up towards the door (+y), never into the wall (+x, the leader)
    assert direction[0, 0] < 0 and direction[0, 1] > 0.5, direction


def test_the_grid_is_built_once_per_scene_and_radius():
    scene = two_rooms(1.0)
    assert route_grid(scene, RADIUS) is route_grid(scene, RADIUS)
    assert route_grid(scene, RADIUS) is not route_grid(scene, 0.1)


def test_the_route_block_is_opt_in_and_last():
    plain = EnvConfig.from_kwargs(scene="doorway")
    routed = plain.replace(route_sensing=True)
    env = BoidsEnv(routed)
    assert "route" not in [b for b, _ in BoidsEnv(plain).layout.blocks]
    assert env.layout.blocks[-1] == ("route", 4)
    assert ObservationLayout.from_blocks(env.layout.blocks) == env.layout
    obs, _ = env.reset(seed=0)
    for agent, o in obs.items():
        assert env.observation_space(agent).contains(o), agent
        route = o[env.layout.block("route")]
        assert route[3] == 1.0 and abs(np.hypot(route[0], route[1]) - 1) < 1e-5, route


def test_route_cell_is_validated():
    with pytest.raises(ValueError, match="route_cell"):
        EnvConfig.from_kwargs(route_cell=0.0)


@pytest.mark.parametrize("spec", ["lab", "eval/data/unseen_room.toml", "floorplan:3"])
def test_maps_shapes_files_and_floor_plans_have_routes(spec):
    from pathlib import Path

    from boids_env.world.scenes import load_scene

    root = Path(__file__).resolve().parents[2]
    scene = load_scene(str(root / spec) if spec.endswith(".toml") else spec)
    grid = route_grid(scene, RADIUS)
    d = scene.defaults
    points = np.array([d["start"], *d["waypoints"]])  # the leader's path: all one free space
    _, length, valid = sense_route(grid, points)
    assert valid.all(), points[1:][~valid]
    straight = np.linalg.norm(points[1:] - points[0], axis=1)
    assert (length >= straight - 0.15).all()


def _leader_blocks(route_leader: bool, positions: np.ndarray, velocities=None,
                   block: str = "leader_position") -> np.ndarray:
    """A leader block of every follower in the ``doorway`` scene (world frame)."""
    from boids_env.observations import Observer

    config = EnvConfig.from_kwargs(scene="doorway", robots=len(positions), route_sensing=True,
                                   route_leader=route_leader)
    observer = Observer(config)
    velocities = np.zeros_like(positions) if velocities is None else velocities
    obs = observer(positions, velocities)
    return obs[:, getattr(observer.layout, block)].astype(float)


def test_route_leader_shows_the_leaders_motion_along_the_route():
    # the leader drives east, away from the wall; the follower west of it, south of the door,
    # sees its speed along its own way (towards the door); the one in sight sees it as is
    positions = np.array([[1.0, -2.0], [-1.0, -2.0], [2.0, -1.0]])
    velocities = np.array([[0.4, 0.0], [0.0, 0.0], [0.0, 0.0]])
    plain = _leader_blocks(False, positions, velocities, "leader_velocity")
    routed = _leader_blocks(True, positions, velocities, "leader_velocity")
    np.testing.assert_allclose(plain, [[0.4, 0.0], [0.4, 0.0]], atol=1e-7)  # float32
    np.testing.assert_array_equal(routed[1], plain[1])
    assert abs(np.linalg.norm(routed[0]) - 0.4) < 1e-6, routed[0]
    to_door = np.array([1.0, 2.0]) / np.sqrt(5.0)  # from (-1, -2) to the door at (0, 0)
    assert routed[0] @ to_door / 0.4 > 0.9, routed[0]


def test_route_leader_shows_the_leader_through_the_door():
    # doorway: a wall at x = 0 with a 1 m door at y = 0; the leader east of it, one follower
    # west of the wall 2 m south of the door, one in the leader's room
    positions = np.array([[1.0, -2.0], [-1.0, -2.0], [2.0, -1.0]])
    straight = _leader_blocks(False, positions)
    routed = _leader_blocks(True, positions)
    np.testing.assert_allclose(straight[0], [2.0, 0.0], atol=1e-6)  # through the wall
    to_door = np.array([0.0, 0.0]) - positions[1]
    cosine = routed[0] @ to_door / (np.linalg.norm(routed[0]) * np.linalg.norm(to_door))
    assert cosine > 0.9, routed[0]  # towards the door, not the leader's bearing
    # as far as the way round: over the door (2.24 m + 2.24 m), not the 2 m through the wall
    assert np.linalg.norm(routed[0]) > 4.0, routed[0]
    # in sight of the leader it reads the straight line, bit for bit
    np.testing.assert_array_equal(routed[1], straight[1])


def test_leader_in_sight_through_free_space_only():
    from boids_env.world.route import leader_in_sight

    grid = route_grid(two_rooms(1.0), RADIUS)
    positions = np.array([[1.0, -1.0],     # the leader, east of the wall
                          [2.5, 1.5],      # same room
                          [-1.0, -1.0],    # west, the wall between
                          [-1.0, 1.0],     # west, straight through the door's middle
                          [-1.0, 1.45]])   # west, the segment grazes the door's jamb
    # (1, -1) -> (-1, 1.45) crosses x = 0 at y = 0.225: inside the wall below the door
    assert leader_in_sight(grid, positions).tolist() == [True, False, False, False]
    positions[0] = (1.0, 1.0)  # the leader in the doorway's line: the door's middle is free
    assert leader_in_sight(grid, positions).tolist() == [True, False, True, True]


def test_route_leader_needs_route_sensing():
    with pytest.raises(ValueError, match=r"route_leader=True .* needs route_sensing=True"):
        EnvConfig.from_kwargs(scene="doorway", route_leader=True)
    with pytest.raises(ValueError, match="route_leader"):
        EnvConfig.from_kwargs(scene="doorway", route_sensing=True, route_leader=2)


def test_route_leader_counts_the_gap_along_the_route():
    # one follower 2 m from the leader through the wall: inside the 2.25 m cohesion
    # threshold in a straight line, about 4.5 m by the door
    positions = np.array([[1.0, -2.0], [-1.0, -2.0]])
    gaps = {}
    for routed in (False, True):
        env = BoidsEnv(scene="doorway", robots=2, reward="safe", reward_gap=10.0,
                       route_sensing=True, route_leader=routed)
        env.reset(seed=0)
        gaps[routed] = float(env.episode.rewards.gap_term(positions)[0, 0])
    assert gaps[False] == 0.0
    dt = 0.1
    assert gaps[True] < -10.0 * dt * 2.0, gaps  # at least 2 m beyond the threshold


def test_parked_within_leaves_a_far_follower_free_to_come():
    velocities = np.array([[0.0, 0.0], [0.3, 0.4], [0.0, 0.5]])  # leader, near, far
    terms = {}
    for within in (0.0, 2.25):
        env = BoidsEnv(robots=3, reward="safe", reward_parked=30.0, parked_within=within)
        env.reset(seed=0)
        rewards = env.episode.rewards
        rewards.still_steps = 10**6  # the leader has stood still for long
        rewards.leader_distances = lambda positions: np.array([1.0, 5.0])
        terms[within] = rewards.parked_term(np.zeros((3, 2)), velocities)[0]
    dt = 0.1
    np.testing.assert_allclose(terms[0.0], [-30.0 * dt * 0.5, -30.0 * dt * 0.5])
    np.testing.assert_allclose(terms[2.25], [-30.0 * dt * 0.5, 0.0])
    with pytest.raises(ValueError, match="parked_within"):
        EnvConfig.from_kwargs(parked_within=-1.0)
