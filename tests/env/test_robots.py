"""Robot models: presets in the config, the unicycle's physics (no sideways slip, bounded
turn rate and speed, rigid contacts with robots, walls and obstacles), the drivers' law and
the native (v, ω) actions."""

import math
import pickle

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.config import EnvConfig, WorldConfig
from boids_env.world import robots
from boids_env.world.space import World


def unit(angles):
    return np.stack([np.cos(angles), np.sin(angles)], axis=-1)


# ----------------------------------------------------------------------------- config
def test_choosing_a_robot_sets_its_fields_and_scales_the_study_case():
    cfg = EnvConfig.from_kwargs(robot="turtlebot3_burger")
    w, sc = cfg.world, cfg.scenario
    assert (w.robot_radius, w.robot_mass, w.max_speed, w.drive_force) == (0.105, 1.0, 0.22, 2.5)
    assert (w.drive, w.max_turn_rate, w.max_turn_acceleration) == ("unicycle", 2.84, 3.2)
    assert sc.leader_speed == 0.242, "1.1 x the top speed, as 0.55 = 1.1 x 0.5"
    assert sc.layout_spacing == 0.638, "the study's 0.428 m gap plus a 0.21 m diameter"


def test_the_study_sphero_preset_is_exactly_the_default_config():
    assert EnvConfig.from_kwargs(robot="sphero") == EnvConfig()


def test_fields_given_with_the_robot_win_and_later_changes_keep_the_robot():
    cfg = EnvConfig.from_kwargs(robot="gritsbot", leader_speed=0.3, max_speed=0.15)
    assert cfg.scenario.leader_speed == 0.3
    assert cfg.world.max_speed == 0.15
    assert cfg.scenario.layout_spacing == round(robots.STUDY_GAP + 0.11, 9)
    assert cfg.replace(robots=7).world == cfg.world  # no robot given: nothing re-applied
    derived = EnvConfig.from_kwargs(robot="gritsbot", max_speed=0.15)
    assert derived.scenario.leader_speed == round(1.1 * 0.15, 9), "scaled to the given speed"


def test_a_saved_robot_config_round_trips():
    cfg = EnvConfig.from_kwargs(robot="turtlebot3_burger", leader_speed=0.2)
    assert EnvConfig.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize(("fields", "message"), [
    ({"robot": "roomba"}, "robot must be one of"),
    ({"drive": "tank"}, "drive must be one of"),
    ({"drive": "unicycle"}, "needs max_turn_rate"),
    ({"velocity_law": "skid"}, "velocity_law must be one of"),
    ({"robot": "turtlebot3_burger", "max_turn_rate": -1.0}, "max_turn_rate must be in"),
    ({"robot": "turtlebot3_burger", "heading_gain": 20.0}, "heading_gain × dt must be at most"),
    ({"robot": "turtlebot3_burger", "max_turn_rate": 30.0}, "use substeps >= 15"),
    ({"action": "unicycle"}, "this robot is holonomic"),
    ({"action": "drive"}, "action must be one of"),
    ({"robot": "gritsbot", "action": "unicycle", "relative_actions": True}, "use one of them"),
    ({"robot": "gritsbot", "action": "unicycle", "realism": "ros"}, "action='velocity'"),
])
def test_bad_robot_fields_are_refused_by_name(fields, message):
    with pytest.raises(ValueError, match=message):
        EnvConfig.from_kwargs(**fields)


# ------------------------------------------------------------------------------- law
def test_the_turn_and_drive_law_on_hand_computed_commands():
    model = robots.Unicycle(WorldConfig(drive="unicycle", max_turn_rate=2.0))
    heading = np.tile([1.0, 0.0], (6, 1))  # every robot faces +x
    u = np.array([[0.2, 0.0], [0.0, 0.2], [-0.2, 0.0], [0.1, 0.1], [0.1, -0.1], [0.0, 0.0]])
    v, w = model.native(u, heading).T
    np.testing.assert_allclose(v, [0.2, 0.0, 0.0, 0.1, 0.1, 0.0], atol=1e-15)
    # k = max_turn_rate: 2·sin 90° = 2 (left), behind: full rate (left), ±45°: 2·sin 45°
    np.testing.assert_allclose(w, [0.0, 2.0, 2.0, math.sqrt(2), -math.sqrt(2), 0.0],
                               atol=1e-15)


def test_the_roll_law_keeps_the_commanded_speed_while_turning():
    model = robots.Unicycle(WorldConfig(drive="unicycle", max_turn_rate=2.0, heading_gain=5.0,
                                        velocity_law="roll"))
    v, w = model.native(np.array([[0.0, 0.3], [0.0, -0.01]]), np.array([[1.0, 0.0]] * 2)).T
    np.testing.assert_allclose(v, [0.3, 0.01])
    np.testing.assert_allclose(w, [2.0, -2.0])  # 5·sin 90° = 5, clipped to the rate


def test_odometry_headings_and_velocities_round_trip_as_a_ros_message_does():
    rng = np.random.default_rng(0)
    h = unit(rng.uniform(-math.pi, math.pi, 50))
    h[0] = [-1.0, 0.0]  # the half-angle formula's worst case
    q = robots.quaternions(h)
    assert np.allclose(q[:, 0] ** 2 + q[:, 1] ** 2, 1.0)
    np.testing.assert_allclose(robots.quaternion_headings(q[:, 0], q[:, 1]), h, atol=1e-7)
    v = rng.normal(size=(50, 2))
    body = robots.to_body(v, h)
    np.testing.assert_allclose(body[:, 0], (v * h).sum(axis=1), atol=1e-15)
    np.testing.assert_allclose(robots.to_world(body, h), v, atol=1e-15)


def test_the_small_angle_rotation_matches_the_c_library():
    phi = np.linspace(-robots.MAX_TURN_PER_SUBSTEP, robots.MAX_TURN_PER_SUBSTEP, 101)
    c, s = robots.rotation_terms(phi)
    assert np.max(np.abs(c - np.cos(phi))) < 2e-16
    assert np.max(np.abs(s - np.sin(phi))) < 2e-16


# --------------------------------------------------------------------------- physics
CASES = [("turtlebot3_burger", "arena", "velocity"), ("turtlebot3_burger", "small_room",
                                                      "unicycle"),
         ("turtlebot3_burger", "pillars", "velocity"), ("gritsbot", "arena", "unicycle"),
         ("sphero_sprk", "pillars", "velocity")]


@pytest.mark.parametrize(("robot", "scene", "action"), CASES)
def test_random_commands_keep_every_limit_for_1000_steps(robot, scene, action):
    """19 robots, a random command each step (50 % beyond the limits), 1,000 steps: the turn
    rate never exceeds its limit, no robot slips sideways (1 cm/s) or overlaps another by
    more than 5 mm, and a robot that touches nothing keeps within 2 % of its top speed (a
    robot pushed by another can be pushed faster than its drive: that is measured too)."""
    e = parallel_env(robot=robot, scene=scene, robots=19, path="external", startup_time=0.0,
                     max_cycles=10**6, action=action)
    e.reset(seed=1)
    rng = np.random.default_rng(1)
    w = e.config.world
    box = e.action_space("follower_1")
    before = e.snapshot()
    pushed = 0.0
    for step in range(1000):
        angle = rng.uniform(0, 2 * math.pi, 19)
        u = unit(angle) * w.max_speed * 1.5
        e.set_leader_command(u[0] / 1.5)
        actions = (rng.uniform(1.5 * box.low, 1.5 * box.high, (18, 2)) if action == "unicycle"
                   else u[1:])
        e.step(dict(zip(e.agents, actions, strict=True)))
        snap = e.snapshot()
        turn = np.abs((snap.headings - before.headings + math.pi) % (2 * math.pi) - math.pi)
        assert turn.max() <= w.max_turn_rate * w.dt * 1.02, f"step {step}: turned {turn.max()}"
        h, v = unit(snap.headings), snap.velocities
        side = np.abs(h[:, 0] * v[:, 1] - h[:, 1] * v[:, 0])
        assert side.max() < 0.01, f"step {step}: robot {side.argmax()} slips {side.max()} m/s"
        gaps = np.linalg.norm(snap.positions[:, None] - snap.positions[None], axis=-1)
        gaps[np.diag_indices(19)] = np.inf
        assert 2 * w.robot_radius - gaps.min() <= 0.005, f"step {step}: overlap"
        assert np.all(e.config.scene.clearance(snap.positions) > w.robot_radius - 0.005), step
        free = np.ones(19, bool)
        for s in (snap, before):
            free[s.contacts.ravel()] = False
            free[s.wall_contacts] = False
        free[0] = False  # the leader drives its own speed
        speed = np.hypot(snap.velocities[:, 0], snap.velocities[:, 1])
        assert np.all(speed[free] <= w.max_speed * 1.02), f"step {step}: {speed[free].max()}"
        pushed = max(pushed, float(speed[1:].max()) / w.max_speed)
        before = snap
    assert pushed < 1.3, f"a pushed robot reached {pushed:.2f}x its top speed"


def test_a_unicycle_drives_along_its_heading_and_turns_at_its_rate():
    cfg = WorldConfig(robot="turtlebot3_burger", drive="unicycle", max_turn_rate=2.84,
                      max_turn_acceleration=3.2, robot_radius=0.105, robot_mass=1.0,
                      max_speed=0.22, drive_force=2.5)
    world = World(cfg, [[0.0, 0.0]], headings=[math.pi / 2])
    for _ in range(20):  # forward at 0.2 m/s: straight up +y
        world.step(None, native=np.array([[0.2, 0.0]]))
    np.testing.assert_allclose(world.velocities[0], [0.0, 0.2], atol=1e-9)
    assert abs(world.positions[0, 0]) < 1e-12
    rates = []
    for _ in range(12):  # turn in place: the rate ramps by 0.32 rad/s a step to 2.84
        world.step(None, native=np.array([[0.0, 2.84]]))
        rates.append(float(world.angular_velocities[0]))
    np.testing.assert_allclose(rates[:3], [0.32, 0.64, 0.96])
    assert rates[-1] == pytest.approx(2.84, abs=1e-12)
    assert world.snapshot().native.tolist() == [[0.0, 2.84]]


def test_unicycle_episodes_are_deterministic_and_pickle_mid_episode():
    def run(env, steps):
        out = []
        for _ in range(steps):
            env.step({a: np.array([0.1, 0.05]) for a in env.agents})
            out.append(env.snapshot())
        return out

    a = parallel_env(robot="turtlebot3_burger", robots=7)
    b = parallel_env(robot="turtlebot3_burger", robots=7)
    a.reset(seed=3)
    b.reset(seed=3)
    run(a, 30)
    run(b, 30)
    c = pickle.loads(pickle.dumps(a))
    for k, (sa, sc) in enumerate(zip(run(a, 40), run(c, 40), strict=True)):
        assert np.array_equal(sa.positions, sc.positions), f"step {k}"
        assert np.array_equal(sa.headings, sc.headings), f"step {k}"
    assert np.array_equal(a.snapshot().positions, run(b, 40)[-1].positions)


def test_native_actions_are_clipped_to_the_robot_limits():
    e = parallel_env(robot="gritsbot", robots=3, action="unicycle", startup_time=0.0)
    box = e.action_space("follower_1")
    np.testing.assert_allclose(box.high, [0.2, 2 * 0.2 / 0.11], rtol=1e-6)
    e.reset(seed=0)
    for _ in range(5):
        heading = e.snapshot().headings[1:]
        e.step({a: np.array([9.0, -9.0]) for a in e.agents})
    native = e.snapshot().native
    np.testing.assert_allclose(native[1:], [[0.2, -2 * 0.2 / 0.11]] * 2, rtol=1e-6)
    # the command as cmd_vel carries it: v along the heading the robot had when commanded
    np.testing.assert_allclose(e.snapshot().commanded[1:], 0.2 * unit(heading), atol=1e-7)


# ----------------------------------------------------------------------- observations
def test_robots_with_a_heading_observe_headings_in_blocks_of_their_own():
    from boids_env.observations import ObservationLayout

    e = parallel_env(robot="turtlebot3_burger", robots=7, startup_time=0.0, horizon=1.0)
    default = parallel_env(robots=7)
    assert [b for b, _ in default.layout.blocks] == ["own_velocity", "leader_position",
                                                     "leader_velocity", "neighbours"]
    assert [b for b, _ in e.layout.blocks][4:] == ["own_heading", "leader_heading",
                                                   "neighbour_headings"]
    assert ObservationLayout.from_blocks(e.layout.blocks) == e.layout
    e.reset(seed=0)
    for _ in range(30):
        obs, *_ = e.step({a: np.array([0.1, 0.2]) for a in e.agents})
    snap = e.snapshot()
    rows = np.stack([obs[a] for a in e.agents])
    h = unit(snap.headings)
    np.testing.assert_allclose(rows[:, e.layout.block("own_heading")], h[1:], atol=1e-6)
    np.testing.assert_allclose(rows[:, e.layout.block("leader_heading")], np.tile(h[0], (6, 1)),
                               atol=1e-6)
    slots = e.layout.slots(rows)
    headings = e.layout.neighbour_headings(rows)
    valid = slots[..., 4] > 0.5
    assert valid.any() and (~valid).any(), "some slots full, some empty"
    assert np.all(headings[~valid] == 0.0)
    positions = snap.positions
    for f, k in zip(*np.nonzero(valid), strict=True):
        j = np.argmin(np.linalg.norm(positions - (positions[f + 1] + slots[f, k, :2]), axis=1))
        np.testing.assert_allclose(headings[f, k], h[j], atol=1e-6)
    assert all(o in e.observation_space(a) for a, o in obs.items())


def test_headings_turn_with_the_leader_frame():
    from boids_env.observations import ObservationLayout, build_observations, rotation

    rng = np.random.default_rng(0)
    positions = rng.uniform(-1, 1, (5, 2))
    velocities = rng.normal(size=(5, 2))
    headings = unit(rng.uniform(-math.pi, math.pi, 5))
    layout = ObservationLayout(4, headings=True)
    frame = rotation(0.7)
    plain = build_observations(positions, velocities, layout, 5.0, 3.0, 10.0, None, None,
                               headings=headings)
    turned = build_observations(positions, velocities, layout, 5.0, 3.0, 10.0, frame, None,
                                headings=headings)
    for name in ("own_heading", "leader_heading", "neighbour_headings"):
        block = layout.block(name)
        expected = (plain[:, block].reshape(4, -1, 2).astype(float) @ frame).reshape(4, -1)
        np.testing.assert_allclose(turned[:, block], expected, atol=1e-6)
    with pytest.raises(ValueError, match="give the headings"):
        build_observations(positions, velocities, layout, 5.0, 3.0, 10.0)


def test_the_reynolds_policy_adopts_the_robot_top_speed_unless_given():
    from boids_env.policies import ReynoldsPolicy

    env = parallel_env(robot="turtlebot3_burger")
    free, fixed = ReynoldsPolicy(), ReynoldsPolicy(max_speed=0.2)
    free.bind(env)
    fixed.bind(env)
    assert free.params.max_speed == 0.22
    assert fixed.params.max_speed == 0.2, "its own top speed, below the robot's, is kept"
    # faster than the robot goes: refused (issue 39 item 7), no longer kept silently
    with pytest.raises(ValueError, match=r"max_speed=0.4 m/s conflicts with the env's "
                                         r"max_speed=0.22 m/s"):
        ReynoldsPolicy(max_speed=0.4).bind(env)
    study = ReynoldsPolicy()
    study.bind(parallel_env())
    assert study.params == ReynoldsPolicy().params


# ------------------------------------------------------------ recordings and metrics
def test_a_unicycle_recording_keeps_headings_turn_rates_and_native_commands(tmp_path):
    from boids_env.eval.episode import run_episode
    from boids_env.policies import ReynoldsPolicy
    from boids_env.recording import HEADING_COLUMNS, Recording

    env = parallel_env(robot="turtlebot3_burger", robots=5, max_cycles=40)
    rec = run_episode(env, ReynoldsPolicy(), seed=0).recording
    assert rec.headings.shape == (41, 5) and rec.native.shape == (41, 5, 2)
    assert np.all(rec.native[0] == 0.0) and np.any(rec.native[-1] != 0.0)
    rec.to_parquet(tmp_path / "t.parquet")
    back = Recording.from_parquet(tmp_path / "t.parquet")
    for name in ("headings", "angular_velocities", "native", "positions", "commanded"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    assert back.metrics() == rec.metrics()
    plain = run_episode(parallel_env(robots=5, max_cycles=40), ReynoldsPolicy(), seed=0)
    plain.recording.to_parquet(tmp_path / "s.parquet")
    import pyarrow.parquet as pq

    columns = pq.read_table(tmp_path / "s.parquet").column_names
    assert not set(HEADING_COLUMNS) & set(columns), "the study's robots record no headings"


def test_alignment_on_measured_headings_by_hand():
    from boids_env.config import MetricsConfig
    from boids_env.metrics import heading_misalignment

    headings = np.array([[0.0, 0.9, -0.5], [3.1, -3.1, 3.1]])  # leader first
    flags = heading_misalignment(headings, MetricsConfig())
    assert flags.tolist() == [[True, False], [False, False]]  # 51.6° vs 28.6°; 4.8° wrapped
    study = heading_misalignment(headings, MetricsConfig(wrap_alignment=False))
    assert study.tolist() == [[True, False], [True, False]]  # 355° unwrapped


def test_the_heading_rule_is_reported_beside_the_study_rule_and_drives_the_reward():
    from boids_env.metrics import heading_misalignment

    env = parallel_env(robot="turtlebot3_burger", robots=5, alignment_source="heading",
                       startup_time=0.0)
    env.reset(seed=0)
    for step in range(20):
        *_, infos = env.step({a: np.array([0.0, 0.2 if step % 2 else -0.2])
                                            for a in env.agents})
        snap = env.snapshot()
        flags = heading_misalignment(snap.headings, env.config.metrics)
        got = [infos[a]["reward_alignment"] for a in env.agents]
        assert got == (-0.1 * flags).tolist(), f"step {step}"
    m = parallel_env(robot="turtlebot3_burger", robots=5, max_cycles=60)
    from boids_env.eval.episode import run_episode
    from boids_env.policies import ReynoldsPolicy

    metrics = run_episode(m, ReynoldsPolicy(), seed=0).metrics
    assert metrics["V_align"] == metrics["V_align_command"]
    assert "V_align_heading" in metrics and len(metrics["count_align_heading"]) == 4
    with pytest.raises(ValueError, match="holonomic and has none"):
        EnvConfig.from_kwargs(alignment_source="heading")


def test_robots_with_a_heading_are_drawn_with_a_mark_towards_it():
    from boids_env import style
    from boids_env.render import Frame, Renderer

    positions = np.array([[0.0, 0.0], [1.0, 0.0]])
    r = Renderer("rgb_array", 5.0, view="follow")
    plain = r.draw(Frame(positions, 5, 0.105))
    r = Renderer("rgb_array", 5.0, view="follow")
    marked = r.draw(Frame(positions, 5, 0.105, headings=np.array([0.0, math.pi / 2])))
    x, y = r.to_px(positions)[1]
    reach = r.robot_radius_px(0.105, 2)
    white = (np.abs(marked.astype(int) - style.HEADING).max(axis=-1) <= 10)
    assert white[y - reach + 2:y - 1, x - 1:x + 2].any(), "follower 1's mark points up (+y)"
    assert not white[y + 2:y + reach - 1, x - 1:x + 2].any(), "and not down"
    assert not (np.abs(plain.astype(int) - style.HEADING).max(axis=-1) <= 10)[
        y - reach + 2:y - 1, x - 1:x + 2].any(), "no mark without headings"


def test_a_turtlebot_bag_speaks_rep_105_and_reads_back_into_the_same_metrics(tmp_path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from boids_env.eval.episode import run_episode
    from boids_env.policies import ReynoldsPolicy
    from boids_env.rosbag import read_bag, write_bag

    env = parallel_env(robot="turtlebot3_burger", robots=5, max_cycles=120)
    rec = run_episode(env, ReynoldsPolicy(), seed=1).recording
    write_bag(rec, tmp_path / "t.bag", start=100.0)
    seen = {"cmd": [], "odom": []}
    with AnyReader([tmp_path / "t.bag"],
                   default_typestore=get_typestore(Stores.ROS1_NOETIC)) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/robot_2/cmd_vel":
                seen["cmd"].append((msg.linear.x, msg.linear.y, msg.angular.z))
            elif conn.topic == "/robot_2/odom":
                seen["odom"].append((msg.twist.twist.linear.x, msg.twist.twist.linear.y,
                                     msg.twist.twist.angular.z))
    cmd, odom = np.array(seen["cmd"]), np.array(seen["odom"])
    np.testing.assert_array_equal(cmd[:, [0, 2]], rec.native[:, 2])
    assert np.all(cmd[:, 1] == 0.0)
    np.testing.assert_allclose(odom[:, 0], np.hypot(*rec.velocities[:, 2].T), atol=1e-12)
    assert np.abs(odom[:, 1]).max() < 1e-12 and np.array_equal(odom[:, 2],
                                                               rec.angular_velocities[:, 2])
    back = read_bag(tmp_path / "t.bag", rec.config)
    assert np.array_equal(back.positions, rec.positions)
    assert np.array_equal(back.native, rec.native)
    np.testing.assert_allclose(back.headings, rec.headings, atol=1e-15)
    np.testing.assert_allclose(back.commanded, rec.commanded, atol=1e-14)
    ours, theirs = back.metrics(), rec.metrics()
    for key in ("V_sep", "V_coh", "V_align", "V_align_heading", "V_align_command",
                "count_align", "count_align_heading", "touching_fraction"):
        assert ours[key] == theirs[key], key
    for key, value in theirs.items():  # velocities go through the heading: to rounding
        assert ours[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key
