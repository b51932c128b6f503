"""A learned episode (and a Reynolds one in a scene with a lidar) is the same bits whatever
BLAS kernel and SIMD level the CPU gets: each run is a fresh process with another OpenBLAS
kernel (``OPENBLAS_CORETYPE``) or numpy's SIMD dispatch turned down
(``NPY_DISABLE_CPU_FEATURES``), as a user's machine would pick them.

Two settings (two OpenBLAS kernels, full SIMD) run every episode to its end, the default case
(746 steps) among them; every setting runs the same episodes cut to ``SHORT`` steps, where a
kernel's or a SIMD level's rounding shows (its first differing bit changes the trajectory from
there on), at a fraction of the time."""

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
horizons = [int(h) for h in sys.argv[2].split()]  # 0: every episode to its end
assert not any(__cpu_features__[f] for f in disabled), "numpy ignored NPY_DISABLE_CPU_FEATURES"
out = {}
episodes = (("learned", {}), ("learned", {"robots": 25, "obs_noise": 0.02, "max_cycles": 300}),
            ("learned", {"scene": "pillars", "max_cycles": 300}),
            ("reynolds", {"scene": "lab", "lidar_rays": 16, "max_cycles": 300}),
            # the study's slow leader: a crowded flock whose separation forces (a
            # cube, norms) once took pow and hypot, which round per CPU
            ("reynolds", {"leader_speed": 0.5}))
for horizon, (spec, fields) in ((h, e) for h in horizons for e in episodes):
    policy = load_policy(spec)
    if horizon:
        fields = {**fields, "max_cycles": horizon}
    env = BoidsEnv(**env_fields_for(policy, fields))
    result = run_episode(env, policy, 3, record=True)
    rec = result.recording
    digest = hashlib.sha256(rec.positions.tobytes() + rec.commanded.tobytes()).hexdigest()
    out[f"{horizon}:{spec}{fields}"] = [digest, result.metrics]
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


SHORT = 120
"""Steps of each episode in every setting (the two full ones run them to the end too)."""


def run(coretype, disabled, full):
    env = {**os.environ, "OPENBLAS_CORETYPE": coretype, "OPENBLAS_VERBOSE": "2",
           "NPY_DISABLE_CPU_FEATURES": " ".join(disabled)}
    horizons = f"0 {SHORT}" if full else str(SHORT)
    done = subprocess.run([sys.executable, "-c", EPISODE, " ".join(disabled), horizons],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    core = next((line for line in done.stderr.splitlines() if line.startswith("Core:")), None)
    return json.loads(done.stdout), core


def test_learned_episodes_are_bit_identical_on_every_blas_kernel_and_simd_level():
    targets = dispatch_targets()
    settings = [("Haswell", [], True), ("Prescott", [], True), ("Haswell", targets[1:], False),
                ("Prescott", targets, False)]
    if avx512():
        settings += [("SkylakeX", [], False), ("SkylakeX", targets, False)]
    runs = {setting_name(*s): run(*s) for s in settings}
    (first_name, (first, _)), *others = runs.items()
    assert len(first) == 10 and first["0:learned{}"][1]["steps"] > 700, "the default case"
    for name, (result, _) in others:
        for episode, (digest, metrics) in first.items():
            if episode in result or not episode.startswith("0:"):
                assert result[episode][1] == metrics, f"{episode}: {name} vs {first_name}"
                assert result[episode][0] == digest, (
                    f"{episode} trajectory: {name} vs {first_name}")
    assert "0:learned{}" in runs[setting_name(*settings[1])][0], "two kernels run it all"
    cores = {core for _, core in runs.values()}
    assert len(cores) >= 2 or cores == {None}, f"OpenBLAS ignored OPENBLAS_CORETYPE: {cores}"


def setting_name(coretype, disabled, full):
    return (f"OPENBLAS_CORETYPE={coretype} NPY_DISABLE_CPU_FEATURES={' '.join(disabled)!r}"
            f"{' (full episodes)' if full else ''}")
