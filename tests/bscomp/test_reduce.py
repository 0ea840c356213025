"""Tests of bscomp.linear.reduction: CMS reduction and MD/MA recovery (thesis Sec 5.2.3, Eq 5.10-5.18, Table 5.3).

The test structure is the thesis's sub-model 1 (Table 5.1, Sec 5.3.1): the axial + torsional DOF of
the ballscrew with the parts attached to it, but not the nut and table (sub-model 2):

* screw: Table B.1 sections, 48 Timoshenko nodes, DOF ``w`` and ``θz`` only (bending deleted, Sec 5.3.1);
* thrust (angular-contact) bearing: axial spring 2.70e8 N/m at x = 0.8755 m (CHOICE of the parameter
  file: middle node of section E);
* deep-groove bearing: radial only (k_axial = 0), so it adds nothing to the axial/torsional DOF;
* coupling: torsional spring k_T = 3938 N m/rad between the motor DOF and the screw end node
  (x = 0.9205 m, CHOICE), screw-side jaw J2 lumped on that node;
* rotor: one torsional DOF carrying I_rotor + J1 (CHOICE: motor-side jaw on the rigid motor shaft).

That is 97 DOF; Table 5.1 says 101 and does not say where the other 4 are (THESIS-NOTES).  The torsion
has no ground (bearings are axial/radial springs), so the sub-model has one rigid-body mode, which is
why the thesis's reduced model has ``E + P + 1 = 6`` coordinates (Sec 5.3.2).

The second exterior DOF ("a node at the centre of the ballscrew", Sec 5.3.2) is taken as ``θz`` of the
node nearest mid-length: with ``w`` the axial mode picks up a 2.8 % error and the torsional modes none,
the opposite of Table 5.3; with ``θz`` the pattern of Table 5.3 (0.8 / 0.000 / 0.007 %) is reproduced.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.components._beam_fe import BeamModel, DofSelection, assemble_shaft, select_dofs
from bscomp.errors import SingularSystemError
from bscomp.kernel.damping import modal_damping_matrix
from bscomp.linear.reduction import ReducedModel, cms_reduce
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.thesis_parts import thesis_sections as table_b1

P = load_parameters()
THESIS_FULL = np.array(get_value(P, "reference_results.table53_full"))  # 260.86, 793.46, 1276.40 Hz
THESIS_ERR = np.array(get_value(P, "reference_results.table53_error_percent"))
R_G = get_value(P, "control.r_g")


@dataclass
class SubModel1:
    M: np.ndarray
    K: np.ndarray
    names: list
    beam: BeamModel
    sel: DofSelection
    motor: int
    centre_node: int

    def dof(self, node: int, name: str) -> int:
        return self.sel.local_index(node, name)

    def nut_row(self, z: float) -> sp.csr_matrix:
        """(2, n) row N(z): (w, θz) of the screw at axial position z (Sec 5.2.2.3)."""
        S = self.beam.shape_matrix(z)[[2, 5]][:, self.sel.index]
        return sp.hstack([S, sp.csr_matrix((2, 1))]).tocsr()


def build_submodel1() -> SubModel1:
    screw = P["screw"]
    beam = assemble_shaft(
        table_b1(d_root=get_value(P, "screw.root_diameter"),
                 d_equiv=get_value(P, "screw.equivalent_diameter")),
        E=screw["material"]["youngs_modulus"]["value"], rho=screw["material"]["density"]["value"],
        nu=screw["material"]["poissons_ratio"]["value"], kappa=screw["material"]["shear_factor"]["value"],
    )
    sel = select_dofs(beam, ("w", "tz"))
    z = beam.z_nodes
    n = sel.M.shape[0]
    M = np.zeros((n + 1, n + 1))
    K = np.zeros((n + 1, n + 1))
    M[:n, :n] = sel.M.toarray()
    K[:n, :n] = sel.K.toarray()
    ib = sel.local_index(int(np.argmin(abs(z - get_value(P, "bearings.b1_position")))), "w")
    K[ib, ib] += get_value(P, "bearings.b1_k_axial")
    jc = sel.local_index(int(np.argmin(abs(z - get_value(P, "coupling.attach_position")))), "tz")
    M[jc, jc] += get_value(P, "coupling.J2")
    motor = n
    M[motor, motor] = get_value(P, "rotor.Izz") + get_value(P, "coupling.J1")
    K[np.ix_([motor, jc], [motor, jc])] += get_value(P, "coupling.kT") * np.array([[1.0, -1.0], [-1.0, 1.0]])
    names = [f"screw.n{k}.{d}" for k in range(beam.n_nodes) for d in ("w", "tz")] + ["rotor.phi"]
    centre = int(np.argmin(abs(z - z[-1] / 2)))
    return SubModel1(M=M, K=K, names=names, beam=beam, sel=sel, motor=motor, centre_node=centre)


def full_frequencies(M, K):
    return np.sqrt(np.clip(sla.eigh(K, M, eigvals_only=True), 0.0, None)) / (2 * np.pi)


@pytest.fixture(scope="module")
def sm1() -> SubModel1:
    return build_submodel1()


@pytest.fixture(scope="module")
def f_full(sm1):
    return full_frequencies(sm1.M, sm1.K)


@pytest.fixture(scope="module")
def thesis_red(sm1) -> ReducedModel:
    """Sec 5.3.2: E = 2 (motor, centre-node θz), P = 3 free-interface modes + 1 rigid-body mode."""
    return cms_reduce(sm1.M, sm1.K, ["rotor.phi", f"screw.n{sm1.centre_node}.tz"], 3, dof_names=sm1.names)


NUT_POSITIONS = np.linspace(get_value(P, "table.nut_position_L"), get_value(P, "table.nut_position_R"), 9)


# ------------------------------------------------------------------------------ the full sub-model
def test_submodel1_full_frequencies_vs_table53(sm1, f_full):
    assert sm1.M.shape == (97, 97)  # Table 5.1: 101 (see module docstring)
    assert f_full[0] < 1e-2 and f_full[1] > 100.0  # exactly one rigid-body (torsional) mode
    # regression pin of our model, and the documented gap to Table 5.3 (not tuned):
    # +1.0 % (coupling torsion), +5.9 % (axial), -3.2 % (2nd torsion)
    np.testing.assert_allclose(f_full[1:4], [263.565, 840.204, 1235.701], rtol=2e-5)
    gap = f_full[1:4] / THESIS_FULL - 1.0
    assert np.all(np.abs(gap) < 0.07), gap


# ------------------------------------------------------------------------------ reduction, Table 5.3
def test_table53_reduced_model(thesis_red, f_full):
    red = thesis_red
    assert red.n_reduced == 6 and red.n_rigid == 1
    assert red.names == ("rotor.phi", "screw.n23.tz", "q_rb1", "q1", "q2", "q3")
    fr = red.natural_frequencies()
    assert fr[0] < 1e-2  # rigid-body mode kept exactly (it lies in the span of the constraint modes)
    err = 100 * (fr[1:4] / f_full[1:4] - 1.0)
    assert np.all(err > -1e-9)  # Rayleigh-Ritz: upper bounds
    assert np.all(err < 1.0)  # Table 5.3: max 0.8 %
    # the thesis's pattern: the coupling mode carries the error, the axial mode is exact
    assert 0.3 < err[0] < 1.0 and abs(err[1]) < 1e-6 and err[2] < 0.05
    assert THESIS_ERR[1] == 0.0 and abs(err[0] - THESIS_ERR[0]) < 0.2


@pytest.mark.parametrize("interface", ["free", "fixed"])
@pytest.mark.parametrize("f_cut", [3000.0, 6000.0])
def test_frequencies_below_cutoff_within_one_percent(sm1, f_full, interface, f_cut):
    ext = [sm1.motor, sm1.dof(sm1.centre_node, "tz")]
    red = cms_reduce(sm1.M, sm1.K, ext, f_cut=f_cut, interface=interface)
    assert np.all(red.mode_frequencies <= f_cut)
    fr = red.natural_frequencies()
    k = int(np.searchsorted(f_full, f_cut))
    assert k >= 5
    err = fr[1:k] / f_full[1:k] - 1.0
    assert np.all(err > -1e-9) and np.all(err < 0.01), err


@pytest.mark.parametrize("interface", ["free", "fixed"])
def test_frequency_error_decreases_with_modes(sm1, f_full, interface):
    ext = [sm1.motor, sm1.dof(sm1.centre_node, "tz")]
    errs = [cms_reduce(sm1.M, sm1.K, ext, p, interface=interface).natural_frequencies()[1] / f_full[1] - 1
            for p in (3, 5, 7, 9, 11)]
    assert np.all(np.diff(errs) <= 1e-12) and errs[-1] < errs[0]


@pytest.mark.parametrize("interface", ["free", "fixed"])
def test_reduced_matrix_invariants(sm1, interface):
    red = cms_reduce(sm1.M, sm1.K, [sm1.motor, sm1.dof(sm1.centre_node, "tz")], 4, interface=interface)
    for A in (red.M, red.K):
        np.testing.assert_array_equal(A, A.T)
    assert np.all(np.linalg.eigvalsh(red.M) > 0)
    assert np.min(np.linalg.eigvalsh(red.K)) > -1e-9 * np.max(np.abs(red.K))
    # Eq 5.12: identity on the exterior rows, zero modal part there
    np.testing.assert_array_equal(red.Psi[red.exterior], np.eye(red.n_exterior, red.n_reduced))
    # constraint modes are K-orthogonal to the modal columns (K_red block-diagonal)
    E = red.n_exterior
    assert np.max(np.abs(red.K[:E, E:])) < 1e-8 * np.max(np.abs(red.K))
    # Eq 5.14 literally
    np.testing.assert_allclose(red.M, red.Psi.T @ sm1.M @ red.Psi, rtol=1e-12, atol=1e-15)


def test_sparse_input_and_names(sm1, thesis_red):
    ext = [sm1.motor, sm1.dof(sm1.centre_node, "tz")]
    red = cms_reduce(sp.csr_matrix(sm1.M), sp.csr_matrix(sm1.K), ext, 3)
    np.testing.assert_allclose(red.K, thesis_red.K, rtol=1e-10, atol=1e-6)
    assert red.names[:2] == (f"d{sm1.motor}", f"d{sm1.dof(sm1.centre_node, 'tz')}")


# ------------------------------------------------------------------------------ recovery, statics
def _static_motor_held(sm1, red, F):
    """Full and reduced static solutions with the motor rotation held at 0 (servo-locked)."""
    free = np.arange(sm1.M.shape[0]) != sm1.motor
    d = np.zeros(sm1.M.shape[0])
    d[free] = np.linalg.solve(sm1.K[np.ix_(free, free)], F[free])
    x = np.zeros(red.n_reduced)
    x[1:] = np.linalg.solve(red.K[1:, 1:], red.force(F)[1:])
    return d, x


@pytest.mark.parametrize("z_nut", [0.1531, 0.3, 0.4325, 0.5555, 0.7119])
def test_ma_static_recovery_exact_at_any_nut_position(sm1, thesis_red, z_nut):
    R = sm1.nut_row(z_nut)
    F = R.T @ np.array([1.0e3, R_G * 1.0e3])  # axial force and the screw torque it implies
    d, x = _static_motor_held(sm1, thesis_red, F)
    d_ma = thesis_red.recover(x, np.zeros_like(x), F, method="MA")
    assert np.max(np.abs(d_ma - d)) <= 1e-8 * np.max(np.abs(d))
    y = R @ d
    np.testing.assert_allclose(thesis_red.recover(x, f=F, at=R), y, rtol=1e-8)
    # MD misses the static effect of the interior load
    assert np.all(np.abs(thesis_red.recover(x, method="MD", at=R) - y) > 1e-3 * np.abs(y))


@pytest.mark.parametrize("anchor, load", [("tz", 1), ("w", 0)])
def test_md_error_grows_away_from_anchor(sm1, anchor, load):
    """MD is exact with the load on the anchor node; its error grows with the nut's distance from it."""
    red = cms_reduce(sm1.M, sm1.K, [sm1.motor, sm1.dof(sm1.centre_node, anchor)], 3)
    z_a = sm1.beam.z_nodes[sm1.centre_node]
    zs = np.sort(np.append(NUT_POSITIONS, z_a))
    err_md, err_ma = [], []
    for z in zs:
        R = sm1.nut_row(z)
        F = R.T @ np.eye(2)[load]
        d, x = _static_motor_held(sm1, red, F)
        y = (R @ d)[load]
        err_md.append(abs(red.recover(x, method="MD", at=R)[load] - y) / abs(y))
        err_ma.append(abs(red.recover(x, f=F, at=R)[load] - y) / abs(y))
    err_md = np.array(err_md)
    ia = int(np.flatnonzero(zs == z_a)[0])
    assert err_md[ia] < 1e-10 and max(err_ma) < 1e-8
    assert np.all(np.diff(err_md[: ia + 1]) < 0) and np.all(np.diff(err_md[ia:]) > 0)
    assert min(err_md[0], err_md[-1]) > 0.02  # 3-20 % at the ends of travel (see docs)


# ------------------------------------------------------------------------------ recovery, dynamics
@pytest.mark.parametrize("f_hz", [25.0, 50.0, 100.0])
@pytest.mark.parametrize("z_nut", [0.1531, 0.4325, 0.7119])
def test_ma_beats_md_for_harmonic_nut_load_below_first_mode(sm1, thesis_red, f_full, f_hz, z_nut):
    """Harmonic nut load at z_nut, well below the first elastic mode (264 Hz).

    Axial force -> axial nut displacement: MD misses 5-17 % (the static residual), MA < 2e-4.
    Torque -> nut rotation: both are dominated by the rigid-body inertia that both capture, yet MA is
    still ~10x better (MD up to 28 % at 100 Hz near the L position).
    """
    assert f_hz < 0.5 * f_full[1]
    w = 2 * np.pi * f_hz
    R = sm1.nut_row(z_nut)
    red = thesis_red
    err = {}
    for k in (0, 1):  # 0: axial force / w, 1: torque / θz
        F = R.T @ np.eye(2)[k]
        y = (R @ np.linalg.solve(sm1.K - w * w * sm1.M, F))[k]
        x = np.linalg.solve(red.K - w * w * red.M, red.force(F))
        e_ma = abs(red.recover(x, -w * w * x, F, at=R)[k] - y) / abs(y)
        e_md = abs(red.recover(x, method="MD", at=R)[k] - y) / abs(y)
        err[k] = (e_ma, e_md)
    assert err[0][0] < 2e-4 and err[0][1] > 0.04 and err[0][0] < 0.01 * err[0][1], err
    assert err[1][0] < 0.01 and err[1][0] < 0.15 * err[1][1], err


def test_ma_recovery_with_damping(sm1, thesis_red):
    C = modal_damping_matrix(sm1.M, sm1.K, 0.06)
    red = cms_reduce(sm1.M, sm1.K, list(thesis_red.exterior), 3, C=C)
    np.testing.assert_allclose(red.C, red.C.T)
    w = 2 * np.pi * 100.0
    R = sm1.nut_row(0.6)
    F = R.T @ np.array([1.0e3, R_G * 1.0e3])
    y = R @ np.linalg.solve(sm1.K + 1j * w * C - w * w * sm1.M, F)
    x = np.linalg.solve(red.K + 1j * w * red.C - w * w * red.M, red.force(F))
    # complex amplitudes through the real recovery matrices
    ma = red.T1 @ (-w * w * x) + red.T1v @ (1j * w * x) + red.T2 @ x
    ma[red.interior] += red.G_ii @ F[red.interior]
    e_ma = np.abs(R @ ma - y) / np.abs(y)
    e_md = np.abs(R @ (red.Psi @ x) - y) / np.abs(y)
    assert np.all(e_ma < 0.1 * e_md), (e_ma, e_md)
    # real-valued API with velocities gives the same as the matrices
    xr = x.real
    np.testing.assert_allclose(
        red.recover(xr, xr, F, xd=xr, at=R), R @ (red.T2 @ xr + red.T1 @ xr + red.T1v @ xr)
        + R @ red.recover(np.zeros_like(xr), f=F), rtol=1e-12)


# ------------------------------------------------------------------------------ moving nut port
def test_port_matches_recover_and_is_cheap_to_move(sm1, thesis_red):
    red = thesis_red
    rng = np.random.default_rng(0)
    x, xdd, fp = rng.normal(size=6), rng.normal(size=6), rng.normal(size=2)
    for z in (0.1531, 0.4325, sm1.beam.z_nodes[sm1.centre_node], 0.7119):
        R = sm1.nut_row(z)
        port = red.port(R)
        np.testing.assert_allclose(port.B, red.Psi.T @ R.T.toarray(), rtol=1e-12, atol=1e-18)
        F = R.T @ fp
        np.testing.assert_allclose(port.output(x, xdd, fp), red.recover(x, xdd, F, at=R), rtol=1e-10)
        np.testing.assert_allclose(port.output(x, method="MD"), red.recover(x, method="MD", at=R), rtol=1e-12)
        np.testing.assert_allclose(port.D, port.D.T)
        assert np.all(np.linalg.eigvalsh(port.D) > -1e-18)
    # an integer DOF as a row equals selecting that DOF
    j = sm1.dof(10, "w")
    np.testing.assert_allclose(red.port(j).output(x, xdd), red.recover(x, xdd, at=[j]))


def _ksn_2x2():
    c = get_value(P, "screw_nut.K_SN_coefficients")
    kb = get_value(P, "screw_nut.k_ball")
    return kb * np.array([[c[2], c[10]], [c[10], c[5]]])  # (w, θz): k_zz, k_ztz, k_tztz (Eq 3.45)


@pytest.mark.parametrize("z_nut", [0.1531, 0.4325, 0.7119])
def test_moving_nut_joint_static_with_ma_port_is_exact(sm1, thesis_red, z_nut):
    """Sec 5.2.2.3 / Fig 5.8: K_SN between the screw at z_nut and the table displaced by u.

    The port's feed-through D closes the algebraic loop of the MA output; the static coupled result
    then equals the full model's, with no re-reduction for the new nut position.
    """
    Ksn = _ksn_2x2()
    u = np.array([1e-5, 0.0])  # table displaced 10 µm, nut does not rotate
    R = sm1.nut_row(z_nut)
    Rd = R.toarray()
    Kfull = sm1.K + Rd.T @ Ksn @ Rd
    d = np.linalg.solve(Kfull, R.T @ (Ksn @ u))
    y_full = R @ d
    port = thesis_red.port(R)
    # f = -Ksn (y - u), y = C_x x + D f  =>  f = -S (C_x x - u), S = (I + Ksn D)^-1 Ksn
    S = np.linalg.solve(np.eye(2) + Ksn @ port.D, Ksn)
    x = np.linalg.solve(thesis_red.K + port.B @ S @ port.C_x, port.B @ S @ u)
    f = -S @ (port.C_x @ x - u)
    np.testing.assert_allclose(port.output(x, f=f), y_full, rtol=1e-7)
    x_md = np.linalg.solve(thesis_red.K + port.B @ Ksn @ port.C_md, port.B @ Ksn @ u)
    assert abs(port.output(x_md, method="MD")[0] - y_full[0]) > 1e-3 * abs(y_full[0])


def _coupled_frequencies(sm1, red, z_nut, method):
    """Sub-model 1 + K_SN joint at z_nut + table/nut mass (sub-model 2), Fig 5.8: frequencies [Hz].

    Returns (full, reduced) sorted frequencies.  With MA the port output ``y = C_x x + C_a x'' + D f``
    and ``f = -K_SN (y - [u, 0])`` are solved for ``f`` (``S = (I + K_SN D)^-1 K_SN``), which puts
    ``B S C_a`` into the mass and ``B S C_x`` into the stiffness of the coupled reduced model.
    """
    Ksn = _ksn_2x2()
    mt = get_value(P, "table.mass") + get_value(P, "nut.mass")
    e1 = np.array([1.0, 0.0])
    R = sm1.nut_row(z_nut).toarray()
    n, m = sm1.M.shape[0], red.n_reduced
    Rf = np.hstack([R, -e1[:, None]])
    Mf = np.zeros((n + 1, n + 1))
    Mf[:n, :n], Mf[n, n] = sm1.M, mt
    Kf = np.zeros((n + 1, n + 1))
    Kf[:n, :n] = sm1.K
    Kf += Rf.T @ Ksn @ Rf
    port = red.port(R)
    Mc = np.zeros((m + 1, m + 1))
    Kc = np.zeros((m + 1, m + 1))
    Mc[m, m] = mt
    if method == "MA":
        S = np.linalg.solve(np.eye(2) + Ksn @ port.D, Ksn)
        Mc[:m, :m] = red.M + port.B @ S @ port.C_a
        Mc[m, :m] = -e1 @ S @ port.C_a
        Kc[:m, :m] = red.K + port.B @ S @ port.C_x
        Kc[:m, m] = -port.B @ S @ e1
        Kc[m, :m] = -e1 @ S @ port.C_x
        Kc[m, m] = e1 @ S @ e1
    else:
        Rr = np.hstack([port.C_md, -e1[:, None]])
        Mc[:m, :m] = red.M
        Kc[:m, :m] = red.K
        Kc += Rr.T @ Ksn @ Rr
    lam = np.sort(sla.eigvals(Kc, Mc).real)
    return full_frequencies(Mf, Kf), np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)


@pytest.mark.parametrize("z_nut", [0.1531, 0.4325, 0.7119])
def test_coupled_axial_mode_with_moving_nut(sm1, thesis_red, z_nut):
    """First axial mode of screw + nut + table (Table 4.1: 109.5 / 117.7 / 133.8 Hz at L / C / R).

    The reduced sub-model (6 coordinates, reduced once) with the MA port reproduces the full model's
    mode at every nut position; with MD the interior nut load makes it 2-7 % too stiff.
    """
    f_full, f_ma = _coupled_frequencies(sm1, thesis_red, z_nut, "MA")
    _, f_md = _coupled_frequencies(sm1, thesis_red, z_nut, "MD")
    # mode 0 (~11.5 Hz): table on the nearly singular 2x2 K_SN (rounded Eq 3.45 coefficients)
    assert 100.0 < f_full[1] < 140.0
    assert abs(f_ma[1] / f_full[1] - 1) < 1e-3
    assert f_md[1] / f_full[1] - 1 > 0.02


# ------------------------------------------------------------------------------ bad input
def test_bad_input_raises(sm1):
    M, K = sm1.M, sm1.K
    anchor = sm1.dof(sm1.centre_node, "tz")
    with pytest.raises(SingularSystemError, match="K_ii is singular"):
        cms_reduce(M, K, [sm1.dof(sm1.centre_node, "w")], 3)  # torsion left free (no θz exterior)
    cms_reduce(M, K, [anchor], 3)  # a torsional screw DOF alone restrains the rigid rotation
    with pytest.raises(ValueError, match="exactly one"):
        cms_reduce(M, K, [sm1.motor], 3, f_cut=1000.0)
    with pytest.raises(ValueError, match="exactly one"):
        cms_reduce(M, K, [sm1.motor])
    with pytest.raises(ValueError, match="interface"):
        cms_reduce(M, K, [sm1.motor], 3, interface="mixed")
    with pytest.raises(ValueError, match="symmetric"):
        A = K.copy()
        A[0, 1] += 1e3
        cms_reduce(M, A, [sm1.motor], 3)
    with pytest.raises(ValueError, match="duplicate"):
        cms_reduce(M, K, [sm1.motor, sm1.motor], 3)
    with pytest.raises(ValueError, match="unknown DOF name"):
        cms_reduce(M, K, ["rotor.phi"], 3)
    with pytest.raises(ValueError, match="out of range"):
        cms_reduce(M, K, [10_000], 3)
    with pytest.raises(ValueError, match="interior DOF"):
        cms_reduce(M, K, [sm1.motor], 200)
    with pytest.raises(ValueError, match="n_modes"):
        cms_reduce(M, K, [sm1.motor], -1)
    with pytest.raises(SingularSystemError, match="positive definite"):
        cms_reduce(np.zeros_like(M), K, [sm1.motor], 3)
    red = cms_reduce(M, K, [sm1.motor], 3)
    with pytest.raises(ValueError, match="method"):
        red.recover(np.zeros(red.n_reduced), method="XY")
    with pytest.raises(ValueError, match="reduced coordinates"):
        red.recover(np.zeros(3))
    with pytest.raises(ValueError, match="columns"):
        red.port(np.ones((1, 5)))
