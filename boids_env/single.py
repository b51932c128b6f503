"""A Gymnasium view of one follower, for single-agent tools (``gymnasium.utils.env_checker``,
single-agent RL libraries). The other followers, if any, are driven by ``others``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from boids_env.environment import BoidsEnv

OthersFn = Callable[[Mapping[str, np.ndarray]], dict[str, npt.ArrayLike]]


class SingleFollowerEnv(gym.Env[np.ndarray, np.ndarray]):
    """Controls ``agent`` of a :class:`BoidsEnv`; ``others`` maps the remaining followers'
    observations to their actions (default: zero velocity). Keyword arguments are env fields;
    the default group is the leader and one follower (``robots=2``)."""

    metadata = BoidsEnv.metadata

    def __init__(self, agent: str = "follower_1", others: OthersFn | None = None,
                 render_mode: str | None = None, **fields: Any) -> None:
        fields.setdefault("robots", 2)
        self.par = BoidsEnv(render_mode=render_mode, **fields)
        if agent not in self.par.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents: {self.par.possible_agents}")
        self.agent = agent
        self.others = others
        self.render_mode = render_mode
        self.observation_space = self.par.observation_space(agent)
        self.action_space = self.par.action_space(agent)
        self._obs: dict[str, np.ndarray] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._obs, infos = self.par.reset(seed=seed, options=options)
        return self._obs[self.agent], infos[self.agent]

    def step(self, action: npt.ArrayLike) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        rest = {a: o for a, o in self._obs.items() if a != self.agent}
        actions: dict[str, npt.ArrayLike] = (dict(self.others(rest)) if self.others and rest
                                             else {a: np.zeros(2) for a in rest})
        actions[self.agent] = action
        self._obs, rew, term, trunc, info = self.par.step(actions)
        a = self.agent
        return self._obs[a], rew[a], term[a], trunc[a], info[a]

    # gymnasium's Env.render returns its own unbound TypeVar (RenderFrame), which no concrete
    # override matches; the frame is the parallel env's (an RGB array, or None)
    def render(self) -> np.ndarray | None:  # type: ignore[override]
        return self.par.render()

    def close(self) -> None:
        self.par.close()
