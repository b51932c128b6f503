"""One follower policy from two learned models, switched by sight: a follower that sees the
leader through free space acts with a model trained for the straight line (``learned-scenes``),
one that does not acts with a model trained to follow the route (route sensing with
``route_leader``). ``learned-buildings`` is such a pair.

The switch is the env's own sight test (:attr:`BoidsEnv.leader_hidden
<boids_env.environment.BoidsEnv.leader_hidden>`, the rows whose leader blocks ``route_leader``
read along the route), so a policy bound to an env reads it there at every step: the in-sight
model then sees exactly the observation it was trained on (the route block dropped), and the
out-of-sight model the route's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.config import FIELD_OWNER
from boids_env.policies.base import BatchPolicy
from boids_env.world.route import SIZE as ROUTE_SIZE

ROUTE_FIELDS = ("route_sensing", "route_leader", "route_cell")
"""The env fields only the out-of-sight model may set (besides its reward's)."""


class SightSwitch(BatchPolicy):
    """Acts with ``seen`` for the followers that see the leader, with ``hidden`` for the
    rest.

    Args:
        seen: a learned policy trained without route sensing (its observation is the env's
            without the ``route`` block, which comes last).
        hidden: a learned policy trained with ``route_sensing`` and ``route_leader``; the
            pair's env fields, layout and card are its own.
        name: the pair's name in tables and messages.

    Its env fields (``seen``'s, which ``hidden`` must share, plus route sensing) are checked
    when it is built; it must then be bound (:meth:`bind`) to the env or ROS controller whose
    observations it acts on.
    """

    def __init__(self, seen: Any, hidden: Any, name: str = "sight-switch") -> None:
        seen_fields = getattr(seen, "env_fields", None)
        hidden_fields = getattr(hidden, "env_fields", None)
        if not isinstance(hidden_fields, dict) or not hidden_fields.get("route_leader"):
            raise ValueError(f"{name}: the out-of-sight model must be trained with "
                             f"route_sensing and route_leader (its env_fields: "
                             f"{hidden_fields})")
        if not isinstance(seen_fields, dict) or any(f in seen_fields for f in ROUTE_FIELDS):
            raise ValueError(f"{name}: the in-sight model must be a learned model trained "
                             f"without route sensing (its env_fields: {seen_fields})")
        differ = sorted(k for k, v in seen_fields.items()
                        if k not in hidden_fields or hidden_fields[k] != v)
        differ += sorted(k for k in hidden_fields if k not in seen_fields
                         and k not in ROUTE_FIELDS and FIELD_OWNER.get(k) != "metrics")
        if differ:
            raise ValueError(f"{name}: the two models were trained in different envs: "
                             + ", ".join(f"{k}={seen_fields.get(k, '(unset)')!r} against "
                                         f"{hidden_fields.get(k, '(unset)')!r}"
                                         for k in differ))
        seen_size, hidden_size = getattr(seen, "obs_size", None), getattr(hidden, "obs_size",
                                                                          None)
        if seen_size is None or hidden_size is None or seen_size + ROUTE_SIZE != hidden_size:
            raise ValueError(f"{name}: the in-sight model must read the out-of-sight model's "
                             f"observation without its {ROUTE_SIZE} route inputs (sizes "
                             f"{seen_size} and {hidden_size})")
        self.seen, self.hidden, self.name = seen, hidden, name
        self.env_fields = dict(hidden_fields)
        self.training_known = True
        self.obs_size = int(hidden_size)
        self.card = getattr(hidden, "card", None)
        layout = getattr(hidden, "observation_layout", None)
        if layout is not None:
            self.observation_layout = layout
        self._source: Any = None

    def bind(self, env: Any) -> None:
        """The env (or ROS controller) whose ``leader_hidden`` switches the two models."""
        if not getattr(env, "layout", None) or not env.layout.route:
            raise ValueError(f"{self.name}: the env has no route sensing (route_sensing and "
                             f"route_leader, the out-of-sight model's env fields)")
        self._source = env

    def reset(self, seed: int | None = None) -> None:
        self.seen.reset(seed)
        self.hidden.reset(seed)

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        """Actions (F, 2): ``seen``'s on the rows whose follower saw the leader at the bound
        env's last observation, ``hidden``'s on the others."""
        if self._source is None:
            raise RuntimeError(f"{self.name} switches on the env's sight test: bind it to "
                               f"the env first (boids_env.eval.episode.bind_policy)")
        hidden = self._source.leader_hidden
        obs = np.asarray(obs)
        if hidden is None or obs.ndim != 2 or len(hidden) != len(obs):
            raise ValueError(f"{self.name}: {len(obs)} observation rows, but the bound env's "
                             f"last observation marked "
                             f"{'none' if hidden is None else len(hidden)} (act on the rows "
                             f"of its last observation, every follower in agent order)")
        if hidden.all():
            return self.hidden.act_batch(obs)
        seen = self.seen.act_batch(np.ascontiguousarray(obs[:, :-ROUTE_SIZE]))
        if not hidden.any():
            return seen
        return np.where(hidden[:, None], self.hidden.act_batch(obs), seen).astype(np.float32)
