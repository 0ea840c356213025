"""The own share of a candidate's action (bscomp.validate.collinearity): collinearity of sensitivities, on
Jacobians with known geometry, and the acceptance rule it feeds."""

import numpy as np
import pytest

from bscomp.validate.acceptance import verdict as _verdict
from bscomp.validate.collinearity import MIN_OWN_SHARE, own_share


def _columns(n=500, k=3, seed=0):
    return np.random.default_rng(seed).standard_normal((n, k))


@pytest.mark.parametrize("eps", [0.0, 0.01, 0.1, 1.0])
def test_share_of_a_column_near_the_span_of_the_others(eps):
    """c = a + b + eps * e (e orthogonal to a, b): the own share is |eps e|^2 / |c|^2 (1 / the VIF)."""
    q, _ = np.linalg.qr(_columns(k=3))
    a, b, e = q.T * 10
    c = a + b + eps * e
    share, partners = own_share(np.c_[a, b, c], [2], ["table.m", "coupling.k", "J"])
    assert share == pytest.approx(eps ** 2 * 100 / (c @ c), abs=1e-12)
    assert {p for p, _ in partners} == {"table.m", "coupling.k"}          # |cos| = 1 / sqrt(2 + eps^2) >= 0.58


def test_the_most_independent_direction_counts():
    """A two-parameter effect whose first parameter duplicates an uncertain one (``a``) and whose second (``x``)
    is new does something of its own: the share of its best direction, ``x`` without its part along ``a``,
    outside span(a, b); with both parameters in the span of the others it does nothing of its own."""
    a, b, x = _columns(k=3, seed=1).T
    share, _ = own_share(np.c_[a, b, a, x], [2, 3])
    outside = x - _project(np.c_[a, b], x)
    along_a = x - _project(a[:, None], x)
    assert share == pytest.approx((outside @ outside) / (along_a @ along_a), rel=1e-9)
    assert share > 0.9
    share, _ = own_share(np.c_[a, b, a, 2 * a - b], [2, 3])
    assert share < 1e-20


def _project(basis, x):
    return basis @ np.linalg.lstsq(basis, x, rcond=None)[0]


def test_an_effect_that_does_nothing_and_one_alone():
    a, x = _columns(k=2, seed=2).T
    assert own_share(np.c_[a, np.zeros(a.size)], [1]) == (0.0, [])
    assert own_share(x[:, None], [0])[0] == pytest.approx(1.0)           # nothing else free: all its own


def test_the_rule_rejects_a_trade_off_and_says_with_what():
    before = {"error": 1.6, "per_dataset": [1.5, 1.7], "heldout": 2.1, "heldout_per_dataset": [2.1]}
    after = {"error": 1.1, "per_dataset": [1.0, 1.2], "heldout": 1.3, "heldout_per_dataset": [1.3]}
    thresholds = (10.0, 0.5, 0.25, 0.5)
    ok, why = _verdict(before, after, -500.0, [], [], thresholds, (0.2, []))
    assert ok and why == ""
    ok, why = _verdict(before, after, -500.0, [], [], thresholds, (6e-4, [("table.m", 0.9997)]))
    assert not ok and why.startswith("trades off against table.m: only 0.06 % of what it does is its own")
    assert "variance inflation 1.67e+03 > 10" in why
    assert MIN_OWN_SHARE == 0.1


def test_the_rule_yields_when_the_partners_alone_left_far_more_than_the_candidate():
    """The damping truth, seed 2203 (docs/validation.md, rule f): the coupling damping took 14.5 -> 1.01, every dataset
    within its noise, at an own share of 3.1 % -- its partners (k_T, the bearing's damping) were free in the fit
    without it and left 14.5. Not rejected then; at 1.6 before (the motor inertia's case) the rule holds, and it holds
    when the candidate stops above the floor however far it started."""
    thresholds = (10.0, 0.5, 0.25, 0.5)
    partners = (0.031, [("coupling.k_T", 0.68), ("support_damping.c", 0.63)])
    before = {"error": 14.5, "per_dataset": [14.5], "heldout": None, "heldout_per_dataset": []}
    after = {"error": 1.01, "per_dataset": [1.01], "heldout": None, "heldout_per_dataset": []}
    assert _verdict(before, after, -16000.0, [], [], thresholds, partners) == (True, "")
    short = dict(after, error=1.7, per_dataset=[1.7])                     # not within 1 + 0.5 of the floor
    ok, why = _verdict(before, short, -16000.0, [], [], thresholds, partners)
    assert not ok and why.startswith("trades off against coupling.k_T, support_damping.c: only 3.1 %")
    near = dict(before, error=1.6, per_dataset=[1.6])                     # the motor inertia's case: started near
    ok, why = _verdict(near, after, -500.0, [], [], thresholds, partners)
    assert not ok and "trades off" in why
