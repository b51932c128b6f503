"""The rollout boundary a checkpoint carries, so ``boids train --resume`` goes on bit for bit.

A PPO checkpoint is written mid-rollout (every ``checkpoint_every`` follower-steps), when its
weights are still those of the rollout's start: PPO updates only once a rollout is collected.
What else makes the rest of the run is the state at that start, and each checkpoint (and the
final ``model.zip``) keeps it in one more entry, ``boids_resume.npz``:

- the follower-steps and update count at the rollout's start;
- every random stream the run draws from: torch's (the policy's action noise), numpy's
  global one (SB3 shuffles the minibatches with it), Python's, and each env copy's own;
- each env copy's episode so far as data: its reset's seed and options and the actions of
  its steps since (:meth:`Shard.state <boids_env.train.shards.Shard.state>`), replayed on a
  resume to rebuild the copy exactly (the env is deterministic; no pymunk state is stored);
- the observations and episode starts the policy acts on next, and VecMonitor's running
  episode returns.

A resume of the same training (its :func:`~boids_env.train.run.identity`) restores all of it
and collects that rollout again: the weights, the optimizer's moments, every later checkpoint
and ``evaluations.csv`` are those of a run never stopped. Only plain arrays and JSON are
stored (read with ``allow_pickle=False``), so nothing in the entry runs code. What is not
kept: SAC's replay buffer (a SAC resume restarts the env copies' episodes), TensorBoard's
logs of the rollout collected twice, and the zip's SB3 ``data`` timings.
"""

from __future__ import annotations

import hashlib
import io
import json
import random
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.files import read_zip_entry

ENTRY = "boids_resume.npz"
"""The model-zip entry holding the rollout boundary."""
LIMIT = 1 << 30
"""Most bytes the entry may inflate to (a default training's is about 2 MB)."""
ARRAYS = ("meta", "torch_rng", "numpy_keys", "last_obs", "episode_starts", "monitor_returns",
          "monitor_lengths", "actions")
"""The arrays of the entry (``meta``: the JSON of everything else, as bytes)."""


def digest(identity: dict[str, Any]) -> str:
    """A training's identity as a short hash: a boundary applies to the training it is of."""
    return hashlib.sha256(json.dumps(identity, sort_keys=True, default=str).encode()
                          ).hexdigest()[:32]


def applies(model: Any) -> bool:
    """Whether ``model`` can resume from a boundary (on-policy: nothing lives across
    rollouts but what the entry keeps)."""
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    return isinstance(model, OnPolicyAlgorithm)


def capture(model: Any, monitor: Any, identity: str, extra: dict[str, Any] | None = None
            ) -> bytes:
    """The entry for the state of ``model`` and its env now, at a rollout's start (``monitor``:
    the VecMonitor over the :class:`~boids_env.train.vec_env.FlockVecEnv`; ``extra``: the
    callbacks' own state, as JSON)."""
    import torch

    copies = monitor.venv.episodes_state()
    name, keys, pos, has_gauss, cached = np.random.get_state()  # noqa: NPY002 - SB3 shuffles with it
    meta = {"identity": identity, "timesteps": int(model.num_timesteps),
            "n_updates": int(model._n_updates), "numpy": [name, int(pos), int(has_gauss),
                                                          float(cached)],
            "random": _listed(random.getstate()), "monitor_count": int(monitor.episode_count),
            "extra": dict(extra or {}),
            "copies": [{"seed": c["seed"], "options": c["options"], "rng": c["rng"],
                        "steps": len(c["actions"]), "followers": int(c["actions"].shape[1])}
                       for c in copies]}
    actions = [c["actions"].reshape(-1, 2) for c in copies]
    arrays: dict[str, np.ndarray] = {
              "meta": np.frombuffer(json.dumps(meta).encode(), np.uint8),
              "torch_rng": torch.get_rng_state().numpy().copy(), "numpy_keys": keys,
              "last_obs": np.asarray(model._last_obs, np.float32),
              "episode_starts": np.asarray(model._last_episode_starts, bool),
              "monitor_returns": np.asarray(monitor.episode_returns),
              "monitor_lengths": np.asarray(monitor.episode_lengths),
              "actions": np.concatenate(actions) if actions else np.zeros((0, 2), np.float32)}
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def _listed(value: Any) -> Any:
    """Tuples as lists, all the way down (Python's random state as JSON)."""
    return [_listed(v) for v in value] if isinstance(value, tuple | list) else value


def _tupled(value: Any) -> Any:
    return tuple(_tupled(v) for v in value) if isinstance(value, list) else value


def write(path: str | Path, entry: bytes) -> None:
    """Adds the entry to the model zip at ``path`` (a temporary being written atomically)."""
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(ENTRY, entry)


def read(path: str | Path) -> dict[str, Any] | None:
    """The boundary a checkpoint carries (None when it has none: an older zip, SAC's);
    ``ValueError`` naming the file when the entry is not what :func:`capture` writes."""
    from boids_env.policies.mlp_actor import _read_arrays
    from boids_env.untrusted import open_zip

    with open_zip(path, "checkpoint") as zf:
        if ENTRY not in zf.namelist():
            return None
        raw = read_zip_entry(zf, ENTRY, LIMIT)
    try:
        # each array read within the budget, none declaring more than its entry holds
        read = _read_arrays(raw, LIMIT)
        arrays = {name: read[name] for name in ARRAYS}
        meta = json.loads(arrays.pop("meta").tobytes())
        return {**meta, **arrays, "copies": _copies(meta["copies"], arrays.pop("actions"))}
    except (ValueError, KeyError, TypeError, OSError, zipfile.BadZipFile) as exc:
        raise ValueError(f"checkpoint {path}: its {ENTRY} is not a rollout boundary of boids "
                         f"train ({type(exc).__name__}: {exc})") from None


def _copies(saved: Sequence[dict[str, Any]], actions: np.ndarray) -> list[dict[str, Any]]:
    """Each copy's saved episode with its actions (steps, F, 2) cut from the one array."""
    out, start = [], 0
    for copy in saved:
        steps, followers = int(copy["steps"]), int(copy["followers"])
        rows = steps * followers
        if min(steps, followers) < 0 or rows > len(actions) - start:
            raise ValueError(f"the actions hold {len(actions)} rows, the copies more")
        out.append({**copy, "actions": actions[start:start + rows].reshape(
            steps, followers, 2)})
        start += rows
    return out


def restore(model: Any, monitor: Any, state: dict[str, Any]) -> bool:
    """Puts ``model``, its env copies and the random streams back at the boundary ``state``
    (as :func:`read` gives it); False, with nothing of the model changed, when the replayed
    episodes do not give the saved observations (the env's code changed since)."""
    import torch

    obs = monitor.venv.restore_episodes(state["copies"])
    last = state["last_obs"]
    if obs.shape != last.shape or not np.array_equal(obs, last):
        return False
    model.num_timesteps = int(state["timesteps"])
    model._n_updates = int(state["n_updates"])
    model._last_obs = last.copy()
    model._last_episode_starts = state["episode_starts"].copy()
    monitor.episode_returns = state["monitor_returns"].copy()
    monitor.episode_lengths = state["monitor_lengths"].copy()
    monitor.episode_count = int(state["monitor_count"])
    torch.set_rng_state(torch.from_numpy(state["torch_rng"].copy()))
    name, pos, has_gauss, cached = state["numpy"]
    np.random.set_state((name,  # noqa: NPY002 - SB3 shuffles with it
                         state["numpy_keys"], pos, has_gauss, cached))
    random.setstate(_tupled(state["random"]))
    return True
