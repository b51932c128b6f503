"""Temporary folders are removed only when provably ours and abandoned, and a journal moves
only names its caller writes."""

import json
import os
import socket

from boids_env import temporaries

DEAD = 999_999_999  # no such process


def _box(folder, target="out", tag="run", pid=DEAD, host=None, marker=True):
    box = folder / f".{target}.{tag}-{pid}-0123abcd"
    box.mkdir()
    if marker:
        (box / temporaries.MARKER).write_text(json.dumps({
            "written_by": temporaries.PROGRAM, "host": host or socket.gethostname(),
            "pid": pid, "target": target, "tag": tag}))
    return box


def test_only_our_abandoned_folders_are_stale(tmp_path):
    ours = _box(tmp_path)
    live = _box(tmp_path, target="b", pid=os.getpid())
    elsewhere = _box(tmp_path, target="c", host="another-host")
    unmarked = _box(tmp_path, target="d", marker=False)
    linked = _box(tmp_path, target="e", marker=False)
    (linked / temporaries.MARKER).symlink_to(ours / temporaries.MARKER)
    as_file = tmp_path / f".f.run-{DEAD}-0123abcd"
    as_file.write_text("a user's file")
    assert temporaries.stale(tmp_path) == [ours]
    assert temporaries.stale(tmp_path, "other") == []
    assert temporaries.clear_stale(tmp_path) == [ours]
    assert all(p.exists() for p in (live, elsewhere, unmarked, linked, as_file))


def test_a_journal_moves_only_allowed_names(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "thesis.tex").write_text("precious")
    box = _box(tmp_path)
    (box / "new").mkdir()
    (box / "new" / "thesis.tex").write_text("forged")
    (box / temporaries.JOURNAL).write_text(json.dumps({"from": "new", "names": ["thesis.tex"],
                                                       "remove": []}))
    allowed = {"out", "metrics.json"}.__contains__
    assert temporaries.clear_stale(tmp_path, "out", allowed) == []
    assert (tmp_path / "out" / "thesis.tex").read_text() == "precious"
    assert box.exists(), "left as it is: it may hold the only copy of an output"


def test_a_cut_short_swap_is_completed(tmp_path):
    box = _box(tmp_path)
    (box / "new").mkdir()
    (box / "new" / "metrics.json").write_text("new")
    (box / temporaries.JOURNAL).write_text(json.dumps({"swap": "new"}))
    (box / "old").mkdir()  # killed after moving the earlier folder aside
    temporaries.clear_stale(tmp_path, "out", {"out"}.__contains__)
    assert (tmp_path / "out" / "metrics.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
