"""One episode of a policy in the env, with optional recording and video frames."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.config import FIELD_OWNER, EnvConfig, ObservationConfig
from boids_env.environment import BoidsEnv
from boids_env.observations import ObservationLayout, interface_fields
from boids_env.policies.base import Policy
from boids_env.policies.cards import ModelCardWarning, explain_layout, layout_reasons
from boids_env.recording import Recorder, Recording


@dataclass
class EpisodeResult:
    """What one episode produced."""

    metrics: dict[str, Any]
    """V_*, per-follower counts and the extra flock metrics (see boids_env.metrics)."""
    recording: Recording | None
    frames: list[npt.NDArray[np.uint8]] = field(default_factory=list)
    wall_time: float = 0.0
    """Seconds the episode took (stepping, policy and recording; not the video encoding)."""
    reward_total: float = 0.0
    """The env's rewards summed over followers and steps (its configured reward)."""


def env_fields_for(policy: Policy, fields: dict[str, Any] | None = None) -> dict[str, Any]:
    """Env config fields for running ``policy``: those its observations need (a trained model's
    ``env_fields``, e.g. its number of neighbour slots), then ``fields``; for a policy with
    Reynolds parameters the sensing horizon covers its neighbour radius unless given."""
    out = {**getattr(policy, "env_fields", {}), **(fields or {})}
    params = getattr(policy, "params", None)
    if params is not None and "horizon" not in out:
        out["horizon"] = max(params.horizon, ObservationConfig().horizon)
    return out


TRAINED_INTERFACE = ("dt", "frame", "relative_actions", "action", *interface_fields())
"""Env fields that fix what a learned policy's observations and actions mean (their frame,
the control period its actions were learned at, then each observation block's scale, slots
and ranges: its spec's ``fields``, :mod:`boids_env.observations.blocks`). A model acts
only in an env that has its training's values of these: its ``env_fields``, the defaults
for the rest. The other fields are the world's conditions (speeds, scenes, noise, the safety
filter): a case may change them (:func:`world_changes` records it)."""
WORLD_SECTIONS = ("world", "scenario", "observation", "realism", "safety")
"""Config sections whose fields change what happens in an episode (the metrics section
changes only the rewards)."""


def _value(config: EnvConfig, name: str) -> Any:
    return getattr(getattr(config, FIELD_OWNER[name]), name)


def check_training(policy: Policy, config: EnvConfig) -> None:
    """``ValueError`` when ``config`` contradicts the training of ``policy`` (a learned model,
    one with ``env_fields``) in a field of :data:`TRAINED_INTERFACE`, naming each field, the
    trained value and the env's."""
    fields = getattr(policy, "env_fields", None)
    if not isinstance(fields, dict) or not getattr(policy, "training_known", True):
        return  # not a learned model (Reynolds, random adapt to any env), or one wrapped bare
    trained = EnvConfig.from_kwargs(**fields)
    bad = [(n, _value(trained, n), _value(config, n)) for n in TRAINED_INTERFACE
           if _value(trained, n) != _value(config, n)]
    if bad:
        said = ", ".join(f"{n}={t!r}" for n, t, _ in bad)
        got = ", ".join(f"{n}={g!r}" for n, _, g in bad)
        raise ValueError(f"the policy was trained with {said}; this env has {got}, which it "
                         f"was not trained for: leave these fields to the model (its "
                         f"env_fields {fields})")


def world_changes(policy: Any, fields: dict[str, Any] | None = None, *,
                  configs: tuple[EnvConfig, EnvConfig] | None = None
                  ) -> dict[str, dict[str, list[Any]]]:
    """What running ``policy`` changes in the world of the episodes ``fields`` ask for:
    ``changed``, the fields its env fields (a model's, or a Reynolds policy's sensing
    horizon) set otherwise, as ``[asked, ran]`` (its control period ``dt`` included, not its
    own observation and action interface, which changes no one else's world);
    ``untrained``, the fields of a model's training that ``fields`` override, as
    ``[trained, ran]`` (the reward fields aside: they change no episode). Empty tables when
    nothing changes. ``configs``: the (asked, ran) configs when the caller has built them
    already (from ``fields`` and :func:`env_fields_for`), so that none is built twice."""
    fields = dict(fields or {})
    if configs is None:
        configs = (EnvConfig.from_kwargs(**fields),
                   EnvConfig.from_kwargs(**env_fields_for(policy, fields)))
    asked, ran = configs
    changed = {}
    for name, section in FIELD_OWNER.items():
        if section not in WORLD_SECTIONS or (section == "observation"
                                             and name in TRAINED_INTERFACE):
            continue  # rewards; the model's own sensors and actions (checked at binding)
        if _value(asked, name) != _value(ran, name):
            changed[name] = [_plain(_value(asked, name)), _plain(_value(ran, name))]
    model = getattr(policy, "env_fields", None)
    untrained = {}
    if isinstance(model, dict):
        trained = EnvConfig.from_kwargs(**model)
        for name in model:
            if FIELD_OWNER.get(name) in WORLD_SECTIONS and (
                    _value(trained, name) != _value(ran, name)):
                untrained[name] = [_plain(_value(trained, name)), _plain(_value(ran, name))]
    return {"changed": changed, "untrained": untrained}


def _plain(value: Any) -> Any:
    """A config value as JSON has it (tuples as lists)."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def bind_policy(policy: Policy, env: BoidsEnv) -> None:
    """Tells a policy that reads the env's layout (``bind``, e.g. the Reynolds policy: static
    slots, range sensing, obstacle avoidance in scenes, the env's timing) which env it acts
    in, after checking that the env is one it can act in: a learned model's saved layout
    and its training (:func:`check_training`). Run, eval, the live window and the ROS
    controller all bind through here."""
    config = getattr(env, "episode_config", None) or env.config
    check_layout(policy, env.layout, config)
    check_training(policy, config)
    bind = getattr(policy, "bind", None)
    if callable(bind):
        bind(env)


def check_layout(policy: Policy, layout: ObservationLayout, config: EnvConfig,
                 fields: dict[str, Any] | None = None) -> None:
    """``ValueError`` saying why, when observations laid out as ``layout`` (by the env
    ``config``) do not fit ``policy``: a learned model's saved layout (from its metadata or
    card) that differs, or a network that takes another size. The reasons name the blocks
    (headings, pedestrian slots, route sensing, ...; :func:`~boids_env.policies.cards.
    explain_layout`)."""
    saved = getattr(policy, "observation_layout", None)
    size = getattr(policy, "obs_size", None)
    card = getattr(policy, "card", None)
    where = f" (env fields {fields})" if fields else ""
    if saved is not None and saved != layout:
        raise ValueError(f"the policy cannot act in this env{where}: "
                         f"{explain_layout(saved, layout, config, card)}; the policy reads "
                         f"observations laid out as {list(saved.blocks)}, the env gives "
                         f"{list(layout.blocks)}")
    if isinstance(size, int | np.integer) and size and int(size) != layout.size:
        try:
            reasons = layout_reasons(ObservationLayout.for_size(int(size)), layout, config,
                                     card)
        except ValueError:  # not a study-era size: no guess at its blocks
            reasons = []
        why = f"; {'; '.join(reasons)} (its layout guessed from its size)" if reasons else ""
        raise ValueError(f"the policy's network takes observations of size {size}, the env "
                         f"gives {layout.size}{where}: the model was trained with other "
                         f"observation settings{why}")


def card_note(policy: Policy, config: EnvConfig, name: str | None = None) -> str | None:
    """One line saying what of the env ``config`` lies outside the card of ``policy`` (a
    learned model's, :mod:`~boids_env.policies.cards`) and which shipped model was made for
    it; None when the policy has no card or the card covers the env."""
    card = getattr(policy, "card", None)
    outside = card.outside(config) if card is not None else []
    if not outside:
        return None
    label = name or getattr(policy, "name", "the model")
    return f"{label} was not made for this env: {'; '.join(outside)}; {_fit(config, card)}"


def _fit(config: EnvConfig, card: Any) -> str:
    from boids_env.policies.registry import fitting_model

    fit = fitting_model(config, card)
    return (f"use --policy {fit}, the shipped model made for it" if fit
            else "none of the shipped models was made for it")


def warn_outside_card(policy: Policy, configs: dict[str, EnvConfig],
                      name: str | None = None) -> str | None:
    """Warns (:class:`~boids_env.policies.cards.ModelCardWarning`, one line) when any env of
    ``configs`` (by case name; one env: its name is not shown) lies outside the card of
    ``policy``; returns the line (None: no warning)."""
    if len(configs) == 1:
        note = card_note(policy, next(iter(configs.values())), name)
    else:
        card = getattr(policy, "card", None)
        outside = {case: card.outside(c) for case, c in configs.items()} if card else {}
        outside = {case: why for case, why in outside.items() if why}
        if not outside:
            return None
        shown = [f"[{case}] {'; '.join(why)}" for case, why in list(outside.items())[:3]]
        more = f" and {len(outside) - 3} more" if len(outside) > 3 else ""
        label = name or getattr(policy, "name", "the model")
        fits = {_fit(configs[case], card) for case in outside}
        note = (f"{label} was not made for {len(outside)} of the {len(configs)} cases: "
                f"{' '.join(shown)}{more}; "
                + (fits.pop() if len(fits) == 1 else "see boids card for what each model "
                   "was made for"))
    if note:
        warnings.warn(note, ModelCardWarning, stacklevel=2)
    return note


def check_fits(policy: Policy, envs: list[dict[str, Any]]) -> None:
    """Raises, before any episode runs, the ``ValueError`` acting in each env of ``envs``
    (env config fields, e.g. a suite's cases) would raise: observations laid out other than
    the policy reads them, or of a size its network does not take. Each distinct env is built
    once (not reset)."""
    seen: set[str] = set()
    for fields in envs:
        merged = env_fields_for(policy, fields)
        key = repr(sorted(merged.items()))
        if key in seen:
            continue
        seen.add(key)
        env = BoidsEnv(**merged)
        try:
            check_layout(policy, env.layout, env.config, fields)
        finally:
            env.close()


def run_episode(env: BoidsEnv, policy: Policy, seed: int | None = None, *,
                options: dict[str, Any] | None = None, record: bool = True,
                frame_every: int = 0,
                on_step: Callable[[BoidsEnv, int], None] | None = None) -> EpisodeResult:
    """Runs ``policy`` for one whole episode of ``env``.

    Args:
        env: the environment (``render_mode="rgb_array"`` if frames are wanted).
        policy: any Policy; if it exposes ``forces`` (the Reynolds policy does), they are drawn.
        seed: episode seed, passed to both ``env.reset`` and ``policy.reset``.
        options: reset options (scenario fields for this episode).
        record: keep the trajectory (needed for the extra flock metrics).
        frame_every: keep a rendered frame every this many steps (0: none).
        on_step: called with the env and the step count after the reset (0) and after every
            step (a live view); it must not change the env.
    """
    start = time.perf_counter()
    obs, _ = env.reset(seed=seed, options=options)
    bind_policy(policy, env)
    policy.reset(seed)
    recorder = Recorder() if record else None
    frames: list[npt.NDArray[np.uint8]] = []
    if recorder:
        recorder.capture(env)
    if on_step is not None:
        on_step(env, 0)
    step = 0
    reward_total = 0.0
    while env.agents:
        actions = policy.act(obs)
        forces = getattr(policy, "forces", None)
        if forces:
            env.overlays = forces
        if frame_every and step % frame_every == 0:
            frames.append(env.render())
        obs, rewards, *_ = env.step(actions)
        reward_total += sum(rewards.values())
        step += 1
        if recorder:
            recorder.capture(env)
        if on_step is not None:
            on_step(env, step)
    if frame_every:
        frames.append(env.render())
    recording = recorder.recording(env, seed=seed) if recorder else None
    metrics = recording.metrics() if recording else env.episode_metrics()
    return EpisodeResult(metrics, recording, frames, time.perf_counter() - start, reward_total)
