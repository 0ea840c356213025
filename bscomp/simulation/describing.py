r"""Describing-function FRF: the first-harmonic balance of a drive with friction and backlash at an excitation
amplitude, a few milliseconds per frequency.

:func:`~bscomp.simulation.stepped.stepped_sine` measures the FRF at an amplitude by simulating every frequency
until the response is periodic (~0.2 s per frequency on the test bed). The classical shortcut of the field is
the *describing function* (harmonic balance with one harmonic): every nonlinear element is assumed to move
sinusoidally about its rest point, ``s(θ) = s_0 + Re(Ŝ e^{jθ})``, ``v(θ) = v_0 + Re(V̂ e^{jθ})``, and only the
first harmonic of its force is kept,

.. math:: \hat F = \frac{1}{\pi}\int_0^{2\pi} f\big(s(θ), v(θ)\big)\, e^{-jθ}\, dθ .

For Coulomb friction ``f = F_c sign(v)`` this is ``F̂ = (4 F_c / π) V̂ / |V̂|``; for a clearance ``b`` with contact
stiffness ``c`` (a dead zone, thesis Eq 5.8) ``F̂ = c (1 - (2/π)(asin β + β sqrt(1 - β²))) Ŝ``,
``β = b / (2 |Ŝ|)`` (``tests/bscomp/test_describing.py`` checks both). Here the integral is taken numerically,
at ``points`` phases, on the element's own law (Eq 5.7 friction, the contact law of Eq 5.8-5.9), so any
element ``method="modal"`` can cut works.

The rest of the drive is linear. With every element's tangent at rest ``(k_0, d_0)`` in the linear part (the
:class:`~bscomp.simulation.modal_channels.LinearPart` that ``method="modal"`` integrates; the corrections
``g = f - k_0 s - d_0 v`` are its force inputs) the phasors obey

.. math:: jω X = A X + B Û + E ĝ, \qquad [Ŝ;\ V̂;\ Ŷ] = C (jω - A)^{-1} (B Û + E ĝ) + D_u Û + D_g ĝ ,

so at each frequency the balance ``ĝ = F̂(Ŝ, V̂) - k_0 Ŝ - d_0 V̂`` is a damped Newton solve in as many complex
unknowns as there are elements, and ``H = Ŷ / Û``. ``(jω - A)^{-1}`` comes from one eigen-decomposition of
``A`` (a direct solve per frequency when the eigenvectors are ill-conditioned).

Limits (``docs/nonlinear.md``, "Describing-function FRF", measures them against the stepped sine): one
harmonic by default -- where friction sticks for part of each period, or a body rattles in a clearance, the
motion is not sinusoidal and the result is an approximation (the distortion :func:`stepped_sine` reports says
how far); ``harmonics=h`` balances the odd orders up to ``2h - 1`` as well (a harmonic balance: on the test bed
sticking and slipping at 2 V, 20 Hz, rotor.w 18 % -> 0.3 % off the settled stepped sine with ``h = 5``); one
solution -- the Newton solve starts from the previous frequency's, so of several coexisting responses (the
jump of a softening resonance) the one continued from low frequency is taken; no bias -- the elements
oscillate about their rest point (``offset`` is not supported: use :func:`stepped_sine`); a moving joint is
held at its start position by its tangent there, as :func:`bscomp.frf` does.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.linalg as sla

from bscomp.errors import (
    BscompError,
    ModelLimitationWarning,
    UnknownNameError,
    UsageError,
    check_number,
)
from bscomp.linear.response import Frf
from bscomp.model import as_dae, run_overrides
from bscomp.simulation.harmonic_balance import HarmonicBalance, check_harmonics, first_harmonic
from bscomp.simulation.modal_channels import Channels, LinearPart
from bscomp.simulation.stepped import check_sine_request

__all__ = ["describing_frf", "DescribingFrf", "DescribingFunctionError", "first_harmonic", "HarmonicBalance", "spans",
           "frequency_share", "SMALL_SIGNAL"]

#: eigenvector condition number above which the resolvent is solved directly per frequency
COND_MAX = 1e8
#: an element whose fundamental force is within this fraction of its tangent at rest acts as its linearization
SMALL_SIGNAL = 0.05


class DescribingFunctionError(BscompError):
    """The model has a nonlinearity the describing function does not treat (outside the friction and backlash
    elements), or no nonlinear element at all."""


@dataclass
class DescribingFrf(Frf):
    """A describing-function FRF (:func:`describing_frf`): :class:`~bscomp.linear.Frf` with ``H[freq, output, 0]``
    plus

    Attributes
    ----------
    amplitude : float
        Excitation amplitude (the input's unit).
    elements : list of str
        The nonlinear elements balanced (friction, backlash).
    motion : (nf, n_el) complex ndarray
        The first harmonic ``Ŝ`` of each element's relative displacement [m].
    velocity : (nf, n_el) complex ndarray
        ... and of its relative velocity ``V̂`` [m/s].
    residual : (nf,) ndarray
        ``max |ĝ - F̂ + k_0 Ŝ + d_0 V̂|`` at the solution over the elements' force scale.
    harmonics : int
        Odd harmonics balanced (1: the describing function; ``h``: the orders 1, 3, ..., ``2h - 1``).
    deviation : (nf, n_el) ndarray
        How far each element's fundamental force is from its tangent at rest, ``|F̂_1 - k_0 Ŝ - d_0 V̂| /
        max(|F̂_1|, |k_0 Ŝ + d_0 V̂|)``: below :data:`SMALL_SIGNAL` the element acts as its linearization at rest
        (friction stuck, a clearance that stays open or closed), so the FRF there measures its slope at rest
        (for regularised Coulomb friction ``F_c / v_reg``), not its level; about 1 where it slides or impacts.
        For ``tanh`` friction it is ``(|V̂| / v_reg)^2 / 4`` for small ``|V̂|``.
    """

    amplitude: float = 0.0
    elements: list = field(default_factory=list)
    motion: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), complex))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), complex))
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    harmonics: int = 1
    deviation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def small_signal(self) -> dict:
        """Element -> the frequencies [Hz] at which it acts as its tangent at rest (``deviation`` below
        :data:`SMALL_SIGNAL`): there this amplitude does not move it out of its small-signal range."""
        out = {}
        for j, name in enumerate(self.elements):
            quiet = self.deviation[:, j] < SMALL_SIGNAL if self.deviation.size else np.zeros(0, bool)
            if quiet.any():
                out[name] = self.freqs[quiet]
        return out

    def summary(self) -> str:
        """One line: the amplitude, the elements, the harmonics, the largest residual and the elements that stay
        in their small-signal range (:meth:`small_signal`)."""
        kept = "one harmonic" if self.harmonics == 1 else f"odd harmonics up to {2 * self.harmonics - 1}"
        line = (f"describing function at {self.amplitude:g} of {', '.join(self.elements)} ({kept}; largest "
                f"balance residual {self.residual.max(initial=0.0):.1e}; stepped_sine for every harmonic)")
        for name, f in self.small_signal().items():
            line += (f"; {name} stays within {100 * SMALL_SIGNAL:g} % of its tangent at rest "
                     f"{frequency_share(self.freqs, f)}: there this amplitude measures its slope at rest (friction "
                     "stuck, a clearance not crossed), not its level")
        return line


def frequency_share(freqs, chosen) -> str:
    """``"at every frequency"`` or ``"at 13 of 14 frequencies (10-25.14, 39.85-200 Hz)"`` (:func:`spans`)."""
    n, m = np.size(freqs), np.size(chosen)
    return "at every frequency" if m == n else f"at {m} of {n} frequencies ({spans(freqs, chosen)} Hz)"


def spans(freqs, chosen) -> str:
    """``"10-25.1, 39.8-200"``: the runs of consecutive frequencies (in ascending order) that are in ``chosen``."""
    f = np.sort(np.asarray(freqs, float))
    inside = np.isin(f, chosen)
    runs, start = [], None
    for i, x in enumerate(inside):
        if x and start is None:
            start = i
        if start is not None and (not x or i == f.size - 1):
            end = i if x else i - 1
            runs.append(f"{f[start]:.4g}" if end == start else f"{f[start]:.4g}-{f[end]:.4g}")
            start = None
    return ", ".join(runs)


class _Balance(HarmonicBalance):
    """The linear maps ``ĝ -> (Ŝ, V̂, Ŷ)`` per frequency of a flattened model (module docstring)."""

    def __init__(self, dae, p, input, outs, points, harmonics=1):
        ch = Channels(dae, p)
        if not ch.elements:
            moving = (f"; its moving joints {[j.path for j in ch.joints]} change with the position, not the "
                      "amplitude: bscomp.frf at each position (position_sweep), or bscomp.stepped_sine"
                      if ch.joints else ": its FRF is the same at every amplitude (use bscomp.frf)")
            raise DescribingFunctionError(f"'{dae.name}' has no friction or backlash element{moving}")
        y0 = ch.el_rows[0]
        super().__init__([el.law for el in ch.elements], [el.pvec for el in ch.elements], y0[0::2], y0[1::2],
                         [r[2] for r in ch.rest], [r[3] for r in ch.rest], points, harmonics)
        self.ch = ch
        self.names = [el.path for el in ch.elements]
        lin = LinearPart(ch, [tuple(r[2:4]) for r in ch.rest], [jt.z0 for jt in ch.joints])
        self.lin = lin
        A, B, E, _, Zx, Zu, Zg, _ = lin.explicit()
        n = len(ch.elements)
        iu = dae.u_names.index(input)
        cols = np.column_stack([B[:, iu], E[:, :n]])             # [u, g_1 .. g_n]
        zcols = np.column_stack([Zu[:, iu], Zg[:, :n]])
        _, Ryd, Ry, Rz, Ru = ch.el_rows
        Oyd, Oy, Oz, Ou = _output_rows(dae, outs, ch, p)
        Ryd, Ry, Rz = (np.vstack([a, b]) for a, b in ((Ryd, Oyd), (Ry, Oy), (Rz, Oz)))
        Ru = np.vstack([Ru, Ou])[:, iu]
        # y = Ryd x' + Ry x + Rz z + Ru u, x' = A X + cols w, z = Zx X + zcols w, w = [U; ĝ]
        self.C = Ryd @ A + Ry + (Rz @ Zx if dae.nz else 0.0)
        self.D = Ryd @ cols + (Rz @ zcols if dae.nz else 0.0)
        self.D[:, 0] += Ru
        self.A, self.cols = A, cols
        lam, V = sla.eig(A)
        self.direct = not np.all(np.isfinite(V)) or np.linalg.cond(V) > COND_MAX
        if not self.direct:
            self.lam, self.CV, self.W = lam, self.C @ V, np.linalg.solve(V, cols)

    def maps(self, f_hz):
        """``T`` at ``f_hz`` [Hz] (rows: s_1, v_1, ..., outputs; columns: U, ĝ_1, ...)."""
        w = 2 * np.pi * f_hz
        if self.direct:
            X = np.linalg.solve(1j * w * np.eye(self.A.shape[0]) - self.A, self.cols)
            return self.C @ X + self.D
        return self.CV @ (self.W / (1j * w - self.lam)[:, None]) + self.D


def _output_rows(dae, outs, ch, p):
    """``(Jxd, Jx, Jz, Ju)`` of the outputs at the start point; an output that is nonlinear in the states (an
    element's force) is taken by its tangent there, with a warning."""
    y = dae.output_expr(outs)
    args = [dae.xds, dae.xs, dae.zs, dae.us]
    jac = [ca.jacobian(y, a) for a in args]
    bad = [o for i, o in enumerate(outs)
           if any(ca.depends_on(J[i, :], ca.vertcat(*args)) for J in jac if J.numel())]
    if bad:
        warnings.warn(f"describing_frf on '{dae.name}': outputs {bad} are nonlinear in the states; their tangent at "
                      "the start point is used (the first harmonic of a nonlinear output needs stepped_sine)",
                      ModelLimitationWarning, stacklevel=4)
    f = ca.Function("orows", [*args, dae.ps], jac)
    vals = f(np.zeros(dae.nx), ch.x_a, ch.z_a, np.zeros(dae.nu), p)
    return [np.asarray(ca.DM(v).full(), float) for v in vals]


def _check_channels(bal, dae, iu, amplitude):
    """The linear part plus the element corrections is the model at the input's extremes
    (:meth:`~bscomp.simulation.modal_channels.LinearPart.outside`): else DescribingFunctionError naming the
    equation."""
    u = np.zeros((3, dae.nu))
    u[0, iu], u[1, iu] = -amplitude, amplitude
    bad = bal.lin.outside(*u)
    if bad is not None:
        origin, err, scale = bad
        raise DescribingFunctionError(
            f"'{dae.name}': equation '{origin}' is nonlinear outside the friction/backlash elements the "
            f"describing function balances (residual {err:.2g} of {scale:.2g} at input amplitude {amplitude:g}, "
            "e.g. an amplifier current limit): use bscomp.stepped_sine")


def _check(input, output, freqs, amplitude, points, tol, harmonics):
    outs, f = check_sine_request("describing_frf", input, output, freqs, amplitude)
    check_number("points", points, integer=True, minimum=16)
    if points % 4:
        raise UsageError(f"describing_frf: points must be a multiple of 4 (a velocity reversal between two phases), "
                         f"got {points}")
    check_number("tol", tol, positive=True)
    check_harmonics("describing_frf", harmonics, points)
    return list(outs), f


def describing_frf(model, input: str, output, freqs, amplitude: float, *, params: dict | None = None,
                   points: int = 256, tol: float = 1e-8, harmonics: int = 1) -> DescribingFrf:
    """Frequency response of ``output`` to a sine of amplitude ``amplitude`` on ``input`` by the describing
    function of every friction and backlash element (module docstring): the fast, one-harmonic estimate of what
    :func:`~bscomp.simulation.stepped.stepped_sine` simulates.

    Parameters
    ----------
    model : str, path, System, Dae or ModelSpec
        Anything :func:`bscomp.simulate` takes (flattened from a System: the elements are its components).
    input : str
        The driven input (``"amp.u"``, ``"motor.tau"``...).
    output : str or list of str
        Observables (``"table.a"``...), linear in the states.
    freqs : array_like
        Frequencies [Hz]; solved in ascending order, each from the last one's solution.
    amplitude : float
        Sine amplitude in the input's unit.
    params : dict, optional
        Parameter overrides.
    points : int
        Phases at which each element's law is evaluated per first harmonic.
    tol : float
        Newton's residual relative to the elements' force scale.
    harmonics : int
        Odd harmonics balanced: 1 is the describing function; ``h`` balances the orders 1, 3, ..., ``2h - 1`` of
        every element's motion and force (the linear part at each order's frequency), and ``H`` is still the
        fundamental's ratio, as the stepped sine measures it. Where the drive sticks and slips the higher
        orders carry the distortion (``docs/nonlinear.md``, "Describing-function FRF").

    Returns
    -------
    DescribingFrf
        ``H[freq, output, 0]``, the elements' first harmonics ``motion``/``velocity`` and the ``residual``.

    Raises
    ------
    UsageError, ArgumentTypeError
        Bad frequencies, amplitude or counts (named).
    UnknownNameError
        ``input`` is not an input of the model, or an output is not a signal of it (a parameter, a constant).
    DescribingFunctionError
        No friction/backlash element, or a nonlinearity outside them.
    """
    outs, f = _check(input, output, freqs, amplitude, points, tol, harmonics)
    dae = as_dae(model, params)
    if input not in dae.u_names:
        raise UnknownNameError(f"describing_frf: '{input}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
    dae.require_signals(outs, "describing_frf")
    p = dae.parameter_vector(run_overrides(model, dae, params))
    bal = _Balance(dae, p, input, outs, points, harmonics)
    _check_channels(bal, dae, dae.u_names.index(input), float(amplitude))
    Y, S_all, V_all, res = bal.sweep(f, lambda i, k=1: bal.maps(k * f[i]), float(amplitude), tol)
    H = (Y / amplitude)[:, :, None]
    bad = ~(res <= 10 * tol)
    H[bad] = np.nan                     # a balance that did not converge gives no number, not a wrong one
    failed = [float(x) for x in f[bad]]
    notes = [f"describing function of {bal.names}, {input} = {amplitude:g} sin(2 pi f t), {points} phases"
             + (f", odd harmonics up to {2 * harmonics - 1} balanced" if harmonics > 1 else "")]
    if bal.ch.joints:
        notes.append(f"moving joints {[j.path for j in bal.ch.joints]} held at their start position (tangent)")
    fewer = [(float(x), 2 * int(m) - 1) for x, m in zip(f, bal.used, strict=True) if m < harmonics and x not in failed]
    if fewer:
        warnings.warn(f"describing_frf on '{dae.name}': the balance with the odd orders up to {2 * harmonics - 1} did "
                      f"not converge at {[x for x, _ in fewer][:6]} Hz; there H is the balance of the orders up to "
                      f"{sorted({o for _, o in fewer})} (Hz, order): {fewer[:6]}", ModelLimitationWarning, stacklevel=2)
        notes.append(f"fewer orders balanced at {fewer}")
    if failed:
        warnings.warn(f"describing_frf on '{dae.name}': the harmonic balance did not converge at {failed[:6]} Hz "
                      f"(residual above {10 * tol:g}): H is NaN there; use stepped_sine", ModelLimitationWarning,
                      stacklevel=2)
        notes.append(f"not converged at {failed} Hz")
    return DescribingFrf(freqs=f, H=H, inputs=[input], outputs=outs, name=dae.name, notes=notes,
                         amplitude=float(amplitude), elements=bal.names, motion=S_all, velocity=V_all, residual=res,
                         harmonics=int(harmonics), deviation=np.where(bad[:, None], np.nan, bal.deviation))
