"""`boids eval` and `boids report` end to end on a tiny suite."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from boids_env.train.cli import main


@pytest.mark.slow
def test_boids_eval_writes_every_file_and_report_rebuilds(tmp_path):
    suite = tmp_path / "tiny.toml"
    suite.write_text('name = "tiny"\nseeds = 2\n[defaults]\nrobots = 7\nmax_cycles = 40\n'
                     '[[factor]]\nname = "leader_speed"\nlevels = [0.5, 0.6]\n')
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "eval", "--policy", "reynolds",
         "--policy", "random", "--suite", str(suite), "--workers", "2", "--out", str(out),
         "--no-progress"], capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    files = {p.name for p in out.iterdir()}
    assert {"results.parquet", "results.csv", "episodes.jsonl", "suite.json", "report.md",
            "report.html", "stats_anova.csv", "stats_tukey.csv", "policy_comparison.csv",
            "figures", "trajectories"} <= files
    table = pd.read_parquet(out / "results.parquet")
    assert len(table) == 8 and set(table["policy"]) == {"reynolds[paper]", "random"}
    assert {"policy", "suite", "case", "factor", "level", "seed", "V_sep", "V_coh", "V_align",
            "count_sep", "min_distance", "steps", "wall_time"} <= set(table.columns)
    assert len(pd.read_csv(out / "results.csv")) == 8
    figures = {p.name for p in (out / "figures").iterdir()}
    assert "policies_total.png" in figures and any(f.startswith("traj_") for f in figures)
    report = (out / "report.md").read_text()
    assert "One-way ANOVA" in report and "Policies compared per case" in report
    (out / "report.md").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "report.md").read_text() == report


def test_report_of_a_missing_folder_is_a_clear_error(tmp_path, capsys):
    assert main(["report", str(tmp_path / "none")]) == 2
    assert "no results.parquet" in capsys.readouterr().err


def test_eval_rejects_a_preset_on_a_non_reynolds_policy(tmp_path, capsys):
    assert main(["eval", "--policy", "random@paper", "--out", str(tmp_path)]) == 2
    assert "only reynolds takes a @preset" in capsys.readouterr().err


def test_eval_refuses_a_zip_that_is_no_model_before_writing(tmp_path, capsys):
    """The README promises a policy that cannot load is refused first; a zip without a model
    in it once made the folder, failed every episode and exited 1."""
    import zipfile

    junk = tmp_path / "junk.zip"
    with zipfile.ZipFile(junk, "w") as archive:
        archive.writestr("readme.txt", "not a model")
    out = tmp_path / "out"
    assert main(["eval", "--policy", str(junk), "--seeds", "1", "--out", str(out),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "junk.zip is not a Stable-Baselines3 model" in err and "Traceback" not in err, err
    assert not out.exists()


def test_eval_says_it_builds_the_report_and_names_both_reports(tmp_path, capsys, monkeypatch):
    """The report takes seconds with nothing shown, and the last line named report.md only."""
    import boids_env.eval.report as report

    def build(out):
        out = Path(out)
        said = capsys.readouterr().out
        assert "building the statistics, figures and report" in said, said
        (out / "report.md").write_text("# r\n")
        (out / "report.html").write_text("<p>r</p>\n")
        return out / "report.md"

    monkeypatch.setattr(report, "build_report", build)
    suite = tmp_path / "tiny.toml"
    suite.write_text('name = "tiny"\nseeds = 1\n[defaults]\nrobots = 3\nmax_cycles = 5\n'
                     '[[case]]\nname = "one"\n')
    out = tmp_path / "out"
    assert main(["eval", "--suite", str(suite), "--backend", "inline", "--out", str(out)]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert str(out / "report.md") in last and str(out / "report.html") in last, last
    assert main(["report", str(out)]) == 0
    said = capsys.readouterr().out
    assert str(out / "report.html") in said.strip().splitlines()[-1], said
