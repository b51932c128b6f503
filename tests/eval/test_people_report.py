"""The report's person section on a hand-made results table."""

import pandas as pd

from boids_env.eval.people_report import statement, trade_offs


def table():
    rows = []
    for level, coh, inside in (("0.4", (0.0, 0.1), (0.5, 0.6)), ("0.75", (2.0, 2.2),
                                                                 (0.5, 0.6))):
        for seed, (c, i) in enumerate(zip(coh, inside, strict=True)):
            rows.append({"policy": "reynolds", "group": "speed", "factor": "leader_speed",
                         "level": level, "seed": seed, "V_coh": c, "V_sep": 1.0,
                         "intimate_fraction": i / 2, "personal_fraction": i / 2})
    return pd.DataFrame(rows)


def test_trade_offs_state_what_changes_and_what_does_not():
    found = trade_offs(table()).set_index("metric")
    coh = found.loc["V_coh"]
    assert (coh["first_mean"], coh["last_mean"]) == (0.05, 2.1)
    assert coh["significant"]
    assert statement(coh).startswith(
        "cohesion violation V_coh rises from 0.05 at leader_speed 0.4 to 2.1 at 0.75")
    inside = found.loc["personal_space_fraction"]
    assert not inside["significant"]
    assert "no significant effect" in statement(inside)
    assert "V_sep" in found.index and not found.loc["V_sep"]["significant"]


def test_a_crowd_metric_is_compared_over_the_levels_that_have_a_crowd():
    rows = []
    for level, contacts in (("0", (None, None)), ("5", (1.0, 2.0)), ("20", (10.0, 12.0))):
        for seed, c in enumerate(contacts):
            rows.append({"policy": "p", "group": "crowd", "factor": "crowd", "level": level,
                         "seed": seed, "pedestrian_contacts": c})
    found = trade_offs(pd.DataFrame(rows)).set_index("metric").loc["pedestrian_contacts"]
    assert (found["first_level"], found["first_mean"]) == ("5", 1.5)
    assert found["significant"] and "rises from 1.5 at crowd 5 to 11 at 20" in statement(found)
