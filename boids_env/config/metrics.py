"""The metrics section of the env config: the study's violation thresholds (all against the
leader) and the reward's weights."""

from __future__ import annotations

from dataclasses import dataclass

from boids_env.checks import number as _number
from boids_env.checks import set_field as _set

REWARDS = ("study", "safe")
"""Reward presets: ``study`` (the study's three violations only, the default) and ``safe``
(adds penalties for crowding, contact and walls; see :data:`SAFE_WEIGHTS`)."""
ALIGNMENT_SOURCES = ("command", "heading")
"""What the alignment rule compares (``alignment_source``)."""
SAFE_WEIGHTS = {"reward_proximity": 1.0, "reward_contact": 4.0, "reward_wall": 2.0}
"""Weights of the safety terms under ``reward="safe"`` (per step, × dt, like a violation)."""


@dataclass(frozen=True)
class MetricsConfig:
    """Violation thresholds (all against the leader) and reward weights (the study's)."""

    separation_threshold: float = 0.7
    """Separation violation when a follower is closer than this to the leader (m)."""
    cohesion_threshold: float = 2.25
    """Cohesion violation when a follower is farther than this from the leader (m)."""
    alignment_threshold_deg: float = 45.0
    """Alignment violation when the commanded directions differ by more than this (degrees)."""
    wrap_alignment: bool = True
    """Wrap the angle difference into [0°, 180°]. False reproduces the study's analysis, which
    took |θ_leader − θ_i| unwrapped (so −179° vs 180° counted as a violation)."""
    alignment_source: str = "command"
    """What the alignment rule compares: ``command`` (the commanded velocities' directions,
    the study's) or ``heading`` (the robots' measured headings; robots with a heading only,
    the study's own complaint about its holonomic robots). Both are reported for robots with
    a heading (``V_align_command``, ``V_align_heading``); this one is ``V_align`` and the
    reward's."""
    reward_separation: float = 1.0
    """Weight of the separation flag in the reward."""
    reward_cohesion: float = 1.0
    """Weight of the cohesion flag in the reward."""
    reward_alignment: float = 1.0
    """Weight of the alignment flag in the reward."""
    reward: str = "study"
    """Reward preset, one of REWARDS: ``study`` (the study's metrics only) or ``safe`` (the
    study's plus the safety terms below at :data:`SAFE_WEIGHTS`)."""
    reward_proximity: float | None = None
    """Weight of the penalty while a follower is closer than ``safety_distance`` to another
    robot (follower or leader); None: the preset's (0 for ``study``)."""
    reward_contact: float | None = None
    """Weight of the penalty while a follower touches another robot; None: the preset's."""
    reward_wall: float | None = None
    """Weight of the penalty while a follower's centre is within ``wall_distance`` of a wall;
    None: the preset's."""
    reward_gap: float = 0.0
    """Weight of the penalty per metre a follower is beyond ``cohesion_threshold`` (−w · excess
    · dt per step). Not in the study: the cohesion flag alone tells a follower too far to get
    back soon nothing about getting closer, so it trades the flag for alignment; this dense
    term pays for closing in. 0 (off) under both rewards."""
    reward_intrusion: float = 0.0
    """Weight of the penalty while a follower's centre is within ``intrusion_distance`` of
    the leader (a person's personal space) or of a pedestrian (−w · dt per step). Not in the
    study; 0 (off) under both rewards."""
    intrusion_distance: float = 1.2
    """Centre distance (m) under which ``reward_intrusion`` applies: the outer edge of Hall's
    personal zone (1.2 m)."""
    reward_parked: float = 0.0
    """Weight of the penalty on a follower's speed while the leader stands still (−w · speed
    · dt per step, once the leader's command has been zero for more than ``parked_after``).
    Not in the study (its leader never stops): followers should park around a leader who
    stands, not mill. 0 (off) under both rewards."""
    parked_after: float = 2.0
    """Seconds the leader must have stood still before ``reward_parked`` applies (the
    followers first settle around it)."""
    parked_within: float = 0.0
    """``reward_parked`` applies only to followers within this distance (m) of the leader
    (along the route for one that does not see it, with ``route_leader``): one still far
    behind a standing leader should come, not stop. 0: to every follower (as before)."""
    safety_distance: float = 0.3
    """Centre distance (m) under which ``reward_proximity`` applies. Not in the study."""
    wall_distance: float = 0.15
    """Centre-to-wall distance (m) under which ``reward_wall`` applies (a robot touches at
    its radius, 0.036 m). Not in the study."""

    def __post_init__(self) -> None:
        _set(self, "separation_threshold",
             _number("separation_threshold", self.separation_threshold, 0.0, 100, unit="m"))
        _set(self, "cohesion_threshold",
             _number("cohesion_threshold", self.cohesion_threshold, 0.0, 1000, lo_open=True,
                     unit="m"))
        _set(self, "alignment_threshold_deg",
             _number("alignment_threshold_deg", self.alignment_threshold_deg, 0.0, 360,
                     unit="degrees"))
        if not isinstance(self.wrap_alignment, bool):
            raise ValueError(f"wrap_alignment must be True or False, got {self.wrap_alignment!r}")
        for name in ("reward_separation", "reward_cohesion", "reward_alignment", "reward_gap",
                     "reward_intrusion", "reward_parked"):
            _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
        _set(self, "parked_after", _number("parked_after", self.parked_after, 0.0, 3600,
                                           unit="s"))
        _set(self, "parked_within", _number("parked_within", self.parked_within, 0.0, 1000,
                                            unit="m"))
        if self.separation_threshold >= self.cohesion_threshold:
            raise ValueError(f"separation_threshold ({self.separation_threshold} m) must be "
                             f"below cohesion_threshold ({self.cohesion_threshold} m)")
        if self.alignment_source not in ALIGNMENT_SOURCES:
            raise ValueError(f"alignment_source must be one of {ALIGNMENT_SOURCES}, got "
                             f"{self.alignment_source!r}")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
        for name in SAFE_WEIGHTS:
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
        _set(self, "intrusion_distance", _number("intrusion_distance", self.intrusion_distance,
                                                 0.0, 10, lo_open=True, unit="m"))
        _set(self, "safety_distance", _number("safety_distance", self.safety_distance, 0.0, 10,
                                              lo_open=True, unit="m"))
        _set(self, "wall_distance", _number("wall_distance", self.wall_distance, 0.0, 10,
                                            unit="m"))

    @property
    def safety_weights(self) -> tuple[float, float, float]:
        """Resolved weights of the proximity, contact and wall terms (the preset's where a
        field is None)."""
        preset = SAFE_WEIGHTS if self.reward == "safe" else dict.fromkeys(SAFE_WEIGHTS, 0.0)
        proximity, contact, wall = (preset[name] if getattr(self, name) is None
                                    else getattr(self, name) for name in SAFE_WEIGHTS)
        return proximity, contact, wall
