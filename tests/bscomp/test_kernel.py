"""Kernel: components -> System -> flatten -> Dae -> linearize, checked against analytic results."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse.linalg as spla

import bscomp
from bscomp import Component, Parameter, System, Variable, flatten, linearize, second_order
from bscomp.components import (
    Damper,
    Fixed,
    Force,
    Gain,
    IdealLeadScrew,
    Inertia,
    Mass,
    Spring,
    Torque,
    TorsionalDamper,
    VelocitySensor,
)
from bscomp.kernel.mechanics import start_matrices
from bscomp.kernel.partials import PartialCompliant
from bscomp.linear.modal import modes
from bscomp.systems import mass_spring_chain


def two_mass(m1=2.0, m2=3.0, k1=1.0e4, k2=2.5e4):
    return mass_spring_chain((m1, m2), (k1, k2), name="two_mass")


def analytic_two_mass(m1, m2, k1, k2):
    a = m1 * m2
    b = -(m1 * k2 + m2 * (k1 + k2))
    c = k1 * k2
    disc = math.sqrt(b * b - 4 * a * c)
    return sorted(math.sqrt(x) / (2 * math.pi) for x in ((-b - disc) / (2 * a), (-b + disc) / (2 * a)))


def freqs_of(so):
    ev = sl.eigh(so.K.toarray(), so.M.toarray(), eigvals_only=True)
    return np.sqrt(np.clip(ev, 0, None)) / (2 * np.pi)


def test_two_mass_frequencies_match_analytic():
    dae = flatten(two_mass())
    assert dae.x_names == ["m1.s", "m2.s", "der(m1.s)", "der(m2.s)"]
    f = freqs_of(second_order(dae))
    ref = analytic_two_mass(2.0, 3.0, 1.0e4, 2.5e4)
    np.testing.assert_allclose(f, ref, rtol=1e-9)
    # the first-order state space has the same eigenvalues
    lin = linearize(dae)
    w = np.sort(np.abs(np.linalg.eigvals(lin.A).imag))[::2] / (2 * np.pi)
    np.testing.assert_allclose(w, ref, rtol=1e-9)


def test_state_order_matches_names():
    lin = linearize(two_mass(), inputs=["F.f"], outputs=["m2.s"])
    labels = lin.state_labels
    i_v2, i_x1, i_x2 = labels.index("der(m2/s)"), labels.index("m1/s"), labels.index("m2/s")
    # m2 a = -k2 (x2 - x1) + F
    assert lin.A[i_v2, i_x1] == pytest.approx(2.5e4 / 3.0, rel=1e-12)
    assert lin.A[i_v2, i_x2] == pytest.approx(-2.5e4 / 3.0, rel=1e-12)
    assert lin.B[i_v2, 0] == pytest.approx(1 / 3.0, rel=1e-12)
    assert lin.C[0, i_x2] == 1.0


def test_parameters_passed_in_are_honoured():
    s = two_mass()
    f_default = freqs_of(second_order(s))
    so = second_order(s, params={"m2.m": 6.0, "k1.c": 4.0e4})
    np.testing.assert_allclose(freqs_of(so), analytic_two_mass(2.0, 6.0, 4.0e4, 2.5e4), rtol=1e-9)
    # the system itself is unchanged
    np.testing.assert_allclose(freqs_of(second_order(s)), f_default, rtol=1e-12)
    # on a Dae, non-structural parameters are passed through the p vector
    dae = flatten(s)
    lin = linearize(dae, params={"k2.c": 1.0e4})
    w = np.sort(np.abs(np.linalg.eigvals(lin.A).imag))[::2] / (2 * np.pi)
    np.testing.assert_allclose(w, analytic_two_mass(2.0, 3.0, 1.0e4, 1.0e4), rtol=1e-9)


class CubicSpring(PartialCompliant):
    """f = c1 s + c3 s^3: its tangent stiffness depends on the operating point."""

    c1 = Parameter(unit="N/m", positive=True)
    c3 = Parameter(unit="N/m3", min=0)

    def equations(self):
        return [self.f - self.c1 * self.s_rel - self.c3 * self.s_rel**3]


def test_operating_point_is_honoured():
    s = System("duffing")
    s.add("wall", Fixed())
    s.add("k", CubicSpring(c1=100.0, c3=1.0e6))
    s.add("m", Mass(m=1.0))
    s.add("F", Force())
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("F.flange", "m.flange_b")
    for x0 in (0.0, 0.01, 0.02):
        so = second_order(s, at={"m.s": x0})
        assert so.K.toarray()[0, 0] == pytest.approx(100.0 + 3e6 * x0**2, rel=1e-12)


def test_rigid_drive_transfer_function_is_eq_4_2():
    """Rotor - ideal lead screw - table: G(s) = 1/(J s + B), J = J_rotor + m r_g^2 (thesis Eq 4.2)."""
    J_r, m, lead, B = 5.98e-3, 250.0, 0.010, 0.0321
    r_g = lead / (2 * math.pi)
    s = System("rigid_drive")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J_r))
    s.add("screw", IdealLeadScrew(lead=lead))
    s.add("table", Mass(m=m))
    s.add("ground_rot", bscomp.components.FixedRotational())
    s.add("friction", TorsionalDamper(d=B))
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("rotor.flange_b", "screw.flange_a")
    s.connect("screw.flange_b", "table.flange_a")
    s.connect("friction.flange_a", "ground_rot.flange")
    s.connect("friction.flange_b", "rotor.flange_a")
    dae = flatten(s)
    assert dae.nx == 2  # one coordinate (rotor angle) and its velocity: the constraint is eliminated
    lin = linearize(dae, inputs=["motor.tau"], outputs=["rotor.w", "table.v"])
    J = J_r + m * r_g**2
    for f in (0.1, 1.0, 10.0, 100.0):
        s_ = 2j * math.pi * f
        H = lin(s_)
        assert H[0, 0] == pytest.approx(1 / (J * s_ + B), rel=1e-10)
        assert H[1, 0] == pytest.approx(r_g / (J * s_ + B), rel=1e-10)
    so = lin.second_order
    assert so.M.toarray()[0, 0] == pytest.approx(J, rel=1e-12)
    assert so.C.toarray()[0, 0] == pytest.approx(B, rel=1e-12)


def test_chain_of_1000_flattens_and_linearizes():
    """Fixed-free chain of N equal masses: w_k = 2 sqrt(k/m) sin((2k-1) pi / (2 (2N+1)))."""
    N, m, k = 1000, 0.1, 1.0e6
    s = mass_spring_chain([m] * N, [k] * N, first=0)
    dae = flatten(s)
    assert dae.nx == 2 * N and dae.nz == 0
    so = second_order(dae)
    assert so.M.nnz == N and so.K.nnz == 3 * N - 2
    ev = spla.eigsh(so.K.tocsc(), k=3, M=so.M.tocsc(), sigma=0, which="LM", return_eigenvectors=False)
    w = np.sort(np.sqrt(ev))
    ref = [2 * math.sqrt(k / m) * math.sin((2 * j - 1) * math.pi / (2 * (2 * N + 1))) for j in (1, 2, 3)]
    np.testing.assert_allclose(w, ref, rtol=1e-9)
    lin = linearize(dae, outputs=[f"m{N - 1}.s"])
    assert lin.A.shape == (2 * N, 2 * N)


def test_signal_feedback_equals_damper():
    """VelocitySensor -> Gain(-d) -> Force is the same physics as a Damper of constant d."""
    def build(feedback):
        s = System("fb")
        s.add("wall", Fixed())
        s.add("k", Spring(c=1.0e4))
        s.add("m", Mass(m=1.0))
        s.connect("wall.flange", "k.flange_a")
        s.connect("k.flange_b", "m.flange_a")
        if feedback:
            s.add("sensor", VelocitySensor())
            s.add("gain", Gain(k=-30.0))
            s.add("act", Force())
            s.connect("sensor.flange", "m.flange_b")
            s.connect("sensor.v", "gain.u")
            s.connect("gain.y", "act.f")
            s.connect("act.flange", "m.flange_b")
        else:
            s.add("d", Damper(d=30.0))
            s.connect("d.flange_a", "wall.flange")
            s.connect("d.flange_b", "m.flange_b")
        return s

    s1, s2 = second_order(build(True)), second_order(build(False))
    for a, b in ((s1.M, s2.M), (s1.C, s2.C), (s1.K, s2.K)):
        np.testing.assert_allclose(a.toarray(), b.toarray(), rtol=1e-12)
    assert s1.C.toarray()[0, 0] == pytest.approx(30.0, rel=1e-12)


def test_composite_system_as_component():
    inner = System("cell")
    inner.add("k", Spring(c=2.5e4))
    inner.add("m", Mass(m=3.0))
    inner.connect("k.flange_b", "m.flange_a")
    inner.expose("flange_a", "k.flange_a")
    inner.expose("flange_b", "m.flange_b")
    s = System("outer")
    s.add("wall", Fixed())
    s.add("k1", Spring(c=1.0e4))
    s.add("m1", Mass(m=2.0))
    s.add("cell", inner)
    s.connect("wall.flange", "k1.flange_a")
    s.connect("k1.flange_b", "m1.flange_a")
    s.connect("m1.flange_b", "cell.flange_a")
    s.set("cell.m.m", 3.0)
    f = freqs_of(second_order(s))
    np.testing.assert_allclose(f, analytic_two_mass(2.0, 3.0, 1.0e4, 2.5e4), rtol=1e-9)
    assert "cell.m.s" in flatten(s).x_names


class Lag(Component):
    """First-order lag y' = (u - y)/T: an internal differential state."""

    u = bscomp.kernel.ports.RealInput()
    y = bscomp.kernel.ports.RealOutput()
    x = Variable(start=0.0)
    T = Parameter(0.01, unit="s", positive=True)

    def equations(self):
        return [self.T * self.der(self.x) - (self.u.u - self.x), self.y.y - self.x]


def test_internal_states_linearize_and_have_no_second_order_form():
    s = System("lagged")
    s.add("lag", Lag())
    s.add("F", Force())
    s.add("m", Mass(m=2.0))
    s.add("wall", Fixed())
    s.add("k", Spring(c=800.0))
    s.connect("lag.y", "F.f")
    s.connect("F.flange", "m.flange_a")
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_b")
    lin = linearize(s, inputs=["lag.u"], outputs=["m.s"])
    assert lin.nstates == 3
    assert lin.second_order is None
    with pytest.raises(bscomp.NotLinearError):
        second_order(s)
    # DC gain: 1/k
    assert lin.dcgain() == pytest.approx(1 / 800.0, rel=1e-10)


def test_insert_a_compliance_between_connected_ports():
    """Insert a spring in series into the two-mass chain: frequencies follow the new series stiffness."""
    s = two_mass(k2=2.5e4)
    s.insert("joint", Spring(c=2.5e4), between=("m1.flange_b", "k2.flange_a"))
    # k2 in series with the joint: 1.25e4
    # the joint adds a massless node: modes() condenses it statically
    np.testing.assert_allclose(modes(s).frequencies, analytic_two_mass(2.0, 3.0, 1.0e4, 1.25e4), rtol=1e-9)
    s.remove("joint")
    s.connect("m1.flange_b", "k2.flange_a")
    np.testing.assert_allclose(freqs_of(second_order(s)), analytic_two_mass(2.0, 3.0, 1.0e4, 2.5e4), rtol=1e-9)
    with pytest.raises(bscomp.UnknownNameError, match="no connection"):
        s.disconnect("m1.flange_a", "m2.flange_b")


def test_kernel_imports_nothing_above_it():
    """Every kernel module imports only the kernel and bscomp.errors of bscomp (DESIGN.md layer table)."""
    kernel = Path(bscomp.__file__).parent / "kernel"
    bad = []
    for f in sorted(kernel.glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
            bad += [f"{f.name}: {n}" for n in names if n.split(".")[0] == "bscomp"
                    and not (n == "bscomp.errors" or n.startswith("bscomp.kernel"))]
    assert not bad


def test_start_matrices_are_the_undamped_second_order_form():
    """The M, K flattening gives a system damping are those of second_order at the start point."""
    dae = flatten(two_mass())
    M, K = start_matrices(dae)
    so = second_order(dae, inputs=[], outputs=[])
    np.testing.assert_array_equal(M.toarray(), so.M.toarray())
    np.testing.assert_array_equal(K.toarray(), so.K.toarray())
    np.testing.assert_allclose(np.sqrt(sl.eigh(K.toarray(), M.toarray(), eigvals_only=True)) / (2 * np.pi),
                               analytic_two_mass(2.0, 3.0, 1.0e4, 2.5e4), rtol=1e-9)
