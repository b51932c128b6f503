"""The world section of the env config: arena, robots and the physics time step."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set

if TYPE_CHECKING:
    from boids_env.world.robots import RobotModel

MAX_SPEED_RANGE = (0.0, 5.0)
"""The range (m/s, open below) of a top speed: the robots' ``max_speed``, a controller's,
a random policy's; the one check every layer uses."""


@dataclass(frozen=True)
class WorldConfig:
    """The physical world: arena, robots and the physics time step."""

    arena_half_size: float = 5.0
    """Half the side of the square arena (m); walls at ±arena_half_size. Paper: 10 m × 10 m."""
    robot_radius: float = 0.036
    """Sphero SPRK+ radius (m)."""
    robot_mass: float = 0.18
    """Sphero SPRK+ mass (kg)."""
    max_speed: float = 0.5
    """Followers' speed limit (m/s); actions are clipped to it. Paper: 0.5 m/s."""
    drive_force: float = 1.0
    """Largest force (N) a robot's drive applies to track its commanded velocity. Not in the
    paper (Stage set velocities instantly); 1 N reaches 0.5 m/s from rest in 0.09 s."""
    dt: float = 0.1
    """Control period (s): 10 Hz, as the original controller and simulator."""
    substeps: int = 10
    """Physics substeps per control step (fixed step dt / substeps)."""
    collision_slop: float = 0.001
    """pymunk collision slop (m). Its default (0.1) assumes pixels; in metres robots would sink."""
    scene: str = "arena"
    """The static world: a built-in scene (``arena``, the study's empty box of side
    2·``arena_half_size``; ``small_room``, ``doorway``, ``corridor``, ``pillars``, ``lab``), a
    ROS ``map_server`` YAML or a shapes file (``.toml`` / ``.json``). Choosing one also sets its
    leader path and start unless given (``map=PATH`` is the same as ``scene=PATH``)."""
    robot: str = "sphero"
    """The robot preset the robot fields come from (:data:`boids_env.world.robots.ROBOT_PRESETS`:
    ``sphero``, the study's; ``sphero_sprk``, ``turtlebot3_burger``, ``gritsbot``). Choosing
    one sets ``robot_radius``, ``robot_mass``, ``max_speed``, ``drive_force``, ``drive``,
    ``max_turn_rate``, ``max_turn_acceleration``, ``heading_gain`` and ``velocity_law``, and
    scales ``leader_speed`` and ``layout_spacing`` to the robot, unless they are given too."""
    drive: str = "holonomic"
    """``holonomic`` (the study's omnidirectional disc) or ``unicycle`` (moves only along its
    heading, which turns at a bounded rate; :mod:`boids_env.world.robots`)."""
    max_turn_rate: float | None = None
    """Top turn rate (rad/s) of a unicycle (required for one; ignored when holonomic)."""
    max_turn_acceleration: float | None = None
    """Largest change of a unicycle's turn rate (rad/s²); None: it follows its command at
    once."""
    heading_gain: float | None = None
    """Gain k (1/s) of a unicycle driver's heading controller, ω = clip(k·sin e, ±ω_max) for
    a heading error e within 90°; None: ``max_turn_rate``."""
    velocity_law: str = "turn_and_drive"
    """A unicycle driver's speed: ``turn_and_drive`` (differential drive: the command's
    component along the heading, never reversing) or ``roll`` (a Sphero: the command's full
    speed while the heading turns)."""

    def __post_init__(self) -> None:
        _set(self, "arena_half_size", _number("arena_half_size", self.arena_half_size, 0.5, 1000,
                                              unit="m"))
        _set(self, "robot_radius", _number("robot_radius", self.robot_radius, 0.0, 0.5,
                                           lo_open=True, unit="m"))
        _set(self, "robot_mass", _number("robot_mass", self.robot_mass, 0.001, 100,
                                         unit="kg"))
        _set(self, "max_speed", _number("max_speed", self.max_speed, *MAX_SPEED_RANGE,
                                        lo_open=True, unit="m/s"))
        _set(self, "drive_force", _number("drive_force", self.drive_force, 0.0, 1000,
                                          lo_open=True, unit="N"))
        _set(self, "dt", _number("dt", self.dt, 0.0, 1.0, lo_open=True, unit="s"))
        _set(self, "substeps", _integer("substeps", self.substeps, 1, 1000))
        _set(self, "collision_slop", _number("collision_slop", self.collision_slop, 0.0, 0.01,
                                             unit="m"))
        from boids_env.world.scenes import load_scene, scene_key

        load_scene(self.scene, self.arena_half_size)  # a bad name or file is refused here
        _set(self, "scene", scene_key(self.scene))
        self._check_robot()

    def _check_robot(self) -> None:
        """The robot model's fields: a known preset, drive and velocity law, the turn limits
        in range, and whatever the drive itself requires (:meth:`RobotModel.check_config`)."""
        from boids_env.world.robots import ROBOT_PRESETS, VELOCITY_LAWS, drive_model

        if self.robot not in ROBOT_PRESETS:
            raise ValueError(f"robot must be one of {sorted(ROBOT_PRESETS)}, got {self.robot!r}")
        model = drive_model(self.drive)
        if self.velocity_law not in VELOCITY_LAWS:
            raise ValueError(f"velocity_law must be one of {VELOCITY_LAWS}, got "
                             f"{self.velocity_law!r}")
        for name, hi, unit in (("max_turn_rate", 50.0, "rad/s"),
                               ("max_turn_acceleration", 10_000.0, "rad/s²"),
                               ("heading_gain", 1000.0, "1/s")):
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, hi, lo_open=True,
                                         unit=unit))
        model.check_config(self)

    @property
    def drive_model(self) -> type[RobotModel]:
        """The robot model class of ``drive`` (:data:`boids_env.world.robots.DRIVES`): what
        every caller asks about the drive (its heading, its turn time, its checks)."""
        from boids_env.world.robots import drive_model

        return drive_model(self.drive)

    @property
    def has_heading(self) -> bool:
        """Whether these robots have a heading (their drive's answer)."""
        return self.drive_model.has_heading
