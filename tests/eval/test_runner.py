"""The suite runner: determinism across worker counts, resume, crash isolation."""


import pandas as pd
import pytest

from boids_env.eval.runner import EPISODES, ERRORS, PolicySpec, read_jsonl, run_suite, run_task
from boids_env.eval.suites import suite_from_dict

TINY = {"name": "tiny", "seeds": 2, "defaults": {"robots": 7, "max_cycles": 40},
        "factor": [{"name": "leader_speed", "levels": [0.5, 0.6]}]}
COLUMNS = ["V_sep", "V_coh", "V_align", "V_align_unwrapped", "min_distance", "collisions",
           "polarization", "mean_leader_distance", "steps"]


def test_same_results_with_one_or_two_workers(tmp_path):
    suite = suite_from_dict(TINY)
    one = run_suite([PolicySpec("reynolds")], suite, tmp_path / "a", workers=1, progress=False)
    two = run_suite([PolicySpec("reynolds")], suite, tmp_path / "b", workers=2, progress=False)
    assert len(one) == 4
    key = ["case", "seed"]
    pd.testing.assert_frame_equal(one.sort_values(key)[key + COLUMNS].reset_index(drop=True),
                                  two.sort_values(key)[key + COLUMNS].reset_index(drop=True))
    assert one["V_align"].nunique() > 1  # the cases and seeds really differ
    saved = pd.read_parquet(tmp_path / "a" / "results.parquet")
    assert list(saved["count_sep"].iloc[0]) == list(one["count_sep"].iloc[0])
    assert len(saved["count_sep"].iloc[0]) == 6


def test_resume_skips_finished_episodes(tmp_path):
    suite = suite_from_dict(TINY)
    calls = []

    def counting(task):
        calls.append(task.key)
        return run_task(task)

    first = run_suite([PolicySpec("reynolds")], suite.with_seeds(1), tmp_path, workers=1,
                      progress=False, runner=counting, backend="inline")
    assert len(calls) == 2 and len(first) == 2
    calls.clear()
    second = run_suite([PolicySpec("reynolds")], suite, tmp_path, workers=1, progress=False,
                       runner=counting, backend="inline")
    assert len(calls) == 2 and len(second) == 4  # only the new seed ran
    calls.clear()
    run_suite([PolicySpec("reynolds")], suite, tmp_path, workers=1, progress=False,
              runner=counting, backend="inline")
    assert calls == []
    assert len(read_jsonl(tmp_path / EPISODES)) == 4


def test_shared_configurations_run_once(tmp_path):
    spec = {"name": "shared", "seeds": 1, "defaults": {"robots": 5, "max_cycles": 20},
            "case": [{"name": "a", "leader_speed": 0.55}, {"name": "b", "leader_speed": 0.55},
                     {"name": "c", "leader_speed": 0.6}]}
    calls = []

    def counting(task):
        calls.append(task.case.name)
        return run_task(task)

    table = run_suite([PolicySpec("reynolds")], suite_from_dict(spec), tmp_path, workers=1,
                      progress=False, runner=counting, backend="inline")
    assert sorted(calls) == ["a", "c"] and list(table["case"]) == ["a", "b", "c"]
    assert table["V_align"].iloc[0] == table["V_align"].iloc[1]


def test_a_policy_that_cannot_load_is_refused_before_anything_is_written(tmp_path):
    # Before, each of its episodes failed in the workers after the folder was made.
    spec = {"name": "crash", "seeds": 1, "defaults": {"robots": 5, "max_cycles": 20},
            "case": [{"name": "ok", "leader_speed": 0.55}, {"name": "ok2", "leader_speed": 0.6}]}
    out = tmp_path / "out"
    with pytest.raises(ValueError, match="cannot import policy 'no_such_module:policy'"):
        run_suite([PolicySpec("reynolds"), PolicySpec("no_such_module:policy")],
                  suite_from_dict(spec), out, workers=2, progress=False)
    with pytest.raises(FileNotFoundError, match=r"missing\.zip"):
        run_suite([PolicySpec(str(tmp_path / "missing.zip"))], suite_from_dict(spec), out)
    assert not out.exists()


def test_module_class_specs_run_in_the_eval_workers(tmp_path):
    # Issue 14 item 3: a Policy class given as module:Class is built in each worker.
    suite = suite_from_dict({**TINY, "seeds": 1})
    ours = run_suite([PolicySpec("reynolds"),
                      PolicySpec("boids_env.policies.reynolds:ReynoldsPolicy")], suite,
                     tmp_path, workers=2, progress=False)
    assert not read_jsonl(tmp_path / ERRORS)
    by = {p: g.sort_values("case")["V_align"].tolist() for p, g in ours.groupby("policy")}
    assert by["boids_env.policies.reynolds:ReynoldsPolicy"] == by["reynolds[paper]"]


def test_runner_bad_arguments(tmp_path):
    suite = suite_from_dict(TINY)
    with pytest.raises(ValueError, match="workers"):
        run_suite([PolicySpec("reynolds")], suite, tmp_path, workers=0)
    with pytest.raises(ValueError, match="backend"):
        run_suite([PolicySpec("reynolds")], suite, tmp_path, backend="slurm")


def test_a_runner_row_that_is_not_json_is_a_failed_episode_not_a_crash(tmp_path):
    suite = suite_from_dict({**TINY, "seeds": 1})
    table = run_suite([PolicySpec("reynolds")], suite, tmp_path, backend="inline",
                      progress=False, runner=lambda task: {"V_sep": object()})
    assert table.empty and pd.read_parquet(tmp_path / "results.parquet").empty
    errors = read_jsonl(tmp_path / ERRORS)
    assert len(errors) == 2 and all("not a JSON object" in e["error"] for e in errors)


def test_the_episodes_bar_shows_on_a_terminal_only(tmp_path, monkeypatch):
    """Piped into a log (boids eval > log), the bar's redraws filled it with half lines."""
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    suite = suite_from_dict({**TINY, "seeds": 1})
    for stream, out in ((io.StringIO(), "piped"), (Terminal(), "terminal")):
        monkeypatch.setattr(sys, "stderr", stream)
        run_suite([PolicySpec("reynolds")], suite, tmp_path / out, workers=1, progress=True,
                  backend="inline")
        shown = stream.getvalue()
        if out == "piped":
            assert shown == "", shown
        else:
            assert "episodes: 100%" in shown and "2/2" in shown, shown
