"""Moving nut (Sec 5.2.2.3): equals the frozen joint at any position; carries rigid travel; conservative."""

import numpy as np
import pytest

from bscomp import System, second_order
from bscomp.components import Ballscrew, FixedNode, MovingNutJoint, RigidBody, Section
from bscomp.linear.modal import modes
from bscomp.systems.thesis_parts import thesis_screw_nut

SECTIONS = [Section(length=0.8, d_out=0.04, n_elements=16)]


def frozen(z):
    s = System("frozen")
    s.add("screw", Ballscrew(SECTIONS, dofs=("w", "tz"), points={"p": z}))
    s.add("sn", thesis_screw_nut())
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, dofs=("w", "tz"), m=1.49 + 250.0, I=[2.56e-3, 2.56e-3, 1.31e-3]))
    s.add("bearing", FixedNode(dofs=("w",)))
    s.connect("screw.p", "sn.screw")
    s.connect("sn.nut", "nut.c")
    s.connect("screw.n0", "bearing.node")
    return s


def moving(z0):
    screw = Ballscrew(SECTIONS, dofs=("w", "tz"))
    s = System("moving")
    s.add("screw", screw)
    s.add("joint", MovingNutJoint.from_screw_nut(thesis_screw_nut(), screw.z_nodes, z0=z0))
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, dofs=("w", "tz"), m=1.49 + 250.0, I=[2.56e-3, 2.56e-3, 1.31e-3]))
    s.add("bearing", FixedNode(dofs=("w",)))
    for i in range(screw.n_nodes):
        s.connect(f"screw.n{i}", f"joint.n{i}")
    s.connect("joint.nut", "nut.c")
    s.connect("screw.n0", "bearing.node")
    return s


@pytest.mark.parametrize("z", [0.2, 0.43, 0.615])
def test_moving_joint_linearizes_to_the_frozen_joint(z):
    f_frozen = modes(frozen(z)).frequencies[:4]
    f_moving = modes(moving(z)).frequencies[:4]
    np.testing.assert_allclose(f_moving, f_frozen, rtol=1e-8, atol=1e-6)


def test_operating_point_moves_the_nut():
    """Moved by Δ along the thread (nut travel Δ, screw turned by the helical null motion of K_SN),
    the linearized moving joint equals the frozen joint at z0 + Δ; the joint force stays zero."""
    from bscomp import flatten

    sys_m = moving(0.3)
    dae = flatten(sys_m)
    joint = sys_m.component("joint")
    theta_per_w = -joint.get("k_w") / joint.get("k_wt")  # null vector of the (w, θz) block
    w_nut = [n for n in dae.x_names if n.startswith("nut") and n.endswith(".w")][0]
    tz_screw = [n for n in dae.x_names if n.startswith("screw.n") and n.endswith(".tz")]
    for delta in (0.05, 0.237):
        at = {w_nut: delta, **{n: -theta_per_w * delta for n in tz_screw}}
        f_m = modes(second_order(dae, at=at)).frequencies[:4]
        f_f = modes(frozen(0.3 + delta)).frequencies[:4]
        np.testing.assert_allclose(f_m, f_f, rtol=1e-7, atol=1e-5)


# ------------------------------------------------------------------------------ time domain: slow creep
CREEP_SECTIONS = [Section(length=0.8, d_out=0.04, n_elements=8)]  # nodes every 0.1 m
M_TABLE = 1.49 + 250.0


def _loaded_nut(s, brake):
    """Nut + table (axial DOF only, bolted to the table) pushed along +z by ``F.f``; the screw is held
    axially at node 0 and turns against a rotary damper ``brake`` there (``None``: rotation held)."""
    from bscomp.components import FixedRotational, Force, NodeToFlange, NodeToRotFlange, TorsionalDamper

    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, dofs=("w",), m=M_TABLE, I=[2.56e-3, 2.56e-3, 1.31e-3]))
    s.add("tab", NodeToFlange())
    s.add("F", Force())
    s.connect("nut.c", "tab.node")
    s.connect("F.flange", "tab.flange")
    s.add("bearing", FixedNode(dofs=("w",) if brake else ("w", "tz")))
    s.connect("screw.n0", "bearing.node")
    if brake:
        s.add("end", NodeToRotFlange())
        s.add("brake", TorsionalDamper(d=brake))
        s.add("ground", FixedRotational())
        s.connect("screw.n0", "end.node")
        s.connect("end.flange", "brake.flange_a")
        s.connect("brake.flange_b", "ground.flange")


def _frozen_stretch(z, F):
    """Static axial displacement of the screw at the nut, nut frozen at z, load F, rotation held."""
    s = System("frozen_static")
    s.add("screw", Ballscrew(CREEP_SECTIONS, dofs=("w", "tz"), points={"p": z}))
    s.add("sn", thesis_screw_nut())
    s.connect("screw.p", "sn.screw")
    _loaded_nut(s, None)
    s.connect("sn.nut", "nut.c")
    so = second_order(s, inputs=["F.f"], outputs=[])
    u = np.linalg.solve(so.K.toarray(), so.B.toarray()[:, 0] * F)
    c = list(so.coordinates)
    z_nodes = s.component("screw").z_nodes
    w = [u[c.index(f"screw.n{i}.w")] if f"screw.n{i}.w" in c else 0.0 for i in range(len(z_nodes))]
    return float(np.interp(z, z_nodes, w))


def _creeping(z0, v, F=2000.0):
    """The creep test's drive (nut + table pushed by F, screw turning against a damper: creeps at v) and its
    start state at that speed."""
    from bscomp import flatten
    from bscomp.kernel.damping import ModalDamping

    K = thesis_screw_nut().stiffness_matrix()
    r_g = -K[2, 5] / K[2, 2]  # helical null motion: nut travel = -r_g * screw rotation
    screw = Ballscrew(CREEP_SECTIONS, dofs=("w", "tz"))
    s = System("creep")
    s.add("screw", screw)
    s.add("joint", MovingNutJoint.from_screw_nut(thesis_screw_nut(), screw.z_nodes, z0=z0))
    for i in range(screw.n_nodes):
        s.connect(f"screw.n{i}", f"joint.n{i}")
    _loaded_nut(s, brake=F * r_g**2 / v)
    s.connect("joint.nut", "nut.c")
    s.damping = ModalDamping(0.05)  # leaves the helical rigid motion undamped
    dae = flatten(s)
    x0 = {"der(nut.com.w)": v, **{n: -v / r_g for n in dae.x_names if n.startswith("der(screw.n")
                                  and n.endswith(".tz)")}}
    return dae, x0


@pytest.mark.parametrize("method", ["idas", "modal"])
def test_slow_creep_matches_frozen_quasi_static_stretch(method):
    """A nut creeping at 0.4 m/s across a screw node loads the screw as the frozen joint does statically.

    F = 2 kN pushes the nut; the screw turns against a rotary damper d = F r_g^2 / v, so the drive creeps
    at v = 0.4 m/s (started at that speed, helical rigid motion). The axial displacement of the screw at
    the nut (a few µm, growing with the loaded length) must equal the frozen model's static value at the
    nut's current position. Tolerance 1e-3 relative: the quasi-static error terms are the start transient
    (zero initial stretch, 5 % modal damping; compared only after 80 ms, when it has decayed) and the
    inertia of the stretch changing at ~v dw/dz (µm over tenths of a second: negligible next to 2 kN),
    plus the integrator's atol/stretch = 1e-10/2e-6 = 5e-5; measured ~1e-4 (7e-5 at the end).
    The stretch itself changes by ~35 % over the window, so a joint stuck at its start position fails.
    ``method="modal"`` holds the joint frozen at its start in the linear part and moves the contact point in
    the low-rank correction across the node (bscomp/simulation/moving_joints.py).
    """
    from bscomp.simulation.dispatch import simulate

    F, v = 2000.0, 0.4
    dae, x0 = _creeping(0.25, v, F)
    screw_z = Ballscrew(CREEP_SECTIONS, dofs=("w", "tz")).z_nodes
    t = np.arange(0.0, 0.3 + 1e-12, 2.0**-10)
    w_names = [f"screw.n{i}.w" for i in range(1, screw_z.size)]
    r = simulate(dae, t, inputs={"F.f": F}, x0=x0, outputs=["joint.z"] + w_names, rtol=1e-5, atol=1e-10,
                 method=method)
    z = r["joint.z"]
    assert z[-1] - z[0] == pytest.approx(v * t[-1], rel=0.02)  # creeps at the set speed
    assert z[0] < 0.3 < z[-1]                                   # and crosses a screw node
    W = np.column_stack([np.zeros_like(t)] + [r[n] for n in w_names])
    check = np.flatnonzero(t >= 0.08)[::25]
    w_moving = np.array([np.interp(z[k], screw_z, W[k]) for k in check])
    w_frozen = np.array([_frozen_stretch(z[k], F) for k in check])
    assert w_frozen[-1] / w_frozen[0] - 1 > 0.2
    np.testing.assert_allclose(w_moving, w_frozen, rtol=1e-3)


@pytest.mark.filterwarnings("ignore::bscomp.errors.SlowMethodWarning")     # fixed with a moving nut: said below
@pytest.mark.parametrize("method", ["idas", "modal", "fixed"])
def test_a_nut_driven_off_the_screw_is_refused_with_the_time_it_left(method):
    """Creeping at 0.4 m/s from z0 = 0.55 m, the nut passes the 0.8 m screw's last node at 0.625 s; the
    components clamp the shape functions there (the run would go on with the nut glued to the end node), so
    every method raises NutOffScrewError naming the joint, the time and the span, with the run up to then --
    and a run that ends before stays silent (its outputs as asked, the checked position not added)."""
    from bscomp.simulation.dispatch import NutOffScrewError, simulate

    dae, x0 = _creeping(0.55, 0.4)
    t = np.arange(0.0, 0.8 + 1e-12, 2.0**-9)
    with pytest.raises(NutOffScrewError, match=r"'joint' left the screw at t = 0\.6.*last node.*\[0, 0\.8\] m") as exc:
        simulate(dae, t, inputs={"F.f": 2000.0}, x0=x0, outputs=["nut.com.w"], method=method, rtol=1e-5)
    err = exc.value
    assert err.joint == "joint" and err.span == pytest.approx((0.0, 0.8))
    assert err.t == pytest.approx(0.625, abs=0.01) and err.z > 0.8
    part = err.partial
    assert part.t[-1] < err.t and len(part.t) == len(part["nut.com.w"]) == part.x.shape[0]
    assert 0.55 + part["nut.com.w"][-1] <= 0.8 + 1e-9 and "joint.z" in part.outputs
    assert "simulate(method=" in str(err) and "joint.z0" in err.hint
    r = simulate(dae, t[t < 0.6], inputs={"F.f": 2000.0}, x0=x0, outputs=["nut.com.w"], method=method, rtol=1e-5)
    assert list(r.outputs) == ["nut.com.w"]


@pytest.mark.parametrize("method", ["split", "fixed"])
def test_methods_slowed_by_a_moving_nut_say_so_and_name_modal(method):
    """With the nut moving, every screw coordinate its shape functions reach is nonlinear for the split
    integrator (dense re-linearization, ~1,000x slower: 138 s per 2 ms on the test bed) and the fixed-step
    method factorizes its Newton matrix again at every step (30x: 18.5 s per 10 ms; docs/nonlinear.md): each
    says so before running, naming the joint and method='modal', at the caller's line; a frozen nut is
    silent, and so is method='modal'."""
    import warnings

    from bscomp import flatten
    from bscomp.errors import SlowMethodWarning
    from bscomp.simulation.dispatch import simulate

    dae, x0 = _creeping(0.3, 0.4)
    t = np.array([0.0, 1e-4, 2e-4])
    with pytest.warns(SlowMethodWarning, match=r"\['joint'\] moves along the screw.*method='modal'") as rec:
        simulate(dae, t, inputs={"F.f": 2000.0}, x0=x0, method=method)
    assert rec[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error", SlowMethodWarning)
        simulate(flatten(frozen(0.3)), t, method=method)
        simulate(dae, t, inputs={"F.f": 2000.0}, x0=x0, method="modal")
