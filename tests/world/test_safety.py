"""The opt-in safety filter (boids_env.world.safety): the exact 2-D projection on
hand-computed half-planes, the barrier constraints on hand-computed geometry, and in the env:
commands driving robots at full speed into a wall or into each other are stopped short of
contact (the same commands without the filter touch), deterministically."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.config import EnvConfig
from boids_env.world.safety import SafetyConfig, barrier_constraints, nearest_allowed

FREE = 1e9


def test_one_half_plane_projects_only_a_command_it_forbids():
    a = np.array([[[1.0, 0.0]], [[1.0, 0.0]]])
    b = np.array([[0.2], [0.2]])
    out = nearest_allowed(np.array([[0.5, 0.1], [0.1, 0.3]]), a, b)
    np.testing.assert_allclose(out, [[0.2, 0.1], [0.1, 0.3]], atol=1e-15)


def test_two_half_planes_meet_at_their_corner():
    a = np.array([[[1.0, 0.0], [0.0, 1.0]]] * 3)
    b = np.array([[0.1, 0.2]] * 3)
    out = nearest_allowed(np.array([[0.5, 0.5], [0.5, 0.0], [-0.3, 0.1]]), a, b)
    np.testing.assert_allclose(out, [[0.1, 0.2], [0.1, 0.0], [-0.3, 0.1]], atol=1e-15)
    # a diagonal wall: the nearest point of x + y <= 0 to (0.4, 0.2) is (0.1, -0.1)
    n = np.array([[[1.0, 1.0]]]) / np.sqrt(2.0)
    out = nearest_allowed(np.array([[0.4, 0.2]]), n, np.array([[0.0]]))
    np.testing.assert_allclose(out, [[0.1, -0.1]], atol=1e-12)


def test_unused_rows_change_nothing_and_a_squeeze_violates_least():
    a = np.zeros((1, 3, 2))
    b = np.full((1, 3), FREE)
    command = np.array([[0.3, -0.4]])
    np.testing.assert_array_equal(nearest_allowed(command, a, b), command)
    # must move left by 0.2 and right by 0.1 at once: impossible; the command (0, 0) violates
    # the worst by 0.2, each projection by 0.3, so the command stays
    a = np.array([[[1.0, 0.0], [-1.0, 0.0]]])
    b = np.array([[-0.2, -0.1]])
    np.testing.assert_allclose(nearest_allowed(np.zeros((1, 2)), a, b), [[0.0, 0.0]])
    # the first row hard (a wall or the leader), the second soft (a follower, who yields
    # too): the hard row holds, (−0.2, 0)
    hard = np.array([[True, False]])
    np.testing.assert_allclose(nearest_allowed(np.zeros((1, 2)), a, b, hard), [[-0.2, 0.0]])


def test_barrier_constraints_of_a_wall_a_follower_and_the_leader():
    """Follower 1 at (0.2, 0) moving east at 0.2 m/s, 0.3 m west of a wall point; the leader
    at the origin commanding 0.5 m/s east; follower 2 at (0.6, 0) moving east at 0.1 m/s
    (the slower of them: 0.1 m/s east). α = 2 /s, margin 0.03 m, radius 0.036 m."""
    cfg = SafetyConfig(safety_filter=True, safety_margin=0.03, safety_gain=2.0,
                       safety_range=0.5, safety_neighbours=2)
    positions = np.array([[0.0, 0.0], [0.2, 0.0], [0.6, 0.0]])
    surfaces = np.array([[[0.3, 0.0]], [[0.0, 0.0]]])
    valid = np.array([[True], [False]])
    velocities = np.array([[0.4, 0.0], [0.2, 0.0], [0.1, 0.0]])
    a, b, hard = barrier_constraints(positions, velocities, np.array([0.5, 0.0]), 0.036, cfg,
                                     surfaces, valid)
    # follower 1: the wall 0.3 m east (n = +x), the leader 0.2 m west (n = −x), follower 2
    # 0.4 m east (n = +x, half the barrier plus the slower of their speeds along n)
    np.testing.assert_allclose(a[0], [[1.0, 0.0], [-1.0, 0.0], [1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(b[0], [2 * (0.3 - 0.036 - 0.03),
                                      2 * (0.2 - 0.072 - 0.03) - 0.5,
                                      0.5 * 2 * (0.4 - 0.072 - 0.03) + 0.1], atol=1e-12)
    # follower 2: no wall; follower 1 0.4 m west; the leader 0.6 m away, beyond the range
    np.testing.assert_allclose(a[1], [[0.0, 0.0], [-1.0, 0.0], [0.0, 0.0]], atol=1e-15)
    # along n = −x their speeds are −0.2 and −0.1: the smaller is −0.2
    np.testing.assert_allclose(b[1], [FREE, 0.5 * 2 * (0.4 - 0.072 - 0.03) - 0.2, FREE],
                               atol=1e-12)
    np.testing.assert_array_equal(hard, [[True, True, False], [True, False, False]])


def _drive(filtered, command_of, steps=80, **fields):
    env = parallel_env(safety_filter=filtered, startup_time=100.0, **fields)
    env.reset(seed=3)
    walls = contacts = 0
    for _ in range(steps):
        snap = env.snapshot()
        env.step({a: command_of(snap.positions, k + 1) for k, a in enumerate(env.agents)})
        after = env.snapshot()
        walls += len(after.wall_contacts)
        contacts += len(after.contacts)
    return walls, contacts, env.snapshot().positions


def test_full_speed_into_the_walls_stops_short_with_the_filter_only():
    east = lambda positions, k: np.array([0.5, 0.1])  # noqa: E731
    walls, _, _ = _drive(False, east, robots=7, scene="small_room")
    assert walls > 0, "without the filter the robots reach the east wall"
    walls, contacts, positions = _drive(True, east, robots=7, scene="small_room")
    assert walls == 0 and contacts == 0, (walls, contacts)
    assert positions[1:, 0].max() > 2.2, "the followers still went east, to the wall's margin"


def test_full_speed_into_each_other_stops_short_with_the_filter_only():
    def to_leader(positions, k):
        offset = positions[0] - positions[k]
        return 0.5 * offset / np.linalg.norm(offset)

    _, contacts, _ = _drive(False, to_leader, robots=13)
    assert contacts > 0, "without the filter the followers pile up on the leader"
    _, contacts, positions = _drive(True, to_leader, robots=13)
    assert contacts == 0, contacts
    d = np.linalg.norm(positions[1:] - positions[0], axis=1)
    assert d.min() < 0.3, "they still closed in on the leader"


def test_the_filter_is_off_by_default_deterministic_and_checked():
    assert EnvConfig().safety.safety_filter is False
    runs = []
    for _ in range(2):
        env = parallel_env(scene="pillars", safety_filter=True, max_cycles=60)
        env.reset(seed=5)
        rng = np.random.default_rng(0)
        while env.agents:
            env.step({a: rng.uniform(-0.5, 0.5, 2) for a in env.agents})
        runs.append(env.snapshot().positions)
    np.testing.assert_array_equal(runs[0], runs[1])
    with pytest.raises(ValueError, match=r"safety_gain must be in \(0.0, 100"):
        parallel_env(safety_gain=0.0)
    with pytest.raises(ValueError, match="safety_filter must be"):
        parallel_env(safety_filter="yes")


def test_people_constraints_of_a_person_and_a_pedestrian():
    """A follower (radius 0.036 m) at the origin; a person (radius 0.22 m) 0.4 m east walking
    west at 0.3 m/s; a pedestrian 0.6 m north standing; another 2 m away, beyond reach.
    Bodies: 0.256 m between centres; kept: 0.45 m, plus the 0.03 m margin."""
    from boids_env.world.safety import People, people_constraints

    people = People(np.array([[0.4, 0.0], [0.0, 0.6], [2.0, 0.0]]),
                    np.array([[-0.3, 0.0], [0.0, 0.0], [0.0, 0.0]]), 0.22, person_leads=True)
    bodies = SafetyConfig(safety_filter=True, safety_margin=0.03, safety_gain=2.0,
                          safety_range=0.5)
    a, b = people_constraints(np.zeros((1, 2)), people, 0.036, bodies)
    # reach: 0.5 + (0.256 - 0.072) = 0.684 m, so the person and the pedestrian, nearest first
    np.testing.assert_allclose(a[0, :2], [[1.0, 0.0], [0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(b[0, :2], [2 * (0.4 - 0.256 - 0.03) - 0.3,
                                          2 * (0.6 - 0.256 - 0.03)], atol=1e-12)
    assert (a[0, 2:] == 0).all() and (b[0, 2:] == FREE).all()
    zone = SafetyConfig(safety_filter=True, safety_margin=0.03, safety_gain=2.0,
                        safety_range=0.5, safety_person_distance=0.45)
    a, b = people_constraints(np.zeros((1, 2)), people, 0.036, zone)
    # the person leading: kept 0.48 m off, and already inside: back off; the pedestrian
    # at its body's distance
    np.testing.assert_allclose(b[0, :2], [2 * (0.4 - 0.48) - 0.3, 2 * (0.6 - 0.256 - 0.03)],
                               atol=1e-12)
    both = SafetyConfig(safety_filter=True, safety_margin=0.03, safety_gain=2.0,
                        safety_range=0.5, safety_person_distance=0.45,
                        safety_pedestrian_distance=0.7)
    a, b = people_constraints(np.zeros((1, 2)), people, 0.036, both)
    np.testing.assert_allclose(b[0, :2], [2 * (0.4 - 0.48) - 0.3, 2 * (0.6 - 0.73)],
                               atol=1e-12)
    # a pedestrian beyond reach (0.5 + 0.7 - 0.072 = 1.128 m) is no row
    far = People(np.array([[1.2, 0.0]]), np.zeros((1, 2)), 0.22)
    assert (people_constraints(np.zeros((1, 2)), far, 0.036, both)[1] == FREE).all()


def _person_run(filtered, steps=120, **fields):
    """Followers driven at full speed at the person leading (or, with a crowd, at the
    nearest pedestrian): the nearest centre distance to a person each follower-step."""
    env = parallel_env(leader="person", safety_filter=filtered, startup_time=100.0,
                       robots=7, **fields)
    env.reset(seed=2)
    nearest = []
    for _ in range(steps):
        world = env.unwrapped._world
        people = np.concatenate([world.positions[:1], world.pedestrian_positions])
        target = people[0] if not len(world.pedestrian_positions) else None
        actions = {}
        for k, agent in enumerate(env.agents):
            p = world.positions[k + 1]
            goal = target if target is not None else world.pedestrian_positions[
                np.argmin(np.linalg.norm(world.pedestrian_positions - p, axis=1))]
            offset = goal - p  # world-frame actions (the default frame)
            actions[agent] = 0.5 * offset / np.linalg.norm(offset)
        env.step(actions)
        world = env.unwrapped._world
        people = np.concatenate([world.positions[:1], world.pedestrian_positions])
        d = np.linalg.norm(world.positions[1:, None] - people[None], axis=2)
        nearest.append(d.min(axis=1))
    return np.array(nearest)


def test_a_person_leading_is_kept_off_at_its_own_width():
    """The filter used to keep a person leading off as if it were a robot (0.072 m between
    centres instead of 0.256 m), so followers drove into it."""
    bodies = 0.22 + 0.036
    assert _person_run(False).min() < bodies, "unfiltered, they reach the person"
    assert _person_run(True).min() > bodies
    near = _person_run(True, safety_person_distance=0.45)
    assert near.min() > 0.45 - 0.01, near.min()


def test_pedestrians_are_kept_off_as_far_as_the_robots_can():
    """Followers driven at their nearest pedestrian among 6: unfiltered they are in contact
    with a person 1.7 % of the follower-steps (the pedestrians walk around robots, but a
    robot driven at one catches it) and within 0.45 m 12 %; the filter, which keeps
    pedestrians off too, cuts both (measured: to 0)."""
    bodies = 0.22 + 0.036
    free = _person_run(False, crowd=6)
    kept = _person_run(True, crowd=6, safety_pedestrian_distance=0.45)
    assert (free < bodies).mean() > 0.01 and (free < 0.45).mean() > 0.05
    assert (kept < bodies).mean() < 0.3 * (free < bodies).mean()
    assert (kept < 0.45).mean() < 0.6 * (free < 0.45).mean()


def test_person_path_constraints_on_hand_computed_geometry():
    """A person at the origin walking east at 0.5 m/s (radius 0.22 m), kept 0.45 + 0.03 m off,
    path 2 s: the strip ahead reaches 0.5 × 2 + 0.48 = 1.48 m. A follower 0.6 m ahead and
    0.1 m to the left is 0.38 m inside the strip: it must move left at 2 × 0.38 m/s; one
    0.8 m to the right is 0.32 m outside it: it may close at most 2 × 0.32 m/s; one straight
    ahead takes the left; one behind the person or beyond the strip's end has no row, nor
    has anyone while the person stands."""
    from boids_env.world.safety import People, person_path_constraints

    config = SafetyConfig(safety_filter=True, safety_margin=0.03, safety_gain=2.0,
                          safety_range=0.5, safety_person_distance=0.45,
                          safety_person_path=2.0)
    walking = People(np.zeros((1, 2)), np.array([[0.5, 0.0]]), 0.22, person_leads=True)
    followers = np.array([[0.6, 0.1], [0.6, -0.8], [1.0, 0.0], [-0.3, 0.0], [1.6, 0.0]])
    a, b = person_path_constraints(followers, walking, 0.036, config)
    # a·v ≤ b: left is +y, so moving left at ≥ s is −v_y ≤ −s
    np.testing.assert_allclose(a[:, 0], [[0, -1], [0, 1], [0, -1], [0, 0], [0, 0]],
                               atol=1e-15)
    np.testing.assert_allclose(b[:3, 0], [-2 * 0.38, 2 * 0.32, -2 * 0.48], atol=1e-12)
    assert (b[3:, 0] == FREE).all()
    standing = People(np.zeros((1, 2)), np.array([[0.1, 0.0]]), 0.22, person_leads=True)
    assert (person_path_constraints(followers, standing, 0.036, config)[1] == FREE).all()
    off = SafetyConfig(safety_filter=True, safety_person_distance=0.45)
    assert (person_path_constraints(followers, walking, 0.036, off)[1] == FREE).all()
    with pytest.raises(ValueError, match="safety_person_path"):
        SafetyConfig(safety_person_path=-1.0)


def _ahead_of_the_person(path, steps=900):
    """Followers driven to a point 0.6 m ahead of a person walking the square at 0.5 m/s
    (a robot cannot outrun it backwards): each follower-step's centre distance to it."""
    env = parallel_env(leader="person", safety_filter=True, safety_person_distance=0.45,
                       safety_person_path=path, leader_speed=0.5, robots=7)
    env.reset(seed=2)
    distances = []
    for _ in range(steps):
        world = env.unwrapped._world
        velocity = world.velocities[0]
        speed = np.linalg.norm(velocity)
        heading = velocity / speed if speed > 0.1 else np.array([1.0, 0.0])
        offset = world.positions[0] + 0.6 * heading - world.positions[1:]
        commands = 0.5 * offset / np.maximum(np.linalg.norm(offset, axis=1, keepdims=True),
                                             1e-9)
        env.step({agent: commands[k] for k, agent in enumerate(env.agents)})
        if not env.agents:
            break
        world = env.unwrapped._world
        distances.append(np.linalg.norm(world.positions[1:] - world.positions[0], axis=1))
    return np.array(distances)


def test_a_walking_persons_path_is_kept_clear_where_backing_off_is_not_enough():
    """Followers that try to walk in front of the person: keeping 0.45 m off by backing away
    fails where the person walks as fast as they drive (the person reaches 0.39 m); with
    the path kept clear they step aside and never come within 0.45 m."""
    assert _ahead_of_the_person(0.0).min() < 0.42
    assert _ahead_of_the_person(2.0).min() > 0.45
