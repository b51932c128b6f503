"""A new user's first hour with the ``boids`` command (issue 35): negative coordinates,
flags that cannot go together, help for every option."""

import json

import pytest

from boids_env.train.cli import build_parser, main


def test_negative_coordinates_are_values_not_options(tmp_path):
    """The arena is centred on 0: ``--start -3,0`` is a start, not an unknown option."""
    args = build_parser().parse_args(["run", "--start", "-1,0", "--waypoints", "-1,1",
                                      "--start-heading", "-90"])
    assert (args.start, args.waypoints, args.start_heading) == ((-1.0, 0.0), ((-1.0, 1.0),),
                                                                -90.0)
    args = build_parser().parse_args(["run", "--waypoints", "-1,1 0,-1.5", "--start=-.5,-2"])
    assert (args.start, args.waypoints) == ((-0.5, -2.0), ((-1.0, 1.0), (0.0, -1.5)))
    ros = build_parser().parse_args(["ros", "sim", "--start", "-2.5,1e-1"])
    assert ros.start == (-2.5, 0.1), "nested subcommands too"
    assert main(["run", "--start", "-1,0", "--waypoints", "-1,1", "--robots", "4",
                 "--max-cycles", "25", "--out", str(tmp_path)]) == 0
    scenario = json.loads((tmp_path / "config.json").read_text())["env"]["scenario"]
    assert (scenario["start"], scenario["waypoints"]) == ([-1.0, 0.0], [[-1.0, 1.0]])


def test_the_help_shows_how_to_give_a_negative_start():
    text = build_parser()._subparsers._group_actions[0].choices["run"].format_help()
    assert "--start=-3,0" in " ".join(text.split())


def test_a_start_with_a_recorded_walk_is_refused_before_any_work(tmp_path, capsys):
    """The walk fixes the leader's start (its first row, here (-4, 0)): a --start beside it
    would be ignored, so it is refused, saying why."""
    walk = ["run", "--scene", "doorway", "--leader-trajectory", "doorway_walk",
            "--robots", "4", "--max-cycles", "5"]
    assert main([*walk, "--start=-3,0", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "the walk doorway_walk fixes the start at its first row (-4, 0)" in err, err
    assert "drop start" in err and "--start" in err, err
    assert not (tmp_path / "o").exists()
    assert main([*walk, "--set", "start=[-3, 0]", "--out", str(tmp_path / "o")]) == 2
    assert main([*walk, "--out", str(tmp_path / "ok")]) == 0
    saved = json.loads((tmp_path / "ok" / "config.json").read_text())["env"]["scenario"]
    assert saved["start"] == [-4.0, 0.0]


def test_a_walk_whose_grid_does_not_fit_is_not_told_to_change_the_start():
    from boids_env.config import EnvConfig

    with pytest.raises(ValueError, match=r"the walk doorway_walk fixes the start \(-4, 0\): "
                       r"change start_heading") as info:
        EnvConfig.from_kwargs(scene="doorway", leader_trajectory="doorway_walk",
                              leader="trajectory", robots=40)
    assert "change start (" not in str(info.value)
    config = EnvConfig.from_kwargs(scene="doorway", leader_trajectory="doorway_walk",
                                   leader="trajectory")
    assert EnvConfig.from_dict(config.to_dict()) == config, "a saved config holds the start"
    # a scene's own start (the arena's 0,0) is no start given: the walk's wins
    arena = EnvConfig.from_kwargs(scene="arena", leader_trajectory="doorway_walk",
                                  leader="trajectory", start_heading=180.0)
    assert arena.scenario.start == (-4.0, 0.0)


def _parsers(parser, name="boids"):
    """Every parser of the command, nested subcommands included, by its command line."""
    import argparse

    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            listed = {a.dest: a.help for a in action._choices_actions}
            for sub, child in action.choices.items():
                assert listed.get(sub), f"{name} {sub} has no help line in {name} --help"
                yield from _parsers(child, f"{name} {sub}")


def test_every_option_of_every_command_has_help():
    import argparse

    seen = 0
    for name, parser in _parsers(build_parser()):
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            what = "/".join(action.option_strings) or action.dest
            assert action.help and action.help.strip(), f"{name} {what} has no help"
            seen += 1
    assert seen > 100, seen  # run, eval, report, ros ..., scenes, select, train, curves


def test_an_unknown_set_field_names_the_close_ones_not_all_of_them(tmp_path, capsys):
    assert main(["run", "--set", "lidar_ray=16", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "lidar_ray: did you mean lidar_rays" in err, err
    assert "arena_half_size" not in err, "not the list of every field"
    assert main(["run", "--set", "qqqq=1", "--out", str(tmp_path / "o")]) == 2
    assert "arena_half_size" in capsys.readouterr().err, "nothing close: every field"


def test_boids_help_shows_examples_that_parse():
    import shlex

    text = build_parser().format_help()
    examples = text.split("examples:\n")[1].split("\n\n")[0].splitlines()
    assert len(examples) >= 5, text
    commands = set()
    for line in examples:
        argv = shlex.split(line.split("   ")[0])
        assert argv[0] == "boids", line
        commands.add(build_parser().parse_args(argv[1:]).command)
    assert {"run", "eval", "train", "curves", "scenes"} <= commands


@pytest.mark.parametrize("levels", [9, 5000])
def test_a_deeply_nested_set_value_is_refused_naming_the_field(tmp_path, capsys, levels):
    """Issue 55: ``--set waypoints=[[[[...`` ended in a RecursionError traceback from the JSON
    decoder; it is refused by the argument parser, naming the field and the bound."""
    value = "[" * levels + "]" * levels
    out = tmp_path / "o"
    with pytest.raises(SystemExit) as info:
        main(["run", "--set", f"waypoints={value}", "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--set waypoints=...: the value nests lists deeper than 8 levels" in err, err[-500:]
    assert "Traceback" not in err and "RecursionError" not in err, err[-500:]
    assert not out.exists()


def test_set_values_nested_as_deep_as_a_config_needs_still_pass():
    from boids_env.eval.flags import parse_setting

    assert parse_setting("waypoints=[[0,4],[-4,4]]") == ("waypoints", [[0, 4], [-4, 4]])
    assert parse_setting("x=" + "[" * 8 + "]" * 8)[1] == [[[[[[[[]]]]]]]]
    assert parse_setting("scene=[[[not json") == ("scene", "[[[not json")
