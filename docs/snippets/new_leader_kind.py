"""A new leader kind: a wheelchair user driving the leader's path.

In the repository this class would sit in ``boids_env/world/leader_kinds.py`` (with its
``LEADER_KINDS`` entry) and get a test: the world, the observations, the metrics, recordings,
bags, ROS and the model cards ask the kind (``scenario.leader_kind``) or the scenario's
``leader_radius``, never the kind's name.
"""

from boids_env import BoidsEnv
from boids_env.world.leader_kinds import LEADER_KINDS, LeaderKind, register_leader_kind


class WheelchairLeader(LeaderKind):
    """A wheelchair (a 0.35 m body the robots cannot push) along the scripted path."""

    name = "wheelchair"
    words = "a wheelchair user"

    def radius(self, scenario):
        return 0.35


if WheelchairLeader.name not in LEADER_KINDS:  # the snippet may run twice in one process
    register_leader_kind(WheelchairLeader())

env = BoidsEnv(robots=7, leader="wheelchair", max_cycles=100)
env.reset(seed=0)
print("leader:", env.config.scenario.leader_kind.words, "of radius",
      env.config.scenario.leader_radius, "m")
