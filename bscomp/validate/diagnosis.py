"""Results of :func:`~bscomp.validate.diagnostics.diagnose`: fitted effects and the diagnosis."""

from __future__ import annotations

import inspect
import json
import math
from dataclasses import dataclass, field

from bscomp.files import atomic_write, json_default
from bscomp.model import as_system, build_keywords, model_name
from bscomp.plotting.validate import plot_diagnosis
from bscomp.validate.equivalence import Z_CRIT
from bscomp.validate.evaluation import BOUND_TOL, FIT_MAX_SUB
from bscomp.validate.uncertainty import STD_NOTE

__all__ = ["EffectFit", "Diagnosis", "Skipped"]


@dataclass
class Skipped:
    """A candidate that was not tried, and why (not applicable to this drive, or re-calibrated instead)."""

    name: str
    title: str
    reason: str

    def to_dict(self):
        return {"candidate": self.name, "title": self.title, "reason": self.reason}


@dataclass
class EffectFit:
    """One candidate effect fitted in one round.

    Attributes
    ----------
    candidate : Candidate
    values, std : dict
        Fitted free parameters and their standard deviations (after polishing, if accepted).
    error_before, error_after : float
        Normalised fitting error (mean chi^2 over datasets, 1 = at the noise floor) without / with it.
    heldout_before, heldout_after : float or None
        The same on the held-out halves of the time series.
    delta_bic : float
        BIC with the effect minus BIC without (negative = better).
    accepted : bool
    verdict : str
        Why it was accepted or rejected (plain words).
    evidence : str
        Which errors fell, the candidate's signature.
    user_before, user_after : dict
        The errors as the user reads them (FRF magnitude/phase per pair, fit % per time channel).
    refined : bool
        False when only screened (not fitted by least squares).
    equivalent : dict
        The other candidates of the round that the data cannot tell apart from this one
        (:mod:`bscomp.validate.equivalence`): ``{name: {"D", "z", "dchi2", "shared", "n", "tell_apart"}}``.
    compared : dict
        The same test numbers for every other refined candidate of the round, with ``indistinguishable``.
    own_share : float or None
        Share of what it does that the parameters fitted with it cannot do
        (:func:`~bscomp.validate.collinearity.own_share`; None where not judged).
    trades_with : list
        The parameters its most independent direction is most aligned with (``|cos| >= 0.5``).
    together : str
        The candidate it was fitted and accepted together with, when neither passed alone
        (:mod:`bscomp.validate.pairs`); "" otherwise.
    partner : bool
        It entered that pair as the linear partner of a nonlinear lead (screened on the FRFs beside it,
        :func:`~bscomp.validate.pairs.linear_partner`), not as a candidate that failed a rule alone.
    """

    candidate: object
    values: dict
    std: dict
    error_before: float
    error_after: float
    delta_bic: float
    heldout_before: float | None = None
    heldout_after: float | None = None
    accepted: bool = False
    verdict: str = ""
    evidence: str = ""
    refined: bool = True
    per_dataset: tuple = ()
    round: int = 1
    user_before: dict = field(default_factory=dict)
    user_after: dict = field(default_factory=dict)
    equivalent: dict = field(default_factory=dict)
    compared: dict = field(default_factory=dict)
    own_share: float | None = None
    trades_with: list = field(default_factory=list)
    together: str = ""
    partner: bool = False
    _start: dict = field(default_factory=dict, repr=False)

    @property
    def name(self):
        return self.candidate.name

    @property
    def group_names(self) -> tuple:
        """This candidate and those the data cannot tell apart from it (ranking order of the round)."""
        return (self.name, *self.equivalent)

    @property
    def drop(self) -> float:
        """Relative error reduction ``1 - after/before``."""
        return 1.0 - self.error_after / self.error_before if self.error_before > 0 else 0.0

    def to_dict(self):
        return {"candidate": self.name, "title": self.candidate.title, "where": self.candidate.where,
                "values": self.values, "std": self.std, "error_before": self.error_before,
                "error_after": self.error_after, "drop": self.drop, "delta_bic": self.delta_bic,
                "heldout_before": self.heldout_before, "heldout_after": self.heldout_after,
                "accepted": self.accepted, "verdict": self.verdict, "refined": self.refined, "round": self.round,
                "evidence": self.evidence, "signature": self.candidate.signature,
                "user_before": self.user_before, "user_after": self.user_after, "equivalent": self.equivalent,
                "compared": self.compared, "own_share": self.own_share, "trades_with": self.trades_with,
                "together": self.together, "partner": self.partner}

    def equivalence_lines(self, indent: str = "     ", skip=()) -> list:
        """The candidates this one cannot be told apart from (but those in ``skip``), with the numbers and
        what would separate them."""
        out = []
        for other, st in self.equivalent.items():
            if other in skip:
                continue
            d_noise = (2 * Z_CRIT) ** 2
            why = (f"predictions within noise of each other, D = {st['D']:.3g} < {d_noise:.3g}"
                   if st["D"] < d_noise else
                   f"predictions D = {st['D']:.3g} apart in chi^2, but neither fits better: Vuong z = "
                   f"{st['z']:+.2f}, |z| < {Z_CRIT:.2f}")
            out.append(f"{indent}{self.name} ~ {other}: indistinguishable on this model and data ({why}; "
                       f"{100 * st['shared']:.2f} % of the improvements shared); both explain the data; to tell "
                       f"them apart: {st['tell_apart']}")
        return out


def _fmt_user(u: dict) -> str:
    parts = []
    for d in u.get("per_dataset", []):
        for item in d.get("frf", []):
            i, o = item["pair"]
            parts.append(f"{i}->{o} |H| {item['mag_mean_abs_dlog10']:.3g} dec, phase {item['phase_deg_rms']:.3g} deg")
        for item in d.get("time", []):
            parts.append(f"{item['channel']} fit {item['fit_percent']:.1f} %")
    return "; ".join(parts)


@dataclass
class Diagnosis:
    """Result of :func:`~bscomp.validate.diagnostics.diagnose`.

    Attributes
    ----------
    ranked : list of EffectFit
        First-round fits of every candidate tried, best (lowest BIC) first; screened-only ones last.
    accepted : list of EffectFit
        Effects accepted one after another (greedy), each with its polished values.
    skipped : list of Skipped
        Candidates not tried (not applicable to this drive, or re-calibrated instead), with the reason.
    rounds : list of list of EffectFit
    recalibrated : dict
        Re-calibrated uncertain parameters ``{name: (value, std)}``.
    staircase : list of (label, error)
        Nominal, re-calibrated, then after each accepted effect (normalised error, 1 = noise floor).
    user_errors : list of (label, dict)
        The errors as the user reads them at each step of the staircase.
    calibration : Calibration
        The re-calibration step (:func:`~bscomp.validate.calibration.calibrate`'s result: values, spreads,
        errors per channel before and after).
    unconfirmed : list of EffectFit
        Linear candidates that passed every rule but were not accepted because nothing confirms FRFs measured
        at one stated amplitude (:func:`~bscomp.validate.amplitude.frf_confirmation`).
    amplitude : list of AmplitudeDependence
        FRF pairs measured at two stated amplitudes, compared with themselves
        (:func:`~bscomp.validate.amplitude.amplitude_dependence`): where they differ beyond noise a nonlinearity
        acts, which the small-signal FRF fit cannot see.
    remainder : dict
        What the final model leaves (:func:`~bscomp.validate.conclusion.remainder`): ``error`` (mean chi^2, 1 =
        the noise floor), ``within_noise``, ``orders`` (time-series residual components periodic in a measured
        angle, :class:`~bscomp.validate.periodicity.AngleOrder`: an effect no candidate has), ``frf_values`` (the
        uncertain parameters fitted to the FRFs alone, when the error left is above
        :data:`~bscomp.validate.conclusion.UNEXPLAINED`).
    pairs : list of dict
        Candidates fitted in pairs after a round that accepted none alone (:mod:`bscomp.validate.pairs`): per pair
        ``members``, ``round``, ``values``, ``error``, ``heldout``, ``delta_bic``, ``accepted``, ``verdict``.
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
    skipped: list = field(default_factory=list)
    user_errors: list = field(default_factory=list)
    noise: list = field(default_factory=list)
    final_values: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    calibration: object = None
    amplitude: list = field(default_factory=list)
    unconfirmed: list = field(default_factory=list)
    remainder: dict = field(default_factory=dict)
    pairs: list = field(default_factory=list)

    @property
    def found(self) -> bool:
        return bool(self.accepted)

    def table(self) -> str:
        """Ranked candidates of the first round, skipped ones, the accepted effects, as text."""
        lines = [self.message, "",
                 "round 1 ranking (error = mean chi^2 over datasets, 1 = at the noise floor; held-out = second "
                 "halves of the time series):",
                 f"  {'#':>2} {'candidate':<26} {'error':>9} {'held-out':>9} {'dBIC':>10}  fitted parameters"]
        for i, r in enumerate(self.ranked, 1):
            vals = ", ".join(f"{k}={v:.4g}" for k, v in r.values.items())
            flag = "" if r.refined else " (screened)"
            held = f"{r.heldout_after:9.4g}" if r.heldout_after is not None else f"{'-':>9}"
            lines.append(f"  {i:>2} {r.name:<26} {r.error_after:9.4g} {held} {r.delta_bic:10.1f}  {vals}{flag}")
            if r.verdict and not r.accepted:
                lines.append(f"     not accepted: {r.verdict}")
            lines += r.equivalence_lines(skip=[q.name for q in self.ranked[:i - 1]])   # each pair once
        if self.amplitude:
            lines += ["", "FRFs measured at two amplitudes (the data alone, no model):"]
            lines += [f"  {a.summary()}" for a in self.amplitude]
        for k, rr in enumerate(self.rounds[1:], 2):
            lines += ["", f"round {k} (with the effects accepted before), best three:"]
            for r in [r for r in rr if r.refined][:3]:
                vals = ", ".join(f"{kk}={v:.4g}" for kk, v in r.values.items())
                held = f", held-out {r.heldout_after:.4g}" if r.heldout_after is not None else ""
                lines.append(f"  {r.name:<26} error {r.error_after:.4g}{held}; {vals}")
                if r.verdict and not r.accepted:
                    lines.append(f"     not accepted: {r.verdict}")
        lines += self._pair_lines()
        if self.skipped:
            lines += ["", "not tried:"] + [f"  {s.name:<26} {s.reason}" for s in self.skipped]
        if self.recalibrated:
            lines += ["", "re-calibrated:"] + [f"  {k} = {v:.6g} +- {s:.2g}" for k, (v, s) in self.recalibrated.items()]
        if self.remainder.get("frf_values"):
            lines += ["", "fitted to the FRFs alone (an effect the FRFs do not see bends the fit to every dataset):"]
            lines += [f"  {k} = {v:.6g}" for k, v in self.remainder["frf_values"].items()]
        if self.accepted:
            lines += ["", "accepted effects:"]
            for r in self.accepted:
                vals = ", ".join(f"{k} = {v:.4g} +- {r.std.get(k, float('nan')):.2g}{_bound_note(r, k, v)}"
                                 for k, v in r.values.items())
                lines.append(f"  {r.round}. {r.candidate.title}: {vals}; error {r.error_before:.4g} -> "
                             f"{r.error_after:.4g} ({100 * r.drop:.1f} % less)")
                lines.append(f"     why: {r.evidence}")
                lines += r.equivalence_lines()
        if self.recalibrated or self.accepted:
            lines += [f"  ({STD_NOTE})"]
        lines += ["", "error staircase: " + " -> ".join(f"{lbl} {e:.4g}" for lbl, e in self.staircase)]
        if self.remainder.get("orders"):
            lines += ["", "left in the residual, periodic in the motor angle (no candidate has such an effect):"]
            lines += [f"  {o.describe()}" for o in self.remainder["orders"]]
        if self.stats.get("unconverged"):
            lines += ["", "time series not trustworthy (the Newton on the friction/backlash forces did not converge "
                      f"at {FIT_MAX_SUB} sub-steps per sample; those evaluations' errors are off):"]
            lines += [f"  {k}: {n} of {tot} evaluations" for k, (n, tot) in self.stats["unconverged"].items()]
        if self.user_errors:
            lines += ["", "errors as measured (magnitude: mean |log10 error| [decades], phase rms, fit %):"]
            lines += [f"  {lbl}: {_fmt_user(u)}" for lbl, u in self.user_errors]
        return "\n".join(lines)

    def _pair_lines(self) -> list:
        lines = []
        for rnd in sorted({p["round"] for p in self.pairs}):
            lines += ["", f"round {rnd}: no candidate passed alone; the best fitted in pairs:"]
            for p in (p for p in self.pairs if p["round"] == rnd):
                vals = ", ".join(f"{k}={v:.4g}" for k, v in p["values"].items())
                held = f", held-out {p['heldout']:.4g}" if p["heldout"] is not None else ""
                lines.append(f"  {' + '.join(p['members']):<40} error {p['error']:.4g}{held}; {vals}")
                if not p["accepted"]:
                    lines.append(f"     not accepted: {p['verdict']}")
        return lines

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

    def updated(self, model):
        """``model`` (the name, ``.py`` path, build function or ModelSpec the diagnosis ran on) as a build function
        with this diagnosis's changes: built at each dataset's conditions (its nut position...), then
        :meth:`apply` -- for ``compare(diag.updated(model), datasets)``, the error after the effects are added, at
        every measured condition (a built System would be compared at the first one only)."""
        return _UpdatedBuild(model, self)

    def code(self) -> str:
        """Python lines to add to a system file (``s`` is the System being built)."""
        lines = ["# --- changes found by bscomp diagnose ---"]
        for k, (v, sd) in self.recalibrated.items():
            lines.append(f's.set("{k}", {v:.6g})  # re-calibrated, +- {sd:.2g}')
        s = self.system.copy()
        for k, (v, _) in self.recalibrated.items():
            s.set(k, v)
        for r in self.accepted:
            lines.append(f"# {r.candidate.title} (error -{100 * r.drop:.0f} %"
                         + (f"; found together with {r.together})" if r.together else ")"))
            lines += r.candidate.code_lines(r.values, s)
            s = r.candidate.apply(s, **r.values)
        if not self.accepted:
            lines.append("# no missing effect found")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"message": self.message, "uncertain": self.uncertain,
                "recalibrated": {k: {"value": v, "std": s} for k, (v, s) in self.recalibrated.items()},
                "ranked": [r.to_dict() for r in self.ranked], "accepted": [r.to_dict() for r in self.accepted],
                "skipped": [s.to_dict() for s in self.skipped],
                "staircase": [[lbl, e] for lbl, e in self.staircase],
                "user_errors": [[lbl, u] for lbl, u in self.user_errors], "noise": self.noise,
                "amplitude": [a.to_dict() for a in self.amplitude],
                "unconfirmed": [r.to_dict() for r in self.unconfirmed], "code": self.code(), "stats": self.stats,
                "pairs": self.pairs,
                "remainder": {**self.remainder, "orders": [o.to_dict() for o in self.remainder.get("orders", [])]}}

    def to_json(self, path=None) -> str:
        text = json.dumps(self.to_dict(), indent=2, default=json_default)
        if path is not None:
            with atomic_write(path, what="Diagnosis.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def plot(self, directory):
        """Write ``error_staircase.png``, ``candidates.png`` (and ``orders.png`` when the remainder holds a component
        periodic in the motor angle) to ``directory``; returns the paths."""
        return plot_diagnosis(self, directory)


class _UpdatedBuild:
    """:meth:`Diagnosis.updated`: a build function taking the model's own build keywords (its signature says which,
    for :func:`bscomp.model.build_keywords`), named after the model and the effects found."""

    def __init__(self, model, diagnosis):
        self.model, self.diagnosis = model, diagnosis
        keys = build_keywords(model)
        kind = inspect.Parameter.KEYWORD_ONLY
        self.__signature__ = inspect.Signature(
            [inspect.Parameter("kwargs", inspect.Parameter.VAR_KEYWORD)] if keys is None
            else [inspect.Parameter(k, kind, default=None) for k in sorted(keys)])
        self.__name__ = " + ".join([model_name(model)] + [a.name for a in diagnosis.accepted])

    def __call__(self, **build):
        s = self.diagnosis.apply(as_system(self.model, build))
        s.name = self.__name__
        return s


def _bound_note(fit, name, value, tol=BOUND_TOL) -> str:
    """`` (at its lower bound)`` when a fitted value ended within ``tol`` (in log) of its candidate parameter's
    hard bound (the polish fit may end there after the rules passed): the data did not determine it there, and
    its ``+-`` is the width of a flat valley, not a measurement."""
    par = next((p for p in fit.candidate.parameters if p.name == name), None)
    if par is None or not value > 0:
        return ""
    if abs(math.log(value / par.lower)) < tol:
        return " (at its lower bound)"
    if abs(math.log(par.upper / value)) < tol:
        return " (at its upper bound)"
    return ""
