"""bscomp.frf: FRFs from the sparse second-order form and modal transfer functions (Eq 4.2-4.9)."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from bscomp import System, linearize, second_order
from bscomp.components import Fixed, Force, Mass, Spring
from bscomp.errors import UnknownNameError
from bscomp.kernel.damping import modal_damping_matrix
from bscomp.linear.modal import modes
from bscomp.linear.response import Frf, _statespace_frf, frf, transfer_function
from bscomp.systems import mass_spring_chain, small_drive


def oscillator(k=2.0e5, m=4.0):
    s = System("oscillator")
    s.add("wall", Fixed())
    s.add("k", Spring(c=k))
    s.add("m", Mass(m=m))
    s.add("F", Force())
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("F.flange", "m.flange_b")
    return s


def chain3():
    return mass_spring_chain((1.0, 2.0, 0.5), (1.0e5, 2.0e5, 1.5e5), name="chain3", first=0)



def test_grounded_spring_mass_is_compliance_at_low_frequency():
    k, m = 2.0e5, 4.0
    f = np.array([1e-3, 1.0, 10.0, 100.0, 1000.0])
    res = frf(oscillator(k, m), "F.f", "m.s", f)
    assert res.H.shape == (5, 1, 1)
    assert res.response()[0].real == pytest.approx(1 / k, rel=1e-9)
    w = 2 * np.pi * f
    np.testing.assert_allclose(res.response(), 1 / (k - w**2 * m), rtol=1e-12)


@pytest.mark.parametrize("output", ["rotor.w", "rotor.phi", "table.a", "table.s"])
def test_residue_transfer_function_equals_full_frf(output):
    """All modes: rigid-body part + damped residues == (K + jwC - w^2 M)^-1 solve (non-proportional C)."""
    s = small_drive()
    f = np.logspace(-1, 3, 300)
    H = frf(s, "motor.tau", output, f).response()
    tf = transfer_function(s, "motor.tau", output)
    G = np.array([tf(2j * np.pi * fk) for fk in f]).ravel()
    np.testing.assert_allclose(G, H, rtol=1e-8)
    Gs = sum(sec(2j * np.pi * f) for sec in tf.sections) + tf.feedthrough
    np.testing.assert_allclose(Gs, H, rtol=1e-8)
    assert [sec.rigid for sec in tf.sections] == [True, False, False]


def test_rigid_body_term_is_eq_4_2():
    """torque -> motor speed: rigid-body term 1/(J s + B) (Eq 4.2) in thesis form R/(s + B/J)."""
    s = small_drive()
    md = modes(s)
    J, B = md.reflected_inertia("rotor.phi"), md.reflected_damping("rotor.phi")
    rigid = transfer_function(s, "motor.tau", "rotor.w").sections[0]
    assert rigid.rigid and len(rigid.den) == 2                       # the pole at s = 0 cancelled
    assert rigid.num[-1] / rigid.den[0] == pytest.approx(1 / J, rel=1e-3)
    assert rigid.den[1] == pytest.approx(B / J, rel=1e-3)            # shifted by damping coupling only
    # torque -> motor angle: R_0 / (s (s + B/J)) (Eq 4.8)
    rigid_phi = transfer_function(s, "motor.tau", "rotor.phi").sections[0]
    assert rigid_phi.den[-1] == 0.0 and len(rigid_phi.den) == 3


def test_proportional_damping_gives_eq_4_3_sections():
    """Modally damped chain: each section R_k / (s^2 + 2 zeta w s + w^2) with R_k = c phi_k phi_k^T b."""
    so = second_order(chain3(), inputs=["F.f"], outputs=["m0.s", "m2.v"])
    zeta = np.array([0.01, 0.05, 0.08])
    so = replace(so, C=sp.csr_matrix(modal_damping_matrix(so.M, so.K, zeta)))
    md = modes(so)
    tf = transfer_function(so, "F.f", "m0.s")
    for k, sec in enumerate(tf.sections):
        w = md.omega[k]
        np.testing.assert_allclose(sec.den, [1.0, 2 * zeta[k] * w, w * w], rtol=1e-9)
        assert abs(sec.num[0]) <= 1e-9 * abs(sec.num[-1])              # no s term: displacement output
        assert sec.num[-1] == pytest.approx(md.residues[k, 0, 0], rel=1e-9)
        assert sec.zeta == pytest.approx(zeta[k], rel=1e-9)
    tfv = transfer_function(so, "F.f", "m2.v")                          # velocity output: R_k s (Eq 4.5)
    for k, sec in enumerate(tfv.sections):
        assert sec.num[0] == pytest.approx(md.residues[k, 1, 0], rel=1e-9)
    f = np.logspace(0, 3, 200)
    H = frf(so, "F.f", "m0.s", f).response()
    np.testing.assert_allclose(sum(s_(2j * np.pi * f) for s_ in tf.sections) + tf.feedthrough, H, rtol=1e-9)


def test_truncated_modes_and_selection():
    s = small_drive()
    tf1 = transfer_function(s, "motor.tau", "rotor.w", modes=1)
    assert [sec.mode for sec in tf1.sections] == [0, 1]
    tfe = transfer_function(s, "motor.tau", "rotor.w", modes=[1, 2], include_rigid=False)
    assert [sec.mode for sec in tfe.sections] == [1, 2] and not any(sec.rigid for sec in tfe.sections)
    # below the first elastic mode, the rigid + first-mode model is close to the full FRF
    f = np.array([1.0, 5.0, 20.0])
    H = frf(s, "motor.tau", "rotor.w", f).response()
    G = np.array([tf1(2j * np.pi * x) for x in f]).ravel()
    assert np.max(np.abs(G - H) / np.abs(H)) < 0.05
    with pytest.raises(UnknownNameError):
        transfer_function(s, "motor.tau", "rotor.w", modes=[7])


def test_statespace_fallback_agrees_with_second_order():
    s = small_drive()
    f = np.logspace(0, 3, 50)
    lin = linearize(s, inputs=["motor.tau"], outputs=["rotor.w", "table.a"])
    np.testing.assert_allclose(_statespace_frf(lin, f), frf(s, "motor.tau", ["rotor.w", "table.a"], f).H,
                               rtol=1e-9)


def test_frf_result_outputs(tmp_path):
    res = frf("small_drive", "motor.tau", ["rotor.w", "table.a"], fmin=1, fmax=500, n=40)
    assert isinstance(res, Frf) and res.H.shape == (40, 2, 1)
    assert res.outputs == ["rotor.w", "table.a"] and res.inputs == ["motor.tau"]
    np.testing.assert_allclose(res.magnitude_db, 20 * np.log10(np.abs(res.H)))
    assert np.all(np.abs(np.diff(res.phase_deg, axis=0)) < 180)       # unwrapped
    res.to_csv(tmp_path / "f.csv")
    lines = (tmp_path / "f.csv").read_text().splitlines()
    assert len(lines) == 41 and lines[0].split(",")[1] == "motor.tau->rotor.w re"
    d = json.loads(res.to_json(tmp_path / "f.json"))
    assert np.allclose(np.array(d["H_re"]) + 1j * np.array(d["H_im"]), res.H)
    fig = res.plot(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 1000
    # the legend carries each pair's unit, from the units the components declare
    assert res.units == {"motor.tau": "N m", "rotor.w": "rad/s", "table.a": "m/s^2"}
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == [
        "motor.tau -> rotor.w [dB re 1 rad/s/(N m)]", "motor.tau -> table.a [dB re 1 m/s^2/(N m)]"]
    with pytest.raises(UnknownNameError):
        res.response("table.s")
    assert math.isclose(res.response("table.a")[0].real, res.H[0, 1, 0].real)


def test_modal_and_direct_frf_agree_on_a_damped_drive():
    """The eigen-decomposition path equals the per-frequency sparse solve (non-proportional damping)."""
    from bscomp import second_order
    from bscomp.systems import small_drive

    so = second_order(small_drive(), inputs=["motor.tau"], outputs=["rotor.w", "table.a", "table.s"])
    f = np.logspace(-1, 3.3, 200)
    H_direct = so.frf(f, method="direct")
    H_modal = so.frf(f, method="modal")
    np.testing.assert_allclose(H_modal, H_direct, rtol=1e-6)


def _drive_with_friction():
    from bscomp.components import CoulombFriction

    s = small_drive()
    s.add("fric", CoulombFriction(F_c_pos=100.0, F_c_neg=100.0))
    s.connect("ground.flange", "fric.flange_a")
    s.connect("fric.flange_b", "table.flange_b")
    return s


def test_linear_analyses_of_a_nonlinear_model_warn_by_name(tmp_path):
    """Issue 15: frf/modes/transfer_function (and simulate(method='lti'), the same detector) of a model with
    friction warn, naming the linearized component and what to use instead; a linear model is silent."""
    import warnings

    from bscomp.cli import main, one_line_warning
    from bscomp.errors import ModelLimitationWarning
    from bscomp.simulation.dispatch import simulate

    s = _drive_with_friction()
    calls = [lambda: frf(s, "motor.tau", "table.s", [10.0, 100.0]), lambda: modes(s),
             lambda: transfer_function(s, "motor.tau", "table.s"),
             lambda: simulate(s, np.linspace(0, 0.05, 51), inputs={"motor.tau": 2.0}, method="lti")]
    for call in calls:
        with pytest.warns(ModelLimitationWarning, match=r"linearizes the nonlinear component\(s\) fric "
                          r"\(CoulombFriction\).*nonlinear in der\(table\.s\)"
                          r".*(method='idas'|bscomp\.stepped_sine)") as rec:
            call()
        assert rec[0].filename == __file__          # points at the caller's line
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelLimitationWarning)
        frf(small_drive(), "motor.tau", "table.s", [10.0, 100.0])
        modes(small_drive())
    path = tmp_path / "fric.py"
    path.write_text("from bscomp.systems import small_drive\nfrom bscomp.components import CoulombFriction\n\n\n"
                    "def build():\n    s = small_drive()\n"
                    "    s.add('fric', CoulombFriction(F_c_pos=100.0, F_c_neg=100.0))\n"
                    "    s.connect('ground.flange', 'fric.flange_a')\n"
                    "    s.connect('fric.flange_b', 'table.flange_b')\n    return s\n")
    with pytest.warns(ModelLimitationWarning, match=r"frf on 'small_drive' linearizes .*fric \(CoulombFriction\)"):
        assert main(["frf", str(path), "--input", "motor.tau", "--output", "table.s", "--n", "3", "--csv",
                     str(tmp_path / "h.csv")]) == 0
    line = one_line_warning("frf")("a\n  b", ModelLimitationWarning, "x.py", 1)
    assert line == "bscomp frf: warning: ModelLimitationWarning: a b\n"
