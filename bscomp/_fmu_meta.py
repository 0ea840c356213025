"""Units and descriptions of a drive's variables, read from the component declarations (for the FMU).

* parameters: the ``Parameter(unit=, doc=, min=, max=)`` declaration;
* inputs: the DAE's input unit and the input port's ``doc``;
* states: the unit of the reduced coordinate (velocity: per second) or of the component ``Variable``;
* outputs (observables): the unit of the state, derivative, input or parameter an observable *is*, else
  the component's ``Variable`` / port potential of that name, else the ``# Observables`` section of the
  component's docstring (``- ``a`` [m/s^2]: acceleration``).
"""

from __future__ import annotations

import re

from ._fmu_xml import derivative_unit

__all__ = ["state_meta", "input_meta", "parameter_meta", "output_meta"]

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
    xd = [dae.xds[k].name() for k in range(dae.nx)]
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
