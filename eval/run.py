"""``boids run``: one episode of a policy on a case, its metrics, trajectory and video."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from boids_env.environment import BoidsEnv
from boids_env.eval.episode import EpisodeResult, env_fields_for, run_episode
from boids_env.policies.registry import load_policy, split_preset

METRIC_ROWS = (("V_sep", "separation violation (study)"), ("V_coh", "cohesion violation (study)"),
               ("V_align", "alignment violation (study)"),
               ("polarization", "polarization (mean)"),
               ("mean_leader_distance", "mean distance to leader (m)"),
               ("min_distance", "min inter-robot distance (m)"),
               ("touching_fraction", "time some pair of robots touches"),
               ("mean_contact_pairs", "pairs touching, mean"),
               ("contacts_follower", "contact onsets follower-follower"),
               ("contacts_leader", "contact onsets leader-follower"),
               ("wall_fraction", "time some robot touches a wall"),
               ("mean_nn_distance", "nearest-neighbour distance, mean (m)"),
               ("leader_path_deviation", "leader off its scripted path, mean (m)"),
               ("duration", "episode length T (s)"))


def metrics_table(metrics: dict[str, Any]) -> str:
    """The metrics as an aligned text table."""
    lines = [f"{'metric':<24} {'value':>10}  meaning", "-" * 72]
    for key, meaning in METRIC_ROWS:
        value = metrics[key]
        shown = f"{value:.4f}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<24} {shown:>10}  {meaning}")
    return "\n".join(lines)


def run(policy: str = "reynolds", *, out: str | Path | None = None, seed: int = 0,
        preset: str = "paper", leader_weight: float | None = None, video: bool = False,
        bag: bool = False, mcap: bool = False, frame_every: int = 2,
        env_fields: dict[str, Any] | None = None,
        quiet: bool = False) -> EpisodeResult:
    """Runs one episode and writes ``metrics.json``, ``trajectory.parquet``, ``config.json``
    (and ``episode.gif`` with ``video``, ``episode.bag`` with ``bag``, the ROS 2 MCAP bag
    folder ``episode_mcap`` with ``mcap``) to ``out``."""
    overrides = {} if leader_weight is None else {"leader_weight": leader_weight}
    policy, preset = split_preset(policy, preset)
    pol = load_policy(policy, preset=preset, **overrides)
    params = getattr(pol, "params", None)
    env = BoidsEnv(render_mode="rgb_array" if video else None,
                   **env_fields_for(pol, env_fields))
    result = run_episode(env, pol, seed, record=True, frame_every=frame_every if video else 0)
    if not quiet:
        name = f"{policy} · preset {preset}" if params is not None else policy
        print(f"policy {name} · robots {env.config.scenario.robots} · "
              f"leader {env.config.scenario.leader_speed} m/s · seed {seed} · "
              f"{result.wall_time:.2f} s wall")
        print(metrics_table(result.metrics))
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(result.metrics, indent=2))
        shown_preset = preset if params is not None else None
        config = {"env": env.config.to_dict(), "policy": policy, "preset": shown_preset,
                  "policy_params": vars(params) if params is not None else None, "seed": seed}
        (out / "config.json").write_text(json.dumps(config, indent=2))
        assert result.recording is not None
        result.recording.extra.update(policy=policy, preset=shown_preset)
        result.recording.to_parquet(out / "trajectory.parquet")
        if video:
            import imageio.v3 as iio

            iio.imwrite(out / "episode.gif", result.frames,
                        duration=int(1000 * env.config.world.dt * frame_every / 2), loop=0)
        if bag or mcap:
            from boids_env.rosbag import write_bag

            if bag:
                write_bag(result.recording, out / "episode.bag")
            if mcap:
                write_bag(result.recording, out / "episode_mcap", format="mcap")
        if not quiet:
            print(f"wrote {', '.join(sorted(p.name for p in out.iterdir()))} to {out}")
    env.close()
    return result
