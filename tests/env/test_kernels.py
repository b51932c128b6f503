"""The compiled kernels (boids_env.kernels) give the numpy reference's bits: whole episodes
stepped side by side, one env on the kernels and one on the reference, every observation,
reward, reward term and count compared bit for bit; and the kernels on hand-made inputs that
stress their edge cases (exact ties, zero distances, a neighbour exactly at the horizon,
overflowing commands)."""

import numpy as np
import pytest

from boids_env import kernels, parallel_env
from boids_env.environment import REWARD_INFO_KEYS
from boids_env.observations import nearest_neighbours
from boids_env.policies import ReynoldsPolicy
from boids_env.vectors import clip_speed


@pytest.fixture(autouse=True)
def _kernels_loaded():
    """The kernels at once (a process loads them on its own only after LOAD_AFTER calls)."""
    assert kernels.load() is not None, "numba is a core dependency: the kernels must load"


def test_reference_turns_the_kernels_off_inside_its_block():
    assert kernels.compiled() is not None
    with kernels.reference():
        assert kernels.compiled() is None
    assert kernels.compiled() is not None


LAZY = """
import sys
import numpy as np
from boids_env import kernels, parallel_env
kernels.LOAD_AFTER = 40
env = parallel_env(robots=7)
env.reset_arrays(seed=0)
for _ in range(5):
    env.step_arrays(np.zeros((6, 2)))
print("numba" in sys.modules, kernels.compiled() is None)
for _ in range(15):
    env.step_arrays(np.zeros((6, 2)))
print("numba" in sys.modules, kernels.compiled() is None)
"""


def test_a_process_loads_the_kernels_only_after_enough_steps():
    """A short run (one ``boids run`` episode) never pays numba's import; a long one loads
    the kernels once it has stepped a while."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "BOIDS_KERNELS"}
    done = subprocess.run([sys.executable, "-c", LAZY], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["False", "True", "True", "False"], done.stdout


def _same(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (what, a.dtype, b.dtype, a.shape, b.shape)
    assert a.tobytes() == b.tobytes(), f"{what}: compiled {a!r} != reference {b!r}"


EPISODES = [
    # the study's default case, a whole episode (746 steps) with the Reynolds flock
    ({}, "reynolds", None),
    ({"robots": 19}, "reynolds", 300),
    # random commands up to twice the speed limit: the limit scales most of them, and every
    # violation flag flips on and off
    ({"robots": 19}, "random", 200),
    # static slots and the leader frame, with the safety reward terms and sensing noise
    ({"sense_walls": True, "frame": "leader", "reward": "safe", "obs_noise": 0.02},
     "reynolds", 300),
    # ppo_safe's copies on a circle: random commands drive followers into the arena's walls
    # (the wall flags of the box, the static slots), the noise pushes observations past
    # their bounds (the clip)
    ({"robots": 13, "sense_walls": True, "frame": "leader", "relative_actions": True,
      "reward": "safe", "reward_gap": 10.0, "obs_noise": 0.05, "path": "circle",
      "startup_hold": True}, "random", 250),
    ({"scene": "pillars", "static_slots": 2, "lidar_rays": 8}, "reynolds", 200),
    # robots with headings (neighbour heading blocks read the kernel's neighbour index)
    ({"robot": "turtlebot3_burger", "robots": 9}, "random", 150),
    # the leader frame with relative actions and no slots, both in one fused call each
    # step (boids_env.fused)
    ({"robots": 13, "frame": "leader", "relative_actions": True}, "random", 150),
    ({"robots": 4, "neighbours": 0, "frame": "leader"}, "random", 40),
    # no neighbour slots at all (the compiled blocks with an empty index)
    ({"robots": 5, "neighbours": 0, "obs_noise": 0.02}, "random", 50),
    # many robots: the grid search standing in for the KD-tree (the KD-tree in the
    # reference), feeding the compiled observation blocks
    ({"robots": 100, "arena_half_size": 8.0}, "random", 20),
    ({"robots": 400, "arena_half_size": 12.0}, "reynolds", 15),
    # the safety filter (commands twice the limit: most followers' constraints bind), the
    # static slots and wall flags on a map's contours and cells (the lab)
    ({"scene": "lab", "robots": 19, "safety_filter": True, "sense_walls": True,
      "reward": "safe", "frame": "leader"}, "random", 250),
    ({"scene": "small_room", "robots": 31, "safety_filter": True, "static_slots": 3,
      "reward": "safe"}, "reynolds", 250),
    # a lidar with a person leading (a wider disc than a robot's) in a walled room
    ({"scene": "small_room", "leader": "person", "lidar_rays": 12, "robots": 7}, "random",
     120),
    # route sensing (the sight lines along each follower's route)
    ({"scene": "lab", "robots": 13, "route_sensing": True}, "reynolds", 300),
    # the learned followers for a lab (the compiled actor, filter and static slots)
    ({"scene": "lab"}, "learned-scenes", None),
]


@pytest.mark.parametrize("fields, policy, cycles", EPISODES, ids=str)
def test_episodes_are_bit_identical_to_the_numpy_reference(fields, policy, cycles):
    fields = dict(fields, **({"max_cycles": cycles} if cycles else {}))
    learned = None
    if policy.startswith("learned"):
        from boids_env.eval.episode import env_fields_for
        from boids_env.policies.registry import load_policy

        learned = load_policy(policy)
        fields = env_fields_for(learned, fields)
    fast, slow = parallel_env(**fields), parallel_env(**fields)
    obs = fast.reset_arrays(seed=2)
    with kernels.reference():
        ref = slow.reset_arrays(seed=2)
    _same(obs, ref, "reset observations")
    reynolds = ReynoldsPolicy()
    reynolds.bind(fast)
    reynolds.reset(0)
    rng = np.random.default_rng(1)
    limit = 2 * fast.config.world.max_speed
    step = 0
    while fast.agents:
        if learned is not None:  # the compiled actor against the numpy one, too
            act = learned.act_batch(obs)
            with kernels.reference():
                _same(act, learned.act_batch(obs), f"step {step} actions")
        else:
            act = (reynolds.act_batch(obs) if policy == "reynolds"
                   else rng.uniform(-limit, limit, (len(obs), 2)))
        res = fast.step_arrays(act)
        with kernels.reference():
            want = slow.step_arrays(act)
        _same(res.observations, want.observations, f"step {step} observations")
        _same(res.rewards, want.rewards, f"step {step} rewards")
        for row, key in enumerate(REWARD_INFO_KEYS):
            _same(res.terms[row], want.terms[row], f"step {step} {key}")
        assert res.truncated == want.truncated, step
        obs = res.observations
        step += 1
    assert step == (cycles or 746) or (learned is not None and step > 400), step
    assert fast.episode_metrics() == slow.episode_metrics()
    _same(fast.state(), slow.state(), "final state")


@pytest.mark.parametrize("fields", [
    {"robots": 19},  # fused: the infos are copies of 8 dicts picked by the flags' bits
    {"robots": 7, "frame": "leader", "relative_actions": True},
    {"robots": 7, "obs_noise": 0.02},  # not fused: the flags' bits of _terms's kernel
    {"robots": 9, "reward": "safe"},  # opt-in terms: a dict literal per agent
], ids=str)
def test_dict_api_infos_hold_the_reference_terms_bit_for_bit(fields):
    fast, slow = parallel_env(max_cycles=120, **fields), parallel_env(max_cycles=120, **fields)
    fast.reset(seed=4)
    with kernels.reference():
        slow.reset_arrays(seed=4)
    agents = fast.possible_agents
    rng = np.random.default_rng(2)
    while fast.agents:
        act = rng.uniform(-1.0, 1.0, (len(agents), 2))  # speeds over the limit too
        _, rewards, _, _, infos = fast.step(dict(zip(agents, act, strict=True)))
        with kernels.reference():
            want = slow.step_arrays(act)
        for row, key in enumerate(REWARD_INFO_KEYS):  # signed zeros included
            _same([infos[a][key] for a in agents], want.terms[row], key)
        _same([rewards[a] for a in agents], want.rewards, "rewards")
        assert len({id(infos[a]) for a in agents}) == len(agents)  # a dict each
        assert all(list(infos[a]) == list(REWARD_INFO_KEYS) for a in agents)


@pytest.mark.parametrize("fields", [
    {"robots": 19},
    {"robots": 13, "neighbours": 3, "frame": "leader"},
    {"robots": 9, "neighbours": 0},
    {"robots": 31, "neighbours": 30, "horizon": 3.0, "obs_noise": 0.05},
    {"robots": 200, "arena_half_size": 10.0, "neighbours": 6},
], ids=str)
def test_reynolds_forces_kernel_gives_the_numpy_policys_bits(fields):
    env = parallel_env(max_cycles=60, **fields)
    obs = env.reset_arrays(seed=5)
    fast, slow = ReynoldsPolicy(), ReynoldsPolicy()
    for policy in (fast, slow):
        policy.bind(env)
        policy.reset(0)
    step = 0
    while env.agents:
        act = fast.act_batch(obs)
        with kernels.reference():
            want = slow.act_batch(obs)
        _same(act, want, f"step {step} actions")
        assert fast.forces.keys() == slow.forces.keys()
        for name in fast.forces:  # the weighted rule forces, signed zeros included
            _same(fast.forces[name], slow.forces[name], f"step {step} {name}")
        obs = env.step_arrays(act).observations
        step += 1


def _both_neighbours(positions, horizon, k):
    got = nearest_neighbours(positions, horizon, k)
    with kernels.reference():
        want = nearest_neighbours(positions, horizon, k)
    return got, want


@pytest.mark.parametrize("k", [1, 3, 5, 30])
def test_neighbour_search_keeps_exact_ties_in_index_order(k):
    # a grid: many exact ties; robot 20 exactly on robot 5 (distance 0: never each other's
    # neighbour); robot 21 exactly at the horizon of robot 19 (it counts)
    grid = np.array([[x, y] for x in range(5) for y in range(4)], dtype=float) * 0.5
    positions = np.vstack([grid, [[0.5, 0.5], [2.0, 3.0]]])
    got, want = _both_neighbours(positions, 1.5, k)
    _same(got[0], want[0], "index")
    _same(got[1], want[1], "distance")
    # hand-checked: robot 1 at (0, 0.5) has robots 0, 2, 5 and 20 at exactly 0.5 m (index
    # order), then robots 4 and 6 at sqrt(0.5) m
    assert got[0][0].tolist() == [0, 2, 5, 20, 4, 6][:k] or k == 30
    assert 20 not in got[0][4] and 5 not in got[0][19], "distance 0 is never a neighbour"
    assert (21 in got[0][18]) == (k == 30), "a robot exactly at the horizon counts"


def test_grid_neighbour_search_gives_the_kd_trees_bits_or_declines():
    from boids_env import _compiled
    from boids_env.observations import KD_TREE_MIN_ROBOTS

    rng = np.random.default_rng(7)
    ran = 0
    for case in range(60):
        n = int(rng.integers(KD_TREE_MIN_ROBOTS, 1200))
        k = int(rng.integers(1, 25))
        horizon = float(rng.choice([0.05, 0.3, 1.0, 2.5, 60.0]))
        positions = rng.uniform(-8.0, 8.0, (n, 2)) * rng.uniform(0.05, 3.0)
        status, index, distance = _compiled.nearest_grid(positions, horizon, k)
        with kernels.reference():  # the KD-tree
            want = nearest_neighbours(positions, horizon, k)
        if status == 0:
            ran += 1
            _same(index, want[0], f"case {case} index")
            _same(distance, want[1], f"case {case} distance")
        got = nearest_neighbours(positions, horizon, k)  # the grid, or the KD-tree after it
        _same(got[0], want[0], f"case {case} index")
        _same(got[1], want[1], f"case {case} distance")
    assert ran >= 55, "random layouts have no exact ties: the grid decides them"
    # exact ties among a follower's nearest (a grid) and a robot exactly on another: the
    # grid declines (the KD-tree orders such ties its own way) and the KD-tree decides
    grid = np.array([[x, y] for x in range(12) for y in range(10)], dtype=float) * 0.5
    jittered = grid + rng.uniform(-0.01, 0.01, grid.shape)
    on_top = np.vstack([jittered, jittered[7]])
    # a horizon of 1 m holds 12 robots of the lattice (placed by rank), one of 3 m 113 (more
    # than _compiled.RANK_LIMIT: sorted)
    for positions, horizon in ((grid, 1.0), (grid, 3.0), (on_top, 1.0), (on_top, 3.0)):
        assert _compiled.nearest_grid(positions, horizon, 6)[0] == 1
        got, want = _both_neighbours(positions, horizon, 6)
        _same(got[0], want[0], "declined index")
        _same(got[1], want[1], "declined distance")
    for bad in (np.inf, np.nan):  # no cell for it (an infinite one once never ended)
        broken = jittered.copy()
        broken[5, 1] = bad
        assert _compiled.nearest_grid(broken, 1.0, 6)[0] == 1
    for horizon in (1.0, 3.0):
        status, index, distance = _compiled.nearest_grid(jittered, horizon, 6)
        assert status == 0
        with kernels.reference():
            want = nearest_neighbours(jittered, horizon, 6)
        _same(index, want[0], f"jittered index, horizon {horizon}")
        _same(distance, want[1], f"jittered distance, horizon {horizon}")


def test_noise_kernel_masks_adds_and_clips_as_numpy_does():
    from boids_env import _compiled

    rng = np.random.default_rng(3)
    low = np.array([-1.0, 0.0, 0.0, -3.0, -0.0], dtype=np.float32)
    high = np.array([1.0, 1.0, 3.0, 3.0, 0.0], dtype=np.float32)
    # values at, inside and past the bounds, signed zeros (np.clip picks the bound of an
    # equal pair: -0.0 at a bound of 0.0 comes out 0.0), NaN and infinities
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
    _same(_compiled.noisy_observations(obs, noise.copy(), scaled, flags, zeroed, low, high),
          want, "noisy observations")


def test_box_wall_flags_kernel_matches_at_the_margins():
    from boids_env import _compiled
    from boids_env.world.scene import Scene

    scene = Scene("box", box=(-5.0, -4.0, 5.0, 4.0))
    margins = (0.1, 0.05)
    edge = np.array([5.0 - 0.1 - 0.05, 4.0 - 0.1 - 0.05, -5.0 + 0.1 + 0.05, -4.0 + 0.15])
    rng = np.random.default_rng(0)
    points = rng.uniform(-5.5, 5.5, (500, 2))
    points[:40] = rng.choice(edge, (40, 2))  # on the margins, as the float sums land
    points[40:42] = [[np.nan, 0.0], [np.inf, 0.0]]
    with kernels.reference():
        want = scene.within(points, *margins)
    got = _compiled.box_within(points, np.array(scene.box), np.array(margins))
    _same(got, want, "box wall flags")
    assert got[:40].any() and not got[40] and got[41]
    _same(scene.within(points, *margins), want, "Scene.within, compiled")
    with pytest.raises(ValueError):  # points (P, 3): refused, never read as pairs
        scene.within(np.zeros((4, 3)), 0.1)


def test_clip_speed_kernel_matches_on_ordinary_zero_and_huge_rows():
    rng = np.random.default_rng(0)
    rows = np.vstack([rng.uniform(-1, 1, (50, 2)), [[0.0, 0.0], [0.3, 0.4]]])
    for limit in (0.5, 2.0):
        got = clip_speed(rows, limit)
        with kernels.reference():
            want = clip_speed(rows, limit)
        _same(got, want, f"limit {limit}")
    assert clip_speed(rows, 2.0) is rows or np.shares_memory(clip_speed(rows, 2.0), rows)
    huge = np.array([[1e155, 0.0], [1e300, -1e300], [0.3, 0.4]])
    np.testing.assert_array_equal(clip_speed(huge, 0.5),
                                  [[0.5, 0.0], [0.5 / np.sqrt(2), -0.5 / np.sqrt(2)],
                                   [0.3, 0.4]])


def test_safety_flags_kernel_matches_the_kd_tree():
    from boids_env.metrics import safety_flags

    rng = np.random.default_rng(3)
    for trial in range(200):
        n = int(rng.integers(2, 40))
        positions = rng.normal(0, [0.05, 0.5, 3.0][trial % 3], (n, 2))
        positions[n // 2] = positions[0]  # a robot exactly on the leader: distance 0
        near = rng.random(n - 1) < 0.5
        got = safety_flags(positions, 0.036, 0.15, near)
        with kernels.reference():
            want = safety_flags(positions, 0.036, 0.15, near)
        for name in want:
            _same(got[name], want[name], f"trial {trial} {name}")
    # hand-checked: followers 0.1 m and 0.3 m from the leader, 0.2 m from each other
    flags = safety_flags(np.array([[0.0, 0.0], [0.1, 0.0], [0.3, 0.0]]), 0.036, 0.15,
                         np.zeros(2, dtype=bool))
    assert flags["proximity"].tolist() == [True, False]
    assert flags["contact"].tolist() == [False, False]


def test_safety_and_gap_terms_kernel_gives_the_envs_numpy_terms():
    from boids_env.metrics import leader_distance, safety_flags

    compiled = kernels.load()
    rng = np.random.default_rng(5)
    for trial in range(200):
        n = int(rng.integers(2, 40))
        positions = rng.normal(0, [0.05, 0.5, 3.0][trial % 3], (n, 2))
        positions[n // 2] = positions[0]  # exactly on the leader: distance 0, gap 0
        positions[-1] = positions[0] + [0.6, 0.8]  # exactly at the threshold: +0.0 gap
        near = rng.random(n - 1) < 0.5
        scale = -np.array([1.0, 2.5, 0.0])[:, None] * 0.1  # −0.0 for the zero weight
        gap_scale, threshold = -10.0 * 0.1, 1.0
        with kernels.reference():
            flags = safety_flags(positions, 0.036, 0.15, near)
            gap = np.maximum(leader_distance(positions) - threshold, 0.0)
        want = np.zeros((9, n - 1))
        want[3:6] = scale * np.stack([flags[k] for k in ("proximity", "contact", "wall")])
        want[6:7] = gap_scale * gap[None]
        got = np.zeros((9, n - 1))
        compiled.safety_gap_terms(positions, near, np.ascontiguousarray(scale[:, 0]), 0.15,
                                  2 * 0.036 + 0.001, True, gap_scale, threshold, True, got)
        _same(got, want, f"trial {trial}")
    # hand-computed: followers 0.1 m (in proximity) and 3 m (2 m beyond 1 m) from the leader
    got = np.zeros((9, 2))
    compiled.safety_gap_terms(np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 3.0]]),
                              np.array([False, True]), np.array([-1.0, -2.0, -4.0]), 0.15,
                              0.073, True, -0.5, 1.0, True, got)
    assert got[3:7].tolist() == [[-1.0, -0.0], [-0.0, -0.0], [-0.0, -4.0], [-0.0, -1.0]]


def test_frame_rotation_runs_compiled_with_the_numpy_bits(monkeypatch):
    from boids_env import _compiled
    from boids_env.observations import rotation
    from boids_env.vectors import times_matrix

    calls = []
    rotated = _compiled.rotated
    monkeypatch.setattr(_compiled, "rotated", lambda v, m: calls.append(1) or rotated(v, m))
    rng = np.random.default_rng(6)
    for shape in [(13, 2), (12, 1, 2), (2,), (12, 4, 2), (0, 2)]:
        v = rng.normal(size=shape) * 10.0 ** rng.integers(-300, 300, size=shape)
        v.reshape(-1)[:3] = [-0.0, 0.0, 1e-310][:v.size]  # signed zeros, a subnormal
        for m in (rotation(0.7), rotation(0.7).T, rotation(-3.0)):  # .T: not contiguous
            got = times_matrix(v, m)
            with kernels.reference():
                want = times_matrix(v, m)
            _same(got, want, f"{shape}")
    assert len(calls) == 15, "the compiled rotation was not used"


DIGEST = """
import hashlib
import numpy as np
from boids_env import kernels, parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.eval.episode import env_fields_for
from boids_env.policies.registry import load_policy
env = parallel_env(robots=19, reward="safe", max_cycles=100)
rec = run_episode(env, ReynoldsPolicy(), seed=4, record=True).recording
# the learned followers in the lab: the actor, the safety filter, the map's queries
learned = load_policy("learned-scenes")
env = parallel_env(**env_fields_for(learned, {"scene": "lab", "max_cycles": 150}))
lab = run_episode(env, learned, seed=1, record=True).recording
print(kernels.compiled() is not None,
      hashlib.sha256(rec.positions.tobytes() + rec.commanded.tobytes()).hexdigest(),
      hashlib.sha256(lab.positions.tobytes() + lab.commanded.tobytes()).hexdigest())
"""


@pytest.mark.slow
def test_kernels_give_the_same_bits_compiled_for_a_baseline_cpu(tmp_path):
    """numba compiles for the host's instruction set; compiled for a baseline x86-64 CPU
    (``NUMBA_CPU_NAME=generic``: no AVX, no FMA) the episode is the same bits, and the
    same as the numpy reference's (each run a fresh process)."""
    import os
    import subprocess
    import sys

    runs = {}
    for name, extra in (("host", {"BOIDS_KERNELS": "1"}),
                        ("generic", {"BOIDS_KERNELS": "1", "NUMBA_CPU_NAME": "generic"}),
                        ("numpy", {"BOIDS_KERNELS": "0"})):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / name), **extra}
        done = subprocess.run([sys.executable, "-c", DIGEST], env=env, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-3000:]
        runs[name] = done.stdout.split()
    assert runs["host"][0] == runs["generic"][0] == "True" and runs["numpy"][0] == "False"
    assert runs["host"][1:] == runs["generic"][1:] == runs["numpy"][1:], runs


def test_kernels_that_cannot_load_leave_the_numpy_reference_with_a_warning(monkeypatch):
    """numba raises RuntimeError when it finds no writable cache folder: the env still
    runs, on numpy, and says why."""
    import sys

    import boids_env

    class Refuse:
        def find_spec(self, name, path=None, target=None):
            if name == "boids_env._compiled":
                raise RuntimeError("cannot cache function 'nearest': no locator available")
            return None

    monkeypatch.delitem(sys.modules, "boids_env._compiled")
    monkeypatch.delattr(boids_env, "_compiled")
    monkeypatch.setattr(sys, "meta_path", [Refuse(), *sys.meta_path])
    monkeypatch.setattr(kernels, "_loaded", False)
    monkeypatch.setattr(kernels, "_module", None)
    with pytest.warns(RuntimeWarning, match="numpy reference runs instead"):
        assert kernels.load() is None
    assert kernels.compiled() is None
    env = parallel_env(robots=5, max_cycles=3)
    env.reset_arrays(seed=0)
    assert env.step_arrays(np.zeros((4, 2))).observations.shape == (4, 6 + 5 * 18)


def _scene(name):
    from boids_env.world.scenes import load_scene

    return load_scene(name)


def _crowd_near_walls(rng, scene, n):
    """``n`` robots bunched around a random free point near static geometry."""
    x0, y0, x1, y1 = scene.bounds
    while True:
        centre = rng.uniform([x0, y0], [x1, y1])
        clearance = scene.clearance(centre[None])[0]
        if 0.05 < clearance < 0.6:
            break
    return centre + rng.normal(0.0, rng.choice([0.08, 0.2, 0.4]), (n, 2))


@pytest.mark.parametrize("name", ["lab", "small_room", "pillars", "arena"])
def test_safety_filter_kernel_matches_the_reference_near_walls_and_robots(name):
    from boids_env import _compiled
    from boids_env.world import safety

    scene = _scene(name)
    config = safety.SafetyConfig(safety_filter=True)
    rng = np.random.default_rng(7)
    ran = 0
    for trial in range(150):
        n = int(rng.integers(2, 40))
        positions = _crowd_near_walls(rng, scene, n)
        velocities = rng.uniform(-0.6, 0.6, (n, 2))
        commands = rng.uniform(-1.0, 1.0, (n - 1, 2))
        lead = rng.uniform(-0.5, 0.5, 2)
        args = (commands, positions, velocities, lead, 0.036, 0.5, scene, config)
        got = safety.filter_commands(*args)
        with kernels.reference():
            want = safety.filter_commands(*args)
        _same(got, want, f"trial {trial}")
        surfaces, valid = scene.nearest_points(positions[1:], safety.STATIC_POINTS, 0.5)
        status, _ = _compiled.safety_filter(commands, positions, velocities, lead, 0.036, 2.0,
                                            0.03, 0.5, 6, surfaces, valid)
        ran += status == 0
    assert ran > 140, "the kernel declined most cases: the test compared the reference alone"


def test_the_safety_filter_kernel_declines_exact_ties_and_the_reference_decides():
    """Robots on a grid: many exactly equal distances, whose order the KD-tree decides; the
    kernel declines them (status 1) and the filter's result is the reference's."""
    from boids_env import _compiled
    from boids_env.world import safety

    scene = _scene("arena")
    grid = np.array([[x, y] for x in range(4) for y in range(4)], dtype=float) * 0.2
    velocities = np.zeros_like(grid)
    commands = np.full((len(grid) - 1, 2), 0.4)
    config = safety.SafetyConfig(safety_filter=True)
    surfaces, valid = scene.nearest_points(grid[1:], safety.STATIC_POINTS, 0.5)
    status, _ = _compiled.safety_filter(commands, grid, velocities, np.zeros(2), 0.036, 2.0,
                                        0.03, 0.5, 6, surfaces, valid)
    assert status == 1
    args = (commands, grid, velocities, np.zeros(2), 0.036, 0.5, scene, config)
    got = safety.filter_commands(*args)
    with kernels.reference():
        _same(got, safety.filter_commands(*args), "grid")


def test_the_safety_filter_kernel_stops_a_robot_short_of_a_wall_as_computed_by_hand():
    """A follower 0.2 m from the arena's east wall commanding 0.5 m/s east: the barrier
    allows α (gap − r − margin) = 2 (0.2 − 0.036 − 0.03) = 0.268 m/s towards it."""
    from boids_env.world import safety

    scene = _scene("arena")
    positions = np.array([[0.0, 0.0], [4.8, 0.0]])
    out = safety.filter_commands(np.array([[0.5, 0.1]]), positions, np.zeros((2, 2)),
                                 np.zeros(2), 0.036, 0.5, scene,
                                 safety.SafetyConfig(safety_filter=True))
    np.testing.assert_allclose(out, [[0.268, 0.1]], rtol=1e-12)


@pytest.mark.parametrize("name", ["lab", "small_room", "pillars", "arena", "corridor"])
def test_scene_query_kernels_match_the_reference(name):
    scene = _scene(name)
    rng = np.random.default_rng(11)
    x0, y0, x1, y1 = scene.bounds
    points = rng.uniform([x0 - 0.5, y0 - 0.5], [x1 + 0.5, y1 + 0.5], (400, 2))
    near = np.vstack([_crowd_near_walls(rng, scene, 20) for _ in range(10)])
    points = np.vstack([points, near])
    for slots, reach in ((1, 0.5), (2, 1.0), (4, 0.5), (3, 3.0)):
        got = scene.nearest_points(points, slots, reach)
        with kernels.reference():
            want = scene.nearest_points(points, slots, reach)
        _same(got[0], want[0], f"offsets {slots} {reach}")
        _same(got[1], want[1], f"valid {slots} {reach}")
    got = scene.clearance(points)
    with kernels.reference():
        _same(got, scene.clearance(points), "clearance")
    for margins in ((0.036, 0.005), (0.25,), (0.5, 0.1)):
        got = scene.within(points, *margins)
        with kernels.reference():
            want = scene.within(points, *margins)
        _same(got, want, f"within {margins}")
    if scene.grid is not None:
        got = scene.grid.occupied(points)
        with kernels.reference():
            _same(got, scene.grid.occupied(points), "occupied")


def test_wall_flags_of_a_map_scene_run_in_one_compiled_call(monkeypatch):
    from boids_env import _compiled

    scene = _scene("lab")  # a map's cells and capsules, no box
    calls = []
    within = _compiled.within
    monkeypatch.setattr(_compiled, "within", lambda *a: calls.append(1) or within(*a))
    rng = np.random.default_rng(12)
    x0, y0, x1, y1 = scene.bounds
    points = np.vstack([rng.uniform([x0 - 0.5, y0 - 0.5], [x1 + 0.5, y1 + 0.5], (400, 2))]
                       + [_crowd_near_walls(rng, scene, 20) for _ in range(10)])
    for margins in ((0.036, 0.001), (0.25,), (0.5, 0.1), ()):
        got = scene.within(points, *margins)
        with kernels.reference():
            want = scene.within(points, *margins)
        _same(got, want, f"within {margins}")
        assert 0 < got.sum() < len(points) or not margins, margins  # both answers occur
    assert len(calls) == 4, "the one-call wall flags were not used"


def test_nearest_points_kernel_on_hand_computed_walls():
    """The arena's east wall 0.1 m from (4.9, 0), the north wall 0.3 m from (4.9, 4.7): one
    slot each within 0.5 m, a later slot only for a direction more than 45° away."""
    scene = _scene("arena")
    offsets, valid = scene.nearest_points(np.array([[4.9, 0.0], [4.9, 4.7]]), 2, 0.5)
    np.testing.assert_allclose(offsets, [[[0.1, 0.0], [0.0, 0.0]],
                                         [[0.1, 0.0], [0.0, 0.3]]], atol=1e-12)
    assert valid.tolist() == [[True, False], [True, True]]


def test_actor_kernel_matches_the_numpy_actor_on_any_input():
    """The shipped actors and a ReLU one: rows of zeros, negative zeros, tiny and huge
    values, no rows at all; every action the same bits."""
    from boids_env.policies.mlp_actor import MLPActor
    from boids_env.policies.registry import load_policy

    rng = np.random.default_rng(5)
    relu = MLPActor([rng.normal(0, 0.3, (16, 9)), rng.normal(0, 0.3, (2, 16))],
                    [rng.normal(0, 0.1, 16), rng.normal(0, 0.1, 2)], "relu", -1.0, 1.0)
    actors = [load_policy(spec) for spec in ("learned", "learned-scenes")] + [relu]
    for actor in actors:
        for trial in range(60):
            f = int(rng.integers(0, 40))
            scale = rng.choice([1e-30, 1e-3, 1.0, 100.0, 1e30])
            x = (rng.normal(size=(f, actor.obs_size)) * scale).astype(np.float32)
            if f and trial % 3 == 0:
                x[0] = 0.0
                x[:, ::4] = -0.0
            got = actor.act_batch(x)
            with kernels.reference():
                want = actor.act_batch(x)
            _same(got, want, f"{actor.name} trial {trial}")


def test_exact_product_and_tanh_kernels_give_the_numpy_bits_inside_the_actor():
    """The hidden layers' float64 values themselves (an action's float32 rounding would hide
    a last-bit difference there)."""
    from boids_env.policies import _compiled, exact

    rng = np.random.default_rng(9)
    for inputs, outputs, rows in ((99, 128, 12), (128, 128, 61), (7, 2, 1), (30, 64, 0)):
        layer = exact.ExactLinear(rng.normal(0, 0.2, (inputs, outputs)),
                                  rng.normal(0, 0.1, outputs))
        x = rng.normal(0, 1, (rows, inputs)) * rng.choice([1e-200, 1e-5, 1.0, 1e200], (rows, 1))
        if rows:
            x[0] = 0.0
        slices, exponents = _compiled.exact_slices(x)
        got = _compiled.exact_combine(layer.products(slices), exponents, layer.column_scale,
                                      layer.bias, 0, exact.INV_LN2, exact.LN2, exact.TANH_ONE)
        _same(got, layer(x), f"layer {inputs}x{outputs}")
        with_tanh = _compiled.exact_combine(layer.products(slices), exponents,
                                            layer.column_scale, layer.bias, 1, exact.INV_LN2,
                                            exact.LN2, exact.TANH_ONE)
        _same(with_tanh, exact.tanh(layer(x)), f"layer {inputs}x{outputs} tanh")
        # a hidden layer's output straight into the next layer's slices (one call)
        fused = _compiled.exact_combine_slices(layer.products(slices), exponents,
                                               layer.column_scale, layer.bias, 1,
                                               exact.INV_LN2, exact.LN2, exact.TANH_ONE)
        for part, want in zip(fused, _compiled.exact_slices(exact.tanh(layer(x))), strict=True):
            _same(part, want, f"layer {inputs}x{outputs} next slices")
    y = np.concatenate([rng.normal(0, s, 2000) for s in (1e-8, 0.01, 0.5, 3.0, 30.0)])
    y = np.concatenate([y, [0.0, -0.0, 20.0, -20.0, 1e300]]).reshape(-1, 5)
    want = exact.tanh(y)
    _compiled._exact_tanh(y, exact.INV_LN2, exact.LN2, exact.TANH_ONE)
    _same(y, want, "tanh")


@pytest.mark.parametrize("name", ["lab", "doorway", "floorplan:3"])
def test_route_sensing_kernel_matches_the_reference(name):
    """Followers anywhere (in walls, off the map, on the leader), leaders anywhere free."""
    from boids_env.world.route import route_grid, sense_route

    scene = _scene(name)
    grid = route_grid(scene, 0.036)
    rng = np.random.default_rng(13)
    x0, y0, x1, y1 = scene.bounds
    for trial in range(40):
        leader = grid.centres[rng.integers(len(grid.centres))]
        points = rng.uniform([x0 - 0.3, y0 - 0.3], [x1 + 0.3, y1 + 0.3], (30, 2))
        points[0] = leader
        positions = np.vstack([leader, points])
        got = sense_route(grid, positions)
        with kernels.reference():
            want = sense_route(grid, positions)
        for g, w, what in zip(got, want, ("direction", "length", "valid"), strict=True):
            _same(g, w, f"trial {trial} {what}")


@pytest.mark.parametrize("name", ["lab", "pillars", "doorway", "floorplan:3", "corridor"])
def test_blocked_segments_kernel_matches_the_reference(name):
    """Sight lines anywhere, some ending on a capsule's surface or axis, some of no length,
    at clearance 0 (line of sight) and 0.1 m (path checks)."""
    from boids_env.metrics import line_of_sight

    scene = _scene(name)
    rng = np.random.default_rng(17)
    x0, y0, x1, y1 = scene.bounds
    starts = rng.uniform([x0, y0], [x1, y1], (600, 2))
    ends = rng.uniform([x0, y0], [x1, y1], (600, 2))
    ends[:50] = starts[:50]
    if len(scene.a):
        ends[50:100] = scene.a[rng.integers(len(scene.a), size=50)]
    for clearance in (0.0, 0.1):
        for grid in (True, False):
            got = scene.blocked(starts, ends, clearance, use_grid=grid)
            with kernels.reference():
                want = scene.blocked(starts, ends, clearance, use_grid=grid)
            _same(got[0], want[0], f"blocked {clearance} {grid}")
            _same(got[1], want[1], f"which {clearance} {grid}")
    positions = rng.uniform([x0, y0], [x1, y1], (40, 9, 2))
    got = line_of_sight(positions, scene)
    with kernels.reference():
        _same(got, line_of_sight(positions, scene), "line of sight")


@pytest.mark.parametrize("name", ["lab", "small_room", "pillars", "arena", "floorplan:3"])
def test_raycast_kernel_matches_the_reference(name):
    """Rays from anywhere (inside walls and pillars, off the map) in every direction, the
    axes' included (a zero component)."""
    scene = _scene(name)
    rng = np.random.default_rng(19)
    x0, y0, x1, y1 = scene.bounds
    origins = rng.uniform([x0 - 0.2, y0 - 0.2], [x1 + 0.2, y1 + 0.2], (300, 2))
    origins = np.vstack([origins, _crowd_near_walls(rng, scene, 60)])
    angles = np.concatenate([rng.uniform(0, 2 * np.pi, 12), np.arange(4) * np.pi / 2])
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    directions[12:] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
    directions = np.broadcast_to(directions, (len(origins), 16, 2))
    for max_range in (0.5, 3.0):
        got = scene.raycast(origins, directions, max_range)
        with kernels.reference():
            want = scene.raycast(origins, directions, max_range)
        _same(got, want, f"ranges {max_range}")
