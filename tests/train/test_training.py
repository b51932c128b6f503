"""Training runs: determinism, config validation, `boids train` end to end, SB3Policy."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest
import torch

from boids_env.policies.registry import load_policy
from boids_env.policies.sb3_policy import SB3Policy, read_meta
from boids_env.train.config import TrainConfig
from boids_env.train.run import train

TINY = {"total_timesteps": 1200, "group_sizes": (4, 5), "copies": 2, "n_steps": 80,
        "batch_size": 140, "n_epochs": 2, "eval_every": 0, "checkpoint_every": 0,
        "env_fields": {"max_cycles": 30, "neighbours": 4}}


def _params(path):
    policy = SB3Policy.load(path, trust=True)
    return [p.detach().clone() for p in policy.model.policy.parameters()]


def test_two_runs_with_the_same_seed_give_identical_parameters(tmp_path):
    a = train(TrainConfig(**TINY, seed=7), tmp_path / "a")
    b = train(TrainConfig(**TINY, seed=7), tmp_path / "b")
    c = train(TrainConfig(**TINY, seed=8), tmp_path / "c")
    pa, pb, pc = _params(a), _params(b), _params(c)
    assert all(torch.equal(x, y) for x, y in zip(pa, pb, strict=True))
    assert not all(torch.equal(x, y) for x, y in zip(pa, pc, strict=True))


def test_model_zip_carries_metadata_and_loads_as_a_policy(tmp_path):
    path = train(TrainConfig(**{**TINY, "eval_every": 600, "checkpoint_every": 600}), tmp_path)
    meta = read_meta(path)
    assert meta["algorithm"] == "ppo" and meta["env_fields"]["neighbours"] == 4
    assert meta["observation_layout"] == [["own_velocity", 2], ["leader_position", 2],
                                          ["leader_velocity", 2], ["neighbours", 20]]
    assert (tmp_path / "best_model.zip").is_file()
    checkpoints = list((tmp_path / "checkpoints").glob("model_*_steps.zip"))
    assert len(checkpoints) >= 1
    for saved in (path, tmp_path / "best_model.zip", *checkpoints):  # each carries its card
        card = read_meta(saved)["card"]
        assert card["group_sizes"] == [4, 5] and card["scenes"] == ["arena"], saved
        assert card["observation"] == meta["observation_layout"], saved
    evals = (tmp_path / "evaluations.csv").read_text().splitlines()
    assert evals[0] == ("timesteps,V_sep,V_coh,V_align,touching_fraction,contacts_follower,"
                        "contacts_leader,wall_fraction,mean_nn_distance,total,cost")
    assert len(evals) >= 2
    assert json.loads((tmp_path / "config.json").read_text())["group_sizes"] == [4, 5]
    policy = load_policy(str(path))
    obs = np.zeros((3, 6 + 5 * 4), np.float32)
    actions = policy.act_batch(obs)
    assert actions.shape == (3, 2) and np.all(np.abs(actions) <= 0.5)
    assert np.array_equal(actions, policy.act_batch(obs))  # deterministic
    with pytest.raises(ValueError, match="observations of size 26"):
        policy.act_batch(np.zeros((3, 96), np.float32))
    # boids run / boids eval build the env the model needs (4 neighbour slots, not 18)
    from boids_env.eval.run import run

    result = run(str(path), out=None, env_fields={"robots": 5, "max_cycles": 10}, quiet=True)
    assert result.metrics["steps"] == 10


def test_resume_continues_to_the_total(tmp_path):
    cfg = TrainConfig(**{**TINY, "checkpoint_every": 600})
    train(cfg, tmp_path / "first")
    ckpt = sorted((tmp_path / "first" / "checkpoints").glob("*.zip"))[0]
    start = SB3Policy.load(ckpt, trust=True).model.num_timesteps
    path = train(cfg.replace(total_timesteps=2400, eval_every=500), tmp_path / "resumed",
                 resume=ckpt)
    final = SB3Policy.load(path, trust=True).model.num_timesteps
    assert final >= 2400
    # evaluations go on every 500 steps from the checkpoint, not once per step to catch up;
    # the last row is the final model's
    evals = (tmp_path / "resumed" / "evaluations.csv").read_text().splitlines()[1:]
    *steps, last = [int(row.split(",")[0]) for row in evals]
    assert last == final
    assert steps and steps[0] > start
    assert len(steps) == len({s // 500 for s in steps}) <= (2400 - start) // 500 + 1
    with pytest.raises(FileNotFoundError, match="checkpoint to resume not found"):
        train(cfg, tmp_path / "x", resume=tmp_path / "missing.zip")


def test_resume_log_std_restarts_exploration(tmp_path):
    cfg = TrainConfig(**{**TINY, "log_std_init": -3.0})
    first = train(cfg, tmp_path / "first")
    before = SB3Policy.load(first, trust=True).model.policy.log_std.detach()
    assert torch.all(before < -2.8), before  # the run's own (tiny) exploration
    longer = {"total_timesteps": 2400, "log_std_init": -3.0}
    kept = train(cfg.replace(**longer), tmp_path / "kept", resume=first)
    reset = train(cfg.replace(**longer, resume_log_std=-1.0), tmp_path / "reset", resume=first)
    kept_std = SB3Policy.load(kept, trust=True).model.policy.log_std.detach()
    reset_std = SB3Policy.load(reset, trust=True).model.policy.log_std.detach()
    # one more rollout of updates moves the log std by far less than the 2.0 of the reset
    assert torch.all(kept_std < -2.6), kept_std
    assert torch.all((reset_std > -1.3) & (reset_std < -0.7)), reset_std
    with pytest.raises(ValueError, match="resume_log_std is set but no checkpoint"):
        train(cfg.replace(resume_log_std=-1.0), tmp_path / "fresh")
    assert not (tmp_path / "fresh").exists()
    with pytest.raises(ValueError, match="resume_log_std applies to PPO"):
        TrainConfig(algorithm="sac", resume_log_std=-1.0)


def test_sac_runs(tmp_path):
    cfg = TrainConfig(**{**TINY, "algorithm": "sac", "learning_starts": 100,
                         "batch_size": 64, "buffer_size": 5000, "total_timesteps": 400})
    path = train(cfg, tmp_path)
    assert read_meta(path)["algorithm"] == "sac"
    assert SB3Policy.load(path, trust=True).act_batch(np.zeros((2, 26), np.float32)).shape == (2, 2)


@pytest.mark.parametrize("changes, match", [
    ({"algorithm": "dqn"}, "algorithm must be one of"),
    ({"total_timesteps": 0}, "total_timesteps must be in"),
    ({"group_sizes": ()}, "group_sizes must not be empty"),
    ({"group_sizes": (1,)}, "group_sizes must be in"),
    ({"leader_speeds": (0.5, -1.0)}, "leader_speeds must be in"),
    ({"paths": ("external",)}, "paths entries must be among"),
    ({"processes": 3, "copies": 2}, r"processes must be in \[0, 2\]"),
    ({"device": "tpu"}, "device must be one of"),
    ({"torch_threads": -1}, r"torch_threads must be in \[0, 256\]"),
    ({"env_fields": {"robots": 5}}, "reserved"),
    ({"env_fields": {"colour": 1}}, "unknown"),
    ({"learning_rate": float("nan")}, "learning_rate must be in"),
    ({"resume_log_std": 9.0}, r"resume_log_std must be in \[-20"),
])
def test_bad_config_values_are_clear_errors(changes, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**changes)


def test_config_from_toml(tmp_path):
    path = tmp_path / "run.toml"
    path.write_text('[train]\nalgorithm = "ppo"\ngroup_sizes = [7, 19]\ncopies = 4\n'
                    '[train.env_fields]\nneighbours = 8\n')
    cfg = TrainConfig.from_toml(path, seed=3, copies=None)
    assert cfg.group_sizes == (7, 19) and cfg.copies == 4 and cfg.seed == 3
    assert cfg.env_fields == {"neighbours": 8}
    (tmp_path / "bad.toml").write_text("copies = [\n")
    with pytest.raises(ValueError, match="cannot read training config"):
        TrainConfig.from_toml(tmp_path / "bad.toml")
    (tmp_path / "typo.toml").write_text("copiez = 3\n")
    with pytest.raises(ValueError, match="unknown training config field"):
        TrainConfig.from_toml(tmp_path / "typo.toml")


def test_unreadable_model_files_are_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_policy(str(tmp_path / "none.zip"))
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="cannot read SB3 model"):
        load_policy(str(bad))


@pytest.mark.slow
def test_boids_train_then_boids_run(tmp_path):
    out = tmp_path / "t"
    proc = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "train", "--timesteps", "1000",
         "--group-sizes", "5", "--copies", "1", "--eval-every", "0", "--checkpoint-every", "0",
         "--no-progress", "--out", str(out)], capture_output=True, text=True, timeout=600,
        check=False)
    assert proc.returncode == 0, proc.stderr
    assert (out / "model.zip").is_file() and (out / "config.json").is_file()
    # PPO runs whole rollouts: the command says so, and names only what it wrote
    assert "round up to" in proc.stdout
    assert "evaluations.csv" not in proc.stdout and "checkpoints" not in proc.stdout
    run = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "run", "--policy", str(out / "model.zip"),
         "--robots", "5", "--max-cycles", "30", "--out", str(tmp_path / "r")],
        capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stderr
    metrics = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert metrics["steps"] == 30 and {"V_sep", "V_coh", "V_align"} <= metrics.keys()


def test_a_short_training_says_how_it_goes_and_evaluates_its_final_model(tmp_path, capsys):
    """A run far shorter than eval_every (the default 1,000,000) still prints its progress and
    evaluates the final model once, so ``boids curves`` has a point to draw."""
    from boids_env.train.cli import main

    path = train(TrainConfig(**{**TINY, "eval_every": 1_000_000}), tmp_path / "t")
    out = capsys.readouterr().out
    # the split and the threads follow the machine's cores (one process and one thread on 2)
    assert re.search(r"boids train: 2 env copies \(7 follower slots\) stepped in this process"
                     r"( and 1 worker process)?; \d+ torch threads? on cpu", out), out
    # 1200 follower-steps round up to 1680 (rollouts of 80 steps × 7 slots): a line a tenth
    lines = [line for line in out.splitlines() if " follower-steps (" in line]
    assert [line.split(":")[1].split()[0] for line in lines] == [
        f"{168 * k:,}/1,680" for k in range(1, 11)], out
    rewards = [float(line.split("follower-step ")[1].split(";")[0]) for line in lines]
    assert all(-0.3 <= r <= 0 for r in rewards), "the study's reward: −(0 to 3 flags)·dt"
    assert "training episode(s) ended: return per follower" in out, "30-step episodes end"
    evals = (tmp_path / "t" / "evaluations.csv").read_text().splitlines()
    assert len(evals) == 2 and evals[1].startswith("1680,"), evals
    assert SB3Policy.load(path, trust=True).model.num_timesteps == 1680
    assert "the final model on the evaluation episodes (seeds 100, 101): total" in out
    assert main(["curves", str(tmp_path / "t"), "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").is_file()


def test_resume_new_blocks_maps_a_model_onto_a_robot_with_headings(tmp_path):
    """A holonomic model resumed on a TurtleBot3 with route sensing: its heading blocks sit
    between the study's blocks and the route block, so the columns move by block name; the
    resumed policy acts as the old one did whatever the new blocks hold."""
    from boids_env.train.resume import load_checkpoint
    from boids_env.train.run import make_vec_env

    arena = {"max_cycles": 30, "neighbours": 4, "route_sensing": True}
    first = train(TrainConfig(**{**TINY, "env_fields": arena}, seed=1), tmp_path / "first")
    turtle = TrainConfig(**{**TINY, "total_timesteps": 2400, "resume_new_blocks": True,
                            "env_fields": {**arena, "robot": "turtlebot3_burger"}})
    venv = make_vec_env(turtle)
    try:
        model = load_checkpoint(first, turtle, venv, "cpu", str(tmp_path / "tb"))
    finally:
        venv.close()
    old = SB3Policy.load(first, trust=True)
    rng = np.random.default_rng(0)
    study = rng.normal(size=(6, 26)).astype(np.float32)   # 2+2+2 + 4 slots of 5
    route = rng.normal(size=(6, 4)).astype(np.float32)
    headings = rng.normal(size=(6, 12)).astype(np.float32)  # own, leader, 4 neighbours
    widened = SB3Policy(model, turtle.env_fields)
    assert widened.obs_size == 42
    # Compare the deterministic means (the TurtleBot3's action bounds clip otherwise).
    import torch

    def mean(policy, obs):
        with torch.no_grad():
            return policy.model.policy.get_distribution(
                torch.as_tensor(obs)).distribution.mean.numpy()

    np.testing.assert_array_equal(mean(widened, np.hstack([study, headings, route])),
                                  mean(old, np.hstack([study, route])))
    path = train(turtle, tmp_path / "turtle", resume=first)
    assert read_meta(path)["observation_layout"][-2] == ["neighbour_headings", 8]
    # a checkpoint block the env lacks is refused before anything is written
    bare = turtle.replace(env_fields={"max_cycles": 30, "neighbours": 4,
                                      "robot": "turtlebot3_burger"})
    with pytest.raises(ValueError, match=r"resume_new_blocks: .* \{'route': \(4, None\)\}"):
        train(bare, tmp_path / "bad", resume=first)
    assert not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match="resume_new_blocks and resume_new_inputs"):
        turtle.replace(resume_new_inputs=4)


def test_resume_new_inputs_widens_a_model_that_first_acts_as_before(tmp_path):
    """A model trained without route sensing resumed with its 4 inputs: the new first-layer
    columns start at zero, so the widened policy's actions equal the old one's."""
    from boids_env.train.resume import load_checkpoint
    from boids_env.train.run import make_vec_env

    arena = {"max_cycles": 30, "neighbours": 4}
    first = train(TrainConfig(**TINY, seed=1), tmp_path / "first")
    routed = TrainConfig(**{**TINY, "total_timesteps": 2400, "resume_new_inputs": 4,
                            "env_fields": {**arena, "route_sensing": True}})
    venv = make_vec_env(routed)
    try:
        model = load_checkpoint(first, routed, venv, "cpu", str(tmp_path / "tb"))
    finally:
        venv.close()
    old = SB3Policy.load(first, trust=True)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(6, 26)).astype(np.float32)
    route = rng.normal(size=(6, 4)).astype(np.float32)
    widened = SB3Policy(model, routed.env_fields)
    assert widened.obs_size == 30
    np.testing.assert_array_equal(widened.act_batch(np.hstack([obs, route])),
                                  old.act_batch(obs))
    # and it trains on from there, the optimizer afresh
    path = train(routed, tmp_path / "widened", resume=first)
    assert read_meta(path)["env_fields"]["route_sensing"] is True
    with pytest.raises(ValueError, match=r"resume_new_inputs=3: checkpoint .* has no first "
                                         r"layer of 27 inputs"):
        train(routed.replace(resume_new_inputs=3), tmp_path / "bad", resume=first)
    with pytest.raises(ValueError, match="resume_new_inputs is set but no checkpoint"):
        train(routed, tmp_path / "fresh")


def test_a_rollout_no_multiple_of_the_batch_is_one_line_not_sb3s_warning(tmp_path, capsys):
    """560 follower-steps per rollout (80 steps × 7 slots) in batches of 150: three of 150 and
    one of 110 per epoch, said in one line; SB3's paragraph-long warning is not shown."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        train(TrainConfig(**{**TINY, "batch_size": 150, "total_timesteps": 560}),
              tmp_path / "t")
    assert not [w for w in caught if "mini-batch" in str(w.message)], [
        str(w.message) for w in caught]
    out = capsys.readouterr().out
    assert ("the rollout (80 steps x 7 follower slots = 560) is not a multiple of batch_size "
            "150: each epoch ends with a mini-batch of 110") in out, out


def test_ppo_safe_says_its_last_mini_batch_and_a_dividing_batch_says_nothing():
    from boids_env.train.config import resolve_recipe, rollout_slots
    from boids_env.train.run import last_minibatch_note

    safe = TrainConfig.from_toml(resolve_recipe("ppo_safe"))
    assert rollout_slots(safe) == 444  # 6 + 12 + 18 + 24 + 30 + 36 + 48 + 48, twice
    assert "= 113,664) is not a multiple of batch_size 4,608" in last_minibatch_note(safe, 444)
    assert "mini-batch of 3,072" in last_minibatch_note(safe, 444)
    assert last_minibatch_note(TrainConfig(**TINY), 7) is None  # 560 = 4 × 140
