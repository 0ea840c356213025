"""6-DOF moving screw-nut interface (Sec 5.2.2.3 with Eq 3.35): equals the frozen point joint at every
position, its tangent is the exact linearization, and a position sweep from one flattening agrees with
re-building the model at every position."""

import numpy as np
import pytest

from bscomp import System, flatten, second_order
from bscomp.components import (
    Ballscrew,
    FixedNode,
    FixedRotational,
    MovingScrewNut,
    NodeToRotFlange,
    RigidBody,
    Section,
    Torque,
    TorsionalDamper,
)
from bscomp.errors import BscompError
from bscomp.linear.frf_engine import modal_frf
from bscomp.linear.sweeps import position_sweep
from bscomp.systems.thesis_parts import thesis_screw_nut

SECTIONS = [Section(length=0.8, d_out=0.04, n_elements=8)]
NUT = dict(m=1.49 + 250.0, I=[2.56e-3, 2.56e-3, 1.31e-3])


def _supports(s):
    s.add("b0", FixedNode(dofs=("u", "v", "w", "tx", "ty")))
    s.add("b1", FixedNode(dofs=("u", "v")))
    s.connect("screw.n0", "b0.node")
    s.connect("screw.n8", "b1.node")


def frozen(z):
    s = System("frozen")
    s.add("screw", Ballscrew(SECTIONS, points={"p": z}))
    s.add("sn", thesis_screw_nut())
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, **NUT))
    s.connect("screw.p", "sn.screw")
    s.connect("sn.nut", "nut.c")
    _supports(s)
    return s


def moving(z0=0.3):
    screw = Ballscrew(SECTIONS)
    s = System("moving")
    s.add("screw", screw)
    s.add("sn", MovingScrewNut.from_screw_nut(screw, thesis_screw_nut(), z0=z0))
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, **NUT))
    for i in range(screw.n_nodes):
        s.connect(f"screw.n{i}", f"sn.n{i}")
    s.connect("sn.nut", "nut.c")
    _supports(s)
    s.position_parameter = "sn.z0"
    return s


@pytest.fixture(scope="module")
def dae():
    return flatten(moving(0.3))


@pytest.mark.parametrize("z", [0.3, 0.0731, 0.4321, 0.8])
def test_parameter_z0_gives_the_frozen_joint(dae, z):
    """One flattening, z0 as a parameter: M, K equal the point-port model re-built at z (round-off)."""
    so_m = second_order(dae, params={"sn.z0": z})
    so_f = second_order(frozen(z))
    for A in ("M", "K"):
        a, b = getattr(so_m, A).toarray(), getattr(so_f, A).toarray()
        assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()


def test_tangent_is_the_linearization(dae):
    """K of the Dae linearized at rest = K without the joint + P^T tangent P, at a position off the nominal."""
    from bscomp.linear.sweeps import _TangentUpdate

    s = moving(0.3)
    upd = _TangentUpdate(s, "sn.z0", "sn", "z0", s.component("sn"), None, None)
    M, K, _ = upd.matrices(0.61)
    ref = second_order(dae, params={"sn.z0": 0.61})
    assert np.abs((K - ref.K).toarray()).max() <= 1e-10 * np.abs(ref.K.toarray()).max()


def test_joint_is_conservative_and_carries_no_force_at_rest(dae):
    """Symmetric K (gradient of a potential); zero residual at rest at every position."""
    for z in (0.1, 0.55):
        K = second_order(dae, params={"sn.z0": z}).K.toarray()
        assert np.abs(K - K.T).max() <= 1e-9 * np.abs(K).max()


def test_lowrank_frf_equals_direct_solve():
    """modal_frf (eigh + Woodbury for discrete dampers) against (K - w^2 M + jw C)^-1 per frequency."""
    rng = np.random.default_rng(1)
    n = 12
    A = rng.normal(size=(n, n))
    M = A @ A.T + n * np.eye(n)
    Bm = rng.normal(size=(n, n))
    K = Bm @ Bm.T
    import scipy.linalg as sla

    lam, phi = sla.eigh(K, M)
    c_modal = 2 * 0.03 * np.sqrt(lam)
    Cs = np.zeros((n, n))
    Cs[2, 2], Cs[5, 5], Cs[2, 5], Cs[5, 2] = 3.0, 2.0, -1.0, -1.0      # two discrete dampers
    C = M @ phi @ np.diag(c_modal) @ phi.T @ M + Cs
    B = rng.normal(size=(n, 2))
    Cq = rng.normal(size=(3, n))
    Cv = rng.normal(size=(3, n))
    Ca = np.zeros((3, n))
    D = np.zeros((3, 2))
    f = np.linspace(0.05, 3.0, 40)
    H = modal_frf(lam, phi, c_modal, Cs, B, Cq, Cv, Ca, D, f)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        ref = (Cq + 1j * w * Cv) @ np.linalg.solve(K - w * w * M + 1j * w * C, B)
        assert np.abs(H[k] - ref).max() <= 1e-10 * np.abs(ref).max()


def _with_damper():
    s = moving(0.3)
    s.add("d", TorsionalDamper(d=0.5))
    s.add("end", NodeToRotFlange())
    s.add("g", FixedRotational())
    s.add("motor", Torque())
    s.connect("screw.n4", "end.node")
    s.connect("end.flange", "d.flange_a")
    s.connect("d.flange_b", "g.flange")
    s.connect("motor.flange", "end.flange")
    return s


def test_tangent_sweep_agrees_with_rebuild_sweep():
    """position_sweep(method='tangent') = method='rebuild' (exact FRF with modal damping + a discrete damper)."""
    from bscomp.kernel.damping import ModalDamping

    def build():
        s = _with_damper()
        s.damping = ModalDamping(0.05)
        return s

    pos = [0.12, 0.33, 0.71]
    f = np.linspace(5.0, 600.0, 60)
    io = dict(inputs=["motor.tau"], outputs=["nut.com.w", "screw.n4.tz"])
    fast = position_sweep(build, pos, freqs=f, method="tangent", **io)
    slow = position_sweep(build, pos, freqs=f, method="rebuild", **io)
    np.testing.assert_allclose(fast.frequencies, slow.frequencies, rtol=1e-6)
    assert np.abs(fast.H - slow.H).max() <= 1e-6 * np.abs(slow.H).max()
    assert fast.stats["method"] == "tangent" and slow.stats["method"] == "rebuild"
    parts = sum(fast.stats[k] for k in ("flatten_s", "linearize_s", "check_s", "positions_s"))
    assert parts <= fast.stats["wall_s"] * (1 + 1e-9)


def test_wrong_tangent_is_caught():
    class Broken(MovingScrewNut):
        def tangent(self):
            t = super().tangent()
            t.K = 1.01 * t.K
            return t

    def build():
        screw = Ballscrew(SECTIONS)
        s = System("broken")
        s.add("screw", screw)
        s.add("sn", Broken.from_screw_nut(screw, thesis_screw_nut(), z0=0.3))
        s.add("nut", RigidBody(points={"c": (0, 0, 0)}, **NUT))
        for i in range(screw.n_nodes):
            s.connect(f"screw.n{i}", f"sn.n{i}")
        s.connect("sn.nut", "nut.c")
        _supports(s)
        return s

    with pytest.raises(BscompError, match="tangent"):
        position_sweep(build, [0.2, 0.5], parameter="sn.z0", method="tangent")
