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
