"""Real modal coordinates of a linear(ized) model and the residual-vibration bound built on them.

One real block-diagonalisation of the state matrix of ``x' = xd0 + A (x - x0) + B u``
(:func:`affine_model`, the index-1 explicit form of :func:`bscomp.linear.linearization.explicit_form`):

* :func:`~bscomp.linear.real_form.modal_basis`: ``A P = P Λ`` with ``Λ`` block diagonal -- a 2 x 2
  block ``[[σ, ω], [-ω, σ]]`` per oscillating mode (eigenvalues ``σ ± jω``; ``σ = -ζω_n`` for a viscously
  damped mode), 1 x 1 blocks for real eigenvalues (e.g. ``-B/J`` of a rigid body on a viscous bearing) and
  one dense block for the eigenvalues at zero (a free rigid body: a Jordan block when undamped). It is
  exact for any damping (modal, a discrete motor damper, non-proportional): the damping is part of ``A``
  and ends up in the blocks, not in an approximation of it.
* :class:`ModalDae`: the model in those coordinates, ``ξ' = Λ ξ + P⁻¹ (x'0 + B u)`` with ``x = x0 + P ξ``;
  outputs and original states are linear maps of ξ. :mod:`bscomp.optimal.modal` transcribes it.
* :func:`residual_rows`: rows ``L`` such that ``||L (x_T - x0) + l|| <= a`` guarantees that the free
  response after ``T`` (input held) stays within ``± a`` of its final value in a named output.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from bscomp.kernel.dae import _sp
from bscomp.linear.linearization import explicit_form
from bscomp.linear.real_form import ModalError, modal_basis

__all__ = ["ModalError", "ModalDae", "modal_basis", "affine_model", "output_rows", "check_linear", "residual_rows"]


def affine_model(dae, p, x0, u0=None) -> dict:
    """The linearization of ``dae`` at ``(x0, u0)`` in explicit form.

    ``x' = xd0 + A (x - x0) + B (u - u0)``, ``z = z0 + Zx (x - x0) + Zu (u - u0)``, with ``(xd0, z0)``
    consistent at the point and ``[A B; Zx Zu] = -[dF/dx', dF/dz]⁻¹ [dF/dx, dF/du]``
    (:func:`bscomp.linear.linearization.explicit_form`).

    Returns
    -------
    dict
        ``x0``, ``u0``, ``xd0``, ``z0``, ``A``, ``B``, ``Zx``, ``Zu`` (dense arrays) and ``J``, the sparse
        Jacobians ``(dF/dx', dF/dx, dF/dz, dF/du)`` at the point (row scales of the transcription).
        Raises what ``initialize`` or ``explicit_form`` raise where the point has no index-1 linearization.
    """
    u0 = np.zeros(dae.nu) if u0 is None else np.asarray(u0, float)
    xd0, z0 = dae.initialize(x0, u0, p, store=False)
    _, Jxd, Jx, Jz, Ju = dae.jacobians_at(xd0, x0, z0, u0, p)
    A, B, Zx, Zu = explicit_form(dae, Jxd, Jx, Jz, Ju)
    return {"x0": np.asarray(x0, float), "u0": u0, "xd0": np.asarray(xd0, float).ravel(),
            "z0": np.asarray(z0, float).ravel(), "A": np.asarray(A), "B": np.asarray(B), "Zx": np.asarray(Zx),
            "Zu": np.asarray(Zu), "J": (Jxd, Jx, Jz, Ju)}


def output_rows(dae, p, lin, names):
    """Exact affine output map of a linear model: ``y = y0 + Cx (x - x0) + Du u`` for each name (an
    observable or a state), derivatives and algebraic variables eliminated through ``A``, ``Zx``."""
    nx, nu = dae.nx, dae.nu
    Cx, Du, y0 = np.zeros((len(names), nx)), np.zeros((len(names), nu)), np.zeros(len(names))
    obs = [n for n in names if n not in dae.x_names]
    if obs:
        f = dae.output_function(obs)
        xd, x, z, u = (ca.SX.sym(s, m) for s, m in (("xd", nx), ("x", nx), ("z", dae.nz), ("u", nu)))
        y = f(xd, x, z, u, p)
        J = ca.Function("J", [xd, x, z, u], [y, ca.jacobian(y, xd), ca.jacobian(y, x), ca.jacobian(y, z),
                                             ca.jacobian(y, u)])
        yv, Jxd, Jx, Jz, Ju = (np.asarray(ca.DM(m)) for m in J(lin["xd0"], lin["x0"], lin["z0"], lin["u0"]))
        Jz = Jz.reshape(len(obs), dae.nz)
        Cobs = Jxd @ lin["A"] + Jx + Jz @ lin["Zx"]
        Dobs = Jxd @ lin["B"] + Ju + Jz @ lin["Zu"]
    for r, n in enumerate(names):
        if n in dae.x_names:
            i = dae.x_names.index(n)
            Cx[r, i], y0[r] = 1.0, lin["x0"][i]
        else:
            o = obs.index(n)
            Cx[r], Du[r], y0[r] = Cobs[o], Dobs[o], float(yv.ravel()[o]) - Dobs[o] @ lin["u0"]
    return y0, Cx, Du


def check_linear(dae, p, lin, rel_tol=1e-8):
    """Raise :class:`ModalError` if the Jacobians of ``F`` differ at a second, perturbed point."""
    rng = np.random.default_rng(0)
    x0, xd0, z0 = lin["x0"], lin["xd0"], lin["z0"]
    pert = [v + (1e-3 + np.abs(v)) * rng.standard_normal(v.shape) for v in (xd0, x0, z0, np.zeros(dae.nu))]
    J0 = dae.jacobians_at(xd0, x0, z0, lin["u0"], p)[1:]
    J1 = dae.jacobians_at(*pert, p)[1:]
    for a, b in zip(J0, J1):
        if a.nnz or b.nnz:
            d = abs(a - b).max() if (a - b).nnz else 0.0
            if d > rel_tol * max(abs(a).max() if a.nnz else 0.0, abs(b).max() if b.nnz else 0.0, 1e-300):
                raise ModalError(f"'{dae.name}' is not linear (its Jacobian changes with the state): modal "
                                 "coordinates need a linear model; use coordinates='physical'")


class ModalDae:
    """A linear model in real modal coordinates ``ξ``: ``x = x0 + P ξ``, ``ξ' = Λ ξ + P⁻¹ (B u + x'0)`` with
    ``P``, ``Λ`` from :func:`modal_basis` (block diagonal: every damping of the model -- modal, discrete,
    non-proportional -- is inside the blocks). It presents the part of the :class:`bscomp.kernel.dae.Dae` interface
    the OCP uses (``F``, ``jacobians``, ``initialize``, ``output_function`` for the original observables and
    states, names, sizes); :func:`bscomp.optimal.modal.solve_modal` transcribes it. Built by :meth:`from_dae`.
    """

    def __init__(self, name, lin, p, u_names, out_map, P, Pinv, Lam, Bm, fm, blocks, info=None):
        self.name = f"{name} (modal)"
        self.lin, self.p = lin, np.asarray(p, float)
        self.P, self.Pinv, self.Asp, self.Bm, self.fm = P, Pinv, Lam, Bm, fm
        n = P.shape[0]
        self.x_names = [f"xi{i}" for i in range(n)]
        self.z_names, self.u_names = [], list(u_names)
        self.x_start, self.z_start = np.zeros(n), np.zeros(0)
        self.structural_parameters = []
        self._out_map = out_map
        self.observables = out_map.names
        self._cache = {}
        self.info = info or {}
        self.self_basis = {"P": np.eye(n), "Pinv": np.eye(n), "Lam": Lam, "blocks": blocks}

    @classmethod
    def from_dae(cls, dae, p, x0, zero_tol=1e-7):
        """The linear model ``dae`` (parameters ``p``) in modal coordinates about the state ``x0``; raises
        :class:`ModalError` if it is not linear or not block-diagonalisable."""
        lin = affine_model(dae, p, x0)
        check_linear(dae, p, lin)
        basis = modal_basis(lin["A"], zero_tol)
        n = lin["A"].shape[0]
        return cls(dae.name, lin, p, dae.u_names, _OutputMap(dae, p, lin), basis["P"], basis["Pinv"], basis["Lam"],
                   basis["Pinv"] @ lin["B"], basis["Pinv"] @ lin["xd0"], basis["blocks"],
                   info={"cond_P": basis["cond"], "n_blocks": len(basis["blocks"]), "n_states": n})

    # sizes
    nx = property(lambda self: self.P.shape[0])
    nz = property(lambda self: 0)
    nu = property(lambda self: len(self.u_names))

    def parameter_vector(self, params=None):
        return self.p

    def _mx(self):
        return (ca.MX.sym("xd", self.nx), ca.MX.sym("x", self.nx), ca.MX.sym("z", self.nz),
                ca.MX.sym("u", self.nu), ca.MX.sym("p", len(self.p)))

    @property
    def F(self):
        if "F" not in self._cache:
            xd, x, z, u, p = self._mx()
            res = xd - ca.mtimes(ca.sparsify(ca.DM(self.Asp)), x) - ca.mtimes(ca.DM(self.Bm), u) - self.fm
            self._cache["F"] = ca.Function("F", [xd, x, z, u, p], [res], ["xd", "x", "z", "u", "p"], ["res"])
        return self._cache["F"]

    def jacobians(self, xd, x, z, u, p):
        n = self.nx
        xd, x, u = (np.asarray(a, float).ravel() for a in (xd, x, u))
        res = xd - self.Asp @ x - self.Bm @ u - self.fm
        return (ca.DM(res), ca.sparsify(ca.DM(np.eye(n))), ca.sparsify(ca.DM(-self.Asp)), ca.DM(n, 0),
                ca.DM(-self.Bm))

    def jacobians_at(self, xd, x, z, u, p):
        """:meth:`jacobians` as ``(F (n,) ndarray, dF/dxd, dF/dx, dF/dz, dF/du)`` scipy csc, the interface of
        :meth:`bscomp.kernel.dae.Dae.jacobians_at`."""
        res, *J = self.jacobians(xd, x, z, u, p)
        return (np.asarray(res, float).ravel(), *(_sp(j) for j in J))

    def initialize(self, x0=None, u0=None, p=None, store=False, **_):
        x = self.x_start if x0 is None else np.asarray(x0, float).ravel()
        u = np.zeros(self.nu) if u0 is None else np.asarray(u0, float).ravel()
        return self.Asp @ x + self.Bm @ u + self.fm, np.zeros(0)

    def output_function(self, names):
        key = tuple(names)
        if key not in self._cache:
            y0, Cm, Du = self.rows(list(names))
            xd, x, z, u, p = self._mx()
            y = ca.mtimes(ca.DM(Cm), x) + ca.mtimes(ca.DM(Du), u) + ca.DM(y0)
            self._cache[key] = ca.Function("y", [xd, x, z, u, p], [y])
        return self._cache[key]

    def rows(self, names):
        """``(y0, C, D)`` with ``y = y0 + C ξ + D u`` for names (observables or original states)."""
        y0, Cx, Du = self._out_map(list(names))
        C = Cx @ self.P
        C[np.abs(C) < 1e-14 * max(float(np.max(np.abs(C))) if C.size else 0.0, 1e-300)] = 0.0
        return y0, C, Du

    def to_physical(self, xi):
        """Original states of modal states ``xi`` ((..., n) rows)."""
        return self.lin["x0"][None, :] + np.atleast_2d(xi) @ self.P.T

    def from_physical(self, x):
        return (np.atleast_2d(x) - self.lin["x0"][None, :]) @ self.Pinv.T


class _OutputMap:
    def __init__(self, dae, p, lin):
        self.dae, self.p, self.lin = dae, p, lin
        self.names = _NameSet(dae)

    def __call__(self, names):
        return output_rows(self.dae, self.p, self.lin, names)


class _NameSet:
    """Membership test for 'observable or state of the original model' (used as ``observables``)."""

    def __init__(self, dae):
        self.dae = dae

    def __contains__(self, name):
        return name in self.dae.observables or name in self.dae.x_names

    def __iter__(self):
        return iter(list(self.dae.observables) + list(self.dae.x_names))


def residual_rows(lin, C, D, hold_u, zero_tol=1e-7, basis=None):
    """Rows bounding the free response after arrival.

    With the input held at ``hold_u`` from ``T`` on, the state of a linear model moves from ``x_T`` to an
    equilibrium ``x_∞`` as a sum of modes, ``x(t) - x_∞ = Σ_k P_k e^{Λ_k (t-T)} e_k`` with
    ``e_k = Pinv_k (x_T - x0) + Λ_k⁻¹ Pinv_k b`` (``b = xd0 + B hold_u``) for every non-zero block ``k``.
    An output ``y = C x + D u`` then deviates from its final value by at most
    ``Σ_k G_k |e_k|`` with ``G_k = |C P_k|`` (a damped block only shrinks ``|e_k|``), and by Cauchy-Schwarz
    ``Σ_k G_k |e_k| <= sqrt(Σ_k G_k) sqrt(Σ_k G_k |e_k|²) = |L (x_T - x0) + l|``.

    Returns ``(L, l)`` (rows for blocks with ``G_k > 1e-12 max G``). Raises :class:`ModalError` if the held
    input has no equilibrium (it drives the zero-eigenvalue block, e.g. a torque held on a free rigid
    body) or a mode is unstable.
    """
    basis = basis or modal_basis(lin["A"], zero_tol)
    P, Pinv = basis["P"], basis["Pinv"]
    b = lin["xd0"] + lin["B"] @ np.asarray(hold_u, float)
    pb = Pinv @ b
    G, rows, offs = [], [], []
    for idx, kind, lam in basis["blocks"]:
        if kind == "zero":
            drift = float(np.linalg.norm(P[:, idx] @ pb[idx]))
            if drift > 1e-6 * max(float(np.linalg.norm(b)), 1e-300) and float(np.linalg.norm(b)) > 0:
                raise ModalError("the held input has no equilibrium: it accelerates the rigid-body (zero-eigenvalue) "
                                 "mode; hold an input that leaves the model at rest (e.g. zero torque)")
            continue
        if lam.real > 0:
            raise ModalError(f"unstable mode (eigenvalue {lam}): no residual-vibration bound")
        Lk = basis["Lam"][np.ix_(idx, idx)]
        G.append(float(np.linalg.norm(C @ P[:, idx])))
        rows.append(Pinv[idx])
        offs.append(np.linalg.solve(Lk, pb[idx]))
    if not G:
        return np.zeros((0, P.shape[0])), np.zeros(0)
    G = np.array(G)
    keep = G > 1e-12 * np.max(G)
    S = float(np.sum(G[keep]))
    L = np.vstack([np.sqrt(g * S) * r for g, r, k in zip(G, rows, keep) if k])
    l_ = np.concatenate([np.sqrt(g * S) * o for g, o, k in zip(G, offs, keep) if k])
    return L, l_
