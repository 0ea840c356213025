"""Tests for bscomp.kernel.damping (thesis Appendix A.3, Eq A.10-A.15, and Rayleigh damping)."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.kernel.damping import (
    damped_modal_properties,
    damping_from_modes,
    matrix_from_ratios,
    modal_damping_matrix,
    rayleigh_coefficients,
    rayleigh_damping_matrix,
)


def chain(masses, springs, grounded=True):
    """Spring-mass chain; with ``grounded`` the first mass is tied to ground by springs[0]."""
    n = len(masses)
    M = np.diag(np.asarray(masses, dtype=float))
    K = np.zeros((n, n))
    ks = list(springs)
    if grounded:
        K[0, 0] += ks.pop(0)
    assert len(ks) == n - 1
    for i, k in enumerate(ks):
        K[i, i] += k
        K[i + 1, i + 1] += k
        K[i, i + 1] -= k
        K[i + 1, i] -= k
    return M, K


@pytest.fixture
def grounded4():
    return chain([1.0, 2.0, 1.5, 0.5], [4.0e5, 2.0e5, 3.0e5, 1.0e5])


@pytest.fixture
def free5():
    # free-free torsional chain, thesis-like magnitudes: rotor+jaw, jaw, screw pieces
    return chain([6.3e-3, 3.1e-4, 4.0e-4, 4.0e-4, 4.0e-4], [3938.0, 2.0e5, 2.0e5, 2.0e5], grounded=False)


def test_per_mode_ratios_recovered(grounded4):
    M, K = grounded4
    zeta = np.array([0.01, 0.05, 0.10, 0.20])
    C = modal_damping_matrix(M, K, zeta)
    wn, z = damped_modal_properties(M, C, K)
    lam = sla.eigh(K, M, eigvals_only=True)
    np.testing.assert_allclose(wn, np.sqrt(lam), rtol=1e-8)
    np.testing.assert_allclose(z, zeta, rtol=0, atol=1e-8)


def test_scalar_ratio_recovered(grounded4):
    M, K = grounded4
    C = modal_damping_matrix(M, K, 0.06)
    _, z = damped_modal_properties(M, C, K)
    np.testing.assert_allclose(z, 0.06, atol=1e-8)


def test_modal_damping_is_diagonal_in_modes(grounded4):
    """Eq A.15 inverted: chi^T C chi = diag(2 zeta omega) (Eq A.14)."""
    M, K = grounded4
    zeta = np.array([0.02, 0.03, 0.04, 0.05])
    C = modal_damping_matrix(M, K, zeta)
    lam, chi = sla.eigh(K, M)
    np.testing.assert_allclose(chi.T @ C @ chi, np.diag(2 * zeta * np.sqrt(lam)), atol=1e-8 * np.abs(C).max())


def test_damping_from_modes_is_eq_a15_on_given_modes(free5):
    """The modes solved once (matrix_from_ratios): the same C as modal_damping_matrix's own eigh, every elastic
    mode at its ratio, the rigid one undamped."""
    M, K = free5
    lam, chi = sla.eigh(K, M)
    zeta = np.array([0.0, 0.06, 0.10, 0.02, 0.02])
    C = damping_from_modes(M, lam, chi, zeta)
    np.testing.assert_array_equal(C, modal_damping_matrix(M, K, zeta))
    om = np.sqrt(np.clip(lam, 0.0, None))
    np.testing.assert_allclose(chi.T @ C @ chi, np.diag(2 * zeta * om), atol=1e-10 * np.abs(C).max())

    class ByFrequency:                       # an option that gives ratios by mode, as DriveModalDamping does
        def modal_ratios(self, lam, phi, M, coordinates=None):
            return np.where(np.sqrt(np.clip(lam, 0.0, None)) > 1e3, 0.02, 0.06)

    C2 = matrix_from_ratios(ByFrequency(), M, K)
    z2 = np.diag(chi.T @ C2 @ chi)[1:] / (2 * om[1:])
    np.testing.assert_allclose(z2, np.where(om[1:] > 1e3, 0.02, 0.06), rtol=1e-9)
    np.testing.assert_allclose(C2 @ np.ones(5), 0.0, atol=1e-12 * np.abs(C2).max())   # the rigid mode


def test_rigid_mode_undamped_free_free(free5):
    M, K = free5
    zeta = np.array([0.06, 0.10, 0.05, 0.05])
    C = modal_damping_matrix(M, K, zeta)
    rigid = np.ones(M.shape[0])
    assert np.max(np.abs(C @ rigid)) <= 1e-10 * np.max(np.abs(C))
    # elastic ratios are still exact
    _, z = damped_modal_properties(M, C, K)
    np.testing.assert_allclose(z, zeta, atol=1e-8)
    # explicit n_rigid gives the same matrix, and a full-length zeta ignores the rigid entry
    np.testing.assert_allclose(modal_damping_matrix(M, K, zeta, n_rigid=1), C, rtol=1e-12, atol=0)
    np.testing.assert_allclose(modal_damping_matrix(M, K, np.r_[0.5, zeta]), C, rtol=1e-12, atol=0)


def test_rigid_mode_gives_zero_eigenvalue(free5):
    M, K = free5
    C = modal_damping_matrix(M, K, 0.05)
    # the damped system keeps a double zero eigenvalue (rigid body, no viscous term)
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    s = np.linalg.eigvals(A)
    assert np.sum(np.abs(s) < 1e-6 * np.abs(s).max()) == 2


@pytest.mark.parametrize("fixture", ["grounded4", "free5"])
def test_symmetric_psd(fixture, request):
    M, K = request.getfixturevalue(fixture)
    C = modal_damping_matrix(M, K, [0.01, 0.2, 0.05, 0.3][: M.shape[0] - (1 if fixture == "free5" else 0)])
    np.testing.assert_array_equal(C, C.T)
    ev = np.linalg.eigvalsh(C)
    assert ev.min() >= -1e-12 * ev.max()


def test_sparse_input_matches_dense(grounded4):
    M, K = grounded4
    Cd = modal_damping_matrix(M, K, 0.05)
    Cs = modal_damping_matrix(sp.csr_matrix(M), sp.csc_matrix(K), 0.05)
    assert isinstance(Cs, np.ndarray)
    np.testing.assert_allclose(Cs, Cd, rtol=1e-12)


def test_modal_damping_validation(grounded4):
    M, K = grounded4
    with pytest.raises(ValueError, match="zeta"):
        modal_damping_matrix(M, K, [0.1, 0.2])
    with pytest.raises(ValueError, match="zeta"):
        modal_damping_matrix(M, K, -0.1)
    with pytest.raises(ValueError, match="zeta"):
        modal_damping_matrix(M, K, np.nan)
    with pytest.raises(ValueError, match="M"):
        modal_damping_matrix(np.ones((3, 4)), K, 0.1)
    with pytest.raises(ValueError, match="M and K"):
        modal_damping_matrix(M[:3, :3], K, 0.1)
    with pytest.raises(ValueError, match="K"):
        Kn = K.copy()
        Kn[0, 1] += 1.0
        modal_damping_matrix(M, Kn, 0.1)
    with pytest.raises(ValueError, match="M"):
        modal_damping_matrix(-M, K, 0.1)
    with pytest.raises(ValueError, match="K"):
        modal_damping_matrix(M, -K, 0.1)
    with pytest.raises(ValueError, match="n_rigid"):
        modal_damping_matrix(M, K, 0.1, n_rigid=7)
    with pytest.raises(ValueError, match="rigid_tol"):
        modal_damping_matrix(M, K, 0.1, rigid_tol=-1.0)


def test_rayleigh_hits_targets_exactly():
    z1, z2, f1, f2 = 0.02, 0.07, 50.0, 400.0
    a, b = rayleigh_coefficients((z1, z2), f1, f2)
    for z, f in ((z1, f1), (z2, f2)):
        w = 2 * np.pi * f
        assert a / (2 * w) + b * w / 2 == pytest.approx(z, rel=1e-12)


def test_rayleigh_matrix_modes_at_f1_f2():
    """2-DOF system whose natural frequencies are f1, f2: eigen-analysis recovers both targets."""
    M, K = chain([1.0, 0.7], [3.0e5, 1.2e5])
    wn = np.sqrt(sla.eigh(K, M, eigvals_only=True))
    f1, f2 = wn / (2 * np.pi)
    C = rayleigh_damping_matrix(M, K, zeta=(0.03, 0.08), f1=f1, f2=f2)
    w, z = damped_modal_properties(M, C, K)
    np.testing.assert_allclose(w, wn, rtol=1e-8)
    np.testing.assert_allclose(z, [0.03, 0.08], atol=1e-8)
    # same ratio at both frequencies from a scalar zeta
    C = rayleigh_damping_matrix(M, K, zeta=0.05, f1=f1, f2=f2)
    np.testing.assert_allclose(damped_modal_properties(M, C, K)[1], 0.05, atol=1e-8)


def test_rayleigh_from_coefficients_and_sparse(grounded4):
    M, K = grounded4
    C = rayleigh_damping_matrix(M, K, alpha=3.0, beta=2e-5)
    np.testing.assert_allclose(C, 3.0 * M + 2e-5 * K)
    np.testing.assert_allclose(rayleigh_damping_matrix(M, K, beta=1e-4), 1e-4 * K)
    Cs = rayleigh_damping_matrix(sp.csr_matrix(M), sp.csr_matrix(K), alpha=3.0, beta=2e-5)
    assert sp.issparse(Cs)
    np.testing.assert_allclose(Cs.toarray(), C)


def test_rayleigh_validation(grounded4):
    M, K = grounded4
    with pytest.raises(ValueError, match="not both"):
        rayleigh_damping_matrix(M, K, alpha=1.0, zeta=0.05, f1=10.0, f2=20.0)
    with pytest.raises(ValueError, match="alpha"):
        rayleigh_damping_matrix(M, K)
    with pytest.raises(ValueError, match="f2"):
        rayleigh_damping_matrix(M, K, zeta=0.05, f1=10.0)
    with pytest.raises(ValueError, match="differ"):
        rayleigh_damping_matrix(M, K, zeta=0.05, f1=10.0, f2=10.0)
    with pytest.raises(ValueError, match="f1"):
        rayleigh_damping_matrix(M, K, zeta=0.05, f1=-1.0, f2=10.0)
    with pytest.raises(ValueError, match="zeta"):
        rayleigh_damping_matrix(M, K, zeta=(0.1, 0.2, 0.3), f1=1.0, f2=10.0)
    with pytest.raises(ValueError, match="alpha"):
        rayleigh_damping_matrix(M, K, alpha=-1.0)
    with pytest.raises(ValueError, match="M and K"):
        rayleigh_damping_matrix(M, K[:2, :2], alpha=1.0)
