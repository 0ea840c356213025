"""diagnose() on synthetic data with a hidden effect (the acceptance of issue 8, item 6).

The generator builds truth = validation_drive + hidden effect + mis-set table mass and coupling
stiffness, and hands only the data and the nominal system to diagnose(). For each hidden effect: it ranks
first, alone (no other candidate fits the data as well: Vuong's z against the runner-up is significant),
and is accepted; its fitted parameter is within 2 % of the truth; the error (after re-calibration) falls
by >= 80 % (>= 50 % for backlash) to the noise floor (every dataset within 1 + noise_tolerance), and
nothing is accepted on top. A no-effect control is explained within its noise floor by re-calibration
alone; a two-effect case finds both.

The truths are built from the candidates themselves, so the right candidate at the right values must
fit to the noise floor: on the joint case the exact truth model scores chi^2 0.85 (FRF) / 0.96 (time
series), tests/bscomp/validate/test_noise.py. With one noise level per FRF block (before the coherence
entered the noise model) it scored 41.6 on the FRF, every case ended at 21 to 25, and the joint and a
bearing housing looked alike (Vuong z 0.29): the anti-resonances' noise drowned what tells them apart.
Each case runs diagnose once (module fixture) and several tests read the result.
"""

import math

import numpy as np
import pytest

from bscomp.systems.validation_drive import validation_drive
from bscomp.validate.diagnostics import Diagnosis, diagnose
from bscomp.validate.synthetic import TRUTH_VALUES, generate

CASES = {
    "joint": ({"nut_table_joint": {}}, "nut_table_joint", "k", 0.80),
    "friction": ({"guideway_friction": {}}, "guideway_friction", "F_c", 0.80),
    "backlash": ({"screw_nut_backlash": {}}, "screw_nut_backlash", "b", 0.50),
    "delay": ({"amplifier_delay": {}}, "amplifier_delay", "T", 0.80),
}

NOISE_TOLERANCE = 0.5           # diagnose's default: "within noise" is chi^2 < 1 + 0.5 in every dataset

_cache = {}


def run_case(key, hidden, seed=3):
    if key not in _cache:
        data = generate(hidden=hidden, seed=seed)
        _cache[key] = (data, diagnose(validation_drive(), data.datasets, max_effects=2))
    return _cache[key]


def _recalibrated_error(diag: Diagnosis) -> float:
    return dict(diag.staircase)["re-calibrated"]


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_hidden_effect_is_found(case):
    hidden, name, pname, min_drop = CASES[case]
    _, diag = run_case(case, hidden)
    # it ranks first in round 1 and is the accepted effect; alone, but for the joint: a light bearing housing with a
    # fitted fastener damping is the same damped spring in series (test_joint_and_a_light_damped_housing_are_one_group)
    for r in (diag.ranked[0], diag.accepted[0] if diag.accepted else None):
        assert r is not None and r.name == name, diag.table()
        assert set(r.group_names) == {name} | ({"bearing_housing"} if case == "joint" else set()), diag.table()
    # the runner-up outside its group is told apart: the data prefer the hidden effect (Vuong z > 1.96)
    runner = next(r for r in diag.ranked[1:] if r.refined and r.name not in diag.ranked[0].group_names)
    assert diag.ranked[0].compared[runner.name]["z"] > 1.96, diag.table()
    # the hidden effect's fitted parameter within 2 % of the truth (the truth is the candidate itself)
    fit = diag.accepted[0]
    truth = TRUTH_VALUES[name][pname]
    assert abs(fit.values[pname] / truth - 1) < 0.02, (fit.values, truth, diag.table())
    # an uncertainty is reported and is finite
    assert np.isfinite(fit.std[pname]) and fit.std[pname] > 0
    # error falls by the required fraction relative to the re-calibrated model, to the noise floor
    final = diag.staircase[-1][1]
    assert 1 - final / _recalibrated_error(diag) >= min_drop, diag.table()
    assert final < 1 + NOISE_TOLERANCE, diag.table()
    # nothing spurious on top
    assert len(diag.accepted) == 1, diag.table()


@pytest.mark.slow
def test_no_effect_control_claims_nothing():
    _, diag = run_case("none", {})
    assert not diag.accepted, diag.table()
    # explained within the noise floor by re-calibration alone (not: no candidate removed enough)
    assert diag.message == "no missing effect found: the model explains every dataset within its noise floor"
    assert _recalibrated_error(diag) < 1 + NOISE_TOLERANCE, diag.table()
    # the mis-set parameters are recovered by re-calibration alone
    assert abs(diag.recalibrated["table.m"][0] / (250.0 * 1.06) - 1) < 0.01
    assert abs(diag.recalibrated["coupling.c"][0] / (3938.0 * 0.93) - 1) < 0.01


@pytest.mark.slow
def test_two_effects_found_one_after_another(monkeypatch):
    """Two effects, one per round, to the noise floor. And the polish after the round-2 acceptance (every accepted
    effect and the uncertain parameters re-fitted together) starts where the round's joint fit left them (the effect
    accepted in round 1 moved in it), so it ends no worse than that fit. Started from the round-1 values instead,
    the polish of a rattling clearance's round-2 fit (1.26) ended at 101 on an FE truth
    (`benchmarks/diagnose_table.py --case backlash --seed 2202`, 130 s; docs/validation.md "The housing truth"); on
    this lumped case both starts end at the same point, so this checks the invariant, not that case."""
    import bscomp.validate.acceptance as acceptance

    verdicts, real = [], acceptance.verdict

    def logged(before, after, *args, **kwargs):
        out = real(before, after, *args, **kwargs)
        verdicts.append((after["error"], out[0]))
        return out

    monkeypatch.setattr(acceptance, "verdict", logged)
    _cache.pop("two", None)                       # diagnosed here, with the verdicts logged
    _, diag = run_case("two", {"nut_table_joint": {}, "guideway_friction": {}})
    round2 = [e for e, ok in verdicts if ok][-1]
    assert diag.staircase[-1][1] <= round2 * (1 + 1e-9), (diag.staircase, round2)
    assert {a.name for a in diag.accepted} == {"nut_table_joint", "guideway_friction"}, diag.table()
    assert all(a.group_names == (a.name,) for a in diag.accepted), diag.table()
    errs = [e for _, e in diag.staircase]
    assert all(b < a for a, b in zip(errs[1:], errs[2:])), diag.staircase  # a staircase down
    assert errs[-1] < 1 + NOISE_TOLERANCE, diag.table()
    joint = next(a for a in diag.accepted if a.name == "nut_table_joint")
    fric = next(a for a in diag.accepted if a.name == "guideway_friction")
    assert abs(joint.values["k"] / TRUTH_VALUES["nut_table_joint"]["k"] - 1) < 0.02
    assert abs(fric.values["F_c"] / TRUTH_VALUES["guideway_friction"]["F_c"] - 1) < 0.02


@pytest.mark.slow
def test_diagnosis_apply_code_json_plot(tmp_path):
    data, diag = run_case("friction", CASES["friction"][0])
    updated = diag.apply(validation_drive())
    assert "friction" in dict(updated.leaves())
    assert abs(updated.get("friction.F_c_pos") / 2066.0 - 1) < 0.15
    code = diag.code()
    assert "CoulombFriction" in code and 's.set("table.m"' in code
    # the lines are valid Python that rebuild the same change on a fresh nominal system
    from bscomp.components import Damper, Mass, Spring  # noqa: F401  (names the code may use)

    s = validation_drive()
    exec(compile(code, "<diagnosis>", "exec"), {"s": s, "Spring": Spring, "Damper": Damper, "Mass": Mass})
    assert abs(s.get("friction.F_c_pos") / updated.get("friction.F_c_pos") - 1) < 1e-5  # 6 significant digits
    import json

    d = json.loads(diag.to_json())
    assert d["accepted"][0]["candidate"] == "guideway_friction"
    paths = diag.plot(tmp_path)
    assert all(p.exists() and p.stat().st_size > 1000 for p in paths)
    assert "guideway_friction" in diag.table()


@pytest.mark.slow
def test_joint_and_a_light_damped_housing_are_one_group():
    """On 3 coordinates a housing at the screw support whose fastener damping is fitted (bearing_housing's zeta)
    stands in for the nut-table joint as a ~1 kg body (its own mode above 2.5 kHz, out of sight) on the joint's
    spring with the joint's damping: a damped spring in series either way, the same error within noise (D < 15.4,
    the improvements 100 % shared). The two are one group, the joint named first (lower BIC: the same fit with two
    parameters instead of three) and accepted, the words say which relative motion tells them apart. (With the
    housing's damping held at 5 % the housing could not take the joint's damping and was told apart, Vuong z
    significant -- a constraint of the candidate, not of the data.) The JSON keeps the numbers."""
    import json

    _, diag = run_case("joint", CASES["joint"][0])
    first, housing = diag.ranked[0], next(r for r in diag.ranked if r.name == "bearing_housing")
    assert first.name == "nut_table_joint" and housing.refined and diag.accepted[0].name == "nut_table_joint"
    assert "bearing_housing" in first.equivalent and first.delta_bic < housing.delta_bic, diag.table()
    st = first.compared["bearing_housing"]
    assert st["shared"] > 0.99 and abs(st["z"]) < 1.96 and st["indistinguishable"], st
    h, j = housing.values, first.values
    assert h["m"] < 2.0 and math.sqrt(h["k"] / h["m"]) / (2 * math.pi) > 2500.0, h
    assert abs(h["k"] / j["k"] - 1) < 0.01 and abs(2 * h["zeta"] * math.sqrt(h["k"] * h["m"]) / j["d"] - 1) < 0.05
    assert "lead.flange_b - axial.flange_a" in first.equivalent["bearing_housing"]["tell_apart"]
    assert "indistinguishable" in diag.table() and "~ bearing_housing" in diag.message
    d = json.loads(diag.to_json())
    assert d["ranked"][0]["compared"]["bearing_housing"]["z"] == pytest.approx(st["z"])


@pytest.mark.slow
@pytest.mark.parametrize("eps, seed", [(1e-12, 3), (1e-11, 4), (1e-11, 5)])
def test_joint_case_does_not_turn_on_round_off(monkeypatch, eps, seed):
    """An earlier knife edge: the compiled time series' modal basis changed by ~1e-13 and the joint case
    named bearing_housing first. Here the basis is perturbed on purpose (T -> T (I + eps R), the block form
    recomputed: outputs off by ~eps); with one noise level per FRF block and without the refinement's
    restart these three named bearing_housing first (nut_table_joint stalled with d on its 1 N s/m bound).
    The diagnosis must not change: same effect named first and accepted, same fit (the runner-up's error too)."""
    from bscomp.simulation import compiled_time

    real = compiled_time.real_modal_form

    def perturbed(A, *args, **kwargs):
        form = real(A, *args, **kwargs)
        if form is None:
            return None
        T, _, _, blocks = form
        T = T @ (np.eye(T.shape[0]) + eps * np.random.default_rng(seed).standard_normal(T.shape))
        Tinv = np.linalg.inv(T)
        return T, (Tinv @ A @ T) * compiled_time._block_mask(blocks), Tinv, blocks

    data, ref = run_case("joint", CASES["joint"][0])
    monkeypatch.setattr(compiled_time, "real_modal_form", perturbed)
    diag = diagnose(validation_drive(), data.datasets, max_effects=1)
    assert diag.ranked[0].name == "nut_table_joint" and diag.accepted, diag.table()
    assert diag.accepted[0].name == ref.accepted[0].name, diag.table()
    for i, r in enumerate(diag.ranked[:2]):
        r0 = next(q for q in ref.ranked if q.name == r.name)
        assert abs(r.error_after / r0.error_after - 1) < 1e-4, (r.name, r.error_after, r0.error_after)
        if i == 0:   # the housing in the joint's group (a ~1 kg mass out of sight) has a flat valley: its values move
            assert all(abs(r.values[p] / r0.values[p] - 1) < 1e-3 for p in r.values), (r.values, r0.values)


def test_a_value_left_at_its_bound_is_marked_in_the_report():
    """The demo's friction d ended at 1.011 N s/m on its lower bound 1 (F_c and d v trade at one sliding speed;
    with the friction candidates' v_reg 5e-4 m/s of before): the report says so instead of printing a
    measurement."""
    from types import SimpleNamespace

    from bscomp.validate.candidates.base import CandidateParameter
    from bscomp.validate.diagnosis import _bound_note

    fit = SimpleNamespace(candidate=SimpleNamespace(parameters=[
        CandidateParameter("F_c", "N", 10.0, 1e5, 1000.0, 1.5, "Coulomb level"),
        CandidateParameter("d", "N.s/m", 1.0, 1e5, 1000.0, 1.5, "added viscous coefficient")]))
    assert _bound_note(fit, "d", 1.011) == " (at its lower bound)"
    assert _bound_note(fit, "d", 0.99e5) == " (at its upper bound)"
    assert _bound_note(fit, "F_c", 2480.0) == ""
    assert _bound_note(fit, "other", 1.0) == ""


def test_a_fit_time_series_whose_newton_did_not_converge_is_counted_and_reported(recwarn):
    """A fit's time series whose Newton on the element forces did not converge at FIT_MAX_SUB sub-steps per sample
    is counted on its evaluator instead of warning at every evaluation (seen: two of 149 evaluations of the backlash
    candidate beside friction at v_reg 1e-4 m/s); any other warning passes; the diagnosis lists the counts."""
    import warnings
    from types import SimpleNamespace

    from bscomp.errors import ModelLimitationWarning
    from bscomp.validate.evaluation import FIT_MAX_SUB, Evaluator

    calls = []

    def simulate(params, t, inputs, outputs, delay, mm, n_sub, max_sub, warn):
        calls.append((max_sub, warn))
        if warn and not params["ok"]:
            warnings.warn("CompiledModel.simulate: the Newton on the forces of ['b'] did not converge",
                          ModelLimitationWarning, stacklevel=2)
        warnings.warn("another limitation", ModelLimitationWarning, stacklevel=2)
        cm.stats["newton_converged"] = params["ok"]
        return {"y": np.zeros(3)}

    cm = SimpleNamespace(simulate=simulate, stats={}, elements=[1])
    ev = Evaluator.__new__(Evaluator)
    ev.n_sub, ev.unconverged = 2, 0
    for ok in (False, True, False):
        ev._simulate(cm, {"ok": ok}, np.arange(3.0), {}, ["y"], 0.0, None)
    assert ev.unconverged == 2 and calls == [(FIT_MAX_SUB, False)] * 3
    msgs = [str(w.message) for w in recwarn.list]
    assert msgs and set(msgs) == {"another limitation"}, msgs      # (repeats from one place may be merged)
    d = Diagnosis(system=None, uncertain=[], recalibrated={}, ranked=[], accepted=[], rounds=[], staircase=[],
                  message="m", stats={"unconverged": {"guideway_friction + screw_nut_backlash": [2, 149]}})
    assert (f"did not converge at {FIT_MAX_SUB} sub-steps" in d.table()
            and "guideway_friction + screw_nut_backlash: 2 of 149 evaluations" in d.table()), d.table()




def test_updated_builds_at_each_condition_with_the_changes_found():
    """``Diagnosis.updated(model)``: the model built with a dataset's build keywords, then the re-calibrated values
    and the accepted effects -- what compare needs to see the error after the effects at every measured condition
    (a built System is compared at one; its plain conditions are dropped with a warning)."""
    from bscomp.model import build_keywords
    from bscomp.validate.candidates import GuidewayFriction
    from bscomp.validate.diagnosis import Diagnosis, EffectFit

    fit = EffectFit(GuidewayFriction(), {"F_c": 321.0, "d": 12.0}, {}, 50.0, 1.1, -9.0, accepted=True)
    diag = Diagnosis(system=None, uncertain=["coupling.c"], recalibrated={"coupling.c": (4321.0, 5.0)}, ranked=[fit],
                     accepted=[fit], rounds=[[fit]], staircase=[], message="1 found")
    build = diag.updated("validation_drive")
    assert build_keywords(build) == build_keywords("validation_drive") == {"k_axial"}
    s = build(k_axial=1.23e8)
    assert s.name == "validation_drive + guideway_friction"
    assert s.get("axial.c") == 1.23e8 and s.get("coupling.c") == 4321.0
    friction = [path for path, comp in s.leaves() if type(comp).__name__ == "CoulombFriction"]
    assert len(friction) == 1 and s.get(f"{friction[0]}.F_c_pos") == 321.0


def _friction_truth(where: str):
    """validation_drive with a friction the candidates do not make (an arc-tangent law): a torque on the screw --
    across the coupling from the rotor, where the candidate puts it -- or a force on the table at the guideways."""
    from bscomp.components import Fixed, FixedRotational
    from bscomp.systems.truth_effects import AtanFriction, AtanTorqueFriction

    truth = validation_drive()
    if where == "screw":
        truth.add("frame", FixedRotational())
        truth.add("bearing_friction", AtanTorqueFriction(T_c=0.4, w_s=2e-2, d=1e-3))
        truth.connect("frame.flange", "bearing_friction.flange_a")
        truth.connect("bearing_friction.flange_b", "screw.flange_b")
    else:
        truth.add("g2", Fixed())
        truth.add("guide_friction", AtanFriction(F_c=1500.0, v_s=4e-5, d=500.0))
        truth.connect("g2.flange", "guide_friction.flange_a")
        truth.connect("guide_friction.flange_b", "table.flange_b")
    return truth


def test_a_synthetic_frf_of_a_drive_with_friction_is_of_its_small_signal_equivalent():
    """``generate`` on a nominal that has a friction of its own models the FRF as compare and diagnose do (the
    viscous part): the same numbers as from ``linear_equivalent()``; before, the friction's tangent at rest (stuck:
    ``(2/pi) T_c / w_s`` = 12.7 N m s/rad on the screw) put the FRF 0.78 decades off."""
    truth = _friction_truth("screw")
    a, b = generate(hidden={}, seed=5, nominal=truth), generate(hidden={}, seed=5, nominal=truth.linear_equivalent())
    for pair in a.frf.H:
        np.testing.assert_array_equal(a.frf.H[pair], b.frf.H[pair])
    assert not np.allclose(a.time.outputs["rotor.w"], b.time.outputs["rotor.w"])      # the time series keep it


@pytest.mark.slow
@pytest.mark.parametrize("where, name, pname, value", [("screw", "rotor_friction", "T_c", 0.4),
                                                         ("table", "guideway_friction", "F_c", 1500.0)])
def test_the_friction_torque_tells_the_bearings_from_the_guideways(where, name, pname, value):
    """With ``rotor_friction`` among the defaults (optional until 2026-12-07), friction on the screw's bearing is named
    a torque at the motor and friction at the guideways a force on the table -- each truth an arc-tangent law the
    candidates' tanh is not, the torque across the coupling from where the candidate puts it. Measured: screw 0.4 N m ->
    T_c 0.394 (chi^2 2.85, the guideway candidates 37); table 1500 N -> F_c 1493 (1.85, the torque 793)."""
    data = generate(hidden={}, seed=5, nominal=_friction_truth(where))
    diag = diagnose(validation_drive(), data.datasets, max_effects=1)
    assert [a.name for a in diag.accepted] == [name], diag.table()
    assert diag.accepted[0].values[pname] == pytest.approx(value, rel=0.03)
    other = next(r for r in diag.ranked if r.refined and r.name != name and "stribeck" not in r.name)
    assert other.error_after > 10 * diag.accepted[0].error_after     # the other place fits 10x worse or more
