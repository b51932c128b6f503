"""The learner ``boids train`` runs: Stable-Baselines3's PPO with a leaner rollout collection.

Collecting a rollout, SB3's PPO runs the policy once per VecEnv step through its general
forward pass: modules called through ``nn.Module.__call__``, a ``torch.distributions.Normal``
built (and its arguments validated) for every step, the sample's log-probability validated
again. At the slots of ``boids train``'s defaults (72 followers a step) that general path cost
about twice the arithmetic itself (measured 281 µs against 156 µs a step).

:class:`FlockPPO` collects with the same operations in the same order on the same tensors
(``F.linear`` and the activations of the policy's own layers, ``torch.normal`` on the same
mean and standard deviation, the Gaussian log-density written out as ``Normal.log_prob``
computes it), so a training run gives bit for bit the model stock SB3 PPO gives
(``tests/train/test_ppo.py`` trains both and compares every weight). The update, saving and
loading are SB3's own: a saved model is an ordinary SB3 PPO zip.

A policy that is not the plain ``MlpPolicy`` shape (a Gaussian over a box, a shared flatten
extractor, sequential hidden layers, no gSDE) or that runs on a GPU is collected through SB3's
own forward pass.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.distributions import DiagGaussianDistribution
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import FlattenExtractor

_LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))
"""The constant ``torch.distributions.Normal.log_prob`` subtracts, computed as it does."""


def _layers(module: torch.nn.Module, x: torch.Tensor) -> torch.Tensor:
    """``module(x)`` for a sequential stack, without the module-call machinery: linear layers
    as ``F.linear`` on their own weights (what ``nn.Linear.forward`` calls), tanh as
    ``torch.tanh``, anything else called as a module."""
    for layer in module.children() if isinstance(module, torch.nn.Sequential) else (module,):
        if type(layer) is torch.nn.Linear:
            x = F.linear(x, layer.weight, layer.bias)
        elif type(layer) is torch.nn.Tanh:
            x = torch.tanh(x)
        else:
            x = layer(x)
    return x


def lean_forward_applies(policy: Any, action_space: Any) -> bool:
    """Whether :func:`lean_forward` computes what ``policy.forward`` does for this policy."""
    return (type(policy) is ActorCriticPolicy and isinstance(action_space, spaces.Box)
            and policy.device.type == "cpu"
            and isinstance(policy.action_dist, DiagGaussianDistribution)
            and not policy.use_sde and policy.share_features_extractor
            and type(policy.features_extractor) is FlattenExtractor
            and not policy.squash_output
            and all(isinstance(getattr(policy.mlp_extractor, name, None), torch.nn.Sequential)
                    for name in ("policy_net", "value_net")))


class _Gaussian:
    """What a rollout's action draws need of a ``DiagGaussianDistribution`` over the policy's
    state-independent log standard deviation, fixed while a rollout is collected: the scale
    (``ones_like(mean) * exp(log_std)`` is ``exp(log_std)`` in every row), and the two terms
    ``Normal.log_prob`` computes from it (``2 * scale**2`` and ``log(scale)``) as numpy rows."""

    def __init__(self, log_std: torch.Tensor) -> None:
        self.std = log_std.detach().exp()
        self.two_var = (2 * self.std**2).numpy()
        self.log_scale = self.std.log().numpy()


def lean_forward(policy: ActorCriticPolicy, obs: np.ndarray, gaussian: _Gaussian | None = None
                 ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``policy(obs)`` (actions, values, log-probabilities) for a float32 batch of flat
    observations under ``torch.no_grad``, the same operations on the same values as SB3's
    ``ActorCriticPolicy.forward`` with a ``DiagGaussianDistribution``: the same bits and the
    same draw from torch's generator. The networks run in torch (their matrix products and
    tanh are torch's kernels); the log-density's elementwise arithmetic, exactly rounded in
    either library, runs in numpy, which calls cheaper on a few hundred numbers."""
    gaussian = gaussian or _Gaussian(policy.log_std)
    features = torch.as_tensor(obs, device=policy.device)
    if features.dtype != torch.float32 or features.dim() != 2:  # else both return it as is
        features = features.float().flatten(1)
    latent_pi = _layers(policy.mlp_extractor.policy_net, features)
    latent_vf = _layers(policy.mlp_extractor.value_net, features)
    values = F.linear(latent_vf, policy.value_net.weight, policy.value_net.bias)
    mean = F.linear(latent_pi, policy.action_net.weight, policy.action_net.bias)
    actions = torch.normal(mean, gaussian.std.expand_as(mean))  # Normal.sample
    diff = actions.numpy() - mean.numpy()  # Normal.log_prob, summed over the action's axes
    log_prob = -(diff**2) / gaussian.two_var - gaussian.log_scale - _LOG_SQRT_2PI
    return actions, values, torch.from_numpy(log_prob.sum(axis=1))


class FlockPPO(PPO):
    """Stable-Baselines3's PPO whose rollouts run the policy through :func:`lean_forward`
    (same bits, about half the per-step cost); everything else is SB3's."""

    def collect_rollouts(self, env: Any, callback: Any, rollout_buffer: Any,
                         n_rollout_steps: int) -> bool:
        if not lean_forward_applies(self.policy, self.action_space):
            return super().collect_rollouts(env, callback, rollout_buffer, n_rollout_steps)
        # SB3's OnPolicyAlgorithm.collect_rollouts (2.x) for a Gaussian policy on a box
        # without gSDE, the same statements in the same order; the callbacks see the same
        # local names
        assert self._last_obs is not None, "No previous observation was provided"
        self.policy.set_training_mode(False)
        n_steps = 0
        rollout_buffer.reset()
        callback.on_rollout_start()
        low, high = self.action_space.low, self.action_space.high
        gaussian = _Gaussian(self.policy.log_std)  # the parameters stay put while collecting
        while n_steps < n_rollout_steps:
            with torch.no_grad():
                actions, values, log_probs = lean_forward(self.policy, self._last_obs,
                                                          gaussian)
            actions = actions.cpu().numpy()
            clipped_actions = np.clip(actions, low, high)
            new_obs, rewards, dones, infos = env.step(clipped_actions)
            self.num_timesteps += env.num_envs
            callback.update_locals(locals())
            if not callback.on_step():
                return False
            self._update_info_buffer(infos, dones)
            n_steps += 1
            # a truncated episode bootstraps from its terminal observation's value
            for idx in np.flatnonzero(dones):
                if (infos[idx].get("terminal_observation") is not None
                        and infos[idx].get("TimeLimit.truncated", False)):
                    terminal_obs = self.policy.obs_to_tensor(
                        infos[idx]["terminal_observation"])[0]
                    with torch.no_grad():
                        terminal_value = self.policy.predict_values(terminal_obs)[0]
                    rewards[idx] += self.gamma * terminal_value
            rollout_buffer.add(self._last_obs, actions, rewards, self._last_episode_starts,
                               values, log_probs)
            self._last_obs = new_obs
            self._last_episode_starts = dones
        with torch.no_grad():
            values = self.policy.predict_values(torch.as_tensor(new_obs, device=self.device))
        rollout_buffer.compute_returns_and_advantage(last_values=values, dones=dones)
        callback.update_locals(locals())
        callback.on_rollout_end()
        return True


def learner_class(algorithm: str) -> Any:
    """The class ``boids train`` trains with: :class:`FlockPPO` for ``ppo``, else SB3's."""
    from boids_env.policies.sb3_policy import algorithm_class

    return FlockPPO if algorithm.lower() == "ppo" else algorithm_class(algorithm)
