"""Thesis data live in systems/: the test-bed screw (Table B.1), the screw-nut interface (Table 3.1/B.3) and the
reference frequency of the lumped drive's extra damping, read from the toml and the declared interfaces; the
registry lists its drives; ``"<number> <unit>"`` overrides reach System.set (as the CLI's --set passes them)."""

import dataclasses
import inspect
import math

import numpy as np
import pytest

import bscomp.systems as systems
from bscomp.components import Ballscrew, ScrewNut, Section
from bscomp.errors import ParameterError
from bscomp.kernel.interface import NotApplicable
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.thesis_parts import thesis_ballscrew, thesis_screw_nut, thesis_sections
from bscomp.systems.validation_drive import F1, validation_drive
from bscomp.validate.candidates import ExtraDamping

P = load_parameters()


def test_thesis_sections_are_table_b1_from_the_toml():
    secs = thesis_sections()
    assert all(isinstance(s, Section) for s in secs) and [s.name for s in secs] == list("ABCDEF")
    for s in secs:
        g = f"screw.sections.{s.name}"
        assert (s.length, s.d_in, s.n_elements) == (get_value(P, f"{g}.length"), get_value(P, f"{g}.inner_diameter"),
                                                    get_value(P, f"{g}.n_elements"))
    c = secs[2]
    assert (c.d_out, c.d_mass) == (get_value(P, "screw.root_diameter"), get_value(P, "screw.equivalent_diameter"))
    assert [s.name for s in thesis_sections(reverse=True)] == list("FEDCBA")
    fine = thesis_sections(d_root=40e-3, n_elements_C=78)
    assert fine[2].d_out == 40e-3 and fine[2].d_mass == c.d_mass and sum(s.n_elements for s in fine) == 47 + 39


def test_thesis_ballscrew_has_the_table_b1_mesh_and_the_app_b1_steel():
    screw = thesis_ballscrew(dofs=("w", "tz"), points={"P": 0.4325})
    assert isinstance(screw, Ballscrew) and screw.n_nodes == 48 and screw.length == pytest.approx(0.9205)
    assert screw.get("E") == get_value(P, "screw.material.youngs_modulus")
    assert screw.get("rho") == get_value(P, "screw.material.density")
    assert screw.get("nu") == get_value(P, "screw.material.poissons_ratio")
    assert screw.get("kappa") == get_value(P, "screw.material.shear_factor")
    assert thesis_ballscrew(E=200e9).get("E") == 200e9


def test_thesis_screw_nut_is_table_3_1_from_the_toml():
    sn = thesis_screw_nut()
    assert isinstance(sn, ScrewNut) and sn.preload == "oversize" and sn.hand == 1
    for name, key in (("k_ball", "k_ball"), ("n_ball", "N_ball"), ("alpha", "alpha"), ("beta", "beta"),
                      ("R", "R"), ("phi_start", "phi_start"), ("phi_end", "phi_end")):
        assert sn.get(name) == get_value(P, f"screw_nut.{key}"), name
    assert sn.get("phi_end") == pytest.approx(10 * math.pi, rel=1e-7)                   # +1800 deg, Eq B.2
    assert thesis_screw_nut(alpha="5 deg").get("alpha") == pytest.approx(math.radians(5.0))
    # Eq 3.45: k_zz = 82.1 k_ball for the test bed
    assert sn.stiffness_matrix()[2, 2] / sn.get("k_ball") == pytest.approx(82.1, rel=2e-3)


def test_the_testbed_uses_the_same_parts():
    s = systems.get("testbed_axial_torsional")
    sn, ref = s.component("sn"), thesis_screw_nut()
    assert {n: sn.get(n) for n in sn.parameters()} == {n: ref.get(n) for n in ref.parameters()}
    screw = s.component("screw")
    assert [dataclasses.astuple(a) for a in screw.sections] == [dataclasses.astuple(b) for b in thesis_sections()]


def test_extra_damping_reads_f1_from_the_declared_interface_or_its_argument():
    s = validation_drive()
    assert s.validation.point("structure").frequency == F1 == 117.7
    k_ax = s.get("axial.c")
    declared = ExtraDamping().apply(s, zeta=0.02)
    assert declared.get("extra_loss_axial.d") == pytest.approx(2 * 0.02 / (2 * math.pi * F1) * k_ax)
    given = ExtraDamping(f1=100.0).apply(s, zeta=0.02)
    assert given.get("extra_loss_axial.d") == pytest.approx(2 * 0.02 / (2 * math.pi * 100.0) * k_ax)
    bare = validation_drive()
    bare.validation.points["structure"] = dataclasses.replace(bare.validation.points["structure"], frequency=None)
    with pytest.raises(NotApplicable, match=r"f_1.*ExtraDamping\(f1=\.\.\.\)"):
        ExtraDamping().structure(bare)
    assert ExtraDamping(f1=117.7).apply(bare, zeta=0.02).get("extra_loss_axial.d") == \
        pytest.approx(declared.get("extra_loss_axial.d"))
    assert inspect.signature(ExtraDamping).parameters["f1"].default is None          # no thesis number in bscomp/


def test_available_lists_every_registered_drive_with_its_one_line_description():
    listed = systems.available()
    assert list(listed) == list(systems.REGISTRY)
    for name, text in listed.items():
        assert text and "\n" not in text, name
        assert text == inspect.getdoc(systems.REGISTRY[name]).splitlines()[0]
    assert listed["testbed"].startswith("Full 6-DOF test bed")


def test_quantity_string_overrides_reach_system_set_like_the_cli():
    from bscomp.cli import _parse_set

    overrides = _parse_set(["table.m=250000 g", "coupling.c=3.938 kN.m/rad", "axial.c=1.357e8"])
    assert overrides == {"table.m": "250000 g", "coupling.c": "3.938 kN.m/rad", "axial.c": 1.357e8}
    s = systems.get("validation_drive", overrides)
    assert (s.get("table.m"), s.get("coupling.c"), s.get("axial.c")) == pytest.approx((250.0, 3938.0, 1.357e8))
    with pytest.raises(ParameterError, match=r"table\.m.*'N'.*'kg'"):
        systems.get("validation_drive", {"table.m": "250 N"})


def test_parameter_tables_are_public():
    import bscomp.systems.parameters as parameters

    assert parameters.load_parameters is load_parameters
    flat = parameters.flatten(P)
    assert np.isclose(flat["table.mass"]["value"], 250.0) and flat["table.mass"]["unit"] == "kg"
