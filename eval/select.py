"""Choosing a checkpoint by bars (``boids select``): every candidate model and a reference
policy run the ``validation`` suite, each candidate is scored on issue 26's bars for lab
followers against the reference, and the candidates are ranked — most bars met first, then
(:data:`ORDERS`) the lower summed total (V_sep + V_coh + V_align over the cases) or the
larger headroom (how far the candidate's closest bar is below its limit). A recipe that keeps
its checkpoints names this rule before it trains; the rule is data (:data:`BARS`), so a
report can say exactly what was met."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from boids_env.files import write_text

TOTAL = ("V_sep", "V_coh", "V_align")


@dataclass(frozen=True)
class Bar:
    """One case's bar: the candidate's episode mean of ``metric`` must be at most
    ``factor`` × the reference's mean + ``offset`` (``strict``: below it), or at most
    ``absolute`` when that is set (no reference needed)."""

    case: str
    metric: str
    factor: float = 1.0
    offset: float = 0.0
    strict: bool = False
    absolute: float | None = None

    def limit(self, reference: float) -> float:
        return self.absolute if self.absolute is not None else \
            self.factor * reference + self.offset

    def met(self, value: float, reference: float) -> bool:
        limit = self.limit(reference)
        return value < limit if self.strict else value <= limit

    @property
    def text(self) -> str:
        rel = "<" if self.strict else "<="
        if self.absolute is not None:
            return f"{self.metric} {rel} {self.absolute:g}"
        scaled = "reference" if self.factor == 1.0 else f"{self.factor:g}x reference"
        return f"{self.metric} {rel} {scaled}" + (f" + {self.offset:g}" if self.offset else "")


BARS = (Bar("arena", "total", factor=0.5),
        *(Bar(scene, "total", strict=True)
          for scene in ("small_room", "doorway", "corridor", "pillars")),
        Bar("61 robots", "V_coh", offset=0.2),
        Bar("standing 40 s", "parked_speed", absolute=0.05))
"""Issue 26's bars on the ``validation`` suite's cases: the open arena at most half the
reference's total, each scene below it, 61 robots' V_coh within 0.2 of it, and followers
parked (mean speed ≤ 0.05 m/s after 5 s of standstill) around a standing leader."""

ORDERS = ("total", "headroom")
"""Tie-breaks among candidates meeting as many bars: ``total``, the lower summed total;
``headroom``, the larger smallest headroom over the bars — a bar's headroom is
``(limit - value) / limit``, so 0.05 means 5 % below the limit and a missed bar is negative —
then the lower summed total. ``headroom`` prefers the candidate whose thinnest margin is the
widest, the one likeliest to keep meeting every bar on other episodes."""

SAFETY = (("wall_fraction", 0.01), ("touching_fraction", 0.01))
"""Every case also needs these episode means at most so (1 % of the time)."""
FARTHEST = 3.0
"""… and no follower farther than this (m) from the leader at any episode's end."""


def bar_table(table: pd.DataFrame, reference: str, bars: Sequence[Bar] = BARS, *,
              candidates: Sequence[str] | None = None, episodes: int | None = None
              ) -> pd.DataFrame:
    """One row per (candidate, bar): its value, the limit, the safety figures and whether
    the bar (with the safety conditions) is met. Every candidate gets a row for every bar: a
    case whose episodes crashed (or never ran) is a missed bar, with no value or total, and so
    is a case with fewer episodes than expected (some crashed).

    Args:
        table: the runner's results (``policy``, ``case``, the metrics; one row per finished
            episode).
        reference: the ``policy`` label the relative bars compare against.
        candidates: the candidates' labels (default: every other policy of the table); one
            without any finished episode still gets its rows, every bar missed.
        episodes: the episodes each candidate must have of each case (default: as many as
            the reference has of the case).
    """
    frame = table.assign(total=table[list(TOTAL)].sum(axis=1))
    if reference not in set(frame["policy"]):
        raise ValueError(f"reference {reference!r} has no episodes; policies: "
                         f"{sorted(set(frame['policy']))}")
    missing = sorted({b.case for b in bars} - set(frame["case"]))
    if missing:
        raise ValueError(f"the results have no episodes of case(s) {missing}")
    if candidates is None:
        candidates = [p for p in dict.fromkeys(frame["policy"]) if p != reference]
    rows = []
    for bar in bars:
        of_case = frame[frame["case"] == bar.case]
        ref_runs = of_case[of_case["policy"] == reference]
        ref = float(ref_runs[bar.metric].mean()) if bar.metric in of_case else float("nan")
        expected = len(ref_runs) if episodes is None else episodes
        for policy in candidates:
            rows.append(_bar_row(bar, policy, of_case[of_case["policy"] == policy], ref,
                                 expected))
    return pd.DataFrame(rows)


def _bar_row(bar: Bar, policy: str, runs: pd.DataFrame, ref: float, expected: int
             ) -> dict[str, Any]:
    """One candidate's row for one bar from its finished episodes of the bar's case."""
    limit = bar.limit(ref)
    complete = len(runs) >= max(expected, 1)
    if not complete:  # crashed (or missing) episodes: the bar is missed, no value counts
        nan = float("nan")
        return {"policy": policy, "case": bar.case, "bar": bar.text, "value": nan,
                "limit": limit, "headroom": nan, **{key: nan for key, _ in SAFETY},
                "farthest": nan, "total": nan, "met": False, "episodes": len(runs),
                "crashed": expected - len(runs)}
    # a metric no episode has (no parked samples: the leader never stood 5 s) is NaN, and
    # NaN meets no bar
    value = float(runs[bar.metric].mean()) if bar.metric in runs else float("nan")
    safety = {key: float(runs[key].mean()) for key, _ in SAFETY}
    farthest = float(runs["final_leader_distance_max"].max())
    met = (bar.met(value, ref) and all(safety[k] <= lim for k, lim in SAFETY)
           and farthest <= FARTHEST)
    return {"policy": policy, "case": bar.case, "bar": bar.text, "value": value,
            "limit": limit, "headroom": (limit - value) / abs(limit) if limit else float("nan"),
            **safety, "farthest": farthest, "total": float(runs["total"].mean()),
            "met": met, "episodes": len(runs), "crashed": 0}


def ranking(bars: pd.DataFrame, order: str = "total") -> pd.DataFrame:
    """Candidates ranked: most bars met, then by ``order`` (:data:`ORDERS`; ties kept in
    order). ``headroom`` is each candidate's smallest headroom over the bars (NaN, a metric
    no episode has or a crashed case, counts as none: minus infinity); a candidate with a
    crashed case has no summed total (NaN), ranked after those with one."""
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    out = bars.groupby("policy", sort=False).agg(
        met=("met", "sum"), bars=("met", "size"),
        # a case that crashed has no total: the sum is NaN, and ranks after every number
        summed_total=("total", lambda t: t.sum(skipna=False)),
        headroom=("headroom", lambda h: h.fillna(float("-inf")).min()))
    missed = bars[~bars["met"]].groupby("policy", sort=False)["case"].agg(", ".join)
    out["missed"] = missed.reindex(out.index, fill_value="")
    keys = ["_neg", "summed_total"] if order == "total" else ["_neg", "_room", "summed_total"]
    return (out.assign(_neg=-out["met"], _room=-out["headroom"])
            .sort_values(keys, kind="stable").drop(columns=["_neg", "_room"])
            .reset_index())


def _steps(path: Path) -> tuple[int, str]:
    """``model_250000_steps.zip`` sorts by its step count, the name's last number (then by
    name)."""
    numbers = re.findall(r"\d+", path.stem)
    return (int(numbers[-1]) if numbers else -1, path.name)


def expand(candidates: Sequence[str]) -> list[str]:
    """Candidates with every folder replaced by the models of the training runs in it: a run
    folder (one holding ``model.zip`` or ``checkpoints/``) gives its checkpoints in step
    order, then its ``model.zip``; another folder (a ``boids train --seeds`` output) gives
    each run folder directly inside it so. Only plain files inside the folder count (no
    symbolic links); a folder without any model is a ``ValueError``."""
    out: list[str] = []
    for candidate in candidates:
        folder = Path(candidate)
        if not folder.is_dir():
            out.append(candidate)
            continue
        runs = [folder] if _is_run(folder) else sorted(
            p for p in folder.iterdir() if p.is_dir() and not p.is_symlink() and _is_run(p))
        found = []
        for run in runs:
            found += sorted((p for p in (run / "checkpoints").glob("*.zip")
                             if p.is_file() and not p.is_symlink()), key=_steps)
            final = run / "model.zip"
            if final.is_file() and not final.is_symlink():
                found.append(final)
        if not found:
            raise ValueError(f"candidate folder {candidate} holds no training run (model.zip "
                             f"or checkpoints/*.zip, in it or in a folder directly inside)")
        out += [str(p) for p in found]
    return out


def _is_run(folder: Path) -> bool:
    return (folder / "model.zip").is_file() or (folder / "checkpoints").is_dir()


def run_of(spec: str) -> str:
    """The training run a candidate comes from: the folder holding ``checkpoints/`` for a
    checkpoint, the zip's folder for another zip (``runs/x/seed_0/model.zip`` and
    ``runs/x/seed_0/checkpoints/model_N_steps.zip`` are both ``runs/x/seed_0``), the name
    itself for a named policy."""
    path = Path(spec)
    if path.suffix != ".zip":
        return spec
    return str(path.parent.parent if path.parent.name == "checkpoints" else path.parent)


def per_run(ranked: pd.DataFrame) -> dict[str, str]:
    """Each run's chosen candidate (its best-ranked ``spec``), runs in order of first rank."""
    return {run: str(group["spec"].iloc[0])
            for run, group in ranked.groupby("run", sort=False)}


def select(candidates: Sequence[str], out: str | Path, *, reference: str = "reynolds",
           workers: int | None = None, seeds: Sequence[int] | None = None,
           trust: bool = False, progress: bool = True, suite: Any = None,
           bars: Sequence[Bar] = BARS, order: str = "total") -> pd.DataFrame:
    """Runs ``suite`` (default: ``validation``) for ``reference`` and every candidate
    (resumable in ``out``), writes ``bars.csv``, ``ranking.csv`` and ``selection.json`` (the
    chosen candidate overall, and each run's: :func:`run_of`) there, and returns the ranking
    (with each candidate's ``run``) by ``order`` (:data:`ORDERS`)."""
    from boids_env.eval import folder
    from boids_env.eval.runner import PolicySpec, distinct_policies, run_suite
    from boids_env.eval.suites import VALIDATION

    if not candidates:
        raise ValueError("candidates must name at least one model")
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    candidates = expand(candidates)
    if reference in candidates:
        raise ValueError(f"reference {reference!r} is also a candidate")
    specs = [PolicySpec.parse(reference), *(PolicySpec.parse(c, trust=trust)
                                            for c in candidates)]
    suite = (VALIDATION if suite is None else suite).with_seeds(seeds)
    table = run_suite(specs, suite, out, workers=workers, progress=progress)
    labelled = distinct_policies(specs)  # the runner's labels (a path where stems repeat)
    labels = {s.label: s.spec for s in labelled}
    # every candidate is scored on every bar: a case whose episodes crashed is a missed bar
    scored = bar_table(table, labelled[0].label, bars,
                       candidates=[s.label for s in labelled[1:]], episodes=len(suite.seeds))
    ranked = ranking(scored, order)
    ranked.insert(1, "spec", [labels.get(p, p) for p in ranked["policy"]])
    ranked.insert(2, "run", [run_of(spec) for spec in ranked["spec"]])
    out = Path(out)
    write_text(out / "bars.csv", scored.to_csv(index=False))
    write_text(out / "ranking.csv", ranked.to_csv(index=False))
    choice: dict[str, Any] = {"chosen": ranked["spec"].iloc[0],
                              "chosen_per_run": per_run(ranked), "reference": reference,
                              "order": order, "seeds": list(suite.seeds),
                              "bars": [b.__dict__ | {"text": b.text} for b in bars],
                              "ranking": ranked.to_dict(orient="records")}
    write_text(out / "selection.json", json.dumps(choice, indent=1, default=float))
    folder.record_files(out, ("bars.csv", "ranking.csv", "selection.json"))
    return ranked

