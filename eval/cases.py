"""The types of an experiment suite: a :class:`Case` (a factor at a level, as env fields and
policy parameters) and a :class:`Suite` (cases × seeds, checked), and :func:`sweep`, the cases
of one factor. The suites themselves, built in or read from a TOML file, are in
:mod:`boids_env.eval.suites`."""

from __future__ import annotations

import dataclasses
import json
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any

from boids_env.config import FIELD_OWNER, EnvConfig, check_integer
from boids_env.policies.reynolds_params import ReynoldsParams
from boids_env.untrusted import excerpt

POLICY_FIELDS = tuple(f.name for f in fields(ReynoldsParams) if f.name not in FIELD_OWNER)
"""Case fields that parameterise the Reynolds controller only (its weights, forces, ...).
Every other field is an env config field, the physical and timing quantities the controller
shares with the env included (``horizon``, ``max_speed``, and its timing ``dt``,
``startup_time``: each routed to the env, which owns it, so every policy's episodes see it
and a bound Reynolds policy takes it from there)."""


@dataclass(frozen=True)
class Case:
    """One experimental condition."""

    name: str
    group: str
    """The research question (or factor group) the case belongs to, e.g. ``rq1``."""
    factor: str
    level: str
    """The factor's level as a label (``"0.55"``, ``"13"``, ``"circle"``)."""
    env: dict[str, Any] = field(default_factory=dict)
    """Env config fields by flat name (``robots``, ``leader_speed``, ``path`` …)."""
    policy: dict[str, Any] = field(default_factory=dict)
    """Reynolds parameters (``leader_weight`` …); policies without them ignore these."""

    @property
    def config_key(self) -> str:
        """Identical for cases that are the same configuration (run once, reused)."""
        return json.dumps({"env": self.env, "policy": self.policy}, sort_keys=True)

    @classmethod
    def from_fields(cls, name: str, group: str, factor: str, level: str,
                    values: dict[str, Any]) -> Case:
        """A case whose ``values`` (env config fields and Reynolds parameters by flat name)
        are split into :attr:`env` and :attr:`policy` (:data:`POLICY_FIELDS`)."""
        return cls(name, group, factor, level,
                   {k: v for k, v in values.items() if k not in POLICY_FIELDS},
                   {k: v for k, v in values.items() if k in POLICY_FIELDS})


MAX_SEEDS = 10_000
"""Most seeds a suite may have (10,000 × the paper's 7 distinct cases is about 6 hours of
episodes on 2 cores); more is refused before anything is allocated."""
BLOCK_SIZE = 5
"""Seeds in one block of ``boids eval --blocks``: the study's runs per case."""
MAX_CASES = 1000
"""Most cases a suite may have (the largest built-in has 30); more is refused before any is
validated."""
MAX_SEED = 2**32 - 1
"""Largest seed value (numpy's legacy seeding range, which every consumer accepts)."""


def check_unique(names: list[str]) -> None:
    """``ValueError`` quoting a few of the repeated names (never the whole list)."""
    counts: dict[str, int] = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    twice = sorted(n for n, k in counts.items() if k > 1)
    if twice:
        raise ValueError(f"case names must be unique; {len(twice)} repeated: {excerpt(twice)}")


@dataclass(frozen=True)
class Suite:
    """Cases × seeds; ``groups`` are analysed separately (one ANOVA per group and metric)."""

    name: str
    cases: tuple[Case, ...]
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    per_follower: tuple[str, ...] = ()
    """Groups analysed on per-follower counts (followers ``1..followers_analysed``) instead of
    V_*, as the study did for group size."""
    followers_analysed: int = 6

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"suite name must be a non-empty string, got {self.name!r}")
        cases = _sequence("cases", self.cases)
        if not cases or not all(isinstance(c, Case) for c in cases):
            raise ValueError(f"cases must be a non-empty sequence of Case, got {self.cases!r}")
        check_unique([c.name for c in cases])
        object.__setattr__(self, "cases", cases)
        object.__setattr__(self, "seeds", check_seeds(self.seeds))
        groups = _sequence("per_follower", self.per_follower)
        unknown = [g for g in groups if g not in {c.group for c in cases}]
        if unknown:
            raise ValueError(f"per_follower names group(s) {unknown} that no case belongs to; "
                             f"groups: {sorted({c.group for c in cases})}")
        object.__setattr__(self, "per_follower", groups)
        object.__setattr__(self, "followers_analysed", check_integer(
            "followers_analysed", self.followers_analysed, 1, 10_000))

    @property
    def groups(self) -> dict[str, list[Case]]:
        out: dict[str, list[Case]] = {}
        for case in self.cases:
            out.setdefault(case.group, []).append(case)
        return out

    def with_env(self, **env: Any) -> Suite:
        """The suite with the env config fields ``env`` set in every case (over the case's
        own), e.g. ``with_env(realism="ros")``; ``ValueError`` naming a bad field or value."""
        if not env:
            return self
        EnvConfig().replace(**env)  # a bad name or value fails here, before any episode
        return dataclasses.replace(self, cases=tuple(
            dataclasses.replace(c, env={**c.env, **env}) for c in self.cases))

    def with_blocks(self, blocks: int | None) -> Suite:
        """The suite with ``blocks`` independent blocks of :data:`BLOCK_SIZE` seeds (seeds
        0..5·blocks−1), scored block by block in the report as separate reproductions."""
        if blocks is None:
            return self
        check_integer("blocks", blocks, 1, MAX_SEEDS // BLOCK_SIZE)
        return self.with_seeds(BLOCK_SIZE * int(blocks))

    def with_seeds(self, seeds: int | Sequence[int] | None) -> Suite:
        """The suite with ``seeds`` (an int n means seeds 0..n-1, 1 <= n <=
        :data:`MAX_SEEDS`)."""
        if seeds is None:
            return self
        return dataclasses.replace(self, seeds=check_seeds(seeds))


def check_seeds(seeds: Any) -> tuple[int, ...]:
    """Seeds as a tuple: a count n (seeds 0..n-1) or distinct integers in [0,
    :data:`MAX_SEED`], at most :data:`MAX_SEEDS` of them; ``ValueError`` otherwise (checked
    before anything is allocated)."""
    allowed = (f"a count in [1, {MAX_SEEDS}] or a list of up to {MAX_SEEDS} distinct "
               f"integers in [0, {MAX_SEED}]")
    if isinstance(seeds, numbers.Integral) and not isinstance(seeds, bool):
        if not 1 <= int(seeds) <= MAX_SEEDS:
            raise ValueError(f"seeds must be {allowed}, got {excerpt(seeds)}")
        return tuple(range(int(seeds)))
    if isinstance(seeds, str | bytes) or not isinstance(seeds, Sequence):
        raise ValueError(f"seeds must be {allowed}, got {excerpt(seeds)}")
    if not 1 <= len(seeds) <= MAX_SEEDS:
        raise ValueError(f"seeds must be {allowed}, got {len(seeds)} seeds")
    bad = [s for s in seeds if isinstance(s, bool) or not isinstance(s, numbers.Integral)
           or not 0 <= int(s) <= MAX_SEED]
    if bad:
        raise ValueError(f"seeds must be {allowed}, got {bad[:5]!r} in {list(seeds)[:10]!r}")
    chosen = tuple(int(s) for s in seeds)
    if len(set(chosen)) != len(chosen):
        repeated = sorted({s for s in chosen if chosen.count(s) > 1})
        raise ValueError(f"seeds must be distinct, got {repeated} more than once")
    return chosen


def _sequence(name: str, value: Any) -> tuple[Any, ...]:
    if isinstance(value, str | bytes) or not isinstance(value, Sequence):
        raise ValueError(f"{name} must be a sequence, got {value!r}")
    return tuple(value)


def sweep(group: str, factor: str, levels: list[tuple[str, dict[str, Any]]],
          base: dict[str, Any] | None = None) -> list[Case]:
    """One case ``factor=label`` of ``group`` per ``(label, values)`` level: ``base`` with
    the level's values over it."""
    return [Case.from_fields(f"{factor}={label}", group, factor, label,
                             {**(base or {}), **values}) for label, values in levels]
