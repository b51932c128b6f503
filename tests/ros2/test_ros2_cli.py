"""``boids ros2`` and the flags of this issue: bad values refused before any network or work,
the ROS 2 modules importable without Zenoh, ``boids run --twist-stamped`` in the bags."""

from __future__ import annotations

import subprocess
import sys

import pytest

from boids_env.train.cli import main


@pytest.mark.parametrize(("argv", "message"), [
    (["ros2", "sim", "--domain", "300"], "domain must be an integer in [0, 232]"),
    (["ros2", "controller", "--connect", "localhost"], "connect must be Zenoh endpoints"),
    (["ros2", "sim", "--lockstep", "--no-wait"], "--no-wait is for real time"),
    (["ros2", "sim", "--live-speed", "2"], "add --live foxglove"),
    (["ros2", "controller", "--arena-half-size", "4"], "goes with --robots"),
    (["run", "--twist-stamped"], "add --bag or --mcap"),
])
def test_bad_flags_are_refused_by_name(argv, message, capsys):
    assert main(argv) != 0
    assert message in capsys.readouterr().err


def test_a_bad_ros_domain_id_is_refused(monkeypatch, capsys):
    monkeypatch.setenv("ROS_DOMAIN_ID", "seven")
    assert main(["ros2", "sim"]) != 0
    assert "ROS_DOMAIN_ID must be an integer" in capsys.readouterr().err


def test_the_ros2_modules_import_without_zenoh_or_foxglove():
    code = ("import sys; sys.modules['zenoh'] = None; sys.modules['foxglove'] = None\n"
            "import boids_env.eval.ros2.sim, boids_env.eval.ros2.controller\n"
            "import boids_env.eval.ros2.cli, boids_env.eval.liveview, boids_env.eval.graph.sim\n"
            "import boids_env.train.cli\n"
            "from boids_env.eval.ros2.node import Node\n"
            "try:\n    Node('x')\nexcept ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "pip install -e '.[ros2]'" in out.stdout


def test_boids_run_writes_twist_stamped_bags(tmp_path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    assert main(["run", "--max-cycles", "5", "--robots", "3", "--mcap", "--twist-stamped",
                 "--out", str(tmp_path / "r")]) == 0
    with AnyReader([tmp_path / "r" / "episode_mcap"],
                   default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
    assert types["/robot_1/cmd_vel"] == "geometry_msgs/msg/TwistStamped"
    assert types["/tf_static"] == "tf2_msgs/msg/TFMessage"
