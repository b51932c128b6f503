"""Issue 39: a recipe whose sizes would exhaust memory when training starts (n_steps or
buffer_size of 1e12, a 64 × 4096 network) is refused when it is read, naming the field."""

import pytest

from boids_env.train.config import RECIPES, TrainConfig


@pytest.mark.parametrize("fields, match", [
    ({"n_steps": 10**12}, r"n_steps \(1,000,000,000,000\) × followers of all copies \(72\)"),
    ({"algorithm": "sac", "buffer_size": 10**12},
     r"buffer_size must be at most 10,000,000 transitions"),
    ({"batch_size": 10**12}, "batch_size must be at most 4,194,304"),
    ({"net_arch": [4096] * 64}, r"net_arch .* has 64 layers and 1,056,964,608 weights"),
    ({"copies": 1024, "group_sizes": [1000], "n_steps": 256}, "transitions per rollout"),
])
def test_sizes_that_cannot_be_allocated_are_refused_by_name(fields, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**fields)


def test_every_shipped_recipe_fits_the_budgets():
    for path in sorted(RECIPES.glob("*.toml")):
        TrainConfig.from_toml(path)


def test_a_deep_or_special_recipe_file_is_a_value_error(tmp_path):
    deep = tmp_path / "r.toml"
    deep.write_text("net_arch = " + "[" * 3000 + "]" * 3000 + "\n")
    with pytest.raises(ValueError, match="nested more than 32 levels"):
        TrainConfig.from_toml(deep)
    with pytest.raises(ValueError, match="not a regular file"):
        TrainConfig.from_toml("/dev/zero")
