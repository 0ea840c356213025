r"""The compiled evaluator behind :func:`bscomp.design_sweep.design_study`: one flattening, many variants.

Each swept parameter is classified once (see the :mod:`bscomp.design_sweep` docstring): *affine*
(sensitivities ``\Delta X`` of the second-order matrices measured at ``p_0 \pm h`` and verified against
each other), *tangent* (a non-structural position whose component gives its exact tangent, the moving
nut's ``sn.z0``) or *direct* (re-flattened per variant). With the mass matrix fixed by the swept
parameters, ``M = L L^T`` is factored once and a variant is the standard symmetric problem

.. math:: \Big(A_0 + \sum_i \Delta p_i\, L^{-1} \Delta K_i L^{-T} + W \Delta K_t W^T\Big) v = \lambda v,
   \qquad \phi = L^{-T} v, \quad W = L^{-1} P^T,

one dense ``eigh``; otherwise the generalized ``eigh(K, M)``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.errors import UnknownNameError
from bscomp.kernel.flattening import flatten
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.linear.frf_engine import dense, modal_frf
from bscomp.linear.linearization import second_order

__all__ = ["ModesEvaluator"]

_MATS = ("M", "K", "Cs", "B", "Cq", "Cv", "Ca", "D")



class ModesEvaluator:
    """Modes (and modal FRFs) of one drive at many parameter values (module docstring)."""

    def __init__(self, spec, names, inputs=None, outputs=None):
        self.spec = spec
        self.system = spec.system()
        self.dae = dae = flatten(self.system)
        val = getattr(self.system, "validation", None)
        self.inputs = list(inputs) if inputs else list(getattr(val, "inputs", None) or dae.u_names)
        self.outputs = list(outputs) if outputs else list(getattr(val, "outputs", None) or dae.mech.coordinate_names)
        if outputs:
            dae.require_signals(self.outputs, "design_study")
        self.damping = getattr(dae, "system_damping", None)
        self.coords = list(dae.mech.coordinate_names)
        self.X0 = self._matrices(dae, {})
        self.kinds, self.sens, self.nominal, self.tangent = {}, {}, {}, None
        for n in names:
            self.kinds[n] = self._classify(n)
        fixed_m = all(k == "tangent" or (k == "affine" and not np.any(self.sens[n]["M"]))
                      for n, k in self.kinds.items())
        self.chol = None
        if fixed_m:
            L = np.linalg.cholesky(self.X0["M"])
            Li = sla.solve_triangular(L, np.eye(L.shape[0]), lower=True)
            A0 = Li @ self.X0["K"] @ Li.T
            self.chol = {"L": L, "A0": 0.5 * (A0 + A0.T),
                         "dA": {n: Li @ s["K"] @ Li.T for n, s in self.sens.items()}}
            if self.tangent is not None:
                self.tangent["W"] = np.asarray(self.tangent["P"] @ Li.T).T

    # ---- second-order matrices ---------------------------------------------------------------------
    def _matrices(self, dae, params):
        so = second_order(dae, refresh_damping=False, params=params or None, inputs=self.inputs,
                          outputs=self.outputs)
        Cs = so.C - sp.csr_matrix(dae.system_damping_basis[2]) if self.damping is not None else so.C
        mats = {"M": so.M, "K": so.K, "Cs": Cs, "B": so.B, "Cq": so.Cq, "Cv": so.Cv, "Ca": so.Ca, "D": so.D}
        return {k: dense(v, float) for k, v in mats.items()}

    def _at(self, params):
        """The matrices at ``params``: the Dae's Jacobians, or a re-flattening for build keywords and
        structural parameters."""
        dae = self.dae
        if any("." not in k or k in dae.structural_parameters for k in params):
            return self._matrices(flatten(self.spec.with_overrides(params).system()), {})
        return self._matrices(dae, params)

    def _classify(self, name):
        dae = self.dae
        if "." not in name:
            return "direct"                                   # a build keyword: re-made per variant
        if name not in dae.p_names:
            raise UnknownNameError(f"design_study: '{dae.name}' has no parameter '{name}' (build keywords have no "
                                   "dot, e.g. nut_position)")
        v0 = float(dae.p0[dae.p_names.index(name)])
        self.nominal[name] = v0
        if name not in dae.structural_parameters and self.tangent is None and self._setup_tangent(name, v0):
            return "tangent"
        h = 0.1 * abs(v0) if v0 != 0.0 else 1e-3
        Xp, Xm = self._at({name: v0 + h}), self._at({name: v0 - h})
        d = {k: (Xp[k] - self.X0[k]) / h for k in _MATS}
        for k in _MATS:
            scale = max(np.abs(self.X0[k]).max(), np.abs(Xp[k]).max(), 1e-300)
            if np.abs(self.X0[k] - h * d[k] - Xm[k]).max() > 1e-8 * scale:
                return "direct"
        self.sens[name] = d
        return "affine"

    def _setup_tangent(self, name, v0):
        path, pname = name.rsplit(".", 1)
        try:
            comp = self.system.component(path)
        except UnknownNameError:
            return False
        t0 = comp.tangent() if hasattr(comp, "tangent") else None
        if t0 is None:
            return False
        m = self.dae.mech
        rows = [m.port_coordinates[f"{path}.{d}"] for d in t0.dofs]
        if np.any(np.asarray(m.t0)[rows] != 0.0):
            return False
        self.tangent = {"name": name, "comp": comp, "pname": pname, "P": sp.csr_matrix(m.T)[rows],
                        "K0": dense(t0.K, float), "C0": None if t0.C is None else dense(t0.C, float)}
        return True

    def _tangent_at(self, x):
        t = self.tangent
        comp, pname = t["comp"], t["pname"]
        old = comp._values[pname]
        try:
            comp._values[pname] = float(x)
            return comp.tangent()
        finally:
            comp._values[pname] = old

    # ---- one variant ----------------------------------------------------------------------------------
    def evaluate(self, values: dict):
        """``(lam, phi, zeta, c_sys, C_extra, X)``: mass-normalised modes (rigid ones at 0), modal damping
        ratios, the system damping per mode and the other damping matrix (for the FRF), the matrices."""
        if any(self.kinds[n] == "direct" for n in values):
            X = self._at(values)
            return self._modes(X, None) + (X,)
        X = {k: v.copy() for k, v in self.X0.items()}
        for n, s in self.sens.items():
            dv = values.get(n, self.nominal[n]) - self.nominal[n]
            if dv:
                for k in _MATS:
                    X[k] += dv * s[k]
        dKt = None
        t = self.tangent
        if t is not None and t["name"] in values:
            tt = self._tangent_at(values[t["name"]])
            P = t["P"]
            dKt = dense(tt.K, float) - t["K0"]
            X["K"] += np.asarray(P.T @ dKt @ P)
            if tt.C is not None or t["C0"] is not None:
                dC = (dense(tt.C, float) if tt.C is not None else 0.0) - (t["C0"] if t["C0"] is not None else 0.0)
                X["Cs"] += np.asarray(P.T @ dC @ P)
        return self._modes(X, (values, dKt)) + (X,)

    def _modes(self, X, fast):
        if fast is not None and self.chol is not None:
            values, dKt = fast
            c = self.chol
            A = c["A0"].copy()
            for n, dA in c["dA"].items():
                dv = values.get(n, self.nominal[n]) - self.nominal[n]
                if dv:
                    A += dv * dA
            if dKt is not None:
                W = self.tangent["W"]
                A += W @ dKt @ W.T
            lam, v = sla.eigh(0.5 * (A + A.T), driver="evd", overwrite_a=True, check_finite=False)
            phi = sla.solve_triangular(c["L"], v, lower=True, trans="T", check_finite=False)
        else:
            lam, phi = sla.eigh(X["K"], X["M"], check_finite=False)
        lam = np.where(np.abs(lam) <= 1e-9 * np.max(np.abs(lam)), 0.0, lam)
        om = np.sqrt(np.clip(lam, 0.0, None))
        if self.damping is not None and hasattr(self.damping, "modal_ratios"):    # by mode character
            c_sys = 2.0 * om * np.asarray(self.damping.modal_ratios(lam, phi, sp.csr_matrix(X["M"]), self.coords))
            C_extra = X["Cs"]
        else:                                                                       # Rayleigh, or none
            c_sys = np.zeros(lam.size)
            C_extra = X["Cs"] + (dense(system_damping_matrix(self.damping, sp.csr_matrix(X["M"]),
                                                              sp.csr_matrix(X["K"]), self.coords), float)
                                 if self.damping is not None else 0.0)
        diag = np.sum(phi * (C_extra @ phi), axis=0) if np.any(C_extra) else 0.0
        zeta = (c_sys + diag) / np.where(om > 0, 2 * om, np.inf)
        return lam, phi, zeta, c_sys, C_extra

    def modes_row(self, values, n):
        lam, _phi, zeta, *_ = self.evaluate(values)
        el = lam > 0
        f = np.sqrt(lam[el]) / (2 * np.pi)
        z = zeta[el]
        out = np.full(2 * n, np.nan)
        k = min(n, f.size)
        out[:k], out[n:n + k] = f[:k], z[:k]
        return out.tolist()

    def frf_row(self, values, freqs):
        """Peak |H| and its frequency for every output/input pair (outputs slowest)."""
        lam, phi, _zeta, c_sys, C_extra, X = self.evaluate(values)
        H = modal_frf(lam, phi, c_sys, sp.csr_matrix(C_extra), X["B"], X["Cq"], X["Cv"], X["Ca"], X["D"], freqs)
        mag = np.abs(H).reshape(len(freqs), -1)
        k = np.argmax(mag, axis=0)
        return mag[k, np.arange(mag.shape[1])].tolist() + np.asarray(freqs)[k].tolist()
