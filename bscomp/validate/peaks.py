"""Resonances of a measured or model FRF: peak picking refined by a local modal fit (thesis Sec 4.2).

The peak of :math:`|H|` is a biased estimate of a damped mode's natural frequency. For a single mode
seen in an acceleration FRF, :math:`|s^2/(s^2 + 2\\zeta\\omega_n s + \\omega_n^2)|` peaks at
:math:`\\omega_n/\\sqrt{1 - 2\\zeta^2}`; the rigid-body term and the neighbouring modes move the peak
further (the test bed's 10 %-damped 275 Hz mode peaks at 291 Hz in the rotor speed, where it sits just
above an antiresonance). :func:`peak_pick` therefore uses the peaks only as starting values and
:func:`modal_fit` estimates the poles from the complex FRF over a band around each peak,

.. math:: H(s) \\approx \\sum_{k=1}^{m} \\frac{a_k \\omega_k^2 + b_k \\omega_k s}
          {s^2 + 2\\zeta_k\\omega_k s + \\omega_k^2} + \\sum_{j=-2}^{2} c_j \\left(\\frac{s}{\\omega_c}\\right)^j,

with real :math:`a_k, b_k, c_j`: one mode (two or three when other peaks lie in the band) and polynomial
residual terms for the modes outside the band and the rigid-body motion. The form holds for any output
type: a displacement, velocity or acceleration output multiplies the receptance modal sum (Eq 4.3,
4.5-4.7) by :math:`s^r`, which adds polynomial terms of degree up to 2 to each mode, and the modes below
and above the band contribute terms in :math:`s^{r-2}` (their mass line) and :math:`s^{r}` (their
stiffness line). The poles are found by nonlinear least squares on the relative complex error with the
linear coefficients eliminated (variable projection), so :math:`f_n = |p|/2\\pi` and
:math:`\\zeta = -\\mathrm{Re}\\,p/|p|` are the pole's, not the peak's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import find_peaks

__all__ = ["Resonance", "ModalFit", "modal_fit", "peak_pick", "merge_resonances"]

#: powers j of the residual terms (s / omega_c)^j
RESIDUAL_POWERS = (-2, -1, 0, 1, 2)
#: a fitted pole more damped than this is no resonance (a hump made by an antiresonance and real poles)
MAX_ZETA = 0.5


@dataclass
class Resonance:
    """A resonance of a measured (or model) FRF.

    ``f`` [Hz] natural frequency :math:`|p|/2\\pi` and ``zeta`` damping ratio of the pole from the local
    modal fit (:func:`modal_fit`) when it succeeds (``refined``), else the raw peak-picking values;
    ``amplitude`` :math:`|H|` at ``f`` (SI) from the fit (at the peak when not refined); ``pair`` the
    (input, output) pair where it is estimated, ``prominence_db`` how far its peak stands out, ``pairs``
    every pair that shows it. ``f_peak`` and ``zeta_half_power`` are the raw peak and its half-power
    damping; ``fit_residual`` the relative rms misfit of the modal fit (inf when not refined).
    """

    f: float
    zeta: float
    amplitude: float
    pair: tuple
    prominence_db: float
    pairs: list = field(default_factory=list)
    f_peak: float = np.nan
    zeta_half_power: float = np.nan
    refined: bool = False
    fit_residual: float = np.inf


@dataclass
class ModalFit:
    """Result of :func:`modal_fit`.

    Attributes
    ----------
    f : ndarray
        Natural frequencies :math:`|p_k|/2\\pi` [Hz] of the fitted modes, in the order of the starts.
    zeta : ndarray
        Their damping ratios :math:`-\\mathrm{Re}\\,p_k/|p_k|`.
    band : (float, float)
        Frequency band of the fit [Hz].
    misfit : float
        Relative rms of the weighted complex residual (about the relative noise level for a good fit).
    n_points : int
    """

    f: np.ndarray
    zeta: np.ndarray
    band: tuple
    misfit: float
    n_points: int
    coefficients: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    omega_c: float = field(repr=False, default=1.0)

    @property
    def poles(self) -> np.ndarray:
        """Poles with positive imaginary part [1/s]."""
        w = 2 * np.pi * self.f
        return -self.zeta * w + 1j * w * np.sqrt(np.maximum(1 - self.zeta ** 2, 0.0))

    def __call__(self, freqs) -> np.ndarray:
        """The fitted FRF at ``freqs`` [Hz] (meaningful inside :attr:`band`)."""
        s = 2j * np.pi * np.asarray(freqs, float) / self.omega_c
        wn = 2 * np.pi * self.f / self.omega_c
        return _basis(s, wn, self.zeta) @ self.coefficients


def _basis(sn, wn, zeta) -> np.ndarray:
    """Columns of the local model at scaled s for scaled natural frequencies ``wn``."""
    cols = []
    for w, z in zip(wn, zeta):
        d = sn ** 2 + 2 * z * w * sn + w ** 2
        cols += [w ** 2 / d, w * sn / d]
    cols += [sn ** j for j in RESIDUAL_POWERS]
    return np.column_stack(cols)


def _project(sn, h, wts, wn, zeta):
    """Linear coefficients for given poles and the stacked real residual (variable projection)."""
    A = _basis(sn, wn, zeta) * wts[:, None]
    b = h * wts
    Ar, br = np.vstack([A.real, A.imag]), np.concatenate([b.real, b.imag])
    cs = np.linalg.norm(Ar, axis=0)
    cs[cs == 0] = 1.0
    c, *_ = np.linalg.lstsq(Ar / cs, br, rcond=None)
    c = c / cs
    return c, Ar @ c - br


def modal_fit(freqs, H, f0, zeta0=0.05, band=None, weights=None) -> ModalFit | None:
    """Poles of one to three modes fitted to a complex FRF over a band (see the module notes).

    Parameters
    ----------
    freqs : array_like
        Frequencies [Hz], ascending.
    H : array_like of complex
        The FRF (any output type).
    f0 : float or sequence of float
        Starting natural frequencies [Hz] (e.g. the peaks in the band).
    zeta0 : float or sequence of float
        Starting damping ratios (NaN: 0.05).
    band : (float, float), optional
        Band [Hz]; default ``f0[0] / (1 + h)`` to ``f0[0] (1 + h)`` with ``h = 3 zeta0[0]`` in [0.08, 0.35].
        Widened to hold at least ``2 m + 6`` points.
    weights : array_like, optional
        Extra weights per frequency (e.g. the square root of the coherence); the error is relative,
        weighted by :math:`1/\\max(|H|, 10^{-2} \\max|H|)` in the band.

    Returns
    -------
    ModalFit, or None when the band holds too few points or the fit does not converge to damped modes.
    """
    f = np.asarray(freqs, float)
    h = np.asarray(H, complex)
    f0 = np.atleast_1d(np.asarray(f0, float))
    z0 = np.broadcast_to(np.asarray(zeta0, float), f0.shape).copy()
    z0 = np.clip(np.where(np.isfinite(z0), z0, 0.05), 0.005, 0.3)
    m = f0.size
    if band is None:
        hw = float(np.clip(3 * z0[0], 0.08, 0.35))
        band = (f0[0] / (1 + hw), f0[0] * (1 + hw))
    sel = np.flatnonzero((f >= band[0]) & (f <= band[1]))
    need = 2 * m + 6
    if f.size < need:
        return None
    if sel.size < need:                          # widen around the first start, in index space
        k = int(np.argmin(np.abs(np.log(f / f0[0]))))
        lo = int(np.clip(k - need // 2, 0, f.size - need))
        sel = np.arange(lo, lo + need)
    fb, hb = f[sel], h[sel]
    wc = 2 * np.pi * float(np.sqrt(fb[0] * fb[-1]))
    sn = 2j * np.pi * fb / wc
    mag = np.abs(hb)
    wts = 1.0 / np.maximum(mag, 1e-2 * max(float(mag.max()), 1e-300))
    if weights is not None:
        wts = wts * np.asarray(weights, float)[sel]
    norm = float(np.linalg.norm(hb * wts)) or 1.0

    def residual(x):
        return _project(sn, hb, wts, np.exp(x[:m]), x[m:])[1]

    lnw_lo, lnw_hi = np.log(2 * np.pi * fb[0] / wc / 1.5), np.log(2 * np.pi * fb[-1] * 1.5 / wc)
    lb = np.r_[np.full(m, lnw_lo), np.full(m, 1e-4)]
    ub = np.r_[np.full(m, lnw_hi), np.full(m, 0.9)]
    best = None
    for scale in (1.0, 0.5, 2.0):
        x0 = np.r_[np.clip(np.log(2 * np.pi * f0 / wc), lnw_lo + 1e-9, lnw_hi - 1e-9),
                   np.clip(scale * z0, 2e-4, 0.85)]
        try:
            sol = least_squares(residual, x0, bounds=(lb, ub), x_scale=np.full(2 * m, 0.05))
        except (ValueError, np.linalg.LinAlgError):
            continue
        fit_f, fit_z = np.exp(sol.x[:m]) * wc / (2 * np.pi), sol.x[m:]
        ok = np.all((fit_z > 2e-4) & (fit_z < 0.85)) and np.all((fit_f > fb[0] / 1.2) & (fit_f < fb[-1] * 1.2))
        cand = (float(np.linalg.norm(sol.fun)) / norm, ok, sol, fit_f, fit_z)
        if best is None or (cand[1], -cand[0]) > (best[1], -best[0]):
            best = cand
        if ok:
            break
    if best is None or not best[1]:
        return None
    misfit, _, sol, fit_f, fit_z = best
    c, _ = _project(sn, hb, wts, np.exp(sol.x[:m]), sol.x[m:])
    return ModalFit(f=fit_f, zeta=fit_z, band=(float(fb[0]), float(fb[-1])), misfit=misfit, n_points=int(sel.size),
                    coefficients=c, omega_c=wc)


def _half_power(logf, L, k, level):
    """Frequencies (log) where L falls to ``level`` on each side of index k (None if not reached)."""
    def cross(indices):
        prev = k
        for j in indices:
            if L[j] > L[prev] + 1e-9 and L[j] > level:   # rose again (next peak) before the half-power level
                return None
            if L[j] <= level:
                a, b = L[prev], L[j]
                w = (a - level) / (a - b) if a != b else 0.0
                return logf[prev] + w * (logf[j] - logf[prev])
            prev = j
        return None

    return cross(range(k - 1, -1, -1)), cross(range(k + 1, len(L)))


def _raw_peaks(f, L, min_prominence_db):
    """(index, peak frequency, peak level [dB], half-power zeta, prominence) of each peak of L."""
    logf = np.log(f)
    idx, props = find_peaks(L, prominence=min_prominence_db)
    out = []
    for k, prom in zip(idx, props["prominences"]):
        x, y = logf[k - 1:k + 2], L[k - 1:k + 2]       # find_peaks never returns an end point
        c2, c1, c0 = np.polyfit(x - x[1], y, 2)
        xv = float(np.clip(-c1 / (2 * c2) if c2 < 0 else 0.0, x[0] - x[1], x[2] - x[1]))
        lp, fp = c0 + c1 * xv + c2 * xv * xv, float(np.exp(x[1] + xv))
        lo, hi = _half_power(logf, L, k, lp - 10 * np.log10(2.0))
        if lo is not None and hi is not None:
            zeta = (np.exp(hi) - np.exp(lo)) / (2 * fp)
        elif hi is not None:
            zeta = (np.exp(hi) - fp) / fp
        elif lo is not None:
            zeta = (fp - np.exp(lo)) / fp
        else:
            zeta = np.nan
        if not zeta > 0:          # a half-power point on the wrong side of the peak: no damping estimate
            zeta = np.nan
        out.append((int(k), fp, float(lp), float(zeta), float(prom)))
    return out


def _half_width(zeta) -> float:
    """Relative half width of the band a mode of damping ``zeta`` is fitted on: 3 zeta, in [0.08, 0.35]."""
    return float(np.clip(3 * zeta, 0.08, 0.35)) if np.isfinite(zeta) else 0.2


def _refine(f, Hc, peaks, i, weights):
    """Modal fit for peak ``i``, jointly with the (at most two nearest) peaks whose bands overlap its band.

    Fitted twice: on the bands around the peaks, then on the bands around the fitted poles. Returns
    ``(estimate, is_mode)``: estimate (f, zeta, amplitude, misfit) or None when the fit fails; ``is_mode``
    False when a good fit puts no pole near the peak (a bump beside an antiresonance, not a mode).
    """
    est = [(p[1], p[3]) for p in peaks]
    fit = None
    for _ in range(2):
        fi, zi = est[i]
        reach = np.log1p(_half_width(zi))
        near = sorted((j for j in range(len(est)) if j != i
                       and abs(np.log(est[j][0] / fi)) < 2 * (reach + np.log1p(_half_width(est[j][1])))),
                      key=lambda j: abs(np.log(est[j][0] / fi)))[:2]
        group = [i] + near
        lo = min(est[j][0] / (1 + _half_width(est[j][1])) for j in group)
        hi = max(est[j][0] * (1 + _half_width(est[j][1])) for j in group)
        new = modal_fit(f, Hc, [est[j][0] for j in group], [est[j][1] for j in group], band=(lo, hi),
                        weights=weights)
        near_peak = new is not None and new.zeta[0] < MAX_ZETA \
            and fi / (1 + 2 * _half_width(zi)) < new.f[0] < fi * (1 + 2 * _half_width(zi))
        if new is None or not near_peak or new.misfit > 0.25:
            enough = np.count_nonzero((f >= lo) & (f <= hi)) >= 2 * len(group) + 6
            if fit is None and enough and (new is None or (not near_peak and new.misfit < 0.25)):
                return None, False              # no damped pole at this peak (a bump beside an antiresonance)
            break
        fit = new
        for k, j in enumerate(group):
            est[j] = (float(new.f[k]), float(new.zeta[k]))
    if fit is None:
        return None, True
    return (float(fit.f[0]), float(fit.zeta[0]), float(abs(fit(fit.f[:1])[0])), fit.misfit), True


def peak_pick(freqs, H, pair=("", ""), min_prominence_db: float = 3.0, coherence=None,
              min_coherence: float = 0.5, refine: bool = True) -> list:
    """Resonances of one FRF: peaks of :math:`|H|`, then the poles of a local modal fit.

    Peaks of :math:`20\\log_{10}|H|` standing out by at least ``min_prominence_db`` are located by a
    parabola through the three highest points (in log frequency), with the half-power damping
    :math:`\\zeta = (f_2 - f_1) / (2 f_r)` from the frequencies where :math:`|H|` falls to
    :math:`|H_r|/\\sqrt 2` (one-sided when only one half-power point is inside the data). Points with
    coherence below ``min_coherence`` and zero or non-finite :math:`|H|` are ignored. With ``refine`` and a
    complex ``H``, these are the starting values of :func:`modal_fit` over a band of :math:`\\pm 3\\zeta`
    (8-35 %) around each peak, fitted jointly with the other peaks in that band; the fitted pole gives ``f``
    and ``zeta``, which removes the bias of the raw peak on damped modes, velocity and acceleration FRFs and near
    neighbouring modes or antiresonances. A peak whose fit fails keeps its raw values (``refined`` False).

    Returns
    -------
    list of Resonance, ascending in frequency.
    """
    f = np.asarray(freqs, float)
    Hc = np.asarray(H)
    # a zero or non-finite |H| is no data point (its -inf dB dip would make its neighbours peaks): skipped
    ok = (f > 0) & np.isfinite(f) & np.isfinite(Hc) & (np.abs(Hc) > 0)
    g = None if coherence is None else np.asarray(coherence, float)
    if g is not None:
        ok &= g >= min_coherence
    f, Hc = f[ok], Hc[ok]
    a = np.abs(Hc)
    if f.size < 5 or not np.any(a > 0):
        return []
    L = 20 * np.log10(np.maximum(a, 1e-12 * a.max()))
    peaks = _raw_peaks(f, L, min_prominence_db)
    weights = None if g is None else np.sqrt(np.clip(g[ok], 0.0, 1.0))
    out = []
    for i, (_, fp, lp, zeta, prom) in enumerate(peaks):
        fit, is_mode = _refine(f, Hc, peaks, i, weights) if refine and np.iscomplexobj(Hc) else (None, True)
        if not is_mode:
            continue
        fr, zr, amp, misfit = fit if fit is not None else (fp, zeta, float(10 ** (lp / 20)), np.inf)
        out.append(Resonance(f=fr, zeta=zr, amplitude=amp, pair=tuple(pair), prominence_db=prom,
                             pairs=[tuple(pair)], f_peak=fp, zeta_half_power=zeta, refined=fit is not None,
                             fit_residual=misfit))
    return sorted(out, key=lambda r: r.f)


def merge_resonances(res_lists, rel_tol=0.05) -> list:
    """One list of resonances from several pairs: estimates within ``rel_tol`` (or the damping ratio) are
    the same mode, taken from the pair the modal fit explains best."""
    allr = sorted((r for rl in res_lists for r in rl), key=lambda r: r.f)
    groups: list = []
    for r in allr:
        g0 = groups[-1][0] if groups else None
        tol = max(rel_tol, np.nan_to_num(g0.zeta), np.nan_to_num(r.zeta)) if g0 else 0.0
        if groups and abs(r.f - g0.f) <= tol * g0.f:
            groups[-1].append(r)
        else:
            groups.append([r])
    merged = []
    for g in groups:
        best = min(g, key=lambda r: (r.fit_residual, -r.prominence_db))
        merged.append(Resonance(best.f, best.zeta, best.amplitude, best.pair, best.prominence_db,
                                pairs=list(dict.fromkeys(p for r in g for p in r.pairs)), f_peak=best.f_peak,
                                zeta_half_power=best.zeta_half_power, refined=best.refined,
                                fit_residual=best.fit_residual))
    return merged
