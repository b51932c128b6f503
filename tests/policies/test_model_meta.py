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
    real = zipfile.ZipFile.writestr
    written = []

    def full_disk(self, name, data, *args, **kwargs):
        if written:
            raise OSError(errno.ENOSPC, "No space left on device")
        written.append(name)
        return real(self, name, data, *args, **kwargs)

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
