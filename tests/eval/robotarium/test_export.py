"""``boids export robotarium``: the exported script run against the stand-in rps (its
rejection rules), and the same case in our env first."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from boids_env.eval.robotarium.case import RobotariumCase
from boids_env.eval.robotarium.script import write_script
from boids_env.train.cli import main

SUBMIT = Path(__file__).parent / "stand_in_rps" / "submit.py"


def submit(script, tmp_path):
    report = tmp_path / "report.json"
    done = subprocess.run([sys.executable, str(SUBMIT), str(script), str(report)],
                          capture_output=True, text=True, timeout=120)
    return done.returncode, json.loads(report.read_text()), done.stdout + done.stderr


@pytest.mark.parametrize("robots", [7, 13, 19])
def test_the_studys_groups_run_on_the_stand_in_without_rejection(robots, tmp_path):
    script = write_script(RobotariumCase(robots=robots, seconds=30.0), tmp_path / "s.py",
                          figure=False)
    rc, report, out = submit(script, tmp_path)
    assert rc == 0 and not report["errors"], (robots, report, out)
    assert report["iterations"] == 910 and report["min_distance"] > 0.135, report
    assert report["max_abs_x"] < 1.6 and report["max_abs_y"] < 1.0, report


def test_the_script_imports_numpy_math_and_rps_only(tmp_path):
    import ast

    source = write_script(RobotariumCase(), tmp_path / "s.py").read_text()
    names = {a.name.split(".")[0] for n in ast.walk(ast.parse(source))
             if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module.split(".")[0] for n in ast.walk(ast.parse(source))
              if isinstance(n, ast.ImportFrom)}
    assert names == {"math", "numpy", "rps"}, names


def test_the_stand_in_rejects_a_script_that_drives_too_fast(tmp_path):
    script = write_script(RobotariumCase(robots=7, seconds=5.0), tmp_path / "s.py",
                          figure=False)
    fast = tmp_path / "fast.py"
    text = script.read_text().replace("dxu = wheel_limited(", "dxu = 2.0 * wheel_limited(")
    fast.write_text(text)
    rc, report, _ = submit(fast, tmp_path)
    assert rc == 1 and report["errors"].get("exceeded_actuator_limits", 0) > 0, report


def test_the_stand_in_refuses_an_import_the_robotarium_lacks(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy as np\nimport boids_env\n")
    rc, report, _ = submit(bad, tmp_path)
    assert rc == 3 and report["disallowed_imports"] == ["boids_env"], report


def test_more_than_20_robots_is_refused_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "s.py"
    assert main(["export", "robotarium", "--out", str(out), "--robots", "21"]) == 2
    assert "robots must be in [2, 20]" in capsys.readouterr().err
    assert not out.exists()


def test_the_command_writes_the_script(tmp_path):
    out = tmp_path / "s.py"
    assert main(["export", "robotarium", "--out", str(out), "--robots", "7"]) == 0
    assert "r.set_velocities(np.arange(N), dxu)" in out.read_text()


def test_the_same_case_in_our_env_stays_inside_and_apart():
    import dataclasses

    from boids_env.environment import BoidsEnv
    from boids_env.policies import ReynoldsPolicy

    case = RobotariumCase(robots=13)
    env = BoidsEnv(case.env_config(max_cycles=600))
    p = case.reynolds()
    policy = ReynoldsPolicy(**{f.name: getattr(p, f.name) for f in dataclasses.fields(p)})
    policy.bind(env)
    obs, _ = env.reset(seed=0)
    step = 0
    while env.agents:
        actions = policy.act_batch(np.stack([obs[k] for k in env.agents]))
        obs, *_ = env.step({k: actions[i] for i, k in enumerate(env.agents)})
        s = env.snapshot()
        centres = s.positions + 0.025 * np.stack([np.cos(s.headings), np.sin(s.headings)], 1)
        d = np.sqrt(((centres[:, None] - centres[None]) ** 2).sum(-1))
        d[np.diag_indices(len(d))] = np.inf
        assert d.min() > 0.135 and not len(s.contacts), (step, d.min())
        assert np.all(np.abs(s.positions) < [1.6, 1.0]), (step, s.positions)
        step += 1
    assert step == 600
