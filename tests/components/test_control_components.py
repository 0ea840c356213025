"""Control components (Chapter 4): continuous blocks in the DAE and sampled blocks with memory."""

import numpy as np
import pytest

import bscomp
from bscomp import System, linearize
from bscomp.components import (
    CurrentAmplifier,
    Damper,
    DigitalPController,
    Fixed,
    FixedRotational,
    Force,
    Gain,
    Inertia,
    Mass,
    NotchFilter,
    PIController,
    RSTController,
    Saturation,
    Tachometer,
    Torque,
    TorsionalDamper,
)
from bscomp.control.design import notch, velocity_loop_tf

K_A, K_T, H_G, J, B = 6.4898, 0.4769, 0.0668, 8.55e-3, 0.0321  # Eq 4.1, Sec 4.2.1, Sec 4.3
K_V, K_I = 18.217, 4081.2  # Eq 4.14


def velocity_loop_system(**amp):
    """Fig 4.3 inner loop on the rigid drive (Eq 4.2): PI, amplifier, K_t, torque, J, B and tachometer."""
    s = System("velocity_loop")
    s.add("pi", PIController(K_v=K_V, K_i=K_I))
    s.add("amp", CurrentAmplifier(K_a=K_A, **amp))
    s.add("kt", Gain(k=K_T))
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J))
    s.add("loss", TorsionalDamper(d=B))
    s.add("ground", FixedRotational())
    s.add("tacho", Tachometer(H_g=H_G))
    s.connect("pi.y", "amp.u")
    s.connect("amp.i", "kt.u")
    s.connect("kt.y", "motor.tau")
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("rotor.flange_b", "loss.flange_a")
    s.connect("loss.flange_b", "ground.flange")
    s.connect("tacho.flange", "rotor.flange_a")
    s.connect("tacho.v", "pi.u_m")
    return s


def _response(sys, w):
    import control

    return np.squeeze(control.frequency_response(sys, w).complex)


def test_pi_loop_flattened_equals_eq_4_10():
    lin = linearize(velocity_loop_system(), inputs=["pi.u_s"], outputs=["rotor.w"])
    assert lin.nstates == 3  # rotor angle and speed, PI integrator
    ref = velocity_loop_tf(J, B, K_A, K_T, H_G, K_V, K_I)
    w = np.logspace(-1, 5, 80)
    h, h_ref = _response(lin, w), _response(ref, w)
    np.testing.assert_allclose(h, h_ref, rtol=1e-8)
    # integral action: w -> u_s / H_g at low frequency (the rotor angle is a free integrator, so no dcgain())
    assert abs(_response(lin, np.array([1e-4]))[()]) == pytest.approx(1 / H_G, rel=1e-6)


def test_pi_integrator_is_a_state_and_tachometer_gain():
    lin = linearize(velocity_loop_system(), inputs=["pi.u_s"], outputs=["tacho.v", "rotor.w", "pi.x_i"])
    assert "pi/x_i" in lin.state_labels
    np.testing.assert_allclose(lin.C[0], H_G * lin.C[1], rtol=1e-12)


def test_current_limit_is_linear_inside_and_open_outside():
    w = np.logspace(0, 4, 30)
    ref = _response(velocity_loop_tf(J, B, K_A, K_T, H_G, K_V, K_I), w)
    lin = linearize(velocity_loop_system(i_max=5.0), inputs=["pi.u_s"], outputs=["rotor.w"])
    np.testing.assert_allclose(_response(lin, w), ref, rtol=1e-8)
    # integrator state far beyond the limit: the amplifier saturates, the loop is open (no path u_s -> w)
    sat = linearize(velocity_loop_system(i_max=5.0), inputs=["pi.u_s"], outputs=["rotor.w"],
                    at={"pi.x_i": 1.0})
    assert np.max(np.abs(_response(sat, w))) < 1e-12


def _force_on_mass(sat):
    s = System("limited_force")
    s.add("sat", sat)
    s.add("F", Force())
    s.add("m", Mass(m=2.0))
    s.add("d", Damper(d=1.0))
    s.add("g", Fixed())
    s.connect("sat.y", "F.f")
    s.connect("F.flange", "m.flange_a")
    s.connect("m.flange_b", "d.flange_a")
    s.connect("d.flange_b", "g.flange")
    return s


@pytest.mark.parametrize("delta", [0.0, 0.1])
def test_saturation_gain_inside_corners_and_outside(delta):
    s = _force_on_mass(Saturation(y_max=1.0, y_min=-0.5, delta=delta))

    def gain(u):
        return linearize(s, inputs=["sat.u"], outputs=["m.a"], at={"sat.u": u}).D[0, 0] * 2.0

    assert gain(0.3) == pytest.approx(1.0, abs=1e-12)  # exactly linear inside the limits
    assert gain(-0.3) == pytest.approx(1.0, abs=1e-12)
    assert gain(2.0) == pytest.approx(0.0, abs=1e-12)
    assert gain(-1.0) == pytest.approx(0.0, abs=1e-12)
    if delta:  # C1 corner: slope 1/2 at the limit itself
        assert gain(1.0) == pytest.approx(0.5, abs=1e-12)


def test_saturation_bad_limits():
    with pytest.raises(bscomp.ParameterError):
        Saturation(y_max=1.0, y_min=2.0)
    with pytest.raises(bscomp.ParameterError):
        Saturation(y_max=1.0, delta=1.5)
    assert Saturation(y_max=3.0).get("y_min") == -3.0


def test_component_parameter_bounds():
    with pytest.raises(bscomp.ParameterError):
        CurrentAmplifier(K_a=-1.0)
    with pytest.raises(bscomp.ParameterError):
        Tachometer(H_g=0.0)
    with pytest.raises(bscomp.ParameterError):
        PIController(K_i=-1.0)


# ---- sampled blocks ----------------------------------------------------------------------------
def _forced(block, u):
    """Output of python-control's forced_response of the block's discrete TF (sum over inputs)."""
    import control

    G = block.tf()
    y = np.zeros(u.shape[1])
    for j in range(G.ninputs):
        y += np.squeeze(control.forced_response(G[0, j], U=u[j]).outputs)
    return y


def _blocks():
    c = notch(0.0855, 753.98, 0.5, 2.0e-4)
    R = np.polymul([1, -0.535], np.polymul([1, -1], [1, 0.5759, 0.5490, 0.2000]))
    S = np.polymul([1, 1], [3.0e8, -1.15e9, 1.67e9, -1.07e9, 2.6e8])
    T = 1.07e6 * np.array([1, -1.7849, 0.8057, 0, 0, 0])
    return [c.filter(), DigitalPController(7000.0), RSTController(R, S, T)]


@pytest.mark.parametrize("k", [0, 1, 2])
def test_step_matches_forced_response_of_same_tf(k):
    block = _blocks()[k]
    rng = np.random.default_rng(3)
    u = rng.standard_normal((len(block.inputs), 200)) * np.array([[1.0], [1e-3]])[: len(block.inputs)]
    y = block.simulate(u)
    y_ref = _forced(block, u)
    np.testing.assert_allclose(y, y_ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(y_ref)))
    # memory: after reset the same input gives the same output
    block.reset()
    np.testing.assert_allclose(block.simulate(u), y, rtol=0, atol=1e-9 * np.max(np.abs(y)))


@pytest.mark.parametrize("k", [0, 1, 2])
def test_state_space_realisation_equals_tf(k):
    block = _blocks()[k]
    w = np.logspace(0, np.log10(np.pi / block.T_s) - 1e-3, 40)
    for j in range(len(block.inputs)):
        np.testing.assert_allclose(_response(block.ss()[0, j], w), _response(block.tf()[0, j], w), rtol=1e-9)


def test_notch_unit_dc_gain_and_deep_notch():
    n = NotchFilter.design(0.0855, 753.98, 0.5, 2.0e-4)
    assert n.tf().dcgain() == pytest.approx(1.0, rel=1e-12)  # Eq 4.19
    # at the mode frequency the gain is the damping ratio quotient zeta_N/zeta_D (about -15 dB)
    g = abs(_response(n.tf(), np.array([753.98 * np.sqrt(1 - 2 * 0.0855**2)]))[()])
    assert 20 * np.log10(g) < -14.0


def test_sampled_block_errors():
    with pytest.raises(bscomp.ParameterError):
        DigitalPController(1.0, T_s=0.0)
    with pytest.raises(bscomp.ParameterError):
        RSTController([1.0, 0.5], [1.0, 0.0, 0.0], [1.0])  # deg S > deg R: not causal
    with pytest.raises(bscomp.ParameterError):
        NotchFilter(-1.95, 0.97, -1.9, 1.2)  # unstable denominator
    with pytest.raises(TypeError):
        DigitalPController(1.0).step(1.0)  # needs (r_k, y_k)
