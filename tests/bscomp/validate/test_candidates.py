"""The candidate-effect library: each candidate edits a copy, flattens, and changes the physics it names."""

import math

import numpy as np
import pytest

from bscomp import flatten
from bscomp.errors import ParameterError, UnknownNameError
from bscomp.systems.validation_drive import INSERTION_POINTS, UNCERTAIN, validation_drive
from bscomp.validate._evaluate import FrfEvaluator, TimeSimulator
from bscomp.validate.candidates import (
    AmplifierDelay,
    NutTableJoint,
    ParameterScale,
    ScrewNutBacklash,
    default_candidates,
)

F = np.logspace(0, 3, 200)
PAIRS = [("amp.u", "rotor.w"), ("amp.u", "table.a")]


def frf(system):
    dae = flatten(system)
    return FrfEvaluator(dae, PAIRS)(F, dae.p0)


def test_validation_drive_matches_table_4_1():
    from bscomp.modal import modes

    md = modes(validation_drive())
    text = md.table()
    assert "117.6" in text  # first (axial) mode at the C-position 117.69 Hz of Table 4.1
    dae = flatten(validation_drive())
    assert dae.nx == 6  # 3 DOF: rotor, screw, table
    assert set(INSERTION_POINTS) >= {"nut_table", "table_guide", "amplifier", "screw_nut"}
    assert all(validation_drive().get(p) > 0 for p in UNCERTAIN)


def test_fast_frf_equals_bscomp_frf():
    from bscomp.frf import frf as kernel_frf

    s = AmplifierDelay().apply(validation_drive(), T=3e-4)
    dae = flatten(s)
    H = FrfEvaluator(dae, PAIRS)(F, dae.p0)
    ref = kernel_frf(dae, input=["amp.u"], output=["rotor.w", "table.a"], freqs=F)
    assert np.allclose(H[PAIRS[0]], ref.H[:, 0, 0], rtol=1e-9)
    assert np.allclose(H[PAIRS[1]], ref.H[:, 1, 0], rtol=1e-9)


@pytest.mark.parametrize("cand", default_candidates(), ids=lambda c: c.name)
def test_every_candidate_applies_to_a_copy_and_flattens(cand):
    nominal = validation_drive()
    n_before = len(list(nominal.leaves()))
    s = cand.apply(nominal)
    assert len(list(nominal.leaves())) == n_before  # the nominal system is untouched
    dae = flatten(s)
    assert dae.nx >= 6
    for p in cand.parameters:
        assert 0 < p.lower < p.median < p.upper
    assert cand.signature and cand.title
    assert cand.code(cand.medians(), nominal)


def test_joint_compliance_lowers_the_axial_mode():
    def peak(system):
        h = np.abs(frf(system)[PAIRS[1]])
        sel = (F > 50) & (F < 200)
        return F[sel][np.argmax(h[sel])]

    f0 = peak(validation_drive())
    k_ax = validation_drive().get("axial.c")
    k_j = 3e8
    f1 = peak(NutTableJoint().apply(validation_drive(), k=k_j, d=1e3))
    # series stiffness: f1/f0 ~ sqrt(k_series / k_ax) (the table dominates the mode)
    assert abs(f0 - 117.7) < 3
    assert abs(f1 / f0 - math.sqrt(k_j / (k_j + k_ax))) < 0.04


def test_delay_is_all_pass_with_pade_phase():
    h0 = frf(validation_drive())[PAIRS[0]]
    T = 3e-4
    h1 = frf(AmplifierDelay().apply(validation_drive(), T=T))[PAIRS[0]]
    assert np.allclose(np.abs(h1), np.abs(h0), rtol=1e-8)
    x = 2 * np.pi * F * T
    pade2 = (1 - 1j * x / 2 - x**2 / 12) / (1 + 1j * x / 2 - x**2 / 12)
    assert np.allclose(h1 / h0, pade2, rtol=1e-8)
    # within 2 degrees of the exact delay up to omega T = 2 (module docstring)
    sel = x <= 2
    assert np.max(np.abs(np.angle(pade2[sel] * np.exp(1j * x[sel])))) < np.radians(2.0)


def test_pade_order_1_and_bad_order():
    from bscomp.components.pade_delay import PadeDelay

    h0 = frf(validation_drive())[PAIRS[0]]
    h1 = frf(AmplifierDelay(order=1).apply(validation_drive(), T=2e-4))[PAIRS[0]]
    x = 2 * np.pi * F * 2e-4
    assert np.allclose(h1 / h0, (1 - 1j * x / 2) / (1 + 1j * x / 2), rtol=1e-8)
    with pytest.raises(ParameterError):
        PadeDelay(order=3)


def test_backlash_is_invisible_in_frf_but_delays_the_time_response():
    cand = ScrewNutBacklash()
    s = cand.apply(validation_drive(), b=2e-5)
    assert cand.structure(validation_drive(), linear=True).get("axial.c") == validation_drive().get("axial.c")
    dt = 5e-4
    t = np.arange(401) * dt
    u = 2.125 * np.where(np.floor(10 * t + 1e-9) % 2 == 0, 1.0, -1.0)
    y = {}
    for key, sys_ in (("nominal", validation_drive()), ("backlash", s)):
        dae = flatten(sys_)
        y[key] = TimeSimulator(dae, dt, ["table.s", "rotor.phi"]).run(u[None, :], dae.p0)
    # the table lags the screw by about the clearance after the first reversal
    lag = (y["nominal"][0] - y["backlash"][0])[-50:]
    assert 0.3e-5 < np.mean(np.abs(lag)) < 4e-5


def test_parameter_scale_and_unknown_parameter():
    sc = ParameterScale("coupling.c")
    assert not sc.is_effect
    s = sc.apply(validation_drive(), factor=1.1)
    assert abs(s.get("coupling.c") / (1.1 * validation_drive().get("coupling.c")) - 1) < 1e-12
    with pytest.raises(UnknownNameError):
        NutTableJoint().apply(validation_drive(), q=1.0)


def test_compare_on_the_updated_system_shows_the_drop():
    """Adding the effects a diagnosis reports (bundled data: joint + friction) makes compare's error fall:
    the FRF is taken on the small-signal equivalent (friction viscous part only, backlash engaged)."""
    from pathlib import Path

    from bscomp.systems import get
    from bscomp.validate.candidates import GuidewayFriction, NutTableJoint
    from bscomp.validate.measurements import load_all
    from bscomp.validate.residuals import cost

    root = Path(__file__).resolve().parents[3] / "systems" / "data" / "validation"
    data = load_all([str(root / "frf.csv"), str(root / "time.csv")])
    nominal = get("validation_drive")
    s = nominal.with_parameters({"table.m": 264.3, "coupling.c": 3677.5, "guide.d": 12908.0})
    s = NutTableJoint().apply(GuidewayFriction().apply(s, F_c=2059.0), k=2.975e8, d=2158.0)
    before, after = cost(nominal, data), cost(s, data)
    assert before > 0.5
    assert after < 0.01 * before
