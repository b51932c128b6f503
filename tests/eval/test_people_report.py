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
