"""Compare a model with measurements and say where it fails (issue 8; thesis Sec 3.5).

:func:`compare` evaluates the model at every dataset's conditions and returns a :class:`Comparison`:

FRF datasets (:class:`~bscomp.validate.frf_comparison.FrfComparison`)
    log-magnitude [dB] and phase [deg] error overall and per band (octaves or user bands) with each band's
    share of the squared residual; fit % per pair (MATLAB ``compare``, on the complex FRF, and on
    log-magnitude); a **mode-pairing table** -- measured resonances, the poles of a local modal fit of the
    complex FRF started from the peaks of :math:`|H|` (:func:`peak_pick`, :mod:`bscomp.validate.peaks`),
    against the model's poles (:func:`bscomp.linear.modal.modes`): frequency error, damping, amplitude; measured
    resonances with no model counterpart and model modes the measurement does not show; the phase
    error's slope as an apparent time delay. The model FRF's resonances are found by the same estimator
    (they decide which model modes the measured pairs can show).
Time series (:class:`~bscomp.validate.time_comparison.TimeComparison`)
    fit % per channel, the residual over time and its worst windows, MATLAB ``resid``'s whiteness and
    input-independence tests (:func:`~bscomp.validate.residual_tests.resid`) and the correlation of the
    residual with physically meaningful signals of the model's own simulation -- table velocity, its sign,
    velocity reversals, acceleration, screw stretch, position, input, output rate -- the **signatures** a
    missing effect leaves (Coulomb friction: sign of velocity; backlash: reversals; a compliance: acceleration or
    stretch; a delay: output rate; :mod:`~bscomp.validate.signatures`).

Residuals are measured minus model (:mod:`bscomp.validate.residuals`). This module holds the whole
result (:class:`Comparison`), :func:`compare` and :func:`user_errors` (the errors as the user reads them).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from bscomp.files import atomic_write
from bscomp.model import model_name
from bscomp.plotting.validate import comparison_plots
from bscomp.simulation.describing import SMALL_SIGNAL
from bscomp.validate.amplitude import amplitude_dependence
from bscomp.validate.arguments import check_compare, load_datasets
from bscomp.validate.datasets import FrfData, TimeData
from bscomp.validate.frf_comparison import compare_frf, frf_user_rows
from bscomp.validate.residuals import build_for_data, fit_percent, frf_errors
from bscomp.validate.signatures import SIGNATURES
from bscomp.validate.time_comparison import compare_time

__all__ = ["compare", "Comparison", "user_errors"]


@dataclass
class Comparison:
    """Result of :func:`compare`: one entry per dataset, the overall cost and the residual signatures.

    Attributes
    ----------
    system : str
    frf : list of :class:`~bscomp.validate.frf_comparison.FrfComparison`
    time : list of :class:`~bscomp.validate.time_comparison.TimeComparison`
    cost : float
        Mean over datasets of the mean squared residual (as :func:`bscomp.validate.residuals.cost`).
    signatures : dict str -> float
        Correlations in [-1, 1] of the time-series residual with the model's physical signals (keys in
        :data:`~bscomp.validate.signatures.SIGNATURES`), each the value with the largest magnitude over
        channels and datasets. Empty without time series.
    evidence : dict str -> float
        Other numbers for the diagnosis (keys in :data:`~bscomp.validate.signatures.EVIDENCE`): apparent
        delays, largest resonance frequency error, counts of unpaired resonances.
    amplitude : list of AmplitudeDependence
        FRF pairs measured at two stated amplitudes compared with themselves, without the model
        (:func:`~bscomp.validate.amplitude.amplitude_dependence`): where they differ beyond noise the drive is
        nonlinear there.
    """

    system: str
    frf: list
    time: list
    cost: float
    signatures: dict
    evidence: dict = field(default_factory=dict)
    amplitude: list = field(default_factory=list)

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
            a = c.at_amplitude
            if a is not None:
                exc = ", ".join(f"a sine of {v:g} on {k}" for k, v in a["excitation"].items())
                L.append(f"  at the measured excitation ({exc}) by the harmonic balance ({a.get('harmonics', 1)} odd "
                         f"harmonics) of {', '.join(a['elements'])}: magnitude error {a['rms_mag_db']:.2f} dB rms, "
                         f"phase error {a['rms_phase_deg']:.1f} deg rms (the figures above: the small-signal model)"
                         if "error" not in a else f"  not compared at the measured excitation ({exc}): {a['error']}")
                if a.get("resonances"):
                    L.append("    the model's resonances at that amplitude: " + ", ".join(
                        f"{f_:.4g} Hz (zeta {z:.3g})" for f_, z in a["resonances"]))
                for el, st in (a.get("small_signal") or {}).items():
                    L.append(f"    at that amplitude the model's {el} stays at its slope at rest (within "
                             f"{100 * SMALL_SIGNAL:g} %: friction stuck, a clearance not crossed) {st['where']}: there "
                             "the file measures that slope, not the element's level")
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
        if self.amplitude:
            L.append("FRFs measured at two amplitudes (the data alone): " + "; ".join(a.summary()
                                                                                    for a in self.amplitude))
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
            L.extend(f"  {o.describe()}" for o in c.orders)
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
                "time": [c.to_dict() for c in self.time], "amplitude": [a.to_dict() for a in self.amplitude]}

    def to_json(self, path=None) -> str:
        """JSON text of the whole comparison; written to ``path`` if given."""
        text = json.dumps(_clean(self.to_dict()))
        if path is not None:
            with atomic_write(path, what="Comparison.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def plot(self, out_dir) -> list:
        """Write PNGs (overlays, residuals, error per band, resid tests, signatures) to ``out_dir``;
        returns their paths."""
        return comparison_plots(self, out_dir, signature_names=tuple(SIGNATURES))


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
            out[int(k)] = {"frf": frf_user_rows(frf_errors(y, d)), "time": []}
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
        Frequency bands [Hz] for the error breakdown, ``0 < lo < hi``, each holding a measured frequency;
        default octaves.
    pair_tolerance : float
        Largest relative frequency difference (> 0) for pairing a measured resonance with a model mode.
    n_windows : int
        Number of equal time windows (>= 1) for locating the error in time series.

    Returns
    -------
    Comparison

    Raises
    ------
    UsageError
        An argument out of range or no dataset (:mod:`bscomp.validate.arguments`).
    """
    datasets = load_datasets(datasets, "compare")
    bands, pair_tolerance, n_windows = check_compare(bands, pair_tolerance, n_windows, datasets)
    frf_c, time_c = [], []
    name = model_name(system_or_build)
    for k, d in enumerate(datasets):
        if not isinstance(d, (FrfData, TimeData)):
            raise TypeError(f"expected FrfData, TimeData or a file path, got {type(d).__name__}")
        system = build_for_data(system_or_build, d, params)
        name = system.name
        c = compare_frf(system, d, bands, pair_tolerance) if isinstance(d, FrfData) else compare_time(system, d,
                                                                                                      n_windows)
        c.index = k
        (frf_c if isinstance(d, FrfData) else time_c).append(c)
    all_c = frf_c + time_c
    cst = float(np.mean([c.cost for c in all_c])) if all_c else 0.0
    sigs, ev = _signatures_and_evidence(frf_c, time_c)
    return Comparison(system=name, frf=frf_c, time=time_c, cost=cst, signatures=sigs, evidence=ev,
                      amplitude=amplitude_dependence(datasets))


def _signatures_and_evidence(frf_c, time_c):
    """:attr:`Comparison.signatures` (per signal, the correlation of largest magnitude over channels and
    datasets) and :attr:`Comparison.evidence` (delays, resonance errors, unpaired counts)."""
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
    return sigs, ev
