"""Issue 55: a PPO training stopped after a checkpoint and resumed from it goes on bit for bit:
its final and best models, every checkpoint and evaluations.csv equal an uninterrupted run's
(the checkpoint carries its rollout boundary, train/boundary.py)."""

import io
import zipfile

import pytest
import torch

from boids_env.train.config import TrainConfig
from boids_env.train.run import train

pytestmark = pytest.mark.slow

TINY = {"total_timesteps": 1400, "group_sizes": (4, 5), "copies": 2, "n_steps": 40,
        "batch_size": 140, "n_epochs": 1, "eval_every": 280, "eval_seeds": (0,),
        "checkpoint_every": 350, "processes": 1, "torch_threads": 1,
        "env_fields": {"max_cycles": 30, "neighbours": 4}}


def _weights(path):
    with zipfile.ZipFile(path) as zf:
        return {name: torch.load(io.BytesIO(zf.read(name)), weights_only=True)
                for name in ("policy.pth", "policy.optimizer.pth")}


def _same(a, b):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, torch.Tensor):
        return torch.equal(a, b)
    return a == b


def test_a_resume_from_a_mid_rollout_checkpoint_equals_an_uninterrupted_run(tmp_path):
    cfg = TrainConfig(**TINY)
    whole, stopped = tmp_path / "whole", tmp_path / "stopped"
    train(cfg, whole)
    train(cfg.replace(total_timesteps=700), stopped)  # stops at 840: as if killed there
    # 700 falls mid-rollout (rollouts of 280): the resume collects from 560 again
    train(cfg, stopped, resume=stopped / "checkpoints" / "model_700_steps.zip")
    names = ["model.zip", "best_model.zip", *(f"checkpoints/model_{n}_steps.zip"
                                              for n in (350, 700, 1050, 1400))]
    for name in names:
        assert _same(_weights(whole / name), _weights(stopped / name)), name
    assert (stopped / "evaluations.csv").read_bytes() == (whole / "evaluations.csv").read_bytes()
