"""Candidates the data cannot tell apart (bscomp.validate.equivalence): the two tests on residuals with a
known answer, the grouping of fitted rounds, and the words that say what to measure.

The residual vectors are whitened (unit noise variance per point), as diagnose's are: an "effect" is a
shape ``g`` it removes from the residual of the model without it.
"""

import math

import numpy as np
import pytest

from bscomp.systems.validation_drive import validation_drive
from bscomp.validate.candidates import BearingHousing, GuidewayFriction, NutTableJoint, StribeckGuidewayFriction
from bscomp.validate.diagnosis import EffectFit
from bscomp.validate.equivalence import SHARED, Z_CRIT, compare_fits, mark_equivalent, tell_apart

N = 4000
X = np.linspace(0.0, 1.0, N)
G1 = 40.0 * np.sin(2 * np.pi * 3 * X) * np.exp(-2 * X)        # the shape of one effect
G2 = 40.0 * np.cos(2 * np.pi * 7 * X)                           # another, nearly orthogonal to it


def _noise(seed):
    return np.random.default_rng(seed).standard_normal(N)


def test_thresholds_are_the_documented_ones():
    assert Z_CRIT == pytest.approx(1.959964, abs=1e-6)          # two-sided 5 % of the standard normal
    assert SHARED == 0.5                                          # more of each improvement along than across
    assert (2 * Z_CRIT) ** 2 == pytest.approx(15.37, abs=0.01)   # "within noise": D below it


def test_a_reparametrisation_is_indistinguishable():
    """y = c g and y = (a b) g fit the same curve: identical predictions, whatever the parameter count."""
    e = _noise(1)
    r0 = G1 + e                        # residual of the model without the effect
    r = e                              # both fits remove G1 exactly
    st = compare_fits(r, r.copy(), r0, 1, 2)
    assert st["indistinguishable"]
    assert st["D"] == 0.0 and st["z"] == 0.0 and st["dchi2"] == 0.0
    assert st["shared"] == pytest.approx(1.0, abs=1e-12)


def test_predictions_within_noise_of_each_other_are_one_group():
    """Two fits 2 noise sigmas apart in total (D = 4 < 15.4): data from either could not prefer it."""
    e = _noise(2)
    delta = 2.0 * G1 / np.linalg.norm(G1)                       # |delta|^2 = 4
    st = compare_fits(e, e - delta, G1 + e, 2, 2)
    assert st["D"] == pytest.approx(4.0, rel=1e-12)
    assert st["indistinguishable"] and st["shared"] > 0.99


def test_same_effect_under_a_large_misfit_is_one_group():
    """The lumped joint case: both remove G1, both leave a large systematic misfit M, and their predictions
    differ by far more than the noise (D ~ 180) -- but not in a way the data prefers: Vuong's |z| < 1.96."""
    e = _noise(3)
    M = 6.0 * np.sign(np.sin(2 * np.pi * 11 * X))             # what neither explains (chi^2 / n ~ 37)
    wiggle = 0.3 * np.sin(2 * np.pi * 40 * X)                  # where the two fits differ, uncorrelated with M
    r_a = M + e
    r_b = M + e + wiggle
    st = compare_fits(r_a, r_b, G1 + M + e, 2, 2)
    assert st["D"] == pytest.approx(180.0, rel=0.01)             # not "within noise" (15.4) ...
    assert abs(st["z"]) < Z_CRIT                                 # ... yet neither fits better
    assert st["shared"] > 0.99 and st["indistinguishable"]


def test_a_clearly_better_fit_is_not_grouped():
    """B removes only half of the effect A removes: the data prefer A by far (z >> 1.96)."""
    e = _noise(4)
    r0 = G1 + e
    st = compare_fits(e, 0.5 * G1 + e, r0, 2, 2)
    assert st["z"] > 10 and not st["indistinguishable"]
    assert st["shared"] == pytest.approx(1.0, abs=1e-9)         # same direction: collinearity alone is not enough


def test_two_different_effects_explaining_as_much_are_not_grouped():
    """The data hold G1 + G2 of equal size; A removes G1, B removes G2: equally good fits (|z| small), but
    they remove different errors (shared ~ 0) -- two effects, which the greedy rounds find one after another."""
    e = _noise(5)
    g2 = G2 * np.linalg.norm(G1) / np.linalg.norm(G2)
    r0 = G1 + g2 + e
    st = compare_fits(g2 + e, G1 + e, r0, 2, 2)
    assert abs(st["z"]) < Z_CRIT
    assert st["shared"] < 0.05 and not st["indistinguishable"]


def test_the_schwarz_correction_charges_the_extra_parameters():
    """Equal fits far apart: the one with 3 more parameters pays 3 ln n in chi^2 (z > 0 for the other)."""
    e = _noise(6)
    w = np.sin(2 * np.pi * 40 * X)
    st = compare_fits(e + w, e - w, G1 + e, 1, 4)                # sum l = 4 e.w: zero mean, no preference
    num = st["dchi2"] - (1 - 4) * math.log(N)
    assert num == pytest.approx(st["dchi2"] + 3 * math.log(N))
    assert st["z"] == pytest.approx(num / (math.sqrt(N) * np.std((e - w) ** 2 - (e + w) ** 2, ddof=1)))


class _Cand:
    def __init__(self, name, k):
        self.name, self.parameters, self.role = name, [object()] * k, "nut_table"

    def applicable(self, system):
        raise AssertionError("not called without a system")


def _fit(name, k, out, refined=True):
    r = EffectFit(candidate=_Cand(name, k), values={}, std={}, error_before=1.0, error_after=1.0, delta_bic=0.0,
                  refined=refined)
    r._after = {"outputs": [out]}
    return r


def test_mark_equivalent_is_symmetric_and_skips_unrefined(monkeypatch):
    """mark_equivalent on a round: the pair that removes the same error is listed both ways (z flips sign),
    a clearly worse fit and a screened-only one are not."""
    import bscomp.validate.equivalence as eq

    monkeypatch.setattr(eq, "residual_blocks", lambda y, d, s: [np.asarray(y, float)])
    e = _noise(7)
    M = 6.0 * np.sign(np.sin(2 * np.pi * 11 * X))
    wiggle = 0.3 * np.sin(2 * np.pi * 40 * X)
    a, b = _fit("a", 2, M + e), _fit("b", 2, M + e + wiggle)
    worse, screened = _fit("worse", 2, M + e + 0.5 * G1), _fit("screened", 1, M + e, refined=False)
    mark_equivalent([a, b, worse, screened], {"outputs": [G1 + M + e]}, [None], [None])
    assert list(a.equivalent) == ["b"] and list(b.equivalent) == ["a"]
    assert a.equivalent["b"]["z"] == -b.equivalent["a"]["z"]
    assert a.group_names == ("a", "b") and worse.group_names == ("worse",) and not screened.equivalent
    # every refined pair is compared (why one is named alone): a against the worse fit, z > 1.96 for a
    assert set(a.compared) == {"b", "worse"} and not screened.compared
    assert a.compared["worse"]["z"] > Z_CRIT and not a.compared["worse"]["indistinguishable"]
    assert a.compared["b"]["indistinguishable"]
    # both at the same role and no system to name the ports: only their laws can differ
    assert a.equivalent["b"]["tell_apart"].startswith("both act at the 'nut_table' point")


def test_tell_apart_names_the_sensor_across_each_joint():
    """Joint at the nut vs housing at the support (validation_drive): measure across either connection;
    Coulomb vs Stribeck at the guideway: same point, only their laws differ."""
    s = validation_drive()
    words = tell_apart(NutTableJoint(), BearingHousing(), s)
    assert "nut.flange_b - table.flange_a" in words and "lead.flange_b - axial.flange_a" in words
    assert words.index("nut_table_joint") < words.index("bearing_housing")
    same = tell_apart(GuidewayFriction(), StribeckGuidewayFriction(), s)
    assert "same point" in same and "laws differ" in same
