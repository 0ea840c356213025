r"""The compiled step of ``simulate(method="modal")``: one CasADi Function per shape (MX matrix operations around
small SX laws), run over chunks of steps through zero-copy buffers (no per-step Python inside a regime), and
optionally compiled to C.

A step's numbers -- the exponentials and the channel rows at the end and at the interior points
(:class:`bscomp.simulation.modal_steps.StepData`) -- are one flat input vector, the channel laws' numbers another
(:meth:`bscomp.simulation.modal_laws.LawSpec.pack`), so one Function serves every regime, reference, element and step
length of a shape (modal coordinates ``m``, inputs, channel forces ``r``, channel coordinates ``r_m``). The
state is ``[Re ξ; Im ξ; g]``; per step the Function returns the next state and
``[error, max |f|, regime ok at the end, element ok, last Newton update]`` (error and update in force units). A
regime change inside a step shows in the error (the law is exact in any regime); at the end it only tells the
driver to switch the linear part.

A chunk stops computing after its first step the driver will not accept (the driver's own rule, evaluated in
the kernel from ``ctl = [tol, force scale, Newton acceptance, steps wanted]``: error or last Newton update too
large for the step's largest force (at least :data:`FORCE_FLOOR` of the running force scale), contact point out
of its element, or a regime change at the end) or after the steps the driver wants (a chunk is a power of 4
long): the remaining steps are skipped by a short-circuit conditional and report an error of ``SKIPPED``, so a
chunk that fails early costs what it computed, not its length. It also returns its running numbers (``AUX``):
the driver reads how many steps it computed and the force scales from them, not from the step infos.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import casadi as ca
import numpy as np

from bscomp.simulation.native import native_functions

__all__ = ["pack_step", "Kernel", "NumpyCall"]

INFO = 5
AUX = 4    # a chunk's running numbers: force scale, stop, steps computed, the scale before the last of them
CTL = 4    # its stop rule: tolerance, force scale, Newton acceptance, steps wanted
#: A step's errors are judged against its own largest force, but at least this fraction of the run's largest so
#: far. 1.0 (the run's largest alone) is the rule. 0.1 was measured (docs/nonlinear.md, "Accuracy on drives we did
#: not build"): 80 random friction + backlash chains 2x closer to IDAS rtol 1e-10 (a light mass in a long stretch of
#: small forces beside large impacts: 30x), but the thesis's beds 15-60 % more sub-steps for nothing and the
#: friction truth's stepped sines changed enough to turn diagnose's verdict (test_amplitude.py) -- not kept until
#: an IDAS stepped sine says which of the two is right. ``benchmarks/fuzz_modal.py --floor`` measures any value.
FORCE_FLOOR = 1.0
SKIPPED = 1e300   # the error a skipped step reports (never accepted)
# a change of this file or of the laws' construction recompiles
_SOURCE_KEY = hashlib.sha1(Path(__file__).read_bytes()
                           + (Path(__file__).parent / "modal_laws.py").read_bytes()).hexdigest()
CONSISTENT_ITERATIONS = 8  # Newton iterations at most for the consistent forces (Kernel.newton_function)
JIT_SCHEMES = (-3, 3)  # the chunks' chord and the batches' Newton iterations (bscomp.simulation.modal_driver)


def pack_step(sd, n_el_rows, m_pad=None) -> np.ndarray:
    """Flat vector of a :class:`~bscomp.simulation.modal_steps.StepData` in the layout of :meth:`Kernel.step`
    (:attr:`Kernel.shapes`): the exponentials ``[Re E, Im E]``; the state update ``[Q_u, q_c, Q_0, Q_1]`` (real rows,
    then imaginary); the channel rows of the end and the interior points stacked as one matrix on
    ``[Re ξ_0; Im ξ_0; u; 1; g_0]`` (the end and the midpoint with every channel row, the other interior points with
    the elements' rows only), their ``Y_1`` (the end's, ``H``, apart: the Newton iterations use it alone), the
    start's rows; the step length. With ``m_pad`` the modal coordinates are padded with inert zeros (one kernel
    serves parts of a few sizes)."""
    m = sd.E.size
    pad = 0 if m_pad is None else m_pad - m

    def rows_(A):                       # modal index first: pad rows
        return np.concatenate([A, np.zeros((pad,) + A.shape[1:], A.dtype)], axis=0) if pad else A

    def cols_(A):                       # modal index last: pad columns
        return np.concatenate([A, np.zeros((A.shape[0], pad), A.dtype)], axis=1) if pad else A

    E, Qu, qc, Q0, Q1 = (rows_(a) for a in (sd.E, sd.Qu, sd.qc, sd.Q0, sd.Q1))
    Q = np.hstack([Qu, qc[:, None], Q0, Q1])

    def lhs(point, rows):               # the rows' matrix on [Re ξ_0; Im ξ_0; u; 1; g_0]
        CE, Yu, Y0, _, yc = point
        CE = cols_(CE[rows])
        return np.hstack([CE.real, -CE.imag, Yu[rows], yc[rows, None], Y0[rows]])

    points = [(sd.end, slice(None))] + [(pt, slice(None) if k == 1 else slice(0, n_el_rows))
                                        for k, pt in enumerate(sd.samples)]
    parts = [np.column_stack([E.real, E.imag]), np.vstack([Q.real, Q.imag]),
             np.vstack([lhs(pt, rows) for pt, rows in points]), sd.end[3],
             np.vstack([pt[3][rows] for pt, rows in points[1:]]), lhs(sd.start, slice(None)),
             np.array([sd.tau], float)]
    return np.concatenate([np.asarray(a, float).reshape(-1, order="F") for a in parts])


class Kernel:
    """Step Functions of one shape (see the module docstring).

    Parameters
    ----------
    m, nu, r, rm : int
        Modal coordinates, inputs, channel forces, channel coordinates.
    laws : tuple of casadi.Function
        The laws' Newton, value, check and elements Functions
        (:meth:`bscomp.simulation.modal_laws.LawSpec.functions`).
    n_el_rows : int
        The elements' rows (first among the channel coordinates).
    thetas : tuple of float
        Interior points of the error check.
    extrema : tuple of int
        Elements whose law depends on their displacement (a clearance, a contact): their displacement's extrema
        between the check points are checked too (:meth:`extremum_function`).
    law : casadi.Function, optional
        The whole law ``(y, theta) -> (g, dg/dy, fmax, regime_ok, element_ok)``
        (:meth:`~bscomp.simulation.modal_laws.LawSpec.function`) the driver calls from numpy between chunks
        (:meth:`law_call`: compiled into the chunks' library with ``jit``).
    """

    def __init__(self, m, nu, r, rm, laws, n_el_rows, thetas, n_newton=3, jit=False, extrema=(), law=None):
        self.m, self.nu, self.r, self.rm, self.thetas = m, nu, r, rm, tuple(thetas)
        self.extrema = tuple(int(i) for i in extrema)
        self.law_newton, self.law_value, self.law_check, self.law_elements = laws
        self.n_theta = self.law_newton.size1_in(1)
        self.ne = n_el_rows
        #: rows of each interior point: every channel at the midpoint, the elements' at the others
        self.point_rows = [rm if k == 1 else n_el_rows for k in range(len(self.thetas))]
        nz = 2 * m + nu + 1 + r                        # [Re ξ_0; Im ξ_0; u; 1; g_0]
        ri = sum(self.point_rows)
        #: the step matrices (:func:`pack_step`): E, Q, the end's and interior points' rows, H, the interior
        #: points' Y_1, the start's rows, the step length
        self.shapes = [(m, 2), (2 * m, nu + 1 + 2 * r), (rm + ri, nz), (rm, r), (ri, r), (rm, nz), (1, 1)]
        self.n_mats = sum(a * b for a, b in self.shapes)
        self.nx = 2 * m + r
        self._f = {}
        self._runs = {}
        self.n_newton = n_newton
        self.jit = bool(jit)
        self._native = None
        self.law = law
        self._calls = {}                               # NumpyCalls of the law and the Newton (_numpy_call)

    def _matrix_symbols(self):
        """One MX symbol per step matrix (separate inputs: a call passes pointers, nothing is copied)."""
        return [ca.MX.sym(f"M{i}", a, b) for i, (a, b) in enumerate(self.shapes)]

    def offsets(self):
        """``(start, end)`` of each step matrix in the packed vector of :func:`pack_step`."""
        out, off = [], 0
        for a, b in self.shapes:
            out.append((off, off + a * b))
            off += a * b
        return out

    def step(self, n_newton):
        """MX Function ``(x, u, *matrices, theta, chord) -> (x1, info)``; ``n_newton`` Newton iterations, or when
        negative that many chord iterations with the matrix ``chord = (I - L_0 H)^{-1}`` (the law's Jacobian
        at the chunk's start: no Jacobian per step, for the chunks of calm steps)."""
        f = self._f.get(n_newton)
        if f is not None:
            return f
        m, r, rm = self.m, self.r, self.rm
        S = ca.MX          # matrix loops and small SX callees: faster than a flat SX in the VM, compact C
        x = S.sym("x", self.nx)
        u = S.sym("u", self.nu)
        P = self._matrix_symbols()
        th = S.sym("theta", self.n_theta)
        Mc = S.sym("chord", r, r)
        xr, xi, g0 = x[:m], x[m:2 * m], x[2 * m:]
        E, Q, A, H, Y1i, _, tau = P
        # every point's rows but the g_1 part in one product (one long loop per column: the C compiler vectorizes
        # it; a product per point and term was most of a step's time)
        z = ca.vertcat(xr, xi, u, 1, g0)
        base = ca.mtimes(A, z)
        y_free = base[:rm]
        g = g0
        upd = S(0)
        solve = self._solver()
        for _ in range(abs(n_newton) if r else 0):
            if n_newton > 0:                            # Newton
                gl, L = self.law_newton(y_free + ca.mtimes(H, g), th)
                dg = solve(L, H, gl - g)
            else:                                       # chord: (I - L0 H)^-1 from the chunk's start
                dg = ca.mtimes(Mc, self.law_value(y_free + ca.mtimes(H, g), th)[0] - g)
            g = g + dg
            upd = ca.norm_inf(dg)
        y_end = y_free + ca.mtimes(H, g)
        _, fmax, okr, oke = self.law_check(y_end, th)
        err = S(0)
        ne = self.ne
        el_rows = [(0.0, None)]                         # (θ, the elements' rows there); the start's built below
        y_int = base[rm:] + ca.mtimes(Y1i, g)
        at = 0
        for k, (theta, n_rows) in enumerate(zip(self.thetas, self.point_rows, strict=True)):
            yj = y_int[at:at + n_rows]
            at += n_rows
            el_rows.append((theta, yj[:ne]))
            if k == 1:                                  # the midpoint: every channel
                gj, fj, okej = self.law_value(yj, th)
                gi = g0 + theta * (g - g0)
            elif ne:                                    # quarter points: the elements (short events)
                gj, fj = self.law_elements(yj, th)
                okej = 1
                nel = gj.numel()
                gi = g0[:nel] + theta * (g[:nel] - g0[:nel])
            else:
                continue
            err = ca.fmax(err, ca.norm_inf(gj - gi))
            fmax, oke = ca.fmax(fmax, fj), oke * okej
        if self.extrema and ne:
            el_rows[0] = (0.0, self._start_rows(P, z)[:ne])
            el_rows.append((1.0, y_end[:ne]))
            err = ca.fmax(err, self._extremum_error(el_rows, tau, g0, g, th))
        w = ca.mtimes(Q, ca.vertcat(u, 1, g0, g))
        Er, Ei = E[:, 0], E[:, 1]
        x1r = Er * xr - Ei * xi + w[:m]
        x1i = Er * xi + Ei * xr + w[m:]
        info = ca.vertcat(err, fmax, okr, oke, upd)
        f = ca.Function(f"modal_step_{_tag(n_newton)}", [x, u, *P, th, Mc], [ca.vertcat(x1r, x1i, g), info])
        self._f[n_newton] = f
        return f

    @staticmethod
    def _start_rows(P, z):
        """The channel rows at a step's start (``θ = 0``: the part ``g_1`` does not move) on ``z = [Re ξ_0; Im ξ_0;
        u; 1; g_0]``, from the step matrices ``P``."""
        return ca.mtimes(P[5], z)

    def _extremum_error(self, el_rows, tau, g0, g1, th):
        """The largest law error at the displacement extrema of the :attr:`extrema` elements between consecutive
        check points (:meth:`extremum_function`, one SX call per step)."""
        nel = self.ne // 2
        return self.extremum_function()(ca.horzcat(*[y for _, y in el_rows]), tau, g0[:nel], g1[:nel], th)

    def extremum_function(self):
        """SX Function ``(Y, τ, g_0, g_1, θ_law) -> error``, ``Y`` the elements' rows at the start, the check points
        and the end (one column each).

        A contact that closes and opens again (a bounce of a few microseconds) between two points of the check
        passes it unseen, and the run goes on as if the clearance had stayed open or closed. Between points
        ``θ_a < θ_b`` the displacement is the cubic Hermite interpolant of ``s`` and ``v = ṡ`` at both
        (``Δ = (θ_b - θ_a) τ``); where ``v`` changes sign, its value at ``x = v_a / (v_a - v_b)`` (where the chord of
        ``v`` crosses zero: the interpolant is flat near its stationary point, so ``s*`` hardly depends on where
        exactly that is) with ``v* = 0`` is where the element's correction is compared with the step's force line,
        at ``θ* = θ_a + x (θ_b - θ_a)``. Only the elements whose law depends on the displacement
        (a clearance, a contact) are checked: a friction's law is in the velocity."""
        F = self._f.get("extremum")
        if F is not None:
            return F
        ne, nel = self.ne, self.ne // 2
        pts = (0.0,) + self.thetas + (1.0,)
        Y = ca.SX.sym("Y", ne, len(pts))
        tau, g0, g1 = ca.SX.sym("tau"), ca.SX.sym("g0", nel), ca.SX.sym("g1", nel)
        th = ca.SX.sym("theta", self.n_theta)
        errs = []
        for k, (ta, tb) in enumerate(zip(pts[:-1], pts[1:], strict=True)):
            dt = (tb - ta) * tau
            for i in self.extrema:
                sa, va, sb, vb = Y[2 * i, k], Y[2 * i + 1, k], Y[2 * i, k + 1], Y[2 * i + 1, k + 1]
                # v changes sign: the stationary point where v's chord crosses zero (the displacement is flat
                # there, so its value is insensitive to where exactly the root is)
                x = ca.if_else(va * vb < 0, va / ca.if_else(va == vb, 1, va - vb), 0)
                x2, x3 = x * x, x * x * x
                s_ = (2 * x3 - 3 * x2 + 1) * sa + (x3 - 2 * x2 + x) * dt * va + (3 * x2 - 2 * x3) * sb \
                    + (x3 - x2) * dt * vb
                v_ = ca.if_else(va * vb < 0, 0, va)
                y = ca.SX.zeros(ne)
                y[2 * i], y[2 * i + 1] = s_, v_
                ge = self.law_elements(y, th)[0][i]
                errs.append(ca.fabs(ge - (g0[i] + (ta + x * (tb - ta)) * (g1[i] - g0[i]))))
        err = ca.mmax(ca.vertcat(*errs)) if errs else ca.SX(0)
        F = self._f["extremum"] = ca.Function("modal_extremum", [Y, tau, g0, g1, th], [err])
        return F

    def guarded(self, n_newton):
        """``(x, aux, u, *matrices, theta, chord, ctl) -> (x1, info, aux1)``: :meth:`step` unless ``aux = [scale,
        stop, count, scale before]`` says an earlier step of the chunk was not acceptable or the ``ctl[3]`` steps
        wanted are done (then the state passes through and the info reports :data:`SKIPPED`). ``aux1`` carries the
        running force scale, the stop flag by the driver's rule
        (:meth:`bscomp.simulation.modal_driver.ModalSimulator._flags`), the steps computed and the scale before the
        last of them."""
        key = ("guarded", n_newton)
        F = self._f.get(key)
        if F is not None:
            return F
        step = self.step(n_newton)
        x, aux, u = ca.MX.sym("x", self.nx), ca.MX.sym("aux", AUX), ca.MX.sym("u", self.nu)
        P = self._matrix_symbols()
        th, Mc, ctl = ca.MX.sym("theta", self.n_theta), ca.MX.sym("chord", self.r, self.r), ca.MX.sym("ctl", CTL)
        args = [x, aux, u, *P, th, Mc, ctl]
        x1, info = step(x, u, *P, th, Mc)
        sc = ca.fmax(aux[0], info[1])
        judge = ca.fmax(info[1], FORCE_FLOOR * sc)
        bad = ca.logic_or(ca.logic_or(info[0] > ctl[0] * judge, info[3] < 0.5),
                          ca.logic_not(info[4] < ctl[2] * judge))
        count = aux[2] + 1
        stop = ca.logic_or(ca.logic_or(bad, info[2] < 0.5), count >= ctl[3])
        run = ca.Function(f"modal_run_{_tag(n_newton)}", args, [x1, info, ca.vertcat(sc, stop, count, aux[0])])
        skip = ca.Function(f"modal_skip_{_tag(n_newton)}", args,
                           [x, ca.DM([SKIPPED, 0.0, 1.0, 0.0, SKIPPED]), aux])
        F = ca.Function.if_else(f"modal_guarded_{_tag(n_newton)}", skip, run)
        g = ca.Function(f"modal_gstep_{_tag(n_newton)}", args, F(aux[1], *args))
        self._f[key] = g
        return g

    def _solver(self, cols=1):
        """SX Function ``(L, H, b) -> (I - L H)^{-1} b`` for ``b`` of ``cols`` columns (the Newton update in the
        channel forces; with the identity, the chord matrix in one factorisation)."""
        F = self._f.get(("solver", cols))
        if F is None:              # one Function per shape: the chunks, the chord and the Newton call the same one
            r, rm = self.r, self.rm
            L, H, b = ca.SX.sym("L", r, rm), ca.SX.sym("H", rm, r), ca.SX.sym("b", r, cols)
            F = self._f[("solver", cols)] = ca.Function(f"newton_update{cols}", [L, H, b],
                                                        [ca.solve(ca.SX.eye(r) - ca.mtimes(L, H), b)])
        return F

    def _inner(self, n, n_newton):
        """``n`` guarded steps (a power of 4) taking the step matrices as separate arguments: four calls of the
        one a quarter as long, ``(x0, aux, U, *P, theta, chord, ctl) -> (X, INFO, aux)``."""
        key = ("inner", n, n_newton)
        F = self._f.get(key)
        if F is not None:
            return F
        x0 = ca.MX.sym("x", self.nx)
        aux0 = ca.MX.sym("aux", AUX)
        U = ca.MX.sym("U", self.nu, n)
        P = self._matrix_symbols()
        th = ca.MX.sym("theta", self.n_theta)
        Mc = ca.MX.sym("chord", self.r, self.r)
        ctl = ca.MX.sym("ctl", CTL)
        sub = self.guarded(n_newton) if n == 1 else self._inner(n // 4, n_newton)
        q = max(n // 4, 1)
        Xs, Is, x, aux = [], [], x0, aux0
        for j in range(n // q):
            X, I, aux = sub(x, aux, U[:, j * q:(j + 1) * q], *P, th, Mc, ctl)
            Xs.append(X)
            Is.append(I)
            x = X[:, -1]
        F = ca.Function(f"modal_inner{n}_{_tag(n_newton)}", [x0, aux0, U, *P, th, Mc, ctl],
                        [ca.horzcat(*Xs), ca.horzcat(*Is), aux])
        self._f[key] = F
        return F

    def chunk(self, n, n_newton):
        """MX Function of ``n`` steps (n a power of 4), ``(x0, U, mats, theta, ctl) -> (X, INFO, AUX)`` with ``U``
        (nu, n), ``mats`` the packed step matrices (:func:`pack_step`; split once per call, passed on by
        reference), ``ctl = [tol, force scale, Newton acceptance, steps wanted]`` (the steps after the first
        unacceptable one, or after the steps wanted, are skipped), ``X`` (nx, n) the states after each step,
        ``INFO`` (5, n) and ``AUX = [running force scale, stop, steps computed, the scale before the last]``. Chord
        iterations use the laws' Jacobian at the chunk's start (computed here, once per call)."""
        key = ("chunk", n, n_newton)
        F = self._f.get(key)
        if F is not None:
            return F
        x0 = ca.MX.sym("x", self.nx)
        U = ca.MX.sym("U", self.nu, n)
        mats = ca.MX.sym("mats", self.n_mats)
        th = ca.MX.sym("theta", self.n_theta)
        ctl = ca.MX.sym("ctl", CTL)
        P = [ca.reshape(mats[a:b], *shape) for (a, b), shape in zip(self.offsets(), self.shapes, strict=True)]
        Mc = self._chord(x0, U[:, 0], P, th) if n_newton < 0 else ca.MX.zeros(self.r, self.r)
        X, I, aux = self._inner(n, n_newton)(x0, ca.vertcat(ctl[1], 0, 0, ctl[1]), U, *P, th, Mc, ctl)
        F = ca.Function(f"modal_chunk{n}_{_tag(n_newton)}", [x0, U, mats, th, ctl], [X, I, aux])
        self._f[key] = F
        return F

    def _chord(self, x0, u0, P, th):
        """``(I - L_0 H)^{-1}``, ``L_0`` the laws' Jacobian at the chunk's start state (the chord iterations')."""
        m, r = self.m, self.r
        if not r:
            return ca.MX.zeros(0, 0)
        y0 = self._start_rows(P, ca.vertcat(x0[:m], x0[m:2 * m], u0, 1, x0[2 * m:]))
        L = self.law_newton(y0, th)[1]
        return self._solver(r)(L, P[3], ca.MX(ca.DM.eye(r)))

    def runner(self, n, n_newton=None):
        """A buffered caller of ``n`` steps (a power of 4): ``call(x0, U (n, nu), mats, theta, ctl) -> (X, INFO)``."""
        n_newton = self.n_newton if n_newton is None else n_newton
        key = (n, n_newton)
        run = self._runs.get(key)
        if run is None:
            F = self.compiled(n, n_newton) if self.jit else self.chunk(n, n_newton)
            run = self._runs[key] = _Buffered(F, self.nx, n)
        return run

    def compiled(self, n, n_newton):
        """The chunk compiled to C: every length and iteration scheme the driver uses in one library,
        compiled once per shape and cached on disk (:func:`~bscomp.simulation.native.native_functions`)."""
        if self._native is None:
            self._native = self._library()
        if (n, n_newton) not in self._native:
            self._native[(n, n_newton)] = native_functions([self.chunk(n, n_newton)])[0]
        return self._native[(n, n_newton)]

    def _library(self):
        """The compiled chunks by ``(length, scheme)`` and the whole law (key ``"law"``, with :attr:`law`)."""
        wanted = [(k, it) for it in JIT_SCHEMES for k in (1, 4, 16, 64, 256)]
        names = [f"modal_chunk{k}_{_tag(it)}" for k, it in wanted]
        if self.law is not None:
            wanted.append("law")
            names.append(_dense_name(self.law))
        if self.r:
            wanted.append("newton")
            names.append(f"modal_newton{CONSISTENT_ITERATIONS}")
        # the laws by their value and check Functions: the Newton one and the whole law are the same expression
        # and its Jacobian (modal_laws.LawSpec._build, in the source key), the largest to serialize
        shape = (self.m, self.nu, self.r, self.rm, self.ne, self.thetas, FORCE_FLOOR, self.extrema)
        key = "|".join([_SOURCE_KEY, repr(shape), repr(names)]
                       + [f.serialize() for f in (self.law_check, self.law_elements)])
        named = {"law": lambda: _dense(self.law), "newton": self.newton_function}
        funcs = native_functions(lambda: [named[w]() if w in named else self.chunk(*w) for w in wanted],
                                 key=key, names=names)
        return dict(zip(wanted, funcs, strict=True))

    def newton_function(self):
        """MX Function ``(y_free, H, g, θ, tol) -> (g, y, upd)``: Newton on ``g = law(y_free + H g)`` in the channel
        forces, at most :data:`CONSISTENT_ITERATIONS` iterations, stopping after the first whose update relative to
        ``1 + max |g|`` is below ``tol`` (the later ones skipped by a short-circuit conditional); ``y = y_free + H g``
        and ``upd`` the last relative update. The consistent forces after a regime switch (the step's static
        feedthrough only): :meth:`bscomp.simulation.modal_steps.Stepper.consistent`."""
        F = self._f.get("newton")
        if F is not None:
            return F
        rm, r = self.rm, self.r
        y_free, H, g, th = (ca.MX.sym("y_free", rm), ca.MX.sym("H", rm, r), ca.MX.sym("g", r),
                            ca.MX.sym("theta", self.n_theta))
        tol = ca.MX.sym("tol")
        args = [y_free, H, g, ca.MX.sym("upd"), th]
        gl, L = self.law_newton(y_free + ca.mtimes(H, g), th)
        dg = self._solver()(L, H, gl - g)
        g1 = g + dg
        run = ca.Function("newton_iteration", args, [g1, ca.norm_inf(dg) / (1 + ca.norm_inf(g1))])
        skip = ca.Function("newton_done", args, [g, args[3]])
        it = ca.Function.if_else("newton_guarded", skip, run)
        gk, upd = g, ca.MX(np.inf)
        for _ in range(CONSISTENT_ITERATIONS):
            gk, upd = it(upd < tol, y_free, H, gk, upd, th)
        F = self._f["newton"] = ca.Function(f"modal_newton{CONSISTENT_ITERATIONS}", [y_free, H, g, th, tol],
                                            [gk, y_free + ca.mtimes(H, gk), upd])
        return F

    def newton_call(self):
        """:class:`NumpyCall` of :meth:`newton_function`: compiled with the chunks under ``jit``."""
        return self._numpy_call("newton", self.newton_function)

    def law_call(self):
        """:class:`NumpyCall` of :attr:`law`: compiled with the chunks under ``jit`` (the consistent forces after
        each regime switch: 4 us a call on the moving-nut bed against 16 us in the virtual machine)."""
        return self._numpy_call("law", lambda: self.law)

    def _numpy_call(self, key, build):
        """:class:`NumpyCall` of the library's Function ``key`` under ``jit``, else of ``build()`` in the virtual
        machine (made once)."""
        call = self._calls.get(key)
        if call is None:
            if self.jit:
                if self._native is None:
                    self._native = self._library()
                F = self._native[key]
            else:
                F = build()
            call = self._calls[key] = NumpyCall(F)
        return call


def _tag(n_newton):
    return f"newton{n_newton}" if n_newton > 0 else f"chord{-n_newton}"


class _Buffered:
    """Calls a Function through its zero-copy buffer (arguments and results numpy, column-major). The state,
    inputs and stop rule are copied into arrays the buffer holds from the start; the step matrices and the law's
    numbers are passed by reference, re-pointed only when another array is given."""

    def __init__(self, F, nx, n):
        self.F, self.n = F, n
        self._mats = self._theta = None
        self.buf, self.trigger = F.buffer()
        self.X = np.zeros((n, nx))           # row k: state after step k (C-order rows = CasADi columns)
        self.I = np.zeros((n, INFO))
        self.buf.set_res(0, memoryview(self.X.reshape(-1)))
        self.buf.set_res(1, memoryview(self.I.reshape(-1)))
        self.aux = np.zeros(AUX)             # [running scale, stop, steps computed, scale before the last]
        self.buf.set_res(2, memoryview(self.aux))
        self.x0 = np.zeros(nx)
        self.U = np.zeros((n, F.size1_in(1)))  # (n, nu) rows = CasADi columns
        self.ctl = np.zeros(F.nnz_in(4))
        for i, a in ((0, self.x0), (1, self.U.reshape(-1)), (4, self.ctl)):
            self.buf.set_arg(i, memoryview(a))

    def __call__(self, x0, U, mats, theta, ctl):
        """``U``: (n, nu) inputs per step, or one (nu,) input held over all of them."""
        self.x0[:] = x0
        self.U[:] = U
        self.ctl[:] = ctl
        if self._mats is not mats:
            self.buf.set_arg(2, memoryview(mats))
            self._mats = mats
        if self._theta is not theta:
            self.buf.set_arg(3, memoryview(theta))
            self._theta = theta
        self.trigger()
        return self.X, self.I


class NumpyCall:
    """A small Function called with numpy vectors (or matrices, passed column by column as CasADi reads them)
    through its buffer (no DM conversion: ~10x cheaper per call than ``F(...)`` from Python). Returns the dense
    outputs as numpy arrays (reused between calls: copy what is kept); a sparse output is densified first."""

    def __init__(self, F):
        self.F = F = _dense(F)
        self.buf, self.trigger = self.F.buffer()
        self._out = [np.zeros((self.F.size1_out(i), self.F.size2_out(i)), order="F") for i in range(self.F.n_out())]
        self._flat = [o.reshape(-1, order="F") for o in self._out]
        for i, o in enumerate(self._flat):
            self.buf.set_res(i, memoryview(o))
        self._args = [np.zeros(self.F.nnz_in(i)) for i in range(self.F.n_in())]
        for i, a in enumerate(self._args):
            self.buf.set_arg(i, memoryview(a))

    def __call__(self, *args):
        for arg, a in zip(self._args, args, strict=True):
            arg[:] = np.ravel(a, order="F")         # a matrix argument column by column, as CasADi reads it
        self.trigger()
        return self._out


def _dense_name(F):
    """The name of :func:`_dense` ``(F)`` (without building it)."""
    return F.name() if all(F.sparsity_out(i).is_dense() for i in range(F.n_out())) else F.name() + "_dense"


def _dense(F):
    """``F`` with dense outputs (itself if they are; an SX Function's densified copy ``<name>_dense``, else)."""
    if _dense_name(F) == F.name():
        return F
    ins = F.sx_in()
    return ca.Function(F.name() + "_dense", ins, [ca.densify(o) for o in F.call(ins)])
