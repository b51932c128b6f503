"""Experiment suites as data: cases (a factor at a level, as env fields and policy
parameters) × seeds. The ``paper`` suite is the study's Table III; ``robustness`` covers what
the study lists as future work. Users write their own in TOML (see :func:`load_suite`)."""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from boids_env.config import FIELD_OWNER, EnvConfig, ReynoldsParams, reynolds_params

POLICY_FIELDS = tuple(f.name for f in fields(ReynoldsParams))
"""Case fields that parameterise the Reynolds policy (others are env config fields)."""


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

    @property
    def groups(self) -> dict[str, list[Case]]:
        out: dict[str, list[Case]] = {}
        for case in self.cases:
            out.setdefault(case.group, []).append(case)
        return out

    def with_seeds(self, seeds: int | tuple[int, ...] | None) -> Suite:
        """The suite with ``seeds`` (an int n means seeds 0..n-1)."""
        if seeds is None:
            return self
        chosen = tuple(range(seeds)) if isinstance(seeds, int) else tuple(seeds)
        if not chosen or any(isinstance(s, bool) or not isinstance(s, int) or s < 0
                             for s in chosen):
            raise ValueError(f"seeds must be a positive count or non-negative integers, got "
                             f"{seeds!r}")
        return Suite(self.name, self.cases, chosen, self.per_follower, self.followers_analysed)


def _sweep(group: str, factor: str, levels: list[tuple[str, dict[str, Any]]],
           base: dict[str, Any] | None = None) -> list[Case]:
    cases = []
    for label, values in levels:
        merged = {**(base or {}), **values}
        env = {k: v for k, v in merged.items() if k not in POLICY_FIELDS}
        pol = {k: v for k, v in merged.items() if k in POLICY_FIELDS}
        cases.append(Case(f"{factor}={label}", group, factor, label, env, pol))
    return cases


CONTROLLED = {"robots": 13, "leader_speed": 0.55, "leader_weight": 1.0}
"""The study's controlled values (DESIGN section 5)."""

PAPER = Suite("paper", tuple(
    _sweep("rq1", "leader_speed", [(s, {"leader_speed": float(s)})
                                   for s in ("0.5", "0.55", "0.6")], CONTROLLED)
    + _sweep("rq2", "leader_weight", [(w, {"leader_weight": float(w)})
                                      for w in ("1.0", "1.1", "1.2")], CONTROLLED)
    + _sweep("rq3", "robots", [(n, {"robots": int(n)}) for n in ("7", "13", "19")],
             CONTROLLED)), per_follower=("rq3",))
"""Table III: three research questions × three levels, five seeds. Cases 2, 4 and 8 are the
same configuration and are run once."""

ROBUSTNESS = Suite("robustness", tuple(
    _sweep("path", "path", [(p, {"path": p}) for p in
                            ("square", "circle", "figure_eight", "random_waypoints")], CONTROLLED)
    + _sweep("placement", "init_jitter", [(j, {"init_jitter": float(j)})
                                          for j in ("0.05", "0.12", "0.2")], CONTROLLED)
    + _sweep("group_size", "robots", [(n, {"robots": int(n)}) for n in ("13", "31", "61")],
             CONTROLLED)
    + _sweep("noise", "obs_noise", [(s, {"obs_noise": float(s)})
                                    for s in ("0.0", "0.02", "0.05")], CONTROLLED)))
"""Future work of the study: other leader paths, initial placement spread, larger groups and
sensing noise (Gaussian, std in m and m/s), 13 robots at 0.55 m/s otherwise."""

SUITES = {"paper": PAPER, "robustness": ROBUSTNESS}


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
    if not path.is_file():
        raise FileNotFoundError(f"suite must be one of {sorted(SUITES)} or a TOML file; "
                                f"{spec} not found")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"cannot read suite file {path}: {exc}") from exc
    return suite_from_dict(data, default_name=path.stem)


def suite_from_dict(data: dict[str, Any], default_name: str = "custom") -> Suite:
    """Builds and validates a suite from the TOML structure of :func:`load_suite`."""
    known = {"name", "seeds", "defaults", "factor", "case", "per_follower"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown suite key(s) {unknown}; allowed: {sorted(known)}")
    defaults = dict(data.get("defaults", {}))
    _check_fields(defaults, "defaults")
    cases: list[Case] = []
    for i, factor in enumerate(data.get("factor", [])):
        name, levels = factor.get("name"), factor.get("levels")
        if not isinstance(name, str) or not isinstance(levels, list) or not levels:
            raise ValueError(f"factor {i} needs a name (a field) and a non-empty list levels")
        _check_fields({name: None}, f"factor {name!r}")
        cases += _sweep(factor.get("group", name), name,
                        [(str(v), {name: v}) for v in levels], defaults)
    for i, raw in enumerate(data.get("case", [])):
        raw = dict(raw)
        name = str(raw.pop("name", f"case{i + 1}"))
        group = str(raw.pop("group", "cases"))
        factor = str(raw.pop("factor", "case"))
        level = str(raw.pop("level", name))
        _check_fields(raw, f"case {name!r}")
        merged = {**defaults, **raw}
        cases.append(Case(name, group, factor, level,
                          {k: v for k, v in merged.items() if k not in POLICY_FIELDS},
                          {k: v for k, v in merged.items() if k in POLICY_FIELDS}))
    if not cases:
        raise ValueError("a suite needs at least one [[factor]] or [[case]]")
    for case in cases:
        try:
            EnvConfig().replace(**case.env)
            reynolds_params("paper", **case.policy)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"case {case.name!r}: {exc}") from exc
    names = [c.name for c in cases]
    if len(set(names)) != len(names):
        raise ValueError(f"case names must be unique, got {names}")
    seeds = data.get("seeds", 5)
    suite = Suite(str(data.get("name", default_name)), tuple(cases),
                  per_follower=tuple(data.get("per_follower", ())))
    return suite.with_seeds(tuple(seeds) if isinstance(seeds, list) else seeds)


def _check_fields(values: dict[str, Any], where: str) -> None:
    bad = sorted(k for k in values if k not in FIELD_OWNER and k not in POLICY_FIELDS)
    if bad:
        raise ValueError(f"{where}: unknown field(s) {bad}; use env config fields "
                         f"{sorted(FIELD_OWNER)} or Reynolds parameters {list(POLICY_FIELDS)}")
