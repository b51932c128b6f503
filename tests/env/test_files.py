"""Atomic writes: a failed write leaves the previous file (or folder) untouched."""

import pytest

from boids_env import files


def test_write_replaces_only_when_complete(tmp_path):
    target = tmp_path / "a.json"
    files.write_json(target, {"x": 1})
    assert target.read_text() == '{\n  "x": 1\n}\n'
    with pytest.raises(RuntimeError), files.atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk full")
    assert target.read_text() == '{\n  "x": 1\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"], "no temporary left behind"


def test_a_folder_is_replaced_as_a_whole(tmp_path):
    target = tmp_path / "bag"
    target.mkdir()
    (target / "old.mcap").write_text("old")
    with files.atomic_path(target) as tmp:
        tmp.mkdir()
        (tmp / "new.mcap").write_text("new")
    assert [p.name for p in target.iterdir()] == ["new.mcap"]
    with pytest.raises(OSError), files.atomic_path(target) as tmp:
        tmp.mkdir()
        raise OSError("no space left")
    assert [p.name for p in target.iterdir()] == ["new.mcap"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_append_line_never_glues_onto_a_torn_line(tmp_path):
    log = tmp_path / "episodes.jsonl"
    files.append_line(log, '{"a": 1}')
    with open(log, "a") as fh:
        fh.write('{"b": 2, "trunc')  # a write torn by a kill
    files.append_line(log, '{"c": 3}')
    assert log.read_text().splitlines() == ['{"a": 1}', '{"b": 2, "trunc', '{"c": 3}']


def test_write_json_writes_non_finite_floats_as_null(tmp_path):
    """NaN (a metric that does not apply) is not JSON: strict readers refused the file."""
    import json

    import numpy as np

    from boids_env.files import write_json

    path = write_json(tmp_path / "m.json", {"a": float("nan"), "b": [np.inf, 1.5, np.float64(2)],
                                            "c": {"d": (-np.inf, "x")}, "e": None})

    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")

    assert json.loads(path.read_text(), parse_constant=refuse) == {
        "a": None, "b": [None, 1.5, 2.0], "c": {"d": [None, "x"]}, "e": None}
