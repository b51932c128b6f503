"""The env as a native batched TorchRL env: ``BoidsTorchRLEnv(num_envs=64, robots=13)`` steps
64 worlds per call through one :class:`~boids_env.batch.EnvBatch` (TensorDict in, TensorDict
out), as VMAS's ``VmasEnv`` steps its batch. Needs ``pip install -e '.[clients]'``
(TorchRL).

Layout (VMAS's and BenchMARL's conventions; ``N`` worlds, ``F`` followers, ``D`` observation
entries): the followers of every world form the group ``"agents"`` (``group=`` renames it),

- ``(group, "action")``: (N, F, 2) float32 within the action Box of the spaces (m/s);
- ``(group, "observation")``: (N, F, D) float32 within the observation Box;
- ``(group, "reward")``: (N, F, 1) float32; ``(group, "info", key)``: (N, F) float32 for every
  key of :data:`~boids_env.rewards.REWARD_INFO_KEYS` (zeros after a reset);
- ``"done"``, ``"truncated"``: (N, 1) bool, the world's episode ended (the step limit or the
  leader's finish and tail); ``"terminated"`` is always False (the env never terminates).

The specs are made from the env's Gymnasium spaces. :meth:`set_seed` (or ``seed=``) resets
world ``k`` with ``seed + k`` at once (TorchRL's Gymnasium wrapper resets with the seed too);
later resets go on with each world's own stream, so a run is reproducible from its seed. A
reset with a ``"_reset"`` mask (TorchRL's partial reset, which collectors send for the worlds
that are done) resets those worlds only. With ``render_mode="rgb_array"`` (the ``render``
extra), :meth:`render` returns world ``env_index``'s frame (H, W, 3) uint8.

Every world's results are bit-identical to its :class:`~boids_env.environment.BoidsEnv`
stepped alone (:class:`~boids_env.batch.EnvBatch`'s guarantee); the actions and observations
travel as float32, as the spaces hold them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boids_env.batch import EnvBatch
from boids_env.config import EnvConfig
from boids_env.environment import BoidsEnv
from boids_env.integrations import missing_extra
from boids_env.rewards import REWARD_INFO_KEYS

try:
    import torch
    from tensordict import TensorDict, TensorDictBase
    from torchrl.data import Bounded, Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase
except ImportError as exc:
    raise missing_extra("torchrl", "clients", exc) from exc


# TensorDict's constructor without its checks of every entry (the entries are made here, of
# the spec's shapes and dtypes), as TorchRL's own envs build theirs; the checked one if absent
_MAKE = getattr(TensorDict, "_new_unsafe", TensorDict)


class BoidsTorchRLEnv(EnvBase):
    """``num_envs`` worlds of one config, stepped together; batch size ``(num_envs,)``.

    Args:
        num_envs: how many worlds (at least 1).
        config: the worlds' :class:`~boids_env.config.EnvConfig` (None: the study's case),
            updated with ``fields`` (env fields by flat name: ``robots``, ``scene``, ...).
        seed: the seed of world 0 (world ``k`` gets ``seed + k``); None: unseeded.
        device: where the TensorDicts live (the worlds step on the CPU).
        group: the name of the followers' group.
        render_mode: None, or ``"rgb_array"`` for :meth:`render`.
    """

    batch_locked = True

    def __init__(self, num_envs: int = 1, config: EnvConfig | None = None, *,
                 seed: int | None = None, device: Any = "cpu", group: str = "agents",
                 render_mode: str | None = None, **fields: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) \
                or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if not isinstance(group, str) or not group:
            raise ValueError(f"group must be a non-empty string, got {group!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        # every world is built (and a bad field refused) before TorchRL's base is set up
        envs = [BoidsEnv(config, render_mode=render_mode, **fields) for _ in range(int(num_envs))]
        super().__init__(device=device, batch_size=torch.Size([int(num_envs)]),
                         allow_done_after_reset=True)
        self.batch = EnvBatch(envs)
        self.group = group
        self.render_mode = render_mode
        self.agent_names = list(envs[0].possible_agents)
        self.group_map = {group: self.agent_names}
        self.n_agents = len(self.agent_names)
        self._make_specs(envs[0])
        self._obs = np.zeros((self.batch_size[0], self.n_agents, self.batch.obs_size),
                             dtype=np.float32)
        self._zero_info = {k: torch.zeros(self._shape, device=self.device)
                           for k in REWARD_INFO_KEYS}
        self._set_seed(seed)

    @property
    def num_envs(self) -> int:
        return int(self.batch_size[0])

    @property
    def _shape(self) -> tuple[int, int]:
        return (self.num_envs, self.n_agents)

    @property
    def envs(self) -> list[BoidsEnv]:
        """The worlds, in batch order."""
        return self.batch.envs

    def _make_specs(self, env: BoidsEnv) -> None:
        """The specs from the first world's spaces (every world has the same)."""
        agent = env.possible_agents[0]
        n, f, dev = self.num_envs, self.n_agents, self.device
        obs_box, act_box = env.observation_space(agent), env.action_space(agent)

        def bounded(box: Any) -> Bounded:
            low = torch.as_tensor(np.broadcast_to(box.low, (n, f, *box.shape)).copy())
            high = torch.as_tensor(np.broadcast_to(box.high, (n, f, *box.shape)).copy())
            return Bounded(low=low, high=high, shape=(n, f, *box.shape), dtype=torch.float32,
                           device=dev)

        info = Composite({k: Unbounded(shape=(n, f), device=dev) for k in REWARD_INFO_KEYS},
                         shape=(n, f))
        self.observation_spec = Composite(
            {self.group: Composite({"observation": bounded(obs_box), "info": info},
                                   shape=(n, f))}, shape=(n,))
        self.action_spec = Composite(
            {self.group: Composite({"action": bounded(act_box)}, shape=(n, f))}, shape=(n,))
        self.reward_spec = Composite(
            {self.group: Composite({"reward": Unbounded(shape=(n, f, 1), device=dev)},
                                   shape=(n, f))}, shape=(n,))
        flag = Categorical(n=2, shape=(n, 1), dtype=torch.bool, device=dev)
        self.done_spec = Composite({"done": flag, "terminated": flag.clone(),
                                    "truncated": flag.clone()}, shape=(n,))

    # ------------------------------------------------------------------------- seeding
    def _set_seed(self, seed: int | None) -> None:
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                                 or seed < 0):
            raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
        seeds = [None if seed is None else int(seed) + k for k in range(self.num_envs)]
        self._obs[:] = self.batch.reset_arrays(seeds).reshape(self._obs.shape)

    # ------------------------------------------------------------------- reset and step
    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        worlds = (np.arange(self.num_envs) if mask is None else
                  np.flatnonzero(mask.reshape(self.num_envs, -1).any(-1).cpu().numpy()))
        obs = self._obs.copy()  # the arrays already handed out stay as they were
        for k in worlds:
            obs[k] = self.batch.reset_copy(int(k))
        self._obs = obs
        false = torch.zeros((self.num_envs, 1), dtype=torch.bool, device=self.device)
        group = {"observation": torch.from_numpy(obs).to(self.device),
                 "info": {k: v.clone() for k, v in self._zero_info.items()}}
        return self._out(group, false)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get((self.group, "action"))
        result = self.batch.step_arrays(action.detach().cpu().numpy().reshape(-1, 2))
        obs = result.observations.reshape(self._obs.shape)
        self._obs = obs
        shape = self._shape
        terms = torch.from_numpy(result.terms.reshape(len(REWARD_INFO_KEYS), *shape)).to(
            self.device, torch.float32)
        group = {"observation": torch.from_numpy(obs).to(self.device),
                 "reward": torch.from_numpy(result.rewards.reshape(*shape, 1)).to(
                     self.device, torch.float32),
                 "info": dict(zip(REWARD_INFO_KEYS, terms.unbind(0), strict=True))}
        done = torch.from_numpy(result.truncated.reshape(-1, 1)).to(self.device)
        return self._out(group, done)

    def _out(self, group: dict[str, Any], done: torch.Tensor) -> TensorDictBase:
        shape = self._shape
        info = _MAKE(group.pop("info"), batch_size=shape, device=self.device)
        return _MAKE({self.group: _MAKE({**group, "info": info}, batch_size=shape,
                                        device=self.device),
                      "done": done, "terminated": torch.zeros_like(done),
                      "truncated": done.clone()},
                     batch_size=self.batch_size, device=self.device)

    # ---------------------------------------------------------------------- rendering
    def render(self, mode: str = "rgb_array", env_index: int = 0) -> np.ndarray:
        """World ``env_index``'s frame (H, W, 3) uint8 (each world makes its renderer when it
        first draws)."""
        if mode != "rgb_array":
            raise ValueError(f"mode must be 'rgb_array', got {mode!r}")
        if self.render_mode != "rgb_array":
            raise RuntimeError("render() needs BoidsTorchRLEnv(..., render_mode='rgb_array')")
        if isinstance(env_index, bool) or not isinstance(env_index, int | np.integer) \
                or not 0 <= env_index < self.num_envs:
            raise ValueError(f"env_index must be an integer in [0, {self.num_envs}), got "
                             f"{env_index!r}")
        frame = self.envs[int(env_index)].render()
        assert frame is not None  # rgb_array mode returns the frame
        return frame

    def close(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()
        super().close(**kwargs)

    @property
    def step_limit(self) -> int:
        """The step limit of world 0's episode (max_cycles, or 3x the leader's path)."""
        episode = self.envs[0].episode
        assert episode is not None  # every world is reset when the env is made
        return int(episode.step_limit)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(num_envs={self.num_envs}, n_agents={self.n_agents}, "
                f"group={self.group!r}, device={self.device})")


__all__ = ["BoidsTorchRLEnv"]
