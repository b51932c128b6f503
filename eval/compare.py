"""Policies against the baseline (the first policy), case by case: the study's violation
metrics and safety, each difference with its 95 % bootstrap CI and a Welch t-test, Holm-
corrected over every row, and the verdicts they support.

A row's verdict is ``lower`` or ``higher`` when its Holm-corrected p is below 0.05 and its
CI excludes zero, else ``no significant difference``. Per case and policy:

- a V_* verdict: ``better`` (lower violation), ``worse`` or ``no significant difference``;
- the **safety verdict** from touching time, contact onsets and wall time (lower is safer):
  ``less safe`` when any of them is significantly higher, ``safer`` when at least one is
  significantly lower and none higher, ``as safe`` (no significant difference) otherwise.
"""

from __future__ import annotations

import pandas as pd

from boids_env.eval.stats import ALPHA, V_METRICS, compare, holm

SAFETY_COMPARED = ("touching_fraction", "contacts", "wall_fraction")
"""The safety metrics of the safety verdict (``contacts``: follower–follower plus
leader–follower contact onsets per episode)."""
NO_DIFFERENCE = "no significant difference"


def with_contacts(table: pd.DataFrame) -> pd.DataFrame:
    """The table with ``contacts`` = ``contacts_follower`` + ``contacts_leader``."""
    if "contacts" in table or "contacts_follower" not in table:
        return table
    return table.assign(contacts=table["contacts_follower"] + table["contacts_leader"])


def policy_comparison(table: pd.DataFrame, metrics: tuple[str, ...] = V_METRICS,
                      safety: tuple[str, ...] = SAFETY_COMPARED) -> pd.DataFrame:
    """Every other policy against the first, per case and metric (``metrics``, their
    ``total``, and the ``safety`` metrics the table has).

    Columns: ``case``, ``metric``, ``kind`` (``study`` or ``safety``), ``baseline``,
    ``policy``, ``baseline_mean``, ``policy_mean``, ``diff`` (policy − baseline),
    ``ci_low``/``ci_high`` (95 % percentile bootstrap), ``p`` (Welch), ``p_holm`` (Holm over
    all rows), ``direction`` (``lower``, ``higher`` or no significant difference).
    """
    table = with_contacts(table)
    policies = list(dict.fromkeys(table["policy"]))
    compared = [(m, "study") for m in (*metrics, "total")]
    compared += [(m, "safety") for m in safety if m in table]
    rows = []
    for other in policies[1:]:
        for case in dict.fromkeys(table["case"]):
            a = table[(table.policy == policies[0]) & (table.case == case)]
            b = table[(table.policy == other) & (table.case == case)]
            if len(a) < 2 or len(b) < 2:
                continue
            for metric, kind in compared:
                av = a[list(metrics)].sum(axis=1) if metric == "total" else a[metric]
                bv = b[list(metrics)].sum(axis=1) if metric == "total" else b[metric]
                rows.append({"case": case, "metric": metric, "kind": kind,
                             "baseline": policies[0], "policy": other,
                             "baseline_mean": float(av.mean()),
                             "policy_mean": float(bv.mean()), **compare(av, bv)})
    out = pd.DataFrame(rows)
    if len(out):
        out["p_holm"] = holm(out["p"].tolist())
        out["direction"] = [_direction(r) for r in out.itertuples()]
    return out


def _direction(row: object) -> str:
    p, low, high, diff = (getattr(row, k) for k in ("p_holm", "ci_low", "ci_high", "diff"))
    if p < ALPHA and (low > 0 or high < 0):
        return "lower" if diff < 0 else "higher"
    return NO_DIFFERENCE


def verdicts(comparison: pd.DataFrame) -> pd.DataFrame:
    """One row per (case, policy): a verdict per V_* metric and total (``better``,
    ``worse``, or no significant difference) and the ``safety`` verdict with its reason."""
    rows = []
    if comparison.empty:
        return pd.DataFrame(rows)
    for (case, policy), g in comparison.groupby(["case", "policy"], sort=False):
        row: dict[str, str] = {"case": str(case), "policy": str(policy),
                               "baseline": str(g["baseline"].iloc[0])}
        for r in g[g.kind == "study"].itertuples():
            row[str(r.metric)] = {"lower": "better", "higher": "worse"}.get(r.direction,
                                                                           NO_DIFFERENCE)
        safety = g[g.kind == "safety"]
        higher = safety[safety.direction == "higher"]
        lower = safety[safety.direction == "lower"]
        if len(higher):
            verdict = "less safe"
            why = ", ".join(f"{m} higher" for m in higher.metric)
        elif len(lower):
            verdict = "safer"
            why = ", ".join(f"{m} lower" for m in lower.metric)
        else:
            verdict, why = "as safe", NO_DIFFERENCE
        row["safety"] = verdict
        row["safety_because"] = why
        rows.append(row)
    return pd.DataFrame(rows)
