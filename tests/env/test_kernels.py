"""The compiled kernels (boids_env.kernels, boids_env.policies.kernels) give the numpy
reference's bits.

One table-driven test walks both kernel tables (``KERNELS``): every kernel defined is listed,
every twin is importable, and every kernel's caller gives the same bits with the kernel as
with its numpy code (inside ``kernels.reference()``) on random inputs and on inputs that
stress its edge cases (exact ties, zero distances, a neighbour exactly at the horizon, values
at the bounds, signed zeros, overflowing commands), the kernel counted so that it is known to
have run. Besides: whole episodes stepped side by side, one env on the kernels and one on the
reference, every observation, reward, reward term and count compared bit for bit; and a few
results computed by hand."""

import importlib
import pkgutil

import numpy as np
import pytest
from kernel_cases import CASES, same_bits, scene_named

from boids_env import kernels, parallel_env
from boids_env.environment import REWARD_INFO_KEYS
from boids_env.policies import ReynoldsPolicy
from boids_env.policies import kernels as policy_kernels


@pytest.fixture(autouse=True)
def _kernels_loaded():
    """The kernels at once (a process loads them on its own only after LOAD_AFTER calls)."""
    assert kernels.load() is not None, "numba is a core dependency: the kernels must load"


def test_reference_turns_the_kernels_off_inside_its_block():
    assert kernels.compiled() is not None and policy_kernels.compiled() is not None
    with kernels.reference():
        assert kernels.compiled() is None and policy_kernels.compiled() is None
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
    same_bits(obs, ref, "reset observations")
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
                same_bits(act, learned.act_batch(obs), f"step {step} actions")
        else:
            act = (reynolds.act_batch(obs) if policy == "reynolds"
                   else rng.uniform(-limit, limit, (len(obs), 2)))
        res = fast.step_arrays(act)
        with kernels.reference():
            want = slow.step_arrays(act)
        same_bits(res.observations, want.observations, f"step {step} observations")
        same_bits(res.rewards, want.rewards, f"step {step} rewards")
        for row, key in enumerate(REWARD_INFO_KEYS):
            same_bits(res.terms[row], want.terms[row], f"step {step} {key}")
        assert res.truncated == want.truncated, step
        obs = res.observations
        step += 1
    assert step == (cycles or 746) or (learned is not None and step > 400), step
    assert fast.episode_metrics() == slow.episode_metrics()
    same_bits(fast.state(), slow.state(), "final state")


@pytest.mark.parametrize("fields", [
    {"robots": 19},  # fused: the infos are copies of 8 dicts picked by the flags' bits
    {"robots": 7, "frame": "leader", "relative_actions": True},
    {"robots": 7, "obs_noise": 0.02},  # not fused: the bits of Rewards.terms's kernel
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
            same_bits([infos[a][key] for a in agents], want.terms[row], key)
        same_bits([rewards[a] for a in agents], want.rewards, "rewards")
        assert len({id(infos[a]) for a in agents}) == len(agents)  # a dict each
        assert all(list(infos[a]) == list(REWARD_INFO_KEYS) for a in agents)


# ------------------------------------------------------------------ the tables, walked
TABLES = {"boids_env._compiled": kernels.KERNELS,
          "boids_env.policies._compiled": policy_kernels.KERNELS}
PAIRS = sorted((package, name) for package, table in TABLES.items() for name in table)


def _handle(package):
    """The module callers reach the package's kernels through."""
    return kernels.load() if package == "boids_env._compiled" else policy_kernels.compiled()


def _defined(package):
    """Every public kernel of a package, by its table name (``module.name`` in a package of
    modules, ``name`` in a single module)."""
    from numba.core.dispatcher import Dispatcher

    root = importlib.import_module(package)
    modules = ([importlib.import_module(f"{package}.{m.name}")
                for m in pkgutil.iter_modules(root.__path__)]
               if hasattr(root, "__path__") else [root])
    found = {}
    for module in modules:
        prefix = module.__name__[len(package) + 1:]
        for name, obj in vars(module).items():
            if (isinstance(obj, Dispatcher) and not name.startswith("_")
                    and obj.py_func.__module__ == module.__name__):
                found[f"{prefix}.{name}" if prefix else name] = obj
    return found


def test_the_tables_pair_every_kernel_with_importable_twins():
    for package, table in TABLES.items():
        defined = _defined(package)
        assert sorted(defined) == sorted(table), f"{package}: kernels and table differ"
        handle = _handle(package)
        for name, twin in table.items():
            assert getattr(handle, name.rpartition(".")[2]) is defined[name], (
                f"{name}: not what callers reach on the handle")
            for path in (twin.caller, *twin.references):
                assert callable(kernels.resolve(path)), path
            assert twin.references or twin.why, f"{name}: no twin and no reason"
            assert name in CASES, f"{name}: no case in this test"


@pytest.mark.parametrize("package, name", PAIRS, ids=[name for _, name in PAIRS])
def test_every_kernel_gives_its_twins_bits(package, name, monkeypatch):
    """The kernel's caller with the kernel (counted) and inside ``kernels.reference()`` (its
    numpy code) on the case's inputs: the same bits."""
    handle = _handle(package)
    attr = name.rpartition(".")[2]
    kernel = getattr(handle, attr)
    calls = []

    def counted(*args):
        calls.append(1)
        return kernel(*args)

    monkeypatch.setattr(handle, attr, counted)
    compared = 0
    for what, thunk in CASES[name](kernel, kernels.resolve(TABLES[package][name].caller)):
        got = thunk()
        with kernels.reference():
            want = thunk()
        same_bits(got, want, f"{name}: {what}")
        compared += 1
    assert compared, f"{name}: no input compared"
    assert calls, f"{name}: the kernel never ran, so the case compared numpy with itself"


# ------------------------------------------------------------- results by hand
def test_safety_and_gap_terms_kernel_on_hand_computed_terms():
    """Followers 0.1 m (in proximity) and 3 m (2 m beyond 1 m) from the leader."""
    got = np.zeros((9, 2))
    kernels.load().safety_gap_terms(np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 3.0]]),
                                    np.array([False, True]), np.array([-1.0, -2.0, -4.0]),
                                    0.15, 0.073, True, -0.5, 1.0, True, got)
    assert got[3:7].tolist() == [[-1.0, -0.0], [-0.0, -0.0], [-0.0, -4.0], [-0.0, -1.0]]


def test_the_safety_filter_kernel_stops_a_robot_short_of_a_wall_as_computed_by_hand():
    """A follower 0.2 m from the arena's east wall commanding 0.5 m/s east: the barrier
    allows α (gap − r − margin) = 2 (0.2 − 0.036 − 0.03) = 0.268 m/s towards it."""
    from boids_env.world import safety

    scene = scene_named("arena")
    positions = np.array([[0.0, 0.0], [4.8, 0.0]])
    out = safety.filter_commands(np.array([[0.5, 0.1]]), positions, np.zeros((2, 2)),
                                 np.zeros(2), 0.036, 0.5, scene,
                                 safety.SafetyConfig(safety_filter=True))
    np.testing.assert_allclose(out, [[0.268, 0.1]], rtol=1e-12)


def test_nearest_points_kernel_on_hand_computed_walls():
    """The arena's east wall 0.1 m from (4.9, 0), the north wall 0.3 m from (4.9, 4.7): one
    slot each within 0.5 m, a later slot only for a direction more than 45° away."""
    scene = scene_named("arena")
    offsets, valid = scene.nearest_points(np.array([[4.9, 0.0], [4.9, 4.7]]), 2, 0.5)
    np.testing.assert_allclose(offsets, [[[0.1, 0.0], [0.0, 0.0]],
                                         [[0.1, 0.0], [0.0, 0.3]]], atol=1e-12)
    assert valid.tolist() == [[True, False], [True, True]]


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



