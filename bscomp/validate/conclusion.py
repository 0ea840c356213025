r"""The conclusion of :func:`~bscomp.validate.diagnose` in words, and what is left when it ends.

A diagnosis ends in one of four states, and its message says which: the model explains every dataset within its
noise (nothing is missing); effects were found (named, with those the data cannot tell apart); a candidate would
explain FRFs that nothing confirms (:func:`~bscomp.validate.amplitude.frf_confirmation`); or no candidate explains
the error. In the last two, and after effects were found, the error left is stated against the noise floor: a
library of candidates cannot name what it does not hold, but it can say that something is still missing.
Above :data:`UNEXPLAINED` x the noise floor the message says so outright -- with the candidates' effects found, the
12 bundled FE truths end at most 2.0x above it (2.9x before the table part's damping was fitted; the truths' own
law shapes and FE mesh, ``docs/validation.md``; on truths drawn anew a broad arc-tangent friction corner left 5.9x
and a rattling clearance 105x with nothing else missing, so after effects were found the message says something
*may* be missing); the ``ripple`` truths (a motor torque ripple, which no candidate has) stay at 273x and
1010x. Then the uncertain parameters are fitted to the FRFs alone too: an effect the FRFs do not see (a
nonlinear one) bends the fit to every dataset -- on the ripple truths the table mass 11 % and 9.5 % light, the FRFs
alone within 0.1 % of the truth -- and both values are given; and the time series' residuals, at the final values
and at the FRFs' values, are searched for a component periodic in the motor angle
(:mod:`~bscomp.validate.periodicity`), the one pattern of an effect outside the library that the data alone can
point at.

When a round accepts nothing and the error left is above :data:`UNEXPLAINED`, its best-ranked candidate that lowers
the BIC and removes at least :data:`CLOSEST` of the fitted error above the noise floor is named as a *lead* (a lead,
not a finding); what it did to the held-out halves is said, better or worse. On two truths drawn anew with a 35 um
clearance the table rattles across (seeds 2205, 2206, ``docs/validation.md``) ``compliant_backlash`` takes 51 % / 46 %
of the fitted excess, but no candidate law follows such a rattle closely enough for the rules (the truth with a 1 %
wider gap is itself 1,400x the noise floor off on the held-out table acceleration); measured by positions only, the
demo's truth has its friction found and then the table part fitted within 0.4 % but its held-out halves worse (16.6
-> 18), and the part is named as the closest *further* candidate. The ripple truths' best candidates remove at most
1 %, and a nut-table joint standing in for a clearance measured by stepped sines raises the BIC: neither is named.

An accepted effect whose own mode lies above every measured FRF (:data:`OUT_OF_BAND` x the top frequency;
:meth:`~bscomp.validate.candidates.base.Candidate.mode_hz`) was seen by the time series alone, where it may stand in
for something else above the band: the message says so. On the rattling clearance of ``docs/validation.md``
("Other draws of the truths", seed 2202) a bearing housing the truth does not have, its mode at 2.1 kHz against
FRFs to 1 kHz, took the error from 105 to 1.26 beside the clearance.

An accepted mass on a spring (a table part, a bearing housing) fitted with a damping ratio above :data:`OVERDAMPED`
has no resonance of its own left: the data then show a loss near its point, not a body, and the message says it
may stand in for damping the model lacks there. On the ``damping`` truths of ``docs/validation.md`` (two viscous
dashpots the model lacks, at the thrust bearing and across the coupling), before the library had candidates for a
local loss (``support_damping``, ``coupling_damping``), a bearing housing damped at 54-73 % of critical was accepted
in their place on all four draws; the ``extra_damping`` candidate's one ratio on every mode makes the table FRF above
400 Hz worse, not better. A loss elsewhere (a joint, the nut) would meet the same stand-in: the sentence says so.

When a guideway friction is accepted (or, nothing accepted, ranked first) and more than :data:`UNEXPLAINED` x the noise
floor is left, and the friction torque at the motor (``rotor_friction``, a default since 2026-12-07) was not among the
candidates given, the message suggests it: on 12 truths drawn with the friction on the screw's bearing instead of the
guideways the candidates without it accepted a guideway friction (or named it as the lead) and left 25-251x, and with
``rotor_friction`` beside them every one was named with its torque within 2.1 % (``docs/validation.md``, "Friction that
is not at the guideways").

A clearance and a nut-table joint accepted on the same line (the FE test beds model the screw-nut clearance on the
nut-table line) are one element in the model -- the gap with the joint's spring as its contact and the joint's damper
beside it -- so the joint may be the clearance's contact re-fitted: the message says so. On the other drive's clearance
seed 2303 the pair was accepted (223 -> 4.7) with the truth's softplus contact and no joint.

A friction torque at the motor is accepted only while the residual it leaves is not periodic in the motor angle
(:func:`~bscomp.validate.acceptance.ripple_left`): over a short stroke a torque ripple (cogging, outside the library)
drags alike -- beside the defaults the torque took 2 of 18 drawn ripples, and the rule gave one of them back (seed
2301). When its fit passed the test but the final residual repeats with the motor angle (seed 2304: rotor.w 8 periods
per revolution, p 7e-4, at the end; not at the fit), the message says the torque may stand in for a ripple.

An accepted mass on a spring (a mode of its own) that left the time series where they were -- the fitted and the
held-out halves each within :data:`UNSEEN` of their error without it -- is supported by the FRFs alone; near the noise
floor that may be a difference of the model's form in the band (a mesh, a joint's shape) that a body can absorb: the
message says so. On a housing truth drawn anew (seed 2210, ``docs/validation.md``), after the housing was found
(1.27 left, the FRF file at 1.57), a 10.5 kg table part at 960 Hz -- at the FRFs' top -- took the FRF to 1.17 and
the time series 0.969 -> 0.967, held-out 1.04 -> 1.04, and passed every rule: the truth has no such part.
"""

from __future__ import annotations

import numpy as np

from bscomp.kernel.interface import NotApplicable
from bscomp.validate.amplitude import stuck_note
from bscomp.validate.measurements import FrfData, TimeData
from bscomp.validate.periodicity import angle_channel, periodic_in_angle

__all__ = ["conclusion", "titles", "remainder", "residual_orders", "UNEXPLAINED", "OUT_OF_BAND", "OVERDAMPED",
           "CLOSEST", "UNSEEN"]

#: Error left (mean chi^2, 1 = the noise floor) above which an effect outside the candidates is called missing.
UNEXPLAINED = 5.0
#: A round that accepted nothing: its best candidate removing this share of the fitted excess is named as a lead.
CLOSEST = 0.25
#: An accepted effect's own mode above this many times the highest measured FRF frequency is said to be out of band.
OUT_OF_BAND = 1.5
#: An accepted mass on a spring damped above this ratio of critical (peak gain < 1.75x) is said to stand for a loss.
OVERDAMPED = 0.3
#: An accepted mass on a spring that changed every time series' fitted and held-out error by less than this share
#: of it is said to be supported by the FRFs alone.
UNSEEN = 0.02


def excess_drop(before: float, after: float) -> float:
    """Share of the error above the noise floor (1) removed: ``(before - after) / (before - 1)``."""
    return (before - after) / max(before - 1.0, 1e-12)


def remainder(summary, datasets, within_noise: bool, frf_view=None) -> dict:
    """What the final model leaves: ``{"error": mean chi^2 of the fitted parts, "within_noise": bool, "orders":
    [AngleOrder], "frf_values": {...} or None}`` -- the orders of the time series' residuals periodic in a
    measured angle channel (none when the model is within its noise), most significant first. ``frf_view``
    ``(values, outputs)``: the uncertain parameters fitted to the FRFs alone and the model's outputs there
    (an effect the FRFs do not see bends the re-calibration on every dataset; the residual at the FRFs' values
    shows it undistorted), searched too; per channel the more significant order is kept."""
    found = {} if within_noise else residual_orders(summary["outputs"], datasets, "")
    if frf_view is not None and not within_noise:
        for ch, o in residual_orders(frf_view[1], datasets, "with the parameters the FRFs alone give").items():
            if ch not in found or o.p_value < found[ch].p_value:
                found[ch] = o
    return {"error": float(summary["error"]), "within_noise": bool(within_noise),
            "orders": sorted(found.values(), key=lambda o: o.p_value),
            "frf_values": None if frf_view is None else dict(frf_view[0])}


def residual_orders(outputs, datasets, note) -> dict:
    """``{(dataset, channel): AngleOrder}`` of the time series' residuals (:func:`periodic_in_angle`)."""
    out = {}
    for i, (y, d) in enumerate(zip(outputs, datasets)):
        angle = angle_channel(d.units) if isinstance(d, TimeData) else None
        if angle is None or y is None or angle not in y:
            continue
        n = np.asarray(y[angle]).size
        e = {ch: np.asarray(v, float)[:n] - np.asarray(y[ch], float) for ch, v in d.outputs.items() if ch in y}
        for o in periodic_in_angle(e, np.asarray(y[angle], float), np.asarray(d.t, float)[:n], angle, d.units):
            o.note = note
            out[(i, o.channel)] = o
    return out


def conclusion(message, accepted, unconfirmed, unconfirmed_why, ranked, max_effects, setup, unc_values,
               rest=None, last=None) -> str:
    """The diagnosis's conclusion (``message`` already set: the model is within its noise; ``rest``:
    :func:`remainder`; ``last``: the fits of the last round when it accepted none after effects were found, for the
    lead of :func:`_closest`). When nothing was accepted and the best candidate is a friction or backlash fitted to FRFs
    at stated amplitudes, where its fitted element stays at its slope at rest is said whatever its verdict
    (:func:`~bscomp.validate.amplitude.stuck_note`): an FRF below breakaway measures the slope, not the level,
    and a fit there can land on either of two near-equal minima (``docs/validation.md``)."""
    left = "" if rest is None or rest["within_noise"] or max_effects == 0 else _left(rest, bool(accepted), unc_values)
    outside = rest is not None and not rest["within_noise"] and rest["error"] > UNEXPLAINED and max_effects > 0
    if accepted:
        return (f"{len(accepted)} missing effect(s) found: " + ", ".join(titles(a) for a in accepted) + left
                + (_closest(last, "The closest further candidate") if outside else "")
                + _together(accepted) + _out_of_band(accepted, setup, unc_values) + _overdamped(accepted)
                + _frf_only(accepted, setup, unc_values) + (_elsewhere(accepted, ranked) if outside else "")
                + _ripple_stand_in(accepted, rest) + _one_line(accepted, setup))
    if unconfirmed:
        u = unconfirmed[0]
        return (f"no missing effect confirmed: {u.candidate.title} would explain the FRFs (error "
                f"{u.error_before:.4g} -> {u.error_after:.4g}), but "
                f"{unconfirmed_why[1 if u.candidate.nonlinear else 0]}") + stuck_note(setup, u, unc_values) + left
    if max_effects == 0:
        return "no effect searched (max_effects=0): the uncertain parameters were only re-calibrated"
    if message:
        return message
    if outside:
        message = ("an effect outside the candidates is missing: none of them explains the remaining error (see why "
                   "each was not accepted)") + _closest(ranked, "The closest")
    else:
        message = ("no missing effect found: no candidate explains the remaining error well enough (see why each "
                   "was not accepted)")
    if outside:
        message += _elsewhere(ranked[:1], ranked)
    best = ranked[0] if ranked else None
    if best is not None and best.candidate.nonlinear and best.values:
        note = stuck_note(setup, best, unc_values)
        if note:
            message += f". The best candidate, {best.candidate.title}, was fitted to FRFs at stated amplitudes" + note
    return message + left


def _is_lead(fit) -> bool:
    """Refined, a lower BIC and at least :data:`CLOSEST` of the fitted error above the noise floor removed."""
    return bool(fit.refined and fit.delta_bic < 0.0 and excess_drop(fit.error_before, fit.error_after) >= CLOSEST)


def _closest(fits, lead: str) -> str:
    """The sentence naming the best-ranked of ``fits`` (a round that accepted none) that is a lead (module docstring,
    :func:`_is_lead`) -- the ranking puts a fit whose held-out halves got worse below one that changed nothing (a
    damping that removes 3 % of the excess, ahead of the table part that removes 84 %: another drive's joint +
    friction truth, seed 2305); what the held-out halves did is said, better or worse."""
    best = next((f for f in fits or () if _is_lead(f)), None)
    if best is None:
        return ""
    drop = excess_drop(best.error_before, best.error_after)
    held = ""
    if best.heldout_before is not None and best.heldout_after is not None:
        hdrop = excess_drop(best.heldout_before, best.heldout_after)
        held = (f", the held-out halves {best.heldout_before:.3g} -> {best.heldout_after:.3g} "
                + (f"({100 * hdrop:.0f} % of theirs)" if hdrop > 0.0 else "(worse)"))
    return (f". {lead} is {best.candidate.title}: it takes the fitted error {best.error_before:.4g} -> "
            f"{best.error_after:.4g} ({100 * drop:.0f} % of the excess){held}, short of the rules (see the table) -- "
            "a lead, not a finding: the missing effect may be of its kind with a law its candidate cannot follow, or "
            "something it stands in for")


def _out_of_band(accepted, setup, values) -> str:
    """A sentence per accepted effect whose own mode lies above every measured FRF (module docstring)."""
    if setup is None:
        return ""
    top = max((float(np.max(d.freqs)) for d in setup.datasets if isinstance(d, FrfData)), default=None)
    text = ""
    for a in accepted if top is not None else []:
        f = a.candidate.mode_hz(a.values, setup.reference, values)
        if f is not None and f > OUT_OF_BAND * top:
            text += (f". {a.candidate.title}: its own mode ({f:.0f} Hz) lies above the measured FRFs (to "
                     f"{top:.0f} Hz), so only the time series saw it, and it may stand in for something else "
                     f"there: an FRF measured to ~{float(f'{1.5 * f:.2g}'):.0f} Hz would show that mode or not")
    return text


def _frf_only(accepted, setup, values) -> str:
    """A sentence per accepted mass on a spring that the time series did not see (module docstring, :data:`UNSEEN`)."""
    if setup is None:
        return ""
    ts = [i for i, d in enumerate(setup.datasets) if isinstance(d, TimeData)]
    frf = [i for i, d in enumerate(setup.datasets) if isinstance(d, FrfData)]
    text = ""
    for a in accepted if ts and frf else []:
        if a.candidate.nonlinear or len(a.per_dataset) != 2 or a.heldout_before is None:
            continue
        f = a.candidate.mode_hz(a.values, setup.reference, values)
        if f is None:
            continue
        (b, e), hb, ha = a.per_dataset, a.heldout_before, a.heldout_after
        if all(abs(e[i] - b[i]) <= UNSEEN * b[i] for i in ts) and abs(ha - hb) <= UNSEEN * hb:
            fb, fa = (float(np.mean([v[i] for i in frf])) for v in (b, e))
            text += (f". {a.candidate.title}: only the FRFs see it (error {fb:.3g} -> {fa:.3g}); the time series are "
                     f"where they were (fitted {np.mean([b[i] for i in ts]):.3g} -> {np.mean([e[i] for i in ts]):.3g}, "
                     f"held-out {hb:.3g} -> {ha:.3g}), so its mode ({f:.0f} Hz) may stand in for a difference of the "
                     "model's form in the band (a mesh, a joint's shape) rather than a body the drive has")
    return text


def _elsewhere(named, ranked) -> str:
    """The friction torque at the motor suggested (module docstring) when a guideway friction is accepted (or, nothing
    accepted, ranked first) with more than :data:`UNEXPLAINED` left and no friction torque was tried."""
    def group(f):
        return getattr(f.candidate, "group", None)

    if not any(group(f) == "guideway_friction" for f in named or ()) or any(
            group(f) == "friction_torque" for f in ranked or ()):
        return ""
    return (". The friction is put at the guideways; if the drive's friction is (also) in its bearings, seals or nut, "
            "add the friction torque at the motor, which these candidates lack (the default 'rotor_friction'; CLI "
            "--candidate rotor_friction): on 12 drawn truths with friction on the screw the guideway candidates alone "
            "left 25-251x the noise floor and it named every one (docs/validation.md, \"Friction that is not at the "
            "guideways\")")


def _ripple_stand_in(accepted, rest) -> str:
    """A sentence per accepted :attr:`~bscomp.validate.candidates.base.Candidate.ripple_alike` effect when the final
    residual repeats with the motor angle (module docstring): the order test passed its fit, not the end."""
    orders = (rest or {}).get("orders") or []
    text = ""
    for a in accepted if orders else []:
        if getattr(a.candidate, "ripple_alike", False):
            text += (f". {a.candidate.title}: the residual left repeats {orders[0].order} times per motor revolution, "
                     "and over a short stroke a torque ripple at the motor (cogging, no candidate) drags like it -- it "
                     "may stand in for the ripple: model the ripple and diagnose again")
    return text


def _one_line(accepted, setup) -> str:
    """The sentence for a clearance and a nut-table joint accepted on the same line (module docstring)."""
    gap = next((a for a in accepted if getattr(a.candidate, "group", "") == "backlash"), None)
    joint = next((a for a in accepted if getattr(a.candidate, "group", "") == "nut_table"), None)
    if gap is None or joint is None or setup is None:
        return ""
    try:
        ports = [a.candidate.applicable(setup.reference).ports[:2] for a in (gap, joint)]
    except NotApplicable:
        return ""
    if ports[0] != ports[1]:
        return ""
    k = (joint.values or {}).get("k")
    return (f". {gap.candidate.title} and {joint.candidate.title} sit on the same line of the drive, so in the model "
            "they are one element: the clearance's gap with the joint's spring as its contact"
            + (f" (k = {k:.3g} N/m" + ("; the clearance's own k is not used)" if "k" in (gap.values or {}) else ")")
               if k is not None else "")
            + " and the joint's damper beside it -- the joint may be the clearance's contact re-fitted (its stiffness "
            "and damping), not a joint of its own")


def _together(accepted) -> str:
    """A sentence per pair accepted together (:mod:`~bscomp.validate.pairs`): neither member passed alone, or a
    nonlinear lead that failed a rule with its linear partner (``EffectFit.partner``)."""
    text, seen = "", set()
    for a in accepted:
        if getattr(a, "together", "") and a.together not in seen:
            seen.add(a.name)
            other = next((b for b in accepted if b.name == a.together), None)
            a_partner, o_partner = (getattr(x, "partner", False) for x in (a, other))
            lead, part = (other, a) if a_partner else (a, other)
            if other is not None and (a_partner or o_partner):    # a linear partner of a nonlinear lead
                text += (f". {lead.candidate.title} and {part.candidate.title} were found together: the first alone "
                         "failed a rule (see the table), the second -- screened on the FRFs beside it, which the "
                         "first made worse; the two explain the data within the rules, each needed beside the other")
                continue
            text += (f". {a.candidate.title} and {other.candidate.title if other else a.together} were found "
                     "together: neither alone explains the data (each stood in for both and failed a rule, see the "
                     "table), the two do within the rules, each needed beside the other")
    return text


def _overdamped(accepted) -> str:
    """A sentence per accepted mass on a spring whose fitted damping ratio exceeds :data:`OVERDAMPED`."""
    text = ""
    for a in accepted:
        v = getattr(a, "values", None) or {}
        if {"m", "k", "zeta"} <= set(v) and v["zeta"] > OVERDAMPED:
            z = v["zeta"]
            text += (f". {a.candidate.title}: fitted with {100 * z:.0f} % of critical damping, it has no resonance "
                     "of its own left -- the data show a loss near that point more than a body, and it may stand in "
                     "for damping the model lacks there (a lossy support, coupling or joint; docs/validation.md, "
                     "\"The damping truth\")")
    return text


def _left(rest, found, values) -> str:
    """The sentence on the error left (module docstring)."""
    e = rest["error"]
    text = f". The error left is {e:.3g}x the noise floor"
    if e > UNEXPLAINED:
        text += (f" (above {UNEXPLAINED:g}x: more than the candidates' law shapes left on the bundled truths, so "
                 + ("something else may be missing too -- or an accepted effect's law differs from the drive's more "
                    "than its candidate can follow (docs/validation.md, \"Other draws of the truths\")" if found
                    else "the re-calibrated values absorb part of what is missing: do not trust them before it is "
                    "modelled") + ")")
    frf = rest.get("frf_values") or {}
    if frf and values:
        text += "; the FRFs alone give " + ", ".join(f"{k} = {v:.4g} (the fit to every dataset: "
                                                     f"{100 * (values[k] / v - 1):+.1f} %)" for k, v in frf.items()
                                                     if k in values)
    for o in rest["orders"]:
        text += f"; {o.describe()}"
    return text


def titles(r) -> str:
    """An accepted effect's title, with those the data cannot tell apart from it (one group)."""
    if not r.equivalent:
        return r.candidate.title
    return f"{r.candidate.title} (~ {' ~ '.join(r.equivalent)}: indistinguishable on this model, see the table)"
