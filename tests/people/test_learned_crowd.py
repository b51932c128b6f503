"""``learned-crowd``: the shipped follower of a person among pedestrians acts with the safety
filter keeping the person's intimate zone (its env fields), is the shipped model an env with
a person and a crowd in a building is pointed to, and follows the person there."""


from boids_env import parallel_env
from boids_env.config import EnvConfig
from boids_env.eval.episode import env_fields_for, run_episode
from boids_env.policies.registry import CROWD_MODEL, fitting_model, load_policy

CASE = {"leader": "person", "crowd": 8, "scene": "floorplan:1004", "robots": 7,
        "max_cycles": 200}


def _run(**change):
    policy = load_policy("learned-crowd")
    env = parallel_env(**{**env_fields_for(policy, CASE), **change})
    return run_episode(env, policy, seed=4).metrics


def test_learned_crowd_keeps_the_persons_intimate_zone_and_follows():
    policy = load_policy("learned-crowd")
    assert policy.env_fields["safety_person_distance"] == 0.45
    assert policy.env_fields["safety_person_path"] == 2.0
    assert policy.env_fields["safety_filter"] is True
    kept = _run()
    # 20 s behind a person through a held-out plan among 8 pedestrians: nobody on the person,
    # nobody inside 0.45 m of it more than a trace, nobody farther than 3 m at the end
    assert kept["person_contacts"] == 0
    assert kept["intimate_fraction"] < 0.005, kept["intimate_fraction"]
    assert kept["lost_followers"] == 0
    # without the zone (the filter keeps only the bodies apart) the same model goes closer
    bodies = _run(safety_person_distance=0.0)
    assert bodies["min_person_distance"] < kept["min_person_distance"]


def test_an_env_with_a_person_and_a_crowd_is_pointed_to_learned_crowd():
    config = EnvConfig.from_kwargs(**{**CASE, "route_sensing": True})
    assert fitting_model(config) == "learned-crowd"
    assert CROWD_MODEL.name == "ppo_crowd.zip"

