r"""The harmonic balance of friction and backlash elements against a linear part given as a complex map per
frequency -- the core of :func:`bscomp.describing_frf` (on the flattened model) and of
:meth:`bscomp.simulation.compiled.CompiledModel.frf` with ``amplitude=`` (on a fit's modal model), so that
``compare``, ``calibrate`` and ``diagnose`` see the model at a measurement's amplitude the same way.

Each element moves as ``s(θ) = s_0 + Re(Ŝ e^{jθ})``, ``v(θ) = v_0 + Re(V̂ e^{jθ})`` and only the first harmonic of
its force is kept, ``F̂ = (1/π) ∫ f(s(θ), v(θ)) e^{-jθ} dθ`` (Coulomb friction, thesis Eq 5.7: ``4 F_c/π``; a
clearance, Eq 5.8: the dead zone's closed form; ``tests/bscomp/test_describing.py``). With ``harmonics = h`` the
odd orders ``k = 1, 3, ..., 2h - 1`` are balanced together (alternating frequency-time: the motion
``s(θ) = s_0 + Σ_k Re(Ŝ_k e^{jkθ})`` from the linear map at ``k ω``, the force's harmonics ``F̂_k`` by the discrete
Fourier sum, ``ĝ_k = F̂_k - k_0 Ŝ_k - d_0 V̂_k``); the even orders and the bias vanish for laws odd about the rest
point under a zero-mean sine (friction; a centred clearance), so they are not carried.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from bscomp.errors import UsageError, check_number
from bscomp.simulation.modal_kernels import NumpyCall

__all__ = ["HarmonicBalance", "first_harmonic", "odd_harmonics", "odd_harmonics_tangent", "check_harmonics",
           "AMPLITUDE_LADDER"]

AMPLITUDE_LADDER = (1 / 64, 1 / 16, 1 / 4, 1 / 2, 1.0)   # continuation when Newton fails from the last solution


def first_harmonic(law, pvec, s0, v0, S, V, points=256):
    """``F̂ = (1/π) ∫ f(s_0 + Re(S e^{jθ}), v_0 + Re(V e^{jθ})) e^{-jθ} dθ`` of a law ``(s, v, p) -> f`` (a CasADi
    Function), by the midpoint rule at ``points`` phases (exact for trigonometric polynomials below
    ``points - 1``). The phases are counted from the velocity's (the displacement's when the velocity is zero),
    so a jump at a velocity reversal -- Coulomb friction's sign -- falls between two phases symmetrically and
    costs ``O(1/points^2)`` instead of ``O(1/points)`` (``points`` a multiple of 4). :func:`odd_harmonics` of
    the order 1 alone."""
    return complex(odd_harmonics(law, pvec, s0, v0, np.array([S]), np.array([V]), (1,), points)[0])


def odd_harmonics(law, pvec, s0, v0, S, V, orders, points=256):
    """The harmonics ``F̂_k = (2/N) Σ f(s(θ_i), v(θ_i)) e^{-jkθ_i}`` of orders ``orders`` (odd) of a law driven
    by ``s(θ) = s_0 + Σ_k Re(S_k e^{jkθ})`` (and ``v`` alike) at ``N = points`` phases, counted from the
    fundamental velocity's (:func:`first_harmonic` is the case ``orders = (1,)``).

    With ``θ_i = θ_i^0 - φ`` (``φ`` the fundamental velocity's phase) ``e^{jkθ_i} = e^{jkθ_i^0} e^{-jkφ}``: the
    table ``e^{jkθ_i^0}`` is computed once per orders and points, the phase enters through the few ``S_k``, ``V_k``
    and ``F̂_k`` (a Newton's residual calls this thousands of times: 89 -> 50 us with five orders)."""
    E0, E0c, k, rot = _frame(S, V, orders, points)
    f = np.asarray(_mapped(law, points)(s0 + ((S * rot) @ E0).real, v0 + ((V * rot) @ E0).real, pvec)).ravel()
    return (2.0 / points) * np.conj(rot) * (E0c @ f)


def odd_harmonics_tangent(law, pvec, s0, v0, S, V, orders, points=256):
    """:func:`odd_harmonics` and its derivative: ``(F, dF)`` with ``dF`` (orders, 4 orders) complex, the change of
    each ``F̂_k`` per unit change of ``Re S, Im S, Re V, Im V`` -- the exact derivative of the discrete sum: the
    law's tangent at the phases and the turn of the phases with the fundamental's (``φ = arg V_1``):
    ``dF̂_k = e^{jkφ} (2/N) Σ (f_s ds̃ + f_v dṽ) e^{-jkθ^0} + jk F̂_k dφ``, ``dS̃_k = e^{-jkφ}(dS_k - jk S_k dφ)``,
    ``dφ = Im(dV_1 / V_1)``. ``None`` when the law has no SX tangent (the caller differences instead)."""
    tan = _mapped(law, points, tangent=True)
    if tan is None:
        return None
    E0, E0c, k, rot = _frame(S, V, orders, points)
    nh = k.size
    ref, ref_col = (V[0], 2 * nh) if V[0] != 0 else (S[0], 0)     # the phase's phasor and its Re column
    St, Vt = S * rot, V * rot
    f, fs, fv = (np.asarray(a).ravel() for a in tan(s0 + (St @ E0).real, v0 + (Vt @ E0).real, pvec))
    F = (2.0 / points) * np.conj(rot) * (E0c @ f)
    dS, dV = _directions(nh)
    dphi = np.zeros(4 * nh)
    if ref != 0:
        dphi[ref_col] = (1.0 / ref).imag                          # Im(1 / P)
        dphi[ref_col + nh] = (1j / ref).imag                      # Im(j / P)
    dSt = (dS - 1j * dphi[:, None] * k[None, :] * S[None, :]) * rot[None, :]
    dVt = (dV - 1j * dphi[:, None] * k[None, :] * V[None, :]) * rot[None, :]
    df = fs[None, :] * (dSt @ E0).real + fv[None, :] * (dVt @ E0).real     # (4 nh, points)
    dF = (2.0 / points) * np.conj(rot)[None, :] * (df @ E0c.T) + 1j * dphi[:, None] * k[None, :] * F[None, :]
    return F, dF.T


_TABLES = {}
_DIRECTIONS = {}


def _directions(nh):
    """``(dS, dV)`` (4 nh, nh) complex: the unit changes of ``Re S_l, Im S_l, Re V_l, Im V_l`` (cached per orders)."""
    d = _DIRECTIONS.get(nh)
    if d is None:
        eye = np.eye(nh)
        d = _DIRECTIONS[nh] = (np.vstack([eye, 1j * eye, 0 * eye, 0 * eye]),
                               np.vstack([0 * eye, 0 * eye, eye, 1j * eye]))
    return d


def _frame(S, V, orders, points):
    """``(e^{jkθ^0}, its conjugate, k, e^{-jkφ})``: the table of the midpoint phases ``θ^0_i = 2π (i + 1/2) /
    points`` (cached per orders and points) and the turn to the fundamental velocity's phase ``φ`` (the
    displacement's when the velocity is zero)."""
    key = (orders if isinstance(orders, tuple) else tuple(int(o) for o in np.ravel(orders)), points)
    table = _TABLES.get(key)
    if table is None:
        k = np.asarray(key[0], float)
        E0 = np.exp(1j * np.outer(k, 2 * np.pi * (np.arange(points) + 0.5) / points))
        table = _TABLES[key] = (E0, np.ascontiguousarray(np.conj(E0)), k)
    phase = np.angle(V[0]) if V[0] != 0 else np.angle(S[0])
    return (*table, np.exp(-1j * phase * table[2]))


def check_harmonics(who: str, harmonics, points: int = 256) -> int:
    """``harmonics`` (odd orders balanced) as an int >= 1 whose highest order ``2h - 1`` the ``points`` phases
    resolve (8 per its period), else a :class:`~bscomp.errors.UsageError` naming ``who``'s argument."""
    h = check_number(f"{who}: harmonics", harmonics, integer=True, minimum=1)
    if 8 * (2 * h - 1) > points:
        raise UsageError(f"{who}: harmonics={h} balances orders up to {2 * h - 1}, which points={points} phases do "
                         f"not resolve (at least 8 per period of the highest): harmonics <= {(points // 8 + 1) // 2} "
                         f"at {points} points")
    return h


_MAPPED = {}


def _mapped(law, points, tangent=False):
    key = (id(law), points, tangent)
    F = _MAPPED.get(key)
    if F is None or F[0] is not law:
        if len(_MAPPED) >= 64:              # laws of models no longer in use: drop them
            _MAPPED.clear()
        F = _MAPPED[key] = (law, _vectorised(law, points, tangent))
    return F[1]


def _vectorised(law, points, tangent=False):
    """``(s[points], v[points], p) -> f[points]`` (with ``tangent`` also ``df/ds``, ``df/dv``) as one SX Function
    called through its buffer (a plain ``law.map`` call from Python costs ~0.1 ms in conversions; this ~10 us).
    A law that does not expand to SX: the mapped call (its tangent: None)."""
    try:
        s, v = ca.SX.sym("s"), ca.SX.sym("v")
        P = ca.SX.sym("p", law.size1_in(2), law.size2_in(2))
        f = law(s, v, P)
        outs = [f, ca.jacobian(f, s), ca.jacobian(f, v)] if tangent else [f]
        one = ca.Function(f"{law.name()}_{'tangent' if tangent else 'value'}", [s, v, P], outs)
        S, V = ca.SX.sym("s", 1, points), ca.SX.sym("v", 1, points)
        res = one.map(points)(S, V, P)
        return NumpyCall(ca.Function(f"{one.name()}_phases", [S, V, P], list(res) if tangent else [res]))
    except RuntimeError:
        return None if tangent else law.map(points)


class HarmonicBalance:
    r"""The elements' side of the first-harmonic balance, shared by :func:`describing_frf` and
    :meth:`bscomp.simulation.compiled.CompiledModel.frf` (``amplitude=``).

    At one frequency the linear part is a complex map ``T`` (rows ``s_1, v_1, ..., s_n, v_n`` and then the
    outputs; columns the excitation ``U`` and the corrections ``ĝ_1 .. ĝ_n``); the balance is
    ``ĝ = F̂(Ŝ, V̂) - k_0 Ŝ - d_0 V̂`` with ``F̂`` the first harmonic of each element's law about its rest point
    ``(s_0, v_0)`` (:func:`first_harmonic`) and ``(k_0, d_0)`` the tangent the linear part already holds.

    Parameters
    ----------
    laws : list of casadi.Function
        ``(s, v, p) -> f`` per element.
    pvecs : list of array_like
        Each law's parameter vector.
    s0, v0, k0, d0 : array_like
        Rest point and the linear part's slopes per element.
    points : int
        Phases per first harmonic (a multiple of 4).
    """

    #: The Newton's Jacobian from the laws' tangents (:meth:`jacobian`); False: forward differences, 1 + 2 x
    #: (orders x elements) residuals a step (``benchmarks/bench_diagnose.py`` times both).
    exact = True

    def __init__(self, laws, pvecs, s0, v0, k0, d0, points=256, harmonics=1):
        self.laws, self.pvecs = list(laws), [np.asarray(p, float) for p in pvecs]
        self.s0, self.v0, self.k0, self.d0 = (np.asarray(a, float).ravel() for a in (s0, v0, k0, d0))
        self.n, self.points = len(self.laws), int(points)
        self.orders = tuple(range(1, 2 * int(harmonics), 2))        # 1, 3, 5, ...

    def residual(self, g, Ts, U):
        """``(r, scale, S, V)``: the balance's residual per harmonic and element at corrections ``g`` (complex,
        ``(harmonics, n)``), ``Ts`` the linear map at each harmonic's frequency (the excitation drives the first)."""
        nh = len(Ts)                             # the first len(Ts) orders (the first alone: the continuation)
        S, V = self._motion(g, Ts, U)
        F = np.column_stack([odd_harmonics(law, pv, self.s0[i], self.v0[i], S[:, i], V[:, i], self.orders[:nh],
                                           self.points) for i, (law, pv) in enumerate(zip(self.laws, self.pvecs))])
        return (*self._close(g, F, S, V), S, V)

    def _motion(self, g, Ts, U):
        """``(S, V)`` (orders, elements): the elements' motion and velocity phasors ``T [U; ĝ]`` per order."""
        n = self.n
        S, V = np.empty((len(Ts), n), complex), np.empty((len(Ts), n), complex)
        for k, T in enumerate(Ts):
            y = T[:2 * n, 1:] @ g[k] + (T[:2 * n, 0] * U if k == 0 else 0.0)
            S[k], V[k] = y[0::2], y[1::2]
        return S, V

    def _close(self, g, F, S, V):
        """``(r, scale)``: ``r = ĝ - (F̂ - k_0 Ŝ - d_0 V̂)`` and the largest of its terms."""
        tangent = self.k0 * S + self.d0 * V
        return g - (F - tangent), max(np.abs(F).max(), np.abs(tangent).max(), np.abs(g).max(), 1e-300)

    def jacobian(self, g, Ts, U):
        """``(r, scale, J)``: :meth:`residual` and its exact Jacobian in the real unknowns ``[Re ĝ; Im ĝ]`` (rows
        ``[Re r; Im r]``), from each law's tangent at the phases (:func:`odd_harmonics_tangent`); ``None`` when a law
        has no SX tangent."""
        n, nh = self.n, len(Ts)
        As = [T[:2 * n:2, 1:] for T in Ts]            # S_k = As_k g_k + ..., V_k = Av_k g_k + ...
        Av = [T[1:2 * n:2, 1:] for T in Ts]
        S, V = self._motion(g, Ts, U)
        m = nh * n
        Jr = np.zeros((m, m), complex)                # d r / d Re g and d r / d Im g (complex rows)
        Ji = np.zeros((m, m), complex)
        F = np.empty((nh, n), complex)
        for i, (law, pv) in enumerate(zip(self.laws, self.pvecs, strict=True)):
            out = odd_harmonics_tangent(law, pv, self.s0[i], self.v0[i], S[:, i], V[:, i], self.orders[:nh],
                                        self.points)
            if out is None:
                return None
            F[:, i], dF = out
            rows = np.arange(nh) * n + i
            for l_ in range(nh):
                a, b = As[l_][i], Av[l_][i]           # (n,) over the corrections of order l
                cols = l_ * n + np.arange(n)
                dS_, dIS, dV_, dIV = (dF[:, q * nh + l_][:, None] for q in range(4))
                Jr[np.ix_(rows, cols)] -= dS_ * a.real + dIS * a.imag + dV_ * b.real + dIV * b.imag
                Ji[np.ix_(rows, cols)] -= -dS_ * a.imag + dIS * a.real - dV_ * b.imag + dIV * b.real
            for k in range(nh):                      # the tangent the linear part holds, k0 S + d0 V
                cols = k * n + np.arange(n)
                lin = self.k0[i] * As[k][i] + self.d0[i] * Av[k][i]
                Jr[k * n + i, cols] += lin
                Ji[k * n + i, cols] += 1j * lin
        Jr += np.eye(m)
        Ji += 1j * np.eye(m)
        return (*self._close(g, F, S, V), np.block([[Jr.real, Ji.real], [Jr.imag, Ji.imag]]))

    def solve(self, Ts, U, g0, tol, max_iter=40):
        """Damped Newton on the real and imaginary parts of ``ĝ`` (the exact Jacobian of :meth:`jacobian`; forward
        differences for a law without an SX tangent): ``(g, rel)``."""
        g = np.array(g0, complex)
        shape, m = g.shape, g.size
        r, scale, *_ = self.residual(g, Ts, U)

        def real(c):
            return np.concatenate((c.real.ravel(), c.imag.ravel()))

        def cplx(x):
            return (x[:m] + 1j * x[m:]).reshape(shape)

        for _ in range(max_iter):
            if np.abs(r).max() <= tol * scale:
                break
            x = real(g)
            exact = self.jacobian(g, Ts, U) if self.exact else None
            if exact is not None:
                J = exact[2]
            else:                                          # a law without an SX tangent: forward differences
                J = np.empty((x.size, x.size))
                for k in range(x.size):
                    h = 1e-7 * max(abs(x[k]), scale)
                    xk = x.copy()
                    xk[k] += h
                    J[:, k] = (real(self.residual(cplx(xk), Ts, U)[0]) - real(r)) / h
            try:
                dx = np.linalg.solve(J, -real(r))
            except np.linalg.LinAlgError:
                break
            norm0, alpha = np.abs(r).max(), 1.0
            while alpha > 1e-3:                            # backtracking: the residual must fall
                gn = cplx(x + alpha * dx)
                rn, sn, *_ = self.residual(gn, Ts, U)
                if np.abs(rn).max() < (1 - alpha / 4) * norm0:
                    break
                alpha /= 2
            else:
                break
            g, r, scale = gn, rn, sn
        return g, float(np.abs(r).max() / scale)

    def sweep(self, freqs, maps, U, tol):
        """Balance at every frequency in ascending order, each started from the last one's solution (from the
        linear response up an amplitude ladder where that fails; with higher harmonics, from the first-harmonic
        balance at that frequency). Returns ``(Y, S, V, rel)``: the outputs' rows of ``T [U; ĝ]`` at the
        fundamental, the elements' fundamental motion and velocity phasors and the relative residual per
        frequency. ``maps(i, k)`` is ``T`` at ``k`` times ``freqs[i]``. ``self.used`` holds the orders balanced
        per frequency: where adding an order does not converge, the balance of the orders below it is kept;
        ``self.deviation`` (nf, n) how far each element's fundamental force is from its tangent at rest,
        ``|F̂_1 - k_0 Ŝ - d_0 V̂| / max(|F̂_1|, |k_0 Ŝ + d_0 V̂|)`` (0: the element acts as its linearization at rest,
        friction stuck or a clearance that stays open or closed; about 1: it slides or impacts)."""
        f = np.asarray(freqs, float)
        n, nf, nh = self.n, f.size, len(self.orders)
        Y, S_all, V_all, rel_all = None, np.zeros((nf, n), complex), np.zeros((nf, n), complex), np.zeros(nf)
        self.used = np.full(nf, nh)
        self.deviation = np.zeros((nf, n))
        g = np.zeros((nh, n), complex)
        for i in np.argsort(f, kind="stable"):
            Ts = [maps(i, k) for k in self.orders]
            g, rel = self.solve(Ts, U, g, tol)
            if not rel <= tol:                        # continuation in the amplitude from the linear response
                g1 = np.zeros((1, n), complex)
                for a in AMPLITUDE_LADDER:
                    g1, rel = self.solve(Ts[:1], a * U, g1, tol)
                g = np.zeros((nh, n), complex)
                g[0] = g1[0]
                self.used[i] = 1
                for m in range(2, nh + 1):            # then the higher harmonics, one more order at a time
                    gm, rel_m = self.solve(Ts[:m], U, g[:m], tol)
                    if not rel_m <= tol and rel <= tol:
                        break                         # keep the converged balance of the orders below
                    g[:m], rel, self.used[i] = gm, rel_m, m
            _, _, S, V = self.residual(g, Ts, U)
            T = Ts[0]
            y = T[2 * n:, 0] * U + T[2 * n:, 1:] @ g[0]
            if Y is None:
                Y = np.zeros((nf, y.size), complex)
            Y[i], S_all[i], V_all[i], rel_all[i] = y, S[0], V[0], rel
            tangent = self.k0 * S[0] + self.d0 * V[0]          # at the solution F̂_1 = ĝ_1 + tangent
            self.deviation[i] = np.abs(g[0]) / np.maximum(np.maximum(np.abs(g[0] + tangent), np.abs(tangent)),
                                                          1e-300)
        return Y, S_all, V_all, rel_all
