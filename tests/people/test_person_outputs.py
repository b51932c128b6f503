"""The person and the crowd in every output: the table, recordings, videos, bags, suites."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.eval.episode import run_episode
from boids_env.eval.run import metrics_table
from boids_env.policies import ReynoldsPolicy
from boids_env.recording import Recording


@pytest.fixture(scope="module")
def crowded():
    env = parallel_env(scene="doorway", leader="person", crowd=3, robots=4, max_cycles=40)
    return run_episode(env, ReynoldsPolicy(), seed=2)


def test_the_table_prints_the_proxemics(crowded):
    table = metrics_table(crowded.metrics)
    for key in ("intimate_fraction", "person_contacts", "cut_in_fraction",
                "pedestrian_contacts"):
        assert key in table, key
    assert "intimate_fraction" not in metrics_table(
        run_episode(parallel_env(robots=3, max_cycles=5), ReynoldsPolicy(), seed=0).metrics)


def test_a_crowd_round_trips_through_parquet(crowded, tmp_path):
    rec = crowded.recording
    assert rec.pedestrians is not None and rec.pedestrians.shape == (41, 3, 2)
    rec.to_parquet(tmp_path / "t.parquet")
    back = Recording.from_parquet(tmp_path / "t.parquet")
    assert np.array_equal(back.pedestrians, rec.pedestrians)
    assert np.array_equal(back.positions, rec.positions)
    assert back.metrics()["pedestrian_contacts"] == crowded.metrics["pedestrian_contacts"]


def test_frames_draw_the_person_and_the_pedestrians(crowded):
    pytest.importorskip("pygame")
    from boids_env import style
    from boids_env.render import Frame, Renderer

    rec = crowded.recording
    renderer = Renderer("rgb_array", rec.config.scene)
    frame = renderer.draw(Frame(rec.positions[-1], 40, 0.036, leader_radius=0.22,
                                pedestrians=rec.pedestrians[-1]))
    person = renderer.to_px(rec.positions[-1][:1])[0]
    assert tuple(frame[person[1], person[0]]) == style.PERSON
    walker = renderer.to_px(rec.pedestrians[-1][:1])[0]
    assert tuple(frame[walker[1], walker[0]]) == style.PEDESTRIAN


def test_bags_carry_the_persons_odometry_and_the_people(crowded, tmp_path):
    pytest.importorskip("rosbags")
    from pathlib import Path

    from rosbags.highlevel import AnyReader

    from boids_env.rosbag import write_bag

    write_bag(crowded.recording, tmp_path / "p.bag", start=1.0e9)
    seen: dict[str, list] = {}
    with AnyReader([Path(tmp_path / "p.bag")]) as reader:
        wanted = [c for c in reader.connections
                  if c.topic in ("/person/odom", "/robot_0/odom", "/markers/people")]
        for conn, _, raw in reader.messages(wanted):
            seen.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    person, robot0 = seen["/person/odom"], seen["/robot_0/odom"]
    assert len(person) == len(robot0) == 41
    assert person[-1].child_frame_id == "person"
    assert person[-1].pose.pose.position.x == robot0[-1].pose.pose.position.x
    people = seen["/markers/people"][-1].markers
    assert [m.ns for m in people] == ["person", "pedestrians", "pedestrians", "pedestrians"]
    assert people[1].pose.position.x == crowded.recording.pedestrians[-1][0][0]
    assert people[1].scale.x == pytest.approx(0.44)


def test_the_person_suite_asks_the_studys_questions():
    from boids_env.eval.suites import SUITES

    suite = SUITES["person"]
    assert set(suite.groups) == {"speed", "group_size", "crowd"}
    speeds = [c.env["leader_speed"] for c in suite.groups["speed"]]
    assert speeds == [0.4, 0.5, 0.6, 0.75]
    assert all(c.env["leader"] == "person" and c.env["scene"] == "doorway"
               for c in suite.cases)


def test_boids_run_takes_the_person_flags_and_set(tmp_path, capsys):
    import json

    from boids_env.train.cli import main

    short = ["--robots", "4", "--max-cycles", "15", "--scene", "doorway"]
    assert main(["run", "--leader-trajectory", "doorway_walk", *short,
                 "--out", str(tmp_path / "walk")]) == 0
    config = json.loads((tmp_path / "walk" / "config.json").read_text())
    assert config["env"]["scenario"]["leader"] == "trajectory"
    assert main(["run", "--leader", "person", "--crowd", "2", *short,
                 "--out", str(tmp_path / "person")]) == 0
    assert "pedestrian_contacts" in capsys.readouterr().out
    assert main(["run", "--set", "leader=person", "--set", "crowd=1", *short,
                 "--out", str(tmp_path / "set")]) == 0
    metrics = json.loads((tmp_path / "set" / "metrics.json").read_text())
    assert "intimate_fraction" in metrics and "pedestrian_contacts" in metrics
    assert main(["run", "--leader", "person", "--set", "crowd=-1", *short,
                 "--out", str(tmp_path / "bad")]) == 2
    assert "crowd must be in [0, 500]" in capsys.readouterr().err


def test_the_person_learned_suite_has_trained_and_unseen_cases():
    from boids_env.config import EnvConfig
    from boids_env.eval.suites import SUITES

    suite = SUITES["person_learned"]
    assert [len(suite.groups[g]) for g in ("trained", "unseen")] == [3, 2]
    for case in suite.cases:
        EnvConfig.from_kwargs(**case.env)  # every case is a valid config
