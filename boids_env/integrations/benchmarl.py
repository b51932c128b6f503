"""The env as a BenchMARL task: ``BoidsTask.LEADER_FOLLOWING.get_from_yaml()`` (the YAML this
package ships, ``benchmarl_conf/task/boids/leader_following.yaml``) or
``BoidsTask.LEADER_FOLLOWING.get_task(config={...})``, where the config holds env fields by flat
name (``robots``, ``scene``, ``lidar_rays``, ...; empty: the study's case). Needs ``pip install -e
'.[benchmarl]'`` (BenchMARL 1.5 wants ``torchrl<0.12``; the extra pins a torchvision
built for torch 2.13 so pip keeps the CPU torch).

The task's env is the batched :class:`~boids_env.integrations.torchrl.BoidsTorchRLEnv`: the
``num_envs`` worlds BenchMARL asks for are one env of batch size ``(num_envs,)`` (as VMAS's),
world ``k`` seeded with ``seed + k``, so the worlds run different episodes. Every follower is
one agent of the group ``agents``; actions are continuous (the commanded velocity),
observations the env's, and each step's reward terms arrive under ``("agents", "info")``.
Evaluation videos come from ``rgb_array`` frames when the ``render`` extra is installed.

Importing this module registers the task as ``boids/leader_following`` in BenchMARL's
``task_config_registry``; ``python -m boids_env.integrations.benchmarl_run algorithm=mappo
task=boids/leader_following`` is BenchMARL's own command line with this package's YAML on
Hydra's search path (:mod:`boids_env.integrations.benchmarl_run`).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from boids_env.environment import BoidsEnv
from boids_env.integrations import missing_extra

try:
    from benchmarl.environments import task_config_registry
    from benchmarl.environments.common import Task, TaskClass
    from torchrl.data import Composite
    from torchrl.envs import EnvBase

    from boids_env.integrations.torchrl import BoidsTorchRLEnv
except ImportError as exc:
    raise missing_extra("benchmarl", "benchmarl", exc) from exc

CONF_DIR = Path(__file__).with_name("benchmarl_conf")
"""The Hydra config folder this package ships (``task/boids/<task>.yaml``): BenchMARL's layout
of ``benchmarl/conf``, for its loader and Hydra's search path."""


class BoidsTaskClass(TaskClass):
    """BenchMARL's :class:`TaskClass` for :class:`BoidsEnv`; ``config`` is env fields."""

    def get_env_fun(self, num_envs: int, continuous_actions: bool, seed: int | None,
                    device: Any) -> Callable[[], BoidsTorchRLEnv]:
        config = dict(self.config)
        BoidsEnv(**config)  # a bad field fails here, before BenchMARL builds anything
        if not continuous_actions:
            raise ValueError("continuous_actions must be True: the followers' actions are "
                             "velocities (the task has no discrete actions)")
        render = "rgb_array" if importlib.util.find_spec("pygame") is not None else None

        def make() -> BoidsTorchRLEnv:
            return BoidsTorchRLEnv(num_envs, seed=seed, device=device, render_mode=render,
                                   **config)

        return make

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return False

    def max_steps(self, env: EnvBase) -> int:
        # the step limit the env has set at its first reset: max_cycles, or 3x the leader's path
        return int(env.step_limit)

    def has_render(self, env: EnvBase) -> bool:
        return env.render_mode == "rgb_array"  # the render extra is installed

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
        return _unbatched(env, env.full_action_spec)

    @staticmethod
    def env_name() -> str:
        return "boids"


def _unbatched(env: EnvBase, spec: Composite) -> Composite:
    """``spec`` without the env's batch dimensions (one world's, as BenchMARL's models take it:
    [n_agents, ...] under each group, as VMAS's task gives)."""
    return spec[(0,) * len(env.batch_size)]


def _only(env: EnvBase, key: str) -> Composite:
    """One world's observation spec with, under each group, only ``key``."""
    spec = _unbatched(env, env.observation_spec).clone()
    for group in env.group_map:
        for other in [k for k in spec[group].keys() if k != key]:
            del spec[group][other]
    return spec


class BoidsTask(Task):
    """BenchMARL's task enum for the env: one task, configured by its dict of env fields
    (from this package's YAML by :meth:`get_from_yaml`)."""

    LEADER_FOLLOWING = None

    @staticmethod
    def associated_class() -> type[BoidsTaskClass]:
        return BoidsTaskClass

    def get_task(self, config: dict[str, Any] | None = None) -> BoidsTaskClass:
        """The task with ``config`` (env fields by flat name; None: the shipped YAML's)."""
        if config is None:
            return self.get_from_yaml()
        return BoidsTaskClass(name=self.name, config=dict(config))

    def get_from_yaml(self, path: str | None = None) -> BoidsTaskClass:
        """The task with the config of the YAML file at ``path`` (None: the one this package
        ships for the task, ``CONF_DIR/task/boids/<task>.yaml``; BenchMARL's own method
        looks in BenchMARL's folder, where the file is not)."""
        if path is None:
            path = str(CONF_DIR / "task" / self.env_name() / f"{self.name.lower()}.yaml")
        config = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
        if config is None:
            config = {}
        if not isinstance(config, dict):
            raise ValueError(f"{path} must hold a mapping of env fields, got "
                             f"{type(config).__name__}")
        config.pop("defaults", None)  # Hydra's list, as BenchMARL's own loader drops it
        return self.get_task(config=config)


# BenchMARL's registry of "env/task" names, which its Hydra loader (and command line) looks
# the task up in; its own environments fill it when benchmarl.environments is imported
for _task in BoidsTask.__members__.values():
    task_config_registry[f"{BoidsTask.env_name()}/{_task.name.lower()}"] = _task


__all__ = ["BoidsTask", "BoidsTaskClass"]
