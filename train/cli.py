"""The ``boids`` command. It lives in the top layer (train -> eval -> policies -> boids_env) so
no layer imports one above it: ``run``, ``eval`` and ``report`` come from
:mod:`boids_env.eval.cli`, ``train`` is defined here. Argument parsing only; each command's code
is imported when it runs, so ``boids run`` works without the train extra. This module imports
only the standard library at its top: everything else is imported inside :func:`main`, which
answers a Ctrl-C at any moment with one line and exit status 130. A command's help is its
handler's docstring (:func:`boids_env.eval.flags.add_command`)."""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import sys
import threading
import warnings
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any


def _train_parser(sub: argparse._SubParsersAction) -> None:
    from boids_env.eval.flags import add_command

    p = add_command(sub, "train", _cmd_train)
    p.add_argument("--config", help="a TOML file of TrainConfig fields, or the name of a "
                   "shipped recipe (ppo_safe, ppo_safe_stage2, ppo_study, ppo_person, "
                   "ppo_scenes, ppo_turtlebot ...); flags override it")
    p.add_argument("--out", default="runs/train", help="output folder (runs/train)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier training in --out (only what it wrote, as listed in "
                   "its manifest.json; your own files there are kept)")
    p.add_argument("--algorithm", choices=("ppo", "sac"), default=None,
                   help="Stable-Baselines3 algorithm (ppo)")
    p.add_argument("--timesteps", type=int, default=None, dest="total_timesteps",
                   help="follower-steps in all (PPO rounds up to whole rollouts)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the env copies, the policy's initial weights and its "
                   "sampling (0)")
    p.add_argument("--seeds", type=int, nargs="+", default=None, metavar="N",
                   help="train these seeds, each in --out/seed_N, as separate processes (or "
                   "Ray tasks with --backend ray), then write --out/seeds.csv and seeds.md; "
                   "a rerun trains only the seeds not finished")
    p.add_argument("--backend", choices=("process", "ray"), default="process",
                   help="with --seeds: local processes (default) or Ray tasks (RAY_ADDRESS "
                   "picks the cluster; --out on a file system every node sees)")
    p.add_argument("--workers", type=int, default=None,
                   help="with --seeds: seeds trained at once (default: all)")
    p.add_argument("--copies", type=int, default=None, help="env copies stepped together")
    p.add_argument("--processes", type=int, default=None,
                   help="processes stepping the env copies, this one included (0: half "
                        "the cores from 3 cores on, else 1, or on 2 cores a worker too "
                        "when the copies' step takes 2 ms or more)")
    p.add_argument("--torch-threads", type=int, default=None, dest="torch_threads",
                   help="learner threads (0: one on 1-2 cores, else the cores the env "
                        "processes leave)")
    p.add_argument("--device", choices=("cpu", "cuda", "auto"), default=None,
                   help="where the policy updates run (cpu)")
    p.add_argument("--group-sizes", type=int, nargs="+", default=None, metavar="N",
                   help="group sizes (leader included) of the env copies, assigned round "
                   "robin (7 13 19)")
    p.add_argument("--leader-speeds", type=float, nargs="+", default=None, metavar="M/S",
                   help="each training episode draws its leader speed from these "
                   "(0.5 0.55 0.6)")
    p.add_argument("--eval-every", type=int, default=None,
                   help="evaluate the model every this many follower-steps, and the final "
                   "model at the end, into evaluations.csv (the recipe's, else 1000000; 0: never)")
    p.add_argument("--checkpoint-every", type=int, default=None, help="timesteps (0: never)")
    p.add_argument("--resume", default=None, help="checkpoint zip to continue from, up to "
                   "--timesteps in all (more than it has); goes on in the --out of the "
                   "same config (the config rebuilds the model; the zip gives weights, "
                   "optimizer state and step count, read without running anything stored in it)")
    p.add_argument("--trust-model", action="store_true",
                   help="with --resume: load the checkpoint through Stable-Baselines3's own "
                   "load, which unpickles objects stored in the file and so runs any code they "
                   "carry (a checkpoint whose network the config does not build; only for "
                   "files you trust)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (shown on a terminal only)")


def _cmd_train(args: argparse.Namespace) -> int:
    """train followers with Stable-Baselines3 (train extra)

    Trains one shared follower policy (PPO by default) on the flock; writes model.zip, config.json,
    evaluations.csv, checkpoints/, tb/ (TensorBoard) and manifest.json to --out, which must be
    empty or new unless --overwrite (or a --resume of the training there).
    """
    from boids_env.train.config import TrainConfig, resolve_recipe

    overrides = {name: getattr(args, name) for name in (
        "algorithm", "total_timesteps", "seed", "copies", "processes", "torch_threads",
        "device", "eval_every", "checkpoint_every")}
    overrides["group_sizes"] = tuple(args.group_sizes) if args.group_sizes else None
    overrides["leader_speeds"] = tuple(args.leader_speeds) if args.leader_speeds else None
    if args.config:
        config = TrainConfig.from_toml(resolve_recipe(args.config), **overrides)
    else:
        config = TrainConfig().replace(**overrides)
    from boids_env.extras import require

    require("train", purpose="boids train")
    if config.device == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise ValueError("--device cuda but torch sees no GPU; use --device cpu or auto")
    if args.seeds is not None:
        return _sweep(args, config)
    if args.backend != "process" or args.workers is not None:
        raise ValueError("--backend and --workers go with --seeds")
    from boids_env.eval.progress import on_terminal
    from boids_env.train.run import train

    # SB3's bar on a terminal only: its redraws would fill a piped log
    model = train(config, args.out, resume=args.resume, overwrite=args.overwrite,
                  progress_bar=not args.no_progress and on_terminal(),
                  trust_model=args.trust_model)
    written = sorted(p.name + ("/" if p.is_dir() else "") for p in model.parent.iterdir())
    print(f"wrote {model}; {args.out} holds {', '.join(written)}")
    return 0


def _sweep(args: argparse.Namespace, config: Any) -> int:
    """``boids train --seeds ...``: every seed in a folder of its own, then the seeds table."""
    if args.seed is not None:
        raise ValueError("--seeds trains several seeds: give no --seed (a rerun goes on from "
                         "each unfinished seed's last checkpoint)")
    if args.backend == "ray":
        from boids_env.extras import require

        require("ray", purpose="boids train --backend ray")
    from boids_env.train.sweep import run_sweep

    table = run_sweep(config, args.seeds, args.out, backend=args.backend, workers=args.workers,
                      overwrite=args.overwrite, resume=args.resume)
    return _wrote(table, table.with_suffix(".md"))


def _wrote(*paths: Path) -> int:
    """Says which files a command wrote; its exit status (0)."""
    print(f"wrote {' and '.join(map(str, paths))}")
    return 0


def _curves_parser(sub: argparse._SubParsersAction) -> None:
    from boids_env.eval.flags import add_command

    p = add_command(sub, "curves", _cmd_curves)
    p.add_argument("runs", nargs="+", help="boids train output folders (or evaluations.csv "
                   "files); label one with LABEL=PATH")
    # dest "figure": --out here names a file, which a rerun replaces (main's --out check is
    # for output folders)
    p.add_argument("--out", dest="figure", default="curves.png",
                   help="figure file (curves.png); a rerun replaces it")
    p.add_argument("--reference", type=float, default=None,
                   help="a total to draw as a dashed line (e.g. Reynolds' on the default "
                   "case)")
    p.add_argument("--title", default="learning curves", help="the figure's title")


def _cmd_curves(args: argparse.Namespace) -> int:
    """learning curves of training runs (eval extra)

    Plots the periodic evaluations (evaluations.csv) of one or more boids train output folders
    against follower-steps: the study's total and the safety figures, one line per run; writes a
    PNG and an SVG beside it.
    """
    from boids_env.extras import require

    require("eval", purpose="boids curves")
    import pandas as pd

    from boids_env.eval.figures import learning_curves

    runs = {}
    for spec in args.runs:
        label, eq, where = spec.partition("=")
        path = Path(where if eq else spec)
        csv = path / "evaluations.csv" if path.is_dir() else path
        if not csv.is_file():
            raise FileNotFoundError(f"no evaluations.csv in {path}: give a boids train "
                                    f"output folder (a training with --eval-every 0 "
                                    f"evaluates nothing)")
        try:
            table = pd.read_csv(csv)
        except (ValueError, UnicodeDecodeError) as exc:
            raise ValueError(f"cannot read {csv}: {exc}") from None
        if "timesteps" not in table or table.empty:
            raise ValueError(f"{csv} is not a boids train evaluations.csv (no timesteps rows)")
        runs[label if eq else str(path)] = table
    reference = {"total": args.reference} if args.reference is not None else None
    out = learning_curves(runs, Path(args.figure), reference, title=args.title)
    return _wrote(out, out.with_suffix(".svg"))


def _card_parser(sub: argparse._SubParsersAction) -> None:
    from boids_env.eval.flags import add_command

    p = add_command(sub, "card", _cmd_card)
    p.add_argument("model", nargs="?", default=None,
                   help="a shipped model's name (learned, learned-scenes, ...) or a zip")
    p.add_argument("--json", action="store_true", help="the card as JSON")
    p.add_argument("--write", action="store_true",
                   help="write the card into the zip: the one its training config describes, "
                   "or --from's")
    p.add_argument("--from", dest="source", default=None, metavar="CARD.json",
                   help="with --write: the card to write (e.g. boids card MODEL --json, edited "
                   "to add validation figures)")


def _cmd_card(args: argparse.Namespace) -> int:
    """what a learned model was made for (its model card)

    Shows the card a model zip carries: the robots, scenes, crowds, leaders, group sizes and speeds
    it was trained and validated on, its sensing and its validation figures (a zip without one: the
    card its training config describes). Without MODEL, lists the shipped models. --write puts a
    card into the zip, everything else in it kept byte for byte.
    """
    import json

    from boids_env.policies.cards import CARD_LIMIT, ModelCard
    from boids_env.policies.registry import MODELS, model_card, model_path, shipped_cards
    from boids_env.train.cards import write_card
    from boids_env.untrusted import parse_json, read_text

    if args.model is None:
        if args.write or args.json or args.source:
            raise ValueError("--json, --write and --from need a MODEL")
        cards = shipped_cards()
        for name, path in MODELS.items():
            card = cards.get(name)
            print(f"{name:<16} {path.name:<16} {card.summary if card else '(no card)'}")
        return 0
    path = model_path(args.model)
    if not path.is_file():
        raise FileNotFoundError(f"model not found: {args.model} (a shipped model: "
                                f"{', '.join(MODELS)}; or a model zip)")
    if args.source is not None and not args.write:
        raise ValueError("--from names the card to write: give --write too")
    card = model_card(path)
    if args.write:
        if args.source is not None:
            where = f"model card {args.source}"
            card = ModelCard.from_dict(parse_json(read_text(args.source, where, CARD_LIMIT),
                                                  where))
        if card is None:
            raise ValueError(f"{path} holds no training config to derive a card from: give "
                             f"one with --from CARD.json")
        write_card(path, card)
        print(f"wrote the card into {path}")
    if card is None:
        print(f"{path} carries no card and no training config (saved outside boids train)")
    elif args.json:
        print(json.dumps(card.to_dict(), indent=1))
    else:
        print("\n".join(card.lines()))
    return 0


EXAMPLES = """\
examples:
  boids run --seed 0 --video                 the study's flock, its metrics and a GIF
  boids run --scene lab --policy learned-scenes
  boids run --map my_map.yaml --start=-3,0 --waypoints "-3,3 2,3"
  boids scenes                               the built-in scenes
  boids eval --policy reynolds --policy learned --out runs/eval
  boids train --config ppo_safe --timesteps 200000 --out runs/train
  boids curves runs/train
  boids card learned                         what a model was made for

boids COMMAND --help describes each command's options."""
"""Shown under ``boids --help``."""

NEGATIVE_PAIR = re.compile(r"-\.?\d[^,\s]*,")
"""A value such as ``-3,0`` or ``-4,4 0,0`` (x,y pairs in metres): argparse would read it as
an option, since it starts with ``-`` and is no plain negative number."""


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` that takes x,y values starting with a minus sign after an option
    (``--start -3,0``, ``--waypoints -4,4``) as ``--start=-3,0``: argparse alone reads
    ``-3,0`` as an unknown option and stops with "expected one argument". Subparsers are built
    of the same class."""

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> Any:
        ns, extras = super().parse_known_args(join_negative_pairs(
            sys.argv[1:] if args is None else list(args)), namespace)
        if extras and not any(isinstance(a, argparse._SubParsersAction) for a in self._actions):
            # a command's own parser (not ``boids`` itself, which would name its own usage)
            self.error(unknown_text(extras, self._option_string_actions))
        return ns, extras


def unknown_text(extras: Sequence[str], known: Iterable[str]) -> str:
    """``unrecognized arguments: --robts 5 (--robts: did you mean --robots?)``: each unknown
    option with the closest of the command's own (difflib), if one is close."""
    import difflib

    hints = []
    for arg in extras:
        flag = arg.partition("=")[0]
        if flag.startswith("--"):
            # the names without the dashes every option shares, which would make anything close
            close = difflib.get_close_matches(flag[2:], [k[2:] for k in known
                                                         if k.startswith("--")], n=1, cutoff=0.75)
            if close:
                hints.append(f"{flag}: did you mean --{close[0]}?")
    return f"unrecognized arguments: {' '.join(extras)}" + (f" ({'; '.join(hints)})"
                                                             if hints else "")


def join_negative_pairs(args: list[str]) -> list[str]:
    """``["--start", "-3,0"]`` -> ``["--start=-3,0"]``; everything else unchanged (an option
    that takes no value then refuses the joined one by name, as it refused ``-3,0``)."""
    out: list[str] = []
    for arg in args:
        prev = out[-1] if out else ""
        if ("--" not in out and NEGATIVE_PAIR.match(arg) and prev.startswith("-")
                and "=" not in prev and not NEGATIVE_PAIR.match(prev)):
            out[-1] = f"{prev}={arg}"
        else:
            out.append(arg)
    return out


def build_parser() -> argparse.ArgumentParser:
    from boids_env import __version__
    from boids_env.eval import cli as eval_cli

    parser = Parser(prog="boids", description="boids-env: leader-following "
                    "boids flock (Akgun's ROS study) as a PettingZoo env",
                    epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"boids-env {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    eval_cli.add_commands(sub)
    _train_parser(sub)
    _curves_parser(sub)
    _card_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the ``boids`` command; returns the exit status (2 for a user error, 130 when
    interrupted)."""
    try:
        with _deferred_ctrl_c() as interrupted:
            args = build_parser().parse_args(argv)  # the first imports of numpy, scipy, pymunk
    except KeyboardInterrupt:
        interrupted = [True]
    if interrupted:
        print("\nboids: interrupted", file=sys.stderr)
        return 130
    try:
        _check_out(args)
        with _one_line_warnings(args.command):
            return int(args.func(args))
    except KeyboardInterrupt:
        out = getattr(args, "out", None)
        # eval and train keep what they finished (a rerun resumes); a run writes all or nothing
        kept = f"; finished work is kept in {out}" if out and args.command in (
            "eval", "train") else ""
        print(f"\nboids {args.command}: interrupted{kept}", file=sys.stderr)
        return 130
    except (ValueError, TypeError, KeyError, OSError, ImportError) as exc:
        print(f"boids {args.command}: error: {error_text(exc)}", file=sys.stderr)
        return 2


@contextlib.contextmanager
def _deferred_ctrl_c() -> Iterator[list[bool]]:
    """Holds a Ctrl-C back until the block ends, recording it in the yielded list. Around the
    command's first imports: a KeyboardInterrupt raised inside a C extension's import comes
    out as an ImportError (numpy's does), printed as a traceback; deferred, the command stops
    cleanly a fraction of a second later. Where Ctrl-C is not Python's default (ignored, as in
    a background job, or another handler) or off the main thread nothing changes."""
    interrupted: list[bool] = []
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield interrupted
        return
    signal.signal(signal.SIGINT, lambda *_: interrupted.append(True))
    try:
        yield interrupted
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextlib.contextmanager
def _one_line_warnings(command: str) -> Iterator[None]:
    """Shows a model-card warning (a model run outside what it was made for) as one line,
    ``boids run: warning: ...``, on stderr; other warnings as Python shows them."""
    shown = warnings.showwarning

    def show(message: Any, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        if category.__name__ == "ModelCardWarning":  # (not imported: the command's own)
            print(f"boids {command}: warning: {message}", file=sys.stderr)
        else:
            shown(message, category, *args, **kwargs)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = shown


def _check_out(args: argparse.Namespace) -> None:
    """``--out`` names a folder: an existing file there, or a path that cannot become a folder
    (a file on the way, a folder we may not write in) is refused before any work, not when
    the outputs are written after it."""
    out = getattr(args, "out", None)
    if not isinstance(out, str):
        return
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(f"--out {out} is an existing file, not a folder; give a new "
                                 f"or existing folder")
    existing = next(p for p in (path.absolute(), *path.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise NotADirectoryError(f"--out {out}: {existing} is a file, so no folder can be "
                                 f"made under it; give a new or existing folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise PermissionError(f"--out {out}: no permission to write in {existing}; give a "
                              f"folder you can write to")


def error_text(exc: BaseException) -> str:
    """A one-line message for a user error: an operating-system error as ``No space left on
    device: runs/x/results.parquet`` (what failed and where), a ``KeyError`` without quotes."""
    if isinstance(exc, OSError) and exc.strerror and exc.filename is not None:
        where = f"{exc.filename}" + (f" -> {exc.filename2}" if exc.filename2 else "")
        return f"{exc.strerror}: {where}"
    if isinstance(exc, KeyError) and len(exc.args) == 1 and isinstance(exc.args[0], str):
        return exc.args[0]
    return str(exc) or type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
