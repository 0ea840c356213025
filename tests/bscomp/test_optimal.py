"""Optimal control with Ipopt: analytic bang-bang case, re-simulation, drive OCP from a cold start."""

import math

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


def test_infeasible_problem_raises_named_error():
    ocp = (Ocp(rotor(), N=10).bound("motor.tau", -1, 1).bound("rotor.w", -1, 1)
           .initial({"rotor.phi": 0.0}).final({"rotor.phi": 10.0}).minimize_effort(T=0.1))
    with pytest.raises(OcpError, match="did not converge"):
        ocp.solve({"max_iter": 50})
