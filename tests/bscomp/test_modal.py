"""bscomp.linear.modal: undamped modes, damping ratios, modal masses and residues (thesis Sec 4.2, App. A.3)."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from bscomp import System, second_order
from bscomp.components import Fixed, Mass, Spring
from bscomp.errors import UnknownNameError
from bscomp.kernel.damping import modal_damping_matrix
from bscomp.linear.linearization import SecondOrderModel
from bscomp.linear.modal import Modes, modes
from bscomp.systems import mass_spring_chain, small_drive


def chain2(m1=2.0, m2=3.0, k1=1.0e4, k2=2.5e4):
    return mass_spring_chain((m1, m2), (k1, k2), name="chain2")


def analytic_chain2(m1, m2, k1, k2):
    """Roots of det(K - w^2 M) = 0 for the grounded 2-mass chain, in Hz."""
    a, b, c = m1 * m2, -(m1 * k2 + m2 * (k1 + k2)), k1 * k2
    disc = math.sqrt(b * b - 4 * a * c)
    return np.sort([math.sqrt(x) / (2 * math.pi) for x in ((-b - disc) / (2 * a), (-b + disc) / (2 * a))])


def test_two_mass_frequencies_match_analytic():
    md = modes(chain2())
    np.testing.assert_allclose(md.frequencies, analytic_chain2(2.0, 3.0, 1.0e4, 2.5e4), rtol=1e-9)
    assert not md.rigid_body.any()
    assert md.coordinates == ["m1.s", "m2.s"]


def test_mass_normalised_shapes():
    so = second_order(small_drive(), inputs=["motor.tau"])
    md = modes(so)
    M, K = so.M.toarray(), so.K.toarray()
    P = md.shapes
    np.testing.assert_allclose(P.T @ M @ P, np.eye(3), atol=1e-10)
    np.testing.assert_allclose(P.T @ K @ P, np.diag(md.omega**2), atol=1e-6 * md.omega.max() ** 2)
    # largest component positive (sign convention)
    assert np.all(P[np.argmax(np.abs(P), axis=0), range(3)] > 0)


@pytest.mark.parametrize("method", ["complex", "projection"])
def test_modal_damping_ratios_recovered(method):
    so = second_order(chain2(), inputs=["F.f"])
    zeta = np.array([0.02, 0.15])
    C = modal_damping_matrix(so.M, so.K, zeta)
    md = modes(replace(so, C=sp.csr_matrix(C)), damping=method)
    assert md.damping_method == method
    np.testing.assert_allclose(md.damping, zeta, atol=1e-10)
    np.testing.assert_allclose(md.frequencies, analytic_chain2(2.0, 3.0, 1.0e4, 2.5e4), rtol=1e-9)
    if method == "complex":  # poles -zeta w +- j w sqrt(1 - zeta^2)
        for k, p in enumerate(md.poles):
            w = md.omega[k]
            wd = w * math.sqrt(1 - zeta[k] ** 2)
            ref = [complex(-zeta[k] * w, -wd), complex(-zeta[k] * w, wd)]
            np.testing.assert_allclose(np.sort_complex(p), ref, rtol=1e-9)


def test_rigid_body_inertia_reflected_at_motor():
    s = small_drive()
    md = modes(s, inputs=["motor.tau"], outputs=["rotor.w"])
    assert md.rigid_body.tolist() == [True, False, False]
    assert md.frequencies[0] == 0.0
    r_g = s.get("lead.lead") / (2 * math.pi)
    J = s.get("rotor.J") + s.get("screw.J") + s.get("table.m") * r_g**2    # Eq 4.2
    assert md.reflected_inertia("rotor.phi") == pytest.approx(J, rel=1e-10)
    # viscous damping of the rigid-body motion (guideway damper) reflected at the motor: B = d r_g^2
    assert md.reflected_damping("rotor.phi") == pytest.approx(s.get("guide.d") * r_g**2, rel=1e-8)
    # projection phi^T C phi = B/J exactly; the damped rigid-body poles are real, 0 and close to -B/J
    # (the guideway damper also couples the rigid and elastic modes: non-proportional damping)
    assert md.decay_rates[0] == pytest.approx(s.get("guide.d") * r_g**2 / J, rel=1e-8)
    assert np.all(md.poles[0].imag == 0)
    np.testing.assert_allclose(np.sort(md.poles[0].real), [-md.decay_rates[0], 0.0], rtol=1e-3, atol=1e-12)
    # the same inertia reflected at the table is J / r_g^2
    assert md.modal_mass("table.s")[0] == pytest.approx(J / r_g**2, rel=1e-10)
    with pytest.raises(UnknownNameError):
        md.modal_mass("nope.phi")


def test_residues_are_products_of_mass_normalised_shapes():
    """Eq 4.4: R_k = P_ik P_jk / m_q,k = chi_ik chi_jk (collocated torque -> angle: chi_motor^2)."""
    md = modes(small_drive(), inputs=["motor.tau"], outputs=["rotor.phi", "table.s", "rotor.w"])
    chi_m, chi_t = md.shapes[0], md.shapes[2]
    np.testing.assert_allclose(md.residues[:, 0, 0], chi_m * chi_m, rtol=1e-12)
    np.testing.assert_allclose(md.residues[:, 1, 0], chi_t * chi_m, rtol=1e-12)
    np.testing.assert_allclose(md.residues[:, 2, 0], chi_m * chi_m, rtol=1e-12)
    assert md.output_order == [0, 0, 1]
    # rigid-body residue at the motor = 1/J (Eq 4.2: G_w^r = 1/(J s + B))
    assert md.residues[0, 0, 0] == pytest.approx(1 / md.reflected_inertia("rotor.phi"), rel=1e-12)


def test_massless_coordinate_condensed():
    """wall -k1- node -k2- m: the node has no mass; w^2 = k1 k2 / ((k1 + k2) m), node moves k2/(k1+k2)."""
    k1, k2, m = 1.0e4, 3.0e4, 2.0
    s = System("series")
    for name, c in (("wall", Fixed()), ("k1", Spring(c=k1)), ("k2", Spring(c=k2)), ("m", Mass(m=m))):
        s.add(name, c)
    s.connect("wall.flange", "k1.flange_a")
    s.connect("k1.flange_b", "k2.flange_a")
    s.connect("k2.flange_b", "m.flange_a")
    md = modes(s)
    assert len(md) == 1
    assert md.frequencies[0] == pytest.approx(math.sqrt(k1 * k2 / (k1 + k2) / m) / (2 * math.pi), rel=1e-12)
    node, mass = md.coordinates.index("k1.flange_b.s"), md.coordinates.index("m.s")
    assert md.shapes[node, 0] / md.shapes[mass, 0] == pytest.approx(k2 / (k1 + k2), rel=1e-12)
    assert md.shapes[mass, 0] == pytest.approx(1 / math.sqrt(m), rel=1e-12)


def test_sparse_shift_invert_matches_analytic_chain():
    """Fixed-free chain of N equal masses and springs: w_k = 2 sqrt(k/m) sin((2k-1) pi / (2(2N+1)))."""
    N, k, m = 600, 1.0e6, 0.5
    main = np.full(N, 2 * k)
    main[-1] = k
    K = sp.diags([main, -k * np.ones(N - 1), -k * np.ones(N - 1)], [0, 1, -1], format="csr")
    M = sp.identity(N, format="csr") * m
    Z = sp.csr_matrix((N, N))
    so = SecondOrderModel(M=M, C=Z, K=K, B=sp.csr_matrix((N, 0)), Cq=sp.identity(N, format="csr"), Cv=Z, Ca=Z,
                          D=sp.csr_matrix((N, 0)), coordinates=[f"x{i}" for i in range(N)], units=["m"] * N,
                          inputs=[], outputs=[f"x{i}" for i in range(N)])
    md = modes(so, n=6)
    assert md.method.startswith("sparse")
    j = np.arange(1, 7)
    w = 2 * math.sqrt(k / m) * np.sin((2 * j - 1) * math.pi / (2 * (2 * N + 1)))
    np.testing.assert_allclose(md.omega, w, rtol=1e-9)
    np.testing.assert_allclose(md.shapes.T @ (M @ md.shapes), np.eye(6), atol=1e-9)
    f3 = md.frequencies[2]
    assert np.all(modes(so, fmax=f3 * 1.0001).frequencies <= f3 * 1.0001)
    assert len(modes(so, fmax=f3 * 1.0001)) == 3


def test_outputs_table_csv_json_plot(tmp_path):
    md = modes(small_drive(), inputs=["motor.tau"], outputs=["rotor.w"])
    assert isinstance(md, Modes)
    txt = md.table("rotor.phi")
    assert "rigid body" in txt and "real poles" in txt and "m_q@rotor.phi" in txt
    d = json.loads(md.to_json(tmp_path / "m.json"))
    assert d["frequencies_hz"][0] == 0.0 and d["damping"][0] is None and len(d["shapes"]) == 3
    md.to_csv(tmp_path / "m.csv")
    rows = (tmp_path / "m.csv").read_text().splitlines()
    assert len(rows) == 4 and rows[0].startswith("mode,f_n_hz")
    md.plot(tmp_path / "m.png")
    assert (tmp_path / "m.png").stat().st_size > 1000


def test_computing_does_not_import_matplotlib():
    """modes() and frf() never import matplotlib (python-control does on import, so transfer_function
    and linearize cannot promise it)."""
    import subprocess
    import sys

    code = ("import sys; from bscomp.linear.modal import modes; from bscomp.linear.response import frf; "
            "from bscomp.systems import small_drive; s = small_drive(); modes(s); "
            "frf(s, 'motor.tau', 'rotor.w', [1.0, 10.0]); "
            "print('matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_non_symmetric_model_left_and_right_modes():
    """A non-symmetric pair (as a CMS superelement with MA recovery makes, Eq 5.18): ``K = [[2, -1], [-0.5, 1]]``,
    ``M = I``: ``w^2 = (3 -+ sqrt 3) / 2``; with proportional damping ``C = 0.02 K`` the ratios are ``0.01 w``,
    and the residues rebuild the FRF ``(K + i w C - w^2 M)^{-1} B`` exactly (left and right vectors)."""
    K = np.array([[2.0, -1.0], [-0.5, 1.0]])
    M, C = np.eye(2), 0.02 * K
    B = np.array([[1.0], [0.0]])
    so = SecondOrderModel(M=sp.csr_matrix(M), C=sp.csr_matrix(C), K=sp.csr_matrix(K), B=sp.csr_matrix(B),
                          Cq=sp.identity(2, format="csr"), Cv=sp.csr_matrix((2, 2)), Ca=sp.csr_matrix((2, 2)),
                          D=sp.csr_matrix((2, 1)), coordinates=["a", "b"], units=["m", "m"], inputs=["F"],
                          outputs=["a", "b"])
    md = modes(so)
    lam = np.array([(3 - math.sqrt(3)) / 2, (3 + math.sqrt(3)) / 2])
    assert md.omega**2 == pytest.approx(lam, rel=1e-12)
    assert md.damping == pytest.approx(0.01 * np.sqrt(lam), rel=1e-9)
    assert any("non-symmetric" in n for n in md.notes)
    for w in (0.3, 1.1, 2.7):
        H = np.linalg.solve(K + 1j * w * C - w**2 * M, B)[:, 0]
        Hm = sum(md.residues[k][:, 0] / (md.omega[k]**2 + 2j * md.damping[k] * md.omega[k] * w - w**2)
                 for k in range(2))
        assert Hm == pytest.approx(H, rel=1e-9)


@pytest.mark.parametrize("K", [np.diag([1.0e4, -2.0e4]), np.array([[2.0, -1.0], [-0.5, -1.0]])],
                         ids=["symmetric", "non-symmetric"])
def test_negative_stiffness_is_an_error_not_a_rigid_mode(K):
    """An indefinite stiffness (an unstable operating point) has a negative eigenvalue of ``K v = w^2 M v``
    (here -2e4, resp. (1 - sqrt 11) / 2): modes() refuses it instead of calling it a rigid-body mode."""
    from bscomp.errors import SingularSystemError

    Z = sp.csr_matrix((2, 2))
    so = SecondOrderModel(M=sp.identity(2, format="csr"), C=Z, K=sp.csr_matrix(K), B=sp.csr_matrix((2, 0)),
                          Cq=sp.identity(2, format="csr"), Cv=Z, Ca=Z, D=sp.csr_matrix((2, 0)),
                          coordinates=["a", "b"], units=["m", "m"], inputs=[], outputs=["a", "b"])
    with pytest.raises(SingularSystemError, match="negative eigenvalue"):
        modes(so)
