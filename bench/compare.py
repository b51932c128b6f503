"""Old code against new in one run: ``python -m boids_env.bench.compare OLD_PYTHON``.

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


def measure(python: str, robots: int, steps: int, repeats: int, policy: str
            ) -> dict[str, float]:
    """One measurement process under ``python``: rates (env-steps/s) and env/physics
    ratios, wall and CPU."""
    done = subprocess.run([python, "-c", MEASURE, str(robots), str(steps), str(repeats),
                           policy], capture_output=True, text=True, timeout=3600, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
    if done.returncode or not lines:
        raise RuntimeError(f"{python} failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    return json.loads(lines[-1].removeprefix("RESULT "))


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
    args = parser.parse_args(argv)
    for name in ("robots", "steps", "repeats", "rounds"):
        if getattr(args, name) < (2 if name == "robots" else 1):
            parser.error(f"--{name} must be at least {2 if name == 'robots' else 1}, got "
                         f"{getattr(args, name)}")
    out = compare(args.old_python, args.robots, args.steps, args.repeats, args.policy,
                  args.rounds)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
