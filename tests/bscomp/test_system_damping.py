"""System-level damping options (Eq A.10-A.15): modal ratios recovered, rigid-body mode undamped."""

import math

import numpy as np
import pytest
import scipy.linalg as sl

import bscomp
from bscomp import System, second_order
from bscomp.components import Force, Mass, Spring
from bscomp.kernel.damping import ModalDamping, RayleighDamping
from bscomp.systems import free_chain as chain


def free_chain():
    return chain(name="free3")


def damping_ratios(so):
    lin = so.to_statespace()
    ev = np.linalg.eigvals(lin.A)
    ev = ev[(ev.imag > 1e-6) & (np.abs(ev) > 1e-3)]  # elastic modes only
    return np.sort(-ev.real / np.abs(ev))


def test_modal_damping_gives_the_ratios_and_leaves_rigid_body_free():
    s = free_chain()
    s.damping = ModalDamping([0.02, 0.07])
    so = second_order(s, inputs=["F.f"])
    np.testing.assert_allclose(damping_ratios(so), [0.02, 0.07], rtol=1e-8)
    rigid = np.ones(3)
    np.testing.assert_allclose(so.C.toarray() @ rigid, 0.0, atol=1e-9)
    np.testing.assert_allclose(so.C.toarray(), so.C.toarray().T, atol=1e-12)


def test_rayleigh_damping_hits_two_targets():
    s = free_chain()
    so0 = second_order(s, inputs=["F.f"])
    w = np.sqrt(np.clip(sl.eigh(so0.K.toarray(), so0.M.toarray(), eigvals_only=True), 0, None))[1:]
    f1, f2 = w / (2 * np.pi)
    s.damping = RayleighDamping(zeta=0.03, f1=f1, f2=f2)
    so = second_order(s, inputs=["F.f"])
    np.testing.assert_allclose(damping_ratios(so), [0.03, 0.03], rtol=1e-6)


def test_bad_damping_values():
    with pytest.raises(ValueError, match="zeta"):
        ModalDamping(-0.1)
    with pytest.raises(ValueError, match="alpha"):
        RayleighDamping()


def test_massless_coordinate_is_condensed_for_modal_damping():
    """A massless node between two springs (wall - k1 - node - k2 - m) is condensed statically before the modes
    are taken: the one mode is sqrt(k1 k2 / (k1 + k2) / m) and gets exactly the option's ratio; the damping acts
    on the coordinate with inertia only (was refused: 'needs inertia on every coordinate')."""
    from bscomp.components import Fixed
    from bscomp.linear import modes

    s = System("massless")
    s.add("wall", Fixed())
    s.add("k1", Spring(c=3.0e4))
    s.add("k2", Spring(c=6.0e4))
    s.add("m", Mass(m=2.0))
    s.add("F", Force())
    s.connect("wall.flange", "k1.flange_a")
    s.connect("k1.flange_b", "k2.flange_a")
    s.connect("k2.flange_b", "m.flange_a")
    s.connect("F.flange", "m.flange_b")
    s.damping = ModalDamping(0.05)
    md = modes(bscomp.flatten(s))
    assert md.omega[-1] == pytest.approx(math.sqrt(2.0e4 / 2.0), rel=1e-12)
    assert md.damping[-1] == pytest.approx(0.05, rel=1e-9)


def test_an_override_that_leaves_the_modes_keeps_the_dae_and_one_that_moves_them_re_derives_the_damping():
    """The modal damping is computed from the start point's (M, K) at flattening. An override that leaves them
    (a friction force, a damper) uses the Dae as it is -- the same result as flattening the overridden System,
    without the ~0.7 s re-flattening of the FE test bed per value of a sweep -- while one that changes K
    re-flattens and the new modes get the ratios again."""
    from bscomp.components import CoulombFriction, Damper, Fixed
    from bscomp.kernel.flattening import flatten
    from bscomp.model import resolve_model

    s = free_chain()
    s.add("ground", Fixed())
    s.add("fr", CoulombFriction(F_c=5.0, v_reg=1e-3))
    s.connect("fr.flange_a", "ground.flange")
    s.connect("fr.flange_b", "m2.flange_b")
    s.add("d", Damper(d=3.0))
    s.connect("d.flange_a", "m0.flange_b")
    s.connect("d.flange_b", "m1.flange_a")
    s.damping = ModalDamping([0.02, 0.07])
    dae = flatten(s)
    keep = {"fr.F_c_pos": 8.0, "fr.F_c_neg": 8.0, "d.d": 5.0}
    assert resolve_model(dae, keep) is dae
    t = np.linspace(0.0, 0.2, 201)
    a = bscomp.simulate(dae, t, inputs={"F.f": 20.0}, outputs=["m2.v"], params=keep)["m2.v"]
    b = bscomp.simulate(flatten(s.with_parameters(keep)), t, inputs={"F.f": 20.0}, outputs=["m2.v"])["m2.v"]
    assert np.abs(b).max() > 1e-3
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
    moved = resolve_model(dae, {"k1.c": 2.0e4})
    assert moved is not dae
    M, K, C = (moved.system_damping_basis[0].toarray(), moved.system_damping_basis[1].toarray(),
               moved.system_damping_basis[2].toarray())
    lam, V = sl.eigh(K, M)
    zeta = np.diag(V.T @ C @ V)[1:] / (2 * np.sqrt(lam[1:]))
    np.testing.assert_allclose(zeta, [0.02, 0.07], rtol=1e-8)


@pytest.mark.parametrize("nut_joint", ["point", "moving"])
def test_a_controller_state_keeps_the_test_beds_modal_damping(nut_joint):
    """The FE test bed closed by the analog P-PI loop of Fig 4.3 (the PI's integrator is an internal state) with
    Table 5.2's guideway friction: flattening applies the bed's DriveModalDamping (toml ``[damping]``) computed
    from the structure alone, so its damping on the mechanical coordinates is the one of the bare bed
    (examples/slotting.py used to add it by hand); the mechanical modes keep their ratios (6 %, 10 % at C)."""
    from bscomp.components import CoulombFriction, Fixed, PIController, Tachometer
    from bscomp.systems.testbed import testbed_axial_torsional

    def bed():
        return testbed_axial_torsional(nut_position="C", coupling="bellows", nut_joint=nut_joint)

    closed = bed()
    closed.add("pi", PIController(K_v=18.217, K_i=4081.2))
    closed.add("tacho", Tachometer(H_g=0.0319))
    closed.connect("pi.y", "amp.u")
    closed.connect("tacho.flange", "rotor.flange_a")
    closed.connect("tacho.v", "pi.u_m")
    closed.add("guide_ground", Fixed())
    closed.add("friction", CoulombFriction(F_c_pos=2066.0, F_c_neg=2066.0, v_reg=1e-4))
    closed.connect("friction.flange_a", "guide_ground.flange")
    closed.connect("friction.flange_b", "table.flange_b")
    dae = bscomp.flatten(closed)
    mech = bscomp.flatten(bed())
    assert dae.mech.has_internal_states and dae.stats["system_damping"] == mech.stats["system_damping"]
    added_closed, added_bed = dae.system_damping_basis[2].toarray(), mech.system_damping_basis[2].toarray()
    names, ref = list(dae.mech.coordinate_names), list(mech.mech.coordinate_names)
    idx = [names.index(c) for c in ref]
    np.testing.assert_allclose(added_closed[np.ix_(idx, idx)], added_bed, rtol=0, atol=1e-9 * np.abs(added_bed).max())
    assert np.abs(np.delete(np.delete(added_closed, idx, 0), idx, 1)).max(initial=0.0) == 0.0
    M, K, _ = mech.system_damping_basis
    w2, V = sl.eigh(K.toarray(), M.toarray())
    elastic = w2 > 1.0
    zeta = np.diag(V[:, elastic].T @ added_bed @ V[:, elastic]) / (2 * np.sqrt(w2[elastic]))
    np.testing.assert_allclose(zeta[:2], [0.06, 0.10], rtol=1e-6)
