"""Parameter tables of the drives (public as ``bscomp.systems.parameters``): the loader for the parameter
files in ``bscomp/systems/data`` (the thesis test bed: ``fadal_vmc2216_x``).

A parameter file is TOML. Every *entry* is a table holding at least ``value``, ``unit`` and
``source`` (and optionally ``note``); every other table is a *group* of entries or sub-groups.
The top-level ``[meta]`` table is free-form. See ``docs/testbed-parameters.md``.
"""

from __future__ import annotations

import math
import os
import re
import sys
from pathlib import Path
from typing import Any

from bscomp.errors import MissingParameterFileError, ParameterFileError, UnknownNameError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised only on Python 3.10
    import tomli as tomllib

__all__ = ["DATA_DIR", "load_parameters", "get_value", "flatten", "write_variant"]

DATA_DIR = Path(__file__).resolve().parent / "data"

_REQUIRED = ("value", "unit", "source")
_OPTIONAL = ("note",)
_ENTRY_KEYS = frozenset(_REQUIRED + _OPTIONAL)
_FREE_TABLES = frozenset({"meta"})


def _resolve(name: str | Path) -> Path:
    """Return the path of parameter set ``name`` (a bundled name or a path to a ``.toml`` file)."""
    p = Path(name)
    if p.suffix == ".toml" or p.is_absolute() or len(p.parts) > 1:
        return p
    return DATA_DIR / f"{name}.toml"


def _is_entry(table: dict[str, Any]) -> bool:
    return any(k in table for k in _ENTRY_KEYS)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_value(path: Path, key: str, value) -> None:
    """A value is a finite number, a string or a list of finite numbers."""
    if isinstance(value, str):
        return
    items = value if isinstance(value, list) else [value]
    for v in items:
        if not _is_number(v):
            raise ParameterFileError(
                f"{path}: entry '{key}' has value {value!r}, which is not a number, a string or a list of numbers; "
                f"write e.g. value = 1.5")
        if not math.isfinite(v):
            raise ParameterFileError(f"{path}: entry '{key}' has the value {value!r}: NaN and inf are not "
                                     "physical; give a finite number")
    if isinstance(value, list) and not value:
        raise ParameterFileError(f"{path}: entry '{key}' has an empty list as value; give at least one number")


def _check_entry(path: Path, key: str, entry: dict[str, Any]) -> None:
    missing = [k for k in _REQUIRED if k not in entry]
    if missing:
        raise ParameterFileError(f"{path}: entry '{key}' lacks required field(s) {', '.join(missing)}; an entry "
                                 "is { value = ..., unit = ..., source = ... }")
    unknown = sorted(set(entry) - _ENTRY_KEYS)
    if unknown:
        raise ParameterFileError(f"{path}: entry '{key}' has unknown field(s) {', '.join(unknown)}; allowed: "
                                 f"{', '.join(_REQUIRED + _OPTIONAL)}")
    for k in ("unit", "source"):
        if not isinstance(entry[k], str):
            raise ParameterFileError(f"{path}: entry '{key}' field '{k}' must be a string, got {entry[k]!r}")
    if not entry["source"].strip():
        raise ParameterFileError(f"{path}: entry '{key}' has an empty 'source'; cite where the value comes from")
    if "note" in entry and not isinstance(entry["note"], str):
        raise ParameterFileError(f"{path}: entry '{key}' field 'note' must be a string, got {entry['note']!r}")
    _check_value(path, key, entry["value"])


def _check_group(path: Path, prefix: str, group: dict[str, Any]) -> None:
    if not group:
        raise ParameterFileError(f"{path}: group '{prefix}' is empty; remove it or add entries")
    for k, v in group.items():
        key = f"{prefix}.{k}" if prefix else k
        if not isinstance(v, dict):
            raise ParameterFileError(
                f"{path}: key '{key}' is a bare value; write it as an entry "
                f"{{ value = ..., unit = ..., source = ... }}"
            )
        if _is_entry(v):
            _check_entry(path, key, v)
        else:
            _check_group(path, key, v)


def load_parameters(name: str | Path = "fadal_vmc2216_x") -> dict[str, Any]:
    """Load and validate a parameter set.

    Parameters
    ----------
    name : str or pathlib.Path, optional
        Name of a bundled parameter file in :data:`DATA_DIR` (without ``.toml``), or a path to a
        TOML file. Default ``"fadal_vmc2216_x"``, the thesis test bed.

    Returns
    -------
    dict
        The parsed TOML as nested dicts. Each entry is a dict with keys ``value``, ``unit``,
        ``source`` and possibly ``note``; use :func:`get_value` for plain values.

    Raises
    ------
    bscomp.errors.MissingParameterFileError
        If the file does not exist (also a ``FileNotFoundError``).
    bscomp.errors.ParameterFileError
        If the file cannot be read or parsed as UTF-8 TOML, or an entry lacks ``value``/``unit``/``source``,
        has unknown fields or a value that is not a finite number, a string or a list of numbers, or a group
        holds a bare value. The message names the file and the dotted key; also a ``ValueError``.
    """
    if not isinstance(name, (str, Path)):
        raise ParameterFileError(f"a parameter set is a bundled name or a .toml path, got {type(name).__name__} "
                                 f"{name!r}; bundled: {sorted(p.stem for p in DATA_DIR.glob('*.toml'))}")
    path = _resolve(name)
    if not path.is_file():
        what = "is a directory, not a file" if path.is_dir() else "not found"
        raise MissingParameterFileError(f"parameter file {what}: {path}; give a .toml file or one of the bundled "
                                        f"sets {sorted(p.stem for p in DATA_DIR.glob('*.toml'))}")
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterFileError(f"{path}: invalid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ParameterFileError(f"{path}: not UTF-8 text (byte {exc.start}); save the file as UTF-8") from None
    except (OSError, RecursionError) as exc:
        raise ParameterFileError(f"{path}: cannot be read ({type(exc).__name__}: {exc})") from None
    for k, v in data.items():
        if k in _FREE_TABLES:
            continue
        if not isinstance(v, dict):
            raise ParameterFileError(f"{path}: top-level key '{k}' must be a table (group or entry), got "
                                     f"{v!r}")
        if _is_entry(v):
            _check_entry(path, k, v)
        else:
            _check_group(path, k, v)
    return data


def get_value(params: dict[str, Any], key: str) -> Any:
    """Return the ``value`` of the entry at dotted ``key`` (e.g. ``"coupling.kT"``).

    Raises
    ------
    bscomp.errors.UnknownNameError
        If ``key`` does not name an entry (also a ``KeyError``).
    """
    node: Any = params
    for part in str(key).split("."):
        if not isinstance(node, dict) or part not in node:
            near = sorted(node) if isinstance(node, dict) else []
            raise UnknownNameError(f"no parameter entry '{key}' ('{part}' not found; there: {near[:12]})")
        node = node[part]
    if not isinstance(node, dict) or "value" not in node:
        raise UnknownNameError(f"'{key}' is a group, not a parameter entry; its entries: "
                               f"{sorted(node)[:12] if isinstance(node, dict) else []}")
    return node["value"]


def flatten(params: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Return ``{dotted_key: entry}`` for every entry (the ``[meta]`` table is skipped)."""
    out: dict[str, dict[str, Any]] = {}

    def walk(prefix: str, group: dict[str, Any]) -> None:
        for k, v in group.items():
            key = f"{prefix}.{k}" if prefix else k
            if not prefix and k in _FREE_TABLES:
                continue
            if isinstance(v, dict) and "value" in v:
                out[key] = v
            elif isinstance(v, dict):
                walk(key, v)

    walk("", params)
    return out


_NUMBER = r"[-+]?[0-9][0-9_.eE+-]*"


def _toml_number(value) -> str:
    """A TOML number: an int stays an int (element counts), anything else a float."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(int(value))
    return repr(float(value))


def _replace_value(text: str, key: str, value: float) -> str:
    """``text`` with the numeric value of the entry at dotted ``key`` set to ``value`` (an inline entry
    ``name = { value = x, ... }`` in its group's table, or a table ``[key]`` with a ``value = x`` line); the old
    value is kept in a comment on the line."""
    group, _, name = key.rpartition(".")
    forms = ((group, rf"^({re.escape(name)}\s*=\s*\{{\s*value\s*=\s*)({_NUMBER})(.*)$"),
             (key, rf"^(value\s*=\s*)({_NUMBER})(.*)$"))
    for table, line in forms:
        head = re.search(rf"^\[{re.escape(table)}\]\s*$", text, flags=re.M) if table else None
        start = head.end() if head else (0 if not table else None)
        if start is None:
            continue
        nxt = re.search(r"^\[", text[start:], flags=re.M)
        end = start + nxt.start() if nxt else len(text)
        body, n = re.subn(line, lambda m: f"{m[1]}{_toml_number(value)}{m[3]}  # variant: was {m[2]}", text[start:end],
                          count=1, flags=re.M)
        if n:
            return text[:start] + body + text[end:]
    raise UnknownNameError(f"write_variant: no numeric parameter entry '{key}' in the parameter file (an inline "
                           "'name = { value = ... }' in its group or a '[key]' table with a 'value' line)")


def write_variant(changes: dict[str, float], path: str | Path, base: str | Path = "fadal_vmc2216_x") -> Path:
    """Write a copy of parameter set ``base`` with the values of ``changes`` (``{dotted key: value}``) to ``path``.

    Another drive built from the same components -- a heavier table, a larger motor, a softer bearing -- without
    editing the bundled file: each changed line keeps its unit and source and gets a comment with the old value.
    The copy is loaded back and each changed value checked; an existing file with the same text is not rewritten
    (several processes may ask for the same variant).

    Raises
    ------
    bscomp.errors.UnknownNameError
        A key that names no numeric entry of ``base`` (also a ``KeyError``).
    """
    text = _resolve(base).read_text(encoding="utf-8")
    for key, value in changes.items():
        text = _replace_value(text, key, value)
    path = Path(path)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")   # one per process: no shared temp file
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)                      # whole or not at all: no half-written file for a reader
    params = load_parameters(path)
    for key, value in changes.items():
        if get_value(params, key) != float(value):
            raise ParameterFileError(f"write_variant: {path}: '{key}' reads {get_value(params, key)!r} after "
                                     f"writing {value!r}")
    return path
