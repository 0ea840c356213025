"""Time series of a :class:`bscomp.simulation.compiled.CompiledModel`: exact-ZOH modal stepping with the nonlinear
element forces solved by Newton at every step (see the module docstring of :mod:`bscomp.simulation.compiled`)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import scipy.linalg as sla

from bscomp.errors import ArgumentTypeError, BscompError, UnknownNameError, UsageError, check_mapping
from bscomp.linear.frf_engine import dense
from bscomp.linear.real_form import ModalError, modal_basis

__all__ = ["CompiledModelError", "TimeSeriesMixin"]


class CompiledModelError(BscompError):
    """A model that the compiled evaluator cannot handle (named element, what to do instead)."""



class TimeSeriesMixin:
    """The time-series methods of CompiledModel (needs ``elements``, ``inputs``, ``outputs``, ``y_op``, ``law_slices``,
    ``modal``, ``_split``, ``law_values``, ``_n_plaw``, ``_steps``, ``_runs``, ``stats``)."""

    def _step_function(self, n2, nu, ny, n_sub, n_newton, blocks=None):
        """One sample (``n_sub`` sub-steps) as an MX Function of the state and the discretised matrices.

        ``blocks``: the diagonal block sizes of the transition matrix in the real modal form
        (:func:`real_modal_form`; ``None``: dense), so that the state update costs ``O(n2)``, not ``O(n2^2)``.
        """
        key = (n2, nu, ny, n_sub, n_newton, blocks)
        if key in self._steps:
            return self._steps[key]
        r = len(self.elements)
        X = ca.MX.sym("x", n2 + r)
        up, uc = ca.MX.sym("up", nu), ca.MX.sym("uc", nu)
        Ad = ca.MX.sym("Ad", n2, n2) if blocks is None else ca.MX.sym("Ad", _block_sparsity(blocks))
        Ga = [ca.MX.sym(f"Ga{j}", n2, nu) for j in range(n_sub)]
        Gb = [ca.MX.sym(f"Gb{j}", n2, nu) for j in range(n_sub)]
        Wend = ca.MX.sym("wend", 2, n_sub)            # weights of (up, uc) in the input at each sub-step's end
        Gw0, Gw1 = ca.MX.sym("Gw0", n2, max(r, 1)), ca.MX.sym("Gw1", n2, max(r, 1))
        Cs, Cv = ca.MX.sym("Cs", max(r, 1), n2), ca.MX.sym("Cv", max(r, 1), n2)
        Dsu = ca.MX.sym("Dsu", max(r, 1), nu)
        Gs, Gv = ca.MX.sym("Gs", max(r, 1), max(r, 1)), ca.MX.sym("Gv", max(r, 1), max(r, 1))
        Cy, Dyu, Dyw = ca.MX.sym("Cy", ny, n2), ca.MX.sym("Dyu", ny, nu), ca.MX.sym("Dyw", ny, max(r, 1))
        plaw = ca.MX.sym("plaw", self._n_plaw())
        x, w = X[:n2], X[n2:]
        bad = ca.MX(0)
        newton = self._newton(n_newton) if r else None
        for j in range(n_sub):
            xp = ca.mtimes(Ad, x) + ca.mtimes(Ga[j], up) + ca.mtimes(Gb[j], uc)
            if r:
                ue = Wend[0, j] * up + Wend[1, j] * uc
                xp = xp + ca.mtimes(Gw0, w)
                a_s = ca.mtimes(Cs, xp) + ca.mtimes(Dsu, ue)
                a_v = ca.mtimes(Cv, xp)
                w, res = newton(a_s, a_v, Gs, Gv, w, plaw)
                bad = ca.fmax(bad, res)
                x = xp + ca.mtimes(Gw1, w)
            else:
                x = xp
        y = ca.mtimes(Cy, x) + ca.mtimes(Dyu, uc)
        if r:
            y = y + ca.mtimes(Dyw, w)
        Xn = ca.vertcat(x, w) if r else x
        f = ca.Function("sample", [X, up, uc, Ad, *Ga, *Gb, Wend, Gw0, Gw1, Cs, Cv, Dsu, Gs, Gv, Cy, Dyu, Dyw, plaw],
                        [Xn, y, bad]).expand()   # SX: ~2x faster per sample than the MX virtual machine
        self._steps[key] = f
        return f

    def _newton(self, n_iter):
        """SX Newton on ``w = law(a_s + Gs w, a_v + Gv w) - lin(...)`` for all elements at once."""
        r = len(self.elements)
        a_s, a_v, w0 = ca.SX.sym("a_s", r), ca.SX.sym("a_v", r), ca.SX.sym("w0", r)
        Gs, Gv = ca.SX.sym("Gs", r, r), ca.SX.sym("Gv", r, r)
        pl = ca.SX.sym("pl", self._n_plaw())
        s, v = ca.SX.sym("s", r), ca.SX.sym("v", r)
        delta = []
        for i, (el, (pe, k_lin, s0_lin, d_lin)) in enumerate(zip(self.elements, self.law_slices(pl), strict=True)):
            law = el.law(s[i], v[i], pe)
            delta.append(law - k_lin * (s[i] - s0_lin) - d_lin * v[i])
        dl = ca.vertcat(*delta)
        dfun = ca.Function("delta", [s, v, pl], [dl, ca.diag(ca.jacobian(dl, s)), ca.diag(ca.jacobian(dl, v))])
        w = w0
        eye = ca.SX.eye(r)
        for _ in range(n_iter):
            ss, vv = a_s + ca.mtimes(Gs, w), a_v + ca.mtimes(Gv, w)
            dv, ds_, dvv = dfun(ss, vv, pl)
            R = w - dv
            J = eye - ca.mtimes(ca.diag(ds_), Gs) - ca.mtimes(ca.diag(dvv), Gv)
            w = w - ca.solve(J, R)
        ss, vv = a_s + ca.mtimes(Gs, w), a_v + ca.mtimes(Gv, w)
        R = w - dfun(ss, vv, pl)[0]
        scale = 1.0 + ca.norm_inf(w)
        return ca.Function("newton", [a_s, a_v, Gs, Gv, w0, pl], [w, ca.norm_inf(R) / scale])

    def _discrete(self, mm, dt, n_sub, alpha, outputs):
        """Discretised modal matrices for one step length, delay fraction and output set (cached per
        modal model by :meth:`simulate`)."""
        so = mm.so
        r = len(self.elements)
        pk = mm.phi[:, mm.keep]
        lk = mm.lam[mm.keep]
        nk = lk.size
        n2 = 2 * nk
        A = np.block([[np.zeros((nk, nk)), np.eye(nk)], [-np.diag(lk), -mm.Ckk]])
        nu = len(self.inputs)
        Ball = dense(so.B, float)
        Bu = np.vstack([np.zeros((nk, nu)), pk.T @ Ball[:, :nu]])
        Bw = np.vstack([np.zeros((nk, r)), pk.T @ Ball[:, nu:]]) if r else np.zeros((n2, 1))
        # the state in the real modal form z = T^-1 x (exact similarity; dense A when ill-conditioned)
        form = real_modal_form(A)
        blocks = None
        if form is not None:
            T, J, Tinv, blocks = form
            A, Bu, Bw = J, Tinv @ Bu, Tinv @ Bw
        h = dt / n_sub
        Phi, G0, G2 = _discretize(A, h)
        Gu = G0 @ Bu
        # sub-step input matrices with the delay switch at fraction alpha of the sample
        Ga, Gb, Wend = [], [], np.zeros((2, n_sub))
        for j in range(n_sub):
            a, b = j / n_sub, (j + 1) / n_sub
            if alpha <= a + 1e-12:
                Ga.append(np.zeros_like(Gu)); Gb.append(Gu); Wend[:, j] = (0, 1)  # noqa: E702
            elif alpha >= b - 1e-12:
                Ga.append(Gu); Gb.append(np.zeros_like(Gu)); Wend[:, j] = (1, 0)  # noqa: E702
            else:
                beta = (alpha - a) / (b - a)
                _, G0b, _ = _discretize(A, (1 - beta) * h)
                Gb.append(G0b @ Bu); Ga.append(Gu - G0b @ Bu); Wend[:, j] = (0, 1)  # noqa: E702
        Gw1 = (G2 / h) @ Bw
        Gw0 = G0 @ Bw - Gw1
        # outputs and element coordinates: y = Cq q + Cv q' + Ca q'' + D u with q = pk eta + Rt B u
        allouts = list(so.outputs)
        Cq_, Cv_, Ca_, D_ = (dense(mat, float) for mat in (so.Cq, so.Cv, so.Ca, so.D))

        def rows(names):
            idx = [allouts.index(n) for n in names]
            Cq, Cv, Ca, D = Cq_[idx], Cv_[idx], Ca_[idx], D_[idx]
            CaP = Ca @ pk
            Cx = np.hstack([Cq @ pk - CaP * lk[None, :], Cv @ pk - CaP @ mm.Ckk])
            if form is not None:
                Cx = Cx @ T
            Dall = CaP @ (pk.T @ Ball) + Cq @ (mm.Rt @ Ball) + D
            return Cx, Dall[:, :nu], Dall[:, nu:]

        Cy, Dyu, Dyw = rows(outputs)
        if r:
            Cs, Dsu, Dsw = rows([f"{el.path}.s_rel" for el in self.elements])
            Cvn, _, _ = rows([f"{el.path}.v_rel" for el in self.elements])
        else:
            Cs = Cvn = np.zeros((1, n2))
            Dsu, Dsw, Dyw = np.zeros((1, nu)), np.zeros((1, 1)), np.zeros((len(outputs), 1))
        # the elements' sensitivity to their own forces within a sub-step (constant over the run)
        Gs, Gv = Cs @ Gw1 + Dsw, Cvn @ Gw1
        Ad = Phi if blocks is None else ca.DM(_block_sparsity(blocks), Phi.T[_block_mask(blocks).T].tolist())
        return n2, blocks, Phi, Ad, Ga, Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw

    def simulate(self, params, t, inputs: dict, outputs=None, extra_damping: float = 0.0, delay: float = 0.0,
                 n_sub: int | None = None, n_newton: int = 8, mm=None):
        """Outputs ``{name: y(t)}`` for measured inputs held over each sample (module docstring).

        ``t`` must be uniform; the first sample is the model at rest with the first input value. ``inputs`` maps
        inputs of this model to ``(nt,)`` arrays (a missing one is 0); ``outputs`` are among its outputs.
        """
        t, inputs, outputs = self._check_run(t, inputs, outputs)
        dt = float(t[1] - t[0])
        mm = mm or self.modal(params, extra_damping, delay)
        _lin, law, _struct = self._split(dict(params or {}))
        r = len(self.elements)
        n_sub = n_sub or (4 if r else 1)
        nt = t.size
        U = np.vstack([np.asarray(inputs.get(n, np.zeros(nt)), float) for n in self.inputs])
        # delayed held inputs: on step k the input is up = u[k-m-1] until fraction alpha, then uc = u[k-m]
        m = int(math.floor(delay / dt + 1e-12))
        alpha = delay / dt - m
        pad = np.zeros((U.shape[0], m + 1))
        Ud = np.hstack([pad, U])
        uc_seq = Ud[:, 1:nt + 1 - 0][:, :nt]
        up_seq = Ud[:, :nt]
        key = (dt, n_sub, round(alpha, 12), tuple(outputs))
        cache = mm.__dict__.setdefault("_discrete", {})
        if key not in cache:   # a change of an element's law parameter only re-runs the integration
            cache[key] = self._discrete(mm, dt, n_sub, alpha, outputs)
        n2, blocks, Phi, Ad, Ga, Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw = cache[key]
        nu = len(self.inputs)
        plaw = self.law_values(law)
        f = self._step_function(n2, nu, len(outputs), n_sub, n_newton, blocks)
        if not r:
            Y = _linear_run(Phi, Ga, Gb, Cy, Dyu, up_seq, uc_seq, n_sub)
            bad = 0.0
        else:
            mkey = (id(f), nt - 1)
            if mkey not in self._runs:
                self._runs[mkey] = f.mapaccum("run", nt - 1, [0], [0])
            F = self._runs[mkey]
            X0 = np.zeros(n2 + r)
            Xs, Y, bad = F(X0, up_seq[:, :nt - 1], uc_seq[:, :nt - 1], Ad, *Ga, *Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs,
                           Gv, Cy, Dyu, Dyw, plaw)
            Y = np.asarray(Y)
            bad = float(np.max(np.asarray(bad))) if nt > 1 else 0.0
        y0 = (Dyu @ uc_seq[:, 0])[:, None]
        Y = np.hstack([y0, np.asarray(Y)])
        yop = np.array([self.y_op[self.outputs.index(o)] if o in self.outputs else 0.0 for o in outputs])
        Y = Y + yop[:, None]
        self.stats["last_newton_residual"] = bad
        return {o: Y[i] for i, o in enumerate(outputs)}

    def _check_run(self, t, inputs, outputs):
        """``(t, inputs, outputs)`` of a :meth:`simulate` request, each checked (named errors)."""
        try:
            t = np.asarray(t, float)
        except (TypeError, ValueError):
            raise UsageError(f"CompiledModel.simulate: t must be an array of times [s], got {t!r}"[:300]) from None
        if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
            raise UsageError("CompiledModel.simulate: t must be a 1-D array of at least 2 finite, increasing times [s]")
        dt = float(t[1] - t[0])
        if np.max(np.abs(np.diff(t) - dt)) > 1e-6 * dt:
            raise CompiledModelError("CompiledModel.simulate needs a uniformly sampled time grid")
        inputs = check_mapping("CompiledModel.simulate: inputs", inputs, "input histories")
        for k, v in inputs.items():
            if k not in self.inputs:
                raise UnknownNameError(f"CompiledModel.simulate: '{k}' is not an input of this compiled model; inputs: "
                                       f"{self.inputs}")
            if np.shape(v) != t.shape or not np.all(np.isfinite(np.asarray(v, float))):
                raise UsageError(f"CompiledModel.simulate: inputs['{k}'] must be {t.size} finite values (one per "
                                 f"time), got shape {np.shape(v)}")
        known = list(self.outputs) + list(getattr(self, "nl_outputs", []))
        if outputs is None:
            outputs = list(self.outputs)
        elif isinstance(outputs, str):
            outputs = [outputs]
        elif not all(isinstance(o, str) for o in outputs):
            raise ArgumentTypeError(f"CompiledModel.simulate: outputs must be names, got {outputs!r}"[:300])
        bad = [o for o in outputs if o not in known]
        if bad:
            raise UnknownNameError(f"CompiledModel.simulate: {bad} are not outputs of this compiled model; outputs: "
                                   f"{self.outputs} (give them to CompiledModel(outputs=...))")
        return t, inputs, list(outputs)


def real_modal_form(A, max_cond: float = 1e6, tol: float = 1e-10):
    """``(T, J, T^-1, blocks)`` with ``A = T J T^-1`` in the real block-diagonal form of
    :func:`bscomp.linear.real_form.modal_basis`, ``blocks`` its block sizes (2 per oscillating mode, 1 per
    real eigenvalue, one block for the zero cluster: an undamped rigid body), or ``None`` where that basis is
    unavailable, ill-conditioned (``cond > max_cond``) or does not reproduce ``A`` to ``tol`` (relative to
    ``max|A|``): the caller then steps the dense ``A``."""
    try:
        basis = modal_basis(A)
    except ModalError:
        return None
    T, J, Tinv = basis["P"], basis["Lam"], basis["Pinv"]
    if not np.isfinite(basis["cond"]) or basis["cond"] > max_cond:
        return None
    if np.max(np.abs(T @ J @ Tinv - A)) > tol * np.max(np.abs(A)):
        return None
    return T, J, Tinv, tuple(len(idx) for idx, _, _ in basis["blocks"])    # blocks are contiguous, in order


def _block_mask(blocks) -> np.ndarray:
    """Boolean mask of a block-diagonal matrix with the given block sizes."""
    n = int(sum(blocks))
    mask = np.zeros((n, n), bool)
    i = 0
    for b in blocks:
        mask[i:i + b, i:i + b] = True
        i += b
    return mask


def _block_sparsity(blocks) -> ca.Sparsity:
    """CasADi sparsity of :func:`_block_mask` (column-major nonzeros, as ``DM(sp, values)`` expects)."""
    rows, cols = np.nonzero(_block_mask(blocks).T)     # transposed: column-major order
    return ca.Sparsity.triplet(int(sum(blocks)), int(sum(blocks)), cols.tolist(), rows.tolist())


def _discretize(A, h):
    """``(e^{Ah}, int_0^h e^{As} ds, int_0^h e^{As} (h - s) ds)`` by one augmented matrix exponential."""
    n = A.shape[0]
    Z = np.zeros((3 * n, 3 * n))
    Z[:n, :n] = A * h
    Z[:n, n:2 * n] = np.eye(n) * h
    Z[n:2 * n, 2 * n:] = np.eye(n) * h
    E = sla.expm(Z)
    # blocks: E12 = int_0^h e^{As} ds; E13 = int_0^h e^{As} (h - s) ds
    return E[:n, :n], E[:n, n:2 * n], E[:n, 2 * n:]


def _linear_run(Phi, Ga, Gb, Cy, Dyu, up_seq, uc_seq, n_sub):
    """Exact ZOH recursion of the linear modal system (no nonlinear elements)."""
    n_steps = up_seq.shape[1] - 1
    PhiS = np.linalg.matrix_power(Phi, n_sub)
    Ea = np.zeros_like(Ga[0])
    Eb = np.zeros_like(Gb[0])
    P = np.eye(Phi.shape[0])
    for j in reversed(range(n_sub)):
        Ea += P @ Ga[j]
        Eb += P @ Gb[j]
        P = P @ Phi
    drive = Ea @ up_seq[:, :n_steps] + Eb @ uc_seq[:, :n_steps]
    X = np.zeros((Phi.shape[0], n_steps))
    x = np.zeros(Phi.shape[0])
    for k in range(n_steps):
        x = PhiS @ x + drive[:, k]
        X[:, k] = x
    return Cy @ X + Dyu @ uc_seq[:, :n_steps]
