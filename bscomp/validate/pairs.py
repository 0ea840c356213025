r"""diagnose's pair round: two candidates fitted together when no single one passes.

Two effects missing at once can each fail alone: fitted alone, a candidate stands in for both and bends to do so,
and the held-out data or another dataset says it is wrong. On the ``damping`` truth drawn with seed 2203
(``docs/validation.md``: viscous dashpots at the thrust bearing and across the coupling, which the model lacks)
the coupling's damper alone took the fitted error from 108 to 13.8 but the held-out halves only from 5.63 to 5.17
(10 % of their excess, 25 % needed), the bearing's alone made them worse, and nothing was found.

When a round accepts nothing, at least two effects may still be added (``max_effects``) and the error left is
above :data:`~bscomp.validate.conclusion.UNEXPLAINED` x the noise floor, the round's best refined candidates
(:data:`PAIR_MEMBERS`, each of which lowered the BIC by ``bic_threshold`` alone, no two of one group) are fitted in
pairs, jointly with the uncertain parameters and the effects accepted before. A pair is accepted only if

1. it passes every rule a single candidate must (:func:`~bscomp.validate.acceptance.verdict` against the fit
   without either; rule f, the own share of the action, for each member against all other free parameters), and
2. **each member is needed beside the other**: against the other's own fit of the round the pair lowers the BIC by
   ``bic_threshold``, removes ``min_drop`` of the excess error that fit left and, where its held-out error was
   above the noise, ``min_heldout_drop`` of that excess -- the rules b and c of accepting it second, in both
   orders (a rider that does nothing of its own, or a pair whose one member carries the fit, fails here).

**A linear partner for a nonlinear lead.** When every member is nonlinear and the best one made an FRF clearly worse
(the re-calibration had bought the FRFs with what a missing linear part does, and that part, screened on time
series the nonlinear effect swamps, was never refined), the linear candidates are screened on the FRFs on top of
the best member's fit, as a later round would screen them after accepting it, and the best of them is paired with
it (:func:`linear_partner`). On the thesis drive's joint + friction truth of seed 2213 (a 52 kg part on its joint
beside 1414 N of guideway friction) the friction alone took 4.1e7 -> 327 but the motor FRF's phase error
4.4 -> 8.9 deg, and the three members were the two guideway laws and the friction torque: no pair held the part.

Of the pairs that pass, the one with the lowest predictive error (:func:`~bscomp.validate.acceptance.score`) is
accepted; both members enter the staircase as one step. Every pair fitted is reported
(:attr:`~bscomp.validate.diagnosis.Diagnosis.pairs`) with its verdict.
"""

from __future__ import annotations

from dataclasses import replace
from itertools import combinations

import numpy as np

from bscomp.kernel.interface import NotApplicable
from bscomp.validate.acceptance import clearly_worse, score, verdict
from bscomp.validate.calibration import parameter_bounds, user_summary
from bscomp.validate.collinearity import own_share
from bscomp.validate.conclusion import UNEXPLAINED, excess_drop
from bscomp.validate.diagnosis import EffectFit
from bscomp.validate.evaluation import Problem
from bscomp.validate.screening import add_baseline, screen

__all__ = ["pair_round", "PAIR_MEMBERS", "wants_pairs", "linear_partner"]

#: The best refined candidates of a round paired with each other (3: three joint fits).
PAIR_MEMBERS = 3


def wants_pairs(current: dict, slots: int) -> bool:
    """Whether a round that accepted nothing tries pairs: two effects may still be added and the error left is above
    :data:`~bscomp.validate.conclusion.UNEXPLAINED` x the noise floor."""
    return slots >= 2 and current["error"] > UNEXPLAINED


def _built(structures, effects, prog, label):
    """``(evaluator, structure)`` of ``effects`` (the progress bar stepped with ``label``), or None where one of them
    does not apply on top of the others."""
    try:
        built = structures.get(effects)
    except NotApplicable:
        return None
    if prog is not None:
        prog.step(label)
    return built


def linear_partner(members, results, fixed_effects, unc, *, structures, sigmas, ref, screening, prog=None):
    """The linear candidate paired with the best of ``members`` when every member is nonlinear and the best made an
    FRF clearly worse than the re-calibrated model (module docstring), or None.

    Every linear candidate of ``results`` outside the best member's group is screened on the FRFs
    (:func:`~bscomp.validate.screening.screen`, ``screening = (n_scan, n_screen)``) on top of the effects accepted
    before and the best member at its fitted values and uncertain parameters; the largest improvement wins. Returns
    ``(partner, evaluations)``: a copy of that candidate's round result (its own fit alone kept for rule 2) with the
    screened values, or None when nothing improves the FRFs."""
    if not members or not all(r.candidate.nonlinear for r in members):
        return None, 0
    best = members[0]
    if not clearly_worse(best.user_before, best.user_after, frf_only=True):
        return None, 0
    unc_best = {k: float(best._start.get(k, ref.get(k))) for k in unc}
    fixed = [(c, v, False) for c, v, _ in fixed_effects] + [(best.candidate, dict(best.values), False)]
    base = {}
    n_evals = add_baseline(base, *structures.get(fixed), sigmas, unc_best, fixed, True)
    found = None
    for r in results:
        if r.candidate.nonlinear or r.candidate.group == best.candidate.group:
            continue
        effects = fixed + [(r.candidate, r.candidate.medians(), True)]
        built = _built(structures, effects, prog, f"partner {r.name}")
        if built is None:
            continue
        ev, st = built
        scores, n = screen(r.candidate, effects, ev, st, sigmas, [unc_best], True, *screening, base, ref)
        n_evals += n
        if scores and scores[0][0] < 0.0 and (found is None or scores[0][0] < found[0]):
            found = (scores[0][0], r, scores[0][1])
    if found is None:
        return None, n_evals
    _, r, theta = found
    values = {p.name: float(v) for p, v in zip(r.candidate.parameters, np.exp(theta), strict=True)}
    partner = replace(r, values=values, _start={**unc_best, **{f"{r.name}.{k}": v for k, v in values.items()}})
    partner._after = r._after
    return partner, n_evals


def pair_round(rnd, results, current, fixed_effects, k_now, unc_nominal, thresholds, *, structures, sigmas, ref,
               unc, datasets, prog=None, unconfirmed_why=("", ""), screening=None):
    """The pairs of the round's best refined candidates fitted together (module docstring).

    Returns ``(accepted, tried, evaluations)``: the two members' :class:`EffectFit` of the pair accepted (or None)
    and a dict per pair fitted (``members``, ``round``, ``values``, ``error``, ``heldout``, ``delta_bic``, ``accepted``,
    ``verdict``), in the order fitted. ``unconfirmed_why`` (:func:`~bscomp.validate.amplitude.frf_confirmation`: for
    linear, for nonlinear candidates): a pair that passes every rule but has a member nothing confirms (FRFs at one
    stated amplitude, no time series) is not accepted, as a single is not."""
    bic_thr = thresholds[0]
    members = [r for r in results if r.refined and r.delta_bic < -bic_thr][:PAIR_MEMBERS]
    user_now = user_summary(current["outputs"], datasets)
    tried, passed, n_evals = [], [], 0
    pairs = list(combinations(members, 2))
    if screening is not None:
        partner, n_evals = linear_partner(members, results, fixed_effects, unc, structures=structures, sigmas=sigmas,
                                          ref=ref, screening=screening, prog=prog)
        pairs += [(members[0], partner)] if partner is not None else []
    for a, b in pairs:
        if a.candidate.group == b.candidate.group:
            continue
        effects = [(c, v, True) for c, v, _ in fixed_effects] + [(a.candidate, dict(a.values), True),
                                                                 (b.candidate, dict(b.values), True)]
        built = _built(structures, effects, prog, f"pair {a.name}+{b.name}")
        if built is None:
            continue
        ev, st = built
        start_unc = {k: a._start.get(k, unc_nominal[k]) for k in unc}
        pr = Problem(ev, sigmas, {}, parameter_bounds(ref, unc, start_unc), effects, st)
        slow = any(c.nonlinear for c, _, _ in effects)
        th, sl = pr.fit(max_nfev=12 if slow else 30)
        n_evals += pr.nfev
        after = pr.summary(th, k_now + len(a.candidate.parameters) + len(b.candidate.parameters))
        fits, why = _judge(a, b, pr, th, sl, after, current, user_now, datasets, thresholds, rnd)
        why = why or _unconfirmed(a, b, unconfirmed_why)
        tried.append({"members": [a.name, b.name], "round": rnd, "values": {f"{r.name}.{k}": v for r in fits
                                                               for k, v in r.values.items()},
                      "error": after["error"], "heldout": after["heldout"],
                      "delta_bic": after["bic"] - current["bic"], "accepted": False, "verdict": why or "passes"})
        if not why:
            passed.append((score(fits[0]), len(tried) - 1, fits))
    if not passed:
        return None, tried, n_evals
    _, i, fits = min(passed, key=lambda x: x[0])
    tried[i]["accepted"] = True
    tried[i]["verdict"] = "accepted"
    return fits, tried, n_evals


def _judge(a, b, pr, th, sl, after, current, user_now, datasets, thresholds, rnd):
    """``([EffectFit of a, of b], why not or "")`` of one pair fit (rules 1 and 2 of the module docstring)."""
    labels = [f.label for f in pr.free]
    vals_all, std_all = pr.values(th), pr.uncertainty(th, sl)
    jac = None if sl is None or getattr(sl, "jac", None) is None else np.asarray(sl.jac, float)
    dbic = after["bic"] - current["bic"]
    fits = []
    for r, other in ((a, b), (b, a)):
        mine = [i for i, lbl in enumerate(labels) if lbl.startswith(r.name + ".")]
        share, partners = own_share(jac, mine, labels) if jac is not None else (1.0, [])
        f = EffectFit(candidate=r.candidate, values={lbl.split(".", 1)[1]: vals_all[lbl] for lbl in
                                                     (labels[i] for i in mine)},
                      std={lbl.split(".", 1)[1]: std_all.get(lbl, float("nan")) for lbl in (labels[i] for i in mine)},
                      error_before=current["error"], error_after=after["error"], delta_bic=dbic,
                      heldout_before=current["heldout"], heldout_after=after["heldout"], refined=True, round=rnd,
                      per_dataset=(current["per_dataset"], after["per_dataset"]), own_share=share,
                      trades_with=[p for p, _ in partners], together=other.name, partner=not r.refined,
                      _start=vals_all)
        fits.append((f, (share, partners)))
    tradeoff = min((t for _, t in fits), key=lambda t: t[0])
    fits = [f for f, _ in fits]
    bound = pr.at_bound(th, [lbl for lbl in labels if lbl.startswith((a.name + ".", b.name + "."))])
    worse = clearly_worse(user_now, user_summary(after["outputs"], datasets))
    ok, why = verdict(current, after, dbic, bound, worse, thresholds, tradeoff)
    needs = [w for w in (_needed(r, other, after, thresholds) for r, other in ((a, b), (b, a))) if w]
    why = "; ".join([why] * (not ok) + needs)
    alone = "; ".join(f"{r.name} alone: " + (f"{r.verdict or 'not judged'}" if r.refined else
                                             f"screened only (the linear partner, screened on the FRFs beside "
                                             f"{other.name})") for r, other in ((a, b), (b, a)))
    for f in fits:
        f.verdict = "accepted" if not why else why
        f.evidence = f"fitted together with {f.together}; neither passed alone ({alone})"
    return fits, why


def _unconfirmed(a, b, unconfirmed_why) -> str:
    """Why a pair that passes every rule is still not accepted: a member nothing confirms, or ""."""
    why = [w for w in (unconfirmed_why[1 if r.candidate.nonlinear else 0] for r in (a, b)) if w]
    return f"passes every rule but is not confirmed: {why[0]}" if why else ""


def _needed(r, other, after, thresholds) -> str:
    """Why ``r`` is not needed beside ``other`` (rule 2: accepting it second after ``other``'s own fit), or ""."""
    bic_thr, min_drop, min_held, tol = thresholds
    alone = other._after
    why = []
    if after["bic"] - alone["bic"] >= -bic_thr:
        why.append(f"BIC not lower by {bic_thr:g} than {other.name} alone ({after['bic'] - alone['bic']:+.1f})")
    drop = excess_drop(alone["error"], after["error"])
    if drop < min_drop:
        why.append(f"removes only {100 * drop:.0f} % of the excess error {other.name} alone left (needs "
                   f"{100 * min_drop:.0f} %)")
    hb, ha = alone["heldout"], after["heldout"]
    if hb is not None and hb > 1.0 + tol and excess_drop(hb, ha) < min_held:
        why.append(f"not confirmed beside {other.name} on held-out data ({hb:.3g} -> {ha:.3g})")
    return f"{r.name} not needed beside {other.name}: " + ", ".join(why) if why else ""
