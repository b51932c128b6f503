"""The cards of the models this package trains and ships (:mod:`boids_env.policies.cards`).

``boids train`` writes :func:`training_card` into every model it saves. The shipped models'
cards are that card (from the training config in their zip) with what their measurements
added: the cases they were validated on (unseen group sizes, speeds, scenes) widen what they
cover, and the figures come from ``docs/explanation/learned-followers.md``, table by table
(:data:`SHIPPED`). ``python -m boids_env.train.cards`` rewrites the shipped zips' cards from
here; nothing else in a zip changes (the weights stay byte for byte).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from boids_env.policies.cards import (
    CARD_KEY,
    ModelCard,
    Validation,
    card_from_training,
    read_card,
)
from boids_env.policies.registry import MODELS
from boids_env.policies.sb3_policy import read_meta, write_meta
from boids_env.train.config import TrainConfig

PAGE = "docs/explanation/learned-followers.md"


def training_card(config: TrainConfig, recipe: str = "") -> ModelCard:
    """The card of a model trained by ``config``: what its recipe trains on (scenes and
    floor plans, robots, crowds, leaders, group sizes, speeds, standstills, noise) and its
    observation layout; no figures yet."""
    return card_from_training(config.to_dict(), config.env_fields, recipe=recipe)


def _cases(suite: str, source: str, rows: list[tuple[str, dict[str, float]]]
           ) -> tuple[Validation, ...]:
    return tuple(Validation(suite, case, tuple(figures.items()), source) for case, figures in rows)


def _f(total: float, touching: float, wall: float, **more: float) -> dict[str, float]:
    return {"total": total, "touching": touching, "wall": wall, **more}


_LEARNED_TABLE = (f"{PAGE}, 'The shipped policy: learned', its table (boids eval --suite "
                  f"generalisation, seeds 0-4, means; touching and wall: fractions of the "
                  f"episode)")
_SCENES_TABLE = (f"{PAGE}, 'Learned followers for a lab: learned-scenes', Results (scenes and "
                 f"deployment suites, seeds 0-4, means; farthest: largest final distance to "
                 f"the leader, m)")
_PERSON_TABLE = (f"{PAGE}, 'A learned policy for following a person: learned-person', its "
                 f"table (boids eval --suite person_learned, 13 robots, seeds 0-4, means)")

_CROWD_TABLE = ("docs/how-to/people.md, 'Following a person through buildings among "
                "pedestrians: learned-crowd' (boids eval --suite person_buildings, 13 robots, "
                "seeds 0-4, means; lost summed; intimate: time in the person's intimate zone)")

_BUILDINGS_TABLE = ("docs/how-to/buildings.md, 'The learned follower: learned-buildings' "
                    "(boids eval --suite buildings, 13 robots, seeds 0-4, means; lost: "
                    "followers > 3 m from the leader at the end, summed)")

SHIPPED: dict[str, dict[str, Any]] = {
    "learned": {
        "summary": "the open floor: the study's arena, any path, 7-49 robots (not walls: "
                   "in small_room robots touch a wall 74 % of the time)",
        "recipe": "ppo_safe + ppo_safe_stage2",
        "leader_speeds": (0.4, 0.7),  # 0.4 and 0.7 m/s validated unseen
        "paths": ("square", "circle", "figure_eight", "random_waypoints", "waypoints"),
        "validation": _cases("generalisation", _LEARNED_TABLE, [
            ("default", _f(0.917, 0.0, 0.0, V_sep=0.643, V_coh=0.0, V_align=0.274)),
            ("7 robots", _f(0.622, 0.0, 0.0)),
            ("19 robots", _f(1.746, 0.002, 0.0)),
            ("leader 0.5", _f(1.631, 0.0, 0.007)),
            ("leader 0.6", _f(1.249, 0.0, 0.0)),
            ("unseen: waypoint square", _f(0.482, 0.0, 0.0)),
            ("unseen: 43 robots", _f(5.497, 0.0, 0.015)),
            ("unseen: leader 0.7", _f(1.316, 0.0, 0.0)),
            ("unseen: figure-eight 3 m", _f(0.246, 0.0, 0.0)),
            ("unseen: leader 0.4", _f(2.327, 0.003, 0.017))])
        + _cases("scenes", _SCENES_TABLE, [
            ("small_room (outside its card)", _f(3.068, 0.0, 0.737)),
            ("doorway (outside its card)", _f(1.335, 0.003, 0.091)),
            ("lab (outside its card)", _f(3.364, 0.02, 0.26))]),
    },
    "learned-study": {
        "summary": "what the study's reward alone teaches; not for robots (some pair "
                   "touches 92 % of the time)",
        "recipe": "ppo_study",
        "validation": _cases("generalisation", _LEARNED_TABLE, [
            ("default", _f(0.262, 0.924, 0.201)),
            ("7 robots", _f(0.079, 0.964, 0.074)),
            ("19 robots", _f(0.398, 0.937, 0.196))]),
    },
    "learned-person": {
        "summary": "following a walking person in open space (no crowd, no walls)",
        "recipe": "ppo_person (on ppo_safe)",
        "validation": _cases("person_learned", _PERSON_TABLE, [
            ("square 0.55", _f(1.21, 0.011, 0.009, V_sep=0.09, V_coh=0.12, V_align=1.0,
                               intimate=0.001, person_contacts=0.0)),
            ("circle 0.5", _f(0.84, 0.0, 0.0, intimate=0.0, person_contacts=0.0)),
            ("figure-eight 0.6", _f(0.89, 0.0, 0.0, intimate=0.0, person_contacts=0.0)),
            ("doorway (outside its card)", _f(3.13, 0.22, 0.16)),
            ("doorway walk replayed (outside its card)", _f(2.71, 0.092, 0.166))]),
    },
    "learned-scenes": {
        "summary": "rooms, doors, corridors, pillars and maps, leaders who stand still, with "
                   "the safety filter (not generated floor plans)",
        "recipe": "ppo_scenes + stages 2-7 (stage 7, seed 0)",
        "validated_scenes": ("small_room", "lab", "map", "shapes"),
        "leader_speeds": (0.25, 0.65),  # 0.25 m/s validated unseen
        "validation": _cases("scenes", _SCENES_TABLE, [
            ("arena", _f(0.890, 0.0016, 0.0, farthest=1.88)),
            ("small_room", _f(4.169, 0.0114, 0.0, farthest=1.82)),
            ("doorway", _f(1.718, 0.0, 0.0, farthest=1.85)),
            ("corridor", _f(3.505, 0.0, 0.0, farthest=1.72)),
            ("pillars", _f(2.190, 0.0, 0.0, farthest=2.26)),
            ("unseen: lab", _f(4.283, 0.0, 0.0, farthest=1.48))])
        + _cases("deployment", _SCENES_TABLE, [
            ("unseen room", _f(5.300, 0.0, 0.0, farthest=1.51)),
            ("square 45° near walls", _f(1.519, 0.0, 0.0, farthest=1.91)),
            ("leader 0.25", _f(1.310, 0.0, 0.0, farthest=1.56)),
            ("standing 30 s", _f(3.365, 0.0, 0.0, farthest=2.02, parked_speed=0.049)),
            ("61 robots", _f(14.514, 0.0029, 0.0, farthest=2.04))]),
    },
    "learned-buildings": {
        "summary": "buildings: generated floor plans, rooms, doors, corridors, shelves and "
                   "maps, leaders who stand in a doorway, with route sensing and the safety "
                   "filter; acts as learned-scenes for the followers that see the leader "
                   "(so on open floor it is learned-scenes) and as this route model for the "
                   "others",
        "recipe": "ppo_buildings + ppo_buildings_stage2 (seed 0), switched by sight with "
                  "learned-scenes",
        "validated_scenes": ("lab", "map"),
        "validation": _cases("buildings", _BUILDINGS_TABLE, [
            ("held-out plans 1000-1019 (100 episodes)", _f(6.14, 0.0009, 0.0, lost=0)),
            ("unseen: lab", _f(5.06, 0.0, 0.0, lost=0)),
            ("doorway stops, plans 1000-1002", _f(6.86, 0.0017, 0.0, lost=0)),
            ("noise 0.05, plans 1000-1002", _f(6.50, 0.0003, 0.0, lost=0)),
            ("ROS realism, plans 1000-1002", _f(9.63, 0.0, 0.0, lost=2))])
        + _cases("open floor", _BUILDINGS_TABLE, [
            ("the study's default case", _f(0.890, 0.0016, 0.0, lost=0))]),
    },
    "learned-crowd": {
        "summary": "a person walking through buildings (generated floor plans, the open "
                   "arena, doorways) among up to 12 pedestrians, with route sensing, 4 "
                   "pedestrian slots and the safety filter keeping robots out of the "
                   "person's intimate zone (0.45 m) and out of its path for the next 2 s; "
                   "pedestrians still come closer than reynolds@proxemic lets them (its "
                   "pedestrian intimate time is 3-6 x)",
        "recipe": "ppo_crowd + ppo_crowd_stage2 (seed 0, 1.25 M + 1.2 M steps on "
                  "learned-buildings' route model)",
        "validation": _cases("person_buildings", _CROWD_TABLE, [
            ("square, crowd 8", _f(2.551, 0.00023, 0.0, lost=0, intimate=0.00028,
                                   pedestrian_intimate=0.0852)),
            ("floorplan 1004, crowd 8", _f(9.662, 0.00866, 0.0, lost=0, intimate=0.00033,
                                           pedestrian_intimate=0.2607)),
            ("floorplan 1011, crowd 8", _f(8.593, 0.00569, 0.0, lost=0, intimate=0.00035,
                                           pedestrian_intimate=0.1534)),
            ("floorplan 1016, crowd 8", _f(8.160, 0.00385, 0.0, lost=0, intimate=0.00066,
                                           pedestrian_intimate=0.0971)),
            ("floorplan 1004, crowd 12", _f(9.663, 0.00614, 0.0, lost=0, intimate=0.00051,
                                            pedestrian_intimate=0.3172))]),
    },
}
"""What each shipped model's measurements add to the card its training config gives. A new
shipped model (a name in :data:`~boids_env.policies.registry.MODELS`) gets its card from its
training config alone until an entry here adds its summary, recipe, what it was validated on
and its figures (``_cases(suite, source, [(case, _f(total, touching, wall, ...)), ...])``);
then ``python -m boids_env.train.cards`` writes it into the zip."""


def write_card(path: str | Path, card: ModelCard) -> None:
    """Writes ``card`` into the ``boids.json`` of the model zip ``path`` (replacing any), every
    other entry kept byte for byte (:func:`~boids_env.policies.sb3_policy.write_meta`)."""
    meta = read_meta(path)
    write_meta(path, {**meta, CARD_KEY: json.loads(card.to_json())})


def shipped_card(name: str) -> ModelCard:
    """The card of shipped model ``name``: its training config's card with :data:`SHIPPED`'s
    additions (none for a model not listed there yet)."""
    meta = read_meta(MODELS[name])
    card = card_from_training(meta["train_config"], meta.get("env_fields"))
    return dataclasses.replace(card, **SHIPPED.get(name, {}))


def write_shipped_cards() -> None:
    """Writes :func:`shipped_card` into every shipped model zip whose card differs."""
    for name, path in MODELS.items():
        card = shipped_card(name)
        meta = read_meta(path)
        if CARD_KEY not in meta or read_card(path, meta) != card:
            write_card(path, card)
            print(f"wrote the card of {name} into {path}")


if __name__ == "__main__":
    write_shipped_cards()
