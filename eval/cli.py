"""The ``boids run``, ``boids eval`` and ``boids report`` subcommands: argument parsing only;
each command's code is imported when it runs. :mod:`boids_env.train.cli` composes them into the
``boids`` command. A command's help is its handler's docstring
(:func:`~boids_env.eval.flags.add_command`)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from boids_env.config import EnvConfig
from boids_env.eval.flags import (
    POLICY_HELP,
    TRUST_HELP,
    add_command,
    add_env_args,
    add_live_args,
    env_fields,
    live_options,
    policy_extras,
    reynolds_preset,
)
from boids_env.eval.pool import BACKENDS, DEFAULT_EPISODE_TIMEOUT
from boids_env.eval.robotarium.cli import add_export_parser
from boids_env.eval.ros.cli import add_ros_parser
from boids_env.eval.ros2.cli import add_ros2_parser
from boids_env.extras import require
from boids_env.policies.reynolds_params import PRESETS
from boids_env.world.realism import REALISMS

MAX_FAST = 1000.0
"""Largest ``--fast`` speed-up of the live window (times real time)."""


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Adds ``run``, ``eval``, ``report``, ``ros``, ``ros2``, ``export``, ``scenes`` and
    ``select`` to the ``boids`` subparsers."""
    _run_parser(sub)
    _eval_parser(sub)
    _report_parser(sub)
    add_ros_parser(sub)
    add_ros2_parser(sub)
    add_export_parser(sub)
    add_command(sub, "scenes", _cmd_scenes)
    _select_parser(sub)


def _run_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "run", _cmd_run)
    p.add_argument("--policy", default="reynolds", help=POLICY_HELP)
    p.add_argument("--trust-model", action="store_true", help=TRUST_HELP)
    add_env_args(p, "leader path (square)", "seed (0)")
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


def _people_flags(fields: dict[str, Any]) -> str:
    """What runs the pedestrian model in the (checked) config of ``fields``, as options (a
    leader the model walks, a crowd), or "" where nothing does."""
    sc = EnvConfig.from_kwargs(**fields).scenario
    walks = f"--leader {sc.leader}" if sc.leader_kind.walks(sc) else ""
    return " ".join(f for f in (walks, f"--crowd {sc.crowd}" * (sc.crowd > 0)) if f)


def _cmd_run(args: argparse.Namespace) -> int:
    """run one episode of a policy, print its metrics, save files

    Run one episode: prints V_sep / V_coh / V_align and the extra flock and safety metrics; writes
    metrics.json, trajectory.parquet, config.json and manifest.json to --out (and a video with
    --video, ROS bags with --bag / --mcap). --out must be empty or new unless --overwrite.
    """
    _check_run_flags(args)
    if args.render == "human" and args.live is not None:
        raise ValueError("--live foxglove serves the episode to Foxglove; --render human "
                         "opens the pygame window: pick one")
    live = live_options(args)
    preset = reynolds_preset([args.policy], args.preset, args.leader_weight)
    fields = env_fields(args)
    needs = policy_extras([args.policy])
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
    people = _people_flags(fields)
    needs += ["people"] if people else []
    require(*needs, purpose="boids run", flags={
        "render": "--video", "ros": "--bag" * args.bag + " --mcap" * args.mcap,
        "people": people, "train": f"--policy {args.policy}"})
    from boids_env.eval.run import run

    run(args.policy, out=args.out, overwrite=args.overwrite, seed=args.seed,
        preset=preset, leader_weight=args.leader_weight, video=args.video, bag=args.bag,
        mcap=args.mcap, bag_start=args.bag_start, env_fields=fields,
        trust_model=args.trust_model, live=live, twist_stamped=args.twist_stamped)
    return 0


def _eval_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "eval", _cmd_eval)
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


def _cmd_eval(args: argparse.Namespace) -> int:
    """rerun the study's experiments (or another suite) for one or more policies, with statistics,
    figures and a report

    Runs every (policy, case, seed) episode of a suite in parallel (resumable), writes
    results.parquet/.csv, the statistics, figures and report.md/report.html to --out. Exits 1 when
    some episodes failed (listed in errors.jsonl and the report), 2 for bad arguments, 130 when
    interrupted (finished episodes are kept).
    """
    specs = args.policy or ["reynolds"]
    preset = reynolds_preset(specs, args.preset)
    require("eval", *policy_extras(specs), *(["ray"] if args.backend == "ray" else []),
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
    p = add_command(sub, "select", _cmd_select)
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


def _cmd_select(args: argparse.Namespace) -> int:
    """rank model checkpoints by the lab-follower bars on the validation suite (trained cases,
    seeds 100-104)

    Runs the validation suite (the scenes but the lab, 61 robots, a leader standing 40 s; seeds
    100-104) for the reference policy and every candidate, scores each candidate on the bars (the
    arena at most half the reference's total, each scene below it, 61 robots' V_coh within 0.2 of
    it, parked speed <= 0.05 m/s; with wall contact and touching <= 1 % and no follower beyond 3 m
    at the end) and prints the ranking: most bars met, then --order. Writes bars.csv, ranking.csv
    and selection.json to --out.
    """
    require("eval", *policy_extras([args.reference, *args.candidates]),
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
    p = add_command(sub, "report", _cmd_report)
    p.add_argument("dir", help="the --out folder of boids eval")


def _cmd_report(args: argparse.Namespace) -> int:
    """rebuild the report of a boids eval folder (no rerun)"""
    require("eval", purpose="boids report")
    from boids_env.eval.report import build_report

    print(f"building the statistics, figures and report of {args.dir} …", flush=True)
    report = build_report(args.dir)
    print(f"wrote {report} and {report.with_suffix('.html')}")
    return 0


def _cmd_scenes(args: argparse.Namespace) -> int:
    """list the built-in scenes (walls, obstacles, maps)

    The built-in scenes with their leader paths; any of them goes to boids run --scene NAME, a ROS
    map to --map lab.yaml.
    """
    from boids_env.config import EnvConfig
    from boids_env.world.scenes import describe

    for name, text in describe().items():
        sc = EnvConfig.from_kwargs(scene=name).scenario
        path = sc.path if sc.path != "waypoints" else f"waypoints from {sc.start}"
        print(f"{name:<11} {text}\n{'':<11} leader path: {path}")
    return 0
