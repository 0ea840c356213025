"""Bad arguments of bscomp.control (and sampled_controller) give a bscomp error naming the function and the
argument; valid calls give the same numbers as before the checks."""

import numpy as np
import pytest

from bscomp.components import DigitalPController
from bscomp.control.closed_loop import modal_plant, p_pi_loop, rigid_plant, rst_loop, velocity_loop
from bscomp.control.design import (
    diophantine,
    notch,
    pi_gains,
    ppc_polynomials,
    rst_design,
    split_polynomial,
    zoh_polynomials,
)
from bscomp.control.loop_analysis import freqresp, margins
from bscomp.errors import ArgumentTypeError, ParameterError, UsageError
from bscomp.simulation.sampled import sampled_controller
from bscomp.systems.parameters import get_value, load_parameters

P = load_parameters()
K_A, K_T, H_G = (get_value(P, f"electrical.{k}") for k in ("K_a", "K_t", "H_g"))
J, B, R_G, TS = (get_value(P, f"control.{k}") for k in ("J", "B", "r_g", "T_s"))
VEL = (K_A, K_T, H_G, 18.2, 4081.2)


@pytest.fixture(scope="module")
def rp():
    return rigid_plant(J, B, R_G)


def _raises(cls, *words):
    """pytest.raises(cls) whose message must contain every word."""
    class _Ctx:
        def __enter__(self):
            self.ctx = pytest.raises(cls)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            out = self.ctx.__exit__(*exc)
            msg = str(self.info.value)
            for w in words:
                assert w in msg, f"{w!r} not in {msg!r}"
            return out
    return _Ctx()


# ---- 1, 2, 6: design functions ---------------------------------------------------------------
def test_pi_gains_type_and_valid_result():
    with _raises(ArgumentTypeError, "pi_gains", "J", "real number"):
        pi_gains("a", B, K_A, K_T, H_G, wn=314.16, zeta=0.7071)
    with _raises(ArgumentTypeError, "pi_gains", "zeta"):
        pi_gains(J, B, K_A, K_T, H_G, wn=314.16, zeta=[0.7])
    with _raises(ParameterError, "pi_gains", "B"):
        pi_gains(J, -1.0, K_A, K_T, H_G, wn=314.16, zeta=0.7071)
    g = pi_gains(J, B, K_A, K_T, H_G, wn=314.16, zeta=0.7071)
    K = K_A * K_T * H_G
    assert g.K_v == pytest.approx((2 * 0.7071 * 314.16 * J - B) / K, rel=1e-14)
    assert g.K_i == pytest.approx(J * 314.16**2 / K, rel=1e-14)
    assert pi_gains(np.float64(J), B, K_A, K_T, H_G, wn=np.array(314.16), zeta=0.7071) == g


def test_ppc_polynomials_n_origin():
    args = (1.0, 565.49, 1.0, 0.7071, 763.43, TS)
    with _raises(UsageError, "ppc_polynomials", "n_origin", ">= 0"):
        ppc_polynomials(*args, n_origin=-1)
    with _raises(UsageError, "ppc_polynomials", "n_origin", "integer"):
        ppc_polynomials(*args, n_origin=1.5)
    with _raises(ArgumentTypeError, "ppc_polynomials", "n_origin"):
        ppc_polynomials(*args, n_origin="3")
    with _raises(ParameterError, "ppc_polynomials", "zeta_o"):
        ppc_polynomials(1.0, 565.49, 1.0, -0.7, 763.43, TS)
    p = ppc_polynomials(*args, n_origin=3)
    assert p.A_o.size == 6 and np.all(p.A_o[3:] == 0) and p.A_c.size == 4


def test_split_polynomial_near():
    P = np.polymul([1.0, -0.5], [1.0, 0.2])
    with _raises(ArgumentTypeError, "split_polynomial", "near"):
        split_polynomial(P, near="abc")
    with _raises(ArgumentTypeError, "split_polynomial", "near"):
        split_polynomial(P, near=None)
    with _raises(UsageError, "split_polynomial", "near", "2 roots"):
        split_polynomial(P, near=[0.5, 0.2, 0.1])
    with _raises(ParameterError, "split_polynomial", "P"):
        split_polynomial([3.0], near=0.5)
    plus, minus = split_polynomial(P, near=0.45)
    np.testing.assert_allclose(plus, [1.0, -0.5], atol=1e-14)
    np.testing.assert_allclose(minus, [1.0, 0.2], atol=1e-14)


# ---- 5: rst_design -----------------------------------------------------------------------------
def test_rst_design_bad_polynomials_and_valid_design():
    A, Bz, A_c = [1.0, -0.9], [0.0, 0.1], [1.0, -0.5]
    with _raises(ParameterError, "rst_design", "A", "empty"):
        rst_design([], [1.0], [1.0], [1.0])
    with _raises(ParameterError, "rst_design", "A", "NaN"):
        rst_design([1.0, np.nan], Bz, A_c, [1.0])
    with _raises(ParameterError, "rst_design", "A", "leading coefficient"):
        rst_design([0.0, 1.0], [0.0, 1.0], A_c, [1.0])
    with _raises(ParameterError, "rst_design", "A", "degree 0"):
        rst_design([2.0], [1.0], A_c, [1.0])
    with _raises(ArgumentTypeError, "rst_design", "B"):
        rst_design(A, "0.1", A_c, [1.0])
    with _raises(ParameterError, "rst_design", "B"):
        rst_design(A, [0.0, 0.0], A_c, [1.0])
    with _raises(ParameterError, "rst_design", "deg B"):
        rst_design(A, [1.0, 0.1, 0.2], A_c, [1.0])
    with _raises(ArgumentTypeError, "rst_design", "t0"):
        rst_design(A, Bz, A_c, [1.0], t0="x")
    d = rst_design(A, Bz, A_c, [1.0])  # first order: R = 1, S = s0 with (z - 0.9) + 0.1 s0 = z - 0.5
    np.testing.assert_allclose(d.R, [1.0], atol=1e-14)
    np.testing.assert_allclose(d.S, [4.0], rtol=1e-12)
    assert d.t0 == pytest.approx(5.0, rel=1e-12) and d.closed_loop_residual() < 1e-12


def test_diophantine_argument_types():
    with _raises(UsageError, "diophantine", "deg_x"):
        diophantine([1, -1], [0, 1], [1, 0, 0], -1, 0)
    with _raises(ArgumentTypeError, "diophantine", "c"):
        diophantine([1, -1], [0, 1], None, 1, 0)


# ---- 8: notch above Nyquist --------------------------------------------------------------------
def test_notch_nyquist_and_valid_coefficients():
    with _raises(UsageError, "notch", "omega_N", "Ts", "Nyquist", "15708"):
        notch(0.0855, 1e6, 0.5, TS)
    with _raises(UsageError, "notch", "omega_D", "Nyquist"):
        notch(0.0855, 753.98, 0.5, TS, omega_D=2e4)
    with _raises(ArgumentTypeError, "notch", "zeta_D"):
        notch(0.0855, 753.98, "0.5", TS)
    c = notch(0.0855, 753.98, 0.5, TS)  # Table 4.3
    x = 753.98 * TS
    assert c.n2 == pytest.approx(np.exp(-2 * 0.0855 * x), rel=1e-14)
    assert c.d2 == pytest.approx(np.exp(-2 * 0.5 * x), rel=1e-14)
    assert c.K_N == pytest.approx((1 + c.d1 + c.d2) / (1 + c.n1 + c.n2), rel=1e-14)


# ---- 7: modal_plant modes ----------------------------------------------------------------------
@pytest.mark.parametrize("modes, cls", [("abc", ArgumentTypeError), (42, ArgumentTypeError),
                                        ([(100.0, 0.05, 1.0)], UsageError), ([("a", 0.05, 1.0, 1.0)], UsageError),
                                        ([(100.0, 0.05, 1.0, 1.0, 2.0)], UsageError)])
def test_modal_plant_malformed_modes(modes, cls):
    with _raises(cls, "modal_plant", "(f_n [Hz], zeta, R_w, R_m)"):
        modal_plant(J, B, R_G, modes)


def test_modal_plant_valid_and_bad_numbers():
    with _raises(ParameterError, "modal_plant", "mode 1"):
        modal_plant(J, B, R_G, [(np.nan, 0.05, 1.0, 0.01)])
    with _raises(ArgumentTypeError, "modal_plant", "J"):
        modal_plant(None, B, R_G, [])
    p = modal_plant(J, B, R_G, [(120.0, 0.05, 0.8, 0.01)])
    q = modal_plant(J, B, R_G, np.array([[120.0, 0.05, 0.8, 0.01]]))
    np.testing.assert_array_equal(p.sys.A, q.sys.A)
    assert p.sys.A[3, 2] == pytest.approx(-(2 * np.pi * 120.0) ** 2) and p.sys.A[0, 0] == pytest.approx(-B / J)


# ---- 3, 4, 10: loops and margins ---------------------------------------------------------------
def test_velocity_loop_checks(rp):
    with _raises(ParameterError, "velocity_loop", "t_final", "> 0"):
        velocity_loop(rp, *VEL, t_final=0)
    with _raises(ParameterError, "velocity_loop", "t_final"):
        velocity_loop(rp, *VEL, t_final=-1)
    with _raises(ArgumentTypeError, "velocity_loop", "plant", "DrivePlant"):
        velocity_loop("small_drive", *VEL)
    with _raises(ArgumentTypeError, "velocity_loop", "K_i"):
        velocity_loop(rp, K_A, K_T, H_G, 18.2, None)
    r = velocity_loop(rp, *VEL)
    assert r.t_final == 0.05 and r.metrics["pm_deg"] == pytest.approx(65.62, abs=0.05)


def test_p_pi_loop_checks(rp):
    with _raises(ArgumentTypeError, "p_pi_loop", "K_p"):
        p_pi_loop(rp, *VEL, K_p="a", Ts=TS)
    with _raises(ArgumentTypeError, "p_pi_loop", "notch", "NotchFilter"):
        p_pi_loop(rp, *VEL, K_p=7000.0, Ts=TS, notch=42)
    with _raises(UsageError, "p_pi_loop", "t_final", "Ts"):
        p_pi_loop(rp, *VEL, K_p=7000.0, Ts=10.0)
    with _raises(ParameterError, "p_pi_loop", "Ts"):
        p_pi_loop(rp, *VEL, K_p=7000.0, Ts=np.nan)
    with _raises(ParameterError, "p_pi_loop", "dt"):  # a notch at another sampling period
        p_pi_loop(rp, *VEL, K_p=7000.0, Ts=TS, notch=notch(0.0855, 753.98, 0.5, 1e-4))
    c = notch(0.0855, 753.98, 0.5, TS)
    a = p_pi_loop(rp, *VEL, K_p=5000.0, Ts=TS, notch=c)
    b = p_pi_loop(rp, *VEL, K_p=5000.0, Ts=TS, notch=c.filter())
    assert a.metrics["pm_deg"] == pytest.approx(b.metrics["pm_deg"], rel=1e-9)


def test_rst_loop_checks():
    d = rst_design([1.0, -0.9], [0.0, 0.1], [1.0, -0.5], [1.0], Ts=TS)
    with _raises(ArgumentTypeError, "rst_loop", "design", "RSTDesign"):
        rst_loop(([1.0, -0.9], [0.0, 0.1]), "rst")
    with _raises(ArgumentTypeError, "rst_loop", "plant"):
        rst_loop("small_drive", d)
    with _raises(UsageError, "rst_loop", "t_final"):
        rst_loop(([1.0, -0.9], [0.0, 0.1]), d, t_final=1e-4)
    r = rst_loop(([1.0, -0.9], [0.0, 0.1]), d)
    _, y = r.step()
    np.testing.assert_allclose(y[:4], [0.0, 0.5, 0.75, 0.875], atol=1e-12)  # pole at z = 0.5, unit DC gain


def test_margins_and_freqresp():
    import control

    w = np.logspace(0, 4, 400)
    with _raises(ArgumentTypeError, "margins", "L", "LTI"):
        margins(None, [1.0, 2.0])
    with _raises(ParameterError, "margins", "w", "> 0"):
        margins(control.tf([1.0], [1.0, 1.0]), [0.0, 1.0])
    with _raises(UsageError, "freqresp", "SISO"):
        freqresp(control.ss(np.zeros((1, 1)), np.ones((1, 2)), np.ones((1, 1)), np.zeros((1, 2))), w)
    L = control.tf([1e4], [1.0, 100.0, 0.0])
    gm, pm, wpc, wgc = margins(L, w)
    ref = control.stability_margins(L)
    assert pm == pytest.approx(ref[1], abs=0.05) and wgc == pytest.approx(ref[4], rel=1e-3)
    np.testing.assert_allclose(freqresp(L, w), control.frequency_response(L, w).complex.ravel(), rtol=1e-10)


# ---- 9: sampled_controller ---------------------------------------------------------------------
def test_sampled_controller_checks():
    with _raises(ArgumentTypeError, "sampled_controller", "blocks", "SampledBlock"):
        sampled_controller(42, "table.s", "amp.u", 0.0)
    with _raises(ArgumentTypeError, "sampled_controller", "[block]"):
        sampled_controller(DigitalPController(7000.0), "table.s", "amp.u", 0.0)
    with _raises(ArgumentTypeError, "sampled_controller", "blocks[1]"):
        sampled_controller([DigitalPController(7000.0), "notch"], "table.s", "amp.u", 0.0)
    with _raises(ArgumentTypeError, "sampled_controller", "measure"):
        sampled_controller([DigitalPController(7000.0)], ["table.s"], "amp.u", 0.0)
    with _raises(ArgumentTypeError, "sampled_controller", "reference"):
        sampled_controller([DigitalPController(7000.0)], "table.s", "amp.u", "1 mm")
    with _raises(ParameterError, "sampled_controller", "measure_gain"):
        sampled_controller([DigitalPController(7000.0)], "table.s", "amp.u", 0.0, measure_gain=0)
    c = sampled_controller([DigitalPController(7000.0)], "table.s", "amp.u", 1e-3, measure_gain=-1)
    assert c.measure == ["table.s"] and c.actuate == ["amp.u"] and c.Ts == DigitalPController(1.0).T_s
    assert c.law(0.0, [0.0]) == [pytest.approx(-7.0)]  # g r - g y = -1e-3, times K_p


def test_zoh_polynomials_plant_type():
    with _raises(ArgumentTypeError, "zoh_polynomials", "plant"):
        zoh_polynomials("plant", TS)
