"""The ``boids run``, ``boids eval`` and ``boids report`` subcommands: argument parsing only;
each command's code is imported when it runs. :mod:`boids_env.train.cli` composes them into the
``boids`` command."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from boids_env.config import PATHS, PRESETS
from boids_env.eval.pool import BACKENDS, DEFAULT_EPISODE_TIMEOUT
from boids_env.extras import require

POLICY_HELP = ("reynolds (default), reynolds@boids_ros (a preset), random, learned (the "
               "shipped PPO followers), an SB3 model .zip, or module:object (a Policy "
               "instance, class or factory)")


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Adds ``run``, ``eval`` and ``report`` to the ``boids`` subparsers."""
    _run_parser(sub)
    _eval_parser(sub)
    _report_parser(sub)


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


def _run_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run one episode of a policy, print its metrics, save files",
                       description="Run one episode: prints V_sep / V_coh / V_align and the "
                       "extra flock and safety metrics; writes metrics.json, "
                       "trajectory.parquet, config.json and manifest.json to --out (and a "
                       "video with --video, ROS bags with --bag / --mcap). --out must be "
                       "empty or new unless --overwrite.")
    p.add_argument("--policy", default="reynolds", help=POLICY_HELP)
    p.add_argument("--robots", type=int, default=13, help="group size, leader included (13)")
    p.add_argument("--leader-speed", type=float, default=0.55, help="m/s (0.55)")
    p.add_argument("--leader-weight", type=float, default=None,
                   help="Reynolds leader weight (preset's: 1.0)")
    p.add_argument("--path", choices=PATHS, default="square", help="leader path (square)")
    p.add_argument("--waypoints", type=parse_waypoints, default=None,
                   help='targets for --path waypoints, "x,y x,y ..." in metres')
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="Reynolds parameters (paper)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-cycles", type=int, default=None, help="hard step limit")
    p.add_argument("--arena-half-size", type=float, default=None, help="m (5.0)")
    p.add_argument("--no-wrap", action="store_true",
                   help="the study's unwrapped alignment angle rule")
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
    p.add_argument("--bag-start", type=parse_start, default=None,
                   help="the bags' first stamp: ISO 8601 date-time (UTC unless it names an "
                   "offset) or Unix seconds (default: now)")
    p.add_argument("--render", choices=("none", "human"), default="none",
                   help="human: live window (arrow keys drive a --path external leader, "
                   "1-6 and +/- tune the Reynolds parameters); nothing is written")
    p.add_argument("--fast", type=float, default=4.0,
                   help="speed-up of the live window's fast mode, key f (4)")
    p.set_defaults(func=_cmd_run)


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
    """Extras the named policies need (a saved SB3 model needs ``train``)."""
    return ["train"] if any(s == "learned" or s.endswith(".zip") for s in specs) else []


def _env_fields(args: argparse.Namespace) -> dict[str, Any]:
    fields: dict[str, Any] = {"robots": args.robots, "leader_speed": args.leader_speed,
                              "path": args.path}
    if args.path == "waypoints" and args.waypoints is None:
        raise ValueError("--path waypoints needs --waypoints \"x,y x,y ...\" (metres)")
    if args.waypoints is not None:
        fields["waypoints"] = args.waypoints
    if args.max_cycles is not None:
        fields["max_cycles"] = args.max_cycles
    if args.arena_half_size is not None:
        fields["arena_half_size"] = args.arena_half_size
    if args.no_wrap:
        fields["wrap_alignment"] = False
    return fields


def _cmd_run(args: argparse.Namespace) -> int:
    fields = _env_fields(args)
    needs = _policy_extras([args.policy])
    if args.render == "human":
        require("render", *needs, purpose="boids run --render human")
        from boids_env.eval.live import run_live
        from boids_env.eval.run import metrics_table
        from boids_env.render import NoDisplayError

        try:
            _, metrics = run_live(args.policy, preset=args.preset, seed=args.seed,
                                  fast_factor=args.fast, env_fields=fields,
                                  leader_weight=args.leader_weight)
        except NoDisplayError as exc:
            print(f"boids run: error: {exc}", file=sys.stderr)
            return 2
        print("last episode of the live window:")
        print(metrics_table(metrics))
        return 0
    needs += ["render"] if args.video else []
    needs += ["ros"] if args.bag or args.mcap else []
    require(*needs, purpose="boids run" + " --video" * bool(args.video) + " --bag" * args.bag
            + " --mcap" * args.mcap + (f" --policy {args.policy}" if "train" in needs else ""))
    from boids_env.eval.run import run

    run(args.policy, out=args.out, overwrite=args.overwrite, seed=args.seed,
        preset=args.preset, leader_weight=args.leader_weight, video=args.video, bag=args.bag,
        mcap=args.mcap, bag_start=args.bag_start, env_fields=fields)
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
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="preset of a bare 'reynolds' policy (paper)")
    p.add_argument("--suite", default="paper", help="paper (default), robustness, or a TOML "
                   "file")
    p.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 (suite's: 5)")
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
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_cmd_eval)


def _cmd_eval(args: argparse.Namespace) -> int:
    specs = args.policy or ["reynolds"]
    require("eval", *_policy_extras(specs), *(["ray"] if args.backend == "ray" else []),
            purpose="boids eval")
    from pathlib import Path

    from boids_env.eval.folder import record_files
    from boids_env.eval.report import build_report
    from boids_env.eval.runner import PolicySpec, failures, run_suite
    from boids_env.eval.suites import load_suite

    if args.episode_timeout < 0:
        raise ValueError(f"--episode-timeout must be >= 0 seconds (0: no limit), got "
                         f"{args.episode_timeout:g}")
    policies = [PolicySpec.parse(spec, args.preset) for spec in specs]
    suite = load_suite(args.suite).with_seeds(args.seeds)
    table = run_suite(policies, suite, args.out, workers=args.workers, backend=args.backend,
                      keep_trajectories=args.keep_trajectories, progress=not args.no_progress,
                      episode_timeout=args.episode_timeout or None, overwrite=args.overwrite)
    failed = failures(args.out)
    out = Path(args.out)
    if table.empty:
        print(f"boids eval: all {len(failed)} episodes failed; see {out / 'errors.jsonl'}",
              file=sys.stderr)
        return 1
    before = {p.name for p in out.iterdir()}
    report = build_report(out)
    record_files(out, sorted({p.name for p in out.iterdir()} - before))
    print(f"{len(table)} episode rows; wrote results.parquet, results.csv and {report}")
    if failed:
        print(f"boids eval: {len(failed)} episodes failed (listed in {out / 'errors.jsonl'} "
              f"and the report)", file=sys.stderr)
        return 1
    return 0


def _report_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="rebuild the report of a boids eval folder (no rerun)")
    p.add_argument("dir", help="the --out folder of boids eval")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    require("eval", purpose="boids report")
    from boids_env.eval.report import build_report

    print(f"wrote {build_report(args.dir)}")
    return 0
