"""Physical component library (issue 3): FE screw, rigid bodies, joints, adapters, screw-nut interface.

Each model is flattened through the kernel and checked against analytic values.
"""

import math

import numpy as np
import pytest
import scipy.linalg as sla

from bscomp import ModelDefinitionError, OverdeterminedError, ParameterError, System, flatten, second_order
from bscomp.components import (
    Ballscrew,
    Bearing,
    BoltedFastener,
    Bushing,
    Coupling,
    FixedNode,
    IdealLeadScrew,
    LinearGuide,
    NodeToFlange,
    NodeToRotFlange,
    RigidBody,
    ScrewNut,
    Section,
)
from bscomp.components._node_dofs import t_point_com
from bscomp.kernel.damping import modal_damping_matrix
from bscomp.systems.thesis_parts import thesis_ballscrew, thesis_screw_nut

E, RHO, NU = 210e9, 7800.0, 0.27
G = E / (2 * (1 + NU))
NUT = dict(m=1.49, I=[2.56e-3, 2.56e-3, 1.31e-3])  # Table 3.1


def freqs(so):
    lam = sla.eigh(so.K.toarray(), so.M.toarray(), eigvals_only=True)
    return np.sqrt(np.abs(lam)) / (2 * np.pi)


def n_zero(f, tol=1.0):
    return int(np.sum(f < tol))


def one(name, comp):
    s = System("t")
    s.add(name, comp)
    return s


# ---- Ballscrew --------------------------------------------------------------------------------
def test_free_free_screw_six_rigid_modes_and_bar_frequencies():
    L = 1.0
    so = second_order(one("screw", Ballscrew([Section(L, 0.04, 0.0, 20)])))
    assert so.M.shape == (6 * 21, 6 * 21)
    f = freqs(so)
    assert n_zero(f) == 6 and f[6] > 100.0
    f_ax = math.sqrt(E / RHO) / (2 * L)      # 2594 Hz
    f_tor = math.sqrt(G / RHO) / (2 * L)     # 1628 Hz
    assert np.min(np.abs(f / f_tor - 1)) < 3e-3
    assert np.min(np.abs(f / f_ax - 1)) < 3e-3


def test_axial_torsional_screw_two_rigid_modes():
    L = 1.0
    so = second_order(one("screw", Ballscrew([Section(L, 0.04, 0.0, 20)], dofs=("w", "tz"))))
    assert so.M.shape == (42, 42)
    f = freqs(so)
    assert n_zero(f) == 2
    np.testing.assert_allclose(f[2], math.sqrt(G / RHO) / (2 * L), rtol=3e-3)   # torsion first
    np.testing.assert_allclose(f[3], math.sqrt(E / RHO) / (2 * L), rtol=3e-3)


def test_thesis_screw_axial_torsional_dof_count():
    screw = thesis_ballscrew(dofs=("w", "tz"))
    assert screw.n_nodes == 48 and screw.length == pytest.approx(0.9205)
    so = second_order(one("screw", screw))
    assert so.M.shape == (96, 96)
    w = [i for i, n in enumerate(so.coordinates) if n.endswith(".w")]
    assert len(w) == 48
    m_w = so.M.toarray()[np.ix_(w, w)].sum()
    np.testing.assert_allclose(m_w, screw.beam_model().total_mass(), rtol=1e-12)


def test_two_instances_with_different_configuration_in_one_system():
    """Same class and port names, different dofs / offsets: each instance keeps its own constraints."""
    s = System("t")
    s.add("a", RigidBody(m=1.0, I=[1.0, 1.0, 1.0], points={"P": [0.0, 0.0, 1.0]}))
    s.add("b", RigidBody(m=2.0, I=[1.0, 1.0, 1.0], points={"P": [0.0, 0.0, -3.0]}, dofs=("u", "ty")))
    s.add("ka", Bushing(K=[1e3, 0, 0, 0, 0, 0], grounded=True))
    s.add("kb", Bushing(K=[1e3, 0, 0, 0, 0, 0], grounded=True))
    s.connect("a.P", "ka.node_a")
    s.connect("b.P", "kb.node_a")
    so = second_order(s)
    assert len(so.coordinates) == 8
    K = so.K.toarray()
    ia, ib = so.coordinates.index("a.com.ty"), so.coordinates.index("b.com.ty")
    np.testing.assert_allclose([K[ia, ia], K[ib, ib]], [1e3 * 1.0, 1e3 * 9.0])   # u_P = u + r_z ty


def test_point_port_follows_shape_functions():
    screw = Ballscrew([Section(0.5, 0.03, 0.0, 5)], points={"P": 0.237})
    dae = flatten(one("screw", screw))
    mech = dae.mech
    names = mech.full_coordinate_names
    rng = np.random.default_rng(0)
    qr = rng.standard_normal(len(mech.coordinate_names))
    q = mech.T @ qr + mech.t0
    d_nodes = np.concatenate([[q[names.index(f"screw.n{i}.{k}")] for k in "u v w tx ty tz".split()]
                              for i in range(screw.n_nodes)])
    d_P = np.array([q[names.index(f"screw.P.{k}")] for k in "u v w tx ty tz".split()])
    np.testing.assert_allclose(d_P, screw.beam_model().shape_matrix(0.237) @ d_nodes, atol=1e-12)
    # the point adds no coordinate
    assert len(mech.coordinate_names) == 6 * screw.n_nodes


def test_point_between_nodes_acts_as_support():
    """Bar clamped at z = 0, held axially at an interior point P (mid-element) by a very stiff spring:
    the free overhang L - z_P then vibrates as a clamped-free bar, f = c / (4 (L - z_P))."""
    L, d, zP, k = 1.0, 0.03, 0.45, 1e13
    s = System("t")
    s.add("screw", Ballscrew([Section(L, d, 0.0, 40)], dofs=("w",), points={"P": zP}))
    s.add("clamp", FixedNode(dofs=("w",)))
    s.add("spring", BoltedFastener(k=k, grounded=True))
    s.connect("screw.n0", "clamp.node")
    s.connect("screw.P", "spring.node_a")
    f = freqs(second_order(s))
    c = math.sqrt(E / RHO)
    np.testing.assert_allclose(f[0], c / (4 * (L - zP)), rtol=1e-2)
    np.testing.assert_allclose(f[1], c / (2 * zP), rtol=2e-2)


def test_point_outside_screw_raises():
    with pytest.raises(ModelDefinitionError, match="outside"):
        Ballscrew([Section(0.5, 0.03, 0.0, 5)], points={"P": 0.6})


# ---- RigidBody --------------------------------------------------------------------------------
def test_rigid_body_offset_point_mass_and_stiffness_transform():
    r = np.array([0.05, -0.02, 0.1])
    Kb = np.diag([1e7, 2e7, 3e7, 1e4, 2e4, 3e4])
    s = System("t")
    I = [[0.01, 0.001, 0.0], [0.001, 0.02, 0.0], [0.0, 0.0, 0.03]]
    s.add("body", RigidBody(points={"P": r}, m=2.0, I=I))
    s.add("mount", Bushing(K=Kb, grounded=True))
    s.connect("body.P", "mount.node_a")
    so = second_order(s)
    body = s.component("body")
    M6 = body.mass_matrix()
    T = t_point_com(r)
    np.testing.assert_allclose(so.M.toarray(), M6, rtol=1e-12)
    np.testing.assert_allclose(so.K.toarray(), T.T @ Kb @ T, rtol=1e-12)   # Eq 3.5
    # same frequencies as the body described at P: M_P = T^-T M T^-1 (T^-1 = T(-r))
    Ti = t_point_com(-r)
    f_P = np.sqrt(sla.eigh(Kb, Ti.T @ M6 @ Ti, eigvals_only=True)) / (2 * np.pi)
    np.testing.assert_allclose(freqs(so), f_P, rtol=1e-9)


def test_rigid_body_kinetic_energy_observable():
    dae = flatten(one("body", RigidBody(m=3.0, I=[1.0, 2.0, 4.0])))
    assert "body.kinetic_energy" in dae.output_names()


def test_table_sliding_only_has_one_dof():
    s = System("t")
    s.add("table", RigidBody(m=250.0, dofs=("w",), points={"a": [0.2, 0.1, 0.0], "b": [-0.2, 0.1, 0.3]}))
    so = second_order(s)
    assert so.coordinates == ["table.com.w"]
    np.testing.assert_allclose(so.M.toarray(), [[250.0]])


def test_rigid_body_singular_inertia_raises():
    with pytest.raises(ParameterError, match="positive definite"):
        flatten(one("rotor", RigidBody(m=1.0, dofs=("w", "tz"))))


# ---- joints -----------------------------------------------------------------------------------
def test_bearing_mass_frequencies():
    m, ka, kr = 5.0, 2.7e8, 1.9e8
    s = System("t")
    s.add("body", RigidBody(m=m, dofs=("u", "v", "w")))
    s.add("brg", Bearing(k_axial=ka, k_radial=kr, grounded=True))
    s.connect("body.com", "brg.node_a")
    f = np.sort(freqs(second_order(s)))
    np.testing.assert_allclose(f, np.sqrt(np.array([kr, kr, ka]) / m) / (2 * np.pi), rtol=1e-12)


def test_bearing_between_two_bodies_and_bushing_relative():
    m1, m2, k = 2.0, 3.0, 1e6
    s = System("t")
    s.add("a", RigidBody(m=m1, dofs=("w",)))
    s.add("b", RigidBody(m=m2, dofs=("w",)))
    s.add("j", Bushing(K=[0, 0, k, 0, 0, 0]))
    s.connect("a.com", "j.node_a")
    s.connect("j.node_b", "b.com")
    f = freqs(second_order(s))
    assert f[0] < 1e-3
    np.testing.assert_allclose(f[1], math.sqrt(k * (1 / m1 + 1 / m2)) / (2 * np.pi), rtol=1e-12)


def test_bushing_rejects_non_symmetric():
    K = np.eye(6)
    K[0, 1] = 1.0
    with pytest.raises(ParameterError, match="symmetric"):
        Bushing(K=K)


def test_coupling_free_jaws_eq_b1():
    kT, J1, J2 = 3938.0, 3.09e-4, 3.06e-4          # Sec B.4
    f = freqs(second_order(one("c", Coupling(k_T=kT, J1=J1, J2=J2))))
    np.testing.assert_allclose(f[1], math.sqrt(kT * (1 / J1 + 1 / J2)) / (2 * np.pi), rtol=1e-12)
    assert 800 < f[1] < 810  # measured f_n2 = 805 Hz


def test_coupling_node_ends_on_screw_and_rotor():
    kT, J1, J2, Jr = 3938.0, 3.09e-4, 3.06e-4, 5.98e-3
    s = System("t")
    s.add("rotor", RigidBody(I=[0, 0, Jr], dofs=("tz",)))
    s.add("c", Coupling(k_T=kT, J1=J1, J2=J2, ends="node"))
    s.add("shaft", RigidBody(I=[0, 0, 1e-3], dofs=("tz",)))
    s.connect("rotor.com", "c.node_a")
    s.connect("c.node_b", "shaft.com")
    f = freqs(second_order(s))
    Ja, Jb = Jr + J1, 1e-3 + J2
    np.testing.assert_allclose(f[1], math.sqrt(kT * (1 / Ja + 1 / Jb)) / (2 * np.pi), rtol=1e-12)


def test_bolted_fastener_along_inclined_axis():
    m, k = 4.0, 1e7
    s = System("t")
    s.add("body", RigidBody(m=m, dofs=("u", "v", "w")))
    s.add("bolt", BoltedFastener(k=BoltedFastener.series(2 * k, 2 * k), axis=[1.0, 0.0, 1.0], grounded=True))
    s.add("guide", Bearing(k_axial=0.0, k_radial=1e3, grounded=True))   # holds u, v weakly
    s.connect("body.com", "bolt.node_a")
    s.connect("body.com", "guide.node_a")
    so = second_order(s)
    K_uw = so.K.toarray()[np.ix_([0, 2], [0, 2])]
    np.testing.assert_allclose(K_uw, 0.5 * k * np.ones((2, 2)) + np.diag([1e3, 0.0]))  # k n n^T


def test_linear_guide_table_rocking():
    """Table on four slides (Fig 3.9): vertical translation sqrt(4 k_v / m), roll about z."""
    m, Izz, kv, kl, a = 250.0, 3.7, 5e8, 4e8, 0.15     # Table C.1
    corners = [(1, 1), (-1, 1), (1, -1), (-1, -1)]
    pts = {f"p{i}": [sx * a, -0.05, sz * 0.2] for i, (sx, sz) in enumerate(corners)}
    s = System("t")
    s.add("table", RigidBody(m=m, I=[24.2, 21.0, Izz], points=pts, dofs=("v", "tz")))
    s.add("guide", LinearGuide(k_vertical=kv, k_lateral=kl, slides=list(pts)))
    for p in pts:
        s.connect(f"table.{p}", f"guide.{p}")
    f = np.sort(freqs(second_order(s)))
    k_roll = 4 * (kv * a**2 + kl * 0.05**2)          # the slides sit 50 mm below the COM (Eq 3.3)
    expected = np.sort([math.sqrt(4 * kv / m), math.sqrt(k_roll / Izz)]) / (2 * np.pi)
    np.testing.assert_allclose(f, expected, rtol=1e-12)


# ---- adapters ---------------------------------------------------------------------------------
def test_adapters_reflected_inertia_with_ideal_lead_screw():
    J, m, lead = 5.98e-3, 250.0, 0.010
    s = System("t")
    s.add("rotor", RigidBody(I=[0, 0, J], dofs=("tz",)))
    s.add("rot", NodeToRotFlange())
    s.add("lead", IdealLeadScrew(lead=lead))
    s.add("tr", NodeToFlange())
    s.add("table", RigidBody(m=m, dofs=("w",)))
    s.connect("rotor.com", "rot.node")
    s.connect("rot.flange", "lead.flange_a")
    s.connect("lead.flange_b", "tr.flange")
    s.connect("tr.node", "table.com")
    so = second_order(s)
    assert so.M.shape == (1, 1)
    r_g = lead / (2 * math.pi)
    np.testing.assert_allclose(so.M.toarray()[0, 0], J + m * r_g**2, rtol=1e-12)   # Eq 4.2


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_node_to_flange_direction_flips_the_axis_not_the_inertia(direction):
    """flange.s = direction * node.w: rotor -> lead screw -> nut node (w) -> adapter -> table flange.

    The table moves direction * r_g per radian, a force on it acts on the node as direction * F
    (virtual work: node.Fz = -direction * flange.f), and the reflected inertia is that of Eq 4.2."""
    from bscomp.components import Force, Mass
    from bscomp.linear.response import frf

    J, m_nut, m, lead = 5.98e-3, 1.49, 250.0, 0.010
    s = System("t")
    s.add("rotor", RigidBody(I=[0, 0, J], dofs=("tz",)))
    s.add("rot", NodeToRotFlange())
    s.add("lead", IdealLeadScrew(lead=lead))
    s.add("lead_nut", NodeToFlange())
    s.add("nut", RigidBody(m=m_nut, dofs=("w",)))
    s.add("tr", NodeToFlange(direction=direction))
    s.add("table", Mass(m=m))
    s.add("F", Force())
    s.connect("rotor.com", "rot.node")
    s.connect("rot.flange", "lead.flange_a")
    s.connect("lead.flange_b", "lead_nut.flange")
    s.connect("lead_nut.node", "nut.com")
    s.connect("nut.com", "tr.node")
    s.connect("tr.flange", "table.flange_a")
    s.connect("F.flange", "table.flange_a")
    so = second_order(s, inputs=["F.f"], outputs=["table.s"])
    r_g = lead / (2 * math.pi)
    assert so.M.shape == (1, 1)
    np.testing.assert_allclose(so.M.toarray()[0, 0], J + (m_nut + m) * r_g**2, rtol=1e-12)   # Eq 4.2
    H = frf(s, input="F.f", output=["rot.flange.phi", "table.s"], freqs=[1.0]).H[0, :, 0]
    assert H[1].real < 0                          # mass line -1/(m_red w^2): the force pushes the table along +s
    np.testing.assert_allclose(H[1] / H[0], direction * r_g, rtol=1e-9)   # table.s = direction * r_g * phi


def test_fixed_node_twice_is_redundant():
    s = System("t")
    s.add("body", RigidBody(m=1.0, dofs=("w",)))
    s.add("g", FixedNode())
    s.connect("body.com", "g.node")
    with pytest.raises(OverdeterminedError):
        flatten(s)


# ---- screw-nut --------------------------------------------------------------------------------
def _screw_nut(nut_dofs, screw_dofs=("u", "v", "w", "tx", "ty", "tz")):
    s = System("sn")
    s.add("screw", thesis_ballscrew(dofs=screw_dofs, points={"P": 0.4325}))
    s.add("nut", RigidBody(dofs=nut_dofs, **NUT))
    s.add("sn", thesis_screw_nut())
    s.connect("screw.P", "sn.screw")
    s.connect("sn.nut", "nut.com")
    return s


def test_screw_nut_matches_eq_3_45():
    K = thesis_screw_nut().stiffness_matrix() / 2.07e7
    np.testing.assert_allclose(np.diag(K)[:3], [58.9, 58.9, 82.1], rtol=2e-3)
    np.testing.assert_allclose(K[2, 5], -0.130, rtol=1e-2)
    np.testing.assert_allclose(K[:6, 6:], -K[:6, :6], atol=1e-9)


def test_free_free_screw_and_nut_modes():
    # nut held against rotation about the axis (as on the table): 6 rigid modes incl. the screw drive motion
    f = freqs(second_order(_screw_nut(("u", "v", "w", "tx", "ty"))))
    assert n_zero(f) == 6
    assert 100.0 < f[6] < 1000.0                   # first bending mode, finite
    # fully free nut: the helical relative motion is a 7th mechanism (K_SN rank 5)
    f7 = freqs(second_order(_screw_nut(("u", "v", "w", "tx", "ty", "tz"))))
    assert n_zero(f7) == 7


def test_screw_nut_axial_torsional_first_modes_finite():
    so = second_order(_screw_nut(("w", "tz"), screw_dofs=("w", "tz")))
    f = freqs(so)
    assert so.M.shape == (98, 98)
    assert n_zero(f) == 3          # common translation, common rotation, nut running along the thread
    assert 1000.0 < f[3] < 5000.0


def test_screw_nut_from_geometry_thesis_b6():
    sn = ScrewNut.from_nut_geometry(L_nut=0.100, lead=0.010, R=0.020, R_ball=3.175e-3,
                                    beta=math.radians(50.0), k_axial=1.70e9)
    assert sn.get("n_ball") == 100                                     # Eq B.3: 99.26 -> 100
    np.testing.assert_allclose(sn.get("phi_end"), 10 * math.pi)         # Eq B.2: 1800 deg
    np.testing.assert_allclose(sn.get("k_ball"), 2.07e7, rtol=2e-3)     # Table 3.1
    np.testing.assert_allclose(sn.stiffness_matrix()[2, 2], 1.70e9, rtol=1e-9)  # Eq 3.41
    with pytest.raises(ModelDefinitionError, match="exactly one"):
        ScrewNut.from_nut_geometry(0.1, 0.01, 0.02, 3.175e-3, 0.87, k_ball=1e7, k_axial=1e9)


# ---- damping ----------------------------------------------------------------------------------
def test_modal_damping_leaves_rigid_mode_undamped():
    so = second_order(_screw_nut(("w",), screw_dofs=("w", "tz")))
    M, K = so.M.toarray(), so.K.toarray()
    C = modal_damping_matrix(M, K, 0.02)
    lam, phi = sla.eigh(K, M)
    rigid = phi[:, lam < 1.0]
    assert rigid.shape[1] == 2
    np.testing.assert_allclose(C @ rigid, 0.0, atol=1e-9 * np.abs(C).max())
    cq = phi.T @ C @ phi
    k = int(np.argmax(lam > 1.0))
    np.testing.assert_allclose(cq[k, k], 2 * 0.02 * math.sqrt(lam[k]), rtol=1e-6)
