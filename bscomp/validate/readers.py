"""Readers of measurement files: plain CSV with its metadata in ``#`` lines or a JSON/TOML sidecar
(format: :mod:`bscomp.validate.measurements`, ``docs/measurements.md``).

A file is parsed, never executed. Values are converted to SI on reading (a channel in ``um`` is multiplied
by 1e-6; ``deg`` becomes ``rad``). Every problem raises :class:`~bscomp.validate.datasets.MeasurementFileError`
naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bscomp.kernel.units import UnitSyntaxError, convention_units, expected_dimension_ok, parse_unit
from bscomp.linear.response import Frf
from bscomp.validate.datasets import FrfData, MeasurementFileError, TimeData

__all__ = ["read_frf_csv", "read_time_csv", "load", "load_all"]

_FREQ_NAMES = ("f", "freq", "freq_hz", "frequency")
_TIME_NAMES = ("t", "time")
_FRF_COL = re.compile(r"^(re|im|mag|mag_db|phase_deg|phase_rad|coh)\((.+)\)$")
_FRF_ARROW = re.compile(r"^(.+?)->(.+)\s+(re|im|mag|mag_db|phase_deg|phase_rad|coh)$")  # Frf.to_csv


# ---- metadata --------------------------------------------------------------------------------------------
@dataclass
class _Meta:
    kind: str | None = None
    source: str | None = None
    conditions: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)      # name -> (text, where: (file, line, col))
    roles: dict = field(default_factory=dict)      # name -> "input" | "output"
    where: dict = field(default_factory=dict)      # key -> (file, line, col)


def _value(text):
    text = str(text).strip()
    try:
        return float(text)
    except ValueError:
        return text


def _meta_set(meta, path, key, value, where):
    """One metadata entry ``key: value``; ``key`` as in the comment syntax."""
    key = key.strip()
    words = key.split(None, 1)
    head = words[0].lower() if words else ""
    if head in ("kind", "source", "description", "name") and len(words) == 1:
        if head == "kind":
            v = str(value).strip().lower()
            if v not in ("frf", "time"):
                raise MeasurementFileError(where[0], where[1], where[2], f"kind must be 'frf' or 'time', got {v!r}")
            meta.kind = v
        elif head == "source":
            meta.source = str(value).strip()
        return
    if head in ("condition", "unit", "input", "output") and len(words) == 2:
        name = words[1].strip()
        if head == "condition":
            meta.conditions[name] = _value(value)
        else:
            if head in ("input", "output"):
                meta.roles[name] = head
            if str(value).strip():
                meta.units[name] = (str(value).strip(), where)
        meta.where[(head, name)] = where
        return
    raise MeasurementFileError(where[0], where[1], where[2],
                               f"unknown metadata key {key!r}: use 'kind', 'source', 'condition NAME', "
                               "'unit NAME', 'input NAME' or 'output NAME'")


def _line_of(text, needle):
    """(line, col) of the first occurrence of ``needle`` in ``text`` (1-based), or (None, None)."""
    k = text.find(needle)
    if k < 0:
        return None, None
    return text.count("\n", 0, k) + 1, k - (text.rfind("\n", 0, k) + 1) + 1


def _sidecar(path: Path, meta: _Meta):
    cands = [Path(str(path) + ".json"), Path(str(path) + ".toml"), path.with_suffix(".json"),
             path.with_suffix(".toml")]
    for sc in cands:
        if sc == path or not sc.is_file():
            continue
        text = sc.read_text(encoding="utf-8")
        if sc.suffix == ".json":
            try:
                d = json.loads(text)
            except json.JSONDecodeError as exc:
                raise MeasurementFileError(sc, exc.lineno, exc.colno, f"invalid JSON: {exc.msg}") from exc
        else:
            import tomllib  # Python >= 3.11; TOML sidecars only

            try:
                d = tomllib.loads(text)
            except tomllib.TOMLDecodeError as exc:
                m = re.search(r"line (\d+), column (\d+)", str(exc))
                raise MeasurementFileError(sc, int(m.group(1)) if m else None, int(m.group(2)) if m else None,
                                           f"invalid TOML: {exc}") from exc
        if not isinstance(d, dict):
            raise MeasurementFileError(sc, 1, 1, "the sidecar must hold a table/object of metadata")

        def at(key, text=text, sc=sc):
            ln, col = _line_of(text, f'"{key}"' if sc.suffix == ".json" else key)
            return (sc, ln, col)

        for k, v in d.items():
            if k in ("kind", "source", "description", "name"):
                _meta_set(meta, sc, k, v, at(k))
            elif k in ("conditions", "units", "inputs", "outputs"):
                if not isinstance(v, dict):
                    w = at(k)
                    raise MeasurementFileError(w[0], w[1], w[2], f"'{k}' must map names to values")
                sub = {"conditions": "condition", "units": "unit", "inputs": "input", "outputs": "output"}[k]
                for name, val in v.items():
                    _meta_set(meta, sc, f"{sub} {name}", val, at(name))
            else:
                w = at(k)
                raise MeasurementFileError(w[0], w[1], w[2], f"unknown sidecar key {k!r}: use kind, source, "
                                           "conditions, units, inputs, outputs")
        return sc
    return None


def _read(path):
    """(meta, header, header_line, rows[(line, fields)]) of a CSV file."""
    path = Path(path)
    if not path.is_file():
        raise MeasurementFileError(path, None, None, "no such file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise MeasurementFileError(path, None, None, f"not a UTF-8 text file ({exc})") from exc
    meta = _Meta()
    _sidecar(path, meta)
    lines = text.splitlines()
    header, header_line, rows = None, None, []
    for ln, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s[1:].strip()
            if header is None and body:
                key, colon, value = body.partition(":")
                if colon:
                    vcol = line.find(":") + 2 + (len(value) - len(value.lstrip()))
                    _meta_set(meta, path, key, value, (path, ln, vcol))
                elif body.split()[0].lower() in ("input", "output") and len(body.split()) == 2:
                    _meta_set(meta, path, body, "", (path, ln, len(line) + 1))  # declared, unit missing
            continue
        fields = next(csv.reader(io.StringIO(line), skipinitialspace=True))
        fields = [f.strip() for f in fields]
        if header is None:
            header, header_line = fields, ln
        else:
            rows.append((ln, fields))
    if header is None:
        raise MeasurementFileError(path, len(lines) or 1, 1, "empty file: no header row and no data")
    if not rows:
        raise MeasurementFileError(path, header_line, 1, "no data rows after the header")
    seen = {}
    for c, name in enumerate(header, start=1):
        if not name:
            raise MeasurementFileError(path, header_line, c, "empty column name in the header")
        if name in seen:
            raise MeasurementFileError(path, header_line, c, f"column {name!r} repeats column {seen[name]}", name)
        seen[name] = c
    return path, meta, header, header_line, rows


def _matrix(path, header, rows):
    """Float matrix (n_rows, n_cols); NaN/inf/non-numeric and ragged rows raise naming line and column."""
    n = len(header)
    A = np.empty((len(rows), n))
    for r, (ln, fields) in enumerate(rows):
        if len(fields) != n:
            c = min(len(fields), n) + 1
            raise MeasurementFileError(path, ln, c, f"row has {len(fields)} fields, the header has {n}",
                                       header[c - 1] if c <= n else None)
        for c, txt in enumerate(fields):
            try:
                v = float(txt)
            except ValueError:
                raise MeasurementFileError(path, ln, c + 1, f"{txt!r} is not a number", header[c]) from None
            if not math.isfinite(v):
                raise MeasurementFileError(path, ln, c + 1, f"value {txt!r} is not finite (NaN or inf): remove "
                                           "the row or fill the gap", header[c])
            A[r, c] = v
    return A


def _increasing(path, x, rows, col, name, what):
    d = np.diff(x)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise MeasurementFileError(path, rows[k][0], col, f"{what} is not strictly increasing ({x[k]:.6g} after "
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


def _conditions_and_source(meta, path):
    return dict(meta.conditions), meta.source or str(path)


# ---- FRF --------------------------------------------------------------------------------------------------
def read_frf_csv(path) -> FrfData:
    """Read an FRF file (columns ``f``, then ``re(out/in)``/``im(out/in)`` or ``mag``/``mag_db`` with
    ``phase_deg``/``phase_rad``, optional ``coh``; or the ``<in>-><out> re`` columns of
    :meth:`bscomp.linear.response.Frf.to_csv`); see ``docs/measurements.md``."""
    path, meta, header, hl, rows = _read(path)
    return _frf_from(path, meta, header, hl, rows)


def _frf_from(path, meta, header, hl, rows):
    if meta.kind not in (None, "frf"):
        raise MeasurementFileError(path, None, None, f"metadata says kind: {meta.kind}, not an FRF file")
    if header[0].lower() not in _FREQ_NAMES:
        raise MeasurementFileError(path, hl, 1, f"the first column of an FRF file must be the frequency "
                                   f"(one of {list(_FREQ_NAMES)}), got {header[0]!r}", header[0])
    A = _matrix(path, header, rows)
    f = A[:, 0] * _frequency_scale(path, meta, header, hl)
    if np.any(f < 0):
        k = int(np.flatnonzero(f < 0)[0])
        raise MeasurementFileError(path, rows[k][0], 1, "negative frequency", header[0])
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
        h = _pair_response(path, header, hl, rows, pname, d, first)
        coh[(inp, out)] = None
        if "coh" in d:
            c, g = d["coh"]
            bad = np.flatnonzero((g < 0) | (g > 1))
            if bad.size:
                k = int(bad[0])
                raise MeasurementFileError(path, rows[k][0], c, f"coherence {g[k]:.6g} outside [0, 1]", header[c - 1])
            coh[(inp, out)] = g
        if pname not in meta.units and (inp, out) in written:
            meta.units[pname] = (Frf.pair_unit(out, inp), (path, hl, first))
        u = _unit(path, meta, pname, (path, hl, first))
        w = meta.units[pname][1]
        loc[("unit", (inp, out))] = (w[1], w[2])
        _check_frf_unit(pname, out, inp, u, meta, w)
        H[(inp, out)] = h * u.scale
        units[(inp, out)] = u.si
    extra = [n for n in meta.units if "/" in n and n not in {f"{o}/{i}" for i, o in H}]
    if extra:
        w = meta.units[extra[0]][1]
        raise MeasurementFileError(w[0], w[1], w[2], f"unit given for {extra[0]!r}, which has no columns in the "
                                   f"file (pairs: {[f'{o}/{i}' for i, o in H]})", extra[0])
    cond, src = _conditions_and_source(meta, path)
    return FrfData(freqs=f, H=H, units=units, conditions=cond, coherence=coh, source=src, locations=loc)


def _frequency_scale(path, meta, header, hl) -> float:
    """Factor from the frequency column's declared unit to Hz (1 when none is declared)."""
    if header[0] not in meta.units and "f" not in meta.units:
        return 1.0
    key = header[0] if header[0] in meta.units else "f"
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
                raise MeasurementFileError(path, rows[int(bad[0])][0], c, f"{pname}: magnitude/phase disagree with "
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
        raise MeasurementFileError(path, rows[k][0], d["mag"][0], "negative magnitude", header[d["mag"][0] - 1])
    ph = d[phase_key][1]
    return mag * np.exp(1j * (np.radians(ph) if phase_key == "phase_deg" else ph))


# ---- time series ------------------------------------------------------------------------------------------
def read_time_csv(path) -> TimeData:
    """Read a time-series file (column ``t``, then channels declared as inputs or outputs with units)."""
    path, meta, header, hl, rows = _read(path)
    return _time_from(path, meta, header, hl, rows)


def _time_from(path, meta, header, hl, rows):
    if meta.kind not in (None, "time"):
        raise MeasurementFileError(path, None, None, f"metadata says kind: {meta.kind}, not a time-series file")
    if header[0].lower() not in _TIME_NAMES:
        raise MeasurementFileError(path, hl, 1, f"the first column of a time-series file must be the time "
                                   f"('t'), got {header[0]!r}", header[0])
    A = _matrix(path, header, rows)
    t = A[:, 0]
    if header[0] in meta.units:
        u = _unit(path, meta, header[0], (path, hl, 1))
        if not np.allclose(u.dims, (0, 0, 1, 0, 0)):
            w = meta.units[header[0]][1]
            raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {u.text!r} for the time: use s or ms",
                                       header[0])
        t = t * u.scale
    _increasing(path, t, rows, 1, header[0], "time")
    if len(t) < 2:
        raise MeasurementFileError(path, rows[0][0], 1, "a time series needs at least two samples", header[0])
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
        (inputs if role == "input" else outputs)[name] = A[:, c - 1] * u.scale
        units[name] = u.si
        loc[("column", name)] = (hl, c)
        loc[("unit", name)] = (w[1], w[2])
    missing = [n for n in meta.roles if n not in header]
    if missing:
        w = meta.where.get((meta.roles[missing[0]], missing[0]), (path, None, None))
        raise MeasurementFileError(w[0], w[1], w[2], f"channel {missing[0]!r} is declared but has no column in the "
                                   f"header (columns: {header})", missing[0])
    if not inputs:
        raise MeasurementFileError(path, hl, None, "no input channel: mark the excitation with '# input NAME: UNIT'")
    if not outputs:
        raise MeasurementFileError(path, hl, None, "no output channel: mark responses with '# output NAME: UNIT'")
    cond, src = _conditions_and_source(meta, path)
    return TimeData(t=t, inputs=inputs, outputs=outputs, units=units, conditions=cond, source=src, locations=loc)



# ---- dispatch ----------------------------------------------------------------------------------------------
def load(path):
    """Read an FRF or time-series file, deciding by the ``kind`` metadata or else the first column name."""
    path, meta, header, hl, rows = _read(path)
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
    return [p if isinstance(p, (FrfData, TimeData)) else load(p) for p in paths]
