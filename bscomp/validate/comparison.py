"""Compare a model with measurements and say where it fails (issue 8; thesis Sec 3.5).

:func:`compare` evaluates the model at every dataset's conditions and returns a :class:`Comparison`:

FRF datasets (:class:`FrfComparison`)
    log-magnitude [dB] and phase [deg] error overall and per band (octaves or user bands) with each band's
    share of the squared residual; fit % per pair (MATLAB ``compare``, on the complex FRF, and on
    log-magnitude); a **mode-pairing table** -- measured resonances, the poles of a local modal fit of the
    complex FRF started from the peaks of :math:`|H|` (:func:`peak_pick`, :mod:`bscomp.validate.peaks`),
    against the model's poles (:func:`bscomp.linear.modal.modes`): frequency error, damping, amplitude; measured
    resonances with no model counterpart and model modes the measurement does not show; the phase
    error's slope as an apparent time delay. The model FRF's resonances are found by the same estimator
    (they decide which model modes the measured pairs can show).
Time series (:class:`TimeComparison`)
    fit % per channel, the residual over time and its worst windows, MATLAB ``resid``'s whiteness and
    input-independence tests (:func:`resid`) and the correlation of the residual with physically
    meaningful signals of the model's own simulation -- table velocity, its sign, velocity reversals,
    acceleration, screw stretch, position, input, output rate -- the **signatures** a missing effect
    leaves (Coulomb friction: sign of velocity; backlash: reversals; a compliance: acceleration or
    stretch; a delay: output rate).

Residuals are measured minus model (:mod:`bscomp.validate.residuals`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bscomp.validate.measurements import FrfData, TimeData, load_all
from bscomp.validate.peaks import ModalFit, Resonance, merge_resonances, modal_fit, peak_pick
from bscomp.validate.residuals import build_for, fit_percent, frf_errors, simulate_at

__all__ = ["compare", "Comparison", "FrfComparison", "TimeComparison", "Resonance", "ModePair", "ResidTest",
           "peak_pick", "modal_fit", "ModalFit", "resid", "user_errors", "octave_bands", "SIGNATURES", "EVIDENCE"]

#: names of :attr:`Comparison.signatures` and what each correlates the residual with
SIGNATURES = {
    "velocity": "table velocity v (viscous friction, velocity-dependent effects)",
    "sign_velocity": "sign(v) (Coulomb/Stribeck friction)",
    "reversal": "|residual| against an indicator of velocity reversals (backlash, stick-slip)",
    "acceleration": "table acceleration a (missing mass or compliance)",
    "screw_stretch": "axial deflection between nut and table (missing compliance in the axial path)",
    "position": "table position s (position-dependent stiffness, guideway)",
    "input": "the excitation at lag 0 (gain error)",
    "output_rate": "the model output's rate dy/dt (time delay, phase lag)",
}

#: names of :attr:`Comparison.evidence`: numbers that are not correlations
EVIDENCE = {
    "time_delay_s": "least-squares delay tau [s] in e = -tau dy/dt (time series)",
    "frf_phase_delay_s": "delay [s] fitted to the FRF phase error's slope",
    "frf_phase_delay_r2": "coefficient of determination of that linear phase fit",
    "frf_max_freq_error_pct": "largest |frequency error| [%] of paired resonances",
    "frf_unmatched_measured": "number of measured resonances with no model counterpart",
    "frf_unmatched_model": "number of model modes not seen in the measurement",
}


# ---- bands -----------------------------------------------------------------------------------------------
def octave_bands(fmin: float, fmax: float) -> list:
    """Octave bands ``(lo, hi)`` [Hz] with centres 1000 * 2^k covering [fmin, fmax]."""
    fmin = max(fmin, 1e-6)
    k0 = int(np.floor(np.log2(fmin / 1000.0) + 0.5))
    k1 = int(np.ceil(np.log2(fmax / 1000.0) - 0.5))
    return [(1000.0 * 2 ** (k - 0.5), 1000.0 * 2 ** (k + 0.5)) for k in range(k0, k1 + 1)]


# ---- results -----------------------------------------------------------------------------------------------
@dataclass
class ModePair:
    """One row of the mode-pairing table; ``measured`` or ``model`` is None for an unpaired mode.

    ``model_f`` [Hz] is the natural frequency :math:`|p|/2\\pi` of the model mode's damped pole pair
    (:attr:`bscomp.linear.modal.Modes.poles`; the undamped frequency when the pair is not available) and
    ``model_zeta`` its damping ratio -- the quantities the modal fit of the measurement estimates.
    ``model_amplitude`` is :math:`|H|` of the model at ``model_f`` in the measured resonance's pair.
    """

    measured: Resonance | None
    model_f: float | None = None
    model_zeta: float | None = None
    model_amplitude: float | None = None
    model_index: int | None = None

    @property
    def freq_error_pct(self) -> float | None:
        """``100 (f_model - f_measured) / f_measured``."""
        if self.measured is None or self.model_f is None:
            return None
        return 100.0 * (self.model_f - self.measured.f) / self.measured.f

    @property
    def amplitude_error_db(self) -> float | None:
        """``20 log10(|H_model| / |H_measured|)`` at the resonance."""
        if self.measured is None or not self.model_amplitude:
            return None
        return 20 * np.log10(self.model_amplitude / self.measured.amplitude)

    def to_dict(self):
        m = self.measured
        return {"measured_f_hz": None if m is None else m.f, "measured_zeta": None if m is None else _num(m.zeta),
                "measured_amplitude": None if m is None else m.amplitude,
                "pair": None if m is None else list(m.pair), "model_f_hz": self.model_f,
                "model_zeta": _num(self.model_zeta), "model_amplitude": self.model_amplitude,
                "model_mode": self.model_index, "freq_error_pct": self.freq_error_pct,
                "amplitude_error_db": self.amplitude_error_db}


def _num(x):
    if x is None:
        return None
    x = float(x)
    return None if not np.isfinite(x) else x


@dataclass
class FrfComparison:
    """An FRF dataset against the model.

    Attributes
    ----------
    source : str
    freqs : ndarray [Hz]
    measured, model : dict (input, output) -> complex ndarray
    units : dict (input, output) -> str
    mag_error_db, phase_error_deg : dict pair -> ndarray
        Measured minus model, per frequency.
    weights : dict pair -> ndarray
        sqrt(coherence) (ones when not measured).
    fit : dict pair -> float
        Fit % on the complex FRF (MATLAB ``compare``).
    fit_logmag : dict pair -> float
        Fit % on :math:`20\\log_{10}|H|`.
    rms_mag_db, rms_phase_deg : float
        Overall (coherence-weighted) RMS errors.
    pair_errors : dict pair -> dict
        The error as the user reads it, per pair (:func:`user_errors`): ``mag_mean_abs_dlog10`` (mean
        :math:`|\\Delta\\log_{10}|H||`), ``mag_db_rms`` [dB] and ``phase_deg_rms`` [deg], coherence-weighted.
    bands : list of dict
        Per band (``lo``, ``hi`` [Hz]) and pair: RMS magnitude and phase error and ``share`` of the
        dataset's squared residual.
    modes : list of ModePair
        Paired resonances, then measured resonances with no model counterpart, then model modes not
        seen (see :attr:`unmatched_measured`, :attr:`unmatched_model`).
    phase_delay_s, phase_delay_r2 : float
        Delay fitted to the unwrapped phase error, :math:`\\Delta\\varphi \\approx -2\\pi f \\tau + c`.
    cost : float
        Mean squared residual of this dataset.
    """

    source: str
    freqs: np.ndarray
    measured: dict
    model: dict
    units: dict
    mag_error_db: dict
    phase_error_deg: dict
    weights: dict
    fit: dict
    fit_logmag: dict
    rms_mag_db: float
    rms_phase_deg: float
    bands: list
    modes: list
    phase_delay_s: float
    phase_delay_r2: float
    cost: float
    conditions: dict = field(default_factory=dict)
    pair_errors: dict = field(default_factory=dict)
    index: int | None = None

    def user_errors(self) -> dict:
        """``{"frf": [{"pair", "mag_mean_abs_dlog10", "mag_db_rms", "phase_deg_rms"}, ...], "time": []}``."""
        return {"frf": [dict(pair=p, **e) for p, e in self.pair_errors.items()], "time": []}

    @property
    def paired(self):
        return [m for m in self.modes if m.measured is not None and m.model_f is not None]

    @property
    def unmatched_measured(self):
        return [m.measured for m in self.modes if m.model_f is None]

    @property
    def unmatched_model(self):
        return [m for m in self.modes if m.measured is None]

    def worst_bands(self, share: float = 0.8) -> list:
        """Bands (summed over pairs) carrying ``share`` of the error, largest first: (lo, hi, share)."""
        agg: dict = {}
        for b in self.bands:
            agg[(b["lo"], b["hi"])] = agg.get((b["lo"], b["hi"]), 0.0) + b["share"]
        rows = sorted(((lo, hi, s) for (lo, hi), s in agg.items()), key=lambda r: -r[2])
        out, acc = [], 0.0
        for r in rows:
            if acc >= share or r[2] <= 0:
                break
            out.append(r)
            acc += r[2]
        return out

    def to_dict(self):
        def pk(p):
            return f"{p[1]}/{p[0]}"
        return {"kind": "frf", "source": self.source, "conditions": self.conditions, "cost": self.cost,
                "freqs_hz": self.freqs.tolist(),
                "pairs": {pk(p): {"fit_pct": self.fit[p], "fit_logmag_pct": self.fit_logmag[p],
                                  "unit": self.units.get(p, ""),
                                  "measured_re": self.measured[p].real.tolist(),
                                  "measured_im": self.measured[p].imag.tolist(),
                                  "model_re": self.model[p].real.tolist(), "model_im": self.model[p].imag.tolist()}
                          for p in self.measured},
                "rms_mag_db": self.rms_mag_db, "rms_phase_deg": self.rms_phase_deg,
                "pair_errors": {pk(p): e for p, e in self.pair_errors.items()},
                "bands": [dict(b, pair=pk(b["pair"])) for b in self.bands],
                "modes": [m.to_dict() for m in self.modes],
                "phase_delay_s": self.phase_delay_s, "phase_delay_r2": self.phase_delay_r2}


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
    from scipy.stats import norm

    e = np.asarray(e, float).ravel()
    u = np.asarray(u, float).ravel()
    n = e.size
    maxlag = int(min(maxlag, max(n // 4, 1)))
    z = float(norm.ppf(0.5 + confidence / 2))
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


@dataclass
class TimeComparison:
    """A time-series dataset against the model.

    Attributes
    ----------
    source : str
    t : ndarray [s]
    inputs : dict name -> ndarray
    measured, model, residual : dict channel -> ndarray (residual = measured - model, SI)
    units : dict channel -> str
    fit : dict channel -> float
        Fit % (MATLAB ``compare``).
    resid : dict channel -> ResidTest
        Against the first input.
    signals : dict name -> ndarray
        The model's physical signals used for the signatures (``velocity``, ``acceleration``...).
    signatures : dict channel -> dict name -> float
        Correlation of the channel's residual with each signal (see :data:`SIGNATURES`).
    delays : dict channel -> float
        Least-squares delay [s] in :math:`e \\approx -\\tau\\,\\dot{\\hat y}`.
    windows : list of dict
        Equal time windows with their share of the squared (normalised) residual and what the model
        does there (``"velocity reversal"``, ``"acceleration"``, ``"constant velocity"``, ``"rest"``).
    cost : float
    """

    source: str
    t: np.ndarray
    inputs: dict
    measured: dict
    model: dict
    residual: dict
    units: dict
    fit: dict
    resid: dict
    signals: dict
    signatures: dict
    windows: list
    cost: float
    conditions: dict = field(default_factory=dict)
    delays: dict = field(default_factory=dict)
    index: int | None = None

    def user_errors(self) -> dict:
        """``{"frf": [], "time": [{"channel", "fit_percent"}, ...]}``."""
        return {"frf": [], "time": [{"channel": n, "fit_percent": float(v)} for n, v in self.fit.items()]}

    def worst_windows(self, share: float = 0.5) -> list:
        rows = sorted(self.windows, key=lambda w: -w["share"])
        out, acc = [], 0.0
        for w in rows:
            if acc >= share or w["share"] <= 0:
                break
            out.append(w)
            acc += w["share"]
        return out

    def to_dict(self):
        return {"kind": "time", "source": self.source, "conditions": self.conditions, "cost": self.cost,
                "t": self.t.tolist(), "fit_pct": self.fit, "units": self.units,
                "measured": {k: v.tolist() for k, v in self.measured.items()},
                "model": {k: v.tolist() for k, v in self.model.items()},
                "resid": {k: v.to_dict() for k, v in self.resid.items()},
                "signatures": self.signatures, "windows": self.windows}


@dataclass
class Comparison:
    """Result of :func:`compare`: one entry per dataset, the overall cost and the residual signatures.

    Attributes
    ----------
    system : str
    frf : list of FrfComparison
    time : list of TimeComparison
    cost : float
        Mean over datasets of the mean squared residual (as :func:`bscomp.validate.residuals.cost`).
    signatures : dict str -> float
        Correlations in [-1, 1] of the time-series residual with the model's physical signals (keys in
        :data:`SIGNATURES`), each the value with the largest magnitude over channels and datasets. Empty
        without time series.
    evidence : dict str -> float
        Other numbers for the diagnosis (keys in :data:`EVIDENCE`): apparent delays, largest resonance
        frequency error, counts of unpaired resonances.
    """

    system: str
    frf: list
    time: list
    cost: float
    signatures: dict
    evidence: dict = field(default_factory=dict)

    @property
    def datasets(self):
        return list(self.frf) + list(self.time)

    def user_errors(self) -> dict:
        """The errors as the user reads them, ``{dataset index: {"frf": [...], "time": [...]}}`` in the order
        the datasets were given (as :func:`user_errors`)."""
        return {c.index: c.user_errors() for c in sorted(self.datasets, key=lambda c: c.index or 0)}

    def summary(self) -> str:
        """Where the model fails, in words: bands, resonances and time windows carrying the error."""
        L = [f"Comparison of '{self.system}' with {len(self.datasets)} dataset(s): cost {self.cost:.4g} "
             "(mean squared residual; 0 = perfect)"]
        for c in self.frf:
            fits = ", ".join(f"{o}/{i} {c.fit[(i, o)]:.1f} %" for i, o in c.measured)
            L.append(f"FRF {c.source}: fit {fits}; magnitude error {c.rms_mag_db:.2f} dB rms, phase error "
                     f"{c.rms_phase_deg:.1f} deg rms")
            if len(c.pair_errors) > 1:
                L.append("  per pair: " + "; ".join(
                    f"{o}/{i} magnitude {e['mag_db_rms']:.2f} dB rms (mean |dlog10| {e['mag_mean_abs_dlog10']:.3f}), "
                    f"phase {e['phase_deg_rms']:.1f} deg rms" for (i, o), e in c.pair_errors.items()))
            wb = c.worst_bands()
            if wb and c.cost > 1e-12:
                L.append("  error concentrated in " + ", ".join(f"{lo:.3g}-{hi:.3g} Hz ({100 * s:.0f} %)"
                                                                 for lo, hi, s in wb))
            for m in c.paired:
                r = m.measured
                L.append(f"  resonance: measured {r.f:.4g} Hz (zeta {r.zeta:.3g}) vs model {m.model_f:.4g} Hz "
                         f"(zeta {_fmt(m.model_zeta)}): frequency error {m.freq_error_pct:+.1f} %, amplitude "
                         f"{_fmt(m.amplitude_error_db, '+.1f')} dB")
            for r in c.unmatched_measured:
                L.append(f"  measured resonance with no model counterpart: {r.f:.4g} Hz (zeta {r.zeta:.3g}) in "
                         + ", ".join(f"{o}/{i}" for i, o in r.pairs))
            for m in c.unmatched_model:
                L.append(f"  model mode not seen in the measurement: {m.model_f:.4g} Hz (zeta {_fmt(m.model_zeta)})")
            if np.isfinite(c.phase_delay_s) and c.phase_delay_r2 > 0.9 and abs(c.phase_delay_s) > 0 \
                    and c.rms_phase_deg > 1.0:
                L.append(f"  phase error grows linearly with frequency: an apparent delay of "
                         f"{1e3 * c.phase_delay_s:.3g} ms (R^2 {c.phase_delay_r2:.2f})")
        for c in self.time:
            fits = ", ".join(f"{k} {v:.1f} %" for k, v in c.fit.items())
            L.append(f"Time series {c.source}: fit {fits}")
            for ch, rt in c.resid.items():
                if c.fit[ch] > 99.99:
                    continue
                words = []
                words.append("white" if rt.white else f"not white ({rt.acf_outside} lags outside the 99 % band)")
                if rt.independent:
                    words.append("independent of the input")
                else:
                    k = int(np.argmax(np.abs(rt.xcf)))
                    words.append(f"correlated with the input (r = {rt.xcf[k]:+.2f} at lag {rt.xlags[k]})")
                L.append(f"  residual of {ch}: " + ", ".join(words))
            ww = c.worst_windows()
            if ww and c.cost > 1e-12:
                L.append("  error concentrated in " + ", ".join(
                    f"t = {w['t0']:.4g}-{w['t1']:.4g} s ({100 * w['share']:.0f} %, {w['activity']})" for w in ww))
        corr = {k: v for k, v in self.signatures.items() if np.isfinite(v)}
        if corr and self.time and any(c.cost > 1e-12 for c in self.time):
            top = sorted(corr.items(), key=lambda kv: -abs(kv[1]))[:4]
            L.append("Residual signatures (correlation with the model's signals): "
                     + ", ".join(f"{k} {v:+.2f}" for k, v in top))
        return "\n".join(L)

    def __str__(self):
        return self.summary()

    def to_dict(self):
        return {"system": self.system, "cost": self.cost, "signatures": self.signatures, "evidence": self.evidence,
                "summary": self.summary(), "frf": [c.to_dict() for c in self.frf],
                "time": [c.to_dict() for c in self.time]}

    def to_json(self, path=None) -> str:
        """JSON text of the whole comparison; written to ``path`` if given."""
        text = json.dumps(_clean(self.to_dict()))
        if path is not None:
            Path(path).write_text(text)
        return text

    def plot(self, out_dir) -> list:
        """Write PNGs (overlays, residuals, error per band, resid tests, signatures) to ``out_dir``;
        returns their paths."""
        from bscomp.plotting.validate import comparison_plots

        return comparison_plots(self, out_dir)


def _fmt(x, spec=".3g"):
    return "n/a" if x is None or not np.isfinite(x) else format(x, spec)


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    return o


# ---- FRF comparison --------------------------------------------------------------------------------------------
def _model_poles(dae, data, fmin, fmax):
    """The model's elastic modes in the band, ``[(f, zeta, index, strong)]`` (``f`` = |p|/2 pi of the damped
    pole pair, the undamped frequency without one), or None when the model has no second-order form."""
    from bscomp.errors import NotLinearError
    from bscomp.linear.modal import modes

    try:
        md = modes(dae, inputs=data.inputs, outputs=data.outputs)
    except NotLinearError:
        return None
    out = []
    for k in np.flatnonzero(~md.rigid_body):
        pk = md.poles[k] if len(md.poles) > k else np.zeros(0)
        f = float(np.sqrt(abs(np.prod(pk))) / (2 * np.pi)) if pk.size == 2 else float(md.frequencies[k])
        if fmin <= f <= fmax:
            strong = bool(np.max(np.abs(md.residues[k])) > 0) if md.residues.size else True
            out.append((f, float(md.damping[k]), int(k), strong))
    return out


def _model_modes(poles, data, Hm):
    """Model resonances the measured pairs can show: ``[(f, zeta, index)]``.

    The model FRF's resonances are found by the same estimator as the measurement's (:func:`peak_pick`);
    an exact mode (``poles`` from :func:`_model_poles`) counts when one of them lies within 10 % (a mode
    the pairs cannot see is neither expected nor missed). Without exact modes, the estimates themselves.
    """
    peaks = merge_resonances([peak_pick(data.freqs, Hm[p], p, min_prominence_db=1.0) for p in data.H])
    if poles is None:
        return [(p.f, p.zeta, None) for p in peaks]
    return [(f, z, k) for f, z, k, strong in poles
            if any(abs(p.f - f) <= 0.1 * f for p in peaks) or (strong and not peaks)]


def _model_frf(dae, data, extra_freqs):
    """Model FRF at the measured frequencies and at ``extra_freqs`` (one FRF evaluation):
    ``({pair: H}, {pair: H at extra_freqs})``."""
    from bscomp.linear.response import frf

    n = data.freqs.size
    res = frf(dae, input=data.inputs, output=data.outputs, freqs=np.concatenate([data.freqs, extra_freqs]))
    H = {(i, o): res.H[:, res.outputs.index(o), res.inputs.index(i)] for i, o in data.H}
    return {p: h[:n] for p, h in H.items()}, {p: h[n:] for p, h in H.items()}


def _mode_rows(data, Hm, poles, Hx, tol) -> list:
    """The mode-pairing table: measured resonances against the model's (see :class:`ModePair`)."""
    meas = merge_resonances([peak_pick(data.freqs, data.H[p], p, coherence=data.coherence.get(p)) for p in data.H])
    mm = _model_modes(poles, data, Hm)
    pairs, used = _pair_modes(meas, mm, tol)
    fx = [] if poles is None else [p[0] for p in poles]
    rows = []
    for i, r in enumerate(meas):
        if i in pairs:
            fmod, zmod, idx = mm[pairs[i]]
            amp = float(abs(Hx[r.pair][fx.index(fmod)])) if fmod in fx else None
            rows.append(ModePair(r, fmod, zmod, amp, idx))
        else:
            rows.append(ModePair(r))
    rows += [ModePair(None, fmod, zmod, None, idx) for j, (fmod, zmod, idx) in enumerate(mm) if j not in used]
    return rows


def _pair_modes(measured, model_modes, tol):
    """Greedy pairing by nearest log-frequency within ``tol`` (relative)."""
    cand = []
    for i, r in enumerate(measured):
        for j, (f, _, _) in enumerate(model_modes):
            d = abs(np.log(f / r.f))
            if d <= np.log1p(tol):
                cand.append((d, i, j))
    cand.sort()
    mi, mj, pairs = set(), set(), {}
    for _, i, j in cand:
        if i in mi or j in mj:
            continue
        mi.add(i)
        mj.add(j)
        pairs[i] = j
    return pairs, mj


def _compare_frf(system, data: FrfData, bands, tol) -> FrfComparison:
    from bscomp.kernel.flattening import flatten
    from bscomp.validate.residuals import _check_names

    dae = flatten(system.linear_equivalent())     # once, for the FRF, the modes and the amplitudes
    _check_names(dae, data, data.inputs, data.outputs)
    f = data.freqs
    poles = _model_poles(dae, data, float(f.min()), float(f.max()))
    Hm, Hx = _model_frf(dae, data, np.array([] if poles is None else [p[0] for p in poles]))
    errs = frf_errors(Hm, data)
    mag_db = {p: 20 * e[0] for p, e in errs.items()}
    ph_deg = {p: np.degrees(e[1]) for p, e in errs.items()}
    wts = {p: e[2] for p, e in errs.items()}
    sq = {p: (e[2] * e[0]) ** 2 + (e[2] * e[1]) ** 2 for p, e in errs.items()}
    total = sum(float(s.sum()) for s in sq.values())
    n_res = 2 * sum(s.size for s in sq.values())
    cst = total / n_res if n_res else 0.0
    W = np.concatenate([wts[p] for p in data.H])
    W2 = max(float(np.sum(W ** 2)), 1e-300)
    rms_mag = float(np.sqrt(np.sum((W * np.concatenate([mag_db[p] for p in data.H])) ** 2) / W2))
    rms_ph = float(np.sqrt(np.sum((W * np.concatenate([ph_deg[p] for p in data.H])) ** 2) / W2))
    fit = {p: fit_percent(Hm[p], data.H[p]) for p in data.H}
    fit_lm = {p: fit_percent(20 * np.log10(np.abs(Hm[p]) + 1e-300), 20 * np.log10(np.abs(data.H[p]) + 1e-300))
              for p in data.H}
    if bands is None:
        bands = octave_bands(float(f[f > 0].min()) if np.any(f > 0) else 1.0, float(f.max()))
    band_rows = []
    for p in data.H:
        for lo, hi in bands:
            sel = (f >= lo) & (f < hi)
            if not sel.any():
                continue
            w = wts[p][sel]
            ws = max(np.sum(w ** 2), 1e-300)
            band_rows.append({"pair": p, "lo": float(lo), "hi": float(hi), "n": int(sel.sum()),
                              "rms_mag_db": float(np.sqrt(np.sum((w * mag_db[p][sel]) ** 2) / ws)),
                              "rms_phase_deg": float(np.sqrt(np.sum((w * ph_deg[p][sel]) ** 2) / ws)),
                              "share": float(sq[p][sel].sum() / total) if total > 0 else 0.0})
    # phase error slope -> apparent delay
    fs, es, ws_ = [], [], []
    for e in errs.values():
        fs.append(f)
        es.append(np.unwrap(e[1]))
        ws_.append(e[2])
    fcat, ecat, wcat = np.concatenate(fs), np.concatenate(es), np.concatenate(ws_)
    delay, r2 = np.nan, np.nan
    if fcat.size >= 3 and np.ptp(fcat) > 0:
        A = np.column_stack([-2 * np.pi * fcat, np.ones_like(fcat)]) * wcat[:, None]
        sol, *_ = np.linalg.lstsq(A, ecat * wcat, rcond=None)
        delay = float(sol[0])
        resid_ = ecat * wcat - A @ sol
        ss = float(np.sum((ecat * wcat - np.mean(ecat * wcat)) ** 2))
        r2 = float(1 - np.sum(resid_ ** 2) / ss) if ss > 0 else np.nan
    rows = _mode_rows(data, Hm, poles, Hx, tol)
    return FrfComparison(source=data.source, freqs=f, measured=dict(data.H), model=Hm, units=dict(data.units),
                         mag_error_db=mag_db, phase_error_deg=ph_deg, weights=wts, fit=fit, fit_logmag=fit_lm,
                         rms_mag_db=rms_mag, rms_phase_deg=rms_ph, bands=band_rows, modes=rows,
                         phase_delay_s=delay, phase_delay_r2=r2, cost=cst, conditions=dict(data.conditions),
                         pair_errors={r.pop("pair"): r for r in _frf_user_rows(errs)})


# ---- time comparison ------------------------------------------------------------------------------------------
def _signal_names(system):
    """Observables of the model used for signatures: the heaviest mass (the table) and the lead screw."""
    from bscomp.components import IdealLeadScrew, Mass

    masses, leads = [], []
    for name, comp in system.leaves():
        if isinstance(comp, Mass):
            masses.append((float(np.max(comp.m)), name))
        elif isinstance(comp, IdealLeadScrew):
            leads.append(name)
    names = {}
    if masses:
        table = max(masses)[1]
        names.update({"s": f"{table}.s", "v": f"{table}.v", "a": f"{table}.a"})
        if leads:
            names["nut"] = f"{leads[0]}.flange_b.s"
    return names


def _corr(a, b):
    a = np.asarray(a, float) - np.mean(a)
    b = np.asarray(b, float) - np.mean(b)
    den = np.linalg.norm(a) * np.linalg.norm(b)
    return float(np.dot(a, b) / den) if den > 0 else 0.0


def _reversal_indicator(t, v):
    """1 near velocity sign changes (within the time |v| stays under 10 % of its peak), else 0."""
    vmax = np.max(np.abs(v)) if v.size else 0.0
    ind = np.zeros(v.size)
    if vmax == 0:
        return ind
    s = np.sign(np.where(np.abs(v) < 1e-6 * vmax, 0.0, v))
    nz = np.flatnonzero(s)
    if nz.size < 2:
        return ind
    flips = nz[1:][s[nz[1:]] != s[nz[:-1]]]
    slow = np.abs(v) < 0.1 * vmax
    for k in flips:
        lo = k
        while lo > 0 and slow[lo - 1]:
            lo -= 1
        hi = k
        while hi < v.size - 1 and slow[hi + 1]:
            hi += 1
        ind[lo:hi + 1] = 1.0
    return ind


def _compare_time(system, data: TimeData, n_windows) -> TimeComparison:
    names = _signal_names(system)
    res = simulate_at(system, data, extra=list(names.values()))
    t = data.t
    y_hat = {n: np.asarray(res[n], float) for n in data.outputs}
    e = {n: data.outputs[n] - y_hat[n] for n in data.outputs}
    fit = {n: fit_percent(y_hat[n], data.outputs[n]) for n in data.outputs}
    rms = {n: (float(np.sqrt(np.mean(y ** 2))) or 1.0) for n, y in data.outputs.items()}
    en = {n: e[n] / rms[n] for n in e}
    cst = float(np.mean(np.concatenate([en[n] ** 2 for n in en]))) if en else 0.0
    u0 = next(iter(data.inputs.values()))
    rt = {n: resid(e[n], u0) for n in e}
    sig = {}
    if "v" in names and names["v"] in res.outputs:
        v = np.asarray(res[names["v"]], float)
        vmax = np.max(np.abs(v)) if v.size else 0.0
        sig["velocity"] = v
        sig["sign_velocity"] = np.sign(np.where(np.abs(v) < 1e-3 * vmax, 0.0, v))
        sig["reversal"] = _reversal_indicator(t, v)
        sig["acceleration"] = np.asarray(res[names["a"]], float)
        sig["position"] = np.asarray(res[names["s"]], float)
        if "nut" in names and names["nut"] in res.outputs:
            sig["screw_stretch"] = np.asarray(res[names["nut"]], float) - sig["position"]
    sig["input"] = u0
    signatures, delays = {}, {}
    for n in e:
        d = {}
        for k, x in sig.items():
            d[k] = _corr(np.abs(e[n]), x) if k == "reversal" else _corr(e[n], x)
        ydot = np.gradient(y_hat[n], t)
        d["output_rate"] = _corr(e[n], ydot)
        dd = float(np.dot(ydot, ydot))
        delays[n] = float(-np.dot(e[n], ydot) / dd) if dd > 0 else 0.0
        signatures[n] = d
    # windows
    edges = np.linspace(t[0], t[-1], n_windows + 1)
    sq = sum(en[n] ** 2 for n in en)
    tot = float(sq.sum())
    windows = []
    for k in range(n_windows):
        sel = (t >= edges[k]) & ((t < edges[k + 1]) if k < n_windows - 1 else (t <= edges[k + 1]))
        if not sel.any():
            continue
        act = "-"
        if "velocity" in sig:
            v = sig["velocity"]
            vmax = np.max(np.abs(v)) or 1.0
            a = sig["acceleration"]
            amax = np.max(np.abs(a)) or 1.0
            if np.any(sig["reversal"][sel] > 0):
                act = "velocity reversal"
            elif np.max(np.abs(v[sel])) < 0.02 * vmax:
                act = "rest"
            elif np.max(np.abs(a[sel])) > 0.3 * amax:
                act = "acceleration"
            else:
                act = "constant velocity"
        windows.append({"t0": float(edges[k]), "t1": float(edges[k + 1]),
                        "share": float(sq[sel].sum() / tot) if tot > 0 else 0.0, "activity": act})
    return TimeComparison(source=data.source, t=t, inputs=dict(data.inputs), measured=dict(data.outputs),
                          model=y_hat, residual=e, units=dict(data.units), fit=fit, resid=rt, signals=sig,
                          signatures=signatures, windows=windows, cost=cst, conditions=dict(data.conditions),
                          delays=delays)


# ---- the error as the user reads it --------------------------------------------------------------------------
def _frf_user_rows(errs: dict) -> list:
    """Rows of :func:`user_errors` from :func:`~bscomp.validate.residuals.frf_errors`' output."""
    rows = []
    for p, (e_mag, e_ph, w) in errs.items():
        w2 = np.asarray(w, float) ** 2
        sw = max(float(w2.sum()), 1e-300)
        rows.append({"pair": p, "mag_mean_abs_dlog10": float(np.sum(w2 * np.abs(e_mag)) / sw),
                     "mag_db_rms": float(20 * np.sqrt(np.sum(w2 * e_mag ** 2) / sw)),
                     "phase_deg_rms": float(np.degrees(np.sqrt(np.sum(w2 * e_ph ** 2) / sw)))})
    return rows


def user_errors(model_outputs, datasets) -> dict:
    """The errors as the user reads them, from model outputs already computed.

    Parameters
    ----------
    model_outputs : sequence or dict
        Per dataset (a sequence in dataset order, or a dict keyed by dataset index): ``{(input, output): H}``
        (complex, at the dataset's frequencies) for an :class:`FrfData`, ``{channel: y}`` (at the
        dataset's times) for a :class:`TimeData`. With a single dataset, its outputs directly.
    datasets : sequence of FrfData / TimeData, or one dataset

    Returns
    -------
    dict
        ``{index: {"frf": [...], "time": [...]}}``. FRF rows ``{"pair": (input, output),
        "mag_mean_abs_dlog10": mean |log10|H_m| - log10|H||, "mag_db_rms": rms of 20 log10 |H_m/H| [dB],
        "phase_deg_rms": rms wrapped phase difference [deg]}``, coherence-weighted where coherence was
        measured (each point by its coherence; plain means otherwise); time rows ``{"channel", "fit_percent"}``
        (MATLAB ``compare`` fit, :func:`~bscomp.validate.residuals.fit_percent`). The same numbers as
        :attr:`FrfComparison.pair_errors` and :attr:`TimeComparison.fit`.
    """
    if isinstance(datasets, (FrfData, TimeData)):
        datasets, model_outputs = [datasets], [model_outputs]
    datasets = list(datasets)
    if isinstance(model_outputs, dict) and all(isinstance(k, (int, np.integer)) for k in model_outputs):
        items = sorted(model_outputs.items())
    else:
        items = list(enumerate(model_outputs))
    out = {}
    for k, y in items:
        d = datasets[k]
        if isinstance(d, FrfData):
            out[int(k)] = {"frf": _frf_user_rows(frf_errors(y, d)), "time": []}
        elif isinstance(d, TimeData):
            missing = [n for n in d.outputs if n not in y]
            if missing:
                raise KeyError(f"model response has no channel {missing[0]!r}; channels: {list(y)}")
            out[int(k)] = {"frf": [], "time": [{"channel": n, "fit_percent": fit_percent(np.asarray(y[n], float), m)}
                                             for n, m in d.outputs.items()]}
        else:
            raise TypeError(f"expected FrfData or TimeData, got {type(d).__name__}")
    return out


# ---- the analysis -----------------------------------------------------------------------------------------------
def compare(system_or_build, datasets, params: dict | None = None, bands=None, pair_tolerance: float = 0.3,
            n_windows: int = 20) -> Comparison:
    """Compare a model with measurements.

    Parameters
    ----------
    system_or_build : System, callable or str
        The model; a callable is called as ``build(**conditions)`` per dataset, a string is a registered
        system name or ``.py`` path (see :func:`bscomp.validate.residuals.build_for`).
    datasets : list of FrfData, TimeData or file paths
    params : dict, optional
        Parameter overrides by dotted name.
    bands : list of (lo, hi), optional
        Frequency bands [Hz] for the error breakdown; default octaves.
    pair_tolerance : float
        Largest relative frequency difference for pairing a measured resonance with a model mode.
    n_windows : int
        Number of equal time windows for locating the error in time series.

    Returns
    -------
    Comparison
    """
    if isinstance(datasets, (FrfData, TimeData, str, Path)):
        datasets = [datasets]
    datasets = load_all(datasets)
    frf_c, time_c = [], []
    name = getattr(system_or_build, "name", None) or getattr(system_or_build, "__name__", None) or str(system_or_build)
    for k, d in enumerate(datasets):
        if not isinstance(d, (FrfData, TimeData)):
            raise TypeError(f"expected FrfData, TimeData or a file path, got {type(d).__name__}")
        system = build_for(system_or_build, d.conditions, params, source=d.source)
        name = system.name
        c = _compare_frf(system, d, bands, pair_tolerance) if isinstance(d, FrfData) else _compare_time(system, d,
                                                                                                        n_windows)
        c.index = k
        (frf_c if isinstance(d, FrfData) else time_c).append(c)
    all_c = frf_c + time_c
    cst = float(np.mean([c.cost for c in all_c])) if all_c else 0.0
    sigs: dict = {}
    ev: dict = {}
    for c in time_c:
        for ch, d in c.signatures.items():
            for k, v in d.items():
                if k not in sigs or abs(v) > abs(sigs[k]):
                    sigs[k] = float(v)
                    if k == "output_rate":
                        ev["time_delay_s"] = c.delays[ch]
    for c in frf_c:
        if np.isfinite(c.phase_delay_s) and (c.phase_delay_r2 or 0) > ev.get("frf_phase_delay_r2", -1):
            ev["frf_phase_delay_s"] = c.phase_delay_s
            ev["frf_phase_delay_r2"] = float(c.phase_delay_r2) if np.isfinite(c.phase_delay_r2) else 0.0
        errs = [abs(m.freq_error_pct) for m in c.paired]
        ev["frf_max_freq_error_pct"] = max([ev.get("frf_max_freq_error_pct", 0.0)] + errs)
        ev["frf_unmatched_measured"] = ev.get("frf_unmatched_measured", 0.0) + len(c.unmatched_measured)
        ev["frf_unmatched_model"] = ev.get("frf_unmatched_model", 0.0) + len(c.unmatched_model)
    return Comparison(system=name, frf=frf_c, time=time_c, cost=cst, signatures=sigs, evidence=ev)
