"""The study's figures for a results table (matplotlib, headless): grouped bars per metric and
level with std error bars (the study's beside ours), per-follower bars for group size,
sample trajectories per case, and policy-vs-policy bars."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from boids_env.eval.stats import group_values
from boids_env.recording import Recording

COLORS = plt.get_cmap("tab10").colors


def _save(fig: plt.Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def level_bars(rows: pd.DataFrame, metrics: Sequence[str], title: str, path: Path,
               study: Mapping[str, Mapping[str, np.ndarray]] | None = None,
               followers: int = 6) -> Path:
    """Grouped bars: one cluster per metric, one bar per level (mean, std error bar); with
    ``study`` ({metric: {level: values}}) the study's bars are drawn hatched beside ours."""
    levels = list(dict.fromkeys(rows["level"]))
    per_bar = 2 if study else 1
    width = 0.8 / (len(levels) * per_bar)
    fig, ax = plt.subplots(figsize=(7, 3.8))
    for m, metric in enumerate(metrics):
        ours = group_values(rows, metric, followers)
        for li, level in enumerate(levels):
            x = m + (li * per_bar - (len(levels) * per_bar - 1) / 2) * width
            vals = ours.get(level, np.array([np.nan]))
            ax.bar(x, np.mean(vals), width, yerr=np.std(vals), capsize=2,
                   color=COLORS[li % 10], label=f"ours {level}" if m == 0 else None)
            if study and metric in study and level in study[metric]:
                sv = study[metric][level]
                ax.bar(x + width, np.mean(sv), width, yerr=np.std(sv), capsize=2,
                       color=COLORS[li % 10], alpha=0.45, hatch="//",
                       label=f"study {level}" if m == 0 else None)
    ax.set_xticks(range(len(metrics)), [m.replace("_unwrapped", " (unwrapped)")
                                        for m in metrics])
    ax.set_ylabel("violation (V)" if metrics[0].startswith("V_") else "violating samples")
    ax.set_title(title)
    ax.legend(fontsize=7, ncols=2)
    return _save(fig, path)


def follower_bars(rows: pd.DataFrame, metrics: Sequence[str], title: str, path: Path,
                  followers: int = 6) -> Path:
    """Per-follower bars (followers 1..``followers``), one panel per count metric, one bar
    per level (mean over runs, std error bar): the study's group-size figures."""
    levels = list(dict.fromkeys(rows["level"]))
    fig, axes = plt.subplots(1, len(metrics), figsize=(4 * len(metrics), 3.4), squeeze=False)
    width = 0.8 / len(levels)
    x = np.arange(1, followers + 1)
    for ax, metric in zip(axes[0], metrics, strict=True):
        for li, level in enumerate(levels):
            counts = np.array([list(c)[:followers] for c in
                               rows.loc[rows["level"] == level, metric]], dtype=float)
            ax.bar(x + (li - (len(levels) - 1) / 2) * width, counts.mean(axis=0), width,
                   yerr=counts.std(axis=0), capsize=2, color=COLORS[li % 10],
                   label=f"{rows['factor'].iloc[0]} {level}")
        ax.set_xticks(x)
        ax.set_xlabel("follower")
        ax.set_title(metric)
    axes[0][0].set_ylabel("violating samples (0.1 s)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(title)
    return _save(fig, path)


def trajectories(recording: Recording, title: str, path: Path) -> Path:
    """The leader's path (red) and every follower's (thin blue) of one episode."""
    pos = recording.positions
    h = recording.config.world.arena_half_size
    fig, ax = plt.subplots(figsize=(4.2, 4.2))
    for k in range(1, pos.shape[1]):
        ax.plot(pos[:, k, 0], pos[:, k, 1], lw=0.5, color="tab:blue", alpha=0.6)
    ax.plot(pos[:, 0, 0], pos[:, 0, 1], lw=1.6, color="tab:red", label="leader")
    ax.scatter(pos[0, 1:, 0], pos[0, 1:, 1], s=4, color="tab:blue", label="followers (start)")
    ax.set_xlim(-h, h)
    ax.set_ylim(-h, h)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=6, loc="lower right")
    return _save(fig, path)


def policy_bars(table: pd.DataFrame, metric: str, path: Path) -> Path:
    """One bar per policy for every case (mean, std error bar) for ``metric``."""
    cases = list(dict.fromkeys(table["case"]))
    policies = list(dict.fromkeys(table["policy"]))
    width = 0.8 / len(policies)
    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(cases)), 3.6))
    for pi, policy in enumerate(policies):
        sub = table[table["policy"] == policy].groupby("case", sort=False)[metric]
        means = sub.mean().reindex(cases)
        stds = sub.std(ddof=0).reindex(cases)
        ax.bar(np.arange(len(cases)) + (pi - (len(policies) - 1) / 2) * width, means, width,
               yerr=stds, capsize=2, color=COLORS[pi % 10], label=policy)
    ax.set_xticks(range(len(cases)), cases, rotation=30, ha="right", fontsize=7)
    ax.set_title(metric)
    ax.legend(fontsize=7)
    return _save(fig, path)
