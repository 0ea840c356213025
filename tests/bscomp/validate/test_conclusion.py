"""The conclusion's lead where a round accepts nothing above 5x the noise floor (bscomp.validate.conclusion._closest),
on the fit summaries of truths (docs/validation.md, "Seeds 2206 and 2207", "Positions only"): a clearance rattling in
its gap, whose time series no candidate law follows closely enough to pass the rules, is named as the closest lead,
and so is a table part that a record of positions only cannot confirm after the friction was found; a torque
ripple, which no candidate lowers, and a stand-in that raises the BIC are not."""

from types import SimpleNamespace

from bscomp.validate.conclusion import CLOSEST, conclusion, excess_drop

LEFT = {"error": 406.4, "within_noise": False, "orders": []}


def _best(title, before, after, held_before, held_after, dbic):
    cand = SimpleNamespace(title=title, nonlinear=False)
    return SimpleNamespace(candidate=cand, refined=True, error_before=before, error_after=after,
                           heldout_before=held_before, heldout_after=held_after, delta_bic=dbic)


def _message(best):
    return conclusion("", [], [], ("", ""), [best], 2, None, {}, LEFT)


def test_the_best_candidate_is_named_as_a_lead_when_it_removes_a_quarter_of_the_excess():
    """Seed 2205's backlash (34.8 um on 2.1e9 N/m): compliant_backlash 406 -> 200 fitted (51 % of the excess),
    1040 -> 859 held-out (17 %, 25 % needed), dBIC -2.5e6."""
    msg = _message(_best("backlash at the screw-nut with a compliant contact", 406.4, 200.0, 1040.0, 858.6, -2.5e6))
    assert msg.startswith("an effect outside the candidates is missing")
    assert ("The closest is backlash at the screw-nut with a compliant contact: it takes the fitted error 406.4 -> "
            "200 (51 % of the excess), the held-out halves 1.04e+03 -> 859 (17 % of theirs)") in msg
    assert "a lead, not a finding" in msg
    assert excess_drop(406.4, 200.0) > CLOSEST > excess_drop(406.4, 406.4 - 0.2 * 405.4)


def test_no_lead_where_the_best_candidate_does_not_help_or_raises_the_bic():
    ripple = _best("amplifier delay", 33.46, 36.54, 60.0, 59.1, 3.1e4)                  # seed 2207's ripple
    assert "closest" not in _message(ripple)
    stand_in = _best("a nut-table joint", 7724.0, 2724.0, 1000.0, 3030.0, 6.03e6)       # stepped-sine backlash truth
    assert "closest" not in _message(stand_in)
    small = _best("a bearing housing", 406.4, 406.4 - 0.2 * 405.4, 1040.0, 1000.0, -50.0)   # 20 % of the excess
    assert "closest" not in _message(small)
    lead = _best("a bearing housing", 406.4, 406.4 - 0.3 * 405.4, None, None, -50.0)      # FRFs only: no held-out
    assert "The closest is a bearing housing: it takes the fitted error 406.4 -> 284.8 (30 % of the excess), short" \
        in _message(lead)
    assert "closest" not in conclusion("", [], [], ("", ""), [lead], 2, None, {}, dict(LEFT, error=4.0))


def test_after_an_effect_is_found_the_last_rounds_best_is_the_further_lead_held_out_worse_said():
    """The demo's truth measured by positions only (rotor.phi, table.s): the friction found, the table part then
    fitted to m -0.4 %, k -0.3 % taking the fitted error 100 -> 1.12, but the held-out halves 16.6 -> 18 (the
    friction law's shape leaves a position offset after each reversal, which the part cannot remove)."""
    friction = SimpleNamespace(candidate=SimpleNamespace(title="Coulomb + viscous friction at the guideways"),
                               equivalent={})
    part = _best("sub-assembly on a compliant joint at the table", 100.2, 1.121, 16.6, 17.96, -3.1e5)
    msg = conclusion("", [friction], [], ("", ""), [], 2, None, {}, dict(LEFT, error=100.2), [part])
    assert msg.startswith("1 missing effect(s) found: Coulomb + viscous friction at the guideways. The error left")
    assert ("The closest further candidate is sub-assembly on a compliant joint at the table: it takes the fitted "
            "error 100.2 -> 1.121 (100 % of the excess), the held-out halves 16.6 -> 18 (worse), short of the rules"
            in msg)
    near = conclusion("", [friction], [], ("", ""), [], 2, None, {}, dict(LEFT, error=2.0), [part])
    assert "closest" not in near                              # within 5x of the noise floor: no lead


def test_held_out_halves_confirm_an_effect_whose_evidence_is_in_the_frfs():
    """Another drive's joint + friction truth, seed 2301, round 2 (docs/validation.md, "Another drive"): the table
    part takes the FRF 17.5 -> 1.14 and leaves the time series' fitted half where the friction law's shape keeps it
    (6.46 -> 6.51); its held-out half 9.45 -> 8.06 is 16 % of the excess, short of 25 %, but more than the fitted half
    lost: the fit carries over, and it is accepted (``CARRIED``). Held-out halves that lose less than the fitted
    halves, or less than 10 %, still reject it."""
    from bscomp.validate.acceptance import CARRIED, carried_over, verdict

    thresholds = (10.0, 0.5, 0.25, 0.5)
    before = {"error": 11.96, "per_dataset": [17.5, 6.46], "heldout": 9.45, "heldout_per_dataset": [9.45],
              "fitted_split": [6.46]}
    after = {"error": 3.825, "per_dataset": [1.14, 6.51], "heldout": 8.06, "heldout_per_dataset": [8.06],
             "fitted_split": [6.51]}
    assert verdict(before, after, -5000.0, [], [], thresholds) == (True, "")
    assert CARRIED == 0.1 and carried_over(before, after, (9.45 - 8.06) / 8.45)
    fitted_fell_more = dict(after, per_dataset=[1.14, 4.0], fitted_split=[4.0])       # 45 % of the fitted excess
    ok, why = verdict(before, fitted_fell_more, -5000.0, [], [], thresholds)
    assert not ok and why == "not confirmed on held-out data (error 9.45 -> 8.06)"
    barely = dict(after, heldout=8.8, heldout_per_dataset=[8.8])                        # 7.7 % < CARRIED
    ok, why = verdict(before, barely, -5000.0, [], [], thresholds)
    assert not ok and why == "not confirmed on held-out data (error 9.45 -> 8.8)"
    no_split = {k: v for k, v in before.items() if k != "fitted_split"}                # older summaries: the old rule
    assert not carried_over(no_split, after, 0.16)


def test_the_lead_is_the_best_ranked_fit_that_is_one_not_the_best_ranked_fit():
    """Another drive's joint + friction truth, seed 2305, round 2 (docs/validation.md, "Seeds 2303-2306"): the
    friction found, the ranking (the mean of the fitted and held-out errors) puts the added damping first -- 7.28 ->
    7.09 fitted (3 % of the excess), held-out 56.2 -> 21.2 -- and the truth's table part third: 7.28 -> 1.99 (84 %),
    its held-out halves 56.2 -> 59.5. The part is the lead; the damping, short of a quarter, is not. (The errors are
    the run's; the BIC changes are not recorded there -- only their sign matters here.)"""
    friction = SimpleNamespace(candidate=SimpleNamespace(title="Coulomb + viscous friction at the guideways"),
                               equivalent={})
    damping = _best("damping added to every mode", 7.281, 7.088, 56.24, 21.18, -1.2e3)
    housing = _best("bearing-housing mass and compliance", 7.281, 7.116, 56.24, 22.86, -9.0e2)
    part = _best("sub-assembly on a compliant joint at the table", 7.281, 1.987, 56.24, 59.51, -2.9e4)
    msg = conclusion("", [friction], [], ("", ""), [], 2, None, {}, dict(LEFT, error=7.281), [damping, housing, part])
    assert ("The closest further candidate is sub-assembly on a compliant joint at the table: it takes the fitted "
            "error 7.281 -> 1.987 (84 % of the excess), the held-out halves 56.2 -> 59.5 (worse), short of the rules"
            in msg)
    assert "damping" not in msg.split("The closest")[1]
    nobody = conclusion("", [friction], [], ("", ""), [], 2, None, {}, dict(LEFT, error=7.281), [damping, housing])
    assert "closest" not in nobody


def test_a_body_that_only_the_frfs_see_is_said_to_be_supported_by_them_alone():
    """Seed 2210's housing truth: after the housing, a 10.5 kg table part at 960 Hz took the FRF 1.57 -> 1.17 and left
    the time series 0.969 -> 0.967, held-out 1.04 -> 1.04 (the truth has no such part); the demo truth's real part in
    round 2 moved the time series 20.9 -> 1.45, and a damping (no mode of its own) or a friction is never so said."""
    from bscomp.validate.conclusion import UNSEEN, _frf_only
    from bscomp.validate.datasets import FrfData, TimeData

    setup = SimpleNamespace(datasets=[object.__new__(FrfData), object.__new__(TimeData)], reference=None)

    def fit(ts_before, ts_after, held_before, held_after, mode=960.0, nonlinear=False):
        cand = SimpleNamespace(title="sub-assembly on a compliant joint at the table", nonlinear=nonlinear,
                               mode_hz=lambda values, system, known: mode)
        return SimpleNamespace(candidate=cand, values={}, per_dataset=([1.57, ts_before], [1.17, ts_after]),
                               heldout_before=held_before, heldout_after=held_after)

    text = _frf_only([fit(0.969, 0.967, 1.04, 1.04)], setup, {})
    assert text == (". sub-assembly on a compliant joint at the table: only the FRFs see it (error 1.57 -> 1.17); the "
                    "time series are where they were (fitted 0.969 -> 0.967, held-out 1.04 -> 1.04), so its mode "
                    "(960 Hz) may stand in for a difference of the model's form in the band (a mesh, a joint's shape) "
                    "rather than a body the drive has")
    assert _frf_only([fit(20.9, 1.45, 34.5, 11.6)], setup, {}) == ""                 # the demo's part
    assert _frf_only([fit(1.0, 1.0, 1.0, 1.0 + 1.5 * UNSEEN)], setup, {}) == ""       # the held-out halves moved
    assert _frf_only([fit(0.969, 0.967, 1.04, 1.04, mode=None)], setup, {}) == ""     # no mode: a damping
    assert _frf_only([fit(0.969, 0.967, 1.04, 1.04, nonlinear=True)], setup, {}) == ""


def test_a_guideway_friction_that_leaves_much_suggests_the_friction_torque_when_it_was_not_tried():
    """The bearing-friction truths (docs/validation.md, "Friction that is not at the guideways"): the guideway
    candidates without ``rotor_friction`` accept a guideway friction and leave 25-251x the noise floor (seed 2201:
    54.5), or accept nothing with the guideway friction ranked first (2203): a candidate list without it gets the
    suggestion; not when it was among the candidates (the defaults), not within 5x (a guideway truth's law shape:
    1.65), not for another effect."""
    def fit(group, title="Coulomb + viscous friction at the guideways"):
        return SimpleNamespace(candidate=SimpleNamespace(title=title, group=group, nonlinear=True), equivalent={},
                               refined=True, error_before=1e7, error_after=54.5, heldout_before=None,
                               heldout_after=None, delta_bic=-1e6, values={})

    friction, torque = fit("guideway_friction"), fit("friction_torque", "friction torque at the motor")
    hint = "add the friction torque at the motor, which these candidates lack (the default 'rotor_friction'"
    assert hint in conclusion("", [friction], [], ("", ""), [friction], 2, None, {}, dict(LEFT, error=54.5))
    assert hint in conclusion("", [], [], ("", ""), [friction], 2, None, {}, dict(LEFT, error=2.2e7))
    assert hint not in conclusion("", [friction], [], ("", ""), [friction, torque], 2, None, {},
                                  dict(LEFT, error=54.5))
    assert hint not in conclusion("", [friction], [], ("", ""), [friction], 2, None, {}, dict(LEFT, error=1.65))
    part = fit("table_part", "sub-assembly on a compliant joint at the table")
    assert hint not in conclusion("", [part], [], ("", ""), [part], 2, None, {}, dict(LEFT, error=54.5))


def test_a_friction_torque_beside_a_residual_periodic_in_the_motor_angle_may_stand_in_for_a_ripple():
    """Seed 2304 of the other drive (a motor torque ripple, docs/validation.md): the friction torque's fit passed the
    order test, the final residual did not (rotor.w 8 periods per revolution, p 7e-4): the message says the torque may
    stand in for a ripple; not without an order, not for an effect a ripple does not imitate."""
    from bscomp.validate.periodicity import AngleOrder

    order = AngleOrder("rotor.w", "rotor.phi", 8, 0.305, 7e-4, 0.0421, "rad/s")

    def fit(title, alike):
        return SimpleNamespace(candidate=SimpleNamespace(title=title, group="g", nonlinear=True, ripple_alike=alike),
                               equivalent={}, values={})

    torque = fit("Coulomb + viscous friction torque at the motor", True)
    rest = dict(LEFT, error=155.0, orders=[order])
    note = ("Coulomb + viscous friction torque at the motor: the residual left repeats 8 times per motor revolution, "
            "and over a short stroke a torque ripple at the motor (cogging, no candidate) drags like it")
    assert note in conclusion("", [torque], [], ("", ""), [torque], 2, None, {}, rest)
    assert note not in conclusion("", [torque], [], ("", ""), [torque], 2, None, {}, dict(rest, orders=[]))
    part = fit("sub-assembly on a compliant joint at the table", False)
    assert "may stand in for the ripple" not in conclusion("", [part], [], ("", ""), [part], 2, None, {}, rest)


def test_a_clearance_and_a_nut_table_joint_on_one_line_are_said_to_be_one_element():
    """On the FE test bed the screw-nut clearance sits on the nut-table line: a clearance and a joint accepted together
    are one element (the gap, the joint's spring its contact, the joint's damper beside it) -- the other drive's
    clearance seed 2303 (223 -> 4.7, a softplus contact and no joint in the truth). The clearance's own k is then not
    written (``merged``: the same overrides whichever came first); on the lumped drive (the clearance on the screw-nut
    spring, the joint between nut and table) nothing is said."""
    from bscomp.systems.testbed import testbed
    from bscomp.systems.validation_drive import validation_drive
    from bscomp.validate.candidates import CompliantBacklash, NutTableJoint, ScrewNutBacklash

    fe = testbed("axial_torsional", "C")
    gap, joint = CompliantBacklash(), NutTableJoint()
    values = {"b": 3e-6, "k": 2e9, "w": 0.3, "x0": 1.0}
    for first, second in ((gap, joint), (joint, gap)):
        s = second.structure(first.structure(fe))
        assert f"{s._effect_state['nut_table_joint']['spring']}.c" not in gap.overrides(values, s)

    def fit(cand, vals):
        return SimpleNamespace(candidate=cand, values=vals, equivalent={}, together="")

    said = "sit on the same line of the drive, so in the model they are one element"
    pair = [fit(gap, values), fit(joint, {"k": 5.1e8, "d": 870.0})]
    text = conclusion("", pair, [], ("", ""), pair, 2, SimpleNamespace(reference=fe, datasets=[]), {},
                      dict(LEFT, error=4.7))
    assert said in text and "(k = 5.1e+08 N/m; the clearance's own k is not used)" in text
    sharp = [fit(ScrewNutBacklash(), {"b": 3e-6}), pair[1]]
    text = conclusion("", sharp, [], ("", ""), sharp, 2, SimpleNamespace(reference=fe, datasets=[]), {}, LEFT)
    assert said in text and "(k = 5.1e+08 N/m) and the joint's damper" in text
    lumped = [fit(ScrewNutBacklash(), {"b": 3e-6}), pair[1]]
    assert said not in conclusion("", lumped, [], ("", ""), lumped, 2,
                                  SimpleNamespace(reference=validation_drive(), datasets=[]), {}, LEFT)
    assert said not in conclusion("", pair[:1], [], ("", ""), pair[:1], 2, SimpleNamespace(reference=fe, datasets=[]),
                                  {}, LEFT)
