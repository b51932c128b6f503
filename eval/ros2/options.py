"""How a ROS 2 node of ours joins a Zenoh network (domain, distribution, endpoints, cmd_vel
type)."""

from __future__ import annotations

from dataclasses import dataclass

from boids_env.eval.ros2.wire import (
    DEFAULT_DISTRIBUTION,
    DEFAULT_ROUTER,
    check_distribution,
    check_domain,
)

TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"


@dataclass(frozen=True)
class Ros2Options:
    """The ROS 2 side of ``boids ros2 sim|controller``."""

    domain: int = 0
    """ROS domain id (``ROS_DOMAIN_ID``): the first chunk of every key expression."""
    distribution: str = DEFAULT_DISTRIBUTION
    """Whose message definitions and RIHS01 type hashes (``jazzy``, ``kilted``,
    ``lyrical``): a node only talks to nodes of the same hashes."""
    connect: tuple[str, ...] = (DEFAULT_ROUTER,)
    """Zenoh endpoints to connect to: rmw_zenoh's router by default."""
    listen: tuple[str, ...] = ("tcp/localhost:0",)
    """Zenoh endpoints to listen on (peers connect here directly)."""
    twist_stamped: bool = False
    """``cmd_vel`` as geometry_msgs/TwistStamped (a TurtleBot3 on Jazzy and later) instead of
    Twist."""

    def __post_init__(self) -> None:
        check_domain(self.domain)
        check_distribution(self.distribution)
        for name, values in (("connect", self.connect), ("listen", self.listen)):
            if not isinstance(values, tuple) or not all(
                    isinstance(v, str) and "/" in v for v in values):
                raise ValueError(f"{name} must be Zenoh endpoints such as tcp/127.0.0.1:7447, "
                                 f"got {values!r}")
        if not isinstance(self.twist_stamped, bool):
            raise TypeError(f"twist_stamped must be True or False, got {self.twist_stamped!r}")

    @property
    def cmd_type(self) -> str:
        """The ``cmd_vel`` message type."""
        return TWIST_STAMPED if self.twist_stamped else TWIST

    def endpoints(self):  # -> Endpoints (imported lazily: zenoh is optional)
        from boids_env.eval.ros2.node import Endpoints

        return Endpoints(self.connect, self.listen)

    def summary(self) -> dict[str, object]:
        """For ``config.json``."""
        return {"transport": "zenoh", "domain": self.domain,
                "distribution": self.distribution, "cmd_vel": self.cmd_type}
