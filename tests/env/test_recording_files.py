"""Recording files: exactly one recording is read, or a ValueError names the file and the
problem; a failed write leaves the previous file intact."""

import errno
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from boids_env.config import EnvConfig
from boids_env.parquet import DIGEST
from boids_env.recording import Recording


def small(robots: int = 3, steps: int = 4, seed: int = 0) -> Recording:
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-2, 2, (steps, robots, 2))
    vel = rng.uniform(-0.5, 0.5, (steps, robots, 2))
    return Recording(EnvConfig.from_kwargs(robots=robots), np.arange(steps) * 0.1, pos, vel,
                     vel * 0.9, {"seed": seed})


def write(tmp_path, table: pa.Table, name: str = "r.parquet"):
    path = tmp_path / name
    pq.write_table(table, str(path))
    return path


def table_of(tmp_path, rec: Recording | None = None) -> pa.Table:
    """A recording's table to craft a file from, without the digest of its schema (a crafted
    file has none; with it, every change below would be refused as damage)."""
    (rec or small()).to_parquet(tmp_path / "src.parquet")
    table = pq.read_table(str(tmp_path / "src.parquet"))
    meta = {k: v for k, v in table.schema.metadata.items() if k != DIGEST}
    return table.replace_schema_metadata(meta)


def with_column(table: pa.Table, name: str, values) -> pa.Table:
    return table.set_column(table.column_names.index(name), name, pa.array(values))


def test_round_trip_is_exact(tmp_path):
    rec = small()
    rec.to_parquet(tmp_path / "r.parquet")
    back = Recording.from_parquet(tmp_path / "r.parquet")
    assert back.config == rec.config and back.extra == {"seed": 0}
    for name in ("time", "positions", "velocities", "commanded"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name


def test_a_folder_of_several_recordings_is_refused(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    small(seed=0).to_parquet(folder / "a.parquet")
    small(seed=1).to_parquet(folder / "b.parquet")
    with pytest.raises(ValueError, match=r"runs is a folder, not a recording file"):
        Recording.from_parquet(folder)


def test_duplicated_rows_are_refused(tmp_path):
    table = table_of(tmp_path)
    doubled = pa.concat_tables([table, table])
    with pytest.raises(ValueError, match=r"r.parquet: 12 duplicated \(step, robot\) rows"):
        Recording.from_parquet(write(tmp_path, doubled))


def test_negative_robot_index_is_refused(tmp_path):
    table = table_of(tmp_path)
    robot = table.column("robot").to_numpy().copy()
    robot[robot == 2] = -1
    with pytest.raises(ValueError, match=r"r.parquet: robot indices must be >= 0, got -1"):
        Recording.from_parquet(write(tmp_path, with_column(table, "robot", robot)))


def test_config_and_data_must_agree_on_the_group_size(tmp_path):
    table = table_of(tmp_path)
    meta = json.loads(table.schema.metadata[b"boids_env"])
    meta["config"]["scenario"]["robots"] = 7
    table = table.replace_schema_metadata({"boids_env": json.dumps(meta)})
    with pytest.raises(ValueError, match=r"config says robots=7 but the data hold 3 robots"):
        Recording.from_parquet(write(tmp_path, table))


def test_missing_samples_are_refused(tmp_path):
    table = table_of(tmp_path)
    with pytest.raises(ValueError, match=r"incomplete samples: 11 rows"):
        Recording.from_parquet(write(tmp_path, table.slice(0, 11)))


def test_an_empty_recording_is_refused(tmp_path):
    table = table_of(tmp_path).slice(0, 0)
    with pytest.raises(ValueError, match=r"r.parquet holds no samples"):
        Recording.from_parquet(write(tmp_path, table))
    empty = tmp_path / "zero.parquet"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match=r"cannot read recording .*zero.parquet"):
        Recording.from_parquet(empty)


@pytest.mark.parametrize("meta, match", [
    (b"{not json", "metadata is not valid JSON"),
    (b'{"extra": {}}', "metadata has no config table"),
    (b'["config"]', "metadata has no config table"),
    (b'{"config": {"world": {"dt": -1}}}', "config metadata is invalid: dt must be"),
    (b'{"config": {"galaxy": {}}}', "config metadata is invalid: unknown config section"),
    (b'{"config": {}, "extra": 5}', "extra metadata must be a table"),
    (b'{"config": {}, "leader_path": [[0, "a"]]}', "leader_path metadata must be"),
])
def test_bad_metadata_is_a_clear_error(tmp_path, meta, match):
    table = table_of(tmp_path).replace_schema_metadata({"boids_env": meta})
    with pytest.raises(ValueError, match=match) as info:
        Recording.from_parquet(write(tmp_path, table))
    assert "r.parquet" in str(info.value)


def test_non_numeric_or_non_finite_columns_are_refused(tmp_path):
    table = table_of(tmp_path)
    x = table.column("x").to_numpy().copy()
    x[4] = np.nan
    with pytest.raises(ValueError, match=r"column 'x' holds non-finite values"):
        Recording.from_parquet(write(tmp_path, with_column(table, "x", x)))
    words = ["a"] * table.num_rows
    with pytest.raises(ValueError, match=r"column 'vy' must hold numbers"):
        Recording.from_parquet(write(tmp_path, with_column(table, "vy", words)))


def test_robots_of_one_step_must_share_its_time(tmp_path):
    table = table_of(tmp_path)
    time = table.column("time").to_numpy().copy()
    time[4] += 0.05
    with pytest.raises(ValueError, match=r"robots of step 1 have different times"):
        Recording.from_parquet(write(tmp_path, with_column(table, "time", time)))


def test_a_failed_write_keeps_the_previous_file(tmp_path, monkeypatch):
    path = tmp_path / "r.parquet"
    small(seed=0).to_parquet(path)
    before = path.read_bytes()

    def full_disk(table, where, **kwargs):
        with open(where, "wb") as fh:
            fh.write(b"PAR1 half a file")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pq, "write_table", full_disk)
    with pytest.raises(OSError, match="No space left"):
        small(seed=1).to_parquet(path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["r.parquet"], "no temporary left behind"
    monkeypatch.undo()
    assert Recording.from_parquet(path).extra == {"seed": 0}


def test_writing_over_a_folder_is_refused(tmp_path):
    folder = tmp_path / "keep"
    folder.mkdir()
    (folder / "mine.txt").write_text("user data")
    with pytest.raises(IsADirectoryError, match="it is a folder"):
        small().to_parquet(folder)
    assert (folder / "mine.txt").read_text() == "user data"


def _same(a: Recording, b: Recording) -> bool:
    arrays = ("time", "positions", "velocities", "commanded")
    forces_a, forces_b = a.forces or {}, b.forces or {}
    return (a.config == b.config and a.extra == b.extra
            and all(np.array_equal(getattr(a, k), getattr(b, k)) for k in arrays)
            and np.array_equal(a.leader_path, b.leader_path) and forces_a.keys() == forces_b.keys()
            and all(np.array_equal(forces_a[k], forces_b[k], equal_nan=True) for k in forces_a))


def test_a_damaged_file_is_refused_never_read_back_as_other_numbers(tmp_path):
    """Bit rot: one byte flipped anywhere (data pages, page headers, metadata) is refused by
    its page checksum or the metadata's SHA-256, or changes nothing that is read."""
    rec = small(robots=4, steps=30)
    rec.forces = {"separation": np.random.default_rng(1).normal(size=(30, 3, 2))}
    rec.leader_path = np.array([[0.0, 0.0], [1.0, 0.5]])
    rec.to_parquet(tmp_path / "r.parquet")
    raw = (tmp_path / "r.parquet").read_bytes()
    original = Recording.from_parquet(tmp_path / "r.parquet")
    damaged = tmp_path / "d.parquet"
    changed = []
    for at in np.linspace(4, len(raw) - 9, 150).astype(int):  # inside the magic bytes
        flipped = bytearray(raw)
        flipped[at] ^= 0x5A
        damaged.write_bytes(bytes(flipped))
        try:
            back = Recording.from_parquet(damaged)
        except ValueError:
            continue
        if not _same(back, original):
            changed.append(int(at))
    assert not changed, f"flips at bytes {changed} of {len(raw)} read back as other data"


def test_a_huge_index_is_refused_before_anything_is_allocated(tmp_path):
    table = table_of(tmp_path)
    robots = table.column("robot").to_numpy().copy()
    robots[-1] = 2**40  # asked numpy for 8 TiB
    with pytest.raises(ValueError, match=r"robot index 1099511627776 is beyond the file's 12 "):
        Recording.from_parquet(write(tmp_path, with_column(table, "robot", robots)))
    steps = table.column("step").to_numpy().copy()
    steps[0] = 2**62
    with pytest.raises(ValueError, match=r"step index 4611686018427387904 is beyond"):
        Recording.from_parquet(write(tmp_path, with_column(table, "step", steps)))


def test_force_columns_without_their_pair_are_refused(tmp_path):
    rec = small()
    rec.forces = {"separation": np.zeros((4, 2, 2))}
    table = table_of(tmp_path, rec).drop_columns(["force_separation_y"])
    with pytest.raises(ValueError, match=r"force columns must come in _x/_y pairs; "
                                         r"\['force_separation_y'\]"):
        Recording.from_parquet(write(tmp_path, table))
