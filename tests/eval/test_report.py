"""The report as a page a reviewer reads, built from a synthetic paper-suite folder (two
policies, the second one crowding): labelled alignment rules, no "-0", the study's bars,
units, PNG + SVG, bootstrap CIs, a self-contained styled HTML page, safety verdicts, and a
rebuild that leaves nothing stale."""

import json
import re

import numpy as np
import pandas as pd
import pytest

from boids_env import parallel_env
from boids_env.eval import figures
from boids_env.eval.compare import policy_comparison, verdicts
from boids_env.eval.episode import run_episode
from boids_env.eval.report import build_report, num
from boids_env.eval.study import signed
from boids_env.eval.suites import PAPER
from boids_env.policies import ReynoldsPolicy

POLICIES = ("reynolds[paper]", "crowder")


def _row(rng, policy, case, seed):
    crowd = policy == "crowder"
    n = int(case.env.get("robots", 13)) - 1
    counts = [int(c) for c in rng.integers(0, 30, n)]
    touching = float(np.clip(rng.normal(0.8 if crowd else 0.0, 0.02), 0, 1))
    contacts = float(rng.integers(100, 140)) if crowd else 0.0
    return {"policy": policy, "policy_spec": policy, "preset": "paper", "suite": "paper",
            "case": case.name, "group": case.group, "factor": case.factor,
            "level": case.level, "seed": seed,
            "V_sep": abs(rng.normal(0.5, 0.05)), "V_coh": 0.0,  # an all-zero metric
            "V_align": abs(rng.normal(1.8, 0.02)), "V_align_unwrapped": abs(rng.normal(1.9, 0.02)),
            "count_sep": counts, "count_coh": [0] * n, "count_align": counts[::-1],
            "count_align_unwrapped": counts, "min_distance": 0.07 if crowd else 0.3,
            "collisions": int(contacts), "polarization": 0.95, "mean_leader_distance": 1.2,
            "touching_fraction": touching, "mean_contact_pairs": 3 * touching,
            "contacts_follower": contacts, "contacts_leader": 0.0,
            "wall_fraction": 0.0, "mean_nn_distance": 0.2 if crowd else 0.3,
            "leader_path_deviation": 0.03, "leader_path_deviation_max": 0.1,
            "steps": 746, "duration": 74.6, "wall_time": 0.3}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval")
    rng = np.random.default_rng(0)
    rows = [_row(rng, p, c, s) for p in POLICIES for c in PAPER.cases for s in range(5)]
    table = pd.DataFrame(rows)
    rec = run_episode(parallel_env(robots=4, max_cycles=30), ReynoldsPolicy(), 0).recording
    (out / "trajectories").mkdir()
    rec.to_parquet(out / "trajectories" / "t.parquet")
    table["trajectory"] = [("t.parquet" if r["seed"] == 0 and r["case"] == "leader_speed=0.5"
                            else None) for r in rows]
    table.to_parquet(out / "results.parquet", index=False)
    suite = {"name": "paper", "seeds": [0, 1, 2, 3, 4], "per_follower": ["rq3"],
             "followers_analysed": 6,
             "policies": [{"spec": p, "preset": "paper", "label": p} for p in POLICIES],
             "cases": [{"name": c.name, "group": c.group, "factor": c.factor,
                        "level": c.level, "env": c.env, "policy": c.policy}
                       for c in PAPER.cases]}
    (out / "suite.json").write_text(json.dumps(suite))
    # an earlier build of another suite left these behind
    (out / "figures").mkdir()
    (out / "figures" / "speeds_old.png").write_bytes(b"stale")
    (out / "verdicts_gone.csv").write_text("stale")
    build_report(out)
    return out


def test_numbers_never_show_minus_zero(folder):
    assert num(-0.0) == "0.000" and num(-1e-9) == "0.000" and num(-0.0012) == "-0.001"
    assert signed(-0.0) == "0" and signed(1e-17) == "0" and signed(-0.0754) == "-0.0754"
    text = (folder / "report.md").read_text()
    for bad in ("(-0)", "(+0)", "Δ -0,", "Δ +0,"):
        assert bad not in text, f"{bad!r} in the report"
    assert not re.search(r"-0\.0+(?![0-9])", text), "a negative zero like -0.000"


def test_p_values_never_print_as_zero():
    """statsmodels' Tukey test returns p = 0 for large differences; the tables printed "0"."""
    from boids_env.eval.report import _md_table

    table = pd.DataFrame({"metric": ["a", "b", "c"], "p_adj": [0.0, 2.26e-8, 0.0421],
                          "levene_p": [1e-12, 0.5, np.nan], "p_holm": [0.0, 1.0, 0.2],
                          "polarization": [0.98765, 0.5, 0.25]})
    rows = [[c.strip() for c in line.strip("|").split("|")]
            for line in _md_table(table).splitlines()[2:]]
    assert [r[1] for r in rows] == ["< 0.001", "< 0.001", "0.0421"], rows
    assert [r[2] for r in rows] == ["< 0.001", "0.5", "—"], rows
    assert [r[3] for r in rows] == ["< 0.001", "1", "0.2"], rows
    assert [r[4] for r in rows] == ["0.9877", "0.5000", "0.2500"], "not a p-value"


def test_every_table_names_its_alignment_rule(folder):
    text = (folder / "report.md").read_text()
    assert "Tukey HSD behind these verdicts (alignment: the study's unwrapped rule)" in text
    assert "## Tukey HSD (FWER 0.05; alignment: wrapped into [0°, 180°])" in text
    assert "V_align (wrapped)" in text and "V_align (study's unwrapped)" in text
    assert text.count("the study's numbers beside ours (mean ± population std; alignment: "
                      "the study's unwrapped rule)") == 2


def test_figures_are_png_at_160_dpi_with_svg_beside_and_the_study_everywhere(folder):
    from PIL import Image

    names = {p.name for p in (folder / "figures").iterdir()}
    assert "speeds_old.png" not in names, "a rebuild replaces figures/ whole"
    pngs = sorted(n for n in names if n.endswith(".png"))
    assert len(pngs) >= 9, pngs
    for name in pngs:
        assert name[:-4] + ".svg" in names, f"SVG beside {name}"
        dpi = Image.open(folder / "figures" / name).info["dpi"][0]
        assert dpi >= 150, (name, dpi)
    for policy in ("reynolds_paper", "crowder"):
        for rq in ("rq1", "rq2", "rq3"):
            svg = (folder / "figures" / f"{policy}_{rq}.svg").read_text()
            assert "study" in svg, f"the study's bars in {policy} {rq}"
            assert "unwrapped" in svg, f"{policy} {rq}: the alignment rule is named"
            assert "95 % bootstrap CI" in svg
        rq3 = (folder / "figures" / f"{policy}_rq3.svg").read_text()
        assert "study, 19 robots" in rq3 and "violating samples (0.1 s each)" in rq3
    traj = (folder / "figures" / "traj_reynolds_paper_leader_speed_0.5.svg").read_text()
    assert "x (m)" in traj and "y (m)" in traj, "trajectory axes in metres"
    total = (folder / "figures" / "policies_total.svg").read_text()
    assert "followers in violation (time average)" in total, "policy bars carry units"


def test_an_all_zero_panel_says_so_and_cis_stay_non_negative(folder, tmp_path):
    rq1 = (folder / "figures" / "reynolds_paper_rq1.svg").read_text()
    assert "V_coh" in rq1  # ours all zero, but the study has cohesion data: bars, no note
    rows = pd.DataFrame({"level": ["a"] * 3 + ["b"] * 3, "factor": "f",
                         "V_coh": [0.0] * 6})
    path = figures.level_bars(rows, ["V_coh"], "zeros", tmp_path / "z")
    assert "all zero" in (tmp_path / "z.svg").read_text() and path.suffix == ".png"
    mean, low, high = figures.mean_ci([0.0, 0.0, 0.0, 0.0, 1.0])
    assert 0 <= low <= mean <= high, (low, mean, high)


def test_safety_table_figure_and_verdicts(folder):
    text = (folder / "report.md").read_text()
    assert "## Safety per case" in text and "touching_fraction" in text
    assert (folder / "figures" / "safety.png").is_file()
    v = pd.read_csv(folder / "policy_verdicts.csv")
    assert len(v) == 9 and set(v["policy"]) == {"crowder"}
    assert (v["safety"] == "less safe").all(), v[["case", "safety", "safety_because"]]
    assert v["safety_because"].str.contains("touching_fraction higher").all()
    comp = pd.read_csv(folder / "policy_comparison.csv")
    assert {"touching_fraction", "contacts", "wall_fraction", "V_sep", "total"} <= set(
        comp["metric"])
    walls = comp[comp.metric == "wall_fraction"]
    assert (walls["direction"] == "no significant difference").all(), "equal: no difference"


def test_every_safety_panel_names_its_cases_and_marks_zero_bars(folder):
    """The upper panels had no case names and zero bars were invisible: mostly empty."""
    svg = (folder / "figures" / "safety.svg").read_text()
    panels = svg.count("nearest-neighbour gap") + svg.count("time some robots touch") + \
        svg.count("time at a wall") + svg.count("contact onsets (all pairs)")
    assert panels == 4, panels
    for case in ("leader_speed=0.5", "robots=19"):
        assert svg.count(f">{case}<") == 4, f"{case} named under every panel"
    # reynolds[paper] has no contact onsets in the fixture, the crowder has many: a zero bar
    # marked in each of the 9 cases (the all-zero wall panel says "all zero" instead)
    assert svg.count('id="zero_bar') == 9, svg.count('id="zero_bar')
    assert "all zero" in svg


def test_safety_verdict_logic_on_hand_made_numbers():
    base = {"policy": "a", "case": "c", "V_sep": [1, 1.1, 0.9, 1.0], "V_coh": [0] * 4,
            "V_align": [1, 1, 1, 1.01], "touching_fraction": [0.5, 0.52, 0.48, 0.5],
            "contacts_follower": [10, 11, 9, 10], "contacts_leader": [0] * 4,
            "wall_fraction": [0] * 4}
    safer = {**base, "policy": "b", "touching_fraction": [0.1, 0.12, 0.08, 0.1]}
    same = {**base, "policy": "d"}
    table = pd.concat([pd.DataFrame(d) for d in (base, safer, same)], ignore_index=True)
    out = verdicts(policy_comparison(table)).set_index("policy")
    assert out.loc["b", "safety"] == "safer" and "touching_fraction lower" in \
        out.loc["b", "safety_because"]
    assert out.loc["d", "safety"] == "as safe"
    assert out.loc["d", "total"] == "no significant difference"


def test_html_is_one_styled_self_contained_page(folder):
    html = (folder / "report.html").read_text()
    assert "<title>Evaluation report: suite paper — reynolds[paper] vs crowder</title>" in html
    assert 'src="figures/' not in html, "every figure inlined"
    assert html.count('src="data:image/png;base64,') >= 9
    assert "<style>" in html and "font:" in html
    assert re.search(r'<td class="good"[^>]*>reproduced</td>', html)
    assert re.search(r'<td class="bad"[^>]*>less safe</td>', html)


def test_a_rebuild_removes_what_it_no_longer_produces(folder):
    assert not (folder / "verdicts_gone.csv").exists()
    assert (folder / "verdicts_crowder.csv").is_file()
    # the same folder with one policy: no comparison any more
    table = pd.read_parquet(folder / "results.parquet")
    table[table.policy == POLICIES[0]].to_parquet(folder / "results.parquet", index=False)
    suite = json.loads((folder / "suite.json").read_text())
    suite["policies"] = suite["policies"][:1]
    (folder / "suite.json").write_text(json.dumps(suite))
    build_report(folder)
    names = {p.name for p in folder.iterdir()}
    assert "policy_comparison.csv" not in names and "policy_verdicts.csv" not in names
    assert "verdicts_crowder.csv" not in names
    assert not any(p.name.startswith("crowder") for p in (folder / "figures").iterdir())
    assert not [p for p in folder.iterdir() if p.name.startswith(".")], "no temporary left"


def test_two_policies_with_one_seed_give_a_report_that_says_why_there_is_no_comparison(
        tmp_path):
    """It crashed (KeyError 'policy') on the empty comparison table."""
    from boids_env.eval.cases import Case, Suite
    from boids_env.eval.runner import PolicySpec, run_suite

    suite = Suite("one", (Case("a", "g", "f", "a", {"max_cycles": 30}),), seeds=(0,))
    run_suite([PolicySpec.parse("reynolds"), PolicySpec.parse("random")], suite, tmp_path,
              workers=1, backend="inline", progress=False)
    report = build_report(tmp_path).read_text()
    assert "needs at least 2 seeds" in report


def test_names_differing_only_in_punctuation_get_their_own_figures(tmp_path):
    # issue 39 item 6: `speed=0.3` and `speed 0.3` (and policies, groups alike) slug to the
    # same file name, so both showed the figure drawn last
    from boids_env.eval.cases import Case

    rng = np.random.default_rng(0)
    policies = ("p=1", "p 1")
    cases = [Case(f"speed{sep}{v}", f"g{sep}1", "leader_speed", str(v), {"robots": 4})
             for sep in ("=", " ") for v in (0.3, 0.4)]
    rows = [_row(rng, p, c, s) for p in policies for c in cases for s in range(3)]
    (tmp_path / "trajectories").mkdir()
    for k, robots in enumerate((3, 4, 5, 6)):  # a different flock in every trajectory
        rec = run_episode(parallel_env(robots=robots, max_cycles=5), ReynoldsPolicy(),
                          0).recording
        rec.to_parquet(tmp_path / "trajectories" / f"t{k}.parquet")
    shown = {(p, c): f"t{k}.parquet" for k, (p, c) in enumerate(
        (p, c) for p in policies for c in ("speed=0.3", "speed 0.3"))}
    table = pd.DataFrame(rows)
    table["trajectory"] = [shown.get((r["policy"], r["case"])) if r["seed"] == 0 else None
                           for r in rows]
    table.to_parquet(tmp_path / "results.parquet", index=False)
    suite = {"name": "punctuation", "seeds": [0, 1, 2], "per_follower": [],
             "followers_analysed": 3,
             "policies": [{"spec": p, "preset": "paper", "label": p} for p in policies],
             "cases": [{"name": c.name, "group": c.group, "factor": c.factor,
                        "level": c.level, "env": c.env, "policy": c.policy} for c in cases]}
    (tmp_path / "suite.json").write_text(json.dumps(suite))
    text = build_report(tmp_path).read_text()
    shown_figures = re.findall(r"!\[([^\]]*)\]\(figures/([^)]+)\)", text)
    per_pair = {alt: path for alt, path in shown_figures}
    groups = [a for a in per_pair if ":" not in a and "Safety" not in a and "Total" not in a]
    trajectories = [a for a in per_pair if ":" in a]
    assert len(groups) == 4 and len(trajectories) == 4, shown_figures
    paths = [per_pair[a] for a in groups + trajectories]
    assert len(set(paths)) == 8, f"figures shared between names: {shown_figures}"
    for path in paths:
        assert (tmp_path / "figures" / path).is_file(), path
    svgs = {(tmp_path / "figures" / per_pair[a]).with_suffix(".svg").read_text()
            for a in trajectories}
    assert len(svgs) == 4, "each trajectory figure draws its own flock"


def test_file_stems_are_plain_unless_names_collide():
    from boids_env.eval.runner import unique_stems

    stems = unique_stems([("p=1",), ("p 1",), ("q",)], "verdicts_")
    assert stems[("q",)] == "verdicts_q", "a name alone keeps its readable stem"
    assert stems[("p=1",)] != stems[("p 1",)]
    assert all(re.fullmatch(r"verdicts_p_1-[0-9a-f]{8}", stems[k]) for k in [("p=1",), ("p 1",)])
    assert unique_stems([("p=1",), ("q",)])[("p=1",)] == "p_1", "no collision: no hash"
    # a key and a fixed figure of the same stem: the key's stem changes, the figure's cannot
    assert unique_stems([("policies", "total")], taken=("policies_total",))[
        ("policies", "total")].startswith("policies_total-")
    # (policy, group) pairs whose joined slugs meet
    pairs = unique_stems([("a_b", "c"), ("a", "b_c")])
    assert len(set(pairs.values())) == 2
