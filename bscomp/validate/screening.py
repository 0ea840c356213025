"""diagnose's screening: a candidate scored over its prior before the best are refined (:func:`screen`), and a
nonlinear candidate's ``linear`` parameters taken from the FRFs (:func:`linear_medians`), and which of the screened
are refined (:func:`to_refine`; every linear one where the screen is :func:`blind`). Shared by a round
(:mod:`~bscomp.validate.diagnostics`) and the pair round's linear partner (:mod:`~bscomp.validate.pairs`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from bscomp.validate.conclusion import CLOSEST, UNEXPLAINED
from bscomp.validate.datasets import FrfData
from bscomp.validate.evaluation import Problem

__all__ = ["screen", "linear_medians", "add_baseline", "to_refine", "blind"]


def set_key(unc: dict) -> tuple:
    """A set of uncertain values as a hashable key (the same values in any order: the same key)."""
    return tuple(sorted(unc.items()))


def base_key(unc: dict, frf_only: bool) -> tuple:
    """The key of :func:`add_baseline`'s squared errors: the uncertain values and whether the FRFs alone count."""
    return set_key(unc), bool(frf_only)


def add_baseline(base: dict, ev, st, sigmas, unc: dict, effects, frf_only: bool) -> int:
    """Put the squared error of the model without the candidate (``effects`` only, uncertain values ``unc``, the FRFs
    alone with ``frf_only``) into ``base`` under :func:`screen`'s key, once; returns the evaluations spent (0 when the
    key was there). Each screening score is the improvement over it."""
    key = base_key(unc, frf_only)
    if key in base:
        return 0
    pb = Problem(ev, sigmas, dict(unc), [], effects, st)
    pb.only_frf = frf_only
    base[key] = float(np.sum(pb.residual(np.zeros(0)) ** 2))
    return pb.nfev


def screen(cand, effects, ev, st, sigmas, unc_sets, frf_only, n_scan, n_screen, base=None, ref=None):
    """Scores ``[(error, log-theta, uncertain values)]`` of a candidate over its prior, best first.

    Each start is scored with the uncertain parameters at each of ``unc_sets`` (nominal and re-calibrated:
    the re-calibration may have absorbed part of the effect -- a heavier table for a table part on a
    joint, a softer bearing for a compliant clearance -- or the nominal values may be far off -- a mis-set
    table mass dominating a time series).
    ``frf_only``: a linear candidate after an accepted nonlinear effect is screened on the FRFs (its
    linear evidence; the time series is then dominated by that effect's fitted parameters).
    A nonlinear candidate with ``linear`` parameters (a clearance's contact stiffness) takes those from
    the FRFs at each uncertain set (:func:`linear_medians`); with more free parameters, the others are
    then tried at their prior's +-1 sigma around the best scanned point.
    """
    p0 = cand.parameters[0]
    if cand.nonlinear or len(cand.parameters) == 1:   # one-parameter effects: a dense scan is cheap
        lo = max(math.log(p0.lower), math.log(p0.median) - 2.5 * p0.sigma_log)
        hi = min(math.log(p0.upper), math.log(p0.median) + 2.5 * p0.sigma_log)
        grid = np.exp(np.linspace(lo, hi, n_scan))
    else:
        grid = p0.starts(n_screen)
    use_lin = cand.nonlinear and base is not None and any(p.linear for p in cand.parameters[1:])
    scores, nfev, seen = [], 0, []
    for unc in unc_sets:
        if any(unc == u for u in seen):
            continue
        seen.append(unc)
        meds = [p.median for p in cand.parameters]
        if use_lin:
            meds, n = linear_medians(cand, effects, ev, st, sigmas, unc, meds)
            nfev += n
        starts = [tuple([v] + meds[1:]) for v in grid]
        if len(cand.parameters) >= 2 and not cand.nonlinear:
            # linear effects of two or more parameters (a mass on a spring, a joint's stiffness and damping): a
            # grid over the first two priors -- evaluations are cheap and the cost is far from convex -- the rest
            # (a sub-assembly's damping ratio) at their medians, left to the refinement
            starts = [(a, b, *meds[2:]) for a in grid for b in cand.parameters[1].starts(n_screen)]
            starts += cand.mode_starts(meds, ref)
        elif len(cand.parameters) > 1 and not use_lin:
            starts += list(zip(*[p.starts(n_screen) for p in cand.parameters]))[1:3]
        pr0 = Problem(ev, sigmas, dict(unc), [], effects, st)
        pr0.only_frf = frf_only and not cand.nonlinear
        e0 = (base or {}).get(base_key(unc, pr0.only_frf), 0.0)

        def score(stv, pr0=pr0, e0=e0, unc=unc):
            th = np.log(np.array(stv, float))
            try:
                e = float(np.sum(pr0.residual(th) ** 2)) - e0
            except RuntimeError:
                e = np.inf
            scores.append((e, th, dict(unc)))
            return e

        errs = [score(stv) for stv in starts]
        if use_lin and len(cand.parameters) > 2:
            best = list(starts[int(np.argmin(errs))])
            for i, p in enumerate(cand.parameters[1:], 1):
                if not p.linear:
                    for q in (-1.0, 1.0):
                        score(tuple(best[:i] + [p.starts(3)[1 if q < 0 else 2]] + best[i + 1:]))
        nfev += pr0.nfev
    scores.sort(key=lambda x: x[0])
    return scores, nfev


def linear_medians(cand, effects, ev, st, sigmas, unc, meds):
    """Screening values of a nonlinear candidate's ``linear`` parameters (a clearance's contact stiffness)
    from the FRFs alone, which see the contact engaged and nothing of the gap: a bounded Brent search per
    parameter in log space over its prior, the others at ``meds``. Returns (values, evaluations)."""
    pr = Problem(ev, sigmas, dict(unc), [], effects, st)
    pr.only_frf = True
    if not any(isinstance(d, FrfData) for d in ev.datasets):
        return meds, 0
    out = np.log(np.asarray(meds, float))
    for i, p in enumerate(cand.parameters):
        if not p.linear:
            continue

        def f(x, i=i):
            th = out.copy()
            th[i] = x
            return float(np.sum(pr.residual(th) ** 2))

        res = minimize_scalar(f, bounds=(math.log(p.lower), math.log(p.upper)), method="bounded",
                              options={"xatol": 1e-2})
        out[i] = res.x
    return list(np.exp(out)), pr.nfev


def to_refine(screened, n_refine) -> set:
    """Names of the screened candidates ``[(error, candidate, effects, scores)]`` (best first) to refine: the best of
    each uncertain-value set (improvements over the nominal model reward candidates that absorb a mis-set parameter;
    over the re-calibrated one, those the re-calibration has not absorbed), up to ``n_refine`` in all. Where round 1
    then accepts nothing and its screen is :func:`blind`, diagnose refines every linear candidate too."""
    refine = set()
    for key in {set_key(sc[2]) for _e, _c, _f, scs in screened for sc in scs}:
        by_set = sorted(screened, key=lambda x: min((sc[0] for sc in x[3] if set_key(sc[2]) == key),
                                                    default=np.inf))
        refine |= {x[1].name for x in by_set[:max(n_refine - 1, 1)]}
    refine |= {x[1].name for x in screened[:n_refine]}
    return refine


def blind(screened, base, unc_start, error) -> bool:
    """The screen is blind: more than :data:`~bscomp.validate.conclusion.UNEXPLAINED` x the noise floor is left
    (``error``), yet at the re-calibrated values ``unc_start`` no candidate's best start takes
    :data:`~bscomp.validate.conclusion.CLOSEST` of the squared error there (``base``: :func:`add_baseline`'s sums).

    The re-calibration of the uncertain parameters -- all linear: a table mass, a bearing, a coupling -- may have
    absorbed what a linear candidate would show; a housing's compliance taken up by a softer bearing and a stiffer
    coupling left it 1.1 of a squared error of 36.7 at those values (the other drive's seed 2304, docs/validation.md
    "The screen's blind spot"), below what the best ``n_refine`` were, though refined it takes the error 18.3 ->
    0.99. So where round 1 then accepts nothing, every linear candidate is refined too, each fit free to undo the
    re-calibration (a nonlinear candidate's screen is not blinded by a linear re-calibration), and the round is
    chosen again."""
    total = base.get(base_key(unc_start, False))
    if error <= UNEXPLAINED or total is None:
        return False
    best = min((sc[0] for _e, _c, _f, scs in screened for sc in scs if sc[2] == unc_start), default=0.0)
    return -best < CLOSEST * total
