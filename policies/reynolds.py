"""The study's reference controller: three Reynolds rules plus leader following (DESIGN §3).

Computed from observations only, through the named layout, for all followers in one numpy pass.
Per follower, with neighbours j (0 < |r_j| ≤ horizon, the leader included), r_j relative
position, v_j their velocity, v own velocity and clip(x, L) = x·L/|x| when |x| > L:

- cohesion   F_coh = (max_force / horizon) · mean_j r_j                (0 without neighbours)
- separation F_sep = clip(mean_{|r_j| < d_sep} (−r_j / |r_j|³), 2·max_force)   (0 if none)
- alignment  F_ali = clip(u − v, max_force), u = Σ_j v_j rescaled to max_speed (direction +x
  when the sum is zero, as the original; 0 without neighbours)
- leader     F_lead = p_leader − p_i (metres, unscaled)
- F = clip(Σ w·F, max_force);  command = clip(v + F / mass · dt, max_speed)
- zero command for the first ``startup_time`` seconds after reset.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.config import ReynoldsParams, reynolds_params
from boids_env.observations import ObservationLayout
from boids_env.policies.base import BatchPolicy

FloatArray = npt.NDArray[np.float64]
RULES = ("separation", "cohesion", "alignment", "leader")


def clip_norm(x: FloatArray, limit: float) -> FloatArray:
    """Scales rows of ``x`` (..., 2) whose norm exceeds ``limit`` down to ``limit``."""
    norm = np.hypot(x[..., 0], x[..., 1])
    # min(1, limit / norm) is exactly 1 where the norm is within the limit (or zero)
    scale = np.minimum(1.0, limit / np.maximum(norm, 1e-300))
    return x * scale[..., None]


def reynolds_forces(rel: FloatArray, vel: FloatArray, valid: npt.NDArray[np.bool_],
                    own_velocity: FloatArray, leader_offset: FloatArray, p: ReynoldsParams
                    ) -> dict[str, FloatArray]:
    """The four unweighted rule forces (F, 2) from neighbour arrays.

    Args:
        rel: (F, K, 2) neighbour positions relative to each follower (m).
        vel: (F, K, 2) neighbour velocities (m/s).
        valid: (F, K) which slots hold a neighbour.
        own_velocity: (F, 2) each follower's velocity.
        leader_offset: (F, 2) leader position relative to each follower.
        p: controller parameters.
    """
    dist = np.sqrt(np.einsum("fkd,fkd->fk", rel, rel))
    near = valid & (dist > 0) & (dist <= p.horizon)
    nearf = near.astype(float)
    count = nearf.sum(axis=1)[:, None]
    has = count > 0
    # Sums over the neighbour slots as (F, K) x (F, K, 2) contractions.
    mean_rel = np.einsum("fk,fkd->fd", nearf, rel) / np.maximum(count, 1)
    cohesion = (p.max_force / p.horizon) * mean_rel

    close = near & (dist < p.desired_separation)
    n_close = close.sum(axis=1)[:, None]
    inv_cube = np.divide(1.0, dist**3, out=np.zeros_like(dist), where=close)
    push = -np.einsum("fk,fkd->fd", inv_cube, rel) / np.maximum(n_close, 1)
    separation = clip_norm(push, 2 * p.max_force)

    total = np.einsum("fk,fkd->fd", nearf, vel)
    norm = np.sqrt(np.einsum("fd,fd->f", total, total))[:, None]
    direction = np.where(norm > 0, total / np.where(norm > 0, norm, 1.0), [1.0, 0.0])
    alignment = clip_norm(direction * p.max_speed - own_velocity, p.max_force) * has
    return {"separation": separation, "cohesion": cohesion, "alignment": alignment,
            "leader": np.array(leader_offset, dtype=float)}


def reynolds_command(forces: dict[str, FloatArray], own_velocity: FloatArray,
                     p: ReynoldsParams) -> tuple[FloatArray, dict[str, FloatArray]]:
    """Combines the rule forces into the commanded velocity; returns it and weighted forces."""
    weights = {"separation": p.separation_weight, "cohesion": p.cohesion_weight,
               "alignment": p.alignment_weight, "leader": p.leader_weight}
    weighted = {name: weights[name] * forces[name] for name in RULES}
    total = clip_norm(sum(weighted.values()), p.max_force)
    command = clip_norm(own_velocity + total / p.mass * p.dt, p.max_speed)
    return command, weighted


class ReynoldsPolicy(BatchPolicy):
    """Reynolds + leader controller of the study, reading observations only.

    ``ReynoldsPolicy(preset="paper", **overrides)``: the ``paper`` (Table IV) or ``boids_ros``
    (original code) parameters, any :class:`~boids_env.config.ReynoldsParams` field
    overridden (``leader_weight=1.2``). After each :meth:`act`, :attr:`forces` holds each
    rule's weighted force per follower (for drawing).
    """

    def __init__(self, preset: str = "paper", **overrides: Any) -> None:
        self.params = reynolds_params(preset, **overrides)
        self.preset = preset
        self.forces: dict[str, FloatArray] = {}
        self._steps = 0
        self._last_command = np.zeros((0, 2))

    def reset(self, seed: int | None = None) -> None:
        self._steps = 0
        self.forces = {}

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        obs = np.asarray(obs, dtype=np.float64)
        layout = ObservationLayout.for_size(obs.shape[1])
        p = self.params
        holding = self._steps * p.dt < p.startup_time - 1e-9
        self._steps += 1
        if holding:
            self.forces = {name: np.zeros((len(obs), 2)) for name in RULES}
            return np.zeros((len(obs), 2), dtype=np.float32)
        slots = layout.slots(obs)
        own = obs[:, layout.own_velocity]
        forces = reynolds_forces(layout.slot_position(slots), layout.slot_velocity(slots),
                                 layout.slot_valid(slots) > 0.5, own,
                                 obs[:, layout.leader_position], p)
        command, self.forces = reynolds_command(forces, own, p)
        self._last_command = command
        return command.astype(np.float32)
