"""``boids report DIR``: statistics, figures and ``report.md`` / ``report.html`` from a folder
of saved results (``results.parquet`` + ``suite.json`` written by the runner); nothing is
rerun."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from boids_env.eval import figures
from boids_env.eval.stats import COUNT_METRICS, V_METRICS, analyse, compare, holm
from boids_env.eval.study import GROUP_OF_RQ, study_groups, study_summary, verdicts
from boids_env.recording import Recording

SUMMARY_METRICS = ("V_sep", "V_coh", "V_align", "V_align_unwrapped", "min_distance",
                   "collisions", "polarization", "mean_leader_distance")


def load_results(out: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The results table and suite description of an eval output folder."""
    out = Path(out)
    path = out / "results.parquet"
    if not path.is_file():
        raise FileNotFoundError(f"no results.parquet in {out}; run boids eval --out {out} "
                                f"first")
    try:
        table = pd.read_parquet(path)
        suite = json.loads((out / "suite.json").read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the results in {out}: {exc}") from exc
    if table.empty:
        raise ValueError(f"{path} holds no finished episodes")
    return table, suite


def _fmt(mean: float, std: float) -> str:
    return f"{mean:.3f} ± {std:.3f}"


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
    """Mean ± population std per policy and case of the main metrics."""
    rows = []
    for (policy, case), g in table.groupby(["policy", "case"], sort=False):
        row = {"policy": policy, "case": case, "runs": len(g)}
        for m in SUMMARY_METRICS:
            if m in g:
                row[m] = _fmt(float(g[m].mean()), float(g[m].std(ddof=0)))
        rows.append(row)
    return pd.DataFrame(rows)


def study_side_by_side(table: pd.DataFrame, policy: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The study's numbers beside ours: V_* (unwrapped alignment) for the RQ1 and RQ2 cases,
    and per-follower counts (followers 1–6) for RQ3."""
    summary = study_summary()
    rows = []
    for rq in (1, 2):
        group = GROUP_OF_RQ[rq]
        ours = table[(table.policy == policy) & (table.group == group)]
        for level, g in ours.groupby("level", sort=False):
            row: dict[str, Any] = {"case": f"{g.factor.iloc[0]} {level}"}
            for metric in V_METRICS:
                s = summary[(summary.rq == rq) & (summary.level == level)
                            & (summary.metric == metric)]
                col = "V_align_unwrapped" if metric == "V_align" else metric
                row[f"study {metric}"] = (_fmt(s["mean"].iloc[0], s["std"].iloc[0])
                                          if len(s) else "—")
                row[f"ours {metric}"] = _fmt(float(g[col].mean()), float(g[col].std(ddof=0)))
            rows.append(row)
    first, rows = pd.DataFrame(rows), []
    ours3 = table[(table.policy == policy) & (table.group == GROUP_OF_RQ[3])]
    for level, g in ours3.groupby("level", sort=False):
        row = {"case": f"robots {level} (per follower 1–6)"}
        for metric in COUNT_METRICS:
            study = study_groups(3, metric).get(level)
            col = metric + ("_unwrapped" if metric == "count_align" else "")
            vals = np.array([c for counts in g[col] for c in list(counts)[:6]], dtype=float)
            row[f"study {metric}"] = _fmt(study.mean(), study.std()) if study is not None \
                else "—"
            row[f"ours {metric}"] = _fmt(vals.mean(), vals.std())
        rows.append(row)
    return first, pd.DataFrame(rows)


def policy_comparison(table: pd.DataFrame, metrics: tuple[str, ...] = V_METRICS
                      ) -> pd.DataFrame:
    """Every other policy against the first, per case and metric: difference, 95 % bootstrap
    CI, Welch p, Holm-corrected over all rows."""
    policies = list(dict.fromkeys(table["policy"]))
    rows = []
    for other in policies[1:]:
        for case in dict.fromkeys(table["case"]):
            a = table[(table.policy == policies[0]) & (table.case == case)]
            b = table[(table.policy == other) & (table.case == case)]
            if len(a) < 2 or len(b) < 2:
                continue
            for metric in (*metrics, "total"):
                av = a[list(metrics)].sum(axis=1) if metric == "total" else a[metric]
                bv = b[list(metrics)].sum(axis=1) if metric == "total" else b[metric]
                rows.append({"case": case, "metric": metric, "baseline": policies[0],
                             "policy": other, "baseline_mean": float(av.mean()),
                             "policy_mean": float(bv.mean()), **compare(av, bv)})
    out = pd.DataFrame(rows)
    if len(out):
        out["p_holm"] = holm(out["p"].tolist())
    return out


def _md_table(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    return df.to_markdown(index=False, floatfmt=floatfmt) if len(df) else "(none)"


def build_report(out: str | Path) -> Path:
    """Writes ``report.md``, ``report.html``, ``stats_anova.csv``, ``stats_tukey.csv``,
    ``verdicts.csv`` (paper suite) and ``figures/`` into ``out``; returns the report path."""
    out = Path(out)
    table, suite = load_results(out)
    per_follower = tuple(suite.get("per_follower", ()))
    followers = int(suite.get("followers_analysed", 6))
    anova, tukey = analyse(table, per_follower, followers)
    _anova_study, tukey_study = analyse(table, per_follower, followers, unwrapped=True)
    anova.to_csv(out / "stats_anova.csv", index=False)
    tukey.to_csv(out / "stats_tukey.csv", index=False)
    fig_dir = out / "figures"
    md: list[str] = [f"# Evaluation report: suite `{suite['name']}`", "",
                     f"Policies: {', '.join(p['label'] for p in suite['policies'])}. "
                     f"Seeds: {suite['seeds']}. Episodes in the table: {len(table)} "
                     f"(cases that are the same configuration share their runs).", ""]
    md += failed_episodes(out)
    policies = list(dict.fromkeys(table["policy"]))
    is_paper = suite["name"] == "paper"
    if is_paper:
        md += ["## The study's findings, reproduced or not", "",
               "Each row is one pair of the study's Tukey HSD tables (FWER 0.05): reproduced "
               "when our Tukey test on the same pair agrees (significant in the same "
               "direction, or not significant). Alignment uses the study's unwrapped rule "
               "here.", ""]
        for policy in policies:
            v = verdicts(tukey_study, policy)
            v.insert(0, "policy", policy)
            v.to_csv(out / f"verdicts_{_slug(policy)}.csv", index=False)
            n_rep = int((v.verdict == "reproduced").sum())
            md += [f"### {policy}: {n_rep} of {len(v)} findings reproduced", "",
                   _md_table(v[["rq", "metric", "pair", "study", "ours", "verdict"]]), ""]
            v_table, count_table = study_side_by_side(table, policy)
            md += [f"#### {policy}: the study's numbers beside ours (mean ± population std)",
                   "", _md_table(v_table), "", _md_table(count_table), ""]
    md += ["## Results per case (mean ± population std)", "", _md_table(summary_table(table)),
           ""]
    md += ["## One-way ANOVA per group and metric", "",
           "`p` is the study's ANOVA; `robust_test`/`robust_p` the test the data call for "
           "(Welch when Levene rejects equal variances, Kruskal–Wallis when a level has zero "
           "variance). eta² = SS_between / SS_total.", ""]
    if len(anova):
        md += [_md_table(anova.drop(columns=["means"])[
            ["policy", "group", "metric", "F", "p", "eta2", "levene_p", "welch_p",
             "kruskal_p", "robust_test", "robust_p"]]), ""]
        md += ["## Tukey HSD (FWER 0.05; meandiff = mean(group2) − mean(group1))", "",
               _md_table(tukey[["policy", "group", "metric", "group1", "group2", "meandiff",
                                "p_adj", "reject"]]), ""]
    if len(policies) > 1:
        comp = policy_comparison(table)
        comp.to_csv(out / "policy_comparison.csv", index=False)
        md += ["## Policies compared per case", "",
               f"Difference = policy − {policies[0]}; 95 % bootstrap CI; Welch t-test p, "
               "Holm-corrected over all rows.", "", _md_table(comp), ""]
        md += ["![total](figures/policies_total.png)", ""]
        plot = table.assign(total=table[list(V_METRICS)].sum(axis=1))
        figures.policy_bars(plot, "total", fig_dir / "policies_total.png")
    md += ["## Figures", ""]
    md += _figures(table, suite, per_follower, followers, fig_dir, out, is_paper)
    report = out / "report.md"
    report.write_text("\n".join(md))
    _write_html(report, out / "report.html")
    return report


# Failed episodes: written by the reliability work (issue 14); one function and its one call.
def failed_episodes(out: Path) -> list[str]:
    """Markdown lines listing the episodes of the last ``boids eval`` run into ``out`` that
    failed (from ``errors.jsonl``: policy, cases, seed, reason and error), so a report never
    silently omits them; no lines when every episode finished."""
    from boids_env.eval.runner import failures

    rows = failures(out)
    if not rows:
        return []
    table = pd.DataFrame([{
        "policy": r.get("policy"), "cases": ", ".join(map(str, r.get("cases") or
                                                          [r.get("case")])),
        "seed": r.get("seed"), "reason": r.get("reason"),
        "error": str(r.get("error") or "-").splitlines()[0][:200].replace("|", "/")}
        for r in rows])
    return ["## Failed episodes", "",
            f"{len(rows)} episode(s) failed and are missing from every table and figure "
            f"below (details and tracebacks in `errors.jsonl`; rerunning the same "
            f"command retries them).", "", _md_table(table), ""]


def _figures(table: pd.DataFrame, suite: dict[str, Any], per_follower: tuple[str, ...],
             followers: int, fig_dir: Path, out: Path, is_paper: bool) -> list[str]:
    md: list[str] = []
    study_rq = {v: k for k, v in GROUP_OF_RQ.items()}
    for (policy, group), rows in table.groupby(["policy", "group"], sort=False):
        name = f"{_slug(policy)}_{group}"
        if group in per_follower:
            path = figures.follower_bars(rows, COUNT_METRICS, f"{policy}: {group}",
                                         fig_dir / f"{name}.png", followers)
        else:
            study = None
            metrics: tuple[str, ...] = V_METRICS
            if is_paper and group in study_rq:
                metrics = ("V_sep", "V_coh", "V_align_unwrapped")
                rq = study_rq[group]
                study = {m if m != "V_align" else "V_align_unwrapped": study_groups(rq, m)
                         for m in V_METRICS}
            path = figures.level_bars(rows, metrics, f"{policy}: {group} "
                                      f"({rows.factor.iloc[0]})", fig_dir / f"{name}.png",
                                      study, followers)
        md += [f"![{policy} {group}]({path.relative_to(out)})", ""]
    if "trajectory" in table:
        shown = table.dropna(subset=["trajectory"]).drop_duplicates(["policy", "case"])
        for _, row in shown.iterrows():
            traj = out / "trajectories" / str(row.trajectory)
            if not traj.is_file():
                continue
            try:
                rec = Recording.from_parquet(traj)
            except (OSError, ValueError) as exc:  # a damaged file must not sink the report
                md += [f"(trajectory of {row.policy}: {row.case}, seed {row.seed} not shown: "
                       f"{exc})", ""]
                continue
            path = figures.trajectories(rec, f"{row.policy}: {row.case}, seed {row.seed}",
                                        fig_dir / f"traj_{_slug(row.policy)}_"
                                                  f"{_slug(row.case)}.png")
            md += [f"![{row.case}]({path.relative_to(out)})"]
        md.append("")
    return md


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in str(text)).strip("_")


def _write_html(markdown_path: Path, html_path: Path) -> None:
    import markdown

    body = markdown.markdown(markdown_path.read_text(), extensions=["tables"])
    style = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;font-size:12px;margin:1em 0}"
             "td,th{border:1px solid #ccc;padding:2px 6px}img{max-width:100%}")
    html_path.write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>"
                         f"{markdown_path.stem}</title><style>{style}</style></head><body>"
                         f"{body}</body></html>")
