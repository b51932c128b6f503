"""The generated reference pages: config fields, CLI, observation layout, metrics, model cards.

Every page is built from the code at build time, never committed as text: the config tables
from the dataclasses (their fields, types, defaults and field docstrings) and from the range
checks their validation makes (recorded with :func:`boids_env.checks.recorded`), the CLI page
from the ``boids`` argparse parser, the observation page from the observation layout and the
env's observation space, the metrics page from what :func:`boids_env.metrics.episode_metrics`
returns and the docstrings that name each key, the model cards page from the cards in the
shipped model zips.

MkDocs runs the hooks here (``hooks:`` in ``mkdocs.yml``): :func:`on_config` lays out the
import tree for mkdocstrings, :func:`on_files` adds the generated pages, :func:`on_page_content`
shows the docstrings' reST roles as code. The tests import the generators directly
(``tests/docs``), so they run without MkDocs installed.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import itertools
import re
import textwrap
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

try:  # the tests import the generators without the docs extra
    from mkdocs.plugins import event_priority
except ImportError:  # pragma: no cover - only without mkdocs
    def event_priority(priority: float) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
        return lambda fn: fn

PAGES: dict[str, Callable[[], str]] = {}
"""Generated page path (under ``docs/``) -> its generator."""


def page(path: str) -> Callable[[Callable[[], str]], Callable[[], str]]:
    def register(fn: Callable[[], str]) -> Callable[[], str]:
        PAGES[path] = fn
        return fn
    return register


# --------------------------------------------------------------------------- Markdown helpers
_ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|obj):`~?([^`]+)`")


def prose(text: str | None) -> str:
    """A docstring as Markdown on one line: reST roles become code spans, whitespace folds."""
    if not text:
        return ""
    text = " ".join(text.split())
    return _ROLE.sub(lambda m: "`" + (m[1].rsplit(".", 1)[-1] if "~" in m[0] else m[1])
                     .replace(" ", "") + "`", text)


_CODE_SPAN = re.compile(r"(``.+?``|`[^`]+`)")


def cell(text: str) -> str:
    """Text safe in a Markdown table cell: pipes outside code spans escaped (the table
    extension leaves those inside alone), no raw HTML."""
    parts = _CODE_SPAN.split(text.replace("\n", " "))
    return "".join(part if i % 2 else part.replace("|", "\\|").replace("<", "&lt;")
                   for i, part in enumerate(parts)) or "—"


def code(text: str) -> str:
    """A code span of ``text``."""
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def table(header: Iterable[str], rows: Iterable[Iterable[str]]) -> str:
    head = list(header)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


GENERATED = ("<!-- Generated at build time by docs/hooks/reference.py from the code; "
             "do not edit. -->\n\n")


# --------------------------------------------------------------------------- config reference
def field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of a dataclass (the string literal after it)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body  # type: ignore[attr-defined]
    docs = {}
    for stmt, nxt in itertools.pairwise(body):
        if (isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name)
                and isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)):
            docs[stmt.target.id] = inspect.cleandoc(nxt.value.value)
    return docs


class _Probe:
    """A value no check accepts: setting a field to it makes the field's check run (and be
    recorded) even where the check is skipped for the default (``None``)."""

    def __repr__(self) -> str:
        return "<probe>"


_ONE_OF = re.compile(r"^(?P<name>\w+) must be one of (?P<allowed>.+?), got ")


@dataclasses.dataclass(frozen=True)
class FieldRow:
    """One config field as its reference row reads it."""

    name: str
    type: str
    default: Any
    allowed: str
    unit: str
    doc: str


def field_rows(cls: type) -> list[FieldRow]:
    """Every field of the config dataclass ``cls``, with the range and unit of the check its
    validation makes (recorded on a default instance, or on one whose field holds a probe
    where the default skips the check), or the choices its error message names."""
    from boids_env.checks import recorded

    with recorded() as made:
        default = cls()
    checks: dict[str, Any] = {}
    for check in made:
        checks.setdefault(check.name, check)
    docs = field_docs(cls)
    rows = []
    for f in dataclasses.fields(cls):
        check, choices = checks.get(f.name), ""
        if check is None:
            check, choices = _probe(cls, f.name)
        allowed, unit = "—", "—"
        if check is not None and check.kind != "flag":
            allowed, unit = check.allowed, check.unit or "—"
            if str(f.type).startswith("tuple"):
                allowed = f"each in {allowed}"
        elif choices:
            allowed = f"one of {choices}"
        rows.append(FieldRow(f.name, str(f.type), getattr(default, f.name), allowed, unit,
                             docs.get(f.name, "")))
    return rows


def _probe(cls: type, name: str) -> tuple[Any, str]:
    """The check a field's validation makes for a value it refuses, and the choices its
    error names (``drive must be one of (...)``)."""
    from boids_env.checks import recorded

    with recorded() as made:
        try:
            cls(**{name: _Probe()})
        except Exception as exc:  # any refusal: what matters is what was checked
            match = _ONE_OF.match(str(exc))
            if match and match["name"] == name:
                return None, match["allowed"]
    return next((c for c in made if c.name == name), None), ""


def _default_text(value: Any) -> str:
    if isinstance(value, float):
        return code(f"{value:g}")
    return code(repr(value))


def config_sections() -> list[tuple[str, type, str]]:
    """(title, class, how it is set) of every config dataclass the user sets."""
    from boids_env.config import EnvConfig
    from boids_env.policies.reynolds_params import ReynoldsParams
    from boids_env.train.config import TrainConfig

    env = EnvConfig()
    out = [(f"`{f.name}`: {type(getattr(env, f.name)).__name__}", type(getattr(env, f.name)),
            "env") for f in dataclasses.fields(EnvConfig)]
    out.append(("Reynolds controller: ReynoldsParams", ReynoldsParams, "reynolds"))
    out.append(("Training: TrainConfig", TrainConfig, "train"))
    return out


_HOW = {
    "env": "Set these by their flat names: `BoidsEnv(robots=19, leader_speed=0.6)`, "
           "`EnvConfig.from_kwargs(...)`, `boids run --set FIELD=VALUE`, or a suite's case.",
    "reynolds": "Set these with `reynolds_params(preset, **overrides)` (presets: "
                "`boids_env.policies.reynolds_params.PRESETS`) or "
                "`ReynoldsPolicy(preset, **overrides)`; the controller's timing (`dt`, "
                "`startup_time`) is the env's.",
    "train": "Set these in a training TOML file (top level or a `[train]` table: `boids "
             "train --config FILE.toml`) or with `boids train`'s flags.",
}


@page("reference/config.md")
def config_page() -> str:
    parts = [GENERATED, "# Configuration reference\n\n",
             "Every field of every configuration dataclass, generated from the code: its type, "
             "its default, the allowed range and unit its validation enforces (a value "
             "outside it raises `ValueError` naming the field, the value and the range), and "
             "its docstring. A range of — means the field has no numeric range (its "
             "docstring says what it takes). Ranges are those a default config enforces; a "
             "bound that depends on another field (`processes` ≤ `copies`) is shown at that "
             "field's default.\n"]
    for title, cls, how in config_sections():
        anchor = cls.__name__.lower()
        parts.append(f"\n## {title} {{#{anchor}}}\n\n{prose(cls.__doc__)}\n\n{_HOW[how]}\n\n")
        rows = [(code(r.name), code(r.type), _default_text(r.default), cell(r.allowed),
                 cell(r.unit), cell(prose(r.doc))) for r in field_rows(cls)]
        parts.append(table(("field", "type", "default", "range", "unit", "description"),
                           rows) + "\n")
    return "".join(parts)


# --------------------------------------------------------------------------- CLI reference
def parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """``(command, parser)`` of ``boids`` and every subcommand, depth first."""
    from boids_env.train.cli import build_parser

    out: list[tuple[str, argparse.ArgumentParser]] = []

    def walk(prefix: str, parser: argparse.ArgumentParser) -> None:
        out.append((prefix, parser))
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(f"{prefix} {name}", sub)

    walk("boids", build_parser())
    return out


def _option_row(parser: argparse.ArgumentParser, action: argparse.Action) -> tuple[str, ...]:
    formatter = parser._get_formatter()
    names = ", ".join(code(s) for s in action.option_strings) or code(action.dest)
    if action.nargs == 0:
        value = "—"
    else:
        value = code(formatter._format_args(action, formatter._get_default_metavar_for_optional(
            action) if action.option_strings else action.dest))
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        value += "<br>one of " + ", ".join(code(str(c)) for c in action.choices)
    default = action.default
    shown = ("—" if default is None or default is argparse.SUPPRESS or action.nargs == 0
             else code(repr(default)))
    helped = formatter._expand_help(action) if action.help else ""
    return names, value, shown, cell(prose(helped))


@page("reference/cli.md")
def cli_page() -> str:
    parts = [GENERATED, "# Command-line reference\n\n",
             "Every `boids` command, subcommand and option, generated from the argparse "
             "parser (`boids_env.train.cli.build_parser`). `boids COMMAND --help` prints the "
             "same.\n"]
    for command, parser in parsers():
        depth = command.count(" ")
        heading = "#" * min(depth + 2, 4)
        parts.append(f"\n{heading} `{command}`\n\n")
        if parser.description:
            parts.append(cell(prose(parser.description)).replace("\\|", "|") + "\n\n")
        usage = parser.format_usage().removeprefix("usage: ").strip()
        parts.append(f"```text\n{usage}\n```\n\n")
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        for action in subs:
            helps = {c.dest: c.help for c in action._choices_actions}
            rows = [(f"[`{command} {name}`](#{_slug(f'{command} {name}')})",
                     cell(prose(helps.get(name) or ""))) for name in action.choices]
            parts.append(table(("subcommand", "what it does"), rows) + "\n\n")
        options = [a for a in parser._actions
                   if not isinstance(a, argparse._SubParsersAction | argparse._HelpAction)]
        if options:
            rows = [_option_row(parser, a) for a in options]
            parts.append(table(("option", "value", "default", "help"), rows) + "\n")
    return "".join(parts)


def _slug(command: str) -> str:
    """The anchor MkDocs' toc extension gives a heading of ``command`` in a code span."""
    return re.sub(r"[^\w]+", "-", command.lower()).strip("-")


# --------------------------------------------------------------------------- observations
OBSERVATION_CASES: tuple[tuple[str, dict[str, Any]], ...] = (
    ("The study's default", {}),
    ("A scene with obstacles (static slots)", {"scene": "pillars"}),
    ("A range sensor", {"lidar_rays": 8}),
    ("A crowd (pedestrian slots)", {"crowd": 5}),
    ("Robots with a heading (unicycle)", {"robot": "turtlebot3_burger"}),
    ("Route sensing", {"scene": "doorway", "route_sensing": True}),
)
"""The configs whose layouts the observation page shows: the default and one per opt-in."""


def _bounds(values: Any, width: int, unit: str = "slot") -> str:
    """A block's bounds: one slot's (ray's) when every slot has the same."""
    import numpy as np

    rows = np.asarray(values, dtype=float).reshape(-1, width)
    if not (rows == rows[0]).all():
        return "[" + ", ".join(f"{v:g}" for v in rows.ravel()) + "]"
    text = "[" + ", ".join(f"{v:g}" for v in rows[0]) + "]"
    return text + (f" per {unit}" if len(rows) > 1 else "")


def observation_layouts() -> list[tuple[str, dict[str, Any], Any, Any]]:
    """``(title, fields, layout, space)`` of every case the observation page shows."""
    from boids_env.config import EnvConfig
    from boids_env.observations import Observer

    out = []
    for title, kwargs in OBSERVATION_CASES:
        observer = Observer(EnvConfig.from_kwargs(**kwargs))
        out.append((title, kwargs, observer.layout, observer.make_space()))
    return out


@page("reference/observations.md")
def observations_page() -> str:
    from boids_env import observations

    specs = observations.specs()
    parts = [GENERATED, "# Observation layout\n\n",
             "Each follower observes one float32 vector made of named blocks, in this order "
             f"(empty blocks are left out): {', '.join(code(s.name) for s in specs)}. "
             "Policies read blocks by name (`ObservationLayout.block(name)`), never by index. "
             "The layouts and bounds below are generated from the env for the default config "
             "and for each opt-in sensor; the bounds are those of the env's observation "
             "`Box`, and follow the config: velocities ±`velocity_bound`, neighbours' relative "
             "positions ±`horizon`, the leader's relative position ± the scene's span "
             "(2·`arena_half_size` in the arena), static slots ±`static_range`, pedestrian "
             "slots ±`pedestrian_range`, rays up to `lidar_range` (see the "
             "[configuration reference](config.md#observationconfig)). A new block is one "
             "more `BlockSpec` at the end of the table in `boids_env/observations/blocks.py` "
             "(`docs/snippets/new_block.py` is a tested example).\n\n"]
    # the package docstring's paragraphs after its first (the summary)
    parts += [prose(p) + "\n\n" for p in observations.__doc__.split("\n\n")[1:]
              if not p.startswith("The modules:")]
    by_name = {s.name: s for s in specs}
    for title, kwargs, layout, space in observation_layouts():
        fields = ", ".join(code(f"{k}={v!r}") for k, v in kwargs.items()) or "no fields set"
        parts.append(f"\n## {title}\n\n{fields}: {layout.size} values per follower.\n\n")
        rows = []
        for name, size in layout.blocks:
            block, spec = layout.block(name), by_name[name]
            rows.append((code(name), f"{block.start}–{block.stop - 1}", str(size),
                         _bounds(space.low[block], spec.width, spec.unit),
                         _bounds(space.high[block], spec.width, spec.unit),
                         cell(spec.doc)))
        parts.append(table(("block", "indices", "size", "low", "high", "meaning"), rows) + "\n")
    return "".join(parts)


# --------------------------------------------------------------------------- model cards
@page("reference/models.md")
def models_page() -> str:
    from boids_env.policies.cards import leader_words
    from boids_env.policies.registry import MODELS, shipped_cards

    cards = shipped_cards()
    parts = [GENERATED, "# Model cards\n\n",
             "Every shipped model carries a card in its zip: what it was trained and validated "
             "on, its sensing and its validation figures (`boids card MODEL` prints one; "
             "[learned followers](../explanation/learned-followers.md#model-cards) says how "
             "cards are made and used). `boids run` and `boids eval` warn in one line when an "
             "env lies outside a model's card (robot, scene, crowd, leader, group size, "
             "leader speed, standstills) and name the shipped model made for it. This page is "
             "generated from the cards in the zips.\n\n"]
    rows = []
    for name, path in MODELS.items():
        if name not in cards:
            rows.append((code(name), code(path.name), "(no card)", *["—"] * 7))
            continue
        card = cards[name]
        rows.append((code(name), code(path.name), cell(card.summary),
                     cell(card.scene_words()), "{}–{}".format(*card.group_sizes),
                     "{:g}–{:g}".format(*card.leader_speeds),
                     cell(", ".join(leader_words(k) for k in card.leaders)
                          + ("; stands still" if card.standstills else "")),
                     str(max(card.crowds)), "on" if card.safety_filter else "off",
                     str(card.layout.size if card.layout else "—")))
    parts.append(table(("model", "file", "made for", "scenes", "robots", "leader m/s",
                        "leaders", "crowd", "safety filter", "obs. values"), rows) + "\n")
    for name, card in cards.items():
        parts.append(f"\n## {name}\n\n{cell(card.summary)}. Recipe: {cell(card.recipe)}. "
                     f"Robots: {', '.join(card.robots)} ({card.drive}). Sensing: "
                     f"{cell(card.sensing)}.\n\n")
        rows = [(cell(v.suite), cell(v.case),
                 cell(", ".join(f"{k} {x:g}" for k, x in v.figures))) for v in card.validation]
        if rows:
            parts.append(table(("suite", "case", "figures"), rows) + "\n\n")
        for source in dict.fromkeys(v.source for v in card.validation if v.source):
            parts.append(f"Figures from {cell(source)}.\n\n")
    return "".join(parts)


# --------------------------------------------------------------------------- metrics
def metric_sources() -> list[Callable[..., Any]]:
    """The functions whose results :func:`boids_env.metrics.episode_metrics` reports, the most
    specific first (a key takes the first docstring that defines it)."""
    from boids_env import metrics, proxemics

    return [metrics.safety_metrics, metrics.parked_metrics, proxemics.person_metrics,
            proxemics.crowd_metrics, metrics.episode_metrics]


def metric_keys() -> dict[str, tuple[str, str]]:
    """Every key ``episode_metrics`` returns -> (its value's type, when it is reported),
    found by calling it on a small episode in each reporting mode."""
    import numpy as np

    from boids_env.config import MetricsConfig
    from boids_env.metrics import episode_metrics

    steps, n, dt = 80, 4, 0.1
    pos = np.zeros((steps, n, 2))
    pos[:, :, 0] = np.arange(n) * 0.5
    vel = np.zeros((steps, n, 2))
    vel[:10, :, 1] = 0.3  # the leader moves, then stands still for 7 s (parked metrics)
    modes = (("always", {}),
             ("robots with a heading", {"headings": np.zeros((steps, n))}),
             ("a person leads", {"person_radius": 0.22}),
             ("with a crowd", {"pedestrians": np.full((steps, 2, 2), 3.0)}))
    found: dict[str, tuple[str, str]] = {}
    for when, extra in modes:
        out = episode_metrics(pos, vel, vel, MetricsConfig(), dt, 0.036, **extra)
        for key, value in out.items():
            kind = "list (per follower)" if isinstance(value, list) else "number"
            mode = "the leader stood still > 5 s" if key.startswith("parked_") else when
            found.setdefault(key, (kind, mode))
    return found


def _returns(fn: Callable[..., Any]) -> str:
    doc = inspect.getdoc(fn) or ""
    return " ".join(doc.split("Returns:", 1)[-1].split())


def metric_docs(keys: list[str]) -> dict[str, tuple[str, str]]:
    """key -> (the function whose docstring defines it, the definition), from the
    ``Returns:`` sections: clauses ``name [/ name ...]: meaning`` separated by semicolons,
    where ``a`` … ``b`` names the keys from a to b and ``x`` / ``_max`` names x_max."""
    out: dict[str, tuple[str, str]] = {}
    for fn in metric_sources():
        for clause in re.split(r";\s*|\.\s+(?=``)", _returns(fn)):
            head, colon, meaning = clause.partition(": ")
            names = re.findall(r"``([^`]+)``", head)
            if not colon or not names:
                continue
            named = [names[i - 1] + name if name.startswith("_") and i else name
                     for i, name in enumerate(names)]
            if "…" in head and len(named) == 2 and set(named) <= set(keys):
                named = keys[keys.index(named[0]):keys.index(named[1]) + 1]
            extra = re.sub(r"``[^`]+``|[/…]", "", head).strip()
            text = f"{meaning.strip().rstrip('.')}" + (f" ({extra.strip('() ')})"
                                                       if extra.startswith("(") else "")
            for key in named:
                out.setdefault(key, (fn.__name__, text))
    return out


@page("reference/metrics.md")
def metrics_page() -> str:
    from boids_env import metrics

    parts = [GENERATED, "# Metrics reference\n\n",
             "Every number `episode_metrics` reports for an episode (the rows of `boids eval`'s "
             "results, `boids run`'s summary), generated by calling it in each reporting mode; "
             "each key's description is the docstring that defines it.\n\n",
             prose(metrics.__doc__.split("\n\n", 1)[0]), "\n\n"]
    intro = metrics.__doc__.split("\n\n", 1)[1]
    parts.append(re.sub(r":\w+:`~?([^`]+)`", r"`\1`", intro).replace("``", "`") + "\n\n")
    rows = []
    keys = metric_keys()
    docs = metric_docs(list(keys))
    for key, (kind, when) in keys.items():
        source, text = docs.get(key, ("", ""))
        rows.append((code(key), kind, when, code(source) if source else "—", cell(prose(text))))
    parts.append("## Episode metrics\n\n")
    parts.append(table(("key", "value", "reported", "defined by", "description"), rows) + "\n")
    return "".join(parts)


# --------------------------------------------------------------------------- MkDocs hooks
API_SOURCE = Path("build", "api-src")
"""Where :func:`on_config` lays out the package as it installs (``mkdocstrings``' ``paths``)."""


def api_source(root: Path) -> Path:
    """The import tree of ``boids_env`` as it installs, copied (its ``.py`` files) under
    ``root/API_SOURCE``: the folders that pyproject's ``package-dir`` maps into it
    (``policies/`` as ``boids_env.policies``, ...) beside the core's own modules, so that
    mkdocstrings (griffe, which follows neither the mapping nor links) finds every
    sub-package by its import name."""
    import shutil
    import tomllib

    mapping = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-dir"]
    out = root / API_SOURCE
    shutil.rmtree(out, ignore_errors=True)

    def python_only(folder: str, names: list[str]) -> list[str]:
        return [n for n in names if n == "__pycache__"
                or (not n.endswith(".py") and not (Path(folder) / n).is_dir())]

    for name, folder in sorted(mapping.items()):  # the core first, then its sub-packages
        shutil.copytree(root / folder, out.joinpath(*name.split(".")), ignore=python_only,
                        dirs_exist_ok=True)
    return out


@event_priority(100)  # before mkdocstrings' own on_config, which looks for its ``paths``
def on_config(config: Any) -> Any:
    """Lays out the import tree for mkdocstrings before any page renders (and before
    mkdocstrings checks its ``paths``: on a fresh clone the folder does not exist yet)."""
    api_source(Path(config.config_file_path).parent)
    return config


def on_files(files: Any, config: Any) -> Any:
    """Adds every generated page to the site (MkDocs 1.6's generated files)."""
    from mkdocs.structure.files import File

    for path, generate in PAGES.items():
        existing = files.get_file_from_path(path)
        if existing is not None:
            files.remove(existing)
        files.append(File.generated(config, path, content=generate()))
    return files


_HTML_ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|obj|exc):<code>(~?)([^<]*)</code>")


def on_page_content(html: str, **kwargs: Any) -> str:
    """The docstrings' reST roles (``:func:`x` ``), which mkdocstrings' Markdown leaves as
    text, as plain code spans (``~a.b.c`` as ``c``)."""
    return _HTML_ROLE.sub(lambda m: "<code>" + (m[2].rsplit(".", 1)[-1] if m[1] else m[2])
                          + "</code>", html)
