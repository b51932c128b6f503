"""`boids eval` interrupted for real: Ctrl-C (SIGINT to the process group, as a terminal
sends it) stops it within seconds, keeps every finished episode and leaves no process behind;
SIGKILL of the main process leaves no orphan (workers, forkserver, resource tracker) for
long; a rerun resumes without redoing finished episodes."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from boids_env.eval.runner import EPISODES, read_jsonl

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc")]

HERE = Path(__file__).parent
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join(
    p for p in (str(HERE), os.environ.get("PYTHONPATH", "")) if p)}
EPISODES_IN_SUITE = 8
SUITE = ('name = "slow"\nseeds = 8\n[defaults]\nrobots = 3\nmax_cycles = 12\n'
         '[[case]]\nname = "one"\n')


def _as_in_a_terminal() -> None:
    """The child's SIGINT as a terminal gives it (default), whatever pytest inherited: a
    shell starting a job in the background (``cmd &``, nohup) sets it to ignored, and Python
    then installs no KeyboardInterrupt handler, so Ctrl-C could not be tested."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def session_processes(sid: int) -> list[int]:
    """Live (non-zombie) processes of session ``sid``."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        state, _ppid, _pgrp, session = text[text.rindex(")") + 2:].split()[:4]
        if int(session) == sid and state != "Z":
            pids.append(int(stat.parent.name))
    return pids


def _start(tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    suite = tmp_path / "slow.toml"
    suite.write_text(SUITE)
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "boids_env.train.cli", "eval", "--policy", "faulty_policies:Slow",
         "--suite", str(suite), "--workers", "2", "--out", str(out), "--no-progress"],
        env=ENV, cwd=tmp_path, start_new_session=True, preexec_fn=_as_in_a_terminal,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, out


def _wait_for_rows(proc: subprocess.Popen, out: Path, rows: int) -> int:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        got = len(read_jsonl(out / EPISODES))
        if got >= rows:
            return got
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    proc.kill()
    raise AssertionError(f"fewer than {rows} episodes after 120 s")


def _gone(sid: int, limit: float) -> float:
    """Seconds until session ``sid`` has no live process (fails after ``limit``)."""
    start = time.monotonic()
    while session_processes(sid):
        if time.monotonic() - start > limit:
            left = session_processes(sid)
            for pid in left:
                os.kill(pid, signal.SIGKILL)
            raise AssertionError(f"processes {left} still alive {limit} s later")
        time.sleep(0.05)
    return time.monotonic() - start


def _rerun_completes(tmp_path: Path, out: Path) -> None:
    before = {r["key"] for r in read_jsonl(out / EPISODES)}
    proc = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "eval", "--policy", "faulty_policies:Slow",
         "--suite", str(tmp_path / "slow.toml"), "--workers", "2", "--out", str(out),
         "--no-progress"], env=ENV, cwd=tmp_path,
        capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    keys = [r["key"] for r in read_jsonl(out / EPISODES)]
    assert len(keys) == len(set(keys)) == EPISODES_IN_SUITE  # nothing finished ran twice
    assert before <= set(keys)
    assert len(pd.read_parquet(out / "results.parquet")) == EPISODES_IN_SUITE


def test_ctrl_c_stops_within_seconds_keeps_finished_episodes_and_leaves_no_process(tmp_path):
    proc, out = _start(tmp_path)
    seen = _wait_for_rows(proc, out, 2)
    assert proc.poll() is None, "the run ended before Ctrl-C was sent"
    os.killpg(proc.pid, signal.SIGINT)
    start = time.monotonic()
    _, err = proc.communicate(timeout=60)
    stopped = time.monotonic() - start
    cleaned = _gone(proc.pid, 10)
    print(f"Ctrl-C: exited after {stopped:.2f} s, last process gone {cleaned:.2f} s later")
    assert proc.returncode == 130, err
    assert stopped < 5, stopped
    assert "interrupted" in err and "Traceback" not in err, err
    kept = read_jsonl(out / EPISODES)
    assert seen <= len(kept) < EPISODES_IN_SUITE
    # The results table was written on the way out, with every kept episode.
    assert len(pd.read_parquet(out / "results.parquet")) == len(kept)
    json.loads((out / "manifest.json").read_text())
    _rerun_completes(tmp_path, out)


def test_sigkill_of_the_main_process_leaves_no_orphan_for_long(tmp_path):
    proc, out = _start(tmp_path)
    _wait_for_rows(proc, out, 1)
    assert len(session_processes(proc.pid)) >= 3  # main, forkserver, workers
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    cleaned = _gone(proc.pid, 10)
    print(f"SIGKILL: every process of the run gone {cleaned:.2f} s after the main one")
    assert cleaned < 5, cleaned
    _rerun_completes(tmp_path, out)
