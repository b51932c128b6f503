"""What a learned model changes in the world is never silent (issue 39 item 8): settings that
contradict its training (the frame it observes in, relative actions, its control period) are
refused wherever it is bound to an env; the world changes its env fields make for its own
episodes, and the fields a case overrides, are recorded in the manifest and shown in the
report (``boids eval``) or in ``config.json`` (``boids run``)."""

import json

import pytest

from boids_env import parallel_env
from boids_env.eval.episode import env_fields_for, run_episode
from boids_env.eval.folder import MANIFEST
from boids_env.eval.report import build_report
from boids_env.eval.runner import PolicySpec, run_suite
from boids_env.eval.suites import suite_from_dict
from boids_env.policies.registry import LEARNED_MODEL, load_policy
from boids_env.policies.sb3_policy import read_meta, write_meta
from boids_env.train.cli import main


@pytest.mark.parametrize(("setting", "trained"), [
    ({"frame": "world"}, "frame='leader'"),
    ({"relative_actions": False}, "relative_actions=True"),
    ({"dt": 0.05}, "dt=0.1"),
])
def test_a_setting_against_the_models_training_is_refused(setting, trained):
    policy = load_policy("learned")
    env = parallel_env(**env_fields_for(policy, {"robots": 4, "max_cycles": 5, **setting}))
    with pytest.raises(ValueError, match=rf"trained with {trained}.*this env has"):
        run_episode(env, policy, seed=0)


def test_boids_run_set_against_a_learned_models_training_is_refused(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "--policy", "learned", "--set", "frame=world", "--max-cycles", "5",
                 "--out", str(out)])
    assert code == 2
    assert "trained with frame='leader'" in capsys.readouterr().err
    assert not out.exists()


def _slow_model(tmp_path):
    """The shipped model with max_speed 0.3 in its env fields (the world of its episodes)."""
    path = tmp_path / "slow.zip"
    path.write_bytes(LEARNED_MODEL.read_bytes())
    meta = read_meta(path)
    write_meta(path, {**meta, "env_fields": {**meta["env_fields"], "max_speed": 0.3}})
    return path


def test_a_models_world_changes_are_in_the_manifest_and_the_report(tmp_path):
    # issue 39 item 8: a model's env fields changed the world of its episodes only (max_speed
    # 0.3 while Reynolds ran at 0.5 under the same case names), and nothing said so
    model = _slow_model(tmp_path)
    suite = suite_from_dict({"name": "w", "seeds": 1, "defaults": {"robots": 4,
                                                                   "max_cycles": 10},
                             "factor": [{"name": "leader_speed", "levels": [0.5, 0.55]}]})
    out = tmp_path / "out"
    run_suite([PolicySpec("reynolds"), PolicySpec(str(model))], suite, out, workers=1,
              progress=False)
    changes = json.loads((out / MANIFEST).read_text())["world_changes"]
    assert set(changes) == {"slow"}, "Reynolds changes nothing"
    for case in ("leader_speed=0.5", "leader_speed=0.55"):
        assert changes["slow"][case]["changed"] == {"max_speed": [0.5, 0.3],
                                                    "startup_hold": [False, True]}
    text = build_report(out).read_text()
    assert "## Worlds changed by a policy" in text
    section = text.split("## Worlds changed by a policy")[1].split("\n## ")[0].replace("\\", "")
    assert "slow" in section and "max_speed" in section and "0.3" in section


def test_a_case_overriding_a_models_world_field_is_recorded(tmp_path):
    model = _slow_model(tmp_path)
    out = tmp_path / "run"
    assert main(["run", "--policy", str(model), "--set", "max_speed=0.4", "--set",
                 "robots=4", "--max-cycles", "5", "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["world_changes"]["untrained"] == {"max_speed": [0.3, 0.4]}
    assert config["world_changes"]["changed"] == {"startup_hold": [False, True]}


def test_a_models_control_period_or_top_speed_is_a_world_change_not_its_frame():
    from types import SimpleNamespace

    from boids_env.eval.episode import world_changes

    model = SimpleNamespace(env_fields={"dt": 0.5, "max_speed": 0.05, "frame": "leader"})
    assert world_changes(model, {}) == {
        "changed": {"dt": [0.1, 0.5], "max_speed": [0.5, 0.05]}, "untrained": {}}
    assert world_changes(model, {"dt": 0.1})["untrained"] == {"dt": [0.5, 0.1]}
    assert world_changes(SimpleNamespace(), {"robots": 4}) == {"changed": {}, "untrained": {}}
