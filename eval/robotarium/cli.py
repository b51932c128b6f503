"""``boids export robotarium``: argument parsing only (the export is imported when it runs)."""

from __future__ import annotations

import argparse

from boids_env.eval.flags import add_command, add_command_group

POLICIES = ("reynolds",)
"""What the script can carry: the study's Reynolds + leader controller (a learned policy's
observations are not rebuilt in the script yet)."""


def add_export_parser(sub: argparse._SubParsersAction) -> None:
    """Adds ``export`` and its ``robotarium`` subcommand to the ``boids`` subparsers."""
    export = add_command_group(
        sub, "export", "write the flock for another platform (robotarium)",
        "Write the flock as a program that runs elsewhere without boids-env installed.")
    p = add_command(export, "robotarium", _cmd_export_robotarium)
    p.add_argument("--out", dest="script", required=True, metavar="SCRIPT.py",
                   help="the script to write")
    p.add_argument("--policy", default="reynolds", choices=POLICIES,
                   help="the followers' controller: reynolds (the study's rules scaled to the "
                   "testbed)")
    p.add_argument("--robots", type=int, default=13,
                   help="robots, leader included: 2..20 (13; the study's 7, 13, 19 fit)")
    p.add_argument("--follower-speed", type=float, default=None,
                   help="followers' top speed in m/s (0.15, 3/4 of a GRITSbot's)")
    p.add_argument("--leader-speed", type=float, default=None,
                   help="leader speed in m/s (1.1 x the followers', the study's ratio)")
    p.add_argument("--seconds", type=float, default=None,
                   help="experiment length in s (the leader's path with slack; at most 840)")
    p.add_argument("--no-figure", action="store_true",
                   help="show_figure=False and sim_in_real_time=False (a fast local check)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing SCRIPT.py")


def _cmd_export_robotarium(args: argparse.Namespace) -> int:
    """a Robotarium script of the flock (GRITSbots, rps API, barrier certificates)

    Writes a script for the Robotarium's testbed: the study's case scaled to its 3.2 m x 2 m
    floor, the leader on the study's square squeezed into it, the followers by the Reynolds
    rules, rps's si-to-unicycle mapping and barrier certificate with boundary, the wheels
    kept within their limits. It imports numpy, math and rps only; run it with the
    Robotarium's simulator, then submit it.
    """
    from pathlib import Path

    from boids_env.eval.robotarium.case import RobotariumCase
    from boids_env.eval.robotarium.script import write_script

    fields = {"robots": args.robots, "leader_speed": args.leader_speed,
              "seconds": args.seconds}
    if args.follower_speed is not None:
        fields["follower_speed"] = args.follower_speed
    case = RobotariumCase(**fields)
    out = Path(args.script)
    if out.suffix != ".py":
        raise ValueError(f"--out must name a .py file, got {args.script}")
    if out.exists() and not args.overwrite:
        raise FileExistsError(f"--out {args.script} exists; give --overwrite to replace it")
    path = write_script(case, out, figure=not args.no_figure)
    config = case.env_config()
    print(f"wrote {path}: {case.robots} robots, {case.iterations(config)} steps "
          f"({case.iterations(config) * 0.033:.0f} s), leader {case.leader:g} m/s")
    return 0
