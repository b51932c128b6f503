"""A learned episode (and a Reynolds one in a scene with a lidar) is the same bits whatever
BLAS kernel and SIMD level the CPU gets: each run is a fresh process with another OpenBLAS
kernel (``OPENBLAS_CORETYPE``) or numpy's SIMD dispatch turned down
(``NPY_DISABLE_CPU_FEATURES``), as a user's machine would pick them."""

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

EPISODE = """
import hashlib, json, sys
import numpy as np
from numpy._core._multiarray_umath import __cpu_features__
from boids_env import BoidsEnv
from boids_env.eval.episode import env_fields_for, run_episode
from boids_env.policies.registry import load_policy
disabled = [f for f in sys.argv[1].split() if f]
assert not any(__cpu_features__[f] for f in disabled), "numpy ignored NPY_DISABLE_CPU_FEATURES"
out = {}
for spec, fields in (("learned", {}), ("learned", {"robots": 25, "obs_noise": 0.02,
                                                    "max_cycles": 300}),
                     ("learned", {"scene": "pillars", "max_cycles": 300}),
                     ("reynolds", {"scene": "lab", "lidar_rays": 16, "max_cycles": 300}),
                     # the study's slow leader: a crowded flock whose separation forces (a
                     # cube, norms) once took pow and hypot, which round per CPU
                     ("reynolds", {"leader_speed": 0.5})):
    policy = load_policy(spec)
    env = BoidsEnv(**env_fields_for(policy, fields))
    result = run_episode(env, policy, 3, record=True)
    rec = result.recording
    digest = hashlib.sha256(rec.positions.tobytes() + rec.commanded.tobytes()).hexdigest()
    out[f"{spec}{fields}"] = [digest, result.metrics]
print(json.dumps(out))
"""


def dispatch_targets():
    """numpy's SIMD dispatch targets this CPU has (the names differ between numpy versions)."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    return [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]


def avx512() -> bool:
    """Whether this CPU runs AVX-512 code (OpenBLAS's SkylakeX kernel dies of SIGILL
    without it)."""
    try:
        with open("/proc/cpuinfo") as f:
            return "avx512f" in f.read().split()
    except OSError:
        return False


def run(coretype, disabled):
    env = {**os.environ, "OPENBLAS_CORETYPE": coretype, "OPENBLAS_VERBOSE": "2",
           "NPY_DISABLE_CPU_FEATURES": " ".join(disabled)}
    done = subprocess.run([sys.executable, "-c", EPISODE, " ".join(disabled)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    core = next((line for line in done.stderr.splitlines() if line.startswith("Core:")), None)
    return json.loads(done.stdout), core


def test_learned_episodes_are_bit_identical_on_every_blas_kernel_and_simd_level():
    targets = dispatch_targets()
    settings = [("Haswell", []), ("Prescott", []), ("Haswell", targets[1:]),
                ("Prescott", targets)]
    if avx512():
        settings += [("SkylakeX", []), ("SkylakeX", targets)]
    runs = {setting_name(*s): run(*s) for s in settings}
    (first_name, (first, _)), *others = runs.items()
    for name, (result, _) in others:
        for episode, (digest, metrics) in first.items():
            assert result[episode][1] == metrics, f"{episode}: {name} vs {first_name}"
            assert result[episode][0] == digest, f"{episode} trajectory: {name} vs {first_name}"
    cores = {core for _, core in runs.values()}
    assert len(cores) >= 2 or cores == {None}, f"OpenBLAS ignored OPENBLAS_CORETYPE: {cores}"


def setting_name(coretype, disabled):
    return f"OPENBLAS_CORETYPE={coretype} NPY_DISABLE_CPU_FEATURES={' '.join(disabled)!r}"
