"""The per-agent edges of :class:`~boids_env.environment.BoidsEnv`'s PettingZoo APIs: the
dict API's actions checked and stacked into the arrays the step runs on
(:func:`parse_actions`), and the AEC conversion that checks each action when it is given
(:class:`BoidsAECWrapper`)."""

from __future__ import annotations

from collections.abc import Mapping
from operator import attrgetter
from typing import Any

import numpy as np
import numpy.typing as npt
from pettingzoo.utils.conversions import parallel_to_aec_wrapper

from boids_env.vectors import as_velocities


def parse_actions(actions: Mapping[str, npt.ArrayLike], agents: list[str],
                  live: frozenset[str]) -> npt.NDArray[np.float64]:
    """The actions (F, 2) of ``agents`` in their order, from a mapping that must name
    exactly them (``live``: the same names as a set); ``TypeError``, ``KeyError`` or
    ``ValueError`` naming the agent otherwise. A NaN or inf passes here: the step's speed
    limit refuses it, before anything moves."""
    if type(actions) is not dict and not isinstance(actions, Mapping):  # ABC check: slow
        raise TypeError(f"actions must be a dict of agent -> (vx, vy), got "
                        f"{type(actions).__name__}")
    if len(actions) != len(agents) or (
            actions.keys() != live if type(actions) is dict  # one set comparison
            else not all(a in actions for a in agents)):
        unknown = sorted(str(a) for a in actions if a not in agents)
        missing = [a for a in agents if a not in actions]
        raise KeyError(f"actions must hold exactly the live agents; unknown: {unknown}, "
                       f"missing: {missing}")
    values = list(map(actions.__getitem__, agents))
    arr = _real_pairs(values)  # the common case: what policies return
    if arr is None:
        return np.stack([as_velocities(v, f"action of {a}", (2,))
                         for a, v in zip(agents, values, strict=True)])
    return arr


_DTYPE = attrgetter("dtype")


def _real_pairs(values: list[Any]) -> npt.NDArray[np.float64] | None:
    """``values`` stacked (F, 2) as float64 if every one is an array of shape (2,) with an
    integer or float dtype, else None (the caller parses each value with its error
    messages). The checks are three C calls, not a Python test per value: the set of
    dtypes (a value without one, a list or a float, is not an array), their kinds, and the
    stacked shape, which is (F, 2) only if every value has shape (2,) (a numpy scalar, of
    shape (), or a value of any other shape gives another, or no stack at all)."""
    try:
        dtypes = set(map(_DTYPE, values))
        real = (dtypes.pop().kind in "iuf" if len(dtypes) == 1  # the common case
                else all(dtype.kind in "iuf" for dtype in dtypes))
    except (AttributeError, TypeError):  # no dtype, or not numpy's (a tensor's)
        return None
    if not real:
        return None
    try:
        arr = np.array(values, dtype=np.float64)
    except (ValueError, TypeError):  # shapes that differ; an object that cannot convert
        return None
    return arr if arr.shape == (len(values), 2) else None


class BoidsAECWrapper(parallel_to_aec_wrapper):
    """PettingZoo's parallel-to-AEC conversion, checking each action when it is given: the
    conversion caches actions until the last agent's, so a bad one would otherwise stay cached
    (and fail every later step) after the error."""

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        live = not (self.terminations.get(agent) or self.truncations.get(agent))
        if live:
            as_velocities(action, f"action of {agent}", (2,))
        super().step(action)
