"""The shipped learned policy acts exactly as SB3's own predict, without an optimizer."""

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from boids_env.policies.registry import LEARNED_MODEL, STUDY_MODEL
from boids_env.policies.sb3_policy import SB3Policy


@pytest.mark.parametrize("path", [LEARNED_MODEL, STUDY_MODEL], ids=["learned", "study"])
def test_actions_equal_sb3_predict_of_the_normally_loaded_model(path):
    from stable_baselines3 import PPO

    ours = SB3Policy.load(path)
    reference = PPO.load(path, device="cpu")  # with its Adam optimizer, as SB3 loads it
    obs = np.random.default_rng(0).normal(0, 1, (12, ours.obs_size)).astype(np.float32)
    expected, _ = reference.predict(obs, deterministic=True)
    assert np.array_equal(ours.act_batch(obs), np.clip(expected, -0.5, 0.5).astype(np.float32))


def test_loading_to_act_builds_no_optimizer():
    code = ("import sys; from boids_env.policies.registry import load_policy; "
            "p = load_policy('learned'); import numpy as np; "
            "p.act_batch(np.zeros((3, p.obs_size), np.float32)); "
            "print('torch._dynamo' in sys.modules, type(p.model.policy.optimizer).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300).stdout.split()
    assert out == ["False", "_NoOptimizer"]
