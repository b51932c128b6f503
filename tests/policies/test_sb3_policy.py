"""The shipped learned policy acts as SB3's own predict: through torch exactly, without an
optimizer; through its stored numpy actor (what ``load_policy`` picks) up to float32 rounding,
without importing torch at all."""

import subprocess
import sys
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from boids_env.policies.mlp_actor import ACTOR_ENTRY, MLPActor
from boids_env.policies.registry import LEARNED_MODEL, STUDY_MODEL, load_policy
from boids_env.policies.sb3_policy import SB3Policy, actor_of, load_model_policy, write_meta
from boids_env.policies.sb3_zip import UntrustedModelError


@pytest.mark.parametrize("path", [LEARNED_MODEL, STUDY_MODEL], ids=["learned", "study"])
def test_actions_equal_sb3_predict_of_the_normally_loaded_model(path):
    from stable_baselines3 import PPO

    ours = SB3Policy.load(path, trust=True)
    reference = PPO.load(path, device="cpu")  # with its Adam optimizer, as SB3 loads it
    obs = np.random.default_rng(0).normal(0, 1, (12, ours.obs_size)).astype(np.float32)
    expected, _ = reference.predict(obs, deterministic=True)
    high = reference.action_space.high
    assert np.array_equal(ours.act_batch(obs), np.clip(expected, -high, high).astype(np.float32))


@pytest.mark.parametrize("path", [LEARNED_MODEL, STUDY_MODEL], ids=["learned", "study"])
def test_the_numpy_actor_acts_as_sb3_predict_up_to_float32_rounding(path):
    from stable_baselines3 import PPO

    actor = load_model_policy(path)
    assert isinstance(actor, MLPActor)
    reference = PPO.load(path, device="cpu")
    # observations as the env makes them and far outside them (saturated tanh units)
    rng = np.random.default_rng(1)
    for scale in (0.5, 1.0, 5.0):
        obs = rng.normal(0, scale, (37, actor.obs_size)).astype(np.float32)
        expected, _ = reference.predict(obs, deterministic=True)
        high = reference.action_space.high
        np.testing.assert_allclose(actor.act_batch(obs), np.clip(expected, -high, high),
                                   rtol=0, atol=2e-6)
    assert actor.env_fields == SB3Policy.load(path, trust=True).env_fields


def test_load_policy_acts_without_importing_torch():
    code = ("import sys; from boids_env.policies.registry import load_policy; "
            "p = load_policy('learned'); import numpy as np; "
            "a = p.act_batch(np.ones((3, p.obs_size), np.float32)); "
            "print(type(p).__name__, 'torch' in sys.modules, "
            "'stable_baselines3' in sys.modules, a.shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300).stdout.strip().split(maxsplit=3)
    assert out == ["MLPActor", "False", "False", "(3, 2)"]


def test_a_model_numpy_cannot_run_keeps_acting_through_torch(tmp_path):
    from stable_baselines3 import PPO
    from torch import nn

    from boids_env.train.vec_env import FlockVecEnv

    env = FlockVecEnv(1)
    elu = PPO("MlpPolicy", env, n_steps=8, batch_size=8, policy_kwargs={
        "activation_fn": nn.ELU, "net_arch": [8]}, device="cpu")
    assert actor_of(elu) is None
    path = tmp_path / "elu.zip"
    path.write_bytes(LEARNED_MODEL.read_bytes())  # holds a numpy actor: a stale one is dropped
    elu.save(path)
    write_meta(path, {"algorithm": "ppo"}, elu)
    with zipfile.ZipFile(path) as zf:
        assert ACTOR_ENTRY not in zf.namelist()
    # its activation is a class, which SB3 keeps only as a pickle: trusted files only
    with pytest.raises(UntrustedModelError, match="--trust-model"):
        load_model_policy(path)
    policy = load_model_policy(path, trust=True)
    assert isinstance(policy, SB3Policy)
    tanh = PPO("MlpPolicy", env, n_steps=8, batch_size=8, policy_kwargs={"net_arch": [8]},
               device="cpu")
    write_meta(path, {"algorithm": "ppo"}, tanh)  # (the zip's weights do not matter here)
    assert isinstance(load_model_policy(path), MLPActor)


def test_a_damaged_numpy_actor_is_a_clear_error(tmp_path):
    path = tmp_path / "model.zip"
    with zipfile.ZipFile(LEARNED_MODEL) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            dst.writestr(name, data[:50] if name == ACTOR_ENTRY else data)
    with pytest.raises(ValueError, match=f"model.zip.*{ACTOR_ENTRY}"):
        load_policy(str(path))


def test_the_numpy_actor_round_trips_and_refuses_layers_that_do_not_chain():
    rng = np.random.default_rng(0)
    w = [rng.normal(size=(4, 3)).astype(np.float32), rng.normal(size=(2, 4)).astype(np.float32)]
    b = [rng.normal(size=4).astype(np.float32), rng.normal(size=2).astype(np.float32)]
    actor = MLPActor(w, b, "relu", [-1, -1], [1, 1])
    back = MLPActor.from_bytes(actor.to_bytes())
    obs = rng.normal(size=(5, 3)).astype(np.float32)
    expected = np.clip(np.maximum(obs @ w[0].T + b[0], 0) @ w[1].T + b[1], -1, 1)
    np.testing.assert_allclose(back.act_batch(obs), expected, rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="layer 1"):
        MLPActor([w[0], w[0]], [b[0], b[0]], "tanh", [-1], [1])
    with pytest.raises(ValueError, match="activation"):
        MLPActor(w, b, "gelu", [-1], [1])
    with pytest.raises(ValueError, match="size 3"):
        actor.act_batch(np.zeros((2, 4), np.float32))


def test_loading_to_act_builds_no_optimizer():
    code = ("import sys; from boids_env.policies.sb3_policy import SB3Policy; "
            "from boids_env.policies.registry import LEARNED_MODEL; "
            "p = SB3Policy.load(LEARNED_MODEL, trust=True); import numpy as np; "
            "p.act_batch(np.zeros((3, p.obs_size), np.float32)); "
            "print('torch._dynamo' in sys.modules, type(p.model.policy.optimizer).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300).stdout.split()
    assert out == ["False", "_NoOptimizer"]


def test_the_learned_policy_is_deterministic_per_seed():
    from boids_env import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode

    runs = []
    for _ in range(2):
        policy = load_policy("learned")  # a fresh load each time
        env = BoidsEnv(**env_fields_for(policy, {"max_cycles": 150, "obs_noise": 0.02}))
        runs.append(run_episode(env, policy, seed=5))
    a, b = (r.recording for r in runs)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.commanded, b.commanded)
    assert runs[0].metrics == runs[1].metrics
    assert np.abs(a.commanded[:, 1:]).max() > 0.1, "the followers moved"


def test_the_shipped_models_need_no_extra_and_a_foreign_zip_names_the_train_extra(
        tmp_path, monkeypatch):
    from boids_env.eval.flags import policy_extras

    assert policy_extras(["learned", "learned-study", str(LEARNED_MODEL), "reynolds"]) == []
    foreign = tmp_path / "foreign.zip"
    with zipfile.ZipFile(LEARNED_MODEL) as src, zipfile.ZipFile(foreign, "w") as dst:
        for name in src.namelist():
            if name != ACTOR_ENTRY:
                dst.writestr(name, src.read(name))
    assert policy_extras([str(foreign)]) == ["train"]

    def no_torch(*args, **kwargs):
        raise ImportError("No module named 'torch'")

    monkeypatch.setattr(SB3Policy, "load", no_torch)
    with pytest.raises(ImportError, match=r"foreign.zip.*-e '\.\[train\]'"):
        load_model_policy(foreign, trust=True)
    monkeypatch.setitem(sys.modules, "torch", None)  # its weights are read with torch
    with pytest.raises(ImportError, match=r"foreign.zip.*-e '\.\[train\]'"):
        load_model_policy(foreign)
    assert isinstance(load_model_policy(LEARNED_MODEL), MLPActor)  # numpy needs no torch
