"""Policy specs: ``module:object`` builds the object (issue 14 item 3) and every spec can be
checked before any side effect without building the policy."""

import sys

import pytest

from boids_env.policies.registry import LEARNED_MODEL, check_policy_spec, load_policy
from boids_env.policies.reynolds import ReynoldsPolicy


class Counting:
    """A tiny Policy class (built with no arguments)."""

    def reset(self, seed=None):
        pass

    def act(self, obs):
        return {agent: (0.0, 0.0) for agent in obs}


INSTANCE = Counting()
NOT_A_POLICY = 42


def make_counting():
    return Counting()


@pytest.fixture
def here(monkeypatch):
    """This test module importable as ``policy_specs_here``."""
    monkeypatch.setitem(sys.modules, "policy_specs_here", sys.modules[__name__])
    return "policy_specs_here"


def test_module_class_specs_are_instantiated(here):
    policy = load_policy("boids_env.policies.reynolds:ReynoldsPolicy")
    assert isinstance(policy, ReynoldsPolicy), "a class is built, not returned"
    assert isinstance(load_policy(f"{here}:Counting"), Counting)
    assert load_policy(f"{here}:INSTANCE") is INSTANCE
    assert isinstance(load_policy(f"{here}:make_counting"), Counting)


@pytest.mark.parametrize("spec", ["reynolds", "reynolds@boids_ros", "random", "learned",
                                  "learned-study", "learned-scenes", str(LEARNED_MODEL),
                                  "boids_env.policies.reynolds:ReynoldsPolicy"])
def test_good_specs_pass_the_check(spec):
    check_policy_spec(spec)


def test_bad_specs_are_refused_without_building_anything(tmp_path, here):
    with pytest.raises(ValueError, match=r"cannot import policy 'no_such_mod:P': "
                                         r"ModuleNotFoundError.*PYTHONPATH"):
        check_policy_spec("no_such_mod:P")
    with pytest.raises(ValueError, match=r"has no attribute 'Missing'"):
        check_policy_spec(f"{here}:Missing")
    with pytest.raises(TypeError, match=r"is not a Policy.*got int"):
        check_policy_spec(f"{here}:NOT_A_POLICY")
    with pytest.raises(ValueError, match=r"needs both parts"):
        check_policy_spec(":Counting")
    with pytest.raises(FileNotFoundError, match="policy model file not found"):
        check_policy_spec(str(tmp_path / "none.zip"))
    junk = tmp_path / "junk.zip"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="cannot read SB3 model"):
        check_policy_spec(str(junk))
    with pytest.raises(ValueError, match="policy must be one of"):
        check_policy_spec("reynold")
    with pytest.raises(ValueError, match="only reynolds takes a @preset"):
        check_policy_spec("random@paper")


def test_a_zip_that_is_no_model_is_refused_by_the_check(tmp_path):
    """A zip without a model in it (or with a broken stored actor) was let through the check
    and failed in every episode of boids eval instead."""
    import zipfile

    from boids_env.policies.mlp_actor import ACTOR_ENTRY

    empty = tmp_path / "empty.zip"
    with zipfile.ZipFile(empty, "w") as archive:
        archive.writestr("notes.txt", "hello")
    with pytest.raises(ValueError, match=r"empty\.zip is not a Stable-Baselines3 model.*"
                                         r"lacks data, policy\.pth"):
        check_policy_spec(str(empty))
    broken = tmp_path / "broken.zip"
    with zipfile.ZipFile(broken, "w") as archive:
        archive.writestr(ACTOR_ENTRY, b"not an npz")
    with pytest.raises(ValueError, match=r"broken\.zip.*not a stored MLP actor"):
        check_policy_spec(str(broken))


def test_a_module_that_fails_to_import_is_a_value_error(tmp_path, monkeypatch):
    (tmp_path / "broken_policy_mod.py").write_text("def oops(:\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match=r"cannot import policy 'broken_policy_mod:P': "
                                         r"SyntaxError"):
        load_policy("broken_policy_mod:P")
