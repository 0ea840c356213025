"""Units and descriptions of a drive's named signals, read from the component declarations.

Used wherever a number is shown with its unit: the FMU's model description (:mod:`bscomp.fmu`), the
optimal-control failure messages (:mod:`bscomp.optimal.infeasibility`). :func:`unit_of` gives the unit of
any state, state derivative, input, parameter or observable of a :class:`~bscomp.kernel.Dae` by name.

* parameters: the ``Parameter(unit=, doc=, min=, max=)`` declaration;
* inputs: the DAE's input unit and the input port's ``doc``;
* states: the unit of the reduced coordinate (velocity: per second) or of the component ``Variable``;
* outputs (observables): the unit of the state, derivative, input or parameter an observable *is*, else
  the component's ``Variable`` / port potential of that name, else the ``# Observables`` section of the
  component's docstring (``- ``a`` [m/s^2]: acceleration``).
"""

from __future__ import annotations

import re

import casadi as ca

from bscomp.kernel.units import convention_units

__all__ = ["state_meta", "input_meta", "parameter_meta", "output_meta", "unit_of", "declared_units", "unit_suffix",
           "measured_outputs", "base_exponents", "derivative_unit", "BASE_ORDER"]

# SI base exponents in the FMI order (kg, m, s, A, K, mol, cd, rad) and a factor to SI
BASE_ORDER = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_UNITS = {
    "kg": (1.0, {"kg": 1}), "g": (1e-3, {"kg": 1}), "m": (1.0, {"m": 1}), "s": (1.0, {"s": 1}),
    "A": (1.0, {"A": 1}), "K": (1.0, {"K": 1}), "mol": (1.0, {"mol": 1}), "cd": (1.0, {"cd": 1}),
    "rad": (1.0, {"rad": 1}), "N": (1.0, {"kg": 1, "m": 1, "s": -2}), "Pa": (1.0, {"kg": 1, "m": -1, "s": -2}),
    "J": (1.0, {"kg": 1, "m": 2, "s": -2}), "W": (1.0, {"kg": 1, "m": 2, "s": -3}),
    "V": (1.0, {"kg": 1, "m": 2, "s": -3, "A": -1}), "Hz": (1.0, {"s": -1}),
    "rev": (6.283185307179586, {"rad": 1}), "deg": (0.017453292519943295, {"rad": 1}),
}
_FACTOR = re.compile(r"^(?P<word>[A-Za-z]+)(?:\^?(?P<exp>-?\d+))?$")


def base_exponents(text: str):
    """A Modelica unit string -> ``(factor, {base: exponent})``, or None when it cannot be parsed.

    ``"1"`` (and ``""``) is dimensionless; ``"N.s/m"`` = ``{"kg": 1, "s": -1}``; ``"m/rev"`` has the factor
    ``1 / (2 pi)`` per radian.
    """
    text = (text or "").strip()
    if text in ("", "1", "-"):
        return 1.0, {}
    num, _, den = text.partition("/")
    if "/" in den or "|" in text or "(" in text:
        return None
    factor, exps = 1.0, {}
    for sign, part in ((1, num), (-1, den)):
        if not part:
            continue
        for tok in part.split("."):
            if tok == "1" and sign == 1:
                continue
            m = _FACTOR.match(tok)
            if not m or m["word"] not in _UNITS:
                return None
            f, base = _UNITS[m["word"]]
            e = sign * int(m["exp"] or 1)
            factor *= f ** e
            for b, k in base.items():
                exps[b] = exps.get(b, 0) + k * e
    return factor, {b: k for b, k in exps.items() if k}


def derivative_unit(unit: str, order: int = 1) -> str:
    """The unit of the ``order``-th time derivative of a quantity in ``unit`` (``"m"`` -> ``"m/s2"``)."""
    if not unit or base_exponents(unit) is None:
        return ""
    num, _, den = unit.partition("/")
    num = "" if num == "1" else num
    s_exp = order
    parts = []
    for tok in (den.split(".") if den else []):
        m = _FACTOR.match(tok)
        if m and m["word"] == "s":
            s_exp += int(m["exp"] or 1)
        else:
            parts.append(tok)
    parts.append("s" if s_exp == 1 else f"s{s_exp}")
    return f"{num or '1'}/{'.'.join(parts)}"


_OBS = re.compile(r"``(\w+)``\s*\[([^\]]*)\](?::\s*([^,`\n]+))?")


def _component(system, dotted):
    """(component, leaf) for the longest component path prefix of ``dotted``, or (None, dotted)."""
    if system is None:
        return None, dotted
    parts = dotted.split(".")
    for k in range(len(parts) - 1, 0, -1):
        try:
            return system.component(".".join(parts[:k])), ".".join(parts[k:])
        except Exception:  # noqa: BLE001 - not a component path at this depth
            continue
    return None, dotted


def _class_line(comp) -> str:
    doc = (type(comp).__doc__ or "").strip().splitlines()
    return f"{type(comp).__name__}: {doc[0].strip()}" if doc else type(comp).__name__


def state_meta(dae, i):
    """(unit, description) of state ``i``."""
    m = dae.mech
    for r, k in m.q_in_x.items():
        if k == i:
            return m.coordinate_units[r], f"position of coordinate {m.coordinate_names[r]}"
    for r, k in m.v_in_x.items():
        if k == i:
            return derivative_unit(m.coordinate_units[r]), f"velocity of coordinate {m.coordinate_names[r]}"
    comp, leaf = _component(dae.system, dae.x_names[i])
    var = comp.variables().get(leaf) if comp is not None else None
    if var is not None:
        return var.unit, var.doc or f"state {leaf} of {_class_line(comp)}"
    return "", f"state {dae.x_names[i]}"


def input_meta(dae, name):
    """(unit, description) of input ``name``."""
    unit = dae.u_units[dae.u_names.index(name)] if name in dae.u_names else ""
    comp, leaf = _component(dae.system, name)
    if comp is not None:
        port = comp.ports().get(leaf)
        doc = port.doc if port is not None and port.doc else ""
        return unit, f"{doc} ({_class_line(comp)})" if doc else _class_line(comp)
    return unit, "input"


def parameter_meta(system, name):
    """(unit, description, min, max) of a dotted parameter name (``nut.I[3]``: entry of ``nut.I``)."""
    comp, leaf = _component(system, name)
    base = leaf.split("[")[0]
    par = comp.parameters().get(base) if comp is not None else None
    if par is None:
        return "", name, None, None
    unit = par.unit if "|" not in par.unit else ""
    lo = par.min if par.min is not None else (0.0 if par.positive else None)
    return unit, f"{par.doc} ({_class_line(comp)})" if par.doc else _class_line(comp), lo, par.max


def _symbol_unit(dae, name):
    if name in dae.x_names:
        return state_meta(dae, dae.x_names.index(name))[0]
    xd = [e.name() for e in ca.vertsplit(dae.xds)]
    if name in xd:
        return derivative_unit(state_meta(dae, xd.index(name))[0])
    if name in dae.u_names:
        return dae.u_units[dae.u_names.index(name)]
    if name in dae.p_names:
        return dae.p_units[dae.p_names.index(name)]
    return None


def output_meta(dae, name, expr):
    """(unit, description) of the observable ``name`` whose expression is ``expr``."""
    comp, leaf = _component(dae.system, name)
    where = f" of {comp._display_name()} ({_class_line(comp)})" if comp is not None else ""
    unit = _symbol_unit(dae, expr.name()) if expr.is_symbolic() else None
    desc = ""
    if comp is not None:
        var = comp.variables().get(leaf)
        if var is not None:
            unit = var.unit if unit is None else unit
            desc = var.doc
        port, _, pot = leaf.rpartition(".")
        spec = comp.ports().get(port) if port else None
        if spec is not None and unit is None:
            units = dict(spec.kind.potentials) | dict(spec.kind.flows)
            unit = units.get(pot) or spec.unit or None
        for obs, u, d in _OBS.findall(type(comp).__doc__ or ""):
            if obs == leaf:
                unit = u.replace("^", "") if unit is None else unit
                desc = desc or (d or "").strip()
    return unit or "", f"{leaf}{where}" + (f": {desc}" if desc else "")


def unit_of(dae, name: str) -> str:
    """The unit of the signal ``name`` of ``dae`` for people to read: the declared one (:func:`_declared_unit`)
    with products as spaces and exponents as ``^`` (``N.m`` -> ``N m``, ``m/s2`` -> ``m/s^2``); ``""`` if none."""
    unit = _declared_unit(dae, name)
    unit = re.sub(r"(?<=[A-Za-z0-9])\.(?=[A-Za-z])", " ", unit)
    return re.sub(r"(?<=[A-Za-z])(-?\d+)", r"^\1", unit)


def declared_units(dae, names) -> dict:
    """``{name: unit_of(dae, name)}`` for each of ``names`` that has a unit other than ``1`` (the units a result or a
    plot carries: ``SimulationResult.units``, ``Frf.units``, the axes of a time plot)."""
    return {n: u for n in names if (u := unit_of(dae, n)) and u != "1"}


def unit_suffix(unit: str) -> str:
    """``unit`` as it follows a number in a message: ``" m"``, or ``""`` for none and for ``"1"``."""
    return f" {unit}" if unit and unit != "1" else ""


def _declared_unit(dae, name: str) -> str:
    """The declared unit of the signal ``name`` of ``dae`` (a state, its derivative ``der(x)``, an input, a
    parameter or an observable), else the Modelica convention's for a flange variable by its last name part
    (``s`` m, ``v`` m/s, ``a`` m/s^2, ``f`` N, ``phi`` rad, ``w`` rad/s, ``tau`` N m), else ``""``; in the
    declaration's spelling (``N.m``, ``m/s2``)."""
    try:
        if name in dae.x_names:
            return state_meta(dae, dae.x_names.index(name))[0] or ""
        if name.startswith("der(") and name[4:-1] in dae.x_names:
            return derivative_unit(state_meta(dae, dae.x_names.index(name[4:-1]))[0])
        if name in dae.u_names:
            return input_meta(dae, name)[0] or ""
        if name in dae.p_names:
            return parameter_meta(dae.system, name)[0] or ""
        if name in dae.observables:
            unit = output_meta(dae, name, dae.observables[name])[0]
            if unit:
                return unit
    except (AttributeError, KeyError, ValueError, TypeError):     # a Dae without its System: no declarations
        pass
    # the Modelica naming convention of a flange's potentials and flow (table.s [m], motor.tau [N m], ...)
    return convention_units.get(name.rsplit(".", 1)[-1], ("",))[0] if "." in name else ""


def measured_outputs(dae) -> list:
    """The outputs a user of this drive measures: its System's declared validation outputs that are observables
    of ``dae``, else the observables that are states (what the FMU and ``bscomp simulate`` record by default)."""
    val = getattr(dae.system, "validation", None)
    outs = [o for o in (getattr(val, "outputs", None) or []) if o in dae.observables]
    return outs or [n for n in dae.x_names if n in dae.observables]
