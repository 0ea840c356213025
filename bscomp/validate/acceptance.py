"""diagnose's acceptance rules: a candidate's fit judged against the fit without it (rules a-f of
:mod:`bscomp.validate.diagnostics`), in words the report repeats."""

from __future__ import annotations

from bscomp.validate.calibration import user_summary
from bscomp.validate.collinearity import MIN_OWN_SHARE, own_share
from bscomp.validate.conclusion import UNEXPLAINED, excess_drop, residual_orders
from bscomp.validate.datasets import FrfData

__all__ = ["clearly_worse", "verdict", "score", "evidence", "choose", "ripple_left", "CARRIED"]

#: Held-out halves that lose less than ``min_heldout_drop`` of their excess still confirm an effect when they lose
#: at least this share and at least the share the same records' fitted first halves lost: the fit's action on the
#: time series carries over, and its evidence is in the FRFs, which have no held-out part (another drive's table part
#: beside a friction whose law the candidate cannot follow: FRF 17.5 -> 1.14, fitted halves 6.46 -> 6.51, held-out
#: 9.45 -> 8.06 -- docs/validation.md, "Another drive").
CARRIED = 0.1


def clearly_worse(before: dict, after: dict, frf_only: bool = False) -> list:
    """User-visible errors that got clearly worse (magnitude/phase of an FRF pair, fit % of a channel; ``frf_only``:
    the FRFs' alone)."""
    worse = []
    for ub, ua in zip(before.get("per_dataset", []), after.get("per_dataset", [])):
        for b, a in zip(ub.get("frf", []), ua.get("frf", [])):
            if a["mag_mean_abs_dlog10"] > 1.2 * b["mag_mean_abs_dlog10"] + 0.005:
                worse.append(f"{b['pair'][0]}->{b['pair'][1]} magnitude error {b['mag_mean_abs_dlog10']:.3g} -> "
                             f"{a['mag_mean_abs_dlog10']:.3g} decades")
            if a["phase_deg_rms"] > 1.2 * b["phase_deg_rms"] + 1.0:
                worse.append(f"{b['pair'][0]}->{b['pair'][1]} phase error {b['phase_deg_rms']:.3g} -> "
                             f"{a['phase_deg_rms']:.3g} deg")
        for b, a in zip([] if frf_only else ub.get("time", []), ua.get("time", [])):
            if a["fit_percent"] < b["fit_percent"] - 2.0:
                worse.append(f"{b['channel']} fit {b['fit_percent']:.1f} -> {a['fit_percent']:.1f} %")
    return worse


def verdict(before, after, dbic, at_bound, worse, thresholds, tradeoff=(1.0, [])):
    """(accepted?, words) for one candidate fit against the acceptance rules of the module docstring;
    ``tradeoff``: (own share of its action, partners), :func:`~bscomp.validate.collinearity.own_share`."""
    bic_thr, min_drop, min_held, tol = thresholds
    why_not = []
    drop = excess_drop(before["error"], after["error"])
    if dbic >= -bic_thr:
        why_not.append(f"BIC not lower by {bic_thr:g} ({dbic:+.1f})")
    if drop < min_drop:
        why_not.append(f"removes only {100 * drop:.0f} % of the error above the noise floor (needs "
                       f"{100 * min_drop:.0f} %)")
    hb, ha = before["heldout"], after["heldout"]
    if hb is not None:
        hdrop = excess_drop(hb, ha)
        if hb > 1.0 + tol and hdrop < min_held and not carried_over(before, after, hdrop):
            why_not.append(f"not confirmed on held-out data (error {hb:.3g} -> {ha:.3g})")
    for i, (b, a) in enumerate(zip(before["per_dataset"] + before["heldout_per_dataset"],
                                   after["per_dataset"] + after["heldout_per_dataset"])):
        if a > 1.1 * b + 0.1:
            why_not.append(f"dataset {i + 1} worse ({b:.3g} -> {a:.3g})")
    if at_bound:
        why_not.append(f"{', '.join(at_bound)} at a bound of the prior (a stand-in for something else)")
    share, partners = tradeoff
    # its partners were free in the fit without it: if that fit left > UNEXPLAINED x the noise floor and this one
    # reaches the floor, what it does is no re-distribution of theirs, however collinear at the solution (rule f)
    floor = all(v < 1.0 + tol for v in after["per_dataset"] + after["heldout_per_dataset"])
    if share < MIN_OWN_SHARE and not (before["error"] > UNEXPLAINED and floor):
        with_ = ", ".join(p for p, _ in partners) or "the parameters already fitted"
        why_not.append(f"trades off against {with_}: only {100 * share:.2g} % of what it does is its own (variance "
                       f"inflation {1 / max(share, 1e-300):.3g} > {1 / MIN_OWN_SHARE:.3g}): a re-distribution, not a "
                       "missing part")
    why_not += [f"{w} (clearly worse)" for w in worse]
    return (not why_not), "; ".join(why_not)


def carried_over(before: dict, after: dict, hdrop: float) -> bool:
    """Whether held-out halves that lost ``hdrop`` of their excess confirm the fit anyway (:data:`CARRIED`): at
    least that share, and at least what the fitted first halves of the same time series lost."""
    fb, fa = before.get("fitted_split") or [], after.get("fitted_split") or []
    if not fb or len(fb) != len(fa):
        return False
    return hdrop >= max(CARRIED, excess_drop(sum(fb) / len(fb), sum(fa) / len(fa)))


def score(r):
    return r.error_after if r.heldout_after is None else 0.5 * (r.error_after + r.heldout_after)


def evidence(before, after, datasets, cand):
    parts = []
    for i, (d, b, a) in enumerate(zip(datasets, before["per_dataset"], after["per_dataset"])):
        what = "FRF" if isinstance(d, FrfData) else "time series (first half, fitted)"
        parts.append(f"{what} {i + 1}: error {b:.3g} -> {a:.3g}")
    if before["heldout"] is not None:
        parts.append(f"held-out second halves: {before['heldout']:.3g} -> {after['heldout']:.3g}")
    return "; ".join(parts) + f". Signature: {cand.signature}"


def ripple_left(outputs, datasets) -> str:
    """Why a :attr:`~bscomp.validate.candidates.base.Candidate.ripple_alike` effect (a friction torque at the motor)
    is not accepted -- the residual it leaves (``outputs``: its fit's) is periodic in the motor angle
    (:func:`~bscomp.validate.conclusion.residual_orders`): over a short stroke a torque ripple at the motor drags like
    it (the other drive's ripple, seed 2304: a friction torque took 766 -> 155, rotor.w then 8 periods per revolution,
    p 7e-4; docs/validation.md) -- or "" when no order is found."""
    orders = sorted(residual_orders(outputs, datasets, "").values(), key=lambda o: o.p_value)
    if not orders:
        return ""
    o = orders[0]
    return (f"the residual it leaves repeats {o.order} times per motor revolution ({o.channel}, p {o.p_value:.1g}): "
            "over a short stroke a torque ripple at the motor (cogging, no candidate) drags like a friction torque -- "
            "model the ripple, then try it again")


def choose(results, current, datasets, thresholds, unconfirmed_why=("", ""), unconfirmed=None):
    """The first refined candidate (in ranking order) that passes every acceptance rule; each gets its
    verdict and evidence in words. With ``unconfirmed_why``
    (:func:`~bscomp.validate.amplitude.frf_confirmation`: for linear, for nonlinear candidates) a candidate
    that passes every rule but is not confirmed is appended to ``unconfirmed``, not accepted."""
    user_now = user_summary(current["outputs"], datasets)
    for r in results:
        if not r.refined:
            r.verdict = "screened only"
            continue
        bound = r._problem.at_bound(r._theta, [f"{r.name}.{p.name}" for p in r.candidate.parameters])
        r.user_before, r.user_after = user_now, user_summary(r._after["outputs"], datasets)
        tradeoff = (1.0, [])
        if r.__dict__.get("_jac") is not None:
            labels = [f.label for f in r._problem.free]
            mine = [i for i, lbl in enumerate(labels) if lbl.startswith(r.name + ".")]
            tradeoff = own_share(r._jac, mine, labels)
            r.own_share, r.trades_with = tradeoff[0], [p for p, _ in tradeoff[1]]
        ok, why = verdict(current, r._after, r.delta_bic, bound, clearly_worse(user_now, r.user_after),
                           thresholds, tradeoff)
        if ok and r.candidate.ripple_alike:
            why = ripple_left(r._after["outputs"], datasets)
            ok = not why
        why_not_confirmed = unconfirmed_why[1 if r.candidate.nonlinear else 0] if unconfirmed_why else ""
        if ok and why_not_confirmed:
            r.verdict = f"passes every rule but is not confirmed: {why_not_confirmed}"
            r.evidence = evidence(current, r._after, datasets, r.candidate)
            if unconfirmed is not None:
                unconfirmed.append(r)
            continue
        r.verdict = "accepted" if ok else why
        r.evidence = evidence(current, r._after, datasets, r.candidate)
        if ok:
            return r
    return None
