"""``boids ros sim|controller|reconfigure|metrics``: the ROS 1 graph's argument parsing
(importing this needs no ROS). The flags it shares with ``boids run`` and ``boids ros2`` come
from :mod:`boids_env.eval.flags`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from boids_env.config import EnvConfig
from boids_env.eval.flags import (
    add_command,
    add_command_group,
    add_controller_args,
    add_sim_args,
    controller_options,
    policy_extras,
    sim_options,
)
from boids_env.extras import require

ROS_ARGS_HELP = ("ROS remapping arguments, as any ROS node takes them: name:=value, "
                 "_param:=value (a private parameter), __name:=node")


def _ros_args(values: list[str]) -> list[str]:
    bad = [v for v in values if ":=" not in v]
    if bad:
        raise ValueError(f"unexpected arguments {bad}: only ROS remapping arguments "
                         f"(name:=value) may follow the options")
    return values


def add_ros_parser(sub: argparse._SubParsersAction) -> None:
    """Adds ``ros`` (``sim``, ``controller``, ``reconfigure``, ``metrics``) to the ``boids``
    subparsers."""
    ros = add_command_group(
        sub, "ros", "the study's ROS 1 graph: the world as a simulator node, any policy as the "
        "controller node, metrics of a recorded bag",
        "ROS 1 nodes on the study's topics (/robot_k/odom, /robot_k/cmd_vel). Needs ROS 1's "
        "Python packages (Debian/Ubuntu: apt-get install ros-core python3-rospy "
        "python3-nav-msgs python3-geometry-msgs python3-visualization-msgs python3-tf2-msgs "
        "python3-dynamic-reconfigure python3-rosbag; or ROS Noetic) and a running roscore.")
    _sim_parser(ros)
    _controller_parser(ros)
    _reconfigure_parser(ros)
    _metrics_parser(ros)


def _sim_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "sim", _cmd_sim)
    add_sim_args(p, "also hold tick 0 until NODE (e.g. /recorder) subscribes to every topic "
                 "of the graph; repeatable")
    p.add_argument("ros_args", nargs="*", help=ROS_ARGS_HELP)


def _cmd_sim(args: argparse.Namespace) -> int:
    """the pymunk world as a ROS node in place of Stage

    Publishes /robot_k/odom (10 Hz), /tf, /clock and the scripted leader's /robot_0/cmd_vel;
    applies the followers' /robot_k/cmd_vel. Ends with the episode (--episodes N for more), prints
    the study's metrics, writes metrics.json, trajectory.parquet and config.json with --out.
    """
    options = sim_options(args)
    from boids_env.eval.ros.sim import run_sim

    run_sim(options, [sys.argv[0], *_ros_args(args.ros_args)])
    return 0


def _controller_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "controller", _cmd_controller)
    add_controller_args(p, "boids ros sim's, read from the /boids/env_config parameter")
    p.add_argument("ros_args", nargs="*", help=ROS_ARGS_HELP)


def _cmd_controller(args: argparse.Namespace) -> int:
    """any policy as the study's reynolds_controller node

    Subscribes to every /robot_k/odom, builds the env's observations, publishes every follower's
    /robot_k/cmd_vel and (Reynolds) the rule-force markers on ~markers; Reynolds parameters are ROS
    parameters, changeable live through dynamic_reconfigure: boids ros reconfigure
    leader_weight=1.1 (or rqt_reconfigure on a full ROS install).
    """
    options = controller_options(args)
    require(*policy_extras([args.policy]), purpose=f"boids ros controller --policy "
            f"{args.policy}")
    from boids_env.eval.ros.controller import run_controller

    run_controller(options, [sys.argv[0], *_ros_args(args.ros_args)])
    return 0


def _reconfigure_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "reconfigure", _cmd_reconfigure)
    p.add_argument("changes", nargs="*", metavar="NAME=VALUE",
                   help="separation_weight, cohesion_weight, alignment_weight, leader_weight, "
                   "horizon, desired_separation, max_speed, max_force")
    p.add_argument("--node", default="/reynolds_controller",
                   help="the controller node (/reynolds_controller)")
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for it (10)")


def _cmd_reconfigure(args: argparse.Namespace) -> int:
    """change a running controller's Reynolds parameters live (dynamic_reconfigure), or show them

    Calls the node's dynamic_reconfigure services, as rqt_reconfigure and dynparam do: boids ros
    reconfigure leader_weight=1.2 horizon=0.8. Without assignments, prints the current values.
    """
    from boids_env.eval.ros.reconfigure import parse_assignments, reconfigure_node

    changes = parse_assignments(args.changes)
    for name, value in reconfigure_node(args.node, changes, args.timeout).items():
        print(f"{name} = {value:g}")
    return 0


def _metrics_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "metrics", _cmd_metrics)
    p.add_argument("bag", help="the .bag file (or a ROS 2 bag folder)")
    p.add_argument("--config", default=None,
                   help="the run's config.json (boids ros sim --out) for its thresholds and "
                   "leader path (default: the study's, robots from the bag)")
    p.add_argument("--out", default=None,
                   help="also write metrics.json and trajectory.parquet here")


def _cmd_metrics(args: argparse.Namespace) -> int:
    """the study's metrics of a bag recorded from the live graph (rosbag record)

    Reads a bag of /robot_k/odom and /robot_k/cmd_vel recorded from boids ros sim and a controller,
    and prints the metrics table of boids run (the live graph's commands answer the odometry: each
    is the command of the next sample).
    """
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
