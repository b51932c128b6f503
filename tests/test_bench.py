"""The benchmark's rows run and its ratios are the quotients it names (no timings asserted:
timing goals live in the benchmark itself)."""

import gc
import weakref

import pytest

from boids_env.bench.run import SCENE_ROWS, _ratios, env_loop


def _row(kind, robots, rate):
    return {"kind": kind, "robots": robots, "env_steps_per_s": {"median": rate}}


def test_ratios_are_each_row_over_its_baseline():
    rows = [_row("physics", 19, 1000.0), _row("env random", 19, 400.0),
            _row("env random arrays", 19, 550.0), _row("env reynolds", 19, 300.0),
            _row("env reynolds lab", 19, 180.0), _row("env reynolds lab route", 19, 150.0),
            _row("env random lidar16", 19, 200.0),
            _row("env random turtlebot3", 19, 100.0), _row("env random person crowd8", 19, 50.0),
            _row("physics", 1000, 100.0), _row("env reynolds", 1000, 60.0),
            _row("env reynolds arrays", 1000, 80.0)]
    ratios = _ratios(rows)
    assert ratios == {
        "lab_over_default_19": 0.6, "route_over_default_19": 0.5, "route_over_lab_19": 150 / 180,
        "lidar16_over_default_19": 0.5,
        "turtlebot3_over_default_19": 0.25, "person_crowd8_over_default_19": 0.125,
        "env_random_dict_19_over_physics_19": 0.4, "env_random_arrays_19_over_physics_19": 0.55,
        "env_reynolds_dict_1000_over_physics_1000": 0.6,
        "env_reynolds_arrays_1000_over_physics_1000": 0.8}


@pytest.mark.parametrize("api", ["dict", "arrays"])
@pytest.mark.parametrize("row", SCENE_ROWS, ids=lambda r: r[0])
def test_every_world_row_steps(row, api):
    _, policy, fields = row
    loop = env_loop(19, 3, policy, api, **dict(fields))
    assert loop() == 3 and loop() == 3  # reset between runs


def test_a_loops_reset_is_off_the_clock(monkeypatch):
    from boids_env.bench import run

    now = [0.0]  # a fake clock: a reset takes 100 s, each step 1 s
    monkeypatch.setattr(run.time, "perf_counter", lambda: now[0])

    def reset():
        now[0] += 100.0
        return "episode"

    def steps(episode):
        assert episode == "episode"  # what the reset returned
        now[0] += 4.0
        return 4

    loop = run.Loop(reset, steps)
    summary, rounds = run.timed_together({"loop": loop}, 3)
    assert summary["loop"]["median"] == 1.0
    assert [r["loop"] for r in rounds] == [1.0, 1.0, 1.0]  # 4 steps in 4 s, every round
    assert run.timed(loop, 2)["median"] == 1.0
    now[0] = 0.0
    assert loop() == 4 and now[0] == 104.0  # called unprepared, it resets first


def test_a_loops_prepare_collects_the_garbage_its_reset_left():
    from boids_env.bench import run

    class Node:
        pass

    left = []

    def reset():  # a reset that drops a reference cycle (as a replaced pymunk world)
        node = Node()
        node.me = node
        left.append(weakref.ref(node))

    loop = run.Loop(reset, lambda _: 0)
    enabled = gc.isenabled()
    gc.disable()  # the collector's own thresholds must not do it
    try:
        loop.prepare()
        assert left[0]() is None, "the cycle the reset left is still alive after prepare"
    finally:
        if enabled:
            gc.enable()


def test_paired_ratios_are_taken_round_by_round():
    from boids_env.bench.run import paired_ratio, timed_together

    # a machine twice as fast in the second round: each round's quotient is 0.5
    rounds = [{"base": 100.0, "kind": 50.0}, {"base": 200.0, "kind": 100.0},
              {"base": 150.0, "kind": 30.0}]
    assert paired_ratio(rounds, "kind", "base") == 0.5
    calls = []
    summary, timed_rounds = timed_together(
        {"a": lambda: calls.append("a") or 10, "b": lambda: calls.append("b") or 20}, 3)
    assert calls == ["a", "b"] * 4  # a warm-up, then every loop once per round, in turn
    assert len(timed_rounds) == 3 and set(summary) == {"a", "b"}
    assert all(s["min"] <= s["median"] <= s["max"] for s in summary.values())


def test_digests_match_the_pinned_golden_trajectories():
    import json
    from pathlib import Path

    from boids_env import parallel_env
    from boids_env.bench.digests import digest
    from boids_env.eval.episode import run_episode
    from boids_env.policies import ReynoldsPolicy

    golden = json.loads((Path(__file__).parent / "env" / "golden_reynolds.json").read_text())
    case = golden[0]  # the study's default case
    result = run_episode(parallel_env(**case["fields"]), ReynoldsPolicy(**case["policy"]),
                         seed=case["seed"])
    assert digest(result.recording.positions, result.recording.commanded) == case["sha"]


@pytest.mark.slow
def test_compare_runs_old_and_new_in_turn_and_takes_ratios_round_by_round():
    import sys

    from boids_env.bench.compare import compare

    out = compare(sys.executable, robots=3, steps=2, repeats=1, rounds=2)
    assert out["setting"]["rounds"] == 2
    for name in ("old", "new"):
        for key in ("physics wall", "dict cpu", "arrays wall", "dict/physics wall",
                    "arrays/physics cpu"):
            assert out[name][key] > 0, (name, key, out[name])
    assert set(out["new_over_old"]) == {"physics wall", "physics cpu", "dict wall", "dict cpu",
                                        "arrays wall", "arrays cpu"}


@pytest.mark.slow
def test_compare_lockstep_takes_turns_block_by_block_in_two_processes():
    import sys

    from boids_env.bench.compare import compare_lockstep

    # 3 blocks of 4 steps in episodes of 8: each loop starts a second episode off the clock
    out = compare_lockstep(sys.executable, robots=3, steps=8, blocks=3, block_steps=4)
    assert out["setting"] == {"robots": 3, "steps": 8, "blocks": 3, "block_steps": 4,
                              "policy": "random", "clock": "cpu"}
    assert set(out["new_over_old_time"]) == {"physics", "dict", "arrays"}
    assert all(0 < v < float("inf") for v in out["new_over_old_time"].values())
    for name in ("old", "new"):
        assert out[name]["dict/physics"] > 0 and out[name]["arrays/physics"] > 0
        assert set(out[name]["us per step"]) == {"physics", "dict", "arrays"}
        assert min(out[name]["us per step"].values()) > 0


def test_compare_lockstep_names_a_process_that_stops(tmp_path):
    from boids_env.bench.compare import compare_lockstep

    broken = tmp_path / "python"
    broken.write_text("#!/bin/sh\nexit 3\n")
    broken.chmod(0o755)
    with pytest.raises(RuntimeError, match=r"the old process stopped \(exit 3\) before "
                                           r"answering 'READY'"):
        compare_lockstep(str(broken), robots=3, steps=4, blocks=1, block_steps=2)


def test_compare_refuses_a_missing_interpreter_and_bad_blocks(capsys):
    from boids_env.bench.compare import main

    for argv, message in ((["/no/such/python", "--lockstep"], "no interpreter at"),
                          (["python", "--lockstep", "--blocks", "0"], "--blocks must be at"),
                          (["python", "--lockstep", "--block-steps", "301"],
                           "--block-steps must be at most --steps")):
        with pytest.raises(SystemExit):
            main(argv)
        assert message in capsys.readouterr().err


def test_compare_refuses_bad_counts():
    from boids_env.bench.compare import main

    with pytest.raises(SystemExit):
        main(["python", "--rounds", "0"])


def test_lab_episode_costs_are_rounds_of_both_policies_and_their_median_quotient():
    from boids_env.bench.training import lab_episode_costs

    costs = lab_episode_costs(rounds=3, max_cycles=15)
    rows = costs["rounds"]
    assert len(rows) == 3 and all(len(r) == 2 and min(r) > 0 for r in rows)
    quotients = sorted(b / a for a, b in rows)
    assert costs["learned_scenes_over_reynolds"] == quotients[1]


def test_the_batch_rows_step_the_same_copies_both_ways():
    from boids_env.bench.batch import batch_loops

    loops, (together, apart) = batch_loops(3, 4)
    assert loops["batch"]() == 12 and loops["separate"]() == 12  # copy-steps
    assert len(together) == len(apart) == 3
    for a, b in zip(together, apart, strict=True):  # the same worlds, bit for bit
        assert a._world.steps == b._world.steps == 4
        assert a.state().tobytes() == b.state().tobytes()


@pytest.mark.slow
def test_compare_training_times_old_new_and_the_physics_round_by_round(tmp_path):
    import sys

    from boids_env.bench.compare import compare_training

    recipe = tmp_path / "tiny.toml"
    recipe.write_text("[train]\ncopies = 1\ngroup_sizes = [3]\nn_steps = 8\nbatch_size = 8\n"
                      "n_epochs = 1\nnet_arch = [8]\n")
    out = compare_training(sys.executable, str(recipe), rounds=2, rollouts=1,
                           physics_steps=20)
    assert len(out["rounds"]) == 2
    for row in out["rounds"]:
        assert row["old"] > 0 and row["new"] > 0 and row["physics"] > 0
    assert out["new_over_old"] == [r["new"] / r["old"] for r in out["rounds"]]
    assert out["new_over_physics_13"] == [r["new"] / r["physics"] for r in out["rounds"]]
    assert out["setting"] == {"recipe": str(recipe), "rounds": 2, "rollouts": 1}


def test_compare_refuses_an_unknown_training_recipe(capsys):
    from boids_env.bench.compare import main

    with pytest.raises(SystemExit):
        main(["python", "--training", "no_such_recipe"])
    assert "training config not found" in capsys.readouterr().err
