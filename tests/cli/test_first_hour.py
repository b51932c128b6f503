"""A new user's first hour with the ``boids`` command (issue 35): negative coordinates,
flags that cannot go together, help for every option."""

import json

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
