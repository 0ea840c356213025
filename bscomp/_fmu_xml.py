"""The ``modelDescription.xml`` of an exported FMU: structured names, units, descriptions, model structure.

CasADi's ``DaeBuilder.export_fmu`` writes a description with the builder's internal names (``x3``,
``__assign__der(x3)__``) and no unit definitions. :func:`write_model_description` replaces its variable
list and model structure with bscomp's hierarchical names in the FMI 3.0 *structured* convention, the
units and descriptions of the component declarations and a ``UnitDefinitions`` block, keeping the
header (``instantiationToken``, ``modelIdentifier``) and the value references the generated C code uses.

Units are Modelica-style strings as the components declare them (``"N.s/m"``, ``"kg.m2"``,
``"m/s2"``, ``"N.m/rad"``; ``^`` exponents also accepted); :func:`~bscomp.kernel.signal_meta.base_exponents`
turns one into the SI base exponents of an FMI ``<BaseUnit>`` (``rad`` kept as its own base unit, as FMI allows).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from fractions import Fraction

from bscomp.kernel.signal_meta import BASE_ORDER, base_exponents, derivative_unit

__all__ = ["FmuVariable", "derivative_unit", "structured_name", "write_model_description"]

_BNAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[\d+(,\d+)*\])?$")
_DER = re.compile(r"^der\((?P<inner>.+?)(?:,(?P<order>\d+))?\)$")


def structured_name(name: str) -> str:
    """``name`` in the FMI structured convention: ``der(x)`` kept, dotted parts that are no plain identifier
    quoted (``'a b'``)."""
    m = _DER.match(name)
    if m:
        inner = structured_name(m["inner"])
        return f"der({inner})" if m["order"] is None else f"der({inner},{m['order']})"
    parts = []
    for part in name.split("."):
        if _BNAME.match(part):
            parts.append(part)
        else:
            parts.append("'" + part.replace("\\", "\\\\").replace("'", "\\'") + "'")
    return ".".join(parts)


def derivative_name(name: str) -> str:
    """FMI structured name of the time derivative of ``name``: ``x`` -> ``der(x)``, ``der(x)`` -> ``der(x,2)``."""
    m = _DER.match(name)
    if m:
        order = int(m["order"] or 1) + 1
        return f"der({m['inner']},{order})"
    return f"der({name})"


@dataclass
class FmuVariable:
    """One ``<Float64>`` of the model description (public name, value reference and attributes)."""

    name: str
    vr: int
    causality: str = "local"
    variability: str = "continuous"
    initial: str | None = None
    start: float | None = None
    unit: str = ""
    description: str = ""
    derivative: int | None = None
    min: float | None = None
    max: float | None = None
    nominal: float | None = None
    extra: dict = field(default_factory=dict)

    def element(self, known_units) -> ET.Element:
        a = {"name": self.name, "valueReference": str(self.vr)}
        if self.description:
            a["description"] = self.description
        if self.causality != "local":
            a["causality"] = self.causality
        if self.variability != "continuous":
            a["variability"] = self.variability
        if self.initial:
            a["initial"] = self.initial
        if self.unit and self.unit in known_units:
            a["unit"] = self.unit
        if self.derivative is not None:
            a["derivative"] = str(self.derivative)
        for key in ("min", "max", "nominal"):
            v = getattr(self, key)
            if v is not None:
                a[key] = repr(float(v))
        if self.start is not None:
            a["start"] = repr(float(self.start))
        return ET.Element("Float64", a)


def _unit_definitions(units) -> tuple[ET.Element, set]:
    root = ET.Element("UnitDefinitions")
    known = set()
    for u in sorted(units):
        parsed = base_exponents(u)
        if parsed is None or not u:
            continue
        factor, exps = parsed
        el = ET.SubElement(root, "Unit", {"name": u})
        base = {b: str(Fraction(exps[b]).limit_denominator()) for b in BASE_ORDER if b in exps}
        if factor != 1.0:
            base["factor"] = repr(factor)
        ET.SubElement(el, "BaseUnit", base)
        known.add(u)
    return root, known


def write_model_description(path, variables, outputs, derivatives, initial_unknowns, description: str = "",
                            generation_tool: str = "", time_vr: int = 4294967295) -> None:
    """Rewrite the ``modelDescription.xml`` at ``path`` (written by CasADi) with bscomp's variables.

    Parameters
    ----------
    path : path-like
        The file CasADi wrote; its header (token, model identifier, capabilities) is kept.
    variables : list of FmuVariable
        Every exposed variable except the independent ``time`` (kept from CasADi's file).
    outputs, derivatives : list of (vr, dependencies or None)
        ``ModelStructure/Output`` and ``ContinuousStateDerivative`` entries, in state order for the latter.
    initial_unknowns : list of int
        Value references of the ``InitialUnknown`` entries (no dependency list: all knowns).
    time_vr : int
        Value reference of the independent variable ``time``.
    """
    tree = ET.parse(path)
    root = tree.getroot()
    if description:
        root.set("description", description)
    if generation_tool:
        root.set("generationTool", generation_tool)
    time_el = None
    for child in list(root):
        if child.tag == "ModelVariables":
            time_el = next((v for v in child if v.get("causality") == "independent"), None)
        if child.tag in ("ModelVariables", "ModelStructure", "UnitDefinitions"):
            root.remove(child)
    units_el, known = _unit_definitions({v.unit for v in variables})
    # schema order: ModelExchange, ..., UnitDefinitions, TypeDefinitions, LogCategories, DefaultExperiment, ...,
    # ModelVariables, ModelStructure
    pos = [i for i, c in enumerate(root) if c.tag in ("ModelExchange", "CoSimulation", "ScheduledExecution")]
    if len(units_el):
        root.insert(pos[-1] + 1 if pos else 0, units_el)
    mv = ET.SubElement(root, "ModelVariables")
    if time_el is None:
        time_el = ET.Element("Float64", {"name": "time", "causality": "independent"})
    time_el.set("valueReference", str(time_vr))
    time_el.set("description", "simulation time [s]")
    mv.append(time_el)
    for v in variables:
        mv.append(v.element(known))
    ms = ET.SubElement(root, "ModelStructure")
    for tag, entries in (("Output", outputs), ("ContinuousStateDerivative", derivatives)):
        for vr, deps in entries:
            a = {"valueReference": str(vr)}
            if deps is not None:
                a["dependencies"] = " ".join(str(d) for d in deps)
            ET.SubElement(ms, tag, a)
    for vr in initial_unknowns:
        ET.SubElement(ms, "InitialUnknown", {"valueReference": str(vr)})
    ET.indent(tree, space="    ")
    tree.write(path, encoding="UTF-8", xml_declaration=True)
