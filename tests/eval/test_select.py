"""Checkpoint selection by bars (``boids select``): the bars' arithmetic on a hand-made table,
the validation suite's cases, and a short end-to-end run."""

import json

import numpy as np
import pandas as pd
import pytest

from boids_env import parallel_env
from boids_env.eval.cases import Case, Suite
from boids_env.eval.episode import run_episode
from boids_env.eval.select import BARS, ORDERS, Bar, bar_table, per_run, ranking, run_of, select
from boids_env.eval.suites import DEPLOYMENT, SCENES, VALIDATION
from boids_env.policies import ReynoldsPolicy
from boids_env.train.cli import main

TWO = (Bar("arena", "total", factor=0.5), Bar("small_room", "total", strict=True))


def _row(policy, case, total, touching=0.0, wall=0.0, farthest=1.0):
    # the total split over the three V_* (the table sums them)
    return {"policy": policy, "case": case, "V_sep": total / 2, "V_coh": total / 4,
            "V_align": total / 4, "touching_fraction": touching, "wall_fraction": wall,
            "final_leader_distance_max": farthest}


def _table(*rows):
    return pd.DataFrame([_row(*r) for r in rows])


def test_bars_compare_episode_means_with_the_reference():
    table = _table(("R", "arena", 1.5), ("R", "arena", 2.5),           # reference mean 2.0
                   ("R", "small_room", 4.0),
                   ("A", "arena", 0.8), ("A", "arena", 1.0),           # 0.9 <= 0.5 * 2.0
                   ("A", "small_room", 4.0),                           # not < 4.0 (strict)
                   ("B", "arena", 1.0), ("B", "arena", 1.0),           # 1.0 <= 1.0: met
                   ("B", "small_room", 3.0))
    bars = bar_table(table, "R", TWO)
    got = {(r.policy, r.case): (r.value, r.limit, r.met) for r in bars.itertuples()}
    assert got[("A", "arena")] == (pytest.approx(0.9), pytest.approx(1.0), True)
    assert got[("A", "small_room")] == (pytest.approx(4.0), pytest.approx(4.0), False)
    assert got[("B", "arena")][2] and got[("B", "small_room")][2]
    ranked = ranking(bars)
    assert list(ranked["policy"]) == ["B", "A"]
    assert list(ranked["met"]) == [2, 1] and list(ranked["missed"]) == ["", "small_room"]


def test_safety_and_a_lost_follower_fail_a_bar_and_ties_go_to_the_lower_total():
    table = _table(("R", "arena", 2.0), ("R", "small_room", 4.0),
                   ("A", "arena", 0.9), ("A", "small_room", 4.5),            # total misses
                   ("B", "arena", 0.5, 0.0, 0.0, 3.2),                       # one lost (3.2 m)
                   ("B", "small_room", 3.0),
                   ("C", "arena", 0.5), ("C", "small_room", 3.0, 0.02),       # touching 2 %
                   ("D", "arena", 0.5), ("D", "small_room", 3.0, 0.0, 0.011))  # wall 1.1 %
    ranked = ranking(bar_table(table, "R", TWO))
    assert dict(zip(ranked["policy"], ranked["met"], strict=True)) == \
        {"A": 1, "B": 1, "C": 1, "D": 1}
    # every one meets one bar; summed totals: A 5.4, B 3.5, C 3.5, D 3.5 (kept in order)
    assert list(ranked["policy"]) == ["B", "C", "D", "A"]
    assert list(ranked["summed_total"]) == pytest.approx([3.5, 3.5, 3.5, 5.4])


def test_headroom_prefers_the_widest_thinnest_margin():
    # reference: arena 2.0 (limit 1.0), small_room 4.0 (limit 4.0, strict)
    table = _table(("R", "arena", 2.0), ("R", "small_room", 4.0),
                   ("A", "arena", 0.2), ("A", "small_room", 3.96),   # headroom 0.8 and 0.01
                   ("B", "arena", 0.8), ("B", "small_room", 3.4),    # 0.2 and 0.15
                   ("C", "arena", 0.9), ("C", "small_room", 3.0),    # 0.1 and 0.25
                   ("D", "arena", 0.1), ("D", "small_room", 4.2))    # misses: 0.9, -0.05
    bars = bar_table(table, "R", TWO)
    room = {(r.policy, r.case): r.headroom for r in bars.itertuples()}
    assert room[("A", "small_room")] == pytest.approx(0.01)
    assert room[("B", "arena")] == pytest.approx(0.2)
    assert room[("D", "small_room")] == pytest.approx(-0.05)
    # summed totals A 4.16, B 4.2, C 3.9, D 4.3: the default order takes the lowest
    assert list(ranking(bars)["policy"]) == ["C", "A", "B", "D"]
    ranked = ranking(bars, "headroom")
    assert list(ranked["policy"]) == ["B", "C", "A", "D"]   # D: fewer bars, still last
    assert list(ranked["headroom"]) == pytest.approx([0.15, 0.1, 0.01, -0.05])
    with pytest.raises(ValueError, match="order must be one of"):
        ranking(bars, "margin")


def test_a_bar_without_a_value_has_no_headroom():
    table = _table(("R", "arena", 2.0), ("A", "arena", 0.5), ("B", "arena", 0.9))
    bars = bar_table(table, "R", (Bar("arena", "parked_speed", absolute=0.05),
                                  Bar("arena", "total", factor=0.5)))
    ranked = ranking(bars, "headroom")
    assert list(ranked["headroom"]) == [float("-inf")] * 2
    assert list(ranked["policy"]) == ["A", "B"]  # then the lower summed total


def test_each_run_gets_its_best_checkpoint():
    assert run_of("runs/s/seed_0/checkpoints/model_250_steps.zip") == "runs/s/seed_0"
    assert run_of("runs/s/seed_0/model.zip") == "runs/s/seed_0"
    assert run_of("learned-scenes") == "learned-scenes"
    specs = ["a/seed_0/checkpoints/m1.zip", "a/seed_0/model.zip", "a/seed_1/model.zip",
             "a/seed_1/checkpoints/m1.zip"]
    table = _table(("R", "arena", 2.0), ("R", "small_room", 4.0),
                   (specs[0], "arena", 1.5), (specs[0], "small_room", 3.0),    # 1 bar
                   (specs[1], "arena", 0.9), (specs[1], "small_room", 3.0),    # 2 bars
                   (specs[2], "arena", 1.2), (specs[2], "small_room", 4.5),    # 0 bars
                   (specs[3], "arena", 0.5), (specs[3], "small_room", 3.9))    # 2 bars
    ranked = ranking(bar_table(table, "R", TWO)).rename(columns={"policy": "spec"})
    ranked["run"] = [run_of(s) for s in ranked["spec"]]
    assert per_run(ranked) == {"a/seed_1": specs[3], "a/seed_0": specs[1]}


def test_a_metric_no_episode_has_meets_no_bar():
    table = _table(("R", "arena", 2.0), ("A", "arena", 0.5))
    bars = bar_table(table, "R", (Bar("arena", "parked_speed", absolute=0.05),))
    assert np.isnan(bars["value"].iloc[0]) and not bars["met"].iloc[0]


def test_bar_table_refuses_a_missing_reference_or_case():
    table = _table(("R", "arena", 2.0), ("A", "arena", 0.5))
    with pytest.raises(ValueError, match="reference 'X'"):
        bar_table(table, "X", TWO[:1])
    with pytest.raises(ValueError, match="small_room"):
        bar_table(table, "R", TWO)


def test_the_bars_are_issue_26s():
    by_case = {b.case: b for b in BARS}
    assert by_case["arena"].text == "total <= 0.5x reference"
    for scene in ("small_room", "doorway", "corridor", "pillars"):
        assert by_case[scene].text == "total < reference"
    assert by_case["61 robots"].text == "V_coh <= reference + 0.2"
    assert by_case["standing 40 s"].text == "parked_speed <= 0.05"
    assert by_case["61 robots"].limit(5.3) == pytest.approx(5.5)


def test_validation_holds_trained_cases_only_on_other_seeds():
    from boids_env.train.config import TrainConfig, resolve_recipe

    names = {c.name for c in VALIDATION.cases}
    assert names == {b.case for b in BARS}
    unseen = {c.name for c in DEPLOYMENT.cases if c.group == "unseen"} | {"lab"}
    assert not names & unseen
    assert not set(VALIDATION.seeds) & set(SCENES.seeds)
    # every case is a world and draw the recipe trains on (the small room: the 5 m arena
    # copies, walls at 2.5 m and the square at 2 m, the same geometry)
    recipe = TrainConfig.from_toml(resolve_recipe("ppo_scenes_stage6"))
    scenes = {w.get("scene", "arena") for w in recipe.worlds}
    if {"arena_half_size": 2.5, "path_size": 2.0} in recipe.worlds:
        scenes.add("small_room")
    pauses = {tuple(map(tuple, p)) for p in recipe.leader_pauses}
    for case in VALIDATION.cases:
        assert case.env.get("scene", "arena") in scenes, case.name
        assert case.env.get("robots", 13) in recipe.group_sizes, case.name
        assert tuple(case.env.get("leader_pauses", ())) in pauses, case.name


def test_final_leader_distance_max_is_the_last_samples_farthest_follower():
    result = run_episode(parallel_env(robots=7, max_cycles=40), ReynoldsPolicy(), seed=3)
    last = result.recording.positions[-1]
    want = max(np.hypot(*(p - last[0])) for p in last[1:])
    assert result.metrics["final_leader_distance_max"] == pytest.approx(want, rel=1e-12)


SHORT = {"robots": 7, "max_cycles": 60}


def test_select_runs_the_suite_and_writes_its_choice(tmp_path):
    suite = Suite("tiny", (Case("arena", "trained", "case", "arena", SHORT),
                           Case("small_room", "trained", "case", "small_room",
                                {**SHORT, "scene": "small_room"})), seeds=(100,))
    ranked = select(["learned-scenes", "random"], tmp_path, suite=suite, bars=TWO,
                    progress=False, workers=1)
    assert set(ranked["policy"]) == {"learned-scenes", "random"}
    results = pd.read_parquet(tmp_path / "results.parquet")
    bars = pd.read_csv(tmp_path / "bars.csv")
    for row in bars.itertuples():
        mine = results[(results.policy == row.policy) & (results.case == row.case)]
        ref = results[(results.policy == "reynolds[paper]") & (results.case == row.case)]
        total = float((mine.V_sep + mine.V_coh + mine.V_align).mean())
        assert row.value == pytest.approx(total)
        factor = 0.5 if row.case == "arena" else 1.0
        assert row.limit == pytest.approx(factor * float((ref.V_sep + ref.V_coh
                                                          + ref.V_align).mean()))
    choice = json.loads((tmp_path / "selection.json").read_text())
    assert choice["chosen"] == ranked["spec"].iloc[0]
    assert choice["chosen_per_run"] == {p: p for p in ranked["spec"]}  # names: runs of one
    assert [b["case"] for b in choice["bars"]] == ["arena", "small_room"]


def test_select_refuses_bad_input_before_writing(tmp_path, capsys):
    out = tmp_path / "sel"
    assert main(["select", "reynolds", "--out", str(out)]) == 2
    assert "reference 'reynolds' is also a candidate" in capsys.readouterr().err
    assert main(["select", "learned", "--seeds", "-1", "--out", str(out)]) == 2
    assert "seeds must be" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["select", "learned", "--order", "margin", "--out", str(out)])
    err = capsys.readouterr().err
    assert "argument --order: invalid choice: 'margin'" in err
    assert all(order in err for order in ORDERS)
    assert not out.exists()


def test_a_training_folder_stands_for_its_checkpoints_and_final_model(tmp_path):
    from boids_env.eval.select import expand

    for seed in (0, 1):
        run = tmp_path / f"seed_{seed}"
        (run / "checkpoints").mkdir(parents=True)
        for steps in (1_000_000, 250_000, 500_000):
            (run / "checkpoints" / f"model_{steps}_steps.zip").write_bytes(b"zip")
        (run / "model.zip").write_bytes(b"zip")
        (run / "tb").mkdir()
    (tmp_path / "seed_1" / "checkpoints" / "linked.zip").symlink_to(tmp_path / "seed_0" /
                                                                    "model.zip")
    one = [f"{tmp_path}/seed_0/checkpoints/model_{n}_steps.zip"
           for n in (250_000, 500_000, 1_000_000)] + [f"{tmp_path}/seed_0/model.zip"]
    assert expand([str(tmp_path / "seed_0")]) == one
    both = expand([str(tmp_path), "learned-scenes"])
    assert both[:4] == one and both[-1] == "learned-scenes" and len(both) == 9
    assert not any("linked" in p for p in both)  # a link may point outside the folder
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no training run"):
        expand([str(tmp_path / "empty")])


def test_a_crashed_case_counts_as_a_missed_bar():
    # issue 39 item 5: a candidate whose episodes crashed in a case dropped that case out of
    # its bars (met 1 of 1) and won over one that ran every case (met 1 of 2)
    table = _table(("R", "arena", 2.0), ("R", "arena", 2.0), ("R", "small_room", 4.0),
                   ("R", "small_room", 4.0),
                   ("A", "arena", 0.9), ("A", "arena", 0.9),             # met
                   ("A", "small_room", 4.5), ("A", "small_room", 4.5),   # missed, ran
                   ("B", "arena", 0.2), ("B", "arena", 0.2),             # met; small_room crashed
                   ("C", "arena", 0.2),                                  # 1 of 2 episodes ran
                   ("C", "small_room", 1.0), ("C", "small_room", 1.0))   # met
    bars = bar_table(table, "R", TWO, candidates=["A", "B", "C", "D"])
    got = {(r.policy, r.case): (r.met, r.episodes) for r in bars.itertuples()}
    assert got[("B", "small_room")] == (False, 0), "a crashed case is a missed bar"
    assert got[("C", "arena")] == (False, 1), "a case with crashed episodes is missed"
    assert got[("C", "small_room")] == (True, 2)
    assert got[("D", "arena")] == (False, 0) and got[("D", "small_room")] == (False, 0)
    ranked = ranking(bars).set_index("policy")
    assert ranked["bars"].to_dict() == {"A": 2, "B": 2, "C": 2, "D": 2}
    assert ranked["met"].to_dict() == {"A": 1, "B": 1, "C": 1, "D": 0}
    assert ranked.loc["B", "missed"] == "small_room" and ranked.loc["C", "missed"] == "arena"
    # A ran everything: it comes before the candidates whose episodes crashed
    assert list(ranking(bars)["policy"]) == ["A", "B", "C", "D"]
    assert ranking(bars, "headroom")["policy"].iloc[0] == "A"
    # without the candidates named, the reference's episode count is the one expected
    assert not bar_table(table, "R", TWO).set_index(["policy", "case"]).loc[
        ("C", "arena"), "met"]


def test_select_never_prefers_a_candidate_whose_episodes_crashed(tmp_path):
    # the faulty policy crashes in every episode of seed 1: it has no bar it could meet
    suite = Suite("tiny", (Case("arena", "trained", "case", "arena", SHORT),
                           Case("small_room", "trained", "case", "small_room",
                                {**SHORT, "scene": "small_room"})), seeds=(1,))
    ranked = select(["random", "faulty_policies:RaisesBaseException"], tmp_path, suite=suite,
                    bars=TWO, progress=False, workers=1)
    faulty = ranked.set_index("policy").loc["faulty_policies:RaisesBaseException"]
    assert faulty["bars"] == 2 and faulty["met"] == 0, faulty.to_dict()
    assert faulty["missed"] == "arena, small_room"
    assert ranked["policy"].iloc[-1] == "faulty_policies:RaisesBaseException"
