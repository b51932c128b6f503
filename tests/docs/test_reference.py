"""The generated reference pages list everything the code defines: every config field with
the range and unit its validation enforces, every CLI option, every observation block, every
metric."""

import argparse
import dataclasses
import re

import numpy as np
import pytest

from boids_env import checks
from boids_env.config import EnvConfig, WorldConfig
from boids_env.observations import BLOCKS, specs
from boids_env.policies.reynolds_params import ReynoldsParams
from boids_env.train.cli import build_parser
from boids_env.train.config import TrainConfig
from boids_env.world.realism import RealismConfig
from boids_env.world.safety import SafetyConfig


# ------------------------------------------------------------------ checks record themselves
def test_checks_record_what_they_enforce_inside_the_block_only():
    checks.number("a", 0.5, 0.0, 1.0)  # outside: nothing kept
    with checks.recorded() as made:
        checks.number("dt", 0.1, 0.0, 1.0, lo_open=True, unit="s")
        checks.integer("n", 3, 1, 10)
        checks.flag("on", True)
        with pytest.raises(ValueError):
            checks.number("bad", 5.0, 0.0, 1.0, hi_open=True)
    assert [(c.name, c.kind, c.allowed, c.unit) for c in made] == [
        ("dt", "number", "(0.0, 1.0]", "s"), ("n", "integer", "[1, 10]", ""),
        ("on", "flag", "True or False", ""), ("bad", "number", "[0.0, 1.0)", "")]
    with checks.recorded() as later:
        pass
    assert later == []


# ------------------------------------------------------------------ config page
def _sections(page: str) -> dict[str, dict[str, list[str]]]:
    """{anchor: {field: [type, default, range, unit, description]}} from the page's tables."""
    out: dict[str, dict[str, list[str]]] = {}
    current = None
    for line in page.splitlines():
        heading = re.match(r"^## .*\{#(\w+)\}$", line)
        if heading:
            current = out.setdefault(heading[1], {})
        elif current is not None and line.startswith("| `"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|(?=(?:[^`]*`[^`]*`)*[^`]*$)",
                                                 line)[1:-1]]
            current[cells[0].strip("`")] = cells[1:]
    return out


@pytest.fixture(scope="module")
def config_page(reference):
    return _sections(reference.config_page())


def test_every_config_section_is_on_the_page(config_page):
    env_sections = {type(getattr(EnvConfig(), f.name)) for f in dataclasses.fields(EnvConfig)}
    classes = env_sections | {ReynoldsParams, TrainConfig}
    assert {RealismConfig, SafetyConfig, WorldConfig} <= classes
    assert set(config_page) == {cls.__name__.lower() for cls in classes}


# one id each, in a fixed order (pytest-xdist's workers must collect the same list)
_SECTIONS = {cls.__name__: cls for cls in (
    WorldConfig, RealismConfig, SafetyConfig, ReynoldsParams, TrainConfig,
    *(type(getattr(EnvConfig(), f.name)) for f in dataclasses.fields(EnvConfig)))}


@pytest.mark.parametrize("cls", list(_SECTIONS.values()), ids=list(_SECTIONS))
def test_the_config_page_lists_every_field_in_order(config_page, cls):
    assert list(config_page[cls.__name__.lower()]) == [f.name for f in dataclasses.fields(cls)]


@pytest.mark.parametrize(("section", "name", "expected"), [
    # (type, default, range, unit) as config.py states them
    ("worldconfig", "dt", ["`float`", "`0.1`", "(0.0, 1.0]", "s"]),
    ("worldconfig", "substeps", ["`int`", "`10`", "[1, 1000]", "—"]),
    # checked only when given (default None): found by a probe
    ("worldconfig", "max_turn_rate", ["`float | None`", "`None`", "(0.0, 50.0]", "rad/s"]),
    ("worldconfig", "drive", ["`str`", "`'holonomic'`", "one of ('holonomic', 'unicycle')",
                              "—"]),
    ("observationconfig", "static_slots", ["`int | None`", "`None`", "[0, 64]", "—"]),
    ("scenarioconfig", "path_rotation", ["`float`", "`0`", "[-360, 360]", "degrees"]),
    ("scenarioconfig", "waypoints", ["`tuple[tuple[float, float], ...]`", "`()`", "—", "—"]),
    ("metricsconfig", "wrap_alignment", ["`bool`", "`True`", "—", "—"]),
    # realism's table of checks
    ("realismconfig", "stale_observations", ["`float | None`", "`None`", "[0.0, 1.0)", "—"]),
    ("realismconfig", "stall_margin", ["`float | None`", "`None`", "[0.0, 1.0]", "m"]),
    ("safetyconfig", "safety_gain", ["`float`", "`2`", "(0.0, 100]", "1/s"]),
    ("reynoldsparams", "max_force", ["`float`", "`0.23`", "(0.0, 1000]", "N"]),
    ("trainconfig", "group_sizes", ["`tuple[int, ...]`", "`(7, 13, 19)`", "each in [2, 1000]",
                                    "—"]),
    ("trainconfig", "algorithm", ["`str`", "`'ppo'`", "one of ('ppo', 'sac')", "—"]),
])
def test_a_field_row_gives_its_type_default_range_and_unit(config_page, section, name,
                                                           expected):
    assert config_page[section][name][:4] == expected


def test_a_field_row_carries_its_docstring(config_page):
    assert config_page["worldconfig"]["dt"][4] == ("Control period (s): 10 Hz, as the original "
                                                   "controller and simulator.")
    undocumented = [f"{section}.{name}" for section, rows in config_page.items()
                    for name, row in rows.items() if row[4] == "—"]
    assert not undocumented, f"fields without a docstring: {undocumented}"
    assert config_page["safetyconfig"]["safety_filter"][4].startswith("Filter every")


# ------------------------------------------------------------------ CLI page
def _all_parsers(parser, name="boids"):
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, child in action.choices.items():
                yield from _all_parsers(child, f"{name} {sub}")


def test_the_cli_page_lists_every_command_and_option(reference):
    page = reference.cli_page()
    commands = list(_all_parsers(build_parser()))
    assert {"boids run", "boids ros sim", "boids ros controller", "boids train"} <= \
        {name for name, _ in commands}
    for name, parser in commands:
        heading = re.search(rf"^#+ `{name}`\n(?P<body>(?:.|\n)*?)(?=^#+ `|\Z)", page, re.M)
        assert heading, f"no section for {name}"
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            for option in action.option_strings or [action.dest]:
                assert f"`{option}`" in heading["body"], f"{name}: {option} missing"


def test_an_option_row_gives_its_value_default_and_help(reference):
    page = reference.cli_page()
    row = next(line for line in page.splitlines() if line.startswith("| `--seed`"))
    assert row.startswith("| `--seed` | `SEED` | `0` | ")


# ------------------------------------------------------------------ observations page
def test_every_observation_block_has_a_meaning_and_appears(reference):
    assert [spec.name for spec in specs()] == list(BLOCKS)
    page = reference.observations_page()
    for spec in specs():
        assert spec.doc and f"| `{spec.name}` |" in page, spec.name
        assert f" | {spec.doc} |" in page, spec.name


def test_the_default_layout_is_the_studys(reference):
    page = reference.observations_page()
    default = page.split("## ")[1]
    rows = [line.split(" | ")[:3] for line in default.splitlines() if line.startswith("| `")]
    # the study's layout: own velocity, leader position, leader velocity, 18 slots of 5
    assert rows == [["| `own_velocity`", "0–1", "2"], ["| `leader_position`", "2–3", "2"],
                    ["| `leader_velocity`", "4–5", "2"], ["| `neighbours`", "6–95", "90"]]
    assert "96 values per follower" in default
    assert "| [-1, -1, -3, -3, 0] per slot | [1, 1, 3, 3, 1] per slot |" in default


# ------------------------------------------------------------------ model cards page
def test_the_model_cards_page_shows_every_shipped_model_from_its_card(reference):
    from boids_env.policies.registry import MODELS

    page = reference.models_page()
    for name, path in MODELS.items():
        assert f"| `{name}` | `{path.name}` |" in page and f"\n## {name}\n" in page, name
    learned = page.split("\n## learned\n")[1].split("\n## ")[0]
    assert "| generalisation | default | total 0.917, touching 0, wall 0," in learned
    assert "trained on the open arena only" in page


# ------------------------------------------------------------------ metrics page
def test_every_metric_an_episode_reports_is_on_the_page_with_a_meaning(reference):
    from boids_env import parallel_env

    env = parallel_env(robots=3, max_cycles=5)
    env.reset(seed=0)
    while env.agents:
        env.step({a: np.zeros(2) for a in env.agents})
    reported = set(env.episode_metrics())
    page = reference.metrics_page()
    rows = {line.split(" | ")[0].strip("| `"): line for line in page.splitlines()
            if line.startswith("| `")}
    assert reported <= set(rows)
    assert {"V_sep", "touching_fraction", "parked_speed", "V_align_heading",
            "person_contacts", "pedestrian_contacts"} <= set(rows)
    for key, line in rows.items():
        assert not line.rstrip().endswith("| — |"), f"{key} has no description"


def test_rest_roles_in_docstrings_render_as_code(reference):
    assert reference.prose("The filter (:mod:`~boids_env.world.\n    safety`), :func:`f`.") == \
        "The filter (`safety`), `f`."
    html = ("<p>See :func:<code>~boids_env.metrics.safety_metrics</code> and "
            ":mod:<code>boids_env.world.robots</code>; keep a:b:<code>c</code>.</p>")
    assert reference.on_page_content(html) == (
        "<p>See <code>safety_metrics</code> and <code>boids_env.world.robots</code>; keep "
        "a:b:<code>c</code>.</p>")
