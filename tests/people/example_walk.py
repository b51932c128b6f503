"""Generates the shipped example walk (``boids_env/world/data/doorway_walk.csv``, the walk
``leader_trajectory="doorway_walk"``) with the pedestrian model: a person in the ``doorway``
scene walking its path (through the door, around the east room and back) at a preferred 0.6
m/s with the default gait and pauses, standing for the first 2 s (the start-up), sampled
every 0.2 s.

    python tests/people/example_walk.py > boids_env/world/data/doorway_walk.csv
"""

from __future__ import annotations

import numpy as np

from boids_env.config import EnvConfig
from boids_env.world.leader import preview_path
from boids_env.world.people import People

SEED = 7
SAMPLE_EVERY = 2
"""Control periods (0.1 s) per row."""
TAIL = 10
"""Periods kept after the person reaches its last goal."""


def example_walk() -> str:
    """The walk's CSV text (t, x, y in s and m, 4 decimals: 0.1 mm)."""
    config = EnvConfig.from_kwargs(scene="doorway", leader="person", leader_speed=0.6)
    sc, dt = config.scenario, config.world.dt
    path = preview_path(sc, dt)
    people = People(config.scene, dt, np.random.default_rng(SEED), person=sc.start,
                    goals=path[1:], speed=sc.leader_speed, gait_variation=sc.gait_variation,
                    goal_pause=sc.goal_pause, startup_time=sc.startup_time, crowd=0,
                    crowd_speed=sc.crowd_speed, radius=sc.person_radius,
                    keep_clear=np.zeros((0, 2)))
    rows = [(0.0, *people.positions[0])]
    done_at = None
    step = 0
    while done_at is None or step < done_at + TAIL:
        people.advance(step * dt)
        step += 1
        if step % SAMPLE_EVERY == 0:
            rows.append((step * dt, *people.positions[0]))
        if people.finished and done_at is None:
            done_at = step
    lines = ["t,x,y"] + [f"{t:.1f},{x:.4f},{y:.4f}" for t, x, y in rows]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(example_walk(), end="")
