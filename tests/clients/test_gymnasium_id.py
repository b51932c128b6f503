"""``import boids_env`` registers ``boids_env/SingleFollower-v0``: ``gym.make`` and
``gym.make_vec`` build :class:`SingleFollowerEnv` with any config."""

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np

import boids_env  # noqa: F401  (registers the id)
from boids_env.single import SingleFollowerEnv

CONFIG = {"robots": 4, "scene": "small_room", "lidar_rays": 8, "max_cycles": 30}


def _rollout(env, seed, steps=10):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, reward, *_ = env.step(np.array([0.2, -0.1]))
        out += [obs, np.array([reward])]
    return np.concatenate(out)


def test_make_builds_the_single_follower_env_with_a_non_default_config():
    env = gym.make("boids_env/SingleFollower-v0", agent="follower_2", **CONFIG)
    assert isinstance(env.unwrapped, SingleFollowerEnv)
    assert env.unwrapped.agent == "follower_2"
    direct = SingleFollowerEnv(agent="follower_2", **CONFIG)
    assert env.observation_space == direct.observation_space
    np.testing.assert_array_equal(_rollout(env, 3), _rollout(direct, 3))


def test_make_vec_gives_copy_i_the_seed_plus_i():
    vec = gym.make_vec("boids_env/SingleFollower-v0", num_envs=3, vectorization_mode="sync",
                       **CONFIG)
    obs, _ = vec.reset(seed=7)
    assert obs.shape == (3, *SingleFollowerEnv(**CONFIG).observation_space.shape)
    for i in range(3):
        first, _ = SingleFollowerEnv(**CONFIG).reset(seed=7 + i)
        np.testing.assert_array_equal(obs[i], first)
    assert not np.array_equal(obs[0], obs[1])  # the start jitter differs per seed
    obs, rewards, *_ = vec.step(np.zeros((3, 2)))
    assert obs.shape[0] == rewards.shape[0] == 3


def test_the_id_is_registered_without_importing_the_env():
    code = ("import sys, boids_env, gymnasium; "
            "print('boids_env/SingleFollower-v0' in gymnasium.registry, "
            "'pymunk' in sys.modules, 'boids_env.single' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "False", "False"]


def test_the_package_imports_no_gymnasium_and_registers_whichever_comes_first():
    """The ``boids`` command imports the package before it can answer a Ctrl-C, so the
    package must not import gymnasium (numpy) itself; the id is there in either order."""
    probe = ("'gymnasium' in sys.modules, "
             "'boids_env/SingleFollower-v0' in gymnasium.registry")
    for imports in ("import sys, boids_env; bare = 'gymnasium' in sys.modules; "
                    "import gymnasium; print(bare, " + probe + ")",
                    # a probe that imports nothing (as boids_env.extras checks the extras)
                    "import sys, importlib.util, boids_env; importlib.util.find_spec("
                    "'gymnasium'); bare = 'gymnasium' in sys.modules; import gymnasium; "
                    "print(bare, " + probe + ")",
                    "import sys, gymnasium, boids_env; print(False, " + probe + ")"):
        out = subprocess.run([sys.executable, "-c", imports], capture_output=True, text=True,
                             check=True)
        assert out.stdout.split() == ["False", "True", "True"], (imports, out.stdout)


def test_check_env_with_its_defaults_passes_headless():
    """``check_env`` opens every declared render mode, ``human`` included; with no display
    (and no ``SDL_VIDEODRIVER``) the window is drawn off-screen with a warning, as CartPole's."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("SDL_VIDEODRIVER", "DISPLAY", "WAYLAND_DISPLAY")}
    code = ("import gymnasium as gym, boids_env\n"
            "from gymnasium.utils.env_checker import check_env\n"
            "check_env(gym.make('boids_env/SingleFollower-v0'))\nprint('passed')\n")
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", code], env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "passed", out.stderr[-2000:]
