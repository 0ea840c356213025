"""Modal analysis of a linear mechanical model (thesis Sec 4.2, Appendix A.3).

* :func:`modes` -> :class:`Modes`: undamped natural frequencies and mass-normalised mode shapes of
  ``K phi = omega^2 M phi`` (Eq A.10-A.11), damping ratios, modal masses (Eq A.12-A.13), the rigid-body
  inertia reflected at a coordinate (``J`` of Eq 4.2) and the participation of each mode in every
  input and output (modal residues, Eq 4.4).

Massless coordinates (rows of ``M`` that are zero, e.g. a node between two springs) are condensed
statically (Guyan): ``q_0 = K_00^{-1} (B_0 u - K_0m q_m)``, exact for the undamped problem; damping that
acts on a massless coordinate is neglected by the condensation (a note is recorded on the result).

Computing never imports matplotlib; :meth:`Modes.plot` does, through :mod:`bscomp.plotting`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.errors import SingularSystemError, UnknownNameError, UsageError, check_number
from bscomp.files import atomic_write
from bscomp.kernel import Dae, System
from bscomp.kernel.condensation import condense_massless, is_asymmetric, massless_split, real_general_eig
from bscomp.linear.frf_engine import dense
from bscomp.linear.linearization import SecondOrderModel, second_order, warn_linearized
from bscomp.model import as_system
from bscomp.plotting.base import mode_shape_plot

__all__ = ["modes", "Modes", "modal_poles"]

#: reduced models up to this size are solved densely even when ``n`` or ``fmax`` is given
DENSE_LIMIT = 400


# ---- model resolution and static condensation ----------------------------------------------------
def _second_order(model, inputs=None, outputs=None, at=None, params=None):
    """A :class:`~bscomp.linear.SecondOrderModel` from a SecondOrderModel, System, Dae or system name."""

    if isinstance(model, SecondOrderModel):
        if at or params:
            raise UsageError("'at' and 'params' cannot be applied to a SecondOrderModel: pass the System "
                             "or Dae")
        return model
    if not isinstance(model, (System, Dae)):         # a name, .py path, build function or ModelSpec
        return second_order(as_system(model, params), inputs=inputs, outputs=outputs, at=at)
    return second_order(model, inputs=inputs, outputs=outputs, at=at, params=params)



@dataclass
class _Reduced:
    """``M q'' + C q' + K q = B u`` over the coordinates with mass; ``q_full = T q + t u``."""

    M: Any
    C: Any
    K: Any
    B: np.ndarray
    Cq: np.ndarray
    Cv: np.ndarray
    Ca: np.ndarray
    D: np.ndarray
    T: Any
    massive: np.ndarray
    notes: list
    symmetric: bool = True
    Ta: Any = None          # non-symmetric: q_full gains Ta q'' (massless rows holding inertia loads)


def _condense(so) -> _Reduced:
    """Static (Guyan) condensation of the massless coordinates of a SecondOrderModel.

    A coordinate is massless when no acceleration of it enters any row (a zero *column* of ``M``). In a
    symmetric model its row is zero too; a model whose massless rows carry inertia loads (a CMS superelement
    with Modal-Acceleration recovery, :class:`~components.reduced_substructure.ReducedSubstructure`, Eq 5.18) or
    whose ``K`` is not symmetric is condensed row by row (:func:`_condense_general`)."""
    M, C, K = (sp.csr_matrix(m) for m in (so.M, so.C, so.K))
    B, Cq, Cv, Ca, D = (dense(m, float) for m in (so.B, so.Cq, so.Cv, so.Ca, so.D))
    n = M.shape[0]
    massless, massive = massless_split(M)
    if is_asymmetric(M) or is_asymmetric(K):
        return _condense_general(so, M, C, K, B, Cq, Cv, Ca, D, massless, massive)
    notes = []
    if massive.size == 0:
        raise SingularSystemError(f"the model has no coordinate with mass ({so.coordinates}): no modes")
    if massless.size == 0:
        return _Reduced(M, C, K, B, Cq, Cv, Ca, D, sp.identity(n, format="csr"), massive, notes)
    K00 = K[massless][:, massless].tocsc()
    try:
        lu = spla.splu(K00)
    except RuntimeError as exc:
        names = [so.coordinates[i] for i in massless]
        raise SingularSystemError(f"massless coordinates {names[:10]} are not held by any stiffness "
                                  "(a mechanism without mass): add a mass or a spring") from exc
    X = lu.solve(K[massless][:, massive].toarray())         # q_0 = -X q_m + t u
    t = lu.solve(B[massless]) if B.size else np.zeros((massless.size, B.shape[1]))
    T = np.zeros((n, massive.size))
    T[massive, np.arange(massive.size)] = 1.0
    T[massless] = -X
    T = sp.csr_matrix(T)
    tu = np.zeros((n, B.shape[1]))
    tu[massless] = t
    if abs(C[massless]).sum() > 0:
        notes.append("damping acting on massless coordinates is neglected by the static condensation")
    if (np.abs(Cv @ tu).sum() + np.abs(Ca @ tu).sum()) > 0:
        notes.append("rates of massless coordinates driven directly by an input are neglected in the outputs")
    Kr = sp.csr_matrix(T.T @ K @ T)
    Kr = 0.5 * (Kr + Kr.T)
    return _Reduced(M=sp.csr_matrix(M[massive][:, massive]), C=sp.csr_matrix(T.T @ C @ T), K=Kr,
                    B=np.asarray(T.T @ B), Cq=np.asarray(Cq @ T), Cv=np.asarray(Cv @ T),
                    Ca=np.asarray(Ca @ T), D=D + Cq @ tu, T=T, massive=massive, notes=notes)


def _condense_general(so, M, C, K, B, Cq, Cv, Ca, D, massless, massive) -> _Reduced:
    """Row-wise static condensation of a non-symmetric model: the massless rows give
    ``q_0 = -X q_m - Y q_m'' - Z q_m' + t u`` (``X, Y, Z, t = K_00^{-1} (K_0m, M_0m, C_0m - C_00 X, B_0)``), and the
    rows with mass keep ``M_mm - K_m0 Y``, ``C_mm - C_m0 X - K_m0 Z``, ``K_mm - K_m0 X``, ``B_m - K_m0 t``."""
    ml, ma = massless, massive
    if ma.size == 0:
        raise SingularSystemError(f"the model has no coordinate with mass ({so.coordinates}): no modes")
    notes = ["non-symmetric model (e.g. a CMS superelement with MA recovery, thesis Eq 5.18): modes from the "
             "general eigenproblem, with left and right eigenvectors (W^T M V = I)"]
    Md, Cd, Kd = M.toarray(), C.toarray(), K.toarray()
    if ml.size:
        Mc, Kc, lu, X, Y = condense_massless(Md, Kd, ml, ma, so.coordinates, "modes")
        Z = sla.lu_solve(lu, Cd[np.ix_(ml, ma)] - Cd[np.ix_(ml, ml)] @ X)
        t = sla.lu_solve(lu, B[ml]) if B.size else np.zeros((ml.size, B.shape[1]))
    else:
        Mc, Kc = Md, Kd
        X = Y = Z = np.zeros((0, ma.size))
        t = np.zeros((0, B.shape[1]))
    Km0 = Kd[np.ix_(ma, ml)]
    n = Md.shape[0]
    T, Ta, Tv = (np.zeros((n, ma.size)) for _ in range(3))
    T[ma, np.arange(ma.size)] = 1.0
    T[ml], Ta[ml], Tv[ml] = -X, -Y, -Z
    tu = np.zeros((n, B.shape[1]))
    tu[ml] = t
    return _Reduced(M=sp.csr_matrix(Mc),
                    C=sp.csr_matrix(Cd[np.ix_(ma, ma)] - Cd[np.ix_(ma, ml)] @ X - Km0 @ Z),
                    K=sp.csr_matrix(Kc), B=np.asarray(B[ma] - Km0 @ t),
                    Cq=np.asarray(Cq @ T), Cv=np.asarray(Cv @ T + Cq @ Tv), Ca=np.asarray(Ca @ T + Cq @ Ta),
                    D=D + Cq @ tu, T=sp.csr_matrix(T), massive=ma, notes=notes, symmetric=False, Ta=Ta)


def _undamped_general(red: _Reduced, n=None, fmax=None):
    """``K V = M V Λ`` of a non-symmetric pair: right eigenvectors ``V`` (``v^T M_s v = 1``, ``M_s`` the symmetric
    part) and left ones ``W = (V^{-1} M^{-1})^T`` (``W^T M V = I``, ``W^T K V = Λ``)."""
    Md, Kd = red.M.toarray(), red.K.toarray()
    lam, V, rigid = real_general_eig(Kd, Md, rigid_rtol=1e-8, what="modes")
    if np.any(lam < 0):
        raise SingularSystemError("negative eigenvalue of K v = w^2 M v (an unstable operating point?)")
    Ms = 0.5 * (Md + Md.T)
    V = V / np.sqrt(np.abs(np.einsum("ik,ik->k", V, Ms @ V)))
    big = np.argmax(np.abs(V), axis=0)
    V = V * np.sign(V[big, np.arange(V.shape[1])])
    W = np.linalg.solve(Md.T, np.linalg.inv(V).T)
    keep = np.ones(lam.size, bool)
    if fmax is not None:
        keep &= np.sqrt(lam) <= 2 * np.pi * fmax
    idx = np.flatnonzero(keep)
    if n is not None:
        idx = idx[:n]
    return lam[idx], V[:, idx], W[:, idx], rigid[idx], "dense eig (non-symmetric)"


# ---- undamped eigenproblem ---------------------------------------------------------------------------
def _eig_scale(red: _Reduced) -> float:
    dk, dm = np.abs(red.K.diagonal()), np.abs(red.M.diagonal())
    ok = dm > 0
    s = float(np.max(dk[ok] / dm[ok])) if ok.any() else 1.0
    return s if s > 0 else 1.0


def _undamped(red: _Reduced, n=None, fmax=None, dense_limit=DENSE_LIMIT):
    """Eigenvalues ``omega^2`` (ascending) and ``M``-normalised modes of ``K phi = omega^2 M phi``."""
    N = red.K.shape[0]
    scale = _eig_scale(red)
    if (n is None and fmax is None) or N <= dense_limit:
        Md, Kd = red.M.toarray(), red.K.toarray()
        try:
            lam, phi = sla.eigh(Kd, 0.5 * (Md + Md.T))
        except np.linalg.LinAlgError as exc:
            raise SingularSystemError("the mass matrix is not positive definite after condensing the "
                                      "massless coordinates") from exc
        method = "dense eigh"
    else:
        sigma = -1e-6 * scale                                # all eigenvalues >= 0 > sigma: nearest = lowest
        k = min(N - 2, max(6, (n or 10) + 4))
        while True:
            lam, phi = spla.eigsh(red.K.tocsc(), k=k, M=red.M.tocsc(), sigma=sigma, which="LM")
            order = np.argsort(lam)
            lam, phi = lam[order], phi[:, order]
            enough = (n is None or k >= n) and (fmax is None or lam[-1] > (2 * np.pi * fmax) ** 2)
            if enough or k >= N - 2:
                break
            k = min(N - 2, 2 * k)
        method = "sparse eigsh (shift-invert)"
        phi = phi / np.sqrt(np.einsum("ik,ik->k", phi, red.M @ phi))
    rigid = np.abs(lam) <= 1e-8 * scale                     # round-off either side of 0; a large negative one is not
    lam = np.where(rigid, 0.0, lam)
    if np.any(lam < 0):
        raise SingularSystemError("negative eigenvalue of K phi = omega^2 M phi: the stiffness matrix is not "
                                  "positive semi-definite (an unstable operating point?)")
    keep = np.ones(lam.size, bool)
    if fmax is not None:
        keep &= np.sqrt(lam) <= 2 * np.pi * fmax
    idx = np.flatnonzero(keep)
    if n is not None:
        idx = idx[:check_number("n", n, integer=True, minimum=1)]
    phi = phi[:, idx]
    # sign convention: the largest component of each mode is positive
    big = np.argmax(np.abs(phi), axis=0)
    phi = phi * np.sign(phi[big, np.arange(phi.shape[1])])
    return lam[idx], phi, rigid[idx], method


# ---- damped poles of the modal model -----------------------------------------------------------------
@dataclass
class _PoleGroups:
    """Poles of the modal state-space model, grouped per undamped mode, with SISO-ready residues."""

    poles: list            # per mode: array of poles [1/s]
    vectors: list          # per mode: (right eigenvectors (2m, p), scaled left rows (p, 2m)) or None
    A: np.ndarray
    decoupled: np.ndarray  # rigid modes with no damping: poles [0, 0], handled in closed form


def modal_poles(omega, Cm, rigid):
    """Poles of ``eta'' + C_m eta' + Omega^2 eta = 0`` grouped per undamped mode.

    Parameters
    ----------
    omega : (m,) array
        Undamped natural frequencies [rad/s].
    Cm : (m, m) array
        Modal damping matrix :math:`\\Phi^T C \\Phi` (mass-normalised modes; diagonal ``2 zeta omega``,
        Eq A.14, for proportional damping).
    rigid : (m,) bool array

    Returns
    -------
    list of ndarray
        For each mode the poles whose eigenvector is dominated by that modal coordinate: a complex pair
        for an underdamped mode, two real poles for an overdamped one, ``0`` and ``-B/J`` for a rigid
        mode with viscous damping, ``0, 0`` for an undamped rigid mode.
    """
    return _group_poles(np.asarray(omega, float), np.asarray(Cm, float), np.asarray(rigid, bool)).poles


def _group_poles(omega, Cm, rigid) -> _PoleGroups:
    m = omega.size
    cmax = np.max(np.abs(Cm)) if Cm.size else 0.0
    decoupled = rigid & (np.abs(Cm).sum(axis=1) <= 1e-12 * max(cmax, np.finfo(float).tiny))
    live = np.flatnonzero(~decoupled)
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-np.diag(omega**2), -Cm]])
    poles: list = [np.zeros(2) if d else np.zeros(0, complex) for d in decoupled]
    vectors: list = [None] * m
    if live.size:
        sel = np.r_[live, m + live]
        lam, wl, vr = sla.eig(A[np.ix_(sel, sel)], left=True, right=True)
        nl = live.size
        scale = max(np.max(np.abs(lam)), np.finfo(float).tiny)
        lam = np.where(np.abs(lam) <= 1e-12 * scale, 0.0, lam)
        lam = np.where(np.abs(lam.imag) <= 1e-12 * scale, lam.real, lam)
        owner = live[np.argmax(np.abs(vr[:nl]), axis=0)]
        V = np.zeros((2 * m, lam.size), complex)
        V[sel] = vr
        W = np.zeros((lam.size, 2 * m), complex)
        W[:, sel] = (wl.conj() / np.einsum("ij,ij->j", wl.conj(), vr)).T   # rows: w_i^H / (w_i^H v_i)
        for k in live:
            i = np.flatnonzero(owner == k)
            poles[k] = lam[i]
            vectors[k] = (V[:, i], W[i])
    return _PoleGroups(poles=poles, vectors=vectors, A=A, decoupled=decoupled)


# ---- result --------------------------------------------------------------------------------------------
@dataclass
class Modes:
    """Modes of a linear mechanical model (result of :func:`modes`).

    Attributes
    ----------
    frequencies : (m,) ndarray
        Undamped natural frequencies [Hz], ascending; exactly 0 for rigid-body modes (Eq A.11).
    omega : (m,) ndarray
        The same in [rad/s].
    damping : (m,) ndarray
        Damping ratios ``zeta`` [-]; NaN for rigid-body modes (see :attr:`decay_rates`).
    damping_method : str
        ``"complex"``: from the damped poles of the modal model (exact for non-proportional damping:
        ``omega_d^2 = p1 p2``, ``2 zeta omega_d = -(p1 + p2)`` over the two poles of each mode);
        ``"projection"``: ``zeta_k = phi_k^T C phi_k / (2 omega_k)`` (Eq A.14 read backwards).
    poles : list of ndarray
        Damped poles [1/s] of each mode (``"complex"`` method; empty for ``"projection"``).
    decay_rates : (m,) ndarray
        ``phi_k^T C phi_k`` [1/s]; for a rigid-body mode this is ``B/J`` of Eq 4.2.
    shapes : (n, m) ndarray
        Mass-normalised mode shapes over all :attr:`coordinates` (``Phi^T M Phi = I``; massless
        coordinates recovered from the static condensation); largest component positive.
    coordinates, units : list of str
    rigid_body : (m,) bool ndarray
    modal_masses : (m,) ndarray
        ``m_q`` of Eq A.12 for shapes scaled to a largest component of 1 (units of the coordinate with
        the largest component: kg or kg m^2).
    inputs, outputs : list of str
    input_factors : (m, n_in) ndarray
        Modal input participation :math:`\\Phi^T B`.
    output_factors : (n_out, m) ndarray
        Modal output participation :math:`(C_q + C_v + C_a)\\Phi`; output ``j`` responds as
        :math:`s^{r_j}` times the modal displacement, ``r_j`` in :attr:`output_order`.
    output_order : list of int
        0 for displacement-like, 1 for velocity-like, 2 for acceleration-like outputs, -1 if mixed.
    residues : (m, n_out, n_in) ndarray
        Modal residues ``R_k = c_k b_k`` (Eq 4.4 with mass-normalised shapes, ``P_i P_j / m_q``), so that
        with proportional damping ``G(s) = sum_k R_k s^r / (s^2 + 2 zeta_k omega_k s + omega_k^2)``
        (Eq 4.3, 4.5-4.7).
    method : str
        Eigen-solver used.
    notes : list of str
    """

    frequencies: np.ndarray
    omega: np.ndarray
    damping: np.ndarray
    damping_method: str
    poles: list
    decay_rates: np.ndarray
    shapes: np.ndarray
    coordinates: list
    units: list
    rigid_body: np.ndarray
    modal_masses: np.ndarray
    inputs: list
    outputs: list
    input_factors: np.ndarray
    output_factors: np.ndarray
    output_order: list
    residues: np.ndarray
    method: str
    name: str = ""
    notes: list = field(default_factory=list)

    def __len__(self):
        return self.frequencies.size

    def _coord(self, coordinate) -> int:
        if coordinate not in self.coordinates:
            raise UnknownNameError(f"'{coordinate}' is not a coordinate of the model; coordinates: "
                                   f"{self.coordinates[:20]}")
        return self.coordinates.index(coordinate)

    def modal_mass(self, coordinate: str) -> np.ndarray:
        """Modal mass of every mode with its shape scaled to 1 at ``coordinate`` (Eq A.12).

        For a mass-normalised shape :math:`\\chi_k`, :math:`(m_q)_k = 1 / \\chi_{ik}^2`; for the rigid-body
        mode of a drive at the motor angle this is the total inertia reflected at the motor shaft, ``J``
        of Eq 4.2 (thesis Sec 4.2.1). Infinite where the mode does not move ``coordinate``.
        """
        x = self.shapes[self._coord(coordinate)]
        with np.errstate(divide="ignore"):
            return np.where(x != 0, 1.0 / np.where(x != 0, x, 1.0) ** 2, np.inf)

    def reflected_inertia(self, coordinate: str) -> float:
        """Inertia (or mass) of the rigid-body mode reflected at ``coordinate``: ``J`` of Eq 4.2."""
        r = np.flatnonzero(self.rigid_body)
        if r.size != 1:
            raise SingularSystemError(f"reflected inertia needs exactly one rigid-body mode, the model has "
                                      f"{r.size}")
        return float(self.modal_mass(coordinate)[r[0]])

    def reflected_damping(self, coordinate: str) -> float:
        """Viscous damping of the rigid-body mode reflected at ``coordinate``: ``B = J * (B/J)`` of Eq 4.2."""
        r = np.flatnonzero(self.rigid_body)
        J = self.reflected_inertia(coordinate)
        return float(J * self.decay_rates[r[0]])

    # ---- output ---------------------------------------------------------------------------------
    def table(self, reference: str | None = None) -> str:
        """Human-readable table; modal masses at ``reference`` if given (else shapes scaled to max 1)."""
        mq = self.modal_mass(reference) if reference else self.modal_masses
        head = f"m_q@{reference}" if reference else "m_q (max=1)"
        lines = [f"{'#':>3} {'f_n [Hz]':>11} {'zeta [-]':>9} {head:>14}  poles [1/s]"]
        for k in range(len(self)):
            p = self.poles[k] if k < len(self.poles) else []
            ptxt = ", ".join(_fmt_pole(x) for x in p if np.imag(x) >= 0 or np.isreal(x))
            if self.rigid_body[k]:
                z = "-"
                ptxt = (f"rigid body; real poles {ptxt}" if len(p)
                        else f"rigid body; B/J = {self.decay_rates[k]:.4g}")
            else:
                z = f"{self.damping[k]:.4f}"
            lines.append(f"{k + 1:>3} {self.frequencies[k]:>11.3f} {z:>9} {mq[k]:>14.5g}  {ptxt}")
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def to_dict(self) -> dict:
        def cx(a):
            return [[float(np.real(x)), float(np.imag(x))] for x in np.atleast_1d(a)]

        return {
            "name": self.name, "coordinates": list(self.coordinates), "units": list(self.units),
            "frequencies_hz": self.frequencies.tolist(),
            "damping": [None if not np.isfinite(z) else float(z) for z in self.damping],
            "damping_method": self.damping_method, "rigid_body": self.rigid_body.tolist(),
            "decay_rates": self.decay_rates.tolist(), "modal_masses": self.modal_masses.tolist(),
            "poles": [cx(p) for p in self.poles], "shapes": self.shapes.T.tolist(),
            "inputs": list(self.inputs), "outputs": list(self.outputs),
            "input_factors": self.input_factors.tolist(), "output_factors": self.output_factors.tolist(),
            "output_order": list(self.output_order), "residues": self.residues.tolist(),
            "method": self.method, "notes": list(self.notes),
        }

    def to_json(self, path=None) -> str:
        """JSON text (``shapes`` as one list per mode); written to ``path`` if given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            with atomic_write(path, what="Modes.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def to_csv(self, path) -> None:
        """One row per mode: frequency, damping, rigid flag, modal mass, then the shape over coordinates."""
        import csv

        with atomic_write(path, what="Modes.to_csv: path", suffixes=(".csv",), newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["mode", "f_n_hz", "zeta", "rigid_body", "modal_mass"]
                       + [f"phi[{c}]" for c in self.coordinates])
            for k in range(len(self)):
                w.writerow([k + 1, repr(float(self.frequencies[k])), repr(float(self.damping[k])),
                            int(self.rigid_body[k]), repr(float(self.modal_masses[k]))]
                           + [repr(float(x)) for x in self.shapes[:, k]])

    def plot(self, path=None, modes=None, title=None):
        """Mode-shape plot (:func:`bscomp.plotting.mode_shape_plot`); returns the figure."""

        return mode_shape_plot(self, path=path, modes=modes, title=title)


def _fmt_pole(p):
    p = complex(p)
    return f"{p.real:.4g}" if p.imag == 0 else f"{p.real:.4g}{p.imag:+.4g}j"


# ---- the analysis ----------------------------------------------------------------------------------------
def modes(model, inputs=None, outputs=None, at: dict | None = None, params: dict | None = None,
          n: int | None = None, fmax: float | None = None, damping: str = "auto", warn: bool = True) -> Modes:
    """Natural frequencies, damping, mode shapes, modal masses and residues of a linear mechanical model.

    The undamped problem (Eq A.10-A.11)

    .. math:: K \\phi_k = \\omega_k^2 M \\phi_k,\\qquad \\Phi^T M \\Phi = I

    is solved after condensing massless coordinates statically. Modal masses follow Eq A.12 for a
    chosen scaling of the shape; :meth:`Modes.modal_mass` gives them for a unit component at a named
    coordinate, so the rigid-body mode yields the inertia reflected at that coordinate (Eq 4.2).
    Residues are :math:`R_k = (c\\,\\phi_k)(\\phi_k^T b)` (Eq 4.4).

    Parameters
    ----------
    model : System, Dae, SecondOrderModel or str
        A system name registered in ``bscomp.systems`` (or a ``.py`` path) is built with ``params``.
    inputs, outputs : list of str, optional
        Inputs and outputs for the participation factors (default: all inputs; the coordinates).
    at : dict, optional
        Operating point (state and input values by name).
    params : dict, optional
        Parameter overrides by dotted name.
    n : int, optional
        Keep the ``n`` lowest modes (rigid-body modes included).
    fmax : float, optional
        Keep the modes up to ``fmax`` [Hz]. With ``n`` or ``fmax`` a reduced model larger than
        ``DENSE_LIMIT`` is solved with ``scipy.sparse.linalg.eigsh`` in shift-invert mode.
    damping : {"auto", "complex", "projection"}
        How damping ratios are obtained; ``"auto"`` is ``"complex"`` up to ``DENSE_LIMIT`` kept modes.
    warn : bool
        Warn (:class:`~bscomp.errors.ModelLimitationWarning`) when the model has nonlinear components, which
        the modes linearize at the operating point; ``False`` for callers that account for them.

    Returns
    -------
    Modes

    Raises
    ------
    NotLinearError
        If the model has no second-order form (internal controller states).
    SingularSystemError
        If massless coordinates are not held by a stiffness, or ``M`` is not positive definite.
    """
    if n is not None:
        n = check_number("n", n, integer=True, minimum=1)
    if fmax is not None:
        fmax = check_number("fmax", fmax, positive=True)
    if damping not in ("auto", "complex", "projection"):
        raise UsageError(f"damping must be 'auto', 'complex' or 'projection', got {damping!r}")
    so = _second_order(model, inputs, outputs, at, params)
    warn_linearized(so.linearized if warn else (), "modes", "its modes are those of small motions about that point; "
                    "for the behaviour at a real amplitude simulate with bscomp.simulate(..., method='modal') "
                    "(friction, backlash, a moving nut; fast) or method='idas' (any model)")
    red = _condense(so)
    if red.symmetric:
        lam, phi, rigid, method = _undamped(red, n=n, fmax=fmax)
        left = phi
    else:
        lam, phi, left, rigid, method = _undamped_general(red, n=n, fmax=fmax)
    omega = np.sqrt(lam)
    m = omega.size
    Cm = left.T @ (red.C @ phi)
    if red.symmetric:
        Cm = 0.5 * (Cm + Cm.T)
    decay = np.diag(Cm).copy()
    if damping == "auto":
        damping = "complex" if m <= DENSE_LIMIT else "projection"
    if damping not in ("complex", "projection"):
        raise UsageError(f"damping must be 'auto', 'complex' or 'projection', got {damping!r}")
    zeta = np.full(m, np.nan)
    el = ~rigid
    zeta[el] = decay[el] / (2 * omega[el])
    poles: list = []
    notes = list(red.notes)
    if damping == "complex" and m:
        groups = _group_poles(omega, Cm, rigid)
        poles = groups.poles
        for k in np.flatnonzero(el):
            p = poles[k]
            if p.size == 2:
                a0, a1 = float(np.real(p[0] * p[1])), float(-np.real(p[0] + p[1]))
                if a0 > 0:
                    zeta[k] = a1 / (2 * np.sqrt(a0))
            else:
                notes.append(f"mode {k + 1}: {p.size} damped poles (strongly coupled by damping); "
                             "its ratio is the projection phi^T C phi / (2 omega)")
    shapes = np.asarray(red.T @ phi)
    if red.Ta is not None:                                 # massless rows carrying inertia: q_0 += -Y q''
        shapes = shapes - np.asarray(red.Ta @ phi) * lam
    big = np.max(np.abs(shapes), axis=0) if m else np.zeros(0)
    modal_masses = 1.0 / big**2
    b = left.T @ red.B
    Cy = red.Cq + red.Cv + red.Ca
    c = Cy @ phi
    order = []
    for j in range(len(so.outputs)):
        has = [bool(np.any(X[j])) for X in (red.Cq, red.Cv, red.Ca)]
        order.append(has.index(True) if sum(has) == 1 else (0 if not any(has) else -1))
    residues = np.einsum("jk,ki->kji", c, b)
    return Modes(frequencies=omega / (2 * np.pi), omega=omega, damping=zeta, damping_method=damping,
                 poles=poles, decay_rates=decay, shapes=shapes, coordinates=list(so.coordinates),
                 units=list(so.units), rigid_body=rigid, modal_masses=modal_masses, inputs=list(so.inputs),
                 outputs=list(so.outputs), input_factors=b, output_factors=c, output_order=order,
                 residues=residues, method=method,
                 name=model if isinstance(model, str) else getattr(model, "name", ""), notes=notes)
