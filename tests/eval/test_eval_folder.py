"""An eval folder is never mixed and never left torn: another evaluation is refused unless
--overwrite (which removes only what ours wrote), results are written atomically, trajectory
files are named by policy, case and seed, and damaged files never break a report or a rerun."""

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet
import pytest

from boids_env.eval.folder import MANIFEST
from boids_env.eval.report import build_report
from boids_env.eval.runner import (
    EPISODES,
    PolicySpec,
    plan,
    read_jsonl,
    run_suite,
    trajectory_name,
)
from boids_env.eval.suites import suite_from_dict
from boids_env.files import atomic_path, write_json
from boids_env.train.cli import main

TINY = {"name": "tiny", "seeds": 2, "defaults": {"robots": 3, "max_cycles": 10},
        "factor": [{"name": "leader_speed", "levels": [0.5, 0.6]}]}
OTHER = {**TINY, "name": "other", "factor": [{"name": "leader_speed", "levels": [0.7]}]}


def _run(out, spec=TINY, policies=("reynolds",), **kwargs):
    return run_suite([PolicySpec(p) for p in policies], suite_from_dict(spec), out,
                     workers=2, progress=False, **kwargs)


def test_another_suite_or_policy_set_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "out"
    _run(out)
    (out / "notes.txt").write_text("mine")
    first = sorted(p.name for p in (out / "trajectories").iterdir())
    with pytest.raises(ValueError, match=r"suite 'tiny' .* this run is suite 'other'.*--overwrite"):
        _run(out, OTHER)
    with pytest.raises(ValueError, match="random"):
        _run(out, policies=("reynolds", "random"))
    assert sorted(p.name for p in (out / "trajectories").iterdir()) == first  # untouched
    table = _run(out, OTHER, overwrite=True)
    assert set(table["case"]) == {"leader_speed=0.7"}
    assert (out / "notes.txt").read_text() == "mine"  # not ours: kept
    assert not set(first) & {p.name for p in (out / "trajectories").iterdir()}
    assert {r["key"] for r in read_jsonl(out / EPISODES)} == set(table["key"])
    assert json.loads((out / MANIFEST).read_text())["identity"]["name"] == "other"


def test_more_seeds_of_the_same_evaluation_resume(tmp_path):
    _run(tmp_path, {**TINY, "seeds": 1})
    table = _run(tmp_path)
    assert len(table) == 4 and len(read_jsonl(tmp_path / EPISODES)) == 4


def test_a_folder_we_did_not_write_is_refused_and_overwrite_keeps_its_files(tmp_path):
    (tmp_path / "data.csv").write_text("a,b\n")
    with pytest.raises(ValueError, match=r"not written by boids eval .*data.csv"):
        _run(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.csv"]
    _run(tmp_path, overwrite=True)
    assert (tmp_path / "data.csv").read_text() == "a,b\n"


def test_eval_cli_refuses_a_mixed_folder_and_a_file_as_out(tmp_path, capsys):
    suite = tmp_path / "tiny.toml"
    suite.write_text('name = "tiny"\nseeds = 1\n[defaults]\nrobots = 3\nmax_cycles = 10\n'
                     '[[case]]\nname = "a"\n')
    other = tmp_path / "other.toml"
    other.write_text(suite.read_text().replace('"a"', '"b"'))
    out = tmp_path / "out"
    args = ["eval", "--workers", "1", "--no-progress", "--out", str(out), "--suite"]
    assert main([*args, str(suite)]) == 0
    figures = {p.name for p in (out / "figures").iterdir()}
    assert "report.md" in json.loads((out / MANIFEST).read_text())["files"]
    capsys.readouterr()
    assert main([*args, str(other)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main([*args, str(other), "--overwrite"]) == 0
    assert set(pd.read_parquet(out / "results.parquet")["case"]) == {"b"}
    # the first run's figure of case a is gone with the folder it was in
    assert "traj_reynolds_paper_a.png" in figures
    assert {p.name for p in (out / "figures").iterdir()} == {
        f"{name}.{ext}" for name in ("reynolds_paper_cases", "traj_reynolds_paper_b", "safety")
        for ext in ("png", "svg")}
    file_out = tmp_path / "a_file"
    file_out.write_text("x")
    assert main(["eval", "--out", str(file_out), "--suite", str(suite)]) == 2
    assert "is an existing file" in capsys.readouterr().err
    assert file_out.read_text() == "x"


def test_trajectory_files_are_named_by_policy_case_and_seed(tmp_path):
    spec = {"name": "names", "seeds": [3, 4], "defaults": {"robots": 3, "max_cycles": 10},
            "case": [{"name": "a/b c:d"}, {"name": "a b c d", "leader_speed": 0.6},
                     {"name": "ünïcode", "leader_speed": 0.7}]}
    tasks = plan([PolicySpec("reynolds"), PolicySpec("random")], suite_from_dict(spec),
                 str(tmp_path), all_trajectories=True)
    names = [Path(t.trajectory).name for t in tasks]
    assert len(set(names)) == len(names) == 12
    # "a/b c:d" and "a b c d" slug alike: both get a short key to stay unique
    assert names[0].startswith("reynolds_paper__a_b_c_d__seed3__") and names[0] != names[2]
    assert "random__n_code__seed4.parquet" in names
    assert all(n.isascii() and "/" not in n and ":" not in n and not n.startswith(".")
               for n in names)
    assert trajectory_name(PolicySpec("learned"), suite_from_dict(spec).cases[2], 4) == \
        "learned__n_code__seed4.parquet"


def test_a_truncated_trajectory_breaks_neither_the_report_nor_a_rerun(tmp_path):
    _run(tmp_path)
    build_report(tmp_path)
    victim = sorted((tmp_path / "trajectories").iterdir())[0]
    victim.write_bytes(victim.read_bytes()[:200])
    report = build_report(tmp_path).read_text()
    assert "not shown" in report and "seed 0" in report
    calls_before = len(read_jsonl(tmp_path / EPISODES))
    table = _run(tmp_path)
    assert len(table) == 4
    assert len(read_jsonl(tmp_path / EPISODES)) == calls_before + 1  # only that episode reran
    pd.read_parquet(victim)  # whole again
    assert "not shown" not in build_report(tmp_path).read_text()


def test_a_torn_episodes_line_never_glues_onto_the_next_row(tmp_path):
    _run(tmp_path, {**TINY, "seeds": 1})
    with (tmp_path / EPISODES).open("a") as fh:
        fh.write('{"key": "torn", "V_sep": 0.')  # an interrupted append
    table = _run(tmp_path)
    assert len(table) == 4
    lines = (tmp_path / EPISODES).read_text().splitlines()
    assert lines[2] == '{"key": "torn", "V_sep": 0.'
    assert all(json.loads(line)["key"] for line in lines[:2] + lines[3:])


def test_results_survive_a_full_disk(tmp_path, monkeypatch):
    _run(tmp_path, {**TINY, "seeds": 1})
    before = pd.read_parquet(tmp_path / "results.parquet")

    def disk_full(table, path, *args, **kwargs):
        Path(path).write_bytes(b"PAR1 partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pyarrow.parquet, "write_table", disk_full)
    with pytest.raises(OSError, match="No space"):
        _run(tmp_path)
    monkeypatch.undo()
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "results.parquet"), before)
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def _killed_write(target):
    """What a write of ``target`` killed half-way leaves (a child process dies inside
    ``atomic_path``, its cleanup never running); returns its temporary folder."""
    before = set(target.parent.iterdir())
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        try:
            with atomic_path(target) as tmp:
                tmp.write_bytes(b"PAR1 torn")
                os._exit(0)
        finally:
            os._exit(1)
    os.waitpid(pid, 0)
    (box,) = set(target.parent.iterdir()) - before
    return box


def test_temporaries_left_by_a_killed_write_are_cleared_on_resume(tmp_path):
    _run(tmp_path, {**TINY, "seeds": 1})
    dead = _killed_write(tmp_path / "results.parquet")
    dead_traj = _killed_write(tmp_path / "trajectories" / "x.parquet")
    with atomic_path(tmp_path / "trajectories" / "y.parquet") as live:  # this process: alive
        live.write_bytes(b"being written")
        _run(tmp_path)
        assert live.exists()
    assert not dead.exists() and not dead_traj.exists()


def test_a_users_file_named_like_a_temporary_is_never_removed(tmp_path):
    _run(tmp_path, {**TINY, "seeds": 1})
    mine = tmp_path / ".results.parquet.tmp-999999999-0123abcd"  # no such process
    mine.write_text("my notes")
    folder = tmp_path / ".trajectories.tmp-999999999-89abcdef"
    folder.mkdir()
    (folder / "data.csv").write_text("1,2\n")
    _run(tmp_path)  # resume
    _run(tmp_path, OTHER, overwrite=True)
    assert mine.read_text() == "my notes" and (folder / "data.csv").read_text() == "1,2\n"


def test_overwrite_removes_only_names_an_evaluation_writes(tmp_path):
    """A manifest is a file anyone can edit: the entries it lists are removed only when they
    are names boids eval writes."""
    out = tmp_path / "out"
    _run(out)
    (out / "my_thesis_data.csv").write_text("precious")
    (out / "thesis").mkdir()
    (out / "thesis" / "ch1.tex").write_text("precious too")
    (tmp_path / "outside.txt").write_text("not in the folder")
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"] += ["my_thesis_data.csv", "thesis", "../outside.txt", "..", "."]
    (out / MANIFEST).write_text(json.dumps(manifest))
    _run(out, OTHER, overwrite=True)
    assert (out / "my_thesis_data.csv").read_text() == "precious"
    assert (out / "thesis" / "ch1.tex").read_text() == "precious too"
    assert (tmp_path / "outside.txt").is_file()
    assert not set(json.loads((out / MANIFEST).read_text())["files"]) & {
        "my_thesis_data.csv", "thesis"}


def test_a_folder_of_another_command_is_refused_even_with_overwrite(tmp_path):
    write_json(tmp_path / MANIFEST, {"kind": "boids train", "identity": {},
                                     "files": ["model.zip"]})
    (tmp_path / "model.zip").write_bytes(b"weights")
    with pytest.raises(ValueError, match=r"belongs to boids train .*even with --overwrite"):
        _run(tmp_path, overwrite=True)
    assert (tmp_path / "model.zip").read_bytes() == b"weights"


def test_a_damaged_results_table_is_refused_not_reported(tmp_path):
    from boids_env.eval.report import load_results

    _run(tmp_path, {**TINY, "seeds": 1})
    path = tmp_path / "results.parquet"
    raw, (table, _) = path.read_bytes(), load_results(tmp_path)
    changed = []
    for at in np.linspace(4, len(raw) - 9, 60).astype(int):
        flipped = bytearray(raw)
        flipped[at] ^= 0x5A
        path.write_bytes(bytes(flipped))
        try:
            back, _ = load_results(tmp_path)
        except ValueError:
            continue
        if not back.equals(table):
            changed.append(int(at))
    assert not changed, f"flips at bytes {changed} of {len(raw)} changed the results"


def _edit_walk(folder):
    (folder / "walk.csv").write_text("t,x,y\n0,0,0\n1,0,1\n")


def _edit_shapes(folder):
    (folder / "room.toml").write_text('box = [-4.0, -4.0, 4.0, 4.0]\n[[circle]]\n'
                                      'center = [3.0, 3.0]\nradius = 0.3\n')


def _edit_map_image(folder):
    from boids_env.world.maps import write_map

    cells = np.zeros((40, 40), dtype=np.int8)
    cells[0, :] = 100
    write_map(folder / "map.yaml", cells, 0.25, (-5.0, -5.0, 0.0))  # same YAML, new image


@pytest.mark.parametrize(("edit", "edited"), [(_edit_walk, "walk.csv"),
                                              (_edit_shapes, "room.toml"),
                                              (_edit_map_image, "map.pgm")])
def test_a_file_a_case_reads_edited_between_runs_is_not_resumed(tmp_path, edit, edited):
    # issue 39 item 3: the folder's identity recorded the file paths only, so a resume after
    # editing a walk, map or shapes file mixed episodes of both versions in one results.csv
    from boids_env.world.maps import write_map

    (tmp_path / "walk.csv").write_text("t,x,y\n0,0,0\n1,1,0\n")
    (tmp_path / "room.toml").write_text("box = [-4.0, -4.0, 4.0, 4.0]\n")
    write_map(tmp_path / "map.yaml", np.zeros((40, 40), dtype=np.int8), 0.25, (-5.0, -5.0, 0.0))
    spec = {"name": "files", "seeds": 1,
            "defaults": {"robots": 3, "max_cycles": 5, "path_size": 2.0},
            "case": [{"name": "walk", "leader": "trajectory",
                      "leader_trajectory": str(tmp_path / "walk.csv")},
                     {"name": "shapes", "scene": str(tmp_path / "room.toml")},
                     {"name": "map", "scene": str(tmp_path / "map.yaml")}]}
    out = tmp_path / "out"
    _run(out, spec)
    assert len(_run(out, {**spec, "seeds": 2})) == 6, "unchanged files: more seeds resume"
    edit(tmp_path)
    with pytest.raises(ValueError,
                       match=rf"content of the files.*edited since: \['[^']*{edited}'\]"):
        _run(out, {**spec, "seeds": 3})
    assert len(read_jsonl(out / EPISODES)) == 6, "nothing of the edited files was added"
    table = _run(out, {**spec, "seeds": 3}, overwrite=True)
    assert len(table) == 9 and len(read_jsonl(out / EPISODES)) == 9, "all rerun"
