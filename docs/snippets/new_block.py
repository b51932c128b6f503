"""Adding an observation block: each follower's distance to the leader (a tested example).

A block is one ``BlockSpec`` appended to the table ``SPECS`` in
``boids_env/observations/blocks.py`` (at the end: a new block never moves an old one, so
the layouts saved with trained models keep their meaning). Its switch is a field of
``ObservationConfig`` in ``boids_env/config/observation.py``, and a test shows it; that is all. The
layout, the observation ``Box``, the sensing-noise masks, the fill loop, the block list
saved in a model's ``boids.json``, the model cards' layout reasons, the fields a trained
model pins and the reference page all read the table.

``tests/docs/test_new_block.py`` runs this file: it appends ``LEADER_DISTANCE`` to the
table for the test's duration and checks the block in the layout, the Box, the saved block
list and the observations.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from boids_env.observations import BlockSpec, Inputs, LayoutParameter


def leader_distance(inputs: Inputs, slots: int) -> npt.NDArray[np.float64]:
    """The block's values (F, 1): each follower's distance (m) to the leader (row 0)."""
    offset = inputs.positions[0] - inputs.positions[1:]
    return np.hypot(offset[:, 0], offset[:, 1])[:, None]


LEADER_DISTANCE = BlockSpec(
    name="leader_distance",
    width=1,  # values per slot; a flag parameter gives the block one slot when on
    doc="the follower's distance to the leader, m",
    # one slot's (low, high) per column: the leader's offset is within ± the scene's span
    # on each axis (``Ranges`` holds the config's ranges)
    bounds=lambda r: ([0.0], [math.sqrt(2.0) * r.reach]),
    parameter=LayoutParameter(
        "leader_distance",  # ObservationLayout(..., leader_distance=True)
        # on in every config here; in the tree, its ObservationConfig field switches it:
        # of_config=lambda config: config.observation.leader_distance
        of_config=lambda config: True,
        flag=True,
        what="the leader distance",
    ),
    fill=leader_distance,
    # no valid flag: its noise (obs_noise) is never masked. With a config field, list it in
    # fields=("leader_distance",) so that a model acts only where it has its training's value.
)
