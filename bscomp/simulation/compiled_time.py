"""Time series of a :class:`bscomp.simulation.compiled.CompiledModel`: exact-ZOH modal stepping with the nonlinear
element forces solved by Newton at every step (see the module docstring of :mod:`bscomp.simulation.compiled`)."""

from __future__ import annotations

import math
import warnings

import casadi as ca
import numpy as np
import scipy.linalg as sla
from scipy.signal import lfilter

from bscomp.errors import ModelLimitationWarning
from bscomp.linear.frf_engine import dense
from bscomp.linear.real_form import ModalError, modal_basis
from bscomp.simulation.compiled_checks import CompiledModelError, check_run
from bscomp.simulation.compiled_hot import skipping_newton

__all__ = ["CompiledModelError", "TimeSeriesMixin"]


class TimeSeriesMixin:
    """The time-series methods of CompiledModel (needs ``elements``, ``inputs``, ``outputs``, ``y_op``, ``law_slices``,
    ``modal``, ``_split``, ``law_values``, ``_n_plaw``, ``_steps``, ``_runs``, ``stats``)."""

    def _step_function(self, n2, nu, ny, n_sub, n_newton, blocks=None, guard=False):
        """One sample (``n_sub`` sub-steps) as an SX Function of the state and the discretised matrices: the
        expansion of :meth:`_sample_graph` with the Newton of :meth:`_newton` (CasADi's virtual machine runs it)."""
        key = (n2, nu, ny, n_sub, n_newton, blocks, guard)
        if key in self._steps:
            return self._steps[key]
        newton = self._newton(n_newton, guard) if self.elements else None
        f = self._sample_graph(n2, nu, ny, n_sub, blocks, newton).expand()   # SX: ~2x faster than the MX VM
        self._steps[key] = f
        return f

    def _native_graph(self, key):
        """The sample of ``key`` (:meth:`_step_function`'s) as compiled to C (:mod:`~bscomp.simulation.compiled_hot`):
        the plain Newton's iterations skipped once one returned its start exactly -- a fixed point, so every later
        one would too and the numbers are the virtual machine's to the bit (the guarded Newton: all of them)."""
        n2, nu, ny, n_sub, n_newton, blocks, guard = key
        newton = self._newton(n_newton, guard) if guard else skipping_newton(*self._newton_parts(), n_newton)
        return self._sample_graph(n2, nu, ny, n_sub, blocks, newton)

    def _sample_graph(self, n2, nu, ny, n_sub, blocks, newton):
        """One sample (``n_sub`` sub-steps) as an MX Function of the state and the discretised matrices, the
        element forces by ``newton`` at every sub-step (``None``: no elements).

        ``blocks``: the diagonal block sizes of the transition matrix in the real modal form
        (:func:`real_modal_form`; ``None``: dense), so that the state update costs ``O(n2)``, not ``O(n2^2)``.
        """
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
        ins = [X, up, uc, Ad, *Ga, *Gb, Wend, Gw0, Gw1, Cs, Cv, Dsu, Gs, Gv, Cy, Dyu, Dyw, plaw]
        return ca.Function("sample", ins, [Xn, y, bad])

    def _newton(self, n_iter, guard=False):
        """SX Newton on ``w = law(a_s + Gs w, a_v + Gv w) - lin(...)`` for all elements at once; ``guard``: safeguarded
        by each element's bracket of the root (the fallback where plain Newton did not converge)."""
        r = len(self.elements)
        a_s, a_v, w0 = ca.SX.sym("a_s", r), ca.SX.sym("a_v", r), ca.SX.sym("w0", r)
        Gs, Gv = ca.SX.sym("Gs", r, r), ca.SX.sym("Gv", r, r)
        pl = ca.SX.sym("pl", self._n_plaw())
        dfun = self._delta(pl)
        w = w0
        eye = ca.SX.eye(r)
        # guard: each element's residual rises with its force (a passive law: J_ii >= 1), so the iterates bracket its
        # root; a Newton step out of the known bracket takes the bracket's secant point instead (a sharp contact corner
        # next to the damping clamp makes plain Newton cycle between two linear pieces). Not the default: with
        # coupled elements an element's bracket goes stale as the others' forces move (a steep friction law beside a
        # contact then converges slower than plain Newton)
        lo, hi, r_lo, r_hi = (ca.SX.zeros(r) for _ in range(4))
        has_lo, has_hi = ca.SX.zeros(r), ca.SX.zeros(r)
        for _ in range(n_iter):
            ss, vv = a_s + ca.mtimes(Gs, w), a_v + ca.mtimes(Gv, w)
            dv, ds_, dvv = dfun(ss, vv, pl)
            R = w - dv
            J = eye - ca.mtimes(ca.diag(ds_), Gs) - ca.mtimes(ca.diag(dvv), Gv)
            wn = w - ca.solve(J, R)
            if not guard:
                w = wn
                continue
            above = R > 0
            hi, r_hi, has_hi = ca.if_else(above, w, hi), ca.if_else(above, R, r_hi), ca.fmax(has_hi, above)
            lo, r_lo, has_lo = ca.if_else(above, lo, w), ca.if_else(above, r_lo, R), ca.fmax(has_lo, 1 - above)
            out = has_lo * has_hi * ((wn <= lo) + (wn >= hi) > 0)
            w = ca.if_else(out, lo - r_lo * (hi - lo) / ca.fmax(r_hi - r_lo, 1e-300), wn)
        ss, vv = a_s + ca.mtimes(Gs, w), a_v + ca.mtimes(Gv, w)
        R = w - dfun(ss, vv, pl)[0]
        scale = 1.0 + ca.norm_inf(w)
        return ca.Function("newton", [a_s, a_v, Gs, Gv, w0, pl], [w, ca.norm_inf(R) / scale])

    def _delta(self, pl):
        """SX Function ``(s, v, pl) -> (law - lin, d/ds, d/dv)`` of every element (what the Newton zeroes), made on
        the caller's law-parameter symbols ``pl`` (called with them, the parameters' own terms are made once, not
        once per iteration: 14 of the 200 instructions of an iteration with friction and a clearance)."""
        r = len(self.elements)
        s, v = ca.SX.sym("s", r), ca.SX.sym("v", r)
        delta = []
        for i, (el, (pe, k_lin, s0_lin, d_lin)) in enumerate(zip(self.elements, self.law_slices(pl), strict=True)):
            law = el.law(s[i], v[i], pe)
            delta.append(law - k_lin * (s[i] - s0_lin) - d_lin * v[i])
        dl = ca.vertcat(*delta)
        return ca.Function("delta", [s, v, pl], [dl, ca.diag(ca.jacobian(dl, s)), ca.diag(ca.jacobian(dl, v))])

    def _newton_parts(self):
        """SX Functions of :meth:`_newton`'s plain iteration (for :func:`~.compiled_hot.skipping_newton`):
        ``step(a_s, a_v, Gs, Gv, w, pl) -> (w_next, R)`` and ``residual(...) -> |R|_inf / (1 + |w|_inf)``, with the
        same operations in the same order (built once)."""
        parts = self._steps.get("newton_parts")
        if parts is not None:
            return parts
        r = len(self.elements)
        a_s, a_v, w = ca.SX.sym("a_s", r), ca.SX.sym("a_v", r), ca.SX.sym("w", r)
        Gs, Gv = ca.SX.sym("Gs", r, r), ca.SX.sym("Gv", r, r)
        pl = ca.SX.sym("pl", self._n_plaw())
        dfun = self._delta(pl)
        ss, vv = a_s + ca.mtimes(Gs, w), a_v + ca.mtimes(Gv, w)
        dv, ds_, dvv = dfun(ss, vv, pl)
        R = w - dv
        J = ca.SX.eye(r) - ca.mtimes(ca.diag(ds_), Gs) - ca.mtimes(ca.diag(dvv), Gv)
        ins = [a_s, a_v, Gs, Gv, w, pl]
        parts = self._steps["newton_parts"] = (
            ca.Function("newton_step", ins, [w - ca.solve(J, R), R]),
            ca.Function("newton_residual", ins, [ca.norm_inf(R) / (1.0 + ca.norm_inf(w))]))
        return parts

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
            Cs, Dsu, Dsw = rows([f"{el.path}.{el.coords[0]}" for el in self.elements])
            Cvn, _, _ = rows([f"{el.path}.{el.coords[1]}" for el in self.elements])
        else:
            Cs = Cvn = np.zeros((1, n2))
            Dsu, Dsw, Dyw = np.zeros((1, nu)), np.zeros((1, 1)), np.zeros((len(outputs), 1))
        # the elements' sensitivity to their own forces within a sub-step (constant over the run)
        Gs, Gv = Cs @ Gw1 + Dsw, Cvn @ Gw1
        Ad = Phi if blocks is None else ca.DM(_block_sparsity(blocks), Phi.T[_block_mask(blocks).T].tolist())
        return n2, blocks, Phi, Ad, Ga, Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw

    def simulate(self, params, t, inputs: dict, outputs=None, extra_damping: float = 0.0, delay: float = 0.0,
                 n_sub: int | None = None, n_newton: int = 8, mm=None, max_sub: int | None = None,
                 warn: bool = True):
        """Outputs ``{name: y(t)}`` for measured inputs held over each sample (module docstring).

        ``t`` must be uniform; the first sample is the model at rest with the first input value. ``inputs`` maps
        inputs of this model to ``(nt,)`` arrays (a missing one is 0); ``outputs`` are among its outputs.

        An element whose small-signal equivalent is a spring (a backlash's contact) is left out of the time series'
        linear part -- its whole law is the correction, so the clearance is free -- and ``mm`` (a modal model of
        :meth:`modal`) is used only when the model has no such element. ``n_sub`` (default 4 with elements) is the
        least number of sub-steps per sample: it is doubled until a sub-step is stable with every such contact
        engaged (:func:`_stable`); where the Newton on the element forces leaves a residual above :data:`NEWTON_TOL`
        the run is repeated with the Newton guarded (:meth:`_newton`), then with twice the sub-steps, and so on (at
        most ``max_sub``, default :data:`MAX_SUB`; then ``stats["newton_converged"]`` False and, with ``warn``, a
        ModelLimitationWarning), and a run that needed more sub-steps to converge is
        taken at twice the count that first converged (``benchmarks/fuzz_compiled.py`` seed 29, Stribeck friction
        with ``v_reg`` 1e-5 beside a clearance: the Newton fails at 4, converges at 8 with the velocity 52 % off,
        2e-6 at 16); ``stats["n_sub_used"]`` and ``stats["newton_guarded"]`` say what was used.
        """
        t, inputs, outputs = check_run(self, t, inputs, outputs)
        dt = float(t[1] - t[0])
        params = dict(params or {})
        cut = self._contact_equivalents()
        _lin, law, _struct = self._split(params)
        plaw = self.law_values(law)
        if cut and getattr(mm, "contacts_cut", ()) != tuple(cut):
            full = mm or self.modal(params, extra_damping, delay)
            f_keep = _band_keep(self._contact_band(full, plaw, cut), self.f_keep)
            rest = self._rest_equivalents(plaw, cut)     # the damping is the drive's linearised at rest
            damp = None if not any(rest.values()) else self.modal({**params, **rest}, extra_damping, delay)
            mm = self.modal({**params, **cut}, extra_damping, delay, damping_of=damp, f_keep=f_keep)
            mm.contacts_cut = tuple(cut)
        mm = mm or self.modal(params, extra_damping, delay)
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
        plaw_run = self._cut_law_values(plaw, cut)
        cap = MAX_SUB if max_sub is None else int(max_sub)
        guard, halved, margin = False, False, False
        while True:       # a Newton that did not converge: guard it, then halve the sub-step (a kink crossed in it)
            n_sub = self._stable_n_sub(mm, dt, n_sub, alpha, outputs, plaw, cut, cap)
            Y, bad = self._run(mm, (dt, n_sub, alpha, outputs), up_seq, uc_seq, plaw_run, n_newton, guard)
            bad = bad if np.all(np.isfinite(Y)) else np.inf
            if n_sub >= cap or (bad <= NEWTON_TOL and (margin or not halved)):
                break
            if bad <= NEWTON_TOL:       # first converged after halving: once more (docstring)
                n_sub, guard, margin = 2 * n_sub, False, True
            else:
                n_sub, guard, halved = (n_sub, True, halved) if not guard else (2 * n_sub, False, True)
        if bad > NEWTON_TOL and warn:
            warnings.warn(f"CompiledModel.simulate: the Newton on the forces of {[el.path for el in self.elements]} "
                          f"did not converge (residual {bad:.1e} of the force) even at {n_sub} sub-steps per sample: "
                          "the time series is not trustworthy; use bscomp.simulate(method='modal')",
                          ModelLimitationWarning, stacklevel=2)
        self.stats.update(n_sub_used=n_sub, newton_guarded=guard, last_newton_residual=bad,
                          newton_converged=bool(bad <= NEWTON_TOL))
        return {o: Y[i] for i, o in enumerate(outputs)}

    def _stable_n_sub(self, mm, dt, n_sub, alpha, outputs, plaw, cut, cap=None) -> int:
        """``n_sub`` doubled until a sub-step twice as long is stable too with the cut contacts engaged
        (:func:`_stable`). At the stability limit itself a kept mode above the contact's rings: the thesis bed with a
        1e11 N/m contact, modes to 12 kHz: stable from 16 sub-steps per 0.2 ms, table.a NRMSE 14 there, 2.1e-2 at
        32."""
        slopes = self._contact_slopes(plaw, cut)

        def stable(n):
            return _stable(self._disc(mm, (dt, n, alpha, outputs)), slopes)

        cap = MAX_SUB if cap is None else cap
        while cut and n_sub < cap and not (stable(n_sub) and (n_sub < 2 or stable(n_sub // 2))):
            n_sub *= 2
        return n_sub

    def _disc(self, mm, key):
        """:meth:`_discrete` cached on the modal model: a change of an element's law parameter only re-runs the
        integration."""
        dt, n_sub, alpha, outputs = key
        cache = mm.__dict__.setdefault("_discrete", {})
        ck = (dt, n_sub, round(alpha, 12), tuple(outputs))
        if ck not in cache:
            cache[ck] = self._discrete(mm, dt, n_sub, alpha, outputs)
        return cache[ck]

    def _run(self, mm, key, up_seq, uc_seq, plaw, n_newton, guard=False):
        """``(Y, worst Newton residual)``: the outputs at every sample (operating point added) for one sub-step
        count."""
        n_sub, outputs = key[1], key[3]
        r, nt, nu = len(self.elements), up_seq.shape[1], len(self.inputs)
        n2, blocks, Phi, Ad, Ga, Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw = self._disc(mm, key)
        fkey = (n2, nu, len(outputs), n_sub, n_newton, blocks, guard)
        native = (self._hot.get(fkey, lambda: self._native_graph(fkey), lambda: self._step_function(*fkey), nt - 1)
                  if r and nt > 1 else None)
        self.stats["native_steps"] = native is not None
        if not r:
            Y = _linear_run(Phi, Ga, Gb, Cy, Dyu, up_seq, uc_seq, n_sub, blocks)
            bad = 0.0
        elif native is not None:                            # the same samples compiled to C: the same numbers
            Y, bad = native(np.zeros(n2 + r), up_seq[:, :nt - 1], uc_seq[:, :nt - 1],
                            (Ad, *Ga, *Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw, plaw))
        else:
            f = self._step_function(*fkey)
            bkey = ("blocked", id(f))                       # f itself is held in _steps: its id stays
            if bkey not in self._steps:
                self._steps[bkey] = _blocked(f)
            fb, per = self._steps[bkey]
            nb = -(-(nt - 1) // per)                       # blocks; the last one padded with the last input
            mkey = (id(fb), nb)
            if mkey not in self._runs:
                self._runs[mkey] = fb.mapaccum("run", nb, [0], [0])
            F = self._runs[mkey]
            X0 = np.zeros(n2 + r)
            pad = nb * per - (nt - 1)
            up_b, uc_b = (np.pad(a[:, :nt - 1], ((0, 0), (0, pad)), mode="edge") for a in (up_seq, uc_seq))
            Xs, Y, bad = F(X0, up_b, uc_b, Ad, *Ga, *Gb, Wend, Gw0, Gw1, Cs, Cvn, Dsu, Gs, Gv, Cy, Dyu, Dyw, plaw)
            Y = np.asarray(Y)[:, :nt - 1]
            bad = float(np.max(np.asarray(bad)[:, :nt - 1])) if nt > 1 else 0.0
        y0 = (Dyu @ uc_seq[:, 0])[:, None]
        Y = np.hstack([y0, np.asarray(Y)])
        yop = np.array([self.y_op[self.outputs.index(o)] if o in self.outputs else 0.0 for o in outputs])
        return Y + yop[:, None], bad

    def _contact_equivalents(self) -> dict:
        """``{"<element>__lin.c": 0, "<element>__lin.d": 0}`` for every element whose small-signal equivalent is a
        spring (a backlash's contact): the time series' linear part leaves it out and the element's whole law is the
        correction. Kept in, the correction would have to cancel a stiff spring in the clearance -- a first-order
        hold cannot (the table stayed on the nut, docs/validation.md "Engine")."""
        out = {}
        for el in self.elements:
            if type(el.lin).__name__ in ("Spring", "SpringDamper"):
                for n in ("c", "d"):
                    if f"{el.path}__lin.{n}" in self.dae.p_names:
                        out[f"{el.path}__lin.{n}"] = 0.0
        return out

    def _is_cut(self, cut) -> list:
        """Per element: whether its small-signal equivalent is cut (:meth:`_contact_equivalents`)."""
        return [f"{el.path}__lin.c" in cut for el in self.elements]

    def _rest_equivalents(self, plaw, cut) -> dict:
        """``{"<element>__lin.c": k, "<element>__lin.d": d}``: each cut contact's law tangent at rest (0 in its
        clearance; its stiffness where it rests engaged): the linearisation a flattened model's system damping is
        derived from (a modal damping by mode character is re-derived from those modes)."""
        out = {}
        tangents = self.__dict__.setdefault("_tangents", {})
        for i, (el, (pe, *_), is_cut) in enumerate(zip(self.elements, self.law_slices(plaw), self._is_cut(cut),
                                                        strict=True)):
            if not is_cut:
                continue
            if i not in tangents:                # built once per element: (s, v, law parameters) -> slopes
                s, v, p = ca.SX.sym("s"), ca.SX.sym("v"), ca.SX.sym("pe", len(el.pnames))
                f = el.law(s, v, p)
                tangents[i] = ca.Function("tangent", [s, v, p], [ca.jacobian(f, s), ca.jacobian(f, v)])
            ks, kv = tangents[i](*self._el_rest[2 * i:2 * i + 2], pe)
            for n, val in (("c", float(ks)), ("d", float(kv))):
                if f"{el.path}__lin.{n}" in cut:
                    out[f"{el.path}__lin.{n}"] = val
        return out

    def _contact_band(self, full, plaw, cut) -> float:
        """:func:`contact_band` of the whole drive ``full`` (contacts engaged) for the cut contacts. Modes up to it
        are kept dynamic in the time series: with the contact force a correction, the modes just above its own
        answer an impact dynamically (the FE backlash truth at 6 kHz: chi^2 37 where every mode kept gives 24, the
        band 10.8 kHz, docs/validation.md)."""
        k, _d = self._contact_slopes(plaw, cut)
        B = dense(full.so.B, float)[:, len(self.inputs):]
        return contact_band(full.lam, full.phi, B, k, full.lam <= 0)

    def _contact_slopes(self, plaw, cut):
        """``(k, d)`` per element: the cut contacts' stiffness and damping (their laws' slopes in contact), 0 else."""
        kd = [(k_lin, d_lin) if c else (0.0, 0.0)
              for (_, k_lin, _, d_lin), c in zip(self.law_slices(plaw), self._is_cut(cut), strict=True)]
        return np.array([float(k) for k, _ in kd]), np.array([float(d) for _, d in kd])

    def _cut_law_values(self, plaw, cut):
        """``plaw`` with the cut elements' small-signal equivalent zeroed (their whole law is the correction)."""
        plaw = np.array(plaw, float)
        where = self.law_slices(np.arange(plaw.size))        # the packed layout's indices (one owner of it)
        for (_, ik, is0, id_), c in zip(where, self._is_cut(cut), strict=True):
            if c:
                plaw[[ik, is0, id_]] = 0.0
        return plaw


#: The modes that carry this share of an element's compliance in its stiffest regime (a contact's own modes) ...
ELEMENT_SHARE = 0.1
#: ... are kept with every mode up to this multiple of their frequency (:meth:`TimeSeriesMixin._contact_band`, and
#: in every regime of ``simulate(method="modal")``: :func:`bscomp.simulation.modal_parts.element_band`)
ELEMENT_BAND = 2.0
BAND_CAP = 2.0
"""The time series keeps modes up to a cut contact's band (:meth:`TimeSeriesMixin._contact_band`) up to this multiple
of the model's ``f_keep`` (:func:`_band_keep`)."""


def contact_band(lam, phi, B, k, rigid) -> float:
    """``ELEMENT_BAND f_e`` [Hz], ``f_e`` the highest frequency of a mode (``lam``, mass-normalised ``phi``) in which
    an element of stiffness slope ``k_i`` and force pattern ``B[:, i]`` carries at least ``ELEMENT_SHARE`` of its
    compliance, ``k_i (phi_j^T b_i)^2 / lam_j`` (the shares of ``b_i^T K^{-1} b_i <= 1/k_i`` sum to at most 1);
    0 without one. Shared by this evaluator and ``simulate(method="modal")``
    (:func:`bscomp.simulation.modal_parts.element_band`)."""
    share = (phi.T @ B) ** 2 * np.asarray(k, float)[None, :] / np.where(rigid, np.inf, lam)[:, None]
    own = (share >= ELEMENT_SHARE).any(axis=1) & ~rigid
    return float(ELEMENT_BAND * np.sqrt(lam[own].max()) / (2 * np.pi)) if own.any() else 0.0


def _band_keep(band: float, f_keep: float) -> float:
    """The time series' ``f_keep`` [Hz] for a cut contact's ``band``: the band itself from ``f_keep`` to ``BAND_CAP
    f_keep``, then back down linearly to ``f_keep`` at twice that, ``f_keep`` above. A contact far stiffer has its own
    modes far above the sampled band and gains nothing from a few more (a 1e11 N/m contact's band, 83 kHz, would keep
    every mode of the FE bed; the thesis bed's 1.7e10 N/m, band 36 kHz: no closer to ``simulate(method="modal")``
    with 12 kHz or the band kept, at 2-4x the cost), while the compliant backlash truth's 1.1e9 N/m, band 10.8 kHz, fits
    to the noise floor only with it (docs/validation.md "Engine"). Continuous in the band: the kept set must not jump
    as a fit moves the contact's stiffness (with a switch at the cap the fit took another basin)."""
    top = BAND_CAP * f_keep
    if band <= top:
        return max(f_keep, band)
    return max(f_keep, top - (band - top) * (top - f_keep) / top)


NEWTON_TOL = 1e-8
"""Largest Newton residual (relative to the element forces) a time series is accepted with at a sub-step count."""
MAX_SUB = 256
"""Most sub-steps per sample :meth:`TimeSeriesMixin.simulate` takes for a stiff contact (``stats["n_sub_used"]``)."""


def _stable(disc, slopes, tol: float = 1e-6) -> bool:
    r"""Whether one sub-step of the time series (:meth:`TimeSeriesMixin._discrete`'s matrices ``disc``) is stable
    with every cut contact engaged: the spectral radius of the linearised map of ``[x; w]`` is at most ``1 + tol``.

    With the contact's force first-order held across a sub-step, a spring of stiffness ``k`` on the kept modes is
    integrated like the linear-acceleration method (Newmark ``beta = 1/6``, ``gamma = 1/2``): stable only for
    ``omega h < 2 sqrt 3``. Linearised, ``w' = N x_p`` with ``N = (I - K G_s - D G_v)^{-1} (K C_s + D C_v)``,
    ``x_p = \Phi x + G_{w0} w`` and ``x' = x_p + G_{w1} w'``."""
    _n2, _b, Phi, _Ad, _Ga, _Gb, _W, Gw0, Gw1, Cs, Cv, _Dsu, Gs, Gv = disc[:14]
    k, d = slopes
    K, D = np.diag(k), np.diag(d)
    N = np.linalg.solve(np.eye(k.size) - K @ Gs - D @ Gv, K @ Cs + D @ Cv)
    P = np.eye(Phi.shape[0]) + Gw1 @ N
    M = np.block([[P @ Phi, P @ Gw0], [N @ Phi, N @ Gw0]])
    return bool(np.max(np.abs(np.linalg.eigvals(M))) <= 1.0 + tol)


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


def _linear_run(Phi, Ga, Gb, Cy, Dyu, up_seq, uc_seq, n_sub, blocks=None):
    """Exact ZOH recursion of the linear modal system (no nonlinear elements); ``blocks``: the block sizes of the
    real modal form (:func:`_recursion`), ``None`` for a dense ``Phi``."""
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
    X = _recursion(PhiS, drive, blocks or (Phi.shape[0],))
    return Cy @ X + Dyu @ uc_seq[:, :n_steps]


def _recursion(P, d, blocks) -> np.ndarray:
    r"""``X[:, k] = x_{k+1}`` of :math:`x_{k+1} = P x_k + d_k`, :math:`x_0 = 0`, for a block-diagonal ``P``.

    A 1 x 1 block is a first-order filter; a 2 x 2 block (an oscillating mode) is, by Cramer's rule on
    :math:`(zI - P) X(z) = D(z)`, :math:`x_{k+1} = e_k + Q e_{k-1}` with :math:`e` the data filtered by
    :math:`1 / (1 - \operatorname{tr} P\, z^{-1} + \det P\, z^{-2})` and :math:`Q = \operatorname{adj}(-P)`
    (``scipy.signal.lfilter``: ~4x faster than the step-by-step loop on diagnose's time series, outputs within
    2e-13 of it); larger blocks are stepped."""
    X = np.zeros_like(d)
    i = 0
    for b in blocks:
        p, di = P[i:i + b, i:i + b], d[i:i + b]
        if b == 1:
            X[i] = lfilter([1.0], [1.0, -p[0, 0]], di[0])
        elif b == 2:
            e = lfilter([1.0], [1.0, -(p[0, 0] + p[1, 1]), p[0, 0] * p[1, 1] - p[0, 1] * p[1, 0]], di, axis=1)
            X[i:i + 2] = e
            X[i:i + 2, 1:] += np.array([[-p[1, 1], p[0, 1]], [p[1, 0], -p[0, 0]]]) @ e[:, :-1]
        else:
            x = np.zeros(b)
            for k in range(d.shape[1]):
                x = p @ x + di[:, k]
                X[i:i + b, k] = x
        i += b
    return X


#: SX instructions of one blocked call (:func:`_blocked`): samples per call = this // the sample's, 1 to 8.
BLOCK_INSTRUCTIONS = 48000


def _blocked(f):
    """``(fb, per)``: ``per`` samples of the sample Function ``f`` in one SX Function (inputs ``up``, ``uc`` and
    outputs ``y``, ``bad`` with ``per`` columns). A ``mapaccum`` passes every matrix input anew
    to each call (~9 us a call, 60 % of a 2,000-instruction sample's run); a call per 8 samples halves the run
    (diagnose of the demo: 62 -> ~32 s in the time series), with the same arithmetic, bit for bit."""
    per = max(1, min(8, BLOCK_INSTRUCTIONS // max(f.n_instructions(), 1)))
    if per == 1:
        return f, 1
    ins = f.sx_in()
    x, rest = ins[0], ins[3:]
    up, uc = ca.SX.sym("up", f.size1_in(1), per), ca.SX.sym("uc", f.size1_in(2), per)
    ys, bads = [], []
    for j in range(per):
        x, y, b = f(x, up[:, j], uc[:, j], *rest)
        ys.append(y)
        bads.append(b)
    return ca.Function(f"{f.name()}_x{per}", [ins[0], up, uc, *rest], [x, ca.horzcat(*ys), ca.horzcat(*bads)]), per
