"""Fuzzing the files that come from elsewhere (issue 39): maps (YAML + PGM/PNG bytes), walks
(CSV), suites and recipes (TOML), and shapes files. Whatever hypothesis writes, reading it
ends in a result or a ``ValueError``/``TypeError`` (``FileNotFoundError`` for a missing
file), never another exception, and within bounded memory. Bounded to a few seconds each."""

from __future__ import annotations

import json
import resource

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from boids_env.eval.suites import load_suite
from boids_env.train.config import TrainConfig
from boids_env.world.maps import load_map
from boids_env.world.scenes import load_scene
from boids_env.world.walks import read_walk

CLEAR = (ValueError, TypeError)
FUZZ = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])

SCALARS = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=True),
                    st.booleans(), st.text(max_size=12), st.none())
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12)


def _yaml_value(value) -> str:
    return json.dumps(value, allow_nan=True)  # JSON is YAML (flow style)


@st.composite
def map_yaml(draw):
    fields = {"image": draw(st.sampled_from(["m.pgm", "m.png", "../m.pgm", "/dev/zero",
                                             "missing.pgm"])),
              "resolution": draw(st.one_of(st.floats(1e-5, 200), SCALARS)),
              "origin": draw(st.one_of(st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3),
                                       VALUES))}
    for key in draw(st.lists(st.sampled_from(["negate", "occupied_thresh", "free_thresh",
                                              "mode"]), unique=True, max_size=4)):
        fields[key] = draw(VALUES)
    lines = [f"{k}: {_yaml_value(v)}" for k, v in fields.items()]
    aliases = draw(st.integers(0, 3))  # anchors and aliases, nested a few levels
    if aliases:
        lines.insert(0, 'a0: &a0 ["x", "x", "x"]')
        for k in range(1, aliases + 1):
            lines.insert(k, f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]")
    text = "\n".join(draw(st.permutations(lines)))
    if draw(st.integers(0, 9)) == 0:  # now and then, raw garbage
        text = draw(st.text(max_size=200))
    return text


@st.composite
def image_bytes(draw):
    w, h = draw(st.integers(0, 12)), draw(st.integers(0, 12))
    kind = draw(st.sampled_from(["P5", "P2", "raw", "png-head", "gif"]))
    if kind == "P5":
        return f"P5\n{w} {h}\n255\n".encode() + draw(st.binary(min_size=0, max_size=w * h + 4))
    if kind == "P2":
        return f"P2\n{w} {h}\n255\n".encode() + " ".join(
            str(draw(st.integers(0, 300))) for _ in range(w * h)).encode()
    if kind == "png-head":
        return b"\x89PNG\r\n\x1a\n" + draw(st.binary(max_size=64))
    if kind == "gif":
        return b"GIF89a" + draw(st.binary(max_size=32))
    return draw(st.binary(max_size=64))


@pytest.fixture(scope="module")
def peak():
    """Fails the module if reading the fuzzed files raised the process's peak memory by more
    than 500 MB (ru_maxrss is in KiB on Linux)."""
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    yield
    grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert grown < 500, f"peak memory grew by {grown:.0f} MB while reading fuzzed files"


@FUZZ
@given(text=map_yaml(), image=image_bytes())
def test_maps_are_read_or_refused_clearly(tmp_path_factory, peak, text, image):
    folder = tmp_path_factory.mktemp("map")
    (folder / "m.pgm").write_bytes(image)
    (folder / "m.png").write_bytes(image)
    path = folder / "m.yaml"
    path.write_text(text)
    try:
        scene = load_map(path)
    except CLEAR as exc:
        assert len(str(exc)) < 1000, str(exc)[:300]
        return
    assert scene.grid is not None and scene.grid.cells.size >= 1


CSV_CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                      st.integers(-2000, 2000).map(str), st.text(max_size=5),
                      st.sampled_from(["t", "x", "y", "#", ""]))


@FUZZ
@given(rows=st.lists(st.lists(CSV_CELLS, min_size=0, max_size=4), max_size=8),
       header=st.booleans())
def test_walks_are_read_or_refused_clearly(tmp_path_factory, peak, rows, header):
    path = tmp_path_factory.mktemp("walk") / "w.csv"
    path.write_text(("t,x,y\n" if header else "") + "\n".join(",".join(r) for r in rows))
    try:
        times, points = read_walk(path)
    except CLEAR as exc:
        assert len(str(exc)) < 1000, str(exc)[:300]
        return
    assert len(times) == len(points) >= 2 and (times[1:] > times[:-1]).all()


def _toml(value) -> str:
    """A TOML value (JSON's syntax for strings, numbers, arrays; inline tables)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if value is None:
        return '""'
    if isinstance(value, float) and value != value:
        return "nan"
    if isinstance(value, float) and value in (float("inf"), float("-inf")):
        return "inf" if value > 0 else "-inf"
    return json.dumps(value)


SUITE_FIELDS = ["robots", "leader_speed", "max_cycles", "leader_weight", "path", "scene",
                "name", "group", "level", "colour"]


@st.composite
def suite_text(draw):
    lines = [f"seeds = {_toml(draw(st.one_of(st.integers(-2, 20), VALUES)))}"]
    if draw(st.booleans()):
        lines.append(f"name = {_toml(draw(st.one_of(st.text(max_size=120), VALUES)))}")
    lines.append("[defaults]\nmax_cycles = 3")
    for _ in range(draw(st.integers(0, 2))):
        lines.append(f'[[factor]]\nname = {_toml(draw(st.sampled_from(SUITE_FIELDS)))}\n'
                     f'levels = {_toml(draw(st.lists(SCALARS, max_size=3)))}')
    for _ in range(draw(st.integers(0, 2))):
        lines.append("[[case]]")
        for key in draw(st.lists(st.sampled_from(SUITE_FIELDS), unique=True, max_size=3)):
            lines.append(f"{key} = {_toml(draw(VALUES))}")
    return "\n".join(lines) + "\n"


@FUZZ
@given(text=suite_text())
def test_suites_are_read_or_refused_clearly(tmp_path_factory, peak, text):
    path = tmp_path_factory.mktemp("suite") / "s.toml"
    path.write_text(text)
    try:
        suite = load_suite(path)
    except CLEAR as exc:
        assert len(str(exc)) < 2000, str(exc)[:300]
        return
    assert suite.cases and all("\x1b" not in c.name for c in suite.cases)


RECIPE_FIELDS = {"n_steps": st.integers(-1, 10**13), "batch_size": st.integers(-1, 10**13),
                 "buffer_size": st.integers(-1, 10**13), "copies": st.integers(-1, 2000),
                 "algorithm": st.sampled_from(["ppo", "sac", "dqn"]),
                 "net_arch": st.lists(st.integers(-1, 5000), max_size=70),
                 "group_sizes": st.lists(st.integers(-1, 1200), max_size=4),
                 "total_timesteps": st.integers(-1, 10**13)}


@FUZZ
@given(fields=st.dictionaries(st.sampled_from(sorted(RECIPE_FIELDS)), VALUES, max_size=3),
       plausible=st.fixed_dictionaries({}, optional=RECIPE_FIELDS))
def test_recipes_are_read_or_refused_clearly(tmp_path_factory, peak, fields, plausible):
    path = tmp_path_factory.mktemp("recipe") / "r.toml"
    path.write_text("\n".join(f"{k} = {_toml(v)}" for k, v in {**plausible, **fields}.items()
                              if v is not None) + "\n")
    try:
        config = TrainConfig.from_toml(path)
    except CLEAR as exc:
        assert len(str(exc)) < 2000, str(exc)[:300]
        return
    assert config.n_steps * sum(g - 1 for g in config.group_sizes) >= 0


SHAPE_KEYS = st.sampled_from(["box", "circle", "segment", "polygon", "name", "defaults"])


@FUZZ
@given(data=st.dictionaries(SHAPE_KEYS, VALUES, max_size=4),
       box=st.lists(st.floats(-2e3, 2e3), min_size=4, max_size=4))
def test_shapes_files_are_read_or_refused_clearly(tmp_path_factory, peak, data, box):
    path = tmp_path_factory.mktemp("shapes") / "s.json"
    path.write_text(json.dumps({"box": box, **data}, allow_nan=True))
    try:
        scene = load_scene(str(path))
    except CLEAR as exc:
        assert len(str(exc)) < 1000, str(exc)[:300]
        return
    x0, y0, x1, y1 = scene.bounds
    assert max(x1 - x0, y1 - y0) <= 500
