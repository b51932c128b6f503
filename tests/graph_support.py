"""What the live-graph tests of ROS 1 (``tests/ros``) and ROS 2 (``tests/ros2``) share: the
nodes as processes, each in a process group of its own, and the bit-for-bit comparison of a
graph's recording with ``boids run``'s."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from boids_env.recording import Recording

FIELDS = ("positions", "velocities", "commanded", "time")
"""What a graph's recording must equal bit for bit."""


def free_port() -> int:
    """A free TCP port, never ROS's default 11311."""
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port != 11311:
            return port


def wait_until(condition, timeout: float) -> bool:
    """Polls ``condition`` until it holds or ``timeout`` seconds passed; returns it."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def assert_same_recording(ours: Recording, reference: Recording, what: str) -> None:
    """``ours`` equals ``reference`` bit for bit (:data:`FIELDS`); else fails at the first
    (step, robot) that differs."""
    for name in FIELDS:
        a, b = getattr(ours, name), getattr(reference, name)
        assert a.shape == b.shape, f"{what}: {name} shape {a.shape} != {b.shape}"
        bad = np.argwhere(a != b)
        if len(bad):
            where = tuple(bad[0][:2])  # (step, robot)
            pytest.fail(f"{what}: {name} differs first at (step, robot) {where}: "
                        f"{a[where]} vs {b[where]}")


@dataclass
class Process:
    """A node process; its output goes to a log file (a pipe could fill and block it)."""

    name: str
    popen: subprocess.Popen
    log: Path

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def wait(self, timeout: float) -> int:
        """The exit code; stops the process and fails the test with its output if it does
        not end in time."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.stop()
            pytest.fail(f"{self.name} did not finish within {timeout} s; output:\n"
                        f"{self.output()[-3000:]}")

    def wait_for_line(self, text: str, timeout: float) -> None:
        """Waits until the process has printed ``text``."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if text in self.output():
                return
            if self.popen.poll() is not None:
                break
            time.sleep(0.05)
        pytest.fail(f"{self.name} never printed {text!r} within {timeout} s; output:\n"
                    f"{self.output()[-3000:]}")

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> None:
        """Stops the process and its children (its own process group, e.g. ``rosbag
        record``'s recorder binary): ``sig``, then SIGKILL after ``timeout`` seconds."""
        if self.popen.poll() is None:
            self._signal_group(sig)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self._signal_group(signal.SIGKILL)
                self.popen.wait(timeout=timeout)
            # rosbag's Python wrapper exits at once; its recorder child still closes and
            # renames the bag (run.bag.active -> run.bag): let the group finish first
            deadline = time.monotonic() + timeout
            while self._group_alive() and time.monotonic() < deadline:
                time.sleep(0.05)
        self._signal_group(signal.SIGKILL)  # a child left behind by the process

    def _group_alive(self) -> bool:
        """Whether a process of the group is still running (zombies, which an exited
        parent leaves to init, do not count)."""
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == self.popen.pid and fields[0] != "Z":
                return True
        return False

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.popen.pid, sig)  # the group this test created for the process
        except ProcessLookupError:
            pass

