"""diagnose() on synthetic data with a hidden effect (the acceptance of issue 8, item 6).

The generator builds truth = validation_drive + hidden effect + mis-set table mass and coupling
stiffness, and hands only the data and the nominal system to diagnose(). For each hidden effect: its group
(the candidates the data cannot tell apart from it, :mod:`bscomp.validate.equivalence`) ranks first and is
accepted, its fitted parameter is within 15 % of the truth and the error (after re-calibration) falls by
>= 80 % (>= 50 % for backlash). On the 3 coordinates of validation_drive a joint at the nut and a housing
at the screw support are one series spring: the joint case's group is exactly those two, whichever of them
round-off puts first. A no-effect control claims nothing; a two-effect case finds both.
Each case runs diagnose once (module fixture) and several tests read the result.
"""

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

#: the group named first, where it is more than the hidden effect alone (the same series spring)
GROUPS = {"joint": {"nut_table_joint", "bearing_housing"}}

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
    # its group ranks first in round 1 and is the first accepted effect; the group is exactly the candidates
    # it is the same effect as on this model, or the hidden effect with at most mates of its own kind
    # (Coulomb ~ Stribeck at the guideway: one place, one exclusive candidate group)
    kind = {r.name: r.candidate.group for r in diag.ranked}
    for r in (diag.ranked[0], diag.accepted[0] if diag.accepted else None):
        assert r is not None and name in r.group_names, diag.table()
        if case in GROUPS:
            assert set(r.group_names) == GROUPS[case], diag.table()
        else:
            assert {kind[n] for n in r.group_names} == {kind[name]}, diag.table()
    if case in GROUPS:                                          # both ways, whichever round-off puts first
        assert all(set(r.group_names) == GROUPS[case] for r in diag.ranked[:len(GROUPS[case])]), diag.table()
    # the hidden effect's fitted parameter within 15 % of the truth (polished if it is the one accepted)
    fit = diag.accepted[0] if diag.accepted[0].name == name else next(r for r in diag.ranked if r.name == name)
    fitted = fit.values[pname]
    truth = TRUTH_VALUES[name][pname]
    assert abs(fitted / truth - 1) < 0.15, (fitted, truth, diag.table())
    # an uncertainty is reported and is finite
    assert np.isfinite(fit.std[pname]) and fit.std[pname] > 0
    # error falls by the required fraction relative to the re-calibrated model
    final = diag.staircase[-1][1]
    assert 1 - final / _recalibrated_error(diag) >= min_drop, diag.table()
    # nothing spurious on top
    assert len(diag.accepted) == 1, diag.table()


@pytest.mark.slow
def test_no_effect_control_claims_nothing():
    _, diag = run_case("none", {})
    assert not diag.accepted, diag.table()
    assert "no missing effect found" in diag.message
    # the mis-set parameters are recovered by re-calibration alone
    assert abs(diag.recalibrated["table.m"][0] / (250.0 * 1.06) - 1) < 0.05
    assert abs(diag.recalibrated["coupling.c"][0] / (3938.0 * 0.93) - 1) < 0.05


@pytest.mark.slow
def test_two_effects_found_one_after_another():
    _, diag = run_case("two", {"nut_table_joint": {}, "guideway_friction": {}})
    names = {a.name for a in diag.accepted}
    # on the 3-coordinate lumped drive a joint in series at the nut and a housing spring in series at the
    # screw's support (with a housing mass small against the 1.49 kg nut) are the same series compliance
    series = {"nut_table_joint", "bearing_housing"}
    assert len(names) == 2 and "guideway_friction" in names and names & series, diag.table()
    errs = [e for _, e in diag.staircase]
    assert all(b < a for a, b in zip(errs[1:], errs[2:])), diag.staircase  # a staircase down
    joint = next(a for a in diag.accepted if a.name in series)
    assert set(joint.group_names) == series, diag.table()      # reported as one group, not one by round-off
    fric = next(a for a in diag.accepted if a.name == "guideway_friction")
    assert abs(joint.values["k"] / TRUTH_VALUES["nut_table_joint"]["k"] - 1) < 0.15
    assert abs(fric.values["F_c"] / TRUTH_VALUES["guideway_friction"]["F_c"] - 1) < 0.15


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
def test_joint_group_is_reported_with_what_to_measure():
    """The joint case's report says the two are one group, why (the test numbers), and which sensor would
    tell them apart; the JSON carries the same."""
    import json

    _, diag = run_case("joint", CASES["joint"][0])
    first, other = diag.accepted[0].name, ({"nut_table_joint", "bearing_housing"} - {diag.accepted[0].name}).pop()
    st = diag.accepted[0].equivalent[other]
    assert st["shared"] > 0.99 and abs(st["z"]) < 1.96 and st["n"] > 1000        # same error, neither better
    text = diag.table()
    assert f"{first} ~ {other}: indistinguishable on this model and data" in text
    assert "nut.flange_b - table.flange_a" in text and "lead.flange_b - axial.flange_a" in text
    assert f"(~ {other}: indistinguishable on this model" in diag.message
    d = json.loads(diag.to_json())
    assert d["accepted"][0]["equivalent"][other]["tell_apart"] == st["tell_apart"]


@pytest.mark.slow
@pytest.mark.parametrize("eps, seed", [(1e-12, 3), (1e-11, 4), (1e-11, 5)])
def test_joint_case_does_not_turn_on_round_off(monkeypatch, eps, seed):
    """Last round's knife edge: the compiled time series' modal basis changed by ~1e-13 and the joint case
    named bearing_housing first. Here the basis is perturbed on purpose (T -> T (I + eps R), the block form
    recomputed: outputs off by ~eps); without the refinement's restart these three named bearing_housing
    first (nut_table_joint stalled with d on its 1 N s/m bound: error 28.5 or 21.14 against 21.00). The
    diagnosis must not change: same group, same accepted effect, same fit."""
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
    assert set(diag.ranked[0].group_names) == GROUPS["joint"] and diag.accepted, diag.table()
    assert diag.accepted[0].name == ref.accepted[0].name, diag.table()
    for r in diag.ranked[:2]:
        r0 = next(q for q in ref.ranked if q.name == r.name)
        assert abs(r.error_after / r0.error_after - 1) < 1e-4, (r.name, r.error_after, r0.error_after)
        assert all(abs(r.values[p] / r0.values[p] - 1) < 1e-3 for p in r.values), (r.values, r0.values)
