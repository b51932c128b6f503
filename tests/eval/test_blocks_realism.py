"""`boids eval --blocks K` (the study's 5-run design repeated) and `--realism` on run/eval."""

import json

import pandas as pd
import pytest

from boids_env.eval.report import build_report
from boids_env.eval.runner import PolicySpec, run_suite
from boids_env.eval.suites import PAPER
from boids_env.train.cli import main


def test_blocks_are_consecutive_five_seed_blocks_and_realism_reaches_every_case():
    assert PAPER.with_blocks(3).seeds == tuple(range(15))
    assert PAPER.with_blocks(None) is PAPER
    suite = PAPER.with_env(realism="ros")
    assert all(c.env["realism"] == "ros" for c in suite.cases)
    assert [c.env for c in PAPER.cases] != [c.env for c in suite.cases]  # PAPER untouched
    assert all("realism" not in c.env for c in PAPER.cases)


@pytest.mark.parametrize("blocks", [0, -1, 2001, 1.5, True])
def test_bad_blocks_are_refused_naming_the_range(blocks):
    with pytest.raises((ValueError, TypeError), match=r"blocks.*2000"):
        PAPER.with_blocks(blocks)


def test_bad_realism_is_refused_naming_the_choices():
    with pytest.raises(ValueError, match=r"realism must be one of \('none', 'ros'\)"):
        PAPER.with_env(realism="stage")


def test_eval_cli_refuses_blocks_with_seeds_and_a_bad_realism(capsys, tmp_path):
    out = str(tmp_path / "out")
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--blocks", "2", "--seeds", "3", "--out", out])
    assert exc.value.code == 2 and "not allowed with argument" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--realism", "stage", "--out", out])
    assert exc.value.code == 2 and "invalid choice: 'stage'" in capsys.readouterr().err
    assert main(["eval", "--blocks", "0", "--out", out]) == 2
    assert "blocks must be" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_each_block_scores_what_a_five_seed_evaluation_of_its_seeds_reports(tmp_path):
    short = PAPER.with_env(max_cycles=25)
    policy = [PolicySpec("reynolds", "paper")]
    both = tmp_path / "blocks"
    run_suite(policy, short.with_blocks(2), both, workers=2, progress=False)
    build_report(both)
    blocks = pd.read_csv(both / "blocks.csv")
    assert list(blocks["seeds"]) == ["0-4", "5-9"] and list(blocks["of"]) == [27, 27]
    report = (both / "report.md").read_text()
    assert "Reproduction score in blocks of 5 seeds" in report
    # the second block's score is exactly what an evaluation of its 5 seeds alone reports
    # (the first block's seeds are an evaluation's own first five: nothing to offset)
    for row in list(blocks.itertuples())[1:]:
        first = int(row.seeds.split("-")[0])
        alone = tmp_path / f"alone_{row.block}"
        run_suite(policy, short.with_seeds(list(range(first, first + 5))), alone, workers=2,
                  progress=False)
        build_report(alone)
        verdicts = pd.read_csv(alone / "verdicts_reynolds_paper.csv")
        assert row.findings == int((verdicts.verdict == "reproduced").sum())
        assert not (alone / "blocks.csv").exists()  # one block: no block section
        assert f"{row.findings} of 27 findings reproduced" in (alone / "report.md").read_text()


def test_run_with_realism_ros_differs_from_the_ideal_world_and_says_so(tmp_path, capsys):
    args = ["run", "--max-cycles", "60", "--seed", "2"]
    assert main([*args, "--out", str(tmp_path / "ideal")]) == 0
    ideal = capsys.readouterr().out
    assert main([*args, "--out", str(tmp_path / "none"), "--realism", "none"]) == 0
    capsys.readouterr()
    assert main([*args, "--out", str(tmp_path / "ros"), "--realism", "ros"]) == 0
    assert "realism ros" in capsys.readouterr().out and "realism" not in ideal.splitlines()[0]
    metrics = {name: json.loads((tmp_path / name / "metrics.json").read_text())
               for name in ("ideal", "none", "ros")}
    assert metrics["none"] == metrics["ideal"]
    assert metrics["ros"] != metrics["ideal"]
    config = json.loads((tmp_path / "ros" / "config.json").read_text())
    assert config["env"]["realism"]["realism"] == "ros"
