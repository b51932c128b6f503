"""The eval runner isolates every failure of an episode (exceptions of any kind, dying
workers, hangs), on the process and Ray backends, and reports it; `boids eval` exits 1 then."""

import time
from pathlib import Path

import pytest

from boids_env.eval.runner import ERRORS, PolicySpec, read_jsonl, run_suite
from boids_env.eval.suites import suite_from_dict
from boids_env.train.cli import main

HERE = Path(__file__).parent
SUITE = {"name": "faulty", "seeds": 3, "defaults": {"robots": 3, "max_cycles": 10},
         "case": [{"name": "one"}]}


def _run(tmp_path, *names, **kwargs):
    policies = [PolicySpec(f"faulty_policies:{n}") for n in names]
    return run_suite(policies, suite_from_dict(SUITE), tmp_path, workers=2, progress=False,
                     **kwargs)


def _failed(tmp_path):
    return sorted((e["policy"].split(":")[1], e["seed"], e["reason"], e["error"])
                  for e in read_jsonl(tmp_path / ERRORS))


def test_any_exception_in_a_policy_fails_only_its_episode(tmp_path):
    names = ("RaisesSystemExit", "RaisesKeyboardInterrupt", "RaisesBaseException")
    table = _run(tmp_path, *names)
    failed = _failed(tmp_path)
    assert [(n, s, r) for n, s, r, _ in failed] == [(n, 1, "exception") for n in sorted(names)]
    assert "SystemExit: 3" in failed[2][3] and "KeyboardInterrupt" in failed[1][3]
    assert "BaseException: a policy raised" in failed[0][3]
    assert sorted(zip(table["policy"], table["seed"], strict=True)) == sorted(
        (f"faulty_policies:{n}", s) for n in names for s in (0, 2))


def test_a_dying_worker_fails_exactly_the_episode_it_ran(tmp_path):
    table = _run(tmp_path, "ExitsProcess", "KillsItself")
    failed = _failed(tmp_path)
    assert [(n, s, r) for n, s, r, _ in failed] == [("ExitsProcess", 1, "worker died"),
                                                    ("KillsItself", 1, "worker died")]
    assert "exit code 7" in failed[0][3] and "SIGKILL" in failed[1][3]
    assert len(table) == 4 and set(table["seed"]) == {0, 2}


def test_a_hanging_episode_is_stopped_at_the_episode_timeout(tmp_path):
    start = time.monotonic()
    table = _run(tmp_path, "Hangs", episode_timeout=3)
    elapsed = time.monotonic() - start
    assert [(n, s, r) for n, s, r, _ in _failed(tmp_path)] == [("Hangs", 1, "timeout")]
    assert sorted(table["seed"]) == [0, 2]
    assert elapsed < 20, elapsed


def test_runner_arguments_are_checked_before_anything_is_written(tmp_path):
    suite = suite_from_dict(SUITE)
    out = tmp_path / "out"
    for kwargs, match in (({"episode_timeout": 0}, "episode_timeout"),
                          ({"episode_timeout": float("nan")}, "episode_timeout"),
                          ({"workers": 0}, "workers"), ({"backend": "slurm"}, "backend"),
                          ({"runner": lambda task: {}}, "picklable")):
        with pytest.raises((ValueError, TypeError), match=match):
            run_suite([PolicySpec("reynolds")], suite, out, progress=False, **kwargs)
    with pytest.raises(ValueError, match="given twice"):
        run_suite([PolicySpec("reynolds"), PolicySpec("reynolds")], suite, out)
    assert not out.exists()


def test_workers_that_cannot_start_are_a_clear_error_not_failed_episodes(tmp_path):
    from faulty_policies import UnstartableRunner

    with pytest.raises(ChildProcessError, match="could not start"):
        run_suite([PolicySpec("reynolds")], suite_from_dict(SUITE), tmp_path, workers=2,
                  progress=False, runner=UnstartableRunner())
    assert not (tmp_path / ERRORS).exists()


def test_ray_backend_isolates_failures_like_the_process_backend(tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": str(HERE)}})
    suite = suite_from_dict(SUITE)
    try:
        # Ray times a task from its submission (at most `workers` in flight): leave room for
        # a worker's first import on a loaded machine (12 s, and once 30 s, timed out a seed
        # that does not hang, in a CI run beside other work: a crashed worker's replacement
        # imports everything again)
        table = _run(tmp_path, "Hangs", "RaisesSystemExit", "ExitsProcess", backend="ray",
                     episode_timeout=60)
        remote = run_suite([PolicySpec("reynolds")], suite, tmp_path / "r", backend="ray",
                           progress=False)
    finally:
        ray.shutdown()
    failed = _failed(tmp_path)
    assert [(n, s, r) for n, s, r, _ in failed] == [
        ("ExitsProcess", 1, "worker died"), ("Hangs", 1, "timeout"),
        ("RaisesSystemExit", 1, "exception")], failed
    assert len(table) == 6 and set(table["seed"]) == {0, 2}
    # and the rows it does produce are the process backend's
    local = run_suite([PolicySpec("reynolds")], suite, tmp_path / "p", workers=1,
                      progress=False)
    assert remote["V_align"].tolist() == local["V_align"].tolist()


def test_boids_eval_exits_1_and_the_report_lists_failed_episodes(tmp_path, capsys):
    suite = tmp_path / "faulty.toml"
    suite.write_text('name = "faulty"\nseeds = 3\n[defaults]\nrobots = 3\nmax_cycles = 10\n'
                     '[[case]]\nname = "one"\n')
    out = tmp_path / "out"
    code = main(["eval", "--policy", "reynolds", "--policy", "faulty_policies:RaisesSystemExit",
                 "--suite", str(suite), "--workers", "2", "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "1 episodes failed" in err and "SystemExit: 3" in err
    report = (out / "report.md").read_text()
    assert "## Failed episodes" in report
    page = (out / "report.html").read_text()  # names are escaped in the Markdown
    assert "faulty_policies:RaisesSystemExit" in page and "SystemExit: 3" in page


def test_boids_eval_exits_1_when_every_episode_failed(tmp_path, capsys):
    suite = tmp_path / "faulty.toml"
    suite.write_text('name = "faulty"\nseeds = [1]\n[defaults]\nrobots = 3\n'
                     'max_cycles = 10\n[[case]]\nname = "one"\n')
    out = tmp_path / "out"
    code = main(["eval", "--policy", "faulty_policies:ExitsProcess", "--suite", str(suite),
                 "--workers", "1", "--out", str(out), "--no-progress"])
    assert code == 1
    assert "all 1 episodes failed" in capsys.readouterr().err
    assert read_jsonl(out / ERRORS)[0]["reason"] == "worker died"
