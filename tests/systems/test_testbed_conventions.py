"""Measured-channel conventions of the test bed (systems/testbed.py, issue 13 point 7).

* Input: the amplifier command voltage ``amp.u`` (Eq 4.1: tau = K_a K_t u, K_a = 6.4898 A/V,
  K_t = 0.4769 N m/A); ``drive_input="torque"`` keeps the torque ``motor.tau``.
* Signs: a positive command gives a positive motor angle and a positive table position, and
  ``table.s = r_g rotor.phi`` at low frequency (thesis Eq 4.2, G_x = r_g / s), for every drive variant,
  nut joint and coupling; the disturbance ``Fd.f`` pushes the table forward (G_d = r_g / (J s + B)).
"""

import math

import numpy as np
import pytest

from bscomp import ModelDefinitionError
from bscomp.linear.response import frf
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed import testbed as build

P = load_parameters("fadal_vmc2216_x")
K_A, K_T = get_value(P, "electrical.K_a"), get_value(P, "electrical.K_t")
R_G = get_value(P, "screw.lead") / (2 * math.pi)          # Eq 3.13: 1.5915e-3 m/rad
F = 0.5                                                    # Hz: rigid-body band (first mode at ~119 Hz)
OUT = ["rotor.phi", "table.s", "table.a"]


def _low_frequency(system, inp):
    return frf(system, input=inp, output=OUT, freqs=[F]).H[0, :, 0]


def _assert_forward(H, rtol=1e-4):
    """Positive command: the motor and the table accelerate forward, table.s = r_g rotor.phi."""
    w = 2 * math.pi * F
    phi, s, a = H
    assert (-w**2 * phi).real > 0              # motor acceleration in phase with the command
    assert (-w**2 * s).real > 0 and a.real > 0  # table position and acceleration likewise
    # r_g of the K_SN helix (R tan(alpha), alpha = 4.55 deg of Table 3.1) is 2.4e-5 above lead / 2 pi,
    # and the drive's compliance adds a few 1e-5 at 0.5 Hz
    np.testing.assert_allclose(s / phi, R_G, rtol=rtol)
    np.testing.assert_allclose(a, -w**2 * s, rtol=1e-7)


@pytest.mark.parametrize("variant,nut_joint,coupling", [
    ("axial_torsional", "point", "jaw"), ("axial_torsional", "moving", "jaw"),
    ("axial_torsional", "point", "bellows"), ("axial_torsional", "moving", "bellows"),
    ("full", "point", "jaw"), ("full", "moving", "jaw"),
])
def test_positive_voltage_moves_motor_and_table_forward(variant, nut_joint, coupling):
    s = build(variant, nut_joint=nut_joint, coupling=coupling)
    assert s.validation.inputs == ["amp.u"]
    _assert_forward(_low_frequency(s, "amp.u"))


@pytest.mark.parametrize("kw", [dict(motor_end="A"), dict(ksn="axial_torsional"), dict(nut_position="L"),
                                dict(viscous="guide")])
def test_sign_holds_for_the_layout_choices(kw):
    # viscous="guide": the guideway damper loads the compliant drive, a 3e-4 phase term at 0.5 Hz
    rtol = 1e-3 if "viscous" in kw else 1e-4
    _assert_forward(_low_frequency(build("axial_torsional", **kw), "amp.u"), rtol)


def test_voltage_input_is_the_torque_input_times_Ka_Kt():
    sv = build("axial_torsional")
    st = build("axial_torsional", drive_input="torque")
    f = np.array([0.5, 50.0, 118.0, 275.0, 900.0])
    Hv = frf(sv, input="amp.u", output=OUT, freqs=f).H
    Ht = frf(st, input="motor.tau", output=OUT, freqs=f).H
    np.testing.assert_allclose(Hv, K_A * K_T * Ht, rtol=1e-9, atol=0)   # Eq 4.1: G_e = K_a K_t = 3.095 N m/V
    assert sv.get("amp.K_a") == K_A and sv.get("kt.k") == K_T
    assert "Eq 4.1" in sv.sources["amp"] and "Eq 4.1" in sv.sources["kt"]
    assert "amp" not in {n for n, _ in st.leaves()} and st.validation.inputs == ["motor.tau"]
    _assert_forward(_low_frequency(st, "motor.tau"))


def test_disturbance_pushes_the_table_forward():
    """G_d = r_g / (J s + B) (Eq 4.2): a positive table force turns the motor forward too."""
    H = frf(build("axial_torsional"), input="Fd.f", output=OUT, freqs=[F]).H[0, :, 0]
    w = 2 * math.pi * F
    assert (-w**2 * H[0]).real > 0 and (-w**2 * H[1]).real > 0
    np.testing.assert_allclose(H[1] / H[0], R_G, rtol=1e-3)   # the force compresses the drive: 4e-4 at 0.5 Hz


def test_fe_coordinates_stay_in_screw_z():
    """The nut (screw z) moves opposite to the table (table axis = -z); the moving joint's sn.z0 is in z."""
    s = build("axial_torsional", nut_joint="moving")
    assert s.get("table_joint.direction") == -1.0
    H = frf(s, input="amp.u", output=["nut.com.w", "table.s"], freqs=[F]).H[0, :, 0]
    np.testing.assert_allclose(H[0], -H[1], rtol=1e-6)


def test_bad_drive_input_raises():
    with pytest.raises(ModelDefinitionError, match="drive_input"):
        build("axial_torsional", drive_input="current")
