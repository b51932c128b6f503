"""Model cards: what a learned model was made for, carried inside its zip.

A card is a plain JSON table under the ``card`` key of a model zip's ``boids.json``
(:mod:`boids_env.policies.sb3_policy`): the robots, scenes, crowds, leaders, group sizes and
leader speeds the model was trained (and validated) on, its observation layout and sensing, and
its validation figures with where they come from. ``boids train`` writes one derived from the
training config (:func:`card_from_training`) into every model it saves; the shipped models
carry curated ones (their figures from ``docs/explanation/learned-followers.md``); ``boids card
MODEL`` shows one and ``boids card MODEL --write`` gives an older zip the card its training
config describes.

The zip is untrusted input: the card is parsed as JSON, bounded (:data:`CARD_LIMIT` bytes,
:data:`MAX_ITEMS` entries per list, :data:`MAX_TEXT` characters per text) and validated field
by field; a malformed one is refused with a ``ValueError`` naming the file. A zip without a
card (saved elsewhere, or before cards) is read as the card its ``train_config`` describes
when it has one, else as having none (nothing is checked against it).

:meth:`ModelCard.outside` says what of an env lies outside a card (robot, scene kind, crowd,
leader kind, group size, leader speed, standstills): ``boids run`` and ``boids eval`` warn in
one line and name the shipped model made for it
(:func:`~boids_env.policies.registry.fitting_model`). :func:`explain_layout` turns an
observation-layout mismatch into its reasons (headings, pedestrian slots, route sensing, ...).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from boids_env.checks import from_fields
from boids_env.world.leader_kinds import LEADER_KINDS

if TYPE_CHECKING:
    from boids_env.config import EnvConfig
    from boids_env.observations import ObservationLayout

CARD_KEY = "card"
"""The key of the card in a model's ``boids.json``."""
CARD_VERSION = 1
CARD_LIMIT = 64 << 10
"""The most bytes a card's JSON may hold (the shipped cards: about 2 kB)."""
MAX_ITEMS = 64
"""The most entries of any list of a card."""
MAX_TEXT = 400
"""The most characters of any text of a card."""
MAX_WORLDS = 4096
"""The most worlds of a training config a card is derived from (a card lists at most
:data:`MAX_ITEMS` floor plans)."""
def leader_words(name: str) -> str:
    """How a warning names leader kind ``name`` (its kind's own words; an unknown name
    as it is)."""
    kind = LEADER_KINDS.get(name)
    return kind.words if kind is not None else name


SCENE_WORDS = {"arena": "the open arena", "map": "map_server maps", "shapes": "shapes files",
               "floorplan": "generated floor plans"}
"""How a warning names a scene kind (a built-in scene by its name)."""


class ModelCardWarning(UserWarning):
    """An env outside what a model's card says it was made for (one line: what is outside,
    and the shipped model made for it)."""


def scene_kind(spec: str) -> str:
    """The kind of scene ``spec`` names, as cards list them: ``arena``, a built-in scene's name
    (``small_room``, ``doorway``, ``corridor``, ``pillars``, ``lab``), ``floorplan`` (any
    generated floor plan), ``map`` (a map_server YAML) or ``shapes`` (a shapes file)."""
    from boids_env.world import floorplans
    from boids_env.world.scenes import BUILTIN

    if spec in BUILTIN:
        return spec
    if isinstance(spec, str) and spec.startswith(floorplans.PREFIX):
        return "floorplan"
    return "map" if Path(str(spec)).suffix.lower() in (".yaml", ".yml") else "shapes"


def _text(name: str, value: Any) -> str:
    if not isinstance(value, str) or len(value) > MAX_TEXT:
        raise ValueError(f"card field {name} must be a text of at most {MAX_TEXT} characters, "
                         f"got {_short(value)}")
    return value


def _items(name: str, value: Any, check: Any, lo: int = 0) -> tuple[Any, ...]:
    if not isinstance(value, list | tuple) or not lo <= len(value) <= MAX_ITEMS:
        raise ValueError(f"card field {name} must be a list of {lo} to {MAX_ITEMS} entries, "
                         f"got {_short(value)}")
    return tuple(check(name, v) for v in value)


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value):
        raise ValueError(f"card field {name} must hold finite numbers, got {_short(value)}")
    return float(value)


def _count(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 2**32:
        raise ValueError(f"card field {name} must hold counts in [0, 2**32], got "
                         f"{_short(value)}")
    return int(value)


def _range(name: str, value: Any, check: Any) -> tuple[Any, Any]:
    pair = _items(name, value, check, 2)
    if len(pair) != 2 or pair[0] > pair[1]:
        raise ValueError(f"card field {name} must be a range [low, high], got {_short(value)}")
    return pair[0], pair[1]


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


@dataclass(frozen=True)
class Validation:
    """One case a model was judged on, and its figures."""

    suite: str
    """The suite of ``boids eval`` the case is in (``generalisation``, ``scenes``, ...)."""
    case: str
    """The case's name (``default``, ``small_room``, ``unseen: 43 robots`` ...)."""
    figures: tuple[tuple[str, float], ...]
    """Metric name and value (``total``: V_sep + V_coh + V_align; fractions of the episode
    for ``touching`` and ``wall``), means over the seeds ``source`` names."""
    source: str = ""
    """Where the figures come from (a docs page and its table, the seeds)."""

    def __post_init__(self) -> None:
        _text("validation suite", self.suite)
        _text("validation case", self.case)
        _text("validation source", self.source)
        pairs = list(self.figures.items()) if isinstance(self.figures, dict) else self.figures
        if not isinstance(pairs, list | tuple) or len(pairs) > MAX_ITEMS:
            raise ValueError(f"card validation figures must be a table of at most {MAX_ITEMS} "
                             f"metric values, got {_short(self.figures)}")
        checked = []
        for pair in pairs:
            if not isinstance(pair, list | tuple) or len(pair) != 2:
                raise ValueError(f"card validation figures must be metric: value pairs, got "
                                 f"{_short(pair)}")
            checked.append((_text("validation metric", pair[0]),
                            _number("validation figures", pair[1])))
        object.__setattr__(self, "figures", tuple(checked))

    def to_dict(self) -> dict[str, Any]:
        return {"suite": self.suite, "case": self.case, "figures": dict(self.figures),
                "source": self.source}


@dataclass(frozen=True)
class ModelCard:
    """What a learned model was trained and validated on (the JSON under ``card`` in its
    ``boids.json``). Lists hold what training or validation covered: an env outside them is
    one the model was not made for."""

    summary: str = ""
    """What the model is for, in one line."""
    recipe: str = ""
    """The training recipe(s) it came from."""
    robots: tuple[str, ...] = ("sphero",)
    """Robot presets (``robot``)."""
    drive: str = "holonomic"
    """The robots' drive (``holonomic`` or ``unicycle``, which adds heading blocks)."""
    scenes: tuple[str, ...] = ("arena",)
    """Scene kinds it trained in (:func:`scene_kind`)."""
    validated_scenes: tuple[str, ...] = ()
    """Scene kinds it never trained in but was judged fit for on unseen cases."""
    floorplans: tuple[int, ...] = ()
    """Seeds of the generated floor plans it trained on (others are held out)."""
    group_sizes: tuple[int, int] = (7, 19)
    """Group sizes, the leader included (trained, or validated where wider)."""
    leader_speeds: tuple[float, float] = (0.5, 0.6)
    """Leader speeds (m/s, trained, or validated where wider)."""
    leaders: tuple[str, ...] = ("robot",)
    """Leader kinds (``robot``: a scripted path; ``person``; ``trajectory``: a recorded
    walk)."""
    paths: tuple[str, ...] = ("square",)
    """Leader paths in the open arena (a scene's leader drives the scene's own path)."""
    crowds: tuple[int, ...] = (0,)
    """Crowd sizes (pedestrians besides the leader)."""
    standstills: bool = False
    """Whether its leaders stood still in training (``leader_pauses``)."""
    obs_noise: float = 0.0
    """The largest sensing noise it trained with (std, m and m/s)."""
    safety_filter: bool = False
    """Whether the safety filter was between it and the robots."""
    observation: tuple[tuple[str, int], ...] = ()
    """Its observation layout: ``[name, size]`` blocks
    (:class:`~boids_env.observations.ObservationLayout`)."""
    sensing: str = ""
    """Its sensing and actions in words (frame, slots, route sensing, ...)."""
    validation: tuple[Validation, ...] = ()
    """Cases it was judged on, with figures."""
    version: int = CARD_VERSION

    def __post_init__(self) -> None:
        _set = object.__setattr__
        for name in ("summary", "recipe", "sensing", "drive"):
            _text(name, getattr(self, name))
        for name in ("robots", "scenes", "validated_scenes", "leaders", "paths"):
            _set(self, name, _items(name, getattr(self, name), _text))
        _set(self, "floorplans", _items("floorplans", self.floorplans, _count))
        _set(self, "crowds", _items("crowds", self.crowds, _count, 1))
        _set(self, "group_sizes", _range("group_sizes", self.group_sizes, _count))
        _set(self, "leader_speeds", _range("leader_speeds", self.leader_speeds, _number))
        _set(self, "obs_noise", _number("obs_noise", self.obs_noise))
        for name in ("standstills", "safety_filter"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"card field {name} must be true or false, got "
                                 f"{_short(getattr(self, name))}")
        if self.version != CARD_VERSION:
            raise ValueError(f"card version must be {CARD_VERSION} (this package's), got "
                             f"{_short(self.version)}")
        blocks = _items("observation", self.observation,
                        lambda n, b: (_text(n, b[0]), _count(n, b[1]))
                        if isinstance(b, list | tuple) and len(b) == 2 else _bad_block(b))
        _set(self, "observation", blocks)
        if blocks:
            self.layout  # noqa: B018 (refuses blocks that are not a layout)
        _set(self, "validation", _items("validation", self.validation,
                                        lambda n, v: v if isinstance(v, Validation)
                                        else Validation(**_table("validation", v))))

    @property
    def layout(self) -> ObservationLayout | None:
        """The observation layout (None when the card does not say)."""
        if not self.observation:
            return None
        from boids_env.observations import ObservationLayout

        try:
            return ObservationLayout.from_blocks([list(b) for b in self.observation])
        except ValueError as exc:
            raise ValueError(f"card field observation: {exc}") from None

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["validation"] = [v.to_dict() for v in self.validation]
        out["observation"] = [list(b) for b in self.observation]
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}

    def to_json(self) -> str:
        text = json.dumps(self.to_dict(), indent=1)
        if len(text.encode()) > CARD_LIMIT:
            raise ValueError(f"a model card must hold at most {CARD_LIMIT:,} bytes of JSON, "
                             f"this one {len(text.encode()):,}")
        return text

    @classmethod
    def from_dict(cls, data: Any) -> ModelCard:
        """The card of a JSON table; ``ValueError`` naming the field for anything else (an
        unknown key, a wrong type, too long a list or text, more than :data:`CARD_LIMIT`
        bytes)."""
        data = _table("card", data)
        try:
            size = len(json.dumps(data).encode())
        except (TypeError, ValueError, RecursionError):
            raise ValueError("a model card must be plain JSON") from None
        if size > CARD_LIMIT:
            raise ValueError(f"a model card must hold at most {CARD_LIMIT:,} bytes of JSON, "
                             f"this one {size:,}")
        return from_fields(cls, data, "model card", _short)

    # ------------------------------------------------------------------ coverage
    def outside(self, config: EnvConfig) -> list[str]:
        """What of the env ``config`` describes lies outside this card, one phrase each
        (empty: the model was made for it)."""
        out = []
        world, scenario = config.world, config.scenario
        if world.robot not in self.robots:
            out.append(f"robot {world.robot} (made for {', '.join(self.robots)})")
        kind = scene_kind(world.scene)
        if kind not in self.scenes + self.validated_scenes:
            shown = Path(world.scene).name if kind in ("map", "shapes") else world.scene
            out.append(f"scene {shown} ({self.scene_words()})")
        if scenario.crowd > max(self.crowds):
            most = max(self.crowds)
            out.append(f"a crowd of {scenario.crowd} (trained "
                       + (f"with at most {most})" if most else "without a crowd)"))
        if scenario.leader not in self.leaders:
            out.append(f"{leader_words(scenario.leader)} leading (made "
                       f"for {' or '.join(leader_words(k) for k in self.leaders)})")
        lo, hi = self.group_sizes
        if not lo <= scenario.robots <= hi:
            out.append(f"{scenario.robots} robots (made for {lo}-{hi})")
        lo_v, hi_v = self.leader_speeds
        if not lo_v - 1e-9 <= scenario.leader_speed <= hi_v + 1e-9:
            out.append(f"leader at {scenario.leader_speed:g} m/s (made for {lo_v:g}-{hi_v:g})")
        if scenario.leader_pauses and not self.standstills:
            out.append("a leader that stands still (trained without standstills)")
        return out

    def scene_words(self) -> str:
        """Where it trained (and was validated), in words."""
        trained = [SCENE_WORDS.get(k, k) for k in self.scenes]
        text = ("trained on " + ", ".join(trained)
                + (" only" if len(trained) == 1 and not self.validated_scenes else ""))
        if self.validated_scenes:
            text += "; validated on " + ", ".join(SCENE_WORDS.get(k, k)
                                                  for k in self.validated_scenes)
        return text

    def lines(self) -> list[str]:
        """The card as text (``boids card MODEL``)."""
        rows = [("what for", self.summary), ("recipe", self.recipe),
                ("robots", f"{', '.join(self.robots)} ({self.drive})"),
                ("scenes", self.scene_words()
                 + (f"; floor plans {_seeds(self.floorplans)}" if self.floorplans else "")),
                ("group sizes", "{}-{} robots, leader included".format(*self.group_sizes)),
                ("leader speeds", "{:g}-{:g} m/s".format(*self.leader_speeds)),
                ("leaders", ", ".join(leader_words(k) for k in self.leaders)
                 + (", standing still at times" if self.standstills else "")),
                ("paths", ", ".join(self.paths)),
                ("crowds", ", ".join(map(str, self.crowds))),
                ("noise", f"up to {self.obs_noise:g}"),
                ("safety filter", "on" if self.safety_filter else "off"),
                ("sensing", self.sensing),
                ("observation", ", ".join(f"{n} {s}" for n, s in self.observation)
                 + (f" ({sum(s for _, s in self.observation)} values)"
                    if self.observation else ""))]
        out = [f"{k:<14} {v}" for k, v in rows if v]
        for v in self.validation:
            figures = ", ".join(f"{k} {x:g}" for k, x in v.figures)
            out.append(f"{'validated':<14} {v.suite} / {v.case}: {figures}")
        for source in dict.fromkeys(v.source for v in self.validation if v.source):
            out.append(f"{'figures from':<14} {source}")
        return out


def _seeds(seeds: tuple[int, ...]) -> str:
    return ", ".join(map(str, seeds[:12])) + (f" (+{len(seeds) - 12})" if len(seeds) > 12
                                              else "")


def _bad_block(block: Any) -> Any:
    raise ValueError(f"card field observation must hold [name, size] pairs, got "
                     f"{_short(block)}")


def _table(name: str, data: Any) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise ValueError(f"a model {name} must be a JSON table, got {type(data).__name__}")
    return data


# ---------------------------------------------------------------------------- derived
def card_from_training(train_config: dict[str, Any], env_fields: dict[str, Any] | None = None,
                       *, summary: str = "", recipe: str = "") -> ModelCard:
    """The card a training config describes (``TrainConfig.to_dict()``, as ``boids.json``
    holds it): its worlds' scenes (``floorplan:SEED`` ones as ``floorplan``, their seeds
    kept), robots, crowds and leaders over ``env_fields``, its group sizes, leader speeds,
    paths, standstills and noise, and the observation layout of ``env_fields`` (route sensing
    included). No validation figures: add them once measured."""
    from boids_env.observations import layout_of
    from boids_env.world import floorplans

    base = dict(env_fields if env_fields is not None else train_config.get("env_fields") or {})
    worlds = train_config.get("worlds") or [{}]
    if not isinstance(worlds, list | tuple) or len(worlds) > MAX_WORLDS:
        raise ValueError(f"train_config worlds must be a list of at most {MAX_WORLDS:,} "
                         f"worlds to derive a card from, got {_short(worlds)[:40]}")
    scenes, plans = [], []
    for world in (w.get("scene", w.get("map", base.get("scene", base.get("map", "arena"))))
                  for w in worlds):
        scenes.append(scene_kind(world))
        seed = floorplans.parse(world) if scenes[-1] == "floorplan" else None
        if seed is not None:
            plans.append(seed)
    if len(set(plans)) > MAX_ITEMS:  # refused before any floor plan is generated
        raise ValueError(f"train_config worlds hold {len(set(plans)):,} floor plans, more than "
                         f"the {MAX_ITEMS} a card lists")
    configs = _world_configs(base, worlds, scenes)
    config = configs[0]
    sizes = [int(n) for n in train_config.get("group_sizes") or [config.scenario.robots]]
    speeds = [float(v) for v in train_config.get("leader_speeds")
              or [config.scenario.leader_speed]]
    pauses = train_config.get("leader_pauses") or [[]]
    layout = layout_of(config)
    return ModelCard(
        summary=summary, recipe=recipe,
        robots=tuple(dict.fromkeys(c.world.robot for c in configs)),
        drive=config.world.drive, scenes=tuple(dict.fromkeys(scenes)),
        floorplans=tuple(dict.fromkeys(plans)),
        group_sizes=(min(sizes), max(sizes)), leader_speeds=(min(speeds), max(speeds)),
        leaders=tuple(dict.fromkeys(c.scenario.leader for c in configs)),
        paths=tuple(train_config.get("paths") or [config.scenario.path]),
        crowds=tuple(sorted({c.scenario.crowd for c in configs})),
        standstills=any(bool(p) for p in pauses),
        obs_noise=max(float(v) for v in train_config.get("obs_noises") or [0.0]),
        safety_filter=any(c.safety.safety_filter for c in configs),
        observation=tuple((n, s) for n, s in layout.blocks), sensing=sensing_words(config))


def _world_configs(base: dict[str, Any], worlds: Any, kinds: list[str]) -> list[Any]:
    """The env config of each world, those that differ only in their floor plan's seed built
    once (a card reads nothing a floor plan's seed changes: the robot, leader, crowd, safety
    filter, drive; generating one costs half a second): the first world exactly, at most
    :data:`MAX_ITEMS` others (``ValueError`` beyond)."""
    from boids_env.config import EnvConfig

    built: dict[str, Any] = {}
    configs = []
    for k, (world, kind) in enumerate(zip(worlds, kinds, strict=True)):
        fields = {**base, **dict(world)}
        key = json.dumps({**fields, "scene": "floorplan"} if kind == "floorplan" and k else
                         fields, sort_keys=True, default=repr)
        if key not in built:
            if len(built) > MAX_ITEMS:
                raise ValueError(f"train_config worlds differ in more than {MAX_ITEMS} ways; "
                                 f"a card describes at most that many")
            built[key] = EnvConfig.from_kwargs(**fields)
        configs.append(built[key])
    return configs


def sensing_words(config: EnvConfig) -> str:
    """An env config's observation and action interface in words."""
    from boids_env.observations import layout_of

    obs, layout = config.observation, layout_of(config)
    parts = [f"{obs.frame} frame",
             "actions relative to the leader's velocity" if obs.relative_actions
             else "absolute velocity actions",
             f"{layout.neighbours} neighbour slots"]
    if layout.static:
        parts.append(f"{layout.static} static slot{'s' * (layout.static > 1)} (walls, "
                     f"obstacles)")
    if layout.lidar:
        parts.append(f"lidar {layout.lidar} rays")
    if layout.pedestrians:
        parts.append(f"{layout.pedestrians} pedestrian slots")
    if layout.headings:
        parts.append("headings")
    parts.append("route sensing" if layout.route else "no route sensing")
    if getattr(obs, "route_leader", False):
        parts.append("the leader sensed where its route leads (route_leader)")
    return "; ".join(parts)


def read_card(path: str | Path, meta: dict[str, Any]) -> ModelCard | None:
    """The card of the model zip ``path`` whose ``boids.json`` is ``meta``
    (:func:`~boids_env.policies.sb3_policy.read_meta`): the one it carries, else the one its
    ``train_config`` describes, else None. ``ValueError`` naming the file for a card that is
    not one."""
    if CARD_KEY in meta:
        try:
            return ModelCard.from_dict(meta[CARD_KEY])
        except (ValueError, TypeError) as exc:
            raise ValueError(f"SB3 model {path}: the card in its boids.json: {exc}") from None
    training = meta.get("train_config")
    if not isinstance(training, dict):
        return None
    try:
        return card_from_training(training, meta.get("env_fields")
                                  if isinstance(meta.get("env_fields"), dict) else None)
    except (ValueError, TypeError, KeyError, AttributeError):
        return None  # a training config of another version: no card rather than a wrong one


# ---------------------------------------------------------------------------- layouts
def explain_layout(trained: ObservationLayout, env: ObservationLayout, config: EnvConfig,
                   card: ModelCard | None = None) -> str:
    """Why observations laid out as ``env`` (of the env ``config``) do not fit a model that
    reads ``trained``: one phrase per block that differs (:func:`layout_reasons`), then both
    sizes."""
    why = layout_reasons(trained, env, config, card)
    return (f"{'; '.join(why) or 'its blocks differ'} (observations of {trained.size} values "
            f"for the model, {env.size} from this env)")


def layout_reasons(trained: ObservationLayout, env: ObservationLayout, config: EnvConfig,
                   card: ModelCard | None = None) -> list[str]:
    """One phrase per layout parameter of ``trained`` that ``env`` has otherwise (neighbour,
    static and pedestrian slots, lidar rays, headings and the robot, route sensing), in the
    block table's order (:func:`boids_env.observations.parameters`); ``card`` names the
    robots the model was trained for."""
    from boids_env.observations import parameters

    made = f"{', '.join(card.robots)} ({card.drive})" if card is not None else None
    return [p.differs(int(trained.value(p.name)), int(env.value(p.name)), config, made)
            for p in parameters() if trained.value(p.name) != env.value(p.name)]

