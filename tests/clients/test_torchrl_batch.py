"""The native batched TorchRL env (``boids_env.integrations.torchrl``): N worlds per call,
TorchRL's own spec check, each world's results those of its env stepped alone, seeding,
partial resets, frames (the ``clients`` extra; CI installs it)."""

import numpy as np
import pytest

pytest.importorskip("torchrl")

import torch
from torchrl.envs.utils import check_env_specs

from boids_env import parallel_env
from boids_env.integrations.torchrl import BoidsTorchRLEnv

FIELDS = {"robots": 4, "max_cycles": 5}


def test_torchrls_spec_check_passes_and_the_shapes_follow_the_spaces():
    env = BoidsTorchRLEnv(3, seed=0, **FIELDS)
    check_env_specs(env, seed=None)
    plain = parallel_env(**FIELDS)
    agent = plain.possible_agents[0]
    obs_box, act_box = plain.observation_space(agent), plain.action_space(agent)
    assert env.group_map == {"agents": plain.possible_agents}
    assert env.batch_size == (3,)
    obs = env.observation_spec["agents", "observation"]
    assert obs.shape == (3, 3, *obs_box.shape)
    np.testing.assert_array_equal(obs.space.low[2, 1].numpy(), obs_box.low)
    action = env.action_spec["agents", "action"]
    assert action.shape == (3, 3, 2)
    np.testing.assert_array_equal(action.space.high[0, 0].numpy(), act_box.high)
    assert env.reward_spec["agents", "reward"].shape == (3, 3, 1)
    assert env.done_spec["truncated"].shape == (3, 1)


def test_each_world_steps_as_its_env_alone_across_the_auto_reset():
    worlds, steps = 3, 8  # max_cycles 5: every world ends at step 5 and is reset
    env = BoidsTorchRLEnv(worlds, seed=10, **FIELDS)
    plains = [parallel_env(**FIELDS) for _ in range(worlds)]
    expected = [p.reset_arrays(seed=10 + k) for k, p in enumerate(plains)]
    td = env.reset()
    expected = [p.reset_arrays() for p in plains]  # the reset goes on with each stream
    rng = np.random.default_rng(0)
    for step in range(steps):
        np.testing.assert_array_equal(td["agents", "observation"].numpy(), np.stack(expected),
                                      err_msg=f"step {step}")
        actions = rng.uniform(-0.4, 0.4, (worlds, 3, 2)).astype(np.float32)
        td["agents", "action"] = torch.from_numpy(actions)
        out, td = env.step_and_maybe_reset(td)
        for k, plain in enumerate(plains):
            result = plain.step_arrays(actions[k])
            np.testing.assert_array_equal(out["next", "agents", "observation"][k].numpy(),
                                          result.observations, err_msg=f"step {step} world {k}")
            np.testing.assert_array_equal(out["next", "agents", "reward"][k, :, 0].numpy(),
                                          result.rewards.astype(np.float32),
                                          err_msg=f"step {step} world {k}")
            np.testing.assert_array_equal(
                out["next", "agents", "info", "reward_separation"][k].numpy(),
                result.terms[0].astype(np.float32), err_msg=f"step {step} world {k}")
            assert bool(out["next", "truncated"][k]) == result.truncated, (step, k)
            assert not bool(out["next", "terminated"][k]), (step, k)
            expected[k] = plain.reset_arrays() if result.truncated else result.observations
    assert env.step_limit == 5


def test_a_partial_reset_resets_the_masked_worlds_only():
    env = BoidsTorchRLEnv(3, seed=0, **FIELDS)
    td = env.reset()
    td["agents", "action"] = torch.full((3, 3, 2), 0.3)
    nxt = env.step(td)["next"]
    after = nxt["agents", "observation"].clone()
    nxt["_reset"] = torch.tensor([[False], [True], [False]])  # as a collector sends it
    out = env.reset(nxt)
    obs = out["agents", "observation"]
    np.testing.assert_array_equal(obs[0].numpy(), after[0].numpy())
    np.testing.assert_array_equal(obs[2].numpy(), after[2].numpy())
    assert not np.array_equal(obs[1].numpy(), after[1].numpy())
    assert env.envs[1].episode.world.steps == 0 and env.envs[0].episode.world.steps == 1


def test_set_seed_makes_the_worlds_reproducible_and_different():
    a, b = BoidsTorchRLEnv(3, **FIELDS), BoidsTorchRLEnv(3, **FIELDS)
    assert a.set_seed(7) == b.set_seed(7) != 7
    first, second = a.reset()["agents", "observation"], b.reset()["agents", "observation"]
    np.testing.assert_array_equal(first.numpy(), second.numpy())
    assert not np.array_equal(first[0].numpy(), first[1].numpy())


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"num_envs": 0}, "num_envs"), ({"num_envs": 2.0}, "num_envs"),
    ({"render_mode": "human"}, "render_mode"), ({"group": ""}, "group"),
    ({"seed": -1}, "seed"), ({"robots": 1}, "robots")])
def test_bad_arguments_are_refused_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        BoidsTorchRLEnv(**{"num_envs": 2, **kwargs})


def test_rgb_array_frames_of_any_world(monkeypatch):
    pytest.importorskip("pygame")
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = BoidsTorchRLEnv(2, seed=0, render_mode="rgb_array", **FIELDS)
    frame = env.render(mode="rgb_array", env_index=1)
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    with pytest.raises(ValueError, match="env_index"):
        env.render(env_index=2)
    with pytest.raises(RuntimeError, match="render_mode"):
        BoidsTorchRLEnv(1, **FIELDS).render()
