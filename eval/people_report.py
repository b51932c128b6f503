"""The report's person section: proxemics per case and the trade-offs the factors show.

Used by :func:`boids_env.eval.report.build_report` when the episodes had a person leading or
a crowd (their proxemics columns are in the results table).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import pandas as pd

from boids_env.eval.stats import ALPHA, group_values, one_way
from boids_env.proxemics import CROWD_KEYS, PERSON_KEYS

PERSON_CSV = "proxemics.csv"
TRADE_OFF_CSV = "person_trade_offs.csv"
TRADE_OFF_METRICS = (("V_coh", "cohesion violation V_coh"),
                     ("V_sep", "separation violation V_sep"),
                     ("personal_space_fraction", "time within 1.2 m of the person"),
                     ("person_contacts", "robot-person contacts"),
                     ("cut_in_fraction", "time in the person's path"),
                     ("pedestrian_contacts", "robot-pedestrian contacts"),
                     ("pedestrian_personal_fraction", "time within 1.2 m of a pedestrian"))
"""What the trade-off statements are about: (results column, words)."""


def has_people(table: pd.DataFrame) -> bool:
    """Whether the results carry the proxemics (a person led or a crowd walked)."""
    return "intimate_fraction" in table or "pedestrian_contacts" in table


def with_personal_space(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` with ``personal_space_fraction``: time within 1.2 m of the person
    (intimate + personal zones)."""
    if "intimate_fraction" not in table:
        return table
    out = table.copy()
    out["personal_space_fraction"] = out["intimate_fraction"] + out["personal_fraction"]
    return out


def trade_offs(table: pd.DataFrame) -> pd.DataFrame:
    """Per policy, factor group and metric: the means at the group's lowest and highest
    level (in the suite's order), the change, and the robust one-way test across all
    levels (ANOVA, Welch or Kruskal-Wallis as :func:`~boids_env.eval.stats.one_way` picks)."""
    table = with_personal_space(table)
    out = []
    for (policy, group), rows in table.groupby(["policy", "group"], sort=False):
        for metric, words in TRADE_OFF_METRICS:
            if metric not in rows:
                continue
            g = rows[rows[metric].notna()]  # a crowd metric has no value without a crowd
            levels = list(dict.fromkeys(g["level"]))
            if len(levels) < 2:
                continue
            try:
                test = one_way(group_values(g, metric))
            except ValueError:
                continue
            low = float(g[g["level"] == levels[0]][metric].mean())
            high = float(g[g["level"] == levels[-1]][metric].mean())
            out.append({"policy": policy, "group": group, "factor": g["factor"].iloc[0],
                         "metric": metric, "words": words, "first_level": levels[0],
                         "last_level": levels[-1], "first_mean": low, "last_mean": high,
                         "test": test["robust_test"], "p": test["robust_p"],
                         "significant": bool(test["robust_p"] < ALPHA)})
    return pd.DataFrame(out)


def statement(row: pd.Series) -> str:
    """One trade-off in words."""
    a, b = row["first_mean"], row["last_mean"]
    if not row["significant"]:
        return (f"{row['words']}: {_n(a)} at {row['factor']} {row['first_level']}, {_n(b)} at "
                f"{row['last_level']}; no significant effect ({row['test']} p = "
                f"{_p(row['p'])})")
    trend = "rises" if b > a else "falls"
    return (f"{row['words']} {trend} from {_n(a)} at {row['factor']} {row['first_level']} to "
            f"{_n(b)} at {row['last_level']} ({row['test']} p = {_p(row['p'])})")


def _n(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:.3g}"


def _p(p: float) -> str:
    if math.isnan(p):
        return "n/a"
    return f"{p:.2g}" if p >= 1e-4 else "< 1e-4"


def person_section(table: pd.DataFrame, summary_table: Callable[..., pd.DataFrame],
                   md_table: Callable[[pd.DataFrame], str], csvs: dict[str, pd.DataFrame],
                   summary: list[str]) -> list[str]:
    """The report's Markdown for the person and the crowd; adds its CSVs and summary lines.

    Args:
        table: the results table.
        summary_table: the report's mean ± std table builder, ``f(table, metrics)``.
        md_table: the report's Markdown table writer.
        csvs: the report's CSVs, by file name.
        summary: the report's summary lines.
    """
    keys = tuple(k for k in (*PERSON_KEYS, *CROWD_KEYS) if k in table)
    csvs[PERSON_CSV] = summary_table(table, keys)
    found = trade_offs(table)
    csvs[TRADE_OFF_CSV] = found
    md = ["## A person as the leader: proxemics per case", "",
          "Hall's zones around the person (time fractions, centre distances: intimate < 0.45 m, "
          "personal 0.45-1.2 m, social 1.2-3.6 m, public beyond), robot-person contacts "
          "(onsets), the closest robot-person centres (m), time a robot is in the person's "
          "path (the strip its body sweeps in the next 2 s) and, with a crowd, time within "
          "0.45 m / 1.2 m of a pedestrian and robot-pedestrian contacts. Mean ± population "
          "std over seeds.", "", md_table(csvs[PERSON_CSV]), ""]
    md += ["## A person as the leader: the trade-offs", "",
           f"For each factor, each metric from its first to its last level, with the robust "
           f"one-way test across all its levels (α = {ALPHA}).", ""]
    lines = []
    for (policy, group), g in found.groupby(["policy", "group"], sort=False) if len(found) \
            else []:
        md += [f"**{policy}, {group}**", ""]
        md += [f"- {statement(r)}" for _, r in g.iterrows()] + [""]
        lines += [f"- {policy}, {group}: {statement(r)}" for _, r in g.iterrows()
                  if r["significant"] and r["metric"] in ("V_coh", "personal_space_fraction",
                                                          "person_contacts")]
    if lines:
        summary += ["Person following, significant trade-offs:", "", *lines, ""]
    return md
