"""``boids run``: one episode of a policy on a case, its metrics, trajectory, video and bags.

The outputs go to a folder the run owns (:class:`~boids_env.eval.outputs.RunFolder`): a
non-empty folder is refused unless ``overwrite``, which replaces only what an earlier run of
ours wrote, and everything is written to a temporary folder that is moved into place when
complete.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from boids_env.config import EnvConfig
from boids_env.environment import BoidsEnv
from boids_env.eval.episode import (
    EpisodeResult,
    env_fields_for,
    run_episode,
    warn_outside_card,
    world_changes,
)
from boids_env.eval.outputs import RunFolder
from boids_env.files import write_json
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
               ("wall_fraction", "time some robot touches a wall or obstacle"),
               ("min_clearance", "closest any robot's edge came to a wall (m)"),
               ("no_sight_fraction", "time a follower cannot see the leader"),
               ("mean_nn_distance", "nearest-neighbour distance, mean (m)"),
               ("leader_path_deviation", "leader off its scripted path, mean (m)"),
               ("intimate_fraction", "time within 0.45 m of the person (Hall)"),
               ("personal_fraction", "time 0.45-1.2 m from the person"),
               ("social_fraction", "time 1.2-3.6 m from the person"),
               ("public_fraction", "time beyond 3.6 m of the person"),
               ("min_person_distance", "closest robot-person centres (m)"),
               ("person_contacts", "contact onsets robot-person"),
               ("person_contact_fraction", "time some robot touches the person"),
               ("cut_in_fraction", "time in the person's path (2 s ahead)"),
               ("pedestrian_intimate_fraction", "time within 0.45 m of a pedestrian"),
               ("pedestrian_personal_fraction", "time within 1.2 m of a pedestrian"),
               ("min_pedestrian_distance", "closest robot-pedestrian centres (m)"),
               ("pedestrian_contacts", "contact onsets robot-pedestrian"),
               ("duration", "episode length T (s)"))


def metrics_table(metrics: dict[str, Any]) -> str:
    """The metrics as an aligned text table (what ``boids run`` and the live window print)."""
    lines = [f"{'metric':<24} {'value':>10}  meaning", "-" * 72]
    for key, meaning in METRIC_ROWS:
        if key not in metrics:
            continue
        value = metrics[key]
        count = key.startswith("contacts_") or key.endswith("_contacts")
        if count and isinstance(value, float) and value.is_integer():
            value = int(value)  # a count
        if isinstance(value, float) and not math.isfinite(value):
            shown = "n/a"  # does not apply: no scripted path to deviate from (external)
        else:
            shown = f"{value:.4f}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<24} {shown:>10}  {meaning}")
    return "\n".join(lines)


def _live_view(env: BoidsEnv, live: dict[str, Any] | None, quiet: bool
               ) -> tuple[Any, Callable[[BoidsEnv, int], None] | None]:
    """The Foxglove live view of ``run`` and the step hook that feeds it (None, None
    without one)."""
    if live is None:
        return None, None
    from boids_env.eval.liveview import FoxgloveView, env_frame

    view = FoxgloveView(env.config, **live)
    if not quiet:
        print(f"live view: open ws://127.0.0.1:{view.port} in Foxglove", flush=True)

    def on_step(env: BoidsEnv, step: int) -> None:
        view.show(step, **env_frame(env))

    return view, on_step


def run(policy: str = "reynolds", *, out: str | Path | None = None, overwrite: bool = False,
        seed: int = 0, preset: str = "paper", leader_weight: float | None = None,
        video: bool | str | None = None, bag: bool = False, mcap: bool = False,
        bag_start: float | None = None, frame_every: int = 2,
        env_fields: dict[str, Any] | None = None, quiet: bool = False,
        progress: bool = True, trust_model: bool = False,
        live: dict[str, Any] | None = None, twist_stamped: bool = False) -> EpisodeResult:
    """Runs one episode and writes its outputs to ``out``.

    Args:
        policy: a policy spec (see :func:`~boids_env.policies.registry.load_policy`).
        out: the run's folder (None: nothing is written): ``metrics.json``, ``config.json``,
            ``trajectory.parquet``, ``manifest.json``, and on request ``episode.gif`` /
            ``episode.mp4``, ``episode.bag`` (ROS 1), ``episode_mcap/`` (ROS 2, MCAP).
        overwrite: replace what an earlier run wrote in ``out`` (a non-empty folder is
            refused otherwise); the user's own files there are kept.
        seed: the episode's seed.
        preset: Reynolds parameters of a bare ``reynolds`` policy.
        leader_weight: override of the Reynolds leader weight.
        video: ``"gif"`` (or True) or ``"mp4"`` (needs imageio-ffmpeg) to write a video.
        bag, mcap: write the ROS 1 bag / the ROS 2 MCAP bag.
        bag_start: the bags' start stamp, Unix time (s); None: the wall clock at writing.
        frame_every: control steps per video frame.
        env_fields: env config fields by flat name.
        quiet: print nothing.
        progress: progress bar while the video is encoded.
        trust_model: a model zip may load through SB3's own load, which runs code stored in
            the file (``load_policy(trust=True)``).
        live: serve the episode live over Foxglove's WebSocket protocol while it runs: the
            keyword arguments of :class:`~boids_env.eval.liveview.FoxgloveView` (``port``,
            ``speed``, ``wait``); None: no live view.
        twist_stamped: the bags' ``cmd_vel`` as geometry_msgs/TwistStamped (a TurtleBot3 on
            Jazzy and later) instead of Twist.
    """
    fmt = ("gif" if video else None) if isinstance(video, bool) or video is None else video
    if fmt is not None:
        from boids_env.eval.video import check_format

        check_format(fmt)
    policy, preset = split_preset(policy, preset)
    if leader_weight is not None and policy != "reynolds":
        raise ValueError(f"leader_weight is a Reynolds parameter: it needs policy 'reynolds' "
                         f"or 'reynolds@PRESET', got {policy!r}")
    folder = RunFolder(out, overwrite=overwrite) if out is not None else None  # refuse early
    overrides = {} if leader_weight is None else {"leader_weight": leader_weight}
    pol = load_policy(policy, preset=preset, trust=trust_model, **overrides)
    params = getattr(pol, "params", None)
    # the asked config and the one the policy runs in, each built and checked once
    asked = EnvConfig.from_kwargs(**(env_fields or {}))
    ran = EnvConfig.from_kwargs(**env_fields_for(pol, env_fields))
    changes = world_changes(pol, env_fields, configs=(asked, ran))  # config.json, printed
    env = BoidsEnv(ran)
    warn_outside_card(pol, {"": env.config}, name=policy)  # one line; the run goes on
    view, on_step = _live_view(env, live, quiet)
    try:
        result = run_episode(env, pol, seed, record=True, on_step=on_step)
    finally:
        env.close()
        if view is not None:
            view.close()
    say = (lambda *a: None) if quiet else print
    shown_preset = preset if params is not None else None
    _say_episode(say, env.config, policy, shown_preset, seed, result)
    _say_changes(say, changes)
    if folder is None:
        return result
    assert result.recording is not None
    result.recording.extra.update(policy=policy, preset=shown_preset)
    config = {"env": env.config.to_dict(), "policy": policy, "preset": shown_preset,
              "policy_params": vars(params) if params is not None else None, "seed": seed,
              "model_env_fields": getattr(pol, "env_fields", None), "world_changes": changes}
    _write_outputs(folder, result, config, say, video=fmt, frame_every=frame_every,
                   progress=progress and not quiet, bags=(bag, mcap), bag_start=bag_start,
                   twist_stamped=twist_stamped)
    return result


def _say_episode(say: Callable[..., Any], config: EnvConfig, policy: str, preset: str | None,
                 seed: int, result: EpisodeResult) -> None:
    """Prints the episode's line (policy, case, seed, wall time) and its metrics table."""
    name = f"{policy} · preset {preset}" if preset is not None else policy
    if config.realism.active:
        name += f" · realism {config.realism.realism}"
    if config.world.scene != "arena":
        name += f" · scene {config.scene.name}"
    say(f"policy {name} · robots {config.scenario.robots} · "
        f"leader {config.scenario.leader_speed} m/s · seed {seed} · "
        f"episode {result.wall_time:.2f} s wall")
    say(metrics_table(result.metrics))


def _write_outputs(folder: RunFolder, result: EpisodeResult, config: dict[str, Any],
                   say: Callable[..., Any], *, video: str | None, frame_every: int,
                   progress: bool, bags: tuple[bool, bool], bag_start: float | None,
                   twist_stamped: bool) -> None:
    """Writes the run's files into ``folder`` (atomically: a temporary folder moved into
    place) and says what it wrote and how long it took."""
    assert result.recording is not None
    fmt, (bag, mcap) = video, bags
    start = time.perf_counter()
    timings: list[str] = []
    with folder as tmp:
        write_json(tmp / "metrics.json", result.metrics)
        write_json(tmp / "config.json", config)
        result.recording.to_parquet(tmp / "trajectory.parquet")
        if fmt is not None:
            from boids_env.eval.video import write_video

            info = write_video(result.recording, tmp / f"episode.{fmt}",
                               frame_every=frame_every, progress=progress)
            timings.append(f"video {info.seconds:.1f} s for {info.frames} frames")
        if bag or mcap:
            from boids_env.rosbag import write_bag

            began = time.perf_counter()
            if bag:
                write_bag(result.recording, tmp / "episode.bag", start=bag_start,
                          twist_stamped=twist_stamped)
            if mcap:
                write_bag(result.recording, tmp / "episode_mcap", format="mcap",
                          start=bag_start, twist_stamped=twist_stamped)
            timings.append(f"bags {time.perf_counter() - began:.1f} s")
    written = sorted(p.name + ("/" if p.is_dir() else "") for p in folder.out.iterdir())
    say(f"wrote {', '.join(written)} to {folder.out}")
    if folder.replaced:
        say(f"replaced the earlier run's {', '.join(folder.replaced)}; kept "
            f"{', '.join(folder.kept) or 'nothing else'}")
    say(f"writing took {time.perf_counter() - start:.1f} s wall"
        + (f" ({'; '.join(timings)})" if timings else "")
        + f"; episode {result.wall_time:.2f} s")


def _say_changes(say: Any, changes: dict[str, dict[str, list[Any]]]) -> None:
    """Prints what the policy changed in the world asked for (see ``world_changes``)."""
    for kind, what in (("changed", "the policy's env fields changed"),
                       ("untrained", "the settings changed the model's training values of")):
        if changes[kind]:
            say(f"note: {what} " + ", ".join(f"{k} ({a!r} -> {b!r})"
                                              for k, (a, b) in changes[kind].items()))
