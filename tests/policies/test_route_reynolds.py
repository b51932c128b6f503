"""Route-Reynolds (preset ``route``) goes round through the door where the study's leader
term pins followers to the wall between them and the leader."""

import numpy as np
import pytest

from boids_env.config import EnvConfig
from boids_env.environment import BoidsEnv
from boids_env.eval.episode import env_fields_for, run_episode
from boids_env.observations import ObservationLayout
from boids_env.policies.reynolds import ReynoldsPolicy
from boids_env.policies.reynolds_params import Timing, reynolds_params

# The doorway scene (a wall at x = 0, a 1 m door at y = 0): the leader goes through the door,
# north along the wall's east face and east, and stands there 20 s. The followers start
# 6 s late (held still 8 s against the leader's 2 s start-up), so the leader has turned
# behind the wall before they reach the door.
CASE = {"scene": "doorway", "robots": 7, "start": (-2.0, 0.0), "start_heading": 0.0,
        "path": "waypoints", "waypoints": ((0.0, 0.0), (0.6, 0.0), (0.6, 2.0), (2.0, 2.0)),
        "leader_pauses": ((10.0, 20.0),)}


class _Late:
    """The policy, its followers held still for ``steps`` control steps (the env owns the
    start-up time, which delays the leader too)."""

    def __init__(self, policy, steps):
        self.policy, self.steps, self.done = policy, steps, 0

    def __getattr__(self, name):
        return getattr(self.policy, name)

    def reset(self, seed=None):
        self.done = 0
        self.policy.reset(seed)

    def act(self, obs):
        actions = self.policy.act(obs)
        self.done += 1
        if self.done <= self.steps:
            return {agent: np.zeros_like(a) for agent, a in actions.items()}
        return actions


def _final(preset):
    policy = ReynoldsPolicy(preset)
    env = BoidsEnv(EnvConfig.from_kwargs(**env_fields_for(policy, CASE)))
    policy.bind(env)
    result = run_episode(env, _Late(policy, 80), seed=0)
    return result.recording.positions[-1], result.metrics


def test_route_reynolds_passes_the_door_where_the_straight_line_strands():
    plain, _ = _final("paper")
    routed, metrics = _final("route")
    plain_gap = np.hypot(*(plain[1:] - plain[0]).T)
    routed_gap = np.hypot(*(routed[1:] - routed[0]).T)
    # the study's term: every follower pinned west of the wall, > 2 m from the leader
    assert (plain[1:, 0] < 0).all() and (plain_gap > 2.0).all(), (plain[1:], plain_gap)
    # along the route: every follower through the door, within 1 m of the leader
    assert (routed[1:, 0] > 0).all() and (routed_gap < 1.0).all(), (routed[1:], routed_gap)
    assert metrics["lost_followers"] == 0 and metrics["wall_fraction"] == 0.0


def test_the_route_preset_asks_for_route_sensing_and_refuses_without_it():
    policy = ReynoldsPolicy("route")
    assert policy.env_fields == {"route_sensing": True}
    assert reynolds_params("route").follow_route and not reynolds_params("paper").follow_route
    assert not hasattr(ReynoldsPolicy("paper"), "env_fields")
    with pytest.raises(ValueError, match="route_sensing"):
        ReynoldsPolicy("route", layout=ObservationLayout(18),
                       timing=Timing(0.1, 0.0)).act_batch(
            np.zeros((2, ObservationLayout(18).size)))
