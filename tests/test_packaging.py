"""The wheel, installed outside the checkout, works from a folder holding a user's own
``train.py`` and ``eval.py`` (which must never be imported in place of ours)."""

import functools
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
                   "boids_env/eval/data/study_runs.csv", "boids_env/eval/data/study_tukey.csv",
                   "boids_env/world/data/lab.yaml", "boids_env/world/data/lab.pgm",
                   "boids_env/world/data/doorway_walk.csv"):
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


def _requirements() -> dict[str, list[str]]:
    """pyproject.toml's requirements: the core ones under "" and each extra's by its name."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return {"": project["dependencies"], **project["optional-dependencies"]}


def _closure(specs: list[str]) -> set[str]:
    """The normalized names of the distributions ``specs`` install (their own requirements
    followed through this environment's metadata); ``boids-env[...]`` expands to its extras."""
    from importlib import metadata

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    own = _requirements()
    seen: set[str] = set()
    expanded: set[str] = set()  # our own extras already followed
    todo = [(Requirement(s), "") for s in specs]
    while todo:
        req, extra = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": extra}):
            continue
        name = canonicalize_name(req.name)
        if name == "boids-env":
            todo += [(Requirement(s), "") for e in sorted(req.extras - expanded)
                     for s in own[e]]
            expanded |= req.extras
            continue
        if name in seen:
            continue
        seen.add(name)
        try:
            needs = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        todo += [(Requirement(s), e) for s in needs for e in ("", *req.extras)]
    return seen


ROS1 = {"rospy", "rosgraph", "rosgraph_msgs", "geometry_msgs", "nav_msgs", "tf2_msgs",
        "visualization_msgs", "dynamic_reconfigure"}
"""ROS 1's own Python packages (apt, not PyPI): the ros extra's live nodes only."""
SCENE_MODULES = ("world/maps.py", "world/scenes.py", "world/scene.py", "world/shapes.py")
"""The core's scene code: maps and the built-in scenes (``lab`` is a map) need no extra."""


def _third_party(path: Path) -> set[str]:
    """Top-level names of the third-party modules ``path`` imports (inside functions too)."""
    import ast

    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found.add(node.module.split(".")[0])
    return {n for n in found if n not in sys.stdlib_module_names and n != "boids_env"} - ROS1


@functools.cache
def _packages_distributions() -> dict[str, list[str]]:
    """importlib's map of top-level modules to distributions, built once (it reads every
    installed distribution's file list)."""
    from importlib import metadata

    return metadata.packages_distributions()


def _distributions(module: str) -> set[str]:
    from packaging.utils import canonicalize_name

    dists = _packages_distributions().get(module)
    assert dists, f"{module} is imported by the package but installed by no distribution here"
    return {canonicalize_name(d) for d in dists}


def test_every_module_the_core_imports_is_declared():
    """Each third-party module the core imports comes with a declared requirement (core or
    an extra); the scene code's with the core requirements alone, so ``pip install -e
    .[render]`` (the README's first install) runs ``boids scenes`` and ``--scene lab``."""
    reqs = _requirements()
    core = _closure(reqs[""])
    everything = _closure([s for specs in reqs.values() for s in specs])
    for path in sorted((ROOT / "boids_env").rglob("*.py")):
        rel = path.relative_to(ROOT / "boids_env").as_posix()
        allowed = core if rel in SCENE_MODULES else everything
        for module in sorted(_third_party(path)):
            assert _distributions(module) & allowed, (
                f"boids_env/{rel} imports {module}, which "
                f"{'no core requirement' if rel in SCENE_MODULES else 'no requirement'} "
                f"in pyproject.toml installs")


@pytest.mark.slow
def test_a_fresh_venv_with_the_render_extra_runs_the_scenes_and_my_map(wheel, tmp_path):
    """The README's first install (the render extra) and nothing else: the built-in scenes,
    ``lab`` (a ROS map) among them, and a user's own map as ``map_saver -f /abs/path`` saves
    it (an absolute image path). Installs from the package index (about a minute with pip's
    cache)."""
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path, os.environ)
    _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", f"{wheel}[render]"],
         tmp_path, os.environ)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(SDL_VIDEODRIVER="dummy", PATH=f"{venv / 'bin'}{os.pathsep}{env['PATH']}")
    boids = str(venv / "bin" / "boids")
    assert "lab" in _run([boids, "scenes"], tmp_path, env).stdout
    _run([boids, "run", "--scene", "lab", "--seed", "0", "--max-cycles", "20", "--out", "lab"],
         tmp_path, env)
    assert json.loads((tmp_path / "lab" / "metrics.json").read_text())["steps"] == 20
    mine = tmp_path / "maps"
    mine.mkdir()
    shipped = ROOT / "boids_env" / "world" / "data"
    (mine / "office.pgm").write_bytes((shipped / "lab.pgm").read_bytes())
    (mine / "office.yaml").write_text((shipped / "lab.yaml").read_text().replace(
        "image: lab.pgm", f"image: {mine / 'office.pgm'}"))
    _run([boids, "run", "--map", str(mine / "office.yaml"), "--start=-3.5,-2.5",
          "--waypoints", "-3.5,2 0.5,2", "--seed", "0", "--max-cycles", "20", "--out", "mine"],
         tmp_path, env)
    assert json.loads((tmp_path / "mine" / "metrics.json").read_text())["steps"] == 20
