"""The robot_types suite: the study's experiment for every robot preset, and the report that
says finding by finding which of the study's findings hold for which robot."""

import json

import numpy as np
import pandas as pd

from boids_env.config import EnvConfig
from boids_env.eval.report import build_report
from boids_env.eval.robot_types import family_table, finding_matrix, robots_in
from boids_env.eval.stats import analyse
from boids_env.eval.suites import PAPER, ROBOT_TYPES, load_suite

# the study's means (its Table V) per level, for a robot that behaves as its Spheros
STUDY_LIKE = {"rq1": {"V_sep": (7.0, 0.16, 0.0), "V_coh": (0.13, 0.3, 2.35),
                      "V_align_unwrapped": (2.46, 2.19, 2.82)},
              "rq3": {"count_sep": (47, 9, 12), "count_coh": (0, 20, 55),
                      "count_align_unwrapped": (118, 137, 153)}}


def test_the_suite_is_the_study_table_iii_for_every_robot_scaled_to_it():
    assert load_suite("robot_types") is ROBOT_TYPES
    robots = ["sphero", "sphero_sprk", "turtlebot3_burger", "gritsbot"]
    assert robots_in(pd.DataFrame({"group": [c.group for c in ROBOT_TYPES.cases]})) == robots
    speeds = {c.env["robot"]: [] for c in ROBOT_TYPES.cases}
    for c in ROBOT_TYPES.cases:
        if c.group.startswith("rq1@"):
            speeds[c.env["robot"]].append(c.env["leader_speed"])
    assert speeds["sphero"] == [0.5, 0.55, 0.6]
    assert speeds["turtlebot3_burger"] == [0.22, 0.242, 0.264]
    assert speeds["gritsbot"] == [0.2, 0.22, 0.24]
    # the Sphero's cases are the paper suite's configurations, exactly
    ours = {EnvConfig().replace(**c.env) for c in ROBOT_TYPES.cases if c.env["robot"] == "sphero"}
    paper = {EnvConfig().replace(**c.env) for c in PAPER.cases}
    assert ours == paper
    assert set(ROBOT_TYPES.per_follower) == {f"rq3@{r}" for r in robots}


def _table(rng):
    rows = []
    for case in ROBOT_TYPES.cases:
        robot = case.env["robot"]
        rq = case.group.split("@")[0]
        index = {"1.0x": 0, "1.1x": 1, "1.2x": 2, "7": 0, "13": 1, "19": 2}.get(case.level, 1)
        study_like = robot == "sphero"
        n = int(case.env.get("robots", 13)) - 1
        for seed in range(5):
            row = {"policy": "reynolds", "case": case.name, "group": case.group,
                   "factor": case.factor, "level": case.level, "seed": seed}
            for metric in ("V_sep", "V_coh", "V_align_unwrapped"):
                mean = STUDY_LIKE["rq1"][metric][index if rq == "rq1" else 1]
                if not study_like:
                    mean = 1.0  # nothing depends on the factor
                row[metric] = abs(rng.normal(mean, 0.05))
            row["V_align"] = row["V_align_unwrapped"]
            for metric in ("count_sep", "count_coh", "count_align_unwrapped"):
                mean = STUDY_LIKE["rq3"][metric][index if rq == "rq3" else 1]
                if not study_like:
                    mean = 30
                row[metric] = [int(max(0, v)) for v in rng.normal(mean, 3, n)]
            row["count_align"] = row["count_align_unwrapped"]
            row.update(touching_fraction=0.0 if study_like else 0.8, mean_nn_distance=0.3,
                       V_align_heading=np.nan if study_like else 1.0)
            rows.append(row)
    return pd.DataFrame(rows)


def test_findings_are_judged_per_robot_as_the_paper_suite_judges_them():
    table = _table(np.random.default_rng(0))
    _, tukey = analyse(table, ROBOT_TYPES.per_follower, unwrapped=True)
    robots = robots_in(table)
    matrix = finding_matrix(tukey, "reynolds", robots)
    assert len(matrix) == 27 and list(matrix.columns[4:]) == robots
    families = family_table(matrix, robots).set_index("finding (study)")
    trade = families.index[0]
    assert families.loc[trade, "sphero"] == "holds"
    assert families.loc[trade, "turtlebot3_burger"] == "0 of 4", "no trade-off without it"
    weight = families.index[2]
    assert families.loc[weight, "turtlebot3_burger"] == "holds", "nothing varies: nulls hold"
    crowd = families.index[3]
    assert families.loc[crowd, "sphero"] == "holds"


def test_the_report_has_a_section_per_robot(tmp_path):
    shown = ("sphero", "turtlebot3_burger")  # two robots keep the figures few
    cases = [c for c in ROBOT_TYPES.cases if c.env["robot"] in shown]
    table = _table(np.random.default_rng(1))
    table = table[table.case.isin({c.name for c in cases})]
    table.to_parquet(tmp_path / "results.parquet", index=False)
    suite = {"name": "robot_types", "seeds": list(range(5)),
             "per_follower": [f"rq3@{r}" for r in shown], "followers_analysed": 6,
             "policies": [{"spec": "reynolds", "preset": "paper", "label": "reynolds"}],
             "cases": [{"name": c.name, "group": c.group, "factor": c.factor,
                        "level": c.level, "env": c.env, "policy": c.policy} for c in cases]}
    (tmp_path / "suite.json").write_text(json.dumps(suite))
    text = build_report(tmp_path).read_text()
    assert "## The study's findings per robot type" in text
    assert "leader-speed trade-off" in text
    section = text.split("## The study's findings per robot type")[1]
    assert "| holds" in section and "0 of 4" in section
    for robot in shown:
        assert robot in section
    findings = pd.read_csv(tmp_path / "robot_findings_reynolds.csv")
    assert set(findings["sphero"]) <= {"reproduced", "not reproduced"}


def test_the_turtlebot_generalisation_suite_is_turtlebots_with_five_unseen_cases():
    from boids_env.eval.suites import TURTLEBOT_GENERALISATION

    suite = load_suite("turtlebot_generalisation")
    assert suite is TURTLEBOT_GENERALISATION
    configs = [EnvConfig().replace(**c.env) for c in suite.cases]
    assert all(cfg.world.robot == "turtlebot3_burger" and cfg.world.drive == "unicycle"
               for cfg in configs)
    assert [c.group for c in suite.cases].count("unseen") == 5
    speeds = {c.name: cfg.scenario.leader_speed for c, cfg in zip(suite.cases, configs,
                                                                  strict=True)}
    assert speeds["default"] == 0.242 and speeds["leader 0.18"] == 0.18
