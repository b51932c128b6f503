"""Throughput benchmark: ``python -m boids_env.bench [--quick] [--out runs/bench/results.json]``.

Measures, after a warm-up, over several repeats (median and spread):
env-steps/s and agent-steps/s of BoidsEnv with random actions and with the Reynolds policy in
the loop, the bare-physics ceiling (World.step alone), a map scene and a lidar against the
default, K copies stepped through one ``EnvBatch`` against the same K envs in turn
(``bench/batch.py``), and MPE2 ``simple_spread`` when the ``bench`` extra is installed.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from boids_env import EnvConfig, ScenarioConfig, kernels, parallel_env
from boids_env.bench.batch import batch_rows
from boids_env.config import layout_extent
from boids_env.files import write_text
from boids_env.policies import ReynoldsPolicy
from boids_env.world.scenario import initial_positions
from boids_env.world.space import World


def arena_for(robots: int) -> float:
    """The paper's 5 m arena, or a larger one that holds the initial grid of ``robots``."""
    need = layout_extent(ScenarioConfig(robots=robots)) + 0.5
    return max(5.0, float(np.ceil(need)))


class Loop:
    """A timed loop of steps: :meth:`prepare` (the reset or a fresh world, then a garbage
    collection, left out of the clock by :func:`timed` and :func:`timed_together`) then the
    call, which steps and returns how many steps it took (preparing first, on the clock, if
    not prepared)."""

    def __init__(self, prepare: Callable[[], Any], run: Callable[[Any], int]) -> None:
        self._prepare, self._run = prepare, run
        self._ready: list[Any] = []
        self._last: Any = None  # the last run's world, freed by the next prepare

    def prepare(self) -> None:
        self._last = None
        self._ready = [self._prepare()]
        # the reset's garbage collected off the clock too: a reset builds (and drops) a
        # pymunk world, thousands of tracked objects; left pending, they made the next loop
        # that allocates enough to trigger the collector (the dict API's per-agent dicts)
        # pay a full collection (150 ms at 1000 robots, in 2 of 3 rounds of 40 steps)
        gc.collect()

    def __call__(self) -> int:
        if not self._ready:
            self.prepare()
        self._last = self._ready.pop()
        return self._run(self._last)


def prepare(fn: Callable[[], int]) -> None:
    """Prepares ``fn`` off the clock if it is a :class:`Loop` (MPE's and the batch's loops
    are timed whole)."""
    if isinstance(fn, Loop):
        fn.prepare()


def timed(fn: Callable[[], int], repeats: int) -> dict[str, float]:
    """Runs ``fn`` (returns steps done) ``repeats`` times; steps/s median and spread."""
    fn()  # warm-up
    rates = []
    for _ in range(repeats):
        prepare(fn)
        t = time.perf_counter()
        steps = fn()
        rates.append(steps / (time.perf_counter() - t))
    return {"median": statistics.median(rates), "min": min(rates), "max": max(rates)}


def timed_together(loops: dict[str, Callable[[], int]], repeats: int
                   ) -> tuple[dict[str, dict[str, float]], list[dict[str, float]]]:
    """Runs every loop once per round, ``repeats`` rounds after a warm-up, so that every row
    sees the same phases of a machine whose speed drifts (a shared VM here: ±25 % between
    minutes); returns each loop's steps/s median and spread, and the rounds' rates (for
    ratios taken round by round, :func:`paired_ratio`)."""
    for fn in loops.values():
        fn()  # warm-up
    rounds = []
    for _ in range(repeats):
        rates = {}
        for kind, fn in loops.items():
            prepare(fn)
            t = time.perf_counter()
            steps = fn()
            rates[kind] = steps / (time.perf_counter() - t)
        rounds.append(rates)
    summary = {kind: {"median": statistics.median(r[kind] for r in rounds),
                      "min": min(r[kind] for r in rounds), "max": max(r[kind] for r in rounds)}
               for kind in loops}
    return summary, rounds


def paired_ratio(rounds: list[dict[str, float]], kind: str, base: str) -> float:
    """The median over rounds of ``kind``'s rate over ``base``'s in the same round."""
    return statistics.median(r[kind] / r[base] for r in rounds)


def env_loop(robots: int, steps: int, policy: str, api: str = "dict",
             **fields: Any) -> Loop:
    """Steps of the env with ``random`` or ``reynolds`` actions through the PettingZoo dict
    API (``dict``) or the array API (``arrays``); ``fields`` change the env config (a scene,
    sensing)."""
    if "scene" not in fields:
        fields["arena_half_size"] = arena_for(robots)
    fields.setdefault("path", "external")  # a person walks its own path (JuPedSim)
    fields.setdefault("startup_time", 0.0)  # the followers move from the first step
    env = parallel_env(robots=robots, max_cycles=10**9, **fields)
    reynolds = ReynoldsPolicy()  # bound below: the env's start-up (none), period and speed
    limit = env.config.world.max_speed
    external = env.config.scenario.path == "external"
    # drawn before the clock starts, as physics_loop draws its commands (each loop's
    # random stream is then neither side's cost); the dict API's dicts are built per step
    draws = (np.random.default_rng(0).uniform(-limit, limit, (steps, robots - 1, 2))
             if policy == "random" else None)

    def start() -> Any:  # off the clock: the reset (an episode's start is not a step)
        _forget_routes(env)
        obs = env.reset(seed=0)[0] if api == "dict" else env.reset_arrays(seed=0)
        if external:
            env.set_leader_command([0.3, 0.0])
        reynolds.bind(env)
        reynolds.reset(0)
        return obs

    def run_dict(obs: Any) -> int:
        for k in range(steps):
            acts = (reynolds.act(obs) if draws is None
                    else dict(zip(env.agents, draws[k], strict=True)))
            obs, *_ = env.step(acts)
        return steps

    def run_arrays(obs: Any) -> int:
        for k in range(steps):
            acts = reynolds.act_batch(obs) if draws is None else draws[k]
            obs = env.step_arrays(acts).observations
        return steps

    return Loop(start, run_dict if api == "dict" else run_arrays)


def _forget_routes(env: Any) -> None:
    """Drops the route fields kept from an earlier round (route sensing's cost, not its
    cache's)."""
    if env.config.observation.route_sensing:
        for value in env.config.scene._cache.values():
            if hasattr(value, "graph"):  # a RouteGrid
                value.__dict__.pop("_fields", None)


def physics_loop(robots: int, steps: int) -> Loop:
    cfg = EnvConfig.from_kwargs(robots=robots, arena_half_size=arena_for(robots))
    start = initial_positions(cfg.scenario, np.random.default_rng(0))
    commands = np.random.default_rng(0).uniform(-0.5, 0.5, (steps, robots, 2))

    def run(world: World) -> int:
        for k in range(steps):
            world.step(commands[k])
        return steps

    return Loop(lambda: World(cfg.world, start), run)  # a fresh world off the clock


def mpe_loop(agents: int, steps: int) -> Callable[[], int] | None:
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        return None
    env = simple_spread_v3.parallel_env(N=agents, max_cycles=10**9, continuous_actions=True)

    def run() -> int:
        env.reset(seed=0)
        for _ in range(steps):
            env.step({a: env.action_space(a).sample() for a in env.agents})
        return steps

    return run


def _env_rows(sizes: list[int], repeats: int, record: Callable[..., None]
              ) -> dict[str, float]:
    """The rows of each group size, timed together; the env/physics ratios at 19 and 1000
    robots, round by round."""
    ratios = {}
    for n in sizes:
        steps = 400 if n <= 100 else 40
        loops = {"physics": physics_loop(n, steps),
                 "env random": env_loop(n, steps, "random"),
                 "env random arrays": env_loop(n, steps, "random", "arrays"),
                 "env reynolds": env_loop(n, steps, "reynolds"),
                 "env reynolds arrays": env_loop(n, steps, "reynolds", "arrays")}
        summary, rounds = timed_together(loops, repeats)
        for kind, rate in summary.items():
            record(kind, n, n if kind == "physics" else n - 1, rate)
        policy = {19: "random", 1000: "reynolds"}.get(n)
        if policy:
            for kind, api in ((f"env {policy}", "dict"), (f"env {policy} arrays", "arrays")):
                ratios[f"env_{policy}_{api}_{n}_over_physics_{n}"] = paired_ratio(
                    rounds, kind, "physics")
    return ratios


SCENE_ROWS = (("env reynolds lab", "reynolds", {"scene": "lab"}),
              ("env reynolds lab route", "reynolds", {"scene": "lab", "route_sensing": True}),
              ("env random lidar16", "random", {"lidar_rays": 16}),
              ("env random turtlebot3", "random", {"robot": "turtlebot3_burger"}),
              ("env random person crowd8", "random", {"leader": "person", "crowd": 8,
                                                      "path": "square"}))
"""The world beyond the study at 19 robots, each against the default with the same policy:
the ``lab`` map scene (a 240 × 200 cell map) with the Reynolds policy avoiding its walls, the
same with route sensing (its fields computed afresh each round, as for a leader that never
drives the same cells twice), a
16-ray lidar, a TurtleBot3 flock (unicycles turned every physics substep), and a person
walked by JuPedSim through the square's corners with 8 pedestrians (the person suite's
crowd)."""
BASE_ROWS = {"reynolds": "env reynolds", "random": "env random"}


def _scene_rows(repeats: int, record: Callable[..., None]) -> dict[str, float]:
    """The world rows, timed together with the default rows they are compared with; each
    one's ratio to its default round by round."""
    loops = {base: env_loop(19, 300, policy) for policy, base in BASE_ROWS.items()}
    loops.update({kind: env_loop(19, 300, policy, **fields) for kind, policy, fields in SCENE_ROWS})
    summary, rounds = timed_together(loops, repeats)
    ratios = {}
    for kind, policy, _ in SCENE_ROWS:
        record(kind, 19, 18, summary[kind])
        ratios[_ratio_name(kind)] = paired_ratio(rounds, kind, BASE_ROWS[policy])
    return ratios


def _ratio_name(kind: str) -> str:
    return f"{kind.split()[-1] if 'crowd' not in kind else 'person_crowd8'}_over_default_19"


def _ratios(rows: list[dict[str, Any]]) -> dict[str, float]:
    by_kind = {(r["kind"], r["robots"]): r["env_steps_per_s"]["median"] for r in rows}
    ratios = {}
    pairs = {_ratio_name(kind): (kind, BASE_ROWS[policy]) for kind, policy, _ in SCENE_ROWS}
    for name, (new, base) in pairs.items():
        if (new, 19) in by_kind and (base, 19) in by_kind:
            ratios[name] = by_kind[(new, 19)] / by_kind[(base, 19)]
    if ("env reynolds lab route", 19) in by_kind and ("env reynolds lab", 19) in by_kind:
        ratios["route_over_lab_19"] = (by_kind[("env reynolds lab route", 19)]
                                       / by_kind[("env reynolds lab", 19)])
    if ("env random", 19) in by_kind and ("mpe2 simple_spread", 18) in by_kind:
        ratios["env_random_19_over_mpe2_18"] = (by_kind[("env random", 19)]
                                                / by_kind[("mpe2 simple_spread", 18)])
    if ("env random", 19) in by_kind:
        for kind, name in (("env random", "dict"), ("env random arrays", "arrays")):
            ratios[f"env_random_{name}_19_over_physics_19"] = (by_kind[(kind, 19)]
                                                               / by_kind[("physics", 19)])
    if ("env reynolds", 1000) in by_kind:
        for kind, name in (("env reynolds", "dict"), ("env reynolds arrays", "arrays")):
            ratios[f"env_reynolds_{name}_1000_over_physics_1000"] = (
                by_kind[(kind, 1000)] / by_kind[("physics", 1000)])
    return ratios


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m boids_env.bench", description=__doc__)
    parser.add_argument("--quick", action="store_true",
                        help="13 and 19 robots, 3 repeats, no training/suite/episode rows")
    parser.add_argument("--training", action="store_true",
                        help="only the training throughput rows (1, 2, all cores)")
    parser.add_argument("--out", default="runs/bench/results.json",
                        help="JSON output (runs/bench/results.json)")
    args = parser.parse_args(argv)
    compiled = kernels.load()  # at once: the rows measure the steady state, not the start
    repeats = 3 if args.quick else 5
    sizes = [13, 19] if args.quick else [7, 13, 19, 100, 1000]
    rows: list[dict[str, Any]] = []
    out: dict[str, Any] = {"machine": {"python": platform.python_version(),
                                       "cpu": platform.processor() or platform.machine(),
                                       "cores": os.cpu_count(),
                                       "kernels": compiled is not None}}

    def record(kind: str, n: int, agents: int, rate: dict[str, float]) -> None:
        rows.append({"kind": kind, "robots": n, "env_steps_per_s": rate,
                     "agent_steps_per_s": rate["median"] * agents})
        print(f"{kind:<20} N={n:<5} {rate['median']:>10.0f} env-steps/s "
              f"({rate['min']:.0f}–{rate['max']:.0f})  {rate['median'] * agents:>12.0f} "
              f"agent-steps/s", flush=True)

    if not args.training:
        paired = _env_rows(sizes, repeats, record)
        paired.update(_scene_rows(repeats, record))
        paired.update(batch_rows([8] if args.quick else [4, 8, 16], 100 if args.quick else 200,
                                 repeats, record, timed_together, paired_ratio))
        for n in [6, 12, 18] if not args.quick else [18]:
            loop = mpe_loop(n, 200)
            if loop is None:
                print("mpe2 not installed (pip install -e '.[bench]'): MPE2 skipped")
                break
            record("mpe2 simple_spread", n, n, timed(loop, repeats))
        out["results"] = rows
        # ratios taken round by round (rows timed together), over the medians' quotients
        out["ratios"] = {**_ratios(rows), **paired}
        for name, value in out["ratios"].items():
            print(f"{name:<32} {value:6.2f}")
    if not args.quick:
        _slow_rows(out, training_only=args.training)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    write_text(args.out, json.dumps(out, indent=2))  # atomic: no torn file on a kill
    print(f"wrote {args.out}")
    return 0


def _slow_rows(out: dict[str, Any], training_only: bool) -> None:
    """Training scaling, learned-vs-Reynolds episode costs (the default case and the lab)
    and the paper suite (training needs the train extra; skipped with a note without it)."""
    from boids_env.bench import training
    from boids_env.extras import missing

    if missing("train"):
        print("train extra not installed: training and learned-policy rows skipped")
    else:
        out["training"] = training.training_scaling()
        for row in out["training"]:
            print(f"training on {row['cores']:>2} cores ({row['processes']} env processes, "
                  f"{row['copies']} copies, {row['torch_threads']} threads, {row['device']}): "
                  f"{row['follower_steps_per_s']:,.0f} follower-steps/s = {row['ratio']:.2f}× "
                  f"the env's raw {row['raw_env_agent_steps_per_s']:,.0f}", flush=True)
        if not training_only:
            out["episode_seconds"] = costs = training.episode_costs()
            print(f"one default episode: Reynolds {costs['reynolds']:.3f} s, learned "
                  f"{costs['learned']:.3f} s ({costs['learned_over_reynolds']:.2f}×)")
            out["command_seconds"] = whole = training.command_costs()
            print(f"whole boids run command: Reynolds {whole['reynolds']:.2f} s, learned "
                  f"{whole['learned']:.2f} s ({whole['learned_over_reynolds']:.2f}×)")
    if not training_only:
        lab = out["lab_episode_seconds"] = training.lab_episode_costs()
        print("one lab episode, CPU s (Reynolds, learned-scenes) by round: "
              + ", ".join(f"{a:.3f}/{b:.3f}" for a, b in lab["rounds"])
              + f" ({lab['learned_scenes_over_reynolds']:.2f}×)")
        suite = training.paper_suite_seconds()
        out["paper_suite_seconds"] = suite
        if suite is not None:
            print(f"paper suite (35 distinct episodes, Reynolds, {suite['workers']} workers): "
                  f"{suite['episodes']:.1f} s episodes + {suite['report']:.1f} s report")
