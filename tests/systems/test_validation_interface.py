"""Declared validation interfaces (bscomp.kernel.interface) of the systems in systems/: every drive variant
declares one, every declared port and parameter exists, the insertion points can be used."""

import re
from pathlib import Path

import numpy as np
import pytest

from bscomp import flatten
from bscomp.components import Damper, Fixed, Mass, Spring
from bscomp.kernel.interface import ROLES, NotApplicable, ValidationInterface, interface_of
from bscomp.linear.response import frf
from bscomp.systems import get
from bscomp.systems.testbed import testbed as build
from bscomp.systems.validation_drive import INPUT, INSERTION_POINTS, OUTPUTS, UNCERTAIN, validation_drive

#: registered names -> does the system drive a table (all four measured channels)?
DRIVES = {"testbed": True, "testbed_axial_torsional": True, "testbed_bellows": True, "validation_drive": True,
          "testbed_submodel1": False, "testbed_appendix_c": False}
NO_DRIVE = ["testbed_free_screw", "testbed_screw_nut", "testbed_no_table", "small_drive"]
TABLE_ROLES = {"nut_table", "screw_nut", "table_guide", "table", "screw_support", "coupling", "amplifier", "rotor",
               "structure"}


def _component_names(system):
    return {p for p, _ in system.leaves()}


def check_declared_names_exist(system, documented=True):
    """Every input, output, uncertain parameter and insertion-point port/parameter names something real."""
    vi = system.validation
    dae = flatten(system)
    names = set(dae.u_names) | set(dae.x_names) | set(dae.observables) | set(getattr(dae, "y_names", []))
    for u in vi.inputs:
        assert u in dae.u_names, u
    for y in vi.outputs:
        assert y in dae.observables or y in dae.x_names, (y, sorted(names)[:20])
    for u in vi.uncertain:
        assert system.get(u.name) > 0 and u.spread > 0 and u.source, u
    comps = _component_names(system)
    for p in vi.points.values():
        assert p.role in ROLES and (p.doc or not documented)
        for port in p.ports:
            if p.kind in ("support", "joint") and port in comps:       # a component (bearing, joint parts)
                continue
            system.port_spec(port)                                      # raises UnknownNameError if absent
        for name in p.parameters:
            system.get(name)
        if p.ground is not None:
            system.port_spec(p.ground)
    if vi.ground is not None:
        system.port_spec(vi.ground)


@pytest.mark.parametrize("name", sorted(DRIVES))
def test_every_registered_drive_declares_its_interface(name):
    s = get(name)
    vi = interface_of(s)
    assert isinstance(vi, ValidationInterface)
    assert vi.inputs == ["amp.u"]
    has_table = DRIVES[name]
    assert vi.outputs == (["rotor.phi", "rotor.w", "table.s", "table.a"] if has_table else ["rotor.phi", "rotor.w"])
    if has_table:
        assert set(vi.points) == TABLE_ROLES
        assert "table" in vi.notes and "positive" in vi.notes
    else:
        assert {"screw_support", "coupling", "amplifier", "rotor", "structure"} <= set(vi.points)
        with pytest.raises(NotApplicable, match="nut_table"):
            vi.point("nut_table")
    assert "uncertain" in vi.describe()
    check_declared_names_exist(s)


@pytest.mark.parametrize("name", NO_DRIVE)
def test_systems_without_a_drive_declare_none(name):
    assert interface_of(get(name)) is None


@pytest.mark.parametrize("kw", [dict(nut_joint="moving"), dict(drive_input="torque"), dict(viscous="guide"),
                                dict(nut_position="L", nut_joint="moving", coupling="bellows"),
                                dict(ksn="axial_torsional")])
def test_testbed_interface_for_each_build_choice(kw):
    s = build("axial_torsional", **kw)
    vi = s.validation
    torque = kw.get("drive_input") == "torque"
    assert vi.inputs == (["motor.tau"] if torque else ["amp.u"])
    assert ("amplifier" in vi.points) is not torque
    guide = kw.get("viscous") == "guide"
    assert vi.points["table_guide"].ground == ("frame.flange" if guide else None) and vi.ground == vi.points[
        "table_guide"].ground
    check_declared_names_exist(s)


def test_full_6dof_interface_names_exist():
    check_declared_names_exist(build("full", nut_joint="moving"))


def test_testbed_uncertain_parameters_and_sources():
    vi = build("axial_torsional").validation
    assert vi.spreads() == {"table.m": 0.2, "coupling.k_T": 0.2, "b1.k_axial": 0.3}
    src = {u.name: u.source for u in vi.uncertain}
    assert "Table 3.1" in src["table.m"] and "Sec B.4" in src["coupling.k_T"] and "Table 3.1" in src["b1.k_axial"]


def _first_mode(system):
    f = np.linspace(80.0, 160.0, 801)
    H = frf(system, input=system.validation.inputs[0], output="rotor.w", freqs=f).H[:, 0, 0]
    return f[np.argmax(np.abs(H))]


def test_structural_uncertain_parameter_works_through_set():
    """b1.k_axial is structural (re-flattens): System.set on it moves the axial mode."""
    s = build("axial_torsional", damping=False)
    f0 = _first_mode(s)
    s.set("b1.k_axial", 0.5 * s.get("b1.k_axial"))
    assert _first_mode(s) < f0 - 2.0


def test_nut_table_point_takes_a_joint_in_series_and_keeps_the_disturbance_on_the_table():
    s = build("axial_torsional")
    a, b = s.validation.point("nut_table").ports
    f0 = _first_mode(s)
    s.insert("joint", Spring(c=3e8), between=(a, b))
    s.add("joint_loss", Damper(d=1e3))
    s.connect(a, "joint_loss.flange_a")
    s.connect("joint_loss.flange_b", b)
    assert ("Fd.flange", "table.flange_a") in s._connections
    assert _first_mode(s) < f0 - 5.0                      # a softer drive: the axial mode falls
    H = frf(s, input="amp.u", output=["rotor.phi", "table.s"], freqs=[0.5]).H[0, :, 0]
    assert (H[1] / H[0]).real > 0                           # the joint keeps the table's sign


def test_table_guide_and_table_points_take_attachments():
    s = build("axial_torsional")
    vi = s.validation
    (node,) = vi.point("table_guide").ports
    s.add("ground2", Fixed())
    s.add("guide_k", Spring(c=1e9))
    s.connect(node, "guide_k.flange_a")
    s.connect("guide_k.flange_b", "ground2.flange")
    (tab,) = vi.point("table").ports
    s.add("extra", Mass(m=10.0))
    s.connect(tab, "extra.flange_a")
    assert flatten(s).nx > 0


def test_validation_drive_interface_and_legacy_aliases():
    s = validation_drive()
    vi = s.validation
    check_declared_names_exist(s)
    assert set(vi.points) == TABLE_ROLES
    assert vi.point("screw_support").ports == ("lead.flange_b", "axial.flange_a")
    assert vi.point("screw_nut").ports == ("axial", "axial_loss")
    assert vi.point("table_guide").ground == "ground.flange" == vi.ground
    assert vi.spreads() == {"table.m": 0.2, "coupling.c": 0.2, "guide.d": 0.3}
    # legacy form, read by bscomp.validate until it reads system.validation
    assert s.insertion_points == INSERTION_POINTS and s.uncertain == UNCERTAIN == list(vi.spreads())
    assert s.input == INPUT == "amp.u" and s.outputs == OUTPUTS == vi.outputs
    assert validation_drive().validation is not vi                   # each build its own declaration
    assert s.copy().validation.points == vi.points


def test_validation_drive_still_diagnoses_through_the_current_code_path():
    """diagnose() re-calibrates the declared uncertain parameters (legacy ``uncertain`` alias) and recovers
    the generator's mis-set table mass (x 1.06) and coupling stiffness (x 0.93)."""
    from bscomp.validate.diagnostics import diagnose
    from bscomp.validate.synthetic import MISSET, generate

    data = generate(hidden={}, seed=1)
    diag = diagnose(validation_drive(), data.datasets, max_effects=0)
    assert list(diag.recalibrated) == UNCERTAIN
    nominal = validation_drive()
    for name, factor in MISSET.items():
        assert abs(diag.recalibrated[name][0] / (factor * nominal.get(name)) - 1) < 0.02, name


def test_the_documented_user_declaration_runs(tmp_path):
    """The example of docs/validation.md ("Declaring the validation interface of your drive") as a user
    file: get() builds it with a build argument, and every name it declares exists."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "validation.md").read_text()
    section = doc.split("## Declaring the validation interface of your drive", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    path = tmp_path / "my_drive.py"
    path.write_text(code)
    s = get(str(path), {"k_axial": 2e8})
    assert s.get("axial.c") == 2e8
    assert s.validation.spreads() == {"table.m": 0.2, "coupling.c": 0.3}
    check_declared_names_exist(s, documented=False)
