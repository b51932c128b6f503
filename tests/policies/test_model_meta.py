"""Model metadata: writing it never truncates the model; bad metadata is a clear error."""

import errno
import json
import zipfile

import pytest

pytest.importorskip("stable_baselines3")

from boids_env.policies.registry import LEARNED_MODEL
from boids_env.policies.sb3_policy import (
    META_ENTRY,
    SB3Policy,
    load_model_policy,
    read_meta,
    write_meta,
)


def model_copy(tmp_path):
    path = tmp_path / "model.zip"
    path.write_bytes(LEARNED_MODEL.read_bytes())
    return path


def test_write_meta_replaces_the_entry_and_keeps_the_model(tmp_path):
    path = model_copy(tmp_path)
    write_meta(path, {"algorithm": "ppo", "env_fields": {"neighbours": 6}, "note": "x"})
    assert read_meta(path)["note"] == "x"
    with zipfile.ZipFile(path) as zf:
        assert zf.namelist().count(META_ENTRY) == 1
    assert SB3Policy.load(path, trust=True).env_fields == {"neighbours": 6}


def test_a_failed_metadata_write_never_truncates_the_model(tmp_path, monkeypatch):
    path = model_copy(tmp_path)
    before = path.read_bytes()

    def full_disk(self, name, data, *args, **kwargs):
        # the disk fills once the model's own entries are copied, as boids.json is written
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(zipfile.ZipFile, "writestr", full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_meta(path, {"algorithm": "ppo"})
    monkeypatch.undo()
    assert path.read_bytes() == before, "the model zip is untouched"
    assert [p.name for p in tmp_path.iterdir()] == ["model.zip"], "no temporary left behind"
    assert SB3Policy.load(path, trust=True).obs_size > 0


def test_unserialisable_metadata_is_refused_before_writing(tmp_path):
    path = model_copy(tmp_path)
    before = path.read_bytes()
    with pytest.raises(ValueError, match="JSON-serialisable"):
        write_meta(path, {"algorithm": object()})
    assert path.read_bytes() == before


def _with_entry(tmp_path, raw: bytes):
    path = tmp_path / "bad.zip"
    with zipfile.ZipFile(LEARNED_MODEL) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            if name != META_ENTRY:
                dst.writestr(name, src.read(name))
        dst.writestr(META_ENTRY, raw)
    return path


@pytest.mark.parametrize("raw, match", [
    (b"{broken", "boids.json is not valid JSON"),
    (b"[" * 100_000, "boids.json is not valid JSON"),  # nested past Python's recursion limit
    (b"[1, 2]", "boids.json must be a JSON table, got list"),
    (b'{"env_fields": [6]}', "env_fields in its boids.json must be a table"),
    (b'{"env_fields": {"neighbours": -3}}', "env_fields in its boids.json are invalid: "
                                             "neighbours must be"),
])
def test_bad_metadata_names_the_model(tmp_path, raw, match):
    path = _with_entry(tmp_path, raw)
    with pytest.raises(ValueError, match=match) as info:
        load_model_policy(path)
    assert "bad.zip" in str(info.value)


def test_a_truncated_model_is_a_clear_error(tmp_path):
    path = tmp_path / "cut.zip"
    path.write_bytes(LEARNED_MODEL.read_bytes()[:100_000])
    with pytest.raises(ValueError, match=r"cannot read SB3 model .*cut.zip"):
        load_model_policy(path)
    with pytest.raises(ValueError, match=r"cannot add metadata to SB3 model .*cut.zip"):
        write_meta(path, {"algorithm": "ppo"})
    assert json.dumps(read_meta(LEARNED_MODEL))  # the shipped model's metadata still reads


def _bomb(path, entry, size):
    """A zip whose ``entry`` is ``{}`` padded with ``size`` spaces: valid JSON that inflates
    from kilobytes to ``size`` bytes (written in chunks, never held whole)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf, zf.open(entry, "w") as fh:
        fh.write(b"{}")
        for _ in range(size >> 20):
            fh.write(b" " * (1 << 20))
    return path


def test_a_zip_bomb_is_refused_before_it_is_inflated(tmp_path):
    import tracemalloc

    from boids_env.policies.registry import load_policy

    path = _bomb(tmp_path / "bomb.zip", META_ENTRY, 64 << 20)
    assert path.stat().st_size < 1 << 20, "a small file"
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"bomb.zip: its entry boids.json holds "
                                             r"67,108,866 bytes uncompressed, more than the "
                                             r"1,048,576 allowed"):
            read_meta(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20, f"refused after allocating {peak:,} bytes"
    with pytest.raises(ValueError, match="more than the 1,048,576 allowed"):
        load_policy(str(path))


def test_read_zip_entry_stops_at_its_limit(tmp_path):
    from boids_env.files import read_zip_entry

    path = _bomb(tmp_path / "b.zip", "x", 2 << 20)
    with zipfile.ZipFile(path) as zf:
        assert read_zip_entry(zf, "x", 3 << 20)[:3] == b"{} "
        with pytest.raises(ValueError, match="entry x holds 2,097,154 bytes"):
            read_zip_entry(zf, "x", 2 << 20)
        with pytest.raises(KeyError):
            read_zip_entry(zf, "missing", 10)


def test_a_saved_observation_layout_is_checked_against_the_env(tmp_path):
    from boids_env import EnvConfig, parallel_env
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.observations import layout_of

    path = model_copy(tmp_path)
    meta = read_meta(path)
    layout = layout_of(EnvConfig.from_kwargs(**meta["env_fields"]))
    assert [b for b, _ in layout.blocks][-1] == "static", "the shipped model reads a wall slot"
    write_meta(path, {**meta, "observation_layout": [list(b) for b in layout.blocks]})
    policy = load_model_policy(path)
    assert policy.observation_layout == layout
    fields = env_fields_for(policy, {"max_cycles": 5})
    assert run_episode(parallel_env(**fields), policy, seed=0).metrics["steps"] == 5
    wrong = {**fields, "sense_walls": False, "lidar_rays": 3}  # the same size, other blocks
    with pytest.raises(ValueError, match=r"laid out as .*static.* the env gives .*lidar"):
        run_episode(parallel_env(**wrong), policy, seed=0)
    write_meta(path, {**meta, "observation_layout": [["own_velocity", 3]]})
    with pytest.raises(ValueError, match=r"observation_layout in its boids\.json"):
        load_model_policy(path)
