"""Optimal control with Ipopt: analytic bang-bang case, re-simulation, drive OCP from a cold start."""

import math
import re

import numpy as np
import pytest

from bscomp import System
from bscomp.components import Inertia, Torque
from bscomp.optimal import Ocp, OcpError
from bscomp.systems import small_drive


def rotor():
    s = System("rotor")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=8.55e-3))
    s.connect("motor.flange", "rotor.flange_a")
    return s


def test_min_time_rigid_inertia_is_bang_bang():
    """|tau| <= tau_max, rest to rest over theta: T = 2 sqrt(theta J / tau_max)."""
    J, tau_max, theta = 8.55e-3, 5.0, 10.0
    r = (Ocp(rotor(), N=40).bound("motor.tau", -tau_max, tau_max)
         .initial({"rotor.phi": 0.0}).final({"rotor.phi": theta}).minimize_time(T_guess=0.5).solve())
    assert r.T == pytest.approx(2 * math.sqrt(theta * J / tau_max), rel=1e-3)
    u = r["motor.tau"]
    assert np.all(u[:18] > 0.99 * tau_max) and np.all(u[-18:] < -0.99 * tau_max)
    assert r.active["motor.tau"] > 0.9
    sim, _ = r.resimulate(outputs=["rotor.phi", "rotor.w"])
    assert sim["rotor.phi"][-1] == pytest.approx(theta, rel=1e-4)
    assert abs(sim["rotor.w"][-1]) < 1e-3 * theta / r.T


def test_drive_ocp_from_cold_start_respects_bounds_on_resimulation():
    r_g = 0.010 / (2 * math.pi)
    ocp = (Ocp(small_drive(), N=60).bound("motor.tau", -8, 8).bound("table.v", -0.2, 0.2)
           .initial({"table.s": 0.0})
           .final({"table.s": 0.05, "rotor.phi": 0.05 / r_g, "screw.phi": 0.05 / r_g})
           .minimize_time(T_guess=0.4))
    r = ocp.solve()
    assert r.stats["return_status"] == "Solve_Succeeded"
    # a velocity-limited move: at least the cruise time 0.05 m / 0.2 m/s
    assert r.T > 0.25
    sim, dev = r.resimulate(outputs=["table.s", "table.v"])
    assert sim["table.s"][-1] == pytest.approx(0.05, abs=2e-4)
    assert np.max(np.abs(sim["table.v"])) < 0.2 * 1.03
    assert dev["table.v"] < 0.05
    import matplotlib.pyplot as plt

    fig = r.plot()                                                # the axes carry the declared units
    assert [ax.get_ylabel() for ax in fig.axes] == ["table.v [m/s]", "motor.tau [N m]"]
    plt.close(fig)


def test_infeasible_problem_raises_named_error():
    ocp = (Ocp(rotor(), N=10).bound("motor.tau", -1, 1).bound("rotor.w", -1, 1)
           .initial({"rotor.phi": 0.0}).final({"rotor.phi": 10.0}).minimize_effort(T=0.1))
    with pytest.raises(OcpError, match="did not converge"):
        ocp.solve({"max_iter": 50})


@pytest.mark.parametrize("coordinates", ["physical", "modal", "modal-sparse"])
def test_infeasible_move_names_the_bound_the_time_and_the_violation(coordinates):
    """Issue 15: 10 rad in 0.1 s with |tau| <= 1 N m needs 171 N m: the error names the torque bound held
    (value, side, times), the constraint missed most (its variable, time, amount) -- from the last iterate."""
    ocp = (Ocp(rotor(), N=10, coordinates=coordinates).bound("motor.tau", -1, 1)
           .initial({"rotor.phi": 0.0}).final({"rotor.phi": 10.0}).minimize_effort(T=0.1))
    with pytest.raises(OcpError) as info:
        ocp.solve({"max_iter": 100})
    msg = str(info.value)
    assert "Largest infeasibility at the last iterate: " in msg
    assert re.search(r"'motor\.tau' at its upper bound 1 N m .*t = 0 s to 0\.04 s", msg)      # values with units
    assert re.search(r"'motor\.tau' at its lower bound -1 N m .*t = 0\.05 s to 0\.09 s", msg)
    worst = info.value.infeasibility["worst"]
    assert worst["violation"] > 0 and 0 <= worst["time"] <= 0.1 and worst["variable"] in msg
    # bang-bang at the bound still reaches only tau T^2 / (4 J) = 0.29 rad of the 10: the miss is of that order
    if coordinates == "modal":
        assert worst["constraint"] == "final value" and worst["variable"] == "rotor.phi" and worst["unit"] == "rad"
        assert re.search(r"final value of 'rotor\.phi' at t = 0\.1 s is off by [0-9.]+ rad", msg)
        assert worst["violation"] == pytest.approx(10.0 - 1.0 * 0.1 ** 2 / (4 * 8.55e-3), rel=0.05)
    sides = {(b["variable"], b["side"]): b["fraction"] for b in info.value.infeasibility["bounds"]}
    assert sides == {("motor.tau", "upper"): 0.5, ("motor.tau", "lower"): 0.5}


def test_infeasible_drive_move_names_a_variable_and_time():
    """The issue's case: a move too long for T on small_drive with a tight torque bound."""
    with pytest.raises(OcpError, match=r"Largest infeasibility at the last iterate: .* of '[^']+' at t = "
                       r"[0-9.e-]+ s is off by") as info:
        Ocp("small_drive", N=10).bound("motor.tau", -0.5, 0.5).initial({}).final({"table.s": 0.1}) \
            .minimize_effort(T=0.02).solve({"max_iter": 60})
    assert "'motor.tau' at its" in str(info.value)


# ---- the drive OCP on the CMS-reduced axial + torsional test bed (issue #7) --------------------------------
TAU_MAX, V_MAX, A_MAX, MOVE = 43.0, 1.0, 1.5 * 9.81, 0.1   # Sec 5.3.3 peak torque; Table 5.4; 100 mm


@pytest.fixture(scope="module")
def reduced_testbed():
    import bscomp
    from bscomp.components import SecondOrderBlock
    from bscomp.linear.reduction import reduce_second_order
    from bscomp.systems.testbed import testbed_axial_torsional

    # torque input: the OCP's limits are the motor's peak torque (Sec 5.3.3)
    so = bscomp.second_order(testbed_axial_torsional(drive_input="torque"), inputs=["motor.tau"],
                             outputs=["table.s", "table.v", "table.a", "rotor.phi"])
    red, _ = reduce_second_order(so, boundary=["rotor.phi", "sn.nut.w"], f_cut=2000.0)
    s = System("reduced_testbed")
    s.add("plant", SecondOrderBlock(red))
    return bscomp.flatten(s), f"plant.q{red.coordinates.index('sn.nut.w')}.q"


def _rigid_min_time(J, B, N=60):
    from bscomp.components import FixedRotational, TorsionalDamper

    s = System("rigid")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J))
    s.add("B", TorsionalDamper(d=B))
    s.add("ground", FixedRotational())
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("B.flange_a", "ground.flange")
    s.connect("B.flange_b", "rotor.flange_b")
    r_g = 0.010 / (2 * math.pi)
    return (Ocp(s, N=N).bound("motor.tau", -TAU_MAX, TAU_MAX).bound("rotor.w", -V_MAX / r_g, V_MAX / r_g)
            .initial({}).final({"rotor.phi": MOVE / r_g}).minimize_time(T_guess=0.2).solve().T)


def test_reduced_testbed_min_time_cold_start_meets_constraints_on_resimulation(reduced_testbed):
    """Cold start (no warm start, default T_guess) on the 6-coordinate CMS model with modes to 3 kHz.

    Tolerances: re-simulated (IDAS, rtol 1e-7) table position within 1e-3 of the move of the OCP's at
    every output time; velocity bound within 2 % and acceleration bound within 8 % between the collocation
    points (bounds are imposed at the collocation points only; the torque steps of the piecewise-constant
    input ring the elastic modes in between: 6.4 % over at N = 80, measured); final position within 10 µm.
    The optimal time is within 3 % of the rigid-body optimum (Eq 4.2 with B = 0.0321) for the same limits:
    the 119 Hz mode is far faster than the ~0.23 s move.
    """
    dae, q_nut = reduced_testbed
    N = 80
    # the nut coordinate is in screw z, the table axis is -z (systems/testbed.py): the table moves +MOVE
    r = (Ocp(dae, N=N).bound("plant.motor_tau", -TAU_MAX, TAU_MAX).bound("plant.table_v", -V_MAX, V_MAX)
         .bound("plant.table_a", -A_MAX, A_MAX).initial({}).final({q_nut: -MOVE}).minimize_time().solve())
    assert r.stats["return_status"] == "Solve_Succeeded"
    assert np.max(np.abs(r["plant.motor_tau"])) <= TAU_MAX * (1 + 1e-6)
    sim, dev = r.resimulate(outputs=["plant.table_s", "plant.table_v", "plant.table_a"], rtol=1e-7, atol=1e-10)
    assert dev["plant.table_s"] < 1e-3
    assert sim["plant.table_s"][-1] == pytest.approx(MOVE, abs=1e-5)
    assert np.max(np.abs(sim["plant.table_v"])) <= V_MAX * 1.02
    assert np.max(np.abs(sim["plant.table_a"])) <= A_MAX * 1.08
    # the same input on the full 98-DOF model the reduced one came from (exact ZOH: it is linear): the
    # reduction (modes to 2 kHz + boundary DOF, Sec 5.2.3) keeps the OCP's prediction within 1e-3 of the move
    from bscomp.systems.testbed import testbed_axial_torsional

    names = {"plant.motor_tau": "motor.tau", "plant.table_s": "table.s", "plant.table_v": "table.v"}
    sim_full, dev_full = r.resimulate(testbed_axial_torsional(drive_input="torque"),
                                      outputs=["plant.table_s", "plant.table_v"], names=names, method="lti")
    assert dev_full["plant.table_s"] < 1e-3
    assert sim_full["table.s"][-1] == pytest.approx(MOVE, abs=1e-5)
    assert np.max(np.abs(sim_full["table.v"])) <= V_MAX * 1.02
    # rigid-body inertia of the model along its rigid mode (rotor angle 1 rad)
    M = dae.mech.M.toarray() if hasattr(dae.mech.M, "toarray") else np.asarray(dae.mech.M)
    K = dae.mech.K.toarray() if hasattr(dae.mech.K, "toarray") else np.asarray(dae.mech.K)
    import scipy.linalg as sla
    lam, V = sla.eigh(K, M)
    phi = V[:, 0] / V[0, 0]
    T_rigid = _rigid_min_time(float(phi @ M @ phi), 0.0321)
    assert r.T == pytest.approx(T_rigid, rel=0.03)


# ---- residual-vibration limit and modal coordinates (issue #7) ---------------------------------------------------
def _small_drive_min_time(coordinates="physical", limit=None, N=40):
    import bscomp

    ocp = (Ocp(bscomp.flatten(small_drive()), N=N, coordinates=coordinates).bound("motor.tau", -8, 8)
           .bound("table.v", -0.2, 0.2).initial({}).final({"table.s": 0.05}, rest=True).minimize_time(T_guess=0.4))
    if limit is not None:
        ocp.limit_residual_vibration({"table.s": limit}, hold={"motor.tau": 0.0})
    return ocp


def _residual_after_arrival(r):
    """Max |table.s(t) - table.s(inf)| for t >= T with the torque released at T (re-simulation with
    ``simulate(method="lti")``, exact zero-order-hold stepping of this linear model).

    table.s(inf): the end of a 6 s run -- the slowest mode (table on its guide damping, -3.8 1/s) has then
    decayed by e^-23."""
    from bscomp.simulation.dispatch import simulate

    f = r.input_function("motor.tau")
    t = np.unique(np.r_[np.linspace(0, r.T, 401), np.linspace(r.T, r.T + 0.2, 4001), np.linspace(r.T + 0.2, 6.0, 2000)])
    sim = simulate(r.dae, t, inputs={"motor.tau": lambda tt: f(tt) if tt < r.T else 0.0}, outputs=["table.s"],
                   method="lti")
    s = sim["table.s"]
    return float(np.max(np.abs(s[sim.t >= r.T] - s[-1])))


def test_residual_vibration_limit_holds_on_resimulation():
    """Min time, rest at arrival, then the torque released: the unconstrained optimum rings (its last
    intervals are at full braking torque); with the limit, the re-simulated residual amplitude is within it."""
    r0 = _small_drive_min_time().solve()
    amp0 = _residual_after_arrival(r0)
    limit = 0.25 * amp0                        # the unconstrained optimum violates it by 4x
    r = _small_drive_min_time(limit=limit).solve()
    assert r.stats["return_status"] == "Solve_Succeeded"
    assert r.residual["table.s"] <= limit * (1 + 1e-6)        # the certified bound at the optimum
    amp = _residual_after_arrival(r)
    assert amp <= limit
    assert amp0 > limit
    assert r.T >= r0.T * (1 - 1e-9)             # a constraint cannot shorten the minimum time


def test_residual_vibration_hold_without_equilibrium_is_an_error():
    """A torque held on a drive whose rigid body is free (only viscous guide damping) has no rest state."""
    ocp = _small_drive_min_time(limit=1e-6)
    ocp.limit_residual_vibration({"table.s": 1e-6}, hold={"motor.tau": 1.0})
    with pytest.raises(OcpError, match="no equilibrium"):
        ocp.solve()


def test_modal_coordinates_give_the_same_optimum():
    """coordinates='modal' is an exact change of state coordinates with the states eliminated by solving the
    same Radau IIA equations block by block: the optimum (T, inputs, states mapped back) equals the one in
    the model's coordinates to solver tolerance, with and without a residual-vibration limit."""
    rp = _small_drive_min_time().solve()
    rm = _small_drive_min_time("modal").solve()
    assert rm.stats["coordinates"] == "modal" and rm.stats["n_unknowns"] == 40 + 1     # N inputs and T
    assert rm.T == pytest.approx(rp.T, rel=1e-6)
    assert np.max(np.abs(rm["motor.tau"] - rp["motor.tau"])) < 1e-4 * 8
    scale = np.max(np.abs(rp.x), axis=0) + 1e-12
    assert np.max(np.abs(rm.x - rp.x) / scale) < 1e-5
    vel = [i for i, n in enumerate(rm.x_names) if n.startswith("der(")]
    assert np.max(np.abs(rm.x[-1, vel]) / scale[vel]) < 1e-8
    lim = 2e-6
    rp2 = _small_drive_min_time(limit=lim).solve()
    rm2 = _small_drive_min_time("modal", limit=lim).solve()
    assert rm2.T == pytest.approx(rp2.T, rel=1e-6)
    assert rm2.residual["table.s"] == pytest.approx(rp2.residual["table.s"], rel=1e-4)


def test_rest_below_hz_puts_the_slow_modes_at_equilibrium():
    """final(rest_below_hz=f): the modes slower than f end at their static values under the held input, so
    releasing the torque at T leaves only the faster modes' vibration; here f is above every mode (294 Hz),
    so the re-simulated table moves after arrival only by the collocation error of the move (h = 11 ms against
    the 3.4 ms period of the 294 Hz mode at N = 40): far less than the ringing of velocities-only rest."""
    import bscomp

    ocp = (Ocp(bscomp.flatten(small_drive()), N=40, coordinates="modal").bound("motor.tau", -8, 8)
           .bound("table.v", -0.2, 0.2).initial({}).final({"table.s": 0.05}, rest_below_hz=1000.0)
           .minimize_time(T_guess=0.4))
    r = ocp.solve()
    r0 = _small_drive_min_time().solve()
    assert r.T > r0.T                       # stricter than velocities-only rest
    assert _residual_after_arrival(r) < 0.05 * _residual_after_arrival(r0)


def test_sparse_modal_transcription_gives_the_same_optimum():
    """coordinates='modal-sparse' keeps the modal collocation states as (scaled) variables with the Radau IIA
    equations as sparse constraints -- the form coordinates='modal' picks for large models: the optimum equals
    the physical-coordinate one to solver tolerance, mapped back to the model's states (re-simulation works),
    with and without a residual-vibration limit."""
    rp = _small_drive_min_time().solve()
    rs = _small_drive_min_time("modal-sparse").solve()
    assert rs.stats["transcription"] == "sparse"
    assert rs.stats["n_unknowns"] == 40 + 1 + 6 * 40 * 3               # inputs, T and the stage states
    assert rs.T == pytest.approx(rp.T, rel=1e-6)
    assert np.max(np.abs(rs["motor.tau"] - rp["motor.tau"])) < 1e-4 * 8
    scale = np.max(np.abs(rp.x), axis=0) + 1e-12
    assert np.max(np.abs(rs.x - rp.x) / scale) < 1e-5
    assert rs.x_names == rp.x_names
    _, dev = rs.resimulate(outputs=["table.s"])
    assert dev["table.s"] < 1e-2
    lim = 2e-6
    rp2 = _small_drive_min_time(limit=lim).solve()
    rs2 = _small_drive_min_time("modal-sparse", limit=lim).solve()
    assert rs2.T == pytest.approx(rp2.T, rel=1e-6)
    assert rs2.residual["table.s"] == pytest.approx(rp2.residual["table.s"], rel=1e-4)
    assert _small_drive_min_time("modal").solve().stats["transcription"] == "condensed"   # 6 states: condensed


def _jerk_limited(N, J=1.0, tau_max=1.0, j_max=2.0, theta=2.0, on="rotor.a"):
    s = System("rotor_j")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J))
    s.connect("motor.flange", "rotor.flange_a")
    limit = j_max if on == "rotor.a" else J * j_max          # torque slew rate equivalent to the jerk limit
    return (Ocp(s, N=N).bound("motor.tau", -tau_max, tau_max).bound_rate(on, limit)
            .initial({"rotor.phi": 0.0}).final({"rotor.phi": theta}).minimize_time(T_guess=3.0).solve())


def test_jerk_limited_min_time_converges_to_the_analytic_move():
    """Rest-to-rest move of a rigid inertia with |a| <= a_max (torque bound) and |jerk| <= j (bound_rate).

    The time-optimal profile (no velocity limit) is jerk +j, 0, -j for the acceleration phase and its
    mirror for the deceleration, with t_j = a/j and a constant-acceleration time t_a from
    theta = a (t_j + t_a)(2 t_j + t_a): T = 2 (2 t_j + t_a) = 3.3723 s for J = 1, a = 1, j = 2, theta = 2.
    The transcription's torque staircase (steps <= J j h) leads the ramp by O(h): T is first order in h
    (measured -0.98 % at N = 100, -0.49 % at N = 200). A torque slew-rate limit J j on the input is the
    same constraint for a rigid inertia.
    """
    J, a, j, theta = 1.0, 1.0, 2.0, 2.0
    tj = a / j
    ta = (-3 * tj + math.sqrt(tj**2 + 4 * theta / a)) / 2
    T_an = 2 * (2 * tj + ta)
    r100, r200 = _jerk_limited(100), _jerk_limited(200)
    assert r200.T == pytest.approx(T_an, rel=1e-2)
    e100, e200 = abs(r100.T - T_an), abs(r200.T - T_an)
    assert 1.6 < e100 / e200 < 2.4                            # first-order convergence
    u, h = r200["motor.tau"], r200.T / 200
    steps = np.abs(np.diff(np.r_[0.0, u, 0.0]))               # from rest, and back to the released torque
    assert steps.max() <= J * j * h * (1 + 1e-6)
    assert r200.active["rate:rotor.a"] > 0.3 and np.max(np.abs(u)) == pytest.approx(a * J, rel=1e-6)
    r_u = _jerk_limited(200, on="motor.tau")
    assert r_u.T == pytest.approx(r200.T, rel=1e-6)
    sim, _ = r200.resimulate(outputs=["rotor.phi", "rotor.w"])
    assert sim["rotor.phi"][-1] == pytest.approx(theta, rel=1e-4)


def test_rate_limit_is_refused_in_modal_coordinates():
    s = System("rotor_m")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=1.0))
    s.connect("motor.flange", "rotor.flange_a")
    ocp = (Ocp(s, N=20, coordinates="modal").bound("motor.tau", -1, 1).bound_rate("rotor.a", 2.0)
           .initial({"rotor.phi": 0.0}).final({"rotor.phi": 1.0}).minimize_time(T_guess=2.0))
    with pytest.raises(OcpError, match="physical"):
        ocp.solve()
    with pytest.raises(ValueError, match="> 0"):
        ocp.bound_rate("rotor.a", 0.0)


# ---- the optimal package: collocation tables, model forms, warm start from a simulation (issue 14) -----------
def _hand_written_radau(d):
    """The Radau IIA tables the transcription used to build by hand (Lagrange basis on [0, tau_1..tau_d]):
    ``C[j, r] = l_j'(tau_r)`` and the quadrature weights ``B[j-1] = ∫_0^1 l_j``."""
    import casadi as ca

    tau = np.append(0.0, ca.collocation_points(d, "radau"))
    C, B = np.zeros((d + 1, d + 1)), np.zeros(d)
    for j in range(d + 1):
        p = np.poly1d([1.0])
        for r in range(d + 1):
            if r != j:
                p *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        dp = np.polyder(p)
        C[j] = [dp(t) for t in tau]
        if j:
            P = np.polyint(p)
            B[j - 1] = P(1.0) - P(0.0)
    return tau, C, B


@pytest.mark.parametrize("d", [1, 2, 3, 4, 5])
def test_collocation_matrices_from_casadi_match_the_hand_written_radau_tables(d):
    """casadi.collocation_coeff gives the tables the hand-written Lagrange construction gave (derivative
    weights at the collocation points, end value = last stage, quadrature weights), and they are what Radau
    IIA must be: exact derivatives of polynomials up to degree d, quadrature exact up to degree 2d - 2 (d >= 2;
    at d = 1 both give the weight 1/2, see RadauScheme)."""
    from bscomp.optimal.collocation import radau

    s = radau(d)
    tau, C_old, B_old = _hand_written_radau(d)
    assert s.C.shape == (d + 1, d) and s.D.shape == (d + 1,) and s.B.shape == (d,)
    np.testing.assert_allclose(s.tau, tau, rtol=0, atol=1e-15)
    np.testing.assert_allclose(s.C, C_old[:, 1:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(s.B, B_old, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(s.D, np.eye(d + 1)[-1], atol=1e-12)
    assert tau[-1] == pytest.approx(1.0, abs=1e-15)
    for m in range(d + 1):                                  # d/dt t^m at the collocation points
        np.testing.assert_allclose(tau**m @ s.C, m * tau[1:] ** max(m - 1, 0) if m else 0.0, atol=1e-10)
    for m in range(2 * d - 1 if d >= 2 else 0):             # ∫_0^1 t^m = 1 / (m + 1)
        assert s.B @ tau[1:] ** m == pytest.approx(1.0 / (m + 1), rel=1e-12)


def test_ocp_accepts_every_model_form(tmp_path):
    """Ocp(model) resolves its model through bscomp.model.as_dae: a registered name, a .py path, a build
    function, a System, a Dae and a ModelSpec give the same problem (same states, same parameter vector with
    the overrides applied; build keywords for the forms that build), and the same optimum."""
    import bscomp
    from bscomp.model import ModelSpec

    path = tmp_path / "my_drive.py"
    path.write_text("from bscomp.systems import small_drive\n\n\ndef build(k_T=3938.0):\n"
                    "    return small_drive(k_T=k_T)\n")
    built = {"k_T": 5000.0, "table.m": 30.0}
    dotted = {"table.m": 30.0}
    forms = [("small_drive", built), (str(path), built), (small_drive, built), (ModelSpec("small_drive"), built),
             (small_drive(k_T=5000.0), dotted), (bscomp.flatten(small_drive(k_T=5000.0)), dotted)]
    ocps = [Ocp(m, N=30, params=p) for m, p in forms]
    ref = ocps[-1]
    assert ref.p[ref.dae.p_names.index("table.m")] == 30.0
    assert not np.array_equal(ref.p, bscomp.flatten(small_drive()).parameter_vector({}))
    for o in ocps:
        assert o.dae.x_names == ref.dae.x_names and o.dae.u_names == ref.dae.u_names
        np.testing.assert_array_equal(o.p, ref.p)
    T = [o.bound("motor.tau", -8, 8).initial({}).final({"table.s": 0.02}).minimize_time(T_guess=0.3).solve().T
         for o in (ocps[0], ref)]
    assert T[0] == pytest.approx(T[1], rel=1e-9)
    with pytest.raises(OcpError, match="did not converge"):     # still the same named errors
        Ocp("small_drive", N=10).bound("motor.tau", -1e-3, 1e-3).initial({}).final({"table.s": 0.1}) \
            .minimize_effort(T=0.01).solve({"max_iter": 20})


def test_warm_start_from_a_simulation():
    """A simulation of a hand-made input (bang-bang switched at the wrong time) is a warm start: the solve
    finds the same bang-bang optimum as from a cold start; a simulation of another model is refused."""
    from bscomp.errors import UnknownNameError
    from bscomp.simulation.dispatch import simulate

    J, tau_max, theta = 8.55e-3, 5.0, 10.0
    T_an = 2 * math.sqrt(theta * J / tau_max)
    t = np.linspace(0.0, 0.3, 301)
    sim = simulate(rotor(), t, inputs={"motor.tau": lambda tt: tau_max if tt < 0.12 else -tau_max},
                   outputs=["rotor.phi"])
    ocp = (Ocp(rotor(), N=40).bound("motor.tau", -tau_max, tau_max).initial({"rotor.phi": 0.0})
           .final({"rotor.phi": theta}).minimize_time())
    r = ocp.warm_start(sim).solve()
    assert ocp.warm.T == pytest.approx(0.3) and ocp.warm.u.shape == (300, 1)
    assert r.T == pytest.approx(T_an, rel=1e-3)
    load = System("load")
    load.add("drive", Torque())
    load.add("load", Inertia(J=1.0))
    load.connect("drive.flange", "load.flange_a")
    other = simulate(load, np.linspace(0, 0.01, 11), outputs=["load.phi"])
    with pytest.raises(UnknownNameError, match="warm start"):
        ocp.warm_start(other)
