"""The observation section of the env config: what each follower senses, in which frame,
and what its actions mean."""

from __future__ import annotations

from dataclasses import dataclass

from boids_env.checks import flag as _flag
from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set

FRAMES = ("world", "leader")
"""Observation (and action) frames: the study's world frame, or the leader's heading frame
(opt-in; see :mod:`boids_env.observations`)."""


@dataclass(frozen=True)
class ObservationConfig:
    """What each follower senses: exact positions and velocities."""

    horizon: float = 1.0
    """Neighbour radius (m): robots within it, the leader included, fill the slots. Paper: 1.0."""
    neighbours: int = 18
    """K, the number of neighbour slots (nearest first). 18 holds every other robot of the
    study's largest group, so the Reynolds policy sees exactly what full state gives it."""
    velocity_bound: float = 3.0
    """Observed velocities are clipped to ±this (m/s) so observations stay in their Box."""
    obs_noise: float = 0.0
    """Std of seeded Gaussian noise added to every observed position (m) and velocity (m/s);
    valid flags and empty slots stay exact. 0 (the study's exact sensing) by default."""
    sense_walls: bool = False
    """Append a wall slot: the offset (m) to the nearest point of the walls (any static
    geometry) and a valid flag, when within ``horizon`` (zeros otherwise). Opt-in: the study's
    followers sensed only robots. The same as ``static_slots=1``."""
    static_slots: int | None = None
    """Static-geometry slots: the nearest point of walls or obstacles within ``static_range``
    (offset in m, valid flag), then in each further slot the nearest point more than 45° away
    from the earlier slots' directions. None: 1 with ``sense_walls``, else 0 in the study's
    empty arena and 4 in any other scene (so every policy, the Reynolds one included, sees the
    obstacles without a flag)."""
    static_range: float | None = None
    """Range (m) of the static slots; None: ``horizon``."""
    lidar_rays: int = 0
    """Rays of a range sensor (0: none): distances (m) to walls, obstacles and other robots
    along rays evenly spaced in the observation's frame, ``lidar_range`` where nothing is hit.
    Opt-in."""
    lidar_range: float = 3.0
    """Range (m) of the range sensor."""
    pedestrian_slots: int | None = None
    """Pedestrian slots: the nearest pedestrians within ``pedestrian_range`` (relative
    position, velocity, valid flag each, as a neighbour slot). None: 4 with a crowd, else 0."""
    pedestrian_range: float = 3.0
    """Range (m) of the pedestrian slots."""
    frame: str = "world"
    """Frame of observations and actions, one of FRAMES: ``world`` (the study's) or
    ``leader`` (x along the leader's heading, y to its left; opt-in, for policies that should
    learn a formation relative to the leader)."""
    action: str = "velocity"
    """Action space, one of :data:`boids_env.world.robots.ACTIONS`: ``velocity`` (world-frame
    (vx, vy), the study's; a robot with a heading turns it into (v, ω) with its driver's law)
    or ``unicycle`` ((v, ω) in the robot's limits, for ``drive="unicycle"``)."""
    relative_actions: bool = False
    """Read each follower's action as a velocity relative to the leader's velocity as that
    follower observes it (noise included): the command is the observed leader velocity plus
    the action, in ``frame``, and the action space widens to ±2·``max_speed`` so that any
    command stays reachable. Opt-in, for learned policies (a zero action matches the leader's
    speed on any path and at any speed); a policy that outputs absolute velocities, like the
    Reynolds controller, needs it off."""
    route_sensing: bool = False
    """Append the ``route`` block (:mod:`boids_env.world.route`): per follower, the unit
    direction of the shortest path to the leader through free space (walls inflated by the
    robot radius, so a door narrower than a robot is no way through), the path's length (m)
    and a valid flag (0 where no free path exists: the straight line's direction and
    distance then). Opt-in; the ``route`` Reynolds preset follows it."""
    route_cell: float = 0.1
    """Cell size (m) of the route sensing's grid (finer: narrower doors resolved, slower)."""
    route_leader: bool = False
    """Sense a leader out of sight along its route: for a follower that does not see the
    leader through free space (walls inflated by the robot radius, the route grid's cells),
    the ``leader_position`` block holds the route's direction × its length (clipped to the
    scene's span like the straight line) instead of the straight-line offset, so a follower
    behind a wall finds the leader through the door; a follower that sees the leader reads
    the straight line, bit for bit as without this flag. Needs ``route_sensing`` (whose
    block still follows, valid flag included). Opt-in, for learned followers in buildings
    (``learned-buildings``)."""

    def __post_init__(self) -> None:
        _set(self, "horizon", _number("horizon", self.horizon, 0.0, 100, lo_open=True, unit="m"))
        _set(self, "neighbours", _integer("neighbours", self.neighbours, 0, 1024))
        _set(self, "velocity_bound", _number("velocity_bound", self.velocity_bound, 0.0, 100,
                                             lo_open=True, unit="m/s"))
        _set(self, "obs_noise", _number("obs_noise", self.obs_noise, 0.0, 10.0, unit="m, m/s"))
        _set(self, "sense_walls", _flag("sense_walls", self.sense_walls))
        if self.static_slots is not None:
            _set(self, "static_slots", _integer("static_slots", self.static_slots, 0, 64))
            if self.sense_walls and self.static_slots == 0:
                raise ValueError("sense_walls=True asks for a static slot; static_slots=0 "
                                 "refuses it (leave static_slots None or >= 1)")
        if self.static_range is not None:
            _set(self, "static_range", _number("static_range", self.static_range, 0.0, 100,
                                               lo_open=True, unit="m"))
        _set(self, "lidar_rays", _integer("lidar_rays", self.lidar_rays, 0, 1024))
        _set(self, "lidar_range", _number("lidar_range", self.lidar_range, 0.0, 100,
                                          lo_open=True, unit="m"))
        if self.pedestrian_slots is not None:
            _set(self, "pedestrian_slots", _integer("pedestrian_slots", self.pedestrian_slots,
                                                    0, 64))
        _set(self, "pedestrian_range", _number("pedestrian_range", self.pedestrian_range, 0.0,
                                               100, lo_open=True, unit="m"))
        _set(self, "relative_actions", _flag("relative_actions", self.relative_actions))
        _set(self, "route_sensing", _flag("route_sensing", self.route_sensing))
        _set(self, "route_cell", _number("route_cell", self.route_cell, 0.02, 1.0, unit="m"))
        _set(self, "route_leader", _flag("route_leader", self.route_leader))
        if self.route_leader and not self.route_sensing:
            raise ValueError("route_leader=True reads the leader along the route: it needs "
                             "route_sensing=True")
        from boids_env.world.robots import ACTIONS

        if self.action not in ACTIONS:
            raise ValueError(f"action must be one of {ACTIONS}, got {self.action!r}")
        if self.action == "unicycle" and self.relative_actions:
            raise ValueError("relative_actions=True reads velocities relative to the leader's; "
                             "action='unicycle' takes (v, ω): use one of them")
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, got {self.frame!r}")
