"""The study's published data (``eval/data``, copied from the study) and the verdicts that put
our results beside it, finding by finding.

A finding is one pair of levels of one metric in the study's Tukey tables: the study either
found a significant difference (with a direction) or none. We reproduce it when our Tukey
test on the same pair agrees: significant in the same direction, or not significant.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from boids_env.eval.stats import pair_difference

DATA = resources.files("boids_env.eval") / "data"
GROUP_OF_RQ = {1: "rq1", 2: "rq2", 3: "rq3"}


def _read(name: str) -> pd.DataFrame:
    with resources.as_file(DATA / name) as path:
        return pd.read_csv(Path(path), dtype={"level": str, "group1": str, "group2": str})


def study_runs() -> pd.DataFrame:
    """Every run the study reported: ``rq, factor, level, run, follower, metric, value``."""
    return _read("study_runs.csv")


def study_tukey() -> pd.DataFrame:
    """The study's Tukey tables: ``rq, metric, group1, group2, meandiff, p_adj_published,
    reject`` (meandiff = mean(group2) − mean(group1))."""
    table = _read("study_tukey.csv")
    table["reject"] = table["reject"].astype(bool)
    return table


def study_groups(rq: int, metric: str, followers: int = 6) -> dict[str, np.ndarray]:
    """The study's values per level for one research question and metric (RQ3: the counts of
    followers 1..``followers`` of every run, pooled as the study did)."""
    runs = study_runs()
    rows = runs[(runs.rq == rq) & (runs.metric == metric)]
    if rq == 3:
        rows = rows[rows.follower.astype(float) <= followers]
    return {str(level): g["value"].to_numpy(float)
            for level, g in rows.groupby("level", sort=False)}


def study_summary() -> pd.DataFrame:
    """Mean and population std (ddof=0, as the study reports them) per rq, level and metric."""
    runs = study_runs()
    runs = runs[(runs.rq != 3) | (runs.follower.astype(float) <= 6)]
    agg = runs.groupby(["rq", "level", "metric"], sort=False)["value"]
    return agg.agg(mean="mean", std=lambda v: float(np.std(v, ddof=0))).reset_index()


def verdicts(tukey_table: pd.DataFrame, policy: str) -> pd.DataFrame:
    """Each of the study's Tukey findings beside ours for ``policy`` (from
    :func:`eval.stats.analyse` with ``unwrapped=True``, the study's alignment rule).

    Columns: ``rq``, ``metric``, ``pair``, ``study`` and ``ours`` (a short statement),
    ``study_meandiff``, ``our_meandiff``, ``our_p``, ``verdict`` (reproduced, not
    reproduced, or not run)."""
    rows: list[dict[str, Any]] = []
    for _, s in study_tukey().iterrows():
        group = GROUP_OF_RQ[int(s.rq)]
        ours = tukey_table[(tukey_table.policy == policy) & (tukey_table.group == group)
                           & (tukey_table.metric == s.metric)] if len(tukey_table) else None
        row = {"rq": int(s.rq), "metric": s.metric, "pair": f"{s.group1} vs {s.group2}",
               "study": statement(s.meandiff, s.reject, s.group1, s.group2),
               "study_meandiff": float(s.meandiff)}
        try:
            if ours is None or ours.empty:
                raise KeyError
            diff, reject, p = pair_difference(ours, s.group1, s.group2)
        except KeyError:
            rows.append({**row, "ours": "—", "our_meandiff": np.nan, "our_p": np.nan,
                         "verdict": "not run"})
            continue
        same = reject == bool(s.reject) and (not reject or np.sign(diff) == np.sign(s.meandiff))
        rows.append({**row, "ours": statement(diff, reject, s.group1, s.group2),
                     "our_meandiff": diff, "our_p": p,
                     "verdict": "reproduced" if same else "not reproduced"})
    return pd.DataFrame(rows)


def statement(diff: float, reject: bool, g1: str, g2: str, p: float | None = None) -> str:
    """A Tukey finding in words: which group is higher and by how much (``diff`` is
    mean(``g2``) − mean(``g1``)), or no significant difference; with ``p`` (the adjusted
    p-value) the p-value, otherwise only whether the difference is significant."""
    if p is None:
        detail, tag = f"{diff:+.3g}", "significant"
    else:
        tag = "p < 0.001" if p < 0.001 else f"p = {p:.3f}"
        detail = f"Δ {signed(diff)}, {tag}"
    if not reject:
        return f"no significant difference ({detail})"
    higher = g2 if diff > 0 else g1
    return f"higher at {higher} by {abs(diff):.3g} ({tag})"


def signed(value: float) -> str:
    """A difference to 3 significant digits with its sign; 0 for (almost) nothing, never
    ``-0``."""
    return "0" if abs(value) < 5e-13 else f"{value:+.3g}"


def magnitudes(table: pd.DataFrame, policy: str) -> pd.DataFrame:
    """Our mean beside the study's for each RQ1/RQ2 level and V_* metric (18 means; the
    study's unwrapped alignment rule), and whether they agree within a factor of 2 (two means
    both below 0.01 agree too: the study's 0.000 ± 0.000 cannot be matched by a ratio)."""
    summary = study_summary()
    rows = []
    for rq in (1, 2):
        ours = table[(table.policy == policy) & (table.group == GROUP_OF_RQ[rq])]
        for level, g in ours.groupby("level", sort=False):
            for metric in ("V_sep", "V_coh", "V_align"):
                s = summary[(summary.rq == rq) & (summary.level == level)
                            & (summary.metric == metric)]
                if s.empty:
                    continue
                col = "V_align_unwrapped" if metric == "V_align" else metric
                mine, theirs = float(g[col].mean()), float(s["mean"].iloc[0])
                low, high = sorted((mine, theirs))
                rows.append({"rq": rq, "level": level, "metric": metric, "study": theirs,
                             "ours": mine,
                             "within_2x": bool(high < 0.01 or (low > 0 and high <= 2 * low))})
    return pd.DataFrame(rows)


def block_scores(table: pd.DataFrame, policy: str, per_follower: tuple[str, ...] = ("rq3",),
                 block_size: int = 5) -> pd.DataFrame:
    """The study's design repeated: the seeds of ``table`` cut into consecutive blocks of
    ``block_size`` (5, the study's runs per case), each scored on its own as one
    reproduction: findings reproduced (of 27), magnitudes within 2× (of 18), and whether
    the 19-robot cohesion finding (count_coh, 13 vs 19) is among them."""
    from boids_env.eval.stats import analyse

    seeds = sorted(table["seed"].unique())
    rows = []
    for b in range(len(seeds) // block_size):
        chosen = seeds[b * block_size:(b + 1) * block_size]
        part = table[table["seed"].isin(chosen) & (table.policy == policy)]
        _, tukey_table = analyse(part, per_follower, unwrapped=True)
        v = verdicts(tukey_table, policy)
        coh19 = v[(v.rq == 3) & (v.metric == "count_coh") & (v.pair.str.contains("19"))
                  & (v.pair.str.contains("13"))]
        m = magnitudes(part, policy)
        rows.append({"block": b + 1, "seeds": f"{chosen[0]}-{chosen[-1]}",
                     "findings": int((v.verdict == "reproduced").sum()), "of": len(v),
                     "magnitudes_within_2x": int(m.within_2x.sum()), "of_means": len(m),
                     "cohesion_19_vs_13": bool((coh19.verdict == "reproduced").all()
                                               and len(coh19))})
    return pd.DataFrame(rows)
