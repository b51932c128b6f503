"""`boids run` end to end in a subprocess, with a short episode."""

import json
import os
import subprocess
import sys

import imageio.v3 as iio
import pytest

from boids_env.recording import Recording


@pytest.mark.slow
def test_boids_run_writes_every_file(tmp_path):
    out = tmp_path / "run"
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    proc = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "run", "--robots", "7",
         "--leader-speed", "0.6", "--max-cycles", "40", "--seed", "3", "--video", "--bag",
         "--mcap", "--out", str(out)],
        capture_output=True, text=True, env=env, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "V_sep" in proc.stdout and "V_align" in proc.stdout
    files = {p.name for p in out.iterdir()}
    assert {"metrics.json", "trajectory.parquet", "config.json", "episode.gif",
            "episode.bag", "episode_mcap"} <= files
    metrics = json.loads((out / "metrics.json").read_text())
    assert {"V_sep", "V_coh", "V_align", "min_distance", "collisions"} <= metrics.keys()
    assert metrics["steps"] == 40
    config = json.loads((out / "config.json").read_text())
    assert config["env"]["scenario"]["robots"] == 7 and config["seed"] == 3
    rec = Recording.from_parquet(out / "trajectory.parquet")
    assert rec.metrics()["V_align"] == metrics["V_align"]
    from boids_env.rosbag import read_bag

    assert read_bag(out / "episode.bag").metrics()["V_align"] == metrics["V_align"]
    assert read_bag(out / "episode_mcap").metrics()["V_align"] == metrics["V_align"]
    frames = iio.imread(out / "episode.gif")
    assert frames.ndim == 4 and frames.shape[0] >= 20
    assert "video" in proc.stdout and "writing took" in proc.stdout, proc.stdout
    manifest = json.loads((out / "manifest.json").read_text())
    assert set(manifest["files"]) == files - {"manifest.json"}, manifest

    # the same command again: refused with a clear message, the folder untouched
    again = [sys.executable, "-m", "boids_env.train.cli", "run", "--robots", "7",
             "--max-cycles", "20", "--seed", "4", "--bag", "--out", str(out)]
    proc = subprocess.run(again, capture_output=True, text=True, env=env, timeout=300,
                          check=False)
    assert proc.returncode == 2 and "--overwrite" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert json.loads((out / "metrics.json").read_text()) == metrics
    # with --overwrite: exactly the new run's files, no stale GIF or MCAP bag beside them
    proc = subprocess.run([*again, "--overwrite"], capture_output=True, text=True, env=env,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in out.iterdir()} == {"metrics.json", "trajectory.parquet",
                                              "config.json", "episode.bag", "manifest.json"}
    assert read_bag(out / "episode.bag").metrics()["steps"] == 20


def test_boids_run_bad_argument_is_a_clear_error(tmp_path, capsys):
    from boids_env.train.cli import main

    assert main(["run", "--leader-speed", "-1", "--out", str(tmp_path)]) == 2
    assert "leader_speed must be in" in capsys.readouterr().err


def test_bag_start_takes_iso_or_unix_seconds():
    import argparse

    from boids_env.eval.cli import parse_start

    assert parse_start("2024-05-01T12:00:00") == 1714564800.0, "UTC when no offset is given"
    assert parse_start("2024-05-01T14:00:00+02:00") == 1714564800.0
    assert parse_start("1714564800.5") == 1714564800.5
    for bad in ("yesterday", "-5", "1e12"):
        with pytest.raises(argparse.ArgumentTypeError, match="--bag-start"):
            parse_start(bad)
