"""The study's statistics and what it lacked, as pure functions of numbers and labels.

- :func:`one_way`: one-way ANOVA (scipy ``f_oneway``, as the study) with eta², Levene's test,
  and the robust alternative the data call for: Welch's ANOVA when variances differ,
  Kruskal–Wallis when a group has zero variance.
- :func:`tukey`: Tukey HSD (statsmodels ``pairwise_tukeyhsd``, FWER 0.05, as the study);
  ``meandiff`` = mean(group2) − mean(group1), the study's convention.
- :func:`bootstrap_ci`, :func:`compare` (two policies on one case: difference, bootstrap CI,
  Welch t-test p) and :func:`holm` (Holm-corrected p values across cases).
- :func:`analyse`: all of it for a results table, per group (research question) and metric.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats

ALPHA = 0.05
V_METRICS = ("V_sep", "V_coh", "V_align")
COUNT_METRICS = ("count_sep", "count_coh", "count_align")


def _arrays(groups: Mapping[str, npt.ArrayLike]) -> dict[str, npt.NDArray[np.float64]]:
    out = {str(k): np.asarray(v, dtype=float).ravel() for k, v in groups.items()}
    if len(out) < 2 or any(len(v) < 2 for v in out.values()):
        raise ValueError("need at least 2 groups of at least 2 values each, got sizes "
                         f"{ {k: len(v) for k, v in out.items()} }")
    return out


def one_way(groups: Mapping[str, npt.ArrayLike]) -> dict[str, Any]:
    """One-way ANOVA across groups, with effect size and robust alternatives.

    Returns ``F``, ``p`` (the study's test), ``eta2`` (SS_between / SS_total), ``levene_p``,
    ``welch_F``/``welch_p``, ``kruskal_H``/``kruskal_p`` (NaN where undefined), and
    ``robust_test``/``robust_p``: the test to trust (``anova`` when variances look equal,
    ``welch`` when Levene rejects, ``kruskal`` when a group has zero variance, ``none`` when
    every value is the same).
    """
    g = _arrays(groups)
    values = np.concatenate(list(g.values()))
    grand = values.mean()
    ss_total = float(((values - grand) ** 2).sum())
    ss_between = float(sum(len(v) * (v.mean() - grand) ** 2 for v in g.values()))
    out: dict[str, Any] = {"k": len(g), "n": len(values),
                           "eta2": ss_between / ss_total if ss_total > 0 else float("nan")}
    if ss_total == 0:
        out.update(F=float("nan"), p=1.0, levene_p=float("nan"), welch_F=float("nan"),
                   welch_p=float("nan"), kruskal_H=float("nan"), kruskal_p=1.0,
                   robust_test="none", robust_p=1.0)
        return out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f, p = stats.f_oneway(*g.values())
        levene_p = float(stats.levene(*g.values()).pvalue)
        kruskal = stats.kruskal(*g.values())
    if ss_total - ss_between <= 1e-15 * ss_total:  # no variance within groups
        f, p = float("inf"), 0.0
    out.update(F=float(f), p=float(p), levene_p=levene_p,
               kruskal_H=float(kruskal.statistic), kruskal_p=float(kruskal.pvalue))
    zero_var = any(np.ptp(v) == 0 for v in g.values())
    if zero_var:
        out.update(welch_F=float("nan"), welch_p=float("nan"), robust_test="kruskal",
                   robust_p=out["kruskal_p"])
        return out
    from statsmodels.stats.oneway import anova_oneway

    labels = np.concatenate([[k] * len(v) for k, v in g.items()])
    welch = anova_oneway(values, labels, use_var="unequal")
    out.update(welch_F=float(welch.statistic), welch_p=float(welch.pvalue))
    if np.isfinite(levene_p) and levene_p < ALPHA:
        out.update(robust_test="welch", robust_p=out["welch_p"])
    else:
        out.update(robust_test="anova", robust_p=out["p"])
    return out


def tukey(values: npt.ArrayLike, labels: Sequence[str], alpha: float = ALPHA) -> pd.DataFrame:
    """Tukey HSD over all pairs of groups: columns ``group1``, ``group2``, ``meandiff``
    (mean(group2) − mean(group1)), ``p_adj``, ``lower``, ``upper``, ``reject``.

    With zero variance inside every group, differences are exact: ``reject`` is whether the
    means differ (p 0 or 1)."""
    from statsmodels.stats.multicomp import pairwise_tukeyhsd

    y = np.asarray(values, dtype=float).ravel()
    lab = np.asarray([str(v) for v in labels])
    if len(y) != len(lab):
        raise ValueError(f"values ({len(y)}) and labels ({len(lab)}) differ in length")
    _arrays({k: y[lab == k] for k in dict.fromkeys(lab)})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pairwise_tukeyhsd(y, lab, alpha=alpha)
    names = res.groupsunique
    rows = []
    k = 0
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            diff = float(res.meandiffs[k])
            p = float(res.pvalues[k])
            reject = bool(res.reject[k])
            lower, upper = (float(x) for x in res.confint[k])
            if not np.isfinite(p):  # zero pooled variance
                p = 0.0 if diff != 0 else 1.0
                reject, lower, upper = diff != 0, diff, diff
            rows.append({"group1": str(names[i]), "group2": str(names[j]), "meandiff": diff,
                         "p_adj": p, "lower": lower, "upper": upper, "reject": reject})
            k += 1
    return pd.DataFrame(rows)


def pair_difference(table: pd.DataFrame, group1: str, group2: str) -> tuple[float, bool, float]:
    """(meandiff = mean(group2) − mean(group1), reject, p_adj) for a pair of a :func:`tukey`
    table in either order."""
    for _, row in table.iterrows():
        if (row.group1, row.group2) == (group1, group2):
            return float(row.meandiff), bool(row.reject), float(row.p_adj)
        if (row.group1, row.group2) == (group2, group1):
            return -float(row.meandiff), bool(row.reject), float(row.p_adj)
    raise KeyError(f"no pair {group1!r}, {group2!r} in the Tukey table")


def iqm(values: npt.ArrayLike) -> float:
    """Interquartile mean: the mean of the middle half of the values (25 % trimmed from each
    end, as rliable reports scores over training seeds; the plain mean below 4 values)."""
    v = np.asarray(values, dtype=float).ravel()
    if len(v) == 0:
        raise ValueError("iqm needs at least one value")
    return float(stats.trim_mean(v, 0.25))


def bootstrap_ci(values: npt.ArrayLike, level: float = 0.95, n_resamples: int = 9999,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean (scipy); exact for constant
    data."""
    v = np.asarray(values, dtype=float).ravel()
    if len(v) == 0:
        raise ValueError("bootstrap_ci needs at least one value")
    if np.ptp(v) == 0:
        return float(v[0]), float(v[0])
    res = stats.bootstrap((v,), np.mean, confidence_level=level, n_resamples=n_resamples,
                          method="percentile", rng=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def compare(a: npt.ArrayLike, b: npt.ArrayLike, level: float = 0.95, n_resamples: int = 9999,
            seed: int = 0) -> dict[str, float]:
    """Policy b against policy a on one case: ``diff`` = mean(b) − mean(a), its bootstrap CI
    (``ci_low``, ``ci_high``, resampling each side) and Welch's t-test ``p``."""
    x = np.asarray(a, dtype=float).ravel()
    y = np.asarray(b, dtype=float).ravel()
    if len(x) < 2 or len(y) < 2:
        raise ValueError("compare needs at least 2 values per policy")
    diff = float(y.mean() - x.mean())
    if np.ptp(x) == 0 and np.ptp(y) == 0:
        return {"diff": diff, "ci_low": diff, "ci_high": diff, "p": 0.0 if diff else 1.0}
    res = stats.bootstrap((x, y), lambda u, v, axis=-1: v.mean(axis) - u.mean(axis),
                          confidence_level=level, n_resamples=n_resamples, method="percentile",
                          rng=np.random.default_rng(seed), vectorized=True)
    p = float(stats.ttest_ind(y, x, equal_var=False).pvalue)
    return {"diff": diff, "ci_low": float(res.confidence_interval.low),
            "ci_high": float(res.confidence_interval.high), "p": p}


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm–Bonferroni adjusted p values (statsmodels ``multipletests``)."""
    from statsmodels.stats.multitest import multipletests

    if len(pvalues) == 0:
        return []
    return [float(p) for p in multipletests(list(pvalues), method="holm")[1]]


def group_values(table: pd.DataFrame, metric: str, followers: int | None = None
                 ) -> dict[str, npt.NDArray[np.float64]]:
    """Values of ``metric`` per level of a results table (rows of one group and policy),
    levels in table order. For ``count_*`` metrics the per-follower counts of followers
    1..``followers`` of every run are pooled (the study's RQ3)."""
    out: dict[str, list[float]] = {}
    for level, rows in table.groupby("level", sort=False):
        col = rows[metric]
        if metric.startswith("count_"):
            vals = [float(c) for counts in col for c in list(counts)[:followers]]
        else:
            vals = [float(v) for v in col]
        out[str(level)] = vals
    return {k: np.asarray(v) for k, v in out.items()}


def analyse(table: pd.DataFrame, per_follower: Sequence[str] = (), followers: int = 6,
            unwrapped: bool = False) -> tuple[pd.DataFrame, pd.DataFrame]:
    """ANOVA and Tukey per policy, group and metric of a results table.

    Groups in ``per_follower`` are analysed on the per-follower counts of followers
    1..``followers``; the others on V_*. ``unwrapped`` uses the study's unwrapped alignment
    rule (``V_align_unwrapped``/``count_align_unwrapped``) in place of the wrapped one.

    Returns (anova table, tukey table); the metric column holds the study's names.
    """
    anova_rows, tukey_rows = [], []
    for (policy, group), rows in table.groupby(["policy", "group"], sort=False):
        if rows["level"].nunique() < 2:
            continue
        metrics = COUNT_METRICS if group in per_follower else V_METRICS
        for metric in metrics:
            column = metric + ("_unwrapped" if unwrapped and metric.endswith("align") else "")
            groups = group_values(rows, column, followers)
            try:
                res = one_way(groups)
                tk = tukey(np.concatenate(list(groups.values())),
                           [k for k, v in groups.items() for _ in v])
            except ValueError:
                continue  # fewer than 2 values per level
            means = {k: float(v.mean()) for k, v in groups.items()}
            anova_rows.append({"policy": policy, "group": group, "metric": metric,
                               "factor": rows["factor"].iloc[0], **res,
                               "means": means})
            for _, t in tk.iterrows():
                tukey_rows.append({"policy": policy, "group": group, "metric": metric,
                                   **t.to_dict()})
    return pd.DataFrame(anova_rows), pd.DataFrame(tukey_rows)
