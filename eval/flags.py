"""How a ``boids`` command is declared (:func:`add_command`, :func:`add_command_group`) and
the flags several commands share: the env's (``boids run``, ``boids ros sim``, ``boids ros2
sim``), the live view's, the policy's, a simulator node's and a controller node's (ROS 1 and
ROS 2 alike). Argument parsing only; the commands' code is imported when they run.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from boids_env.config import PATHS
from boids_env.extras import require
from boids_env.policies.reynolds_params import PRESETS
from boids_env.world.realism import REALISMS
from boids_env.world.robots import ROBOT_PRESETS as ROBOTS
from boids_env.world.scenario import LEADERS

if TYPE_CHECKING:
    from boids_env.eval.graph.controller import ControllerOptions
    from boids_env.eval.graph.sim import SimOptions

TRUST_HELP = ("load a model .zip through Stable-Baselines3's own load, which unpickles "
              "objects stored in the file and so runs any code they carry: only for files you "
              "trust. Without it a zip acts from its weights alone or is refused (see the "
              "docs, how-to/training, 'Model files you did not make')")

POLICY_HELP = ("reynolds (default), reynolds@boids_ros or reynolds@proxemic (a preset), "
               "random, learned (the shipped PPO followers), learned-study (PPO on the study's "
               "reward alone), learned-person (PPO following a person), learned-scenes (the "
               "followers for a lab: walls, obstacles, standstills, the safety filter), "
               "learned-buildings (floor plans, by route), learned-crowd (a person through "
               "buildings among pedestrians), an SB3 "
               "model .zip, or module:object (a Policy instance, class or factory)")


def add_command(sub: argparse._SubParsersAction, name: str,
                handler: Callable[[argparse.Namespace], int]) -> argparse.ArgumentParser:
    """Declares the ``boids`` (sub)command ``name`` under ``sub``, run by ``handler``
    (``args.func``), whose docstring is its help, as click takes it: the first paragraph is
    the command's line in the parent's ``--help`` (lower case, as argparse's help lines), the
    rest the paragraph atop its own ``--help`` (none without one). Returns its parser, for the
    options that are its own."""
    summary, _, description = (handler.__doc__ or "").partition("\n\n")
    p = sub.add_parser(name, help=" ".join(summary.split()) or None,
                       description=" ".join(description.split()) or None)
    p.set_defaults(func=handler)
    return p


def add_command_group(sub: argparse._SubParsersAction, name: str, summary: str,
                      description: str) -> argparse._SubParsersAction:
    """Declares ``name`` as a command of subcommands (``boids ros sim``), one of which must
    follow it (named in ``args.<name>_command``); returns the subparsers to add them to."""
    p = sub.add_parser(name, help=summary, description=description)
    return p.add_subparsers(dest=f"{name}_command", required=True)


def parse_waypoints(text: str) -> tuple[tuple[float, float], ...]:
    """``"0,4 -4,4 -4,-4"`` -> ((0, 4), (-4, 4), (-4, -4)); a clear error otherwise."""
    points = []
    for item in text.replace(";", " ").split():
        try:
            x, y = (float(v) for v in item.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"waypoints must be x,y pairs in metres separated by spaces (e.g. "
                f"\"0,4 -4,4\"), got {item!r}") from None
        points.append((x, y))
    if not points:
        raise argparse.ArgumentTypeError("waypoints needs at least one x,y pair")
    return tuple(points)


def parse_point(text: str) -> tuple[float, float]:
    """``"-4,0"`` -> (-4.0, 0.0); a clear error otherwise."""
    points = parse_waypoints(text)
    if len(points) != 1:
        raise argparse.ArgumentTypeError(f"expected one x,y pair in metres, got {text!r}")
    return points[0]


def parse_setting(text: str) -> tuple[str, Any]:
    """``"lidar_rays=16"`` -> ("lidar_rays", 16): a config field and a JSON value (a bare word
    is a string), nested at most :data:`SETTING_DEPTH` deep; the config checks the field and
    the value."""
    import json

    from boids_env.untrusted import check_depth, printable

    name, eq, raw = text.partition("=")
    if not eq or not name.strip():
        raise argparse.ArgumentTypeError(f"--set takes FIELD=VALUE (e.g. lidar_rays=16), got "
                                         f"{text!r}")
    name = name.strip()
    too_deep = argparse.ArgumentTypeError(
        f"--set {printable(name, 40)}=...: the value nests lists deeper than {SETTING_DEPTH} "
        "levels (waypoints need 2, e.g. waypoints=[[0,4],[-4,4]])")
    try:
        value = json.loads(raw)
    except RecursionError:  # the decoder recurses once a level: a traceback, not a message
        raise too_deep from None
    except ValueError:
        return name, raw
    try:
        return name, check_depth(value, name, SETTING_DEPTH)
    except ValueError:
        raise too_deep from None


SETTING_DEPTH = 8
"""Deepest nesting of a ``--set`` value (the deepest config field, waypoints, needs 2)."""


def add_env_args(p: argparse.ArgumentParser, path_help: str, seed_help: str) -> None:
    """The env-config flags :func:`env_fields` reads (``boids run``, ``boids ros sim``,
    ``boids ros2 sim``)."""
    p.add_argument("--robots", type=int, default=None, help="group size, leader included (13)")
    p.add_argument("--robot", choices=sorted(ROBOTS), default=None,
                   help="robot model: sphero (the study's, default), sphero_sprk, "
                   "turtlebot3_burger, gritsbot; sets the leader speed (1.1 x its top speed) "
                   "and start grid unless given")
    p.add_argument("--leader-speed", type=float, default=None,
                   help="m/s (0.55; with --robot, 1.1 x its top speed)")
    p.add_argument("--scene", default=None,
                   help="arena (the study's, default), small_room, doorway, corridor, pillars, "
                   "lab, a generated floor plan floorplan:SEED, or a shapes file (.toml/.json); "
                   "sets the scene's leader path and start (boids scenes lists them)")
    p.add_argument("--map", default=None, metavar="YAML",
                   help="a ROS map_server map (YAML + PGM/PNG) as the scene")
    p.add_argument("--path", choices=PATHS, default=None, help=path_help)
    p.add_argument("--waypoints", type=parse_waypoints, default=None,
                   help='targets of the leader, "x,y x,y ..." in metres (world frame; e.g. '
                   '"0,4 -4,4" or --waypoints=-4,4); implies --path waypoints')
    p.add_argument("--start", type=parse_point, default=None, metavar="X,Y",
                   help="where the leader starts (m; the scene's, or 0,0); the arena is "
                   "centred on 0,0: --start -3,0 or --start=-3,0")
    p.add_argument("--start-heading", type=float, default=None, metavar="DEG",
                   help="direction the leader faces at the start; the grid lies behind it")
    p.add_argument("--leader", choices=LEADERS, default=None,
                   help="who leads: robot (the study's), person (a pedestrian walking the path "
                   "with JuPedSim, people extra; with --path external, walked by hand) or "
                   "trajectory (a recorded walk, --leader-trajectory)")
    p.add_argument("--leader-trajectory", default=None, metavar="CSV",
                   help="a recorded walk to replay as the leader: a CSV of t,x,y (s, m) on the "
                   "episode's clock, or doorway_walk (shipped); implies --leader trajectory")
    p.add_argument("--crowd", type=int, default=None, metavar="N",
                   help="N pedestrians walking to random goals through the scene (people "
                   "extra; 0)")
    p.add_argument("--set", type=parse_setting, action="append", default=[],
                   metavar="FIELD=VALUE", help="any env config field (e.g. lidar_rays=16, "
                   "static_slots=2, obs_noise=0.02); repeatable")
    p.add_argument("--seed", type=int, default=0, help=seed_help)
    p.add_argument("--max-cycles", type=int, default=None, help="hard step limit")
    p.add_argument("--arena-half-size", type=float, default=None, help="m (5.0)")
    p.add_argument("--realism", choices=REALISMS, default=None,
                   help="ROS/Stage realism: none (the ideal world, default) or ros (stall, "
                   "staggered start, stale observations; docs: explanation/fidelity)")
    p.add_argument("--no-wrap", action="store_true",
                   help="the study's unwrapped alignment angle rule")
    p.add_argument("--safety-filter", action="store_true",
                   help="filter every follower's command so that it does not drive the robot "
                   "into a wall, obstacle or robot (opt-in; docs: how-to/maps)")


def env_fields(args: argparse.Namespace) -> dict[str, Any]:
    """The env config fields of :func:`add_env_args`' flags, checked as a whole config."""
    given = ("robots", "robot", "leader_speed", "path", "scene", "start", "start_heading",
             "leader", "leader_trajectory", "crowd", "max_cycles", "arena_half_size",
             "realism")
    fields: dict[str, Any] = {name: getattr(args, name) for name in given
                              if getattr(args, name) is not None}
    if args.leader_trajectory is not None:
        fields.setdefault("leader", "trajectory")
    if args.map is not None:
        if args.scene is not None:
            raise ValueError("give --scene or --map, not both (a map is a scene)")
        fields["scene"] = args.map
    if args.path == "waypoints" and args.waypoints is None:
        raise ValueError("--path waypoints needs --waypoints \"x,y x,y ...\" (metres)")
    if args.waypoints is not None:
        fields["waypoints"] = args.waypoints
        fields.setdefault("path", "waypoints")
    if args.no_wrap:
        fields["wrap_alignment"] = False
    if args.safety_filter:
        fields["safety_filter"] = True
    return _with_settings(fields, args.set)


def _with_settings(fields: dict[str, Any], settings: list[tuple[str, Any]]) -> dict[str, Any]:
    """``fields`` plus the ``--set FIELD=VALUE`` ones, checked as a whole config before
    anything is written."""
    from boids_env.config import EnvConfig

    for name, value in settings:
        if name in fields:
            raise ValueError(f"--set {name}=... repeats a field given by its own flag")
        fields[name] = tuple(map(tuple, value)) if name == "waypoints" else (
            tuple(value) if name == "start" and isinstance(value, list) else value)
    EnvConfig.from_kwargs(**fields)
    return fields


def add_live_args(p: argparse.ArgumentParser) -> None:
    """``--live foxglove`` and its options (``boids run``, ``boids ros2 sim``)."""
    p.add_argument("--live", choices=("foxglove",), default=None,
                   help="serve the running episode over Foxglove's WebSocket protocol "
                   "(live extra): open ws://127.0.0.1:PORT in Foxglove")
    p.add_argument("--live-port", type=int, default=8765,
                   help="port of the live view (8765; 0: any free port)")
    p.add_argument("--live-speed", type=float, default=1.0,
                   help="the live view's pace, times real time (1; 0: as fast as it runs)")
    p.add_argument("--live-wait", type=float, default=0.0,
                   help="seconds to wait for a viewer to subscribe before the first tick (0)")


def live_options(args: argparse.Namespace) -> dict[str, Any] | None:
    """The live view's keyword arguments, or None without ``--live``; its extra checked."""
    if args.live is None:
        given = [f for f, on in (("--live-port", args.live_port != 8765),
                                 ("--live-speed", args.live_speed != 1.0),
                                 ("--live-wait", args.live_wait != 0.0)) if on]
        if given:
            raise ValueError(f"{', '.join(given)} set the live view: add --live foxglove")
        return None
    require("live", purpose="--live foxglove")
    if not 0 <= args.live_port <= 65535:
        raise ValueError(f"--live-port must be in [0, 65535] (0: any free port), got "
                         f"{args.live_port}")
    from boids_env.eval.liveview import check_port

    check_port(args.live_port)  # a taken port: refused before the run, not at its start
    return {"port": args.live_port, "speed": args.live_speed, "wait": args.live_wait}


def policy_extras(specs: list[str]) -> list[str]:
    """Extras the named policies need: a saved SB3 model without a numpy actor (one not saved
    by ``boids train``) needs ``train``; the shipped ones and ours act in numpy."""
    from boids_env.policies.registry import MODELS, switch_parts
    from boids_env.policies.sb3_policy import has_numpy_actor

    models = [str(p) for s in specs for p in (switch_parts(s) or (MODELS.get(s, s),))]
    needs = any(m.endswith(".zip") and not has_numpy_actor(m) for m in models)
    return ["train"] if needs else []


def reynolds_preset(specs: list[str], preset: str | None,
                    leader_weight: float | None = None) -> str:
    """The preset for a bare ``reynolds`` policy (``paper`` unless ``--preset`` names one);
    ``--preset`` and ``--leader-weight`` are refused where no policy would use them, rather
    than silently ignored (``--preset`` sets only a bare ``reynolds``: ``reynolds@PRESET``
    names its own)."""
    from boids_env.policies.registry import split_preset

    shown = " ".join(f"--policy {s}" for s in specs)
    if leader_weight is not None and not any(split_preset(s)[0] == "reynolds" for s in specs):
        raise ValueError(f"--leader-weight is a Reynolds parameter: it needs --policy reynolds "
                         f"or reynolds@PRESET, got {shown}")
    if preset is not None and "reynolds" not in specs:
        raise ValueError(f"--preset {preset} sets the parameters of --policy reynolds only "
                         f"(reynolds@PRESET names its own), got {shown}")
    return preset or "paper"


def add_controller_args(p: argparse.ArgumentParser, source: str) -> None:
    """The options every policy node takes, ROS 1's ``boids ros controller`` and ROS 2's
    ``boids ros2 controller`` alike (``source``: where the group size comes from)."""
    p.add_argument("--policy", default="reynolds", help=POLICY_HELP)
    p.add_argument("--trust-model", action="store_true", help=TRUST_HELP)
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="Reynolds parameters of --policy reynolds (paper)")
    p.add_argument("--leader-weight", type=float, default=None,
                   help="Reynolds leader weight (preset's: 1.0); reynolds policies only")
    p.add_argument("--robots", type=int, default=None,
                   help=f"group size of the odometry source (default: {source})")
    p.add_argument("--arena-half-size", type=float, default=None,
                   help="m, with --robots (5.0)")
    p.add_argument("--sync", choices=("stamp", "rate"), default="stamp",
                   help="stamp: answer each tick once every robot reported it (default); "
                   "rate: every 0.1 s from the latest odometry (unsynchronised robots)")
    p.add_argument("--seed", type=int, default=0,
                   help="policy seed when the source announces no episode (0)")
    p.add_argument("--max-ticks", type=int, default=None,
                   help="exit after answering this many ticks")
    p.add_argument("--idle-exit", type=float, default=30.0, metavar="S",
                   help="exit once no tick has come for S seconds after the first (the "
                        "simulator ended); 0: run until stopped (30)")
    p.add_argument("--no-markers", action="store_true",
                   help="do not publish the rule-force markers")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (no start line, waiting or new-episode "
                   "notes)")


def controller_options(args: argparse.Namespace, **extra: Any) -> ControllerOptions:
    """The :class:`~boids_env.eval.graph.controller.ControllerOptions` of
    :func:`add_controller_args`' flags (``extra``: the transport's own, e.g.
    ``config_wait``)."""
    from boids_env.eval.graph.controller import ControllerOptions

    preset = reynolds_preset([args.policy], args.preset, args.leader_weight)
    fields: dict[str, Any] = {}
    if args.robots is not None:
        fields["robots"] = args.robots
    if args.arena_half_size is not None:
        if args.robots is None:
            raise ValueError("--arena-half-size goes with --robots (otherwise the simulator's "
                             "config is used)")
        fields["arena_half_size"] = args.arena_half_size
    return ControllerOptions(
        policy=args.policy, preset=preset, leader_weight=args.leader_weight,
        env_fields=fields, sync=args.sync, seed=args.seed, max_ticks=args.max_ticks,
        idle_exit=args.idle_exit,
        markers=not args.no_markers, quiet=args.quiet, trust_model=args.trust_model, **extra)


def add_sim_args(p: argparse.ArgumentParser, wait_for_help: str) -> None:
    """The options every simulator node takes, ROS 1's ``boids ros sim`` and ROS 2's ``boids
    ros2 sim`` alike, the env's included (``wait_for_help``: what ``--wait-for`` waits for)."""
    add_env_args(p, "leader path (square); external: driven by /robot_0/cmd_vel",
                 "seed of the first episode (0)")
    p.add_argument("--episodes", type=int, default=1, help="episodes to run (1)")
    p.add_argument("--lockstep", action="store_true",
                   help="advance a tick only when every follower answered it "
                   "(deterministic: equals boids run); default: real time, like Stage")
    p.add_argument("--cmd-timeout", type=float, default=None,
                   help="real time: a follower without a command for this long (s) gets "
                   "(0, 0), as a robot driver's safety stop (0.5)")
    p.add_argument("--no-wait", action="store_true",
                   help="real time: start at once instead of waiting for a controller")
    p.add_argument("--wait-for", action="append", default=[], metavar="NODE",
                   help=wait_for_help)
    p.add_argument("--out", default=None, help="output folder (none: print only)")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (no waiting notes, metrics table or "
                   "written-files line)")


def sim_options(args: argparse.Namespace) -> SimOptions:
    """The :class:`~boids_env.eval.graph.sim.SimOptions` of :func:`add_sim_args`' flags."""
    from boids_env.eval.graph.protocol import CMD_TIMEOUT
    from boids_env.eval.graph.sim import SimOptions

    if args.no_wait and args.lockstep:
        raise ValueError("--no-wait is for real time; --lockstep always waits for a controller")
    return SimOptions(
        env_fields=env_fields(args), lockstep=args.lockstep, episodes=args.episodes,
        seed=args.seed, cmd_timeout=CMD_TIMEOUT if args.cmd_timeout is None
        else args.cmd_timeout, wait_controller=not args.no_wait,
        wait_for=tuple(args.wait_for), out=args.out, quiet=args.quiet)
