"""The thesis test bed (systems/testbed.py): structure, rigid-body modes and thesis-table reproduction.

Tolerances are the agreement actually achieved with the cited parameters and the toml's documented
CHOICE defaults (docs/thesis-reproduction.md, "Chapter 3 and 4.2" section). Where the gap exceeds 3 %
the test pins our measured value in a tight band instead (a regression guard) and the doc explains the
gap; see docs/testbed-sensitivity.md for how each unpublished detail moves these numbers.
"""

import numpy as np
import pytest

from bscomp import ModelDefinitionError, UnknownNameError, flatten, second_order
from bscomp.linear.modal import modes
from bscomp.systems import REGISTRY, get
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed import VARIANTS, DriveModalDamping, nut_positions
from bscomp.systems.testbed import testbed as build
from bscomp.systems.testbed_analysis import drive_parameters, free_free_modes, submodel1_frequencies

P = load_parameters("fadal_vmc2216_x")
REF = {k: get_value(P, f"reference_results.{k}") for k in (
    "J", "table41_fn1", "table41_fn2", "table41_Rw1", "table41_Rm1", "table42_fn1", "table42_fn2", "table53_full",
    "free_free_axial_simulated", "free_free_torsional_simulated")}


def rel(a, b):
    return np.abs(np.asarray(a, float) / np.asarray(b, float) - 1.0)


@pytest.fixture(scope="module")
def drive_lcr():
    """Table 4.1 (jaw) at L, C, R and Table 4.2 (bellows) at C."""
    out = {pos: drive_parameters(nut_position=pos) for pos in "LCR"}
    out["bellows_C"] = drive_parameters(nut_position="C", coupling="bellows", damping=False)
    return out


@pytest.fixture(scope="module")
def free_free():
    return {pos: free_free_modes(pos) for pos in "123"}


# ---- structure --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["testbed_free_screw", "testbed_screw_nut", "testbed_no_table",
                                  "testbed_axial_torsional", "testbed_submodel1", "testbed_appendix_c"])
def test_each_registered_variant_flattens(name):
    dae = flatten(get(name))
    assert dae.nx > 0
    assert name in REGISTRY


def test_variant_dof_counts():
    # 48 nodes x 6 DOF; + the nut's 6 (free-free) ; Ch 5: 48 x 2 + rotor (J1) + nut/table (1)
    assert second_order(build("free_screw")).M.shape == (288, 288)
    assert second_order(build("screw_nut")).M.shape == (294, 294)
    assert second_order(build("axial_torsional", damping=False), inputs=[], outputs=[]).M.shape == (98, 98)
    # Table 5.1 lists 101 DOF for sub-model 1; we have 48 x 2 + rotor = 97 (see the doc)
    assert second_order(build("submodel1", damping=False), inputs=[], outputs=[]).M.shape == (97, 97)


def test_unknown_variant_and_named_position_raise():
    with pytest.raises(ModelDefinitionError, match="variant"):
        build("half")
    with pytest.raises(ModelDefinitionError, match="named nut position"):
        build("full", nut_position="Q")


def test_get_rebuilds_with_nut_position_and_dotted_overrides():
    s = get("testbed", {"nut_position": 0.43, "coupling.k_T": 45940.0})
    assert s.position_parameter == "nut_position"
    assert s.build_args["nut_position"] == 0.43
    assert s.get("coupling.k_T") == 45940.0
    assert s.component("screw").points["nut"] == 0.43
    with pytest.raises(UnknownNameError, match="build argument"):
        get("small_drive", {"nut_position": 0.4})


def test_every_value_comes_from_the_parameter_file():
    s = build("full")
    assert s.get("table.m") == get_value(P, "table.mass")
    assert s.get("coupling.k_T") == get_value(P, "coupling.kT")
    assert s.get("b1.k_axial") == get_value(P, "bearings.b1_k_axial")
    assert s.get("sn.k_ball") == get_value(P, "screw_nut.k_ball")
    assert s.get("B.d") == get_value(P, "control.B")
    assert build("full", coupling="bellows").get("coupling.k_T") == get_value(P, "coupling.bellows_kT")
    assert s.component("screw").points["nut"] == nut_positions()["C"]


# ---- rigid-body modes and J (Eq 4.2) -------------------------------------------------------------
def test_full_system_has_one_rigid_mode_and_J_at_the_motor(drive_lcr):
    md = drive_lcr["C"]["modes"]
    assert md.rigid_body.sum() == 1          # the screw turns, the table advances r_g per radian
    J = drive_lcr["C"]["J"]
    assert rel(J, REF["J"]) < 0.03           # 8.429e-3 vs 8.55e-3: -1.4 %
    np.testing.assert_allclose(J, 8.4289e-3, rtol=1e-3)
    np.testing.assert_allclose(drive_lcr["C"]["B"], get_value(P, "control.B"), rtol=1e-6)
    np.testing.assert_allclose(drive_lcr["C"]["r_g"], get_value(P, "control.r_g"), rtol=1e-4)


def test_free_free_rigid_modes():
    md = modes(second_order(build("free_screw")), damping="projection")
    assert md.rigid_body.sum() == 6
    # + nut: the helical relative motion of the rank-5 K_SN (nut running along the thread) is a 7th
    assert free_free_modes("2")["n_rigid"] == 7
    # on the frame without coupling/rotor: screw+nut spin together, and the nut runs along the thread
    md = modes(second_order(build("no_table")), damping="projection")
    assert md.rigid_body.sum() == 2


# ---- Tables 3.2 / 3.3: free-free screw + nut ---------------------------------------------------------
def test_table_3_2_3_3_free_free_screw_nut(free_free):
    ax = [free_free[p]["axial"] for p in "123"]
    tor = [free_free[p]["torsional"] for p in "123"]
    # torsion and the axial mode at position 2 (the middle of the thread): within 1 %
    assert np.all(rel(tor, REF["free_free_torsional_simulated"]) < 0.01)
    assert rel(ax[1], REF["free_free_axial_simulated"][1]) < 0.01
    # positions 1 and 3 are a CHOICE (thread ends; the figure is missing): 3.5-3.7 % low, pinned here
    np.testing.assert_allclose([ax[0], ax[2]], [2401.95, 2434.44], rtol=2e-3)
    assert ax[1] > ax[0] and ax[1] > ax[2]               # the variation with position of Table 3.2


# ---- Table 4.1 / 4.2: full system, jaw and bellows coupling ------------------------------------------
def test_table_4_1_frequencies(drive_lcr):
    f1 = [drive_lcr[p]["f1"] for p in "LCR"]
    f2 = [drive_lcr[p]["f2"] for p in "LCR"]
    assert np.all(rel(f1, REF["table41_fn1"]) < 0.015)     # -0.9 / +1.0 / -0.6 %
    assert np.all(rel(f2, REF["table41_fn2"]) < 0.02)      # +1.3 / +1.6 / +1.6 %
    assert f1[0] < f1[1] < f1[2]                           # stiffer as the nut nears the thrust bearing


def test_table_4_1_residues_and_damping(drive_lcr):
    Rw1 = [drive_lcr[p]["Rw1"] for p in "LCR"]
    Rm1 = [drive_lcr[p]["Rm1"] for p in "LCR"]
    assert np.all(rel(Rw1, REF["table41_Rw1"]) < 0.04)     # +1.9 / +3.4 / +2.0 %
    assert np.all(rel(Rm1, REF["table41_Rm1"]) < 0.02)     # same sign as the thesis, +0.8..1.5 %
    np.testing.assert_allclose([drive_lcr[p]["Rw2"] for p in "LCR"], [26.10, 25.10, 23.54], rtol=3e-3)  # -7..8 %
    for p in "LCR":                                         # Table 4.1 ratios on the right modes
        assert abs(drive_lcr[p]["zeta1"] - 0.06) < 2e-3
        assert abs(drive_lcr[p]["zeta2"] - 0.10) < 2e-3


def test_bellows_coupling_raises_the_modes(drive_lcr):
    jaw, bel = drive_lcr["C"], drive_lcr["bellows_C"]
    assert bel["f1"] > jaw["f1"]
    assert bel["f2"] > 1.8 * jaw["f2"]
    assert rel(bel["f1"], REF["table42_fn1"][1]) < 0.015   # 122.97 vs 121.50
    # f_n2 depends on where the coupling clamps the 20 mm journal (CHOICE): -6.6 % at the default
    np.testing.assert_allclose(bel["f2"], 524.46, rtol=2e-3)


# ---- Table 5.3: sub-model 1 (axial + torsional) ------------------------------------------------------
def test_table_5_3_submodel1():
    f = submodel1_frequencies()
    assert rel(f[0], REF["table53_full"][0]) < 0.015        # 263.6 vs 260.86
    np.testing.assert_allclose(f[1:], [840.20, 1235.70], rtol=2e-3)   # +5.9 %, -3.2 % (see the doc)


def test_axial_torsional_model_matches_the_6dof_drive_modes(drive_lcr):
    d = drive_parameters(build("axial_torsional", damping=False))
    np.testing.assert_allclose([d["f1"], d["f2"]], [drive_lcr["C"]["f1"], drive_lcr["C"]["f2"]], rtol=2e-3)
    np.testing.assert_allclose(d["J"], drive_lcr["C"]["J"], rtol=1e-9)


def test_drive_modal_damping_by_character_at_L(drive_lcr):
    md = drive_lcr["L"]["modes"]
    k1, k2 = drive_lcr["L"]["mode1"], drive_lcr["L"]["mode2"]
    assert k2 > k1 + 1           # bending modes of the long span sit between the two drive modes at L
    assert np.nanmax(np.abs(md.damping[k1 + 1:k2] - 0.06)) < 2e-3
    assert "DriveModalDamping" in repr(build("full").damping)
    C = DriveModalDamping(0.06, 0.1, 0.06).matrix(np.eye(2), np.array([[1.0, -1.0], [-1.0, 1.0]]))
    np.testing.assert_allclose(C @ np.ones(2), 0.0, atol=1e-14)      # rigid-body mode undamped


def test_variants_list_is_complete():
    assert set(VARIANTS) == {"free_screw", "screw_nut", "no_table", "full", "axial_torsional", "submodel1",
                             "appendix_c"}
