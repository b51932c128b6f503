"""Recording files: exactly one recording is read, or a ValueError names the file and the
problem; a failed write leaves the previous file intact."""

import errno
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from boids_env.config import EnvConfig
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
    (rec or small()).to_parquet(tmp_path / "src.parquet")
    return pq.read_table(str(tmp_path / "src.parquet"))


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
