"""The ``boids`` command: argument parsing only; each subcommand's code is imported lazily."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from boids_env.config import PATHS, PRESETS


def _run_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run one episode of a policy, print its metrics, save files",
                       description="Run one episode: prints V_sep / V_coh / V_align and the "
                       "extra flock metrics; with --out writes metrics.json, "
                       "trajectory.parquet and config.json (and a GIF with --video).")
    p.add_argument("--policy", default="reynolds",
                   help="reynolds (default), random, an SB3 model .zip, or module:object")
    p.add_argument("--robots", type=int, default=13, help="group size, leader included (13)")
    p.add_argument("--leader-speed", type=float, default=0.55, help="m/s (0.55)")
    p.add_argument("--leader-weight", type=float, default=None,
                   help="Reynolds leader weight (preset's: 1.0)")
    p.add_argument("--path", choices=PATHS, default="square", help="leader path (square)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="Reynolds parameters (paper)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-cycles", type=int, default=None, help="hard step limit")
    p.add_argument("--arena-half-size", type=float, default=None, help="m (5.0)")
    p.add_argument("--no-wrap", action="store_true",
                   help="the study's unwrapped alignment angle rule")
    p.add_argument("--out", default="runs/latest", help="output folder (runs/latest)")
    p.add_argument("--video", action="store_true", help="also write episode.gif")
    p.add_argument("--bag", action="store_true", help="also write a ROS 1 bag (ros extra)")
    p.add_argument("--mcap", action="store_true",
                   help="also write a ROS 2 bag with MCAP storage, episode_mcap/ (ros extra)")
    p.add_argument("--render", choices=("none", "human"), default="none",
                   help="human: live window (arrow keys drive a --path external leader, "
                   "1-6 and +/- tune the Reynolds parameters); nothing is written")
    p.add_argument("--fast", type=float, default=4.0,
                   help="speed-up of the live window's fast mode, key f (4)")
    p.set_defaults(func=_cmd_run)


def _cmd_run(args: argparse.Namespace) -> int:
    from eval.run import run

    fields = {"robots": args.robots, "leader_speed": args.leader_speed, "path": args.path}
    if args.max_cycles is not None:
        fields["max_cycles"] = args.max_cycles
    if args.arena_half_size is not None:
        fields["arena_half_size"] = args.arena_half_size
    if args.no_wrap:
        fields["wrap_alignment"] = False
    if args.render == "human":
        from eval.live import run_live

        _, metrics = run_live(args.policy, preset=args.preset, seed=args.seed,
                           fast_factor=args.fast, env_fields=fields,
                           leader_weight=args.leader_weight)
        print({k: metrics[k] for k in ("V_sep", "V_coh", "V_align", "duration")})
        return 0
    run(args.policy, out=args.out, seed=args.seed, preset=args.preset,
        leader_weight=args.leader_weight, video=args.video, bag=args.bag, mcap=args.mcap,
        env_fields=fields)
    return 0


def _bench_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="measure env throughput (see bench/)")
    p.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
    p.add_argument("--out", default="bench/results.json", help="JSON output")
    p.set_defaults(func=_cmd_bench)


def _cmd_bench(args: argparse.Namespace) -> int:
    from bench.run import main as bench_main

    return bench_main(["--out", args.out] + (["--quick"] if args.quick else []))


def _eval_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="rerun the study's experiments (or another suite) for "
                       "one or more policies, with statistics, figures and a report",
                       description="Runs every (policy, case, seed) episode of a suite in "
                       "parallel (resumable), writes results.parquet/.csv, the statistics, "
                       "figures and report.md/report.html to --out.")
    p.add_argument("--policy", action="append", default=None,
                   help="as for boids run; repeat to compare policies (first = baseline); "
                   "reynolds@boids_ros picks a preset (default: reynolds)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="preset of a bare 'reynolds' policy (paper)")
    p.add_argument("--suite", default="paper", help="paper (default), robustness, or a TOML "
                   "file")
    p.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 (suite's: 5)")
    p.add_argument("--workers", type=int, default=None, help="processes (default: cores)")
    p.add_argument("--backend", choices=("process", "ray"), default="process")
    p.add_argument("--keep-trajectories", action="store_true",
                   help="keep every episode's trajectory (default: first seed per case)")
    p.add_argument("--out", default="runs/eval", help="output folder (runs/eval)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_cmd_eval)


def _cmd_eval(args: argparse.Namespace) -> int:
    from eval.report import build_report
    from eval.runner import PolicySpec, run_suite
    from eval.suites import load_suite

    specs = []
    for spec in args.policy or ["reynolds"]:
        name, _, preset = spec.partition("@")
        if preset and name != "reynolds":
            raise ValueError(f"only reynolds takes a @preset, got {spec!r}")
        if preset and preset not in PRESETS:
            raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}")
        specs.append(PolicySpec(name, preset or args.preset))
    suite = load_suite(args.suite).with_seeds(args.seeds)
    table = run_suite(specs, suite, args.out, workers=args.workers, backend=args.backend,
                      keep_trajectories=args.keep_trajectories, progress=not args.no_progress)
    report = build_report(args.out)
    print(f"{len(table)} episode rows; wrote results.parquet, results.csv and {report}")
    return 0


def _report_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="rebuild the report of a boids eval folder (no rerun)")
    p.add_argument("dir", help="the --out folder of boids eval")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from eval.report import build_report

    print(f"wrote {build_report(args.dir)}")
    return 0


def _train_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train followers with Stable-Baselines3 (train extra)",
                       description="Trains one shared follower policy (PPO by default) on the "
                       "flock; writes model.zip, config.json, checkpoints/, tb/ to --out.")
    p.add_argument("--config", help="TOML file of TrainConfig fields (flags override it)")
    p.add_argument("--out", default="runs/train", help="output folder (runs/train)")
    p.add_argument("--algorithm", choices=("ppo", "sac"), default=None)
    p.add_argument("--timesteps", type=int, default=None, dest="total_timesteps",
                   help="follower-steps in all")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--copies", type=int, default=None, help="env copies stepped together")
    p.add_argument("--processes", type=int, default=None, help="env worker processes")
    p.add_argument("--group-sizes", type=int, nargs="+", default=None)
    p.add_argument("--leader-speeds", type=float, nargs="+", default=None)
    p.add_argument("--eval-every", type=int, default=None, help="timesteps (0: never)")
    p.add_argument("--checkpoint-every", type=int, default=None, help="timesteps (0: never)")
    p.add_argument("--resume", default=None, help="checkpoint zip to continue from")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_train)


def _cmd_train(args: argparse.Namespace) -> int:
    try:
        from train.config import TrainConfig
        from train.run import train
    except ImportError as exc:
        raise ImportError(f"boids train needs the train extra (pip install torch==2.13.0 "
                          f"'boids-env[train]'): {exc}") from exc
    overrides = {name: getattr(args, name) for name in (
        "algorithm", "total_timesteps", "seed", "copies", "processes", "eval_every",
        "checkpoint_every")}
    overrides["group_sizes"] = tuple(args.group_sizes) if args.group_sizes else None
    overrides["leader_speeds"] = tuple(args.leader_speeds) if args.leader_speeds else None
    if args.config:
        config = TrainConfig.from_toml(args.config, **overrides)
    else:
        config = TrainConfig().replace(**overrides)
    model = train(config, args.out, resume=args.resume, progress_bar=not args.no_progress)
    print(f"wrote {model} (and config.json, evaluations.csv, checkpoints/, tb/ in {args.out})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="boids", description="boids-env: leader-following "
                                     "boids flock (Akgun's ROS study) as a PettingZoo env")
    sub = parser.add_subparsers(dest="command", required=True)
    _run_parser(sub)
    _eval_parser(sub)
    _report_parser(sub)
    _train_parser(sub)
    _bench_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (ValueError, TypeError, FileNotFoundError, ImportError) as exc:
        print(f"boids {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
