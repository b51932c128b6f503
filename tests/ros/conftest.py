"""A real ROS 1 master per test, and the graph's nodes as subprocesses.

Every test that takes ``ros`` gets its own ``roscore`` on a free port (never 11311), with
``ROS_MASTER_URI``, ``ROS_HOME`` and ``ROS_LOG_DIR`` pointing at it and at the test's tmp
folder, so tests run in parallel (pytest-xdist) and never touch a user's ROS graph. Nodes are
processes (rospy allows one node per process, bound to one master): ``ros.boids(...)`` runs
the ``boids`` command, ``ros.spawn(...)`` anything else. Each runs in a process group of its
own, which is stopped (by that group's id) when the test ends.

Without ROS 1 installed these tests are skipped, unless ``BOIDS_REQUIRE_ROS=1`` (CI sets it)
makes that a failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import xmlrpc.client
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from graph_support import Process, free_port

from boids_env.eval.ros.rospy_path import MissingRosError, import_rospy

NODES = Path(__file__).parent / "nodes"
REQUIRE_VARIABLE = "BOIDS_REQUIRE_ROS"


def _ros_or_skip() -> None:
    try:
        import_rospy()
    except MissingRosError as exc:
        if os.environ.get(REQUIRE_VARIABLE) == "1":
            pytest.fail(f"{REQUIRE_VARIABLE}=1 but ROS 1 is missing: {exc}")
        pytest.skip(f"ROS 1 is not installed: {exc}")
    if not any((Path(p) / "roscore").exists() for p in os.environ["PATH"].split(os.pathsep)):
        pytest.skip("roscore is not on PATH")


@dataclass
class RosGraph:
    """One test's ROS master and the processes started on it."""

    folder: Path
    env: dict[str, str]
    port: int
    processes: list[Process] = field(default_factory=list)

    @property
    def uri(self) -> str:
        return self.env["ROS_MASTER_URI"]

    def spawn(self, name: str, *argv: str, cwd: Path | None = None) -> Process:
        log = self.folder / f"{name}.log"
        with open(log, "wb") as out:
            popen = subprocess.Popen(list(argv), env=self.env, stdout=out,
                                     stderr=subprocess.STDOUT, cwd=cwd or self.folder,
                                     start_new_session=True)
        proc = Process(name, popen, log)
        self.processes.append(proc)
        return proc

    def boids(self, name: str, *args: str) -> Process:
        """``boids ARGS`` (the installed command's module, with this interpreter)."""
        return self.spawn(name, sys.executable, "-m", "boids_env.train.cli", *args)

    def node(self, name: str, script: str, *args: str) -> Process:
        """One of the test nodes of ``tests/ros/nodes``."""
        return self.spawn(name, sys.executable, str(NODES / script), *args)

    def param(self, name: str) -> object:
        """A parameter from the master (XML-RPC, no rospy node needed)."""
        code, message, value = xmlrpc.client.ServerProxy(self.uri).getParam("/pytest", name)
        assert code == 1, f"no parameter {name}: {message}"
        return value

    def close(self) -> None:
        for proc in reversed(self.processes):
            proc.stop()


@pytest.fixture
def rospy():
    """ROS 1's rospy, its message packages checked (no master)."""
    _ros_or_skip()
    return import_rospy()


@pytest.fixture
def ros(tmp_path):
    """A fresh roscore on a free port, torn down (with every node) after the test."""
    _ros_or_skip()
    port = free_port()
    home = tmp_path / "ros_home"
    home.mkdir()
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_IP": "127.0.0.1",
           "ROS_HOME": str(home), "ROS_LOG_DIR": str(home / "log"),
           "PYTHONUNBUFFERED": "1", "SDL_VIDEODRIVER": "dummy"}
    env.pop("ROS_HOSTNAME", None)
    graph = RosGraph(tmp_path, env, port)
    core = graph.spawn("roscore", "roscore", "-p", str(port))
    master = xmlrpc.client.ServerProxy(graph.uri)
    deadline = time.monotonic() + 30
    while True:
        try:
            master.getPid("/pytest")
            break
        except OSError:
            if time.monotonic() > deadline or core.popen.poll() is not None:
                graph.close()
                pytest.fail(f"roscore did not start on port {port}:\n{core.output()}")
            time.sleep(0.1)
    try:
        yield graph
    finally:
        graph.close()
