"""ROS stays optional: nothing imports rospy until a node starts, the system's ROS packages are
appended behind the virtualenv's, and a missing ROS says what to install."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from boids_env.eval.ros import rospy_path


def _python(code: str, **env: str) -> str:
    import os

    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=120, env={**os.environ, **env}, check=False)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_importing_the_package_and_the_ros_modules_needs_no_rospy():
    out = _python("""
        import sys
        import boids_env, boids_env.eval.cli, boids_env.train.cli
        import boids_env.eval.ros.sim, boids_env.eval.ros.controller, boids_env.eval.ros.bags
        import boids_env.eval.graph.protocol, boids_env.eval.ros.reconfigure
        print(sorted(m for m in ("rospy", "genpy", "rosgraph") if m in sys.modules))
    """)
    assert out.strip() == "[]", out


def test_system_ros_packages_are_appended_behind_the_virtualenvs(tmp_path):
    # a fake ROS install: rospy, the message packages, and a numpy that must never win
    for name in ("rospy", "numpy", *(m.split(".")[0] for m in rospy_path.MESSAGE_MODULES)):
        (tmp_path / name).mkdir(exist_ok=True)
        (tmp_path / name / "__init__.py").write_text("FAKE = True\n")
    for module in rospy_path.MESSAGE_MODULES:
        (tmp_path / module.split(".")[0] / "msg.py").write_text("")
    out = _python("""
        import json, sys
        from boids_env.eval.ros.rospy_path import import_rospy
        before = list(sys.path)
        rospy = import_rospy()
        import numpy
        print(json.dumps({"rospy": rospy.__file__, "last": sys.path[-1],
                          "added": [p for p in sys.path if p not in before],
                          "numpy_fake": hasattr(numpy, "FAKE")}))
    """, BOIDS_ROS_PYTHONPATH=str(tmp_path), PYTHONPATH="")
    result = json.loads(out)
    if not result["added"]:
        pytest.skip("rospy is importable without the search path here (ROS on PYTHONPATH)")
    assert result["added"] == [str(tmp_path)] and result["last"] == str(tmp_path), result
    assert result["rospy"].startswith(str(tmp_path)), result
    assert not result["numpy_fake"], "the system folder must not shadow the venv's numpy"


def test_missing_ros_names_the_packages_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rospy", None)  # `import rospy` fails
    monkeypatch.setattr(rospy_path, "DEFAULT_FOLDERS", ())
    monkeypatch.setenv(rospy_path.SEARCH_PATH_VARIABLE, str(tmp_path))
    with pytest.raises(rospy_path.MissingRosError) as err:
        rospy_path.import_rospy()
    message = str(err.value)
    assert "apt-get install ros-core python3-rospy" in message and "Noetic" in message
    assert str(tmp_path) in message


def test_boids_ros_without_ros_is_a_clear_error(tmp_path):
    import os

    code = """
        import sys
        sys.modules["rospy"] = None
        from boids_env.eval.ros import rospy_path
        rospy_path.DEFAULT_FOLDERS = ()
        from boids_env.train.cli import main
        sys.exit(main(["ros", "sim", "--max-cycles", "5"]))
    """
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=120, check=False,
                          env={**os.environ, rospy_path.SEARCH_PATH_VARIABLE: str(tmp_path)})
    assert proc.returncode == 2, proc.stderr
    assert "boids ros: error:" in proc.stderr and "python3-rospy" in proc.stderr, proc.stderr
