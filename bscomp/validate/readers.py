"""Readers of measurement files: plain CSV with its metadata in ``#`` lines or a JSON/TOML sidecar
(format: :mod:`bscomp.validate.measurements`, ``docs/measurements.md``).

A file is parsed, never executed. Values are converted to SI on reading (a channel in ``um`` is multiplied
by 1e-6; ``deg`` becomes ``rad``). Every problem raises :class:`~bscomp.validate.datasets.MeasurementFileError`
naming the file, the line and the column.
"""

from __future__ import annotations

import difflib
import re
from pathlib import Path

import numpy as np

from bscomp.errors import ArgumentTypeError
from bscomp.kernel.units import UnitSyntaxError, convention_units, expected_dimension_ok, parse_unit
from bscomp.linear.response import Frf
from bscomp.validate.datasets import FrfData, MeasurementFileError, TimeData
from bscomp.validate.parsing import read_table

__all__ = ["read_frf_csv", "read_time_csv", "load", "load_all"]

_FREQ_NAMES = ("f", "freq", "freq_hz", "frequency")
_TIME_NAMES = ("t", "time")
_FRF_COL = re.compile(r"^(re|im|mag|mag_db|phase_deg|phase_rad|coh)\((.+)\)$")
_FRF_ARROW = re.compile(r"^(.+?)->(.+)\s+(re|im|mag|mag_db|phase_deg|phase_rad|coh)$")  # Frf.to_csv


def _finite(path, x, rows, col, name, what):
    """Values must stay finite after conversion to SI (``mag_db`` of 7000 overflows 10**(x/20))."""
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        k = int(bad[0])
        raise MeasurementFileError(path, rows.line(k), col, f"{what} is not finite after conversion to SI (value "
                                   f"{float(rows.A[k, col - 1])!r} in the file): out of range of a float", name)
    return x


def _nonzero(path, h, f, rows, col, name, pname):
    """A response of exactly 0 (or one that underflows to 0 in SI) is no measurement: -inf dB, no phase; peak
    picking would read the dip beside it as a resonance."""
    zero = np.flatnonzero(h == 0)
    if zero.size:
        k = int(zero[0])
        every = " at every frequency: the pair carries no signal" if zero.size == h.size else \
            f" at f = {f[k]:.6g} Hz ({zero.size} row(s))"
        raise MeasurementFileError(path, rows.line(k), col, f"response {pname} is exactly 0{every}; a zero magnitude "
                                   "is not a measured value (-inf dB): drop the row(s), or the pair's columns", name)


def _increasing(path, x, rows, col, name, what):
    d = np.diff(x)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise MeasurementFileError(path, rows.line(k), col, f"{what} is not strictly increasing ({x[k]:.6g} after "
                                   f"{x[k - 1]:.6g}): sort the rows and remove duplicates", name)


def _unit(path, meta, name, fallback_where):
    """Parsed unit of channel ``name`` (error if missing or malformed)."""
    if name not in meta.units:
        w = fallback_where
        raise MeasurementFileError(w[0], w[1], w[2], f"missing unit for {name!r}: add '# unit {name}: <unit>' "
                                   "(or an input/output line) above the header, or a sidecar entry", name)
    text, w = meta.units[name]
    try:
        return parse_unit(text)
    except UnitSyntaxError as exc:
        col = (w[2] or 1) + exc.pos if w[2] is not None else None
        raise MeasurementFileError(w[0], w[1], col, f"bad unit {text!r} for {name!r}: {exc}", name) from None


def _check_convention(name, unit, w):
    ok, expected = expected_dimension_ok(name, unit)
    if not ok:
        raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {unit.text!r} for {name!r}: a channel named "
                                   f"'*.{name.rsplit('.', 1)[-1]}' is measured in {expected} (Modelica naming "
                                   "convention)", name)


def _check_frf_unit(pair_name, out, inp, unit, meta, w):
    """The unit of H must be (unit of out)/(unit of in) when those are known (declared or by convention)."""
    def options(ch):
        if ch in meta.units:
            try:
                return [parse_unit(meta.units[ch][0])]
            except UnitSyntaxError:
                return []
        suf = ch.rsplit(".", 1)[-1]
        opts = list(convention_units.get(suf, ()))
        if suf == "a":
            opts.append("rad/s^2")
        return [parse_unit(o) for o in opts]

    uo, ui = options(out), options(inp)
    if not uo or not ui:
        return
    for a in uo:
        for b in ui:
            d = np.array(a.dims) - np.array(b.dims)
            if np.allclose(d[:4], unit.dims[:4]):
                return
    want = " or ".join(f"{a.text}/({b.text})" for a in uo for b in ui)
    raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {unit.text!r} for {pair_name!r}: output/input "
                               f"units give {want}", pair_name)


def _conditions_and_source(meta, path, loc):
    """The conditions and the source text; where each condition was declared goes into ``loc``."""
    for name in meta.conditions:
        loc[("condition", name)] = meta.where.get(("condition", name), (path, None, None))
    return dict(meta.conditions), meta.source or str(path)


def _axis_unit_key(path, meta, header, names):
    """The ``# unit`` name that gives the unit of the first column (time or frequency), whatever that column is
    called: its own name or one of ``names`` (``t``/``time``, ``f``/``freq``...), in any case; None if none."""
    keys = [k for k in meta.units if k == header[0] or k.lower() in names or k.lower() == header[0].lower()]
    if len(keys) > 1:
        w = meta.units[keys[1]][1]
        raise MeasurementFileError(w[0], w[1], w[2], f"units given for {keys!r}, which all name the first column "
                                   f"{header[0]!r}: declare its unit once", keys[1])
    return keys[0] if keys else None


def _unused_units(meta, known, what):
    """A ``# unit`` line naming nothing of the file is an error (a typo would leave a channel in a wrong unit)."""
    for name, (_text, w) in meta.units.items():
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise MeasurementFileError(w[0], w[1], w[2], f"unit given for {name!r}, which is not {what}{hint}: a unit "
                                       f"line must name one of {sorted(known)}", name)


# ---- FRF --------------------------------------------------------------------------------------------------
def read_frf_csv(path) -> FrfData:
    """Read an FRF file (columns ``f``, then ``re(out/in)``/``im(out/in)`` or ``mag``/``mag_db`` with
    ``phase_deg``/``phase_rad``, optional ``coh``; or the ``<in>-><out> re`` columns of
    :meth:`bscomp.linear.response.Frf.to_csv`); see ``docs/measurements.md``."""
    path, meta, header, hl, rows = read_table(path)
    return _frf_from(path, meta, header, hl, rows)


def _frf_from(path, meta, header, hl, rows):
    if meta.kind not in (None, "frf"):
        raise MeasurementFileError(path, None, None, f"metadata says kind: {meta.kind}, not an FRF file")
    if header[0].lower() not in _FREQ_NAMES:
        raise MeasurementFileError(path, hl, 1, f"the first column of an FRF file must be the frequency "
                                   f"(one of {list(_FREQ_NAMES)}), got {header[0]!r}", header[0])
    A = rows.A
    fkey = _axis_unit_key(path, meta, header, _FREQ_NAMES)
    f = _finite(path, A[:, 0] * _frequency_scale(path, meta, fkey, hl), rows, 1, header[0], "frequency")
    if np.any(f <= 0):
        k = int(np.flatnonzero(f <= 0)[0])
        raise MeasurementFileError(path, rows.line(k), 1, f"frequency {f[k]:.6g} Hz: an FRF is measured at "
                                   "frequencies > 0 (at 0 Hz a drive's rigid-body response is infinite): drop the "
                                   "row", header[0])
    _increasing(path, f, rows, 1, header[0], "frequency")
    cols: dict = {}
    written = set()                      # pairs in the columns of Frf.to_csv (SI, units implied by the names)
    for c, name in enumerate(header[1:], start=2):
        inp, out, quantity, arrow = _frf_column(path, hl, c, name)
        cols.setdefault((inp, out), {})[quantity] = (c, A[:, c - 1])
        if arrow:
            written.add((inp, out))
    if not cols:
        raise MeasurementFileError(path, hl, 2, "no response columns after the frequency")
    H, units, coh, loc = {}, {}, {}, {}
    for (inp, out), d in cols.items():
        pname = f"{out}/{inp}"
        first = min(c for c, _ in d.values())
        loc[("column", (inp, out))] = (hl, first)
        with np.errstate(over="ignore", invalid="ignore"):
            h = _pair_response(path, header, hl, rows, pname, d, first)
        coh[(inp, out)] = None
        if "coh" in d:
            c, g = d["coh"]
            bad = np.flatnonzero((g < 0) | (g > 1))
            if bad.size:
                k = int(bad[0])
                raise MeasurementFileError(path, rows.line(k), c, f"coherence {g[k]:.6g} outside [0, 1]", header[c - 1])
            coh[(inp, out)] = g
        if pname not in meta.units and (inp, out) in written:
            meta.units[pname] = (Frf.pair_unit(out, inp), (path, hl, first))
        u = _unit(path, meta, pname, (path, hl, first))
        w = meta.units[pname][1]
        loc[("unit", (inp, out))] = (w[1], w[2])
        _check_frf_unit(pname, out, inp, u, meta, w)
        with np.errstate(over="ignore", invalid="ignore"):
            H[(inp, out)] = _finite(path, h * u.scale, rows, first, header[first - 1], f"response {pname}")
        _nonzero(path, H[(inp, out)], f, rows, first, header[first - 1], pname)
        units[(inp, out)] = u.si
    extra = [n for n in meta.units if "/" in n and n not in {f"{o}/{i}" for i, o in H}]
    if extra:
        w = meta.units[extra[0]][1]
        raise MeasurementFileError(w[0], w[1], w[2], f"unit given for {extra[0]!r}, which has no columns in the "
                                   f"file (pairs: {[f'{o}/{i}' for i, o in H]})", extra[0])
    channels = {c for pair in H for c in pair}
    _unused_units(meta, {f"{o}/{i}" for i, o in H} | channels | {fkey or header[0]},
                  "the frequency column, a pair or one of its channels")
    cond, src = _conditions_and_source(meta, path, loc)
    for name in meta.excitation:
        w = meta.where[("excitation", name)]
        if name not in {i for i, _ in H}:
            raise MeasurementFileError(w[0], w[1], w[2], f"excitation given for {name!r}, which is not an input of "
                                       f"the file's pairs (inputs: {list(dict.fromkeys(i for i, _ in H))})", name)
        loc[("excitation", name)] = (w[1], w[2])
    return FrfData(freqs=f, H=H, units=units, conditions=cond, coherence=coh, source=src, locations=loc,
                   excitation={k: v for k, v in meta.excitation.items()}, path=str(path),
                   excitation_units=dict(meta.excitation_units))


def _frequency_scale(path, meta, key, hl) -> float:
    """Factor from the frequency column's declared unit (the ``# unit`` line ``key``) to Hz (1 without one)."""
    if key is None:
        return 1.0
    u = _unit(path, meta, key, (path, hl, 1))
    if not np.allclose(u.dims[:4], (0, 0, -1, 0)):
        w = meta.units[key][1]
        raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {u.text!r} for the frequency: use Hz or kHz", key)
    return u.scale / (2 * np.pi if u.dims[4] == 1 else 1.0)


def _frf_column(path, hl, c, name):
    """``(input, output, quantity, written)`` of an FRF column: ``re(<out>/<in>)`` or, as
    :meth:`bscomp.linear.response.Frf.to_csv` writes it, ``<in>-><out> re`` (``written`` True).

    The second form holds SI values; without a declared unit, a pair's unit is
    :meth:`~bscomp.linear.response.Frf.pair_unit` of its names (the Modelica naming convention).
    """
    m = _FRF_COL.match(name)
    if m and "/" in m.group(2):
        out, inp = (x.strip() for x in m.group(2).rsplit("/", 1))
        quantity, written = m.group(1), False
    elif _FRF_ARROW.match(name):
        inp, out, quantity = (x.strip() for x in _FRF_ARROW.match(name).groups())
        written = True
    else:
        raise MeasurementFileError(path, hl, c, f"unknown column {name!r}: FRF columns are re(<out>/<in>), "
                                   "im(...), mag(...), mag_db(...), phase_deg(...), phase_rad(...), coh(...) (or "
                                   "'<in>-><out> re', ... as Frf.to_csv writes them)", name)
    if not out or not inp:
        raise MeasurementFileError(path, hl, c, f"column {name!r} must name <output>/<input>", name)
    return inp, out, quantity, written


def _pair_response(path, header, hl, rows, pname, d, first):
    """The complex response of one pair from its columns ``{quantity: (column, values)}``.

    Real and imaginary parts, or one magnitude and one phase column; both forms together (as
    :meth:`~bscomp.linear.response.Frf.to_csv` writes them) must agree, and the real/imaginary parts are used.
    """
    mags = [k for k in ("mag", "mag_db") if k in d]
    phs = [k for k in ("phase_deg", "phase_rad") if k in d]
    if "re" in d or "im" in d:
        if "re" not in d or "im" not in d:
            raise MeasurementFileError(path, hl, first, f"{pname}: give both re(...) and im(...)", header[first - 1])
        h = d["re"][1] + 1j * d["im"][1]
        if mags or phs:
            c = d[(mags or phs)[0]][0]
            if len(mags) != 1 or len(phs) != 1:
                raise MeasurementFileError(path, hl, c, f"{pname}: give re/im or magnitude/phase (with re/im, one "
                                           "magnitude and one phase column that agree)", header[c - 1])
            bad = np.flatnonzero(np.abs(_polar(path, header, rows, d, mags[0], phs[0]) - h) > 1e-6 * np.abs(h))
            if bad.size:
                raise MeasurementFileError(path, rows.line(int(bad[0])), c, f"{pname}: magnitude/phase disagree with "
                                           "re/im", header[c - 1])
        return h
    if "coh" in d and len(d) == 1:
        c = d["coh"][0]
        raise MeasurementFileError(path, hl, c, f"coherence for {pname} but no response columns for it",
                                   header[c - 1])
    if len(mags) != 1 or len(phs) != 1:
        raise MeasurementFileError(path, hl, first, f"{pname}: give one magnitude column (mag or mag_db) and "
                                   "one phase column (phase_deg or phase_rad)", header[first - 1])
    return _polar(path, header, rows, d, mags[0], phs[0])


def _polar(path, header, rows, d, mag_key, phase_key):
    """``|H| e^{j phase}`` from a magnitude (``mag`` or ``mag_db``) and a phase (``phase_deg`` or ``phase_rad``)."""
    mag = d[mag_key][1]
    if mag_key == "mag_db":
        mag = 10.0 ** (mag / 20.0)
    elif np.any(mag < 0):
        k = int(np.flatnonzero(mag < 0)[0])
        raise MeasurementFileError(path, rows.line(k), d["mag"][0], "negative magnitude", header[d["mag"][0] - 1])
    ph = d[phase_key][1]
    return mag * np.exp(1j * (np.radians(ph) if phase_key == "phase_deg" else ph))


# ---- time series ------------------------------------------------------------------------------------------
def read_time_csv(path) -> TimeData:
    """Read a time-series file (column ``t``, then channels declared as inputs or outputs with units)."""
    path, meta, header, hl, rows = read_table(path)
    return _time_from(path, meta, header, hl, rows)


def _time_from(path, meta, header, hl, rows):
    if meta.kind not in (None, "time"):
        raise MeasurementFileError(path, None, None, f"metadata says kind: {meta.kind}, not a time-series file")
    for name in meta.excitation:
        w = meta.where[("excitation", name)]
        raise MeasurementFileError(w[0], w[1], w[2], f"excitation {name!r} is the sine amplitude of an FRF "
                                   "measurement; a time series gives its input signal as a column", name)
    if header[0].lower() not in _TIME_NAMES:
        raise MeasurementFileError(path, hl, 1, f"the first column of a time-series file must be the time "
                                   f"('t'), got {header[0]!r}", header[0])
    A = rows.A
    t = A[:, 0]
    tkey = _axis_unit_key(path, meta, header, _TIME_NAMES)
    if tkey is not None:
        u = _unit(path, meta, tkey, (path, hl, 1))
        if not np.allclose(u.dims, (0, 0, 1, 0, 0)):
            w = meta.units[tkey][1]
            raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {u.text!r} for the time: use s or ms", tkey)
        t = _finite(path, t * u.scale, rows, 1, header[0], "time")
    _increasing(path, t, rows, 1, header[0], "time")
    if len(t) < 2:
        raise MeasurementFileError(path, rows.line(0), 1, "a time series needs at least two samples", header[0])
    inputs, outputs, units, loc = {}, {}, {}, {}
    for c, name in enumerate(header[1:], start=2):
        role = meta.roles.get(name)
        if role is None:
            declared = sorted(meta.roles)
            raise MeasurementFileError(path, hl, c, f"unknown channel {name!r}: declare it above the header as "
                                       f"'# input {name}: <unit>' or '# output {name}: <unit>' (declared: "
                                       f"{declared})", name)
        u = _unit(path, meta, name, (path, hl, c))
        w = meta.units[name][1]
        _check_convention(name, u, w)
        (inputs if role == "input" else outputs)[name] = _finite(path, A[:, c - 1] * u.scale, rows, c, name,
                                                                 f"channel {name!r}")
        units[name] = u.si
        loc[("column", name)] = (hl, c)
        loc[("unit", name)] = (w[1], w[2])
    missing = [n for n in meta.roles if n not in header]
    if missing:
        w = meta.where.get((meta.roles[missing[0]], missing[0]), (path, None, None))
        raise MeasurementFileError(w[0], w[1], w[2], f"channel {missing[0]!r} is declared but has no column in the "
                                   f"header (columns: {header})", missing[0])
    _unused_units(meta, set(header[1:]) | {tkey or header[0]}, "the time column or a channel column")
    if not inputs:
        raise MeasurementFileError(path, hl, None, "no input channel: mark the excitation with '# input NAME: UNIT'")
    if not outputs:
        raise MeasurementFileError(path, hl, None, "no output channel: mark responses with '# output NAME: UNIT'")
    cond, src = _conditions_and_source(meta, path, loc)
    return TimeData(t=t, inputs=inputs, outputs=outputs, units=units, conditions=cond, source=src, locations=loc,
                    path=str(path))



# ---- dispatch ----------------------------------------------------------------------------------------------
def load(path):
    """Read an FRF or time-series file, deciding by the ``kind`` metadata or else the first column name."""
    path, meta, header, hl, rows = read_table(path)
    kind = meta.kind
    if kind is None:
        first = header[0].lower()
        if first in _FREQ_NAMES:
            kind = "frf"
        elif first in _TIME_NAMES:
            kind = "time"
        else:
            raise MeasurementFileError(path, hl, 1, f"cannot tell the kind of file from column {header[0]!r}: start "
                                       "with 'f' (FRF) or 't' (time series), or add '# kind: frf|time'", header[0])
    return _frf_from(path, meta, header, hl, rows) if kind == "frf" else _time_from(path, meta, header, hl, rows)


def load_all(paths) -> list:
    """:func:`load` each path (an FrfData/TimeData passes through)."""
    if isinstance(paths, (str, Path, FrfData, TimeData)):
        paths = [paths]
    if not isinstance(paths, (list, tuple)):
        raise ArgumentTypeError(f"measurements are a file path, an FrfData/TimeData or a list of them, got "
                                f"{type(paths).__name__} {paths!r}"[:300])
    return [p if isinstance(p, (FrfData, TimeData)) else load(p) for p in paths]
