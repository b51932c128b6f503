"""The ``robot_types`` suite's report section: the study's findings, one by one, for every robot
type (the study's open question: "it would be nice to analyze effect of robot type").

Each robot's research questions are groups ``rq1@robot`` … of the results table (see
:func:`boids_env.eval.suites.robot_cases`); its leader speeds are labelled relative to its top
speed (``1.0x`` = the study's 0.5 m/s case, ``1.1x`` = 0.55, ``1.2x`` = 0.6). Every finding of
the study's Tukey tables is judged per robot exactly as the ``paper`` suite judges it
(:func:`boids_env.eval.study.verdicts`: reproduced when our Tukey test on the same pair agrees).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from boids_env.eval.study import verdicts

STUDY_LEVEL = {"1.0x": "0.5", "1.1x": "0.55", "1.2x": "0.6"}
"""The study's leader-speed labels of the relative levels (RQ1)."""
FAMILIES = (
    ("leader-speed trade-off: slow leader → crowding (V_sep), fast leader → lag (V_coh)",
     ((1, "V_sep", "0.55 vs 0.5"), (1, "V_sep", "0.5 vs 0.6"), (1, "V_coh", "0.5 vs 0.6"),
      (1, "V_coh", "0.55 vs 0.6"))),
    ("alignment differs with leader speed (all pairs)", ((1, "V_align", None),)),
    ("leader weight changes nothing (9 null results)", ((2, None, None),)),
    ("small groups crowd the leader (count_sep 7 vs 13 and 19)",
     ((3, "count_sep", "13 vs 7"), (3, "count_sep", "19 vs 7"))),
    ("large groups lag (count_coh 19 vs 13 and 7)",
     ((3, "count_coh", "13 vs 19"), (3, "count_coh", "19 vs 7"))),
    ("alignment differs with group size (all pairs)", ((3, "count_align", None),)),
    ("the study's other null results (V_sep 0.55 vs 0.6, V_coh 0.55 vs 0.5, count_sep 13 vs "
     "19, count_coh 13 vs 7)",
     ((1, "V_sep", "0.55 vs 0.6"), (1, "V_coh", "0.55 vs 0.5"), (3, "count_sep", "13 vs 19"),
      (3, "count_coh", "13 vs 7"))),
)
"""The study's headline findings as families of its Tukey pairs ((rq, metric, pair); None
matches every metric or pair of the research question)."""


def robots_in(table: pd.DataFrame) -> list[str]:
    """The robot presets of a ``robot_types`` results table, in suite order."""
    groups = [str(g) for g in dict.fromkeys(table["group"])]
    return list(dict.fromkeys(g.split("@", 1)[1] for g in groups if "@" in g))


def robot_verdicts(tukey_study: pd.DataFrame, policy: str, robot: str) -> pd.DataFrame:
    """The study's findings for one robot (the Tukey table of the unwrapped alignment rule,
    as :func:`boids_env.eval.study.verdicts` takes it): ``rq``, ``metric``, ``pair`` (the
    study's labels), ``study``, ``ours``, ``verdict``."""
    part = tukey_study[tukey_study["group"].astype(str).str.endswith(f"@{robot}")].copy() \
        if len(tukey_study) else tukey_study
    if len(part):
        part["group"] = part["group"].str.split("@").str[0]
        for col in ("group1", "group2"):
            part[col] = part[col].astype(str).map(lambda lv: STUDY_LEVEL.get(lv, lv))
    return verdicts(part, policy)


def finding_matrix(tukey_study: pd.DataFrame, policy: str, robots: list[str]) -> pd.DataFrame:
    """One row per finding of the study, one verdict column per robot."""
    out: pd.DataFrame | None = None
    for robot in robots:
        v = robot_verdicts(tukey_study, policy, robot)
        if out is None:
            out = v[["rq", "metric", "pair", "study"]].copy()
        out[robot] = v["verdict"].to_numpy()
    return out if out is not None else pd.DataFrame()


def family_table(matrix: pd.DataFrame, robots: list[str]) -> pd.DataFrame:
    """Each headline finding of :data:`FAMILIES` per robot: ``holds`` when all its pairs are
    reproduced, else how many are (``k of n``)."""
    rows = []
    for name, members in FAMILIES:
        mask = np.zeros(len(matrix), dtype=bool)
        for rq, metric, pair in members:
            hit = matrix["rq"] == rq
            if metric is not None:
                hit &= matrix["metric"] == metric
            if pair is not None:
                hit &= matrix["pair"] == pair
            mask |= hit.to_numpy()
        row: dict[str, Any] = {"finding (study)": name}
        for robot in robots:
            verdicts_ = matrix.loc[mask, robot]
            ran = verdicts_[verdicts_ != "not run"]
            good = int((ran == "reproduced").sum())
            row[robot] = ("not run" if not len(ran) else "holds" if good == len(ran)
                          else f"{good} of {len(ran)}")
        rows.append(row)
    return pd.DataFrame(rows)


def robot_summary(table: pd.DataFrame, policy: str, robots: list[str]) -> pd.DataFrame:
    """The study's case of every robot (13 robots, leader 1.1 × its top speed, weight 1.0):
    mean V_* (alignment: the study's unwrapped rule, and the commands' and the measured
    headings' under the rule the episodes ran with), and the safety the study does not
    measure."""
    rows = []
    for robot in robots:
        g = table[(table.policy == policy) & (table.group == f"rq1@{robot}")
                  & (table.level == "1.1x")]
        if g.empty:
            continue
        row: dict[str, Any] = {"robot": robot, "runs": len(g)}
        for col, name in (("V_sep", "V_sep"), ("V_coh", "V_coh"),
                          ("V_align_unwrapped", "V_align (study's unwrapped rule)"),
                          ("V_align", "V_align (commands, as run)"),
                          ("V_align_heading", "V_align (measured headings, as run)"),
                          ("touching_fraction", "touching"), ("mean_nn_distance", "nn (m)")):
            values = g[col].dropna() if col in g else pd.Series(dtype=float)
            row[name] = f"{values.mean():.3f}" if len(values) else "—"
        rows.append(row)
    return pd.DataFrame(rows)


def robot_sections(table: pd.DataFrame, tukey_study: pd.DataFrame, policies: list[str],
                   md_table: Any, csvs: dict[str, pd.DataFrame], summary: list[str]
                   ) -> list[str]:
    """The report's ``robot_types`` section (Markdown lines): per policy, the headline
    findings per robot, every finding per robot, and each robot's study case."""
    robots = robots_in(table)
    md = ["## The study's findings per robot type", "",
          "The study's experiment rerun for every robot preset, its leader speeds scaled to "
          "the robot's top speed (1.0 / 1.1 / 1.2 ×; the study's 0.5 / 0.55 / 0.6 m/s) and "
          "its start grid to the robot's size; the thresholds are the study's (0.7 m, 2.25 m, "
          "45°). Each of the study's Tukey findings is judged per robot as for the `paper` "
          "suite (*reproduced*: our Tukey test on the same pair agrees). Alignment: the "
          "study's unwrapped rule on the commands.", ""]
    from boids_env.eval.runner import unique_stems

    stems = unique_stems([(p,) for p in policies], "robot_findings_")
    for policy in policies:
        matrix = finding_matrix(tukey_study, policy, robots)
        if matrix.empty:
            continue
        families = family_table(matrix, robots)
        matrix.insert(0, "policy", policy)
        csvs[f"{stems[(policy,)]}.csv"] = matrix
        counts = {r: int((matrix[r] == "reproduced").sum()) for r in robots}
        summary.append(f"- **{policy}**, the study's findings per robot: "
                       + ", ".join(f"{r} {k} of {len(matrix)}" for r, k in counts.items())
                       + ".")
        md += [f"### {policy}: the study's headline findings per robot", "",
               md_table(families), "",
               f"#### {policy}: the study's case for every robot (means)", "",
               md_table(robot_summary(table, policy, robots)), "",
               f"#### {policy}: every finding per robot "
               f"({', '.join(f'{r} {k} of {len(matrix)}' for r, k in counts.items())})", "",
               md_table(matrix.drop(columns=["policy"])), ""]
    return md
