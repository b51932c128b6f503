"""Experiment suites as data: cases (a factor at a level, as env fields and policy
parameters) × seeds (the types are in :mod:`boids_env.eval.cases`). The ``paper`` suite is
the study's Table III; ``robustness`` covers what the study lists as future work. Users write
their own in TOML (see :func:`load_suite`)."""

from __future__ import annotations

import dataclasses
import difflib
from pathlib import Path
from typing import Any

from boids_env.config import FIELD_OWNER, EnvConfig, check_integer
from boids_env.eval.cases import (
    MAX_CASES,
    POLICY_FIELDS,
    Case,
    Suite,
    check_seeds,
    check_unique,
    sweep,
)
from boids_env.policies.reynolds_params import reynolds_params
from boids_env.untrusted import excerpt, parse_toml, quote_path, read_text, safe_name
from boids_env.world.robots import ROBOT_PRESETS

MAX_SUITE_BYTES = 1024 * 1024
"""A suite file larger than this (1 MiB) is refused before it is read."""

CONTROLLED = {"robots": 13, "leader_speed": 0.55, "leader_weight": 1.0}
"""The study's controlled values (its Table III)."""

PAPER = Suite("paper", tuple(
    sweep("rq1", "leader_speed", [(s, {"leader_speed": float(s)})
                                  for s in ("0.5", "0.55", "0.6")], CONTROLLED)
    + sweep("rq2", "leader_weight", [(w, {"leader_weight": float(w)})
                                     for w in ("1.0", "1.1", "1.2")], CONTROLLED)
    + sweep("rq3", "robots", [(n, {"robots": int(n)}) for n in ("7", "13", "19")],
            CONTROLLED)), per_follower=("rq3",))
"""Table III: three research questions × three levels, five seeds. Cases 2, 4 and 8 are the
same configuration and are run once."""

ROBUSTNESS = Suite("robustness", tuple(
    sweep("path", "path", [(p, {"path": p}) for p in
                           ("square", "circle", "figure_eight", "random_waypoints")], CONTROLLED)
    + sweep("placement", "init_jitter", [(j, {"init_jitter": float(j)})
                                         for j in ("0.05", "0.12", "0.2")], CONTROLLED)
    + sweep("group_size", "robots", [(n, {"robots": int(n)}) for n in ("13", "31", "61")],
            CONTROLLED)
    + sweep("noise", "obs_noise", [(s, {"obs_noise": float(s)})
                                   for s in ("0.0", "0.02", "0.05")], CONTROLLED)))
"""Future work of the study: other leader paths, initial placement spread, larger groups and
sensing noise (Gaussian, std in m and m/s), 13 robots at 0.55 m/s otherwise."""

GENERALISATION = Suite("generalisation", (
    Case("default", "trained", "case", "default"),
    Case("7 robots", "trained", "case", "7 robots", {"robots": 7}),
    Case("19 robots", "trained", "case", "19 robots", {"robots": 19}),
    Case("leader 0.5", "trained", "case", "leader 0.5", {"leader_speed": 0.5}),
    Case("leader 0.6", "trained", "case", "leader 0.6", {"leader_speed": 0.6}),
    Case("waypoint square", "unseen", "case", "waypoint square",
         {"path": "waypoints", "waypoints": ((3.0, 3.0), (-3.0, 3.0), (-3.0, -3.0),
                                             (3.0, -3.0), (3.0, 3.0))}),
    Case("43 robots", "unseen", "case", "43 robots", {"robots": 43}),
    Case("leader 0.7", "unseen", "case", "leader 0.7", {"leader_speed": 0.7}),
    Case("figure-eight 3 m", "unseen", "case", "figure-eight 3 m",
         {"robots": 10, "path": "figure_eight", "path_size": 3.0}),
    Case("leader 0.4", "unseen", "case", "leader 0.4", {"leader_speed": 0.4})))
"""The shipped learned policy's bar: five cases its recipe trains on (``trained``) and five it
does not (``unseen``: a path, a group size, speeds and a path size outside the recipe, picked
before training), 13 robots at 0.55 m/s on the study's square otherwise."""

SCENES = Suite("scenes", tuple(
    Case(name, "scenes", "scene", name, {} if name == "arena" else {"scene": name})
    for name in ("arena", "small_room", "doorway", "corridor", "pillars", "lab")))
"""Every built-in scene with its own leader path and start, 13 robots at 0.55 m/s: walls near
the path, a door, a corridor loop, a pillar field and a lab's map. The Reynolds policy
avoids obstacles in all but the arena."""

PERSON_BASE = {"scene": "doorway", "leader": "person", "robots": 13, "leader_speed": 0.5}
"""The ``person`` suite's controlled values: a person walking the doorway scene's path at the
robots' top speed (0.5 m/s preferred), 13 robots, no crowd."""

PERSON = Suite("person", tuple(
    sweep("speed", "leader_speed", [(s, {"leader_speed": float(s)})
                                    for s in ("0.4", "0.5", "0.6", "0.75")], PERSON_BASE)
    + sweep("group_size", "robots", [(n, {"robots": int(n)}) for n in ("7", "13", "19")],
            PERSON_BASE)
    + sweep("crowd", "crowd", [(n, {"crowd": int(n)}) for n in ("0", "5", "10", "20")],
            PERSON_BASE)))
"""The study's questions with a person leading (the ``people`` extra): the person's preferred
walking speed against the robots' top speed of 0.5 m/s (0.8×, 1×, 1.2×, 1.5×: the study's
RQ1 trade-off), the group size, and the crowd's density (0, 5, 10, 20 pedestrians in the
doorway scene's 71.5 m² of floor: 0 to 0.28 per m²). Run it for ``reynolds`` and
``reynolds@proxemic``."""

_FOLLOW = {"leader": "person", "robots": 13}
PERSON_LEARNED = Suite("person_learned", (
    Case("square 0.55", "trained", "case", "square 0.55", {**_FOLLOW, "leader_speed": 0.55}),
    Case("circle 0.5", "trained", "case", "circle 0.5",
         {**_FOLLOW, "path": "circle", "leader_speed": 0.5}),
    Case("figure-eight 0.6", "trained", "case", "figure-eight 0.6",
         {**_FOLLOW, "path": "figure_eight", "leader_speed": 0.6}),
    Case("doorway", "unseen", "case", "doorway", {**_FOLLOW, "scene": "doorway"}),
    Case("doorway walk replayed", "unseen", "case", "doorway walk replayed",
         {**_FOLLOW, "scene": "doorway", "leader": "trajectory",
          "leader_trajectory": "doorway_walk"})))
"""The ``learned-person`` policy's bar: a person walking three paths of the kind its recipe
trains on (``trained``) and two it never saw (``unseen``: the doorway scene, and the shipped
walk replayed there), 13 robots."""

UNSEEN_ROOM = Path(__file__).parent / "data" / "unseen_room.toml"
"""A shapes-file room no recipe trains in: L-shaped, 7 m × 5 m, two pillars."""

DEPLOYMENT = Suite("deployment", (
    Case("lab", "unseen", "case", "lab", {"scene": "lab"}),
    Case("unseen room", "unseen", "case", "unseen room", {"scene": str(UNSEEN_ROOM)}),
    Case("square 45° near walls", "unseen", "case", "square 45° near walls",
         {"path_rotation": 45.0, "path_size": 3.35}),
    Case("leader 0.25", "unseen", "case", "leader 0.25", {"leader_speed": 0.25}),
    Case("standing 30 s", "unseen", "case", "standing 30 s",
         {"leader_pauses": ((20.0, 30.0),)}),
    Case("61 robots", "trained", "case", "61 robots", {"robots": 61})))
"""The lab-deployment bar of the scenes recipe (``ppo_scenes``, issue 26), beside the
``scenes`` and ``generalisation`` suites: five cases picked before its training and never
trained on (``unseen``: the lab's ROS map, a shapes-file room, the study's square turned 45°
and passing 0.26 m from the walls, a 0.25 m/s leader, a leader standing 30 s 20 s into the
square) and 61 robots, its largest trained group; 13 robots at 0.55 m/s otherwise."""

VALIDATION = Suite("validation", (
    *(dataclasses.replace(c, group="trained") for c in SCENES.cases if c.name != "lab"),
    Case("61 robots", "trained", "case", "61 robots", {"robots": 61}),
    Case("standing 40 s", "trained", "case", "standing 40 s",
         {"leader_pauses": ((25.0, 40.0),)})), seeds=(100, 101, 102, 103, 104))
"""What ``boids select`` picks checkpoints on (the scenes recipe's stage 6, issue 26): its
TRAINED cases only — the built-in scenes but the lab, 61 robots, and a leader standing 40 s
after 25 s (one of the recipe's drawn pauses) — on seeds 100-104, so that the episodes a
choice is made on are not the ones reported (seeds 0-4) and no unseen case enters it."""

TURTLEBOT = {"robot": "turtlebot3_burger"}
TURTLEBOT_GENERALISATION = Suite("turtlebot_generalisation", (
    Case("default", "trained", "case", "default", dict(TURTLEBOT)),
    Case("7 robots", "trained", "case", "7 robots", {**TURTLEBOT, "robots": 7}),
    Case("19 robots", "trained", "case", "19 robots", {**TURTLEBOT, "robots": 19}),
    Case("leader 0.22", "trained", "case", "leader 0.22", {**TURTLEBOT, "leader_speed": 0.22}),
    Case("leader 0.264", "trained", "case", "leader 0.264",
         {**TURTLEBOT, "leader_speed": 0.264}),
    Case("waypoint square", "unseen", "case", "waypoint square",
         {**TURTLEBOT, "path": "waypoints",
          "waypoints": ((3.0, 3.0), (-3.0, 3.0), (-3.0, -3.0), (3.0, -3.0), (3.0, 3.0))}),
    Case("25 robots", "unseen", "case", "25 robots", {**TURTLEBOT, "robots": 25}),
    Case("leader 0.18", "unseen", "case", "leader 0.18", {**TURTLEBOT, "leader_speed": 0.18}),
    Case("leader 0.30", "unseen", "case", "leader 0.30", {**TURTLEBOT, "leader_speed": 0.3}),
    Case("figure-eight 3 m", "unseen", "case", "figure-eight 3 m",
         {**TURTLEBOT, "robots": 10, "path": "figure_eight", "path_size": 3.0})))
"""The learned TurtleBot3 follower's bar (recipe ``ppo_turtlebot``): five cases its recipe
trains on and five it does not (a path, a group size, leader speeds below and above its range,
a path size; picked before training), 13 TurtleBots at 0.242 m/s (1.1 × their top speed) on
the study's square otherwise."""

LEADER_RATIOS = (1.0, 1.1, 1.2)
"""The study's leader speeds over the followers' top speed (0.5 / 0.55 / 0.6 m/s over 0.5)."""


def robot_cases(robot: str) -> list[Case]:
    """The study's Table III for robot preset ``robot``: its research questions as groups
    ``rq1@robot`` (leader 1.0 / 1.1 / 1.2 × the robot's top speed, labelled ``1.0x`` …),
    ``rq2@robot`` (leader weight 1.0 / 1.1 / 1.2) and ``rq3@robot`` (7 / 13 / 19 robots), 13
    robots at 1.1 × the top speed and weight 1.0 otherwise (the study's case for that
    robot)."""
    top = ROBOT_PRESETS[robot].max_speed
    speeds = {f"{r:.1f}x": round(r * top, 9) for r in LEADER_RATIOS}
    base = {"robot": robot, "robots": 13, "leader_speed": speeds["1.1x"]}
    cases = []
    sweeps = (("rq1", "leader_speed", [(k, {"leader_speed": v}) for k, v in speeds.items()]),
              ("rq2", "leader_weight", [(w, {"leader_weight": float(w)})
                                        for w in ("1.0", "1.1", "1.2")]),
              ("rq3", "robots", [(n, {"robots": int(n)}) for n in ("7", "13", "19")]))
    for group, factor, levels in sweeps:
        for label, values in levels:
            merged = {**base, "leader_weight": 1.0, **values}
            cases.append(Case.from_fields(f"{robot}: {factor}={label}", f"{group}@{robot}",
                                          factor, label, merged))
    return cases


ROBOT_TYPES = Suite("robot_types", tuple(c for robot in ROBOT_PRESETS
                                         for c in robot_cases(robot)),
                    per_follower=tuple(f"rq3@{robot}" for robot in ROBOT_PRESETS))
"""The study's three research questions for every robot preset (the study's open question on
robot type), with the study's statistics per robot; the report says, finding by finding,
which hold for which robot."""

BUILDING_SEEDS = tuple(range(1000, 1020))
"""Held-out floor-plan seeds (``floorplan:1000`` … ``floorplan:1019``) of the ``buildings``
suite: fixed before route-Reynolds was tuned and never looked at while tuning (tuning used
plans 0-19 and the built-in scenes); a learned follower must not train on them either."""
BUILDINGS_BASE = {"robots": 13, "leader_speed": 0.55, "tail_time": 10.0}
"""The ``buildings`` suite's controlled values: 13 robots at 0.55 m/s, and the episode ends 10 s
after the leader arrives (not 0.5 s), so that a flock still filing through the last door
behind it is not counted lost: lost means stranded."""
DOORWAY_STOPS = {1000: 7.9, 1001: 49.1, 1002: 7.7}
"""Driving time (s, after start-up) at which the leader of these held-out plans stands in
its first doorway (checked by a test); it stands there 20 s."""


def _plan(seed: int, group: str, extra: dict[str, Any] | None = None, label: str = ""
          ) -> Case:
    name = f"floorplan {seed}{label}"
    return Case(name, group, "case", name, {**BUILDINGS_BASE, "scene": f"floorplan:{seed}",
                                            **(extra or {})})


BUILDINGS = Suite("buildings", (
    *(_plan(s, "held_out") for s in BUILDING_SEEDS),
    *(Case(name, "built_in", "case", name, {**BUILDINGS_BASE, "scene": name})
      for name in ("lab", "doorway", "corridor")),
    *(_plan(s, "doorway_stop", {"leader_pauses": ((t, 20.0),)}, " stop 20 s in door")
      for s, t in DOORWAY_STOPS.items()),
    *(_plan(s, "noise", {"obs_noise": 0.05}, " noise 0.05") for s in BUILDING_SEEDS[:3]),
    *(_plan(s, "noise", {"realism": "ros"}, " ros realism") for s in BUILDING_SEEDS[:3])))
"""Issue 36's bar for following through buildings: 20 generated floor plans held out from
tuning and training (:data:`BUILDING_SEEDS`), the built-in ``lab``, ``doorway`` and
``corridor``, a leader standing 20 s in a doorway, sensing noise (0.05 m, m/s) and the ROS
realism; 13 robots at 0.55 m/s, ending 10 s after the leader's arrival. ``lost_followers``
(farther than 3 m from the leader at the end) is in its safety table. Run it for
``reynolds`` and ``reynolds@route``."""

ROBOTS_BUILDINGS_PLANS = (1004, 1011, 1016)
"""Held-out floor plans (of :data:`BUILDING_SEEDS`) of the ``robots_buildings`` suite, picked
before the ``scaled`` Reynolds preset was tuned (it was tuned on plans 3, 5 and 8 and the
study's square on seeds 10-11)."""
ROBOTS_BUILDINGS_ROBOTS = ("turtlebot3_burger", "gritsbot")
"""The robots of the ``robots_buildings`` suite: those larger than the study's Sphero."""


def _robot_building_cases(robot: str) -> list[Case]:
    square = Case(f"{robot}: square", robot, "scene", "square", {"robot": robot, "robots": 13})
    plans = [Case(f"{robot}: floorplan {s}", robot, "scene", f"floorplan {s}",
                  {"robot": robot, "robots": 13, "tail_time": 10.0, "scene": f"floorplan:{s}"})
             for s in ROBOTS_BUILDINGS_PLANS]
    return [square, *plans]


ROBOTS_BUILDINGS = Suite("robots_buildings", tuple(
    c for robot in ROBOTS_BUILDINGS_ROBOTS for c in _robot_building_cases(robot)))
"""Issue 38's bar for robots larger than a Sphero (picked before tuning): TurtleBot3 Burger and
GRITSbot flocks of 13 on the study's square and on held-out floor plans
(:data:`ROBOTS_BUILDINGS_PLANS`), the leader at 1.1 × the robot's top speed, episodes in a
building ending 10 s after the leader's arrival (as ``buildings``); 5 seeds. Bar: touching
≤ 1 %, walls ≤ 1 %, no follower lost. Run it for ``reynolds``, ``reynolds@route`` and
``reynolds@scaled``."""

CROWD_BUILDINGS = Suite("crowd_buildings", (
    Case("square, crowd 8", "crowd", "scene", "square", {"robots": 13, "crowd": 8}),
    *(Case(f"floorplan {s}, crowd 8", "crowd", "scene", f"floorplan {s}",
           {"robots": 13, "crowd": 8, "tail_time": 10.0, "scene": f"floorplan:{s}"})
      for s in ROBOTS_BUILDINGS_PLANS[:2])))
"""The ``scaled`` Reynolds preset's crowd cases (picked before it was run on any crowd): 13
Spheros (crowds walk among holonomic robots only) and 8 pedestrians on the study's square and
two held-out floor plans (as ``robots_buildings``); 5 seeds."""

_PERSON_CROWD = {"leader": "person", "robots": 13, "crowd": 8, "leader_speed": 0.5}
PERSON_BUILDINGS = Suite("person_buildings", (
    Case("square, crowd 8", "crowd", "scene", "square", dict(_PERSON_CROWD)),
    *(Case(f"floorplan {s}, crowd 8", "crowd", "scene", f"floorplan {s}",
           {**_PERSON_CROWD, "tail_time": 10.0, "scene": f"floorplan:{s}"})
      for s in ROBOTS_BUILDINGS_PLANS),
    Case(f"floorplan {ROBOTS_BUILDINGS_PLANS[0]}, crowd 12", "crowd", "scene",
         f"floorplan {ROBOTS_BUILDINGS_PLANS[0]} crowd 12",
         {**_PERSON_CROWD, "crowd": 12, "tail_time": 10.0,
          "scene": f"floorplan:{ROBOTS_BUILDINGS_PLANS[0]}"})))
"""Issue 38's bar for following a person through a crowd (picked before ``learned-crowd`` was
trained, which trains on none of them): a person walking at 0.5 m/s (preferred) leads 13
Spheros with 8 pedestrians on the study's square and through the held-out floor plans of
``robots_buildings``, and with 12 pedestrians in the first; episodes in a building end 10 s
after the person arrives. Bar: touching ≤ 1 %, no follower lost, time in the person's
intimate zone (``intimate_fraction``) below ``reynolds@proxemic``'s. The people extra."""

SUITES = {"paper": PAPER, "robustness": ROBUSTNESS, "generalisation": GENERALISATION,
          "scenes": SCENES, "buildings": BUILDINGS, "deployment": DEPLOYMENT,
          "validation": VALIDATION, "person": PERSON,
          "person_learned": PERSON_LEARNED, "robot_types": ROBOT_TYPES,
          "turtlebot_generalisation": TURTLEBOT_GENERALISATION,
          "robots_buildings": ROBOTS_BUILDINGS, "crowd_buildings": CROWD_BUILDINGS,
          "person_buildings": PERSON_BUILDINGS}


def load_suite(spec: str | Path) -> Suite:
    """A built-in suite by name (``paper``, ``robustness``) or a TOML file::

        name = "speeds"
        seeds = 3                      # or a list [0, 1, 2]
        [defaults]                     # fields shared by every case
        robots = 13
        max_cycles = 300
        [[factor]]                     # one group: a field swept over levels
        name = "leader_speed"
        levels = [0.5, 0.6]
        [[case]]                       # or explicit cases
        name = "big and fast"
        group = "extra"
        robots = 31
        leader_speed = 0.6

    Fields are env config fields by flat name or Reynolds parameters (``leader_weight`` …).
    """
    if isinstance(spec, str) and spec in SUITES:
        return SUITES[spec]
    path = Path(spec)
    if not path.exists():
        raise FileNotFoundError(f"suite must be one of {sorted(SUITES)} or a TOML file; "
                                f"{quote_path(spec)} not found")
    data = parse_toml(read_text(path, "cannot read suite file", MAX_SUITE_BYTES),
                      f"cannot read suite file {quote_path(path)}")
    try:
        return suite_from_dict(data, default_name=path.stem)
    except ValueError as exc:
        raise ValueError(f"suite file {quote_path(path)}: {exc}") from None


SUITE_KEYS = ("name", "seeds", "defaults", "factor", "case", "per_follower",
              "followers_analysed")
FACTOR_KEYS = ("name", "levels", "group")


def suite_from_dict(data: dict[str, Any], default_name: str = "custom") -> Suite:
    """Builds and validates a suite from the TOML structure of :func:`load_suite`; every
    mistake is a ``ValueError`` naming the key and what is allowed."""
    if not isinstance(data, dict):
        raise ValueError(f"a suite must be a table of keys {list(SUITE_KEYS)}, got "
                         f"{excerpt(data)}")
    unknown = sorted(set(data) - set(SUITE_KEYS))
    if unknown:
        raise ValueError(f"unknown suite key(s) {unknown}; allowed: {sorted(SUITE_KEYS)}")
    defaults = _table(data.get("defaults", {}), "defaults", "a table ([defaults]) of env "
                      "config fields and Reynolds parameters")
    _check_fields(defaults, "defaults")
    cases = [*_factor_cases(data.get("factor", []), defaults),
             *_explicit_cases(data.get("case", []), defaults)]
    if not cases:
        raise ValueError("a suite needs at least one [[factor]] or [[case]]")
    if len(cases) > MAX_CASES:
        raise ValueError(f"{len(cases):,} cases, more than the {MAX_CASES:,} allowed")
    cases = [_safe_labels(case) for case in cases]
    for case in cases:
        try:
            EnvConfig().replace(**case.env)
            reynolds_params("paper", **case.policy)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"case {case.name!r}: {exc}") from exc
    check_unique([c.name for c in cases])
    name = safe_name(data.get("name", default_name), "suite key name")
    per_follower = data.get("per_follower", [])
    if not isinstance(per_follower, list) or not all(isinstance(g, str) for g in per_follower):
        raise ValueError(f"suite key per_follower must be a list of group names, got "
                         f"{excerpt(per_follower)}")
    followers = data.get("followers_analysed", 6)
    try:
        seeds = check_seeds(data.get("seeds", 5))
        return Suite(name, tuple(cases), seeds, tuple(per_follower),
                     check_integer("followers_analysed", followers, 1, 10_000))
    except ValueError as exc:
        raise ValueError(f"suite key {exc}") from None


def _safe_labels(case: Case) -> Case:
    """``case`` with its name and labels checked and escaped where they enter (they reach
    terminals, file names and CSVs)."""
    return dataclasses.replace(case, **{
        key: safe_name(getattr(case, key), f"case {excerpt(case.name)}: {key}")
        for key in ("name", "group", "factor", "level")})


def _table(value: Any, key: str, allowed: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"suite key {key} must be {allowed}, got {excerpt(value)}")
    return dict(value)


def _tables(value: Any, key: str) -> list[dict[str, Any]]:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise ValueError(f"suite key {key} must be an array of tables ([[{key}]] sections), "
                         f"got {excerpt(value)}")
    return value


def _label(value: Any, key: str) -> str:
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise ValueError(f"{key} must be a string (or a number), got {excerpt(value)}")
    return str(value)


def _factor_cases(raw: Any, defaults: dict[str, Any]) -> list[Case]:
    cases: list[Case] = []
    for i, factor in enumerate(_tables(raw, "factor")):
        where = f"factor {i + 1}"
        unknown = sorted(set(factor) - set(FACTOR_KEYS))
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {unknown}; a [[factor]] has "
                             f"{list(FACTOR_KEYS)}")
        name, levels = factor.get("name"), factor.get("levels")
        if not isinstance(name, str):
            raise ValueError(f"{where}: name must be the field to sweep (a string), got "
                             f"{name!r}")
        _check_fields({name: None}, f"{where} ({name!r})")
        if not isinstance(levels, list) or not levels:
            raise ValueError(f"{where} ({name!r}): levels must be a non-empty list of values, "
                             f"got {excerpt(levels)}")
        group = _label(factor.get("group", name), f"{where} ({name!r}): group")
        cases += sweep(group, name, [(str(v), {name: v}) for v in levels], defaults)
    return cases


def _explicit_cases(raw: Any, defaults: dict[str, Any]) -> list[Case]:
    cases: list[Case] = []
    for i, table in enumerate(_tables(raw, "case")):
        table = dict(table)
        labels = {"name": f"case{i + 1}", "group": "cases", "factor": "case"}
        labels = {k: _label(table.pop(k, v), f"case {i + 1}: {k}") for k, v in labels.items()}
        level = _label(table.pop("level", labels["name"]), f"case {i + 1}: level")
        _check_fields(table, f"case {labels['name']!r}")
        cases.append(Case.from_fields(labels["name"], labels["group"], labels["factor"],
                                      level, {**defaults, **table}))
    return cases


def _check_fields(values: dict[str, Any], where: str) -> None:
    """Refuses names that are neither env config fields nor Reynolds parameters, naming each
    with the known names closest to it (the whole list, some 130 names, is the
    configuration reference's; an error quoting it ran past 2,000 characters)."""
    bad = sorted(k for k in values if k not in FIELD_OWNER and k not in POLICY_FIELDS)
    if bad:
        known = [*sorted(FIELD_OWNER), *POLICY_FIELDS]
        hints = []
        for name in bad[:5]:
            close = difflib.get_close_matches(str(name), known, n=3, cutoff=0.6)
            hints.append(f"{excerpt(name)} (did you mean {', '.join(map(repr, close))}?)"
                         if close else excerpt(name))
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        raise ValueError(f"{where}: unknown field(s) {', '.join(hints)}{more}: a suite sets "
                         f"env config fields ({len(FIELD_OWNER)}, e.g. robots, leader_speed, "
                         f"scene) or Reynolds parameters ({len(POLICY_FIELDS)}, e.g. "
                         f"leader_weight), listed in the configuration reference")
