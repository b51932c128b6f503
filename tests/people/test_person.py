"""A person as the leader and crowds: the walk, the bodies, determinism, sensing, rewards."""

import hashlib
import pickle
import subprocess
import sys

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.eval.episode import bind_policy, run_episode
from boids_env.observations import Crowd, ObservationLayout, Sensors, build_observations
from boids_env.policies import ReynoldsPolicy
from boids_env.world.people import walkable_area
from boids_env.world.scenes import load_scene


def rollout(steps=60, **fields):
    env = parallel_env(**fields)
    obs, _ = env.reset(seed=3)
    policy = ReynoldsPolicy()
    bind_policy(policy, env)
    policy.reset(3)
    positions, crowd = [env.snapshot().positions], []
    for _ in range(steps):
        obs, *_ = env.step(policy.act(obs))
        positions.append(env.snapshot().positions)
        crowd.append(env._world.pedestrian_positions.copy())
    return env, np.array(positions), np.array(crowd)


def digest(*arrays):
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in arrays)
                          ).hexdigest()


def test_the_walkable_area_of_the_doorway_is_the_box_less_its_walls():
    area = walkable_area(load_scene("doorway"))
    # 12 m x 6 m less two 0.1 m walls from the door's jambs (0.5 m + a 0.05 m round end) to
    # the box: 2 x (2.45 m x 0.1 m + a half disc of radius 0.05 m)
    walls = 2 * (2.45 * 0.1 + np.pi * 0.05**2 / 2)
    # (the buffered walls are polygons circumscribing them: 0.12 % wider, 6e-4 m² more)
    assert area.area == pytest.approx(72.0 - walls, abs=1e-3)
    assert area.contains(__import__("shapely").Point(0.0, 0.0)), "the door is walkable"
    assert not area.contains(__import__("shapely").Point(0.0, 1.0)), "the wall is not"


def test_same_seed_same_walk_bit_for_bit_and_the_gait_varies():
    _, a, ca = rollout(crowd=3, scene="doorway", leader="person")
    _, b, cb = rollout(crowd=3, scene="doorway", leader="person")
    assert digest(a, ca) == digest(b, cb)
    speed = np.hypot(*np.diff(a[:, 0], axis=0).T) / 0.1
    walking = speed[21:]  # after the 2 s start-up
    assert walking.std() > 0.02, f"a constant speed profile: {walking}"
    assert speed[:19].max() < 1e-9, "the person stands still during the start-up"


def test_a_walk_is_the_same_in_another_process():
    code = ("import hashlib, numpy as np\n"
            "from boids_env import parallel_env\n"
            "env = parallel_env(scene='doorway', leader='person', crowd=3)\n"
            "env.reset(seed=3)\n"
            "for _ in range(40):\n"
            "    env.step({a: np.zeros(2) for a in env.agents})\n"
            "w = env._world\n"
            "print(hashlib.sha256(w.positions.tobytes() + w.pedestrian_positions.tobytes())"
            ".hexdigest())\n")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True).stdout for _ in range(2)]
    env = parallel_env(scene="doorway", leader="person", crowd=3)
    env.reset(seed=3)
    for _ in range(40):
        env.step({a: np.zeros(2) for a in env.agents})
    w = env._world
    here = hashlib.sha256(w.positions.tobytes() + w.pedestrian_positions.tobytes()).hexdigest()
    assert runs[0].strip() == runs[1].strip() == here


def test_robots_cannot_push_the_person():
    # a follower driving at full speed into a standing person (start-up: it stands)
    env = parallel_env(robots=2, leader="person", startup_time=30.0, init_jitter=0.0)
    env.reset(seed=0)
    start = env.snapshot().positions[0].copy()
    towards = start - env.snapshot().positions[1]
    for _ in range(30):
        env.step({"follower_1": 0.5 * towards / np.hypot(*towards)})
    snap = env.snapshot()
    gap = np.hypot(*(snap.positions[1] - snap.positions[0])) - 0.22 - 0.036
    assert np.hypot(*(snap.positions[0] - start)) < 1e-4, snap.positions[0]
    assert -0.005 < gap < 0.002, gap


@pytest.mark.slow
def test_no_robot_overlaps_a_person_by_more_than_5_mm_in_a_crowded_doorway():
    _, pos, crowd = rollout(steps=400, scene="doorway", leader="person", crowd=12)
    r = 0.22 + 0.036
    person = np.hypot(*(pos[:, 1:] - pos[:, :1]).transpose(2, 0, 1)) - r
    walkers = np.hypot(*(pos[1:, 1:, None] - crowd[:, None]).transpose(3, 0, 1, 2)) - r
    assert person.min() > -0.005, person.min()
    assert walkers.min() > -0.005, walkers.min()


def test_a_pickled_episode_goes_on_bit_for_bit():
    env = parallel_env(scene="doorway", leader="person", crowd=2, robots=4)
    env.reset(seed=1)
    for _ in range(25):
        env.step({a: np.array([0.1, 0.0]) for a in env.agents})
    copy = pickle.loads(pickle.dumps(env))
    for e in (env, copy):
        for _ in range(10):
            e.step({a: np.array([0.0, 0.1]) for a in e.agents})
    assert np.array_equal(env.snapshot().positions, copy.snapshot().positions)
    assert np.array_equal(env._world.pedestrian_positions, copy._world.pedestrian_positions)


def test_the_person_is_the_leader_everywhere():
    env = parallel_env(leader="person", robots=4)
    obs, _ = env.reset(seed=0)
    snap = env.snapshot()
    o = obs["follower_1"]
    assert np.allclose(o[env.layout.leader_position], snap.positions[0] - snap.positions[1])
    rec = run_episode(parallel_env(leader="person", robots=4, max_cycles=30), ReynoldsPolicy(),
                      seed=0).recording
    assert rec.metrics()["intimate_fraction"] >= 0.0  # the person's metrics are computed
    assert "intimate_fraction" not in run_episode(parallel_env(robots=4, max_cycles=5),
                                                  ReynoldsPolicy(), seed=0).metrics


def test_the_pedestrian_slots_hold_the_nearest_pedestrians():
    positions = np.array([(0.0, 0.0), (1.0, 1.0)])
    velocities = np.zeros((2, 2))
    crowd = Crowd(np.array([(4.0, 1.0), (1.5, 1.0), (9.0, 9.0)]),
                  np.array([(0.0, 1.0), (-1.0, 0.0), (5.0, 5.0)]))
    layout = ObservationLayout(0, pedestrians=3)
    sensors = Sensors(pedestrian_range=3.0)
    obs = build_observations(positions, velocities, layout, 1.0, 3.0, 10.0, None, sensors,
                             crowd)
    slots = obs[0, layout.block("pedestrians")].reshape(3, 5)
    assert slots.tolist() == [[0.5, 0.0, -1.0, 0.0, 1.0], [3.0, 0.0, 0.0, 1.0, 1.0],
                              [0.0, 0.0, 0.0, 0.0, 0.0]]


def test_the_lidar_sees_pedestrians_and_the_person_as_wide_discs():
    from boids_env.observations.sensing import lidar_block

    scene = load_scene("arena")
    positions = np.array([(2.0, 0.0), (0.0, 0.0)])  # the person 2 m east of the follower
    crowd = Crowd(np.array([(0.0, 1.0)]), np.zeros((1, 2)))  # a pedestrian 1 m north
    sensors = Sensors(scene, lidar_range=3.0, leader_radius=0.22, pedestrian_radius=0.25)
    ranges = lidar_block(positions, 4, sensors, None, crowd)[0]
    assert ranges[0] == pytest.approx(2.0 - 0.22) and ranges[1] == pytest.approx(1.0 - 0.25)
    assert ranges[2] == ranges[3] == 3.0


def test_the_intrusion_reward_counts_time_in_the_personal_space():
    env = parallel_env(robots=3, leader="person", reward_intrusion=2.0, init_jitter=0.0)
    env.reset(seed=0)
    _, _, _, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    d = np.hypot(*(env.snapshot().positions[1:] - env.snapshot().positions[0]).T)
    want = [-2.0 * 0.1 if x < 1.2 else 0.0 for x in d]
    assert [infos[a]["reward_intrusion"] for a in env.agents] == pytest.approx(want)
    assert any(want), d
    off = parallel_env(robots=3, leader="person")
    off.reset(seed=0)
    _, _, _, _, infos = off.step({a: np.zeros(2) for a in off.agents})
    assert all(i["reward_intrusion"] == 0.0 for i in infos.values())


@pytest.mark.parametrize(("fields", "message"), [
    ({"leader": "human"}, r"leader must be one of \('robot', 'person', 'trajectory'\)"),
    ({"crowd": -1}, r"crowd must be in \[0, 500\]"),
    ({"crowd_speed": 3.0}, r"crowd_speed must be in \(0.0, 2.0\] m/s"),
    ({"person_radius": 0.9}, r"person_radius must be in \[0.05, 0.5\] m"),
    ({"gait_variation": 1.0}, r"gait_variation must be in \[0.0, 0.5\]"),
    ({"personal_space": 1.0}, r"unknown config field"),
])
def test_bad_people_fields_are_refused(fields, message):
    with pytest.raises((ValueError, TypeError), match=message):
        EnvConfig.from_kwargs(**fields)


def test_crowd_is_not_a_reset_option():
    env = parallel_env(robots=3)
    with pytest.warns(UserWarning, match="ignores unknown option"):
        env.reset(seed=0, options={"crowd": 3})
    assert env._world.p == 0


def test_a_person_walked_by_hand_moves_as_commanded():
    # the live window's keyboard person: --leader person --path external
    env = parallel_env(leader="person", path="external", robots=3, startup_time=0.0)
    env.reset(seed=0)
    env.set_leader_command([0.5, 0.0])
    for _ in range(10):
        env.step({a: np.zeros(2) for a in env.agents})
    assert env.snapshot().positions[0] == pytest.approx([0.5, 0.0], abs=1e-9)
    assert env._people is None  # no pedestrian model runs for a hand-walked person


PEOPLE_GRAPH = dict(scene="doorway", leader="person", crowd=3, robots=4, max_cycles=150)


class _Loopback:
    """The graph's two nodes in one process: every published tick of the simulator ``core``
    goes through the controller's tick assembly (robots, then pedestrians, as their odometry
    arrives) to the controller, whose commands are posted back as they would come on
    cmd_vel."""

    name = "loopback"
    poll = 0.0
    wait_for_topics = ()

    @property
    def malformed(self):
        return {}  # in one process nothing arrives malformed

    def __init__(self, core, controller_core):
        from boids_env.eval.graph.protocol import TickAssembler

        self.controller = controller_core
        self.assembler = TickAssembler(controller_core.robots, controller_core.pedestrians)
        self.core = core
        self.info = None
        self.frames = []

    def publish_clock(self, stamp_ns):
        pass

    def publishers(self, topic):
        return {"/loopback"}

    def receivers(self, topics):
        return {t: {"/loopback"} for t in topics}

    def announce(self, info):
        self.info = info

    def publish(self, frame):
        self.frames.append(frame)
        sources = [(p, v) for p, v in zip(frame.positions, frame.velocities, strict=True)]
        if frame.crowd is not None:
            sources += list(zip(frame.crowd.positions, frame.crowd.velocities, strict=True))
        tick = None
        for k in reversed(range(len(sources))):  # any order: the tick completes at the last
            (x, y), (vx, vy) = sources[k]
            tick = self.assembler.add(k, frame.stamp_ns, x, y, vx, vy)
        assert tick is not None
        for index, (a, b) in enumerate(self.controller.answer(tick)):
            self.core.post_command(index, a, b, 0.0)

    def stopped(self):
        return False


def test_the_ros_graph_core_runs_a_walking_person_and_a_crowd_as_boids_run():
    # the sim core publishes the pedestrians with every tick and the controller observes
    # them: the lockstep graph equals boids run bit for bit
    from boids_env.eval.graph.controller import (
        ControllerCore,
        ControllerOptions,
        controller_policy,
    )
    from boids_env.eval.graph.sim import SimCore, SimOptions
    from boids_env.eval.run import run

    core = SimCore(SimOptions(env_fields=PEOPLE_GRAPH, lockstep=True, quiet=True))
    options = ControllerOptions(quiet=True)
    transport = None

    def episode(_stamp):
        return transport.info

    controller = ControllerCore(options, controller_policy(options), core.config, "/c", episode)
    transport = _Loopback(core, controller)
    ours = core.run_episode(0, transport)
    reference = run("reynolds", out=None, seed=0, quiet=True, env_fields=PEOPLE_GRAPH)
    for name in ("positions", "velocities", "commanded", "time", "pedestrians"):
        assert np.array_equal(getattr(ours.recording, name),
                              getattr(reference.recording, name)), name
    assert ours.metrics == reference.metrics
    assert ours.stats["extra_commands"] == 0
    frame = transport.frames[5]
    assert frame.leader_command is None  # a walking person takes no cmd_vel
    assert frame.crowd.positions.shape == (3, 2)
    assert reference.recording.pedestrians.shape[1] == 3
    # (in 150 cycles the followers meet the crowd: a controller blind to the pedestrians
    # steers otherwise, and the runs differ)


def test_the_walkable_area_of_a_map_is_its_free_cells():
    scene = load_scene("lab")
    area = walkable_area(scene)
    free = float((scene.grid.cells == 0).sum()) * scene.grid.resolution ** 2
    # less the 5 mm contour capsules along the walls (and any free pocket cut off)
    assert 0.99 * free < area.area <= free, (area.area, free)
    occupied = np.argwhere(scene.grid.cells != 0)[0]
    x0, y0, _ = scene.grid.origin
    centre = (x0 + (occupied[1] + 0.5) * scene.grid.resolution,
              y0 + (occupied[0] + 0.5) * scene.grid.resolution)
    assert not area.contains(__import__("shapely").Point(*centre))


def test_a_person_walks_the_lab_map():
    _, pos, _ = rollout(steps=80, scene="lab", leader="person", robots=4)
    assert np.hypot(*(pos[-1, 0] - pos[0, 0])) > 1.0, "the person walked off its start"


def test_a_crowd_that_cannot_fit_is_refused_when_the_env_is_built():
    # 60 pedestrians 1 m apart on a small room's few m² of floor: no draw can place them,
    # so the config says so (it was found only at reset, as a step-time error)
    with pytest.raises(ValueError, match=r"crowd must be at most \d+ in scene 'small_room' "
                                         r"\(got 60\)"):
        parallel_env(scene="small_room", path_size=1.0, crowd=60, robots=4)


def test_a_crowd_that_fits_by_area_but_not_by_draw_is_refused_at_reset_with_no_episode():
    env = parallel_env(scene="arena", crowd=58)  # at the jamming bound: seed 0 is not placed
    with pytest.raises(ValueError, match=r"crowd: no free place for a pedestrian"):
        env.reset(seed=0)
    with pytest.raises(RuntimeError, match=r"call reset\(\) first"):
        env.step({})


def test_wide_pedestrians_start_apart_or_are_refused_never_a_crash():
    # person_radius 0.5: JuPedSim's agents (0.55 m with the robots' room) need centres
    # 1.1 m apart; the crowd's starts were drawn 1.0 m apart and JuPedSim raised RuntimeError
    from boids_env import parallel_env

    env = parallel_env(scene="small_room", crowd=3, max_cycles=5)
    env.reset(seed=0)
    env.reset(seed=1, options={"person_radius": 0.5})
    positions = env._people.pedestrians
    gaps = [np.hypot(*(a - b)) for k, a in enumerate(positions) for b in positions[k + 1:]]
    assert min(gaps) >= 1.1, gaps


def _lockstep(policy_name, fields):
    """A lockstep graph core of ``fields`` and a controller node of ``policy_name`` over the
    loopback: ``(core, controller, episode)``, ``episode()`` running seed 0."""
    from boids_env.eval.graph.controller import (
        ControllerCore,
        ControllerOptions,
        controller_policy,
    )
    from boids_env.eval.graph.sim import SimCore, SimOptions

    options = ControllerOptions(policy=policy_name, quiet=True)
    core = SimCore(SimOptions(env_fields=fields, lockstep=True, quiet=True))
    loop = None

    def info(_stamp):
        return loop.info

    controller = ControllerCore(options, controller_policy(options), core.config, "/c", info)
    loop = _Loopback(core, controller)
    return core, controller, lambda: core.run_episode(0, loop)


def test_the_ros_graph_controller_switches_learned_buildings_on_its_own_sight_test():
    # learned-buildings reads which followers see the leader from the controller's own
    # observer (the controller node builds the observations, not the env)
    from boids_env.policies.registry import load_policy

    fields = {**load_policy("learned-buildings").env_fields, "scene": "floorplan:1016",
              "robots": 7, "max_cycles": 80}
    _, controller, episode = _lockstep("learned-buildings", fields)
    assert controller.leader_hidden is None  # no tick yet
    ours = episode()
    assert ours.recording.positions.shape == (81, 7, 2)
    assert ours.stats["rejected_commands"] == 0
    hidden = controller.leader_hidden
    assert hidden is not None and hidden.shape == (6,) and hidden.dtype == bool


def test_the_ros_graph_controller_applies_the_safety_filter_a_model_was_trained_with():
    # learned-scenes acts through the safety filter (its env fields): the controller node
    # filters its commands too, so a bare simulator (or real robots) gets them filtered.
    # Without it the flock touched 31 % of this episode (0 % in-process).
    from boids_env.eval.run import run

    fields = dict(scene="small_room", robots=13, max_cycles=300)
    core, _, episode = _lockstep("learned-scenes", fields)
    assert not core.config.safety.safety_filter  # no filter in the simulator
    ours = episode().recording
    reference = run("learned-scenes", out=None, seed=0, quiet=True, env_fields=fields)
    # the same episode as in-process until the leader's odometry (which the node filters
    # against) and its command (which the env uses) first lead to other bits
    assert np.array_equal(ours.positions[:150], reference.recording.positions[:150])
    r = ours.config.world.robot_radius
    touching = []
    for p in ours.positions:
        d = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        touching.append((d < 2 * r + 0.005).any())
    assert np.mean(touching) <= 0.02
    assert not any(ours.config.scene.within(p, r, 0.005).any() for p in ours.positions)


def test_the_ros_graph_controller_keeps_the_person_and_the_crowd_off_as_the_env_does():
    # the controller node filters learned-crowd's commands against the person's and the
    # pedestrians' odometry: through the lockstep graph nobody reaches the person's zone

    fields = {"leader": "person", "crowd": 8, "scene": "floorplan:1004", "robots": 7,
              "max_cycles": 400}
    core, _, episode = _lockstep("learned-crowd", fields)
    assert not core.config.safety.safety_filter  # no filter in the simulator
    positions = episode().recording.positions
    person = np.linalg.norm(positions[:, 1:] - positions[:, :1], axis=2)
    assert person.min() > 0.45, person.min()
