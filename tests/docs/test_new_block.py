"""The contributors' example of a new observation block (docs/snippets/new_block.py): one
more spec in the block table reaches the layout, the Box, the saved block list and the
observations, and leaves every other block where it was."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from boids_env import EnvConfig, kernels, parallel_env
from boids_env.observations import ObservationLayout, Observer, blocks, layout_of

SNIPPET = Path(__file__).resolve().parents[2] / "docs" / "snippets" / "new_block.py"


@pytest.fixture
def snippet(monkeypatch):
    """The snippet's module, its block appended to the table for the test's duration."""
    spec = importlib.util.spec_from_file_location("new_block_snippet", SNIPPET)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(blocks, "SPECS", (*blocks.SPECS, module.LEADER_DISTANCE))
    return module


def test_the_new_block_is_in_the_layout_the_box_and_the_saved_blocks(snippet):
    config = EnvConfig.from_kwargs(robots=4, neighbours=3)
    layout = layout_of(config)
    assert layout == ObservationLayout(3, leader_distance=True)
    assert layout.leader_distance is True and layout.value("leader_distance") is True
    assert layout.blocks[-1] == ("leader_distance", 1)
    assert layout.block("leader_distance") == slice(21, 22)
    assert layout.block("neighbours") == slice(6, 21), "the old blocks stay where they were"
    # the saved block list (a model's boids.json) reads back as this layout, and a layout
    # saved before the block existed still reads (the block off)
    saved = [list(block) for block in layout.blocks]
    assert ObservationLayout.from_blocks(saved) == layout
    assert ObservationLayout.from_blocks(saved[:-1]) == ObservationLayout(3)
    space = Observer(config).make_space()
    assert space.shape == (22,)
    assert space.low[21] == 0.0 and space.high[21] == pytest.approx(np.sqrt(2) * 10.0)
    # a model trained without it is told why it does not fit
    off = ObservationLayout(3)
    assert blocks.SPECS[-1].parameter.differs(0, 1, config) == (
        "trained without the leader distance; this env has it on")
    assert not layout.study_only and off.study_only


def test_the_new_block_is_in_the_observations(snippet):
    with kernels.reference():  # the fused step knows the study's blocks only
        env = parallel_env(robots=4, neighbours=3, obs_noise=0.0)
        obs, _ = env.reset(seed=1)
        obs, *_ = env.step({agent: np.zeros(2) for agent in env.agents})
    positions = env.snapshot().positions
    layout = env._observer.layout
    for i, agent in enumerate(env.possible_agents, start=1):
        assert env.observation_space(agent).contains(obs[agent])
        distance = np.hypot(*(positions[0] - positions[i]))
        assert obs[agent][layout.block("leader_distance")] == pytest.approx([distance],
                                                                             abs=1e-6)
    env.close()
