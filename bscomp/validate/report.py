"""An HTML report of comparisons (and diagnoses): one self-contained folder with ``index.html`` and the
PNG figures it embeds by relative path; plain HTML, no extra dependency.

Objects other than :class:`~bscomp.validate.comparison.Comparison` (a ``Diagnosis``, a ``Calibration``) are
rendered through an optional protocol: ``summary() -> str`` (else ``table()`` or ``str()``), ``code() -> str``,
``plot(out_dir) -> list of paths``, ``html_tables() -> list of (caption, header, rows)`` and
``comparisons`` (a list of Comparison); whatever they provide is shown. An object offering none of
``summary``, ``table``, ``html_tables``, ``comparisons`` (a string, a number, a path...) is refused.
"""

from __future__ import annotations

import html
import os
import types
from pathlib import Path

import numpy as np

from bscomp.errors import ArgumentTypeError, UsageError
from bscomp.files import atomic_dir, check_path_type
from bscomp.validate.calibration import Calibration
from bscomp.validate.comparison import Comparison
from bscomp.validate.diagnosis import Diagnosis

__all__ = ["write_report"]

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;color:#222}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}h3{font-size:1.05em}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.9em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f3f3f3}
td.l,th.l{text-align:left}pre{background:#f7f7f7;padding:0.8em;white-space:pre-wrap}
img{max-width:100%;border:1px solid #eee;margin:0.4em 0}.bad{color:#b00}
"""


def _e(x):
    return html.escape(str(x))


def _f(x, spec=".4g"):
    if x is None:
        return "&ndash;"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return _e(x)
    return "&ndash;" if not np.isfinite(v) else format(v, spec)


def _table(caption, header, rows, left=1):
    out = [f"<table><caption>{_e(caption)}</caption><tr>"]
    out += [f"<th class='{'l' if i < left else ''}'>{_e(h)}</th>" for i, h in enumerate(header)]
    out.append("</tr>")
    for r in rows:
        out.append("<tr>" + "".join(f"<td class='{'l' if i < left else ''}'>{c}</td>" for i, c in enumerate(r))
                   + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _imgs(paths, out):
    return "\n".join(f"<p><img src='{_e(os.path.relpath(p, out))}' alt='{_e(Path(p).stem)}'></p>" for p in paths)


def _comparison_html(c: Comparison, out: Path, k: int) -> str:
    figdir = out / f"comparison{k}"
    figs = c.plot(figdir)
    parts = [f"<h2>Comparison {k}: model '{_e(c.system)}', cost {_f(c.cost)}</h2>",
             f"<pre>{_e(c.summary())}</pre>"]
    for j, fc in enumerate(c.frf, 1):
        parts.append(f"<h3>FRF {_e(fc.source)}</h3>")
        rows = [[_e(f"{o}/{i}"), _e(fc.units.get((i, o), "")), _f(fc.fit[(i, o)], ".1f"),
                 _f(fc.fit_logmag[(i, o)], ".1f")] for i, o in fc.measured]
        parts.append(_table("fit per pair", ["pair", "unit", "fit % (complex)", "fit % (log |H|)"], rows))
        rows = []
        for m in fc.modes:
            r = m.measured
            cls = "" if (r is not None and m.model_f is not None) else " class='bad'"
            rows.append([f"<span{cls}>{'paired' if cls == '' else ('measured only' if r else 'model only')}</span>",
                         _f(r.f if r else None), _f(r.zeta if r else None, ".3g"), _f(m.model_f),
                         _f(m.model_zeta, ".3g"), _f(m.freq_error_pct, "+.2f"), _f(m.amplitude_error_db, "+.1f"),
                         _e(", ".join(f"{o}/{i}" for i, o in r.pairs)) if r else ""])
        parts.append(_table("mode pairing", ["", "measured f [Hz]", "measured zeta", "model f [Hz]", "model zeta",
                                             "f error [%]", "amplitude error [dB]", "seen in"], rows))
        bands = {}
        for b in fc.bands:
            key = (b["lo"], b["hi"])
            bands.setdefault(key, [0.0, 0.0, 0.0])
            bands[key][0] += b["share"]
            bands[key][1] = max(bands[key][1], b["rms_mag_db"])
            bands[key][2] = max(bands[key][2], b["rms_phase_deg"])
        rows = [[f"{lo:.4g}&ndash;{hi:.4g}", _f(100 * v[0], ".1f"), _f(v[1], ".2f"), _f(v[2], ".1f")]
                for (lo, hi), v in sorted(bands.items())]
        parts.append(_table("error per band", ["band [Hz]", "share of error [%]", "max rms |H| error [dB]",
                                               "max rms phase error [deg]"], rows))
        parts.append(_imgs([p for p in figs if Path(p).name.startswith(f"frf{j}_")], out))
    for j, tc in enumerate(c.time, 1):
        parts.append(f"<h3>Time series {_e(tc.source)}</h3>")
        rows = [[_e(ch), _e(tc.units.get(ch, "")), _f(tc.fit[ch], ".1f"),
                 "yes" if tc.resid[ch].white else "<span class='bad'>no</span>",
                 "yes" if tc.resid[ch].independent else "<span class='bad'>no</span>"] for ch in tc.measured]
        parts.append(_table("fit and residual tests", ["channel", "unit", "fit %", "white", "independent of input"],
                            rows))
        names = sorted({k for d in tc.signatures.values() for k in d})
        rows = [[_e(n)] + [_f(tc.signatures[ch].get(n), "+.3f") for ch in tc.signatures] for n in names]
        parts.append(_table("residual signatures (correlation of measured - model with the model's signals)",
                            ["signal"] + list(tc.signatures), rows))
        rows = [[f"{w['t0']:.4g}&ndash;{w['t1']:.4g}", _f(100 * w["share"], ".1f"), _e(w["activity"])]
                for w in tc.worst_windows()]
        parts.append(_table("time windows carrying most of the error", ["t [s]", "share [%]", "model is in"], rows))
        parts.append(_imgs([p for p in figs if Path(p).name.startswith(f"time{j}_")], out))
    sig = [p for p in figs if Path(p).name == "signatures.png"]
    if sig:
        parts.append(_imgs(sig, out))
    if c.amplitude:
        parts.append("<h3>The same pairs at two excitation amplitudes (the data alone)</h3>")
        rows = [[_e(f"{a.pair[1]}/{a.pair[0]}"), _e(f"{a.amplitudes[0]:g} / {a.amplitudes[1]:g}"), _f(a.rms_db, ".2f"),
                 _f(a.chi2, ".3g"), _f(a.limit, ".3g"),
                 _e(a.verdict) if a.verdict != "amplitude-dependent" else f"<span class='bad'>{_e(a.verdict)}</span>",
                 _e("" if a.band is None else f"{a.band[0]:.4g}-{a.band[1]:.4g} Hz")] for a in c.amplitude]
        parts.append(_table("amplitude dependence", ["pair", "amplitudes", "apart [dB rms]", "chi^2", "limit",
                                                     "verdict", "where"], rows))
        parts.append(_imgs([p for p in figs if Path(p).name == "amplitude_dependence.png"], out))
    return "\n".join(parts)


def _other_html(obj, out: Path, k: int) -> str:
    name = type(obj).__name__
    parts = [f"<h2>{_e(name)} {k}</h2>"]
    if hasattr(obj, "summary"):
        s = obj.summary() if callable(obj.summary) else obj.summary
        parts.append(f"<pre>{_e(s)}</pre>")
    elif callable(getattr(obj, "table", None)):
        parts.append(f"<pre>{_e(obj.table())}</pre>")
    else:
        parts.append(f"<pre>{_e(obj)}</pre>")
    if callable(getattr(obj, "code", None)):
        parts.append(f"<h3>Lines to add to the system file</h3><pre>{_e(obj.code())}</pre>")
    if hasattr(obj, "html_tables"):
        for caption, header, rows in obj.html_tables():
            parts.append(_table(caption, header, [[_e(c) if not isinstance(c, float) else _f(c) for c in r]
                                                  for r in rows]))
    if isinstance(obj, Calibration):                      # one figure, to a file
        fig = out / f"calibration{k}.png"
        obj.plot(fig)
        parts.append(_imgs([fig], out))
    elif hasattr(obj, "plot"):
        figs = obj.plot(out / f"{name.lower()}{k}") or []
        parts.append(_imgs([p for p in figs if str(p).endswith(".png")], out))
    comps = getattr(obj, "comparisons", None)
    if comps:
        for j, c in enumerate(comps, 1):
            if isinstance(c, Comparison):
                parts.append(_comparison_html(c, out, f"{k}_{j}"))
    return "\n".join(parts)


def write_report(comparisons_or_diagnosis, out_dir, title: str = "bscomp: model vs measurements") -> Path:
    """Write ``out_dir/index.html`` with figures and tables; returns its path.

    Parameters
    ----------
    comparisons_or_diagnosis : Comparison, Diagnosis, Calibration, an object with the protocol above, or a list
        Anything else (a string, a number, an empty list) raises :class:`~bscomp.errors.ArgumentTypeError` /
        :class:`~bscomp.errors.UsageError` before anything is written.
    out_dir : path
        Created if needed, and replaced as a whole when complete (an error leaves the previous report as it
        was); it must be new, empty or a folder bscomp wrote. Figures go to sub-folders and are linked
        relatively, so the folder can be moved or zipped.
    """
    items = _check_arguments(comparisons_or_diagnosis, out_dir)
    with atomic_dir(out_dir) as out:   # complete or absent: built in a temporary folder, renamed into place
        body = []
        for k, obj in enumerate(items, 1):
            body.append(_comparison_html(obj, out, k) if isinstance(obj, Comparison) else _other_html(obj, out, k))
        (out / "index.html").write_text(_document(title, body), encoding="utf-8")
    return Path(out_dir) / "index.html"


_WHAT = ("a Comparison (bscomp.compare), a Diagnosis (bscomp.diagnose), a Calibration (bscomp.calibrate) or a "
         "list of them")


def _reportable(obj) -> bool:
    """A result :func:`write_report` can render: a Comparison, Diagnosis, Calibration or an object with the protocol."""
    if isinstance(obj, (Comparison, Diagnosis, Calibration)):
        return True
    if isinstance(obj, (str, bytes, os.PathLike, int, float, complex, dict, list, tuple, type, types.ModuleType)) \
            or obj is None:
        return False
    return any(hasattr(obj, a) for a in ("summary", "table", "html_tables", "comparisons"))


def _check_arguments(items, out_dir) -> list:
    """The results to report as a list, after checking them and ``out_dir`` (nothing is written on an error)."""
    if isinstance(items, (str, os.PathLike)) and (
            _reportable(out_dir) or (isinstance(out_dir, (list, tuple)) and bool(out_dir)
                                     and all(_reportable(o) for o in out_dir))):
        raise ArgumentTypeError(f"write_report: the arguments are swapped (the folder {str(items)!r} came first): "
                                "call write_report(result, out_dir)")
    seq = list(items) if isinstance(items, (list, tuple)) else [items]
    if not seq:
        raise UsageError(f"write_report: nothing to report (an empty {type(items).__name__}): give {_WHAT}")
    for k, obj in enumerate(seq):
        if not _reportable(obj):
            where = f"item {k} of the list is" if isinstance(items, (list, tuple)) else "got"
            raise ArgumentTypeError(f"write_report: {where} {type(obj).__name__} {obj!r:.80}, not a result to "
                                    f"report: give {_WHAT}, then the folder (write_report(result, out_dir))")
    check_path_type(out_dir, "write_report: out_dir", "folder")
    return seq


def _document(title, body) -> str:
    return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{_e(title)}</title><style>{_CSS}</style>"
            f"</head><body>\n<h1>{_e(title)}</h1>\n<p>Residuals are measured minus model. Cost: mean squared "
            "residual (log10-magnitude and phase [rad] for FRFs, RMS-normalised for time series).</p>\n"
            + "\n".join(body) + "\n</body></html>\n")
