"""diagnose() on the FE test bed with data the candidates did not make (issue 13, point 6).

The bundled measurements (``systems/data/truths``, made by ``bscomp.systems.truths``) come from truth
systems with another FE mesh (section C 30 elements against the model's 39), the moving nut, mis-set
uncertain parameters, hidden effects of their own structure (a table part taken out of the table on its
own spring and dashpot; atan-smoothed friction with its own viscous term; a soft-contact clearance with
softplus corners; an exact delay; a thrust-bearing housing of two bodies on two springs) drawn at random, and
noise (2 % complex FRF; 2e-4 rad, 0.01 rad/s, 3e-7 m, 0.05 m/s^2). The nominal model is the registered
``testbed_axial_torsional``, built at each file's nut position. For each effect: named first, its main
parameter within 15 %, the error (after re-calibration) down by 80 % (backlash 50 %); the control claims
nothing; joint + friction finds both; a torque ripple, which no candidate has, is called an effect outside the
candidates, with its order.
"""

import json
from importlib import resources

import drawn_truths  # this folder's: the truths drawn anew, read from data/truths
import numpy as np
import pytest

from bscomp.validate.diagnostics import diagnose
from bscomp.validate.measurements import load_all

pytestmark = pytest.mark.slow

_cache = {}

#: (case, candidate groups accepted (any order), least error drop after re-calibration)
CASES = [
    ("joint", {"table_mode"}, 0.80),
    ("friction", {"guideway_friction"}, 0.80),
    ("delay", {"delay"}, 0.80),
    ("housing", {"bearing_housing"}, 0.80),
    # backlash ({"backlash"}, 0.50): checked in test_backlash_truth_is_explained_to_the_noise_floor on the same run
    # (one diagnose, ~45 s, whichever pytest-xdist worker takes it)
    # joint + friction: the same diagnose call as `bscomp demo`; its assertions (groups, named first, values,
    # error drop, evidence) run in tests/bscomp/test_cli.py::test_demo_tells_the_story_on_the_fe_test_bed
]


def _case(model, case):
    key = (model, case)
    if key not in _cache:
        *data, truth = _read(resources.files("bscomp.systems") / "data" / "truths" / model / case)
        name = {"axial_torsional": "testbed_axial_torsional", "full": "testbed"}[model]
        _cache[key] = (truth, diagnose(name, data, max_effects=2))
    return _cache[key]


def _drawn(case, seed):
    """(FrfData, TimeData, truth info) of a truth drawn anew, from the files ``drawn_truths.py`` wrote with the
    truths' generator (their time series are 12-47 s of IDAS each)."""
    return _read(drawn_truths.HERE / str(seed) / "axial_torsional" / case)


def _read(root):
    """(FrfData, TimeData, truth info) of a truth's folder (``frf.csv``, ``time.csv``, ``truth.json``)."""
    frf, run = load_all([str(root / "frf.csv"), str(root / "time.csv")])
    return frf, run, json.loads((root / "truth.json").read_text())


def test_the_drawn_truths_are_the_generators():
    """Each drawn truth's FRF file is what the generator draws today (to the CSV's digits), and its truth.json
    names the seed and the hidden effect the tests check against."""
    from bscomp.systems.truths import make_frf

    for case, seed, kw in drawn_truths.TRUTHS:
        frf, _run, info = _drawn(case, seed)
        again, info2 = make_frf(case, "axial_torsional", seed, freqs=kw.get("freqs"))
        assert info["seed"] == seed and info["hidden"] == json.loads(json.dumps(info2["hidden"])), (case, seed)
        for pq, h in again.H.items():
            assert np.allclose(frf.H[pq], h, rtol=1e-6, atol=0), (case, seed, pq)   # 2 % noise; CSV digits
        assert np.allclose(frf.freqs, again.freqs, rtol=1e-12)


def _check_values(acc, hidden):
    """The accepted effect's main parameters against the truth's (within 15 %)."""
    name, v = acc.name, acc.values
    if name == "table_subassembly":
        assert abs(v["m"] / hidden["joint"]["m"] - 1) < 0.15, (v, hidden["joint"])
        assert abs(v["k"] / hidden["joint"]["k"] - 1) < 0.15, (v, hidden["joint"])
    elif name in ("guideway_friction", "guideway_stribeck"):
        assert abs(v["F_c"] / hidden["friction"]["F_c"] - 1) < 0.15, (v, hidden["friction"])
    elif name in ("screw_nut_backlash", "compliant_backlash"):
        assert abs(v["b"] / hidden["backlash"]["b"] - 1) < 0.15, (v, hidden["backlash"])
    elif name == "bearing_housing":
        assert abs(v["m"] / hidden["housing"]["m"] - 1) < 0.15, (v, hidden["housing"])
        assert abs(v["k"] / hidden["housing"]["k"] - 1) < 0.15, (v, hidden["housing"])
    elif name == "amplifier_delay":
        assert abs(v["T"] / hidden["delay"]["T"] - 1) < 0.15, (v, hidden["delay"])
    else:
        raise AssertionError(f"unexpected effect {name}")


def _recalibrated(diag):
    return dict(diag.staircase)["re-calibrated"]


@pytest.mark.parametrize("case, groups, min_drop", CASES)
def test_hidden_effect_found_on_the_axial_torsional_fe_bed(case, groups, min_drop):
    truth, diag = _case("axial_torsional", case)
    if case == "joint":      # the report's user errors and skips, on the same run (a diagnose costs ~40 s)
        _check_report_carries_user_errors_and_skips(diag)
    _check_found(truth, diag, groups, min_drop)


def _check_found(truth, diag, groups, min_drop):
    """The hidden effect named first, alone, its values within 15 %, the error down by ``min_drop``, evidence said."""
    assert {a.candidate.group for a in diag.accepted} == groups, diag.table()
    assert diag.ranked[0].candidate.group in groups, diag.table()           # named first
    # ... alone: on the FE bed the data tell it from every other candidate (bscomp.validate.equivalence);
    # a mate could only be of its own kind (Coulomb ~ Stribeck friction)
    by_name = {r.name: r for r in diag.ranked}
    assert {by_name[n].candidate.group for n in diag.ranked[0].group_names} <= groups, diag.table()
    for a in diag.accepted:
        assert {by_name[n].candidate.group for n in a.group_names if n in by_name} <= groups, diag.table()
    for a in diag.accepted:
        _check_values(a, truth["hidden"])
    final = diag.staircase[-1][1]
    assert 1 - final / _recalibrated(diag) >= min_drop, diag.table()
    assert all(a.evidence and "held-out" in a.evidence for a in diag.accepted)  # says why it is believed


def test_backlash_truth_is_explained_to_the_noise_floor():
    """The soft-contact clearance truth (softplus corners, 1.12e9 N/m, centred) against the compliant backlash
    (gaussian corners): the time series' evaluator cuts the contact out of its linear part and keeps the modes up to
    the contact's band (10.8 kHz here) dynamic, so the fit reaches the noise floor with the truth's stiffness and a
    centred start -- with the contact in the linear part and 6 kHz it stopped at 1.62, k -16 %, and round 2 fitted a
    motor inertia that only traded off against table.m (docs/validation.md "Engine"). Nothing is left for a round 2."""
    truth, diag = _case("axial_torsional", "backlash")
    _check_found(truth, diag, {"backlash"}, 0.50)
    assert [a.name for a in diag.accepted] == ["compliant_backlash"], diag.table()
    v, hidden = diag.accepted[0].values, truth["hidden"]["backlash"]
    assert abs(v["k"] / hidden["c"] - 1) < 0.1 and abs(v["x0"] - 1.0) < 0.05, (v, hidden)
    assert diag.staircase[-1][1] < 1.5 and not diag.rounds[1:], diag.table()
    assert all(a.own_share is None or a.own_share > 0.3 for a in diag.accepted)   # it does things of its own


def test_control_claims_nothing_and_recalibrates():
    truth, diag = _case("axial_torsional", "control")
    assert not diag.accepted, diag.table()
    assert "no missing effect found" in diag.message
    assert abs(diag.recalibrated["table.m"][0] / truth["misset"]["table.m"]["truth"] - 1) < 0.03
    # the candidates that do not apply to this drive are listed with their reason
    assert any("re-calibrated instead" in s.reason for s in diag.skipped)


@pytest.mark.parametrize("seed", [2201, 2203])
def test_a_table_part_drawn_anew_is_found_with_its_damping(seed):
    """Truths drawn anew (not bundled data sets) measured by their FRF alone. Seed 2201: a 48 kg part at 80.5 MN/m
    damped at 3.17 % of critical, on the 45-element mesh -- with the damping ratio held at the prior's 5 % the same
    data gave m +9.6 %, k +8.7 % and 2.9x the noise floor (FRF and time series). Seed 2203: a 38 kg part whose mode
    (205 Hz) fell between the points of the 5 x 5 screening grid -- nothing was accepted and the nut-table joint was
    named first; the screen along the part's frequency finds it (docs/validation.md "Other draws of the truths").
    Mass, stiffness and damping ratio within 2 % / 2 % / 5 % of the truth's, at the noise floor."""
    err = _relative_errors("joint", seed, "table_subassembly")
    assert err["m"] < 0.02 and err["k"] < 0.02 and err["zeta"] < 0.05 and err["chi2"] < 1.5, err


def test_a_compliant_bearing_housing_is_found_with_its_damping():
    """A truth drawn anew (seed 2202, FRF alone): the thrust bearing's housing on its fasteners, two bodies (a 6.6 kg
    seat on a 10.5 GN/m seat spring, a 52 kg block) and two springs (fasteners 506 MN/m), a mode at 541 Hz damped at
    4.2 %. Before the housing's coordinate was held out of the drive's modal damping and its damping ratio fitted,
    the housing was named with m -26 %, k -28 % and 47x the noise floor left; with the ratio fitted alone the extra
    mode stayed over-damped by the drive's modal rule and a table sub-assembly (141 kg) was accepted instead, 148x
    (docs/validation.md "The housing truth"). Mass and fastener stiffness within 3 %, the ratio within 10 %, at the
    noise floor."""
    err = _relative_errors("housing", 2202, "bearing_housing")
    assert err["m"] < 0.03 and err["k"] < 0.03 and err["zeta"] < 0.10 and err["chi2"] < 1.5, err


def test_a_local_loss_is_found_where_it_is_not_passed_off_as_a_housing():
    """The bundled damping truth (FRF alone): two viscous dashpots the model lacks (b1 axial, across the coupling; the
    drive's first two modes 8.3 % / 14.8 % damped against the model's 6 % / 10 %). Before the local-loss candidates a
    bearing housing at 54 % of critical was accepted (14x the noise floor left): a dashpot on its fasteners is a loss
    at the bearing; `extra_damping` (one ratio on every mode) damps the FE modes above 400 Hz that the truth leaves
    alone. Now both dashpots are named, each within 3 % of the truth's, at the noise floor (docs/validation.md,
    "The damping truth")."""
    from bscomp.systems.truths import make_frf

    data, info = make_frf("damping", "axial_torsional", freqs=np.geomspace(2.0, 1000.0, 120))   # 120 of its 300 points
    diag = diagnose("testbed_axial_torsional", [data], max_effects=2)
    assert [a.name for a in diag.accepted] == ["support_damping", "coupling_damping"], diag.table()
    h = info["hidden"]["damping"]
    c, d = diag.accepted[0].values["c"], diag.accepted[1].values["d"]
    assert abs(c / h["c_axial"] - 1) < 0.03 and abs(d / h["d_torsion"] - 1) < 0.03, (c, d, h)
    assert diag.staircase[-1][1] < 1.5, diag.staircase


def test_two_losses_neither_of_which_passes_alone_are_found_together():
    """The damping truth drawn with seed 2203 (another mesh, the moving nut, mis-set parameters, noise), its FRF on 120
    points and its 0.6 s square wave sampled at 2 kHz: each dashpot alone stands in for both and fails a rule -- the
    coupling's the held-out rule (5.4 -> 4.9, 12 % of the excess, while the record's fitted half lost more: not carried
    over, ``acceptance.CARRIED``), the bearing's makes the time record's fitted half worse (3.86 -> 4.4) -- so one
    effect at a time found nothing (108x the noise floor left on the full data, docs/validation.md). Fitted together
    (bscomp.validate.pairs) both are named, each within 3 % of the truth's, each needed beside the other, and the
    error reaches the noise floor."""
    frf, run, info = _drawn("damping", 2203)
    diag = diagnose("testbed_axial_torsional", [frf, run], max_effects=2)
    singles = [r for r in diag.rounds[0] if r.name in ("coupling_damping", "support_damping")]
    assert len(singles) == 2 and all(r.refined and not r.accepted for r in singles), diag.table()
    why = {r.name: r.verdict for r in singles}
    assert "not confirmed on held-out data" in why["coupling_damping"], why
    assert "dataset 2 worse" in why["support_damping"], why
    assert sorted(a.name for a in diag.accepted) == ["coupling_damping", "support_damping"], diag.table()
    assert {a.together for a in diag.accepted} == {"coupling_damping", "support_damping"}
    fit = {a.name: a.values for a in diag.accepted}
    h = info["hidden"]["damping"]
    assert abs(fit["support_damping"]["c"] / h["c_axial"] - 1) < 0.03, (fit, h)
    assert abs(fit["coupling_damping"]["d"] / h["d_torsion"] - 1) < 0.03, (fit, h)
    assert diag.staircase[-1][1] < 1.5 and diag.staircase[-1][0] == "+ coupling_damping + support_damping"
    assert [p["accepted"] for p in diag.pairs].count(True) == 1 and "found together" in diag.message
    assert diag.code().count("; found together with") == 2 and 's.set("coupling.d",' in diag.code()


def test_a_clearance_is_refit_from_its_screening_point_when_its_fit_ends_at_a_bound():
    """The backlash truth drawn with seed 2231: a 10.4 um clearance on a 2.7e9 N/m contact. Screened at b 11.4 um
    and the FRFs' contact stiffness, the compliant backlash's candidate-alone fit (the uncertain parameters held)
    traded the stiffness for the gap, and the joint fit ended at b 21.9 um with k at its 1e11 N/m bound: rejected as
    a stand-in, 16x the noise floor left, nothing found. Started from its screening point the joint fit ends at
    the truth (bscomp.validate.refinement._refine_from); measured b +4.9 %, k +5.9 %, the error 120 -> 1.18 with
    every default candidate (docs/validation.md, "Seeds 2231 and 2331"). Here the candidate alone."""
    from bscomp.validate.candidates.nonlinear import CompliantBacklash

    frf, run, info = _drawn("backlash", 2231)
    diag = diagnose("testbed_axial_torsional", [frf, run], max_effects=1, candidates=[CompliantBacklash()])
    assert [a.name for a in diag.accepted] == ["compliant_backlash"], diag.table()
    v, h = diag.accepted[0].values, info["hidden"]["backlash"]
    assert abs(v["b"] / h["b"] - 1) < 0.10 and abs(v["k"] / h["c"] - 1) < 0.15, (v, h)
    assert diag.staircase[-1][1] < 1.5, diag.staircase


def test_a_heavy_table_part_beside_friction_is_found_with_a_linear_partner():
    """The joint + friction truth drawn with seed 2213: a 52.3 kg part on a 37.5 MN/m joint beside 1414 N of
    guideway friction. The friction alone takes the error 4.1e7 -> 327 but the motor FRF's phase error 4.4 -> 8.9 deg
    (the re-calibration had bought the FRFs with what the part does: table.m at its 300 kg bound), so it is refused;
    the part, screened on time series the friction swamps, was never refined, and the pairs of the three nonlinear
    members (two guideway laws, the friction torque) could not hold it: nothing was found. The linear partner
    (bscomp.validate.pairs.linear_partner: the linear candidates screened on the FRFs on top of the friction's fit)
    is the part; the two fitted together are named, each parameter within 1 % (the part's damping ratio 5 %), at the
    noise floor (docs/validation.md)."""
    frf, run, info = _drawn("joint_friction", 2213)
    diag = diagnose("testbed_axial_torsional", [frf, run], max_effects=2)
    assert not any(r.accepted for r in diag.rounds[0]), diag.table()
    assert "(clearly worse)" in next(r for r in diag.rounds[0] if r.name == "guideway_friction").verdict
    assert sorted(a.name for a in diag.accepted) == ["guideway_friction", "table_subassembly"], diag.table()
    assert {a.together for a in diag.accepted} == {"guideway_friction", "table_subassembly"}
    assert {a.name: a.partner for a in diag.accepted} == {"guideway_friction": False, "table_subassembly": True}
    assert "the first alone failed a rule" in diag.message, diag.message
    fit, h = {a.name: a.values for a in diag.accepted}, info["hidden"]
    assert abs(fit["guideway_friction"]["F_c"] / h["friction"]["F_c"] - 1) < 0.01, (fit, h)
    for p, tol in (("m", 0.01), ("k", 0.01), ("zeta", 0.05)):
        assert abs(fit["table_subassembly"][p] / h["joint"][p] - 1) < tol, (p, fit, h)
    assert diag.staircase[-1][1] < 1.5 and "found together" in diag.message, diag.staircase


def _relative_errors(case, seed, name):
    """diagnose on a truth's FRF alone; ``name`` must be the one accepted effect. Returns |fitted / truth - 1| of its
    m, k and zeta and the final error ``chi2`` (1 = the noise floor)."""
    from bscomp.systems.truths import make_frf

    data, info = make_frf(case, "axial_torsional", seed)
    diag = diagnose("testbed_axial_torsional", [data], max_effects=1)
    assert [a.name for a in diag.accepted] == [name], diag.table()
    v, hidden = diag.accepted[0].values, info["hidden"][case]
    return {**{p: abs(v[p] / hidden[p] - 1) for p in ("m", "k", "zeta")}, "chi2": diag.staircase[-1][1]}


def _check_report_carries_user_errors_and_skips(diag):
    """The report of the joint case: the user's errors per step (magnitude fell), and the untried."""
    d = diag.to_dict()
    labels = [lbl for lbl, _ in d["user_errors"]]
    assert labels[0] == "nominal" and labels[-1].startswith("+ ")
    last = d["user_errors"][-1][1]["per_dataset"]
    first = d["user_errors"][1][1]["per_dataset"]                              # re-calibrated
    mag = [r["mag_mean_abs_dlog10"] for r in last[0]["frf"]]
    mag0 = [r["mag_mean_abs_dlog10"] for r in first[0]["frf"]]
    assert max(mag) < max(mag0)                                               # the user's error fell too
    assert "not tried" in diag.table()


def test_an_effect_outside_the_candidates_is_called_missing_with_its_order(tmp_path):
    """The ripple truth (a 2.9 % motor torque ripple, 12 per revolution; bscomp.systems.truths): nothing accepted,
    the error left far above the noise floor (273x), the message says an effect outside the candidates is missing
    and names the order (bscomp.validate.periodicity); the re-calibrated table mass absorbed part of it (-11 %),
    which the message warns of, and the FRFs alone put it and the coupling stiffness within 0.5 % of the truth's
    (measured: +0.0 %, -0.1 %)."""
    from bscomp.validate.conclusion import UNEXPLAINED

    truth, d = _case("axial_torsional", "ripple")
    assert not d.accepted, d.table()
    assert d.remainder["error"] > 50 * UNEXPLAINED and not d.remainder["within_noise"]
    assert d.message.startswith("an effect outside the candidates is missing"), d.message
    assert [(o.channel, o.order) for o in d.remainder["orders"]] == [("table.a", truth["hidden"]["ripple"]["p"])]
    assert "12 periods per revolution" in d.message and "do not trust them" in d.message
    assert json.loads(d.to_json())["remainder"]["orders"][0]["order"] == 12
    assert "left in the residual, periodic in the motor angle" in d.table()
    for k in ("table.m", "coupling.k_T"):
        assert d.remainder["frf_values"][k] == pytest.approx(truth["misset"][k]["truth"], rel=5e-3)
    assert d.recalibrated["table.m"][0] < 0.92 * truth["misset"]["table.m"]["truth"]
    assert [p.name for p in d.plot(tmp_path)] == ["error_staircase.png", "candidates.png", "orders.png"]
