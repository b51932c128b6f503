"""Statistics against hand-computed values and the study's published Tukey tables."""

import numpy as np
import pytest

from boids_env.eval.stats import bootstrap_ci, compare, holm, one_way, pair_difference, tukey
from boids_env.eval.study import study_groups, study_summary, study_tukey


def test_one_way_matches_hand_computation():
    # means 2 and 5, grand 3.5: SS_between = 2·3·1.5² = 13.5, SS_within = 2 + 2 = 4,
    # F = (13.5 / 1) / (4 / 4) = 13.5, eta² = 13.5 / 17.5.
    res = one_way({"a": [1, 2, 3], "b": [4, 5, 6]})
    assert res["F"] == pytest.approx(13.5)
    assert res["eta2"] == pytest.approx(13.5 / 17.5)
    assert res["robust_test"] == "anova" and res["robust_p"] == res["p"]


def test_one_way_degenerate_cases_choose_a_defined_test():
    same = one_way({"a": [0, 0, 0], "b": [0, 0, 0]})
    assert same["robust_test"] == "none" and same["p"] == 1.0
    # zero variance within one level (the study's V_sep at 0.6 m/s): Kruskal-Wallis
    zero = one_way({"a": [0, 0, 0, 0], "b": [1, 2, 3, 4]})
    assert zero["robust_test"] == "kruskal" and zero["robust_p"] < 0.05
    with pytest.raises(ValueError, match="at least 2 groups"):
        one_way({"a": [1, 2]})


def test_tukey_reproduces_every_published_pair_of_the_study():
    published = study_tukey()
    assert len(published) == 27
    for _, row in published.iterrows():
        groups = study_groups(int(row.rq), row.metric)
        table = tukey(np.concatenate(list(groups.values())),
                      [k for k, v in groups.items() for _ in v])
        diff, reject, _ = pair_difference(table, row.group1, row.group2)
        assert diff == pytest.approx(row.meandiff, abs=1e-3), (row.rq, row.metric)
        assert reject == row.reject, (row.rq, row.metric, row.group1, row.group2)


def test_study_summary_matches_design_section_5():
    s = study_summary()
    pick = s[(s.rq == 1) & (s.level == "0.5") & (s.metric == "V_sep")].iloc[0]
    assert pick["mean"] == pytest.approx(7.055, abs=1e-3)
    assert pick["std"] == pytest.approx(0.314, abs=1e-3)
    rq3 = s[(s.rq == 3) & (s.level == "19") & (s.metric == "count_coh")].iloc[0]
    assert rq3["mean"] == pytest.approx(55.53, abs=1e-2)


def test_tukey_with_zero_variance_is_exact():
    table = tukey([0, 0, 0, 1, 1, 1], ["a"] * 3 + ["b"] * 3)
    assert table.iloc[0].meandiff == 1.0 and bool(table.iloc[0].reject)


def test_holm_matches_hand_computation():
    # sorted p: 0.01·3 = 0.03, 0.03·2 = 0.06, 0.04·1 = 0.04 -> monotone max 0.06
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])


def test_bootstrap_and_compare():
    rng = np.random.default_rng(0)
    values = rng.normal(2.0, 0.1, 50)
    lo, hi = bootstrap_ci(values)
    assert lo < values.mean() < hi and hi - lo < 0.1
    assert bootstrap_ci([3.0, 3.0, 3.0]) == (3.0, 3.0)
    res = compare([1.0, 1.1, 0.9, 1.05], [2.0, 2.1, 1.9, 2.05])
    assert res["diff"] == pytest.approx(1.0, abs=1e-9)
    assert res["ci_low"] > 0.8 and res["ci_high"] < 1.2 and res["p"] < 1e-4
