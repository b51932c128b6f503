"""A saved Stable-Baselines3 model as a :class:`~policies.base.Policy` (deterministic actions).

Models saved by ``boids train`` carry a ``boids.json`` entry in their zip (algorithm, the env
fields the observations depend on, the training config, the model's card:
:mod:`boids_env.policies.cards`) and their actor as numpy arrays
(``boids_actor.npz``). Other SB3 zips act from their weights alone
(:mod:`boids_env.policies.sb3_zip`), or, for a file the user trusts (``trust=True``), through
SB3's own load, trying the algorithms in :data:`ALGORITHMS` in turn: that load unpickles
objects stored in the zip and so runs any code they carry, which is why it is never the
default.
"""

from __future__ import annotations

import copy
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.files import atomic_path, read_zip_entry
from boids_env.policies.base import BatchPolicy
from boids_env.policies.cards import read_card
from boids_env.policies.mlp_actor import ACTOR_ENTRY, ARRAYS_LIMIT, MLPActor
from boids_env.policies.sb3_zip import json_table
from boids_env.untrusted import (
    MAX_MODEL_BYTES,
    check_zip_entries,
    check_zip_entry,
    inflated_allowance,
    open_zip,
    printable,
)

META_ENTRY = "boids.json"
META_LIMIT = 1 << 20
"""The most bytes a model's ``boids.json`` may hold (boids train writes a few kB)."""
ACTOR_LIMIT = 1 << 28
"""The most bytes a model's ``boids_actor.npz`` may hold, 256 MiB (the shipped actor: 0.12
MiB; a layer of 4,096 × 4,096, the widest a training config allows: 64 MiB)."""
ALGORITHMS = ("ppo", "sac", "td3", "a2c", "ddpg")


def algorithm_class(name: str) -> Any:
    """The SB3 class for an algorithm name (``ppo``, ``sac``, …)."""
    import stable_baselines3 as sb3

    key = name.lower()
    if key not in ALGORITHMS:
        raise ValueError(f"algorithm must be one of {ALGORITHMS}, got {name!r}")
    return getattr(sb3, key.upper())


def read_meta(path: str | Path) -> dict[str, Any]:
    """The ``boids.json`` metadata of a model zip ({} for a zip saved elsewhere); a
    ``ValueError`` naming the file for a file that is not a zip or a metadata entry that is
    not a JSON table."""
    try:
        with open_zip(path) as zf:
            if META_ENTRY not in zf.namelist():
                return {}
            raw = read_zip_entry(zf, META_ENTRY, META_LIMIT)  # a zip bomb is refused
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError) as exc:
        raise ValueError(f"cannot read SB3 model {path}: {exc}") from exc
    return json_table(raw, path, META_ENTRY)


def write_meta(path: str | Path, meta: dict[str, Any], model: Any = None) -> None:
    """Adds (or replaces) the ``boids.json`` entry of a model zip saved by SB3, and with
    ``model`` (the SB3 model just saved there) its actor for acting without torch
    (``boids_actor.npz``, see :mod:`boids_env.policies.mlp_actor`) when it is an MLP that
    numpy can run; a model that is not drops a stale one.

    The new zip is written beside the model and renamed over it when complete, so the model
    is never truncated: a full disk or an interrupt leaves the previous file as it was.
    """
    path = Path(path)
    try:
        text = json.dumps(meta, indent=2)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"model metadata must be JSON-serialisable: {exc}") from None
    replaced = {META_ENTRY, ACTOR_ENTRY} if model is not None else {META_ENTRY}
    actor = actor_of(model) if model is not None else None
    try:
        with open_zip(path) as source, atomic_path(path) as tmp, \
                zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
            check_zip_entries(source, MAX_MODEL_BYTES)  # a zip bomb: refused before copying
            for info in source.infolist():
                if info.filename not in replaced:
                    _copy_entry(source, info, zf)
            zf.writestr(META_ENTRY, text)
            if actor is not None:
                zf.writestr(ACTOR_ENTRY, actor.to_bytes())
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError) as exc:
        raise ValueError(f"cannot add metadata to SB3 model {path}: {exc}") from exc


def _copy_entry(source: zipfile.ZipFile, info: zipfile.ZipInfo, target: zipfile.ZipFile
                ) -> None:
    """Copies one entry in chunks (never held whole), stopping one chunk past the bytes its
    directory declares (a declared size that lies is refused, not followed)."""
    allowed = check_zip_entry(info, MAX_MODEL_BYTES)
    copied = 0
    with source.open(info) as src, target.open(copy.copy(info), "w") as dst:
        while chunk := src.read(1 << 20):
            copied += len(chunk)
            if copied > allowed:
                raise ValueError(f"its entry {printable(info.filename, 120)} inflates beyond "
                                 f"the {allowed:,} bytes allowed")
            dst.write(chunk)


def actor_of(model: Any) -> MLPActor | None:
    """The deterministic actor of an SB3 model as an :class:`MLPActor` (numpy), or None when
    it is not a Gaussian MLP actor-critic with a flattening feature extractor and tanh or ReLU
    activations (acting from such a model goes through torch)."""
    from stable_baselines3.common.distributions import DiagGaussianDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor
    from torch import nn

    policy = getattr(model, "policy", None)
    if not (isinstance(policy, ActorCriticPolicy) and not policy.squash_output
            and isinstance(policy.action_dist, DiagGaussianDistribution)
            and isinstance(policy.pi_features_extractor, FlattenExtractor)
            and len(policy.observation_space.shape or ()) == 1):
        return None
    layers, names = [], {nn.Tanh: "tanh", nn.ReLU: "relu"}
    activation = None
    for module in policy.mlp_extractor.policy_net:
        if isinstance(module, nn.Linear):
            layers.append(module)
        elif type(module) in names and activation in (None, names[type(module)]):
            activation = names[type(module)]
        else:
            return None
    layers.append(policy.action_net)
    if not isinstance(policy.action_net, nn.Linear):
        return None
    space = model.action_space
    return MLPActor([m.weight.detach().cpu().numpy() for m in layers],
                    [m.bias.detach().cpu().numpy() for m in layers], activation or "tanh",
                    space.low, space.high)


def has_numpy_actor(path: str | Path) -> bool:
    """Whether a model zip carries its actor for numpy (then acting needs no train extra);
    False for a file that is missing or not a zip (its loading reports why)."""
    try:
        with open_zip(path) as zf:
            return ACTOR_ENTRY in zf.namelist()
    except (OSError, zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError):
        return False


def load_model_policy(path: str | Path, device: str = "cpu", *, trust: bool = False
                      ) -> BatchPolicy:
    """The policy of a model zip, loaded without running anything stored in it unless
    ``trust``:

    - its stored numpy actor when it has one (acting on the CPU without importing torch);
    - else, untrusted, the actor built from its weights alone
      (:func:`~boids_env.policies.sb3_zip.actor_from_weights`, needs torch to read them), or
      an :class:`~boids_env.policies.sb3_zip.UntrustedModelError` naming ``--trust-model``;
    - else, trusted, :meth:`SB3Policy.load` (also for ``device`` other than ``cpu``), which
      unpickles the objects stored in the zip.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"policy model file not found: {path}")
    meta = read_meta(path)  # a file that is not a zip is refused here, by name
    env_fields = _env_fields(path, meta.get("env_fields"))
    layout = _layout(path, meta.get("observation_layout"))
    card = read_card(path, meta)  # a malformed card is refused here, by name
    policy = _load_model_policy(path, device, trust, env_fields)
    policy.card = card  # type: ignore[attr-defined]
    if layout is None and card is not None and card.layout is not None \
            and card.layout.size == getattr(policy, "obs_size", None):
        layout = card.layout  # (a card that disagrees with the network describes nothing)
    if layout is not None:
        policy.observation_layout = layout  # type: ignore[attr-defined]
    return policy


def _layout(path: Path, blocks: Any) -> Any:
    """A model's saved observation layout (None for a model saved before layouts were)."""
    if blocks is None:
        return None
    from boids_env.observations import ObservationLayout

    try:
        return ObservationLayout.from_blocks(blocks)
    except ValueError as exc:
        raise ValueError(f"SB3 model {path}: observation_layout in its {META_ENTRY}: {exc}"
                         ) from None


def _load_model_policy(path: Path, device: str, trust: bool, env_fields: dict[str, Any]
                       ) -> BatchPolicy:
    if device == "cpu":
        with open_zip(path) as zf:
            try:
                raw = (read_zip_entry(zf, ACTOR_ENTRY, ACTOR_LIMIT)
                       if ACTOR_ENTRY in zf.namelist() else None)
            except ValueError as exc:
                raise ValueError(f"SB3 model {path}: {exc}") from None
        if raw is not None:
            # nested: its arrays inflate at most MAX_RATIO times what the entry takes on disk
            arrays = inflated_allowance(zf.getinfo(ACTOR_ENTRY).compress_size, ARRAYS_LIMIT)
            try:
                return MLPActor.from_bytes(raw, env_fields, name=path.stem, limit=arrays)
            except ValueError as exc:
                raise ValueError(f"SB3 model {path}: {exc}") from None
    if not trust:
        from boids_env.policies.sb3_zip import UntrustedModelError, actor_from_weights

        if device != "cpu":
            raise UntrustedModelError(path, f"acting on device {device!r} goes through SB3's "
                                      f"own load")
        return actor_from_weights(path, env_fields, name=path.stem)
    try:
        return SB3Policy.load(path, device=device, trust=True)
    except ImportError as exc:
        raise ImportError(f"acting from {path.name} goes through torch (it holds no "
                          f"{ACTOR_ENTRY}: not saved by boids train, or not an MLP numpy "
                          f"runs) and needs: pip install -e '.[train]' ({exc})") from exc


def check_untrusted_load(path: str | Path) -> None:
    """Raises what :func:`load_model_policy` would for a zip loaded without trust, reading
    only its entry list, metadata and the JSON of its ``data`` (no torch): for callers that
    must refuse a model before any side effect."""
    path = Path(path)
    meta = read_meta(path)
    _env_fields(path, meta.get("env_fields"))
    read_card(path, meta)
    if not has_numpy_actor(path):
        from boids_env.policies.sb3_zip import actor_plan

        actor_plan(path)


class SB3Policy(BatchPolicy):
    """Deterministic actions of an SB3 model for all followers in one ``predict`` call.

    ``env_fields`` holds the env config fields the model's observations need (the number of
    neighbour slots); ``boids run`` and ``boids eval`` apply them. They are its training's:
    binding refuses an env that contradicts them (``eval.episode.check_training``); a model
    wrapped without them (``env_fields=None``) has no known training and is not checked.
    """

    def __init__(self, model: Any, env_fields: dict[str, Any] | None = None,
                 name: str = "sb3") -> None:
        self.model = model
        self.env_fields = dict(env_fields or {})
        self.training_known = env_fields is not None
        self.name = name
        shape = model.observation_space.shape
        self.obs_size = int(shape[0]) if shape else 0
        self.max_speed = float(np.max(model.action_space.high))

    @classmethod
    def load(cls, path: str | Path, device: str = "cpu", threads: int | None = None, *,
             trust: bool = False) -> SB3Policy:
        """Loads a model zip through SB3's own load; the algorithm comes from its metadata or
        is tried in turn. SB3's load unpickles the objects stored in the zip, which runs any
        code they carry: without ``trust=True`` it is refused
        (:class:`~boids_env.policies.sb3_zip.UntrustedModelError`); :func:`load_model_policy`
        acts from a zip's weights alone instead.

        Loading a policy to act outside training also limits torch's CPU threads to
        ``threads`` (default: ``$BOIDS_TORCH_THREADS``, else 1): a batch of a few dozen
        followers through a small MLP gains nothing from more, and parallel eval workers each
        using every core oversubscribed the machine (a learned episode took 28 s instead of
        under 1 s on 2 cores)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"policy model file not found: {path}")
        if not trust:
            from boids_env.policies.sb3_zip import UntrustedModelError

            raise UntrustedModelError(path, "SB3Policy.load goes through SB3's own load")
        set_inference_threads(threads)
        meta = read_meta(path)
        env_fields = _env_fields(path, meta.get("env_fields"))
        names = [meta["algorithm"]] if "algorithm" in meta else list(ALGORITHMS)
        errors = []
        for name in names:
            try:
                model = algorithm_class(name).load(path, device=device,
                                                   custom_objects=_acting_only(path))
            except Exception as exc:
                errors.append(f"{name}: {exc}")
                continue
            return cls(model, env_fields, name=path.stem)
        raise ValueError(f"cannot load SB3 model {path} ({'; '.join(errors)})")

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        """Deterministic actions of all followers in one forward pass: SB3's ``predict``
        (the same numbers) without its per-call checks and conversions."""
        import torch

        obs = np.asarray(obs, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.obs_size:
            raise ValueError(
                f"the model expects observations of size {self.obs_size}, got shape "
                f"{obs.shape}; make the env with the model's env_fields {self.env_fields}")
        policy = self.model.policy
        if policy.training:  # set_training_mode walks every submodule: 15 % of an episode
            policy.set_training_mode(False)
        with torch.inference_mode():
            tensor = torch.as_tensor(obs, device=policy.device)
            if _gaussian_actor_critic(policy):
                # The deterministic action of a Gaussian actor-critic is the mean, the
                # action head's output: the same tensor _predict returns, at half the cost
                # (no distribution object built).
                features = policy.extract_features(tensor, policy.pi_features_extractor)
                out = policy.action_net(policy.mlp_extractor.forward_actor(features))
            else:
                out = policy._predict(tensor, deterministic=True)
            actions = out.cpu().numpy()
        actions = actions.reshape(-1, 2)
        if policy.squash_output:
            actions = policy.unscale_action(actions)
        return np.clip(actions, -self.max_speed, self.max_speed).astype(np.float32)


class _NoOptimizer:
    """Stands in for the optimizer of a model loaded only to act: constructing torch's Adam
    imports ``torch._dynamo`` (1.1 s on 2 cores, a quarter of ``boids run --policy
    learned``), and acting never steps an optimizer. Its saved state is accepted and
    ignored."""

    def __init__(self, params: Any, **kwargs: Any) -> None:
        self.param_groups: list[dict[str, Any]] = []

    def load_state_dict(self, state: Any, *args: Any, **kwargs: Any) -> None:
        pass

    def state_dict(self) -> dict[str, Any]:
        return {}

    def zero_grad(self, set_to_none: bool = True) -> None:
        pass


def _acting_only(path: Path) -> dict[str, Any]:
    """``custom_objects`` for SB3's ``load`` that build the policy without an optimizer
    (the saved policy keyword arguments, the optimizer class replaced). Decodes the zip's
    pickles: for trusted files only."""
    import zipfile

    from stable_baselines3.common.save_util import json_to_data

    try:  # only the zip's "data" entry: the weights are read once, by SB3's load
        with zipfile.ZipFile(path) as archive:
            data = json_to_data(archive.read("data").decode())
    except Exception:  # unreadable: SB3's own load reports it
        return {}
    kwargs = data.get("policy_kwargs") if isinstance(data, dict) else None
    if not isinstance(kwargs, dict):
        return {}
    return {"policy_kwargs": {**kwargs, "optimizer_class": _NoOptimizer}}


def _env_fields(path: Path, fields: Any) -> dict[str, Any]:
    """A model's ``env_fields`` metadata, checked to build a valid env config."""
    if fields is None:
        return {}
    if not isinstance(fields, dict):
        raise ValueError(f"SB3 model {path}: env_fields in its {META_ENTRY} must be a table of "
                         f"env config fields, got {fields!r}")
    from boids_env.config import EnvConfig

    try:
        EnvConfig.from_kwargs(**fields)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"SB3 model {path}: env_fields in its {META_ENTRY} are invalid: {exc}"
                         ) from None
    return dict(fields)


def _gaussian_actor_critic(policy: Any) -> bool:
    from stable_baselines3.common.distributions import DiagGaussianDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy

    return (isinstance(policy, ActorCriticPolicy)
            and isinstance(policy.action_dist, DiagGaussianDistribution))


THREADS_VARIABLE = "BOIDS_TORCH_THREADS"
"""Environment variable: torch CPU threads of a policy acting outside training (default 1)."""


def set_inference_threads(threads: int | None = None) -> int:
    """Limits torch's CPU threads for acting (``threads``, else ``$BOIDS_TORCH_THREADS``, else
    1); returns the number set."""
    import os

    import torch

    if threads is None:
        raw = os.environ.get(THREADS_VARIABLE, "1")
        try:
            threads = int(raw)
        except ValueError:
            raise ValueError(f"{THREADS_VARIABLE} must be a positive integer, got {raw!r}"
                             ) from None
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads must be a positive integer, got {threads!r}")
    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
    return threads
