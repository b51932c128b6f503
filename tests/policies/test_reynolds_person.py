"""The Reynolds policy with a person: the proxemics-aware leader term and pedestrians."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.policies.reynolds import pedestrian_points, proxemic_leader_force


def test_the_leader_term_seeks_the_circle_of_the_personal_space():
    offsets = np.array([[3.0, 0.0], [0.0, -0.6], [0.0, 0.0]])  # person 3 m east, 0.6 m south
    still = np.zeros((3, 2))
    force = proxemic_leader_force(offsets, still, 1.2)
    assert np.allclose(force, [[1.8, 0.0], [0.0, 0.6], [0.0, 0.0]]), force


def test_it_pushes_followers_sideways_out_of_the_path_ahead():
    # the person walks +x at 1 m/s; a follower 1 m ahead and 0.2 m to its left
    offsets = np.array([[-1.0, -0.2]])
    force = proxemic_leader_force(offsets, np.array([[1.0, 0.0]]), 1.2)
    ring = offsets[0] * (1 - 1.2 / np.hypot(1.0, 0.2))
    assert force[0] == pytest.approx(ring + np.array([0.0, 1.2 - 0.2]))
    # behind the person: only the ring
    behind = proxemic_leader_force(np.array([[1.0, -0.2]]), np.array([[1.0, 0.0]]), 1.2)
    assert behind[0] == pytest.approx(np.array([1.0, -0.2]) * (1 - 1.2 / np.hypot(1.0, 0.2)))


def test_pedestrians_are_obstacle_points_on_their_bodies():
    slots = np.array([[[2.0, 0.0, 0.0, 0.0, 1.0], [0.1, 0.0, 0.0, 0.0, 1.0],
                       [0.0, 0.0, 0.0, 0.0, 0.0]]])
    points, valid = pedestrian_points(slots, 0.25)
    assert points[0].tolist() == [[1.75, 0.0], [0.0, 0.0], [0.0, 0.0]]
    assert valid[0].tolist() == [True, True, False]


@pytest.mark.slow
def test_the_proxemic_variant_keeps_out_of_the_personal_space():
    def run(preset):
        env = parallel_env(leader="person", robots=7, path="circle", laps=1)
        return run_episode(env, ReynoldsPolicy(preset), seed=0).metrics

    plain, proxemic = run("paper"), run("proxemic")
    inside = {m: m_["intimate_fraction"] + m_["personal_fraction"]
              for m, m_ in (("paper", plain), ("proxemic", proxemic))}
    assert plain["person_contacts"] > 0, "the study's leader term runs into the person"
    assert proxemic["person_contacts"] == 0
    assert inside["proxemic"] < inside["paper"] / 2, inside
