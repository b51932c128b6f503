"""Issue 55: ``boids eval`` killed at seeded-random moments (SIGKILL after the k-th finished
episode appears, Ctrl-C at a random time into a resumed run) loses no finished episode, and
the run resumed to the end gives the table of a run never stopped, bit for bit (the wall
time aside) with the same trajectory files."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from boids_env.eval.runner import EPISODES, TRAJECTORIES, PolicySpec, read_jsonl, run_suite
from boids_env.eval.suites import load_suite

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX signals")]

HERE = Path(__file__).parent
ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "PYTHONPATH": os.pathsep.join(
    p for p in (str(HERE), os.environ.get("PYTHONPATH", "")) if p)}
SUITE = ('name = "kills"\nseeds = 3\n[defaults]\nrobots = 4\nmax_cycles = 30\n'
         '[[case]]\nname = "one"\n[[case]]\nname = "slower"\nleader_speed = 0.45\n')
EPISODES_IN_SUITE = 6
POLICY = "faulty_policies:SlowReynolds"


def _as_in_a_terminal() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(suite: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "boids_env.train.cli", "eval", "--policy", POLICY,
         "--suite", str(suite), "--workers", "2", "--out", str(out), "--no-progress"],
        env=ENV, cwd=suite.parent, start_new_session=True, preexec_fn=_as_in_a_terminal,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _keys(out: Path) -> list[str]:
    return [r["key"] for r in read_jsonl(out / EPISODES)]


def _wait_for_rows(proc: subprocess.Popen, out: Path, rows: int) -> None:
    deadline = time.monotonic() + 120
    while len(_keys(out)) < rows:
        assert proc.poll() is None, ("the run ended before it was killed", proc.communicate())
        assert time.monotonic() < deadline, f"fewer than {rows} episodes after 120 s"
        time.sleep(0.01)


def _frame(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=["wall_time"]).reset_index(drop=True)


def test_kills_at_random_moments_lose_no_episode_and_the_resumed_table_is_the_same(tmp_path):
    rng = np.random.default_rng(55)
    suite = tmp_path / "kills.toml"
    suite.write_text(SUITE)
    run_suite([PolicySpec(POLICY)], load_suite(suite),
                          tmp_path / "reference", backend="inline", progress=False)
    out = tmp_path / "out"

    # SIGKILL of the main process after the k-th finished episode appears
    k = int(rng.integers(1, EPISODES_IN_SUITE - 1))
    proc = _start(suite, out)
    _wait_for_rows(proc, out, k)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    kept = _keys(out)
    assert k <= len(kept) < EPISODES_IN_SUITE, (k, kept)

    # Ctrl-C (to the process group, as a terminal sends it) at a random time into a resume
    proc = _start(suite, out)
    time.sleep(float(rng.uniform(0.0, 3.0)))
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode in (0, 130), err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    again = _keys(out)
    assert set(kept) <= set(again), "a finished episode was lost"
    assert len(again) == len(set(again)), "a finished episode ran twice"

    done = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "eval", "--policy", POLICY, "--suite",
         str(suite), "--workers", "2", "--out", str(out), "--no-progress"], env=ENV,
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    keys = _keys(out)
    assert len(keys) == len(set(keys)) == EPISODES_IN_SUITE, "each episode once"
    assert set(again) <= set(keys)
    resumed = pd.read_parquet(out / "results.parquet")
    reference = pd.read_parquet(tmp_path / "reference" / "results.parquet")
    pd.testing.assert_frame_equal(_frame(resumed), _frame(reference), check_exact=True)
    for path in sorted((tmp_path / "reference" / TRAJECTORIES).iterdir()):
        assert pd.read_parquet(out / TRAJECTORIES / path.name).equals(pd.read_parquet(path)), \
            path.name
