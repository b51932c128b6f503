"""A Stable-Baselines3 model zip read without running anything stored in it.

SB3 writes what JSON cannot hold into the zip's ``data`` entry as cloudpickle, base64-encoded
under a ``:serialized:`` key (the policy class, the spaces, the learning-rate schedule, ...),
and its ``load`` unpickles them: unpickling runs whatever code the file's author chose, before
anything checks the file. A zip from a model hub can therefore run code on the machine that
loads it. Here nothing is ever unpickled:

- ``data`` is parsed as JSON and every ``:serialized:`` value is skipped; SB3 writes the
  attributes of a serialized object beside it as plain text (a Box's ``_shape``, ``low``,
  ``high``), and only those are read;
- the weights come from ``policy.pth`` through torch's ``weights_only`` loader, which
  rebuilds tensors and plain containers and refuses anything else;
- the other entries (``pytorch_variables.pth``, the optimizer) are not read at all.

What a Gaussian MLP actor-critic (SB3's PPO/A2C ``MlpPolicy``, tanh activations, the default)
needs in order to act is all there: :func:`actor_from_weights` builds it as an
:class:`~boids_env.policies.mlp_actor.MLPActor`. Anything else (another activation, feature
extractor or policy class, all of which SB3 keeps only as pickles) raises
:class:`UntrustedModelError`, which names ``--trust-model`` / ``trust=True``: SB3's own load,
for a file the user trusts.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.files import read_zip_entry
from boids_env.policies.mlp_actor import MLPActor
from boids_env.untrusted import open_zip

DATA_LIMIT = 16 << 20
"""Largest ``data`` entry read (uncompressed bytes; SB3 writes a few kB)."""
WEIGHTS_LIMIT = 1 << 28
"""Largest ``policy.pth`` read (uncompressed bytes, 256 MiB)."""
SERIALIZED = ":serialized:"
TYPE = ":type:"
TRUST_FLAG = "--trust-model"
POLICY_ENTRY = "policy.pth"
ACTOR_CRITIC = "<function ActorCriticPolicy.__init__ "
"""How SB3 writes the ``__init__`` of its ``ActorCriticPolicy`` (PPO's and A2C's
``MlpPolicy``) beside the pickled class."""
BOX_TYPES = ("<class 'gymnasium.spaces.box.Box'>", "<class 'gym.spaces.box.Box'>")
PLAIN_POLICY_KWARGS = {"net_arch", "log_std_init", "ortho_init", "share_features_extractor",
                       "normalize_images", "full_std", "use_expln", "squash_output",
                       "optimizer_kwargs"}
"""``policy_kwargs`` keys that do not change a Gaussian MLP actor's deterministic action (or
that are checked: ``squash_output`` must be false); a class (activation, feature extractor)
would have made SB3 pickle the whole table."""
_ACTOR_KEY = re.compile(r"mlp_extractor\.policy_net\.(\d+)\.(weight|bias)")
_CRITIC_KEY = re.compile(r"(mlp_extractor\.value_net\.\d+|value_net)\.(weight|bias)")


class UntrustedModelError(ValueError):
    """A model zip that only Stable-Baselines3's own load can read, which runs code stored in
    the file; the message says why and names ``--trust-model`` / ``trust=True``."""

    def __init__(self, path: str | Path, why: str) -> None:
        super().__init__(
            f"SB3 model {path}: {why}. Loading it through Stable-Baselines3 unpickles objects "
            f"stored in the file, which runs any code its author put there: if you trust "
            f"where the file comes from, pass {TRUST_FLAG} (trust=True in Python)")


@dataclass(frozen=True)
class Serialized:
    """A ``:serialized:`` value of ``data``, never decoded: its type name and the plain
    attributes SB3 wrote beside it."""

    type: str
    attributes: dict[str, Any] = field(default_factory=dict)


def read_plain_data(path: str | Path) -> dict[str, Any]:
    """The ``data`` entry of a model zip as JSON, each ``:serialized:`` top-level value as a
    :class:`Serialized` (the pickle itself dropped unread); a ``ValueError`` naming the file
    when it is not a zip or ``data`` is not a JSON table."""
    try:
        with open_zip(path) as zf:
            if "data" not in zf.namelist():
                raise ValueError(f"SB3 model {path} has no 'data' entry")
            raw = read_zip_entry(zf, "data", DATA_LIMIT)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError) as exc:
        raise ValueError(f"cannot read SB3 model {path}: {exc}") from exc
    data = json_table(raw, path, "data entry")
    return {key: _plain(value) for key, value in data.items()}


def json_table(raw: bytes, path: str | Path, entry: str) -> dict[str, Any]:
    """The JSON table in ``raw``, the bytes of a model zip's ``entry`` (its name in the
    messages); a ``ValueError`` naming the file and the entry when they are not valid JSON
    or not a table."""
    try:
        table = json.loads(raw)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise ValueError(f"SB3 model {path}: its {entry} is not valid JSON ({exc})") from None
    if not isinstance(table, dict):
        raise ValueError(f"SB3 model {path}: its {entry} must be a JSON table, got "
                         f"{type(table).__name__}")
    return table


def _plain(value: Any) -> Any:
    if isinstance(value, dict) and SERIALIZED in value:
        return Serialized(str(value.get(TYPE, "")),
                          {k: v for k, v in value.items() if k not in (SERIALIZED, TYPE)})
    return value


@dataclass(frozen=True)
class ActorPlan:
    """What the JSON of ``data`` says about a zip's actor: enough to check it before loading
    anything (``boids eval`` refuses a policy before it starts workers)."""

    obs_size: int
    low: npt.NDArray[np.float32]
    high: npt.NDArray[np.float32]


def actor_plan(path: str | Path) -> ActorPlan:
    """Checks from ``data``'s JSON alone that the zip holds a Gaussian MLP actor-critic with
    tanh activations on a flat Box observation and a (vx, vy) Box action; raises
    :class:`UntrustedModelError` for anything only its pickles describe."""
    data = read_plain_data(path)
    policy_class = data.get("policy_class")
    init = policy_class.attributes.get("__init__") if isinstance(policy_class, Serialized) \
        else None
    if not (isinstance(init, str) and init.startswith(ACTOR_CRITIC)):
        raise UntrustedModelError(path, "its policy class is not SB3's ActorCriticPolicy "
                                  "(PPO's or A2C's MlpPolicy)")
    kwargs = data.get("policy_kwargs") or {}
    if not isinstance(kwargs, dict):
        raise UntrustedModelError(path, "its policy_kwargs hold a class (an activation, "
                                  "feature extractor or optimizer), kept only as a pickle")
    unknown = sorted(set(kwargs) - PLAIN_POLICY_KWARGS)
    if unknown or kwargs.get("squash_output") or data.get("use_sde"):
        what = f"policy_kwargs {unknown}" if unknown else "squashed or state-dependent actions"
        raise UntrustedModelError(path, f"its actor is not a plain Gaussian MLP ({what})")
    obs_shape = _box(path, data, "observation_space")[0]
    act_shape, low, high = _box(path, data, "action_space", bounds=True)
    if len(obs_shape) != 1 or act_shape != (2,):
        raise UntrustedModelError(path, f"its spaces are not a flat observation and a (vx, vy) "
                                  f"action (shapes {obs_shape} and {act_shape})")
    return ActorPlan(obs_shape[0], low, high)


def _box(path: str | Path, data: dict[str, Any], key: str, bounds: bool = False
         ) -> tuple[tuple[int, ...], Any, Any]:
    """A Box space's shape (and bounds) from the plain attributes beside its pickle."""
    space = data.get(key)
    if not (isinstance(space, Serialized) and space.type in BOX_TYPES):
        raise UntrustedModelError(path, f"its {key} is not a Box space")
    shape = space.attributes.get("_shape")
    if not (isinstance(shape, list) and all(type(n) is int and n > 0 for n in shape)):
        raise UntrustedModelError(path, f"its {key} has no readable shape")
    if not bounds:
        return tuple(shape), None, None
    low, high = (_numbers(space.attributes.get(name), shape) for name in ("low", "high"))
    if low is None or high is None or not (low <= high).all():
        raise UntrustedModelError(path, f"its {key} has no readable bounds")
    return tuple(shape), low, high


def _numbers(text: Any, shape: list[int]) -> npt.NDArray[np.float32] | None:
    """A 1-D array as numpy prints it (``'[-1. -1.]'``), or None."""
    if not isinstance(text, str) or "..." in text or not text.startswith("[") \
            or not text.endswith("]"):
        return None
    try:
        values = np.array([float(v) for v in text[1:-1].split()], dtype=np.float32)
    except ValueError:
        return None
    return values if values.shape == tuple(shape) and not np.isnan(values).any() else None


def actor_from_weights(path: str | Path, env_fields: dict[str, Any] | None = None,
                       name: str = "sb3") -> MLPActor:
    """The deterministic actor of a zip SB3 saved (not by ``boids train``), built from its
    weights alone without running anything stored in the file (see the module's docstring);
    :class:`UntrustedModelError` when only its pickles say what it is. Needs torch (to read
    ``policy.pth``), not Stable-Baselines3."""
    plan = actor_plan(path)
    state = _state_dict(path)
    layers = sorted({int(m.group(1)) for key in state if (m := _ACTOR_KEY.fullmatch(key))})
    expected = {f"mlp_extractor.policy_net.{i}.{p}" for i in layers for p in ("weight", "bias")}
    expected |= {"action_net.weight", "action_net.bias", "log_std"}
    other = {k for k in state if k not in expected and not _CRITIC_KEY.fullmatch(k)}
    if other or not expected <= set(state) or layers != list(range(0, 2 * len(layers), 2)):
        raise UntrustedModelError(path, f"its {POLICY_ENTRY} is not a Gaussian MLP "
                                  f"actor-critic with a flattening extractor (keys "
                                  f"{sorted(other or expected - set(state))[:4]})")
    names = [f"mlp_extractor.policy_net.{i}" for i in layers] + ["action_net"]
    try:
        actor = MLPActor([state[f"{n}.weight"] for n in names],
                         [state[f"{n}.bias"] for n in names], "tanh", plan.low, plan.high,
                         env_fields, name=name)
    except ValueError as exc:
        raise ValueError(f"SB3 model {path}: {exc}") from None
    if actor.obs_size != plan.obs_size:
        raise ValueError(f"SB3 model {path}: its first layer takes {actor.obs_size} inputs, "
                         f"its observation space has {plan.obs_size}")
    return actor


def _state_dict(path: str | Path) -> dict[str, npt.NDArray[np.float32]]:
    """``policy.pth`` through torch's ``weights_only`` loader, as float32 arrays."""
    try:
        import torch
    except ImportError as exc:
        raise ImportError(f"reading the weights of {Path(path).name} needs torch: pip "
                          f"install -e '.[train]' ({exc})") from exc
    try:
        with open_zip(path) as zf:
            raw = read_zip_entry(zf, POLICY_ENTRY, WEIGHTS_LIMIT)
        state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except KeyError:
        raise ValueError(f"SB3 model {path} has no {POLICY_ENTRY}") from None
    except Exception as exc:  # the weights_only unpickler refuses anything but tensors
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"SB3 model {path}: its {POLICY_ENTRY} is not a plain table of "
                         f"weights ({first})") from None
    if not (isinstance(state, dict) and all(isinstance(v, torch.Tensor) and
                                            v.is_floating_point() for v in state.values())):
        raise ValueError(f"SB3 model {path}: its {POLICY_ENTRY} is not a table of float "
                         f"tensors")
    return {str(k): v.detach().to(torch.float32).numpy() for k, v in state.items()}
