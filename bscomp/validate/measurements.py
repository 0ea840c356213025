"""Measurements: frequency responses (:class:`FrfData`) and time series (:class:`TimeData`) read from and
written to plain CSV (format documented in ``docs/measurements.md``).

A file is a header row of column names and rows of numbers. Its metadata -- kind, units, which channels
are inputs, operating conditions such as the nut position -- is given either as ``# key: value`` comment
lines above the header or in a JSON/TOML sidecar (``data.csv.json``, ``data.csv.toml``, ``data.json`` or
``data.toml``)::

    # kind: frf
    # source: stepped sine, test bed x-axis, 2024-03-02
    # condition nut_position: 0.43
    # unit rotor.w/motor.tau: rad/s/(N m)
    f,re(rotor.w/motor.tau),im(rotor.w/motor.tau),coh(rotor.w/motor.tau)
    10.0,-0.05,-2.6,0.99

Values are converted to SI on reading (a channel in ``um`` is multiplied by 1e-6; ``deg`` becomes
``rad``), so :attr:`FrfData.units` and :attr:`TimeData.units` hold SI spellings. Data files are parsed,
never executed. Every problem raises :class:`MeasurementFileError` naming the file, the line and the
column.
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

from bscomp.errors import BscompError
from bscomp.kernel.units import UnitSyntaxError, convention_units, expected_dimension_ok, parse_unit

__all__ = ["FrfData", "TimeData", "MeasurementFileError", "read_frf_csv", "write_frf_csv", "read_time_csv",
           "write_time_csv", "load", "load_all"]

_FREQ_NAMES = ("f", "freq", "freq_hz", "frequency")
_TIME_NAMES = ("t", "time")
_FRF_COL = re.compile(r"^(re|im|mag|mag_db|phase_deg|phase_rad|coh)\((.+)\)$")


class MeasurementFileError(BscompError, ValueError):
    """A measurement file cannot be used; the message names the file, line and column.

    Attributes
    ----------
    path : str
    line : int or None
        1-based line in the file (of the CSV, or of the sidecar for sidecar problems).
    column : int or None
        1-based CSV column (field number), or character column in a sidecar or metadata line.
    """

    def __init__(self, path, line, column, message, column_name=None):
        self.path, self.line, self.column, self.column_name = str(path), line, column, column_name
        where = str(path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column {column}"
            if column_name:
                where += f" ({column_name!r})"
        super().__init__(f"{where}: {message}")


# ---- data classes -------------------------------------------------------------------------------------
@dataclass
class FrfData:
    """Measured frequency responses.

    Attributes
    ----------
    freqs : (nf,) ndarray
        Frequencies [Hz], strictly increasing.
    H : dict (input, output) -> (nf,) complex ndarray
        Response of ``output`` to ``input``, in SI units (:attr:`units`).
    units : dict (input, output) -> str
        SI unit of each response, e.g. ``"rad/s/(N m)"``.
    conditions : dict str -> float or str
        Operating conditions (``nut_position``...); passed to a build function by
        :func:`bscomp.validate.residuals.model_frf`.
    coherence : dict (input, output) -> ndarray or None
        Ordinary coherence in [0, 1] per pair (None: not measured).
    source : str
        File name or description.
    locations : dict
        Where things were declared in the file (``("column", pair)`` / ``("unit", pair)`` -> (line,
        column)), so later checks can point at the file.
    """

    freqs: np.ndarray
    H: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    coherence: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)

    kind = "frf"

    @property
    def pairs(self) -> list:
        """(input, output) pairs in file order."""
        return list(self.H)

    @property
    def inputs(self) -> list:
        return list(dict.fromkeys(i for i, _ in self.H))

    @property
    def outputs(self) -> list:
        return list(dict.fromkeys(o for _, o in self.H))

    def __post_init__(self):
        self.freqs = np.asarray(self.freqs, float)
        self.H = {tuple(k): np.asarray(v, complex) for k, v in self.H.items()}
        self.coherence = {tuple(k): (None if v is None else np.asarray(v, float))
                          for k, v in (self.coherence or {}).items()}
        self.units = {tuple(k): v for k, v in (self.units or {}).items()}


@dataclass
class TimeData:
    """Measured time series.

    Attributes
    ----------
    t : (nt,) ndarray
        Sample times [s], strictly increasing.
    inputs : dict name -> (nt,) ndarray
        Excitations applied to the model (``motor.tau``), SI.
    outputs : dict name -> (nt,) ndarray
        Measured responses compared with the model (``table.a``), SI.
    units : dict name -> str
        SI unit of each channel.
    conditions : dict str -> float or str
    source : str
    locations : dict
        ``("column", name)`` / ``("unit", name)`` -> (line, column) in the file.
    """

    t: np.ndarray
    inputs: dict
    outputs: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)

    kind = "time"

    def __post_init__(self):
        self.t = np.asarray(self.t, float)
        self.inputs = {k: np.asarray(v, float) for k, v in self.inputs.items()}
        self.outputs = {k: np.asarray(v, float) for k, v in self.outputs.items()}


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
            import tomllib

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
    ``phase_deg``/``phase_rad``, optional ``coh``); see ``docs/measurements.md``."""
    path, meta, header, hl, rows = _read(path)
    return _frf_from(path, meta, header, hl, rows)


def _frf_from(path, meta, header, hl, rows):
    if meta.kind not in (None, "frf"):
        raise MeasurementFileError(path, None, None, f"metadata says kind: {meta.kind}, not an FRF file")
    if header[0].lower() not in _FREQ_NAMES:
        raise MeasurementFileError(path, hl, 1, f"the first column of an FRF file must be the frequency "
                                   f"(one of {list(_FREQ_NAMES)}), got {header[0]!r}", header[0])
    A = _matrix(path, header, rows)
    f = A[:, 0]
    fscale = 1.0
    if header[0] in meta.units or "f" in meta.units:
        key = header[0] if header[0] in meta.units else "f"
        u = _unit(path, meta, key, (path, hl, 1))
        if not np.allclose(u.dims[:4], (0, 0, -1, 0)):
            w = meta.units[key][1]
            raise MeasurementFileError(w[0], w[1], w[2], f"wrong unit {u.text!r} for the frequency: use Hz or kHz",
                                       key)
        fscale = u.scale / (2 * np.pi if u.dims[4] == 1 else 1.0)
    f = f * fscale
    if np.any(f < 0):
        k = int(np.flatnonzero(f < 0)[0])
        raise MeasurementFileError(path, rows[k][0], 1, "negative frequency", header[0])
    _increasing(path, f, rows, 1, header[0], "frequency")
    cols: dict = {}
    for c, name in enumerate(header[1:], start=2):
        m = _FRF_COL.match(name)
        inner = m.group(2) if m else ""
        if not m or "/" not in inner:
            raise MeasurementFileError(path, hl, c, f"unknown column {name!r}: FRF columns are re(<out>/<in>), "
                                       "im(...), mag(...), mag_db(...), phase_deg(...), phase_rad(...), coh(...)",
                                       name)
        out, inp = inner.rsplit("/", 1)
        out, inp = out.strip(), inp.strip()
        if not out or not inp:
            raise MeasurementFileError(path, hl, c, f"column {name!r} must name <output>/<input>", name)
        cols.setdefault((inp, out), {})[m.group(1)] = (c, A[:, c - 1])
    if not cols:
        raise MeasurementFileError(path, hl, 2, "no response columns after the frequency")
    H, units, coh, loc = {}, {}, {}, {}
    for (inp, out), d in cols.items():
        pname = f"{out}/{inp}"
        first = min(c for c, _ in d.values())
        loc[("column", (inp, out))] = (hl, first)
        if "re" in d or "im" in d:
            if "re" not in d or "im" not in d:
                c = first
                raise MeasurementFileError(path, hl, c, f"{pname}: give both re(...) and im(...)", header[c - 1])
            h = d["re"][1] + 1j * d["im"][1]
            extra = [k for k in ("mag", "mag_db", "phase_deg", "phase_rad") if k in d]
            if extra:
                c = d[extra[0]][0]
                raise MeasurementFileError(path, hl, c, f"{pname}: give re/im or magnitude/phase, not both",
                                           header[c - 1])
        elif "coh" in d and len(d) == 1:
            c = d["coh"][0]
            raise MeasurementFileError(path, hl, c, f"coherence for {pname} but no response columns for it",
                                       header[c - 1])
        else:
            mags = [k for k in ("mag", "mag_db") if k in d]
            phs = [k for k in ("phase_deg", "phase_rad") if k in d]
            if len(mags) != 1 or len(phs) != 1:
                c = first
                raise MeasurementFileError(path, hl, c, f"{pname}: give one magnitude column (mag or mag_db) and "
                                           "one phase column (phase_deg or phase_rad)", header[c - 1])
            mag = d[mags[0]][1]
            if mags[0] == "mag_db":
                mag = 10.0 ** (mag / 20.0)
            elif np.any(mag < 0):
                k = int(np.flatnonzero(mag < 0)[0])
                raise MeasurementFileError(path, rows[k][0], d["mag"][0], "negative magnitude", header[d["mag"][0] - 1])
            ph = d[phs[0]][1]
            h = mag * np.exp(1j * (np.radians(ph) if phs[0] == "phase_deg" else ph))
        if "coh" in d:
            c, g = d["coh"]
            bad = np.flatnonzero((g < 0) | (g > 1))
            if bad.size:
                k = int(bad[0])
                raise MeasurementFileError(path, rows[k][0], c, f"coherence {g[k]:.6g} outside [0, 1]", header[c - 1])
            coh[(inp, out)] = g
        else:
            coh[(inp, out)] = None
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


def _fmt(x):
    return repr(float(x))


def _meta_lines(kind, source, conditions):
    out = [f"# kind: {kind}"]
    if source:
        out.append(f"# source: {source}")
    for k, v in (conditions or {}).items():
        out.append(f"# condition {k}: {v}")
    return out


def write_frf_csv(data: FrfData, path, form: str = "reim") -> Path:
    """Write ``data`` as CSV with ``# key: value`` metadata (``form``: ``"reim"`` or ``"magphase"``)."""
    if form not in ("reim", "magphase"):
        raise ValueError(f"form must be 'reim' or 'magphase', got {form!r}")
    path = Path(path)
    lines = _meta_lines("frf", data.source, data.conditions)
    head = ["f"]
    cols = [np.asarray(data.freqs, float)]
    for (inp, out), h in data.H.items():
        p = f"{out}/{inp}"
        lines.append(f"# unit {p}: {data.units.get((inp, out), '1')}")
        if form == "reim":
            head += [f"re({p})", f"im({p})"]
            cols += [h.real, h.imag]
        else:
            head += [f"mag({p})", f"phase_deg({p})"]
            cols += [np.abs(h), np.degrees(np.angle(h))]
        g = data.coherence.get((inp, out))
        if g is not None:
            head.append(f"coh({p})")
            cols.append(np.asarray(g, float))
    lines.append(",".join(head))
    M = np.column_stack(cols)
    lines += [",".join(_fmt(v) for v in row) for row in M]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


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


def write_time_csv(data: TimeData, path) -> Path:
    """Write ``data`` as CSV with ``# input``/``# output`` unit lines and conditions."""
    path = Path(path)
    lines = _meta_lines("time", data.source, data.conditions)
    lines.append("# unit t: s")
    for n in data.inputs:
        lines.append(f"# input {n}: {data.units.get(n, '1')}")
    for n in data.outputs:
        lines.append(f"# output {n}: {data.units.get(n, '1')}")
    names = list(data.inputs) + list(data.outputs)
    lines.append(",".join(["t"] + names))
    M = np.column_stack([data.t] + [data.inputs[n] for n in data.inputs] + [data.outputs[n] for n in data.outputs])
    lines += [",".join(_fmt(v) for v in row) for row in M]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


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
