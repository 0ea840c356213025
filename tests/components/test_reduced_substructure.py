"""CMS superelement with MA-recovered interior ports (thesis Eq 5.10-5.18) and the generic StructuralBlock.

Truths are the unreduced FE sub-model 1 of the test bed (97 axial + torsional DOF): the superelement's static
response to a load at an *interior* node must be the full model's exactly (MA is statically exact, Eq 5.18),
while the mode-displacement basis alone (Eq 5.11) misses it.
"""

import numpy as np
import pytest

from bscomp import System, flatten
from bscomp.components import FixedRotational, Force, NodeToFlange, ReducedSubstructure, StructuralBlock
from bscomp.errors import ModelDefinitionError
from bscomp.linear import second_order
from bscomp.linear.reduction import cms_reduce
from bscomp.systems.reduced_testbed import submodel1_matrices
from bscomp.systems.testbed import testbed as build


@pytest.fixture(scope="module")
def sub1():
    full = build("axial_torsional", "C", nut_joint="moving")
    M, K, names, sm1, _ = submodel1_matrices(full)
    red = cms_reduce(M, K, ["rotor.phi", "screw.n23.tz"], 3, dof_names=names)
    return M, K, names, red, sm1


def _static(se, node):
    """The superelement with the motor held and a 1 kN axial force at ``node``: static displacements by name
    (``K q = B u`` of its second-order form; its node potentials are quasi-static coordinates)."""
    s = System("static")
    s.add("sm1", se)
    s.add("hold", FixedRotational())
    s.connect("sm1.rotor", "hold.flange")
    s.add("push", Force())
    s.add("to_node", NodeToFlange(direction=1.0))
    s.connect(f"sm1.screw_n{node}", "to_node.node")
    s.connect("to_node.flange", "push.flange")
    so = second_order(flatten(s), inputs=["push.f"])
    q = np.linalg.solve(so.K.toarray(), so.B.toarray() @ [1000.0])
    return dict(zip(so.coordinates, q, strict=True))


@pytest.mark.parametrize("node", [10, 30, 40])
def test_static_load_at_an_interior_node_is_exact(sub1, node):
    M, K, names, red, sm1 = sub1
    se = ReducedSubstructure.from_reduction(red, M, K, names, beam=sm1.component("screw").beam_model())
    # truth: the unreduced sub-model, K d = F with the motor held
    i = names.index(f"screw.n{node}.w")
    free = np.array([n != "rotor.phi" for n in names])
    F = np.zeros(len(names))
    F[i] = 1000.0
    d = np.zeros(len(names))
    d[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    q = _static(se, node)
    assert q[f"sm1.screw_n{node}.w"] == pytest.approx(d[i], rel=1e-9)
    # the other nodes too (MA recovers the whole interior statically)
    for k in (5, 25, 45):
        assert q[f"sm1.screw_n{k}.w"] == pytest.approx(d[names.index(f"screw.n{k}.w")], rel=1e-8, abs=1e-15)
    # the mode-displacement recovery (Eq 5.11) of the same reduced state misses the interior load's static part
    x = np.linalg.lstsq(red.K[1:, 1:], red.force(F)[1:], rcond=None)[0]
    md = red.recover(np.r_[0.0, x], method="MD", at=[i])[0]
    assert abs(md - d[i]) > 1e-3 * abs(d[i])


def test_superelement_checks_its_input(sub1):
    M, K, names, red, _ = sub1
    with pytest.raises(ModelDefinitionError, match="K_r"):
        ReducedSubstructure(red.M, red.K[:3, :3], red.names, 2, [names[k] for k in red.interior],
                            K[np.ix_(red.interior, red.interior)], red.Psi[red.interior], (M @ red.Psi)[red.interior])
    with pytest.raises(ModelDefinitionError, match="n_exterior"):
        ReducedSubstructure(red.M, red.K, red.names, 0, [names[k] for k in red.interior],
                            K[np.ix_(red.interior, red.interior)], red.Psi[red.interior], (M @ red.Psi)[red.interior])
    se = ReducedSubstructure.from_reduction(red, M, K, names)
    with pytest.raises(ModelDefinitionError, match="beam"):
        se.beam_model()


def test_structural_block_adds_its_matrix_between_ports():
    """A StructuralBlock spring between two masses: the mode is sqrt(k (1/m1 + 1/m2)), its damper the decay."""
    from bscomp.components import Mass
    from bscomp.linear import modes

    s = System("two_masses")
    s.add("m1", Mass(m=2.0))
    s.add("m2", Mass(m=3.0))
    k, c = 1.2e4, 6.0
    Kb = k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    s.add("blk", StructuralBlock({"a": "Flange", "b": "Flange"}, ["a.s", "b.s"], K=Kb, C=c / k * Kb))
    s.connect("m1.flange_a", "blk.a")
    s.connect("m2.flange_a", "blk.b")
    md = modes(s)
    w = np.sqrt(k * (1 / 2.0 + 1 / 3.0))
    assert md.omega[-1] == pytest.approx(w, rel=1e-12)
    assert md.damping[-1] == pytest.approx(c * (1 / 2.0 + 1 / 3.0) / (2 * w), rel=1e-9)
    with pytest.raises(ModelDefinitionError, match="kind"):
        StructuralBlock({"a": "Spring"}, ["a.s"], K=[[1.0]])
    with pytest.raises(ModelDefinitionError, match="names no declared port"):
        StructuralBlock({"a": "Flange"}, ["b.s"], K=[[1.0]])
    with pytest.raises(ModelDefinitionError, match=r"\(1, 1\)"):
        StructuralBlock({"a": "Flange"}, ["a.s"], K=np.eye(2))


def test_node_ports_give_the_ma_port_of_the_reduction(sub1):
    """At any nut position z, the superelement's interior equations recover ``N(z) d`` exactly as
    ``ReducedModel.port(N(z))`` does (Eq 5.18: ``C_x x + C_a x'' + D f``, ``D = N K_ii^{-1} N^T``) for random
    reduced states, accelerations and joint forces."""
    M, K, names, red, sm1 = sub1
    se = ReducedSubstructure.from_reduction(red, M, K, names, beam=sm1.component("screw").beam_model())
    blk = se.structure()
    m, n_i = red.n_reduced, red.interior.size
    Kb, Mb = blk.K.toarray(), blk.M.toarray()
    # the correction rows: d_i - T2 x - T1 x'' - mu = 0, and the node rows: F_i = K_ii mu
    rows = slice(m + n_i, m + 2 * n_i)
    T2x, T1x = -Kb[rows, :m], -Mb[rows, :m]
    Kii = Kb[m:m + n_i, m + n_i:]
    beam = sm1.component("screw").beam_model()
    rng = np.random.default_rng(3)
    for z in (0.2113, 0.4325, 0.70):
        S = beam.shape_matrix(z).toarray()[[2, 5]]                # (w, tz) rows of N(z) over the 6-DOF nodes
        cols = {f"screw.n{k}.{d}": 6 * k + j for k in range(beam.n_nodes) for j, d in ((2, "w"), (5, "tz"))}
        N = np.zeros((2, len(names)))
        for c, name in enumerate(names):
            if name in cols:
                N[:, c] = S[:, cols[name]]
        port = red.port(N)
        x, xdd, f = rng.normal(size=m), rng.normal(size=m), rng.normal(size=2) * [1e3, 10.0]
        F_i = (N.T @ f)[red.interior]
        d_i = T2x @ x + T1x @ xdd + np.linalg.solve(Kii, F_i)
        y = N[:, red.interior] @ d_i + N[:, red.exterior] @ x[:red.n_exterior]
        assert y == pytest.approx(port.output(x, xdd, f), rel=1e-9, abs=1e-15)
