"""Many worlds per process: K copies of the env stepped in one call through arrays.

Each copy keeps its own pymunk space, random stream and episode; the batch only moves their
arrays in one block, one row per follower, the copies' followers one after another (copies
may have different group sizes). Each copy's results are bit-identical to stepping it alone
with :meth:`BoidsEnv.step_arrays` (``tests/env/test_batch.py``). The actions of the whole
batch are checked once, in one call, instead of once per copy.

Each copy runs its step's first part (:meth:`BoidsEnv._before_physics`: speed limit, leader
command, safety filter) and its physics in turn; then, with the compiled kernels loaded
(:mod:`boids_env.kernels`), the observations, violation flags and reward terms of every
*fused* copy come from one compiled call (``batch_after``: the same kernels one env runs,
copy by copy, in one loop). A copy is fused when its step needs nothing else
(:func:`~boids_env.fused.fusable`): holonomic robots below ``KD_TREE_MIN_ROBOTS``, the
study's blocks only (any number of neighbour slots; world or leader frame; relative actions
or not), no sensing noise, realism or crowd, alignment on the commands and none of the
opt-in reward terms. Any other copy computes them with its own code
(:meth:`Rewards.terms <boids_env.rewards.Rewards.terms>`, :meth:`BoidsEnv._observe`), in the
same call.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import kernels
from boids_env.environment import BoidsEnv
from boids_env.fused import Fused
from boids_env.rewards import REWARD_INFO_KEYS


@dataclass(frozen=True)
class BatchStep:
    """One step of every copy: rows of all copies' followers, in copy order."""

    observations: npt.NDArray[np.float32]
    """(sum F, D) next observations."""
    rewards: npt.NDArray[np.float64]
    """(sum F,) rewards."""
    terms: npt.NDArray[np.float64]
    """(9, sum F) reward terms in ``REWARD_INFO_KEYS`` order."""
    truncated: npt.NDArray[np.bool_]
    """(K,) whether each copy's episode ended with this step."""


class EnvBatch:
    """K env copies stepped together.

    Args:
        envs: the copies (each its own :class:`BoidsEnv`; one object may not appear twice).
            Their observations must have one size.
    """

    def __init__(self, envs: Sequence[BoidsEnv]) -> None:
        envs = list(envs)
        if not envs or not all(isinstance(e, BoidsEnv) for e in envs):
            raise TypeError(f"envs must be a non-empty sequence of BoidsEnv, got {envs!r}")
        if len({id(e) for e in envs}) != len(envs):
            raise ValueError("envs must be distinct objects: a copy listed twice would step "
                             "twice per call")
        sizes = {e.observation_space(e.possible_agents[0]).shape[0] for e in envs}
        if len(sizes) != 1:
            raise ValueError(f"the copies' observations must have one size, got "
                             f"{sorted(sizes)}")
        self.envs = envs
        self.sizes = [len(e.possible_agents) for e in envs]
        self.bounds = np.cumsum([0, *self.sizes]).tolist()
        self.obs_size = sizes.pop()
        self._fused: Fused | None = None

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_fused": None}  # rebuilt on use (views of the counts)

    def __len__(self) -> int:
        return len(self.envs)

    @property
    def rows(self) -> int:
        """Followers of all copies: the rows of every array."""
        return self.bounds[-1]

    def reset_copy(self, copy: int, seed: int | None = None,
                   options: Mapping[str, Any] | None = None) -> npt.NDArray[np.float32]:
        """Resets copy ``copy`` (as its ``reset_arrays``); its observations (F, D)."""
        return self.envs[copy].reset_arrays(seed, dict(options) if options else None)

    def reset_arrays(self, seeds: Sequence[int | None],
                     options: Sequence[Mapping[str, Any] | None] | None = None
                     ) -> npt.NDArray[np.float32]:
        """Resets every copy with its seed and options; observations (sum F, D)."""
        if len(seeds) != len(self.envs) or (options is not None
                                             and len(options) != len(self.envs)):
            raise ValueError(f"give one seed (and one options entry) per copy: "
                             f"{len(self.envs)} copies, got {len(seeds)} seeds")
        opts = options if options is not None else [None] * len(self.envs)
        return np.concatenate([self.reset_copy(i, s, o)
                               for i, (s, o) in enumerate(zip(seeds, opts, strict=True))])

    def step_arrays(self, actions: npt.ArrayLike) -> BatchStep:
        """Steps every copy with its rows of ``actions`` (sum F, 2), in copy order.

        The actions are checked as :meth:`BoidsEnv.step_arrays` checks them (a clear
        ``ValueError`` for a wrong shape, dtype or a NaN/inf, naming the copy and follower),
        before any copy steps; a copy whose episode has ended is refused the same way."""
        arr = np.asarray(actions)
        shape = (self.rows, 2)
        if arr.dtype.kind not in "iuf" or arr.shape != shape:
            raise ValueError(f"actions must be a real array of shape {shape} (vx, vy per "
                             f"follower of every copy, m/s), got dtype {arr.dtype} and "
                             f"shape {arr.shape}")
        arr = np.array(arr, dtype=np.float64)  # a copy: the caller's array stays its own
        if not np.isfinite(arr).all():
            row = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
            copy = int(np.searchsorted(self.bounds, row, side="right")) - 1
            raise ValueError(f"actions must be finite; NaN or inf in copy {copy}, "
                             f"follower row {row - self.bounds[copy]}")
        for i, env in enumerate(self.envs):
            if env.episode is None or not env.agents:
                raise RuntimeError(f"copy {i} has no live episode (reset it before stepping)")
        for env, start, stop in zip(self.envs, self.bounds, self.bounds[1:], strict=False):
            env._physics(env._before_physics(arr[start:stop]))
        observations = np.empty((self.rows, self.obs_size), dtype=np.float32)
        terms = np.zeros((len(REWARD_INFO_KEYS), self.rows))
        compiled = kernels.loaded()
        fused = self._fused_plan() if compiled is not None else None
        if fused is not None:
            fused.run(compiled, observations, terms)
        for i, env in enumerate(self.envs):
            if fused is None or not fused.member[i]:
                start, stop = self.bounds[i], self.bounds[i + 1]
                terms[:, start:stop], observations[start:stop] = env._outcome()
        truncated = np.array([env._end_step() for env in self.envs])
        return BatchStep(observations, terms.sum(axis=0), terms, truncated)

    def _fused_plan(self) -> Fused | None:
        """The fused copies' constants (:class:`~boids_env.fused.Fused`), rebuilt when a
        copy's episode config or counters changed (a reset); None when no copy is fused."""
        self._fused = Fused.current(self._fused, self.envs, self.bounds)
        return self._fused if self._fused.member.any() else None
