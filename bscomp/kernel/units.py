"""A small SI unit parser for measurement files: ``"um/(N m)"`` -> scale 1e-6 to SI, dimensions, and
the SI spelling ``"m/(N m)"``.

Grammar: products by ``*``, ``.``, ``·`` or a space, quotients by ``/`` (left to right, so
``rad/s/(N m)`` is rad per second per newton-metre), parentheses, integer exponents written ``^2``,
``**2`` or ``²``. Units: m, g, s, A, N, J, W, Pa, V, Hz, rad, deg, rev, rpm, min, h with the SI prefixes
n, u/µ, m, c, k, M, G (``mm``, ``um``, ``kN``, ``mrad``...); ``1`` or ``-`` for dimensionless.

The angle is kept as its own dimension (so ``deg`` converts to ``rad``) but :func:`same_dimension`
ignores it, as SI does (``1/s`` and ``rad/s`` agree).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["Unit", "parse_unit", "parse_quantity", "same_dimension", "UnitSyntaxError", "convention_units"]

# dimension order: m, kg, s, A, rad
_BASE = {
    "m": (1.0, (1, 0, 0, 0, 0), "m"),
    "g": (1e-3, (0, 1, 0, 0, 0), "kg"),
    "s": (1.0, (0, 0, 1, 0, 0), "s"),
    "A": (1.0, (0, 0, 0, 1, 0), "A"),
    "N": (1.0, (1, 1, -2, 0, 0), "N"),
    "J": (1.0, (2, 1, -2, 0, 0), "J"),
    "W": (1.0, (2, 1, -3, 0, 0), "W"),
    "Pa": (1.0, (-1, 1, -2, 0, 0), "Pa"),
    "V": (1.0, (2, 1, -3, -1, 0), "V"),
    "Hz": (1.0, (0, 0, -1, 0, 0), "Hz"),
    "rad": (1.0, (0, 0, 0, 0, 1), "rad"),
}
_SPECIAL = {
    "kg": (1.0, (0, 1, 0, 0, 0), "kg"),
    "deg": (math.pi / 180, (0, 0, 0, 0, 1), "rad"),
    "rev": (2 * math.pi, (0, 0, 0, 0, 1), "rad"),
    "rpm": (2 * math.pi / 60, (0, 0, -1, 0, 1), "(rad/s)"),
    "min": (60.0, (0, 0, 1, 0, 0), "s"),
    "h": (3600.0, (0, 0, 1, 0, 0), "s"),
    "Nm": (1.0, (2, 1, -2, 0, 0), "(N m)"),
    "1": (1.0, (0, 0, 0, 0, 0), "1"),
    "-": (1.0, (0, 0, 0, 0, 0), "1"),
}
_PREFIX = {"n": 1e-9, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "m": 1e-3, "c": 1e-2, "k": 1e3, "M": 1e6, "G": 1e9}
_TOKEN = re.compile(r"\s*(?:(?P<num>[+-]?\d+)|(?P<word>[A-Za-zµμ]+|-)|(?P<op>\*\*|[*/·.()^])|"
                    r"(?P<sup>⁻?[¹²³⁴⁵⁶⁷⁸⁹⁰]+))")
_SUP = str.maketrans("⁻¹²³⁴⁵⁶⁷⁸⁹⁰", "-1234567890")
#: bounds that keep every unit a physical one and every scale a finite, nonzero float
MAX_EXPONENT = 9           # |n| in m^n, s⁻², ...
MAX_DIMENSION = 12         # |exponent| of a base dimension in the result (kg m^2 s^-3 A^-1 is 3)
MAX_LENGTH = 200           # characters of a unit string
MAX_DEPTH = 10             # nested parentheses


class UnitSyntaxError(ValueError):
    """A unit string that cannot be parsed; ``pos`` is the 0-based character offset of the problem."""

    def __init__(self, msg, pos=0):
        super().__init__(msg)
        self.pos = pos


@dataclass(frozen=True)
class Unit:
    """A parsed unit: multiply a value by :attr:`scale` to get SI; :attr:`si` is its SI spelling."""

    text: str
    scale: float
    dims: tuple
    si: str


def _power(scale: float, n: int) -> float:
    """``scale ** n``; inf on overflow (the final check of :func:`parse_unit` names it)."""
    try:
        return scale ** n
    except (OverflowError, ZeroDivisionError):
        return math.inf


def _lookup(word, pos):
    if word in _SPECIAL:
        return _SPECIAL[word]
    if word in _BASE:
        return _BASE[word]
    if len(word) > 1 and word[0] in _PREFIX and word[1:] in _BASE:
        sc, d, si = _BASE[word[1:]]
        return _PREFIX[word[0]] * sc, d, si
    raise UnitSyntaxError(f"unknown unit '{word}' (known: {', '.join(sorted(set(_BASE) | set(_SPECIAL)))}, "
                          "with prefixes n, u, m, c, k, M, G)", pos)


def parse_unit(text: str) -> Unit:
    """Parse a unit string; raises :class:`UnitSyntaxError` with the offending position."""
    text = str(text).strip()
    if not text:
        raise UnitSyntaxError("empty unit (write 1 for a dimensionless quantity)", 0)
    if len(text) > MAX_LENGTH:
        raise UnitSyntaxError(f"unit of {len(text)} characters (at most {MAX_LENGTH})", MAX_LENGTH)
    toks = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            raise UnitSyntaxError(f"unexpected character {text[pos]!r} in unit '{text}'", pos)
        kind = m.lastgroup
        toks.append((kind, m.group(kind), m.start(kind)))
        pos = m.end()
    i = 0
    depth = 0

    def exponent(val, p):
        try:
            n = int(val.translate(_SUP))
        except ValueError:
            raise UnitSyntaxError(f"malformed exponent {val!r} in unit '{text}'", p) from None
        if abs(n) > MAX_EXPONENT:
            raise UnitSyntaxError(f"exponent {n} in unit '{text}' is out of range (|n| <= {MAX_EXPONENT})", p)
        return n

    def peek():
        return toks[i] if i < len(toks) else (None, None, len(text))

    def factor():
        nonlocal i, depth
        kind, val, p = peek()
        if kind == "word" or (kind == "num" and val == "1"):
            i += 1
            sc, d, si = _lookup(val, p)
            node = (sc, np.array(d, float), si)
        elif kind == "op" and val == "(":
            i += 1
            depth += 1
            if depth > MAX_DEPTH:
                raise UnitSyntaxError(f"parentheses nested deeper than {MAX_DEPTH} in unit '{text}'", p)
            node = expr()
            depth -= 1
            k2, v2, p2 = peek()
            if v2 != ")":
                raise UnitSyntaxError(f"missing ')' in unit '{text}'", p2)
            i += 1
            node = (node[0], node[1], f"({node[2]})")
        else:
            raise UnitSyntaxError(f"expected a unit name in '{text}'", p)
        kind, val, p = peek()
        exp = None
        if kind == "op" and val in ("^", "**"):
            i += 1
            k2, v2, p2 = peek()
            if k2 != "num":
                raise UnitSyntaxError(f"expected an integer exponent after '{val}' in '{text}'", p2)
            i += 1
            exp = exponent(v2, p2)
        elif kind == "sup":
            i += 1
            exp = exponent(val, p)
        elif kind == "num":
            i += 1
            exp = exponent(val, p)
        if exp is not None:
            node = (_power(node[0], exp), node[1] * exp, f"{node[2]}^{exp}")
        return node

    def expr():
        nonlocal i
        sc, d, si = factor()
        while True:
            kind, val, p = peek()
            if kind is None or (kind == "op" and val == ")"):
                return sc, d, si
            if kind == "op" and val == "/":
                i += 1
                s2, d2, si2 = factor()
                sc, d, si = (sc / s2 if s2 else math.inf), d - d2, f"{si}/{si2}"
            else:
                if kind == "op" and val in ("*", "·", "."):
                    i += 1
                s2, d2, si2 = factor()
                sc, d, si = sc * s2, d + d2, f"{si} {si2}"

    sc, d, si = expr()
    if i != len(toks):
        raise UnitSyntaxError(f"unexpected {toks[i][1]!r} in unit '{text}'", toks[i][2])
    if np.max(np.abs(d)) > MAX_DIMENSION:
        raise UnitSyntaxError(f"unit '{text}' has a dimension exponent beyond {MAX_DIMENSION}: not a physical unit", 0)
    if not (math.isfinite(sc) and sc > 0):
        raise UnitSyntaxError(f"unit '{text}' has a scale to SI ({sc}) that is not a finite positive number", 0)
    return Unit(text=text, scale=float(sc), dims=tuple(float(x) for x in d), si=si)


_NUMBER = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)(.*)$", re.S)


def parse_quantity(text: str) -> tuple[float, Unit | None]:
    """Split ``"<number> <unit>"`` into the number and its parsed unit: ``"250 kg"`` -> (250.0, kg),
    ``"20.7 N/um"`` -> (20.7, N/um). A bare number gives ``(value, None)``.

    Raises :class:`UnitSyntaxError` when the text does not start with a number or its unit does not
    parse (``pos`` counts from the start of ``text``).
    """
    text = str(text)
    m = _NUMBER.match(text)
    if not m:
        raise UnitSyntaxError(f"'{text}' is not '<number> <unit>' (e.g. '250 kg', '20.7 N/um')", 0)
    rest = m.group(2)
    if not rest.strip():
        return float(m.group(1)), None
    try:
        return float(m.group(1)), parse_unit(rest)
    except UnitSyntaxError as exc:
        raise UnitSyntaxError(str(exc), exc.pos + m.start(2) + len(rest) - len(rest.lstrip())) from None


def same_dimension(a: Unit, b: Unit, angle: bool = False) -> bool:
    """Equal dimensions, ignoring the angle (SI treats rad as 1) unless ``angle`` is True."""
    n = 5 if angle else 4
    return np.allclose(a.dims[:n], b.dims[:n])


#: units a channel named ``<component>.<suffix>`` must have, by Modelica naming convention
convention_units = {
    "s": ("m",), "v": ("m/s",), "a": ("m/s^2",), "f": ("N",),
    "phi": ("rad",), "w": ("rad/s",), "tau": ("N m",),
}


def expected_dimension_ok(channel: str, unit: Unit) -> tuple[bool, str]:
    """Whether ``unit`` fits the channel's name by the Modelica convention (``table.a`` -> m/s^2);
    unknown suffixes pass. ``a`` accepts angular acceleration too (``rotor.a`` is rad/s^2)."""
    suffix = channel.rsplit(".", 1)[-1]
    allowed = list(convention_units.get(suffix, ()))
    if not allowed:
        return True, ""
    if suffix == "a":
        allowed.append("rad/s^2")
    for a in allowed:
        ua = parse_unit(a)
        if same_dimension(ua, unit) and (ua.dims[4] == unit.dims[4] or unit.dims[4] == 0 or ua.dims[4] == 0):
            return True, ""
    return False, " or ".join(allowed)
