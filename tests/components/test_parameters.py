"""Parameters from one source: units parsed at class creation, ``"<number> <unit>"`` values converted to the
declared unit with a dimension check, and numpydoc ``Parameters`` sections generated from the declarations."""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest

import bscomp.components as C
from bscomp import Component, ModelDefinitionError, Parameter, ParameterError, System
from bscomp.kernel.ports import Flange

COMPONENTS_DIR = Path(C.__file__).resolve().parent
COMPONENT_CLASSES = [getattr(C, n) for n in C.__all__ if isinstance(getattr(C, n), type)
                     and issubclass(getattr(C, n), Component)]


def _numpydoc_sections(doc: str) -> dict:
    """``{heading: [lines]}`` of a numpydoc docstring (a heading is a line underlined by dashes)."""
    lines = (doc or "").splitlines()
    out, current = {}, None
    for i, line in enumerate(lines):
        under = lines[i + 1].strip() if i + 1 < len(lines) else ""
        if line.strip() and len(under) >= 3 and set(under) == {"-"}:
            current = line.strip()
            out[current] = []
        elif current is not None and not (set(line.strip()) == {"-"} and out[current] == []):
            out[current].append(line)
    return out


# ---- docs from one source --------------------------------------------------------------------------------
@pytest.mark.parametrize("cls", COMPONENT_CLASSES, ids=lambda c: c.__name__)
def test_every_component_docstring_lists_every_parameter_with_its_unit(cls):
    params = cls.parameters()
    if not params:
        return
    section = _numpydoc_sections(cls.__doc__).get("Parameters")
    assert section is not None, f"{cls.__name__} has no numpydoc Parameters section"
    entries = [line for line in section if line and not line.startswith(" ")]
    for name, p in params.items():
        mine = [e for e in entries if e.split(" : ")[0] == name]
        assert len(mine) == 1, f"{cls.__name__}.{name} is listed {len(mine)} times"
        assert f"[{p.unit}]" in mine[0], f"{cls.__name__}.{name}: {mine[0]!r} lacks its unit [{p.unit}]"
        if p.default is not None and np.ndim(p.default) == 0:
            assert f"default {float(p.default):.6g}" in mine[0]
        if p.positive:
            assert "> 0" in mine[0]


def test_one_docstring_dialect_in_components():
    """numpydoc only: no Markdown ``# Parameters`` / ``# Connectors`` lists, no Sphinx ``:param``."""
    bad = []
    for f in sorted(COMPONENTS_DIR.glob("*.py")):
        tree = ast.parse(f.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef)):
                doc = ast.get_docstring(node) or ""
                if re.search(r"^\s*# (Parameters|Connectors|Observables|Variables)\b|:param\b", doc, re.M):
                    bad.append(f"{f.name}:{getattr(node, 'name', '<module>')}")
    assert not bad, f"non-numpydoc docstrings: {bad}"


def test_generated_section_merges_with_constructor_arguments():
    doc = C.Coupling.__doc__
    sections = _numpydoc_sections(doc)
    assert list(sections).count("Parameters") == 1 and doc.count("Parameters\n---") == 1
    names = [line.split(" : ")[0] for line in sections["Parameters"] if line and not line.startswith(" ")]
    assert names == ["ends", "k_T", "J1", "J2", "d"]          # constructor argument first, then declarations
    assert list(sections) == ["Parameters", "Attributes"]


def test_a_class_without_docstring_gets_its_parameters_documented():
    class Bare(Component):
        k = Parameter(2.0, unit="N/m", min=0.0, doc="a stiffness")

    assert Bare.__doc__.splitlines()[:4] == ["Parameters", "----------", "k : [N/m], >= 0, default 2",
                                             "    a stiffness"]


# ---- units parsed at class creation ----------------------------------------------------------------------
@pytest.mark.parametrize("unit", ["N/mm2x", "kgg", "N//m", ""])
def test_a_unit_typo_is_a_model_definition_error_naming_class_and_parameter(unit):
    with pytest.raises(ModelDefinitionError, match=r"Typo\.c: unit"):
        class Typo(Component):
            c = Parameter(unit=unit, doc="stiffness")


def test_every_declared_unit_parses():
    for cls in COMPONENT_CLASSES:
        for name, p in cls.parameters().items():
            assert p.units and all(u.scale > 0 for u in p.units), f"{cls.__name__}.{name}"
    assert C.Bushing.parameters()["K"].units[2].si == "N m/rad"          # one unit per '|' entry


# ---- "<number> <unit>" values -----------------------------------------------------------------------------
def _table_system():
    s = System("table")
    s.add("ground", C.Fixed())
    s.add("k", C.Spring(c=1e8))
    s.add("table", C.Mass(m=100.0))
    s.connect("ground.flange", "k.flange_a")
    s.connect("k.flange_b", "table.flange_a")
    return s


@pytest.mark.parametrize("text, value", [("250 kg", 250.0), ("250000 g", 250.0), ("0.25 Mg", 250.0),
                                         ("250", 250.0), ("2.5e2kg", 250.0)])
def test_system_set_converts_a_quantity_string_to_the_declared_unit(text, value):
    s = _table_system()
    s.set("table.m", text)
    assert s.get("table.m") == pytest.approx(value, rel=1e-12)


def test_quantity_strings_in_component_keywords_and_set():
    assert C.Spring(c="20.7 N/um").get("c") == pytest.approx(2.07e7)
    assert C.ScrewNut(k_ball=1e7, n_ball=100, alpha="4.55 deg", beta="50 deg", R="20 mm").get("alpha") == \
        pytest.approx(math.radians(4.55))
    assert C.IdealLeadScrew(lead="10 mm/rev").get("lead") == pytest.approx(0.010)      # declared m/rev
    assert C.IdealLeadScrew(lead="1.5915494 mm/rad").get("lead") == pytest.approx(0.010, rel=1e-7)
    assert C.TorsionalSpring(c="3.938 kN.m/rad").get("c") == pytest.approx(3938.0)
    assert C.Coupling(k_T=1.0, J1="3.09 kg.cm^2").get("J1") == pytest.approx(3.09e-4)
    assert C.Damper().set("d", "12.673 kN s/m").get("d") == pytest.approx(12673.0)


def test_a_quantity_of_another_dimension_names_parameter_given_and_expected_unit():
    s = _table_system()
    with pytest.raises(ParameterError, match=r"table\.m.*'250 N'.*'N'.*'kg'"):
        s.set("table.m", "250 N")
    with pytest.raises(ParameterError, match=r"k\.c.*'N/m'"):
        s.set("k.c", "3 N.m/rad")          # angles count: a torsional stiffness is not a spring constant
    assert s.get("table.m") == 100.0 and s.get("k.c") == 1e8


def test_angles_are_a_dimension_for_quantity_strings():
    class Wheel(Component):
        flange = Flange("rim")
        w0 = Parameter(0.0, unit="rad/s", doc="spin")

    assert Wheel(w0="600 rpm").get("w0") == pytest.approx(20 * math.pi)
    with pytest.raises(ParameterError, match=r"w0.*'Hz'.*'rad/s'"):
        Wheel(w0="100 Hz")


@pytest.mark.parametrize("text", ["kg", "250 kgs", "250 kg kg/", "two kg"])
def test_an_unreadable_quantity_string_is_a_parameter_error(text):
    with pytest.raises(ParameterError, match=r"table\.m \[kg\]"):
        _table_system().set("table.m", text)


def test_bounds_still_apply_after_conversion():
    with pytest.raises(ParameterError, match="must be > 0"):
        _table_system().set("table.m", "-3 kg")


def test_a_parameter_with_one_unit_per_entry_takes_no_quantity_string():
    with pytest.raises(ParameterError, match=r"one unit per entry"):
        C.Bushing(K="1e8 N/m")


# ---- components keep physics only ------------------------------------------------------------------------
def test_thesis_data_left_the_components():
    assert not hasattr(C.ScrewNut, "thesis") and not hasattr(C.Ballscrew, "thesis_table_b1")
    import bscomp.components._beam_fe as fe

    assert not hasattr(fe, "thesis_table_b1_sections")


def test_section_and_pade_delay_are_public():
    from bscomp.components import PadeDelay, Section

    assert Section(0.1, 0.02).mass(7800.0) == pytest.approx(7800.0 * math.pi / 4 * 0.02**2 * 0.1)
    assert PadeDelay(T=1e-4).get("T") == 1e-4


def test_notch_filter_designs_table_4_3_without_the_control_package():
    """Eq 4.19-4.21 at the Sec 4.4.2 mode (zeta 0.0855, 753.98 rad/s, zeta_D 0.5, T_s = 200 us): Table 4.3."""
    src = (COMPONENTS_DIR / "notch_filter.py").read_text(encoding="utf-8")
    assert "bscomp.control" not in src.replace("bscomp.control.design.notch`", "")
    nf = C.NotchFilter.design(0.0855, 753.98, 0.5, 2e-4)
    got = (nf.n1, nf.n2, nf.d1, nf.d2, nf.K_N)
    assert np.allclose(got, (-1.9521, 0.9745, -1.8390, 0.8600, 0.9402), atol=1e-4)   # printed to 4 decimals
    from bscomp.control.design import notch

    c = notch(0.0855, 753.98, 0.5, 2e-4)
    assert (c.n1, c.n2, c.d1, c.d2, c.K_N) == got
