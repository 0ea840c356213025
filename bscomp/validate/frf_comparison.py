"""An FRF dataset against the model: log-magnitude [dB] and phase [deg] error overall and per band, fit %
per pair, the phase error's slope as an apparent delay, and the **mode-pairing table** -- measured
resonances (the poles of a local modal fit of the complex FRF started from the peaks of :math:`|H|`,
:func:`~bscomp.validate.peaks.peak_pick`) against the model's poles (:func:`bscomp.linear.modal.modes`).
The model FRF's resonances are found by the same estimator (they decide which model modes the measured
pairs can show). Residuals are measured minus model (:mod:`bscomp.validate.residuals`).

The model is the system's small-signal equivalent (friction reduced to its viscous part, backlash engaged: what
calibrate and diagnose fit). When the file declares the sine amplitude it was measured at (``# excitation
amp.u: 2 V``) and the model has friction or backlash, the model at that amplitude is compared too
(:func:`bscomp.simulation.describing.describing_frf`; :attr:`FrfComparison.at_amplitude`), so a user sees how much
of the error is the amplitude and how much a missing effect.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import BscompError, NotLinearError
from bscomp.kernel.flattening import flatten
from bscomp.linear.modal import modes
from bscomp.linear.response import frf
from bscomp.simulation.compiled import nonlinear_elements
from bscomp.simulation.describing import describing_frf, frequency_share, spans
from bscomp.validate.datasets import AMPLITUDE_HARMONICS, FrfData
from bscomp.validate.peaks import Resonance, merge_resonances, peak_pick
from bscomp.validate.residuals import check_channels, fit_percent, frf_errors

__all__ = ["FrfComparison", "ModePair", "compare_frf", "octave_bands", "frf_user_rows"]


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
    at_amplitude : dict or None
        With a declared excitation amplitude and a model with friction/backlash: ``excitation`` ({input:
        amplitude}), ``elements``, ``model`` ({pair: H} at that amplitude by the describing function; the
        small-signal H for pairs of other inputs), ``rms_mag_db``, ``rms_phase_deg``, ``residual`` (the
        harmonic balance's, largest), ``resonances`` ([(f, zeta)] of the model at that amplitude, by the
        measurement's own estimator), ``small_signal`` ({element: {freqs, of, spans, where}}: where the element stays
        within 5 % of its tangent at rest at that amplitude, :meth:`DescribingFrf.small_signal`); or ``error``
        (why it could not be taken).
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
    at_amplitude: dict | None = None

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
                "phase_delay_s": self.phase_delay_s, "phase_delay_r2": self.phase_delay_r2,
                "at_amplitude": _amplitude_dict(self.at_amplitude, pk)}


def _amplitude_dict(a, pk):
    if a is None or "model" not in a:
        return a
    return dict(a, model={pk(p): {"re": h.real.tolist(), "im": h.imag.tolist()} for p, h in a["model"].items()})



def _model_poles(dae, data, fmin, fmax):
    """The model's elastic modes in the band, ``[(f, zeta, index, strong)]`` (``f`` = |p|/2 pi of the damped
    pole pair, the undamped frequency without one), or None when the model has no second-order form."""
    try:
        md = modes(dae, inputs=data.inputs, outputs=data.outputs, warn=False)
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
    n = data.freqs.size
    with np.errstate(divide="ignore", invalid="ignore"):        # an undamped model at its own pole: inf
        res = frf(dae, input=data.inputs, output=data.outputs, freqs=np.concatenate([data.freqs, extra_freqs]),
                  warn=False)
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


def compare_frf(system, data: FrfData, bands=None, tol: float = 0.3) -> FrfComparison:
    """Compare the FRF of ``system`` (built at the dataset's conditions) with a measured one.

    The system's small-signal equivalent is flattened once for the FRF, the modes and the amplitudes at
    the model's resonances. ``bands``: ``(lo, hi)`` [Hz] for the error breakdown (default octaves);
    ``tol``: the largest relative frequency difference for pairing a measured resonance with a model mode.
    """
    dae = flatten(system.linear_equivalent())     # once, for the FRF, the modes and the amplitudes
    check_channels(dae, data, data.inputs, data.outputs)
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
    rms_mag, rms_ph = _weighted_rms(errs, data)
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
                         pair_errors={r.pop("pair"): r for r in frf_user_rows(errs)},
                         at_amplitude=_at_amplitude(system, data, Hm) if data.excitation else None)


def _weighted_rms(errs, data):
    """Coherence-weighted RMS magnitude [dB] and phase [deg] errors over every pair."""
    W = np.concatenate([errs[p][2] for p in data.H])
    W2 = max(float(np.sum(W ** 2)), 1e-300)
    mag = np.concatenate([20 * errs[p][0] for p in data.H])
    ph = np.concatenate([np.degrees(errs[p][1]) for p in data.H])
    return float(np.sqrt(np.sum((W * mag) ** 2) / W2)), float(np.sqrt(np.sum((W * ph) ** 2) / W2))


def _at_amplitude(system, data, Hm):
    """The model at the measured excitation amplitudes (module docstring): ``FrfComparison.at_amplitude``."""
    if not nonlinear_elements(system):
        return None
    dae = flatten(system)
    H, elements, residual, stuck = dict(Hm), [], 0.0, {}
    try:
        for inp, a in data.excitation.items():
            outs = [o for i, o in data.H if i == inp]
            r = describing_frf(dae, inp, outs, data.freqs, a, harmonics=AMPLITUDE_HARMONICS)
            H.update({(inp, o): r.H[:, j, 0] for j, o in enumerate(outs)})
            elements, residual = r.elements, max(residual, float(r.residual.max(initial=0.0)))
            stuck.update({el: {"freqs": f.tolist(), "of": int(r.freqs.size), "spans": spans(r.freqs, f),
                               "where": frequency_share(r.freqs, f)} for el, f in r.small_signal().items()})
    except BscompError as exc:          # e.g. a current limit the describing function does not treat
        return {"excitation": dict(data.excitation), "error": str(exc)}
    mag, ph = _weighted_rms(frf_errors(H, data), data)
    peaks = merge_resonances([peak_pick(data.freqs, H[p], p, min_prominence_db=1.0) for p in data.H
                              if p[0] in data.excitation])
    return {"excitation": dict(data.excitation), "elements": elements, "harmonics": AMPLITUDE_HARMONICS,
            "model": H, "rms_mag_db": mag,
            "rms_phase_deg": ph, "residual": residual, "resonances": [(r.f, r.zeta) for r in peaks],
            "small_signal": stuck}



def frf_user_rows(errs: dict) -> list:
    """Rows of :func:`user_errors` from :func:`~bscomp.validate.residuals.frf_errors`' output."""
    rows = []
    for p, (e_mag, e_ph, w) in errs.items():
        w2 = np.asarray(w, float) ** 2
        sw = max(float(w2.sum()), 1e-300)
        rows.append({"pair": p, "mag_mean_abs_dlog10": float(np.sum(w2 * np.abs(e_mag)) / sw),
                     "mag_db_rms": float(20 * np.sqrt(np.sum(w2 * e_mag ** 2) / sw)),
                     "phase_deg_rms": float(np.degrees(np.sqrt(np.sum(w2 * e_ph ** 2) / sw)))})
    return rows

