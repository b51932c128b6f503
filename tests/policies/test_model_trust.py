"""A model zip never runs code unless the user trusts it.

Payloads are planted in every place a zip can carry one: the ``:serialized:`` (cloudpickle)
values of ``data``, top level and nested; the ``.pth`` entries (torch pickles); ``boids.json``;
``boids_actor.npz`` (an object array). Each payload writes a marker file named for its place
when unpickled. Loaded through every entry point (``load_policy``, ``boids run``, ``boids
eval``, ``boids train --resume``, the ROS controller's loading) without trust, no marker may
appear; with ``--trust-model`` / ``trust=True`` SB3's own load runs them, which shows the flag
is what guards the door.
"""

import base64
import io
import json
import pickle
import subprocess
import sys
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import torch

from boids_env.policies.mlp_actor import ACTOR_ENTRY, MLPActor
from boids_env.policies.registry import check_policy_spec, load_policy
from boids_env.policies.sb3_policy import META_ENTRY, SB3Policy, load_model_policy
from boids_env.policies.sb3_zip import UntrustedModelError, actor_from_weights
from boids_env.train.config import TrainConfig
from boids_env.train.run import train

pytestmark = pytest.mark.slow

TINY = {"total_timesteps": 320, "group_sizes": (4,), "copies": 1, "n_steps": 80,
        "batch_size": 80, "n_epochs": 1, "eval_every": 0, "checkpoint_every": 0,
        "net_arch": (8, 8), "env_fields": {"max_cycles": 30, "neighbours": 3}}


class Payload:
    """Unpickling this runs ``exec``: it writes ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('ran')",)


def serialized(marker, type_name="<class 'object'>"):
    return {":type:": type_name,
            ":serialized:": base64.b64encode(pickle.dumps(Payload(marker))).decode()}


def torch_payload(marker):
    buffer = io.BytesIO()
    torch.save(Payload(marker), buffer)
    return buffer.getvalue()


def npz_payload(marker):
    buffer = io.BytesIO()
    np.savez(buffer, w0=np.array([Payload(marker)], dtype=object))
    return buffer.getvalue()


def rewrite(src, dst, changes, drop=()):
    """``src`` with entries replaced (name -> bytes) or dropped."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            if name not in drop and name not in changes:
                zout.writestr(name, zin.read(name))
        for name, raw in changes.items():
            zout.writestr(name, raw)
    return dst


def poisoned_data(model, markers, extra=None, shape=False):
    """``data`` with every ``:serialized:`` value's pickle a payload (its plain attributes
    kept), payloads nested in a space and a schedule, ``extra`` keys set, and with ``shape``
    the observation space's shape a payload too."""
    with zipfile.ZipFile(model) as zf:
        data = json.loads(zf.read("data"))
    for key, value in data.items():
        if isinstance(value, dict) and ":serialized:" in value:
            value[":serialized:"] = serialized(markers / f"data.{key}")[":serialized:"]
    data["observation_space"]["nested"] = serialized(markers / "data.observation_space.nested")
    data["action_space"]["nested"] = serialized(markers / "data.action_space.nested")
    data["lr_schedule"]["nested"] = serialized(markers / "data.lr_schedule.nested")
    data.update(extra or {})
    if shape:
        data["observation_space"]["_shape"] = serialized(markers / "data.shape")
    return json.dumps(data).encode()


@pytest.fixture(scope="module")
def zips(tmp_path_factory):
    """A tiny model saved by ``boids train`` and its poisoned variants: ``acts`` carries
    payloads in every place an untrusted load never decodes (it must still act), the others
    one payload each where the actor itself would be (they must be refused)."""
    root = tmp_path_factory.mktemp("models")
    markers = root / "markers"
    markers.mkdir()
    model = train(TrainConfig(**TINY), root / "run")
    meta = json.loads(zipfile.ZipFile(model).read(META_ENTRY))
    meta["note"] = serialized(markers / "boids.json")
    common = {META_ENTRY: json.dumps(meta).encode(),
              "policy.optimizer.pth": torch_payload(markers / "policy.optimizer.pth"),
              "pytorch_variables.pth": torch_payload(markers / "pytorch_variables.pth")}
    out = {"markers": markers, "clean": model}
    out["acts"] = rewrite(model, root / "acts.zip", {
        **common, "data": poisoned_data(model, markers)}, drop=(ACTOR_ENTRY,))
    with zipfile.ZipFile(model) as zf:
        kwargs = json.loads(zf.read("data"))["policy_kwargs"]
    refused = {
        "policy_kwargs": {"data": poisoned_data(model, markers, {
            "policy_kwargs": serialized(markers / "data.policy_kwargs", "<class 'dict'>")})},
        "policy_kwargs.activation_fn": {"data": poisoned_data(model, markers, {
            "policy_kwargs": {**kwargs, "activation_fn": serialized(
                markers / "data.policy_kwargs.activation_fn", "<class 'type'>")}})},
        "observation_space._shape": {"data": poisoned_data(model, markers, shape=True)},
        "policy.pth": {"policy.pth": torch_payload(markers / "policy.pth")},
        ACTOR_ENTRY: {ACTOR_ENTRY: npz_payload(markers / ACTOR_ENTRY)},
    }
    for place, changes in refused.items():
        drop = () if place == ACTOR_ENTRY else (ACTOR_ENTRY,)
        out[place] = rewrite(model, root / f"refused_{place}.zip", {**common, **changes},
                             drop=drop)
    return out


def ran(zips):
    return sorted(p.name for p in zips["markers"].iterdir())


def clear(zips):
    for p in zips["markers"].iterdir():
        p.unlink()


def test_an_untrusted_zip_acts_from_its_weights_and_runs_nothing(zips):
    policy = load_policy(str(zips["acts"]))
    check_policy_spec(str(zips["acts"]))
    assert isinstance(policy, MLPActor) and ran(zips) == []
    # the same actions as the zip's own numpy actor (ours) and as SB3's forward pass
    ours = load_policy(str(zips["clean"]))
    obs = np.random.default_rng(0).normal(0, 1, (7, ours.obs_size)).astype(np.float32)
    assert np.array_equal(policy.act_batch(obs), ours.act_batch(obs))
    reference = SB3Policy.load(zips["clean"], trust=True)
    np.testing.assert_allclose(policy.act_batch(obs), reference.act_batch(obs), atol=2e-6)
    assert policy.env_fields == ours.env_fields == {"max_cycles": 30, "neighbours": 3}


@pytest.mark.parametrize("place", ["policy_kwargs", "policy_kwargs.activation_fn",
                                   "observation_space._shape", "policy.pth", ACTOR_ENTRY])
def test_a_zip_whose_actor_is_only_a_pickle_is_refused_without_running_it(zips, place):
    with pytest.raises(ValueError) as info:
        load_policy(str(zips[place]))
    if place != ACTOR_ENTRY:  # a damaged npz of ours is refused outright, trust or not
        if "pth" not in place:
            assert isinstance(info.value, UntrustedModelError)
            assert "--trust-model" in str(info.value) and "trust=True" in str(info.value)
            with pytest.raises(UntrustedModelError):  # and before any side effect
                check_policy_spec(str(zips[place]))
        else:
            assert "not a plain table of weights" in str(info.value)
    assert ran(zips) == []
    with pytest.raises(UntrustedModelError, match="--trust-model"):
        SB3Policy.load(zips[place])  # SB3's own load is never the default
    assert ran(zips) == []


def test_trust_lets_sb3_load_the_zip_and_so_runs_its_payloads(zips):
    with pytest.raises(ValueError):  # the payloads replaced the spaces: SB3 cannot use them
        load_policy(str(zips["acts"]), trust=True)
    assert "data.observation_space" in ran(zips) and "data.lr_schedule" in ran(zips)
    clear(zips)
    # a clean zip without a numpy actor loads through SB3, as before
    plain = rewrite(zips["clean"], zips["markers"].parent / "plain.zip", {}, drop=(ACTOR_ENTRY,))
    policy = load_model_policy(plain, trust=True)
    assert isinstance(policy, SB3Policy)
    obs = np.zeros((3, policy.obs_size), np.float32)
    np.testing.assert_allclose(policy.act_batch(obs), actor_from_weights(plain).act_batch(obs),
                               atol=2e-6)


def boids(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "boids_env.train.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, check=False)


def test_boids_run_acts_untrusted_refuses_by_name_and_trusts_on_request(zips, tmp_path):
    flags = ("--robots", 4, "--max-cycles", 10)
    done = boids("run", "--policy", zips["acts"], *flags, "--out", tmp_path / "a")
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "a" / "metrics.json").read_text())["steps"] == 10
    assert ran(zips) == []
    done = boids("run", "--policy", zips["policy_kwargs"], *flags, "--out", tmp_path / "b")
    assert done.returncode == 2 and "--trust-model" in done.stderr, done.stderr
    assert not (tmp_path / "b").exists() and ran(zips) == []
    done = boids("run", "--policy", zips["acts"], "--trust-model", *flags, "--out",
                 tmp_path / "c")
    assert done.returncode == 2 and "data.policy_class" in ran(zips), done.stderr
    clear(zips)


def test_boids_eval_workers_run_nothing_without_trust(zips, tmp_path):
    from boids_env.train.cli import main

    suite = tmp_path / "tiny.toml"
    suite.write_text('seeds = 1\n[[case]]\nname = "small"\nrobots = 4\nmax_cycles = 10\n')
    args = ["eval", "--suite", suite, "--workers", "1", "--no-progress"]
    assert main([*map(str, args), "--policy", str(zips["acts"]),
                 "--out", str(tmp_path / "a")]) == 0
    assert (tmp_path / "a" / "results.csv").is_file() and ran(zips) == []
    assert main([*map(str, args), "--policy", str(zips["policy_kwargs"]),
                 "--out", str(tmp_path / "b")]) == 2
    assert not (tmp_path / "b").exists() and ran(zips) == []
    # trusted, the worker unpickles the payloads (and then the episode fails)
    assert main([*map(str, args), "--policy", str(zips["acts"]), "--trust-model",
                 "--out", str(tmp_path / "c")]) == 1
    assert "data.policy_class" in ran(zips)
    clear(zips)


def test_the_ros_controller_loads_its_policy_by_the_same_rule(zips):
    from boids_env.eval.ros.controller import ControllerOptions, controller_policy

    assert isinstance(controller_policy(ControllerOptions(policy=str(zips["acts"]))),
                      MLPActor)
    with pytest.raises(UntrustedModelError, match="--trust-model"):
        controller_policy(ControllerOptions(policy=str(zips["policy_kwargs"])))
    assert ran(zips) == []
    with pytest.raises(ValueError):
        controller_policy(ControllerOptions(policy=str(zips["acts"]), trust_model=True))
    assert "data.policy_class" in ran(zips)
    clear(zips)
    with pytest.raises(TypeError, match="trust_model"):
        ControllerOptions(trust_model="yes")


def test_resume_reads_only_weights_and_counters_unless_trusted(zips, tmp_path):
    config = TrainConfig(**{**TINY, "total_timesteps": 960})
    # data's pickles poisoned (the optimizer's entry clean): resumed from the weights alone
    checkpoint = rewrite(zips["clean"], tmp_path / "ckpt.zip", {
        "data": poisoned_data(zips["clean"], zips["markers"])})
    model = train(config, tmp_path / "a", resume=checkpoint)
    assert ran(zips) == []
    resumed = SB3Policy.load(model, trust=True).model
    assert resumed.num_timesteps == 960  # from the checkpoint's 480 (two rollouts of 240)
    # a poisoned optimizer state is refused by torch's weights_only loader, by name
    with pytest.raises(ValueError, match=r"policy\.optimizer\.pth is not plain weights"):
        train(config, tmp_path / "b", resume=zips["acts"])
    assert ran(zips) == []
    # trusted, SB3's load unpickles data (the boids train command passes the flag)
    from boids_env.train.cli import main

    main(["train", "--config", str(write_toml(tmp_path / "run.toml", config)), "--resume",
          str(checkpoint), "--trust-model", "--no-progress", "--out", str(tmp_path / "c")])
    assert "data.policy_class" in ran(zips)
    clear(zips)


def write_toml(path, config):
    lines = ["[train]"]
    for key, value in config.to_dict().items():
        if value is None or isinstance(value, dict):
            continue
        lines.append(f"{key} = {json.dumps(value)}")
    lines.append("[train.env_fields]")
    lines += [f"{k} = {json.dumps(v)}" for k, v in config.env_fields.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_resume_from_the_weights_trains_as_sb3s_own_load_does(zips, tmp_path):
    config = TrainConfig(**{**TINY, "total_timesteps": 960})
    safe = train(config, tmp_path / "safe", resume=zips["clean"])
    trusted = train(config, tmp_path / "trusted", resume=zips["clean"], trust_model=True)
    a = SB3Policy.load(safe, trust=True).model
    b = SB3Policy.load(trusted, trust=True).model
    assert a.num_timesteps == b.num_timesteps == 960
    for (name, x), y in zip(a.policy.state_dict().items(), b.policy.state_dict().values(),
                            strict=True):
        assert torch.equal(x, y), name
    start = SB3Policy.load(zips["clean"], trust=True).model.policy.state_dict()
    assert not torch.equal(start["action_net.weight"], a.policy.state_dict()["action_net.weight"])
    # a config that builds another network is refused, naming the flag for SB3's own load
    with pytest.raises(UntrustedModelError, match=r"net_arch \[16\].*--trust-model"):
        train(config.replace(net_arch=(16,)), tmp_path / "other", resume=zips["clean"])
    with pytest.raises(ValueError, match="trust_model applies to the checkpoint"):
        train(config, tmp_path / "none", trust_model=True)
