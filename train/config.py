"""The training run's configuration: one frozen, validated dataclass, read from TOML or flags."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from itertools import pairwise
from pathlib import Path
from typing import Any

from boids_env.checks import from_fields
from boids_env.config import (
    FIELD_OWNER,
    LEADER_MAX_SPEED,
    PATHS,
    EnvConfig,
    check_integer,
    check_number,
)
from boids_env.untrusted import excerpt, parse_toml, quote_path, read_text

ALGORITHMS = ("ppo", "sac")
DEVICES = ("cpu", "cuda", "auto")
RECIPES = Path(__file__).parent / "recipes"
"""The shipped training recipes (``boids train --config ppo_safe``)."""
MAX_RECIPE_BYTES = 1024 * 1024
"""A training config file larger than this (1 MiB) is refused before it is read."""
MAX_ROLLOUT = 1 << 22
"""Most transitions in one PPO rollout (``n_steps`` × the followers of all copies; about
1 GB of buffers at the observation sizes here) and largest ``batch_size``. The recipes use
256 × 72."""
MAX_BUFFER = 10_000_000
"""Largest SAC replay buffer (transitions; SB3's default is 1,000,000)."""
MAX_LAYERS = 16
"""Most hidden layers in ``net_arch``."""
MAX_NET_WEIGHTS = 16_000_000
"""Most weights between the hidden layers of ``net_arch`` (the recipes' 128 × 128 has
16,384)."""


def resolve_recipe(spec: str | Path) -> Path:
    """A TOML file path as given, or the shipped recipe of that name (``ppo_safe`` or
    ``ppo_safe.toml``); ``FileNotFoundError`` naming both otherwise."""
    path = Path(spec)
    if path.is_file():
        return path
    name = path.name if path.suffix == ".toml" else f"{path.name}.toml"
    shipped = RECIPES / name
    if shipped.is_file():
        return shipped
    known = sorted(p.stem for p in RECIPES.glob("*.toml"))
    raise FileNotFoundError(f"training config not found: {spec} (not a file, and not a shipped "
                            f"recipe: {known})")


@dataclass(frozen=True)
class TrainConfig:
    """A Stable-Baselines3 run with parameter sharing (one VecEnv slot per follower).

    Timesteps count follower-steps (one per follower per 0.1 s step), SB3's convention for a
    VecEnv whose slots are followers.
    """

    algorithm: str = "ppo"
    """``ppo`` (default) or ``sac``."""
    total_timesteps: int = 12_000_000
    """Follower-steps to train for in all."""
    seed: int = 0
    """Seed of the learner and of the env copies' episodes."""
    group_sizes: tuple[int, ...] = (7, 13, 19)
    """Group sizes (leader included) of the env copies, assigned round robin."""
    copies: int = 6
    """Env copies stepped together (their followers are the VecEnv's slots)."""
    leader_speeds: tuple[float, ...] = (0.5, 0.55, 0.6)
    """Each episode draws its leader speed from these (m/s)."""
    paths: tuple[str, ...] = ("square",)
    """Each episode draws its leader path from these."""
    path_rotations: tuple[float, ...] = (0.0,)
    """Each episode draws the rotation of its scene (path and layout, degrees) from these."""
    path_mirrors: tuple[bool, ...] = (False,)
    """Each episode draws whether its scene is mirrored from these."""
    obs_noises: tuple[float, ...] = (0.0,)
    """Each episode draws its sensing noise (std, m and m/s) from these."""
    leader_pauses: tuple[tuple[tuple[float, float], ...], ...] = ((),)
    """Each episode draws its leader's standstills (the env's ``leader_pauses``: (when, how
    long) pairs in s of driving time) from these; ``[]`` is an episode without one."""
    worlds: tuple[dict[str, Any], ...] = ({},)
    """The worlds of the env copies, assigned round robin (as ``group_sizes``, so two lists of
    the same length pair up copy by copy): tables of env fields over ``env_fields``, e.g.
    ``{scene = "doorway"}`` or ``{arena_half_size = 2.5, path_size = 2.0}`` (walls near the
    path). In a copy whose scene is not the study's arena the leader drives the scene's own
    path: ``paths``, ``path_rotations`` and ``path_mirrors`` are drawn in arena copies only.
    A world table must not set what an episode draws."""
    processes: int = 0
    """Processes the env copies are split over, the training process included (1: all
    stepped in the training process; ``k``: it and ``k - 1`` workers; 0: half the cores from
    3 cores on, else 1, and on 2 cores a worker too when the copies' step is slow; see
    ``vec_env.default_processes`` and ``vec_env.SECOND_CORE_STEP``)."""
    torch_threads: int = 0
    """Torch threads of the learner; 0: the cores the env processes leave (one on 1 or 2
    cores, where a second thread spins against the env; see ``vec_env.default_threads``)."""
    device: str = "cpu"
    """Where the policy and its updates run: ``cpu`` (default), ``cuda``, or ``auto`` (cuda
    when a GPU is present). The env always runs on the CPU."""
    env_fields: dict[str, Any] = field(default_factory=dict)
    """Other env config fields by flat name (e.g. ``{"neighbours": 6}``)."""
    # Hyperparameters shared by both algorithms.
    learning_rate: float = 3e-4
    """Learning rate of the optimiser (Adam)."""
    gamma: float = 0.99
    """Discount factor."""
    batch_size: int = 4608
    """Minibatch size (follower-steps) of each gradient step."""
    net_arch: tuple[int, ...] = (64, 64)
    """Hidden layer widths of the actor and of the critic (each its own network)."""
    log_std_init: float = -1.5
    """Initial log standard deviation of the Gaussian policy's actions."""
    resume_log_std: float | None = None
    """With ``--resume``: set the policy's log action std to this before training on (PPO;
    None keeps the checkpoint's). A converged policy acts with a std of about 0.04 m/s and
    explores too little to find what a changed reward asks for (docs:
    explanation/learned-followers)."""
    resume_new_inputs: int = 0
    """With ``--resume``: the checkpoint's network reads this many fewer observation values,
    the last ones (a sensing block added since it was trained, e.g. route sensing's 4).
    Their first-layer weights start at zero, so the resumed policy first acts exactly as
    the checkpoint did; the optimizer starts afresh."""
    resume_new_blocks: bool = False
    """With ``--resume``: map the checkpoint's saved observation layout into this env's
    block by block (by name); the blocks it lacks, wherever they sit (headings, pedestrian
    slots, route sensing), get zero first-layer weights, so the resumed policy first acts
    exactly as the checkpoint did on a robot or crowd it never saw. Every block the
    checkpoint reads must be in this env's layout with the same size. The optimizer starts
    afresh."""
    # PPO.
    n_steps: int = 256
    """PPO: steps each VecEnv slot (a follower) collects per rollout."""
    n_epochs: int = 5
    """PPO: passes over each rollout."""
    gae_lambda: float = 0.95
    """PPO: λ of the generalised advantage estimate."""
    clip_range: float = 0.2
    """PPO: clipping range of the probability ratio."""
    ent_coef: float = 0.0
    """PPO: weight of the entropy bonus."""
    # SAC.
    buffer_size: int = 1_000_000
    """SAC: replay buffer size (transitions)."""
    learning_starts: int = 20_000
    """SAC: follower-steps collected before the first update."""
    train_freq: int = 1
    """SAC: steps of each VecEnv slot between updates."""
    gradient_steps: int = 1
    """SAC: gradient steps per update."""
    tau: float = 0.005
    """SAC: soft update coefficient of the target networks."""
    # Logging, evaluation, checkpoints (in timesteps).
    eval_every: int = 1_000_000
    """Follower-steps between evaluations on ``eval_seeds`` (0: none)."""
    eval_seeds: tuple[int, ...] = (100, 101)
    """Seeds of the evaluation episodes (default case: 13 robots, 0.55 m/s)."""
    checkpoint_every: int = 2_000_000
    """Follower-steps between checkpoints (0: none)."""

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"algorithm must be one of {ALGORITHMS}, got {self.algorithm!r}")
        _set(self, "total_timesteps", check_integer("total_timesteps", self.total_timesteps,
                                                    1, 10**12))
        _set(self, "seed", check_integer("seed", self.seed, 0, 2**32 - 1))
        _set(self, "group_sizes", _tuple("group_sizes", self.group_sizes,
                                         lambda n, v: check_integer(n, v, 2, 1000)))
        _set(self, "copies", check_integer("copies", self.copies, 1, 1024))
        _set(self, "leader_speeds", _tuple("leader_speeds", self.leader_speeds,
                                           lambda n, v: check_number(n, v, 0.0,
                                                                     LEADER_MAX_SPEED,
                                                                     lo_open=True, unit="m/s")))
        _set(self, "paths", _tuple("paths", self.paths, _path))
        _set(self, "path_rotations", _tuple("path_rotations", self.path_rotations,
                                            lambda n, v: check_number(n, v, -360, 360,
                                                                      unit="degrees")))
        _set(self, "path_mirrors", _tuple("path_mirrors", self.path_mirrors, _flag))
        _set(self, "obs_noises", _tuple("obs_noises", self.obs_noises,
                                        lambda n, v: check_number(n, v, 0.0, 10.0)))
        _set(self, "leader_pauses", _tuple("leader_pauses", self.leader_pauses, _pause_list))
        _set(self, "worlds", _tuple("worlds", self.worlds, _world))
        _set(self, "processes", check_integer("processes", self.processes, 0, self.copies))
        _set(self, "torch_threads", check_integer("torch_threads", self.torch_threads, 0, 256))
        if self.device not in DEVICES:
            raise ValueError(f"device must be one of {DEVICES}, got {self.device!r}")
        _check_env_fields(self)
        for name, lo, hi in (("learning_rate", 0.0, 1.0), ("gamma", 0.0, 1.0),
                             ("gae_lambda", 0.0, 1.0), ("clip_range", 0.0, 10.0),
                             ("tau", 0.0, 1.0)):
            _set(self, name, check_number(name, getattr(self, name), lo, hi, lo_open=True))
        _set(self, "ent_coef", check_number("ent_coef", self.ent_coef, 0.0, 10.0))
        _set(self, "log_std_init", check_number("log_std_init", self.log_std_init, -20, 5))
        if self.resume_log_std is not None:
            if self.algorithm != "ppo":
                raise ValueError("resume_log_std applies to PPO's Gaussian policy only, got "
                                 f"algorithm={self.algorithm!r}")
            _set(self, "resume_log_std", check_number("resume_log_std", self.resume_log_std,
                                                      -20, 5))
        _set(self, "resume_new_inputs", check_integer("resume_new_inputs",
                                                      self.resume_new_inputs, 0, 1024))
        if not isinstance(self.resume_new_blocks, bool):
            raise ValueError(f"resume_new_blocks must be true or false, got "
                             f"{self.resume_new_blocks!r}")
        if self.resume_new_blocks and self.resume_new_inputs:
            raise ValueError("resume_new_blocks and resume_new_inputs both widen a resumed "
                             "model's inputs: give one (resume_new_blocks maps the saved "
                             "layout by block name)")
        for name, lo in (("batch_size", 1), ("n_steps", 1), ("n_epochs", 1), ("buffer_size", 1),
                         ("learning_starts", 0), ("train_freq", 1), ("gradient_steps", 1),
                         ("eval_every", 0), ("checkpoint_every", 0)):
            _set(self, name, check_integer(name, getattr(self, name), lo, 10**12))
        _set(self, "net_arch", _tuple("net_arch", self.net_arch,
                                      lambda n, v: check_integer(n, v, 1, 4096)))
        _set(self, "eval_seeds", tuple(check_integer("eval_seeds", s, 0, 2**32 - 1)
                                       for s in _as_tuple("eval_seeds", self.eval_seeds)))

        _check_sizes(self)
        _check_draws(self)

    # ------------------------------------------------------------------------- building
    @classmethod
    def from_toml(cls, path: str | Path, **overrides: Any) -> TrainConfig:
        """Reads a TOML file of fields (top level or a ``[train]`` table); ``overrides``
        (e.g. from command-line flags, None ignored) win."""
        if not Path(path).exists():
            raise FileNotFoundError(f"training config not found: {quote_path(path)}")
        where = f"cannot read training config {quote_path(path)}"
        data = parse_toml(read_text(path, where, MAX_RECIPE_BYTES), where)
        data = data.get("train", data)
        if not isinstance(data, dict):
            raise ValueError(f"training config {quote_path(path)}: [train] must be a table of "
                             f"TrainConfig fields, got {excerpt(data)}")
        return cls.from_dict({**data, **{k: v for k, v in overrides.items() if v is not None}})

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        return from_fields(cls, data, "training config")

    def replace(self, **changes: Any) -> TrainConfig:
        return replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["leader_pauses"] = [[list(p) for p in entry] for entry in self.leader_pauses]
        out["worlds"] = [dict(w) for w in self.worlds]
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}

    # -------------------------------------------------------------------------- derived
    def resolved_processes(self) -> int:
        """``processes``, or ``vec_env.default_processes`` of the copies when it is 0 (on 2
        cores the env may still add a worker: ``FlockVecEnv.processes`` says)."""
        from boids_env.train.vec_env import default_processes

        return self.processes or default_processes(self.copies)

    def resolved_threads(self) -> int:
        """``torch_threads``, or when it is 0 the cores the env processes leave
        (``vec_env.default_threads``)."""
        from boids_env.train.vec_env import default_threads

        return self.torch_threads or default_threads(self.resolved_processes())

    def resolved_device(self) -> str:
        """``device`` with ``auto`` resolved (cuda if torch sees a GPU)."""
        if self.device != "auto":
            return self.device
        import torch

        return "cuda" if torch.cuda.is_available() else "cpu"

    def algorithm_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for the SB3 algorithm's constructor."""
        common = {"learning_rate": self.learning_rate, "gamma": self.gamma,
                  "batch_size": self.batch_size, "seed": self.seed}
        if self.algorithm == "ppo":
            return {**common, "n_steps": self.n_steps, "n_epochs": self.n_epochs,
                    "gae_lambda": self.gae_lambda, "clip_range": self.clip_range,
                    "ent_coef": self.ent_coef,
                    "policy_kwargs": {"net_arch": list(self.net_arch),
                                      "log_std_init": self.log_std_init}}
        return {**common, "buffer_size": self.buffer_size,
                "learning_starts": self.learning_starts, "train_freq": self.train_freq,
                "gradient_steps": self.gradient_steps, "tau": self.tau,
                "policy_kwargs": {"net_arch": list(self.net_arch),
                                  "log_std_init": self.log_std_init}}


DRAWN = {"group_sizes": "robots", "leader_speeds": "leader_speed", "paths": "path",
         "path_rotations": "path_rotation", "path_mirrors": "path_mirror",
         "obs_noises": "obs_noise", "leader_pauses": "leader_pauses"}
"""Training fields whose entries each episode draws, and the env field each sets."""
_ALWAYS_DRAWN = ("group_sizes", "leader_speeds", "paths")
"""Drawn fields that always override the env field (the others only when not the default)."""


def _check_env_fields(config: TrainConfig) -> None:
    """``env_fields`` must be a table of env config fields that builds a valid env config, and
    must not set a field a training list draws (it would be silently overridden)."""
    fields_ = config.env_fields
    if not isinstance(fields_, dict):
        raise ValueError(f"env_fields must be a table of env config fields, got {fields_!r}")
    unknown = sorted(set(fields_) - set(FIELD_OWNER))
    if unknown:
        raise ValueError(f"env_fields has unknown key(s) {unknown}; allowed: "
                         f"{sorted(FIELD_OWNER)}")
    defaults = {f.name: f.default for f in fields(TrainConfig)}
    for name, env_name in DRAWN.items():
        drawn = name in _ALWAYS_DRAWN or getattr(config, name) != defaults[name]
        if env_name in fields_ and drawn:
            raise ValueError(f"env_fields must not set {env_name!r} (reserved: each episode "
                             f"draws it from the training field {name}; put the value there, "
                             f"e.g. {name} = [{fields_[env_name]!r}])")
    for k, world in enumerate(config.worlds):
        unknown = sorted(set(world) - set(FIELD_OWNER) - {"map"})
        if unknown:
            raise ValueError(f"worlds entry {k + 1} has unknown key(s) {unknown}; allowed: "
                             f"env config fields {sorted(FIELD_OWNER)}")
        reserved = sorted(set(world) & set(DRAWN.values()))
        if reserved:
            raise ValueError(f"worlds entry {k + 1} must not set {reserved} (reserved: each "
                             f"episode draws them from the training fields "
                             f"{[n for n, e in DRAWN.items() if e in reserved]})")


def _check_draws(config: TrainConfig) -> None:
    """``env_fields`` with the first entry of every drawn training field (group_sizes,
    leader_speeds, …), and then each other entry in turn, must give an env config the env
    accepts; the error names the training field. (``boids_env.train.run.check_episodes``
    checks every combination before a run writes anything.)"""
    first = {env_name: getattr(config, name)[0] for name, env_name in DRAWN.items()}
    try:
        base = EnvConfig.from_kwargs(**{**config.env_fields, **first})
    except (ValueError, TypeError) as exc:
        try:
            EnvConfig.from_kwargs(**config.env_fields)
        except (ValueError, TypeError) as alone:
            raise ValueError(f"env_fields: {alone}") from None
        raise ValueError(f"env_fields {config.env_fields} with the first entry of each drawn "
                         f"field ({', '.join(f'{n}[0]={getattr(config, n)[0]!r}' for n in DRAWN)})"
                         f" give episodes the env refuses: {exc}") from None
    for name, env_name in DRAWN.items():
        for value in dict.fromkeys(getattr(config, name)):
            try:
                base.replace(**{env_name: value})
            except (ValueError, TypeError) as exc:
                raise ValueError(f"{name} entry {value!r} gives episodes the env refuses "
                                 f"({env_name}={value!r}): {exc}") from None
    shaped = ("path", "path_rotation", "path_mirror")
    for i in range(config.copies):  # each world with the group size of its copies
        k = i % len(config.worlds)
        world = config.worlds[k]
        fields_ = {**config.env_fields, **world, **first,
                   "robots": config.group_sizes[i % len(config.group_sizes)]}
        if world.get("scene", world.get("map", "arena")) != "arena":
            fields_ = {n: v for n, v in fields_.items() if n not in shaped}
        try:
            EnvConfig.from_kwargs(**fields_)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"worlds entry {k + 1} {world} (copy {i + 1}, robots="
                             f"{fields_['robots']}, over env_fields) gives episodes the env "
                             f"refuses: {exc}") from None


def rollout_slots(config: TrainConfig) -> int:
    """The VecEnv's slots: the followers of every env copy (copies take the group sizes
    round robin)."""
    sizes = config.group_sizes
    return sum(sizes[i % len(sizes)] - 1 for i in range(config.copies))


def _check_sizes(config: TrainConfig) -> None:
    """Refuses sizes that would exhaust memory when training starts (checked here, before
    anything is allocated): PPO's rollout (``n_steps`` × the followers of all copies),
    SAC's replay buffer, the minibatch and the network."""
    slots = rollout_slots(config)
    if config.algorithm == "ppo" and config.n_steps * slots > MAX_ROLLOUT:
        raise ValueError(f"n_steps ({config.n_steps:,}) × followers of all copies ({slots:,}) "
                         f"= {config.n_steps * slots:,} transitions per rollout, more than the "
                         f"{MAX_ROLLOUT:,} allowed (lower n_steps, copies or group_sizes)")
    if config.algorithm == "sac" and config.buffer_size > MAX_BUFFER:
        raise ValueError(f"buffer_size must be at most {MAX_BUFFER:,} transitions, got "
                         f"{config.buffer_size:,}")
    if config.batch_size > MAX_ROLLOUT:
        raise ValueError(f"batch_size must be at most {MAX_ROLLOUT:,}, got "
                         f"{config.batch_size:,}")
    arch = config.net_arch
    weights = sum(a * b for a, b in pairwise(arch))
    if len(arch) > MAX_LAYERS or weights > MAX_NET_WEIGHTS:
        raise ValueError(f"net_arch {excerpt(list(arch))} has {len(arch)} layers and "
                         f"{weights:,} weights between them; at most {MAX_LAYERS} layers and "
                         f"{MAX_NET_WEIGHTS:,} weights are allowed")


def _set(obj: object, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


def _as_tuple(name: str, value: Any) -> tuple[Any, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise ValueError(f"{name} must be a list, got {value!r}")
    if not value:
        raise ValueError(f"{name} must not be empty")
    return tuple(value)


def _tuple(name: str, value: Any, check: Any) -> tuple[Any, ...]:
    return tuple(check(name, v) for v in _as_tuple(name, value))


def _flag(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{name} entries must be true or false, got {value!r}")
    return value


def _pause_list(name: str, value: Any) -> tuple[tuple[float, float], ...]:
    from boids_env.world.scenario import ScenarioConfig

    try:
        return ScenarioConfig(leader_pauses=value).leader_pauses
    except ValueError as exc:
        raise ValueError(f"{name} entries: {exc}") from None


def _world(name: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"{name} entries must be tables of env fields (e.g. {{scene = "
                         f"\"doorway\"}}), got {value!r}")
    return dict(value)


def _path(name: str, value: Any) -> str:
    if value not in PATHS or value == "external":
        raise ValueError(f"{name} entries must be among {[p for p in PATHS if p != 'external']},"
                         f" got {value!r}")
    return str(value)
