"""Proxemics metrics on hand-computed positions (boids_env.proxemics)."""

import numpy as np
import pytest

from boids_env import proxemics as px


def test_zones_count_each_followers_time_by_hall_distance():
    # person at the origin; follower 1 at 0.3, 1.0, 2.0, 5.0 m; follower 2 always at 0.45 m
    # (the intimate zone ends there: 0.45 is personal)
    d1 = [0.3, 1.0, 2.0, 5.0]
    pos = np.zeros((4, 3, 2))
    pos[:, 1, 0] = d1
    pos[:, 2, 1] = 0.45
    zones = px.zone_fractions(px.person_distance(pos))
    assert zones["intimate"].tolist() == [0.25, 0.0]
    assert zones["personal"].tolist() == [0.25, 1.0]
    assert zones["social"].tolist() == [0.25, 0.0]
    assert zones["public"].tolist() == [0.25, 0.0]


def test_contact_onsets_count_each_touching_run_once():
    flags = np.array([[1, 0], [1, 0], [0, 1], [1, 1]], dtype=bool)
    # follower 1: runs starting at 0 and 3; follower 2: one run from 2
    assert px.onsets(flags) == 3


def test_cut_in_is_the_strip_the_person_sweeps_in_two_seconds():
    # the person walks +x at 1 m/s: 2 s ahead plus its radius 0.2 -> along in (0, 2.2],
    # across < 0.2 + 0.05
    followers = [(1.0, 0.0), (2.1, 0.2), (2.3, 0.0), (1.0, 0.3), (-0.5, 0.0)]
    pos = np.array([[(0.0, 0.0), *followers]])
    vel = np.array([[1.0, 0.0]])
    flags = px.cut_in_flags(pos, vel, robot_radius=0.05, person_radius=0.2)
    assert flags.tolist() == [[True, True, False, False, False]]
    # a person standing (below 0.2 m/s) has no path
    assert not px.cut_in_flags(pos, np.array([[0.1, 0.0]]), 0.05, 0.2).any()


def test_person_metrics_of_a_two_sample_episode():
    pos = np.array([[(0.0, 0.0), (0.25, 0.0), (3.0, 0.0)],
                    [(0.0, 0.0), (1.0, 0.0), (0.0, 4.0)]])
    vel = np.array([[0.0, 0.0], [0.0, 0.0]])
    m = px.person_metrics(pos, vel, robot_radius=0.03, person_radius=0.22)
    # follower 1: 0.25 (intimate, touching: 0.25 < 0.22 + 0.03 + 0.001), 1.0 (personal);
    # follower 2: 3.0 (social), 4.0 (public)
    assert m["intimate_fraction"] == 0.25 and m["personal_fraction"] == 0.25
    assert m["social_fraction"] == 0.25 and m["public_fraction"] == 0.25
    assert m["personal_space"] == [1.0, 0.0]
    assert m["min_person_distance"] == 0.25
    assert m["person_contacts"] == 1 and m["person_contact_fraction"] == 0.5
    assert m["cut_in_fraction"] == 0.0


def test_crowd_metrics_take_the_nearest_pedestrian():
    pos = np.array([[(0.0, 0.0), (0.0, 0.0)], [(0.0, 0.0), (5.0, 0.0)]])
    peds = np.array([[(0.3, 0.0), (3.0, 3.0)], [(5.0, 1.0), (9.0, 0.0)]])
    m = px.crowd_metrics(pos, peds, robot_radius=0.05, pedestrian_radius=0.25)
    assert m["pedestrian_intimate_fraction"] == 0.5  # 0.3 m, then 1.0 m
    assert m["pedestrian_personal_fraction"] == 1.0
    assert m["min_pedestrian_distance"] == pytest.approx(0.3)
    assert m["pedestrian_contacts"] == 1  # 0.3 < 0.25 + 0.05 + 0.001


def test_intrusion_flags_see_the_leader_and_pedestrians():
    pos = np.array([(0.0, 0.0), (1.0, 0.0), (3.0, 0.0), (5.0, 5.0)])
    peds = np.array([(3.5, 0.0)])
    assert px.intrusion_flags(pos, peds, 1.2).tolist() == [True, True, False]
    assert px.intrusion_flags(pos, np.zeros((0, 2)), 1.2).tolist() == [True, False, False]
