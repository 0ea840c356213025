"""The CMS-reduced test bed (thesis Sec 5.2.3 / 5.3.2, :mod:`bscomp.systems.reduced_testbed`) against its full FE
twin: modes, damping ratios, linear and nonlinear time responses with the moving nut, and convergence with
the number of kept modes (the truth is the unreduced 98-coordinate model, not built from the reduction)."""

import numpy as np
import pytest

from bscomp import flatten
from bscomp.linear import modes
from bscomp.simulation import simulate
from bscomp.systems import get
from bscomp.systems.reduced_testbed import reduce_testbed
from bscomp.systems.testbed import testbed as build
from bscomp.systems.thesis_effects import with_friction_backlash

AMP, F_SQ = 2.125, 5.0


def square(t):
    return AMP if (t * F_SQ) % 1.0 < 0.5 else -AMP


def nrmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(np.asarray(b) ** 2)))


@pytest.fixture(scope="module")
def linear_pair():
    full = build("axial_torsional", "C", nut_joint="moving")
    return full, {P: reduce_testbed(full, P) for P in (3, 20)}


def test_registered_and_sized_as_in_the_thesis():
    s = get("testbed_reduced")
    dae = flatten(s)
    # 6 reduced coordinates of sub-model 1 (E = 2, P = 3, one rigid-body mode; Sec 5.3.2) + the nut: 7 x 2 states
    assert dae.nx == 14
    assert {"rotor.phi", "table.a", "sn.z"} <= set(dae.observables)
    assert s.validation is not None and s.position_parameter == "sn.z0"


def test_modes_converge_to_the_full_model(linear_pair):
    full, reds = linear_pair
    mf = modes(full, warn=False)
    el_f = mf.frequencies[~mf.rigid_body][:3]
    for P, tol in ((3, 1e-2), (20, 3e-4)):
        mr = modes(reds[P][0], warn=False)
        el_r = mr.frequencies[~mr.rigid_body][:3]
        assert np.max(np.abs(el_r / el_f - 1)) < tol, (P, el_r, el_f)
        # the drive's ratios (Tables 4.1/4.2: 6 %, 10 %, 6 %) on the reduced drive's own modes
        assert mr.damping[~mr.rigid_body][:3] == pytest.approx([0.06, 0.10, 0.06], abs=5e-4)
        # the rigid-body inertia reflected at the motor shaft is untouched by the reduction (Eq 4.2)
        assert mr.reflected_inertia("rotor.phi") == pytest.approx(mf.reflected_inertia("rotor.phi"), rel=1e-9)


def test_linear_square_wave_converges(linear_pair):
    full, reds = linear_pair
    t = 1e-4 * np.arange(1501)
    outs = ["table.a", "table.v", "rotor.phi"]
    ref = simulate(full, t, inputs={"amp.u": square}, outputs=outs, method="lti")
    err = {P: {o: nrmse(simulate(s, t, inputs={"amp.u": square}, outputs=outs, method="lti")[o], ref[o])
               for o in outs} for P, (s, _) in reds.items()}
    assert err[3]["table.a"] < 5e-3 and err[3]["table.v"] < 1e-4          # thesis P = 3: "slight discrepancy"
    assert err[20]["table.a"] < 2e-4 and err[20]["table.a"] < err[3]["table.a"] / 10
    assert max(e["rotor.phi"] for e in err.values()) < 1e-5


@pytest.mark.slow
def test_moving_nut_with_friction_and_backlash_matches_the_full_model():
    """Ch 5 scenario (first 0.15 s): reduced (method="modal") against the full model (method="modal"); the
    modal method on the reduced model against IDAS rtol 1e-9 on the same reduced equations."""
    t = 1e-4 * np.arange(1501)
    outs = ["table.a", "table.v", "rotor.phi", "backlash.f", "sn.z"]
    full = with_friction_backlash(build("axial_torsional", "C", nut_joint="moving"))
    ref = simulate(full, t, inputs={"amp.u": square}, outputs=outs, method="modal")
    assert np.ptp(ref["sn.z"]) > 1e-3                                   # the nut travels across elements
    red3, _ = reduce_testbed(full, 3)
    r3 = simulate(red3, t, inputs={"amp.u": square}, outputs=outs, method="modal")
    assert nrmse(r3["table.v"], ref["table.v"]) < 1e-3
    assert nrmse(r3["rotor.phi"], ref["rotor.phi"]) < 1e-4
    assert nrmse(r3["table.a"], ref["table.a"]) < 0.1
    red20, _ = reduce_testbed(full, 20)
    r20 = simulate(red20, t, inputs={"amp.u": square}, outputs=outs, method="modal")
    assert nrmse(r20["table.a"], ref["table.a"]) < nrmse(r3["table.a"], ref["table.a"]) / 5
    ts = t[:301]
    idas = simulate(red3, ts, inputs={"amp.u": square}, outputs=outs, rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    for o, tol in (("table.v", 1e-4), ("rotor.phi", 1e-5), ("table.a", 1e-3)):
        assert nrmse(r3[o][:301], idas[o]) < tol, o


def test_idas_at_tight_tolerance_agrees_with_the_modal_method(linear_pair):
    """The superelement keeps its interior loads as unknowns, so every reduced coordinate carries its own inertia
    and IDAS converges at rtol 1e-9 (it could not when the loads were substituted: the modal rows then held only
    K_ii-sized terms); the moving-nut run equals method="modal" on the same equations."""
    s, _ = linear_pair[1][3]
    t = 1e-4 * np.arange(501)
    outs = ["table.a", "table.v", "rotor.phi"]
    ref = simulate(s, t, inputs={"amp.u": square}, outputs=outs, rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    r = simulate(s, t, inputs={"amp.u": square}, outputs=outs, method="modal")
    for o, tol in (("table.a", 2e-4), ("table.v", 1e-5), ("rotor.phi", 1e-7)):
        assert nrmse(r[o], ref[o]) < tol, (o, nrmse(r[o], ref[o]))


def test_position_sweep_follows_the_nut_without_re_reduction():
    """Sec 5.3.2: one reduction serves every nut position (MA recovery). The first axial mode at L, C, R from
    the reduced drive (position_sweep falls back to rebuilding: the superelement's mass matrix is not symmetric)
    against the full model's tangent sweep (Table 4.1: 109.5 / 117.7 / 133.8 Hz from the 6-DOF model)."""
    from bscomp.linear.sweeps import position_sweep
    from bscomp.systems.testbed import nut_positions

    pos = [nut_positions()[k] for k in "LCR"]
    red = position_sweep("testbed_reduced", pos, parameter="sn.z0", n_modes=3)
    full = position_sweep("testbed_axial_torsional", pos, parameter="sn.z0", n_modes=3,
                          overrides={"nut_joint": "moving"})
    assert red.stats["method"] == "rebuild" and full.stats["method"] == "tangent"
    assert red.frequencies[:, 0] == pytest.approx(full.frequencies[:, 0], rel=1e-3)
    # the modal damping is re-derived at every position from the reduced drive's own modes, as in the full model
    assert red.damping[:, :2] == pytest.approx(full.damping[:, :2], abs=2e-4)
    assert np.all(np.diff(red.frequencies[:, 0]) > 5.0)            # stiffer towards R (shorter screw span)
