"""Crowded episodes against the physics' invariants: ``python -m boids_env.bench.crowd``.

For each case (a scene, a person leading, a crowd) and seed, one whole episode of a policy:
the fastest pedestrian and robot (measured body speeds, m/s), how deep any robot's body got
into static geometry (its radius minus its centre's clearance, m; a touching robot reads
about 0), and the step count. The docs' people page quotes it.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

CASES: tuple[dict[str, Any], ...] = (
    {"scene": "corridor", "leader": "person", "crowd": 8},
    {"scene": "doorway", "leader": "person", "crowd": 8},
    {"scene": "lab", "leader": "person", "crowd": 10},
    {"scene": "floorplan:7", "leader": "person", "crowd": 8},
)
"""The measured cases: a person among pedestrians in a corridor, a door, the lab and a
generated floor plan."""


def crowded_episode(fields: dict[str, Any], seed: int, policy: str = "reynolds"
                    ) -> dict[str, float]:
    """One episode's figures (see the module doc)."""
    from boids_env import BoidsEnv
    from boids_env.eval.episode import bind_policy, env_fields_for
    from boids_env.policies.registry import load_policy

    pol = load_policy(policy)
    env = BoidsEnv(**env_fields_for(pol, fields))
    obs, _ = env.reset(seed=seed)
    bind_policy(pol, env)
    pol.reset(seed)
    scene, radius = env.config.scene, env.config.world.robot_radius
    out = {"steps": 0, "pedestrian_speed": 0.0, "robot_speed": 0.0, "robot_depth": 0.0}
    episode = getattr(env, "episode", None)  # (the code before the Episode record: _world)
    world = episode.world if episode is not None else env._world
    while env.agents:
        obs, *_ = env.step(pol.act(obs))
        out["steps"] += 1
        robots = slice(1, None) if world.person_leader else slice(None)
        speed = np.hypot(*world.velocities[robots].T).max()
        out["robot_speed"] = max(out["robot_speed"], float(speed))
        depth = radius - scene.clearance(world.positions[robots]).min()
        out["robot_depth"] = max(out["robot_depth"], float(depth))
        if world.p:
            walking = np.hypot(*world.pedestrian_velocities.T).max()
            out["pedestrian_speed"] = max(out["pedestrian_speed"], float(walking))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m boids_env.bench.crowd", description=__doc__)
    p.add_argument("--seeds", type=int, default=2, help="seeds per case (2)")
    p.add_argument("--policy", default="reynolds", help="the followers' policy (reynolds)")
    args = p.parse_args(argv)
    for fields in CASES:
        for seed in range(args.seeds):
            figures = crowded_episode(fields, seed, args.policy)
            print(json.dumps({**fields, "seed": seed, **{k: round(v, 3) for k, v in
                                                         figures.items()}}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
