"""``boids report DIR``: statistics, figures and ``report.md`` / ``report.html`` from a folder
of saved results (``results.parquet`` + ``suite.json`` written by the runner); nothing is
rerun.

Every table uses one alignment rule and says which: the study's verdicts (and the Tukey
table behind them) its unwrapped rule, the other tables the rule the episodes ran with
(wrapped into [0°, 180°] by default). A rebuild replaces ``figures/`` whole and removes the
CSVs an earlier build wrote that this one does not (another suite's verdicts).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from boids_env.eval import figures
from boids_env.eval.cases import BLOCK_SIZE
from boids_env.eval.compare import policy_comparison, with_contacts
from boids_env.eval.compare import verdicts as policy_verdicts
from boids_env.eval.folder import REPORT_OUTPUTS, read_manifest, record_files
from boids_env.eval.html import write_html
from boids_env.eval.markup import escape
from boids_env.eval.people_report import has_people, person_section
from boids_env.eval.robot_types import robot_sections
from boids_env.eval.runner import WORLD_CHANGES, unique_stems
from boids_env.eval.stats import COUNT_METRICS, V_METRICS, analyse, pair_difference
from boids_env.eval.study import (
    GROUP_OF_RQ,
    block_scores,
    statement,
    study_groups,
    study_runs,
    study_summary,
    study_tukey,
    verdicts,
)
from boids_env.files import atomic_path, write_text
from boids_env.metrics import SAFETY_KEYS
from boids_env.parquet import read_table
from boids_env.recording import Recording
from boids_env.untrusted import parse_json, read_text

__all__ = ["build_report", "load_results", "policy_comparison", "safety_table",
           "study_side_by_side", "summary_table"]

UNWRAPPED = "the study's unwrapped rule"
SUMMARY_METRICS = ("V_sep", "V_coh", "V_align", "V_align_unwrapped", "polarization",
                   "mean_leader_distance")
SAFETY_METRICS = ("touching_fraction", "mean_contact_pairs", "contacts_follower",
                  "contacts_leader", "wall_fraction", "min_clearance", "no_sight_fraction",
                  "mean_nn_distance", "min_distance", "leader_path_deviation",
                  "leader_path_deviation_max", "lost_followers")
"""The safety table's columns: :data:`boids_env.metrics.SAFETY_KEYS` and the minimum
distance, and the followers lost (farther than 3 m from the leader at the end)."""
assert set(SAFETY_KEYS) <= set(SAFETY_METRICS)
OWN_CSVS = ("stats_anova.csv", "stats_tukey.csv", "stats_tukey_study.csv",
            "policy_comparison.csv", "policy_verdicts.csv", "safety.csv", "blocks.csv",
            "proxemics.csv", "person_trade_offs.csv")
"""CSVs a build may write (besides ``verdicts_<policy>.csv``); stale ones are removed."""
assert set(OWN_CSVS) <= set(REPORT_OUTPUTS)


def load_results(out: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The results table and suite description of an eval output folder."""
    out = Path(out)
    path = out / "results.parquet"
    if not path.is_file():
        raise FileNotFoundError(f"no results.parquet in {out}; run boids eval --out {out} "
                                f"first")
    try:
        table = read_table(path).to_pandas()  # checksums verified
        suite = parse_json(read_text(out / "suite.json", "suite.json", 16 << 20), "suite.json")
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the results in {out}: {exc}") from exc
    if table.empty:
        raise ValueError(f"{path} holds no finished episodes")
    _check_suite(out / "suite.json", suite)
    return table, suite


def _check_suite(path: Path, suite: Any) -> None:
    """``ValueError`` naming the key when ``suite.json`` (a file anyone can edit) is not what
    the runner writes; the follower count that sizes figures is bounded as in a suite file."""
    from boids_env.config import check_integer

    if not isinstance(suite, dict):
        raise ValueError(f"{path} must hold a JSON table, got {type(suite).__name__}")
    shapes = (("name", str), ("seeds", list), ("policies", list), ("cases", list),
              ("per_follower", list))
    for key, kind in shapes:
        if not isinstance(suite.get(key), kind):
            raise ValueError(f"{path}: {key} must be a {kind.__name__}, got "
                             f"{suite.get(key)!r:.80}")
    if not all(isinstance(p, dict) and "label" in p for p in suite["policies"]):
        raise ValueError(f"{path}: policies must be tables with a label")
    try:
        check_integer("followers_analysed", suite.get("followers_analysed", 6), 1, 10_000)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: {exc}") from None


def num(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals, never ``-0.000``."""
    text = f"{float(value):.{digits}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text


def p_text(value: float) -> str:
    """A p-value to 3 significant digits; below 0.001 as ``< 0.001`` (statsmodels' Tukey test
    returns an exact 0 for large differences, which is no probability to print)."""
    return "< 0.001" if value < 0.001 else f"{value:.3g}"


def _is_p(column: str) -> bool:
    return column in ("p", "p_adj") or column.startswith("p_") or column.endswith("_p")


def _fmt(mean: float, std: float) -> str:
    return f"{num(mean)} ± {num(std)}"


def alignment_rule(suite: dict[str, Any]) -> str:
    """The alignment rule the suite's episodes ran with (their ``V_align``)."""
    wraps = {c.get("env", {}).get("wrap_alignment", True) for c in suite.get("cases", [])}
    if wraps == {False}:
        return UNWRAPPED
    return "wrapped into [0°, 180°]" if wraps <= {True} else "as configured per case"


def summary_table(table: pd.DataFrame, metrics: tuple[str, ...] = SUMMARY_METRICS,
                  rule: str = "wrapped into [0°, 180°]") -> pd.DataFrame:
    """Mean ± population std per policy and case of ``metrics``; the alignment columns are
    named with their rule (``rule``: the one the episodes ran with)."""
    names = {"V_align": f"V_align ({'unwrapped' if rule == UNWRAPPED else rule.split()[0]})",
             "V_align_unwrapped": "V_align (study's unwrapped)"}
    rows = []
    for (policy, case), g in table.groupby(["policy", "case"], sort=False):
        row = {"policy": policy, "case": case, "runs": len(g)}
        for m in metrics:
            if m in g:
                row[names.get(m, m)] = _fmt(float(g[m].mean()), float(g[m].std(ddof=0)))
        rows.append(row)
    return pd.DataFrame(rows)


def safety_table(table: pd.DataFrame) -> pd.DataFrame:
    """The safety metrics, mean ± population std per policy and case."""
    return summary_table(table, tuple(m for m in SAFETY_METRICS if m in table))


def study_side_by_side(table: pd.DataFrame, policy: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The study's numbers beside ours (mean ± population std; alignment: the study's
    unwrapped rule): V_* for the RQ1 and RQ2 cases, per-follower counts (followers 1–6) for
    RQ3."""
    summary = study_summary()
    rows = []
    for rq in (1, 2):
        ours = table[(table.policy == policy) & (table.group == GROUP_OF_RQ[rq])]
        for level, g in ours.groupby("level", sort=False):
            row: dict[str, Any] = {"case": f"{g.factor.iloc[0]} {level}"}
            for metric in V_METRICS:
                s = summary[(summary.rq == rq) & (summary.level == level)
                            & (summary.metric == metric)]
                col = "V_align_unwrapped" if metric == "V_align" else metric
                name = metric  # the table's heading names the alignment rule
                row[f"study {name}"] = _fmt(s["mean"].iloc[0], s["std"].iloc[0]) if len(s) \
                    else "—"
                row[f"ours {name}"] = _fmt(float(g[col].mean()), float(g[col].std(ddof=0)))
            rows.append(row)
    first, rows = pd.DataFrame(rows), []
    ours3 = table[(table.policy == policy) & (table.group == GROUP_OF_RQ[3])]
    for level, g in ours3.groupby("level", sort=False):
        row = {"case": f"robots {level} (per follower 1–6)"}
        for metric in COUNT_METRICS:
            study = study_groups(3, metric).get(level)
            col = metric + ("_unwrapped" if metric == "count_align" else "")
            name = metric
            vals = np.array([c for counts in g[col] for c in list(counts)[:6]], dtype=float)
            row[f"study {name}"] = _fmt(study.mean(), study.std()) if study is not None \
                else "—"
            row[f"ours {name}"] = _fmt(vals.mean(), vals.std())
        rows.append(row)
    return first, pd.DataFrame(rows)


def finding_table(tukey_study: pd.DataFrame, policy: str) -> pd.DataFrame:
    """The study's findings beside ours for ``policy`` (from the unwrapped-rule Tukey
    table): each pair as a statement, with the numbers and the verdict."""
    v = verdicts(tukey_study, policy)
    study = study_tukey()
    ours = tukey_study[tukey_study.policy == policy] if len(tukey_study) else tukey_study
    statements = []
    for (_, s), (_, row) in zip(study.iterrows(), v.iterrows(), strict=True):
        mine = "—"
        if row.verdict != "not run":
            part = ours[(ours.group == GROUP_OF_RQ[int(s.rq)]) & (ours.metric == s.metric)]
            diff, reject, p = pair_difference(part, s.group1, s.group2)
            mine = statement(diff, reject, s.group1, s.group2, p)
        statements.append((statement(s.meandiff, bool(s.reject), s.group1, s.group2,
                                     s.p_adj_published), mine))
    v["study"] = [a for a, _ in statements]
    v["ours"] = [b for _, b in statements]
    return v


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
        "error": (str(r.get("error") or "-").splitlines() or ["-"])[0][:200]}
        for r in rows])
    return ["## Failed episodes", "",
            f"{len(rows)} episode(s) failed and are missing from every table and figure "
            f"below (details and tracebacks in `errors.jsonl`; rerunning the same "
            f"command retries them).", "", _md_table(table), ""]


def _md_table(df: pd.DataFrame) -> str:
    """The table in Markdown: floats formatted, every other cell escaped (names come from
    the user's files)."""
    if not len(df):
        return "(none)"
    shown = df.copy()
    for col in shown.columns:
        if pd.api.types.is_float_dtype(shown[col]):
            shown[col] = [("—" if not np.isfinite(v) else
                           (p_text(v) if _is_p(col) else num(v, 4)))
                          for v in shown[col]]
        else:
            shown[col] = [escape(v) for v in shown[col]]
    return shown.to_markdown(index=False, disable_numparse=True)


def build_report(out: str | Path) -> Path:
    """Writes ``report.md``, ``report.html``, ``stats_anova.csv``, ``stats_tukey.csv``,
    ``safety.csv``, for the paper suite ``stats_tukey_study.csv`` and
    ``verdicts_<policy>.csv``, for two or more policies ``policy_comparison.csv`` and
    ``policy_verdicts.csv``, and ``figures/`` (PNG and SVG) into ``out``; returns the
    Markdown report's path."""
    out = Path(out)
    table, suite = load_results(out)
    table = with_contacts(table)
    per_follower = tuple(suite.get("per_follower", ()))
    followers = int(suite.get("followers_analysed", 6))
    policies = list(dict.fromkeys(table["policy"]))
    is_paper = suite["name"] == "paper"
    rule = alignment_rule(suite)
    anova, tukey = analyse(table, per_follower, followers)
    csvs: dict[str, pd.DataFrame] = {"stats_anova.csv": anova, "stats_tukey.csv": tukey,
                                     "safety.csv": safety_table(table)}
    title = (f"Evaluation report: suite {suite['name']} — "
             f"{' vs '.join(policies)}")
    md = [f"# {escape(title)}", "",
          f"Policies: {escape(', '.join(str(p['label']) for p in suite['policies']))} (the "
          f"first is the baseline). Seeds: {escape(', '.join(map(str, suite['seeds'])))}. "
          f"Episodes in the table: "
          f"{len(table)} (cases that are the same configuration share their runs). "
          f"Mean ± population std over seeds unless stated; figures show 95 % "
          f"percentile-bootstrap confidence intervals.{_realism_note(suite)}", ""]
    md += failed_episodes(out)
    summary = ["## Summary", ""]
    if is_paper:
        _, tukey_study = analyse(table, per_follower, followers, unwrapped=True)
        csvs["stats_tukey_study.csv"] = tukey_study
        md += _paper_sections(table, tukey_study, policies, csvs, summary)
        md += _block_section(table, policies, per_follower, csvs, summary)
    if suite["name"] == "robot_types":
        _, tukey_study = analyse(table, per_follower, followers, unwrapped=True)
        csvs["stats_tukey_study.csv"] = tukey_study
        md += robot_sections(table, tukey_study, policies, _md_table, csvs, summary)
    md += _world_changes_section(out)
    md += ["## Results per case", "",
           f"Two alignment columns: the rule the episodes ran with ({rule}) and the study's "
           f"unwrapped rule. Distances in m.", "",
           _md_table(summary_table(table, rule=rule)), ""]
    md += ["## Safety per case", "",
           "The study measures violations against the leader only, so a policy can score well "
           "while its robots touch each other. `touching_fraction`: time some pair of robots "
           "(the leader included) is in contact; `contacts_*`: contact onsets per episode; "
           "`wall_fraction`: time some robot touches a wall; distances in m.", "",
           _md_table(csvs["safety.csv"]), ""]
    if has_people(table):
        md += person_section(table, summary_table, _md_table, csvs, summary)
    if len(policies) > 1:
        md += _comparison_section(table, policies, csvs, summary)
    md += _stats_section(anova, tukey, rule)
    with atomic_path(out / "figures") as fig_dir:
        fig_dir.mkdir()
        md += ["## Figures", "", f"Each figure is in `figures/` as PNG and SVG. "
               f"{figures.CI_NOTE}.", ""]
        md += _figures(table, suite, per_follower, followers, fig_dir, is_paper, policies)
        md += _trajectory_figures(table, fig_dir, out)
        drawn = [f"figures/{p.name}" for p in fig_dir.iterdir()]
    _write_csvs(out, csvs)
    md = md[:2] + summary + [""] + md[2:] if len(summary) > 2 else md
    text = "\n".join(md) + "\n"
    write_text(out / "report.md", text)
    write_html(text, out / "report.html", title, out, drawn)
    record_files(out, ["report.md", "report.html", "figures", *csvs])
    return out / "report.md"


def _own_file(folder: Path, name: str) -> bool:
    """Whether ``name`` (a trajectory named in ``results.parquet``) is a file name in
    ``folder`` that stays there: a plain name, not a link (it need not exist)."""
    return (name not in ("", ".", "..") and "/" not in name and "\\" not in name
            and not (folder / name).is_symlink())


def _realism_note(suite: dict[str, Any]) -> str:
    """" Realism: ros in every case." when the episodes ran with a realism preset."""
    found = {str(c.get("env", {}).get("realism")) for c in suite.get("cases", [])
             if isinstance(c, dict) and isinstance(c.get("env"), dict)}
    found.discard("None")
    found.discard("none")
    return (f" **Realism: {escape(', '.join(sorted(found)))}** (ROS/Stage realism)." if found
            else "")


def _paper_sections(table: pd.DataFrame, tukey_study: pd.DataFrame, policies: list[str],
                    csvs: dict[str, pd.DataFrame], summary: list[str]) -> list[str]:
    md = ["## The study's findings, reproduced or not", "",
          "Each row is one pair of the study's Tukey HSD tables (FWER 0.05; Δ = mean of the "
          "second level − mean of the first): *reproduced* when our Tukey test on the same "
          "pair agrees (significant in the same direction, or not significant). **Alignment: "
          f"{UNWRAPPED}** (|θ_leader − θ_i| without wrapping), in the verdicts and in the "
          "Tukey table behind them.", ""]
    stems = unique_stems([(p,) for p in policies], "verdicts_")
    for policy in policies:
        v = finding_table(tukey_study, policy)
        v.insert(0, "policy", policy)
        csvs[f"{stems[(policy,)]}.csv"] = v
        n_rep = int((v.verdict == "reproduced").sum())
        summary.append(f"- **{escape(policy)}**: {n_rep} of {len(v)} of the study's findings "
                       f"reproduced.")
        md += [f"### {escape(policy)}: {n_rep} of {len(v)} findings reproduced", "",
               _md_table(v[["rq", "metric", "pair", "study", "ours", "verdict"]]), "",
               f"#### {escape(policy)}: Tukey HSD behind these verdicts (alignment: "
               f"{UNWRAPPED})", "",
               _md_table(tukey_study[tukey_study.policy == policy][
                   ["group", "metric", "group1", "group2", "meandiff", "p_adj", "lower",
                    "upper", "reject"]]), ""]
        v_table, count_table = study_side_by_side(table, policy)
        md += [f"#### {escape(policy)}: the study's numbers beside ours (mean ± population std; "
               f"alignment: {UNWRAPPED})", "", _md_table(v_table), "", _md_table(count_table),
               ""]
    return md


def _block_section(table: pd.DataFrame, policies: list[str], per_follower: tuple[str, ...],
                   csvs: dict[str, pd.DataFrame], summary: list[str]) -> list[str]:
    """With two or more blocks of 5 seeds (``boids eval --blocks K``): each block scored as
    its own reproduction of the study (its design: 5 runs per case), per policy."""
    seeds = sorted(table["seed"].unique())
    if len(seeds) < 2 * BLOCK_SIZE:
        return []
    parts = []
    for policy in policies:
        scores = block_scores(table, policy, per_follower, BLOCK_SIZE)
        scores.insert(0, "policy", policy)
        parts.append(scores)
        found = scores["findings"]
        summary.append(
            f"- **{escape(policy)}**, {len(scores)} blocks of {BLOCK_SIZE} seeds: findings "
            f"reproduced "
            f"per block {', '.join(map(str, found))} of {scores['of'].iloc[0]} (mean "
            f"{found.mean():.2f}, range {found.min()}–{found.max()}); magnitudes within 2× "
            f"mean {scores['magnitudes_within_2x'].mean():.1f} of "
            f"{scores['of_means'].iloc[0]}; 19-robot cohesion finding in "
            f"{int(scores['cohesion_19_vs_13'].sum())} of {len(scores)} blocks.")
    blocks = pd.concat(parts, ignore_index=True)
    csvs["blocks.csv"] = blocks
    return ["## Reproduction score in blocks of 5 seeds", "",
            f"The study ran 5 runs per case. Here the seeds are cut into consecutive blocks of "
            f"{BLOCK_SIZE}, each scored on its own exactly as above (Tukey HSD, alignment: "
            f"{UNWRAPPED}): how many of the study's findings one 5-run reproduction "
            f"recovers, and how much that moves between blocks. (The verdicts above pool all "
            f"{len(seeds)} seeds, so they have more power than the study had and call more "
            f"of its null results significant.) `magnitudes_within_2x`: of the study's RQ1 "
            f"and RQ2 means, how many ours are within a factor 2 of.", "",
            _md_table(blocks), ""]


def _comparison_section(table: pd.DataFrame, policies: list[str],
                        csvs: dict[str, pd.DataFrame], summary: list[str]) -> list[str]:
    comp = policy_comparison(table)
    if comp.empty:  # one seed per case: nothing to compare with statistics
        summary.append("- Policies not compared: a comparison needs at least 2 seeds per case.")
        return ["## Policies compared per case", "",
                "Not computed: comparing two policies on a case needs at least 2 seeds of "
                "each (rerun with `--seeds 2` or more).", ""]
    verdict = policy_verdicts(comp)
    csvs["policy_comparison.csv"], csvs["policy_verdicts.csv"] = comp, verdict
    for policy, g in verdict.groupby("policy", sort=False):
        counts = g["safety"].value_counts()
        better = int((g["total"] == "better").sum())
        summary.append(
            f"- **{escape(policy)}** against {escape(policies[0])}: total violation better in "
            f"{better} of "
            f"{len(g)} cases; safety: " + ", ".join(f"{k} in {v}" for k, v in counts.items())
            + ".")
    return ["## Policies compared per case", "",
            f"Each policy against the baseline **{escape(policies[0])}**, case by case: difference "
            f"(policy − baseline) with its 95 % percentile-bootstrap CI and Welch's t-test, "
            f"Holm-corrected over all rows. A difference counts when its corrected p < 0.05 "
            f"and its CI excludes 0. V_* (lower is better): *better*, *worse* or *no "
            f"significant difference*. **Safety verdict** from `touching_fraction`, "
            f"`contacts` (contact onsets, all pairs) and `wall_fraction` (lower is safer): "
            f"*less safe* when any is significantly higher, *safer* when one is "
            f"significantly lower and none higher, *as safe* otherwise.", "",
            _md_table(verdict), "", "#### Every comparison", "", _md_table(comp), "",
            "![Total violation per case and policy](figures/policies_total.png)", "",
            "![Safety per case and policy](figures/safety.png)", ""]


def _stats_section(anova: pd.DataFrame, tukey: pd.DataFrame, rule: str) -> list[str]:
    if not len(anova):
        return []
    return ["## One-way ANOVA per group and metric", "",
            f"Alignment: {rule}. `p` is the study's ANOVA; `robust_test`/`robust_p` the test "
            "the data call for (Welch when Levene rejects equal variances, Kruskal–Wallis "
            "when a level has zero variance). eta² = SS_between / SS_total.", "",
            _md_table(anova.drop(columns=["means"])[
                ["policy", "group", "metric", "F", "p", "eta2", "levene_p", "welch_p",
                 "kruskal_p", "robust_test", "robust_p"]]), "",
            f"## Tukey HSD (FWER 0.05; alignment: {rule})", "",
            "meandiff = mean(group2) − mean(group1).", "",
            _md_table(tukey[["policy", "group", "metric", "group1", "group2", "meandiff",
                             "p_adj", "lower", "upper", "reject"]]), ""]


def _study_per_follower(metric: str, followers: int) -> dict[str, np.ndarray]:
    """The study's RQ3 counts per level as (runs, followers) arrays."""
    runs = study_runs()
    rows = runs[(runs.rq == 3) & (runs.metric == metric)
                & (runs.follower.astype(float) <= followers)]
    return {str(level): g.pivot(index="run", columns="follower", values="value").to_numpy(float)
            for level, g in rows.groupby("level", sort=False)}


def _world_changes_section(out: Path) -> list[str]:
    """What a policy changed in the world of its own episodes (a model's env fields), and
    which fields of a model's training a case overrode, from the folder's manifest."""
    manifest = read_manifest(out) or {}
    changes = manifest.get(WORLD_CHANGES)
    if not isinstance(changes, dict) or not changes:
        return []
    rows = []
    for policy, cases in changes.items():
        for case, kinds in (cases.items() if isinstance(cases, dict) else []):
            for kind, label in (("changed", "its env fields"),
                                ("untrained", "the case, against its training")):
                table = kinds.get(kind) if isinstance(kinds, dict) else None
                for name, pair in (table.items() if isinstance(table, dict) else []):
                    if isinstance(pair, list) and len(pair) == 2:
                        rows.append({"policy": str(policy), "case": str(case),
                                     "field": str(name), "set by": label,
                                     "case asked": json.dumps(pair[0]),
                                     "episodes ran with": json.dumps(pair[1])})
    if not rows:
        return []
    return ["## Worlds changed by a policy", "",
            "These policies' episodes did not run in the world the case describes: a model's "
            "env fields changed it for its own episodes (*its env fields*), or the case "
            "changed a field the model was trained with (*the case, against its training*; "
            "for those, *case asked* is the trained value). Compare their numbers with the "
            "other policies' knowing this.", "",
            _md_table(pd.DataFrame(rows)), ""]


FIXED_FIGURES = ("safety", "policies_total")
"""Figures of every report, by stem (a policy–group figure never takes their names)."""


def _figures(table: pd.DataFrame, suite: dict[str, Any], per_follower: tuple[str, ...],
             followers: int, fig_dir: Path, is_paper: bool, policies: list[str]) -> list[str]:
    md: list[str] = []
    study_rq = {v: k for k, v in GROUP_OF_RQ.items()}
    unwrapped_only = alignment_rule(suite) == UNWRAPPED
    grouped = table.groupby(["policy", "group"], sort=False)
    stems = unique_stems(list(grouped.groups), taken=FIXED_FIGURES)
    for (policy, group), rows in grouped:
        name = stems[(str(policy), str(group))]
        rq = study_rq.get(group) if is_paper else None
        if group in per_follower:
            metrics = COUNT_METRICS
            study = None
            if rq is not None or unwrapped_only:
                metrics = ("count_sep", "count_coh", "count_align_unwrapped")
            if rq is not None:
                study = {m: _study_per_follower(m.replace("_unwrapped", ""), followers)
                         for m in metrics}
            path = figures.follower_bars(rows, metrics, f"{policy}: {group}, per follower",
                                         fig_dir / name, followers, study)
        else:
            metrics, study = V_METRICS, None
            if rq is not None or unwrapped_only:
                metrics = ("V_sep", "V_coh", "V_align_unwrapped")
            if rq is not None:
                study = {m: study_groups(rq, m.replace("_unwrapped", "")) for m in metrics}
            path = figures.level_bars(rows, metrics, f"{policy}: {group} "
                                      f"({rows.factor.iloc[0]})", fig_dir / name, study,
                                      followers)
        md += [f"![{escape(policy)} {escape(group)}](figures/{path.name})", ""]
    md += ["![Safety per case and policy](figures/safety.png)", ""] if len(policies) == 1 \
        else []
    figures.safety_bars(table, fig_dir / "safety")
    if len(policies) > 1:
        plot = table.assign(total=table[list(V_METRICS)].sum(axis=1))
        figures.policy_bars(plot, "total", fig_dir / "policies_total",
                            "Total violation V_sep + V_coh + V_align per case")
    return md


def _trajectory_figures(table: pd.DataFrame, fig_dir: Path, out: Path) -> list[str]:
    if "trajectory" not in table:
        return []
    md = ["### Sample trajectories (first seed of each case)", ""]
    shown = table.dropna(subset=["trajectory"]).drop_duplicates(["policy", "case"])
    stems = unique_stems(list(zip(shown["policy"], shown["case"], strict=True)), "traj_")
    for _, row in shown.iterrows():
        traj = out / "trajectories" / str(row.trajectory)
        if not _own_file(out / "trajectories", str(row.trajectory)):
            md.append(escape(f"(trajectory of {row.policy}: {row.case}, seed {row.seed} not "
                             f"shown: {str(row.trajectory)!r} is not a file inside "
                             f"trajectories/)"))
            continue
        if not traj.is_file():
            continue
        try:
            rec = Recording.from_parquet(traj)
        except (OSError, ValueError) as exc:  # a damaged file must not sink the report
            md.append(escape(f"(trajectory of {row.policy}: {row.case}, seed {row.seed} not "
                             f"shown: {exc})"))
            continue
        path = figures.trajectories(rec, f"{row.policy}: {row.case}, seed {row.seed}",
                                    fig_dir / stems[(str(row.policy), str(row.case))])
        md.append(f"![{escape(row.policy)}: {escape(row.case)}](figures/{path.name})")
    return [*md, ""]


def _write_csvs(out: Path, csvs: dict[str, pd.DataFrame]) -> None:
    """Writes this build's CSVs and removes the ones an earlier build wrote that this one
    does not (another suite's verdicts, a comparison of policies no longer in the table)."""
    for name, df in csvs.items():
        write_text(out / name, df.to_csv(index=False))
    stale = [p for p in (*out.glob("verdicts_*.csv"), *out.glob("robot_findings_*.csv"))
             if p.name not in csvs]
    stale += [out / n for n in OWN_CSVS if n not in csvs and (out / n).is_file()]
    for path in stale:
        path.unlink()
