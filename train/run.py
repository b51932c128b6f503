"""``boids train``: a Stable-Baselines3 run with parameter sharing over the flock's followers.

Writes to the output folder: ``config.json`` (the resolved :class:`TrainConfig`),
``model.zip`` (the final model, loadable by ``boids run --policy``), ``best_model.zip`` (best
periodic evaluation), ``evaluations.csv``, ``checkpoints/model_<steps>_steps.zip``, TensorBoard
logs under ``tb/`` and ``manifest.json``.

The folder belongs to one training, as an eval folder to one evaluation
(:mod:`boids_env.eval.folder`): a folder holding anything else is refused unless
``overwrite``, which first removes what an earlier training of ours wrote (only the names
above) and keeps the user's own files; a training resumed from a checkpoint goes on in the
folder of the same config. The training writes into the folder as it goes, so TensorBoard
shows it live and an interrupted run keeps its checkpoints; every model zip is written
atomically (a kill never leaves a torn one).
"""

from __future__ import annotations

import json
import warnings
import zipfile
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.vec_env import VecMonitor

from boids_env.eval import folder
from boids_env.files import atomic_path, read_zip_entry, write_json
from boids_env.policies.cards import CARD_KEY
from boids_env.policies.registry import SB3_ENTRIES
from boids_env.policies.sb3_policy import read_meta, write_meta
from boids_env.train import boundary
from boids_env.train.callbacks import (
    Checkpoints,
    FlockEvalCallback,
    TrainingMetricsCallback,
    TrainingSummary,
)
from boids_env.train.cards import training_card
from boids_env.train.config import TrainConfig
from boids_env.train.ppo import learner_class
from boids_env.train.resume import load_checkpoint
from boids_env.train.vec_env import CopySpec, FlockVecEnv


def copy_specs(config: TrainConfig) -> list[CopySpec]:
    """The env copies of a run: ``copies`` of them, group sizes and worlds assigned round
    robin; a copy in a scene other than the study's arena drives the scene's own path (no
    path, rotation or mirror drawn)."""
    sizes, worlds = config.group_sizes, config.worlds
    shaped = {name: values for name, values in (
        ("path_rotation", config.path_rotations), ("path_mirror", config.path_mirrors))
        if values != (0.0,) and values != (False,)}
    common = {name: values for name, values in (
        ("obs_noise", config.obs_noises), ("leader_pauses", config.leader_pauses))
        if values != (0.0,) and values != ((),)}
    specs = []
    for i in range(config.copies):
        world = worlds[i % len(worlds)]
        fields = {**config.env_fields, **world}
        arena = _in_arena(fields)
        specs.append(CopySpec(sizes[i % len(sizes)], config.leader_speeds,
                              config.paths if arena else (), fields,
                              {**shaped, **common} if arena else dict(common)))
    return specs


def _in_arena(fields: dict[str, Any]) -> bool:
    """Whether env fields put the episode in the study's arena (of any size)."""
    return fields.get("scene", fields.get("map", "arena")) == "arena"


def check_episodes(config: TrainConfig) -> None:
    """Builds the env config of every episode the run can draw (each copy's group size and
    world with each speed, path, rotation and mirror; each noise and pause list), so a
    combination the env refuses fails before anything is written, naming the training field
    that holds it."""
    from itertools import product

    from boids_env.config import EnvConfig

    copies = {(s.robots, json.dumps(s.env_fields, sort_keys=True)): s
              for s in copy_specs(config)}
    for spec in copies.values():
        base = EnvConfig.from_kwargs(**spec.env_fields)
        arena = bool(spec.paths)
        shapes = product(spec.paths, config.path_rotations, config.path_mirrors) if arena \
            else [(None, None, None)]
        for speed, (path, turn, mirror) in product(config.leader_speeds, list(shapes)):
            drawn = {"robots": spec.robots, "leader_speed": speed}
            if arena:
                drawn.update(path=path, path_rotation=turn, path_mirror=mirror)
            _check_episode(config, base, drawn)
        for noise, pauses in product(config.obs_noises, config.leader_pauses):
            _check_episode(config, base, {"robots": spec.robots, "obs_noise": noise,
                                          "leader_pauses": pauses})


def _check_episode(config: TrainConfig, base: Any, drawn: dict[str, Any]) -> None:
    try:
        base.replace(**drawn)
    except (ValueError, TypeError) as exc:
        where = {k: v for k, v in base.to_dict()["world"].items() if k in ("scene",
                                                                        "arena_half_size")}
        raise ValueError(
            f"the training config draws an episode the env refuses ({drawn}, world {where}, "
            f"env_fields {config.env_fields}; from group_sizes, leader_speeds, paths, "
            f"path_rotations, path_mirrors, obs_noises, leader_pauses and worlds): {exc}"
        ) from None


def make_vec_env(config: TrainConfig) -> FlockVecEnv:
    """The VecEnv of a run over :func:`copy_specs`."""
    return FlockVecEnv(copy_specs(config), seed=config.seed, processes=config.processes)


def model_meta(config: TrainConfig) -> dict[str, Any]:
    """The ``boids.json`` entry written into every model zip of the run (final, best and
    checkpoints), with the observation layout the model reads (its named blocks), so that an
    env built otherwise is refused by name rather than fed the wrong numbers, and the model's
    card (what it was trained on: :func:`~boids_env.train.cards.training_card`)."""
    from boids_env.config import EnvConfig
    from boids_env.observations import layout_of

    layout = layout_of(EnvConfig.from_kwargs(**config.env_fields))
    return {"algorithm": config.algorithm, "env_fields": dict(config.env_fields),
            "observation_layout": [list(block) for block in layout.blocks],
            "train_config": config.to_dict(), CARD_KEY: training_card(config).to_dict()}


DATA_LIMIT = 16 << 20
"""The most bytes a checkpoint's SB3 ``data`` entry may hold when its timesteps are read
(SB3 writes a few hundred kB)."""
RESUME_FREE = ("total_timesteps", "processes", "torch_threads", "device", "resume_log_std",
               "resume_new_inputs", "resume_new_blocks")
"""Config fields that do not make another training: a resume may change them."""


def identity(config: TrainConfig) -> dict[str, Any]:
    """What makes two trainings the same (a resume goes on in the folder of the same one):
    its config, and the content of every file its env copies read (a scene file, a map's
    YAML and image, a recorded walk), so an edited file is never resumed as the old one."""
    from boids_env.config import EnvConfig
    from boids_env.files import file_digest

    out = {k: v for k, v in config.to_dict().items() if k not in RESUME_FREE}
    files = {path for spec in copy_specs(config)
             for path in EnvConfig.from_kwargs(**spec.env_fields).input_files()}
    if files:  # absent without files: trainings that read none keep their identity
        out["inputs"] = {str(path): file_digest(path) for path in sorted(files)}
    return out


def checkpoint_timesteps(path: str | Path) -> int:
    """The follower-steps an SB3 model zip has trained, from its ``data`` entry (without
    loading the model); ``ValueError`` naming the file when it is not such a zip."""
    try:
        with zipfile.ZipFile(path) as zf:
            data = json.loads(read_zip_entry(zf, "data", DATA_LIMIT))
        steps = data["num_timesteps"]
    except (OSError, zipfile.BadZipFile, EOFError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"cannot read the checkpoint to resume {path}: not an SB3 model zip "
                         f"({exc})") from None
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise ValueError(f"checkpoint {path}: num_timesteps must be a count, got {steps!r}")
    return steps


def check_resume(config: TrainConfig, out: Path, resume: str | Path | None,
                 overwrite: bool, trust_model: bool = False) -> None:
    """Refuses, before anything is written, a resume that would train nothing or of another
    algorithm, a checkpoint that ``overwrite`` would delete, and ``resume_log_std`` or
    ``trust_model`` without a resume."""
    if resume is None:
        if trust_model:
            raise ValueError("trust_model applies to the checkpoint of --resume; none is given")
        if config.resume_log_std is not None:
            raise ValueError("resume_log_std is set but no checkpoint is resumed: it resets the "
                             "exploration of a trained model (give --resume CHECKPOINT.zip)")
        for name in ("resume_new_inputs", "resume_new_blocks"):
            if getattr(config, name):
                raise ValueError(f"{name} is set but no checkpoint is resumed: it widens "
                                 "a trained model's inputs (give --resume CHECKPOINT.zip)")
        return
    if not Path(resume).is_file():
        raise FileNotFoundError(f"checkpoint to resume not found: {resume}")
    saved = read_meta(resume).get("algorithm", config.algorithm)  # refuses a non-zip by name
    with zipfile.ZipFile(resume) as archive:
        names = set(archive.namelist())
    missing = [name for name in SB3_ENTRIES if name not in names]
    if missing:
        raise ValueError(f"--resume {resume} is not a Stable-Baselines3 checkpoint (its zip "
                         f"lacks {', '.join(missing)}); give a model.zip or "
                         f"checkpoints/model_<steps>_steps.zip of boids train")
    done = checkpoint_timesteps(resume)
    if config.total_timesteps <= done:
        raise ValueError(f"--timesteps (total_timesteps) must exceed the {done:,} follower-steps "
                         f"checkpoint {resume} has already trained, got "
                         f"{config.total_timesteps:,}: a resume trains on until the total, so "
                         f"this one would train nothing")
    if saved != config.algorithm:
        raise ValueError(f"checkpoint {resume} was trained with {saved}, the config says "
                         f"algorithm={config.algorithm!r}")
    if config.resume_new_blocks:
        from boids_env.train.resume import checked_layouts

        checked_layouts(resume, config)
    if overwrite and Path(resume).resolve().is_relative_to(out.resolve()):
        raise ValueError(f"--resume {resume} is inside --out {out}, which --overwrite would "
                         f"empty first: copy the checkpoint elsewhere, or choose another --out")


def last_minibatch_note(config: TrainConfig, slots: int) -> str | None:
    """In words, where PPO's rollout (``n_steps`` × slots) is no multiple of ``batch_size``:
    each epoch then ends with a smaller mini-batch, as the shipped recipes were trained
    (their rollouts differ in size per recipe; one batch size keeps them comparable). SB3
    warns of it in a paragraph on every start; this line replaces it. None where it divides
    (and for SAC, which draws its batches from the buffer)."""
    rollout = config.n_steps * slots
    if config.algorithm != "ppo" or rollout % config.batch_size == 0:
        return None
    return (f"the rollout ({config.n_steps} steps x {slots} follower slots = {rollout:,}) is "
            f"not a multiple of batch_size {config.batch_size:,}: each epoch ends with a "
            f"mini-batch of {rollout % config.batch_size:,} (as the shipped models were "
            f"trained)")


def whole_rollouts(config: TrainConfig, slots: int, remaining: int) -> int:
    """``remaining`` follower-steps rounded up to what the algorithm really runs: PPO collects
    whole rollouts of ``n_steps`` × slots, SAC ``train_freq`` × slots per update."""
    chunk = slots * (config.n_steps if config.algorithm == "ppo" else config.train_freq)
    return -(-remaining // chunk) * chunk


SUMMARIES = 10
"""Progress lines a training prints (one every tenth of its follower-steps; the last at the
end)."""


def _final_evaluation(evaluator: FlockEvalCallback, config: TrainConfig) -> None:
    """Evaluates the final model (unless the last periodic evaluation just did), so every
    run with ``eval_every`` > 0, however short, leaves a row in ``evaluations.csv`` for
    ``boids curves``; after the training, so the model is unchanged."""
    evaluator.num_timesteps = evaluator.model.num_timesteps
    result = evaluator.evaluate()
    evaluator.logger.dump(evaluator.num_timesteps)
    print(f"boids train: the final model on the evaluation episodes (seeds "
          f"{', '.join(map(str, config.eval_seeds))}): total {result['total']:.3f} (" +
          ", ".join(f"{k} {result[k]:.3f}" for k in ("V_sep", "V_coh", "V_align")) +
          f"), cost {result['cost']:.3f}; written to evaluations.csv")


def _say_where(flock: FlockVecEnv, threads: int, device: str) -> None:
    """Prints where a training steps its env copies and runs torch."""
    workers = flock.processes - 1
    beside = f" and {workers} worker process{'es' * (workers > 1)}" if workers else ""
    print(f"boids train: {len(flock.specs)} env copies ({flock.num_envs} follower slots) "
          f"stepped in this process{beside}; {threads} torch thread{'s' * (threads > 1)} "
          f"on {device}")


def _model(config: TrainConfig, venv: VecMonitor, device: str, out: Path,
           resume: str | Path | None, verbose: int, trust_model: bool
           ) -> tuple[Any, dict[str, Any] | None]:
    """The learner :func:`train` trains: the checkpoint ``resume`` (a checkpoint that cannot
    be read is refused before anything is written), else a new one built from ``config``;
    and the rollout boundary it was put back at (its callbacks' state), None when it goes on
    with fresh episodes."""
    import torch

    if resume is None:
        return learner_class(config.algorithm)(
            "MlpPolicy", venv, device=device, verbose=verbose,
            tensorboard_log=str(out / "tb"), **config.algorithm_kwargs()), None
    model = load_checkpoint(resume, config, venv, device, str(out / "tb"), verbose,
                            trust=trust_model)
    model.set_random_seed(config.seed)
    extra = _at_boundary(model, venv, resume, config)
    if config.resume_log_std is not None:  # explore again (PPO's state-free log std)
        with torch.no_grad():
            model.policy.log_std.fill_(config.resume_log_std)
    return model, extra


def _at_boundary(model: Any, venv: VecMonitor, resume: str | Path, config: TrainConfig
                 ) -> dict[str, Any] | None:
    """Puts a resumed model back at the rollout boundary its checkpoint carries
    (:mod:`boids_env.train.boundary`) when it is of this training, so the run goes on bit for
    bit as if never stopped; returns the callbacks' saved state, or None (and says why) when
    the env copies restart their episodes instead."""
    state = boundary.read(resume) if boundary.applies(model) else None
    where = f"boids train: resuming from {resume}"
    if state is None:
        why = "an older checkpoint" if boundary.applies(model) else "SAC's buffer is not kept"
        print(f"{where} with fresh episodes (no rollout boundary to go on from: {why})")
        return None
    if (state["identity"] != boundary.digest(identity(config)) or config.resume_new_inputs
            or config.resume_new_blocks):
        print(f"{where} with fresh episodes (its rollout boundary is of another training "
              f"config)")
        return None
    if not boundary.restore(model, venv, state):
        print(f"{where} with fresh episodes (its saved episodes replay otherwise here: the "
              f"env changed since)")
        return None
    print(f"{where} at its rollout boundary, {model.num_timesteps:,} follower-steps: the "
          f"run goes on as if never stopped")
    return dict(state.get("extra") or {})


def _best_cost(evaluator: FlockEvalCallback) -> dict[str, Any]:
    """What a rollout boundary keeps of the evaluations: the best cost so far, exactly."""
    return {"best_cost": None if evaluator.best == float("inf") else evaluator.best}


def _saved_best(extra: dict[str, Any] | None) -> float | None:
    """The best cost a rollout boundary kept (None: no boundary)."""
    if extra is None:
        return None
    best = extra.get("best_cost")
    return float("inf") if best is None else float(best)


def _callbacks(config: TrainConfig, out: Path, slots: int, meta: dict[str, Any],
               digest: str, save: Any, verbose: int) -> tuple[FlockEvalCallback, list[Any]]:
    """The periodic evaluation and the callbacks of a training (checkpoints carrying their
    rollout boundary), the progress summary aside."""
    evaluator = FlockEvalCallback(out, config.eval_every, config.eval_seeds,
                                  config.env_fields, save_best=save)
    evaluator.verbose = verbose
    callbacks: list[Any] = [TrainingMetricsCallback(), evaluator]
    if config.checkpoint_every:
        callbacks.append(Checkpoints(config.checkpoint_every // slots, out / "checkpoints",
                                     meta, digest, lambda: _best_cost(evaluator)))
    return evaluator, callbacks


def _quiet_model(config: TrainConfig, venv: Any, device: str, out: Path,
                 resume: str | Path | None, verbose: int,
                 trust_model: bool) -> tuple[Any, Any]:
    """:func:`_model`, with SB3's mini-batch warning said once in our words instead."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "You have specified a mini-batch size", UserWarning)
        built = _model(config, venv, device, out, resume, verbose, trust_model)
    if (note := last_minibatch_note(config, venv.num_envs)) is not None:
        print(f"boids train: {note}")
    return built


def train(config: TrainConfig, out: str | Path, *, resume: str | Path | None = None,
          overwrite: bool = False, progress_bar: bool = False, verbose: int = 0,
          trust_model: bool = False) -> Path:
    """Trains a follower policy and returns the path of the final ``model.zip``.

    Everything is checked before the folder is touched.

    Args:
        config: the run's configuration.
        out: output folder (created); it belongs to this training (see the module).
        resume: a checkpoint zip to continue from; training goes on until
            ``config.total_timesteps`` in all (which must exceed the checkpoint's; the env
            copies restart their episodes). In the folder of a training of the same config
            (other timesteps, processes, threads or device allowed) it goes on there. The
            config rebuilds the model and the checkpoint gives its weights, optimizer state
            and step count, read without running anything stored in the zip
            (:mod:`boids_env.train.resume`).
        overwrite: replace an earlier training (or other outputs of ours) in ``out``: only
            what it wrote is removed.
        trust_model: load ``resume`` through SB3's own load instead, which unpickles the
            objects stored in the zip (a checkpoint whose network the config does not build;
            only for files you trust).
        progress_bar: show SB3's progress bar (tqdm + rich).
        verbose: SB3 verbosity (0 quiet, 1 tables).
    """
    import torch

    check_episodes(config)
    out = Path(out)
    folder.check_target(out)
    check_resume(config, out, resume, overwrite, trust_model)
    device = config.resolved_device()
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("device='cuda' but torch sees no GPU; use device='cpu' or 'auto'")
    torch.set_num_threads(config.resolved_threads())
    meta = model_meta(config)
    flock = make_vec_env(config)
    _say_where(flock, torch.get_num_threads(), device)
    venv = VecMonitor(flock)
    try:
        model, extra = _quiet_model(config, venv, device, out, resume, verbose, trust_model)
        # the folder is claimed once the model is built: a checkpoint that cannot be resumed
        # leaves nothing behind
        folder.claim(out, identity(config), overwrite=overwrite, owner=folder.TRAIN,
                     resume=resume is not None)
        write_json(out / "config.json", config.to_dict())
        remaining = config.total_timesteps - (model.num_timesteps if resume else 0)
        final: bytes | None = None

        def save(path: Path, at: bytes | None = None) -> None:
            with atomic_path(path) as tmp:  # a kill never leaves a torn model
                model.save(tmp)
                write_meta(tmp, meta, model)
                if at is not None:  # the rollout boundary it resumes from
                    boundary.write(tmp, at)

        digest = boundary.digest(identity(config))
        evaluator, callbacks = _callbacks(config, out, venv.num_envs, meta, digest, save,
                                          verbose)
        if resume is not None:
            evaluator.resume_at(model.num_timesteps, _saved_best(extra))
        if remaining > 0:
            rounded = whole_rollouts(config, venv.num_envs, remaining)
            if rounded != remaining:
                print(f"boids train: {remaining:,} follower-steps round up to {rounded:,} "
                      f"(whole rollouts of {venv.num_envs} follower slots)")
            total = (model.num_timesteps if resume else 0) + rounded
            callbacks.append(TrainingSummary(max(rounded // SUMMARIES, 1), total))
            model.learn(rounded, callback=CallbackList(callbacks), progress_bar=progress_bar,
                        reset_num_timesteps=resume is None, tb_log_name="run")
            # the end of a rollout and its update: a boundary a longer training goes on from
            if boundary.applies(model):
                final = boundary.capture(model, venv, digest, _best_cost(evaluator))
            if config.eval_every and evaluator.last != model.num_timesteps:
                _final_evaluation(evaluator, config)
        save(out / "model.zip", final)
    finally:
        venv.close()
    return out / "model.zip"
