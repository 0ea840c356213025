r"""Re-calibrate a drive's uncertain parameters on measurements, with no effect added.

A wrong parameter value is not a missing effect (thesis Sec 3.5.2.3: the test bed's table mass and
coupling stiffness are known only to a few per cent). :func:`calibrate` fits the parameters the drive
declares uncertain (``system.validation.uncertain``, each with its relative spread; or a list/dict given
by the caller) to FRFs and time series at once, and says how much of the error that removes. It is the
first step of :func:`~bscomp.validate.diagnostics.diagnose`, which calls it.

Method: the model at every measurement condition is evaluated by the shared engine
(:class:`~bscomp.validate.evaluation.Evaluator`); each residual block (FRF log-magnitude and phase per pair,
each time channel) is whitened by its noise floor estimated from the data
(:func:`~bscomp.validate.noise.noise_levels`: per frequency where an FRF states its coherence), so the
normalised error :math:`\chi^2` is 1 where the model explains a block within noise. Bounded least squares
in log space over

.. math::

    \theta_i = \ln p_i, \qquad p_{i,0} / (1 + s_i) \le p_i \le p_{i,0} (1 + s_i)

(:math:`s_i` the spread) on the fitted part of the data -- FRFs whole, the first half of each time series;
the second halves are held out and report whether the fit carries over. Standard deviations from
:math:`\operatorname{cov}\theta = \hat\sigma^2 (J^T J)^{-1}` at the solution, mapped to :math:`p` by the delta
method (:meth:`~bscomp.validate.evaluation.Problem.uncertainty`).
"""

from __future__ import annotations

import functools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from bscomp.errors import ArgumentTypeError, UsageError, check_number
from bscomp.files import atomic_write, json_default
from bscomp.kernel.interface import interface_of
from bscomp.kernel.system import System
from bscomp.model import ModelSpec, spec_of, split_overrides
from bscomp.plotting.validate import calibration_plot
from bscomp.simulation.harmonic_balance import check_harmonics
from bscomp.validate.arguments import check_fit, check_uncertain_names, load_datasets
from bscomp.validate.comparison import user_errors
from bscomp.validate.datasets import AMPLITUDE_HARMONICS, FrfData, warn_amplitude_fit
from bscomp.validate.evaluation import Problem, Structures, noise_levels, residual_blocks
from bscomp.validate.residuals import build_for, data_label
from bscomp.validate.uncertainty import STD_NOTE

__all__ = ["calibrate", "Calibration", "FitSetup", "fit_uncertain", "parameter_bounds", "user_summary"]


# ---- the model at the measurement conditions --------------------------------------------------------------
def _condition_key(data, overrides):
    cond = {**dict(getattr(data, "conditions", {}) or {}), **dict(overrides or {})}
    return tuple(sorted((k, v if isinstance(v, (int, float, str)) else str(v)) for k, v in cond.items()))


def _systems(model, datasets, overrides):
    """``({key: System}, keys)``: the nominal model built at each dataset's conditions (a condition the model
    refuses is an error naming its file and line). The caller's ``overrides`` are not file conditions: its build
    keywords (a parameter file, a coupling variant) build the model, its dotted values are applied last."""
    keys = [_condition_key(d, overrides) for d in datasets]
    build_kw, dotted_kw = split_overrides(overrides)
    model_kw = _with_build_keywords(model, build_kw)
    systems = {}
    for key in dict.fromkeys(keys):
        cond = {k: v for k, v in key if k not in (overrides or {})}         # the file's own conditions
        d = datasets[keys.index(key)]
        locs = {k: v for (kind, k), v in d.locations.items() if kind == "condition" and k in cond}
        if isinstance(model, System):
            dotted = {k: v for k, v in cond.items() if "." in k}
            systems[key] = (build_for(model, dotted, dotted_kw or None, source=data_label(d), locations=locs)
                            if dotted or dotted_kw else model)
        else:
            systems[key] = build_for(model_kw, cond, dotted_kw or None, source=data_label(d), locations=locs)
    return systems, keys


def _with_build_keywords(model, build_kw: dict):
    """The model with the caller's build keywords bound: a name, path or spec as a :class:`~bscomp.model.ModelSpec`
    (:func:`~bscomp.model.spec_of`), a build function partially applied (a built System takes none: they are dropped,
    as before)."""
    if not build_kw or isinstance(model, System):
        return model
    if isinstance(model, (str, Path, ModelSpec)):
        return spec_of(model, build_kw)
    return functools.partial(model, **build_kw)


def _uncertain(system, uncertain, default_spread):
    """``{name: spread}`` from the argument, or the drive's declared interface."""
    if uncertain is None:
        iface = interface_of(system)
        if iface is not None:
            return iface.spreads()
        return {k: default_spread for k in (getattr(system, "uncertain", None) or [])}
    if isinstance(uncertain, str):
        uncertain = [uncertain]
    if not isinstance(uncertain, (dict, list, tuple, set)):
        raise ArgumentTypeError(f"uncertain must be a list of parameter names 'component.parameter' or a dict "
                                f"{{name: spread}}, got {type(uncertain).__name__} {uncertain!r}"[:300])
    if isinstance(uncertain, dict):
        out = {k: check_number(f"spread of '{k}'", v, positive=True) for k, v in uncertain.items()}
    else:
        out = {k: default_spread for k in uncertain}
    if not out:
        raise UsageError("uncertain is empty: name at least one parameter to calibrate (e.g. ['table.m']), or "
                         "leave it out to use the drive's declared uncertain parameters")
    check_uncertain_names(system, out)
    return out


def parameter_bounds(system, uncertain: dict, values: dict) -> list:
    """``[(name, (lower, upper, start))]`` with bounds ``v0 / (1 + spread)`` .. ``v0 (1 + spread)`` around the
    system's value ``v0``; the start is ``values[name]`` (clipped to the bounds) or ``v0``."""
    out = []
    for name, spread in uncertain.items():
        v0 = float(system.get(name))
        f = 1.0 + spread
        v = min(max(values.get(name, v0), v0 / f), v0 * f)
        out.append((name, (v0 / f, v0 * f, v)))
    return out


@dataclass
class FitSetup:
    """The model at the measurements, ready for fitting (shared by :func:`calibrate` and
    :func:`~bscomp.validate.diagnostics.diagnose`).

    Attributes
    ----------
    datasets : list of FrfData / TimeData
    systems : dict
        ``{condition key: System}``, the nominal model at each measurement condition.
    keys : list
        The condition key of each dataset.
    reference : System
        The model at the first dataset's condition (parameters and candidates are read from it).
    uncertain : dict
        ``{parameter: relative spread}``.
    sigmas : list
        Noise floors of each dataset's residual blocks.
    structures : Structures
        Evaluators per model structure.
    """

    datasets: list
    systems: dict
    keys: list
    reference: System
    uncertain: dict
    sigmas: list
    structures: Structures

    @classmethod
    def build(cls, model, datasets, uncertain=None, overrides: dict | None = None,
              default_spread: float = 0.2, harmonics: int = 1) -> FitSetup:
        """Build the model at each dataset's conditions (``overrides`` over the files' conditions) and read
        the uncertain parameters (argument, else the drive's declared interface); ``harmonics``: odd harmonics
        balanced for FRFs measured at an amplitude."""
        systems, keys = _systems(model, datasets, overrides)
        ref = systems[keys[0]]
        unc = _uncertain(ref, uncertain, default_spread)
        return cls(datasets=list(datasets), systems=systems, keys=keys, reference=ref, uncertain=unc,
                   sigmas=[noise_levels(d) for d in datasets],
                   structures=Structures(systems, datasets, keys, list(unc), harmonics))

    def only(self, keep) -> FitSetup:
        """The same fit on the datasets at indices ``keep``: their built systems, noise floors and the uncertain
        parameters reused (not built again), evaluators made anew when first asked for."""
        datasets, keys = [self.datasets[i] for i in keep], [self.keys[i] for i in keep]
        systems = {k: self.systems[k] for k in keys}
        return FitSetup(datasets=datasets, systems=systems, keys=keys, reference=systems[keys[0]],
                        uncertain=self.uncertain, sigmas=[self.sigmas[i] for i in keep],
                        structures=Structures(systems, datasets, keys, list(self.uncertain), self.structures.harmonics))

    def bounds(self, values: dict | None = None) -> list:
        """:func:`parameter_bounds` of the uncertain parameters around the reference values."""
        return parameter_bounds(self.reference, self.uncertain, values or {})


def user_summary(outputs, datasets) -> dict:
    """The errors as the user reads them (:func:`~bscomp.validate.comparison.user_errors`) for model outputs
    per dataset: ``{"per_dataset": [{"frf": [...], "time": [...]}, ...]}``."""
    per = user_errors(list(outputs), datasets)
    return {"per_dataset": [per[i] for i in range(len(datasets))]}


def _channel_errors(outputs, setup) -> list:
    """``[(dataset index, source, channel, chi^2)]``: each residual block's normalised error over the whole
    dataset (fitted and held-out parts)."""
    rows = []
    for i, (y, d, s) in enumerate(zip(outputs, setup.datasets, setup.sigmas)):
        blocks = residual_blocks(y, d, s)
        if isinstance(d, FrfData):
            names = [f"{o}/{n} {part}" for n, o in d.H for part in ("magnitude", "phase")]
        else:
            names = list(d.outputs)
        for name, b in zip(names, blocks):
            chi2 = float(np.mean(np.where(np.isfinite(b), b, 1e6) ** 2)) if b.size else 0.0
            rows.append((i, d.source, name, chi2))
    return rows


# ---- the result ---------------------------------------------------------------------------------------------
@dataclass
class Calibration:
    """Result of :func:`calibrate`: the uncertain parameters fitted, and the errors before and after.

    Attributes
    ----------
    system : System
        The nominal model (at the first dataset's condition).
    uncertain : dict
        ``{parameter: relative spread}`` that set the bounds.
    nominal, values, std : dict
        ``{parameter: value}``: nominal, fitted, and the fitted value's standard deviation.
    bounds : dict
        ``{parameter: (lower, upper)}``.
    at_bound : list of str
        Fitted parameters that ended at a bound (the spread is too small, or the parameter stands in for
        a missing effect).
    error_before, error_after : float
        Normalised error (mean :math:`\\chi^2` of the fitted parts over datasets, 1 = noise floor).
    heldout_before, heldout_after : float or None
        The same on the held-out second halves of the time series (None without any).
    channels : list of dict
        Per dataset and residual block (FRF pair magnitude or phase, time channel): ``dataset`` (index),
        ``source``, ``channel``, ``before`` and ``after`` (:math:`\\chi^2` over the whole dataset).
    user_before, user_after : dict
        The errors as the user reads them (FRF magnitude/phase per pair, fit % per time channel).
    evaluations : int
        Model evaluations of the fit.
    wall_s : float
    """

    system: System
    uncertain: dict
    nominal: dict
    values: dict
    std: dict
    bounds: dict
    at_bound: list
    error_before: float
    error_after: float
    heldout_before: float | None
    heldout_after: float | None
    channels: list
    user_before: dict
    user_after: dict
    evaluations: int = 0
    wall_s: float = 0.0
    summary_before: dict = field(default_factory=dict, repr=False)
    summary_after: dict = field(default_factory=dict, repr=False)

    @property
    def drop(self) -> float:
        """Relative error reduction ``1 - after/before``."""
        return 1.0 - self.error_after / self.error_before if self.error_before > 0 else 0.0

    def apply(self, system: System | None = None) -> System:
        """A copy of ``system`` (default the nominal model) with the fitted values set."""
        s = (self.system if system is None else system).copy()
        for k, v in self.values.items():
            s.set(k, v)
        return s

    def table(self) -> str:
        """The fitted parameters and the errors per channel, as text."""
        held = "" if self.heldout_before is None else \
            f"; held-out {self.heldout_before:.4g} -> {self.heldout_after:.4g}"
        lines = [f"re-calibrated {len(self.values)} uncertain parameter(s) of '{self.system.name}': error "
                 f"{self.error_before:.4g} -> {self.error_after:.4g} ({100 * self.drop:.1f} % less; mean chi^2 of "
                 f"the fitted parts, 1 = noise floor){held}", "",
                 f"  {'parameter':<24} {'nominal':>12} {'fitted':>12} {'+- std':>10} {'change':>8}  bounds"]
        for k, v in self.values.items():
            v0, (lo, hi) = self.nominal[k], self.bounds[k]
            flag = "  (at a bound)" if k in self.at_bound else ""
            lines.append(f"  {k:<24} {v0:12.6g} {v:12.6g} {self.std.get(k, float('nan')):10.2g} "
                         f"{100 * (v / v0 - 1):+7.2f} %  [{lo:.4g}, {hi:.4g}]{flag}")
        lines += [f"  ({STD_NOTE})", "", "errors per channel (chi^2 over the whole dataset, before -> after):"]
        lines += [f"  {r['dataset'] + 1}. {r['channel']:<28} {r['before']:10.4g} -> {r['after']:.4g}"
                  for r in self.channels]
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def to_dict(self) -> dict:
        return {"system": self.system.name, "uncertain": self.uncertain, "nominal": self.nominal,
                "values": self.values, "std": self.std, "bounds": {k: list(v) for k, v in self.bounds.items()},
                "at_bound": self.at_bound, "error_before": self.error_before, "error_after": self.error_after,
                "drop": self.drop, "heldout_before": self.heldout_before, "heldout_after": self.heldout_after,
                "channels": self.channels, "user_before": self.user_before, "user_after": self.user_after,
                "evaluations": self.evaluations, "wall_s": self.wall_s}

    def to_json(self, path=None) -> str:
        """JSON text of :meth:`to_dict`; written to ``path`` if given."""
        text = json.dumps(self.to_dict(), indent=2, default=json_default)
        if path is not None:
            with atomic_write(path, what="Calibration.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def plot(self, path=None):
        """Fitted parameters (change from nominal with +- std) and the error per channel before/after
        (:func:`bscomp.plotting.validate.calibration_plot`); returns the figure."""
        changes = {k: 100 * (v / self.nominal[k] - 1) for k, v in self.values.items()}
        spread = {k: 100 * self.std.get(k, float("nan")) / self.nominal[k] for k in self.values}
        labels = [f"{r['dataset'] + 1}. {r['channel']}" for r in self.channels]
        return calibration_plot(changes, spread, labels, [r["before"] for r in self.channels],
                                [r["after"] for r in self.channels], path=path,
                                title=f"{self.system.name}: re-calibration")



# ---- the fit ---------------------------------------------------------------------------------------------------
def fit_uncertain(setup: FitSetup, max_nfev: int | None = None) -> Calibration:
    """Fit the uncertain parameters of ``setup`` with no effect added (see the module docstring).

    The nominal model's errors are evaluated first, then the bounded least squares starts from the
    nominal values. Runs in the calling thread's BLAS settings (:func:`calibrate` limits them).
    """
    t0 = time.perf_counter()
    ev0, st0 = setup.structures.get([])
    before = Problem(ev0, setup.sigmas, {}, [], [], st0).summary(np.zeros(0), 0)
    prob = Problem(ev0, setup.sigmas, {}, setup.bounds(), [], st0)
    theta, sol = prob.fit(max_nfev=max_nfev)
    after = prob.summary(theta, len(setup.uncertain))
    values, std = prob.values(theta), prob.uncertainty(theta, sol)
    ch_before = _channel_errors(before["outputs"], setup)
    ch_after = _channel_errors(after["outputs"], setup)
    channels = [{"dataset": i, "source": src, "channel": name, "before": b, "after": a}
                for (i, src, name, b), (_, _, _, a) in zip(ch_before, ch_after)]
    ref = setup.reference
    return Calibration(
        system=ref, uncertain=dict(setup.uncertain), nominal={k: float(ref.get(k)) for k in setup.uncertain},
        values=values, std={k: std.get(k, float("nan")) for k in values},
        bounds={name: (lo, hi) for name, (lo, hi, _) in setup.bounds()},
        at_bound=prob.at_bound(theta, list(setup.uncertain)) if len(theta) else [],
        error_before=before["error"], error_after=after["error"], heldout_before=before["heldout"],
        heldout_after=after["heldout"], channels=channels,
        user_before=user_summary(before["outputs"], setup.datasets),
        user_after=user_summary(after["outputs"], setup.datasets), evaluations=prob.nfev,
        wall_s=time.perf_counter() - t0, summary_before=before, summary_after=after)


def calibrate(model, datasets, uncertain=None, *, overrides: dict | None = None, default_spread: float = 0.2,
              max_nfev: int | None = None, harmonics: int = AMPLITUDE_HARMONICS) -> Calibration:
    """Fit a drive's uncertain parameters to measurements, no effect added.

    Parameters
    ----------
    model : str, callable or System
        The nominal model: a registered name, ``.py`` path or build function is built at each dataset's
        conditions (:func:`~bscomp.validate.residuals.build_for`); a System is used as is (dotted
        conditions applied as parameter values).
    datasets : FrfData, TimeData, file path, or a list of them
    uncertain : list of str or dict, optional
        The parameters to fit; a dict gives each one's relative spread (the bounds are
        ``v0 / (1 + spread)`` .. ``v0 (1 + spread)``), a list uses ``default_spread``. Default: the
        drive's declared ``validation.uncertain`` with its spreads.
    overrides : dict, optional
        Build arguments / parameter values for every dataset, over the files' conditions.
    default_spread : float
        Relative spread (> 0) of the parameters given as a list.
    max_nfev : int, optional
        Most residual evaluations of the least-squares fit (>= 1).
    harmonics : int
        For an FRF file that states its sine amplitude: the odd harmonics balanced in the model at that
        amplitude (:meth:`~bscomp.simulation.compiled.CompiledModel.frf`). One (the describing function) is
        biased where the drive sticks and slips (F_c -13 %, table mass +29 % on an FE truth with the model's
        own friction law); the default five are within 2 % there at ~6x the cost (``docs/measurements.md``).

    Returns
    -------
    Calibration
        ``.values``, ``.std``, ``.error_before``/``.error_after``, ``.channels``, ``.apply()`` -> the
        re-calibrated System, ``.table()``, ``.to_json()``, ``.plot()``.

    Examples
    --------
    >>> cal = calibrate("testbed_axial_torsional", ["frf.csv", "time.csv"])   # doctest: +SKIP
    >>> cal.values["table.m"], cal.error_after < cal.error_before             # doctest: +SKIP

    Notes
    -----
    BLAS runs on one thread inside (``threadpoolctl``), as in :func:`~bscomp.validate.diagnostics.diagnose`:
    the work is many small dense eigen-decompositions.
    """
    datasets = load_datasets(datasets, "calibrate")
    default_spread, max_nfev = check_fit(default_spread, max_nfev)
    harmonics = check_harmonics("calibrate", harmonics)
    warn_amplitude_fit(datasets, "calibrate", harmonics=harmonics)
    with threadpool_limits(limits=1, user_api="blas"):
        setup = FitSetup.build(model, datasets, uncertain, overrides, default_spread, harmonics)
        return fit_uncertain(setup, max_nfev=max_nfev)
