"""Suites as data: the study's Table III and user TOML files."""

import pytest

from boids_env.environment import BoidsEnv
from boids_env.eval.suites import GENERALISATION, PAPER, ROBUSTNESS, load_suite
from boids_env.policies.reynolds_params import reynolds_params


def test_paper_suite_is_table_iii():
    assert len(PAPER.cases) == 9 and PAPER.seeds == (0, 1, 2, 3, 4)
    assert {g: [c.level for c in cs] for g, cs in PAPER.groups.items()} == {
        "rq1": ["0.5", "0.55", "0.6"], "rq2": ["1.0", "1.1", "1.2"], "rq3": ["7", "13", "19"]}
    # cases 2, 4 and 8 are the same configuration: 7 distinct ones
    keys = [c.config_key for c in PAPER.cases]
    assert len(set(keys)) == 7
    assert keys[1] == keys[3] == keys[7]
    assert PAPER.cases[3].policy == {"leader_weight": 1.0}
    assert PAPER.cases[6].env == {"robots": 7, "leader_speed": 0.55}


def test_robustness_suite_covers_future_work():
    factors = {c.factor for c in ROBUSTNESS.cases}
    assert factors == {"path", "init_jitter", "robots", "obs_noise"}
    assert max(c.env["robots"] for c in ROBUSTNESS.cases) == 61


def test_generalisation_suite_unseen_cases_lie_outside_the_shipped_recipe():
    from boids_env.config import EnvConfig
    from boids_env.train.config import TrainConfig, resolve_recipe

    default_size = EnvConfig().scenario.path_size
    first, second = (TrainConfig.from_toml(resolve_recipe(n))
                     for n in ("ppo_safe", "ppo_safe_stage2"))
    assert (first.group_sizes, first.leader_speeds, first.paths) == (
        second.group_sizes, second.leader_speeds, second.paths)
    recipe = first

    def trained_on(env):
        return (env.get("robots", 13) in recipe.group_sizes
                and min(recipe.leader_speeds) <= env.get("leader_speed", 0.55)
                <= max(recipe.leader_speeds)
                and env.get("path", "square") in recipe.paths
                and env.get("path_size", default_size) == default_size)

    groups = GENERALISATION.groups
    assert len(groups["trained"]) == len(groups["unseen"]) == 5
    assert all(trained_on(c.env) for c in groups["trained"])
    assert not any(trained_on(c.env) for c in groups["unseen"])


@pytest.mark.parametrize("suite", [PAPER, ROBUSTNESS, GENERALISATION],
                         ids=["paper", "robustness", "generalisation"])
def test_every_built_in_case_is_a_valid_configuration(suite):
    for case in suite.cases:
        env = BoidsEnv(**case.env)  # validates, and checks the layout and path fit
        env.reset(seed=0)
        reynolds_params("paper", **case.policy)


def test_toml_suite(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('name = "mine"\nseeds = [3, 4]\n[defaults]\nrobots = 7\nmax_cycles = 50\n'
                    '[[factor]]\nname = "leader_speed"\nlevels = [0.5, 0.6]\n'
                    '[[case]]\nname = "heavy"\nleader_weight = 1.3\n')
    suite = load_suite(path)
    assert suite.name == "mine" and suite.seeds == (3, 4)
    assert [c.name for c in suite.cases] == ["leader_speed=0.5", "leader_speed=0.6", "heavy"]
    assert suite.cases[0].env == {"robots": 7, "max_cycles": 50, "leader_speed": 0.5}
    assert suite.cases[2].policy == {"leader_weight": 1.3}
    assert suite.with_seeds(2).seeds == (0, 1)


@pytest.mark.parametrize("text, match", [
    ('[[factor]]\nname = "speed"\nlevels = [1]\n', "unknown field"),
    ('seeds = 2\n', "at least one"),
    ('[[case]]\nname="a"\nrobots = 1\n', "robots must be"),
    ('colour = 1\n[[case]]\nname="a"\n', "unknown suite key"),
    ('[[case]\n', "cannot read suite file"),
])
def test_bad_toml_suites_are_clear_errors(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_suite(path)


def test_a_misspelt_field_is_named_with_its_closest_fields_in_a_short_message(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[[case]]\nname = "a"\nleader_sped = 0.5\n' + "".join(
        f"x{i}yz = 1\n" for i in range(9)))
    with pytest.raises(ValueError) as err:
        load_suite(path)
    message = str(err.value)
    assert "'leader_sped' (did you mean 'leader_speed'" in message
    assert "and 5 more" in message and "configuration reference" in message
    assert len(message) < 600  # it quoted every field name before: 2,059 characters


def test_unknown_suite_name():
    with pytest.raises(FileNotFoundError, match="paper"):
        load_suite("nope")


CASE = '[[case]]\nname = "a"\n'


@pytest.mark.parametrize("text, match", [
    # Before: AttributeError / TypeError / 'float' object is not iterable, from deep inside.
    ('factor = "x"\n', r"factor must be an array of tables \(\[\[factor\]\] sections\), "
                       r"got 'x'"),
    ('case = 5\n', r"case must be an array of tables \(\[\[case\]\] sections\), got 5"),
    ('seeds = 3.5\n' + CASE, r"seeds must be a count in \[1, 10000\] .*got 3.5"),
    ('seeds = "3"\n' + CASE, r"seeds must be a count .*got '3'"),
    ('seeds = [0, 0]\n' + CASE, r"seeds must be distinct, got \[0\]"),
    ('seeds = [-1]\n' + CASE, r"seeds must be .*got \[-1\]"),
    ('seeds = 0\n' + CASE, r"seeds must be a count in \[1, 10000\]"),
    ('defaults = 5\n' + CASE, r"defaults must be a table"),
    ('per_follower = "rq3"\n' + CASE, r"per_follower must be a list of group names"),
    ('per_follower = ["rq9"]\n' + CASE, r"per_follower names group\(s\) \['rq9'\]"),
    ('[[factor]]\nname = 5\nlevels = [1]\n', r"factor 1: name must be the field to sweep"),
    ('[[factor]]\nname = "robots"\nlevels = 7\n', r"levels must be a non-empty list"),
    ('[[factor]]\nname = "robots"\nlevel = [7]\n', r"factor 1: unknown key\(s\) \['level'\]"),
    ('[[case]]\nname = ["a"]\n', r"case 1: name must be a string"),
    ('name = 3\n' + CASE, r"name must be a non-empty string, got 3"),
])
def test_mistakes_in_a_suite_file_name_the_key_and_what_is_allowed(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as info:
        load_suite(path)
    assert str(path) in str(info.value)


def test_a_huge_seed_count_is_refused_at_once(tmp_path, capsys):
    import time

    from boids_env.eval.cases import MAX_SEEDS
    from boids_env.train.cli import main

    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"seeds must be a count in \[1, 10000\]"):
        PAPER.with_seeds(10_000_000)
    assert main(["eval", "--seeds", "10000000", "--out", str(tmp_path / "out")]) == 2
    assert time.perf_counter() - start < 5
    assert "seeds must be a count in [1, 10000]" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert len(PAPER.with_seeds(MAX_SEEDS).seeds) == MAX_SEEDS


def test_physical_and_timing_fields_go_to_the_env_for_every_policy(tmp_path):
    # issue 39 item 7: horizon, max_speed, dt and startup_time went to the Reynolds
    # parameters only: the env never saw them (max_speed = 0.3 left the robots at 0.5 m/s)
    # and other policies dropped them
    import numpy as np

    from boids_env.eval.runner import PolicySpec, Task, run_task
    from boids_env.eval.suites import suite_from_dict
    from boids_env.recording import Recording

    suite = suite_from_dict({"name": "t", "defaults": {"robots": 4, "max_cycles": 40},
                             "case": [{"name": "slow", "max_speed": 0.3, "dt": 0.05,
                                       "startup_time": 1.0, "horizon": 0.8,
                                       "leader_weight": 1.1}]})
    case = suite.cases[0]
    assert case.policy == {"leader_weight": 1.1}, "only the controller's own parameter"
    assert {k: case.env[k] for k in ("max_speed", "dt", "startup_time", "horizon")} == {
        "max_speed": 0.3, "dt": 0.05, "startup_time": 1.0, "horizon": 0.8}
    for spec in ("random", "reynolds"):
        path = tmp_path / f"{spec}.parquet"
        run_task(Task(PolicySpec(spec), case, 0, str(path)))
        rec = Recording.from_parquet(path)
        world = rec.config.world
        assert (world.max_speed, world.dt) == (0.3, 0.05), spec
        assert rec.config.observation.horizon == 0.8, spec
        assert rec.time[1] == pytest.approx(0.05), spec
        speeds = np.hypot(rec.commanded[1:, 1:, 0], rec.commanded[1:, 1:, 1])
        assert speeds.max() <= 0.3 + 1e-9, (spec, speeds.max())
        if spec == "reynolds":  # held for the env's start-up (20 periods of 0.05 s), then moving
            assert not speeds[:20].any() and speeds[20:].any(), speeds.max(axis=1).tolist()
