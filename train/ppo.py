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
(``tests/train/test_ppo.py`` trains both and compares every weight).

Its update is SB3's, except that with one torch thread on a machine of two cores or more each
minibatch's critic half (value network, value loss, its backward pass) runs in a second
thread beside the actor half: the two share no weights, so every weight gets the same
gradient bits, and on two idle cores the update took 0.65–0.81 of SB3's time (a core held by
other work: 0.99–1.16). Saving and loading are SB3's own: a saved model is an ordinary SB3
PPO zip.

A policy that is not the plain ``MlpPolicy`` shape (a Gaussian over a box, a shared flatten
extractor, sequential hidden layers, no gSDE) or that runs on a GPU is collected and updated
by SB3's own code, and so is a run that stops its update early on the KL divergence
(``target_kl``).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.distributions import DiagGaussianDistribution
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import FlattenExtractor

from boids_env.eval.pool import available_cores

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
    (same bits, about half the per-step cost) and whose update, with one torch thread on a
    machine of two cores or more, runs the critic's half of each minibatch in a second
    thread (:meth:`train`); saving, loading and everything else is SB3's."""

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

    def _splits_update(self) -> bool:
        """Whether :meth:`train` runs the actor's and the critic's halves side by side: the
        policy of :func:`lean_forward_applies` (its actor and critic share no weights), no
        early stop on the KL divergence, one torch thread (two threads of ours each opening
        torch's parallel regions would oversubscribe a larger machine) and a second core."""
        return (lean_forward_applies(self.policy, self.action_space)
                and self.target_kl is None and torch.get_num_threads() == 1
                and available_cores() >= 2)

    def train(self) -> None:
        """SB3's PPO update (``PPO.train``, 2.x), each minibatch's critic in a second thread.

        The actor (the Gaussian's mean and log std) and the critic share no weights, so the
        minibatch loss ``policy_loss + ent_coef·entropy_loss + vf_coef·value_loss`` splits
        into two graphs with no tensor in common: each half runs its forward pass and its
        backward pass with the same operations on the same tensors as in the one graph, and
        every weight receives the same gradient, bit for bit. torch runs its kernels and its
        backward pass without the GIL, so on two cores the halves run side by side; the
        gradient's clipping and Adam's step wait for both. One synchronisation a minibatch,
        not one a kernel as with a second intra-op thread, so a core held by other work costs
        the update the straggler's half, not a stall at every operation."""
        if not self._splits_update():
            return super().train()
        policy = self.policy
        policy.set_training_mode(True)
        self._update_learning_rate(policy.optimizer)
        clip_range = self.clip_range(self._current_progress_remaining)
        clip_range_vf = (None if self.clip_range_vf is None
                         else self.clip_range_vf(self._current_progress_remaining))
        entropy_losses, pg_losses, value_losses, clip_fractions = [], [], [], []
        approx_kl_divs: list[Any] = []
        with ThreadPoolExecutor(1, thread_name_prefix="boids-critic") as critic_thread:
            # OpenMP's thread count is per thread: the new one gets the learner's one thread
            critic_thread.submit(torch.set_num_threads, torch.get_num_threads()).result()
            for _ in range(self.n_epochs):
                approx_kl_divs = []
                for data in self.rollout_buffer.get(self.batch_size):
                    policy.optimizer.zero_grad()
                    features = policy.extract_features(data.observations)
                    critic = critic_thread.submit(self._critic_half, features, data,
                                                  clip_range_vf)
                    policy_loss, entropy_loss, clip_fraction, approx_kl = self._actor_half(
                        features, data, clip_range)
                    value_loss = critic.result()
                    pg_losses.append(policy_loss.item())
                    clip_fractions.append(clip_fraction)
                    value_losses.append(value_loss.item())
                    entropy_losses.append(entropy_loss.item())
                    approx_kl_divs.append(approx_kl)
                    torch.nn.utils.clip_grad_norm_(policy.parameters(), self.max_grad_norm)
                    policy.optimizer.step()
                self._n_updates += 1
        with torch.no_grad():
            loss = policy_loss + self.ent_coef * entropy_loss + self.vf_coef * value_loss
        self._log_update(entropy_losses, pg_losses, value_losses, approx_kl_divs,
                         clip_fractions, loss, clip_range, clip_range_vf)

    def _actor_half(self, features: torch.Tensor, data: Any, clip_range: float
                    ) -> tuple[torch.Tensor, torch.Tensor, float, np.ndarray]:
        """A minibatch's clipped surrogate and entropy terms as ``PPO.train`` computes them,
        and their backward pass."""
        policy = self.policy
        latent_pi = policy.mlp_extractor.forward_actor(features)
        distribution = policy._get_action_dist_from_latent(latent_pi)
        log_prob = distribution.log_prob(data.actions)
        entropy = distribution.entropy()
        advantages = data.advantages
        if self.normalize_advantage and len(advantages) > 1:
            advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        ratio = torch.exp(log_prob - data.old_log_prob)
        policy_loss_1 = advantages * ratio
        policy_loss_2 = advantages * torch.clamp(ratio, 1 - clip_range, 1 + clip_range)
        policy_loss = -torch.min(policy_loss_1, policy_loss_2).mean()
        clip_fraction = torch.mean((torch.abs(ratio - 1) > clip_range).float()).item()
        entropy_loss = -torch.mean(entropy)
        with torch.no_grad():
            log_ratio = log_prob - data.old_log_prob
            approx_kl = torch.mean((torch.exp(log_ratio) - 1) - log_ratio).cpu().numpy()
        (policy_loss + self.ent_coef * entropy_loss).backward()
        return policy_loss.detach(), entropy_loss.detach(), clip_fraction, approx_kl

    def _critic_half(self, features: torch.Tensor, data: Any, clip_range_vf: float | None
                     ) -> torch.Tensor:
        """A minibatch's value loss as ``PPO.train`` computes it, and its backward pass."""
        latent_vf = self.policy.mlp_extractor.forward_critic(features)
        values = self.policy.value_net(latent_vf).flatten()
        if clip_range_vf is None:
            values_pred = values
        else:
            values_pred = data.old_values + torch.clamp(values - data.old_values,
                                                        -clip_range_vf, clip_range_vf)
        value_loss = F.mse_loss(data.returns, values_pred)
        (self.vf_coef * value_loss).backward()
        return value_loss.detach()

    def _log_update(self, entropy_losses: list[float], pg_losses: list[float],
                    value_losses: list[float], approx_kl_divs: list[Any],
                    clip_fractions: list[float], loss: torch.Tensor, clip_range: float,
                    clip_range_vf: float | None) -> None:
        """``PPO.train``'s log records."""
        from stable_baselines3.common.utils import explained_variance

        buffer = self.rollout_buffer
        record = self.logger.record
        record("train/entropy_loss", np.mean(entropy_losses))
        record("train/policy_gradient_loss", np.mean(pg_losses))
        record("train/value_loss", np.mean(value_losses))
        record("train/approx_kl", np.mean(approx_kl_divs))
        record("train/clip_fraction", np.mean(clip_fractions))
        record("train/loss", loss.item())
        record("train/explained_variance",
               explained_variance(buffer.values.flatten(), buffer.returns.flatten()))
        record("train/std", torch.exp(self.policy.log_std).mean().item())
        record("train/n_updates", self._n_updates, exclude="tensorboard")
        record("train/clip_range", clip_range)
        if clip_range_vf is not None:
            record("train/clip_range_vf", clip_range_vf)


def learner_class(algorithm: str) -> Any:
    """The class ``boids train`` trains with: :class:`FlockPPO` for ``ppo``, else SB3's."""
    from boids_env.policies.sb3_policy import algorithm_class

    return FlockPPO if algorithm.lower() == "ppo" else algorithm_class(algorithm)
