"""The wheel, installed outside the checkout, works from a folder holding a user's own
``train.py`` and ``eval.py`` (which must never be imported in place of ours)."""

import json
import os
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, env, timeout=600):
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False)
    assert proc.returncode == 0, f"{cmd}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    dist = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", str(dist), str(ROOT)], ROOT, os.environ)
    (path,) = dist.glob("boids_env-*.whl")
    return path


def test_the_wheel_has_one_top_level_name_and_all_its_data(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"boids_env"}, tops
    for needed in ("boids_env/train/recipes/ppo_safe.toml",
                   "boids_env/train/recipes/ppo_study.toml",
                   "boids_env/policies/models/ppo_safe.zip",
                   "boids_env/policies/models/ppo_safe_evaluations.csv",
                   "boids_env/policies/models/ppo_study.zip",
                   "boids_env/eval/data/study_runs.csv", "boids_env/eval/data/study_tukey.csv"):
        assert needed in names, needed
    for package in ("", "policies/", "eval/", "train/", "bench/"):
        assert f"boids_env/{package}py.typed" in names, package


@pytest.mark.slow
def test_installed_wheel_runs_every_command_beside_a_users_train_and_eval(wheel, tmp_path):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path, os.environ)
    py = venv / "bin" / "python"
    purelib = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()"
                         "['purelib'])"], tmp_path, os.environ).stdout.strip())
    # The fresh venv sees this venv's third-party packages (a plain path line: .pth files
    # there, such as the checkout's editable finder, are not processed), and only the wheel
    # of ours.
    (purelib / "deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    _run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
         tmp_path, os.environ)
    work = tmp_path / "project"
    work.mkdir()
    for name in ("train.py", "eval.py", "policies.py", "bench.py"):
        (work / name).write_text(f"raise SystemExit('the user\\'s {name} was imported')\n")
    (work / "one.toml").write_text('name = "one"\nseeds = 2\n[[case]]\nname = "short"\n'
                                   'robots = 7\nmax_cycles = 30\n')
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(SDL_VIDEODRIVER="dummy", PATH=f"{venv / 'bin'}{os.pathsep}{env['PATH']}")
    boids = str(venv / "bin" / "boids")
    located = _run([str(py), "-c", "import boids_env.train.config as c, boids_env.eval.report; "
                    "print(c.__file__)"], work, env).stdout
    assert str(venv) in located and str(ROOT) not in located, located
    _run([boids, "run", "--robots", "7", "--max-cycles", "30", "--out", "r1"], work, env)
    assert json.loads((work / "r1" / "metrics.json").read_text())["steps"] == 30
    _run([boids, "run", "--policy", "learned", "--max-cycles", "30", "--out", "r2"], work, env)
    _run([boids, "eval", "--suite", "one.toml", "--workers", "1", "--no-progress",
          "--out", "e"], work, env)
    assert (work / "e" / "report.html").is_file()
    _run([boids, "train", "--config", "ppo_safe", "--timesteps", "1000", "--copies", "1",
          "--group-sizes", "5", "--eval-every", "0", "--checkpoint-every", "0",
          "--no-progress", "--out", "t"], work, env)
    assert (work / "t" / "model.zip").is_file()
    _run([str(py), "-m", "boids_env.bench", "--help"], work, env)
