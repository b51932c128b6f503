"""``boids train --resume``: a checkpoint continued without running anything stored in it.

SB3's ``load`` unpickles the objects its zips keep in ``data`` (the policy class, the spaces,
the learning-rate schedule, ...), which runs any code they carry. A run's own checkpoint does
not need them: the config rebuilds the same model (the algorithm, the MlpPolicy and its
``net_arch``, the hyperparameters, the env copies), and what training learned is all in the
state dicts (the policy's weights and the optimizer's moments) and the step counter. So by
default the model is built from the config, the state dicts are read with torch's
``weights_only`` loader (which refuses anything but tensors and plain containers), and the
counters from the plain JSON of ``data``. A checkpoint whose network the config does not build
is refused with a message naming ``--trust-model``, which loads it through SB3 (for files you
trust). Either way the config's hyperparameters apply, as ``config.json`` says.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from boids_env.files import read_zip_entry
from boids_env.policies.sb3_zip import UntrustedModelError, read_plain_data
from boids_env.train.config import TrainConfig
from boids_env.untrusted import open_zip

COUNTERS = ("num_timesteps", "_n_updates", "_episode_num")
"""Plain integers of ``data`` a resumed run carries on (the step count sets what is left to
train; the others are logged)."""


def load_checkpoint(path: str | Path, config: TrainConfig, env: Any, device: str,
                    tensorboard_log: str, verbose: int = 0, trust: bool = False) -> Any:
    """The SB3 model of ``config`` on ``env`` with the checkpoint's weights, optimizer state
    and step count (see the module's docstring); ``trust`` loads it through SB3's own load,
    which unpickles the objects stored in the zip, with the config's hyperparameters."""
    from stable_baselines3.common.utils import get_device

    from boids_env.train.ppo import learner_class

    cls = learner_class(config.algorithm)
    kwargs = config.algorithm_kwargs()
    if trust:
        kwargs.pop("policy_kwargs")  # SB3 refuses ones that differ from the saved network
        return cls.load(path, env=env, device=device, tensorboard_log=tensorboard_log,
                        **kwargs)
    counters = _counters(path)
    model = cls("MlpPolicy", env, device=device, verbose=verbose,
                tensorboard_log=tensorboard_log, **kwargs)
    names, variables = model._get_torch_save_params()
    where = get_device(device)
    states = {name: _weights(path, f"{name}.pth", where) for name in names}
    exact = True
    if config.resume_new_blocks:
        states = {"policy": _mapped(path, states.get("policy"), _saved_layout(path),
                                    _layout(config))}
        exact = False  # the optimizer starts afresh: its moments are of the narrower network
    elif config.resume_new_inputs:
        states = {"policy": _widened(path, states.get("policy"), config.resume_new_inputs,
                                     model.observation_space.shape[0])}
        exact = False  # the optimizer starts afresh: its moments are of the narrower network
    try:
        model.set_parameters(states, exact_match=exact, device=device)
    except (RuntimeError, ValueError, KeyError, IndexError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UntrustedModelError(path, f"its weights do not fit the network this config "
                                  f"builds ({config.algorithm}, net_arch "
                                  f"{list(config.net_arch)}): {first}") from None
    if variables:
        saved = _weights(path, "pytorch_variables.pth", where)
        if not isinstance(saved, dict):
            raise ValueError(f"checkpoint {path}: pytorch_variables.pth is not a table")
        for name in variables:
            value = saved.get(name)
            if value is not None:
                _set_tensor(model, name, value)
    for name, value in counters.items():
        setattr(model, name, value)
    return model


def _widened(path: str | Path, policy: Any, new: int, size: int) -> dict[str, Any]:
    """The policy state dict of a checkpoint whose network reads ``new`` fewer inputs than
    ``size``: each first layer (a weight whose input width is ``size - new``) gains ``new``
    zero columns at the end, so the widened network computes what the checkpoint did."""
    import torch

    if not isinstance(policy, dict):
        raise ValueError(f"checkpoint {path}: its policy.pth is not a table of weights")
    old = size - new
    out, widened = {}, 0
    for name, tensor in policy.items():
        if (isinstance(tensor, torch.Tensor) and tensor.ndim == 2
                and name.endswith(".0.weight") and tensor.shape[1] == old):
            tensor = torch.cat([tensor, tensor.new_zeros((tensor.shape[0], new))], dim=1)
            widened += 1
        out[name] = tensor
    if not widened:
        widths = sorted({int(t.shape[1]) for t in policy.values()
                         if isinstance(t, torch.Tensor) and t.ndim == 2})
        raise ValueError(f"resume_new_inputs={new}: checkpoint {path} has no first layer of "
                         f"{old} inputs (this env's {size} observation values less {new}); "
                         f"its layers read {widths}")
    return out


def _layout(config: TrainConfig) -> Any:
    from boids_env.config import EnvConfig
    from boids_env.observations import layout_of

    return layout_of(EnvConfig.from_kwargs(**config.env_fields))


def _saved_layout(path: str | Path) -> Any:
    """The observation layout a checkpoint's ``boids.json`` says its network reads."""
    from boids_env.observations import ObservationLayout
    from boids_env.policies.sb3_policy import read_meta

    blocks = read_meta(path).get("observation_layout")
    if blocks is None:
        raise ValueError(f"resume_new_blocks: checkpoint {path} has no saved observation "
                         f"layout (a model of boids train saves one): use resume_new_inputs")
    try:
        return ObservationLayout.from_blocks(blocks)
    except ValueError as exc:
        raise ValueError(f"resume_new_blocks: checkpoint {path}: {exc}") from None


def check_blocks(path: str | Path, old: Any, new: Any) -> None:
    """``ValueError`` unless every block of layout ``old`` is in ``new`` with its size."""
    ours = dict(new.blocks)
    wrong = {name: (size, ours.get(name)) for name, size in old.blocks
             if ours.get(name) != size}
    if wrong:
        raise ValueError(f"resume_new_blocks: checkpoint {path} reads blocks this env's "
                         f"observation lacks or sizes otherwise (block: (checkpoint, env)): "
                         f"{wrong}; env_fields must keep every block it was trained on "
                         f"(same neighbours, static slots, lidar rays, pedestrian slots)")


def checked_layouts(path: str | Path, config: TrainConfig) -> None:
    """Refuses, before anything is written, a ``resume_new_blocks`` checkpoint whose saved
    layout does not fit this config's env."""
    check_blocks(path, _saved_layout(path), _layout(config))


def _mapped(path: str | Path, policy: Any, old: Any, new: Any) -> dict[str, Any]:
    """The policy state dict of a checkpoint whose network reads layout ``old``, for an env
    of layout ``new``: each first layer's columns move to their block's place in ``new``,
    and the columns of blocks ``old`` lacks are zero (so the network computes what the
    checkpoint did on the blocks it knows, whatever the new ones hold)."""
    import torch

    if not isinstance(policy, dict):
        raise ValueError(f"checkpoint {path}: its policy.pth is not a table of weights")
    check_blocks(path, old, new)
    out, widened = {}, 0
    for name, tensor in policy.items():
        if (isinstance(tensor, torch.Tensor) and tensor.ndim == 2
                and name.endswith(".0.weight") and tensor.shape[1] == old.size):
            wide = tensor.new_zeros((tensor.shape[0], new.size))
            for block, _ in old.blocks:
                wide[:, new.block(block)] = tensor[:, old.block(block)]
            tensor = wide
            widened += 1
        out[name] = tensor
    if not widened:
        raise ValueError(f"resume_new_blocks: checkpoint {path} has no first layer of "
                         f"{old.size} inputs (its saved layout's size)")
    return out


def _counters(path: str | Path) -> dict[str, int]:
    data = read_plain_data(path)
    counters = {name: data[name] for name in COUNTERS if name in data}
    bad = {k: v for k, v in counters.items() if type(v) is not int or v < 0}
    if "num_timesteps" not in counters or bad:
        raise ValueError(f"checkpoint {path}: its data has no step count (num_timesteps) or "
                         f"holds a bad counter {bad}")
    return counters


def _weights(path: str | Path, entry: str, device: Any) -> Any:
    """A ``.pth`` entry through torch's ``weights_only`` loader."""
    import torch

    try:
        with open_zip(path, "checkpoint") as zf:
            raw = read_zip_entry(zf, entry, 1 << 30)
    except KeyError:
        raise ValueError(f"checkpoint {path} has no {entry}") from None
    try:
        return torch.load(io.BytesIO(raw), map_location=device, weights_only=True)
    except Exception as exc:  # the weights_only unpickler refuses anything but tensors
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"checkpoint {path}: its {entry} is not plain weights "
                         f"({first})") from None


def _set_tensor(model: Any, name: str, value: Any) -> None:
    """``model.<name>.data = value`` for a dotted name, as SB3's load puts torch variables
    back (the optimizer keeps the same tensor object)."""
    import torch

    if not isinstance(value, torch.Tensor):
        raise ValueError(f"checkpoint variable {name} is not a tensor")
    owner = model
    *parents, last = name.split(".")
    for part in parents:
        owner = getattr(owner, part)
    getattr(owner, last).data = value.data
