"""Training seeds side by side: ``boids train --seeds``, locally and as Ray tasks on a local
two-node cluster; a killed sweep trains only what is missing; the seeds table."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from boids_env.eval.stats import iqm
from boids_env.train.config import TrainConfig
from boids_env.train.sweep import check_seeds, latest_checkpoint, plan, run_sweep

TINY = ["--timesteps", "3000", "--copies", "1", "--group-sizes", "3", "--eval-every", "0",
        "--processes", "1", "--torch-threads", "1"]


def test_iqm_is_the_mean_of_the_middle_half():
    assert iqm([1.0, 2.0, 3.0, 100.0]) == 2.5, "25 % trimmed from each end"
    assert iqm([1.0, 2.0, 3.0]) == 2.0
    assert iqm(np.arange(8.0)) == np.mean([2.0, 3.0, 4.0, 5.0])


def test_bad_seed_lists_are_refused():
    for bad, match in (([], "1 to 64"), ([1, 1], "distinct"), ([-1], "integers"),
                       ([True], "integers")):
        with pytest.raises(ValueError, match=match):
            check_seeds(bad)


def test_the_plan_skips_finished_seeds_and_resumes_the_others(tmp_path):
    config = TrainConfig(total_timesteps=1000, copies=1, group_sizes=(3,))
    (tmp_path / "seed_0").mkdir()
    (tmp_path / "seed_0" / "model.zip").write_bytes(b"x")
    checkpoints = tmp_path / "seed_1" / "checkpoints"
    checkpoints.mkdir(parents=True)
    for steps in (512, 2048, 1024):
        (checkpoints / f"model_{steps}_steps.zip").write_bytes(b"x")
    jobs, done = plan(config, (0, 1, 2), tmp_path)
    assert done == [0]
    assert [(j.config["seed"], j.resume and os.path.basename(j.resume)) for j in jobs] == [
        (1, "model_2048_steps.zip"), (2, None)]
    assert latest_checkpoint(tmp_path / "seed_2") is None


def _boids(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "boids_env.train.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, **kwargs)


@pytest.mark.slow
def test_a_killed_sweep_goes_on_with_only_what_is_missing(tmp_path):
    out = tmp_path / "sweep"
    args = ["train", "--seeds", "0", "1", "--workers", "1", "--checkpoint-every", "1024",
            *TINY, "--out", str(out)]
    proc = _boids(*args)
    deadline = time.monotonic() + 240
    while not (latest_checkpoint(out / "seed_1") and (out / "seed_0" / "model.zip").exists()):
        assert proc.poll() is None, proc.stdout.read()
        assert time.monotonic() < deadline, "seed 1 never got a checkpoint"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its seed's training
    proc.wait()
    assert not (out / "seed_1" / "model.zip").exists(), "killed before seed 1 finished"
    first = (out / "seed_0" / "model.zip").stat().st_mtime_ns
    rerun = _boids(*args)
    text, _ = rerun.communicate(timeout=300)
    assert rerun.returncode == 0, text
    assert "seeds [0] already trained" in text and "seed 1 goes on from" in text, text
    assert (out / "seed_0" / "model.zip").stat().st_mtime_ns == first, "seed 0 untouched"
    table = pd.read_csv(out / "seeds.csv")
    assert table["seed"].tolist() == [0, 1]
    assert "| total |" in (out / "seeds.md").read_text()


@pytest.mark.slow
def test_seeds_train_as_ray_tasks_on_a_two_node_cluster(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    try:
        cluster.wait_for_nodes()
        monkeypatch.setenv("RAY_ADDRESS", cluster.address)
        ray.init(address=cluster.address, include_dashboard=False)
        assert len([n for n in ray.nodes() if n["Alive"]]) == 2
        config = TrainConfig(total_timesteps=2000, copies=1, group_sizes=(3,), eval_every=0,
                             checkpoint_every=0, processes=1, torch_threads=1)
        table = run_sweep(config, (0, 1), tmp_path / "sweep", backend="ray")
        rows = pd.read_csv(table)
        assert rows["seed"].tolist() == [0, 1]
        for seed in (0, 1):
            assert (tmp_path / "sweep" / f"seed_{seed}" / "model.zip").is_file()
        assert np.isfinite(rows["total"]).all()
        # the two seeds are different trainings
        assert rows.loc[0, "total"] != rows.loc[1, "total"]
    finally:
        ray.shutdown()
        cluster.shutdown()


def test_every_seed_fine_tunes_the_given_model_unless_it_has_checkpoints(tmp_path):
    config = TrainConfig(total_timesteps=1000, copies=1, group_sizes=(3,))
    checkpoints = tmp_path / "seed_1" / "checkpoints"
    checkpoints.mkdir(parents=True)
    (checkpoints / "model_512_steps.zip").write_bytes(b"x")
    jobs, done = plan(config, (0, 1), tmp_path, resume="/models/shipped.zip")
    assert done == []
    assert [(j.config["seed"], j.resume and os.path.basename(j.resume)) for j in jobs] == [
        (0, "shipped.zip"), (1, "model_512_steps.zip")]


def test_a_sweep_with_more_timesteps_is_the_same_sweep():
    """It was refused: the sweep's identity held total_timesteps, so a killed sweep could not
    be rerun longer (or shorter)."""
    from boids_env.train.sweep import sweep_identity

    config = TrainConfig(total_timesteps=1000, copies=1, group_sizes=(3,))
    assert sweep_identity(config) == sweep_identity(config.replace(
        total_timesteps=5000, processes=1, torch_threads=1, seed=4))
    assert sweep_identity(config) != sweep_identity(config.replace(learning_rate=1e-3))
