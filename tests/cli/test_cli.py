"""The ``boids`` command's arguments: every spelling of a policy, paths, extras, interrupts."""

import dataclasses
import json
import re

import pytest

from boids_env import extras
from boids_env.train.cli import build_parser, main

SHORT = ["--robots", "5", "--max-cycles", "25"]


def test_run_accepts_a_policy_class_by_module_path(tmp_path, capsys):
    spec = "boids_env.policies.reynolds:ReynoldsPolicy"
    assert main(["run", "--policy", spec, *SHORT, "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "metrics.json").read_text())["steps"] == 25
    assert f"policy {spec} ·" in capsys.readouterr().out


def test_run_accepts_a_preset_after_at(tmp_path, capsys):
    assert main(["run", "--policy", "reynolds@boids_ros", *SHORT, "--out", str(tmp_path)]) == 0
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["preset"] == "boids_ros"
    assert config["policy_params"]["horizon"] == 0.75
    assert "preset boids_ros" in capsys.readouterr().out


def test_run_prints_no_preset_for_a_policy_without_one(tmp_path, capsys):
    assert main(["run", "--policy", "random", *SHORT, "--out", str(tmp_path)]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("policy random ·") and "preset" not in first
    assert json.loads((tmp_path / "config.json").read_text())["preset"] is None


def test_run_help_lists_every_builtin_policy():
    text = build_parser()._subparsers._group_actions[0].choices["run"].format_help()
    text = re.sub(r"-\s+", "-", text)  # argparse wraps lines after hyphens
    for name in ("reynolds", "boids_ros", "random", "learned", "learned-study", ".zip",
                 "module:object"):
        assert name in text, name


def test_run_drives_a_waypoint_path(tmp_path):
    assert main(["run", "--path", "waypoints", "--waypoints", "0,1 -1,1", "--robots", "4",
                 "--out", str(tmp_path)]) == 0
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["env"]["scenario"]["waypoints"] == [[0.0, 1.0], [-1.0, 1.0]]
    # the leader reached its last target: the episode ended on its own, not at a step limit
    assert json.loads((tmp_path / "metrics.json").read_text())["steps"] < 100


def test_waypoint_path_without_waypoints_is_a_clear_error(tmp_path, capsys):
    assert main(["run", "--path", "waypoints", "--out", str(tmp_path / "o")]) == 2
    assert "--waypoints" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    with pytest.raises(SystemExit):
        main(["run", "--path", "waypoints", "--waypoints", "1;x"])


def test_a_missing_extra_is_named_before_any_work(tmp_path, capsys, monkeypatch):
    real = extras.importlib.util.find_spec
    monkeypatch.setattr(extras.importlib.util, "find_spec",
                        lambda name: None if name == "rosbags" else real(name))
    out = tmp_path / "o"
    assert main(["run", "--bag", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pip install 'boids-env[ros]'" in err and "rosbags" in err
    assert not out.exists()


def test_missing_train_extra_gives_the_torch_hint(monkeypatch):
    monkeypatch.setattr(extras.importlib.util, "find_spec",
                        lambda name: None if name == "torch" else object())
    with pytest.raises(extras.MissingExtraError, match=r"boids-env\[train\].*CPU build"):
        extras.require("train", purpose="boids train")


def test_ctrl_c_is_a_short_message_and_exit_130(tmp_path, capsys, monkeypatch):
    import boids_env.eval.runner as runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_suite", interrupted)
    assert main(["eval", "--out", str(tmp_path)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted" in err[0] and str(tmp_path) in err[0]


def test_train_config_accepts_a_shipped_recipe_name():
    from boids_env.train.config import TrainConfig, resolve_recipe

    path = resolve_recipe("ppo_safe")
    assert path.is_file() and TrainConfig.from_toml(path).algorithm == "ppo"
    with pytest.raises(FileNotFoundError, match="shipped recipe"):
        resolve_recipe("no_such_recipe")


def _recipes():
    from boids_env.train.config import RECIPES

    return sorted(p.stem for p in RECIPES.glob("*.toml"))


def test_the_recipes_are_the_documented_ones():
    assert _recipes() == ["ppo_person", "ppo_safe", "ppo_safe_stage2", "ppo_study"]


@pytest.mark.parametrize("name", _recipes())
def test_every_shipped_recipe_builds_its_env(name):
    from boids_env import BoidsEnv
    from boids_env.train.config import TrainConfig, resolve_recipe

    config = TrainConfig.from_toml(resolve_recipe(name))
    env = BoidsEnv(robots=max(config.group_sizes), **config.env_fields)
    env.reset(seed=0)
    relative = config.env_fields.get("relative_actions", False)
    assert env.action_space("follower_1").high[0] == pytest.approx(1.0 if relative else 0.5)
    assert relative == (name in ("ppo_person", "ppo_safe", "ppo_safe_stage2"))


def test_stage2_continues_a_ppo_safe_run():
    # ppo_safe_stage2 resumes a ppo_safe model: the same observations, actions and draws, more
    # steps, its exploration restarted, and a stronger wall term
    from boids_env.train.config import TrainConfig, resolve_recipe

    first, second = (TrainConfig.from_toml(resolve_recipe(n))
                     for n in ("ppo_safe", "ppo_safe_stage2"))
    wall = {"reward_wall", "wall_distance"}
    assert {k: v for k, v in second.env_fields.items() if k not in wall} == first.env_fields
    assert dataclasses.replace(second, total_timesteps=first.total_timesteps,
                               env_fields=first.env_fields, resume_log_std=None) == first
    assert second.total_timesteps > first.total_timesteps
    assert first.resume_log_std is None and second.resume_log_std is not None


def test_whole_rollouts_rounds_up_to_what_ppo_runs():
    from boids_env.train.config import TrainConfig
    from boids_env.train.run import whole_rollouts

    config = TrainConfig(n_steps=256)
    assert whole_rollouts(config, 36, 5000) == 256 * 36
    assert whole_rollouts(config, 36, 256 * 36 * 2) == 256 * 36 * 2
    assert whole_rollouts(TrainConfig(algorithm="sac", train_freq=1), 36, 50) == 72
