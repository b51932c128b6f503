"""The report's figures (matplotlib, headless), each saved as PNG (160 dpi) and SVG.

- :func:`level_bars`: one panel per metric, one bar per level, the study's bars hatched
  beside ours;
- :func:`follower_bars`: the study's group-size figure, per-follower bars (followers 1–6) per
  group size, the study's beside ours;
- :func:`trajectories`: one episode's paths in the arena, the leader's scripted path dashed;
- :func:`policy_bars` and :func:`safety_bars`: policies side by side per case;
- :func:`learning_curves`: training runs' periodic evaluations against timesteps.

Every bar is a mean with its 95 % percentile-bootstrap confidence interval
(:func:`~boids_env.eval.stats.bootstrap_ci`), which never goes below zero for the
non-negative metrics; axes start at zero and carry units; a panel whose values are all zero
says so instead of drawing an empty axis.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt
import pandas as pd

from boids_env import style
from boids_env.eval.compare import with_contacts
from boids_env.eval.stats import bootstrap_ci, group_values
from boids_env.recording import Recording

COLORS = plt.get_cmap("tab10").colors
DPI = 160
CI_NOTE = "bars: mean · whiskers: 95 % bootstrap CI of the mean"
V_UNIT = "followers in violation (time average)"
UNITS = {
    "V_sep": V_UNIT, "V_coh": V_UNIT, "V_align": V_UNIT, "V_align_unwrapped": V_UNIT,
    "total": V_UNIT,
    "count_sep": "violating samples (0.1 s each)", "count_coh": "violating samples (0.1 s each)",
    "count_align": "violating samples (0.1 s each)",
    "count_align_unwrapped": "violating samples (0.1 s each)",
    "touching_fraction": "fraction of time", "wall_fraction": "fraction of time",
    "mean_contact_pairs": "pairs in contact (mean)",
    "contacts": "contact onsets per episode", "contacts_follower": "contact onsets per episode",
    "contacts_leader": "contact onsets per episode", "collisions": "contact onsets per episode",
    "mean_nn_distance": "distance (m)", "min_distance": "distance (m)",
    "min_clearance": "distance (m)", "no_sight_fraction": "fraction of time",
    "leader_path_deviation": "distance (m)", "mean_leader_distance": "distance (m)",
}
"""The y-axis label (with its unit) of each metric."""
NAMES = {"V_align": "V_align (wrapped)", "V_align_unwrapped": "V_align (study's unwrapped rule)",
         "count_align": "count_align (wrapped)",
         "count_align_unwrapped": "count_align (study's unwrapped rule)",
         "touching_fraction": "time some robots touch", "wall_fraction": "time at a wall",
         "contacts": "contact onsets (all pairs)", "mean_nn_distance": "nearest-neighbour gap",
         "total": "V_sep + V_coh + V_align"}
"""Panel titles that say which alignment rule a metric uses."""
plt.rcParams.update({"font.size": 9, "axes.titlesize": 10, "axes.spines.top": False,
                     "axes.spines.right": False, "svg.fonttype": "none",
                     "svg.hashsalt": "boids-env"})


def metric_name(metric: str) -> str:
    return NAMES.get(metric, metric)


def save(fig: plt.Figure, path: Path) -> Path:
    """Saves ``path`` (PNG, :data:`DPI`) and the same figure as SVG beside it; returns the
    PNG's path."""
    path = Path(path)
    if path.suffix != ".png":  # a stem: "traj_x_leader_speed_0.5" keeps its ".5"
        path = path.with_name(path.name + ".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    fig.savefig(path.with_suffix(".svg"), bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)
    return path


def mean_ci(values: npt.ArrayLike) -> tuple[float, float, float]:
    """(mean, CI low, CI high) of the finite values; NaNs when there are none."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), float("nan")
    low, high = bootstrap_ci(v)
    return float(v.mean()), low, high


def _bar(ax: plt.Axes, x: float, values: npt.ArrayLike, width: float, colour: tuple,
         label: str | None, study: bool = False) -> float:
    """One mean bar with its CI whisker (the study's: white with a coloured hatch); returns
    the whisker's top."""
    mean, low, high = mean_ci(values)
    if not np.isfinite(mean):
        return 0.0
    ax.bar(x, mean, width, color="white" if study else colour, edgecolor=colour,
           hatch="////" if study else None, linewidth=0.8, label=label)
    # a percentile interval need not hold the mean exactly (skewed data, rounding)
    ax.errorbar(x, mean, yerr=[[max(mean - low, 0.0)], [max(high - mean, 0.0)]], fmt="none",
                ecolor="0.15",
                elinewidth=0.9, capsize=2)
    return high


def _finish(ax: plt.Axes, top: float, metric: str) -> None:
    """Axis from zero; an all-zero panel says so (no empty axis on a ±0.04 scale)."""
    if top <= 0:
        ax.set_ylim(0, 1)
        ax.text(0.5, 0.5, "all zero", transform=ax.transAxes, ha="center", va="center",
                color="0.4")
    else:
        ax.set_ylim(0, top * 1.12)
    ax.set_ylabel(UNITS.get(metric, metric))
    ax.set_title(metric_name(metric))
    ax.grid(axis="y", color="0.92")
    ax.set_axisbelow(True)


def level_bars(rows: pd.DataFrame, metrics: Sequence[str], title: str, path: Path,
               study: Mapping[str, Mapping[str, np.ndarray]] | None = None,
               followers: int = 6) -> Path:
    """One panel per metric, one bar per level (mean, 95 % CI); with ``study``
    ({metric: {level: values}}) the study's bars, hatched, beside ours."""
    levels = [str(v) for v in dict.fromkeys(rows["level"])]
    factor = str(rows["factor"].iloc[0])
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.4 * len(metrics), 3.3), squeeze=False)
    width = 0.38 if study else 0.6
    for ax, metric in zip(axes[0], metrics, strict=True):
        ours = group_values(rows, metric, followers)
        top = 0.0
        for li, level in enumerate(levels):
            offset = -width / 2 if study else 0.0
            top = max(top, _bar(ax, li + offset, ours.get(level, []), width, COLORS[0],
                                "ours" if li == 0 else None))
            theirs = (study or {}).get(metric, {}).get(level)
            if theirs is not None:
                top = max(top, _bar(ax, li + width / 2, theirs, width, COLORS[1],
                                    "study" if li == 0 else None, study=True))
        ax.set_xticks(range(len(levels)), levels)
        ax.set_xlabel(_factor_label(factor))
        _finish(ax, top, metric)
    axes[0][0].legend(fontsize=8, frameon=False)
    fig.suptitle(f"{title}\n{CI_NOTE}", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def follower_bars(rows: pd.DataFrame, metrics: Sequence[str], title: str, path: Path,
                  followers: int = 6,
                  study: Mapping[str, Mapping[str, np.ndarray]] | None = None) -> Path:
    """The group-size figure: per-follower bars (followers 1..``followers``), one panel per
    count metric, one colour per level (mean over runs, 95 % CI); with ``study``
    ({metric: {level: (runs, followers) counts}}) the study's bars, hatched, beside ours."""
    levels = [str(v) for v in dict.fromkeys(rows["level"])]
    factor = str(rows["factor"].iloc[0])
    fig, axes = plt.subplots(len(metrics), 1, figsize=(9.5, 2.9 * len(metrics)),
                             squeeze=False)
    per_level = 2 if study else 1
    width = 0.84 / (len(levels) * per_level)
    x = np.arange(1, followers + 1)
    for ax, metric in zip(axes[:, 0], metrics, strict=True):
        top = 0.0
        for li, level in enumerate(levels):
            counts = np.array([list(c)[:followers] for c in
                               rows.loc[rows["level"].astype(str) == level, metric]], dtype=float)
            theirs = (study or {}).get(metric, {}).get(level)
            for f in range(followers):
                base = x[f] + (li * per_level - (len(levels) * per_level - 1) / 2) * width
                top = max(top, _bar(ax, base, counts[:, f], width, COLORS[li % 10],
                                    f"ours, {_level_label(factor, level)}" if f == 0 else None))
                if theirs is not None:
                    top = max(top, _bar(ax, base + width, theirs[:, f], width, COLORS[li % 10],
                                        f"study, {_level_label(factor, level)}" if f == 0
                                        else None, study=True))
        ax.set_xticks(x)
        ax.set_xlabel("follower")
        _finish(ax, top, metric)
    axes[0, 0].legend(fontsize=7, ncols=len(levels), frameon=False, loc="upper left",
                      bbox_to_anchor=(1.0, 1.0))
    fig.suptitle(f"{title}\n{CI_NOTE}", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def trajectories(recording: Recording, title: str, path: Path) -> Path:
    """The leader's path (red; its scripted path dashed), every follower's (thin blue) and
    their starts, in the scene (its walls and obstacles grey), axes in metres."""
    pos = recording.positions
    scene = recording.config.scene
    x0, y0, x1, y1 = scene.bounds
    leader, follower = style.rgb01(style.LEADER), style.rgb01(style.FOLLOWER)
    fig, ax = plt.subplots(figsize=(4.4, 4.9))
    draw_scene(ax, scene)
    if recording.leader_path is not None:
        ax.plot(*recording.leader_path.T, ls="--", lw=0.9, color="0.45",
                label="leader's scripted path")
    for k in range(1, pos.shape[1]):
        ax.plot(pos[:, k, 0], pos[:, k, 1], lw=0.5, color=follower, alpha=0.5,
                label="followers" if k == 1 else None)
    ax.plot(pos[:, 0, 0], pos[:, 0, 1], lw=1.4, color=leader, label="leader")
    ax.scatter(pos[0, 1:, 0], pos[0, 1:, 1], s=5, color=follower, zorder=3)
    ax.scatter(*pos[0, 0], s=14, color=leader, zorder=3, label="start")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(color="0.93")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncols=2,
              frameon=False)  # below the arena, off the paths
    return save(fig, path)


def draw_scene(ax: Any, scene: Any) -> None:
    """A scene's static geometry on matplotlib axes: a map's occupied (dark) and unknown
    (light) cells, capsules as thick lines with round ends (pillars as discs), blocks
    filled."""
    grey = "0.42"
    if scene.grid is not None and scene.grid.origin[2] == 0.0:
        grid = scene.grid
        h, w = grid.cells.shape
        gx0, gy0, _ = grid.origin
        shade = np.where(grid.cells == 100, 0.42, np.where(grid.cells == -1, 0.8, 1.0))
        ax.imshow(shade, cmap="gray", vmin=0, vmax=1, origin="lower", interpolation="nearest",
                  extent=(gx0, gx0 + w * grid.resolution, gy0, gy0 + h * grid.resolution),
                  zorder=0)
    else:
        from matplotlib.patches import Circle

        for a, b, r in zip(scene.a, scene.b, scene.radius, strict=True):
            if np.all(a == b):
                ax.add_patch(Circle(tuple(a), float(r), color=grey, lw=0, zorder=1))
            else:
                ax.add_patch(_capsule(a, b, float(r), grey))
    for poly in scene.polygons:
        ax.fill(poly[:, 0], poly[:, 1], color=grey, lw=0, zorder=1)
    if scene.box is not None:
        bx0, by0, bx1, by1 = scene.box
        ax.plot([bx0, bx1, bx1, bx0, bx0], [by0, by0, by1, by1, by0], color="0.15", lw=1.2)


def _capsule(a: np.ndarray, b: np.ndarray, r: float, colour: str) -> Any:
    """A segment swept by a disc as a matplotlib polygon."""
    from matplotlib.patches import Polygon

    d = (b - a) / max(float(np.hypot(*(b - a))), 1e-12)
    angle = np.arctan2(d[1], d[0])
    half = np.linspace(-np.pi / 2, np.pi / 2, 9)
    ends = [b + r * np.column_stack([np.cos(angle + half), np.sin(angle + half)]),
            a + r * np.column_stack([np.cos(angle + np.pi + half),
                                     np.sin(angle + np.pi + half)])]
    return Polygon(np.vstack(ends), closed=True, color=colour, lw=0, zorder=1)


def policy_bars(table: pd.DataFrame, metric: str, path: Path, title: str | None = None
                ) -> Path:
    """One bar per policy for every case (mean, 95 % CI) of ``metric``."""
    fig, ax = plt.subplots(figsize=(max(6.5, 0.85 * table["case"].nunique() + 2), 3.6))
    _policy_panel(ax, table, metric)
    ax.set_title("")  # the figure's title says it
    ax.legend(fontsize=8, frameon=False)
    fig.suptitle(f"{title or metric_name(metric)}\n{CI_NOTE}", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


SAFETY_PANELS = ("touching_fraction", "contacts", "wall_fraction", "mean_nn_distance")
"""The safety figure's metrics (``contacts``: follower–follower plus leader–follower)."""


def safety_bars(table: pd.DataFrame, path: Path) -> Path:
    """The safety metrics per case, one bar per policy (mean, 95 % CI), one panel each."""
    table = with_contacts(table)
    panels = [m for m in SAFETY_PANELS if m in table]
    width = max(6.5, 0.85 * table["case"].nunique() + 2)
    # every panel names its cases (a panel of mostly zero bars read as empty without them)
    fig, axes = plt.subplots(len(panels), 1, figsize=(width, 3.4 * len(panels)),
                             squeeze=False)
    for ax, metric in zip(axes[:, 0], panels, strict=True):
        _policy_panel(ax, table, metric, ticks=True)
    axes[0, 0].legend(fontsize=8, frameon=False)
    fig.suptitle(f"Safety per case (the study does not measure it)\n{CI_NOTE}", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def _policy_panel(ax: plt.Axes, table: pd.DataFrame, metric: str, ticks: bool = True) -> None:
    cases = list(dict.fromkeys(table["case"]))
    policies = list(dict.fromkeys(table["policy"]))
    width = 0.8 / len(policies)
    top = 0.0
    zeros = []
    for pi, policy in enumerate(policies):
        sub = table[table["policy"] == policy]
        for ci, case in enumerate(cases):
            values = sub.loc[sub["case"] == case, metric]
            x = ci + (pi - (len(policies) - 1) / 2) * width
            top = max(top, _bar(ax, x, values, width, COLORS[pi % 10],
                                policy if ci == 0 else None))
            if len(values) and np.all(np.asarray(values, dtype=float) == 0):
                zeros.append((x, pi))
    if top > 0:  # a zero bar is invisible: mark it, so it reads as measured zero, not missing
        for x, pi in zeros:
            ax.text(x, 0, "0", ha="center", va="bottom", fontsize=7, color=COLORS[pi % 10],
                    gid="zero_bar")
    ax.set_xticks(range(len(cases)), cases if ticks else [""] * len(cases), rotation=30,
                  ha="right", fontsize=8)
    if ticks:
        ax.set_xlabel("case")
    _finish(ax, top, metric)


def _factor_label(factor: str) -> str:
    return {"leader_speed": "leader speed (m/s)", "leader_weight": "leader weight",
            "robots": "robots (leader included)"}.get(factor, factor)


def _level_label(factor: str, level: str) -> str:
    return {"leader_speed": f"{level} m/s", "robots": f"{level} robots",
            "leader_weight": f"weight {level}"}.get(factor, f"{factor} {level}")


CURVE_METRICS = ("total", "touching_fraction", "wall_fraction")
"""The panels of :func:`learning_curves`: the study's total, then the safety figures."""


def learning_curves(runs: Mapping[str, pd.DataFrame], path: Path,
                    reference: Mapping[str, float] | None = None,
                    title: str = "learning curves") -> Path:
    """One panel per metric of :data:`CURVE_METRICS` (those every run's table has), one line
    per run: its periodic evaluations (``evaluations.csv`` of ``boids train``: a
    ``timesteps`` column and the metrics) against follower-steps. ``reference`` draws a
    dashed horizontal line per metric (e.g. the Reynolds controller's value)."""
    metrics = [m for m in CURVE_METRICS if all(m in t for t in runs.values())]
    if not runs or not metrics:
        raise ValueError(f"learning curves need runs whose evaluations hold timesteps and "
                         f"one of {list(CURVE_METRICS)}")
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 3.2), squeeze=False)
    for ax, metric in zip(axes[0], metrics, strict=True):
        top = 0.0
        for k, (label, table) in enumerate(runs.items()):
            ax.plot(table["timesteps"] / 1e6, table[metric], color=COLORS[k % len(COLORS)],
                    label=label, linewidth=1.4, marker="o", markersize=2.5)
            top = max(top, float(table[metric].max()))
        if reference and metric in reference:
            ax.axhline(reference[metric], color="0.3", linestyle="--", linewidth=1)
            ax.annotate(f"Reynolds {reference[metric]:.3g}", (0.98, reference[metric]),
                        xycoords=("axes fraction", "data"), ha="right", va="bottom",
                        fontsize=8, color="0.3")
            top = max(top, reference[metric])
        ax.set_title(metric_name(metric))
        ax.set_xlabel("follower-steps (millions)")
        ax.set_ylabel(UNITS.get(metric, metric))
        ax.set_ylim(0, top * 1.1 if top > 0 else 1)
    axes[0][0].legend(frameon=False, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path)
