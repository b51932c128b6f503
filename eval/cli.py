"""The ``boids run``, ``boids eval`` and ``boids report`` subcommands: argument parsing only;
each command's code is imported when it runs. :mod:`boids_env.train.cli` composes them into the
``boids`` command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from boids_env.config import PATHS, PRESETS, EnvConfig
from boids_env.eval.pool import BACKENDS, DEFAULT_EPISODE_TIMEOUT
from boids_env.extras import require
from boids_env.world.realism import REALISMS
from boids_env.world.robots import PRESETS as ROBOTS
from boids_env.world.scenario import LEADERS

MAX_FAST = 1000.0
"""Largest ``--fast`` speed-up of the live window (times real time)."""
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


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Adds ``run``, ``eval``, ``report`` and ``ros`` to the ``boids`` subparsers."""
    _run_parser(sub)
    _eval_parser(sub)
    _report_parser(sub)
    _ros_parser(sub)
    from boids_env.eval.ros2.cli import add_ros2_parser

    add_ros2_parser(sub, dict(
        add_env_args=_add_env_args, env_fields=_env_fields, add_live_args=add_live_args,
        live_options=live_options, policy_extras=_policy_extras,
        reynolds_preset=reynolds_preset, add_controller_args=add_controller_args))
    _scenes_parser(sub)
    _select_parser(sub)


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
    is a string); the config checks the field and the value."""
    import json

    name, eq, raw = text.partition("=")
    if not eq or not name.strip():
        raise argparse.ArgumentTypeError(f"--set takes FIELD=VALUE (e.g. lidar_rays=16), got "
                                         f"{text!r}")
    try:
        value = json.loads(raw)
    except ValueError:
        value = raw
    return name.strip(), value


def _add_env_args(p: argparse.ArgumentParser, path_help: str, seed_help: str) -> None:
    """The env-config flags :func:`_env_fields` reads (``boids run``, ``boids ros sim``)."""
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


def _run_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run one episode of a policy, print its metrics, save files",
                       description="Run one episode: prints V_sep / V_coh / V_align and the "
                       "extra flock and safety metrics; writes metrics.json, "
                       "trajectory.parquet, config.json and manifest.json to --out (and a "
                       "video with --video, ROS bags with --bag / --mcap). --out must be "
                       "empty or new unless --overwrite.")
    p.add_argument("--policy", default="reynolds", help=POLICY_HELP)
    p.add_argument("--trust-model", action="store_true", help=TRUST_HELP)
    _add_env_args(p, "leader path (square)", "seed (0)")
    p.add_argument("--leader-weight", type=float, default=None,
                   help="Reynolds leader weight (preset's: 1.0); reynolds policies only")
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="Reynolds parameters of --policy reynolds (paper)")
    p.add_argument("--out", default="runs/latest", help="output folder (runs/latest)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace what an earlier boids run wrote in --out (listed in its "
                   "manifest.json; your own files there are kept)")
    p.add_argument("--video", nargs="?", const="gif", choices=("gif", "mp4"), default=None,
                   help="also write episode.gif (render extra), or episode.mp4 with "
                   "--video mp4 (video extra: imageio-ffmpeg)")
    p.add_argument("--bag", action="store_true", help="also write a ROS 1 bag (ros extra)")
    p.add_argument("--mcap", action="store_true",
                   help="also write a ROS 2 bag with MCAP storage, episode_mcap/ (ros extra)")
    p.add_argument("--twist-stamped", action="store_true",
                   help="the bags' cmd_vel as geometry_msgs/TwistStamped (a TurtleBot3 on "
                   "Jazzy and later) instead of Twist; with --bag or --mcap")
    p.add_argument("--bag-start", type=parse_start, default=None,
                   help="the bags' first stamp: ISO 8601 date-time (UTC unless it names an "
                   "offset) or Unix seconds (default: now)")
    p.add_argument("--render", choices=("none", "human"), default="none",
                   help="human: live window (arrow keys drive a --path external leader, "
                   "1-6 and +/- tune the Reynolds parameters); nothing is written")
    p.add_argument("--fast", type=float, default=None,
                   help="speed-up of the live window's fast mode, key f, with --render human "
                   f"(a number in (0, {MAX_FAST:g}]; 4)")
    add_live_args(p)
    p.set_defaults(func=_cmd_run)


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
    return {"port": args.live_port, "speed": args.live_speed, "wait": args.live_wait}


def parse_start(text: str) -> float:
    """``"2024-05-01T12:00:00"`` (UTC unless an offset is given) or ``"1714564800.5"`` (Unix
    seconds) -> Unix seconds."""
    from datetime import UTC, datetime

    try:
        value = float(text)
    except ValueError:
        try:
            moment = datetime.fromisoformat(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"--bag-start must be an ISO 8601 date-time (e.g. 2024-05-01T12:00:00) or "
                f"Unix seconds, got {text!r}") from None
        if moment.tzinfo is None:
            moment = moment.replace(tzinfo=UTC)
        value = moment.timestamp()
    if not 0 <= value < 2**32:  # ROS 1 stamps: unsigned 32-bit seconds
        raise argparse.ArgumentTypeError(
            f"--bag-start must be between 1970 and 2106 (Unix seconds 0 to 2^32), got {text!r}")
    return value


def _policy_extras(specs: list[str]) -> list[str]:
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


def _check_run_flags(args: argparse.Namespace) -> None:
    """Flags of ``boids run`` that only one mode reads are refused in the other."""
    if args.render == "human":
        given = [flag for flag, on in (("--video", args.video), ("--bag", args.bag),
                                       ("--mcap", args.mcap),
                                       ("--bag-start", args.bag_start is not None),
                                       ("--overwrite", args.overwrite)) if on]
        if given:
            raise ValueError(f"{', '.join(given)}: the live window (--render human) writes "
                             f"nothing; drop {'them' if len(given) > 1 else 'it'} or drop "
                             f"--render human")
    elif args.fast is not None:
        raise ValueError("--fast is the live window's fast mode: it needs --render human")
    if args.twist_stamped and not (args.bag or args.mcap):
        raise ValueError("--twist-stamped sets the bags' cmd_vel type: add --bag or --mcap")
    if args.fast is not None and not 0 < args.fast <= MAX_FAST:  # NaN fails too
        raise ValueError(f"--fast must be a speed-up in (0, {MAX_FAST:g}] times real time, "
                         f"got {args.fast:g}")


def _env_fields(args: argparse.Namespace) -> dict[str, Any]:
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


def _needs_people(fields: dict[str, Any]) -> bool:
    """Whether the pedestrian model runs: a person walking a path or a crowd."""
    walking = fields.get("leader") == "person" and fields.get("path") != "external"
    return walking or bool(fields.get("crowd"))


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


def _cmd_run(args: argparse.Namespace) -> int:
    _check_run_flags(args)
    if args.render == "human" and args.live is not None:
        raise ValueError("--live foxglove serves the episode to Foxglove; --render human "
                         "opens the pygame window: pick one")
    live = live_options(args)
    preset = reynolds_preset([args.policy], args.preset, args.leader_weight)
    fields = _env_fields(args)
    needs = _policy_extras([args.policy])
    if args.render == "human":
        require("render", *needs, purpose="boids run --render human")
        from boids_env.eval.live import run_live
        from boids_env.eval.run import metrics_table
        from boids_env.render import NoDisplayError

        try:
            _, metrics = run_live(args.policy, preset=preset, seed=args.seed,
                                  fast_factor=args.fast or 4.0, env_fields=fields,
                                  leader_weight=args.leader_weight,
                                  trust_model=args.trust_model)
        except NoDisplayError as exc:
            print(f"boids run: error: {exc}", file=sys.stderr)
            return 2
        print("last episode of the live window:")
        print(metrics_table(metrics))
        return 0
    needs += ["render"] if args.video else []
    needs += ["ros"] if args.bag or args.mcap else []
    needs += ["people"] if _needs_people(fields) else []
    require(*needs, purpose="boids run" + " --video" * bool(args.video) + " --bag" * args.bag
            + " --mcap" * args.mcap + (f" --policy {args.policy}" if "train" in needs else ""))
    from boids_env.eval.run import run

    run(args.policy, out=args.out, overwrite=args.overwrite, seed=args.seed,
        preset=preset, leader_weight=args.leader_weight, video=args.video, bag=args.bag,
        mcap=args.mcap, bag_start=args.bag_start, env_fields=fields,
        trust_model=args.trust_model, live=live, twist_stamped=args.twist_stamped)
    return 0


def _eval_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="rerun the study's experiments (or another suite) for "
                       "one or more policies, with statistics, figures and a report",
                       description="Runs every (policy, case, seed) episode of a suite in "
                       "parallel (resumable), writes results.parquet/.csv, the statistics, "
                       "figures and report.md/report.html to --out. Exits 1 when some "
                       "episodes failed (listed in errors.jsonl and the report), 2 for bad "
                       "arguments, 130 when interrupted (finished episodes are kept).")
    p.add_argument("--policy", action="append", default=None,
                   help=POLICY_HELP + "; repeat to compare policies (first = baseline)")
    p.add_argument("--trust-model", action="store_true", help=TRUST_HELP)
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="preset of a bare 'reynolds' policy (paper)")
    p.add_argument("--suite", default="paper", help="paper (default), robustness, "
                   "generalisation (the learned policy's trained and unseen cases), scenes, "
                   "deployment, validation (trained cases on seeds 100-104, what boids select "
                   "ranks on), "
                   "person (a person leading: speed, group size, crowd), "
                   "robot_types (the study's experiment for every robot preset), "
                   "robots_buildings and crowd_buildings (larger robots and crowds on the "
                   "square and held-out floor plans), person_buildings (a person leading "
                   "through them among pedestrians), or a TOML file")
    seeds = p.add_mutually_exclusive_group()
    seeds.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 (suite's: 5)")
    seeds.add_argument("--blocks", type=int, default=None, metavar="K",
                       help="K independent blocks of 5 seeds (seeds 0..5K-1), the study's "
                       "design repeated: the report scores each block as its own "
                       "reproduction (findings per block, mean and range)")
    p.add_argument("--realism", choices=REALISMS, default=None,
                   help="ROS/Stage realism in every case: none (the ideal world, default) or "
                   "ros (stall, staggered start, stale observations; docs: explanation/fidelity)")
    p.add_argument("--safety-filter", action="store_true",
                   help="the safety filter between the policies and the robots in every case "
                   "(opt-in; docs: how-to/maps)")
    p.add_argument("--workers", type=int, default=None, help="processes (default: cores)")
    p.add_argument("--backend", choices=BACKENDS, default="process",
                   help="process (isolated worker processes, default), ray, or inline (in "
                   "this process, for debugging: no timeout, a crash ends the run)")
    p.add_argument("--episode-timeout", type=float, default=DEFAULT_EPISODE_TIMEOUT,
                   metavar="SECONDS", help="stop an episode running longer and record it as "
                   f"failed ({DEFAULT_EPISODE_TIMEOUT:g}; 0: no limit)")
    p.add_argument("--keep-trajectories", action="store_true",
                   help="keep every episode's trajectory (default: first seed per case)")
    p.add_argument("--out", default="runs/eval", help="output folder (runs/eval); rerunning "
                   "the same suite and policies resumes there")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier evaluation of another suite or policies in --out "
                   "(only the files it wrote are removed)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (shown on a terminal only)")
    p.set_defaults(func=_cmd_eval)


def _cmd_eval(args: argparse.Namespace) -> int:
    specs = args.policy or ["reynolds"]
    preset = reynolds_preset(specs, args.preset)
    require("eval", *_policy_extras(specs), *(["ray"] if args.backend == "ray" else []),
            purpose="boids eval")
    from pathlib import Path

    from boids_env.eval.report import build_report
    from boids_env.eval.runner import PolicySpec, failures, run_suite
    from boids_env.eval.suites import load_suite

    if args.episode_timeout < 0:
        raise ValueError(f"--episode-timeout must be >= 0 seconds (0: no limit), got "
                         f"{args.episode_timeout:g}")
    policies = [PolicySpec.parse(spec, preset, args.trust_model) for spec in specs]
    suite = load_suite(args.suite).with_seeds(args.seeds).with_blocks(args.blocks)
    if args.realism is not None:
        suite = suite.with_env(realism=args.realism)
    if args.safety_filter:
        suite = suite.with_env(safety_filter=True)
    table = run_suite(policies, suite, args.out, workers=args.workers, backend=args.backend,
                      keep_trajectories=args.keep_trajectories, progress=not args.no_progress,
                      episode_timeout=args.episode_timeout or None, overwrite=args.overwrite)
    failed = failures(args.out)
    out = Path(args.out)
    if table.empty:
        print(f"boids eval: all {len(failed)} episodes failed; see {out / 'errors.jsonl'}",
              file=sys.stderr)
        return 1
    print(f"{len(table)} episode rows; building the statistics, figures and report …",
          flush=True)  # seconds of work: say so rather than sit silent
    report = build_report(out)  # it records its files in the folder's manifest
    print(f"wrote results.parquet, results.csv, {report} and {report.with_suffix('.html')}")
    if failed:
        print(f"boids eval: {len(failed)} episodes failed (listed in {out / 'errors.jsonl'} "
              f"and the report)", file=sys.stderr)
        return 1
    return 0


def _select_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("select", help="rank model checkpoints by the lab-follower bars on "
                       "the validation suite (trained cases, seeds 100-104)",
                       description="Runs the validation suite (the scenes but the lab, 61 "
                       "robots, a leader standing 40 s; seeds 100-104) for the reference "
                       "policy and every candidate, scores each candidate on the bars (the "
                       "arena at most half the reference's total, each scene below it, 61 "
                       "robots' V_coh within 0.2 of it, parked speed <= 0.05 m/s; with wall "
                       "contact and touching <= 1 % and no follower beyond 3 m at the end) "
                       "and prints the ranking: most bars met, then --order. "
                       "Writes bars.csv, ranking.csv and selection.json to --out.")
    p.add_argument("candidates", nargs="+", metavar="MODEL",
                   help="model .zip files (checkpoints), policy names, or training folders "
                   "(a run's --out: its checkpoints and model.zip; a --seeds output: every "
                   "seed's) to rank")
    p.add_argument("--reference", default="reynolds",
                   help="the policy the relative bars compare against (reynolds)")
    p.add_argument("--trust-model", action="store_true", help=TRUST_HELP)
    p.add_argument("--seeds", type=int, nargs="+", default=None, metavar="SEED",
                   help="validation episodes' seeds (100 101 102 103 104)")
    p.add_argument("--order", choices=("total", "headroom"), default="total",
                   help="tie-break among candidates meeting as many bars: total (the lower "
                   "summed total, the default) or headroom (the larger smallest headroom, "
                   "(limit - value) / limit over the bars, then the lower summed total)")
    p.add_argument("--workers", type=int, default=None, help="processes (default: cores)")
    p.add_argument("--out", default="runs/select", help="output folder (runs/select); "
                   "rerunning with the same candidates resumes there")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (shown on a terminal only)")
    p.set_defaults(func=_cmd_select)


def _cmd_select(args: argparse.Namespace) -> int:
    require("eval", *_policy_extras([args.reference, *args.candidates]),
            purpose="boids select")
    import pandas as pd

    from boids_env.eval.select import per_run, select

    ranked = select(args.candidates, args.out, reference=args.reference,
                    workers=args.workers, seeds=args.seeds, trust=args.trust_model,
                    progress=not args.no_progress, order=args.order)
    with pd.option_context("display.width", 200, "display.max_colwidth", 80):
        print(ranked.drop(columns=["spec", "run"]).to_string(index=False))
    chosen = per_run(ranked)
    if len(chosen) > 1:  # candidates from several runs (seeds): each run's pick too
        met = dict(zip(ranked["spec"], ranked["met"], strict=True))
        for run, spec in chosen.items():
            print(f"run {run}: {spec} ({met[spec]} bars)")
    print(f"chosen: {ranked['spec'].iloc[0]} ({ranked['met'].iloc[0]} of "
          f"{ranked['bars'].iloc[0]} bars); wrote bars.csv, ranking.csv, selection.json "
          f"to {args.out}")
    return 0


def _report_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="rebuild the report of a boids eval folder (no rerun)")
    p.add_argument("dir", help="the --out folder of boids eval")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    require("eval", purpose="boids report")
    from boids_env.eval.report import build_report

    print(f"building the statistics, figures and report of {args.dir} …", flush=True)
    report = build_report(args.dir)
    print(f"wrote {report} and {report.with_suffix('.html')}")
    return 0


def _scenes_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scenes", help="list the built-in scenes (walls, obstacles, maps)",
                       description="The built-in scenes with their leader paths; any of them "
                       "goes to boids run --scene NAME, a ROS map to --map lab.yaml.")
    p.set_defaults(func=_cmd_scenes)


def _cmd_scenes(args: argparse.Namespace) -> int:
    from boids_env.config import EnvConfig
    from boids_env.world.scenes import describe

    for name, text in describe().items():
        sc = EnvConfig.from_kwargs(scene=name).scenario
        path = sc.path if sc.path != "waypoints" else f"waypoints from {sc.start}"
        print(f"{name:<11} {text}\n{'':<11} leader path: {path}")
    return 0


# ----------------------------------------------------------------------------------- ros
ROS_ARGS_HELP = ("ROS remapping arguments, as any ROS node takes them: name:=value, "
                 "_param:=value (a private parameter), __name:=node")


def _ros_args(values: list[str]) -> list[str]:
    bad = [v for v in values if ":=" not in v]
    if bad:
        raise ValueError(f"unexpected arguments {bad}: only ROS remapping arguments "
                         f"(name:=value) may follow the options")
    return values


def _ros_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ros", help="the study's ROS 1 graph: the world as a simulator node, "
                       "any policy as the controller node, metrics of a recorded bag",
                       description="ROS 1 nodes on the study's topics (/robot_k/odom, "
                       "/robot_k/cmd_vel). Needs ROS 1's Python packages (Debian/Ubuntu: "
                       "apt-get install ros-core python3-rospy python3-nav-msgs "
                       "python3-geometry-msgs python3-visualization-msgs python3-tf2-msgs "
                       "python3-dynamic-reconfigure python3-rosbag; or ROS Noetic) and a "
                       "running roscore.")
    ros = p.add_subparsers(dest="ros_command", required=True)
    _ros_sim_parser(ros)
    _ros_controller_parser(ros)
    _ros_reconfigure_parser(ros)
    _ros_metrics_parser(ros)


def _ros_sim_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sim", help="the pymunk world as a ROS node in place of Stage",
                       description="Publishes /robot_k/odom (10 Hz), /tf, /clock and the "
                       "scripted leader's /robot_0/cmd_vel; applies the followers' "
                       "/robot_k/cmd_vel. Ends with the episode (--episodes N for more), "
                       "prints the study's metrics, writes metrics.json, "
                       "trajectory.parquet and config.json with --out.")
    _add_env_args(p, "leader path (square); external: driven by /robot_0/cmd_vel",
                  "seed of the first episode (0)")
    p.add_argument("--episodes", type=int, default=1, help="episodes to run (1)")
    p.add_argument("--lockstep", action="store_true",
                   help="advance a tick only when every follower answered it "
                   "(deterministic); default: real time, like Stage")
    p.add_argument("--cmd-timeout", type=float, default=None,
                   help="real time: a follower without a command for this long (s) gets "
                   "(0, 0), as a robot driver's safety stop (0.5)")
    p.add_argument("--no-wait", action="store_true",
                   help="real time: start at once instead of waiting for a controller")
    p.add_argument("--wait-for", action="append", default=[], metavar="NODE",
                   help="also hold tick 0 until NODE (e.g. /recorder) subscribes to every "
                   "topic of the graph; repeatable")
    p.add_argument("--out", default=None, help="output folder (none: print only)")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (no waiting notes, metrics table or "
                   "written-files line)")
    p.add_argument("ros_args", nargs="*", help=ROS_ARGS_HELP)
    p.set_defaults(func=_cmd_ros_sim)


def _cmd_ros_sim(args: argparse.Namespace) -> int:
    import sys

    from boids_env.eval.graph.protocol import CMD_TIMEOUT
    from boids_env.eval.ros.sim import SimOptions, run_sim

    if args.no_wait and args.lockstep:
        raise ValueError("--no-wait is for real time; --lockstep always waits for a controller")
    options = SimOptions(
        env_fields=_env_fields(args), lockstep=args.lockstep, episodes=args.episodes,
        seed=args.seed, cmd_timeout=CMD_TIMEOUT if args.cmd_timeout is None
        else args.cmd_timeout, wait_controller=not args.no_wait,
        wait_for=tuple(args.wait_for), out=args.out, quiet=args.quiet)
    run_sim(options, [sys.argv[0], *_ros_args(args.ros_args)])
    return 0


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


def _ros_controller_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("controller", help="any policy as the study's reynolds_controller "
                       "node", description="Subscribes to every /robot_k/odom, builds the "
                       "env's observations, publishes every follower's /robot_k/cmd_vel and "
                       "(Reynolds) the rule-force markers on ~markers; Reynolds parameters are "
                       "ROS parameters, changeable live through dynamic_reconfigure: "
                       "boids ros reconfigure leader_weight=1.1 (or rqt_reconfigure on a full "
                       "ROS install).")
    add_controller_args(p, "boids ros sim's, read from the /boids/env_config parameter")
    p.add_argument("--no-markers", action="store_true", help="do not publish ~markers")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (no start line, waiting or new-episode "
                   "notes)")
    p.add_argument("ros_args", nargs="*", help=ROS_ARGS_HELP)
    p.set_defaults(func=_cmd_ros_controller)


def _cmd_ros_controller(args: argparse.Namespace) -> int:
    import sys

    preset = reynolds_preset([args.policy], args.preset, args.leader_weight)
    require(*_policy_extras([args.policy]), purpose=f"boids ros controller --policy "
            f"{args.policy}")
    from boids_env.eval.ros.controller import ControllerOptions, run_controller

    fields: dict[str, Any] = {}
    if args.robots is not None:
        fields["robots"] = args.robots
    if args.arena_half_size is not None:
        if args.robots is None:
            raise ValueError("--arena-half-size goes with --robots (otherwise the simulator's "
                             "config is used)")
        fields["arena_half_size"] = args.arena_half_size
    options = ControllerOptions(
        policy=args.policy, preset=preset, leader_weight=args.leader_weight,
        env_fields=fields, sync=args.sync, seed=args.seed, max_ticks=args.max_ticks,
        markers=not args.no_markers, quiet=args.quiet, trust_model=args.trust_model)
    run_controller(options, [sys.argv[0], *_ros_args(args.ros_args)])
    return 0


def _ros_reconfigure_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reconfigure", help="change a running controller's Reynolds "
                       "parameters live (dynamic_reconfigure), or show them",
                       description="Calls the node's dynamic_reconfigure services, as "
                       "rqt_reconfigure and dynparam do: boids ros reconfigure "
                       "leader_weight=1.2 horizon=0.8. Without assignments, prints the "
                       "current values.")
    p.add_argument("changes", nargs="*", metavar="NAME=VALUE",
                   help="separation_weight, cohesion_weight, alignment_weight, leader_weight, "
                   "horizon, desired_separation, max_speed, max_force")
    p.add_argument("--node", default="/reynolds_controller",
                   help="the controller node (/reynolds_controller)")
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for it (10)")
    p.set_defaults(func=_cmd_ros_reconfigure)


def _cmd_ros_reconfigure(args: argparse.Namespace) -> int:
    from boids_env.eval.ros.reconfigure import parse_assignments, reconfigure_node

    changes = parse_assignments(args.changes)
    for name, value in reconfigure_node(args.node, changes, args.timeout).items():
        print(f"{name} = {value:g}")
    return 0


def _ros_metrics_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("metrics", help="the study's metrics of a bag recorded from the live "
                       "graph (rosbag record)",
                       description="Reads a bag of /robot_k/odom and /robot_k/cmd_vel "
                       "recorded from boids ros sim and a controller, and prints the metrics "
                       "table of boids run (the live graph's commands answer the odometry: "
                       "each is the command of the next sample).")
    p.add_argument("bag", help="the .bag file (or a ROS 2 bag folder)")
    p.add_argument("--config", default=None,
                   help="the run's config.json (boids ros sim --out) for its thresholds and "
                   "leader path (default: the study's, robots from the bag)")
    p.add_argument("--out", default=None,
                   help="also write metrics.json and trajectory.parquet here")
    p.set_defaults(func=_cmd_ros_metrics)


def _cmd_ros_metrics(args: argparse.Namespace) -> int:
    require("ros", purpose="boids ros metrics")
    from boids_env.eval.ros.bags import read_live_bag
    from boids_env.eval.run import metrics_table
    from boids_env.files import atomic_path, write_json

    config = None
    if args.config is not None:
        config = _run_config(Path(args.config))
    recording = read_live_bag(args.bag, config)
    metrics = recording.metrics()
    print(f"bag {args.bag} · {recording.positions.shape[1]} robots · "
          f"{recording.positions.shape[0] - 1} steps")
    print(metrics_table(metrics))
    if args.out is not None:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "metrics.json", metrics)
        with atomic_path(out / "trajectory.parquet") as tmp:
            recording.to_parquet(tmp)
        print(f"wrote metrics.json, trajectory.parquet to {out}")
    return 0


def _run_config(path: Path) -> EnvConfig:
    """The env config of a run's ``config.json`` (``boids run`` / ``boids ros sim --out``);
    every error names the file."""
    import json

    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        raise ValueError(f"--config {path}: cannot read it as JSON ({reason})") from None
    if not isinstance(data, dict) or not isinstance(data.get("env"), dict):
        raise ValueError(f"--config {path} is not a run's config.json (no \"env\" table; "
                         f"boids ros sim --out and boids run write one)")
    try:
        return EnvConfig.from_dict(data["env"])
    except (ValueError, TypeError) as exc:
        raise ValueError(f"--config {path}: {exc}") from None
