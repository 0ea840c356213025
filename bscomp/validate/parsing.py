"""The text layer of the measurement readers: a CSV file's ``#`` metadata lines, its JSON/TOML sidecar and
its table of numbers, guarded so that every problem raises
:class:`~bscomp.validate.datasets.MeasurementFileError` (format: ``docs/measurements.md``).

Guards: files are decoded as UTF-8 (a Latin-1 file is a named error with its line), sizes are capped
(:data:`MAX_FILE_BYTES`, :data:`MAX_SIDECAR_BYTES`), a sidecar nested too deep is a named error, a unit or
condition given twice with different values is an error naming both places, and conditions are checked by
:func:`~bscomp.validate.datasets.check_condition` (plain numbers or strings, never a file path). The table is
parsed by NumPy's C reader (10⁶ rows in about a second, memory proportional to the data); only a table that
reader rejects is re-read line by line to name the offending line and column.
"""

from __future__ import annotations

import csv
import json
import math
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from bscomp.kernel.units import UnitSyntaxError, parse_unit
from bscomp.validate.datasets import MeasurementFileError, check_condition

__all__ = ["Meta", "Table", "read_table", "MAX_FILE_BYTES", "MAX_SIDECAR_BYTES"]

#: largest measurement CSV read (2 GiB: ~2·10⁷ rows of five channels)
MAX_FILE_BYTES = 2 * 1024 ** 3
#: largest sidecar read (metadata only)
MAX_SIDECAR_BYTES = 1024 ** 2
#: a number and an optional unit: "2 V", "2V", "200 mV", "2.0"
_NUMBER_UNIT = re.compile(r"^([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf))\s*(.*)$", re.I)
#: deepest nesting of a sidecar (its format needs 2)
MAX_SIDECAR_DEPTH = 8


@dataclass
class Meta:
    """Metadata of one measurement file, from its sidecar and its ``#`` lines."""

    kind: str | None = None
    source: str | None = None
    conditions: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)      # name -> (text, where: (file, line, col))
    roles: dict = field(default_factory=dict)      # name -> "input" | "output"
    excitation: dict = field(default_factory=dict)  # input -> sine amplitude of an FRF measurement [SI]
    excitation_units: dict = field(default_factory=dict)  # input -> SI unit of that amplitude (if one was given)
    where: dict = field(default_factory=dict)      # key -> (file, line, col)


def _value(value):
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    text = str(value).strip()
    try:
        return float(text)
    except ValueError:
        return text


def _place(w) -> str:
    return f"{w[0]}" + (f", line {w[1]}" if w[1] is not None else "")


def _same_unit(a: str, b: str) -> bool:
    if a == b:
        return True
    try:
        ua, ub = parse_unit(a), parse_unit(b)
    except UnitSyntaxError:
        return False
    return math.isclose(ua.scale, ub.scale, rel_tol=1e-12) and ua.dims == ub.dims


def _set_once(meta, table, head, name, value, where, same):
    """Enter ``table[name] = value``; a second, different value is an error naming both places."""
    if name in table and not same(table[name], value):
        w0 = meta.where.get((head, name), (None, None, None))
        raise MeasurementFileError(where[0], where[1], where[2], f"{head} {name!r} is {value!r} here but "
                                   f"{table[name]!r} in {_place(w0)}: give it once, or make both agree", name)
    table[name] = value


def meta_set(meta, key, value, where):
    """One metadata entry ``key: value``; ``key`` as in the comment syntax."""
    key = key.strip()
    words = key.split(None, 1)
    head = words[0].lower() if words else ""
    if head in ("kind", "source", "description", "name") and len(words) == 1:
        if isinstance(value, (dict, list)):
            raise MeasurementFileError(where[0], where[1], where[2], f"{head!r} must be a string, not a "
                                       f"{type(value).__name__}")
        if head == "kind":
            v = str(value).strip().lower()
            if v not in ("frf", "time"):
                raise MeasurementFileError(where[0], where[1], where[2], f"kind must be 'frf' or 'time', got {v!r}")
            meta.kind = v
        elif head == "source":
            meta.source = str(value).strip()
        return
    if head == "excitation" and len(words) == 2:
        name = words[1].strip()
        a, unit = _amplitude(name, value, where)
        _set_once(meta, meta.excitation, head, name, a, where, lambda a, b: math.isclose(a, b, rel_tol=1e-12))
        if unit:
            meta.excitation_units.setdefault(name, unit)
        meta.where.setdefault((head, name), where)
        return
    if head in ("condition", "unit", "input", "output") and len(words) == 2:
        name = words[1].strip()
        if isinstance(value, (dict, list)):
            raise MeasurementFileError(where[0], where[1], where[2], f"{head} {name!r} must be a number or a "
                                       f"string, not a {type(value).__name__}", name)
        if head == "condition":
            v = check_condition(name, _value(value), where)
            _set_once(meta, meta.conditions, head, name, v, where, lambda a, b: a == b)
        else:
            if head in ("input", "output"):
                _set_once(meta, meta.roles, "role of", name, head, where, lambda a, b: a == b)
            if str(value).strip():
                text = str(value).strip()
                if name in meta.units and not _same_unit(meta.units[name][0], text):
                    w0 = meta.units[name][1]
                    raise MeasurementFileError(where[0], where[1], where[2], f"unit of {name!r} is {text!r} here "
                                               f"but {meta.units[name][0]!r} in {_place(w0)}: declare it once, or "
                                               "make both agree", name)
                meta.units.setdefault(name, (text, where))
        meta.where.setdefault((head, name), where)
        meta.where.setdefault(("role of", name), where)
        return
    raise MeasurementFileError(where[0], where[1], where[2],
                               f"unknown metadata key {key!r}: use 'kind', 'source', 'condition NAME', "
                               "'unit NAME', 'input NAME', 'output NAME' or 'excitation NAME'")


def _amplitude(name, value, where) -> tuple:
    """``excitation NAME: 2 V`` (or a bare number, SI): the sine amplitude an FRF was measured at, in SI, and
    the SI spelling of its unit ("" for a bare number)."""
    text = str(value).strip()
    m = _NUMBER_UNIT.match(text)
    try:
        if m is None:
            raise ValueError("no number first")
        unit = parse_unit(m.group(2)) if m.group(2).strip() else None
        a = float(m.group(1)) * (unit.scale if unit else 1.0)
    except (ValueError, UnitSyntaxError) as exc:
        raise MeasurementFileError(where[0], where[1], where[2], f"excitation {name!r} must be the sine's amplitude, "
                                   f"a number with an optional unit (e.g. '2 V'), got {text!r} ({exc})", name) from None
    if not (math.isfinite(a) and a > 0):
        raise MeasurementFileError(where[0], where[1], where[2], f"excitation {name!r} must be a positive, finite "
                                   f"amplitude, got {text!r}", name)
    return a, (unit.si if unit else "")


def _line_of(text, needle):
    """(line, col) of the first occurrence of ``needle`` in ``text`` (1-based), or (None, None)."""
    k = text.find(needle)
    if k < 0:
        return None, None
    return text.count("\n", 0, k) + 1, k - (text.rfind("\n", 0, k) + 1) + 1


def _depth(obj, limit, d=1):
    """Nesting depth of parsed JSON/TOML, stopping past ``limit``."""
    if d > limit or not isinstance(obj, (dict, list)):
        return d
    items = obj.values() if isinstance(obj, dict) else obj
    return max([d] + [_depth(v, limit, d + 1) for v in items])


def _decode(path: Path, raw: bytes) -> str:
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise MeasurementFileError(path, line, None, f"not a UTF-8 text file (byte 0x{raw[exc.start]:02x} at "
                                   f"offset {exc.start}): save it as UTF-8") from None


def _parse_sidecar(sc: Path):
    """The sidecar's text and its parsed top-level object."""
    size = sc.stat().st_size
    if size > MAX_SIDECAR_BYTES:
        raise MeasurementFileError(sc, None, None, f"sidecar of {size} bytes (at most {MAX_SIDECAR_BYTES}): it "
                                   "holds metadata only")
    text = _decode(sc, sc.read_bytes())
    try:
        if sc.suffix == ".json":
            d = json.loads(text)
        else:
            d = tomllib.loads(text)
    except json.JSONDecodeError as exc:
        raise MeasurementFileError(sc, exc.lineno, exc.colno, f"invalid JSON: {exc.msg}") from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+), column (\d+)", str(exc))
        raise MeasurementFileError(sc, int(m.group(1)) if m else None, int(m.group(2)) if m else None,
                                   f"invalid TOML: {exc}") from None
    except RecursionError:
        raise MeasurementFileError(sc, None, None, "sidecar nested too deep to parse (its format needs two "
                                   "levels: {\"units\": {name: unit}})") from None
    except ValueError as exc:           # e.g. an integer of more than 4300 digits
        raise MeasurementFileError(sc, None, None, f"invalid sidecar: {exc}") from None
    if not isinstance(d, dict):
        raise MeasurementFileError(sc, 1, 1, "the sidecar must hold a table/object of metadata")
    if _depth(d, MAX_SIDECAR_DEPTH) > MAX_SIDECAR_DEPTH:
        raise MeasurementFileError(sc, None, None, f"sidecar nested deeper than {MAX_SIDECAR_DEPTH} levels (its "
                                   "format needs two: {\"units\": {name: unit}})")
    return text, d


def _sidecar(path: Path, meta: Meta):
    cands = [Path(str(path) + ".json"), Path(str(path) + ".toml"), path.with_suffix(".json"),
             path.with_suffix(".toml")]
    for sc in cands:
        if sc == path or not sc.is_file():
            continue
        text, d = _parse_sidecar(sc)

        def at(key, text=text, sc=sc):
            ln, col = _line_of(text, f'"{key}"' if sc.suffix == ".json" else str(key))
            return (sc, ln, col)

        for k, v in d.items():
            if k in ("kind", "source", "description", "name"):
                meta_set(meta, k, v, at(k))
            elif k in ("conditions", "units", "inputs", "outputs", "excitation"):
                if not isinstance(v, dict):
                    w = at(k)
                    raise MeasurementFileError(w[0], w[1], w[2], f"'{k}' must map names to values")
                sub = {"conditions": "condition", "units": "unit", "inputs": "input", "outputs": "output",
                       "excitation": "excitation"}[k]
                for name, val in v.items():
                    meta_set(meta, f"{sub} {name}", val, at(name))
            else:
                w = at(k)
                raise MeasurementFileError(w[0], w[1], w[2], f"unknown sidecar key {k!r}: use kind, source, "
                                           "conditions, units, inputs, outputs, excitation")
        return sc
    return None


# ---- the table ------------------------------------------------------------------------------------------------
class Table:
    """The numbers of a CSV file: :attr:`A` (rows x columns, float) and the file line of each row (found
    only when an error needs it, by reading the file again)."""

    def __init__(self, A, path, first_line: int, lines=None):
        self.A, self._path, self._first, self._lines = A, path, first_line, lines

    def __len__(self):
        return self.A.shape[0]

    def line(self, k: int) -> int:
        """File line (1-based) of data row ``k``."""
        if self._lines is None:
            body = _body(self._path, self._first)
            self._lines = [self._first + i for i, s in enumerate(body.split("\n"))
                           if s.strip() and not s.lstrip().startswith("#")]
        return self._lines[k]


def _body(path, first_line: int) -> str:
    """The file's text from line ``first_line`` on (newlines normalised)."""
    text = _decode(path, path.read_bytes()).replace("\r\n", "\n").replace("\r", "\n")
    pos = 0
    for _ in range(first_line - 1):
        pos = text.find("\n", pos) + 1
        if pos == 0:
            return ""
    return text[pos:]


def _rows_slow(path, header, first_line):
    """Row-by-row parse with the exact line and column of the first problem (the fallback)."""
    n = len(header)
    rows, lines = [], []
    for i, line in enumerate(_body(path, first_line).split("\n")):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        ln = first_line + i
        try:
            fields = [f.strip() for f in next(csv.reader([line], skipinitialspace=True))]
        except csv.Error as exc:
            raise MeasurementFileError(path, ln, None, f"malformed CSV row: {exc}") from None
        if len(fields) != n:
            c = min(len(fields), n) + 1
            raise MeasurementFileError(path, ln, c, f"row has {len(fields)} fields, the header has {n}",
                                       header[c - 1] if c <= n else None)
        row = []
        for c, txt in enumerate(fields):
            try:
                row.append(float(txt))
            except ValueError:
                raise MeasurementFileError(path, ln, c + 1, f"{txt[:40]!r} is not a number", header[c]) from None
        rows.append(row)
        lines.append(ln)
    return np.array(rows, float).reshape(len(rows), n), lines


def _table(path, header, hl) -> Table:
    """The rows after the header line ``hl``: NumPy's C reader streams the file; what it rejects is re-read
    row by row for the exact place."""
    lines = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            A = np.loadtxt(path, delimiter=",", comments="#", ndmin=2, dtype=float, skiprows=hl,
                           encoding="utf-8-sig")
        if A.shape[1] != len(header) and A.shape[0] > 0:
            raise ValueError("column count")
    except (ValueError, UnicodeDecodeError):
        A, lines = _rows_slow(path, header, hl + 1)
    if A.shape[0] == 0:
        raise MeasurementFileError(path, hl, 1, "no data rows after the header")
    table = Table(A, path, hl + 1, lines)
    bad = ~np.isfinite(A)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise MeasurementFileError(path, table.line(int(r)), int(c) + 1, f"value {float(A[r, c])!r} is not finite "
                                   "(NaN or inf): remove the row or fill the gap", header[c])
    return table


def _header(path, meta):
    """Read the ``#`` metadata lines up to the header row: ``(header, header_line, last_line)``."""
    ln = 0
    with open(path, encoding="utf-8-sig", newline=None) as fh:
        for ln, line in enumerate(fh, start=1):
            line = line.rstrip("\n")
            s = line.strip()
            if not s:
                continue
            if s.startswith("#"):
                body = s[1:].strip()
                key, colon, value = body.partition(":")
                if colon:
                    vcol = line.find(":") + 2 + (len(value) - len(value.lstrip()))
                    meta_set(meta, key, value, (path, ln, vcol))
                elif body and body.split()[0].lower() in ("input", "output") and len(body.split()) == 2:
                    meta_set(meta, body, "", (path, ln, len(line) + 1))  # declared, unit missing
                continue
            try:
                return [f.strip() for f in next(csv.reader([line], skipinitialspace=True))], ln, ln
            except csv.Error as exc:
                raise MeasurementFileError(path, ln, None, f"malformed CSV header: {exc}") from None
    return None, None, ln


def read_table(path):
    """``(path, meta, header, header_line, table)`` of a measurement CSV file (see the module notes)."""
    if not isinstance(path, (str, Path)):
        raise MeasurementFileError(str(path)[:80], None, None, f"a measurement file is given by its path (str or "
                                   f"pathlib.Path), got {type(path).__name__}")
    path = Path(path)
    if not path.is_file():
        raise MeasurementFileError(path, None, None, "no such file")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise MeasurementFileError(path, None, None, f"file of {size} bytes (at most {MAX_FILE_BYTES}): split it "
                                   "or decimate the data")
    meta = Meta()
    _sidecar(path, meta)
    try:
        header, hl, ln = _header(path, meta)
    except UnicodeDecodeError:
        _decode(path, path.read_bytes())       # raises, naming the line
        raise
    if header is None:
        raise MeasurementFileError(path, ln or 1, 1, "empty file: no header row and no data")
    seen = {}
    for c, name in enumerate(header, start=1):
        if not name:
            raise MeasurementFileError(path, hl, c, "empty column name in the header")
        if name in seen:
            raise MeasurementFileError(path, hl, c, f"column {name!r} repeats column {seen[name]}", name)
        seen[name] = c
    return path, meta, header, hl, _table(path, header, hl)
