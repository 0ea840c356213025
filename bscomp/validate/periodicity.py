r"""Order analysis of a time-series residual: is what the model misses periodic in the motor angle?

A drive's effects tied to the motor angle -- a torque ripple (cogging: the magnets passing the slots), an
eccentric coupling, a lead error of the screw -- repeat a whole number of times per revolution. None of them is a
candidate of :func:`~bscomp.validate.diagnose`, and on the square-wave records a feed drive is tested with they
leave an error that re-calibration cannot remove (the ``ripple`` truth of :mod:`bscomp.systems.truths`: 273x the
noise floor). This module says whether a residual ``e(t)`` holds such a component, and at which order.

**Method.** For each order ``k`` the residual is fitted by least squares with ``cos k phi(t)``, ``sin k phi(t)``
beside a nuisance part -- a slow trend (Legendre polynomials in time to degree :data:`TREND_DEGREE`) and the
residual's :data:`LINES` strongest sinusoids in time (resonances ringing, the input's harmonics: :func:`with_lines`)
-- and the order's *share* :math:`R^2_k` is the fraction of the residual less its nuisance part that the two
columns remove (their amplitude is the joint fit's). For a residual with no component at ``k`` and ``N``
independent samples, :math:`N R^2_k / 2` is close to an exponential. A residual is rarely white (a mis-set mass
leaves a smooth error), so its level is taken locally, from the neighbouring orders ``2 <= |j - k| <=
NEIGHBOURS + 1``: the p-value is the exact tail of ``R^2_k`` over their median under independent exponentials
(:func:`tail`), times the number of orders tested (Bonferroni); a smooth error spreads over many orders and fails
the test, a periodic effect stands out of its neighbours. A component is reported below :data:`ALPHA`, and only
if a sinusoid in time cannot take it (:data:`MIN_OWN`) and the speed varies over the record (:data:`STEADY`): at
one speed an order *is* a sinusoid in time.

Orders are tested from ``k_min`` -- at least 3, and at least :data:`MIN_PERIODS` periods over the angle the
record sweeps (lower orders cannot be told from an error that grows with position) -- to ``k_max`` -- at most
:data:`MAX_ORDER`, and below half the Nyquist limit of the largest angle step between samples -- less the
neighbourhood. Measured on the 14 bundled FE truths (``docs/validation.md``, "An effect outside the library"): the
ripple truths' orders 12 and 9 in ``table.a`` at p 3e-6 and 1e-5 (the residual at the parameters the FRFs alone
give); on the other 12 truths' final residuals nothing below p 1e-3 (at 1e-2 the demo's truth had an order 31
in ``table.s``, p 0.009).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["AngleOrder", "order_spectrum", "periodic_in_angle", "angle_channel", "steady_fraction", "ALPHA"]

TREND_DEGREE = 5     # Legendre degree of the slow trend fitted beside each order
MAX_ORDER = 80       # highest order tested (periods per revolution)
NEIGHBOURS = 10      # orders on each side (beyond the adjacent one) whose median share sets the local level
MIN_PERIODS = 3      # periods of the lowest order tested over the angle the record sweeps
ALPHA = 1e-3         # p-value below which a component is reported (1e-2 called an order 31 on the demo truth)
LINES = 5            # strongest sinusoids in time removed from a residual before its orders are tested
STEADY = 0.5         # largest fraction of the moving samples within 10 % of the median speed (else no claim)
BINS = 24            # bins of the residual folded over one period of the order (the figure)
MIN_OWN = 0.75       # least share of the order's component a sinusoid in time must leave (:func:`_tone_share`)


@dataclass
class AngleOrder:
    """A residual component periodic in an angle: ``order`` periods per revolution of ``angle``.

    ``share``: fraction of the channel's trend-free residual sum of squares it explains; ``amplitude`` in the
    channel's unit; ``p_value``: :mod:`module docstring <bscomp.validate.periodicity>`; ``note``: which model's
    residual (e.g. ``"with the parameters the FRFs alone give"``). For the figure
    (:func:`bscomp.plotting.validate.order_plot`): ``spectrum``, the share of every order ``1..k_max``; ``phase``
    [rad] of the fitted ``amplitude cos(k phi + phase)``; ``folded``, ``[[k phi mod 2 pi, mean residual less its
    nuisance part], ...]`` in :data:`BINS` bins."""

    channel: str
    angle: str
    order: int
    share: float
    p_value: float
    amplitude: float
    unit: str = ""
    note: str = ""
    spectrum: list = field(default_factory=list, repr=False)
    phase: float = 0.0
    folded: list = field(default_factory=list, repr=False)

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        at = f" {self.note}" if self.note else ""
        return (f"the residual of {self.channel}{at} is periodic in {self.angle}: {self.order} periods per revolution "
                f"(amplitude {self.amplitude:.3g}{unit}, {100 * self.share:.1f} % of its variance, "
                f"p {self.p_value:.1g}) -- a torque ripple (cogging), an eccentric or a lead error repeats so")

    def to_dict(self) -> dict:
        return asdict(self)


def _off(Q, X):
    """``X`` less its projection on the orthonormal columns ``Q`` (the nuisance part)."""
    return X - Q @ (Q.T @ X)


def _trend(t, degree):
    span = float(np.ptp(t)) or 1.0
    x = 2.0 * (np.asarray(t, float) - float(np.min(t))) / span - 1.0
    return np.polynomial.legendre.legvander(x, degree)


def order_spectrum(e, phi, t, max_order: int = MAX_ORDER, basis=None):
    """``(R2, coefficients)``: per order ``k = 1..max_order`` the share :math:`R^2_k` of the residual less its
    nuisance part and the complex amplitude ``a - j b`` of ``a cos k phi + b sin k phi`` fitted jointly with the
    nuisance (module docstring). ``basis``: orthonormal columns of the nuisance (default: the slow trend)."""
    e = np.asarray(e, float)
    phi = np.asarray(phi, float)
    Q = np.linalg.qr(_trend(t, TREND_DEGREE))[0] if basis is None else basis
    r0 = _off(Q, e)                                 # the residual less its nuisance part
    ss0 = float(r0 @ r0)
    R2, coef = np.zeros(max_order), np.zeros(max_order, complex)
    if ss0 <= 0.0:
        return R2, coef
    for k in range(1, max_order + 1):
        C = np.column_stack([np.cos(k * phi), np.sin(k * phi)])
        C = _off(Q, C)                              # the two columns, nuisance removed (Frisch-Waugh)
        c, *_ = np.linalg.lstsq(C, r0, rcond=None)
        fit = C @ c
        R2[k - 1] = float(fit @ fit) / ss0
        coef[k - 1] = complex(c[0], -c[1])
    return R2, coef


def _order_range(phi):
    """``(k_min, k_max)`` of the orders the record can resolve (module docstring), or None."""
    sweep = float(np.ptp(phi))
    step = float(np.max(np.abs(np.diff(phi)))) if phi.size > 1 else 0.0
    if sweep <= 0.0 or step <= 0.0:
        return None
    k_min = max(3, math.ceil(MIN_PERIODS * 2.0 * math.pi / sweep))
    k_max = min(MAX_ORDER, int(0.5 * math.pi / step))
    return (k_min, k_max) if k_max - NEIGHBOURS - 1 >= k_min else None


def tail(x: float, n: int) -> float:
    r"""``P(R > x M)`` for ``R`` and ``n`` others iid exponential, ``M`` the ``(n//2 + 1)``-th smallest of the
    others: :math:`\prod_{i=0}^{n//2} (n - i) / (n - i + x)` (an exponential order statistic is a sum of
    independent exponentials of rates ``n - i``). Exact, and robust to a few peaks among the neighbours."""
    return float(np.prod([(n - i) / (n - i + x) for i in range(n // 2 + 1)]))


def steady_fraction(phi, t) -> float:
    """Fraction of the moving samples (speed above 5 % of its largest) within 10 % of their median speed. A
    component periodic in the angle chirps with the speed; at one speed it is a sinusoid in time -- a resonance
    ringing after each reversal of a periodic motion looks the same -- so above :data:`STEADY` no order is
    claimed."""
    moving = _moving_speeds(phi, t)
    if not moving.size:
        return 1.0
    med = float(np.median(moving))
    return float(np.mean(np.abs(moving - med) < 0.1 * med))


def _moving_speeds(phi, t):
    """The angle's speeds |dphi/dt| where it moves (above 5 % of the largest)."""
    w = np.abs(np.gradient(np.asarray(phi, float), np.asarray(t, float)))
    return w[w > 0.05 * w.max()] if w.size and w.max() > 0 else w[:0]


def _best_order(R2, k_min, k_max):
    """``(k, p)`` of the order least likely under no periodic component (module docstring)."""
    tested = k_max - NEIGHBOURS - k_min
    best = (0, 1.0)
    for k in range(k_min, k_max - NEIGHBOURS):
        nb = np.sort([R2[j - 1] for j in range(k - NEIGHBOURS - 1, k + NEIGHBOURS + 2) if abs(j - k) > 1 and j >= 1])
        M = float(nb[nb.size // 2])
        if M > 0.0:
            p = min(1.0, tested * tail(R2[k - 1] / M, nb.size))
            if p < best[1]:
                best = (k, p)
    return best


def with_lines(e, t, Q, n_lines: int = LINES):
    """The nuisance basis ``Q`` (orthonormal) widened by the ``n_lines`` strongest sinusoids in time of the
    residual (each at the periodogram's peak of what the basis leaves): resonances ringing, the input's harmonics.
    A component periodic in the angle of a drive whose speed varies chirps and is not a line; a line is what a
    tone in time is."""
    span, dt = float(np.ptp(t)), float(np.median(np.diff(t)))
    n_fft = 1 << int(np.ceil(np.log2(4 * e.size)))
    for _ in range(n_lines):
        r = _off(Q, e)
        P = np.abs(np.fft.rfft(r, n_fft))
        P[0] = 0.0
        f = np.fft.rfftfreq(n_fft, dt)[int(np.argmax(P))]
        if f < 0.5 / span:
            break
        Q = np.linalg.qr(np.column_stack([Q, np.cos(2.0 * np.pi * f * t), np.sin(2.0 * np.pi * f * t)]))[0]
    return Q


def _tone_share(e, phi, t, k, Q):
    """Share of order ``k``'s component that a sinusoid in *time* cannot take: the order's partial
    :math:`R^2` beside the time frequency closest to its fitted component, over its own :math:`R^2` (near 0
    when the speed hardly varies: a resonance ringing at constant speed is then indistinguishable from an
    order, and none is claimed)."""
    r0 = _off(Q, e)

    def cols(*c):
        C = np.column_stack(c)
        return _off(Q, C)

    def rss(C):
        c, *_ = np.linalg.lstsq(C, r0, rcond=None)
        r = r0 - C @ c
        return float(r @ r)

    Ck = cols(np.cos(k * phi), np.sin(k * phi))
    c, *_ = np.linalg.lstsq(Ck, r0, rcond=None)
    yk = Ck @ c
    span = float(np.ptp(t))
    moving = _moving_speeds(phi, t)
    fs = np.arange(max(k * moving.min() / (2.0 * np.pi), 0.5 / span), k * moving.max() / (2.0 * np.pi), 0.5 / span)
    best, f_best = -1.0, fs[0]
    for i in range(0, fs.size, 256):                  # the time frequency that best carries the order's component
        arg = 2.0 * np.pi * np.outer(t, fs[i:i + 256])
        C, S = np.cos(arg), np.sin(arg)
        C, S = _off(Q, C), _off(Q, S)
        cc, ss, cs = (np.einsum("ij,ij->j", a, b) for a, b in ((C, C), (S, S), (C, S)))
        ce, se = C.T @ yk, S.T @ yk
        fit = (ss * ce * ce - 2.0 * cs * ce * se + cc * se * se) / np.maximum(cc * ss - cs * cs, 1e-300)
        j = int(np.argmax(fit))
        if fit[j] > best:
            best, f_best = float(fit[j]), float(fs[i + j])
    w = 2.0 * np.pi * f_best * t
    own = rss(cols(np.cos(w), np.sin(w))) - rss(cols(np.cos(w), np.sin(w), np.cos(k * phi), np.sin(k * phi)))
    whole = float(r0 @ r0) - rss(Ck)
    return own / whole if whole > 0.0 else 0.0


def periodic_in_angle(residuals: dict, phi, t, angle: str, units: dict | None = None,
                      alpha: float = ALPHA) -> list:
    """The residual components periodic in ``phi`` [rad] (named ``angle``), one :class:`AngleOrder` per channel
    of ``residuals`` ``{channel: e(t)}`` whose most significant order has a p-value below ``alpha`` and is not a
    sinusoid in time (:data:`MIN_OWN`); most significant first. Empty when the record does not sweep enough of a
    revolution (module docstring)."""
    phi = np.asarray(phi, float)
    t = np.asarray(t, float)
    rng = _order_range(phi)
    if rng is None or steady_fraction(phi, t) > STEADY:
        return []
    Q, _ = np.linalg.qr(_trend(t, TREND_DEGREE))
    out = []
    for ch, e in residuals.items():
        e = np.asarray(e, float)
        if e.size != phi.size or not np.all(np.isfinite(e)):
            continue
        Ql = with_lines(e, t, Q)
        R2, coef = order_spectrum(e, phi, t, rng[1], Ql)
        k, p = _best_order(R2, *rng)
        if p < alpha and _tone_share(e, phi, t, k, Ql) >= MIN_OWN:
            c = coef[k - 1]
            out.append(AngleOrder(ch, angle, k, float(R2[k - 1]), p, float(abs(c)), (units or {}).get(ch, ""),
                                  spectrum=R2.tolist(), phase=float(np.angle(c)), folded=_folded(e, phi, k, Ql)))
    return sorted(out, key=lambda a: a.p_value)


def _folded(e, phi, k, Q) -> list:
    """``[[bin centre, mean], ...]`` of the residual less its nuisance part over ``k phi mod 2 pi``."""
    r = _off(Q, e)
    th = np.mod(k * phi, 2.0 * np.pi)
    idx = np.minimum((th / (2.0 * np.pi) * BINS).astype(int), BINS - 1)
    n = np.bincount(idx, minlength=BINS)
    mean = np.bincount(idx, weights=r, minlength=BINS) / np.maximum(n, 1)
    return [[(i + 0.5) * 2.0 * np.pi / BINS, float(mean[i])] for i in range(BINS) if n[i]]


def angle_channel(units: dict) -> str | None:
    """The first channel measured in rad (an angle, not a rate), or None."""
    return next((n for n, u in units.items() if str(u).strip() == "rad"), None)
