r"""One step of ``simulate(method="modal")``: exact exponential of the modal linear part, the channel forces
first-order held between the step's ends and solved implicitly, checked at three interior points.

With modal coordinates ``ξ' = λ ξ + B_u u + B_g g + b_c`` (:class:`bscomp.simulation.modal_parts.ModalPart`), the input
held over the step and the channel forces ``g(t) = g_0 + (g_1 - g_0) t/τ``, the step is exact per mode:

.. math::
    ξ(θτ) = e^{λθτ} ξ_0 + φ_1(θτ)\,(B_u u + b_c + B_g g_0) + θ\,φ_2(θτ)\,B_g (g_1 - g_0), \qquad
    φ_1(τ) = \frac{e^{λτ} - 1}{λ}, \quad φ_2(τ) = \frac{e^{λτ} - 1 - λτ}{λ^2 τ},

and the channel coordinates are rows of it, ``y(θ) = Re(C_ξ ξ(θτ)) + D_u u + D_g g(θτ) + y_c``. At the end
(``θ = 1``) ``y_1 = c + H g_1``, so ``g_1 = law(y_1)`` is a Newton (or chord) solve in the few channel forces
only. The linear structure is exact for any step; the force's linear interpolation (trapezoidal: second order,
A-stable) is checked at ``θ = 1/4, 1/2, 3/4`` (the elements' rows at the quarter points, every channel at the
midpoint): the error ``max_j |law(y(θ_j)) - g(θ_j τ)|`` must stay below the tolerance times the largest
channel force so far (:data:`~bscomp.simulation.modal_kernels.FORCE_FLOOR`), or the driver redoes the step in
four (:mod:`bscomp.simulation.modal_driver`). A clearance's or contact's displacement is also checked at its
extrema between the points (cubic Hermite of ``s`` and ``v``:
:meth:`~bscomp.simulation.modal_kernels.Kernel.extremum_function`), so a bounce shorter than a quarter step is
seen. This module
computes the matrices of those formulas per sub-step length (:class:`StepData`); the compiled kernel
(:mod:`bscomp.simulation.modal_kernels`) evaluates them.
"""

from __future__ import annotations

import numpy as np

from bscomp.simulation.modal_kernels import pack_step

__all__ = ["phis", "StepData", "Stepper", "ModalHistory", "block"]

THETAS = (0.25, 0.5, 0.75)
NEWTON_TOL = 1e-9    # last Newton update relative to 1 + max |g| accepted as converged


def phis(lam, tau):
    """``(e^{λτ}, φ_1, φ_2)`` per mode (series near ``λτ = 0``: rigid-body modes, a zero length). ``lam`` and
    ``tau`` broadcast (a row of modes against a column of lengths gives every length at once)."""
    x = lam * tau
    E = np.exp(x)
    small = np.abs(x) < 1e-4
    safe = np.where(small, 1.0, lam)
    xs = np.where(small, 1.0, x)
    phi1 = np.where(small, tau * (1 + x / 2 + x * x / 6), (E - 1) / safe)
    phi2 = np.where(small, tau * (0.5 + x / 6 + x * x / 24), (E - 1 - x) / (safe * xs))
    return E, phi1, phi2


class StepData:
    """The matrices of one step length for one modal part and channel set (module docstring).

    ``ξ_1 = E ξ_0 + Q_u u + q_c + Q_0 g_0 + Q_1 g_1``; at ``θ`` (1 = the end)
    ``y(θ) = Re(C_E(θ) ξ_0) + Y_u(θ) u + Y_0(θ) g_0 + Y_1(θ) g_1 + y_c(θ)``.
    """

    def __init__(self, mp, rows, gsel, tau, thetas=THETAS):
        Cxi, Du, Dg, yc = rows
        Bg = mp.Bg[:, gsel]
        Dg = Dg[:, gsel]
        lam = mp.lam
        E, p1, p2 = phis(lam, tau)
        self.tau = tau
        self.E = E
        self.Qu, self.qc = p1[:, None] * mp.Bu, p1 * mp.bc
        self.Q0, self.Q1 = (p1 - p2)[:, None] * Bg, p2[:, None] * Bg
        pts = at_points(np.r_[1.0, thetas, 0.0], lam, tau, Cxi, Du, Dg, yc, mp.Bu, Bg, mp.bc)
        self.end = pts[0]
        self.samples = pts[1:-1]
        self.start = pts[-1]                   # the channels at the step's start
        self.thetas = tuple(thetas)


def at_points(theta, lam, tau, Cxi, Du, Dg, yc, Bu, Bg, bc):
    """``[(C_E, Y_u, Y_0, Y_1, y_c)]`` at each fraction ``θ`` of a step of length ``τ`` (rows ``Cxi`` of the channel
    coordinates): the step's formula evaluated at all points at once (one ``phis`` and batched products)."""
    theta = np.asarray(theta, float)
    E, p1, p2 = phis(lam[None, :], theta[:, None] * tau)          # (points, m)
    CE = Cxi[None, :, :] * E[:, None, :]
    A1 = Cxi[None, :, :] * p1[:, None, :]
    Yu = (A1 @ Bu).real + Du
    yct = (A1 @ bc).real + yc
    Y0 = (Cxi[None, :, :] * (p1 - theta[:, None] * p2)[:, None, :] @ Bg).real + (1 - theta)[:, None, None] * Dg
    Y1 = (Cxi[None, :, :] * (theta[:, None] * p2)[:, None, :] @ Bg).real + theta[:, None, None] * Dg
    return [(CE[k], Yu[k], Y0[k], Y1[k], yct[k]) for k in range(theta.size)]


class Stepper:
    """One modal part with one channel set: its step data per sub-step length, its compiled kernel, and the
    few numpy operations the driver does between kernel calls (consistent forces, channel values).

    Parameters
    ----------
    mp : ModalPart
    rows : tuple
        ``(Cxi, Du, Dg, yc)`` of the measured channel coordinates.
    gsel : ndarray of int
        Columns of ``Bg`` of the active channel forces (the others are zero).
    theta : ndarray
        Packed numbers of the law.
    kernel : Kernel
        The compiled steps of this shape; its :meth:`~bscomp.simulation.modal_kernels.Kernel.law_call` is the law
        called from numpy here.
    """

    def __init__(self, mp, rows, gsel, theta, kernel):
        self.mp, self.rows, self.theta, self.kernel = mp, rows, theta, kernel
        self._law = kernel.law_call()
        self.gsel = np.asarray(gsel, int)
        self.r = self.gsel.size
        self.m = kernel.m                    # modal coordinates of the kernel (>= the part's: padded)
        self.m_part = mp.lam.size
        self._data = {}
        self._last_tau = self._last_data = None
        self._packed = np.zeros(2 * self.m + self.r)

    def data(self, tau):
        """``(StepData, packed vector)`` for a sub-step length (cached)."""
        if tau == self._last_tau:
            return self._last_data
        d = self._data.get(tau)
        if d is None:
            key = round(tau, 16)
            d = self._data.get(key)
        if d is None:
            sd = StepData(self.mp, self.rows, self.gsel, tau)
            d = self._data[key] = (sd, pack_step(sd, self.kernel.ne, self.m))
        self._data[tau] = d
        self._last_tau, self._last_data = tau, d
        return d

    def evaluate(self, y):
        """``(g, dg/dy, fmax, regime_ok, element_ok)`` at channel values ``y``."""
        g, L, fmax, okr, oke = self._law(y, self.theta)
        return g.ravel().copy(), L.copy(), float(fmax[0, 0]), bool(okr[0, 0]), bool(oke[0, 0])

    def consistent(self, xi, u, g):
        """Channel forces consistent with ``xi`` at zero step length (static feedthrough only)."""
        Cxi, Du, Dg, yc = self.rows
        y_free = (Cxi @ xi).real + Du @ u + yc
        return self.newton(y_free, Dg[:, self.gsel], g)

    def newton(self, y_free, H, g):
        """Newton on ``g = law(y_free + H g)``: ``(g, y, last relative update)``, converged when the update relative
        to ``1 + max |g|`` is below :data:`NEWTON_TOL` (one compiled call:
        :meth:`~bscomp.simulation.modal_kernels.Kernel.newton_function`)."""
        g = np.array(g, float)
        if not self.r:
            return g, y_free, 0.0
        g, y, upd = self.kernel.newton_call()(y_free, H, g, self.theta, NEWTON_TOL)
        return g.ravel().copy(), y.ravel().copy(), float(upd[0, 0])

    def pack_state(self, xi, g):
        """The kernel's state ``[Re ξ; 0; Im ξ; 0; g]`` in this stepper's buffer (valid until the next call; a
        kernel call copies it)."""
        x, m, n = self._packed, self.m, self.m_part
        x[:n] = xi.real
        x[m:m + n] = xi.imag
        x[2 * m:] = g
        return x

    def unpack_state(self, x):
        m, n = self.m, self.m_part
        xi = np.empty(n, complex)
        xi.real, xi.imag = x[:n], x[m:m + n]
        return xi, x[2 * m:].copy()

    def end_values(self, xi0, g0, g1, u, tau):
        """Channel values at the end of a step (numpy)."""
        sd, _ = self.data(tau)
        CE, Yu, Y0, H, yct = sd.end
        return (CE @ xi0).real + Yu @ u + Y0 @ g0 + H @ g1 + yct


class ModalHistory:
    """The modal coordinates at the grid points: one complex row per point, as wide as the largest modal part
    stored so far (a point of a part with ``m`` coordinates uses the first ``m`` columns)."""

    def __init__(self, nt, m):
        self.a = np.zeros((nt, m), complex)

    def __len__(self):
        return self.a.shape[0]

    def _fit(self, m):
        if m > self.a.shape[1]:
            self.a = np.hstack([self.a, np.zeros((self.a.shape[0], m - self.a.shape[1]), complex)])

    def put(self, k, xi):
        self._fit(xi.size)
        self.a[k, :xi.size] = xi

    def put_rows(self, k, xs):
        self._fit(xs.shape[1])
        self.a[k:k + len(xs), :xs.shape[1]] = xs

    def block(self, k0, k1, m):
        """Rows ``k0:k1`` in a part of ``m`` coordinates."""
        return self.a[k0:k1, :m]

    def thinned(self, keep):
        out = ModalHistory(0, 0)
        out.a = self.a[keep]
        return out


def block(XI, k0, k1, m):
    """Rows ``k0:k1`` of a :class:`ModalHistory` or of a list of coordinate vectors (m coordinates each)."""
    return XI.block(k0, k1, m) if isinstance(XI, ModalHistory) else np.array(XI[k0:k1])
