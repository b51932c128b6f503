"""The bounded reader every file from elsewhere goes through (boids_env.untrusted)."""

import os
import zipfile

import pytest

from boids_env import untrusted
from boids_env.world import scene as scene_module
from boids_env.world.scenes import arena


def test_read_bytes_refuses_by_size_before_reading(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"x" * 101)
    with pytest.raises(ValueError, match=r"field .*/f: 101 bytes, more than the 100 allowed"):
        untrusted.read_bytes(path, "field", 100)
    assert untrusted.read_bytes(path, "field", 101) == b"x" * 101
    with pytest.raises(ValueError, match=r"not a regular file \(a folder\)"):
        untrusted.read_bytes(tmp_path, "field", 100)


def test_excerpt_is_short_and_escaped_whatever_the_value():
    shared = ["lol"] * 9
    for _ in range(8):  # 9**8 items if printed in full
        shared = [shared] * 9
    text = untrusted.excerpt(shared)
    assert len(text) <= untrusted.EXCERPT
    assert untrusted.excerpt("\x1b[31mred") == "'\\x1b[31mred'"
    assert untrusted.excerpt("x" * 500).endswith("…") and len(untrusted.excerpt("x" * 500)) == 60


def test_safe_name_bounds_and_escapes():
    assert untrusted.safe_name("a\x1b]0;t\x07\nb", "n") == "a\\x1b]0;t\\x07 b"
    with pytest.raises(ValueError, match="n must be at most 100 characters, got 101"):
        untrusted.safe_name("y" * 101, "n")
    with pytest.raises(ValueError, match="n must be a non-empty string"):
        untrusted.safe_name(5, "n")


def test_yaml_merge_keys_and_small_anchors_still_read():
    data = untrusted.parse_yaml("x: &x {a: 1}\ny: {<<: *x, b: 2}\nz: [*x, *x]\n", "f")
    assert data == {"x": {"a": 1}, "y": {"a": 1, "b": 2}, "z": [{"a": 1}, {"a": 1}]}


def test_check_depth_walks_without_recursion():
    deep = []
    for _ in range(100_000):
        deep = [deep]
    with pytest.raises(ValueError, match="f: nested more than 32 levels deep"):
        untrusted.check_depth(deep, "f")
    assert untrusted.check_depth({"a": [[1]]}, "f") == {"a": [[1]]}


def test_open_zip_refuses_special_files_and_too_many_entries(tmp_path, monkeypatch):
    fifo = tmp_path / "m.zip"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match=r"not a regular file \(a FIFO"):
        untrusted.open_zip(fifo)
    many = tmp_path / "many.zip"
    with zipfile.ZipFile(many, "w") as zf:
        for k in range(5):
            zf.writestr(f"e{k}", b"")
    monkeypatch.setattr(untrusted, "MAX_ZIP_ENTRIES", 4)
    with pytest.raises(ValueError, match="5 entries, more than the 4 allowed"):
        untrusted.open_zip(many)


def test_a_huge_arena_is_rasterised_with_coarser_cells(monkeypatch):
    assert arena(5.0).occupancy().resolution == 0.05, "the study's arena is unchanged"
    monkeypatch.setattr(scene_module, "MAX_RASTER", 64)  # 4096 in use: too big for a test
    grid = arena(1000.0).occupancy()
    assert grid.resolution == 2000.0 / 64
    assert grid.cells.shape == (66, 66)
