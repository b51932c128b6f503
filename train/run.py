"""``boids train``: a Stable-Baselines3 run with parameter sharing over the flock's followers.

Writes to the output folder: ``config.json`` (the resolved :class:`TrainConfig`),
``model.zip`` (the final model, loadable by ``boids run --policy``), ``best_model.zip`` (best
periodic evaluation), ``evaluations.csv``, ``checkpoints/model_<steps>_steps.zip`` and
TensorBoard logs under ``tb/``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.vec_env import VecMonitor

from boids_env.policies.sb3_policy import algorithm_class, read_meta, write_meta
from boids_env.train.callbacks import Checkpoints, FlockEvalCallback, TrainingMetricsCallback
from boids_env.train.config import TrainConfig
from boids_env.train.resume import load_checkpoint
from boids_env.train.vec_env import CopySpec, FlockVecEnv


def copy_specs(config: TrainConfig) -> list[CopySpec]:
    """The env copies of a run: ``copies`` of them, group sizes assigned round robin."""
    sizes = config.group_sizes
    choices = {name: values for name, values in (
        ("path_rotation", config.path_rotations), ("path_mirror", config.path_mirrors),
        ("obs_noise", config.obs_noises)) if values != (0.0,) and values != (False,)}
    return [CopySpec(sizes[i % len(sizes)], config.leader_speeds, config.paths,
                     dict(config.env_fields), choices) for i in range(config.copies)]


def check_episodes(config: TrainConfig) -> None:
    """Builds the env config of every episode the run can draw (each group size, speed, path,
    rotation, mirror and noise), so a combination the env refuses fails before anything is
    written, naming the training field that holds it."""
    from itertools import product

    from boids_env.config import EnvConfig

    base = EnvConfig.from_kwargs(**config.env_fields)
    for combo in product(sorted(set(config.group_sizes)), config.leader_speeds, config.paths,
                         config.path_rotations, config.path_mirrors, config.obs_noises):
        robots, speed, path, turn, mirror, noise = combo
        try:
            base.replace(robots=robots, leader_speed=speed, path=path, path_rotation=turn,
                         path_mirror=mirror, obs_noise=noise)
        except (ValueError, TypeError) as exc:
            raise ValueError(
                f"the training config draws an episode the env refuses (group_sizes {robots}, "
                f"leader_speeds {speed}, paths {path!r}, path_rotations {turn}, path_mirrors "
                f"{mirror}, obs_noises {noise}, env_fields {config.env_fields}): {exc}"
            ) from None


def make_vec_env(config: TrainConfig) -> FlockVecEnv:
    """The VecEnv of a run over :func:`copy_specs`."""
    return FlockVecEnv(copy_specs(config), seed=config.seed, processes=config.processes)


def model_meta(config: TrainConfig) -> dict[str, Any]:
    """The ``boids.json`` entry written into every model zip of the run."""
    return {"algorithm": config.algorithm, "env_fields": dict(config.env_fields),
            "train_config": config.to_dict()}


def whole_rollouts(config: TrainConfig, slots: int, remaining: int) -> int:
    """``remaining`` follower-steps rounded up to what the algorithm really runs: PPO collects
    whole rollouts of ``n_steps`` × slots, SAC ``train_freq`` × slots per update."""
    chunk = slots * (config.n_steps if config.algorithm == "ppo" else config.train_freq)
    return -(-remaining // chunk) * chunk


def check_resume(config: TrainConfig, resume: str | Path | None, trust_model: bool) -> None:
    """The checks of ``--resume`` (and what needs it) before anything is built or written."""
    if resume is None:
        if trust_model:
            raise ValueError("trust_model applies to the checkpoint of --resume; none is given")
        if config.resume_log_std is not None:
            raise ValueError("resume_log_std is set but no checkpoint is resumed: it resets "
                             "the exploration of a trained model (give --resume "
                             "CHECKPOINT.zip)")
        return
    if not Path(resume).is_file():
        raise FileNotFoundError(f"checkpoint to resume not found: {resume}")
    saved = read_meta(resume).get("algorithm", config.algorithm)
    if saved != config.algorithm:
        raise ValueError(f"checkpoint {resume} was trained with {saved}, the config says "
                         f"algorithm={config.algorithm!r}")


def train(config: TrainConfig, out: str | Path, *, resume: str | Path | None = None,
          progress_bar: bool = False, verbose: int = 0, trust_model: bool = False) -> Path:
    """Trains a follower policy and returns the path of the final ``model.zip``.

    Args:
        config: the run's configuration.
        out: output folder (created).
        resume: a checkpoint zip of this run to continue from; training goes on until
            ``config.total_timesteps`` in all (the env copies restart their episodes). The
            config rebuilds the model and the checkpoint gives its weights, optimizer state
            and step count, read without running anything stored in the zip
            (:mod:`boids_env.train.resume`).
        trust_model: load ``resume`` through SB3's own load instead, which unpickles the
            objects stored in the zip (a checkpoint whose network the config does not build;
            only for files you trust).
        progress_bar: show SB3's progress bar (tqdm + rich).
        verbose: SB3 verbosity (0 quiet, 1 tables).
    """
    import torch

    check_episodes(config)
    out = Path(out)
    check_resume(config, resume, trust_model)
    torch.set_num_threads(config.resolved_threads())
    device = config.resolved_device()
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("device='cuda' but torch sees no GPU; use device='cpu' or 'auto'")
    meta = model_meta(config)
    venv = VecMonitor(make_vec_env(config))
    cls = algorithm_class(config.algorithm)
    try:
        if resume is not None:  # a checkpoint that cannot be read is refused before writing
            model = load_checkpoint(resume, config, venv, device, str(out / "tb"), verbose,
                                    trust=trust_model)
            model.set_random_seed(config.seed)
            if config.resume_log_std is not None:  # explore again (PPO's state-free log std)
                with torch.no_grad():
                    model.policy.log_std.fill_(config.resume_log_std)
        else:
            model = cls("MlpPolicy", venv, device=device, verbose=verbose,
                        tensorboard_log=str(out / "tb"), **config.algorithm_kwargs())
        out.mkdir(parents=True, exist_ok=True)
        (out / "config.json").write_text(json.dumps(config.to_dict(), indent=2))
        remaining = config.total_timesteps - (model.num_timesteps if resume else 0)

        def save(path: Path) -> None:
            model.save(path)
            write_meta(path, meta, model)

        evaluator = FlockEvalCallback(out, config.eval_every, config.eval_seeds,
                                      config.env_fields, save_best=save)
        evaluator.verbose = verbose
        callbacks: list[Any] = [TrainingMetricsCallback(), evaluator]
        if config.checkpoint_every:
            callbacks.append(Checkpoints(config.checkpoint_every // venv.num_envs,
                                         out / "checkpoints", meta))
        if remaining > 0:
            rounded = whole_rollouts(config, venv.num_envs, remaining)
            if rounded != remaining:
                print(f"boids train: {remaining:,} follower-steps round up to {rounded:,} "
                      f"(whole rollouts of {venv.num_envs} follower slots)")
            model.learn(rounded, callback=CallbackList(callbacks), progress_bar=progress_bar,
                        reset_num_timesteps=resume is None, tb_log_name="run")
        save(out / "model.zip")
    finally:
        venv.close()
    return out / "model.zip"
