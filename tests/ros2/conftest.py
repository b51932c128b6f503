"""ROS 2 over Zenoh on loopback, without a ROS 2 install: the graph's nodes as subprocesses
(``boids ros2 sim|controller``) that meet on a free 127.0.0.1 port (the simulator listens,
every other session connects to it: no router, no multicast scouting), and an in-process
"spy" session that sees every sample and liveliness token on the wire.

Without the ``ros2`` extra (eclipse-zenoh) these tests are skipped, unless
``BOIDS_REQUIRE_ROS2=1`` (CI sets it) makes that a failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from graph_support import Process, free_port

REQUIRE_VARIABLE = "BOIDS_REQUIRE_ROS2"


def zenoh_or_skip():
    try:
        import zenoh
    except ImportError as exc:
        if os.environ.get(REQUIRE_VARIABLE) == "1":
            pytest.fail(f"{REQUIRE_VARIABLE}=1 but eclipse-zenoh is missing: {exc}")
        pytest.skip(f"the ros2 extra (eclipse-zenoh) is not installed: {exc}")
    return zenoh


@dataclass
class Spy:
    """Every data sample (key, payload, attachment) and liveliness token seen on the wire."""

    samples: list[tuple[str, bytes, bytes | None]] = field(default_factory=list)
    tokens: set[str] = field(default_factory=set)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_sample(self, sample) -> None:
        attachment = None if sample.attachment is None else sample.attachment.to_bytes()
        with self.lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes(), attachment))

    def on_token(self, sample) -> None:
        with self.lock:
            self.tokens.add(str(sample.key_expr))


@dataclass
class Ros2Graph:
    """One test's loopback network: the simulator listens on ``port``."""

    folder: Path
    port: int
    processes: list[Process] = field(default_factory=list)
    keep: list[object] = field(default_factory=list)

    @property
    def endpoint(self) -> str:
        return f"tcp/127.0.0.1:{self.port}"

    def boids(self, name: str, *argv: str) -> Process:
        """``boids ros2 <argv>``: the sim listens on the test's port, others connect to it."""
        if argv[0] == "sim":
            net = ["--listen", self.endpoint, "--connect", self.endpoint]
        else:
            net = ["--connect", self.endpoint, "--listen", "tcp/127.0.0.1:0"]
        log = self.folder / f"{name}.log"
        env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "ROS_DOMAIN_ID": "0"}
        with open(log, "wb") as out:
            popen = subprocess.Popen(
                [sys.executable, "-m", "boids_env.train.cli", "ros2", *argv, *net], env=env,
                stdout=out, stderr=subprocess.STDOUT, cwd=self.folder, start_new_session=True)
        process = Process(name, popen, log)
        self.processes.append(process)
        return process

    def spy(self) -> tuple[object, Spy]:
        """An in-process session connected to the simulator that records everything."""
        zenoh = zenoh_or_skip()
        from boids_env.eval.ros2.node import Endpoints

        conf = Endpoints(connect=(self.endpoint,), listen=("tcp/127.0.0.1:0",)).config()
        session = zenoh.open(conf)
        spy = Spy()
        import zenoh.ext as zext

        # an advanced subscriber with history: also the latched topics' cached samples
        subs = [zext.declare_advanced_subscriber(
                    session, "0/**", spy.on_sample,
                    history=zext.HistoryConfig(detect_late_publishers=True)),
                session.liveliness().declare_subscriber("@ros2_lv/**", spy.on_token,
                                                        history=True)]
        self.keep.extend(subs)  # undeclared when garbage collected: keep them
        return session, spy


@pytest.fixture
def ros2(tmp_path):
    zenoh_or_skip()
    graph = Ros2Graph(tmp_path, free_port())
    yield graph
    for process in graph.processes:
        process.stop()

