"""diagnose's pair round (bscomp.validate.pairs): when it runs, and rule 2 -- each member needed beside the other --
on hand-made fit summaries whose verdicts follow from the rules' arithmetic. The pair found on an FE truth: the
integration test ``test_two_losses_neither_of_which_passes_alone_are_found_together``."""

from types import SimpleNamespace

import pytest

from bscomp.validate.acceptance import clearly_worse
from bscomp.validate.conclusion import UNEXPLAINED, conclusion
from bscomp.validate.pairs import PAIR_MEMBERS, _needed, _unconfirmed, linear_partner, wants_pairs

THRESHOLDS = (10.0, 0.5, 0.25, 0.5)          # bic, min_drop, min_heldout_drop, noise tolerance (diagnose's defaults)


def _summary(error, heldout, bic):
    return {"error": error, "heldout": heldout, "bic": bic}


def _fit(name, error, heldout, bic):
    return SimpleNamespace(name=name, _after=_summary(error, heldout, bic))


def test_pairs_are_tried_only_with_two_slots_and_an_unexplained_error():
    assert wants_pairs({"error": UNEXPLAINED * 1.01}, 2)
    assert not wants_pairs({"error": UNEXPLAINED * 1.01}, 1)           # one effect left to add: no pair
    assert not wants_pairs({"error": UNEXPLAINED * 0.99}, 3)           # near the floor: a single would do or nothing
    assert PAIR_MEMBERS == 3                                           # three joint fits at most


def test_each_member_must_be_needed_beside_the_other():
    """Seed 2203's damping truth in numbers (docs/validation.md): the coupling's damper alone 13.8 fitted / 5.17
    held-out, the bearing's 28.3 / 6.97, the two together 0.98 / 1.05 -- each removes > 99 % of what the other
    left; a rider that adds nothing (the pair as good as one alone) is not needed."""
    pair = _summary(0.978, 1.047, 1000.0)
    coupling, bearing = _fit("coupling_damping", 13.82, 5.169, 1900.0), _fit("support_damping", 28.31, 6.969, 4000.0)
    assert _needed(bearing, coupling, pair, THRESHOLDS) == ""
    assert _needed(coupling, bearing, pair, THRESHOLDS) == ""
    rider = _summary(13.5, 5.10, 1895.0)
    why = _needed(bearing, coupling, rider, THRESHOLDS)
    assert why.startswith("support_damping not needed beside coupling_damping: BIC not lower by 10")
    assert "removes only 2 % of the excess error coupling_damping alone left (needs 50 %)" in why
    assert "not confirmed beside coupling_damping on held-out data (5.17 -> 5.1)" in why


def test_the_held_out_rule_applies_only_above_the_noise():
    """Beside a fit whose held-out error is already within noise (1 + tolerance) the held-out part is not asked to
    fall; the fitted part still is."""
    pair = _summary(1.2, 1.45, 100.0)
    other = _fit("a", 6.0, 1.4, 400.0)
    assert _needed(SimpleNamespace(name="b"), other, pair, THRESHOLDS) == ""
    held = _fit("a", 6.0, 3.0, 400.0)                                   # above it: 3.0 -> 1.45 is 78 % of the excess
    assert _needed(SimpleNamespace(name="b"), held, pair, THRESHOLDS) == ""
    assert _needed(SimpleNamespace(name="b"), held, _summary(1.2, 2.8, 100.0), THRESHOLDS) == (
        "b not needed beside a: not confirmed beside a on held-out data (3 -> 2.8)")   # 10 % of it


@pytest.mark.parametrize("together", [True, False])
def test_the_conclusion_says_a_pair_was_found_together(together):
    a = SimpleNamespace(candidate=SimpleNamespace(title="torsional damping in the coupling", nonlinear=False),
                        name="coupling_damping", equivalent={}, together="support_damping" if together else "",
                        values={"d": 0.22})
    b = SimpleNamespace(candidate=SimpleNamespace(title="axial damping at the thrust bearing", nonlinear=False),
                        name="support_damping", equivalent={}, together="coupling_damping" if together else "",
                        values={"c": 2.3e4})
    msg = conclusion("", [a, b], [], ("", ""), [], 2, None, {})
    assert msg.startswith("2 missing effect(s) found: torsional damping in the coupling, axial damping at the thrust")
    said = "torsional damping in the coupling and axial damping at the thrust bearing were found together"
    assert (said in msg) is together
    assert msg.count("found together") == int(together)                 # once per pair, not per member


def test_a_pair_nothing_confirms_is_not_accepted():
    """FRFs at one stated amplitude and no time series confirm no linear effect and no nonlinear one (as for a single,
    bscomp.validate.amplitude.frf_confirmation): a pair with such a member is not accepted."""
    lin = SimpleNamespace(candidate=SimpleNamespace(nonlinear=False))
    nonlin = SimpleNamespace(candidate=SimpleNamespace(nonlinear=True))
    assert _unconfirmed(lin, lin, ("", "")) == ""
    assert _unconfirmed(lin, nonlin, ("", "only a time series confirms friction")) == (
        "passes every rule but is not confirmed: only a time series confirms friction")
    assert _unconfirmed(lin, lin, ("", "only a time series")) == ""          # linear members: the linear reason
    assert _unconfirmed(lin, lin, ("one amplitude", "x")).endswith("one amplitude")


def _user(phase_deg, fit_percent):
    """A user summary of one dataset with one FRF pair and one time channel (acceptance.clearly_worse's input)."""
    return {"per_dataset": [{"frf": [{"pair": ("amp.u", "rotor.w"), "mag_mean_abs_dlog10": 0.02,
                                      "phase_deg_rms": phase_deg}],
                             "time": [{"channel": "table.a", "fit_percent": fit_percent}]}]}


def test_clearly_worse_can_look_at_the_frfs_alone():
    """Seed 2213's joint + friction in numbers: the friction alone took the motor FRF's phase error 4.4 -> 8.9 deg
    (> 1.2 x 4.4 + 1 deg) and the table acceleration's fit 32.7 -> 12.8 %; ``frf_only`` keeps the first."""
    before, after = _user(4.4, 32.7), _user(8.9, 12.8)
    assert clearly_worse(before, after) == ["amp.u->rotor.w phase error 4.4 -> 8.9 deg", "table.a fit 32.7 -> 12.8 %"]
    assert clearly_worse(before, after, frf_only=True) == ["amp.u->rotor.w phase error 4.4 -> 8.9 deg"]
    assert clearly_worse(before, _user(6.2, 12.8), frf_only=True) == []          # 6.2 < 1.2 x 4.4 + 1: not clearly


def _member(name, nonlinear, phase_after=8.9):
    return SimpleNamespace(name=name, candidate=SimpleNamespace(nonlinear=nonlinear, group=name),
                           user_before=_user(4.4, 32.7), user_after=_user(phase_after, 12.8))


@pytest.mark.parametrize("members", [
    [],                                                                          # no member to pair
    [_member("guideway_friction", True), _member("table_subassembly", False)],   # a linear member: pairs hold it
    [_member("guideway_friction", True, phase_after=4.5), _member("rotor_friction", True)],   # FRFs not worse
])
def test_no_linear_partner_is_looked_for_unless_every_member_is_nonlinear_and_an_frf_got_worse(members):
    """The partner is screened only where the pairs of members cannot hold a linear part and the best member's FRFs
    say one is missing (the time series alone getting worse is the nonlinear effect's own business); nothing is
    evaluated then (no structures are needed: these calls would fail on ``None``)."""
    assert linear_partner(members, [], [], ["table.m"], structures=None, sigmas=None, ref=None,
                          screening=(21, 5)) == (None, 0)


def test_the_conclusion_says_which_member_is_the_linear_partner():
    """A pair found by a linear partner (pairs.linear_partner) is not 'each stood in for both': the lead failed a rule
    alone and the partner was screened beside it -- the sentence says so, lead first, whichever order they come in."""
    lead = SimpleNamespace(candidate=SimpleNamespace(title="Coulomb + viscous friction at the guideways",
                                                     nonlinear=True),
                           name="guideway_friction", equivalent={}, together="table_subassembly", partner=False,
                           values={"F_c": 1410.0})
    part = SimpleNamespace(candidate=SimpleNamespace(title="sub-assembly on a compliant joint at the table",
                                                     nonlinear=False),
                           name="table_subassembly", equivalent={}, together="guideway_friction", partner=True,
                           values={"m": 52.4})
    for accepted in ([lead, part], [part, lead]):
        msg = conclusion("", accepted, [], ("", ""), [], 2, None, {})
        said = ("Coulomb + viscous friction at the guideways and sub-assembly on a compliant joint at the table were "
                "found together: the first alone failed a rule (see the table), the second -- screened on the FRFs "
                "beside it")
        assert said in msg and msg.count("found together") == 1, msg
        assert "each stood in for both" not in msg
