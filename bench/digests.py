"""Digests of episodes, to compare machines: ``python -m boids_env.bench.digests [--out F]``.

Prints (and writes, with ``--out``) a JSON object: for each episode, the SHA-256 of every
position and command (16 hex digits, as ``tests/env/test_golden.py`` pins them) and its
metrics. Run it on two machines and compare the files: the docs (explanation/guarantees)
say which figures are exact on every CPU; this checks it on yours.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.files import write_text

EPISODES: tuple[tuple[str, dict[str, Any], int], ...] = (
    ("reynolds", {}, 0),
    ("reynolds", {"leader_speed": 0.5}, 4),
    ("reynolds", {"path": "circle", "path_rotation": 30.0}, 1),
    ("reynolds", {"scene": "lab", "lidar_rays": 16, "max_cycles": 300}, 3),
    ("reynolds", {"robot": "turtlebot3_burger", "max_cycles": 400}, 3),
    ("learned", {}, 0),
    ("learned", {"robots": 25, "obs_noise": 0.02, "max_cycles": 300}, 3),
    ("learned-scenes", {"scene": "doorway", "max_cycles": 300}, 3),
)
"""(policy, env fields, seed) of the compared episodes: the study's default, a slow leader
(the case whose Reynolds forces once differed between AVX2 and AVX-512 machines), a turned
circle, a map with a lidar, a TurtleBot3 flock, and learned policies acting in numpy."""


def digest(positions: np.ndarray, commanded: np.ndarray) -> str:
    """16 hex digits of the SHA-256 of an episode's positions then commands."""
    data = np.ascontiguousarray(positions).tobytes() + np.ascontiguousarray(commanded).tobytes()
    return hashlib.sha256(data).hexdigest()[:16]


def digests() -> dict[str, Any]:
    """Every episode of :data:`EPISODES`: its digest and metrics, keyed by a readable name."""
    from boids_env import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.registry import load_policy

    out: dict[str, Any] = {"python": platform.python_version(),
                           "numpy": np.__version__, "episodes": {}}
    for spec, fields, seed in EPISODES:
        policy = load_policy(spec)
        env = BoidsEnv(**env_fields_for(policy, fields))
        result = run_episode(env, policy, seed, record=True)
        rec = result.recording
        out["episodes"][f"{spec} {json.dumps(fields, sort_keys=True)} seed {seed}"] = {
            "digest": digest(rec.positions, rec.commanded), "metrics": result.metrics}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m boids_env.bench.digests",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args(argv)
    text = json.dumps(digests(), indent=1, sort_keys=True, default=float)
    print(text)
    if args.out:
        write_text(Path(args.out), text + "\n")  # atomic: no torn file on a kill
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
