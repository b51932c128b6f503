"""Issue 36 item 5: a model knows what it was made for. Every shipped model carries a card
(robots, scenes, crowds, leaders, group sizes, speeds, sensing, validation figures); ``boids
run``/``boids eval`` with an env outside it warn in one line and name the shipped model made
for it; an observation layout that does not fit says why."""

import hashlib
import json
import shutil
import warnings
import zipfile

import numpy as np
import pytest

from boids_env.environment import BoidsEnv
from boids_env.eval.episode import bind_policy, env_fields_for
from boids_env.policies.cards import CARD_LIMIT, ModelCard, ModelCardWarning, Validation
from boids_env.policies.registry import MODELS, fitting_model, model_card
from boids_env.policies.sb3_policy import load_model_policy, read_meta, write_meta

BEFORE = {  # sha256 of the weights' entries and of the actions on a fixed observation, taken
    # from the zips as shipped before they carried cards
    "learned": ("0fa45e8363ebff20d9dfb62d44bc70968659a225863319b95f6cbdb8e308ac21",
                "b3aef6c1ee02f9d02c7115fd7a1d8f6ce4b213891284d79f0c3974bb98fcfbba",
                "505ad69d1d4eae573aa9dcf70b357b23bf5a38185a675c26ee5123d557c42eed"),
    "learned-study": ("1985daefbd8c11f95b57861d9700998caaf8fa0a8d533ed3f2b626c4f0ad13ab",
                      "7bd61989772d320c6371dd31e588d4af28e3f1a9e723a15a24ea0ba6a0bb5361",
                      "df5739db03b3d73ebce45afe4b02c4799629d3d5d1fa71e56c1110c6b1c6416a"),
    "learned-person": ("25b74373ffa1cce17cd85216bb3418822634f15e09100fac2dfcaae03b4dc717",
                       "b0ca6d3e4c6f1bbc7aa2b223e1e8232bf556ecb00bf447a06939fabbe1b24a89",
                       "6aa30579f2ed452dcbcadeddf520c44844ca6a4c66072425eef8341cde5ea322"),
    "learned-scenes": ("8d68529d5382b61dc90d6ae7c8e8ddba624fc126f84401dc901689b14d83737f",
                       "d3bebf180738bd71a4f0c8f8fe4beda18757d5e615d8932b62f3741e79a79871",
                       "e83c80f0ce0f4b10ba8ccb7305d57bd04950284314009d3ce254ef3668302db9"),
}


def _card(**changes):
    base = dict(summary="test", robots=("sphero",), scenes=("arena", "floorplan"),
                floorplans=(3, 8), group_sizes=(7, 19), leader_speeds=(0.45, 0.65),
                leaders=("robot",), crowds=(0,), standstills=True,
                observation=(("own_velocity", 2), ("leader_position", 2),
                             ("leader_velocity", 2), ("neighbours", 90), ("static", 3),
                             ("route", 4)),
                validation=(Validation("buildings", "floorplan 1001", (("total", 1.5),
                                                                       ("wall", 0.01)),
                                       "docs page"),))
    return ModelCard(**{**base, **changes})


def _copy(tmp_path, name="learned"):
    path = tmp_path / "model.zip"
    shutil.copy(MODELS[name], path)
    return path


def test_a_card_round_trips_through_json_and_a_model_zip(tmp_path):
    card = _card()
    again = ModelCard.from_dict(json.loads(card.to_json()))
    assert again == card
    assert again.validation[0].figures == (("total", 1.5), ("wall", 0.01))
    assert again.layout.route and again.layout.size == 103
    path = _copy(tmp_path)
    meta = read_meta(path)
    write_meta(path, {**meta, "card": card.to_dict()})
    assert model_card(path) == card
    assert load_model_policy(path).card == card


@pytest.mark.parametrize("name", list(MODELS))
def test_every_shipped_model_carries_a_card(name):
    with zipfile.ZipFile(MODELS[name]) as zf:
        card = json.loads(zf.read("boids.json")).get("card")
    assert card is not None, (f"{name} carries no card: add it to SHIPPED in train/cards.py "
                              f"and run python -m boids_env.train.cards")
    assert ModelCard.from_dict(card).summary


@pytest.mark.parametrize("name", list(BEFORE))
def test_the_shipped_weights_are_those_shipped_before_the_cards(name):
    pth, actor, actions = BEFORE[name]
    with zipfile.ZipFile(MODELS[name]) as zf:
        assert hashlib.sha256(zf.read("policy.pth")).hexdigest() == pth
        assert hashlib.sha256(zf.read("boids_actor.npz")).hexdigest() == actor
    policy = load_model_policy(MODELS[name])
    obs = np.random.default_rng(0).normal(0, 0.5, (12, policy.obs_size)).astype(np.float32)
    assert hashlib.sha256(policy.act_batch(obs).tobytes()).hexdigest() == actions


def test_the_shipped_cards_say_what_each_model_was_made_for():
    cards = {name: model_card(path) for name, path in MODELS.items()}
    learned = cards["learned"]
    assert learned.scenes == ("arena",) and learned.validated_scenes == ()
    assert learned.group_sizes == (7, 49) and learned.leaders == ("robot",)
    assert learned.robots == ("sphero",) and learned.drive == "holonomic"
    assert learned.leader_speeds == (0.4, 0.7)  # trained 0.45-0.65, validated 0.4 and 0.7
    assert learned.crowds == (0,) and not learned.standstills and not learned.safety_filter
    assert learned.layout.size == 99 and not learned.layout.route
    assert learned.recipe == "ppo_safe + ppo_safe_stage2"
    default = next(v for v in learned.validation if v.case == "default")
    assert default.suite == "generalisation" and dict(default.figures)["total"] == 0.917
    assert "learned-followers.md" in default.source
    room = next(v for v in learned.validation if v.case.startswith("small_room"))
    assert dict(room.figures)["wall"] == 0.737

    scenes = cards["learned-scenes"]
    assert scenes.scenes == ("arena", "doorway", "corridor", "pillars")
    assert {"small_room", "lab", "map", "shapes"} <= set(scenes.validated_scenes)
    assert "floorplan" not in scenes.scenes + scenes.validated_scenes
    assert scenes.group_sizes == (7, 61) and scenes.standstills and scenes.safety_filter
    assert dict(next(v for v in scenes.validation if v.case == "small_room").figures) == {
        "total": 4.169, "touching": 0.0114, "wall": 0.0, "farthest": 1.82}

    person = cards["learned-person"]
    assert person.leaders == ("person",) and person.group_sizes == (7, 19)
    assert person.crowds == (0,) and person.scenes == ("arena",)

    study = cards["learned-study"]
    assert study.group_sizes == (7, 19) and study.leader_speeds == (0.5, 0.6)
    assert study.layout.size == 96 and "world frame" in study.sensing
    assert dict(study.validation[0].figures)["touching"] == 0.924


def _run(args, tmp_path, capsys):
    from boids_env.train.cli import main

    code = main(["run", *args, "--max-cycles", "5", "--out", str(tmp_path / "run")])
    return code, capsys.readouterr()


def test_boids_run_learned_in_a_room_warns_in_one_line_naming_learned_scenes(tmp_path, capsys):
    code, out = _run(["--policy", "learned", "--scene", "small_room"], tmp_path, capsys)
    assert code == 0, out.err
    lines = out.err.strip().splitlines()
    assert lines == ["boids run: warning: learned was not made for this env: scene small_room "
                     "(trained on the open arena only); use --policy learned-scenes, the "
                     "shipped model made for it"], out.err


def test_no_warning_in_the_default_case(tmp_path, capsys):
    for policy in ("learned", "learned-scenes", "learned-person"):
        code, out = _run(["--policy", policy, "--overwrite"], tmp_path, capsys)
        assert code == 0 and out.err == "", (policy, out.err)
    from boids_env.eval.run import run

    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelCardWarning)
        run("learned", env_fields={"max_cycles": 3}, quiet=True)


def test_the_warning_names_what_is_outside_and_which_model_fits():
    from boids_env.eval.episode import card_note

    policy = load_model_policy(MODELS["learned"])
    config = BoidsEnv(**env_fields_for(policy, {"robots": 61, "leader": "person"})).config
    note = card_note(policy, config, "learned")
    assert "61 robots (made for 7-49)" in note and "a walking person leading" in note
    assert note.endswith("none of the shipped models was made for it"), note
    scenes = load_model_policy(MODELS["learned-scenes"])
    plan = BoidsEnv(**env_fields_for(scenes, {"scene": "floorplan:3"})).config
    assert "scene floorplan@1:3" in card_note(scenes, plan, "learned-scenes")
    assert fitting_model(BoidsEnv(robots=61).config) == "learned-scenes"


def test_boids_eval_warns_once_for_the_cases_outside_the_card():
    from boids_env.eval.runner import PolicySpec, _check_model_fits
    from boids_env.eval.suites import suite_from_dict

    suite = suite_from_dict({"seeds": 1, "defaults": {"max_cycles": 3}, "case": [
        {"name": "open"}, {"name": "room", "scene": "small_room"}, {"name": "lab",
                                                                     "scene": "lab"}]})
    with pytest.warns(ModelCardWarning) as caught:
        _check_model_fits(PolicySpec.parse("learned"), suite)
    assert len(caught) == 1
    text = str(caught[0].message)
    assert text == ("learned was not made for 2 of the 3 cases: [room] scene small_room "
                    "(trained on the open arena only) [lab] scene lab (trained on the open "
                    "arena only); use --policy learned-scenes, the shipped model made for it")


@pytest.mark.parametrize("fields, reason", [
    ({"robot": "sphero_sprk"}, "trained for sphero (holonomic) without headings; this env's "
                               "sphero_sprk (unicycle) has headings"),
    ({"crowd": 8}, "trained without pedestrian slots; this env has 4 (crowd=8)"),
    ({"route_sensing": True}, "trained without route sensing; this env has route_sensing on"),
])
def test_a_layout_mismatch_says_why(fields, reason):
    policy = load_model_policy(MODELS["learned"])
    env = BoidsEnv(**env_fields_for(policy, fields))
    with pytest.raises(ValueError) as err:
        bind_policy(policy, env)
    assert reason in str(err.value), str(err.value)
    assert "(observations of 99 values for the model" in str(err.value)


def test_a_model_without_card_or_layout_still_says_why(tmp_path):
    path = _copy(tmp_path)
    meta = read_meta(path)
    write_meta(path, {k: v for k, v in meta.items() if k not in ("card", "train_config")})
    policy = load_model_policy(path)
    assert policy.card is None and getattr(policy, "observation_layout", None) is None
    env = BoidsEnv(**env_fields_for(policy, {"route_sensing": True}))
    with pytest.raises(ValueError, match=r"takes observations of size 99, the env gives 103.*"
                       r"trained without route sensing.*guessed from its size"):
        bind_policy(policy, env)
    from boids_env.eval.episode import card_note

    assert card_note(policy, BoidsEnv(scene="small_room").config) is None  # nothing to check


def test_an_old_zip_without_a_card_reads_the_one_its_training_config_describes(tmp_path):
    path = _copy(tmp_path, "learned-scenes")
    meta = read_meta(path)
    write_meta(path, {k: v for k, v in meta.items() if k != "card"})
    card = load_model_policy(path).card
    assert card.scenes == ("arena", "doorway", "corridor", "pillars")
    assert card.validation == () and card.validated_scenes == ()


@pytest.mark.parametrize("card, message", [
    ("a card", "must be a JSON table"),
    ({"summary": "x", "weights": "rm -rf"}, r"unknown model card field\(s\) \['weights'\]"),
    ({"summary": "x" * 5000}, "summary must be a text of at most 400"),
    ({"group_sizes": [19, 7]}, r"group_sizes must be a range"),
    ({"scenes": ["arena"] * 1000}, "scenes must be a list of 0 to 64 entries"),
    ({"leader_speeds": [0.1, float("nan")]}, "leader_speeds must hold finite numbers"),
    ({"observation": [["own_velocity", 3]]}, "card field observation: not an observation"),
    ({"version": 99}, "card version must be 1"),
    ({"validation": [{"suite": "s", "case": f"c{i}", "source": "s" * 399,
                      "figures": {f"m{j}": 1.0 for j in range(60)}} for i in range(60)]},
     f"at most {CARD_LIMIT:,} bytes"),
])
def test_a_malformed_or_oversized_card_is_refused_by_name(tmp_path, card, message):
    path = _copy(tmp_path)
    write_meta(path, {**read_meta(path), "card": card})
    with pytest.raises(ValueError, match=message) as err:
        load_model_policy(path)
    assert str(path) in str(err.value) and "card" in str(err.value)


def test_boids_train_writes_a_card_of_its_recipe_floor_plans_and_route_sensing():
    from boids_env.train.config import TrainConfig
    from boids_env.train.run import model_meta

    config = TrainConfig(group_sizes=(7, 13), copies=3, leader_speeds=(0.3, 0.6),
                         worlds=({"scene": "floorplan:3"}, {"scene": "floorplan:8"}, {}),
                         leader_pauses=([], [[10.0, 20.0]]),
                         env_fields={"route_sensing": True, "frame": "leader",
                                     "sense_walls": True})
    card = ModelCard.from_dict(model_meta(config)["card"])
    assert card.scenes == ("floorplan", "arena") and card.floorplans == (3, 8)
    assert card.group_sizes == (7, 13) and card.leader_speeds == (0.3, 0.6)
    assert card.standstills and card.layout.route and "route sensing" in card.sensing
    assert card.observation[-1] == ("route", 4)
    from boids_env.config import EnvConfig

    assert card.outside(EnvConfig.from_kwargs(scene="floorplan:1001", route_sensing=True)) == []
    assert card.outside(EnvConfig.from_kwargs(scene="lab")) == [
        "scene lab (trained on generated floor plans, the open arena)"]


def test_boids_card_shows_lists_and_writes_a_card(tmp_path, capsys):
    from boids_env.train.cli import main

    assert main(["card"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listing] == list(MODELS)
    assert main(["card", "learned"]) == 0
    shown = capsys.readouterr().out
    assert "trained on the open arena only" in shown and "generalisation / default" in shown
    path = _copy(tmp_path, "learned-scenes")
    source = tmp_path / "card.json"
    source.write_text(json.dumps(_card(summary="for buildings").to_dict()))
    assert main(["card", str(path), "--write", "--from", str(source)]) == 0
    assert model_card(path).summary == "for buildings"
    source.write_text(json.dumps({"summary": "x", "code": "import os"}))
    assert main(["card", str(path), "--write", "--from", str(source)]) == 2
    assert "unknown model card field(s) ['code']" in capsys.readouterr().err
    assert model_card(path).summary == "for buildings"  # refused before anything is written


def test_the_card_of_the_buildings_recipe_names_its_floor_plans_and_route_sensing():
    from boids_env.config import EnvConfig
    from boids_env.train.cards import training_card
    from boids_env.train.config import TrainConfig, resolve_recipe

    config = TrainConfig.from_toml(resolve_recipe("ppo_buildings"))
    card = training_card(config, recipe="ppo_buildings")
    assert card.floorplans == tuple(range(20, 40))  # the recipe's training plans, in order
    assert card.scenes == ("floorplan", "arena", "doorway", "corridor", "pillars")
    assert card.layout.route and "route_leader" in card.sensing and card.safety_filter
    assert card.outside(EnvConfig.from_kwargs(**{**config.env_fields,
                                                 "scene": "floorplan:1001"})) == []
