"""The study's cases stay bit-identical: trajectories and metrics of the Reynolds flock pinned
from the code before scenes, robot models and people were added (commit e649aa0). Two
trajectories were re-pinned once, when 2×2 rotations became elementwise products so that they
round the same on every CPU (a turned circle and the leader frame: their metrics unchanged).
Two again when the Reynolds forces stopped taking ``pow`` and ``hypot`` (the slow leader with
weight 1.2: its pinned bits came from an AVX-512 machine's SIMD ``pow``; an AVX2 machine gave
others) and the curves stopped taking numpy's ``sin``/``cos`` (the circle): the last digit of
the mean leader distance moved in each, nothing else. Both are now the same bits on AVX2 and
AVX-512 machines (checked on both).

Every case is the ideal arena (or an opt-in of that era); the SHA-256 covers every position
and command of the episode, so any change to the physics, the leader, the observations, the
policy or the metrics of these cases fails here.
"""

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy

CASES = json.loads((Path(__file__).parent / "golden_reynolds.json").read_text())


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c['fields']}-{c['policy']}-{c['seed']}")
def test_study_era_cases_are_bit_identical(case):
    env = parallel_env(**case["fields"])
    result = run_episode(env, ReynoldsPolicy(**case["policy"]), seed=case["seed"])
    rec = result.recording
    digest = hashlib.sha256(np.ascontiguousarray(rec.positions).tobytes()
                            + np.ascontiguousarray(rec.commanded).tobytes()).hexdigest()[:16]
    assert digest == case["sha"], f"trajectory of {case['fields']} seed {case['seed']} changed"
    for key, want in case.items():
        if key not in ("fields", "policy", "seed", "sha"):
            assert result.metrics[key] == want, f"{key}: {result.metrics[key]!r} != {want!r}"
