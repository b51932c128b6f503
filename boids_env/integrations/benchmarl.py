"""The env as a BenchMARL task: ``BoidsTask.LEADER_FOLLOWING.get_task(config={...})``, where
the config holds env fields by flat name (``robots``, ``scene``, ``lidar_rays``, ...; empty: the
study's case). Needs ``pip install -e '.[benchmarl]'`` (BenchMARL 1.5 wants
``torchrl<0.12``; the extra pins a torchvision built for torch 2.13 so pip keeps the CPU torch).

Every follower is one agent of the group ``follower``; actions are continuous (the commanded
velocity), observations the env's, and each step's reward terms arrive under
``("follower", "info")``. The ``k``-th env the task's env function makes is seeded with
``seed + k``, so the copies BenchMARL collects from run different episodes. BenchMARL's other
tasks read a YAML file of their own; this one takes its config as a dict (``get_task()``
without one is the study's case).
"""

from __future__ import annotations

from typing import Any

from boids_env.environment import BoidsEnv
from boids_env.integrations import missing_extra

try:
    from benchmarl.environments.common import Task, TaskClass
    from torchrl.data import Composite
    from torchrl.envs import EnvBase, PettingZooWrapper
except ImportError as exc:
    raise missing_extra("benchmarl", "benchmarl", exc) from exc


class BoidsTaskClass(TaskClass):
    """BenchMARL's :class:`TaskClass` for :class:`BoidsEnv`; ``config`` is env fields."""

    def get_env_fun(self, num_envs: int, continuous_actions: bool, seed: int | None,
                    device: Any) -> _EnvMaker:
        config = dict(self.config)
        BoidsEnv(**config)  # a bad field fails here, before BenchMARL builds anything
        return _EnvMaker(config, seed, device)

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return False

    def max_steps(self, env: EnvBase) -> int:
        # the step limit the env has set at its first reset: max_cycles, or 3x the leader's path
        return int(env._env.episode.step_limit)

    def has_render(self, env: EnvBase) -> bool:
        return False  # frames need render_mode="rgb_array" and the render extra

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return env.group_map

    def observation_spec(self, env: EnvBase) -> Composite:
        return _only(env, "observation")

    def info_spec(self, env: EnvBase) -> Composite | None:
        return _only(env, "info")

    def state_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec

    @staticmethod
    def env_name() -> str:
        return "boids"


class _EnvMaker:
    """The env function of :meth:`BoidsTaskClass.get_env_fun`: its ``k``-th env (from 0) is
    seeded with ``seed + k``. BenchMARL calls one function for every copy of its ``SerialEnv``
    with the same seed; seeded alike, every copy would start the same episode (the SuperSuit
    pitfall). With ``parallel_collection=True`` each worker process counts from its own copy
    of this function, so the copies would share seeds again: keep the default serial collection.
    """

    def __init__(self, config: dict[str, Any], seed: int | None, device: Any) -> None:
        self.config, self.seed, self.device = config, seed, device
        self.made = 0

    def __call__(self) -> EnvBase:
        seed = None if self.seed is None else self.seed + self.made
        self.made += 1
        return PettingZooWrapper(BoidsEnv(**self.config), return_state=False, use_mask=False,
                                 categorical_actions=False, seed=seed, device=self.device)


def _only(env: EnvBase, key: str) -> Composite:
    """The env's observation spec with, under each group, only ``key``."""
    spec = env.observation_spec.clone()
    for group in env.group_map:
        for other in [k for k in spec[group].keys() if k != key]:
            del spec[group][other]
    return spec


class BoidsTask(Task):
    """BenchMARL's task enum for the env: one task, configured by its dict of env fields."""

    LEADER_FOLLOWING = None

    @staticmethod
    def associated_class() -> type[BoidsTaskClass]:
        return BoidsTaskClass

    def get_task(self, config: dict[str, Any] | None = None) -> BoidsTaskClass:
        """The task with ``config`` (env fields by flat name; None: the study's case)."""
        return BoidsTaskClass(name=self.name, config=dict(config or {}))


__all__ = ["BoidsTask", "BoidsTaskClass"]
