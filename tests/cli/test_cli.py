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
    for name in ("reynolds", "boids_ros", "random", "learned", "learned-study",
                 "learned-scenes", ".zip", "module:object"):
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
    assert "pip install -e '.[ros]' (in the boids-env clone)" in err and "rosbags" in err
    assert "boids run --bag needs the ros extra" in err, err
    assert not out.exists()


@pytest.mark.parametrize("argv, needs", [
    (["--leader", "person", "--crowd", "10", "--video"],
     "boids run --leader person --crowd 10 needs the people extra"),
    (["--crowd", "3", "--video"], "boids run --crowd 3 needs the people extra"),
])
def test_a_missing_people_extra_names_the_crowd_not_the_video(argv, needs, tmp_path, capsys,
                                                               monkeypatch):
    real = extras.importlib.util.find_spec
    monkeypatch.setattr(extras.importlib.util, "find_spec",
                        lambda name: None if name == "jupedsim" else real(name))
    assert main(["run", *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert needs in err and "--video" not in err, err
    assert "pip install -e '.[people]'" in err, err


def test_missing_train_extra_gives_the_torch_hint(monkeypatch):
    monkeypatch.setattr(extras.importlib.util, "find_spec",
                        lambda name: None if name == "torch" else object())
    with pytest.raises(extras.MissingExtraError, match=r"'\.\[train\]'.*CPU build"):
        extras.require("train", purpose="boids train")


def test_ctrl_c_is_a_short_message_and_exit_130(tmp_path, capsys, monkeypatch):
    import boids_env.eval.runner as runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_suite", interrupted)
    assert main(["eval", "--out", str(tmp_path)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted" in err[0] and str(tmp_path) in err[0]


@pytest.fixture
def nothing_starts(monkeypatch):
    """The episode, the live window, the evaluation and the ROS node raise if reached: a flag
    refused too late would start them."""
    import boids_env.eval.live as live
    import boids_env.eval.ros.controller as controller
    import boids_env.eval.run as run
    import boids_env.eval.runner as runner

    def started(*args, **kwargs):
        raise AssertionError("the command started its work before refusing the flag")

    for module, name in ((run, "run"), (live, "run_live"), (runner, "run_suite"),
                         (controller, "run_controller")):
        monkeypatch.setattr(module, name, started)


@pytest.mark.parametrize("argv, named", [
    (["run", "--policy", "random", "--leader-weight", "1.1"], "--leader-weight"),
    (["run", "--policy", "learned", "--leader-weight", "1.1"], "--leader-weight"),
    (["run", "--policy", "learned", "--preset", "boids_ros"], "--preset boids_ros"),
    (["run", "--policy", "reynolds@boids_ros", "--preset", "paper"], "--preset paper"),
    (["run", "--render", "human", "--policy", "random", "--leader-weight", "1"],
     "--leader-weight"),
    (["eval", "--policy", "learned", "--policy", "random", "--preset", "boids_ros"],
     "--preset boids_ros"),
    (["ros", "controller", "--policy", "learned", "--leader-weight", "1.1"], "--leader-weight"),
    (["ros", "controller", "--policy", "random", "--preset", "boids_ros"], "--preset"),
])
def test_reynolds_flags_are_refused_for_other_policies(argv, named, tmp_path, capsys,
                                                        nothing_starts):
    out = ["--out", str(tmp_path / "o")] if argv[0] != "ros" else []
    assert main([*argv, *out]) == 2
    err = capsys.readouterr().err
    assert named in err and "reynolds" in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("argv, named", [
    (["--render", "human", "--fast", "0"], r"--fast must be a speed-up in \(0, 1000\]"),
    (["--render", "human", "--fast", "-1"], r"--fast must be .* got -1"),
    (["--render", "human", "--fast", "nan"], r"--fast must be .* got nan"),
    (["--fast", "2"], "--fast .* needs --render human"),
    (["--render", "human", "--video"], r"--video: the live window \(--render human\) writes"),
    (["--render", "human", "--bag", "--overwrite"], "--bag, --overwrite: the live window"),
])
def test_live_window_flags_are_checked(argv, named, tmp_path, capsys, nothing_starts):
    assert main(["run", *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(named, err), err
    assert not (tmp_path / "o").exists()


def test_run_live_refuses_a_bad_fast_factor_before_opening_a_window():
    from boids_env.eval.live import run_live

    with pytest.raises(ValueError, match=r"fast_factor must be in \(0.0, 1000.0\]"):
        run_live(fast_factor=float("nan"))


def test_run_refuses_a_leader_weight_for_another_policy(tmp_path):
    from boids_env.eval.run import run

    with pytest.raises(ValueError, match="leader_weight is a Reynolds parameter"):
        run("random", leader_weight=1.1, out=tmp_path / "o")
    assert not (tmp_path / "o").exists()


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
    assert _recipes() == ["ppo_buildings", "ppo_buildings_stage2", "ppo_crowd", "ppo_crowd_stage2",
                          "ppo_person",
                          "ppo_safe", "ppo_safe_stage2", "ppo_scenes",
                          "ppo_scenes_stage2", "ppo_scenes_stage3", "ppo_scenes_stage4",
                          "ppo_scenes_stage5", "ppo_scenes_stage6", "ppo_scenes_stage7",
                          "ppo_study", "ppo_turtlebot", "ppo_turtlebot_buildings",
                          "ppo_turtlebot_stage2"]


@pytest.mark.parametrize("name", _recipes())
def test_every_shipped_recipe_builds_its_env(name):
    from boids_env import BoidsEnv
    from boids_env.train.config import TrainConfig, resolve_recipe

    config = TrainConfig.from_toml(resolve_recipe(name))
    env = BoidsEnv(robots=max(config.group_sizes), **config.env_fields)
    env.reset(seed=0)
    relative = config.env_fields.get("relative_actions", False)
    top = env.config.world.max_speed  # the robot's (the TurtleBot3's 0.22 m/s)
    assert env.action_space("follower_1").high[0] == pytest.approx(2 * top if relative else top)
    assert relative == (name != "ppo_study")


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


def test_scenes_recipes_keep_the_shipped_observations_and_stage2_adds_the_filter():
    # ppo_scenes fine-tunes the shipped model: the same observation layout and actions;
    # its stage 2 is the same run with the safety filter in the loop
    from boids_env import BoidsEnv
    from boids_env.train.config import TrainConfig, resolve_recipe

    shipped, first, second = (TrainConfig.from_toml(resolve_recipe(n)) for n in (
        "ppo_safe_stage2", "ppo_scenes", "ppo_scenes_stage2"))
    for world in first.worlds:
        env = BoidsEnv(robots=7, **{**first.env_fields, **world})
        assert env.layout == BoidsEnv(**shipped.env_fields).layout, world
    assert {k: v for k, v in second.env_fields.items() if k != "safety_filter"} == \
        first.env_fields
    assert second.env_fields["safety_filter"] is True
    assert dataclasses.replace(second, total_timesteps=first.total_timesteps,
                               env_fields=first.env_fields) == first
    third = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage3"))
    assert third.env_fields == {**second.env_fields, "reward_parked": 10.0}
    assert third.total_timesteps > second.total_timesteps
    # stage 4 (the shipped learned-scenes): the parked term doubled, four 61-robot copies
    fourth = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage4"))
    assert fourth.env_fields == {**third.env_fields, "reward_parked": 20.0}
    assert fourth.total_timesteps > third.total_timesteps
    assert fourth.worlds == third.worlds
    assert fourth.group_sizes.count(61) == 4 and third.group_sizes.count(61) == 2
    # stage 5 (the experiment): stage 4 with two more pillar-field copies, nothing else
    fifth = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage5"))
    assert fifth.env_fields == fourth.env_fields
    assert fifth.total_timesteps > fourth.total_timesteps
    assert fifth.copies == fourth.copies + 2 == len(fifth.worlds) == len(fifth.group_sizes)
    assert fifth.worlds[:16] == fourth.worlds and fifth.group_sizes[:16] == fourth.group_sizes
    assert fifth.worlds[16:] == ({"scene": "pillars"},) * 2 and fifth.group_sizes[16:] == (13, 19)
    assert dataclasses.replace(fifth, total_timesteps=fourth.total_timesteps,
                               worlds=fourth.worlds, group_sizes=fourth.group_sizes,
                               copies=fourth.copies) == fourth
    # stage 6 (consolidation, then boids select): two more open-arena copies, the parked term
    # 30, a third of the learning rate, a checkpoint every 250 k steps
    sixth = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage6"))
    assert sixth.env_fields == {**fifth.env_fields, "reward_parked": 30.0}
    assert sixth.worlds[:18] == fifth.worlds and sixth.worlds[18:] == ({}, {})
    assert sixth.group_sizes[:18] == fifth.group_sizes and sixth.group_sizes[18:] == (13, 19)
    assert (sixth.learning_rate, fifth.learning_rate) == (1e-4, 3e-4)
    assert sixth.checkpoint_every == 250_000
    assert sixth.total_timesteps == fifth.total_timesteps + 3_000_000
    assert dataclasses.replace(
        sixth, total_timesteps=fifth.total_timesteps, worlds=fifth.worlds,
        group_sizes=fifth.group_sizes, copies=fifth.copies, env_fields=fifth.env_fields,
        learning_rate=fifth.learning_rate, checkpoint_every=fifth.checkpoint_every) == fifth
    # stage 7 (a pillar-field margin): stage 6 with two more pillar-field copies, 3 M steps
    # from the shipped model (62.5 M), a checkpoint every 500 k steps
    seventh = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage7"))
    assert seventh.worlds[:20] == sixth.worlds
    assert seventh.worlds[20:] == ({"scene": "pillars"},) * 2
    assert seventh.group_sizes[:20] == sixth.group_sizes and seventh.group_sizes[20:] == (13, 19)
    assert seventh.copies == 22 and seventh.checkpoint_every == 500_000
    assert seventh.total_timesteps == 65_500_000
    assert dataclasses.replace(
        seventh, total_timesteps=sixth.total_timesteps, worlds=sixth.worlds,
        group_sizes=sixth.group_sizes, copies=sixth.copies,
        checkpoint_every=sixth.checkpoint_every) == sixth


def test_learned_scenes_is_the_selected_stage7_model():
    # stage 7 run from the stage-6 pick (62.5 M steps) with seed 0, its checkpoint at 63.0 M
    # picked by boids select --order headroom: the recipe's env fields, the filter on
    import zipfile

    from boids_env.policies.registry import MODELS, load_policy
    from boids_env.train.config import TrainConfig, resolve_recipe

    fields = load_policy("learned-scenes").env_fields
    seventh = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage7"))
    assert fields == seventh.env_fields and fields["safety_filter"] is True
    with zipfile.ZipFile(MODELS["learned-scenes"]) as z:
        data = json.loads(z.read("data"))
        meta = json.loads(z.read("boids.json"))
    assert data["num_timesteps"] == 63_016_932
    assert meta["train_config"]["learning_rate"] == 1e-4
    assert meta["train_config"]["total_timesteps"] == 65_500_000
    assert len(meta["train_config"]["worlds"]) == 22


def test_safety_filter_flag_reaches_the_env(tmp_path):
    out = tmp_path / "run"
    assert main(["run", "--safety-filter", "--scene", "small_room", *SHORT, "--out",
                 str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["env"]["safety"]["safety_filter"] is True
    plain = tmp_path / "plain"
    assert main(["run", *SHORT, "--out", str(plain)]) == 0
    assert json.loads((plain / "config.json").read_text())["env"]["safety"][
        "safety_filter"] is False
    args = build_parser().parse_args(["eval", "--safety-filter", "--suite", "scenes"])
    assert args.safety_filter is True


def test_whole_rollouts_rounds_up_to_what_ppo_runs():
    from boids_env.train.config import TrainConfig
    from boids_env.train.run import whole_rollouts

    config = TrainConfig(n_steps=256)
    assert whole_rollouts(config, 36, 5000) == 256 * 36
    assert whole_rollouts(config, 36, 256 * 36 * 2) == 256 * 36 * 2
    assert whole_rollouts(TrainConfig(algorithm="sac", train_freq=1), 36, 50) == 72


@pytest.mark.parametrize("content, reason", [
    ("{not json", "cannot read it as JSON"),
    ('{"policy": "reynolds"}', 'no "env" table'),
    ('{"env": {"scenario": {"robots": 1}}}', "robots must be in"),
    ('{"env": {"scenario": {"leader_sped": 1}}}', "leader_sped"),
])
def test_ros_metrics_config_errors_name_the_file(tmp_path, capsys, content, reason):
    config = tmp_path / "my_config.json"
    config.write_text(content)
    assert main(["ros", "metrics", str(tmp_path / "run.bag"), "--config", str(config)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--config {config}" in err and reason in err, err
    assert len(err.splitlines()) == 1, err


INTERRUPTED_IMPORT = """
import builtins, os, signal, sys
real = builtins.__import__

def interrupted(name, *args, **kwargs):
    if name == {module!r} and {module!r} not in sys.modules:
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, arriving while this module loads
    return real(name, *args, **kwargs)

builtins.__import__ = interrupted
sys.argv = ["boids", "run", "--robots", "3", "--out", {out!r}]
# what the boids script that pip installs runs
from boids_env.train.cli import main
sys.exit(main())
"""


def _ctrl_c_as_in_a_terminal():
    """SIGINT as a terminal gives it, whatever pytest inherited (ignored in a background
    job, where Python installs no KeyboardInterrupt handler)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("module", ["numpy", "scipy.spatial", "boids_env.config", "pymunk"])
def test_ctrl_c_while_the_command_starts_is_one_line_and_exit_130(tmp_path, module):
    """The imports of the first second (numpy, scipy, pymunk) ran before main() could catch
    a Ctrl-C, which printed a traceback (inside numpy's import, as an ImportError)."""
    import subprocess
    import sys

    out = tmp_path / "o"
    code = INTERRUPTED_IMPORT.format(module=module, out=str(out))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=False, preexec_fn=_ctrl_c_as_in_a_terminal)
    err = proc.stderr.strip()
    assert proc.returncode == 130, (proc.returncode, err)
    assert re.fullmatch(r"boids( run)?: interrupted", err), err
    assert not out.exists()


def test_boids_version_is_the_packages(capsys):
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"boids-env {project['project']['version']}"


def test_ros_controller_help_recommends_what_works():
    """It recommended Debian's dynparam, which the README says cannot find its package."""
    text = build_parser()._subparsers._group_actions[0].choices["ros"]._subparsers \
        ._group_actions[0].choices["controller"].format_help()
    text = re.sub(r"\s+", " ", text)
    assert "boids ros reconfigure leader_weight=1.1" in text, text
    assert "dynparam" not in text


def test_an_external_leader_has_no_path_deviation_and_metrics_json_stays_json(tmp_path,
                                                                             capsys):
    """It printed nan and wrote NaN, which is not JSON, into metrics.json."""
    assert main(["run", "--path", "external", "--robots", "3", "--max-cycles", "10",
                 "--out", str(tmp_path / "o")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines()
                if x.startswith("leader_path_deviation"))
    assert line.split()[1] == "n/a", line

    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")

    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text(), parse_constant=refuse)
    assert metrics["leader_path_deviation"] is None
    assert metrics["leader_path_deviation_max"] is None
    assert metrics["steps"] == 10 and metrics["min_distance"] > 0


@pytest.mark.parametrize("argv, hint", [
    (["run", "--robts", "5"], "--robts: did you mean --robots?"),
    (["run", "--robts=5"], "--robts: did you mean --robots?"),
    (["eval", "--polcy", "learned"], "--polcy: did you mean --policy?"),
    (["ros", "controller", "--polcy", "reynolds"], "--polcy: did you mean --policy?"),
])
def test_an_unknown_flag_suggests_the_closest_one_with_exit_2(argv, hint, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"boids {' '.join(a for a in argv[:2] if not a.startswith('-'))}: error: " in err, err
    assert "unrecognized arguments" in err and hint in err, err


def test_an_unknown_flag_far_from_every_option_gets_no_guess(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--qqqqqq"])
    err = capsys.readouterr().err
    assert "unrecognized arguments: --qqqqqq" in err and "did you mean" not in err, err
