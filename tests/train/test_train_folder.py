"""A training owns its output folder as a run or an evaluation does: a used folder is refused
unless --overwrite (which removes only what a training wrote), a resume goes on in the folder
of its own training, a resume that would train nothing is refused before anything is written,
and a model zip is never left torn."""

import errno
import json

import pytest
import stable_baselines3

from boids_env.eval.folder import MANIFEST
from boids_env.policies.sb3_policy import SB3Policy
from boids_env.train import run as train_run
from boids_env.train.cli import main
from boids_env.train.config import TrainConfig
from boids_env.train.run import train

TINY = {"total_timesteps": 600, "group_sizes": (4, 5), "copies": 2, "n_steps": 40,
        "batch_size": 140, "n_epochs": 1, "eval_every": 0, "checkpoint_every": 300,
        "env_fields": {"max_cycles": 30, "neighbours": 4}}


def _state(folder):
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.rglob("*")}


def test_a_used_folder_is_refused_and_overwrite_replaces_only_the_training(tmp_path,
                                                                           monkeypatch, capsys):
    out = tmp_path / "t"
    cfg = TrainConfig(**TINY)
    train(cfg, out)
    before = _state(out)
    with pytest.raises(ValueError, match=r"holds a training of this config; pass --resume"):
        train(cfg, out)
    with pytest.raises(ValueError, match=r"holds a training \(algorithm 'ppo', seed 0\), this "
                                         r"run is a training \(algorithm 'ppo', seed 1\)"):
        train(cfg.replace(seed=1), out)
    assert main(["train", "--timesteps", "600", "--group-sizes", "4", "--copies", "1",
                 "--no-progress", "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert _state(out) == before, "a refused training touches nothing"

    # Ctrl-C in an overwriting run: the folder holds that run's outputs, not the old model
    (out / "notes.txt").write_text("mine")

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(stable_baselines3.PPO, "learn", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train(cfg.replace(seed=1), out, overwrite=True)
    monkeypatch.undo()
    assert not (out / "model.zip").exists(), "the earlier training's model is gone"
    assert not (out / "checkpoints").exists() and not (out / "tb").exists()
    assert json.loads((out / "config.json").read_text())["seed"] == 1

    train(cfg.replace(seed=2), out, overwrite=True)
    assert (out / "notes.txt").read_text() == "mine", "the user's file is kept"
    assert sorted(p.name for p in (out / "tb").iterdir()) == ["run_1"], "one training's logs"
    assert json.loads((out / MANIFEST).read_text())["kind"] == "boids train"


def test_overwrite_removes_only_names_a_training_writes(tmp_path):
    out = tmp_path / "t"
    out.mkdir()
    (out / "my_thesis_data.csv").write_text("precious")
    (out / MANIFEST).write_text(json.dumps({"kind": "boids train", "identity": {},
                                            "files": ["my_thesis_data.csv", "..", "model.zip"]}))
    with pytest.raises(ValueError, match="--overwrite"):
        train(TrainConfig(**TINY), out)
    train(TrainConfig(**{**TINY, "total_timesteps": 300, "checkpoint_every": 0}), out,
          overwrite=True)
    assert (out / "my_thesis_data.csv").read_text() == "precious"


def test_a_resume_goes_on_in_its_folder_and_never_tears_the_model(tmp_path, monkeypatch):
    out = tmp_path / "t"
    cfg = TrainConfig(**TINY)
    train(cfg, out)
    first = (out / "model.zip").read_bytes()
    checkpoint = out / "checkpoints" / "model_588_steps.zip"
    done = SB3Policy.load(checkpoint, trust=True).model.num_timesteps
    assert done == 588

    # a resume that would train nothing is refused before anything is written
    for total in (588, 500):
        with pytest.raises(ValueError, match=r"must exceed the 588 follower-steps checkpoint "
                                             r".*model_588_steps.zip has already trained"):
            train(cfg.replace(total_timesteps=total), tmp_path / "new", resume=checkpoint)
    assert not (tmp_path / "new").exists()
    with pytest.raises(ValueError, match=r"inside --out .* --overwrite would empty first"):
        train(cfg.replace(total_timesteps=1200), out, resume=checkpoint, overwrite=True)
    with pytest.raises(ValueError, match="holds a training"):  # another training's folder
        train(cfg.replace(total_timesteps=1200, seed=5), out, resume=checkpoint)
    assert (out / "model.zip").read_bytes() == first

    # the same training resumed in its folder; the final save fails on a full disk
    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(train_run, "write_meta", full_disk)
    with pytest.raises(OSError, match="No space left"):
        train(cfg.replace(total_timesteps=1200), out, resume=checkpoint)
    monkeypatch.undo()
    assert (out / "model.zip").read_bytes() == first, "the earlier model, whole"
    assert (out / "checkpoints" / "model_1176_steps.zip").is_file(), "the resumed run's"
    assert sorted(p.name for p in (out / "tb").iterdir()) == ["run_1"], "logs go on"
    assert not [p for p in out.rglob(".*") if p.name != ".boids-temporary"], \
        "no temporary left"


def test_a_trainings_identity_covers_the_content_of_the_files_it_reads(tmp_path):
    # issue 39 item 3, for trainings: a resume after editing a scene file would go on in a
    # world other than the one the checkpoint learned
    from boids_env.train.config import TrainConfig
    from boids_env.train.run import identity

    room = tmp_path / "room.toml"
    room.write_text("box = [-4.0, -4.0, 4.0, 4.0]\n[defaults]\npath_size = 2.0\n")
    config = TrainConfig(worlds=({"scene": str(room)},))
    before = identity(config)
    assert str(room) in before["inputs"]
    assert identity(config) == before
    room.write_text("box = [-4.0, -4.0, 4.0, 4.0]\n[[circle]]\ncenter = [3.0, 3.0]\n"
                    "radius = 0.2\n[defaults]\npath_size = 2.0\n")
    assert identity(config) != before, "the same path, another scene"
    assert "inputs" not in identity(TrainConfig()), "no file: the identity it had"
