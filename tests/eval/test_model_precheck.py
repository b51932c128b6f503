"""Issue 39: a model zip whose weights do not load, or whose network takes observations of
another size than the suite's envs give, is refused by boids eval's check before anything is
written or any worker starts (it used to pass the check and fail every episode)."""

import zipfile

import numpy as np
import pytest

from boids_env.eval.runner import PolicySpec, run_suite
from boids_env.eval.suites import suite_from_dict
from boids_env.policies.mlp_actor import ACTOR_ENTRY, MLPActor
from boids_env.policies.registry import LEARNED_MODEL

SUITE = suite_from_dict({"seeds": 1, "defaults": {"max_cycles": 3},
                         "case": [{"name": "one"}]})


def _copy(path, replace):
    with zipfile.ZipFile(LEARNED_MODEL) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            if name in replace:
                if replace[name] is not None:
                    dst.writestr(name, replace[name])
            else:
                dst.writestr(name, src.read(name))
    return path


def test_a_zip_whose_policy_pth_is_broken_is_refused_before_the_run(tmp_path):
    pytest.importorskip("torch")
    model = _copy(tmp_path / "bad.zip", {ACTOR_ENTRY: None, "policy.pth": b"not weights"})
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=r"policy\.pth is not a plain table of weights"):
        run_suite([PolicySpec.parse(str(model))], SUITE, out, progress=False)
    assert not out.exists()


def test_a_network_of_another_observation_size_is_refused_before_the_run(tmp_path):
    actor = MLPActor([np.zeros((4, 5), np.float32), np.zeros((2, 4), np.float32)],
                     [np.zeros(4, np.float32), np.zeros(2, np.float32)], "tanh",
                     [-0.5, -0.5], [0.5, 0.5])
    model = _copy(tmp_path / "small.zip", {ACTOR_ENTRY: actor.to_bytes()})
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=r"takes observations of size 5, the env gives"):
        run_suite([PolicySpec.parse(str(model))], SUITE, out, progress=False)
    assert not out.exists()
