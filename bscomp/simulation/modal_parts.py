r"""Modal coordinates of a :class:`bscomp.simulation.modal_channels.LinearPart` for ``simulate(method="modal")``.

Mechanical models (every coordinate with inertia, no algebraic variables; controller states allowed) use
the undamped modes: ``K Φ = M Φ Λ`` (symmetric ``eigh``, mass-normalised, Eq A.10), modes up to ``f_keep``
kept, the others static (residual flexibility ``R_t = Φ_t Λ_t^{-1} Φ_t^T``, Eq 5.16-5.18: exact at low
frequency). With ``r = [η; η'; x_i]`` (kept modes and internal states such as a PI controller's)

.. math::
    η'' + C_{kk} η' + Λ_k η = -Φ_k^T (K_{qi} x_i + f), \qquad q = Φ_k η - R_t (K_{qi} x_i + f),

``f`` the forces of the inputs, channels and the constant term of the balance rows, and the internal rows
solved for ``x_i'``. The reduced matrix (size ``2 n_k + n_i``, coupled by non-proportional damping) is
diagonalised: ``r = Y ξ``. Other models use the eigenvectors of the full explicit form (``Δx = V ξ``).

Either way ``Δx = Re(V_x ξ) + X_u u + X_g g + x_c`` and ``ẋ = Re(V_d (λ ξ + B_u u + B_g g + b_c))`` (the rate of
the static part is neglected), one complex coordinate per real eigenvalue and per conjugate pair (``V``
carries the factor 2 of a pair).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from bscomp.linear.frf_engine import dense
from bscomp.simulation.compiled_time import contact_band
from bscomp.simulation.modal_channels import DefectiveLinearPart, LinearPart

__all__ = ["ModalPart", "element_band", "element_bands"]

COND_MAX = 1e10


class ModalPart:
    """A linear part in complex modal coordinates (see the module docstring).

    Parameters
    ----------
    lin : LinearPart
    f_keep : float or None
        Highest undamped natural frequency [Hz] kept dynamically (mechanical models); None keeps all.

    Attributes
    ----------
    lam : ndarray (m,) complex
    Vx, Vd : ndarray (nx, m) complex
    W : ndarray (m, nx) complex
        ``ξ = W Δx``: the kept part of a state.
    Bu, Bg, bc : ndarray
        Modal inputs.
    Xu, Xg, xc : ndarray
        Static part of the state.
    route : str
        ``"second-order"`` or ``"first-order"``.
    """

    def __init__(self, lin, f_keep: float | None = None):
        self.lin = lin
        dae = lin.ch.dae
        m = dae.mech
        mb = _mechanical_blocks(lin) if dae.nz == 0 and not m.damped and not m.static else None
        if mb is not None:
            self._second_order(lin, f_keep, mb)
            self.route = "second-order"
        else:
            self._first_order(lin)
            self.route = "first-order"

    # ---- construction -------------------------------------------------------------------------------
    def _first_order(self, lin):
        A, B, E, c, Zx, Zu, Zg, zc = lin.explicit()
        lam, V = sla.eig(A, check_finite=False)
        W = _inverse(V, lin.ch.dae.name)
        self._take(lam, V, W, B, E, c)
        self.Vd = self.Vx
        nx = A.shape[0]
        self.Xu, self.Xg, self.xc = np.zeros((nx, B.shape[1])), np.zeros((nx, E.shape[1])), np.zeros(nx)
        self.Z = (Zx, Zu, Zg, zc)
        self.n_kept = lam.size

    def _take(self, lam, V, W, B, E, c):
        """Keep one coordinate per real eigenvalue and per conjugate pair."""
        keep = np.flatnonzero(lam.imag >= -1e-9 * np.maximum(np.abs(lam), 1.0))
        pair = np.abs(lam[keep].imag) > 1e-9 * np.maximum(np.abs(lam[keep]), 1.0)
        self.lam = lam[keep]
        self.Vx = V[:, keep] * np.where(pair, 2.0, 1.0)
        self.W = W[keep]
        self.Bu, self.Bg, self.bc = self.W @ B, self.W @ E, self.W @ c

    def _second_order(self, lin, f_keep, mb):
        dae = lin.ch.dae
        M, C, K, Kqi, Rb, Ri, Iq, Iv, Ii, Jxd_d, Jx_d = mb
        lam, phi, rigid = _undamped_modes(lin, K, M)
        lam = np.where(rigid, 0.0, lam)
        w_keep = np.inf if f_keep is None else (2 * np.pi * f_keep) ** 2
        keep = np.flatnonzero((lam <= w_keep) | rigid)
        trunc = np.setdiff1d(np.arange(lam.size), keep)
        pk, lk, pt = phi[:, keep], lam[keep], phi[:, trunc]
        Rt = (pt / lam[trunc]) @ pt.T if trunc.size else np.zeros_like(K)
        nk, ni, nx = keep.size, len(Ii), dae.nx
        # forces on the balance rows: inputs, channels, constant
        Fb = np.hstack([dense(lin.Ju[Rb], float), lin.G[Rb], lin.F0[Rb][:, None]])
        Fi = np.hstack([dense(lin.Ju[Ri], float), lin.G[Ri], lin.F0[Ri][:, None]]) if ni else np.zeros((0, Fb.shape[1]))
        n = 2 * nk + ni
        Ared = np.zeros((n, n))
        Bred = np.zeros((n, Fb.shape[1]))
        Ared[:nk, nk:2 * nk] = np.eye(nk)
        Ared[nk:2 * nk, :nk] = -np.diag(lk)
        Ared[nk:2 * nk, nk:2 * nk] = -(pk.T @ C @ pk)
        Bred[nk:2 * nk] = -pk.T @ Fb
        # q = pk eta + qs, qs = -Rt (Kqi x_i + Fb col)
        if ni:
            Ared[nk:2 * nk, 2 * nk:] = -pk.T @ Kqi
            Eii = Jxd_d[np.ix_(Ri, Ii)]
            Aiq, Aiv, Aii = Jx_d[np.ix_(Ri, Iq)], Jx_d[np.ix_(Ri, Iv)], Jx_d[np.ix_(Ri, Ii)]
            Einv = np.linalg.inv(Eii)
            Ared[2 * nk:, :nk] = -Einv @ Aiq @ pk
            Ared[2 * nk:, nk:2 * nk] = -Einv @ Aiv @ pk
            Ared[2 * nk:, 2 * nk:] = -Einv @ (Aii - Aiq @ Rt @ Kqi)
            Bred[2 * nk:] = -Einv @ (Fi - Aiq @ Rt @ Fb)
        mu, Y = sla.eig(Ared, check_finite=False)
        Yi = _inverse(Y, dae.name)
        nu, ng = lin.Ju.shape[1], lin.ng
        keepc = np.flatnonzero(mu.imag >= -1e-9 * np.maximum(np.abs(mu), 1.0))
        pair = np.abs(mu[keepc].imag) > 1e-9 * np.maximum(np.abs(mu[keepc]), 1.0)
        wgt = np.where(pair, 2.0, 1.0)
        self.lam = mu[keepc]
        Yk = Y[:, keepc] * wgt
        m = keepc.size
        # r = [eta; eta'; x_i] -> Δx, and r, r' -> ẋ, in the Dae's state order, block by block (the maps are
        # block-sparse: positions = pk eta (+ the static part of x_i), velocities = pk eta')
        P1, P2 = _rmul(pk, Yk[:nk]), _rmul(pk, Yk[nk:2 * nk])
        self.Vx = np.zeros((nx, m), complex)
        self.Vx[Iq], self.Vx[Iv] = P1, P2
        self._Vd_r = np.zeros((nx, m), complex)      # rate of a position: the velocity (in r)
        self._Vd_r[Iq] = P2
        self._Vd_rd = np.zeros((nx, m), complex)     # rate of a velocity: the acceleration (in r')
        self._Vd_rd[Iv] = P2
        if ni:
            self.Vx[Iq] += _rmul(-Rt @ Kqi, Yk[2 * nk:])
            self.Vx[Ii] = Yk[2 * nk:]
            self._Vd_rd[Ii] = Yk[2 * nk:]
        # ξ = W Δx with W = Y^-1 [M pk on positions; M pk on velocities; I on x_i]
        Yik = Yi[keepc]
        Mp = M @ pk
        self.W = np.zeros((m, nx), complex)
        self.W[:, Iq] = _rmul(Yik[:, :nk], Mp.T, left=True)
        self.W[:, Iv] = _rmul(Yik[:, nk:2 * nk], Mp.T, left=True)
        if ni:
            self.W[:, Ii] = Yik[:, 2 * nk:]
        Bm = _rmul(Yik, Bred, left=True)
        self.Bu, self.Bg, self.bc = Bm[:, :nu], Bm[:, nu:nu + ng], Bm[:, -1]
        Xs = np.zeros((nx, Fb.shape[1]))
        Xs[Iq] = -Rt @ Fb
        self.Xu, self.Xg, self.xc = Xs[:, :nu], Xs[:, nu:nu + ng], Xs[:, -1]
        self.Z = None
        self.n_kept = nk
        self.Vd = None

    # ---- use ------------------------------------------------------------------------------------------
    def state(self, xi, u, g):
        """``Δx`` at modal coordinates ``xi`` (rows: time points allowed), input ``u`` and forces ``g`` (only the
        forces that are non-zero somewhere enter the product: a joint's channels are a few of its columns)."""
        g = np.asarray(g)
        act = np.flatnonzero(np.any(g != 0.0, axis=tuple(range(g.ndim - 1))))
        Vr, Vi = self._split()
        return xi.real @ Vr - xi.imag @ Vi + u @ self.Xu.T + g[..., act] @ self.Xg[:, act].T + self.xc

    def project(self, dx):
        """``ξ = W Δx`` for a real state ``dx`` (two real products)."""
        if getattr(self, "_W_split", None) is None:
            self._W_split = (np.ascontiguousarray(self.W.real), np.ascontiguousarray(self.W.imag))
        Wr, Wi = self._W_split
        return Wr @ dx + 1j * (Wi @ dx)

    def _split(self):
        """``(Re V_x^T, Im V_x^T)``, contiguous (``Re(ξ V_x^T)`` without the imaginary part)."""
        if getattr(self, "_V_split", None) is None:
            self._V_split = (np.ascontiguousarray(self.Vx.real.T), np.ascontiguousarray(self.Vx.imag.T))
        return self._V_split

    def rate_rows(self):
        """``(Vr, Vrd)``: ``ẋ = Re(Vr ξ + Vrd ξ')`` (first-order route: ``Vr = 0``, ``Vrd = V``)."""
        if self.Vd is not None:
            return np.zeros_like(self.Vd), self.Vd
        return self._Vd_r, self._Vd_rd

    def rows(self, Cxd, Cx, Cz, Cu, y0):
        """A linear function ``y = y0 + Cxd ẋ + Cx Δx + Cz Δz + Cu u`` as ``(Cξ, Du, Dg, yc)``:
        ``y = Re(Cξ ξ) + Du u + Dg g + yc``."""
        Cxd, Cx, Cz, Cu = (dense(A, float) for A in (Cxd, Cx, Cz, Cu))
        Vr, Vrd = self.rate_rows()
        CdR, CdD = Cxd @ Vr, Cxd @ Vrd
        Cxi = Cx @ self.Vx + CdR + CdD * self.lam[None, :]
        Du = Cu + Cx @ self.Xu + (CdD @ self.Bu).real
        Dg = Cx @ self.Xg + (CdD @ self.Bg).real
        yc = np.asarray(y0, float).ravel() + Cx @ self.xc + (CdD @ self.bc).real
        if self.Z is not None and Cz.shape[1]:
            Zx, Zu, Zg, zc = self.Z
            Cxi = Cxi + Cz @ Zx @ self.Vx
            Du = Du + Cz @ (Zx @ self.Xu + Zu)
            Dg = Dg + Cz @ (Zx @ self.Xg + Zg)
            yc = yc + Cz @ (Zx @ self.xc + zc)
        return Cxi, Du, Dg, yc


def _mechanical_blocks(lin):
    """``(M, C, K, K_qi, rows, ...)`` of a model whose balance rows see positions, velocities, accelerations and
    internal states only (else None: the first-order route is used)."""
    dae = lin.ch.dae
    m = dae.mech
    nr = len(m.coordinate_names)
    Iq = np.array([m.q_in_x[j] for j in range(nr)], int)
    Iv = np.array([m.v_in_x[j] for j in range(nr)], int)
    Ia = np.array([m.a_in_xd[j] for j in range(nr)], int)
    if not np.array_equal(Ia, Iv):
        return None
    Rb = np.asarray(m.balance_rows, int)
    ni_rows = np.arange(len(m.inertial), len(m.inertial) + nr)
    if not np.array_equal(np.sort(Rb), ni_rows):
        return None
    Ii = np.setdiff1d(np.arange(dae.nx), np.r_[Iq, Iv])
    Ri = np.setdiff1d(np.arange(lin.Jx.shape[0]), np.r_[np.arange(len(m.inertial)), Rb])
    if Ii.size != Ri.size:
        return None
    Jxd, Jx = lin.dense_jacobians()      # a few hundred rows: dense slicing is cheapest
    M = Jxd[np.ix_(Rb, Iv)]
    K = Jx[np.ix_(Rb, Iq)]
    C = Jx[np.ix_(Rb, Iv)]
    if Ii.size:
        if np.abs(Jxd[np.ix_(Rb, Ii)]).sum() or np.abs(Jxd[np.ix_(Ri, Iv)]).sum():
            return None                       # rates of internal states in the balances, or accelerations fed back
    if np.abs(Jxd[np.ix_(Rb, Iq)]).max(initial=0.0) > 0:
        return None
    sym = max(np.abs(K - K.T).max(), np.abs(M - M.T).max())
    if sym > 1e-9 * max(np.abs(K).max(), 1e-300):
        return None
    Kqi = Jx[np.ix_(Rb, Ii)] if Ii.size else np.zeros((nr, 0))
    return M, C, 0.5 * (K + K.T), Kqi, Rb, Ri, Iq, Iv, Ii, Jxd, Jx


def _rmul(A, B, left=False):
    """A real matrix times a complex one (``left``: complex times real) by two real products."""
    if left:
        return A.real @ B + 1j * (A.imag @ B)
    return A @ B.real + 1j * (A @ B.imag)


def _inverse(V, name):
    """``V^{-1}``, refused when ``V`` is (nearly) singular: its 1-norm condition number ``|V|_1 |V^{-1}|_1`` above
    :data:`COND_MAX` (no SVD: the inverse is needed anyway)."""
    try:
        W = np.linalg.inv(V)
        cond = np.linalg.norm(V, 1) * np.linalg.norm(W, 1)
    except np.linalg.LinAlgError:
        cond = np.inf
    if not np.isfinite(cond) or cond > COND_MAX:
        raise DefectiveLinearPart(
            f"'{name}': the linear part is not diagonalisable (eigenvector condition {cond:.2g}: a Jordan block, e.g. "
            "an undamped rigid-body mode): give the rigid-body motion some damping (viscous guide or motor "
            "damping), or use method='split' / 'idas'")
    return W


def _undamped_modes(lin, K, M):
    """``(λ, Φ, rigid)`` of ``K Φ = M Φ Λ`` (cached on the channels: regimes that change only damping, and
    :func:`element_band` before the contact regime's part, share them)."""
    key = (K.tobytes(), M.tobytes())
    cache = lin.ch.__dict__.setdefault("_eigh", {})
    if key not in cache:
        if len(cache) > 8:
            cache.clear()
        cache[key] = sla.eigh(K, M, check_finite=False, driver="gvd")
    lam, phi = cache[key]
    return lam, phi, np.abs(lam) <= 1e-9 * np.max(np.abs(lam))


def element_band(lin) -> float:
    """:func:`~bscomp.simulation.compiled_time.contact_band` of the elements' regime slopes in the linear part
    ``lin`` (``ELEMENT_BAND`` x the highest mode carrying ``ELEMENT_SHARE`` of an element's compliance); 0 without a
    stiff regime, or for a model that is not mechanical.

    The modes above ``f_keep`` are static (residual flexibility): exact for slow forces, but an impact on a stiff
    contact rings the contact's own mode, the modes just above it answer that ringing dynamically (at 0.76 of
    their frequency, 2.4x the static answer), and a regime switch projects the state onto a part where they are
    static. A random test bed with a 3e10 N/m contact (its modes at 23.5 and 24.6 kHz; ``f_keep`` 30 kHz in every
    regime): table.a NRMSE 4.0e-3 whatever ``tol``; every mode to 35 kHz kept 6.6e-4, to 45 kHz 3.4e-4, no better
    above; the band kept in the contact regime alone 2.1e-3 (docs/nonlinear.md, Limits)."""
    dae = lin.ch.dae
    k = np.array([kd[0] for kd in lin.regime], float)
    if dae.nz or dae.mech.damped or dae.mech.static or not np.any(k > 0):
        return 0.0
    mb = _mechanical_blocks(lin)
    if mb is None:
        return 0.0
    M, _, K, _, Rb, *_ = mb
    lam, phi, rigid = _undamped_modes(lin, K, M)
    return contact_band(lam, phi, lin.G[Rb][:, :k.size], k, rigid)


def element_bands(ch, cands):
    """``[(element path, band [Hz])]``: :func:`element_band` of each element with a stiff candidate regime, in
    the linear part where it alone takes its stiffest regime (the others at rest, the joints at their start)."""
    z0 = [jt.z0 for jt in ch.joints]
    out = []
    for i, cand in enumerate(cands):
        j = int(np.argmax([c[0] for c in cand]))
        if cand[j][0] > 0.0:
            slopes = [c[0] for c in cands]
            slopes[i] = cand[j]
            out.append((ch.elements[i].path, element_band(LinearPart(ch, slopes, z0))))
    return out
