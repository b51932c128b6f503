"""Small files, huge costs (issue 39): writes each hostile small file into a temporary folder,
reads it in a fresh process as the CLI would, and prints how long the refusal took, the
process's peak memory and the message, as a Markdown table.

    python -m boids_env.bench.small_files

Each file is read in its own ``python`` process with its address space capped at 3 GB
(RLIMIT_AS), so a regression shows as a MemoryError rather than eating the machine.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

CAP = 3_000_000_000
"""Address-space cap (bytes) of each measuring process."""

PROBE = textwrap.dedent("""
    import resource, sys, time
    resource.setrlimit(resource.RLIMIT_AS, ({cap}, {cap}))
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "scene":
        from boids_env.world.scenes import load_scene as read
    elif kind == "suite":
        from boids_env.eval.suites import load_suite as read
    elif kind == "recipe":
        from boids_env.train.config import TrainConfig
        read = TrainConfig.from_toml
    elif kind == "model":
        from boids_env.policies.registry import check_policy_spec as read
    else:
        from boids_env.world.walks import read_walk as read
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    start = time.perf_counter()
    try:
        read(path)
        outcome = "accepted"
    except (ValueError, TypeError, FileNotFoundError) as exc:
        outcome = str(exc)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{{seconds:.3f}}\t{{before:.0f}}\t{{peak:.0f}}\t{{len(outcome)}}\t{{outcome[:160]}}")
""")


def _laughs(levels: int) -> str:
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, levels + 1):
        lines.append(f"l{k}: &l{k} [" + ", ".join([f"*l{k - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def write_files(folder: Path) -> list[tuple[str, str, Path]]:
    """The issue's small files in ``folder``: ``(what, kind, path)`` each."""
    import numpy as np
    from PIL import Image

    Image.fromarray(np.full((10, 10), 254, dtype=np.uint8)).save(folder / "free.pgm")
    files = []

    def add(what: str, kind: str, name: str, text: str | None = None) -> None:
        if text is not None:
            (folder / name).write_text(text)
        files.append((what, kind, folder / name))

    add("map YAML, 'billion laughs' (9 levels of aliases)", "scene", "laughs.yaml",
        "image: free.pgm\norigin: [0, 0, 0]\n" + _laughs(8) + "resolution: *l8\n")
    add("map YAML whose bad field is an alias of 9^6 values", "scene", "message.yaml",
        "image: free.pgm\norigin: [0, 0, 0]\n" + _laughs(5) + "resolution: *l5\n")
    add("`resolution: 100` on a 10 × 10 image", "scene", "huge_cells.yaml",
        "image: free.pgm\nresolution: 100\norigin: [-500, -500, 0]\n")
    y, x = np.mgrid[0:4096, 0:4096]
    Image.fromarray(np.where((x + y) % 2, 0, 254).astype(np.uint8)).save(
        folder / "checker.png", optimize=True)
    add("4096² checkerboard PNG", "scene", "checker.yaml",
        "image: checker.png\nresolution: 0.05\norigin: [-102.4, -102.4, 0]\n")
    add("shapes file with a ±1000 m box", "scene", "box.toml",
        "box = [-1000.0, -1000.0, 1000.0, 1000.0]\n[[circle]]\ncenter = [1.0, 1.0]\n"
        "radius = 0.1\n")
    os.symlink("/dev/zero", folder / "zero.yaml")
    add("`map.yaml` symlinked to /dev/zero", "scene", "zero.yaml")
    os.mkfifo(folder / "fifo.yaml")
    add("a FIFO as a map", "scene", "fifo.yaml")
    add("suite with 20,000 identical cases", "suite", "cases.toml",
        'seeds = 1\n[[factor]]\nname = "robots"\nlevels = [' + ",".join(["13"] * 20_000) + "]\n")
    add("suite nested 3000 deep", "suite", "deep.toml",
        "seeds = " + "[" * 3000 + "]" * 3000 + "\n")
    add("suite with a 300-character case name", "suite", "long.toml",
        f'seeds = 1\n[[case]]\nname = "{"x" * 300}"\n')
    add("recipe with n_steps = 1e12", "recipe", "steps.toml", "n_steps = 1000000000000\n")
    add("recipe with a 64 × 4096 network", "recipe", "net.toml",
        "net_arch = [" + ", ".join(["4096"] * 64) + "]\n")
    os.symlink("/dev/zero", folder / "model.zip")
    add("`model.zip` symlinked to /dev/zero", "model", "model.zip")
    add("`leader_trajectory=/etc/passwd`", "walk", "/etc/passwd")
    return files


def main() -> None:
    if sys.argv[1:2] == ["--write"]:  # in a process of its own: see below
        print(json.dumps([(what, kind, str(path)) for what, kind, path in
                          write_files(Path(sys.argv[2]))]))
        return
    print("| small file | size | refused in | peak memory (after imports → after refusal) "
          "| message |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        # written by another process: Linux carries a process's peak memory over to the
        # processes it starts, and drawing the 4096² image would inflate every figure
        written = subprocess.run([sys.executable, "-m", "boids_env.bench.small_files",
                                  "--write", tmp], capture_output=True, text=True, check=True)
        for what, kind, name in json.loads(written.stdout):
            path = Path(name)
            size = path.lstat().st_size
            if path.name == "checker.yaml":
                size += (path.parent / "checker.png").stat().st_size
            done = subprocess.run([sys.executable, "-c", PROBE.format(cap=CAP), kind,
                                   str(path)], capture_output=True, text=True, timeout=300)
            if done.returncode != 0:
                tail = done.stderr.strip().splitlines()[-1:] or ["?"]
                print(f"| {what} | {size:,} B | failed | | {tail[0][:120]} |")
                continue
            seconds, before, peak, length, message = done.stdout.strip().split("\t", 4)
            message = message.replace(tmp, "…").replace("|", "\\|")
            print(f"| {what} | {size:,} B | {float(seconds):.2f} s | {before} → {peak} MB | "
                  f"{message} ({length} characters) |")


if __name__ == "__main__":
    main()
