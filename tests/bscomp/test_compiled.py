"""CompiledModel: one flattening, FRFs and time series per parameter vector, checked against the library's
own independent paths (bscomp.frf on a re-flattened system, IDAS at tight tolerance) and exact identities
(a delay is e^{-jwT}; an integer-sample delay is a shift); the time series' sample compiled to C once hot
(bscomp.simulation.compiled_hot) against the virtual machine, to the bit."""

import shutil
import warnings

import numpy as np
import pytest

from bscomp.components import Fixed
from bscomp.components.backlash import Backlash
from bscomp.components.coulomb_friction import CoulombFriction
from bscomp.errors import BscompError
from bscomp.linear.response import frf
from bscomp.simulation import compiled_hot
from bscomp.simulation.compiled import CompiledModel
from bscomp.simulation.dispatch import simulate
from bscomp.systems import get

OUTS = ["rotor.phi", "rotor.w", "table.s", "table.a"]
F = np.logspace(0, 3, 120)
needs_cc = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="needs a C compiler")


def _nrmse(a, b):
    b = np.asarray(b, float)
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def _square(t, amp=2.125):
    return amp * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)


def _chain(name, masses, links, dampers, friction=None, at=None):
    """A grounded chain as ``benchmarks/fuzz_modal.py`` builds it: wall -- link and dashpot -- mass -- ..., the force
    ``F.f`` on the last mass, ``friction`` (a component) to ground on mass ``at``."""
    from bscomp.components import Damper, Force, Mass
    from bscomp.kernel.system import System

    s = System(name)
    s.add("wall", Fixed())
    prev = "wall.flange"
    for i, (m, link, d) in enumerate(zip(masses, links, dampers, strict=True)):
        s.add(f"m{i}", Mass(m=m))
        s.add(f"k{i}", link)
        s.add(f"d{i}", Damper(d=d))
        for a, b in ((prev, f"k{i}.flange_a"), (f"k{i}.flange_b", f"m{i}.flange_a"), (prev, f"d{i}.flange_a"),
                     (f"d{i}.flange_b", f"m{i}.flange_a")):
            s.connect(a, b)
        prev = f"m{i}.flange_b"
    if friction is not None:
        s.add("ground", Fixed())
        s.add("fr", friction)
        s.connect("ground.flange", "fr.flange_a")
        s.connect("fr.flange_b", f"m{at}.flange_a")
    s.add("F", Force())
    s.connect("F.flange", prev)
    return s


@pytest.fixture(scope="module")
def testbed_model():
    s = get("testbed_axial_torsional")
    cm = CompiledModel(s, ["amp.u"], OUTS, free=["table.m", "coupling.k_T", "b1.k_axial"])
    assert cm.inputs == ["amp.u"] and not cm.elements     # linear drive: nothing cut out
    return s, cm


def test_modes_are_mass_normalised_with_one_rigid_body_mode(testbed_model):
    _, cm = testbed_model
    mm = cm.modal({})
    M = mm.so.M.toarray()
    assert np.allclose(mm.phi.T @ M @ mm.phi, np.eye(mm.lam.size), atol=1e-8)
    assert int(np.sum(mm.lam == 0.0)) == 1 and 0 in mm.keep                # the drive's rigid-body mode
    f = mm.frequencies[mm.keep]
    assert abs(f[1] - 118.87) < 0.05 and np.all(f <= cm.f_keep)            # first axial mode, kept modes


def test_frf_equals_bscomp_frf_on_the_fe_test_bed_after_parameter_changes(testbed_model):
    s, cm = testbed_model
    # structural parameters (coupling, thrust bearing) through affine sensitivities, table mass through p
    assert set(cm._sens) == {"coupling.k_T", "b1.k_axial"}
    for pv in ({}, {"table.m": 272.0, "coupling.k_T": 3500.0, "b1.k_axial": 3.1e8}):
        H = cm.frf(pv, F, [("amp.u", "table.a"), ("amp.u", "rotor.w")])
        ref = frf(s.with_parameters(pv), input="amp.u", output=["table.a", "rotor.w"], freqs=F)
        for o in ("table.a", "rotor.w"):
            r = ref.H[:, ref.outputs.index(o), 0]
            assert np.max(np.abs(H[("amp.u", o)] - r) / np.abs(r)) < 1e-6


def test_the_linear_frf_is_kept_per_modal_model_and_handed_out_as_a_copy(testbed_model):
    """CompiledModel.frf keeps the linear part's FRFs on its modal model (a fit that varies only a friction or a
    clearance meets them again): the same arrays to the bit as computed anew, one entry per frequencies and pairs,
    and what a caller does to the arrays it got does not reach the next call."""
    _, cm = testbed_model
    pairs = [("amp.u", "table.a"), ("amp.u", "rotor.w")]
    pv = {"table.m": 263.0}
    H1 = cm.frf(pv, F, pairs)
    mm = cm.modal(pv)
    fresh = cm._modal_map(mm, F, ["amp.u"], ["table.a", "rotor.w"])
    assert np.array_equal(H1[pairs[0]], fresh[:, 0, 0]) and np.array_equal(H1[pairs[1]], fresh[:, 1, 0])
    H1[pairs[0]][:] = 0.0                                    # a caller writing into what it got
    H2 = cm.frf(pv, F, pairs)
    assert np.array_equal(H2[pairs[0]], fresh[:, 0, 0]) and len(mm.__dict__["_frf"]) == 1
    cm.frf(pv, F[:50], pairs)                                # other frequencies: their own entry
    assert len(mm.__dict__["_frf"]) == 2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_frfs_on_random_chains_follow_parameter_changes_back_and_forth(seed):
    """Random damped chains (2-4 masses of 0.5-50 kg on 1e4-1e7 N/m, a dashpot beside each spring), a sequence of 12
    parameter vectors drawn from 4 (so the modal models and their kept FRFs are met again, in another order): every
    FRF equals ``bscomp.frf`` on the re-flattened system at those values."""
    from bscomp.components import Spring

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    ms, ks = rng.uniform(0.5, 50, n), 10 ** rng.uniform(4, 7, n)
    s = _chain(f"chain_{seed}", ms, [Spring(c=k) for k in ks], 0.02 * np.sqrt(ks * ms) * rng.uniform(0.5, 2, n))
    free = ["m0.m", f"k{n - 1}.c", "d0.d"]
    outs = [f"m{n - 1}.a", "m0.v"]
    cm = CompiledModel(s, ["F.f"], outs, free=free)
    f = np.logspace(0, 2.5, 80)
    vectors = [{p: s.get(p) * float(np.exp(rng.normal(0, 0.3))) for p in free} for _ in range(4)]
    for j in rng.integers(0, 4, 12):
        pv = vectors[j]
        H = cm.frf(pv, f, [("F.f", o) for o in outs])
        ref = frf(s.with_parameters(pv), input="F.f", output=outs, freqs=f)
        for o in outs:
            r = ref.H[:, ref.outputs.index(o), 0]
            assert np.max(np.abs(H[("F.f", o)] - r) / np.abs(r)) < 1e-6, (seed, j, o)


def test_a_damping_the_model_leaves_at_zero_gets_an_exact_sensitivity(testbed_model):
    """b1.c_axial and coupling.d are 0 in the thesis model (its damping is modal): their sensitivities are probed at
    0 and +-1 (a relative step of a zero value divided by zero before), and the FRF with them turned on equals the
    re-flattened model's (the support_damping and coupling_damping candidates fit exactly these). The bearing's
    dashpot couples the drive's modes to high ones a static residual cannot stand for: they are kept dynamic
    (`damped_beyond_static`: 9 -> 47 modes; with the 9 alone the table FRF was 44 % off near 1 kHz). Exact to the
    static residual of the weakly coupled modes it leaves out (3.4e-3 at the FRF's worst point, an anti-resonance;
    the data's noise is 2e-2)."""
    s, _ = testbed_model
    cm = CompiledModel(s, ["amp.u"], OUTS, free=["b1.c_axial", "coupling.d"])
    assert set(cm._sens) == {"b1.c_axial", "coupling.d"} and s.get("b1.c_axial") == 0.0 == s.get("coupling.d")
    pv = {"b1.c_axial": 3.0e4, "coupling.d": 0.12}
    H = cm.frf(pv, F, [("amp.u", "table.a"), ("amp.u", "rotor.w")])
    ref = frf(s.with_parameters(pv), input="amp.u", output=["table.a", "rotor.w"], freqs=F)
    H0 = cm.frf({}, F, [("amp.u", "table.a")])[("amp.u", "table.a")]
    for o in ("table.a", "rotor.w"):
        r = ref.H[:, ref.outputs.index(o), 0]
        assert np.max(np.abs(H[("amp.u", o)] - r) / np.abs(r)) < 5e-3
    assert np.max(np.abs(H[("amp.u", "table.a")] / H0 - 1)) > 0.05          # and the dashpots do act
    assert len(cm.modal(pv).keep) > len(cm.modal({}).keep) == 9


def test_delay_is_exact_in_frf_and_a_shift_in_time(testbed_model):
    _, cm = testbed_model
    T = 3.7e-4
    H0 = cm.frf({}, F, [("amp.u", "table.a")])[("amp.u", "table.a")]
    H1 = cm.frf({}, F, [("amp.u", "table.a")], delay=T)[("amp.u", "table.a")]
    assert np.allclose(H1, H0 * np.exp(-2j * np.pi * F * T), rtol=1e-12, atol=0)
    t = np.arange(0, 0.2, 2e-4)
    u = _square(t)
    y0 = cm.simulate({}, t, {"amp.u": u})["table.s"]
    y3 = cm.simulate({}, t, {"amp.u": u}, delay=3 * 2e-4)["table.s"]
    assert np.allclose(y3[3:], y0[:-3], rtol=0, atol=1e-12 * np.max(np.abs(y0)))


def test_linear_time_series_matches_exact_zoh_of_the_full_model(testbed_model):
    s, cm = testbed_model
    t = np.arange(0, 0.3, 2e-4)
    u = _square(t)
    Y = cm.simulate({}, t, {"amp.u": u})
    ref = simulate(s, t, inputs={"amp.u": u}, outputs=OUTS, method="lti")
    for o in OUTS:  # modes above 6 kHz enter statically: 1e-6 of the signal
        assert _nrmse(Y[o], ref[o]) < 1e-5, o


def _friction_backlash_drive():
    """The validation drive with guideway friction and a screw-nut clearance (two elements)."""
    s = get("validation_drive")
    s.add("friction", CoulombFriction(F_c=1500.0, v_reg=5e-4))
    s.connect("friction.flange_a", "ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    c, d = s.get("axial.c"), s.get("axial_loss.d")
    s.remove("axial")
    s.remove("axial_loss")
    s.add("axial", Backlash(b=2e-5, c=c, d=d, s_rel0=-1e-5, eps=4e-6))
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    return s


def test_friction_and_backlash_agree_with_idas_at_tight_tolerance():
    s = _friction_backlash_drive()
    cm = CompiledModel(s, ["amp.u"], OUTS)
    assert [e.path for e in cm.elements] == ["friction", "axial"]
    t = np.arange(0, 0.4, 2e-4)
    u = _square(t)
    Y = cm.simulate({}, t, {"amp.u": u}, n_sub=8)
    assert cm.stats["last_newton_residual"] < 1e-9
    ref = simulate(s, t, inputs={"amp.u": u}, outputs=OUTS, rtol=1e-9, atol=1e-12)
    for o in ("rotor.phi", "rotor.w", "table.s"):
        assert _nrmse(Y[o], ref[o]) < 2e-5, o
    assert _nrmse(Y["table.a"], ref["table.a"]) < 1e-2
    # a change of a law parameter alone re-uses the modal model and changes the response
    Y2 = cm.simulate({"friction.F_c_pos": 1200.0, "friction.F_c_neg": 1200.0}, t, {"amp.u": u}, n_sub=8)
    assert _nrmse(Y2["table.s"], Y["table.s"]) > 1e-2


def test_samples_run_in_blocks_equal_one_sample_per_call(monkeypatch):
    """The time series runs several samples per mapaccum call (compiled_time._blocked); a grid of 1004 samples is
    not a multiple of the block, so the last block is padded: the outputs and the Newton residual equal the
    one-sample-per-call run to round-off, the padded tail dropped."""
    import bscomp.simulation.compiled_time as ct

    s = get("validation_drive")
    s.add("friction", CoulombFriction(F_c=1500.0, v_reg=5e-4))
    s.connect("friction.flange_a", "ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    t = np.arange(1004) * 2e-4
    u = _square(t)
    cm = CompiledModel(s, ["amp.u"], OUTS)
    Y = cm.simulate({}, t, {"amp.u": u}, n_sub=4)
    steps = [v for k, v in cm._steps.items() if k[0] == "blocked"]
    assert steps and all(per > 1 for _, per in steps)       # blocks were used
    assert (len(t) - 1) % steps[0][1] != 0                    # and the last one was padded
    res = cm.stats["last_newton_residual"]
    monkeypatch.setattr(ct, "BLOCK_INSTRUCTIONS", 0)          # one sample per call
    cm1 = CompiledModel(s, ["amp.u"], OUTS)
    Y1 = cm1.simulate({}, t, {"amp.u": u}, n_sub=4)
    assert all(v[1] == 1 for k, v in cm1._steps.items() if k[0] == "blocked")
    for o in OUTS:
        assert Y[o].shape == t.shape
        np.testing.assert_allclose(Y[o], Y1[o], rtol=1e-12, atol=1e-12 * np.abs(Y1[o]).max())
    assert cm1.stats["last_newton_residual"] == pytest.approx(res, rel=1e-9, abs=1e-15)


def test_a_cut_elements_own_signals_are_refused_not_mislabelled():
    """The compiled evaluator cuts friction and backlash out and carries their force as a correction: a request
    for ``backlash.f`` would have returned that correction (in the clearance ``-c s``: 24.7 N where the element
    carries 0, measured on a 1 kg mass against a 1e7 N/m contact), so it is refused with the elements named;
    their ``s_rel`` / ``v_rel`` are served."""
    from bscomp.errors import UnknownNameError

    s = get("validation_drive")
    s.add("friction", CoulombFriction(F_c=1500.0, v_reg=5e-4))
    s.connect("friction.flange_a", "ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    with pytest.raises(UnknownNameError, match=r"\['friction.f'\] are signals of the nonlinear elements \['friction"):
        CompiledModel(s, ["amp.u"], ["table.a", "friction.f"])
    cm = CompiledModel(s, ["amp.u"], ["table.a"])
    t = np.arange(0, 0.02, 2e-4)
    Y = cm.simulate({}, t, {"amp.u": _square(t)}, outputs=["table.a", "friction.v_rel"])
    assert np.all(np.isfinite(Y["friction.v_rel"])) and np.ptp(Y["friction.v_rel"]) > 0


def test_friction_on_the_fe_test_bed_converges_with_substeps(testbed_model):
    s, _ = testbed_model
    s2 = s.copy()
    s2.add("fr", CoulombFriction(F_c=2066.0, v_reg=5e-4))
    s2.add("gnd", Fixed())
    s2.connect("fr.flange_a", "gnd.flange")
    s2.connect("fr.flange_b", "table.flange_b")
    cm = CompiledModel(s2, ["amp.u"], OUTS)
    t = np.arange(0, 0.3, 2e-4)
    u = _square(t)
    ys = [cm.simulate({}, t, {"amp.u": u}, n_sub=n)["table.a"] for n in (2, 4, 16)]
    e2, e4 = _nrmse(ys[0], ys[2]), _nrmse(ys[1], ys[2])
    assert e4 < e2 and e4 < 1e-3, (e2, e4)  # converges towards the fine-step solution


def _thesis_bed(contact=None):
    from bscomp.systems.testbed import testbed
    from bscomp.systems.thesis_effects import with_friction_backlash

    return with_friction_backlash(testbed("axial_torsional", "C"), **({} if contact is None else
                                                                        {"contact_stiffness": contact}))


def test_backlash_on_the_fe_test_bed_flies_through_the_clearance_as_the_modal_simulation_does():
    """The thesis's Ch 5 case (Table 5.2 friction + the 1.7e10 N/m screw-nut backlash, the square wave) against
    simulate(method="modal") at tol 1e-5 (8.7e-4 from IDAS rtol 1e-8 on table.a). With the contact spring kept in
    the linear part the table stayed on the nut (over these 0.15 s: table.a 0.47, table.v 4.8e-2, rotor.phi 2.2e-3
    whatever n_sub): the contact is now cut from the time series' linear part and the default 4 sub-steps per sample
    are raised to a stable count (16): 5.0e-2, 4.2e-5, 3.5e-7. table.a's rest is the modes above f_keep taken
    statically at the impacts (no better at 64 sub-steps)."""
    s = _thesis_bed()
    t = np.arange(0, 0.15, 2e-4)
    u = _square(t)
    outs = ["table.a", "table.v", "rotor.phi"]
    ref = simulate(s, t, inputs={"amp.u": u}, outputs=outs, method="modal", modal_options={"tol": 1e-5})
    cm = CompiledModel(s, ["amp.u"], outs)
    Y = cm.simulate({}, t, {"amp.u": u})
    assert cm.stats["n_sub_used"] >= 8 and cm.stats["last_newton_residual"] < 1e-8, cm.stats
    err = {o: _nrmse(Y[o], ref[o]) for o in outs}
    assert err["table.v"] < 1e-4 and err["rotor.phi"] < 1e-5 and err["table.a"] < 0.1, err


def test_a_stiff_contact_raises_the_substeps_to_a_stable_count():
    """A 1e11 N/m contact integrated with its force first-order held is stable from 16 sub-steps per 0.2 ms
    (the linear-acceleration limit omega h < 2 sqrt 3 on the contact's own mode); the rule takes twice that
    (at the limit a kept mode rings: table.a NRMSE 14 there). A given n_sub is a minimum."""
    from bscomp.simulation.compiled_time import _stable

    cm = CompiledModel(_thesis_bed(1e11), ["amp.u"], ["table.v"])
    cut = cm._contact_equivalents()
    assert cut == {"backlash__lin.c": 0.0}
    mm = cm.modal(cut)
    slopes = cm._contact_slopes(cm.law_values({}), cut)
    assert [e.path for e in cm.elements] == ["friction", "backlash"] and list(slopes[0]) == [0.0, 1e11]
    stable = [_stable(cm._disc(mm, (2e-4, n, 0.0, ["table.v"])), slopes) for n in (2, 4, 8, 16, 32)]
    assert stable == [False, False, True, True, True], stable
    t = np.arange(0, 0.02, 2e-4)
    Y = cm.simulate({}, t, {"amp.u": _square(t)}, n_sub=2)
    assert cm.stats["n_sub_used"] == 16 and np.all(np.isfinite(Y["table.v"])), cm.stats


def test_the_guarded_newton_finds_the_force_where_plain_newton_cycles():
    """A sharp-cornered contact (eps 0) with damping 1e3 N s/m, its force clamped to [0, 2 c e] (Modelica's
    ElastoBacklash): just past the corner the law has slopes 2c then c, and plain Newton cycles between the two
    pieces (a residual of 35x the force at every sub-step count, seen in a diagnose fit); the bracketed one
    converges. Values of that fit's failing sub-step."""
    s = get("validation_drive")
    s.remove("axial")
    s.remove("axial_loss")
    s.add("axial", Backlash(b=1.55e-5, c=1e11, d=1e3, s_rel0=-7.75e-6, eps=0.0))   # its law's values: pl
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    cm = CompiledModel(s, ["amp.u"], ["table.s"])
    assert [e.pnames for e in cm.elements] == [["b", "c", "d", "s_rel0", "eps"]]
    pl = [1.54991899e-05, 1e11, 1e3, -7.74959494e-06, 0.0, 0.0, 0.0, 0.0]     # law, then k_lin, s0_lin, d_lin
    args = (-1.55002498e-05, -0.00743141, -2.66598737e-10, -8.79873549e-06, 0.0, pl)    # a_s, a_v, Gs, Gv, w0
    res = {guard: float(cm._newton(8, guard)(*args)[1]) for guard in (False, True)}
    assert res[False] > 1.0 and res[True] < 1e-9, res     # the root: w = -4 N (a scan of the residual)


def test_a_run_that_needed_more_substeps_takes_twice_the_first_that_converged():
    """benchmarks/fuzz_compiled.py seed 29: four masses to a wall, a 3 um clearance (5.7e6 N/m) between the first
    two, Stribeck friction (v_reg 1e-5 m/s) on the last, a 51 Hz square wave of 199 N held per 0.1 ms. The Newton
    fails at 4 sub-steps and converges at 8 with the last mass's velocity 52 % off (a stick-slip resolved wrongly);
    at 16, 2e-6. Against IDAS at rtol 1e-10 on the same held input."""
    from bscomp.components import Spring, StribeckFriction

    links = [Spring(c=12103.87), Backlash(b=2.99518e-6, c=5.720993e6, eps=1.497592e-7), Spring(c=331829.05),
             Spring(c=12411.03)]
    s = _chain("fuzz_seed_29", (25.563, 26.202, 13.628, 6.8965), links, (22.25, 125.57, 85.06, 11.70),
               StribeckFriction(F_s_pos=224.07, F_s_neg=224.07, F_c_pos=172.36, F_c_neg=172.36, v_reg=1e-5), at=3)
    t = np.round(np.arange(2001) * 1e-4, 12)
    u = 198.685 * np.sign(np.sin(2 * np.pi * 51.304 * t) + 1e-12)
    ref = simulate(s, t, inputs={"F.f": lambda tt: u[min(int(np.floor(tt / 1e-4 + 1e-9)), u.size - 1)]},
                   outputs=["m3.v"], rtol=1e-10, atol=1e-13, max_num_steps=10**7)
    cm = CompiledModel(s, ["F.f"], ["m3.v"])
    y = cm.simulate({}, t, {"F.f": u})
    assert cm.stats["n_sub_used"] == 16, cm.stats
    err = np.sqrt(np.mean((y["m3.v"] - ref["m3.v"]) ** 2)) / np.ptp(ref["m3.v"])
    assert err < 1e-4, err


@pytest.mark.parametrize("s_rel0, engaged", [(0.0, False), (-1.1e-5, True)])
def test_the_time_series_damping_is_the_drives_linearised_at_rest(s_rel0, engaged):
    """A clearance resting open gives the damping of the drive without its contact (as the flattened model
    linearised at rest does); resting engaged (b/2 = 1e-5 m, centre 1.1e-5 m away), the engaged drive's: the slope
    at rest is the law's own tangent there."""
    s = get("validation_drive")
    c = s.get("axial.c")
    s.remove("axial")
    s.remove("axial_loss")
    s.add("axial", Backlash(b=2e-5, c=c, s_rel0=s_rel0))
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    cm = CompiledModel(s, ["amp.u"], ["table.s"])
    cut = cm._contact_equivalents()
    rest = cm._rest_equivalents(cm.law_values({}), cut)
    assert rest == {"axial__lin.c": (c if engaged else 0.0)}, (rest, c)


def test_a_newton_that_never_converges_warns_naming_the_elements(monkeypatch):
    """One Newton iteration cannot solve a 1e11 N/m contact: the run is repeated guarded, then at twice the
    sub-steps up to the cap, and then it says so (never a silent wrong time series)."""
    import bscomp.simulation.compiled_time as ct
    from bscomp.errors import ModelLimitationWarning

    s = get("validation_drive")
    s.remove("axial")
    s.remove("axial_loss")
    s.add("axial", Backlash(b=1.55e-5, c=1e11, d=1e3, s_rel0=-7.75e-6))
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    cm = CompiledModel(s, ["amp.u"], ["table.s"])
    monkeypatch.setattr(ct, "MAX_SUB", 8)
    t = np.arange(0, 0.05, 2e-4)
    with pytest.warns(ModelLimitationWarning, match=r"forces of \['axial'\] did not converge .* at 8 sub-steps"):
        cm.simulate({}, t, {"amp.u": _square(t, 2.0)}, n_newton=1)
    assert cm.stats["n_sub_used"] == 8 and cm.stats["last_newton_residual"] > 1e-8
    assert cm.stats["newton_converged"] is False
    monkeypatch.setattr(ct, "MAX_SUB", 256)            # a caller's own cap (diagnose's fits: 64) does the same
    with pytest.warns(ModelLimitationWarning, match=r"at 4 sub-steps"):
        cm.simulate({}, t, {"amp.u": _square(t, 2.0)}, n_newton=1, max_sub=4)
    assert cm.stats["n_sub_used"] == 4 and not cm.stats["newton_converged"], cm.stats
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # warn=False: said in stats only (diagnose counts it)
        cm.simulate({}, t, {"amp.u": _square(t, 2.0)}, n_newton=1, max_sub=4, warn=False)
    assert not cm.stats["newton_converged"], cm.stats


def test_the_block_filter_recursion_is_the_step_by_step_one():
    """``_recursion`` (a first-/second-order filter per block of the real modal form, a loop for larger blocks)
    against ``x_{k+1} = P x_k + d_k`` stepped one sample at a time: a decaying real mode, a lightly damped and a
    slow oscillating one, an undamped rigid body (double pole at 1) and a 3 x 3 block."""
    from bscomp.simulation.compiled_time import _recursion

    rng = np.random.default_rng(7)

    def osc(w, z, h=1e-4):
        s = -z * w + 1j * w * np.sqrt(1 - z * z)
        return np.exp(s.real * h) * np.array([[np.cos(s.imag * h), np.sin(s.imag * h)],
                                              [-np.sin(s.imag * h), np.cos(s.imag * h)]])

    blocks = [np.array([[0.97]]), osc(2 * np.pi * 800, 0.01), osc(2 * np.pi * 3, 0.002),
              np.array([[1.0, 1e-4], [0.0, 1.0]]), 0.3 * rng.standard_normal((3, 3))]
    n = sum(b.shape[0] for b in blocks)
    P = np.zeros((n, n))
    i = 0
    for b in blocks:
        P[i:i + b.shape[0], i:i + b.shape[0]] = b
        i += b.shape[0]
    d = rng.standard_normal((n, 3000))
    X = np.zeros_like(d)
    x = np.zeros(n)
    for k in range(d.shape[1]):
        x = P @ x + d[:, k]
        X[:, k] = x
    Y = _recursion(P, d, tuple(b.shape[0] for b in blocks))
    scale = np.max(np.abs(X), axis=1)
    assert np.all(np.max(np.abs(Y - X), axis=1) <= 1e-11 * scale), np.max(np.abs(Y - X), axis=1) / scale
    assert np.array_equal(_recursion(P, d, (n,)), X)       # one dense block: the loop itself


# ---- the time series' sample compiled to C once hot (bscomp.simulation.compiled_hot): the same numbers to the bit
# as CasADi's virtual machine, loaded from the on-disk cache by a later model, the virtual machine kept where
# nothing can be compiled

def _run(cm, F_c=1500.0):
    t = np.arange(0, 0.4, 2e-4)                 # 1,999 steps: every block length (256, 64, 16, 4, 1) is used
    u = 2.125 * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)
    y = cm.simulate({"friction.F_c_pos": F_c, "friction.F_c_neg": F_c}, t, {"amp.u": u})
    return y, cm.stats["native_steps"]


@needs_cc
def test_a_hot_sample_runs_compiled_with_the_numbers_of_the_virtual_machine(tmp_path, monkeypatch):
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 1.0)          # hot after one run
    monkeypatch.setattr(compiled_hot, "BACKGROUND", False)      # compiled at once (the next test: in the background)
    s = _friction_backlash_drive()
    monkeypatch.setenv("BSCOMP_NATIVE_STEPS", "0")
    vm = CompiledModel(s, ["amp.u"], OUTS)
    ref = [_run(vm, F) for F in (1500.0, 1200.0, 1500.0)]
    assert [n for _, n in ref] == [False] * 3                   # switched off: always the virtual machine
    monkeypatch.delenv("BSCOMP_NATIVE_STEPS")
    cm = CompiledModel(s, ["amp.u"], OUTS)
    got = [_run(cm, F) for F in (1500.0, 1200.0, 1500.0)]
    assert [n for _, n in got] == [False, True, True]           # counted once, then compiled
    for (y0, _), (y1, _) in zip(ref, got, strict=True):
        for o in OUTS:
            assert np.array_equal(y0[o], y1[o]), o             # to the bit
    assert np.max(np.abs(ref[1][0]["table.a"] - ref[0][0]["table.a"])) > 0.01   # the parameter did change the run
    later = CompiledModel(s, ["amp.u"], OUTS)   # another model (a later process): from disk
    y, native = _run(later, 1200.0)
    assert native and all(np.array_equal(y[o], ref[1][0][o]) for o in OUTS)
    assert list(tmp_path.glob("jit/sample_x256_k*.so"))


@needs_cc
def test_compiled_in_the_background_the_runs_go_on_in_the_virtual_machine_until_it_is_there(tmp_path, monkeypatch):
    """The default: the compiler runs in a background thread once the sample is hot; the runs meanwhile are the
    virtual machine's, the later ones compiled -- every one the same numbers."""
    import time

    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 1.0)
    cm = CompiledModel(_friction_backlash_drive(), ["amp.u"], OUTS)
    runs = [_run(cm), _run(cm)]                                  # counted, then the compilation started
    assert [n for _, n in runs] == [False, False] and cm._hot.pending
    deadline = time.monotonic() + 120.0
    while not runs[-1][1] and time.monotonic() < deadline:
        time.sleep(0.05)
        runs.append(_run(cm))
    assert runs[-1][1], "the background compilation did not end in 120 s"
    for y, _ in runs[1:]:
        assert all(np.array_equal(y[o], runs[0][0][o]) for o in OUTS)


def test_where_nothing_compiles_the_virtual_machine_goes_on(tmp_path, monkeypatch):
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 0.0)

    def no_compiler(*args, **kwargs):
        raise BscompError("jit=True needs a C compiler (cc or gcc on PATH, or $CC)")

    monkeypatch.setattr(compiled_hot, "library_job", no_compiler)
    s = _friction_backlash_drive()
    cm = CompiledModel(s, ["amp.u"], OUTS)
    (y1, n1), (y2, n2) = _run(cm), _run(cm)
    assert not n1 and not n2
    assert all(np.array_equal(y1[o], y2[o]) for o in OUTS) and np.all(np.isfinite(y1["table.a"]))
    assert not list(tmp_path.glob("jit/sample_*"))


def test_the_skipping_newton_is_the_full_newton_to_the_bit():
    """compiled_hot.skipping_newton (the compiled sample's Newton: an iteration skipped once one returned its start)
    against CompiledModel._newton (every iteration), at 300 random element coordinates through and around the
    clearance and the friction's regularised band, started as in a run from the forces of a sub-step before (the
    coordinates 1e-8 m and 1e-4 m/s away) and from far off: equal to the bit, and from the sub-step before most
    reach the fixed point before the eighth iteration (so the skip saves work)."""
    cm = CompiledModel(_friction_backlash_drive(), ["amp.u"], OUTS)
    full = cm._newton(8)
    step, residual = cm._newton_parts()
    skip = compiled_hot.skipping_newton(step, residual, 8)
    pl = cm.law_values(cm._split({})[1])
    rng = np.random.default_rng(7)
    Gs, Gv = np.array([[-2e-9, 1e-10], [1e-10, -3e-9]]), np.array([[-1e-6, 0.0], [0.0, -2e-6]])
    first_fixed = []
    for _ in range(300):
        a_s, a_v = rng.uniform(-4e-5, 4e-5, 2), rng.uniform(-2e-3, 2e-3, 2)
        far = rng.uniform(-2e3, 2e3, 2)
        w0 = np.asarray(full(a_s - 1e-8, a_v - 1e-4, Gs, Gv, far, pl)[0]).ravel()     # the sub-step before's
        for start in (w0, far):
            ref, got = full(a_s, a_v, Gs, Gv, start, pl), skip(a_s, a_v, Gs, Gv, start, pl)
            assert np.array_equal(np.asarray(ref[0]), np.asarray(got[0])) and float(ref[1]) == float(got[1])
        w, k = w0, 0
        while k < 8:
            wn = np.asarray(step(a_s, a_v, Gs, Gv, w, pl)[0]).ravel()
            k += 1
            if np.array_equal(wn, w):
                break
            w = wn
        first_fixed.append(k)
    assert np.median(first_fixed) < 8, np.bincount(first_fixed)


def test_a_cache_folder_that_cannot_be_written_leaves_the_virtual_machine(tmp_path, monkeypatch):
    """BSCOMP_CACHE_DIR naming a file (a read-only or mistyped folder): the run is not refused, it stays in the
    virtual machine with the same numbers."""
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(blocker))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 0.0)
    cm = CompiledModel(_friction_backlash_drive(), ["amp.u"], OUTS)
    (y1, n1), (y2, n2) = _run(cm), _run(cm)
    assert not n1 and not n2 and all(np.array_equal(y1[o], y2[o]) for o in OUTS)


@needs_cc
def test_a_chain_where_the_slp_vectorizer_fused_products_is_compiled_to_the_bit(tmp_path, monkeypatch):
    """benchmarks/fuzz_compiled.py's chain of seed 48 (two masses to a wall, a 53 um clearance of 3.1e7 N/m
    between them, asymmetric Coulomb friction on the second, a 24 Hz square wave of 174 N held per 0.1 ms). Built
    with ``-march=native`` on a CPU with FMA, GCC 12's straight-line vectorizer fused products in the sample's C
    despite ``-ffp-contract=off``: from sample 387 on the outputs left the virtual machine's by ~1e-13 of their
    scale (4 of 80 fuzz chains). ``native.CFLAGS`` turns that vectorizer off; compiled and VM agree to the bit."""
    from bscomp.components import Spring

    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 0.0)
    monkeypatch.setattr(compiled_hot, "BACKGROUND", False)
    s = _chain("fuzz_seed_48", (29.99078775645233, 25.933126980173498),
               [Spring(c=5997463.533932531), Backlash(b=5.323945613991864e-05, c=31242911.398465965, d=0.0, eps=0.0)],
               (536.4604826799202, 411.13167168375855),
               CoulombFriction(F_c_pos=154.57231873988755, F_c_neg=117.9457381521684, d_pos=8.551473272188803,
                               d_neg=47.533266371353065, v_reg=5.669733539059217e-05), at=1)
    t = np.round(np.arange(2001) * 1e-4, 12)
    u = 174.4761970366625 * np.sign(np.sin(2 * np.pi * 24.187745162844184 * t) + 1e-12)
    outs = ["m1.v", "m1.a"]
    monkeypatch.setenv("BSCOMP_NATIVE_STEPS", "0")
    vm = CompiledModel(s, ["F.f"], outs).simulate({}, t, {"F.f": u})
    monkeypatch.delenv("BSCOMP_NATIVE_STEPS")
    cm = CompiledModel(s, ["F.f"], outs)
    got = cm.simulate({}, t, {"F.f": u})
    assert cm.stats["native_steps"]
    for o in outs:
        assert np.array_equal(vm[o], got[o]), (o, np.flatnonzero(vm[o] != got[o])[:3])
