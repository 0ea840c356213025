r"""Noise levels of measurements, estimated from the data: what every residual is divided by.

:func:`~bscomp.validate.diagnostics.diagnose` and :func:`~bscomp.validate.calibration.calibrate` whiten each
residual block (the log10-magnitude or the phase error of one FRF pair, one time channel) by the noise of
the measurement, so the normalised error :math:`\chi^2` of a block is 1 where a model explains it within
noise. The noise is estimated the way an experimentalist would, from the measurement's own scatter and
from what the measurement states about itself.

**Scatter.** The robust scale of third differences, which a smooth signal barely touches (a white error
of variance :math:`\sigma^2` gives third differences of variance :math:`20\sigma^2`; the median ignores the
few samples at input steps and resonances)::

    sigma = median(|y[k+2] - 3 y[k+1] + 3 y[k] - y[k-1]|) / 0.6745 / sqrt(20)

The higher the order, the less of the signal's curvature survives (difference-based variance estimators:
Hall, Kay & Titterington, Biometrika 77, 1990), at a slightly larger sampling scatter. Second differences
(used before) left too much of a sampled response in: on the lumped drive's table acceleration (a 117 Hz
ringing at 2 kHz, 17 samples per period) they read 0.027 to 0.044 m/s^2 for a noise of 0.020 (third
differences 0.020 to 0.024); on H1 FRFs of 20 and 80 averages they read 17 and 65 averages (third: 18.5, 73).

* **Time series**: that scale per channel. A **quantised** channel (an encoder, a linear scale, an ADC: every
  sample an integer multiple of one step ``q``, :func:`quantisation_step`) has at least the rounding error
  :math:`q/\sqrt{12}`; where the scale is below one step the differences are mostly 0 or one step, the
  median of those few discrete values is no scale (it read 0.6 q on the lumped drive's encoders), and the
  rounding error is taken as the noise. (The former floor took ``q`` as the 5th percentile of the nonzero
  sample-to-sample changes: three encoder counts on a turning motor, and 0.03 rad/s on the FE truths'
  continuous motor speed, whose noise is 0.01 rad/s.)
* **FRFs with coherence** (H1 estimates): the random error of an H1 estimate from :math:`n_d` averages
  with coherence :math:`\gamma^2` is (Bendat & Piersol, *Random Data*, ch. 9)

  .. math::

      \varepsilon[|\hat H|] \approx \frac{\sqrt{1 - \gamma^2}}{|\gamma| \sqrt{2 n_d}}, \qquad
      \sigma[\hat\phi] \approx \varepsilon[|\hat H|] \ \text{rad},

  so :math:`\sigma(\log_{10}|\hat H|) = \varepsilon / \ln 10`. The noise varies along the frequency axis
  by orders of magnitude: at a resonance the coherence is ~1, at an anti-resonance the output sinks into
  its noise. The shape comes from the stated coherence, point by point; the one scale
  :math:`c = 1/\sqrt{2 n_d}` (the number of averages, which a file does not state) from the data's
  scatter: the robust scale of the third differences of :math:`\ln|H|` and of the phase, each divided by
  the standard deviation the shape predicts for it (:math:`r_k = \sqrt{1-\gamma_k^2}/|\gamma_k|`
  combined with the difference's weights 1, 3, 3, 1), pooled over every pair of the file (one
  measurement, one number of averages; :func:`h1_averages` reports it). A point stated with coherence
  exactly 1 gets the pair's smallest stated error (the file's resolution), a point with coherence 0 no
  weight.
* **FRFs without coherence**, or with coherence 1 everywhere (no statement about the noise): one level per
  block, the robust scale of :math:`\log_{10}|H|` and of the phase.

One level per FRF block underrates the noise at anti-resonances by up to a factor 100 (on the lumped
joint truth of :mod:`bscomp.validate.synthetic` the exact truth model scored :math:`\chi^2` 41.6 on the FRF
with it, 0.85 with the coherence's shape).
"""

from __future__ import annotations

import math

import numpy as np

from bscomp.validate.datasets import FrfData

__all__ = ["noise_levels", "robust_sigma", "quantisation_step", "h1_scale", "h1_averages", "time_sigma", "FLOOR"]

_MAD = 0.6744897501960817

FLOOR = 1.0e-4
"""Least noise level of an FRF block [log10 units or rad]: data without any scatter are not exact."""


def robust_sigma(y, floor: float, order: int = 3) -> float:
    """Robust noise scale of a sequence from its differences of ``order`` (module docstring), at least
    ``floor``: ``median |Delta^order y| / 0.6745 / sqrt(C(2 order, order))`` (a white error of variance
    sigma^2 gives differences of variance ``C(2 order, order) sigma^2``: 6 for second, 20 for third order)."""
    y = np.asarray(y, float)
    if y.size < order + 3:
        return floor
    d = np.diff(y, n=order)
    s = float(np.median(np.abs(d))) / _MAD / math.sqrt(math.comb(2 * order, order))
    return max(s, floor)


def quantisation_step(y, tol: float = 1e-3, most: int = 20) -> float:
    """The step ``q`` of a quantised channel, 0 for a continuous one.

    ``q`` is the greatest common divisor of the spacings of the distinct values (Euclid's algorithm within
    ``tol`` of a step; spacings below 1e-9 of the range are round-off of one level): a channel is quantised
    when every spacing is a whole number of steps and the step is at least ``1/most`` of the smallest
    spacing seen (a sampled periodic signal may skip levels). A continuous noisy channel fails (the divisor
    of arbitrary spacings collapses to round-off), so no floor is invented for it; a file written with few
    digits on a fixed grid is quantised by that grid, rightly.
    """
    y = np.asarray(y, float)
    levels = np.unique(y[np.isfinite(y)])
    if levels.size < 3:
        return 0.0
    d = np.diff(levels)
    d = d[d > 1e-9 * float(levels[-1] - levels[0])]
    if d.size < 2:
        return 0.0
    d_min = float(np.min(d))
    eps = tol * d_min / most
    q = d_min
    for x in np.unique(np.round(d / eps)) * eps:       # distinct spacings, to the tolerance
        a, b = float(x), q
        while b > eps:                                  # Euclid on floats: gcd(a, b) within eps
            r = math.fmod(a, b)
            a, b = b, (0.0 if b - r < eps else r)
        q = a
        if q < d_min / most:
            return 0.0
    m = d / q
    return q if float(np.max(np.abs(m - np.round(m)))) < tol * most else 0.0


def _h1_shape(g2) -> np.ndarray | None:
    """:math:`r_k = \\sqrt{1-\\gamma_k^2}/|\\gamma_k|` of a pair, or None when its coherence says nothing
    (not measured, or 1 everywhere). Coherence 1 at some points: the pair's smallest positive
    :math:`1-\\gamma^2` there; coherence 0: infinite (no information)."""
    if g2 is None:
        return None
    g2 = np.clip(np.asarray(g2, float), 0.0, 1.0)
    one_minus = 1.0 - g2
    pos = one_minus[one_minus > 0]
    if pos.size == 0:
        return None
    one_minus = np.maximum(one_minus, float(np.min(pos)))
    with np.errstate(divide="ignore"):
        return np.sqrt(one_minus) / np.sqrt(g2)


ORDER = 3
"""Order of the differences every noise level is read from (module docstring)."""


def _differences(h, order: int = ORDER):
    """Differences of ``order`` of ``ln|H|`` and of the phase (wrapped back to (-pi, pi])."""
    h = np.asarray(h, complex)
    a = np.maximum(np.abs(h), 1e-300)
    d_ph = np.diff(np.unwrap(np.angle(h)), n=order)
    return np.diff(np.log(a), n=order), np.angle(np.exp(1j * d_ph))


def _predicted(r, order: int = ORDER):
    """Standard deviation of the differences of ``order`` of independent errors of standard deviations ``r``."""
    coef = np.array([(-1) ** (order - j) * math.comb(order, j) for j in range(order + 1)], float)
    n = r.size - order
    return np.sqrt(sum(coef[j] ** 2 * r[j:j + n] ** 2 for j in range(order + 1)))


def h1_scale(data: FrfData) -> float | None:
    r"""The scale :math:`c = 1/\sqrt{2 n_d}` of the H1 random error, from the scatter of every pair with a
    stated coherence (module docstring); None when no pair states one."""
    z = []
    for pair, h in data.H.items():
        r = _h1_shape(data.coherence.get(pair))
        if r is None or np.size(h) < 5:
            continue
        pred = _predicted(r)
        ok = np.isfinite(pred) & (pred > 0)
        for d in _differences(h):
            z.append(np.abs(d[ok]) / pred[ok])
    if not z:
        return None
    z = np.concatenate(z)
    return float(np.median(z)) / _MAD if z.size else None


def h1_averages(data: FrfData) -> float | None:
    """The number of averages :math:`n_d = 1/(2c^2)` the FRF's scatter corresponds to (None: no coherence)."""
    c = h1_scale(data)
    return None if not c else 1.0 / (2.0 * c * c)


def noise_levels(data) -> list:
    """Noise level of every residual block of a dataset (module docstring).

    Parameters
    ----------
    data : FrfData or TimeData

    Returns
    -------
    list
        FRF: per pair ``[sigma(log10 |H|), sigma(phase)]``, each an array over the frequencies where the
        pair states a coherence, else a float; time: per channel ``sigma(y)`` in its unit (float).
    """
    if isinstance(data, FrfData):
        c = h1_scale(data)
        out = []
        for pair, h in data.H.items():
            r = _h1_shape(data.coherence.get(pair))
            if r is None or c is None:
                h = np.asarray(h, complex)
                mag = np.log10(np.maximum(np.abs(h), 1e-300))
                ph = np.unwrap(np.angle(h))
                out += [robust_sigma(mag, FLOOR, ORDER), robust_sigma(ph, FLOOR, ORDER)]
            else:
                out += [np.maximum(c * r / math.log(10.0), FLOOR), np.maximum(c * r, FLOOR)]
        return out
    return [time_sigma(y) for y in data.outputs.values()]


def time_sigma(y) -> float:
    """Noise level of one time channel (module docstring): the robust scale of its third differences; for a
    quantised channel whose scale is below one step (its differences are mostly 0 or one step, and the
    median of a few discrete values is no scale), the rounding error ``q / sqrt(12)``; never below it,
    nor below 1e-6 of the channel's rms."""
    y = np.asarray(y, float)
    rms = float(np.sqrt(np.mean(y * y))) if y.size else 1.0
    q = quantisation_step(y)
    floor = max(1e-6 * max(rms, 1e-300), q / math.sqrt(12.0))
    s = robust_sigma(y, floor, ORDER)
    return floor if q > 0 and s < q else s
