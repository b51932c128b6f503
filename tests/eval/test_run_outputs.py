"""`boids run`'s output folder: a run owns it, --overwrite replaces only what an earlier run
of ours wrote, and a failed or killed run leaves the earlier folder as it was."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from boids_env.eval.outputs import MANIFEST, RunFolder
from boids_env.eval.run import run
from boids_env.files import write_json
from boids_env.train.cli import main

FIELDS = {"robots": 3, "max_cycles": 6}


def _run(out, seed=0, **kwargs):
    return run(out=out, seed=seed, env_fields=FIELDS, quiet=True, **kwargs)


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_a_run_writes_a_manifest_of_exactly_its_files(tmp_path):
    out = tmp_path / "run"
    _run(out)
    assert _names(out) == ["config.json", MANIFEST, "metrics.json", "trajectory.parquet"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["files"] == ["config.json", "metrics.json", "trajectory.parquet"], manifest
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], \
        f"no temporary folder left beside the run: {_names(tmp_path)}"


def test_an_empty_folder_is_used(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    _run(out)
    assert "metrics.json" in _names(out)


def test_a_non_empty_folder_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "run"
    _run(out)
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    with pytest.raises(FileExistsError, match=r"is not empty .*--overwrite"):
        _run(out, seed=3)
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before, "nothing touched"
    assert main(["run", "--robots", "3", "--max-cycles", "4", "--out", str(out)]) == 2
    assert "pass --overwrite" in capsys.readouterr().err


def test_overwrite_replaces_the_earlier_run_and_keeps_the_users_files(tmp_path):
    out = tmp_path / "run"
    _run(out, seed=0, video="gif")
    assert "episode.gif" in _names(out)
    (out / "notes.txt").write_text("mine")
    (out / "plots").mkdir()
    (out / "plots" / "a.png").write_bytes(b"x")
    result = _run(out, seed=3, overwrite=True)
    names = _names(out)
    assert "episode.gif" not in names, f"the earlier run's video is stale: {names}"
    assert {"notes.txt", "plots", "metrics.json"} <= set(names), names
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "plots" / "a.png").is_file()
    config = json.loads((out / "config.json").read_text())
    assert config["seed"] == 3
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["V_align"] == result.metrics["V_align"]
    assert json.loads((out / MANIFEST).read_text())["files"] == [
        "config.json", "metrics.json", "trajectory.parquet"]


def test_overwrite_of_a_folder_holding_only_our_run_swaps_it_whole(tmp_path):
    out = tmp_path / "run"
    _run(out, seed=0, video="gif")
    _run(out, seed=1, overwrite=True)
    assert _names(out) == ["config.json", MANIFEST, "metrics.json", "trajectory.parquet"]
    assert _names(tmp_path) == ["run"], "no temporary or old folder left"


def test_overwrite_never_deletes_an_unlisted_output_or_a_forged_entry(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "episode.gif").write_bytes(b"GIF89a from an older version")
    with pytest.raises(FileExistsError, match=r"episode\.gif.*no manifest\.json lists"):
        _run(out, overwrite=True)
    assert (out / "episode.gif").read_bytes().startswith(b"GIF89a from")
    # a manifest that lists a user's file: only our own names are ever removed
    (out / "episode.gif").unlink()
    (out / "thesis.tex").write_text("precious")
    write_json(out / MANIFEST, {"files": ["thesis.tex", "../escape"]})
    _run(out, overwrite=True)
    assert (out / "thesis.tex").read_text() == "precious"


def test_a_failed_run_leaves_the_earlier_folder_as_it_was(tmp_path):
    out = tmp_path / "run"
    _run(out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    folder = RunFolder(out, overwrite=True)
    with pytest.raises(RuntimeError, match="boom"), folder as tmp:
        write_json(tmp / "metrics.json", {"V_sep": -1})
        raise RuntimeError("boom")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _names(tmp_path) == ["run"], "the temporary folder is removed"


@pytest.mark.slow
def test_a_killed_run_leaves_the_earlier_folder_as_it_was(tmp_path):
    out = tmp_path / "run"
    _run(out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "boids_env.train.cli", "run", "--robots", "13", "--video",
         "--overwrite", "--out", str(out)], env=env, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not any(p.name.startswith(".run.run-") for p in tmp_path.iterdir()):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    time.sleep(0.5)  # writing into the temporary folder
    proc.send_signal(signal.SIGKILL)
    proc.wait(30)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before, \
        "the earlier run's folder is untouched by a killed run"


def test_out_naming_a_file_is_refused(tmp_path):
    (tmp_path / "f").write_text("")
    with pytest.raises(FileExistsError, match="is a file"):
        _run(tmp_path / "f")


OLD = {"metrics.json": b"old", "config.json": b"old", "episode.gif": b"old",
       "episode_mcap/episode_mcap.mcap": b"old"}
NEW = {"metrics.json": b"new", "config.json": b"new", "trajectory.parquet": b"new",
       "episode_mcap/episode_mcap.mcap": b"new"}


def _put(folder, files):
    for name, data in files.items():
        (folder / name).parent.mkdir(exist_ok=True)
        (folder / name).write_bytes(data)


def _write(out, files, **kwargs):
    with RunFolder(out, **kwargs) as tmp:
        _put(tmp, files)


def _killed_in_commit(out, files, k, can_exchange=True):
    """Writes ``files`` as a run into ``out`` in a child process that SIGKILLs itself at the
    k-th rename of the commit (a file replaced, a folder moved or exchanged); returns whether
    it was killed (False: the commit has fewer than k renames)."""
    from boids_env import temporaries

    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        try:
            with RunFolder(out, overwrite=True) as tmp:
                _put(tmp, files)
                calls = [0]

                def dying(real):
                    def call(*args, **kwargs):
                        calls[0] += 1
                        if calls[0] == k:
                            os.kill(os.getpid(), signal.SIGKILL)
                        return real(*args, **kwargs)
                    return call

                os.rename, os.replace = dying(os.rename), dying(os.replace)
                temporaries.exchange = (dying(temporaries.exchange) if can_exchange
                                        else lambda a, b: False)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    return os.WIFSIGNALED(status)


def _contents(out):
    return {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*")
            if p.is_file() and p.name != MANIFEST}


@pytest.mark.parametrize("mine, can_exchange", [({}, True), ({}, False),
                                                 ({"notes.txt": b"mine"}, True)],
                         ids=["only-ours", "only-ours-no-exchange", "with-users-files"])
def test_a_run_killed_at_any_point_of_its_commit_leaves_one_whole_run(tmp_path, mine,
                                                                      can_exchange):
    """Killed at each rename of the final moves, the folder is there and holds the earlier
    run or the new one (never none, never a mix of both) once the next run into it has
    cleared what the killed one left; with nothing of the user's in it, and where the OS
    exchanges two names, it is whole at every instant."""
    old, new = {**OLD, **mine}, {**NEW, **mine}
    for k in range(1, 20):
        out = tmp_path / f"k{k}" / "run"
        _write(out, OLD)
        for name, data in mine.items():
            (out / name).write_bytes(data)
        killed = _killed_in_commit(out, NEW, k, can_exchange)
        if not mine and can_exchange:
            assert out.is_dir() and _contents(out) in (old, new), (k, _contents(out))
        if mine:  # the user's files never move
            assert out.is_dir() and mine.items() <= _contents(out).items(), k
        RunFolder(out, overwrite=True)  # the next run into the folder
        assert _contents(out) in (old, new), (k, _contents(out))
        listed = json.loads((out / MANIFEST).read_text())["files"]
        assert set(listed) == {n.split("/")[0] for n in _contents(out)} - set(mine), k
        assert _names(out.parent) == ["run"], (k, _names(out.parent))
        if not killed:
            assert _contents(out) == new
            break
    else:
        pytest.fail("the commit never finished")


def test_what_a_killed_run_leaves_beside_out_is_removed_by_the_next_run(tmp_path):
    out = tmp_path / "run"
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child, killed while writing
        try:
            with RunFolder(out) as tmp:
                (tmp / "metrics.json").write_text("{}")
                os._exit(0)
        finally:
            os._exit(1)
    os.waitpid(pid, 0)
    (left,) = [p for p in tmp_path.iterdir() if p.name.startswith(".run.run-")]
    users = tmp_path / ".run.run-999999999-0123abcd"  # a name like ours, no marker
    users.mkdir()
    (users / "data.csv").write_text("1,2\n")
    lookalike = tmp_path / ".run.run-999999998-89abcdef"
    lookalike.write_text("a file")
    _run(out)
    assert not left.exists(), "the killed run's temporary folder is removed"
    assert (users / "data.csv").read_text() == "1,2\n" and lookalike.read_text() == "a file"
    assert sorted(_names(tmp_path)) == sorted(["run", users.name, lookalike.name])


def test_boids_run_refuses_an_eval_folder_even_with_overwrite(tmp_path):
    write_json(tmp_path / MANIFEST, {"kind": "boids eval", "identity": {},
                                     "files": ["results.parquet"]})
    with pytest.raises(FileExistsError, match="belongs to boids eval"):
        _run(tmp_path, overwrite=True)
