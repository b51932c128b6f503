"""Old code against new in one run: ``python -m boids_env.bench.compare OLD_PYTHON``.

With ``--training RECIPE`` (a shipped recipe, a TOML file, or ``defaults`` for ``boids
train``'s defaults) each process instead trains PPO on that config as ``boids train`` would
(``boids_env.bench.training.training_rate``: one warm-up rollout, then ``--rollouts`` timed,
with the threads and processes each commit's defaults resolve to), and after each old/new
pair a third process, under this interpreter, times the bench's bare physics of 13 robots
(``physics_loop``): the issue's training/physics quotient, taken round by round.

With ``--lockstep`` the two interpreters run side by side instead, one process each, taking
turns block by block: ``--block-steps`` steps of the bare physics, the dict API or the array
API at a time, the order reversed every block, ``--blocks`` blocks of each, each loop going on
where its last block stopped (a new episode off the clock every ``--steps`` steps). Only one
of them runs at any moment, and the two codes' blocks of a kind are a few milliseconds
apart, so a change of a few per cent shows through a machine whose speed drifts by tens
of per cent between processes (the medians of the blocks' CPU-time quotients, new over old
and each API over its own process's physics).

``OLD_PYTHON`` is the interpreter of a venv that has another commit of boids-env installed
(e.g. ``git worktree add ../old COMMIT`` and ``pip install -e ../old`` into a venv of its
own). Each round runs one measurement process under the old interpreter, then one under this
one (old, new, old, new, ...), so both see the same phases of a machine whose speed drifts.
Every process times the env's dict and array APIs against the bare physics of the same
group, interleaved round by round, on the wall clock and on its own CPU time
(``time.process_time``: on a machine whose other jobs hold cores, CPU time still measures
the work a step costs). The measurement uses only ``boids_env.bench.run``'s ``env_loop`` and
``physics_loop``, which older commits have too.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
from collections.abc import Sequence
from typing import Any

MEASURE = """
import json, statistics, sys, time
try:
    from boids_env import kernels
    kernels.load()  # the steady state (a process loads them on its own after a while)
except ImportError:  # a commit before the kernels
    pass
from boids_env.bench.run import env_loop, physics_loop
robots, steps, repeats, policy = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
loops = {"physics": physics_loop(robots, steps), "dict": env_loop(robots, steps, policy),
         "arrays": env_loop(robots, steps, policy, "arrays")}
for f in loops.values():
    f()
rounds = []
for _ in range(repeats):
    r = {}
    for kind, f in loops.items():
        if hasattr(f, "prepare"):  # the reset or a fresh world off the clock (newer benches)
            f.prepare()
        wall, cpu = time.perf_counter(), time.process_time()
        f()
        r[kind] = (steps / (time.perf_counter() - wall), steps / (time.process_time() - cpu))
    rounds.append(r)
out = {}
for kind in loops:
    for i, clock in enumerate(("wall", "cpu")):
        out[f"{kind} {clock}"] = statistics.median(r[kind][i] for r in rounds)
        if kind != "physics":
            out[f"{kind}/physics {clock}"] = statistics.median(r[kind][i] / r["physics"][i]
                                                               for r in rounds)
print("RESULT " + json.dumps(out))
"""


MEASURE_TRAINING = """
import json, sys
from boids_env.bench.training import training_rate
from boids_env.train.config import TrainConfig, resolve_recipe
recipe, rollouts = sys.argv[1], int(sys.argv[2])
config = TrainConfig() if recipe == "defaults" else TrainConfig.from_toml(resolve_recipe(recipe))
row = training_rate(config.replace(eval_every=0, checkpoint_every=0), rollouts=rollouts)
print("RESULT " + json.dumps({"follower-steps/s": row["follower_steps_per_s"],
                              "torch threads": row["torch_threads"]}))
"""

MEASURE_PHYSICS = """
import json, sys
from boids_env.bench.run import physics_loop, timed
robots, steps = int(sys.argv[1]), int(sys.argv[2])
rate = timed(physics_loop(robots, steps), 5)["median"]
print("RESULT " + json.dumps({"physics agent-steps/s": rate * robots}))
"""


LOCKSTEP = """
import gc, sys, time
import numpy as np
try:
    from boids_env import kernels
    kernels.load()
except ImportError:  # a commit before the kernels
    pass
from boids_env import EnvConfig, parallel_env
from boids_env.bench.run import arena_for
from boids_env.policies import ReynoldsPolicy
from boids_env.world.scenario import initial_positions
from boids_env.world.space import World
robots, steps, policy = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
# the set-up of bench.run's physics_loop and env_loop, stepped a block at a time here (their
# loops run whole episodes, and older commits' versions of them differ)
cfg = EnvConfig.from_kwargs(robots=robots, arena_half_size=arena_for(robots))
start = initial_positions(cfg.scenario, np.random.default_rng(0))
commands = np.random.default_rng(0).uniform(-0.5, 0.5, (steps, robots, 2))


class Physics:
    def begin(self):
        self.world, self.k = World(cfg.world, start), 0

    def step(self):
        self.world.step(commands[self.k])


class Env:
    def __init__(self, api):
        self.api = api
        self.env = parallel_env(robots=robots, max_cycles=10**9, path="external",
                                arena_half_size=arena_for(robots), startup_time=0.0)
        limit = self.env.config.world.max_speed
        self.draws = np.random.default_rng(0).uniform(-limit, limit, (steps, robots - 1, 2))
        self.policy = ReynoldsPolicy() if policy == "reynolds" else None

    def begin(self):
        env = self.env
        self.obs = env.reset(seed=0)[0] if self.api == "dict" else env.reset_arrays(seed=0)
        env.set_leader_command([0.3, 0.0])
        if self.policy is not None:
            self.policy.bind(env)
            self.policy.reset(0)
        self.k = 0

    def step(self):
        env, p, k = self.env, self.policy, self.k
        if self.api == "dict":
            acts = p.act(self.obs) if p else dict(zip(env.agents, self.draws[k], strict=True))
            self.obs = env.step(acts)[0]
        else:
            acts = p.act_batch(self.obs) if p else self.draws[k]
            self.obs = env.step_arrays(acts).observations


loops = {"physics": Physics(), "dict": Env("dict"), "arrays": Env("arrays")}
for loop in loops.values():  # a warm-up episode, then a fresh one
    loop.begin()
    for loop.k in range(steps):
        loop.step()
    loop.begin()
gc.collect()
print("READY", flush=True)
for line in sys.stdin:
    kind, block = line.split()
    loop = loops[kind]
    if loop.k + int(block) > steps:  # a new episode, off the clock
        loop.begin()
        gc.collect()
    cpu = time.process_time()
    for _ in range(int(block)):
        loop.step()
        loop.k += 1
    print(f"T {time.process_time() - cpu!r}", flush=True)
"""


def compare_lockstep(old_python: str, robots: int = 19, steps: int = 400, blocks: int = 200,
                     block_steps: int = 25, policy: str = "random",
                     new_python: str | None = None) -> dict[str, Any]:
    """The old and the new code in two processes taking turns block by block (the module
    doc): the medians over blocks of new/old CPU time of each loop, and of each API's
    physics/API quotient (its env-steps/s over the bare physics') in each process."""
    pythons = {"old": old_python, "new": new_python or sys.executable}
    kinds = ("physics", "dict", "arrays")
    times: dict[tuple[str, str], list[float]] = {(n, k): [] for n in pythons for k in kinds}
    procs: dict[str, subprocess.Popen[str]] = {}
    try:
        for name, python in pythons.items():
            procs[name] = subprocess.Popen(
                [python, "-c", LOCKSTEP, str(robots), str(steps), policy],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        for name, proc in procs.items():
            _expect(proc, name, "READY")
        order = [(n, k) for k in kinds for n in procs]
        for b in range(blocks):
            for name, kind in order if b % 2 == 0 else order[::-1]:
                proc = procs[name]
                assert proc.stdin is not None
                proc.stdin.write(f"{kind} {block_steps}\n")
                proc.stdin.flush()
                times[name, kind].append(float(_expect(proc, name, "T")))
    finally:
        for proc in procs.values():
            if proc.stdin is not None:
                proc.stdin.close()
            proc.wait(timeout=60)
    out: dict[str, Any] = {"new_over_old_time": {
        k: statistics.median(n / o for n, o in zip(times["new", k], times["old", k],
                                                    strict=True)) for k in kinds}}
    for name in procs:
        physics = times[name, "physics"]
        out[name] = {f"{k}/physics": statistics.median(
            p / t for p, t in zip(physics, times[name, k], strict=True)) for k in kinds[1:]}
        out[name]["us per step"] = {k: statistics.median(times[name, k]) / block_steps * 1e6
                                    for k in kinds}
    out["setting"] = {"robots": robots, "steps": steps, "blocks": blocks,
                      "block_steps": block_steps, "policy": policy, "clock": "cpu"}
    return out


def _expect(proc: subprocess.Popen[str], name: str, word: str) -> str:
    """The rest of the next line of ``proc``'s output, which must start with ``word``."""
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line.startswith(word):
        proc.kill()
        raise RuntimeError(f"the {name} process stopped (exit {proc.wait()}) before "
                           f"answering {word!r}; its output: {line!r}")
    return line[len(word):].strip()


def _run(python: str, script: str, *args: Any) -> dict[str, float]:
    done = subprocess.run([python, "-c", script, *map(str, args)], capture_output=True,
                          text=True, timeout=3600, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
    if done.returncode or not lines:
        raise RuntimeError(f"{python} failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    return json.loads(lines[-1].removeprefix("RESULT "))


def compare_training(old_python: str, recipe: str = "defaults", rounds: int = 3,
                     rollouts: int = 3, physics_steps: int = 1000,
                     new_python: str | None = None) -> dict[str, Any]:
    """Training throughput of the old and the new code in turn, and the bare physics of 13
    robots after each pair: each one's median follower-steps/s, and the rounds' new/old and
    new/physics quotients with their medians."""
    new_python = new_python or sys.executable
    rows = []
    for _ in range(rounds):
        old = _run(old_python, MEASURE_TRAINING, recipe, rollouts)
        new = _run(new_python, MEASURE_TRAINING, recipe, rollouts)
        physics = _run(new_python, MEASURE_PHYSICS, 13, physics_steps)
        rows.append({"old": old["follower-steps/s"], "new": new["follower-steps/s"],
                     "physics": physics["physics agent-steps/s"],
                     "threads": (old["torch threads"], new["torch threads"])})
    new_over_old = [r["new"] / r["old"] for r in rows]
    new_over_physics = [r["new"] / r["physics"] for r in rows]
    return {"rounds": rows,
            "old": statistics.median(r["old"] for r in rows),
            "new": statistics.median(r["new"] for r in rows),
            "new_over_old": new_over_old,
            "new_over_old_median": statistics.median(new_over_old),
            "new_over_physics_13": new_over_physics,
            "new_over_physics_13_median": statistics.median(new_over_physics),
            "setting": {"recipe": recipe, "rounds": rounds, "rollouts": rollouts}}


def measure(python: str, robots: int, steps: int, repeats: int, policy: str
            ) -> dict[str, float]:
    """One measurement process under ``python``: rates (env-steps/s) and env/physics
    ratios, wall and CPU."""
    return _run(python, MEASURE, robots, steps, repeats, policy)


def compare(old_python: str, robots: int = 19, steps: int = 300, repeats: int = 5,
            policy: str = "random", rounds: int = 3, new_python: str | None = None
            ) -> dict[str, Any]:
    """Old and new measured in turn for ``rounds`` rounds: each one's medians over rounds
    and new/old ratios of the rates taken round by round."""
    pythons = {"old": old_python, "new": new_python or sys.executable}
    runs: dict[str, list[dict[str, float]]] = {"old": [], "new": []}
    for _ in range(rounds):
        for name, python in pythons.items():
            runs[name].append(measure(python, robots, steps, repeats, policy))
    keys = runs["new"][0].keys()
    out: dict[str, Any] = {name: {k: statistics.median(r[k] for r in rs) for k in keys}
                           for name, rs in runs.items()}
    out["new_over_old"] = {k: statistics.median(n[k] / o[k] for n, o in zip(
        runs["new"], runs["old"], strict=True)) for k in keys if "/" not in k}
    out["setting"] = {"robots": robots, "steps": steps, "repeats": repeats, "policy": policy,
                      "rounds": rounds}
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m boids_env.bench.compare",
                                     description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("old_python", help="the old commit's venv interpreter")
    parser.add_argument("--robots", type=int, default=19, help="group size (19)")
    parser.add_argument("--steps", type=int, default=300, help="steps per timed loop (300)")
    parser.add_argument("--repeats", type=int, default=5, help="timed loops per process (5)")
    parser.add_argument("--policy", choices=["random", "reynolds"], default="random",
                        help="the env's actions (random)")
    parser.add_argument("--rounds", type=int, default=3, help="old/new process pairs (3)")
    parser.add_argument("--training", metavar="RECIPE",
                        help="compare training throughput on this recipe instead (a shipped "
                             "recipe, a TOML file, or 'defaults')")
    parser.add_argument("--rollouts", type=int, default=3,
                        help="with --training: rollouts timed per process (3)")
    parser.add_argument("--lockstep", action="store_true",
                        help="two processes taking turns block by block (module doc)")
    parser.add_argument("--blocks", type=int, default=200,
                        help="with --lockstep: blocks of each loop (200)")
    parser.add_argument("--block-steps", type=int, default=25,
                        help="with --lockstep: steps per block (25)")
    args = parser.parse_args(argv)
    if shutil.which(args.old_python) is None:
        parser.error(f"old_python: no interpreter at {args.old_python!r} (the old commit's "
                     f"venv's python, an executable file)")
    for name in ("robots", "steps", "repeats", "rounds", "rollouts", "blocks", "block_steps"):
        if getattr(args, name) < (2 if name == "robots" else 1):
            parser.error(f"--{name.replace('_', '-')} must be at least "
                         f"{2 if name == 'robots' else 1}, got {getattr(args, name)}")
    if args.lockstep and args.block_steps > args.steps:
        parser.error(f"--block-steps must be at most --steps ({args.steps}), got "
                     f"{args.block_steps}")
    if args.training:
        if args.training != "defaults":
            from boids_env.train.config import resolve_recipe
            try:
                resolve_recipe(args.training)
            except FileNotFoundError as err:
                parser.error(f"--training: {err}")
        out = compare_training(args.old_python, args.training, args.rounds, args.rollouts)
    elif args.lockstep:
        out = compare_lockstep(args.old_python, args.robots, args.steps, args.blocks,
                               args.block_steps, args.policy)
    else:
        out = compare(args.old_python, args.robots, args.steps, args.repeats, args.policy,
                      args.rounds)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
