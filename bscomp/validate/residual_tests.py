"""Residual tests of MATLAB ``resid``: whiteness of a residual and its independence of the input.

A model that explains a time series leaves a residual :math:`e = y - \\hat y` that is white (its
autocorrelation is inside the confidence band at every lag but zero) and uncorrelated with the input at
every lag (Ljung, *System Identification*, Sec 16.6). A residual correlated with the input at lag 0
points at a gain error; at positive lags at missing dynamics or a delay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

__all__ = ["ResidTest", "resid"]


@dataclass
class ResidTest:
    """MATLAB ``resid``: residual autocorrelation and cross-correlation with an input, 99 % bands.

    ``acf[k]`` for lags 0..M, ``xcf[k]`` for lags -M..M (positive lag: input leads the residual);
    ``white`` / ``independent``: at most 5 % of the lags (at least one) outside the band.
    """

    lags: np.ndarray
    acf: np.ndarray
    acf_bound: float
    xlags: np.ndarray
    xcf: np.ndarray
    xcf_bound: float
    white: bool
    independent: bool
    acf_outside: int
    xcf_outside: int

    def to_dict(self):
        return {"lags": self.lags.tolist(), "acf": self.acf.tolist(), "acf_bound": self.acf_bound,
                "xlags": self.xlags.tolist(), "xcf": self.xcf.tolist(), "xcf_bound": self.xcf_bound,
                "white": self.white, "independent": self.independent}


def _xcorr(a, b, maxlag):
    """Normalised cross-correlation r_ab(k) = sum a[t+k] b[t] / (N sigma_a sigma_b), k = -maxlag..maxlag."""
    a = a - a.mean()
    b = b - b.mean()
    n = a.size
    den = n * a.std() * b.std()
    lags = np.arange(-maxlag, maxlag + 1)
    if den == 0:
        return lags, np.zeros(lags.size)
    r = np.array([np.dot(a[max(k, 0):n + min(k, 0)], b[max(-k, 0):n - max(k, 0)]) for k in lags]) / den
    return lags, r


def resid(e, u, maxlag: int = 25, confidence: float = 0.99) -> ResidTest:
    """Whiteness of the residual ``e`` and its independence of the input ``u`` (MATLAB ``resid``).

    Autocorrelation bound :math:`z/\\sqrt N`; cross-correlation bound
    :math:`z\\sqrt{\\sum_k r_e(k) r_u(k)}/\\sqrt N` (accounts for a coloured input), z = 2.58 for 99 %.
    A zero residual is white and independent.
    """
    e = np.asarray(e, float).ravel()
    u = np.asarray(u, float).ravel()
    n = e.size
    maxlag = int(min(maxlag, max(n // 4, 1)))
    z = float(ndtri(0.5 + confidence / 2))
    lags_full, acf_full = _xcorr(e, e, maxlag)
    lags = lags_full[maxlag:]
    acf = acf_full[maxlag:]
    xl, xcf = _xcorr(e, u, maxlag)
    _, ru = _xcorr(u, u, maxlag)
    acf_bound = z / np.sqrt(n)
    P = float(np.dot(acf_full, ru)) if np.std(e) > 0 else 1.0
    xcf_bound = z * np.sqrt(max(P, 1e-12)) / np.sqrt(n)
    if np.std(e) == 0:
        acf = np.zeros_like(acf)
        xcf = np.zeros_like(xcf)
    a_out = int(np.sum(np.abs(acf[1:]) > acf_bound))
    x_out = int(np.sum(np.abs(xcf) > xcf_bound))
    a_ok = max(1, int(np.ceil(0.05 * maxlag)))
    x_ok = max(1, int(np.ceil(0.05 * (2 * maxlag + 1))))
    return ResidTest(lags=lags, acf=acf, acf_bound=float(acf_bound), xlags=xl, xcf=xcf, xcf_bound=float(xcf_bound),
                     white=a_out <= a_ok, independent=x_out <= x_ok, acf_outside=a_out, xcf_outside=x_out)

