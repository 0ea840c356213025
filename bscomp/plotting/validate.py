"""Figures of validation results (matplotlib imported lazily, as in :mod:`bscomp.plotting`): FRF overlays
with resonance markers, error per band, time overlays with residuals, MATLAB-``resid`` correlation plots,
the residual signatures, a diagnosis's error staircase and candidate ranking, a calibration's parameters
and errors.

The figures receive the numbers (result objects of :mod:`bscomp.validate` are read, never asked to
compute) and import nothing from :mod:`bscomp.validate`: what a figure needs from there (the names of the
residual signatures) is passed in by the caller.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np

from bscomp.plotting.base import _finish, _plt, figure_folder, save_figure

__all__ = ["comparison_plots", "frf_comparison_plot", "band_error_plot", "time_comparison_plot",
           "resid_plot", "signature_plot", "plot_diagnosis", "calibration_plot", "amplitude_plot", "order_plot"]


def _slug(text):
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(str(text)).name)[:60] or "data"


def _wrapped(text: str, width: int) -> str:
    """A title broken into lines of at most ``width`` characters (a data file's source can be a long sentence)."""
    return "\n".join(textwrap.wrap(str(text), width)) or str(text)


def _hz(f: float) -> str:
    """A frequency for a tick: three significant digits below 100 Hz, whole hertz above (1000, not 1e+03)."""
    return f"{f:.3g}" if f < 100 else f"{f:.0f}"


def frf_comparison_plot(fc, path=None, title=None):
    """Measured and model magnitude [dB] and phase [deg] per pair, resonances marked (x measured,
    dotted lines model modes, red: unpaired); dashed, the model at the measured excitation amplitude when the
    file declares one (:attr:`~bscomp.validate.frf_comparison.FrfComparison.at_amplitude`)."""
    plt = _plt()
    pairs = list(fc.measured)
    fig, axes = plt.subplots(2, len(pairs), sharex=True, figsize=(6.5 * len(pairs), 6), squeeze=False)
    f = fc.freqs
    for j, p in enumerate(pairs):
        am, ap = axes[0, j], axes[1, j]
        hm, hh = fc.measured[p], fc.model[p]
        am.semilogx(f, 20 * np.log10(np.abs(hm) + 1e-300), "k.", ms=2.5, label="measured")
        am.semilogx(f, 20 * np.log10(np.abs(hh) + 1e-300), "C0-", lw=1.2, label="model")
        ap.semilogx(f, np.degrees(np.angle(hm)), "k.", ms=2.5)
        ap.semilogx(f, np.degrees(np.angle(hh)), "C0-", lw=1.2)
        a = fc.at_amplitude or {}
        if "model" in a and p[0] in a["excitation"]:          # the model at the measured sine amplitude
            ha = a["model"][p]
            am.semilogx(f, 20 * np.log10(np.abs(ha) + 1e-300), "C1--", lw=1.2,
                        label=f"model at {p[0]} = {a['excitation'][p[0]]:g} (describing function)")
            ap.semilogx(f, np.degrees(np.angle(ha)), "C1--", lw=1.2)
        for m in fc.modes:
            if m.model_f is not None:
                am.axvline(m.model_f, color="C0" if m.measured is not None else "r", ls=":", lw=0.8)
            if m.measured is not None and p in m.measured.pairs:
                r = m.measured         # its fitted amplitude is of its own pair; on the others, the measured |H| there
                amp = r.amplitude if tuple(p) == tuple(r.pair) else float(np.interp(r.f, f, np.abs(hm)))
                am.plot([r.f], [20 * np.log10(amp)], "x", color="k" if m.model_f is not None else "r", ms=8)
        am.set_title(f"{p[1]} / {p[0]} [{fc.units.get(p, '')}]", fontsize=9)
        am.set_ylabel("magnitude [dB]")
        ap.set_ylabel("phase [deg]")
        ap.set_xlabel("frequency [Hz]")
        for ax in (am, ap):
            ax.grid(True, which="both", alpha=0.3)
        am.legend(fontsize=8)
    fig.suptitle(_wrapped(title or f"{fc.source}: measured vs model", int(10 * 6.5 * len(pairs))))
    return _finish(fig, plt, path)


def band_error_plot(fc, path=None, title=None):
    """Share of the squared residual per band (stacked over pairs) and RMS magnitude error per band."""
    plt = _plt()
    bands = sorted({(b["lo"], b["hi"]) for b in fc.bands})
    pairs = list(fc.measured)
    x = np.arange(len(bands))
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    bottom = np.zeros(len(bands))
    for p in pairs:
        s = np.array([sum(b["share"] for b in fc.bands if b["pair"] == p and (b["lo"], b["hi"]) == bb) for bb in bands])
        m = np.array([next((b["rms_mag_db"] for b in fc.bands if b["pair"] == p and (b["lo"], b["hi"]) == bb), 0.0)
                      for bb in bands])
        a1.bar(x, 100 * s, bottom=bottom, label=f"{p[1]}/{p[0]}")
        bottom += 100 * s
        a2.plot(x, m, "o-", label=f"{p[1]}/{p[0]}")
    a1.set_ylabel("share of error [%]")
    a2.set_ylabel("rms magnitude error [dB]")
    a2.set_xticks(x)
    a2.set_xticklabels([_hz(np.sqrt(lo * hi)) for lo, hi in bands], rotation=45)
    a2.set_xlabel("band centre [Hz]")
    for ax in (a1, a2):
        ax.grid(True, alpha=0.3)
    a1.legend(fontsize=8)
    a1.set_title(_wrapped(title or f"{fc.source}: where the FRF error is", 90), fontsize=9)
    return _finish(fig, plt, path)


def time_comparison_plot(tc, path=None, title=None):
    """Measured and simulated channels with the residual (measured - model) under each; worst windows
    shaded."""
    plt = _plt()
    chans = list(tc.measured)
    fig, axes = plt.subplots(2 * len(chans), 1, sharex=True, figsize=(8, 2.2 + 2.6 * len(chans)), squeeze=False)
    worst = tc.worst_windows()
    for k, ch in enumerate(chans):
        ay, ae = axes[2 * k, 0], axes[2 * k + 1, 0]
        ay.plot(tc.t, tc.measured[ch], "k-", lw=1.0, label="measured")
        ay.plot(tc.t, tc.model[ch], "C0--", lw=1.0, label=f"model (fit {tc.fit[ch]:.1f} %)")
        ay.set_ylabel(f"{ch} [{tc.units.get(ch, '')}]", fontsize=8)
        ay.legend(fontsize=8, loc="upper right")
        ae.plot(tc.t, tc.residual[ch], "C3-", lw=0.8)
        unit = tc.units.get(ch, "")
        ae.set_ylabel(f"residual [{unit}]" if unit else "residual", fontsize=8)
        for w in worst:
            for ax in (ay, ae):
                ax.axvspan(w["t0"], w["t1"], color="orange", alpha=0.15)
        for ax in (ay, ae):
            ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].set_title(_wrapped(title or f"{tc.source}: measured vs model (shaded: windows carrying most error)",
                                  90), fontsize=9)
    return _finish(fig, plt, path)


def resid_plot(tc, path=None, title=None):
    """Residual autocorrelation and cross-correlation with the input, 99 % bands (MATLAB ``resid``)."""
    plt = _plt()
    chans = list(tc.resid)
    fig, axes = plt.subplots(len(chans), 2, figsize=(9, 2.4 + 2.2 * len(chans)), squeeze=False)
    for k, ch in enumerate(chans):
        r = tc.resid[ch]
        a, b = axes[k, 0], axes[k, 1]
        a.stem(r.lags, r.acf, basefmt=" ")
        a.axhspan(-r.acf_bound, r.acf_bound, color="C2", alpha=0.2)
        a.set_title(f"{ch}: autocorrelation ({'white' if r.white else 'not white'})", fontsize=9)
        b.stem(r.xlags, r.xcf, basefmt=" ")
        b.axhspan(-r.xcf_bound, r.xcf_bound, color="C2", alpha=0.2)
        b.set_title(f"cross-correlation with input ({'independent' if r.independent else 'correlated'})", fontsize=9)
        for ax in (a, b):
            ax.set_xlabel("lag [samples]")
            ax.grid(True, alpha=0.3)
    fig.suptitle(_wrapped(title or f"{tc.source}: residual tests (99 % confidence)", 85))
    return _finish(fig, plt, path)


def signature_plot(signatures, path=None, title=None, names=None):
    """Correlation of the residual with physical signals (horizontal bars).

    ``signatures``: ``{signal: correlation}``; ``names``: the signals to show, in the order of
    ``signatures`` (default: all of them).
    """
    plt = _plt()
    items = [(k, v) for k, v in signatures.items() if (names is None or k in names) and np.isfinite(v)]
    fig, ax = plt.subplots(figsize=(7, 0.8 + 0.4 * max(len(items), 1)))
    if items:
        names, vals = zip(*items)
        ax.barh(range(len(vals)), vals, color=["C3" if abs(v) > 0.5 else "C0" for v in vals])
        ax.set_yticks(range(len(vals)))
        ax.set_yticklabels(names)
    ax.set_xlim(-1, 1)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("correlation with the residual")
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title(title or "residual signatures")
    return _finish(fig, plt, path)


def amplitude_plot(found, path=None, title=None):
    """The same pairs measured at two amplitudes: ``20 log10 |H_high/H_low|`` [dB] and the phase difference [deg]
    over frequency, filled where they differ by more than twice their noise (``z > 2``). ``found``: a list of
    :class:`~bscomp.validate.amplitude.AmplitudeDependence` (read, never asked to compute)."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for k, a in enumerate(found):
        i, o = a.pair
        lbl = f"{o}/{i}: {a.amplitudes[1]:g} vs {a.amplitudes[0]:g} ({a.verdict})"
        a1.semilogx(a.freqs, a.db, "o-", color=f"C{k}", label=lbl, ms=4)
        a2.semilogx(a.freqs, a.phase_deg, "o-", color=f"C{k}", ms=4)
        beyond = a.z > 2.0
        a1.plot(a.freqs[beyond], a.db[beyond], "o", color=f"C{k}", ms=9, mfc="none")
        a1.fill_between(a.freqs, -2 * a.noise[0], 2 * a.noise[0], color=f"C{k}", alpha=0.12, lw=0)
    a1.axhline(0, color="k", lw=0.5)
    a2.axhline(0, color="k", lw=0.5)
    a1.set_ylabel("|H| high / low [dB]")
    a2.set_ylabel("phase difference [deg]")
    a2.set_xlabel("frequency [Hz]")
    a1.legend(fontsize=8)
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
    a1.set_title(title or "the same pairs at two excitation amplitudes (circled: beyond twice the noise band)")
    return _finish(fig, plt, path)


def comparison_plots(comparison, out_dir, signature_names=None) -> list:
    """All figures of a Comparison as PNGs in ``out_dir``; returns their paths.

    ``signature_names``: the residual signatures to draw (:data:`bscomp.validate.signatures.SIGNATURES`,
    passed by :meth:`~bscomp.validate.comparison.Comparison.plot`; default all).
    """
    out = figure_folder(out_dir, "Comparison.plot: out_dir")
    paths = []
    for k, fc in enumerate(comparison.frf):
        stem = f"frf{k + 1}_{_slug(fc.source)}"
        for suffix, fn in (("overlay", frf_comparison_plot), ("bands", band_error_plot)):
            p = out / f"{stem}_{suffix}.png"
            fn(fc, p)
            paths.append(p)
    for k, tc in enumerate(comparison.time):
        stem = f"time{k + 1}_{_slug(tc.source)}"
        for suffix, fn in (("overlay", time_comparison_plot), ("resid", resid_plot)):
            p = out / f"{stem}_{suffix}.png"
            fn(tc, p)
            paths.append(p)
    if comparison.time:
        p = out / "signatures.png"
        signature_plot(comparison.signatures, p, names=signature_names)
        paths.append(p)
    for k, tc in enumerate(comparison.time):
        if getattr(tc, "orders", None):
            p = out / f"time{k + 1}_{_slug(tc.source)}_orders.png"
            order_plot(tc.orders, p)
            paths.append(p)
    if getattr(comparison, "amplitude", None):
        p = out / "amplitude_dependence.png"
        amplitude_plot(comparison.amplitude, p)
        paths.append(p)
    return paths


def order_plot(orders, path=None, title=None):
    """Residual components periodic in the motor angle (:class:`~bscomp.validate.periodicity.AngleOrder`), one row
    each: the share of the residual per order (the one found in red) and the residual folded over one period of that
    order -- bin means against ``k phi mod 2 pi`` -- with the fitted ``amplitude cos(k phi + phase)``."""
    plt = _plt()
    fig, axes = plt.subplots(len(orders), 2, figsize=(12, 3.2 * len(orders)), squeeze=False)
    for (a1, a2), o in zip(axes, orders):
        R2 = np.asarray(o.spectrum, float)
        k = np.arange(1, R2.size + 1)
        a1.bar(k, 100 * R2, color=["tab:red" if kk == o.order else "0.6" for kk in k], width=0.8)
        a1.set_xlabel(f"order [periods per revolution of {o.angle}]")
        a1.set_ylabel("share of the residual [%]")
        a1.set_title(f"{o.channel}{' ' + o.note if o.note else ''}: order {o.order}, p {o.p_value:.1g}", fontsize=9)
        a1.grid(True, axis="y", alpha=0.3)
        f = np.asarray(o.folded, float).reshape(-1, 2)
        th = np.linspace(0.0, 2.0 * np.pi, 200)
        a2.plot(f[:, 0], f[:, 1], "ko", ms=4, label="residual, bin means")
        a2.plot(th, o.amplitude * np.cos(th + o.phase), "C3-", label=f"fit, amplitude {o.amplitude:.3g} {o.unit}")
        a2.set_xlabel(f"{o.order} {o.angle} mod 2 pi [rad]")
        a2.set_ylabel(f"{o.channel} residual [{o.unit}]" if o.unit else f"{o.channel} residual")
        a2.grid(True, alpha=0.3)
        a2.legend(fontsize=8)
    fig.suptitle(title or "what the model misses, periodic in the motor angle")
    return _finish(fig, plt, path)


def plot_diagnosis(diag, directory):
    """The error staircase and the candidates of every round of a Diagnosis (one panel per round), as two PNGs in
    ``directory``."""
    plt = _plt()
    d = figure_folder(directory, "Diagnosis.plot: directory")
    fig, ax = plt.subplots(figsize=(7, 4))
    labels = [lbl for lbl, _ in diag.staircase]
    errs = [e for _, e in diag.staircase]
    ax.step(range(len(errs)), errs, where="mid", lw=2)
    ax.plot(range(len(errs)), errs, "o")
    ax.axhline(1.0, color="0.5", ls="--", lw=1, label="noise floor")
    ax.set_xticks(range(len(errs)))
    ax.set_xticklabels(labels, rotation=20, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel("error (mean chi^2, 1 = noise floor)")
    ax.set_title("error staircase: effects added one after another")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    p1 = d / "error_staircase.png"
    save_figure(fig, p1, dpi=110)
    plt.close(fig)
    rounds = [rr for rr in (diag.rounds or [diag.ranked]) if rr]
    heights = [0.9 + 0.28 * len(rr) for rr in rounds] or [1.5]
    fig, axes = plt.subplots(len(heights), 1, figsize=(7.5, sum(heights) + 0.6), squeeze=False,
                             gridspec_kw={"height_ratios": heights})
    for k, (ax, fits) in enumerate(zip(axes[:, 0], rounds), 1):
        _round_bars(ax, fits, {a.name for a in diag.accepted if getattr(a, "round", 1) == k}, k)
    if not rounds:
        axes[0, 0].text(0.5, 0.5, "no candidate tried (max_effects=0)", ha="center", va="center")
        axes[0, 0].set_axis_off()
    fig.suptitle("candidate effects per round (green: accepted; grey: fitted, not accepted)", fontsize=10)
    fig.tight_layout()
    p2 = d / "candidates.png"
    save_figure(fig, p2, dpi=110)
    plt.close(fig)
    orders = (getattr(diag, "remainder", None) or {}).get("orders")
    if orders:
        p3 = d / "orders.png"
        order_plot(orders, p3, title="left by the diagnosis, periodic in the motor angle (no candidate has it)")
        return [p1, p2, p3]
    return [p1, p2]


#: Error increases below this share [%] are drawn to it, with their value written beside the bar.
CLIP_PERCENT = -50.0


def _round_bars(ax, fits, accepted, k):
    """One round of a diagnosis: each fitted candidate's error reduction [%] against the model of that round (its
    effects accepted before), best-ranked on top; worse than :data:`CLIP_PERCENT` clipped and labelled. A candidate
    only screened has no bar: its screening error was taken at other start values (in round 2 the nominal uncertain
    parameters too), not comparable with the round's fits."""
    fits = list(fits)[::-1]
    drops = np.array([100.0 * f.drop if f.refined else 0.0 for f in fits])
    colors = ["tab:green" if f.name in accepted else "tab:gray" for f in fits]
    y = np.arange(len(fits))
    ax.barh(y, np.maximum(drops, CLIP_PERCENT), color=colors)
    for yi, v in zip(y, drops):
        if v < CLIP_PERCENT:
            ax.text(CLIP_PERCENT, yi, f" {v:.0f} %", va="center", ha="left", fontsize=7)
    ax.set_yticks(y)
    ax.set_yticklabels([f.name if f.refined else f"{f.name} (screened only)" for f in fits], fontsize=8)
    for yl, f in zip(ax.get_yticklabels(), fits):
        yl.set_color("k" if f.refined else "0.5")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlim(max(float(drops.min(initial=0.0)), CLIP_PERCENT) - 5.0, 105.0)
    before = fits[0].error_before if fits else float("nan")
    ax.set_xlabel(f"round {k}: error reduction [%] from {before:.4g} (1 = noise floor)", fontsize=8)
    ax.grid(True, axis="x", alpha=0.3)


def calibration_plot(changes, spreads, channels, before, after, path=None, title=None):
    """A re-calibration: each fitted parameter's change from nominal [%] with its +- 1 std bar, and each
    residual channel's normalised error before and after (log scale; 1 = noise floor).

    ``changes``, ``spreads``: ``{parameter: percent}``; ``channels``: labels; ``before``, ``after``: the
    channels' chi^2 values.
    """
    plt = _plt()
    n_ch = max(len(channels), 1)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 1.5 + 0.35 * max(n_ch, len(changes))), squeeze=True)
    names = list(changes)
    y = np.arange(len(names))
    a1.barh(y, [changes[k] for k in names], xerr=[abs(spreads.get(k, np.nan)) for k in names], color="C0",
            capsize=3)
    a1.set_yticks(y)
    a1.set_yticklabels(names)
    a1.axvline(0, color="k", lw=0.5)
    a1.set_xlabel("fitted - nominal [%] (+- 1 std)")
    a1.grid(True, axis="x", alpha=0.3)
    y = np.arange(len(channels))
    a2.barh(y + 0.2, before, height=0.4, color="0.6", label="nominal")
    a2.barh(y - 0.2, after, height=0.4, color="C2", label="re-calibrated")
    a2.axvline(1.0, color="0.3", ls="--", lw=1, label="noise floor")
    a2.set_yticks(y)
    a2.set_yticklabels(channels, fontsize=8)
    a2.invert_yaxis()
    a2.set_xscale("log")
    a2.set_xlabel("error (chi^2, 1 = noise floor)")
    a2.grid(True, axis="x", which="both", alpha=0.3)
    a2.legend(fontsize=8, loc="lower right")
    fig.suptitle(title or "re-calibration of the uncertain parameters")
    return _finish(fig, plt, path)
