"""One look for every picture of a flock: the renderer's frames, the report's trajectory
figures and the ROS bag's RViz markers use these colours, names and arrow scales.

Plain data only (no pygame, no matplotlib), so any layer can import it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Colour = tuple[int, int, int]

LEADER: Colour = (214, 39, 40)
"""The leader (robot 0): red."""
FOLLOWER: Colour = (31, 119, 180)
"""Followers: blue."""
TRAIL: Colour = (244, 170, 170)
"""The leader's trail: light red."""
PERSON: Colour = (140, 20, 75)
"""A person as the leader: dark magenta, drawn at its true size (about 0.44 m across)."""
PEDESTRIAN: Colour = (150, 150, 150)
"""The crowd's pedestrians: grey."""
PERSONAL_SPACE: Colour = (225, 190, 210)
"""The ring of the person's personal space (1.2 m, Hall's personal zone)."""
PERSONAL_SPACE_RADIUS = 1.2
"""Radius (m) of the drawn personal-space ring."""
CONTACT: Colour = (20, 20, 20)
"""Ring around a robot that touches another."""
HEADING: Colour = (255, 255, 255)
"""Heading mark of a robot that has one (centre to rim): white on red or blue."""
RULE_COLOURS: dict[str, Colour] = {
    # distinct from each other and from the robots' red and blue (colour-blind-safe hues)
    "separation": (255, 127, 14),  # orange
    "cohesion": (44, 160, 44),  # green
    "alignment": (148, 103, 189),  # purple
    "leader": (120, 72, 40),  # brown: pulls towards the (red) leader
    "obstacle": (227, 119, 194),  # pink: away from walls and obstacles (beyond the study)
}
"""Arrow colour of each Reynolds rule's force."""
RULE_LABELS = {"separation": "separation force", "cohesion": "cohesion force",
               "alignment": "alignment force", "leader": "leader term",
               "obstacle": "obstacle force"}
"""Legend text of each rule's arrow."""
OTHER_ARROW: Colour = (90, 90, 90)
"""Arrow colour of an overlay that is not a Reynolds rule."""

ARROW_SCALE = 0.5
"""Metres drawn per unit of an overlay vector (newton for forces, metre for the leader term):
the separation force at its limit (0.46 N) is a 0.23 m arrow, shorter than the spacing the
rules aim at."""
ARROW_MAX = 0.25
"""Longest arrow drawn (m), so that the raw leader vector (metres to the leader) does not
cover the flock."""


def rgb01(colour: Colour, alpha: float = 1.0) -> tuple[float, float, float, float]:
    """A colour as (r, g, b, a) floats in [0, 1] (matplotlib, ROS ``std_msgs/ColorRGBA``)."""
    return (colour[0] / 255, colour[1] / 255, colour[2] / 255, alpha)


def arrow_vectors(vectors: npt.ArrayLike, scale: float = ARROW_SCALE,
                  longest: float = ARROW_MAX) -> npt.NDArray[np.float64]:
    """Overlay vectors (F, 2) as drawn arrows (m): times ``scale`` and shortened to at most
    ``longest``, direction kept; non-finite vectors become zero."""
    vec = scale * np.asarray(vectors, dtype=float)
    vec = np.where(np.isfinite(vec), vec, 0.0)
    length = np.linalg.norm(vec, axis=-1, keepdims=True)
    return np.where(length > longest, vec * longest / np.maximum(length, 1e-12), vec)
