"""The env through the batched clients against the raw batch, and VMAS's CPU ``VmasEnv``:
``python -m boids_env.bench.clients [--worlds 64] [--steps 100] [--rounds 5]``.

The same ``worlds`` copies of 13 robots (12 followers, random actions drawn beforehand) stepped
in turn, round by round, three ways: ``EnvBatch.step_arrays`` (``raw``), the batched TorchRL
env's ``step_and_maybe_reset`` (``torchrl``, :class:`~boids_env.integrations.torchrl.
BoidsTorchRLEnv`, TensorDict in and out, as a TorchRL collector steps it) and, when ``vmas`` is
installed, VMAS's ``flocking`` scenario with 12 agents in TorchRL's ``VmasEnv`` on the CPU at
the same batch size (``vmas``), stepped the same way. Prints one JSON object: env-steps/s
(median, min, max over rounds; one env-step is one world's step) and the ratios taken round by
round (``torchrl_over_raw``, ``torchrl_over_vmas``). Needs the ``clients`` extra (TorchRL).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
from collections.abc import Callable, Sequence

import numpy as np

from boids_env import kernels, parallel_env
from boids_env.batch import EnvBatch
from boids_env.bench.run import paired_ratio, timed_together

ROBOTS = 13


def _tensordict_loop(env, actions) -> Callable[[], int]:
    """``len(actions)`` steps of a TorchRL env through ``step_and_maybe_reset``."""
    import torch

    group = next(iter(env.action_keys))
    acts = [torch.as_tensor(a) for a in actions]
    td = env.reset()

    def run() -> int:
        nonlocal td
        for a in acts:
            td.set(group, a)
            _, td = env.step_and_maybe_reset(td)
        return len(acts) * env.batch_size[0]

    return run


def client_loops(worlds: int, steps: int, vmas: bool) -> dict[str, Callable[[], int]]:
    """The loops, each returning the env-steps (world steps) it made."""
    import torch

    from boids_env.integrations.torchrl import BoidsTorchRLEnv

    fields = {"robots": ROBOTS, "max_cycles": 10**9, "startup_time": 0.0}
    followers = ROBOTS - 1
    raw = EnvBatch([parallel_env(**fields) for _ in range(worlds)])
    raw.reset_arrays(list(range(worlds)))
    limit = raw.envs[0].config.world.max_speed
    rng = np.random.default_rng(0)
    actions = rng.uniform(-limit, limit, (steps, worlds, followers, 2)).astype(np.float32)
    flat = actions.reshape(steps, worlds * followers, 2).astype(np.float64)

    def run_raw() -> int:
        for a in flat:
            raw.step_arrays(a)
        return steps * worlds

    loops = {"raw": run_raw,
             "torchrl": _tensordict_loop(BoidsTorchRLEnv(worlds, seed=0, **fields), actions)}
    if vmas:
        from torchrl.envs.libs.vmas import VmasEnv

        torch.manual_seed(0)
        env = VmasEnv("flocking", num_envs=worlds, device="cpu", continuous_actions=True,
                      n_agents=followers, seed=0)
        spec = env.full_action_spec[next(iter(env.action_keys))]
        loops["vmas"] = _tensordict_loop(env, [spec.rand() for _ in range(steps)])
    return loops


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m boids_env.bench.clients",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, default=64, help="worlds per batch (64)")
    parser.add_argument("--steps", type=int, default=100, help="steps per round (100)")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds (5)")
    args = parser.parse_args(argv)
    for name in ("worlds", "steps", "rounds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    kernels.load()
    vmas = importlib.util.find_spec("vmas") is not None
    summary, rounds = timed_together(client_loops(args.worlds, args.steps, vmas), args.rounds)
    ratios = {"torchrl_over_raw": paired_ratio(rounds, "torchrl", "raw")}
    if vmas:
        ratios["torchrl_over_vmas"] = paired_ratio(rounds, "torchrl", "vmas")
    print(json.dumps({"worlds": args.worlds, "robots": ROBOTS, "steps": args.steps,
                      "rounds": args.rounds, "machine": platform.processor() or
                      platform.machine(), "env_steps_per_s": summary, **ratios,
                      "vmas": "flocking, 12 agents" if vmas else "not installed"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
