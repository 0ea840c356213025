"""diagnose's refinement starts for a mass on a spring (bscomp.validate.refinement._other_masses): besides the best
screening point, the best one more than OTHER_MASS x heavier and the best one more than that lighter. The case that
needed both sides: the bundled housing truth (28.7 kg) measured by positions only, whose screening ranked a 10 kg
point first and a 0.74 kg one second (both refined into the 8.7 kg valley, 124x the noise floor) and a 100 kg one
later (refined to 28.4 kg, 0.94) -- docs/validation.md, "Positions only"."""

import numpy as np

from bscomp.validate.candidates import default_candidates
from bscomp.validate.refinement import OTHER_MASS, _other_masses


def _candidate(name):
    return next(c for c in default_candidates() if c.name == name)


def _score(cost, m, k):
    return (cost, np.log([m, k, 0.05]), {"table.m": 250.0})


def test_a_mass_on_a_spring_is_also_started_from_the_best_heavier_and_the_best_lighter_point():
    scores = [_score(-900.0, 10.0, 3.35e8), _score(-850.0, 0.7427, 1.35e8), _score(-800.0, 12.0, 4e8),
              _score(-700.0, 100.0, 1.64e9), _score(-650.0, 60.0, 1e9), _score(np.inf, 300.0, 1e9)]
    starts = _other_masses(_candidate("bearing_housing"), scores)
    masses = [round(float(np.exp(sc[1][0])), 6) for sc in starts]
    assert masses == [100.0, 0.7427]          # the heavier first, then the lighter; 12 kg is within 2x of 10 kg
    assert all(abs(np.log(m / 10.0)) > np.log(OTHER_MASS) for m in masses)


def test_one_side_only_where_the_other_has_no_point_and_none_for_other_candidates():
    scores = [_score(-900.0, 1.0, 3e8), _score(-800.0, 1.5, 3e8), _score(-700.0, 5.0, 3e8)]
    assert [round(float(np.exp(sc[1][0])), 6) for sc in _other_masses(_candidate("table_subassembly"), scores)] == [5.0]
    assert _other_masses(_candidate("compliant_backlash"), scores) == []      # nonlinear, no mass first
    assert _other_masses(_candidate("amplifier_delay"), scores) == []         # one parameter
