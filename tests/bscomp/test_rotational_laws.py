"""Rotational nonlinear elements -- a friction torque (``RotationalFriction``: bearings, seals, a preloaded nut) and
the thesis's torsional backlash (``RotationalBacklash``, Sec 5.3.1 puts the clearance on the joint's torsional DOF)
-- in the fast paths: ``simulate(method="modal")`` and the compiled evaluator diagnose fits with
(:class:`~bscomp.simulation.compiled.CompiledModel`). Checked against an analytic spin-down, against the
translational twin of the same equations (a mass on ``CoulombFriction``: the same numbers to round-off) and against
IDAS at tight tolerance on a drive."""

import numpy as np
import pytest

from bscomp import System
from bscomp.components import (
    CoulombFriction,
    Fixed,
    FixedRotational,
    Force,
    Inertia,
    Mass,
    RotationalBacklash,
    RotationalFriction,
    Spring,
    Torque,
    TorqueBetween,
    TorsionalSpring,
)
from bscomp.simulation.compiled import CompiledModel, element_coordinates
from bscomp.simulation.dispatch import simulate
from bscomp.systems import get

OUTS = ["rotor.phi", "rotor.w", "table.s", "table.a"]


def _nrmse(a, b):
    b = np.asarray(b, float)
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def _square(t, amp=2.125):
    return amp * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)


def _oscillator(rotational: bool):
    """A body on a spring to ground with Coulomb + viscous friction to ground, driven at ``drive``: J = 0.02 kg m^2,
    c = 800 N m/rad, T_c = 1.5 N m, d = 0.05 N m s/rad, w_reg = 1e-3 rad/s -- or the same numbers as a mass, a
    spring, a force and ``CoulombFriction`` (m, c, F_c, d, v_reg)."""
    s = System("rot_oscillator" if rotational else "lin_oscillator")
    if rotational:
        s.add("ground", FixedRotational())
        s.add("body", Inertia(J=0.02))
        s.add("spring", TorsionalSpring(c=800.0))
        s.add("friction", RotationalFriction(T_c=1.5, d=0.05, w_reg=1e-3))
        s.add("drive", Torque())
    else:
        s.add("ground", Fixed())
        s.add("body", Mass(m=0.02))
        s.add("spring", Spring(c=800.0))
        s.add("friction", CoulombFriction(F_c=1.5, d=0.05, v_reg=1e-3))
        s.add("drive", Force())
    s.connect("ground.flange", "spring.flange_a")
    s.connect("spring.flange_b", "body.flange_a")
    s.connect("ground.flange", "friction.flange_a")
    s.connect("friction.flange_b", "body.flange_b")
    s.connect("drive.flange", "body.flange_a")
    return s


def test_a_friction_torque_spins_a_rotor_down_at_the_coulomb_rate():
    """A free rotor (J = 0.01 kg m^2) spinning at 10 rad/s against T_c = 0.5 N m decelerates at T_c / J = 50 rad/s^2
    and stops at t = J w0 / T_c = 0.2 s, then holds (Eq 5.7 for a torque): ``method="modal"`` follows the straight
    line to 1e-6 of w0 and the stop to the regularisation's creep."""
    s = System("spin_down")
    s.add("ground", FixedRotational())
    s.add("rotor", Inertia(J=0.01))
    s.add("bearing", RotationalFriction(T_c=0.5, w_reg=1e-4))
    s.connect("ground.flange", "bearing.flange_a")
    s.connect("bearing.flange_b", "rotor.flange_a")
    t = np.linspace(0.0, 0.3, 301)
    r = simulate(s, t, x0={"der(rotor.phi)": 10.0}, outputs=["rotor.w", "bearing.tau"], method="modal")
    sliding = t < 0.19
    np.testing.assert_allclose(r["rotor.w"][sliding], 10.0 - 50.0 * t[sliding], atol=1e-5)
    assert np.all(np.abs(r["rotor.w"][t > 0.21]) < 1e-3)
    assert r["bearing.tau"][sliding] == pytest.approx(np.full(sliding.sum(), 0.5), rel=1e-6)


@pytest.mark.parametrize("method", ["modal", "compiled"])
def test_a_friction_torque_is_the_translational_friction_with_its_names_changed(method):
    """The rotational oscillator and its translational twin (the same numbers as J, c, T_c or m, c, F_c) are the same
    equations: ``method="modal"`` and the compiled evaluator give the same response to 1e-9 of its range (a 10 Hz
    sine that makes the body stick and slip), and the evaluator cuts the element with a ``TorqueBetween``."""
    t = np.linspace(0.0, 0.2, 801)
    u = 3.0 * np.sin(2 * np.pi * 10.0 * t)
    out = {}
    for rot in (True, False):
        s = _oscillator(rot)
        ins = "drive.tau" if rot else "drive.f"
        q, w = ("body.phi", "body.w") if rot else ("body.s", "body.v")
        if method == "modal":
            r = simulate(s, t, inputs={ins: u}, outputs=[q, w], method="modal")
            out[rot] = (r[q], r[w])
        else:
            cm = CompiledModel(s, [ins], [q, w])
            assert element_coordinates(cm.elements[0].comp) == (("phi_rel", "w_rel") if rot else ("s_rel", "v_rel"))
            if rot:
                assert isinstance(cm.linear_system.component("friction"), TorqueBetween)
            Y = cm.simulate({}, t, {ins: u}, n_sub=8)
            out[rot] = (Y[q], Y[w])
    for a, b in zip(out[True], out[False], strict=True):
        assert np.ptp(b) > 0
        np.testing.assert_allclose(a, b, atol=1e-9 * np.ptp(b))
    stuck = np.abs(out[False][1]) < 1e-2
    assert 0.05 < stuck.mean() < 0.95              # it sticks and slips


def _drive_with_rotational_laws():
    """``validation_drive`` with a friction torque at the rotor (the bearings and the nut, 0.6 N m, ~27 % of the
    2.1 V square wave's motor torque) and the coupling's spring replaced by a torsional backlash of 1 mrad on the
    same stiffness (thesis Sec 5.3.1: the clearance on a torsional DOF)."""
    s = get("validation_drive")
    s.add("frame", FixedRotational())
    s.add("bearing_friction", RotationalFriction(T_c=0.6, d=1e-3, w_reg=3e-2))
    s.connect("frame.flange", "bearing_friction.flange_a")
    s.connect("bearing_friction.flange_b", "rotor.flange_a")
    c = s.get("coupling.c")
    s.remove("coupling")
    s.add("coupling", RotationalBacklash(b=1e-3, c=c, d=0.0, phi_rel0=-5e-4, eps=1e-4))
    s.connect("rotor.flange_b", "coupling.flange_a")
    s.connect("coupling.flange_b", "screw.flange_a")
    return s


@pytest.fixture(scope="module")
def drive_reference():
    s = _drive_with_rotational_laws()
    t = np.arange(0.0, 0.4, 2e-4)
    u = _square(t)
    ref = simulate(s, t, inputs={"amp.u": u}, outputs=OUTS + ["coupling.phi_rel"], rtol=1e-9, atol=1e-12,
                   max_num_steps=10**7)
    return s, t, u, ref


def test_the_modal_method_runs_a_drive_with_a_friction_torque_and_a_torsional_backlash(drive_reference):
    """Before, ``method="modal"`` refused such a drive ("nonlinear outside the friction/backlash elements"): now it
    agrees with IDAS at rtol 1e-9 -- measured: positions 9e-8, rotor speed 2.6e-6, table acceleration 1.7e-4
    (NRMSE; IDAS at its default rtol 1e-6: 1.9e-6, 2.1e-5, 4.4e-3) -- and the coupling crosses its clearance."""
    s, t, u, ref = drive_reference
    r = simulate(s, t, inputs={"amp.u": u}, outputs=OUTS + ["coupling.phi_rel"], method="modal")
    assert np.ptp(ref["coupling.phi_rel"]) > 1e-3                 # both flanks touched: the gap crossed
    for o, bound in (("rotor.phi", 1e-6), ("table.s", 1e-6), ("rotor.w", 2e-5), ("table.a", 1e-3)):
        assert _nrmse(r[o], ref[o]) < bound, o


def test_the_compiled_evaluator_fits_with_a_friction_torque_and_a_torsional_backlash(drive_reference):
    """The evaluator diagnose fits with takes both rotational elements (cut with ``TorqueBetween``, their small-signal
    equivalents a torsional damper and spring) and agrees with IDAS at rtol 1e-9 (measured: positions 3.8e-6, rotor
    speed 2.5e-6, table acceleration 4.9e-5 at 8 sub-steps); a change of the friction torque alone changes the
    response."""
    s, t, u, ref = drive_reference
    cm = CompiledModel(s, ["amp.u"], OUTS)
    assert sorted(e.path for e in cm.elements) == ["bearing_friction", "coupling"]
    Y = cm.simulate({}, t, {"amp.u": u}, n_sub=8)
    for o, bound in (("rotor.phi", 2e-5), ("table.s", 2e-5), ("rotor.w", 2e-5), ("table.a", 1e-3)):
        assert _nrmse(Y[o], ref[o]) < bound, o
    Y2 = cm.simulate({"bearing_friction.T_c_pos": 0.4, "bearing_friction.T_c_neg": 0.4}, t, {"amp.u": u}, n_sub=8)
    assert _nrmse(Y2["table.s"], Y["table.s"]) > 1e-2
