"""``boids ros2 sim|controller``: the argument parsing (importing this needs no Zenoh).

The flags it shares with ``boids run`` and ``boids ros`` (the env's, the live view's, the
policy's, a simulator's and a controller's) come from :mod:`boids_env.eval.flags`.
"""

from __future__ import annotations

import argparse
from typing import Any

from boids_env.eval.flags import (
    add_command,
    add_command_group,
    add_controller_args,
    add_live_args,
    add_sim_args,
    controller_options,
    live_options,
    policy_extras,
    sim_options,
)
from boids_env.eval.ros2.wire import DEFAULT_DISTRIBUTION, DEFAULT_ROUTER, DISTRIBUTIONS


def add_ros2_parser(sub: argparse._SubParsersAction) -> None:
    """Adds ``ros2`` (``sim``, ``controller``) to the ``boids`` subparsers."""
    ros2 = add_command_group(
        sub, "ros2", "the study's graph as ROS 2 nodes over Zenoh (rmw_zenoh's conventions; no "
        "ROS install)",
        "ROS 2 nodes on the study's topics (/robot_k/odom, /robot_k/cmd_vel) speaking "
        "rmw_zenoh's protocol: a ROS 2 system with RMW_IMPLEMENTATION=rmw_zenoh_cpp and its "
        "router sees and talks to them. Needs the ros2 extra: pip install -e '.[ros2]'.")
    _sim_parser(ros2)
    _controller_parser(ros2)


def _add_transport_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--domain", type=int, default=None,
                   help="ROS domain id (default: $ROS_DOMAIN_ID, else 0)")
    p.add_argument("--distribution", choices=DISTRIBUTIONS, default=DEFAULT_DISTRIBUTION,
                   help=f"message definitions and type hashes of this ROS 2 distribution "
                   f"({DEFAULT_DISTRIBUTION})")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                   help=f"Zenoh endpoint to connect to; repeatable ({DEFAULT_ROUTER}: "
                   f"rmw_zenoh's router, ros2 run rmw_zenoh_cpp rmw_zenohd)")
    p.add_argument("--listen", action="append", default=None, metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on for peers; repeatable "
                   "(tcp/localhost:0)")
    p.add_argument("--twist-stamped", action="store_true",
                   help="cmd_vel as geometry_msgs/TwistStamped (a TurtleBot3 on Jazzy and "
                   "later) instead of Twist")


def _ros2_options(args: argparse.Namespace) -> Any:
    import os

    from boids_env.eval.ros2.options import Ros2Options

    domain = args.domain
    if domain is None:
        text = os.environ.get("ROS_DOMAIN_ID", "0") or "0"
        try:
            domain = int(text)
        except ValueError:
            raise ValueError(f"ROS_DOMAIN_ID must be an integer in [0, 232], got {text!r}"
                             ) from None
    return Ros2Options(domain=domain, distribution=args.distribution,
                       connect=tuple(args.connect) if args.connect is not None
                       else Ros2Options.connect,
                       listen=tuple(args.listen) if args.listen is not None
                       else Ros2Options.listen,
                       twist_stamped=args.twist_stamped)


def _sim_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "sim", _cmd_sim)
    add_sim_args(p, "also hold tick 0 until NODE subscribes to the odometry, /tf and /clock; "
                 "repeatable")
    _add_transport_args(p)
    add_live_args(p)


def _cmd_sim(args: argparse.Namespace) -> int:
    """the pymunk world as a ROS 2 simulator node

    Publishes /robot_k/odom (10 Hz), /tf and /tf_static (map -> robot_k/odom ->
    robot_k/base_footprint), /clock, /map, markers and the scripted leader's /robot_0/cmd_vel;
    applies the followers' /robot_k/cmd_vel. Ends with the episode (--episodes N for more), prints
    the study's metrics, writes metrics.json, trajectory.parquet and config.json with --out.
    """
    from boids_env.extras import require

    options = sim_options(args)
    ros2 = _ros2_options(args)
    live = live_options(args)
    require("ros2", purpose="boids ros2 sim")
    from boids_env.eval.ros2.sim import run_sim

    run_sim(options, ros2, live)
    return 0


def _controller_parser(sub: argparse._SubParsersAction) -> None:
    p = add_command(sub, "controller", _cmd_controller)
    add_controller_args(p, "boids ros2 sim's, read from /boids/env_config")
    p.add_argument("--config-wait", type=float, default=30.0,
                   help="seconds to wait for the simulator's /boids/env_config (30)")
    _add_transport_args(p)


def _cmd_controller(args: argparse.Namespace) -> int:
    """any policy as the study's reynolds_controller, a ROS 2 node

    Subscribes to every /robot_k/odom, builds the env's observations, publishes every follower's
    /robot_k/cmd_vel and (Reynolds) the rule-force markers on /<node>/markers. Runs until stopped
    (Ctrl-C) or --max-ticks.
    """
    from boids_env.extras import require

    options = controller_options(args, config_wait=args.config_wait)
    ros2 = _ros2_options(args)
    require("ros2", *policy_extras([args.policy]),
            purpose=f"boids ros2 controller --policy {args.policy}")
    from boids_env.eval.ros2.controller import run_controller

    run_controller(options, ros2)
    return 0
