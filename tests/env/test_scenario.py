"""Initial layouts: the study's grids, the extension to any N, jitter, arena checks."""

import numpy as np
import pytest

from boids_env.config import EnvConfig, ScenarioConfig
from boids_env.world.scenario import grid_cells, initial_positions

PAPER_13 = [(-0.5, -0.5), (-1.0, -0.5), (-0.5, -1.0), (-1.0, -1.0), (-1.5, -1.0), (-1.0, -1.5),
            (0.5, -0.5), (1.0, -0.5), (0.5, -1.0), (1.0, -1.0), (1.5, -1.0), (1.0, -1.5)]


def test_paper_grids_cell_for_cell():
    p13 = initial_positions(ScenarioConfig(robots=13, init_jitter=0.0), None)
    assert p13[0].tolist() == [0, 0]
    assert [tuple(p) for p in p13[1:]] == PAPER_13
    p7 = initial_positions(ScenarioConfig(robots=7, init_jitter=0.0), None)
    assert [tuple(p) for p in p7[1:]] == PAPER_13[:3] + PAPER_13[6:9]
    p19 = initial_positions(ScenarioConfig(robots=19, init_jitter=0.0), None)
    assert [tuple(p) for p in p19[13:]] == [(-1.5, -0.5), (1.5, -0.5), (-0.5, -1.5),
                                            (0.5, -1.5), (-1.5, -1.5), (1.5, -1.5)]


@pytest.mark.parametrize("n", [2, 10, 40, 1000])
def test_grid_extension_behind_leader_unique_symmetric(n):
    cells = grid_cells(n - 1)
    assert len({tuple(c) for c in cells}) == n - 1
    assert np.all(cells[:, 1] < 0) and np.all(cells[:, 0] != 0)
    if (n - 1) % 2 == 0:
        assert sorted(map(tuple, cells * [-1, 1])) == sorted(map(tuple, cells))
    dist = np.linalg.norm(cells, axis=1)
    assert np.all(np.diff(dist) >= -1e-12), "nearest cells first"


def test_thousand_robots_need_a_bigger_arena():
    with pytest.raises(ValueError, match="arena_half_size must exceed"):
        EnvConfig.from_kwargs(robots=1000)
    cfg = EnvConfig.from_kwargs(robots=1000, arena_half_size=14.0)
    assert cfg.scenario.robots == 1000


def test_jitter_is_seeded_and_bounded():
    sc = ScenarioConfig(robots=13)
    a = initial_positions(sc, np.random.default_rng(1))
    b = initial_positions(sc, np.random.default_rng(1))
    c = initial_positions(sc, np.random.default_rng(2))
    base = initial_positions(sc, None)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.abs(a - base).max() <= sc.init_jitter
