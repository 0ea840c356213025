"""Cross-parameter checks (Component.check) on every path a value takes: constructor, Component.set /
System.set, ``params=`` overrides (Dae.parameter_vector), design_study grids and build options."""

import numpy as np
import pytest
import scipy.sparse as sp

import bscomp
import bscomp.systems
from bscomp import System
from bscomp.components import (
    BoltedFastener,
    Bushing,
    CurrentAmplifier,
    FixedRotational,
    IdealLeadScrew,
    Inertia,
    MovingNutJoint,
    NodeToFlange,
    RigidBody,
    Saturation,
    ScrewNutShapeFunction,
    Torque,
    TorsionalDamper,
)
from bscomp.errors import ParameterError, UsageError
from bscomp.kernel.component import Component, Parameter
from bscomp.systems.thesis_parts import thesis_ballscrew, thesis_screw_nut

T = np.linspace(0.0, 1.0, 11)


def sat_system(sat: Saturation) -> System:
    """Saturated torque on an inertia with a damper: w(t) follows the limited command."""
    s = System("sat")
    s.add("sat", sat)
    s.add("mot", Torque())
    s.add("J", Inertia(J=1.0))
    s.add("d", TorsionalDamper(d=1.0))
    s.add("g", FixedRotational())
    s.connect("sat.y", "mot.tau")
    s.connect("mot.flange", "J.flange_a")
    s.connect("J.flange_b", "d.flange_a")
    s.connect("d.flange_b", "g.flange")
    return s


def speed(model, u=3.0, **kw):
    return bscomp.simulate(model, T, inputs={"sat.u": u}, outputs=["J.w"], **kw).outputs["J.w"]


# ---- the hook itself -----------------------------------------------------------------------------------
class _Ordered(Component):
    lo = Parameter(0.0, unit="1")
    hi = Parameter(1.0, unit="1")
    calls = 0

    def check(self, values):
        type(self).calls += 1
        if not values["lo"] < values["hi"]:
            raise ParameterError(f"{self._where('lo', 'hi')}: need lo < hi")


def test_check_runs_in_constructor_and_set_and_a_failed_set_changes_nothing():
    with pytest.raises(ParameterError, match="lo"):
        _Ordered(lo=2.0)
    c = _Ordered()
    with pytest.raises(ParameterError, match="need lo < hi"):
        c.set("lo", 5.0)
    assert c.get("lo") == 0.0                                     # unchanged
    with pytest.raises(ParameterError):
        c.hi = -1.0                                               # attribute assignment goes through set
    assert c.get("hi") == 1.0
    c.set("hi", 3.0).set("lo", 2.0)
    assert (c.get("lo"), c.get("hi")) == (2.0, 3.0)


# ---- Saturation / CurrentAmplifier (finding 1, 7) ------------------------------------------------------
@pytest.mark.parametrize("name, value, names", [("sat.y_min", 5.0, "sat.y_min"), ("sat.delta", 10.0, "sat.delta")])
def test_saturation_set_checks_the_limits(name, value, names):
    s = sat_system(Saturation(y_max=1.0))
    with pytest.raises(ParameterError, match=names.replace(".", r"\.")):
        s.set(name, value)
    assert s.get(name) == {"sat.y_min": -1.0, "sat.delta": 0.0}[name]


def test_saturation_constructor_checks():
    with pytest.raises(ParameterError, match="y_min"):
        Saturation(y_max=1.0, y_min=2.0)
    with pytest.raises(ParameterError, match="delta"):
        Saturation(y_max=1.0, delta=1.5)
    with pytest.raises(ParameterError, match="y_max"):
        Saturation(y_max="2 V")                      # a unit of another dimension than the declared '1'
    with pytest.raises(ParameterError, match="y_max"):
        Saturation(y_max=float("nan"))
    assert Saturation(y_max="2").get("y_min") == -2.0


def test_saturation_params_override_is_checked():
    dae = bscomp.flatten(sat_system(Saturation(y_max=1.0)))
    with pytest.raises(ParameterError, match=r"sat\.y_min"):
        dae.parameter_vector({"sat.y_min": 5.0})
    with pytest.raises(ParameterError, match=r"sat\.delta"):
        dae.parameter_vector({"sat.delta": 10.0})
    p = dae.parameter_vector({"sat.y_max": "2", "sat.delta": 0.5})          # strings converted, valid pair
    assert p[dae.p_names.index("sat.y_max")] == 2.0 and p[dae.p_names.index("sat.delta")] == 0.5


def test_saturation_set_to_valid_values_equals_constructing_it_so():
    s = sat_system(Saturation(y_max=1.0))
    s.set("sat.y_max", 2.0)
    s.set("sat.y_min", -1.5)
    s.set("sat.delta", 0.25)
    w_set = speed(s)
    w_new = speed(sat_system(Saturation(y_max=2.0, y_min=-1.5, delta=0.25)))
    np.testing.assert_allclose(w_set, w_new, rtol=1e-12, atol=1e-15)
    assert w_set[-1] == pytest.approx(2.0 * (1 - np.exp(-1.0)), rel=1e-3)     # limited at y_max = 2


def test_current_amplifier_delta_within_the_limit():
    with pytest.raises(ParameterError, match="delta.*i_max"):
        CurrentAmplifier(K_a=1.0, i_max=1.0, delta=5.0)
    amp = CurrentAmplifier(K_a=1.0, i_max=1.0, delta=0.5)
    with pytest.raises(ParameterError, match="i_max"):
        amp.set("i_max", 0.4)
    assert amp.get("i_max") == 1.0
    CurrentAmplifier(K_a=1.0, i_max=0.0, delta=5.0)          # no limit: delta unused


# ---- moving nut on the screw (finding 2) ---------------------------------------------------------------
@pytest.mark.parametrize("z0", [5.0, 1.5, 100.0, -1.0])
def test_moving_nut_off_the_screw_is_rejected(z0):
    with pytest.raises(ParameterError, match=r"sn\.z0.*0\.9205"):
        bscomp.systems.get("testbed_axial_torsional", {"nut_joint": "moving", "sn.z0": z0})


def test_moving_nut_params_override_and_valid_position():
    dae = bscomp.flatten(bscomp.systems.get("testbed_axial_torsional", {"nut_joint": "moving"}))
    with pytest.raises(ParameterError, match=r"sn\.z0"):
        dae.parameter_vector({"sn.z0": 5.0})
    f = bscomp.modes(dae, n=3, warn=False, params={"sn.z0": 0.5}).frequencies
    assert f[0] == pytest.approx(0.0, abs=1e-6) and 100.0 < f[1] < 150.0


def test_moving_nut_joint_and_shape_function_ranges():
    with pytest.raises(ParameterError, match=r"z0.*\[0, 1\]"):
        MovingNutJoint([0.0, 0.5, 1.0], k_w=1e8, k_t=1e4, z0=2.0)
    j = MovingNutJoint([0.0, 0.5, 1.0], k_w=1e8, k_t=1e4, z0=0.5)
    with pytest.raises(ParameterError, match="z0"):
        j.set("z0", -0.1)
    assert j.get("z0") == 0.5
    with pytest.raises(ParameterError, match="z_nut.*0.9205"):
        ScrewNutShapeFunction(thesis_ballscrew(dofs=("w", "tz")), 3.0, thesis_screw_nut())


# ---- design_study (finding 3) --------------------------------------------------------------------------
@pytest.mark.parametrize("grid, name", [({"guide.d": [-1e5]}, "guide.d"), ({"axial.c": [0.0]}, "axial.c"),
                                        ({"axial.c": [-1e8]}, "axial.c"), ({"lead.lead": [0]}, "lead.lead"),
                                        ({"table.m": [float("nan")]}, "table.m"), ({"table.m": [-200]}, "table.m"),
                                        ({"table.m": ["250 m"]}, "table.m")])
def test_design_study_validates_the_grid(grid, name):
    with pytest.raises(ParameterError, match=name.replace(".", r"\.")):
        bscomp.design_study("small_drive", grid, executor="serial")


def test_design_study_converts_unit_strings():
    t = bscomp.design_study("small_drive", {"table.m": ["250 kg", 250.0]}, executor="serial")
    assert t["table.m"].tolist() == [250.0, 250.0]
    np.testing.assert_allclose(t.data[0], t.data[1])


@pytest.mark.parametrize("freqs", [[0.0, -1.0], [float("nan")], []])
def test_design_study_frf_freqs(freqs):
    with pytest.raises(UsageError, match="freqs"):
        bscomp.design_study("small_drive", {"table.m": [250.0]}, analysis="frf", inputs=["motor.tau"],
                            outputs=["table.s"], freqs=freqs, executor="serial")


# ---- single components (findings 4, 5) -----------------------------------------------------------------
def test_rigid_body_inertia_must_be_symmetric():
    bad = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ParameterError, match="I.*symmetric"):
        RigidBody(m=1.0, I=bad)
    b = RigidBody(m=1.0, I=np.eye(3))
    with pytest.raises(ParameterError, match="symmetric"):
        b.set("I", bad)
    np.testing.assert_array_equal(b.get("I"), np.eye(3))
    RigidBody(m=1.0, I=np.eye(3) + 1e-13 * bad)                      # round-off asymmetry is fine
    with pytest.raises(ParameterError, match="3x3"):
        b.set("I", [1.0, 2.0, 3.0])


def test_bushing_bolt_and_screw_nut_checks_on_set():
    k = Bushing(K=np.full(6, 1e6))
    K = np.diag(np.full(6, 1e6))
    K[0, 1] = 1.0
    with pytest.raises(ParameterError, match="K.*symmetric"):
        k.set("K", K)
    with pytest.raises(ParameterError, match="axis"):
        BoltedFastener(k=1e6).set("axis", np.zeros(3))
    sn = thesis_screw_nut()
    with pytest.raises(ParameterError, match="phi_end"):
        sn.set("phi_end", sn.get("phi_start") - 1.0)


def test_lead_and_direction():
    with pytest.raises(ParameterError, match="lead"):
        IdealLeadScrew(lead=0.0)
    with pytest.raises(ParameterError, match=r"lead\.lead"):
        bscomp.systems.get("small_drive", {"lead.lead": 0.0})
    assert IdealLeadScrew(lead=-0.01).get("lead") == -0.01           # left-hand thread (documented)
    for d in (0.5, 0.0):
        with pytest.raises(ParameterError, match="direction"):
            NodeToFlange(direction=d)
    assert NodeToFlange(direction=-1.0).get("direction") == -1.0


def test_cms_reduce_rejects_negative_indices():
    n = 6
    K = sp.csr_matrix(sp.diags([2.0] * n) - sp.diags([1.0] * (n - 1), 1) - sp.diags([1.0] * (n - 1), -1)) * 1e6
    M = sp.identity(n, format="csr")
    with pytest.raises(UsageError, match="boundary_dofs.*-1"):
        bscomp.cms_reduce(M, K, [-1], n_modes=2)
    assert bscomp.cms_reduce(M, K, [0, 5], n_modes=2).M.shape == (4, 4)


# ---- test-bed build options (finding 6) ----------------------------------------------------------------
@pytest.mark.parametrize("option, value", [("root_diameter", 0.0), ("root_diameter", -0.03),
                                           ("root_diameter", 35.5), ("pitch", 0.0), ("pitch", -0.01)])
def test_testbed_numeric_options(option, value):
    with pytest.raises(ParameterError, match=option):
        bscomp.systems.get("testbed_axial_torsional", {option: value})


def test_testbed_variant_keyword():
    with pytest.raises(UsageError, match="variant='ful'"):
        bscomp.systems.get("testbed", {"variant": "ful"})
    assert bscomp.systems.get("testbed_axial_torsional", {"variant": "axial_torsional", "pitch": 0.01,
                                                          "root_diameter": 0.04}).name == "testbed_axial_torsional"


def test_position_sweep_checks_the_positions_its_tangent_update_writes():
    """The tangent update of position_sweep writes z0 itself: a position off the screw is refused before any
    analysis (it was clamped to the end node silently), and a built System is accepted as the model."""
    from bscomp.linear.sweeps import position_sweep
    from bscomp.systems.testbed import testbed

    s = testbed("axial_torsional", nut_joint="moving")
    with pytest.raises(ParameterError, match=r"'sn.z0' \(MovingScrewNut\): z0 = 5.0 m puts the nut off the screw"):
        position_sweep(s, [0.3, 5.0])
    r = position_sweep(s, [0.3])
    assert 100.0 < r.frequencies[0, 0] < 130.0
