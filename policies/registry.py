"""Turns a policy spec (``reynolds``, ``reynolds@boids_ros``, ``random``, ``learned``,
``learned-study``, ``learned-scenes``, ``model.zip``, ``module:object``) into a
:class:`~boids_env.policies.base.Policy`."""

from __future__ import annotations

import functools
import importlib
import inspect
from pathlib import Path
from typing import TYPE_CHECKING, Any

from boids_env.policies.base import Policy
from boids_env.policies.cards import ModelCard, read_card
from boids_env.policies.random_policy import RandomPolicy
from boids_env.policies.reynolds import ReynoldsPolicy
from boids_env.policies.reynolds_params import PRESETS
from boids_env.untrusted import open_zip

if TYPE_CHECKING:
    from boids_env.config import EnvConfig

BUILTIN = ("reynolds", "random", "learned", "learned-study", "learned-person",
           "learned-scenes", "learned-buildings", "learned-crowd")
LEARNED_MODEL = Path(__file__).parent / "models" / "ppo_safe.zip"
"""The shipped PPO follower policy (recipes ``ppo_safe`` then ``ppo_safe_stage2``: leader frame,
actions relative to the leader's velocity, safe reward with the cohesion gap, varied paths,
sizes and speeds); acts in numpy (its zip carries the actor), no extra needed."""
STUDY_MODEL = Path(__file__).parent / "models" / "ppo_study.zip"
"""PPO trained on the study's reward alone (recipe ``ppo_study``): it wins on the study's metrics
while its robots touch most of the time; kept to show what optimising those metrics does."""
PERSON_MODEL = Path(__file__).parent / "models" / "ppo_person.zip"
"""The shipped follower policy for a person leading (recipe ``ppo_person``: ``learned``
trained on for 3 M steps with a walking person and the intrusion reward); acts in numpy."""
SCENES_MODEL = Path(__file__).parent / "models" / "ppo_scenes.zip"
"""The shipped followers fine-tuned in scenes for a lab (recipe ``ppo_scenes``, its stages 2-4,
then stages 6 and 7, each with the checkpoint ``boids select`` picked): walls near the path,
doorways, corridors, pillars, up to 61 robots, leaders who stand still, with the safety filter
in the loop; its env fields switch the filter on."""
BUILDINGS_MODEL = Path(__file__).parent / "models" / "ppo_buildings.zip"
"""The shipped followers for buildings (recipes ``ppo_buildings`` and its stage 2:
``learned-scenes`` widened by route sensing and trained on generated floor plans, the open
arena, doorway, corridor and pillars): a follower that does not see the leader reads it
along its route (``route_leader``); its env fields switch route sensing and the safety
filter on."""
CROWD_MODEL = Path(__file__).parent / "models" / "ppo_crowd.zip"
"""The shipped followers of a person walking through buildings among pedestrians (recipe
``ppo_crowd``: the route model of ``learned-buildings`` widened by 4 pedestrian slots and
trained on with a person leading and crowds of 0-12); its env fields switch route sensing
and the safety filter on, the filter keeping people 0.45 m off (Hall's intimate zone)."""
MODELS = {"learned": LEARNED_MODEL, "learned-study": STUDY_MODEL,
          "learned-person": PERSON_MODEL, "learned-scenes": SCENES_MODEL,
          "learned-buildings": BUILDINGS_MODEL, "learned-crowd": CROWD_MODEL}
SIGHT_SWITCHED = {"learned-buildings": "learned-scenes"}
"""Shipped names that act as a :class:`~boids_env.policies.sight_switch.SightSwitch`: the
followers that see the leader act with the model named here, the others with the name's own
model (:data:`MODELS`). ``SEEN+HIDDEN`` (two model names or zips) builds any such pair."""
NOT_SUGGESTED = ("learned-study",)
"""Shipped models never named as the one that fits an env (not made for robots)."""


def shipped_cards() -> dict[str, ModelCard]:
    """The cards of the shipped models (:data:`MODELS`) that carry one, by name."""
    return {name: card for name, path in MODELS.items()
            if (card := _card(str(path))) is not None}


@functools.lru_cache(maxsize=16)
def _card(path: str) -> ModelCard | None:
    return model_card(path)


def model_card(path: str | Path) -> ModelCard | None:
    """The card of a model zip (:func:`~boids_env.policies.cards.read_card`): the one it
    carries, else the one its training config describes, else None."""
    from boids_env.policies.sb3_policy import read_meta

    return read_card(path, read_meta(path))


def fitting_model(config: EnvConfig, card: ModelCard | None = None) -> str | None:
    """The first shipped model (in :data:`MODELS` order, :data:`NOT_SUGGESTED` aside, and not
    the one ``card`` belongs to) whose card covers the env ``config``; None when none does."""
    for name, other in shipped_cards().items():
        if name not in NOT_SUGGESTED and other != card and not other.outside(config):
            return name
    return None


def switch_parts(spec: str) -> tuple[Path, Path] | None:
    """The (in-sight, out-of-sight) model files of a policy that switches by sight
    (:data:`SIGHT_SWITCHED` names, ``SEEN+HIDDEN``); None for any other spec."""
    if spec in SIGHT_SWITCHED:
        return MODELS[SIGHT_SWITCHED[spec]], MODELS[spec]
    seen, plus, hidden = spec.partition("+")
    if not plus or (spec.endswith(".zip") and Path(spec).is_file()):
        return None
    parts = (Path(MODELS.get(seen, seen)), Path(MODELS.get(hidden, hidden)))
    return parts if all(p.suffix == ".zip" for p in parts) else None


def model_path(spec: str) -> Path:
    """The model file whose metadata (env fields, card) stands for the policy ``spec``: a
    shipped name's, a zip's own, or a sight switch's out-of-sight model."""
    parts = switch_parts(spec)
    return parts[1] if parts else Path(MODELS.get(spec, spec))


def split_preset(spec: str, preset: str = "paper") -> tuple[str, str]:
    """``"reynolds@boids_ros"`` -> ``("reynolds", "boids_ros")``; any other spec keeps
    ``preset``. A preset on another policy, or an unknown preset, is a ``ValueError``."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"policy must be a non-empty string, got {spec!r}")
    name, at, chosen = spec.partition("@")
    if not at or name.endswith(".zip") or "/" in name:
        return spec, preset
    if name != "reynolds":
        raise ValueError(f"only reynolds takes a @preset (reynolds@{'|'.join(sorted(PRESETS))}),"
                         f" got {spec!r}")
    if chosen not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {chosen!r} in {spec!r}")
    return name, chosen


def load_policy(spec: str, *, preset: str = "paper", max_speed: float = 0.5,
                trust: bool = False, **reynolds_overrides: Any) -> Policy:
    """Builds the policy named by ``spec``.

    Args:
        spec: ``reynolds`` (the study's controller; ``reynolds@boids_ros`` picks a preset),
            ``random``, ``learned`` (the shipped PPO followers), ``learned-study`` (PPO on the
            study's reward alone), ``learned-scenes`` (the followers for a lab: scenes,
            standstills, the safety filter), ``learned-buildings`` (``learned-scenes`` for the
            followers that see the leader, a route-sensing model for the others), a path to a
            saved SB3 model (``.zip``), ``SEEN+HIDDEN`` (two of those models switched by sight,
            :class:`~boids_env.policies.sight_switch.SightSwitch`), or ``module:object``
            naming a Policy instance, a Policy class (built
            with no arguments) or a factory returning a Policy.
        preset: Reynolds parameter preset (``paper`` or ``boids_ros``) unless ``spec`` names
            one.
        max_speed: the random policy's speed range (m/s).
        trust: a model zip may be loaded through Stable-Baselines3's own load, which
            unpickles objects stored in the file and so runs any code they carry (only for
            files you trust). Without it a zip acts from its arrays alone (see
            :func:`~boids_env.policies.sb3_policy.load_model_policy`) or is refused with an
            error that names ``--trust-model``. A model's card (what it was made for,
            :mod:`~boids_env.policies.cards`) is its ``card`` attribute (None without one).
        reynolds_overrides: Reynolds parameters (e.g. ``leader_weight=1.1``); other policies
            ignore them. The physical and timing ones (``dt``, ``startup_time``,
            ``max_speed``, ``horizon``) belong to the env: bound, the policy takes them from
            it and refuses a given value that conflicts (suites send them to the env).
    """
    spec, preset = split_preset(spec, preset)
    if spec == "reynolds":
        return ReynoldsPolicy(preset, **reynolds_overrides)
    if spec == "random":
        return RandomPolicy(max_speed)
    parts = switch_parts(spec)
    if parts is not None:
        from boids_env.policies.sight_switch import SightSwitch

        seen, hidden = (load_policy(str(p), trust=trust) for p in parts)
        return SightSwitch(seen, hidden, name=spec)
    spec = str(MODELS.get(spec, spec))
    if spec.endswith(".zip"):
        if not Path(spec).is_file():
            raise FileNotFoundError(f"policy model file not found: {spec}")
        # numpy only: torch is imported (and its extra asked for) only for a model without
        # a numpy actor
        from boids_env.policies.sb3_policy import load_model_policy

        return load_model_policy(spec, trust=trust)
    if ":" in spec:
        obj = _import_object(spec)
        # A class passes isinstance(.., Policy) (its methods are attributes), so classes and
        # factories are told apart from instances explicitly.
        if inspect.isclass(obj) or (callable(obj) and not _is_policy(obj)):
            try:
                policy = obj()
            except TypeError as exc:
                raise TypeError(f"cannot build policy {spec!r} without arguments: {exc}"
                                ) from exc
        else:
            policy = obj
        if not _is_policy(policy):
            raise TypeError(f"{spec!r} is not a Policy (needs reset(seed) and act(obs))")
        return policy
    raise ValueError(f"policy must be one of {BUILTIN}, reynolds@PRESET, a .zip SB3 model or "
                     f"module:object, got {spec!r}")


def check_policy_spec(spec: str, preset: str = "paper", *, trust: bool = False) -> None:
    """Checks, without building the policy, that :func:`load_policy` can: a built-in name, a
    model zip that exists and whose metadata reads (and, without ``trust``, that it can act
    without its pickles), or a ``module:object`` that imports and is a Policy instance, class
    or factory. For callers that must refuse a bad spec before any side effect (creating an
    output folder, starting workers); raises what ``load_policy`` would (``ValueError``,
    ``TypeError``, ``FileNotFoundError``)."""
    spec, preset = split_preset(spec, preset)
    if spec in ("reynolds", "random"):
        return
    parts = switch_parts(spec)
    if parts is not None:
        for part in parts:
            check_policy_spec(str(part), trust=trust)
        return
    spec = str(MODELS.get(spec, spec))
    if spec.endswith(".zip"):
        if not Path(spec).is_file():
            raise FileNotFoundError(f"policy model file not found: {spec}")
        _check_model_zip(Path(spec), trust)
        return
    if ":" in spec:
        obj = _import_object(spec)
        if not (inspect.isclass(obj) or callable(obj) or _is_policy(obj)):
            raise TypeError(f"{spec!r} is not a Policy (needs reset(seed) and act(obs)), a "
                            f"Policy class or a factory, got {type(obj).__name__}")
        return
    raise ValueError(f"policy must be one of {BUILTIN}, reynolds@PRESET, a .zip SB3 model or "
                     f"module:object, got {spec!r}")


SB3_ENTRIES = ("data", "policy.pth")
"""Entries every zip that Stable-Baselines3's ``model.save`` writes holds."""


def _check_model_zip(path: Path, trust: bool = False) -> None:
    """Refuses a zip that cannot act as a policy: not a zip or unreadable metadata; a stored
    numpy actor is loaded whole (numpy only, milliseconds); a zip without one must at least
    hold SB3's model entries (loading it needs torch, which this check does not import) and,
    untrusted, a network its weights alone can run (nothing in it is unpickled)."""
    from boids_env.policies.mlp_actor import ACTOR_ENTRY
    from boids_env.policies.sb3_policy import check_untrusted_load, load_model_policy, read_meta

    read_meta(path)  # not a zip, or a bad boids.json: refused by name
    with open_zip(path) as archive:
        names = set(archive.namelist())
    if ACTOR_ENTRY in names:
        load_model_policy(path)
        return
    missing = [name for name in SB3_ENTRIES if name not in names]
    if missing:
        raise ValueError(f"policy model {path} is not a Stable-Baselines3 model: its zip holds "
                         f"neither {ACTOR_ENTRY} (saved by boids train) nor SB3's "
                         f"{' and '.join(SB3_ENTRIES)} (lacks {', '.join(missing)}); give a "
                         f"zip saved by boids train or by an SB3 model's save()")
    if not trust:
        check_untrusted_load(path)


def _import_object(spec: str) -> Any:
    """The object a ``module:object`` spec names; ``ValueError`` saying what is missing."""
    module_name, _, attr = spec.partition(":")
    if not module_name or not attr:
        raise ValueError(f"a policy given as module:object needs both parts, got {spec!r}")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # the module's own code may raise anything while importing
        hint = (" (is its folder on PYTHONPATH? e.g. PYTHONPATH=. boids ...)"
                if isinstance(exc, ModuleNotFoundError) else "")
        raise ValueError(f"cannot import policy {spec!r}: {type(exc).__name__}: {exc}{hint}"
                         ) from exc
    try:
        return getattr(module, attr)
    except AttributeError as exc:
        raise ValueError(f"cannot import policy {spec!r}: {exc}") from exc


def _is_policy(obj: Any) -> bool:
    """An instance (not a class) with callable ``reset`` and ``act``."""
    return (not inspect.isclass(obj) and callable(getattr(obj, "reset", None))
            and callable(getattr(obj, "act", None)))
