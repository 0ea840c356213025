"""Friction (Eq 5.6, 5.7) and backlash (Eq 5.8-5.9) against exact references (issue 6, item 2).

The friction laws are regularised (``tanh(v/v_reg)``, no events: casadi#4393), so every test measures
the regularisation error against an exact answer: the piecewise-analytic Coulomb oscillator, zero
motion below breakaway, energy balance, and the dead-zone hysteresis loop of width ``b``.
"""

import math

import numpy as np
import pytest

from bscomp import ParameterError, System
from bscomp.components import (
    Backlash,
    CoulombFriction,
    Damper,
    Fixed,
    FixedRotational,
    Force,
    Inertia,
    Mass,
    RotationalBacklash,
    Spring,
    StribeckFriction,
    TorsionalDamper,
    TorsionalSpring,
)
from bscomp.components.backlash import contact_force
from bscomp.simulation.dispatch import simulate

M, K = 1.0, 1.0e4  # oscillator: omega = 100 rad/s, half period 31.4 ms
W = math.sqrt(K / M)
HALF = math.pi / W


# ---- exact reference --------------------------------------------------------------------------------
def coulomb_oscillator_exact(t, x0, m, k, F_c_pos, F_c_neg, F_s_pos=None, F_s_neg=None):
    """Mass-spring with Coulomb friction released at rest from ``x0``: exact piecewise solution.

    Each half period the mass oscillates about the shifted equilibrium ``c = +F_c^-/k`` (moving in -x)
    or ``c = -F_c^+/k`` (moving in +x), so the turning point maps ``x_n -> 2c - x_n``; it sticks at the
    first turning point where the spring force cannot overcome the breakaway force ``F_s`` (default
    ``F_c``). Returns ``x(t)``, the turning points (``x0`` first) and the stick time.
    """
    F_s_pos = F_c_pos if F_s_pos is None else F_s_pos
    F_s_neg = F_c_neg if F_s_neg is None else F_s_neg
    w = math.sqrt(k / m)
    x = np.full_like(t, np.nan)
    turns, tn, xn = [x0], 0.0, x0
    while True:
        if xn > 0 and k * xn > F_s_neg:
            c = F_c_neg / k
        elif xn < 0 and -k * xn > F_s_pos:
            c = -F_c_pos / k
        else:
            x[t >= tn] = xn
            return x, np.array(turns), tn
        seg = (t >= tn) & (t <= tn + math.pi / w)
        x[seg] = c + (xn - c) * np.cos(w * (t[seg] - tn))
        xn, tn = 2 * c - xn, tn + math.pi / w
        turns.append(xn)


def turning_points(t, x, v):
    """Positions and times where the velocity changes sign (constant acceleration across the step)."""
    i = np.nonzero(np.sign(v[1:]) * np.sign(v[:-1]) < 0)[0]
    a = (v[i + 1] - v[i]) / (t[i + 1] - t[i])
    return x[i] - v[i] ** 2 / (2 * a), t[i] - v[i] / a


def oscillator(friction):
    s = System("coulomb_oscillator")
    s.add("wall", Fixed())
    s.add("k", Spring(c=K))
    s.add("m", Mass(m=M))
    s.add("fr", friction)
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("wall.flange", "fr.flange_a")
    s.connect("fr.flange_b", "m.flange_b")
    return s


def run_oscillator(friction, x0, t_end, dt=2.0**-12):
    # dt a power of two: the grid is exactly uniform, so simulate() integrates it in long chunks
    t = dt * np.arange(int(t_end / dt) + 2)
    r = simulate(oscillator(friction), t, x0={"m.s": x0}, outputs=["m.s", "m.v", "fr.f", "fr.power"])
    return t, r


# ---- Coulomb friction, Eq (5.7) ---------------------------------------------------------------------
@pytest.mark.parametrize("F_pos, F_neg", [(10.0, 10.0), (10.0, 7.0)])
def test_coulomb_oscillator_matches_exact_piecewise_solution(F_pos, F_neg):
    x0, v_reg = 10.5e-3, 1e-4  # sliding speeds 0.1 ... 1 m/s: v_reg / v >= 1e-4 ... 1e-3
    _, turns_ex, t_stick = coulomb_oscillator_exact(np.zeros(1), x0, M, K, F_pos, F_neg)
    friction = CoulombFriction(F_c_pos=F_pos, F_c_neg=F_neg, v_reg=v_reg)
    t, r = run_oscillator(friction, x0, t_stick + 1.5 * HALF)
    x_ex, _, _ = coulomb_oscillator_exact(t, x0, M, K, F_pos, F_neg)
    turns, t_turn = turning_points(t, r["m.s"], r["m.v"])
    n = len(turns_ex) - 1  # half periods of sliding
    assert n >= 4
    # decay per half period: exact 2 F_c^-/k moving in -x, 2 F_c^+/k in +x; regularisation error << 1 %
    decay = np.abs(turns_ex[:-1]) - np.abs(turns[:n])
    decay_ex = np.abs(turns_ex[:-1]) - np.abs(turns_ex[1:])
    np.testing.assert_allclose(decay_ex[::2], 2 * F_neg / K, rtol=1e-12)
    assert np.max(np.abs(decay / decay_ex - 1)) < 5e-3
    # half period pi sqrt(m/k), unchanged by Coulomb friction
    half_periods = np.diff(np.r_[0.0, t_turn[:n]])
    assert np.max(np.abs(half_periods[:-1] / HALF - 1)) < 1.5e-3
    assert abs(half_periods[-1] / HALF - 1) < 1e-2  # the last one ends in the creep of the stick phase
    # sticks at the exact turning point, inside the band |x| <= F_s/k, and stays there (creep only)
    assert abs(turns[n - 1] - turns_ex[-1]) < 1e-3 * x0
    stuck = r["m.s"][t > t_stick + 0.2 * HALF]
    assert np.all(np.abs(stuck) <= max(F_pos, F_neg) / K)
    assert np.max(np.abs(stuck - turns_ex[-1])) < 1e-3 * x0
    # whole trajectory
    assert np.max(np.abs(r["m.s"] - x_ex)) < 2e-3 * x0


def test_regularisation_error_shrinks_with_v_reg():
    """After sticking the regularised mass creeps back to x = 0 with time constant F_c / (k v_reg).

    The decay per half period hardly depends on v_reg (<= 1e-3 relative for v_reg <= 1e-2 m/s here);
    the stick phase does: 1e-2 m/s loses the stick position within a period, 1e-4 m/s holds it.
    """
    x0, F_c = 10.5e-3, 10.0
    drifts = []
    for v_reg in (1e-2, 1e-3, 1e-4):
        _, turns_ex, t_stick = coulomb_oscillator_exact(np.zeros(1), x0, M, K, F_c, F_c)
        t, r = run_oscillator(CoulombFriction(F_c=F_c, v_reg=v_reg), x0, t_stick + 2 * HALF)
        turns, _ = turning_points(t, r["m.s"], r["m.v"])
        n = len(turns_ex) - 1
        decay = (np.abs(turns_ex[:-1]) - np.abs(turns[:n])) / (2 * F_c / K)
        assert np.max(np.abs(decay - 1)) < 5e-3
        x_end, tau = r["m.s"][-1], F_c / (K * v_reg)
        assert x_end == pytest.approx(turns_ex[-1] * math.exp(-(t[-1] - t_stick) / tau), rel=0.05)
        drifts.append(abs(x_end - turns_ex[-1]) / abs(turns_ex[-1]))
    assert drifts[0] > 0.4 and drifts[1] < 0.07 and drifts[2] < 0.01


def test_energy_never_increases_and_balances_the_friction_work():
    x0 = 10.5e-3
    t, r = run_oscillator(CoulombFriction(F_c=10.0, d=20.0, v_reg=1e-4), x0, 5 * HALF)
    E = 0.5 * K * r["m.s"] ** 2 + 0.5 * M * r["m.v"] ** 2
    assert np.all(np.diff(E) <= 1e-9 * E[0])
    assert np.all(r["fr.power"] >= -1e-12)
    P = r["fr.power"]
    dissipated = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(t))])
    assert np.max(np.abs(E[0] - E - dissipated)) < 1e-3 * E[0]


def table_on_guideway(friction, F_max, T=1.0):
    """100 kg table on a friction guideway, pushed by a force ramped from 0 to F_max in T."""
    s = System("table")
    s.add("ground", Fixed())
    s.add("table", Mass(m=100.0))
    s.add("fr", friction)
    s.add("push", Force())
    s.connect("ground.flange", "fr.flange_a")
    s.connect("fr.flange_b", "table.flange_a")
    s.connect("push.flange", "table.flange_b")
    t = np.linspace(0.0, T, 201)
    return t, simulate(s, t, inputs={"push.f": lambda tt: F_max * tt / T}, outputs=["table.s", "table.v"])


@pytest.mark.parametrize("friction, F_break", [
    (CoulombFriction(F_c=2066.0, d=12673.0, v_reg=1e-5), 2066.0),  # Table 5.2
    (StribeckFriction(F_s=2500.0, F_c=2066.0, d=12673.0, v1=1e-3, v2=1e-3, v_reg=1e-5), 2500.0),
])
def test_friction_holds_table_below_breakaway_with_bounded_creep(friction, F_break):
    """Exact answer: no motion. Regularised: quasi-static creep v = v_reg artanh(F / F_break)."""
    v_reg, a = 1e-5, 0.9
    t, r = table_on_guideway(friction, a * F_break)
    v_creep_max = v_reg * math.atanh(a)  # 1.47 v_reg at 90 % of breakaway
    s_creep = v_reg * 1.0 * (math.atanh(a) + math.log(1 - a * a) / (2 * a))  # 0.549 v_reg T
    assert np.max(np.abs(r["table.v"])) < 1.05 * v_creep_max
    assert r["table.s"][-1] == pytest.approx(s_creep, rel=0.05)
    assert r["table.s"][-1] < 6e-6  # 5.5 um of creep in 1 s at 90 % of breakaway, v_reg = 10 um/s


# ---- Stribeck friction, Eq (5.6) --------------------------------------------------------------------
def test_stribeck_law_is_eq_5_6_away_from_zero_and_reduces_to_eq_5_7():
    fr = StribeckFriction(F_s_pos=15.0, F_s_neg=12.0, F_c_pos=10.0, F_c_neg=8.0, v1_pos=2e-3, v1_neg=1e-3,
                          v2_pos=5e-3, v2_neg=4e-3, d_pos=3.0, d_neg=2.0, v_reg=1e-6)
    for v in (1e-3, 4e-3, 2e-2, 0.3):
        eq56_pos = 15.0 * math.exp(-v / 2e-3) + 10.0 * (1 - math.exp(-v / 5e-3)) + 3.0 * v
        eq56_neg = 12.0 * math.exp(-v / 1e-3) + 8.0 * (1 - math.exp(-v / 4e-3)) + 2.0 * v
        assert float(fr.friction_force(v)) == pytest.approx(eq56_pos, rel=1e-9)
        assert float(fr.friction_force(-v)) == pytest.approx(-eq56_neg, rel=1e-9)
    coul = CoulombFriction(F_c_pos=10.0, F_c_neg=8.0, d_pos=3.0, d_neg=2.0, v_reg=1e-6)
    assert float(coul.friction_force(0.3)) == pytest.approx(10.0 + 0.9, rel=1e-12)
    assert float(coul.friction_force(-0.3)) == pytest.approx(-8.0 - 0.6, rel=1e-12)
    # breakaway: the largest force the regularised law resists is F_s (1 - O(v_reg/V1))
    v = np.linspace(0, 1e-3, 20001)
    peak = max(float(fr.friction_force(vv)) for vv in v)
    assert 15.0 * (1 - 0.01) < peak <= 15.0


def test_stribeck_oscillator_sticks_where_coulomb_would_slide():
    """F_c = 10 N, F_s = 15 N: the turning point at 1.2 mm (|k x| = 12 N) is inside the stick band."""
    x0 = 9.2e-3
    fr = StribeckFriction(F_s=15.0, F_c=10.0, v1=1e-3, v2=1e-3, v_reg=1e-5)
    t, r = run_oscillator(fr, x0, 6 * HALF)
    x_ex, turns_ex, t_stick = coulomb_oscillator_exact(t, x0, M, K, 10.0, 10.0, 15.0, 15.0)
    np.testing.assert_allclose(turns_ex, [9.2e-3, -7.2e-3, 5.2e-3, -3.2e-3, 1.2e-3], atol=1e-12)
    stuck = r["m.s"][t > t_stick + 0.2 * HALF]
    assert np.all(np.abs(stuck) <= 15.0 / K)
    # the Stribeck hump dissipates a little more near each reversal: within 2 % of the band
    assert np.max(np.abs(stuck - 1.2e-3)) < 0.02 * 15.0 / K
    assert np.max(np.abs(r["m.s"] - x_ex)) < 0.02 * x0


def test_friction_parameters_are_validated():
    with pytest.raises(ParameterError, match="below"):
        CoulombFriction(F_c_pos=10.0, F_c_neg=-2066.0)  # magnitudes, not the signed F_coul^- of Table 5.2
    with pytest.raises(ParameterError, match="> 0"):
        CoulombFriction(F_c=10.0, v_reg=0.0)
    with pytest.raises(ParameterError, match="> 0"):
        StribeckFriction(F_s=1.0, F_c=1.0, v1=0.0)


# ---- backlash, Eq (5.8)-(5.9) -----------------------------------------------------------------------
def test_dead_zone_force_law():
    b, c = 1e-3, 1e6
    for delta in (-3e-3, -0.6e-3, -0.2e-3, 0.0, 0.4e-3, 0.7e-3, 2e-3):
        exact = c * (abs(delta) - b / 2) * math.copysign(1, delta) if abs(delta) > b / 2 else 0.0
        assert float(contact_force(delta, 0.0, b, c, 0.0, 0.0)) == pytest.approx(exact, abs=1e-9)
        # smoothed corners: exact outside (b + eps)/2, zero inside (b - eps)/2
        assert float(contact_force(delta, 0.0, b, c, 0.0, 1e-5)) == pytest.approx(exact, abs=1e-9)
    # damping acts only in contact, is bounded by the elastic force and never pulls (no adhesion)
    assert float(contact_force(0.2e-3, 1.0, b, c, 1e3, 0.0)) == 0.0
    assert float(contact_force(0.6e-3, 0.01, b, c, 1e3, 0.0)) == pytest.approx(100.0 + 10.0)
    assert float(contact_force(0.6e-3, -1.0, b, c, 1e3, 0.0)) == 0.0
    assert float(contact_force(0.6e-3, 1.0, b, c, 1e3, 0.0)) == pytest.approx(200.0)
    assert float(contact_force(-0.6e-3, 0.01, b, c, 1e3, 0.0)) == pytest.approx(-100.0 + 10.0)
    assert float(contact_force(-0.6e-3, 1.0, b, c, 1e3, 0.0)) == 0.0


def loop_width(x_in, x_out, t, t_from):
    """Horizontal width of the output-vs-input loop at mid output height (one full cycle)."""
    sel = t >= t_from
    xi, xo, ti = x_in[sel], x_out[sel], t[sel]
    vi = np.gradient(xi, ti)
    level = 0.5 * (xo.max() + xo.min())

    def branch(mask):
        o = np.argsort(xo[mask])
        return np.interp(level, xo[mask][o], xi[mask][o])

    return branch(vi > 0) - branch(vi < 0)


def test_translational_backlash_hysteresis_loop_has_width_b():
    """A heavy 1 Hz oscillator drives, through the backlash, a mass on a viscous guide (Fig 5.5)."""
    b, A, M_in = 1e-3, 5e-3, 1.0e4
    s = System("backlash_loop")
    s.add("wall", Fixed())
    s.add("k_in", Spring(c=M_in * (2 * math.pi) ** 2))
    s.add("inp", Mass(m=M_in))
    s.add("bl", Backlash(b=b, c=1e8, d=1e4))
    s.add("out", Mass(m=1.0))
    s.add("guide", Damper(d=1e3))
    s.connect("wall.flange", "k_in.flange_a")
    s.connect("k_in.flange_b", "inp.flange_a")
    s.connect("inp.flange_b", "bl.flange_a")
    s.connect("bl.flange_b", "out.flange_a")
    s.connect("out.flange_b", "guide.flange_b")
    s.connect("wall.flange", "guide.flange_a")
    t = np.linspace(0.0, 2.0, 2001)
    r = simulate(s, t, x0={"inp.s": A, "out.s": A - b / 2}, outputs=["inp.s", "out.s", "bl.f"])
    width = loop_width(r["inp.s"], r["out.s"], t, 1.0)
    assert width == pytest.approx(b, rel=0.02)
    assert abs(width / b - 1) < 2e-3  # measured 0.06 %
    # in the gap the output stands still and carries no force
    gap = np.abs(r["inp.s"] - r["out.s"]) < 0.45 * b
    assert np.any(gap) and np.all(r["bl.f"][gap] == 0.0)


def test_rotational_backlash_hysteresis_loop_has_width_b():
    """Same loop on the torsional DOF with the test-bed clearance L = 0.001885 rad (Table 5.2)."""
    b, A, J_in = 0.001885, 0.01, 10.0
    s = System("rot_backlash_loop")
    s.add("frame", FixedRotational())
    s.add("k_in", TorsionalSpring(c=J_in * (2 * math.pi) ** 2))
    s.add("inp", Inertia(J=J_in))
    s.add("bl", RotationalBacklash(b=b, c=1e5, d=10.0))
    s.add("out", Inertia(J=1e-3))
    s.add("guide", TorsionalDamper(d=1.0))
    s.connect("frame.flange", "k_in.flange_a")
    s.connect("k_in.flange_b", "inp.flange_a")
    s.connect("inp.flange_b", "bl.flange_a")
    s.connect("bl.flange_b", "out.flange_a")
    s.connect("out.flange_b", "guide.flange_b")
    s.connect("frame.flange", "guide.flange_a")
    t = np.linspace(0.0, 2.0, 2001)
    r = simulate(s, t, x0={"inp.phi": A, "out.phi": A - b / 2}, outputs=["inp.phi", "out.phi"])
    width = loop_width(r["inp.phi"], r["out.phi"], t, 1.0)
    assert width == pytest.approx(b, rel=0.02)


def test_backlash_parameters_are_validated():
    with pytest.raises(ParameterError, match="below"):
        Backlash(b=-1e-6, c=1e8)
    with pytest.raises(ParameterError, match="> 0"):
        RotationalBacklash(b=1e-3, c=0.0)
