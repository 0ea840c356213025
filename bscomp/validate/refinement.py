"""diagnose's candidate refinement: least squares from the best screening point, in this process or on a
worker (``diagnose(..., executor=)``).

What travels to a worker: the model as its registered name, ``.py`` path, :class:`~bscomp.model.ModelSpec`
or a module-level build function (never a built System or compiled CasADi objects), the datasets
(numbers), the overrides and the uncertain parameters, and per fit the candidate with its screening
results. Each worker process builds the :class:`~bscomp.validate.calibration.FitSetup` (the models at the
measurement conditions and their evaluators) once per diagnosis -- a token names it -- and keeps it for the
following rounds.
"""

from __future__ import annotations

import uuid

import numpy as np
from scipy.optimize import minimize_scalar
from threadpoolctl import threadpool_limits

from bscomp.errors import UnknownNameError
from bscomp.kernel.system import System
from bscomp.memo import kept
from bscomp.validate.calibration import FitSetup, parameter_bounds
from bscomp.validate.evaluation import Problem

__all__ = ["refine_candidate", "job_base", "refine_task"]

_CACHE: dict = {}
"""(token, uncertain names) -> FitSetup, per worker process (the two latest diagnoses)."""


def refine_candidate(cand, effects, ev, st, sigmas, scores, pr, frf_only, rnd):
    """Least squares from the best screening point: the candidate alone (into the valley), then jointly
    with the uncertain parameters and the effects accepted before (``pr``). Returns (theta, sol, nfev).

    A mass on a spring (first parameter ``m``, linear) is also refined from the best screening point whose mass
    is more than :data:`OTHER_MASS` x heavier and from the best one more than that lighter, and the best end kept:
    its cost has a valley per mass range -- a light housing with its dashpot at the bound and the bearing
    re-calibrated to its bound stands in for a heavy one (the bundled housing truth, 28.7 kg: from the best point,
    10 kg on a scan along the frequency, the fit ended at 9 kg, 126x the noise floor; seed 2205's 22 kg from a 2.7
    kg grid point at 5.8 kg, 260x). One other start (the best of either side) was not enough: the bundled housing
    truth measured by positions only (rotor.phi, table.s) had its best other point at 0.74 kg, lighter, which ended
    in the same 8.7 kg valley (124x); from the best heavier one, 100 kg, the fit ends at 28.4 kg (0.94)."""
    th, sl, n0 = _refine_from(cand, effects, ev, st, sigmas, scores, pr, frf_only, rnd)
    for other in _other_masses(cand, scores):
        th2, sl2, n2 = _refine_from(cand, effects, ev, st, sigmas, [other], pr, frf_only, rnd)
        n0 += n2
        if sl is None or (sl2 is not None and sl2.cost < sl.cost):
            th, sl = th2, sl2
    return th, sl, pr.nfev + n0


#: A mass on a spring is refined again from the best screening points with a mass this many times off the first's.
OTHER_MASS = 2.0


def _other_masses(cand, scores) -> list:
    """The best screening score whose mass is more than :data:`OTHER_MASS` x the best one's, and the best whose mass
    is less than its 1/:data:`OTHER_MASS` (a linear candidate whose first parameter is a mass ``m``; each where one
    exists)."""
    if cand.nonlinear or len(cand.parameters) < 2 or cand.parameters[0].name != "m":
        return []
    m0 = scores[0][1][0]
    out = []
    for side in (1.0, -1.0):                # heavier, lighter
        sc = next((sc for sc in scores[1:] if np.isfinite(sc[0]) and side * (sc[1][0] - m0) > np.log(OTHER_MASS)),
                  None)
        if sc is not None:
            out.append(sc)
    return out


def _refine_from(cand, effects, ev, st, sigmas, scores, pr, frf_only, rnd):
    """:func:`refine_candidate` from ``scores[0]``: ``(theta, sol, evaluations of the candidate-alone fit)``."""
    pr0 = Problem(ev, sigmas, dict(scores[0][2]), [], effects, st)
    pr0.only_frf = frf_only and not cand.nonlinear
    th0 = scores[0][1]
    if cand.nonlinear:
        th0 = _line_search(pr0, th0, [sc for sc in scores if sc[2] == scores[0][2]])
    th_screen = np.array(th0, float)
    th0, _ = pr0.fit(th0, max_nfev=8 if cand.nonlinear else 15)
    th_prev = pr.theta0()[:len(pr.free) - len(cand.parameters)]   # uncertain + earlier effects
    slow = cand.nonlinear or any(c.nonlinear for c, _, _ in effects)
    # evaluations of the joint fit: a linear candidate after a nonlinear effect fits its own 2 parameters, the
    # effect's and the uncertain ones together (7 on the test bed) through a curved valley -- 12 left the table part
    # of the joint + friction truth at 12.2 kg / 3e7 N/m removing 2 %, 40 find it (34.7 kg / 3.9e7 N/m, the error
    # 2.9 instead of 106); a nonlinear one costs 2-element time series at 8-64 sub-steps per sample: 12
    budget = ((12 if cand.nonlinear else 40) if rnd > 1 else 6) if slow else 20
    th, sl = pr.fit(np.r_[th_prev, th0], max_nfev=budget)
    # a parameter the candidate-alone fit drove to a bound of its prior (where the uncertain parameters are
    # still at their start values it may stand in for one of them) can sit there on a plateau: the cost does
    # not depend on it (a joint damper of 1 N s/m), so the joint fit sees no gradient, and whether it leaves
    # within its budget is decided by round-off. Where the joint fit ended with it still at that bound, the
    # joint fit is also started from the parameter's screening value, and the better of the two ends kept.
    moved = pr0.near_bounds(th0) & ~pr0.near_bounds(th_screen) & pr0.near_bounds(th[len(th_prev):])
    if np.any(moved):
        th, sl = _better_end(pr, th, sl, np.r_[th_prev, np.where(moved, th_screen, th0)], budget)
    # a clearance's contact stiffness (a ``linear`` parameter of a nonlinear candidate) is screened at the FRFs'
    # value; the candidate-alone fit, the uncertain parameters held at their start, can trade it for the gap and
    # lead the joint fit into another valley that ends at a bound -- which rule (e) rejects as a stand-in. Where the
    # joint fit ended with a parameter of the candidate at a bound its screening point was not at, the joint fit is
    # also started from the screening point itself, and the better end kept (seed 2231's 10.4 um clearance on 2.7e9
    # N/m: the first end b 21.9 um, k at the 1e11 N/m bound, 16.0x the noise floor; from the screening point b
    # 11.0 um, k 2.9e9 N/m, 1.18x -- docs/validation.md, "Seeds 2231 and 2331").
    if cand.nonlinear and any(p.linear for p in cand.parameters):
        th_point = np.asarray(scores[0][1], float)
        if sl is not None and np.any(pr0.near_bounds(th[len(th_prev):]) & ~pr0.near_bounds(th_point)):
            th, sl = _better_end(pr, th, sl, np.r_[th_prev, th_point], budget)
    return th, sl, pr0.nfev


def _better_end(pr, th, sl, start, budget):
    """The joint fit ``pr`` also run from ``start``: the end with the lower cost, ``(theta, sol)``."""
    th2, sl2 = pr.fit(start, max_nfev=budget)
    return (th2, sl2) if sl is None or (sl2 is not None and sl2.cost < sl.cost) else (th, sl)


def _line_search(pr, th0, scores):
    """Bounded Brent search on the first free parameter between the scan neighbours of ``th0``."""
    xs = sorted(sc[1][0] for sc in scores if np.all(sc[1][1:] == th0[1:]))
    i = int(np.argmin([abs(x - th0[0]) for x in xs]))
    lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, len(xs) - 1)]
    if hi <= lo:
        return th0

    def f(x):
        th = np.array(th0, float)
        th[0] = x
        return float(np.sum(pr.residual(th) ** 2))

    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 2e-3})
    th = np.array(th0, float)
    th[0] = res.x if res.fun <= f(th0[0]) else th0[0]
    return th


# ---- on a worker ----------------------------------------------------------------------------------------
def job_base(system_or_build, datasets, overrides, harmonics: int = 1) -> tuple:
    """The part of every fit's job that is the same for the whole diagnosis."""
    if isinstance(system_or_build, System):
        raise UnknownNameError(f"diagnose(executor=...): a built System ('{system_or_build.name}') cannot travel to "
                               "a worker: pass the system's registered name, .py path, a ModelSpec or a module-level "
                               "build function")
    return (system_or_build, list(datasets), dict(overrides or {}), int(harmonics), uuid.uuid4().hex)


def refine_task(job, unc, cand, effects, scores, unc_nominal, frf_only, rnd):
    """One candidate's refinement as ``diagnose`` does it in process: ``(theta, sol, nfev)``."""
    model, datasets, overrides, harmonics, token = job
    setup = kept(_CACHE, (token, tuple(unc)),
                 lambda: FitSetup.build(model, datasets, dict(unc), overrides, harmonics=harmonics), 2)
    with threadpool_limits(limits=1, user_api="blas"):
        ev, st = setup.structures.get(effects)
        effects_free = [(c, v, True) for c, v, _ in effects]
        pr = Problem(ev, setup.sigmas, {}, parameter_bounds(setup.reference, unc, unc_nominal), effects_free, st)
        return refine_candidate(cand, effects, ev, st, setup.sigmas, scores, pr, frf_only, rnd)
