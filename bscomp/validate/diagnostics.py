r"""Which physical effect is the model missing? Re-calibrate, fit candidate effects, confirm, accept.

:func:`diagnose` automates the guessing of thesis Sec 3.5.2.3-3.5.2.4 on the user's own drive and data:

1. **Noise floors** of every residual block (FRF magnitude and phase per pair, time channels) from the
   data (:func:`~bscomp.validate.noise.noise_levels`: per frequency where an FRF states its coherence);
   residuals are whitened by them, so the normalised error :math:`\chi^2` is 1 where the model explains a
   block within noise.
2. **Re-calibrate** the parameters the drive declares uncertain (``system.validation.uncertain``, each
   with its spread: a wrong value is not a missing effect), bounded least squares in log space on the
   fitted part of the data (FRFs whole, the first half of each time series): the same fit as
   :func:`~bscomp.validate.calibration.calibrate` (:attr:`Diagnosis.calibration`).
3. If every dataset is already explained within noise (:math:`\chi^2 < 1 +` ``noise_tolerance``,
   fitted and held-out parts): **no missing effect**.
4. **Fit every applicable candidate** (:mod:`~bscomp.validate.candidates`; the drive's insertion points
   by role decide which apply; the others are listed as skipped with the reason): screened over its
   prior, the best ``n_refine`` fitted jointly with the uncertain parameters.
5. **Accept** the best candidate only if it (a) lowers the BIC by more than ``bic_threshold``, (b)
   removes at least ``min_drop`` of the *excess* error over the noise floor on the fitted data, (c)
   confirms on held-out data -- the second halves of the time series, which the fit did not see, lose at
   least ``min_heldout_drop`` of their excess (a linear effect fitted to FRFs must also explain the
   time series) -- or, where its evidence is in the FRFs, at least
   :data:`~bscomp.validate.acceptance.CARRIED` and no less than the fitted halves of the same records lost
   (the fit carries over; an accepted effect's law shape can hold the time series' error up), (d) makes no
   dataset clearly worse (normalised error up more than 10 %) and no error
   the user reads clearly worse (FRF magnitude or phase error of a pair, fit % of a channel), (e)
   does not sit at a bound of its prior (a stand-in for something else), and (f) does something the
   parameters already fitted cannot: at least 10 % of its action its own, variance inflation at most 10
   (:mod:`~bscomp.validate.collinearity`; a motor inertia beside a re-calibrated table mass only
   re-distributes the rigid-body inertia) -- unless the fit without it left more than ``UNEXPLAINED`` x the noise
   floor and it brings every dataset within the floor (its partners, free there, could not). The report says which
   of these held. Candidates the data
   cannot tell apart (Vuong's test prefers neither, and they remove the same error:
   :mod:`~bscomp.validate.equivalence`) are reported as **one group** with the one accepted
   (``EffectFit.equivalent``, with what to measure to separate them), not one picked by round-off: within
   a group the lower BIC (the same fit with fewer parameters) is named first.
   When none passes alone, at least two effects may still be added and the error left is above ``UNEXPLAINED`` x
   the noise floor, the round's best refined candidates are fitted **in pairs** (:mod:`~bscomp.validate.pairs`: two
   effects missing at once, each of which stands in for both when fitted alone and fails a rule); a pair passes the
   same rules and each member must be needed beside the other. When every member is nonlinear and the best made an
   FRF clearly worse, the linear candidate that best mends the FRFs on top of it is paired with it too
   (:func:`~bscomp.validate.pairs.linear_partner`: a table part the friction swamped in the screen).
   Repeat (greedy) up to ``max_effects``. FRF files that state their sine amplitude are compared with the
   model at that amplitude (the describing function of its friction and backlash,
   :class:`~bscomp.validate.evaluation.Evaluator`). With FRFs at an amplitude and no time series
   (:func:`~bscomp.validate.amplitude.frf_confirmation`), a linear effect is confirmed only by a second
   amplitude found the same, a nonlinear one not at all: one that passes every rule is reported in
   :attr:`Diagnosis.unconfirmed`, not accepted (a linear one may stand for friction acting at that amplitude;
   a clearance's describing function can imitate friction's).

The model is evaluated by the library's shared engine (:class:`bscomp.simulation.compiled.CompiledModel`, through
:class:`~bscomp.validate.evaluation.Evaluator`): one flattening per model structure and measurement
condition, then modal FRFs and exact-ZOH time series per parameter vector -- the FE test bed included.

Information criterion: with whitened residuals, ``-2 ln L = sum r^2`` and ``BIC = sum r^2 + k ln n``
(``k`` fitted parameters, ``n`` fitted residuals). Gradients: forward differences in log space.
"""

from __future__ import annotations

import inspect
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

from bscomp.kernel.interface import NotApplicable
from bscomp.validate.acceptance import choose, evidence, score
from bscomp.validate.amplitude import amplitude_dependence, amplitude_note, frf_confirmation
from bscomp.validate.arguments import check_diagnose, load_datasets, resolve_candidates
from bscomp.validate.calibration import FitSetup, fit_uncertain, parameter_bounds, user_summary
from bscomp.validate.candidates import default_candidates
from bscomp.validate.conclusion import UNEXPLAINED, conclusion, remainder
from bscomp.validate.datasets import FrfData, warn_amplitude_fit
from bscomp.validate.diagnosis import Diagnosis, EffectFit, Skipped
from bscomp.validate.equivalence import mark_equivalent, simpler_first
from bscomp.validate.evaluation import Problem
from bscomp.validate.pairs import pair_round, wants_pairs
from bscomp.validate.refinement import job_base, refine_candidate, refine_task
from bscomp.validate.screening import add_baseline, blind, screen, to_refine

__all__ = ["diagnose", "Diagnosis", "EffectFit"]


class _Progress:
    def __init__(self, enabled, total):
        self.enabled, self.total, self.k, self.t0 = enabled, max(total, 1), 0, time.perf_counter()

    def step(self, label):
        self.k += 1
        if not self.enabled:
            return
        frac = min(self.k / self.total, 1.0)
        bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
        wall = time.perf_counter() - self.t0
        sys.stderr.write(f"\rdiagnose [{bar}] {self.k}/{self.total} {label[:28]:<28} {wall:5.0f} s")
        sys.stderr.flush()

    def done(self):
        if self.enabled:
            sys.stderr.write("\n")


# ---- the algorithm -------------------------------------------------------------------------------------------
def diagnose(system_or_build, datasets, uncertain=None, candidates=None, max_effects: int = 3,
             n_refine: int = 3, bic_threshold: float = 10.0, min_drop: float = 0.5, min_heldout_drop: float = 0.25,
             noise_tolerance: float = 0.5, overrides: dict | None = None, verbose: bool = False,
             progress: bool | None = None, default_spread: float = 0.2, n_screen: int = 5, n_scan: int = 21,
             harmonics: int = 1, executor=None, **_legacy) -> Diagnosis:
    """Find the physical effects the model is missing (see the module docstring).

    Parameters
    ----------
    system_or_build : System, callable or str
        The nominal model. A name or build function is built at each dataset's conditions (a System is
        used as is, dotted conditions applied as parameter values).
    datasets : list of FrfData / TimeData
    uncertain : list of str or dict, optional
        Parameters to re-calibrate first; a dict gives each one's relative spread. Default: the drive's
        declared ``validation.uncertain``.
    candidates : list of Candidate or of their names, optional
        Default :func:`~bscomp.validate.candidates.default_candidates` (a name picks one of those or of
        :func:`~bscomp.validate.candidates.optional_candidates`; a name given twice is tried once).
    max_effects : int
        Most effects accepted (greedy rounds, >= 0; 0 re-calibrates the uncertain parameters only).
    n_refine : int
        Candidates fitted by least squares per round (the rest are only screened).
    bic_threshold, min_drop, min_heldout_drop, noise_tolerance : float
        Acceptance rules (module docstring).
    overrides : dict, optional
        Build arguments / parameter values for every dataset (the CLI's ``--set``), over the files'
        conditions.
    progress : bool, optional
        Progress bar on stderr (default: when stderr is a terminal).
    harmonics : int
        For an FRF file that states its sine amplitude: the odd harmonics balanced in the model at that amplitude
        (1, the describing function, by default: many candidate fits; :func:`~bscomp.validate.calibrate` balances
        five, which removes the one-harmonic bias of fitted values where the drive sticks and slips at ~6x the
        cost, ``docs/measurements.md``). The acceptance rules are the same.
    executor : concurrent.futures.Executor, optional
        Run each round's candidate fits (the least-squares refinements) on it, e.g. a process pool or a Dask
        ``Client.get_executor()``; the model travels as its name / path / ModelSpec and each worker builds
        its evaluators once (:mod:`bscomp.validate.refinement`). Same result as the serial run.

    **_legacy
        Keywords of earlier versions (:data:`~bscomp.validate.arguments.LEGACY_DIAGNOSE`), ignored with a
        DeprecationWarning; any other keyword is a :class:`~bscomp.errors.UsageError`.

    Returns
    -------
    Diagnosis

    Notes
    -----
    BLAS runs on one thread inside (``threadpoolctl``): the work is thousands of small dense
    eigen-decompositions, which a multi-threaded BLAS slows down by up to 100x on a loaded 2-core machine
    (98x98 ``eigh``: 1.7 ms on one thread, 0.24 s on two under load).
    """
    n = check_diagnose(_legacy, [k for k in inspect.signature(diagnose).parameters if k != "_legacy"],
                       max_effects=max_effects, n_refine=n_refine, bic_threshold=bic_threshold, min_drop=min_drop,
                       min_heldout_drop=min_heldout_drop, noise_tolerance=noise_tolerance,
                       default_spread=default_spread, n_screen=n_screen, n_scan=n_scan, harmonics=harmonics)
    datasets, candidates = load_datasets(datasets, "diagnose"), resolve_candidates(candidates)
    max_effects, n_refine, n_screen, n_scan = n["max_effects"], n["n_refine"], n["n_screen"], n["n_scan"]
    with threadpool_limits(limits=1, user_api="blas"):
        return _diagnose(system_or_build, datasets, uncertain, candidates, max_effects, n_refine, bic_threshold,
                         min_drop, min_heldout_drop, noise_tolerance, overrides, verbose, progress, default_spread,
                         n_screen, n_scan, None if executor is None else
                         (executor, job_base(system_or_build, datasets, overrides, n["harmonics"])), n["harmonics"])


def _diagnose(system_or_build, datasets, uncertain, candidates, max_effects, n_refine, bic_threshold, min_drop,
              min_heldout_drop, noise_tolerance, overrides, verbose, progress, default_spread, n_screen, n_scan,
              remote, harmonics=1):
    t_start = time.perf_counter()
    warn_amplitude_fit(datasets, "diagnose", stacklevel=4, harmonics=harmonics)
    amplitude = amplitude_dependence(datasets)
    unconfirmed_why, unconfirmed = frf_confirmation(amplitude, datasets, harmonics), []
    log = print if verbose else (lambda *a, **k: None)
    progress = sys.stderr.isatty() if progress is None else progress
    setup = FitSetup.build(system_or_build, datasets, uncertain, overrides, default_spread, harmonics)
    ref, unc, sigmas, structures = setup.reference, setup.uncertain, setup.sigmas, setup.structures
    has_frf = any(isinstance(d, FrfData) for d in datasets)
    thresholds = (bic_threshold, min_drop, min_heldout_drop, noise_tolerance)

    cands, skipped = _applicable(candidates, ref, unc)
    prog = _Progress(progress, 2 + max_effects * (len(cands) + n_refine))

    calibration = fit_uncertain(setup)            # the nominal model, then the uncertain parameters re-calibrated
    prog.step("re-calibration")
    nominal, current = calibration.summary_before, calibration.summary_after
    unc_values, unc_std = dict(calibration.values), dict(calibration.std)
    n_evals = calibration.evaluations
    staircase = [("nominal", nominal["error"])]
    user_errs = [("nominal", calibration.user_before)]
    if unc:
        staircase.append(("re-calibrated", current["error"]))
        user_errs.append(("re-calibrated", calibration.user_after))
    log(f"nominal error {nominal['error']:.4g}; re-calibrated {current['error']:.4g} ({unc_values})")

    def within_noise(st):
        vals = st["per_dataset"] + st["heldout_per_dataset"]
        return all(v < 1.0 + noise_tolerance for v in vals)

    accepted_effects, accepted, rounds, pairs = [], [], [], []
    message = ""
    for rnd in range(1, max_effects + 1):
        if within_noise(current):
            message = ("no missing effect found: the model explains every dataset within its noise floor"
                       if not accepted else "")
            break
        taken = {c.group for c, _, _ in accepted_effects}
        pool = [c for c in cands if c.group not in taken]
        if not pool:
            break
        k_now = len(unc) + sum(len(c.parameters) for c, _, _ in accepted_effects)
        fixed_effects = [(c, v, False) for c, v, _ in accepted_effects]
        # screening at the nominal and at the current (re-calibrated) values, in every round (a nonlinear candidate
        # after round 1: the current ones, _round): with the nominal ones alone a mis-set table mass dominates the
        # time series; with the current ones alone a friction accepted before may have taken a table part's mass
        # into the table (docs/validation.md); the joint fits below restart the uncertain parameters from nominal
        unc_start = dict(unc_values)
        unc_nominal = {k: float(ref.get(k)) for k in unc}
        fit_ctx = dict(structures=structures, sigmas=sigmas, ref=ref, unc=unc, has_frf=has_frf, prog=prog,
                       remote=remote)
        ctx = dict(fit_ctx, n_scan=n_scan, n_screen=n_screen, n_refine=n_refine, skipped=skipped)
        results, n, (screened, base) = _round(rnd, pool, fixed_effects, current, k_now, unc_nominal, unc_start,
                                              **ctx)
        n_evals += n
        n_unconfirmed = len(unconfirmed)
        chosen = _rank_and_choose(results, current, datasets, sigmas, ref, thresholds, unconfirmed_why, unconfirmed)
        if chosen is None and rnd == 1 and blind(screened, base, unc_start, current["error"]):
            # the screen could not tell: every linear candidate refined (screening.blind), then chosen again
            more, n = _refine_more(results, screened, current, k_now, unc_nominal, **fit_ctx)
            n_evals += n
            if more:
                del unconfirmed[n_unconfirmed:]
                results[:] = [r for r in results if r.name not in more] + list(more.values())
                chosen = _rank_and_choose(results, current, datasets, sigmas, ref, thresholds, unconfirmed_why,
                                          unconfirmed)
        rounds.append(results)
        log(f"round {rnd}: " + ", ".join(f"{r.name} {r.error_after:.3g} dBIC {r.delta_bic:.0f}" for r in results))
        new_fits = None if chosen is None else [chosen]
        if chosen is None and wants_pairs(current, max_effects - len(accepted)):
            new_fits, tried, n = pair_round(rnd, results, current, fixed_effects, k_now, unc_nominal, thresholds,
                                            structures=structures, sigmas=sigmas, ref=ref, unc=unc,
                                            datasets=datasets, prog=prog, unconfirmed_why=unconfirmed_why,
                                            screening=(n_scan, n_screen))
            pairs += tried
            n_evals += n
        if not new_fits:
            break
        accepted_effects, new, unc_values, unc_std, n = _polish(new_fits, accepted, accepted_effects, current,
                                                                 unc_values, structures, sigmas, ref, unc, datasets)
        n_evals += n
        accepted += new_fits
        label = "+ " + " + ".join(f.name for f in new_fits)
        staircase.append((label, new["error"]))
        user_errs.append((label, user_summary(new["outputs"], datasets)))
        current = new
        if len(accepted) >= max_effects:
            break
    prog.done()
    ranked = list(rounds[0]) if rounds else []
    for r in ranked:
        if not r.evidence:
            r.evidence = f"Signature: {r.candidate.signature}"
    for rr in rounds:
        for r in rr:
            for attr in ("_after", "_problem", "_theta", "_jac"):
                r.__dict__.pop(attr, None)
    within = within_noise(current)
    view = _frf_view(setup) if not within and max_effects and current["error"] > UNEXPLAINED else None
    rest = remainder(current, setup.datasets, within, view)
    last = rounds[-1] if accepted and rounds and not any(r.accepted for r in rounds[-1]) else None
    message = conclusion(message, accepted, unconfirmed, unconfirmed_why, ranked, max_effects, setup, unc_values,
                         rest, last) + (amplitude_note(amplitude, datasets)
           if accepted or not unconfirmed or unconfirmed[0].candidate.nonlinear else "")  # else the linear reason
    return Diagnosis(system=ref, uncertain=list(unc),
                     recalibrated={k: (unc_values[k], unc_std.get(k, float("nan"))) for k in unc},
                     ranked=ranked, accepted=accepted, rounds=rounds, staircase=staircase, message=message,
                     skipped=skipped, user_errors=user_errs,
                     noise=[[np.asarray(b, float).tolist() if np.ndim(b) else float(b) for b in s] for s in sigmas],
                     stats={"wall_s": time.perf_counter() - t_start, "evaluations": n_evals,
                            "conditions": len(setup.systems), "unconverged": _unconverged(structures)},
                     calibration=calibration, amplitude=amplitude,
                     unconfirmed=unconfirmed, remainder=rest, pairs=pairs)


def _rank_and_choose(results, current, datasets, sigmas, ref, thresholds, unconfirmed_why, unconfirmed):
    """Rank a round's fits in place -- refined first, by their predictive error (the mean of the fitted and the
    held-out error: a candidate that only fits the fitted half, e.g. by absorbing noise or a smoothing detail,
    drops), one group where the data cannot tell them apart, the lower BIC named first in it -- and return the
    first that passes every acceptance rule (or None)."""
    results.sort(key=lambda r: (not r.refined, score(r), r.delta_bic))
    mark_equivalent(results, current, datasets, sigmas, ref)
    simpler_first(results)
    return choose(results, current, datasets, thresholds, unconfirmed_why, unconfirmed)


def _refine_more(results, screened, current, k_now, unc_nominal, *, structures, sigmas, ref, unc, has_frf, prog,
                 remote=None):
    """Where round 1 accepted nothing and its screen was blind (:func:`~bscomp.validate.screening.blind`): fit
    every linear candidate not refined yet; returns ``({name: EffectFit}, evaluations)``."""
    done = {r.name for r in results if r.refined}
    rest = [x for x in screened if not x[1].nonlinear and x[1].name not in done]
    if not rest:
        return {}, 0
    prog.total += len(rest)
    fits, n = _fits(1, rest, {x[1].name for x in rest}, current, k_now, unc_nominal, structures=structures,
                    sigmas=sigmas, ref=ref, unc=unc, has_frf=has_frf, prog=prog, remote=remote)
    return {r.name: r for r in fits}, n


def _polish(new_fits, accepted, accepted_effects, current, unc_values, structures, sigmas, ref, unc, datasets):
    """Accept ``new_fits`` (one candidate, or a pair fitted together) and polish: the uncertain parameters and every
    accepted effect re-fitted together, from where the round's joint fit left them (the effects accepted before
    moved in it: started from their previous values instead, the polish of a rattling clearance's round-2 fit at
    1.26 ended at 101, seed 2202). Updates the fits' values, errors and evidence (and the earlier accepted ones'
    values); returns ``(accepted_effects, summary, uncertain values, their std, evaluations)``."""
    start = new_fits[-1]._start
    effects = [(c, {p.name: start.get(f"{c.name}.{p.name}", v[p.name]) for p in c.parameters}, True)
               for c, v, _ in accepted_effects] + [(f.candidate, f.values, True) for f in new_fits]
    ev, st = structures.get(effects)
    start_unc = {k: start.get(k, unc_values[k]) for k in unc}
    pr = Problem(ev, sigmas, {}, parameter_bounds(ref, unc, start_unc), effects, st)
    th, sl = pr.fit(max_nfev=40)
    new = pr.summary(th, len(pr.free))
    vals_all, std_all = pr.values(th), pr.uncertainty(th, sl)
    accepted_effects = [(c, {p.name: vals_all[f"{c.name}.{p.name}"] for p in c.parameters}, True)
                        for c, _, _ in effects]
    for f in [*accepted, *new_fits]:
        f.values = dict(next(v for c, v, _ in accepted_effects if c is f.candidate))
        f.std = {p.name: std_all.get(f"{f.name}.{p.name}", float("nan")) for p in f.candidate.parameters}
    for f in new_fits:
        f.error_after, f.heldout_after = new["error"], new["heldout"]
        f.delta_bic = new["bic"] - current["bic"]
        f.accepted = True
        f.evidence = (f"{f.evidence}. " if f.together else "") + evidence(current, new, datasets, f.candidate)
    return (accepted_effects, new, {k: vals_all[k] for k in unc},
            {k: std_all.get(k, float("nan")) for k in unc}, pr.nfev)


def _unconverged(structures) -> dict:
    """``{"effect + effect": [evaluations whose time series' Newton did not converge, evaluations]}`` of the model
    structures evaluated in this process (:data:`~bscomp.validate.evaluation.FIT_MAX_SUB`)."""
    return {" + ".join(key): [ev.unconverged, ev.n_evaluations] for key, (ev, _) in structures.cache.items()
            if ev.unconverged}


def _frf_view(setup):
    """``(values, outputs)``: the uncertain parameters fitted to the FRFs alone and the no-effect model's outputs on
    every dataset there (:func:`~bscomp.validate.conclusion.remainder`); None without both FRFs and time series."""
    frfs = [i for i, d in enumerate(setup.datasets) if isinstance(d, FrfData)]
    if not frfs or len(frfs) == len(setup.datasets) or not setup.uncertain:
        return None
    cal = fit_uncertain(setup.only(frfs))
    ev0, _ = setup.structures.get([])
    return dict(cal.values), ev0.outputs(dict(cal.values), {})


def _applicable(candidates, ref, unc):
    """(candidates that apply to this drive, [Skipped]): the others are listed with the reason."""
    cands, skipped = [], []
    for c in (default_candidates() if candidates is None else candidates):
        if not c.is_effect:
            continue
        deg = sorted(c.degenerate(ref) & set(unc))
        if deg:
            skipped.append(Skipped(c.name, c.title, f"re-calibrated instead ({', '.join(deg)} uncertain)"))
            continue
        try:
            c.applicable(ref)
        except NotApplicable as exc:
            skipped.append(Skipped(c.name, c.title, f"not applicable: {exc}"))
            continue
        cands.append(c)
    return cands, skipped


def _round(rnd, pool, fixed_effects, current, k_now, unc_nominal, unc_start, *, structures, sigmas, ref, unc,
           has_frf, n_scan, n_screen, n_refine, prog, skipped, remote=None):
    """One round: screen every candidate of the pool on top of the effects accepted so far, refine the
    best ``n_refine`` (:func:`~bscomp.validate.screening.to_refine`); returns ([EffectFit], evaluations,
    ``(screened, base)``: the screen, for :func:`_refine_more`)."""
    n_evals = 0
    # each screening score is the improvement over the model without the candidate at the same
    # uncertain values: a candidate that can do nothing (a joint made rigid) then does not outrank the
    # one that explains the data but needs the re-calibration undone (a table part taken from the table)
    base_ev, base_st = structures.get(fixed_effects)
    base = {}
    for u in (unc_nominal, unc_start):
        for frf_only in {False, has_frf and rnd > 1}:
            n_evals += add_baseline(base, base_ev, base_st, sigmas, u, fixed_effects, frf_only)
    screened = []
    for cand in pool:
        prog.step(cand.name)
        effects = fixed_effects + [(cand, cand.medians(), True)]
        try:
            ev, st = structures.get(effects)
        except NotApplicable as exc:   # on top of the effects accepted so far (e.g. damping replaced)
            skipped.append(Skipped(cand.name, cand.title, f"not applicable in round {rnd}: {exc}"))
            continue
        # after round 1 a nonlinear candidate is screened at the current values only: its screen is 2-element time
        # series (8-64 sub-steps per sample), and what the nominal screen is for -- a part's mass an earlier effect's
        # polish put into the re-calibrated table -- is a structure candidate's (demo's truth: diagnose 67 -> 51 s,
        # the same result)
        sets = [unc_start] if cand.nonlinear and rnd > 1 else [unc_nominal, unc_start]
        scores, n = screen(cand, effects, ev, st, sigmas, sets, has_frf and rnd > 1,
                            n_scan, n_screen, base, ref)
        n_evals += n
        screened.append((scores[0][0], cand, effects, scores))  # (error, theta, uncertain values)
    screened.sort(key=lambda x: x[0])
    results, n = _fits(rnd, screened, to_refine(screened, n_refine), current, k_now, unc_nominal, structures=structures,
                       sigmas=sigmas, ref=ref, unc=unc, has_frf=has_frf, prog=prog, remote=remote)
    return results, n_evals + n, (screened, base)


def _fits(rnd, screened, refine, current, k_now, unc_nominal, *, structures, sigmas, ref, unc, has_frf, prog,
          remote=None):
    """An :class:`EffectFit` of each screened candidate, refined for the names in ``refine`` (else at its best
    screened start); returns ([EffectFit], evaluations)."""
    n_evals = 0
    futures = {}
    if remote is not None:                       # the refinements on the executor, collected in order below
        executor, job = remote
        futures = {cand.name: executor.submit(refine_task, job, unc, cand, effects, scores, unc_nominal,
                                              has_frf and rnd > 1, rnd)
                   for _e, cand, effects, scores in screened if cand.name in refine}
    results = []
    for _e, cand, effects, scores in screened:
        ev, st = structures.get(effects)
        # the effects accepted before are re-fitted with the candidate: an early one was fitted while
        # this one was still missing (friction fitted without the joint absorbs part of it)
        effects_free = [(c, v, True) for c, v, _ in effects]
        pr = Problem(ev, sigmas, {}, parameter_bounds(ref, unc, unc_nominal), effects_free, st)
        if cand.name in refine:
            prog.step(f"fit {cand.name}")
            th, sl, n = futures[cand.name].result() if cand.name in futures else \
                refine_candidate(cand, effects, ev, st, sigmas, scores, pr, has_frf and rnd > 1, rnd)
            n_evals += n
            refined = True
        else:
            th = np.r_[pr.theta0()[:len(pr.free) - len(cand.parameters)], scores[0][1]]  # nominal start
            sl, refined = None, False
        after = pr.summary(th, k_now + len(cand.parameters))
        vals_all = pr.values(th)
        vals = {lbl.split(".", 1)[1]: v for lbl, v in vals_all.items() if lbl.startswith(cand.name + ".")}
        std = {lbl.split(".", 1)[1]: s for lbl, s in pr.uncertainty(th, sl).items()
               if lbl.startswith(cand.name + ".")}
        r = EffectFit(candidate=cand, values=vals, std=std, error_before=current["error"],
                      error_after=after["error"], delta_bic=after["bic"] - current["bic"],
                      heldout_before=current["heldout"], heldout_after=after["heldout"], refined=refined,
                      round=rnd, per_dataset=(current["per_dataset"], after["per_dataset"]),
                      _start=vals_all)
        r._after, r._problem, r._theta = after, pr, th
        r._jac = None if sl is None or getattr(sl, "jac", None) is None else np.asarray(sl.jac, float)
        results.append(r)
    return results, n_evals
