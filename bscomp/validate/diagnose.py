"""Which physical effect is the model missing? Re-calibrate, fit candidate effects, rank, accept greedily.

:func:`diagnose` automates the guessing of thesis Sec 3.5.2.3-3.5.2.4:

1. **Re-calibrate** the parameters the user marks as uncertain (a wrong value is not a missing effect):
   bounded least squares (``scipy.optimize.least_squares``, trust-region reflective) in log space on the
   residual vector of all datasets.
2. **Fit every candidate** of the library (:mod:`~bscomp.validate.candidates`) on top of the current
   model: each is first *screened* at ``n_screen`` points of its prior, the most promising ``n_refine`` are
   fitted by bounded least squares from the best ``n_starts`` screening points (the candidate's parameters
   alone, then together with the uncertain ones).
3. **Rank** by the information criterion (error reduction against parameters spent), and **accept**
   the best only if the BIC improves by more than ``bic_threshold`` *and* the error falls by at least
   ``min_drop``; the accepted effect and the uncertain parameters are then re-fitted together
   (polish). Repeat (greedy) up to ``max_effects``; then a *swap* pass replaces an early effect by a
   runner-up of its round if that lowers the BIC with everything re-fitted (an effect accepted while
   another one was still missing may have stood in for it). If the first round accepts nothing:
   "no missing effect found".

Residuals and error
-------------------
The residual of a dataset is the compare engineer's (:mod:`~bscomp.validate.residuals`):
coherence-weighted ``log10`` magnitude and phase errors for FRFs, ``(y - y_hat)/rms(y)`` per channel for
time series. The **error** reported everywhere is :func:`~bscomp.validate.residuals.cost`'s: the mean over
datasets of the mean squared residual; the fit minimises the same quantity (each dataset's residuals
scaled by ``1/sqrt(n_d)``). The model is evaluated by the fast engine of :mod:`._evaluate` (one
flattening per model structure; FRF from the symbolic linearization, time series by fixed-step Radau
IIA), not by re-flattening per evaluation.

Information criterion
---------------------
With an unknown noise variance per dataset (profile likelihood),
``-2 ln L = sum_d n_d ln(RSS_d / n_d)`` and ``BIC = -2 ln L + k ln(n)``, ``k`` the number of fitted
parameters (uncertain + effects), ``n`` the number of residuals.

Gradients
---------
The Jacobian used by the least squares and for the uncertainties is by forward finite differences in
log-parameter space (``scipy``'s ``2-point``): a time-series evaluation is a fixed-step simulation whose
CasADi forward sensitivities measured ~9x the cost of a plain run, against ``k+1`` runs for differences.
Uncertainty: ``cov = s^2 (J^T J)^{-1}`` at the optimum with ``s^2 = RSS/(n - k)``, mapped from log space.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .candidates import Candidate, default_candidates
from .measurements import FrfData, TimeData
from .residuals import frf_residuals, time_residuals

__all__ = ["diagnose", "Diagnosis", "EffectFit"]


# ---- model evaluation for one structure ------------------------------------------------------------------
class _Model:
    """One model structure (base + effects) evaluated at parameter overrides on all datasets."""

    def __init__(self, system, linear_system, datasets):
        from bscomp.flatten import flatten

        from ._evaluate import FrfEvaluator, TimeSimulator

        self.system, self.linear_system = system, linear_system
        self.datasets = datasets
        self.dae = flatten(system)
        self.dae_lin = flatten(linear_system) if linear_system is not system else self.dae
        self._ev = []
        for d in datasets:
            if isinstance(d, FrfData):
                self._ev.append(FrfEvaluator(self.dae_lin, d.pairs))
            elif isinstance(d, TimeData):
                dts = np.diff(d.t)
                if np.max(np.abs(dts - dts[0])) > 1e-6 * dts[0]:
                    raise ValueError(f"{d.source}: diagnose needs uniformly sampled time series")
                self._ev.append(TimeSimulator(self.dae, float(dts[0]), list(d.outputs)))
            else:
                raise TypeError(f"expected FrfData or TimeData, got {type(d).__name__}")

    def _p(self, dae, overrides):
        p = dae.p0.copy()
        for k, v in overrides.items():
            if k in dae.p_names:
                p[dae.p_names.index(k)] = v
        return p

    def outputs(self, overrides):
        out = []
        for d, ev in zip(self.datasets, self._ev):
            if isinstance(d, FrfData):
                out.append(ev(d.freqs, self._p(self.dae_lin, overrides)))
            else:
                U = np.vstack([d.inputs[n] if n in d.inputs else np.zeros(len(d.t)) for n in self.dae.u_names])
                Y = ev.run(U, self._p(self.dae, overrides))
                out.append({n: Y[i] for i, n in enumerate(d.outputs)})
        return out

    def residual_blocks(self, overrides):
        blocks = []
        for d, y in zip(self.datasets, self.outputs(overrides)):
            r = frf_residuals(y, d) if isinstance(d, FrfData) else time_residuals(y, d)
            blocks.append(np.where(np.isfinite(r), r, 1e3))
        return blocks


def _stats(blocks, k):
    n_d = np.array([b.size for b in blocks], float)
    rss_d = np.array([float(np.sum(b * b)) for b in blocks])
    err = float(np.mean(rss_d / n_d))
    n = float(n_d.sum())
    m2ll = float(np.sum(n_d * np.log(np.maximum(rss_d / n_d, 1e-300))))
    return {"error": err, "error_per_dataset": (rss_d / n_d).tolist(), "bic": m2ll + k * math.log(n),
            "aic": m2ll + 2 * k, "n": int(n)}


# ---- a fit problem: free parameters mapped to overrides ----------------------------------------------------
@dataclass
class _Free:
    label: str          # "table.m" or "nut_table_joint.k"
    lower: float
    upper: float
    start: float


class _Problem:
    def __init__(self, model, fixed, uncertain, effects):
        """``effects``: list of (candidate, values dict, fit?)."""
        self.model, self.fixed = model, dict(fixed)
        self.uncertain = list(uncertain)
        self.effects = effects
        self.free = []
        for name, (lo, hi, v) in self.uncertain:
            self.free.append(_Free(name, lo, hi, v))
        for cand, values, fit in effects:
            if fit:
                for p in cand.parameters:
                    self.free.append(_Free(f"{cand.name}.{p.name}", p.lower, p.upper, values.get(p.name, p.median)))
        self.nfev = 0

    def overrides(self, theta):
        vals = dict(zip([f.label for f in self.free], np.exp(theta)))
        ov = dict(self.fixed)
        for name, _ in self.uncertain:
            ov[name] = vals[name]
        for cand, values, fit in self.effects:
            v = dict(values)
            if fit:
                v.update({p.name: vals[f"{cand.name}.{p.name}"] for p in cand.parameters})
            ov.update(cand.overrides(v, self.model.system))
        return ov

    def values(self, theta):
        return dict(zip([f.label for f in self.free], np.exp(theta).tolist()))

    def residual(self, theta):
        self.nfev += 1
        blocks = self.model.residual_blocks(self.overrides(theta))
        return np.concatenate([b / math.sqrt(b.size) for b in blocks])

    def bounds(self):
        return (np.log([f.lower for f in self.free]), np.log([f.upper for f in self.free]))

    def theta0(self):
        lo, hi = self.bounds()
        return np.clip(np.log([f.start for f in self.free]), lo + 1e-9, hi - 1e-9)

    def fit(self, theta0=None, max_nfev=None):
        from scipy.optimize import least_squares

        theta0 = self.theta0() if theta0 is None else np.asarray(theta0, float)
        if not self.free:
            return theta0, None
        lo, hi = self.bounds()
        sol = least_squares(self.residual, np.clip(theta0, lo + 1e-9, hi - 1e-9), bounds=(lo, hi), method="trf",
                            diff_step=1e-4, x_scale=1.0, max_nfev=max_nfev, xtol=1e-6, ftol=1e-8)
        return sol.x, sol

    def uncertainty(self, theta, sol):
        """Standard deviations of the free parameters (``cov = s^2 (J^T J)^-1``, delta method from logs)."""
        if sol is None or sol.jac is None:
            return {}
        J = np.asarray(sol.jac)
        r = np.asarray(sol.fun)
        dof = max(r.size - J.shape[1], 1)
        s2 = float(r @ r) / dof
        try:
            cov = s2 * np.linalg.pinv(J.T @ J)
        except np.linalg.LinAlgError:
            return {}
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        return {f.label: float(math.exp(t) * s) for f, t, s in zip(self.free, theta, sd)}


# ---- results -------------------------------------------------------------------------------------------------
@dataclass
class EffectFit:
    """One candidate effect fitted in one round.

    Attributes
    ----------
    candidate : Candidate
    values, std : dict
        Fitted free parameters and their standard deviations (after polishing, if accepted).
    error_before, error_after : float
        Error (``cost``) of the model without / with the effect.
    delta_bic : float
        BIC with the effect minus BIC without (negative = better).
    accepted : bool
    evidence : str
        Plain words: which datasets improved, the candidate's signature, correlations.
    refined : bool
        False when only screened (not fitted by least squares).
    """

    candidate: Candidate
    values: dict
    std: dict
    error_before: float
    error_after: float
    delta_bic: float
    accepted: bool = False
    evidence: str = ""
    refined: bool = True
    per_dataset: tuple = ()
    round: int = 1
    _start: dict = field(default_factory=dict, repr=False)

    @property
    def name(self):
        return self.candidate.name

    @property
    def drop(self) -> float:
        """Relative error reduction ``1 - after/before``."""
        return 1.0 - self.error_after / self.error_before if self.error_before > 0 else 0.0

    def to_dict(self):
        return {"candidate": self.name, "title": self.candidate.title, "where": self.candidate.where,
                "values": self.values, "std": self.std, "error_before": self.error_before,
                "error_after": self.error_after, "drop": self.drop, "delta_bic": self.delta_bic,
                "accepted": self.accepted, "refined": self.refined, "round": self.round,
                "evidence": self.evidence, "signature": self.candidate.signature}


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`.

    Attributes
    ----------
    ranked : list of EffectFit
        First-round fits of every candidate, best (lowest BIC) first; screened-only ones last.
    accepted : list of EffectFit
        Effects accepted one after another (greedy), each with its polished values.
    rounds : list of list of EffectFit
    recalibrated : dict
        Re-calibrated uncertain parameters ``{name: (value, std)}``.
    staircase : list of (label, error)
        Nominal, re-calibrated, then after each accepted effect.
    message : str
    """

    system: object
    uncertain: list
    recalibrated: dict
    ranked: list
    accepted: list
    rounds: list
    staircase: list
    message: str
    final_values: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def found(self) -> bool:
        return bool(self.accepted)

    def table(self) -> str:
        """Ranked candidates of the first round, then the accepted effects, as text."""
        lines = [self.message, "",
                 "round 1 ranking (error = mean squared residual per dataset, averaged):",
                 f"  {'#':>2} {'candidate':<24} {'drop':>7} {'dBIC':>10}  fitted parameters"]
        for i, r in enumerate(self.ranked, 1):
            vals = ", ".join(f"{k}={v:.4g}" for k, v in r.values.items())
            flag = "" if r.refined else " (screened)"
            lines.append(f"  {i:>2} {r.name:<24} {100 * r.drop:6.1f}% {r.delta_bic:10.1f}  {vals}{flag}")
        if self.recalibrated:
            lines += ["", "re-calibrated:"] + [f"  {k} = {v:.6g} +- {s:.2g}" for k, (v, s) in self.recalibrated.items()]
        if self.accepted:
            lines += ["", "accepted effects:"]
            for r in self.accepted:
                vals = ", ".join(f"{k} = {v:.4g} +- {r.std.get(k, float('nan')):.2g}" for k, v in r.values.items())
                lines.append(f"  {r.round}. {r.candidate.title}: {vals}; error {r.error_before:.4g} -> "
                             f"{r.error_after:.4g} ({100 * r.drop:.1f} % less)")
                lines.append(f"     evidence: {r.evidence}")
        lines += ["", "error staircase: " + " -> ".join(f"{lbl} {e:.4g}" for lbl, e in self.staircase)]
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def apply(self, system=None, linear: bool = False):
        """The updated System: re-calibrated values set and the accepted effects added.

        ``linear=True`` leaves out the nonlinear effects (friction, backlash): the model for FRFs.
        """
        s = (self.system if system is None else system).copy()
        for k, (v, _) in self.recalibrated.items():
            s.set(k, v)
        for r in self.accepted:
            if linear and r.candidate.nonlinear:
                continue
            s = r.candidate.apply(s, **r.values)
        return s

    def code(self) -> str:
        """Python lines to add to a system file (``s`` is the System being built)."""
        lines = ["# --- changes found by bscomp diagnose ---"]
        for k, (v, sd) in self.recalibrated.items():
            lines.append(f's.set("{k}", {v:.6g})  # re-calibrated, +- {sd:.2g}')
        s = self.system.copy()
        for k, (v, _) in self.recalibrated.items():
            s.set(k, v)
        for r in self.accepted:
            lines.append(f"# {r.candidate.title} (error -{100 * r.drop:.0f} %)")
            lines += r.candidate.code_lines(r.values, s)
            s = r.candidate.apply(s, **r.values)
        if not self.accepted:
            lines.append("# no missing effect found")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"message": self.message, "uncertain": self.uncertain,
                "recalibrated": {k: {"value": v, "std": s} for k, (v, s) in self.recalibrated.items()},
                "ranked": [r.to_dict() for r in self.ranked], "accepted": [r.to_dict() for r in self.accepted],
                "staircase": [[lbl, e] for lbl, e in self.staircase], "code": self.code(), "stats": self.stats}

    def to_json(self, path=None) -> str:
        text = json.dumps(self.to_dict(), indent=2, default=float)
        if path is not None:
            Path(path).write_text(text)
        return text

    def plot(self, directory):
        """Write ``error_staircase.png`` and ``candidates.png`` to ``directory``; returns the paths."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(7, 4))
        labels = [lbl for lbl, _ in self.staircase]
        errs = [e for _, e in self.staircase]
        ax.step(range(len(errs)), errs, where="mid", lw=2)
        ax.plot(range(len(errs)), errs, "o")
        ax.set_xticks(range(len(errs)))
        ax.set_xticklabels(labels, rotation=20, ha="right")
        ax.set_yscale("log")
        ax.set_ylabel("error (mean squared residual)")
        ax.set_title("error staircase: effects added one after another")
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        p1 = d / "error_staircase.png"
        fig.savefig(p1, dpi=110)
        plt.close(fig)
        fig, ax = plt.subplots(figsize=(7, 4))
        names = [r.name for r in self.ranked][::-1]
        drops = [100 * r.drop for r in self.ranked][::-1]
        colors = ["tab:green" if any(a.name == n for a in self.accepted) else "tab:gray" for n in names]
        ax.barh(names, drops, color=colors)
        ax.set_xlabel("error reduction in round 1 [%]")
        ax.set_title("candidate effects (green: accepted)")
        fig.tight_layout()
        p2 = d / "candidates.png"
        fig.savefig(p2, dpi=110)
        plt.close(fig)
        return [p1, p2]


# ---- evidence in words ---------------------------------------------------------------------------------------
def _evidence(cand, before, after, datasets):
    parts = []
    for d, b, a in zip(datasets, before, after):
        what = "FRF" if isinstance(d, FrfData) else "time series"
        if b > 0:
            parts.append(f"{what} error {100 * (1 - a / b):.0f} % lower")
    return "; ".join(parts) + f". Signature: {cand.signature}"


def _signature_words(comparison) -> str:
    sig = getattr(comparison, "signatures", None) or {}
    if not sig:
        return ""
    best = sorted(sig.items(), key=lambda kv: -abs(kv[1]))[:2]
    return "; residual correlates with " + ", ".join(f"{k} ({v:+.2f})" for k, v in best)


def _line_search(pr, th0, scores):
    """Bounded Brent search on the first free parameter between the scan neighbours of ``th0``."""
    from scipy.optimize import minimize_scalar

    xs = sorted(s[1][0] for s in scores if np.all(s[1][1:] == th0[1:]))
    i = int(np.argmin([abs(x - th0[0]) for x in xs]))
    lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, len(xs) - 1)]
    if hi <= lo:
        return th0

    def f(x):
        th = np.array(th0, float)
        th[0] = x
        return float(np.sum(pr.residual(th) ** 2))

    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 2e-4})
    th = np.array(th0, float)
    th[0] = res.x if res.fun <= f(th0[0]) else th0[0]
    return th


# ---- the algorithm ---------------------------------------------------------------------------------------------
def _resolve(system_or_build):
    from bscomp.system import System

    if isinstance(system_or_build, System):
        return system_or_build
    from .residuals import build_for

    return build_for(system_or_build)


def _chain(system, effects, linear):
    s = system
    for cand, _values, _fit in effects:
        s = cand.structure(s, linear=linear)
    return s


def _build(system, effects, datasets):
    full = _chain(system, effects, linear=False)
    if any(c.nonlinear for c, _, _ in effects):
        lin = _chain(system, effects, linear=True)
    else:
        lin = full
    return _Model(full, lin, datasets)


def _uncertain_specs(system, uncertain, values):
    """(name, (lower, upper, start)) with bounds ``v0 / (1 + spread)`` .. ``v0 (1 + spread)``."""
    out = []
    for name, spread in uncertain.items():
        v0 = float(system.get(name))
        v = values.get(name, v0)
        f = 1.0 + spread
        out.append((name, (v0 / f, v0 * f, min(max(v, v0 / f), v0 * f))))
    return out


def diagnose(system_or_build, datasets, uncertain=None, candidates=None, max_effects: int = 3,
             n_refine: int = 4, bic_threshold: float = 10.0, min_drop: float = 0.10, verbose: bool = False,
             compare_signatures: bool = False, default_spread: float = 0.2, n_starts: int = 1,
             n_screen: int = 7, n_scan: int = 41, n_swap: int = 2) -> Diagnosis:
    """Find the physical effects the model is missing (see the module docstring).

    Parameters
    ----------
    system_or_build : System, callable or str
        The nominal model (as :func:`~bscomp.validate.compare`).
    datasets : list of FrfData / TimeData
    uncertain : list of str or dict, optional
        Dotted parameters to re-calibrate first; a dict gives each one's relative spread (bounds
        ``v0/(1+spread)`` .. ``v0 (1+spread)``), a list uses ``default_spread``. Default: the system's
        ``uncertain`` attribute, or none. The bounds are what keeps a re-calibration from absorbing a
        missing effect (a 50 % heavier table mimics a soft nut-table joint in the axial mode).
    candidates : list of Candidate, optional
        Default :func:`~bscomp.validate.candidates.default_candidates`. Candidates that only re-scale an
        uncertain parameter (``degenerate_with``) are skipped.
    max_effects : int
        Most effects accepted (greedy rounds).
    n_refine : int
        Candidates fitted by least squares per round (the rest are only screened).
    n_starts : int
        Least-squares starts per refined candidate (the best screening points).
    n_screen : int
        Screening points per candidate along its first parameter's prior (median, +-0.5, +-1, ... sigma).
    n_swap : int
        After the forward pass (when it accepted two or more effects): for each accepted effect, try
        the ``n_swap`` best other candidates of its round in its place, everything re-fitted together;
        keep a swap that lowers the BIC. 0 disables.
    n_scan : int
        Scan points (log-spaced over +-2 sigma) for nonlinear candidates, followed by a bounded Brent
        search between the best point's neighbours: their cost has many local minima.
    bic_threshold : float
        Required BIC decrease to accept an effect (10: "very strong" evidence, Kass & Raftery).
    min_drop : float
        Required relative error decrease to accept an effect.
    default_spread : float
        Relative spread of uncertain parameters given as a list (0.2: +-20 %).
    compare_signatures : bool
        Also run :func:`~bscomp.validate.compare` on the updated model and quote its signatures.

    Returns
    -------
    Diagnosis
    """
    t_start = time.perf_counter()
    system = _resolve(system_or_build)
    if isinstance(datasets, (FrfData, TimeData)):
        datasets = [datasets]
    datasets = list(datasets)
    uncertain = getattr(system, "uncertain", []) if uncertain is None else uncertain
    uncertain = dict(uncertain) if isinstance(uncertain, dict) else {k: default_spread for k in uncertain}
    cands = list(default_candidates() if candidates is None else candidates)
    cands = [c for c in cands if c.is_effect and getattr(c, "degenerate_with", None) not in uncertain]
    log = print if verbose else (lambda *a, **k: None)

    # 0. nominal error, 1. re-calibration
    base = _build(system, [], datasets)
    nominal = _stats(base.residual_blocks({}), 0)
    prob = _Problem(base, {}, _uncertain_specs(system, uncertain, {}), [])
    uncertain_names = list(uncertain)
    theta, sol = prob.fit()
    unc_values = {k: v for k, v in prob.values(theta).items()}
    unc_std = prob.uncertainty(theta, sol)
    current = _stats(base.residual_blocks(prob.overrides(theta)), len(uncertain))
    log(f"nominal error {nominal['error']:.4g}; re-calibrated {current['error']:.4g} ({unc_values})")
    staircase = [("nominal", nominal["error"])]
    if uncertain:
        staircase.append(("re-calibrated", current["error"]))
    accepted_effects = []  # (candidate, values, fit=True)
    accepted, rounds = [], []
    n_evals = prob.nfev
    for rnd in range(1, max_effects + 1):
        taken = {c.group for c, _, _ in accepted_effects}
        pool = [c for c in cands if c.group not in taken]
        if not pool:
            break
        k_now = len(uncertain) + sum(len(c.parameters) for c, _, _ in accepted_effects)
        fixed_effects = [(c, v, False) for c, v, _ in accepted_effects]
        # start of the joint fits: nominal values in round 1, the polished values after an acceptance
        unc_start = {k: float(system.get(k)) for k in uncertain} if rnd == 1 else dict(unc_values)
        results = []
        screened = []
        for cand in pool:
            try:
                model = _build(system, fixed_effects + [(cand, cand.medians(), True)], datasets)
            except Exception as exc:  # a candidate that cannot be built here is reported, not fatal
                log(f"  {cand.name}: cannot be inserted ({exc})")
                continue
            pr = _Problem(model, dict(unc_start), [], fixed_effects + [(cand, cand.medians(), True)])
            meds = [p.median for p in cand.parameters]
            p0 = cand.parameters[0]
            if cand.nonlinear:
                # open-loop runs with friction or backlash have a multimodal cost (the number and timing
                # of stops): a dense scan of the first parameter over +-2 sigma of its prior
                lo = max(math.log(p0.lower), math.log(p0.median) - 2 * p0.sigma_log)
                hi = min(math.log(p0.upper), math.log(p0.median) + 2 * p0.sigma_log)
                grid = np.exp(np.linspace(lo, hi, n_scan))
            else:
                grid = p0.starts(n_screen)
            starts = [tuple([v] + meds[1:]) for v in grid]
            if len(cand.parameters) > 1:
                starts += list(zip(*[p.starts(n_screen) for p in cand.parameters]))[1:3]
            scores = []
            for st in starts:
                th = np.log(np.array(st, float))
                try:
                    e = float(np.sum(pr.residual(th) ** 2))
                except RuntimeError:
                    e = np.inf
                scores.append((e, th))
            scores.sort(key=lambda x: x[0])
            screened.append((scores[0][0], cand, model, pr, scores))
            n_evals += pr.nfev
        screened.sort(key=lambda x: x[0])
        for i, (_e0, cand, model, pr, scores) in enumerate(screened):
            if i < n_refine:
                # joint fit: the candidate's parameters and the uncertain ones (so a re-calibration pushed
                # to its bounds by the missing effect relaxes), from the two best screening points
                # the uncertain parameters restart from their nominal values: the re-calibrated ones were
                # pushed (often to a bound) by the very effect being tested
                pr = _Problem(model, {}, _uncertain_specs(system, uncertain, unc_start),
                              fixed_effects + [(cand, cand.medians(), True)])
                n_unc = len(uncertain)
                th_unc = pr.theta0()[:n_unc]
                pr0 = _Problem(model, dict(unc_start), [], fixed_effects + [(cand, cand.medians(), True)])
                best = None
                for _, th0 in scores[:n_starts]:
                    if cand.nonlinear:
                        th0 = _line_search(pr0, th0, scores)
                    th0, _ = pr0.fit(th0, max_nfev=20)  # candidate alone first: into the valley
                    th, sl = pr.fit(np.r_[th_unc, th0], max_nfev=50)
                    e = float(np.sum(sl.fun ** 2))
                    if best is None or e < best[0]:
                        best = (e, th, sl)
                _, th, sl = best
                refined = True
            else:
                th, sl, refined, pr0 = scores[0][1], None, False, None
            n_evals += pr.nfev + (pr0.nfev if refined else 0)
            st = _stats(model.residual_blocks(pr.overrides(th)), k_now + len(cand.parameters))
            vals = {lbl.split(".", 1)[1]: v for lbl, v in pr.values(th).items() if lbl.startswith(cand.name + ".")}
            results.append(EffectFit(candidate=cand, _start=pr.values(th), values=vals, std=pr.uncertainty(th, sl) and
                                     {lbl.split(".", 1)[1]: s for lbl, s in pr.uncertainty(th, sl).items()
                                      if lbl.startswith(cand.name + ".")},
                                     error_before=current["error"], error_after=st["error"],
                                     delta_bic=st["bic"] - current["bic"], refined=refined, round=rnd,
                                     per_dataset=(current["error_per_dataset"], st["error_per_dataset"])))
        results.sort(key=lambda r: (not r.refined, r.delta_bic))
        rounds.append(results)
        log(f"round {rnd}: " + ", ".join(f"{r.name} {100 * r.drop:.1f}% dBIC {r.delta_bic:.0f}" for r in results))
        if not results:
            break
        best = results[0]
        if not (best.refined and best.delta_bic < -bic_threshold and best.drop >= min_drop):
            break
        # accept and polish: re-fit the uncertain parameters and every accepted effect together
        effects = [(c, v, True) for c, v, _ in accepted_effects] + [(best.candidate, best.values, True)]
        model = _build(system, effects, datasets)
        start_unc = {k: best._start.get(k, unc_values[k]) for k in uncertain}
        pr = _Problem(model, {}, _uncertain_specs(system, uncertain, start_unc), effects)
        th, sl = pr.fit(max_nfev=100)
        n_evals += pr.nfev
        new = _stats(model.residual_blocks(pr.overrides(th)), pr.free.__len__())
        vals_all = pr.values(th)
        std_all = pr.uncertainty(th, sl)
        unc_values = {k: vals_all[k] for k in uncertain}
        unc_std = {k: std_all.get(k, float("nan")) for k in uncertain}
        accepted_effects = [(c, {p.name: vals_all[f"{c.name}.{p.name}"] for p in c.parameters}, True)
                            for c, _, _ in effects]
        best.values = dict(accepted_effects[-1][1])
        best.std = {p.name: std_all.get(f"{best.name}.{p.name}", float("nan")) for p in best.candidate.parameters}
        best.error_after = new["error"]
        best.delta_bic = new["bic"] - current["bic"]
        best.accepted = True
        best.evidence = _evidence(best.candidate, current["error_per_dataset"], new["error_per_dataset"], datasets)
        for a in accepted:  # earlier effects re-fitted together with this one
            a.values = dict(next(v for c, v, _ in accepted_effects if c is a.candidate))
            a.std = {p.name: std_all.get(f"{a.name}.{p.name}", float("nan")) for p in a.candidate.parameters}
        accepted.append(best)
        staircase.append((f"+ {best.name}", new["error"]))
        current = new
    # swap pass (stepwise selection): an effect accepted early was fitted while the later ones were still
    # missing and may stand in for them; try each round's runners-up in its place, all re-fitted together
    for _sweep in range(2 if n_swap and len(accepted) >= 2 else 0):
        swapped = False
        for i in range(len(accepted)):
            others = {a.candidate.group for j, a in enumerate(accepted) if j != i}
            alts = [r for r in rounds[accepted[i].round - 1] if r.refined
                    and r.candidate is not accepted[i].candidate and r.candidate.group not in others][:n_swap]
            for alt in alts:
                effects = [(c, v, True) for c, v, _ in accepted_effects]
                effects[i] = (alt.candidate, dict(alt.values), True)
                model = _build(system, effects, datasets)
                pr = _Problem(model, {}, _uncertain_specs(system, uncertain, unc_values), effects)
                th, sl = pr.fit(max_nfev=60)
                n_evals += pr.nfev
                new = _stats(model.residual_blocks(pr.overrides(th)), len(pr.free))
                log(f"swap {accepted[i].name} -> {alt.name}: BIC {new['bic'] - current['bic']:+.0f}")
                if new["bic"] >= current["bic"]:
                    continue
                vals_all, std_all = pr.values(th), pr.uncertainty(th, sl)
                unc_values = {k: vals_all[k] for k in uncertain}
                unc_std = {k: std_all.get(k, float("nan")) for k in uncertain}
                accepted_effects = [(c, {p.name: vals_all[f"{c.name}.{p.name}"] for p in c.parameters}, True)
                                    for c, _, _ in effects]
                alt.accepted = True
                accepted[i].accepted = False
                alt.error_before, alt.error_after = accepted[i].error_before, accepted[i].error_after
                alt.evidence = (accepted[i].evidence.split(". Signature:")[0].split(" (swapped")[0]
                                + f" (swapped in for {accepted[i].name}). Signature: {alt.candidate.signature}")
                accepted[i] = alt
                for a, (_c, v, _f) in zip(accepted, accepted_effects):
                    a.values = dict(v)
                    a.std = {p.name: std_all.get(f"{a.name}.{p.name}", float("nan"))
                             for p in a.candidate.parameters}
                staircase = staircase[:len(staircase) - len(accepted)] + [
                    (f"+ {a.name}", e) for a, (_, e) in zip(accepted, staircase[len(staircase) - len(accepted):])]
                staircase[-1] = (staircase[-1][0].replace(" (after swaps)", "") + " (after swaps)", new["error"])
                accepted[-1].error_after = new["error"]
                current = new
                swapped = True
        if not swapped:
            break
    ranked = list(rounds[0]) if rounds else []
    for r in ranked:
        if not r.evidence:
            r.evidence = _evidence(r.candidate, *r.per_dataset, datasets)
    if accepted:
        msg = f"{len(accepted)} missing effect(s) found: " + ", ".join(a.candidate.title for a in accepted)
    else:
        msg = "no missing effect found: no candidate improves the fit enough to justify its parameters"
    diag = Diagnosis(system=system, uncertain=uncertain_names,
                     recalibrated={k: (unc_values[k], unc_std.get(k, float("nan"))) for k in uncertain},
                     ranked=ranked, accepted=accepted, rounds=rounds, staircase=staircase, message=msg,
                     stats={"wall_s": time.perf_counter() - t_start, "evaluations": n_evals})
    if compare_signatures and accepted:
        try:
            from .compare import compare

            words = _signature_words(compare(system, datasets))
            if words:
                accepted[0].evidence += words
        except Exception as exc:  # signatures are a bonus; the diagnosis stands without them
            log(f"compare() failed: {exc}")
    return diag

