"""Training configs are checked before anything is written, and errors name the training
field; the ``boids`` command turns user errors (operating-system ones included) into one
clear line and exit status 2."""

import errno

import numpy as np
import pytest

from boids_env.train.cli import main
from boids_env.train.config import TrainConfig


def test_leader_speeds_beyond_the_env_cap_name_the_training_field():
    with pytest.raises(ValueError, match=r"leader_speeds must be in \(0.0, 2.0\] m/s, got 5.0"):
        TrainConfig(leader_speeds=(0.5, 5.0))


def test_env_fields_are_validated_when_the_config_is_built():
    with pytest.raises(ValueError, match=r"env_fields: dt must be in"):
        TrainConfig(env_fields={"dt": -1})
    with pytest.raises(ValueError, match=r"env_fields: max_cycles must be in \[1, "):
        TrainConfig(env_fields={"max_cycles": -5})


def test_env_fields_must_not_set_what_an_episode_draws():
    with pytest.raises(ValueError, match=r"env_fields must not set 'leader_speed' \(reserved.*"
                                         r"leader_speeds = \[0.6\]"):
        TrainConfig(env_fields={"leader_speed": 0.6})
    with pytest.raises(ValueError, match=r"must not set 'path'.*training field paths"):
        TrainConfig(env_fields={"path": "circle"})
    # a fixed sensing noise is fine while obs_noises is not drawn, refused when it is
    assert TrainConfig(env_fields={"obs_noise": 0.02}).env_fields == {"obs_noise": 0.02}
    with pytest.raises(ValueError, match=r"must not set 'obs_noise'.*obs_noises"):
        TrainConfig(env_fields={"obs_noise": 0.02}, obs_noises=(0.0, 0.05))


def test_every_drawn_entry_is_checked_and_named():
    with pytest.raises(ValueError, match=r"group_sizes entry 900 gives episodes the env refuses "
                                         r"\(robots=900\): arena_half_size must exceed"):
        TrainConfig(group_sizes=(7, 900))
    with pytest.raises(ValueError, match=r"leader_speeds entry 1.9 .*substeps"):
        TrainConfig(leader_speeds=(0.5, 1.9), env_fields={"substeps": 2})
    small = {"arena_half_size": 1.5, "path_size": 0.5}
    assert TrainConfig(group_sizes=(4,), env_fields=small).group_sizes == (4,)
    with pytest.raises(ValueError, match=r"group_sizes entry 13"):
        TrainConfig(group_sizes=(4, 13), env_fields=small)


def test_boids_train_refuses_a_bad_config_before_writing(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["train", "--leader-speeds", "0.5", "5", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "leader_speeds must be in (0.0, 2.0] m/s, got 5.0" in err
    assert not out.exists()
    bad = tmp_path / "bad.toml"
    bad.write_text("train = 5\n")
    assert main(["train", "--config", str(bad), "--out", str(out)]) == 2
    assert "[train] must be a table" in capsys.readouterr().err
    toml = tmp_path / "env.toml"
    toml.write_text('[train]\nenv_fields = { dt = -1 }\n')
    assert main(["train", "--config", str(toml), "--out", str(out)]) == 2
    assert "env_fields: dt must be in" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("entries, message", [
    ({"notes.txt": "x"}, "is not a Stable-Baselines3 checkpoint (its zip lacks data, "
                         "policy.pth)"),
    ({"data": '{"num_timesteps": 5}', "policy.pth": "garbage"}, "is not plain weights"),
])
def test_a_checkpoint_that_cannot_resume_is_refused_before_writing(tmp_path, capsys, entries,
                                                                   message):
    """It once wrote config.json, then printed SB3's AssertionError traceback."""
    import zipfile

    junk = tmp_path / "junk.zip"
    with zipfile.ZipFile(junk, "w") as archive:
        for name, text in entries.items():
            archive.writestr(name, text)
    out = tmp_path / "t"
    assert main(["train", "--resume", str(junk), "--timesteps", "100", "--copies", "1",
                 "--group-sizes", "3", "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "junk.zip" in err, err
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert not out.exists()


@pytest.mark.parametrize("command", [
    ["train", "--timesteps", "100", "--copies", "1", "--group-sizes", "3", "--no-progress"],
    ["run", "--robots", "3"], ["eval", "--seeds", "1", "--no-progress"]])
def test_out_under_a_file_is_refused_before_any_work(tmp_path, capsys, command):
    """``--out /etc/hostname/sub`` was found only when the outputs were written, after the
    episode had run."""
    target = tmp_path / "taken"
    target.write_text("a user's file")
    assert main([*command, "--out", str(target / "sub")]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert f"--out {target / 'sub'}: {target} is a file, so no folder can be made" in err, err
    assert "Traceback" not in err and len(err.splitlines()) == 1
    assert "V_sep" not in captured.out, "the episode ran before the refusal"
    assert target.read_text() == "a user's file"


@pytest.mark.parametrize("command", [["train"], ["run", "--robots", "3"],
                                     ["eval", "--seeds", "1"]])
def test_out_that_is_a_file_is_refused_before_any_work(tmp_path, capsys, command):
    target = tmp_path / "taken"
    target.write_text("a user's file")
    assert main([*command, "--out", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--out {target} is an existing file, not a folder" in err
    assert "Traceback" not in err and len(err.splitlines()) == 1
    assert target.read_text() == "a user's file"


def test_operating_system_errors_are_one_clear_line(tmp_path, capsys, monkeypatch):
    import boids_env.eval.run as run_module

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", "runs/x/metrics.json")

    monkeypatch.setattr(run_module, "run", full_disk)
    assert main(["run", "--robots", "3", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "boids run: error: No space left on device: runs/x/metrics.json"


def test_cuda_without_a_gpu_is_refused_before_writing(tmp_path, capsys):
    torch = pytest.importorskip("torch")
    if torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    out = tmp_path / "t"
    assert main(["train", "--device", "cuda", "--out", str(out)]) == 2
    assert "torch sees no GPU" in capsys.readouterr().err
    assert not out.exists()


def test_boids_train_shows_its_bar_on_a_terminal_only(tmp_path, monkeypatch):
    """SB3's bar redraws filled a piped training log."""
    import io
    import sys

    import boids_env.train.run as run

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    asked = []

    def train(config, out, *, resume=None, overwrite=False, progress_bar=False,
              trust_model=False):
        asked.append(progress_bar)
        raise ValueError("stop here")

    monkeypatch.setattr(run, "train", train)
    argv = ["train", "--timesteps", "100", "--copies", "1", "--group-sizes", "3", "--out",
            str(tmp_path / "t")]
    for stream in (io.StringIO(), Terminal()):
        monkeypatch.setattr(sys, "stderr", stream)
        assert main(argv) == 2
    assert asked == [False, True]
    monkeypatch.setattr(sys, "stderr", Terminal())
    assert main([*argv, "--no-progress"]) == 2
    assert asked[-1] is False


def test_worlds_pair_with_group_sizes_and_scenes_drive_their_own_paths():
    from boids_env.train.run import check_episodes, copy_specs

    config = TrainConfig(group_sizes=(13, 7), copies=4, paths=("square", "circle"),
                         path_rotations=(0.0, 90.0), leader_pauses=((), ((5.0, 10.0),)),
                         worlds=({}, {"scene": "corridor"}))
    specs = copy_specs(config)
    assert [(s.robots, s.env_fields.get("scene")) for s in specs] == [
        (13, None), (7, "corridor"), (13, None), (7, "corridor")]
    assert specs[0].paths == ("square", "circle") and "path_rotation" in specs[0].choices
    assert specs[1].paths == () and set(specs[1].choices) == {"leader_pauses"}
    options = specs[1].draw(np.random.default_rng(0))
    assert "path" not in options and options["leader_pauses"] in ((), ((5.0, 10.0),))
    check_episodes(config)
    with pytest.raises(ValueError, match=r"worlds entry 2 \{'scene': 'corridor'\} \(copy 2, "
                                         r"robots=37.*does not fit scene 'corridor'"):
        TrainConfig(group_sizes=(13, 37), copies=2, worlds=({}, {"scene": "corridor"}))


def test_bad_worlds_and_pauses_are_refused_by_name():
    with pytest.raises(ValueError, match=r"worlds entry 2 must not set \['robots'\]"):
        TrainConfig(worlds=({}, {"robots": 7}))
    with pytest.raises(ValueError, match=r"worlds entry 1 has unknown key\(s\) \['sceen'\]"):
        TrainConfig(worlds=({"sceen": "doorway"},))
    with pytest.raises(ValueError, match="worlds entries must be tables"):
        TrainConfig(worlds=("doorway",))
    with pytest.raises(ValueError, match=r"worlds entry 1 .* gives episodes the env refuses"):
        TrainConfig(worlds=({"arena_half_size": 1.0},))
    with pytest.raises(ValueError, match="leader_pauses entries: leader_pauses must be in "
                                         "increasing order"):
        TrainConfig(leader_pauses=(((5.0, 1.0), (2.0, 1.0)),))
    assert TrainConfig.from_dict(TrainConfig(
        leader_pauses=((), ((5.0, 1.0),)), worlds=({"scene": "doorway"},)).to_dict()
    ).leader_pauses == ((), ((5.0, 1.0),))


def test_a_floor_plan_world_reads_no_file():
    """A generated floor plan is built from its seed: a run's identity lists no input file
    for it (it was once taken for a file named ``floorplan@1:3`` and refused)."""
    from boids_env.train.config import TrainConfig
    from boids_env.train.run import identity
    from boids_env.world.scenes import scene_files

    assert scene_files("floorplan:3") == () and scene_files("floorplan@1:3") == ()
    cfg = TrainConfig(group_sizes=(7,), copies=1, worlds=({"scene": "floorplan:3"},))
    assert "inputs" not in identity(cfg)
