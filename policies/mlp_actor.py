"""A trained MLP actor's deterministic actions in numpy: acting without importing torch.

``boids train`` stores the actor of every Gaussian MLP policy it saves (SB3's PPO/A2C
``MlpPolicy``: the policy network's linear layers and activations, then the action head) as
an extra ``boids_actor.npz`` entry in the model zip. Acting from it needs only numpy: loading
torch and Stable-Baselines3 costs about 1.5 s, four times a whole 13-robot episode.

The actions are the same bits on every CPU: the layers' products are exact and tanh is built
from + - * / (:mod:`boids_env.policies.exact`), so neither the BLAS kernel nor numpy's SIMD
dispatch changes them. They equal torch's forward pass up to torch's own float32 rounding, so
trajectories agree with those of the torch model for a while and then drift.
"""

from __future__ import annotations

import io
import math
import zipfile
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.files import read_zip_entry
from boids_env.policies import exact, kernels
from boids_env.policies.base import BatchPolicy
from boids_env.untrusted import printable

ACTOR_ENTRY = "boids_actor.npz"
ACTIVATIONS = {"tanh": exact.tanh, "relu": exact.relu}
ARRAYS_LIMIT = 1 << 28
"""The most bytes a stored actor's arrays may hold in all, 256 MiB (a layer of 4,096 x 4,096,
the widest a training config allows: 64 MiB)."""
_ACTIVATION_CODES = {"tanh": 1, "relu": 2}
"""The compiled path's names for :data:`ACTIVATIONS` (0: none, the action head)."""


class MLPActor(BatchPolicy):
    """Deterministic actions ``clip(head(act(... act(W0 x + b0) ...)), low, high)``.

    Args:
        weights: the layers' matrices (out, in), first to last, the action head last.
        biases: their bias vectors.
        activation: a name in :data:`ACTIVATIONS`, applied after every layer but the head.
        low, high: the action space's bounds (per component).
        env_fields: the env config fields the observations need (from the model's metadata).
    """

    def __init__(self, weights: list[npt.NDArray[np.float32]],
                 biases: list[npt.NDArray[np.float32]], activation: str,
                 low: npt.ArrayLike, high: npt.ArrayLike,
                 env_fields: dict[str, Any] | None = None, name: str = "mlp") -> None:
        if activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got "
                             f"{activation!r}")
        if not weights or len(weights) != len(biases):
            raise ValueError("an MLP actor needs one layer or more, one bias per weight matrix")
        for k, (w, b) in enumerate(zip(weights, biases, strict=True)):
            chained = k == 0 or w.shape[1:] == weights[k - 1].shape[:1]
            if w.ndim != 2 or b.shape != (w.shape[0],) or not chained:
                raise ValueError(f"layer {k}: weight {w.shape} and bias {b.shape} do not chain")
        if weights[-1].shape[0] != 2:
            raise ValueError(f"the last layer must output an action (vx, vy), got "
                             f"{weights[-1].shape[0]} outputs")
        # stored transposed: x @ W.T is the torch Linear's x W^T + b
        self.weights = [np.ascontiguousarray(w.T, dtype=np.float32) for w in weights]
        self.biases = [np.asarray(b, dtype=np.float32) for b in biases]
        self.layers = [exact.ExactLinear(w, b) for w, b in zip(self.weights, self.biases,
                                                                strict=True)]
        self.activation = activation
        self.low = np.asarray(low, dtype=np.float32)
        self.high = np.asarray(high, dtype=np.float32)
        self.env_fields = dict(env_fields or {})
        self.name = name
        self.obs_size = int(weights[0].shape[1])
        self._bounds = np.array(np.broadcast_arrays(self.low, self.high), dtype=np.float32)

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        """Actions (F, 2) of all followers' observations (F, D) in one pass (float64 inside,
        the same bits on every CPU)."""
        x = np.asarray(obs, dtype=np.float32)  # what torch is given
        if x.ndim != 2 or x.shape[1] != self.obs_size:
            raise ValueError(
                f"the model expects observations of size {self.obs_size}, got shape "
                f"{x.shape}; make the env with the model's env_fields {self.env_fields}")
        compiled = kernels.compiled()
        if compiled is not None and self._bounds.shape == (2, 2) and np.isfinite(x).all():
            # the same bits in fewer calls: the elementwise parts compiled, the exact
            # products numpy's as below (policies.exact)
            code = _ACTIVATION_CODES[self.activation]
            slices, exponents = compiled.exact_slices(np.ascontiguousarray(x))
            for layer in self.layers[:-1]:  # a layer's sums and tanh, the next one's slices
                slices, exponents = compiled.exact_combine_slices(
                    layer.products(slices), exponents, layer.column_scale, layer.bias, code,
                    exact.INV_LN2, exact.LN2, exact.TANH_ONE)
            head = self.layers[-1]
            y = compiled.exact_combine(head.products(slices), exponents, head.column_scale,
                                       head.bias, 0, exact.INV_LN2, exact.LN2, exact.TANH_ONE)
            return compiled.clip_actions(y, self._bounds[0], self._bounds[1])
        act = ACTIVATIONS[self.activation]
        y = x.astype(np.float64)
        for layer in self.layers[:-1]:
            y = act(layer(y))
        out = self.layers[-1](y).reshape(-1, 2)
        return np.clip(out, self.low, self.high).astype(np.float32)

    def to_bytes(self) -> bytes:
        """The ``boids_actor.npz`` entry: this actor's arrays (read back by
        :meth:`from_bytes`)."""
        arrays: dict[str, Any] = {"activation": np.array(self.activation),
                                  "low": self.low, "high": self.high}
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            arrays[f"w{k}"], arrays[f"b{k}"] = w.T, b
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, raw: bytes, env_fields: dict[str, Any] | None = None,
                   name: str = "mlp", limit: int = ARRAYS_LIMIT) -> MLPActor:
        """The actor stored by :meth:`to_bytes`; ``ValueError`` for anything else, among it
        arrays that hold more than ``limit`` bytes in all (refused from the entry's directory
        before any is inflated or allocated)."""
        try:
            arrays = _read_arrays(raw, limit)
            layers = sum(1 for key in arrays if key.startswith("w"))
            weights = [arrays[f"w{k}"] for k in range(layers)]
            biases = [arrays[f"b{k}"] for k in range(layers)]
            activation = str(arrays["activation"])
            low, high = arrays["low"], arrays["high"]
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise ValueError(f"not a stored MLP actor ({ACTOR_ENTRY}): {exc}") from None
        return cls(weights, biases, activation, low, high, env_fields, name)


MAX_MEMBERS = 64
"""Most arrays in a stored actor (3 plus 2 per layer)."""


def _read_arrays(raw: bytes, limit: int) -> dict[str, Any]:
    """The arrays of an ``.npz``, each read within its budget: refused, before numpy allocates
    any of them, when they are too many, declare more than ``limit`` bytes in all, inflate
    more than :data:`~boids_env.untrusted.MAX_RATIO` times (a zip bomb) or declare in their
    header more data than their entry holds (numpy sizes an array from its header and
    allocates it before reading; a small entry could declare terabytes). Nothing is
    unpickled."""
    with zipfile.ZipFile(io.BytesIO(raw)) as archive:
        infos = archive.infolist()
        if len(infos) > MAX_MEMBERS:
            raise ValueError(f"{len(infos)} arrays, more than the {MAX_MEMBERS} allowed")
        total = sum(info.file_size for info in infos)
        if total > limit:
            raise ValueError(f"its arrays hold {total:,} bytes uncompressed, more than the "
                             f"{limit:,} allowed")
        arrays = {}
        for info in infos:
            data = read_zip_entry(archive, info.filename, limit)
            arrays[info.filename.removesuffix(".npy")] = _array(info.filename, data)
    return arrays


def _array(name: str, data: bytes) -> Any:
    """The array an ``.npy`` entry holds, its header checked against the entry's size."""
    fh = io.BytesIO(data)
    version = np.lib.format.read_magic(fh)
    header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
              else np.lib.format.read_array_header_2_0)
    shape, _, dtype = header(fh)
    nbytes = math.prod(shape) * dtype.itemsize
    if nbytes > len(data) - fh.tell():
        raise ValueError(f"array {printable(name, 120)} declares {nbytes:,} bytes but its entry "
                         f"holds {len(data):,}")
    fh.seek(0)
    return np.lib.format.read_array(fh, allow_pickle=False)
