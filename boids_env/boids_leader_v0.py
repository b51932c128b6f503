"""PettingZoo-style versioned module of the env: ``env``, ``parallel_env`` and ``raw_env``
(``from boids_env import boids_leader_v0``), so PettingZoo's module-level tests
(``max_cycles_test``) and client code written for PettingZoo's own envs work unchanged."""

from boids_env.environment import BoidsEnv, env, parallel_env, raw_env

__all__ = ["BoidsEnv", "env", "parallel_env", "raw_env"]
