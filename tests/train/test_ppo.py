"""FlockPPO (boids train's learner) against stock Stable-Baselines3 PPO: the same model, bit for
bit, from a leaner rollout collection."""

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC

from boids_env.train.ppo import FlockPPO, lean_forward, lean_forward_applies, learner_class
from boids_env.train.vec_env import CopySpec, FlockVecEnv

# episodes of 30 steps in rollouts of 40: every rollout holds a truncation, whose terminal
# observation's value SB3 adds to the reward
SPECS = [CopySpec(4, (0.5, 0.6), env_fields={"max_cycles": 30}),
         CopySpec(5, (0.55,), env_fields={"max_cycles": 30})]


def _trained(cls, rollouts=3, **kwargs):
    torch.set_num_threads(1)
    venv = FlockVecEnv(SPECS, seed=3)
    model = cls("MlpPolicy", venv, n_steps=40, batch_size=70, n_epochs=2, seed=1, **kwargs)
    initial = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.learn(40 * venv.num_envs * rollouts)
    venv.close()
    return model, initial


def _same_weights(a, b):
    sa, sb = a.policy.state_dict(), b.policy.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


@pytest.mark.parametrize(("split", "kwargs"), [
    (True, {}), (False, {}),
    (True, {"clip_range_vf": 0.3, "normalize_advantage": False, "ent_coef": 0.01}),
])
def test_flock_ppo_trains_the_same_model_as_stock_ppo_bit_for_bit(split, kwargs, monkeypatch):
    """Its rollouts (lean forward) and its update, the critic's half in a second thread or
    not (a second core and one torch thread decide, so both are forced here)."""
    stock, initial = _trained(PPO, **kwargs)
    monkeypatch.setattr(FlockPPO, "_splits_update", lambda self: split)
    ours, _ = _trained(FlockPPO, **kwargs)
    assert lean_forward_applies(ours.policy, ours.action_space)
    moved = [k for k, v in stock.policy.state_dict().items() if not torch.equal(v, initial[k])]
    assert "action_net.weight" in moved and "value_net.weight" in moved  # it did train
    assert _same_weights(stock, ours)
    # the last rollouts are the same too (the buffer the last update read)
    for name in ("observations", "actions", "rewards", "values", "log_probs", "advantages"):
        assert np.array_equal(getattr(stock.rollout_buffer, name),
                              getattr(ours.rollout_buffer, name)), name
    assert stock.num_timesteps == ours.num_timesteps


def test_a_policy_outside_the_lean_path_is_collected_and_updated_by_sb3_itself():
    stock, _ = _trained(PPO, rollouts=1, use_sde=True)
    ours, _ = _trained(FlockPPO, rollouts=1, use_sde=True)
    assert not lean_forward_applies(ours.policy, ours.action_space)
    assert not ours._splits_update()
    assert _same_weights(stock, ours)


def test_the_update_splits_only_with_one_torch_thread_and_no_kl_stop(monkeypatch):
    import boids_env.train.ppo as ppo

    model, _ = _trained(FlockPPO, rollouts=1)
    monkeypatch.setattr(ppo, "available_cores", lambda: 2)
    assert model._splits_update()
    monkeypatch.setattr(ppo, "available_cores", lambda: 1)
    assert not model._splits_update()
    monkeypatch.setattr(ppo, "available_cores", lambda: 2)
    model.target_kl = 0.01
    assert not model._splits_update()
    model.target_kl = None
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        assert not model._splits_update()
    finally:
        torch.set_num_threads(before)


def test_the_split_update_logs_what_sb3s_update_logs(monkeypatch):
    logged = {}
    for split in (False, True):
        monkeypatch.setattr(FlockPPO, "_splits_update", lambda self, s=split: s)
        model, _ = _trained(FlockPPO, rollouts=1)
        logged[split] = dict(model.logger.name_to_value)
    assert logged[True].keys() == logged[False].keys()
    assert {"train/value_loss", "train/loss", "train/approx_kl", "train/std"} <= logged[True].keys()
    assert logged[True] == logged[False]


@pytest.mark.parametrize("policy_kwargs", [
    {"net_arch": [64, 64]},
    {"net_arch": {"pi": [32], "vf": [16, 16]}, "activation_fn": torch.nn.ReLU},
    {"net_arch": [], "log_std_init": -2.0},
])
def test_lean_forward_gives_the_policys_own_forward_bits_and_draws(policy_kwargs):
    venv = FlockVecEnv(SPECS, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=7, seed=0,
                policy_kwargs=policy_kwargs)
    obs = np.random.default_rng(4).normal(0, 2, (venv.num_envs, venv.observation_space.shape[0]))
    obs = obs.astype(np.float32)
    venv.close()
    assert lean_forward_applies(model.policy, model.action_space)
    with torch.no_grad():
        torch.manual_seed(11)
        expected = model.policy(torch.as_tensor(obs))
        torch.manual_seed(11)
        got = lean_forward(model.policy, obs)
    for e, g in zip(expected, got, strict=True):
        assert e.shape == g.shape and torch.equal(e, g)


def test_a_flock_ppo_zip_is_an_ordinary_sb3_ppo_zip(tmp_path):
    ours, _ = _trained(FlockPPO, rollouts=1)
    ours.save(tmp_path / "m.zip")
    loaded = PPO.load(tmp_path / "m.zip", device="cpu")
    assert type(loaded) is PPO and _same_weights(ours, loaded)


def test_learner_class_is_flock_ppo_for_ppo_only():
    assert learner_class("ppo") is FlockPPO and learner_class("PPO") is FlockPPO
    assert learner_class("sac") is SAC
    with pytest.raises(ValueError, match="algorithm must be one of"):
        learner_class("dqn")
