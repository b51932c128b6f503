"""The contributors' page's examples run, and each does what the page says with the files it
says: a new drive and a new leader kind are one class registered, every other part of the
code asks the object. Each runs in a subprocess: registering a kind is global to a process."""

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SNIPPETS = ROOT / "docs" / "snippets"


def _run(snippet: str, checks: str) -> str:
    code = f"import runpy\nns = runpy.run_path({str(SNIPPETS / snippet)!r})\n" + \
        textwrap.dedent(checks)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, env={"SDL_VIDEODRIVER": "dummy", "PATH": "/usr/bin"})
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_a_new_drive_is_one_registered_class_the_env_runs():
    out = _run("new_drive.py", """
        import numpy as np, pytest
        from boids_env import BoidsEnv, EnvConfig
        # below the band nothing moves; above it the robots move as a holonomic one does
        env, plain = BoidsEnv(robots=4, drive="dead_band"), BoidsEnv(robots=4)
        for e in (env, plain):
            e.reset(seed=1)
        for _ in range(20):
            for e in (env, plain):
                e.step({a: np.array([0.3, 0.0]) for a in e.agents})
        assert np.array_equal(env.snapshot().positions, plain.snapshot().positions)
        assert not env.config.world.has_heading
        # its own check runs when a config is built, naming the field
        try:
            EnvConfig.from_kwargs(drive="dead_band", max_speed=0.01)
        except ValueError as exc:
            assert "max_speed above 0.02" in str(exc), exc
        else:
            raise AssertionError("max_speed=0.01 was accepted")
        print("checked")
    """)
    assert "moved 0.000 m/s at most" in out and "checked" in out, out


def test_a_new_leader_kind_is_one_registered_object_every_part_asks():
    out = _run("new_leader_kind.py", """
        import numpy as np
        from boids_env import BoidsEnv
        env = BoidsEnv(robots=7, leader="wheelchair", max_cycles=60)
        env.reset(seed=0)
        # the world gives robot 0 the kind's body; the observer's lidar sees that disc
        world = env.episode.world
        shapes = [s for s in world.space.shapes if getattr(s, "body", None) is world._robots[0]]
        assert [round(s.radius, 6) for s in shapes] == [0.35], shapes
        assert env.episode.observer.sensors.leader_radius == 0.35
        for _ in range(60):
            env.step({a: np.zeros(2) for a in env.agents})
        from boids_env.policies.cards import leader_words
        assert leader_words("wheelchair") == "a wheelchair user"
        print("checked")
    """)
    assert "a wheelchair user of radius 0.35 m" in out and "checked" in out, out


def test_a_new_suite_is_a_toml_file_the_runner_takes(tmp_path):
    from boids_env.eval.runner import PolicySpec, run_suite
    from boids_env.eval.suites import load_suite

    suite = load_suite(SNIPPETS / "new_suite.toml")
    assert suite.name == "doorway_speeds"
    assert [c.name for c in suite.cases] == ["leader_speed=0.4", "leader_speed=0.5",
                                            "crowded doorway"], suite.cases
    table = run_suite([PolicySpec("reynolds")], suite, tmp_path / "out", backend="inline",
                      progress=False)
    assert len(table) == 3 * 2, table  # cases × seeds, one row each
    assert (table["steps"] == 60).all(), table["steps"]
    robots = {c.name: c.env["robots"] for c in suite.cases}
    assert robots == {"leader_speed=0.4": 7, "leader_speed=0.5": 7, "crowded doorway": 13}
    assert {c.name: c.env["scene"] for c in suite.cases} == dict.fromkeys(robots, "doorway")
