"""SuperSuit's vector env for Stable-Baselines3, one episode per copy and seedable the SB3 way
(``pip install -e '.[clients,train]'``).

SuperSuit's recipe, ``concat_vec_envs_v1(pettingzoo_env_to_vec_env_v1(env), n)``, copies ``env``
with cloudpickle, exact state included. Two pitfalls follow:

- an env seeded (reset) before the copy gives every copy the same generator state, so every copy
  runs the same episode, forever: ``n`` copies teach no more than one;
- SB3 seeds a vector env with ``VecEnv.seed(seed)`` (``PPO(seed=...)`` calls it), which SuperSuit's
  SB3 wrapper passes to its ``ConcatVecEnv``, which has no ``seed``: ``AttributeError`` (the same
  with MPE2's envs).

:func:`make_vec_env` copies an env that was never reset and returns :class:`SeededVecEnv`, whose
``seed(s)`` gives copy ``i`` the seed ``s + i`` at the next reset (SB3's convention), so
``PPO(..., seed=s)`` works, every copy runs its own episode, and a seed repeats the run. In-process
only: SuperSuit's multiprocess ``num_cpus`` hands overlapping seeds to its workers.
:mod:`boids_env.train.vec_env` is the same idea without SuperSuit (what ``boids train`` uses).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boids_env.environment import BoidsEnv
from boids_env.integrations import missing_extra

try:
    import supersuit
    from supersuit.vector.sb3_vector_wrapper import SB3VecEnvWrapper
except ImportError as exc:  # SuperSuit's SB3 wrapper imports stable_baselines3
    raise missing_extra("supersuit", "clients,train", exc) from exc


class SeededVecEnv(SB3VecEnvWrapper):
    """SuperSuit's SB3 vector env with a working ``seed``: copy ``i`` (one :class:`BoidsEnv`,
    ``followers`` consecutive sub-envs, one per follower) is reset with ``seed + i`` at the next
    :meth:`reset`; later resets continue each copy's own generator."""

    def __init__(self, venv: Any, followers: int) -> None:
        super().__init__(venv)
        self.followers = followers
        self._seed: int | None = None

    def seed(self, seed: int | None = None) -> list[int | None]:
        """Seed copy ``i`` with ``seed + i`` at the next reset (None: leave the copies as they
        are). Returns each sub-env's seed, as SB3's ``VecEnv.seed`` does."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                                 or seed < 0):
            raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
        self._seed = None if seed is None else int(seed)
        return [None if seed is None else int(seed) + i // self.followers
                for i in range(self.num_envs)]

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> np.ndarray:
        if seed is not None:
            self.seed(seed)
        seed, self._seed = self._seed, None
        observations, self.reset_infos = self.venv.reset(seed=seed, options=options)
        return observations


def make_vec_env(n_copies: int, seed: int | None = None, **fields: Any) -> SeededVecEnv:
    """``n_copies`` copies of ``BoidsEnv(**fields)`` (env fields by flat name) as one SB3 vector
    env of ``n_copies × followers`` sub-envs (SuperSuit's parameter-sharing layout: every
    follower of every copy is one sub-env of the same policy). ``seed``: copy ``i`` starts with
    ``seed + i`` (None: unseeded, each copy from fresh entropy; ``PPO(seed=...)`` seeds it too)."""
    if isinstance(n_copies, bool) or not isinstance(n_copies, int | np.integer) or n_copies < 1:
        raise ValueError(f"n_copies must be an integer >= 1, got {n_copies!r}")
    env = BoidsEnv(**fields)  # never reset: the copies must not share its generator's state
    vec = supersuit.concat_vec_envs_v1(supersuit.pettingzoo_env_to_vec_env_v1(env), int(n_copies),
                                       num_cpus=0, base_class="gymnasium")
    out = SeededVecEnv(vec, followers=len(env.possible_agents))
    out.seed(seed)
    return out


__all__ = ["SeededVecEnv", "make_vec_env"]
