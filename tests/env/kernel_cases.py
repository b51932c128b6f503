"""The inputs of each kernel's comparison in ``test_kernels.py``'s table-driven test (the
case functions of :data:`CASES`, by the kernels' table names) and the helpers both use."""

from types import SimpleNamespace

import numpy as np
import pytest

from boids_env import kernels, parallel_env
from boids_env.config import EnvConfig
from boids_env.observations import KD_TREE_MIN_ROBOTS, Observer, rotation
from boids_env.policies import ReynoldsPolicy
from boids_env.rewards import Rewards


def same_bits(a, b, what):
    """``a`` and ``b`` the same bits: arrays (dtype, shape, bytes), or tuples, lists and dicts
    of them, element by element."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), what
        for key in a:
            same_bits(a[key], b[key], f"{what} {key}")
        return
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            same_bits(x, y, f"{what}[{i}]")
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (what, a.dtype, b.dtype, a.shape, b.shape)
    assert a.tobytes() == b.tobytes(), f"{what}: compiled {a!r} != reference {b!r}"


def _observations(caller, fields, positions, velocities, seed=0):
    """What an Observer of ``fields`` (reset with a fresh stream) makes of the robots."""
    observer = Observer(EnvConfig.from_kwargs(**fields))
    observer.reset(np.random.default_rng(seed), 0.3)
    return caller(observer, positions, velocities)


def _robots(rng, n, spread, scene=None):
    """``n`` robots' positions (the leader first; some bunched near walls in a scene) and
    velocities past the observations' bound, some rows signed zeros."""
    if scene is None:
        positions = rng.normal(0.0, spread, (n, 2))
    else:
        positions = _crowd_near_walls(rng, scene, n)
    velocities = rng.uniform(-4.0, 4.0, (n, 2))
    velocities[1::5] = -0.0
    return positions, velocities


# ---------------------------------------------------------------- the study's step
def _case_nearest(kernel, caller):
    # a grid: many exact ties; robot 20 exactly on robot 5 (distance 0: never each other's
    # neighbour); robot 21 exactly at the horizon of robot 19 (it counts)
    grid = np.array([[x, y] for x in range(5) for y in range(4)], dtype=float) * 0.5
    positions = np.vstack([grid, [[0.5, 0.5], [2.0, 3.0]]])
    for k in (1, 3, 5, 30):
        yield f"ties, k {k}", lambda k=k: caller(positions, 1.5, k)
        index = caller(positions, 1.5, k)[0]
        # hand-checked: robot 1 at (0, 0.5) has robots 0, 2, 5 and 20 at exactly 0.5 m
        # (index order), then robots 4 and 6 at sqrt(0.5) m
        assert index[0].tolist() == [0, 2, 5, 20, 4, 6][:k] or k == 30
        assert 20 not in index[4] and 5 not in index[19], "distance 0 is never a neighbour"
        assert (21 in index[18]) == (k == 30), "a robot exactly at the horizon counts"
    rng = np.random.default_rng(21)
    for trial in range(40):
        n = int(rng.integers(2, KD_TREE_MIN_ROBOTS))
        p = rng.normal(0.0, rng.choice([0.3, 1.0, 4.0]), (n, 2))
        h, k = float(rng.choice([0.5, 1.0, 3.0, 60.0])), int(rng.integers(1, 25))
        yield f"random {trial}", lambda p=p, h=h, k=k: caller(p, h, k)


def _case_nearest_grid(kernel, caller):
    rng = np.random.default_rng(7)
    ran = 0
    for case in range(60):
        n = int(rng.integers(KD_TREE_MIN_ROBOTS, 1200))
        k = int(rng.integers(1, 25))
        horizon = float(rng.choice([0.05, 0.3, 1.0, 2.5, 60.0]))
        positions = rng.uniform(-8.0, 8.0, (n, 2)) * rng.uniform(0.05, 3.0)
        status, index, distance = kernel(positions, horizon, k)
        if status == 0:  # the grid decides: its own bits are the KD-tree's
            ran += 1
            with kernels.reference():
                same_bits((index, distance), caller(positions, horizon, k), f"case {case}")
        yield f"case {case}", lambda p=positions, h=horizon, k=k: caller(p, h, k)
    assert ran >= 55, "random layouts have no exact ties: the grid decides them"
    # exact ties among a follower's nearest (a grid) and a robot exactly on another: the
    # grid declines (the KD-tree orders such ties its own way) and the KD-tree decides. A
    # horizon of 1 m holds 12 robots of the lattice (placed by rank), one of 3 m 113 (more
    # than RANK_LIMIT: sorted)
    grid = np.array([[x, y] for x in range(12) for y in range(10)], dtype=float) * 0.5
    jittered = grid + rng.uniform(-0.01, 0.01, grid.shape)
    on_top = np.vstack([jittered, jittered[7]])
    for label, positions in (("lattice", grid), ("on top", on_top)):
        for horizon in (1.0, 3.0):
            assert kernel(positions, horizon, 6)[0] == 1, (label, horizon)
            yield f"declined, {label} {horizon}", lambda p=positions, h=horizon: caller(p, h, 6)
    for bad in (np.inf, np.nan):  # no cell for it (an infinite one once never ended)
        broken = jittered.copy()
        broken[5, 1] = bad
        assert kernel(broken, 1.0, 6)[0] == 1
    for horizon in (1.0, 3.0):
        assert kernel(jittered, horizon, 6)[0] == 0
        yield f"jittered {horizon}", lambda h=horizon: caller(jittered, h, 6)


def _case_fill_observations(kernel, caller):
    rng = np.random.default_rng(22)
    for fields in ({"robots": 19}, {"robots": 7, "neighbours": 0},
                   {"robots": 31, "neighbours": 30, "horizon": 3.0},
                   {"robots": 13, "frame": "leader"}):
        for trial in range(5):
            positions, velocities = _robots(rng, fields["robots"], [0.5, 2.0, 30.0][trial % 3])
            yield f"{fields} {trial}", lambda f=fields, p=positions, v=velocities: (
                _observations(caller, f, p, v))


def _world(positions, commanded, velocities=None):
    """What ``Rewards.terms`` reads of a world."""
    return SimpleNamespace(positions=positions, commanded=commanded, headings=None,
                           velocities=np.zeros_like(positions) if velocities is None
                           else velocities, pedestrian_positions=np.zeros((0, 2)))


def _terms(caller, fields, world):
    """A fresh episode's reward terms of one step and the counts they leave."""
    rewards = Rewards(EnvConfig.from_kwargs(**fields), len(world.positions) - 1)
    return caller(rewards, world), rewards.counts.copy()


def _case_violations(kernel, caller):
    rng = np.random.default_rng(23)
    for fields in ({}, {"wrap_alignment": False}, {"reward_alignment": 0.0}):
        for trial in range(30):
            n = int(rng.integers(2, 40))
            positions = rng.normal(0.0, [0.3, 1.5, 4.0][trial % 3], (n, 2))
            positions[1] = positions[0] + [0.7, 0.0]  # at the thresholds, as sums land
            positions[-1] = positions[0] + [0.0, 2.25]
            commanded = rng.uniform(-0.6, 0.6, (n, 2))
            commanded[::4] = 0.0  # standing still: direction 0
            commanded[1] = commanded[0] @ rotation(np.pi / 4)  # about 45° off the leader's
            world = _world(positions, commanded)
            yield f"{fields} {trial}", lambda f=fields, w=world: _terms(caller, f, w)


def _case_rotated(kernel, caller):
    rng = np.random.default_rng(6)
    for shape in [(13, 2), (12, 1, 2), (2,), (12, 4, 2), (0, 2)]:
        v = rng.normal(size=shape) * 10.0 ** rng.integers(-300, 300, size=shape)
        v.reshape(-1)[:3] = [-0.0, 0.0, 1e-310][:v.size]  # signed zeros, a subnormal
        for m in (rotation(0.7), rotation(0.7).T, rotation(-3.0)):  # .T: not contiguous
            yield f"{shape}", lambda v=v, m=m: caller(v, m)


def _case_batch_after(kernel, caller):
    from boids_env.batch import EnvBatch

    fields = [{"robots": 7}, {"robots": 13, "frame": "leader", "relative_actions": True},
              {"robots": 9, "frame": "leader"}, {"robots": 19, "reward": "study"},
              {"robots": 5, "obs_noise": 0.02}]  # not fused: its own step in the same call

    def run():
        batch = EnvBatch([parallel_env(max_cycles=60, **f) for f in fields])
        out = [batch.reset_arrays([0, 1, 2, 3, 4])]
        rng = np.random.default_rng(3)
        for _ in range(50):
            step = caller(batch, rng.uniform(-1.0, 1.0, (batch.rows, 2)))
            out.append((step.observations, step.rewards, step.terms, step.truncated))
        return out, [env.episode_metrics() for env in batch.envs]

    yield "50 steps of 5 copies", run
# --------------------------------------------------------- flags, motion, the scene
def _case_nearest_other(kernel, caller):
    rng = np.random.default_rng(3)
    for trial in range(200):
        n = int(rng.integers(2, 40))
        positions = rng.normal(0, [0.05, 0.5, 3.0][trial % 3], (n, 2))
        positions[n // 2] = positions[0]  # a robot exactly on the leader: distance 0
        near = rng.random(n - 1) < 0.5
        yield f"trial {trial}", lambda p=positions, w=near: caller(p, 0.036, 0.15, w)
    # hand-checked: followers 0.1 m and 0.3 m from the leader, 0.2 m from each other
    flags = caller(np.array([[0.0, 0.0], [0.1, 0.0], [0.3, 0.0]]), 0.036, 0.15,
                   np.zeros(2, dtype=bool))
    assert flags["proximity"].tolist() == [True, False]
    assert flags["contact"].tolist() == [False, False]


def _case_safety_gap_terms(kernel, caller):
    rng = np.random.default_rng(5)
    fields = {"reward": "safe", "reward_gap": 10.0, "cohesion_threshold": 1.0,
              "reward_contact": 0.0}  # a zero weight: its terms −0.0
    for trial in range(200):
        n = int(rng.integers(2, 40))
        positions = rng.normal(0, [0.05, 0.5, 3.0][trial % 3], (n, 2))
        positions[n // 2] = positions[0]  # exactly on the leader: distance 0, gap 0
        positions[-1] = positions[0] + [0.6, 0.8]  # exactly at the threshold: +0.0 gap
        positions[1] = [4.9, rng.uniform(-5.0, 5.0)]  # at the arena's wall
        world = _world(positions, rng.uniform(-0.5, 0.5, (n, 2)))
        yield f"trial {trial}", lambda w=world: _terms(caller, fields, w)
    for only in ({"reward": "safe"}, {"reward_gap": 2.0}):
        world = _world(rng.normal(0, 2.0, (9, 2)), rng.uniform(-0.5, 0.5, (9, 2)))
        yield f"{only}", lambda f=only, w=world: _terms(caller, f, w)


def _case_clip_speed(kernel, caller):
    rng = np.random.default_rng(0)
    rows = np.vstack([rng.uniform(-1, 1, (50, 2)), [[0.0, 0.0], [-0.0, 0.0], [0.3, 0.4],
                                                     [1e-300, -1e-300], [3.0, -4.0]]])
    for limit in (0.5, 2.0):
        yield f"limit {limit}", lambda limit=limit: caller(rows, limit)
    huge = np.array([[1e155, 0.0], [1e300, -1e300], [0.3, 0.4]])  # the kernel leaves these
    yield "overflowing speeds", lambda: caller(huge, 0.5)
    slow = rows[:52]  # no row over 2 m/s: returned as it is
    assert caller(slow, 2.0) is slow or np.shares_memory(caller(slow, 2.0), slow)
    np.testing.assert_array_equal(caller(huge, 0.5),
                                  [[0.5, 0.0], [0.5 / np.sqrt(2), -0.5 / np.sqrt(2)],
                                   [0.3, 0.4]])


def _case_unicycle_substep(kernel, caller):
    from boids_env.world.scenario import initial_positions
    from boids_env.world.space import World

    cfg = EnvConfig.from_kwargs(robot="turtlebot3_burger", robots=9)
    start = initial_positions(cfg.scenario, np.random.default_rng(0))
    commands = np.random.default_rng(1).uniform(-0.4, 0.4, (40, 9, 2))
    commands[::7] = 0.0  # standing still between turns

    def run():
        world = World(cfg.world, start, cfg.scene, np.zeros(9))
        out = []
        for command in commands:
            caller(world, command)
            out.append((world.positions.copy(), world.velocities.copy(),
                        np.array(world.headings)))
        return out

    yield "40 steps of 9 TurtleBots", run


def scene_named(name):
    from boids_env.world.scenes import load_scene

    return load_scene(name)


def _points(rng, scene, far=400, near=10):
    """Points anywhere in and around the scene, and bunched near its walls."""
    x0, y0, x1, y1 = scene.bounds
    points = rng.uniform([x0 - 0.5, y0 - 0.5], [x1 + 0.5, y1 + 0.5], (far, 2))
    return np.vstack([points, *(_crowd_near_walls(rng, scene, 20) for _ in range(near))])


def _case_nearest_points(kernel, caller):
    rng = np.random.default_rng(11)
    for name in ("lab", "small_room", "pillars", "arena", "corridor"):
        scene = scene_named(name)
        points = _points(rng, scene)
        for slots, reach in ((1, 0.5), (2, 1.0), (4, 0.5), (3, 3.0)):
            yield f"{name} {slots} {reach}", lambda s=scene, p=points, k=slots, r=reach: (
                caller(s, p, k, r))


def _case_shape_clearance(kernel, caller):
    rng = np.random.default_rng(24)
    for name in ("pillars", "doorway", "corridor", "floorplan:3"):  # a box and capsules
        scene = scene_named(name)
        points = _points(rng, scene)
        for margins in ((0.036, 0.005), (0.25,), (0.5, 0.1)):
            yield f"{name} {margins}", lambda s=scene, p=points, m=margins: caller(s, p, *m)


def _case_capsule_clearance(kernel, caller):
    rng = np.random.default_rng(25)
    for name in ("lab", "pillars", "corridor", "floorplan:3"):
        scene = scene_named(name)
        points = _points(rng, scene)
        yield name, lambda s=scene, p=points: caller(s, p)


def _case_occupied(kernel, caller):
    scene = scene_named("lab")
    points = _points(np.random.default_rng(26), scene)
    yield "lab", lambda: caller(scene.grid, points)


def _case_within(kernel, caller):
    scene = scene_named("lab")  # a map's cells and capsules, no box: one compiled call
    points = _points(np.random.default_rng(12), scene)
    for margins in ((0.036, 0.001), (0.25,), (0.5, 0.1), ()):
        yield f"lab {margins}", lambda m=margins: caller(scene, points, *m)
        got = caller(scene, points, *margins)
        assert 0 < got.sum() < len(points) or not margins, margins  # both answers occur


def _case_box_within(kernel, caller):
    from boids_env.world.scene import Scene

    scene = Scene("box", box=(-5.0, -4.0, 5.0, 4.0))
    margins = (0.1, 0.05)
    edge = np.array([5.0 - 0.1 - 0.05, 4.0 - 0.1 - 0.05, -5.0 + 0.1 + 0.05, -4.0 + 0.15])
    rng = np.random.default_rng(0)
    points = rng.uniform(-5.5, 5.5, (500, 2))
    points[:40] = rng.choice(edge, (40, 2))  # on the margins, as the float sums land
    points[40:42] = [[np.nan, 0.0], [np.inf, 0.0]]
    yield "box, at the margins", lambda: caller(scene, points, *margins)
    got = caller(scene, points, *margins)
    assert got[:40].any() and not got[40] and got[41]
    with pytest.raises(ValueError):  # points (P, 3): refused, never read as pairs
        caller(scene, np.zeros((4, 3)), 0.1)
    arena = scene_named("arena")
    points = _points(rng, arena)
    for margins in ((0.036, 0.005), (0.25,)):
        yield f"arena {margins}", lambda m=margins: caller(arena, points, *m)


def _case_segments_blocked(kernel, caller):
    """Sight lines anywhere, some ending on a capsule's surface or axis, some of no length,
    at clearance 0 (line of sight) and 0.1 m (path checks)."""
    rng = np.random.default_rng(17)
    for name in ("lab", "pillars", "doorway", "floorplan:3", "corridor"):
        scene = scene_named(name)
        x0, y0, x1, y1 = scene.bounds
        starts = rng.uniform([x0, y0], [x1, y1], (600, 2))
        ends = rng.uniform([x0, y0], [x1, y1], (600, 2))
        ends[:50] = starts[:50]
        if len(scene.a):
            ends[50:100] = scene.a[rng.integers(len(scene.a), size=50)]
        for clearance in (0.0, 0.1):
            for grid in (True, False):
                yield f"{name} {clearance} {grid}", lambda s=scene, a=starts, b=ends, c=clearance, \
                    g=grid: caller(s, a, b, c, use_grid=g)


def _case_raycast(kernel, caller):
    """Rays from anywhere (inside walls and pillars, off the map) in every direction, the
    axes' included (a zero component)."""
    rng = np.random.default_rng(19)
    for name in ("lab", "small_room", "pillars", "arena", "floorplan:3"):
        scene = scene_named(name)
        x0, y0, x1, y1 = scene.bounds
        origins = rng.uniform([x0 - 0.2, y0 - 0.2], [x1 + 0.2, y1 + 0.2], (300, 2))
        origins = np.vstack([origins, _crowd_near_walls(rng, scene, 60)])
        angles = np.concatenate([rng.uniform(0, 2 * np.pi, 12), np.arange(4) * np.pi / 2])
        directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        directions[12:] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
        directions = np.broadcast_to(directions, (len(origins), 16, 2))
        for max_range in (0.5, 3.0):
            yield f"{name} {max_range}", lambda s=scene, o=origins, d=directions, r=max_range: (
                caller(s, o, d, r))


def _sensed(caller, seed, cases):
    """Observers of each of ``cases`` (env fields) on robots bunched near walls."""
    rng = np.random.default_rng(seed)
    for fields in cases:
        scene = EnvConfig.from_kwargs(**fields).scene
        for trial in range(4):
            positions, velocities = _robots(rng, fields.get("robots", 13), 0.0, scene)
            yield f"{fields} {trial}", lambda f=fields, p=positions, v=velocities, s=trial: (
                _observations(caller, f, p, v, seed=s))


def _case_ray_circles_nearest(kernel, caller):
    yield from _sensed(caller, 27, [
        {"scene": "small_room", "lidar_rays": 12, "robots": 7},
        {"scene": "small_room", "leader": "person", "lidar_rays": 12, "robots": 7},
        {"scene": "pillars", "lidar_rays": 8, "robots": 13, "frame": "leader"}])


def _case_static_block(kernel, caller):
    yield from _sensed(caller, 28, [
        {"sense_walls": True}, {"sense_walls": True, "frame": "leader"},
        {"scene": "lab", "static_slots": 3}, {"scene": "pillars", "static_slots": 2,
                                              "frame": "leader", "robots": 19}])


def _case_noisy_observations(kernel, caller):
    rng = np.random.default_rng(3)
    low = np.array([-1.0, 0.0, 0.0, -3.0, -0.0], dtype=np.float32)
    high = np.array([1.0, 1.0, 3.0, 3.0, 0.0], dtype=np.float32)
    # the kernel alone against numpy's masking, sum and clip: values at, inside and past the
    # bounds, signed zeros (np.clip picks the bound of an equal pair: -0.0 at a bound of 0.0
    # comes out 0.0), NaN and infinities
    values = np.array([-1.0, -0.0, 0.0, 1.0, 3.0, 0.5, -2.0, 4.0, np.nan, np.inf, -np.inf],
                      dtype=np.float32)
    obs = rng.choice(values, (400, 5))
    obs[:, 1] = rng.choice([0.0, 1.0], 400)  # column 1: a valid flag
    noise = rng.choice(np.array([0.0, -0.0, 1e-3, -1e-3, 2.5, -2.5, np.nan]), (400, 5))
    scaled, flags, zeroed = np.array([0, 2, 3, 4]), np.array([1, 1, 1, 1]), np.array([1])
    want = noise.copy()
    want[:, scaled] *= obs[:, flags]
    want[:, zeroed] = 0.0
    want = np.clip(obs + want, low, high).astype(np.float32)
    same_bits(kernel(obs, noise.copy(), scaled, flags, zeroed, low, high), want, "edge values")
    yield from _sensed(caller, 29, [
        {"obs_noise": 0.02}, {"obs_noise": 0.3, "frame": "leader", "relative_actions": True},
        {"obs_noise": 0.05, "sense_walls": True, "robots": 9},
        {"scene": "small_room", "obs_noise": 0.3, "lidar_rays": 6, "robots": 7}])


def _case_in_sight_ahead(kernel, caller):
    """Followers anywhere (in walls, off the map, on the leader), leaders anywhere free."""
    from boids_env.world.route import route_grid

    rng = np.random.default_rng(13)
    for name in ("lab", "doorway", "floorplan:3"):
        scene = scene_named(name)
        grid = route_grid(scene, 0.036)
        x0, y0, x1, y1 = scene.bounds
        for trial in range(40):
            leader = grid.centres[rng.integers(len(grid.centres))]
            points = rng.uniform([x0 - 0.3, y0 - 0.3], [x1 + 0.3, y1 + 0.3], (30, 2))
            points[0] = leader
            positions = np.vstack([leader, points])
            yield f"{name} {trial}", lambda g=grid, p=positions: caller(g, p)


def _case_safety_filter(kernel, caller):
    from boids_env.world import safety

    config = safety.SafetyConfig(safety_filter=True)
    rng = np.random.default_rng(7)
    for name in ("lab", "small_room", "pillars", "arena"):
        scene = scene_named(name)
        ran = 0
        for trial in range(150):
            n = int(rng.integers(2, 40))
            positions = _crowd_near_walls(rng, scene, n)
            velocities = rng.uniform(-0.6, 0.6, (n, 2))
            commands = rng.uniform(-1.0, 1.0, (n - 1, 2))
            lead = rng.uniform(-0.5, 0.5, 2)
            args = (commands, positions, velocities, lead, 0.036, 0.5, scene, config)
            yield f"{name} {trial}", lambda a=args: caller(*a)
            surfaces, valid = scene.nearest_points(positions[1:], safety.STATIC_POINTS, 0.5)
            status, _ = kernel(commands, positions, velocities, lead, 0.036, 2.0, 0.03, 0.5, 6,
                               surfaces, valid)
            ran += status == 0
        assert ran > 140, f"{name}: the kernel declined most cases"
    # robots on a grid: many exactly equal distances, whose order the KD-tree decides; the
    # kernel declines them (status 1) and the filter's result is the reference's
    scene = scene_named("arena")
    grid = np.array([[x, y] for x in range(4) for y in range(4)], dtype=float) * 0.2
    commands = np.full((len(grid) - 1, 2), 0.4)
    surfaces, valid = scene.nearest_points(grid[1:], safety.STATIC_POINTS, 0.5)
    status, _ = kernel(commands, grid, np.zeros_like(grid), np.zeros(2), 0.036, 2.0, 0.03,
                       0.5, 6, surfaces, valid)
    assert status == 1
    args = (commands, grid, np.zeros_like(grid), np.zeros(2), 0.036, 0.5, scene, config)
    yield "exact ties (declined)", lambda: caller(*args)


# ------------------------------------------------------------------- the policies'
def _case_reynolds_forces(kernel, caller):
    for fields in ({"robots": 19}, {"robots": 13, "neighbours": 3, "frame": "leader"},
                   {"robots": 9, "neighbours": 0},
                   {"robots": 31, "neighbours": 30, "horizon": 3.0, "obs_noise": 0.05},
                   {"robots": 200, "arena_half_size": 10.0, "neighbours": 6}):
        env = parallel_env(max_cycles=60, **fields)
        seen = [env.reset_arrays(seed=5)]
        driver = ReynoldsPolicy()
        driver.bind(env)
        driver.reset(0)
        while env.agents:
            seen.append(env.step_arrays(driver.act_batch(seen[-1])).observations)

        def run(env=env, seen=seen):
            policy = ReynoldsPolicy()
            policy.bind(env)
            policy.reset(0)
            # the actions and the weighted rule forces, signed zeros included
            return [(caller(policy, obs), dict(policy.forces)) for obs in seen]

        yield f"{fields}", run


def _case_actor(kernel, caller):
    """The shipped actors and a ReLU one: rows of zeros, negative zeros, tiny and huge
    values, no rows at all; every action the same bits."""
    from boids_env.policies.mlp_actor import MLPActor
    from boids_env.policies.registry import load_policy

    rng = np.random.default_rng(5)
    relu = MLPActor([rng.normal(0, 0.3, (16, 9)), rng.normal(0, 0.3, (2, 16))],
                    [rng.normal(0, 0.1, 16), rng.normal(0, 0.1, 2)], "relu", -1.0, 1.0)
    for actor in [load_policy(spec) for spec in ("learned", "learned-scenes")] + [relu]:
        for trial in range(60):
            f = int(rng.integers(0, 40))
            scale = rng.choice([1e-30, 1e-3, 1.0, 100.0, 1e30])
            x = (rng.normal(size=(f, actor.obs_size)) * scale).astype(np.float32)
            if f and trial % 3 == 0:
                x[0] = 0.0
                x[:, ::4] = -0.0
            yield f"{actor.name} {trial}", lambda a=actor, x=x: caller(a, x)


def _case_exact_layers(kernel, caller):
    """The hidden layers' float64 values themselves, against ``exact.ExactLinear`` and
    ``exact.tanh`` (an action's float32 rounding would hide a last-bit difference there);
    then the actors."""
    from boids_env.policies import _compiled, exact

    rng = np.random.default_rng(9)
    for inputs, outputs, rows in ((99, 128, 12), (128, 128, 61), (7, 2, 1), (30, 64, 0)):
        layer = exact.ExactLinear(rng.normal(0, 0.2, (inputs, outputs)),
                                  rng.normal(0, 0.1, outputs))
        x = rng.normal(0, 1, (rows, inputs)) * rng.choice([1e-200, 1e-5, 1.0, 1e200], (rows, 1))
        if rows:
            x[0] = 0.0
        what = f"layer {inputs}x{outputs}"
        slices, exponents = _compiled.exact_slices(x)
        constants = (exact.INV_LN2, exact.LN2, exact.TANH_ONE)
        for code, act in ((0, lambda y: y), (1, exact.tanh), (2, exact.relu)):
            got = _compiled.exact_combine(layer.products(slices), exponents, layer.column_scale,
                                          layer.bias, code, *constants)
            same_bits(got, act(layer(x)), f"{what}, activation {code}")
        # a hidden layer's output straight into the next layer's slices (one call)
        fused = _compiled.exact_combine_slices(layer.products(slices), exponents,
                                               layer.column_scale, layer.bias, 1, *constants)
        same_bits(fused, _compiled.exact_slices(exact.tanh(layer(x))), f"{what} next slices")
    y = np.concatenate([rng.normal(0, s, 2000) for s in (1e-8, 0.01, 0.5, 3.0, 30.0)])
    y = np.concatenate([y, [0.0, -0.0, 20.0, -20.0, 1e300]]).reshape(-1, 5)
    want = exact.tanh(y)
    _compiled._exact_tanh(y, exact.INV_LN2, exact.LN2, exact.TANH_ONE)
    same_bits(y, want, "tanh")
    yield from _case_actor(kernel, caller)


CASES = {
    "study.nearest": _case_nearest, "grid.nearest_grid": _case_nearest_grid,
    "study.fill_observations": _case_fill_observations, "study.violations": _case_violations,
    "study.rotated": _case_rotated, "study.batch_after": _case_batch_after,
    "flags.nearest_other": _case_nearest_other, "flags.safety_gap_terms": _case_safety_gap_terms,
    "motion.clip_speed": _case_clip_speed, "motion.unicycle_substep": _case_unicycle_substep,
    "scene.nearest_points": _case_nearest_points, "scene.shape_clearance": _case_shape_clearance,
    "scene.capsule_clearance": _case_capsule_clearance, "scene.occupied": _case_occupied,
    "scene.within": _case_within, "scene.box_within": _case_box_within,
    "scene.segments_blocked": _case_segments_blocked, "scene.raycast": _case_raycast,
    "scene.ray_circles_nearest": _case_ray_circles_nearest,
    "sensing.static_block": _case_static_block,
    "sensing.noisy_observations": _case_noisy_observations,
    "sensing.in_sight_ahead": _case_in_sight_ahead, "safety.safety_filter": _case_safety_filter,
    "reynolds_forces": _case_reynolds_forces, "exact_slices": _case_exact_layers,
    "exact_combine": _case_exact_layers, "exact_combine_slices": _case_exact_layers,
    "clip_actions": _case_actor,
}
"""Each kernel's inputs: ``case(kernel, caller)`` yields (label, thunk) pairs, each thunk
calling the table's caller; it may also check the kernel alone (its status where it
declines, its values against the numpy functions directly)."""


def _crowd_near_walls(rng, scene, n):
    """``n`` robots bunched around a random free point near static geometry."""
    x0, y0, x1, y1 = scene.bounds
    while True:
        centre = rng.uniform([x0, y0], [x1, y1])
        clearance = scene.clearance(centre[None])[0]
        if 0.05 < clearance < 0.6:
            break
    return centre + rng.normal(0.0, rng.choice([0.08, 0.2, 0.4]), (n, 2))
