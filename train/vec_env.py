"""An SB3 ``VecEnv`` over several flock envs with parameter sharing: one slot per follower.

Every follower of every env copy is one VecEnv slot, so one shared SB3 policy acts for all of
them. Copies may have different group sizes (observations have a fixed size), and each episode
may sample its leader speed and path. SB3's contract is kept: when a copy's episode ends, all of
its slots report ``done``, carry ``terminal_observation`` and ``TimeLimit.truncated`` (episodes
end by truncation only), and their observation is already that of the next episode.

Seeding: ``seed(s)`` spawns one independent ``numpy.random.SeedSequence`` child per copy; each
copy draws its episode seeds and sampled options from its own stream, so copies never share a
random stream and a run is reproducible from one integer.

With ``processes > 1`` the copies are split over that many processes, this one included: this
process steps the first shard of copies itself while ``processes - 1`` worker processes step
the others (each shard in one call), so the training process's core steps copies too instead
of waiting for the workers.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from boids_env.eval.pool import available_cores
from boids_env.train.shards import EPISODE_INFO, CopySpec, RemoteShard, Shard

__all__ = ["EPISODE_INFO", "CopySpec", "FlockVecEnv", "default_processes", "default_threads"]


class FlockVecEnv(VecEnv):
    """SB3 VecEnv with one slot per follower over several :class:`BoidsEnv` copies.

    Args:
        copies: the env copies (their group sizes, sampled leader speeds and paths); an int
            ``n`` means ``n`` copies of the study's default case.
        seed: base seed (see :meth:`seed`); reseed any time with ``seed()``.
        processes: processes the copies are split over, this one included (1: all in this
            process; ``k``: this process steps the first shard of copies and ``k - 1`` worker
            processes the others; 0: :func:`default_processes`). Results do not depend on
            it: every copy has its own random stream, so a run is deterministic for a given
            seed whatever the split.
    """

    def __init__(self, copies: int | Iterable[CopySpec] = 1, *, seed: int = 0,
                 processes: int = 1) -> None:
        specs = [CopySpec() for _ in range(copies)] if isinstance(copies, int) else list(copies)
        if not specs:
            raise ValueError("copies must hold at least one CopySpec (or be an int >= 1)")
        for spec in specs:
            if not isinstance(spec, CopySpec):
                raise TypeError(f"copies must be CopySpec instances, got {type(spec).__name__}")
            if spec.robots < 2:
                raise ValueError(f"robots must be >= 2 (one follower at least), got "
                                 f"{spec.robots}")
        if isinstance(processes, bool) or not isinstance(processes, int) \
                or not 0 <= processes <= len(specs):
            raise ValueError(f"processes must be an integer in [0, {len(specs)}] (the number "
                             f"of copies; 0: half the cores), got {processes!r}")
        auto = processes == 0
        processes = processes or default_processes(len(specs))
        self.specs = specs
        probe = [spec.make() for spec in specs]
        obs_spaces = [e.observation_space(e.possible_agents[0]) for e in probe]
        if len({s.shape for s in obs_spaces}) != 1:
            raise ValueError("all copies must have the same observation size (neighbours)")
        act_space = probe[0].action_space(probe[0].possible_agents[0])
        obs_space = obs_spaces[0]
        for e in probe:
            e.close()
        if auto and processes == 1 and len(specs) > 1 and available_cores() == 2:
            processes = 2 if _step_seconds(specs) >= SECOND_CORE_STEP else 1
        self.processes = processes
        """The processes stepping the copies, this one included (``processes`` resolved)."""
        # Contiguous groups of copies per shard, balanced by follower count.
        groups = _split(specs, processes)
        # The first shard is stepped here, the others in workers (started first, so that
        # they build their copies while this process builds its own).
        remote: list[Any] = []
        if processes > 1:
            ctx = mp.get_context("forkserver" if "forkserver" in mp.get_all_start_methods()
                                 else "spawn")
            remote = [RemoteShard(group, obs_space.shape[0], ctx) for group in groups[1:]]
        try:
            self.shards: list[Any] = [Shard(groups[0]), *remote]
        except BaseException:  # no worker or shared memory left behind by a failed build
            for shard in remote:
                shard.close()
            raise
        self.copy_sizes = [spec.robots - 1 for spec in specs]
        self.shard_sizes = [sum(s.sizes) for s in self.shards]
        self._copy_index = [(si, ci) for si, s in enumerate(self.shards)
                            for ci in range(len(s.sizes))]
        self._actions: npt.NDArray[np.float32] | None = None
        self._closed = False
        super().__init__(sum(self.copy_sizes), obs_space, act_space)
        self._base_seed = seed
        self.seed(seed)

    # ------------------------------------------------------------------------- contract
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Gives every copy its own child of ``SeedSequence(seed)``; takes effect at the next
        :meth:`reset`. Returns the per-slot seeds in SB3's style (the base seed per slot)."""
        if seed is None:
            seed = int(np.random.SeedSequence().entropy % (2**31))
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        children = np.random.SeedSequence(int(seed)).spawn(len(self.specs))
        start = 0
        for shard in self.shards:
            n = len(shard.sizes)
            shard.seed(children[start:start + n])
            start += n
        self._base_seed = int(seed)
        return [int(seed)] * self.num_envs

    def reset(self) -> npt.NDArray[np.float32]:
        obs = np.concatenate([s.reset() for s in self.shards])
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions, dtype=np.float32)
        if actions.shape != (self.num_envs, *self.action_space.shape):
            raise ValueError(f"actions must have shape {(self.num_envs, 2)} (one (vx, vy) per "
                             f"slot), got {actions.shape}")
        self._actions = actions
        start = self.shard_sizes[0]
        for shard, n in zip(self.shards[1:], self.shard_sizes[1:], strict=True):
            shard.start_step(actions[start:start + n])
            start += n

    def step_wait(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32],
                                 npt.NDArray[np.bool_], list[dict[str, Any]]]:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        # this process's shard while the workers step theirs
        results = [self.shards[0].step(self._actions[:self.shard_sizes[0]]),
                   *(shard.finish_step() for shard in self.shards[1:])]
        self._actions = None
        obs = np.concatenate([r[0] for r in results])
        rewards = np.concatenate([r[1] for r in results])
        dones = np.concatenate([r[2] for r in results])
        infos = [info for r in results for info in r[3]]
        return obs, rewards, dones, infos

    def episodes_state(self) -> list[dict[str, Any]]:
        """Every copy's episode so far and random stream as plain data, in copy order
        (:meth:`Shard.state <boids_env.train.shards.Shard.state>`), wherever it is stepped."""
        return [copy for shard in self.shards for copy in shard.state()]

    def restore_episodes(self, states: Sequence[dict[str, Any]]) -> npt.NDArray[np.float32]:
        """Rebuilds every copy from :meth:`episodes_state`'s data, bit for bit (however the
        copies are split over processes now and then); returns the observations."""
        if len(states) != len(self.specs):
            raise ValueError(f"the saved env state holds {len(states)} copies, this training "
                             f"steps {len(self.specs)}")
        start, obs = 0, []
        for shard in self.shards:
            n = len(shard.sizes)
            obs.append(shard.restore(list(states[start:start + n])))
            start += n
        return np.concatenate(obs)

    def close(self) -> None:
        if self._closed:
            return
        for shard in self.shards:
            shard.close()
        self._closed = True

    # ---------------------------------------------------------------- per-slot delegation
    def _slot_copies(self, indices: VecEnvIndices) -> list[tuple[int, int]]:
        slots = self._get_indices(indices)
        owner = np.repeat(np.arange(len(self.specs)), self.copy_sizes)
        return [self._copy_index[owner[i]] for i in slots]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [self.shards[s].get(c, attr_name) for s, c in self._slot_copies(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for s, c in dict.fromkeys(self._slot_copies(indices)):
            self.shards[s].set(c, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        return [self.shards[s].call(c, method_name, *method_args, **method_kwargs)
                for s, c in self._slot_copies(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * len(self.specs)


SECOND_CORE_STEP = 0.002
"""On 2 cores, ``processes=0`` gives the copies a worker beside the training process when one
step of them all takes at least this long (seconds) in this process, timed on throwaway
copies before training. A worker's round trip (pipe, shared memory, waking) costs a fixed
part of a step; measured on 2 cores (docs/explanation/speed.md, the fifth pass), it paid for
``ppo_safe``'s copies (7-9 ms a step: 1.2× the training's follower-steps/s idle, even with
a core held) and lost for the defaults' (0.7 ms: 0.7-1.1×)."""


def _step_seconds(specs: Sequence[CopySpec], steps: int = 8) -> float:
    """Seconds one step of all ``specs``' copies takes in this process: throwaway copies,
    reset with fixed seeds, a warm-up step, then the median of ``steps`` zero-action steps
    (nothing of the training's own copies or random streams is touched)."""
    import time

    shard = Shard(specs)
    try:
        shard.seed(np.random.SeedSequence(0).spawn(len(specs)))
        shard.reset()
        actions = np.zeros((sum(shard.sizes), 2), dtype=np.float32)
        shard.step(actions)
        times = []
        for _ in range(steps):
            start = time.perf_counter()
            shard.step(actions)
            times.append(time.perf_counter() - start)
    finally:
        shard.close()
    return float(np.median(times))


def default_processes(copies: int, cores: int | None = None) -> int:
    """Processes stepping ``copies`` env copies (the training process included) on a machine
    of ``cores`` cores (default: :func:`available_cores`): half the cores (at most one per
    copy) from 3 cores on, the other half left to the learner's torch threads
    (:func:`default_threads`). On 1 or 2 cores the training process steps them all (on 2,
    :class:`FlockVecEnv` adds a worker for copies whose step is slow: ``SECOND_CORE_STEP``).
    Measured on 2 cores, two workers beside an idle training process ran 0.31× the env's raw
    speed against 0.43× in one process (the pipes and the learner compete for the cores).
    Measured (when ``processes`` counted the workers only, the training process waiting for
    them) on a 16-core Xeon with the ``ppo_safe`` recipe
    (16 copies, follower-steps/s): 16 cores 8 workers + 8 threads 44,700–50,900 against one
    worker per core + 16 threads 30,500 (10 + 6: 49,900; 6 + 10: 48,600; 15 + 1: 25,100);
    8 cores 4 + 4 34,500 against 8 + 8 29,300; 4 cores 2 + 2 26,300 against 4 + 4 24,300.
    """
    cores = cores or available_cores()
    return 1 if cores <= 2 else max(1, min(copies, cores // 2))


def default_threads(processes: int, cores: int | None = None) -> int:
    """Torch threads for the learner beside ``processes`` processes stepping the copies (the
    training process one of them): one on 1 or 2 cores, else the cores they leave (see
    :func:`default_processes` for those measurements).

    On 2 cores a second intra-op thread buys the learner little (small networks, small
    batches) and costs the env a lot: torch's worker threads spin-wait between operations,
    so on a machine whose other core is busy they take turns with the env for one core.
    Measured on a loaded 2-core machine with ``boids train``'s defaults (follower-steps/s,
    one process): 1 thread 5,920 against 2 threads 906; with two worker processes 11,534
    against 499 (docs/explanation/speed.md). The second core still serves the update:
    :class:`~boids_env.train.ppo.FlockPPO` runs each minibatch's critic half there."""
    cores = cores or available_cores()
    return 1 if cores <= 2 else max(1, cores - processes)


def _split(specs: Sequence[CopySpec], parts: int) -> list[list[CopySpec]]:
    """Contiguous groups of copies with follower counts as equal as possible."""
    weights = np.cumsum([s.robots - 1 for s in specs])
    total = weights[-1]
    bounds = [int(np.searchsorted(weights, total * k / parts, side="left")) + 1
              for k in range(1, parts)]
    groups, start = [], 0
    for b in [*bounds, len(specs)]:
        b = min(max(b, start + 1), len(specs) - (parts - len(groups) - 1))
        groups.append(list(specs[start:b]))
        start = b
    return groups

