r"""A model structure evaluated on a set of measurements: whitened residuals, noise floors, fits.

Used by :func:`~bscomp.validate.calibration.calibrate` and :func:`~bscomp.validate.diagnostics.diagnose`. The
model is evaluated by the library's shared engine :class:`bscomp.simulation.compiled.CompiledModel` (one per model
structure and measurement condition: one flattening, then FRFs and time series per parameter vector in modal
coordinates).

Residuals are *whitened*: each block -- the log10-magnitude or the phase error of one FRF pair, one time
channel -- is divided by that block's **noise level** :math:`\hat\sigma` (:mod:`bscomp.validate.noise`:
estimated from the data's own scatter; per frequency from the stated coherence where an FRF states one),
so magnitude and phase, accelerations and angles, weigh by what the measurement can resolve: the
normalised error :math:`\chi^2` of a block is 1 at the noise floor. A model that explains the data
has :math:`\chi^2 \approx 1` in every block.

Time series are split in two halves in time: the first half is *fitted*, the second is *held out*
to confirm an effect (an effect that only fits noise or stands in for another one does not carry over).
FRFs are fitted whole; a linear effect fitted to them is confirmed by the time series. An FRF file that states
the sine amplitude it was measured at (``FrfData.excitation``) is compared with the model at that amplitude: the
describing function of its friction and backlash elements (:meth:`CompiledModel.frf` ``amplitude=``, with
``harmonics`` odd orders balanced: one is biased where the drive sticks and slips, five are not on the FE truths,
``docs/measurements.md``); a model without them has one FRF at every amplitude.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from bscomp.simulation.compiled import CompiledModel
from bscomp.validate.datasets import FrfData, MeasurementFileError, TimeData
from bscomp.validate.noise import noise_levels
from bscomp.validate.residuals import frf_errors
from bscomp.validate.uncertainty import parameter_std
from bscomp.validate.units_check import check_units

__all__ = ["Evaluator", "Structures", "noise_levels", "Problem", "Free", "block_stats", "residual_blocks"]

BOUND_TOL = 0.02
"""A fitted value within this distance (in log) of a hard bound of its prior is *at* that bound
(:meth:`Problem.near_bounds`; the verdicts and the reports' "(at its lower bound)")."""

FIT_MAX_SUB = 64
"""Most sub-steps per sample of a fit's time series (:meth:`CompiledModel.simulate` ``max_sub``; its own default
256). Where the Newton on the element forces has not converged at 64 it did not at 256 either on the bundled truths
(a screw-nut backlash candidate at b = 0.2-0.4 um beside a steep friction, diagnose's round 2 on the joint + friction
truth: 10 s per evaluation at 256, 2 s at 64); the result is untrustworthy either way and is counted
(``Evaluator.unconverged``), the diagnosis says where."""


def residual_blocks(model_out, data, sigmas):
    """Whitened residual blocks (measured minus model) of one dataset."""
    if isinstance(data, FrfData):
        blocks = []
        # the noise levels carry the coherence (per frequency, where it was stated): no weight on top
        for (e_mag, e_ph, _w), (s_m, s_p) in zip(frf_errors(model_out, data).values(),
                                                 zip(sigmas[0::2], sigmas[1::2])):
            blocks += [e_mag / s_m, e_ph / s_p]
        return blocks
    out = []
    for (n, y), s in zip(data.outputs.items(), sigmas):
        m = np.asarray(model_out[n], float)
        out.append((np.asarray(y, float)[:m.size] - m) / s)     # a model run over a prefix: that prefix
    return out


def _split_point(data, min_events: int = 2):
    """Index splitting a time series into fitted and held-out halves, or None when a half would see fewer
    than ``min_events`` input steps (a 0.2 s record of a 5 Hz square wave: its first half has no reversal,
    so backlash or friction could neither be fitted nor confirmed)."""
    n = data.t.size
    mid = n // 2
    steps = np.zeros(n - 1, bool)
    for u in data.inputs.values():
        du = np.abs(np.diff(np.asarray(u, float)))
        steps |= du > 0.1 * max(float(np.max(du)) if du.size else 0.0, 1e-300)
    k = np.flatnonzero(steps)
    if np.sum(k < mid) >= min_events and np.sum(k >= mid) >= min_events:
        return mid
    return None


def block_stats(blocks) -> float:
    """Normalised error of a dataset: mean over its blocks of the mean squared whitened residual."""
    vals = [float(np.mean(np.where(np.isfinite(b), b, 1e6) ** 2)) for b in blocks if b.size]
    return float(np.mean(vals)) if vals else 0.0


class Evaluator:
    """One model structure (the base system plus effects) on every dataset.

    Parameters
    ----------
    systems : dict
        ``{condition key: System}`` -- the model at each measurement condition (already with the effects).
    datasets : list of FrfData / TimeData
    keys : list
        Condition key of each dataset.
    free : list of str
        Dotted parameters that will be varied (structural ones get their sensitivities measured once).
    harmonics : int
        Odd harmonics balanced for an FRF measured at an amplitude (:meth:`CompiledModel.frf`).
    """

    def __init__(self, systems: dict, datasets, keys, free=(), f_keep: float = 6000.0, n_sub: int = 2,
                 harmonics: int = 1):
        self.datasets, self.keys, self.n_sub, self.harmonics = list(datasets), list(keys), int(n_sub), int(harmonics)
        self.models = {}
        for key, system in systems.items():
            ds = [d for d, k in zip(self.datasets, self.keys) if k == key]
            ins = list(dict.fromkeys([i for d in ds for i in d.inputs]))
            outs = list(dict.fromkeys([o for d in ds for o in d.outputs]))
            cm = CompiledModel(system, ins, outs, f_keep=f_keep)
            for d in ds:                # the files' units against the model's declared ones
                check_units(cm.dae, d)
            for f in free:
                if cm.has_parameter(f):
                    cm.prepare(f)
            self.models[key] = cm
        self.split = []
        for d in self.datasets:
            if isinstance(d, TimeData):
                dt = np.diff(d.t)
                if np.max(np.abs(dt - dt[0])) > 1e-6 * dt[0]:
                    raise MeasurementFileError(d.label, None, 1, "calibrate and diagnose need uniformly sampled "
                                               "time series: resample it to one time step")
                self.split.append(_split_point(d))
            else:
                self.split.append(None)
        self.n_evaluations = 0
        self.unconverged = 0

    def outputs(self, overrides: dict, hooks: dict | None = None, only_frf: bool = False,
                fitted_only: bool = False) -> list:
        """Model outputs per dataset: ``{(input, output): H}`` or ``{name: y}`` (None for time series
        when ``only_frf``; with ``fitted_only`` a split time series is simulated over its fitted first
        half only -- the integration is causal, so those samples equal the whole run's)."""
        hooks = hooks or {}
        delay = float(hooks.get("input_delay", 0.0))
        zeta = float(hooks.get("extra_modal_damping", 0.0))
        out = []
        modal = {}
        for i, (d, key) in enumerate(zip(self.datasets, self.keys)):
            cm = self.models[key]
            mine = {k: v for k, v in overrides.items() if cm.has_parameter(k)}
            if key not in modal:
                modal[key] = cm.modal(mine, extra_damping=zeta, delay=delay)
            mm = modal[key]
            if isinstance(d, FrfData):
                # at the amplitude the file states: the describing function of the model's friction and backlash
                out.append(cm.frf(mine, d.freqs, list(d.H), delay=delay, mm=mm, amplitude=d.excitation,
                                  harmonics=self.harmonics))
            elif only_frf:
                out.append(None)
            else:
                n = self.split[i] if fitted_only and self.split[i] else d.t.size
                inputs = {k: np.asarray(v, float)[:n] for k, v in d.inputs.items()}
                out.append(self._simulate(cm, mine, d.t[:n], inputs, list(d.outputs), delay, mm))
        self.n_evaluations += 1
        return out

    def _simulate(self, cm, params, t, inputs, outputs, delay, mm):
        """One time series at most :data:`FIT_MAX_SUB` sub-steps per sample; one whose Newton did not converge there
        is counted in ``unconverged`` (the diagnosis reports it) instead of warning at every evaluation."""
        y = cm.simulate(params, t, inputs, outputs=outputs, delay=delay, mm=mm,
                        n_sub=self.n_sub if cm.elements else 1, max_sub=FIT_MAX_SUB, warn=False)
        self.unconverged += not cm.stats.get("newton_converged", True)
        return y

    def blocks(self, overrides, hooks, sigmas, only_frf: bool = False, fitted_only: bool = False) -> list:
        """Whitened residual blocks per dataset (a list of lists of arrays; empty for skipped series;
        ``fitted_only``: a split time series' blocks cover its fitted half only)."""
        return [[] if y is None else residual_blocks(y, d, s)
                for y, d, s in zip(self.outputs(overrides, hooks, only_frf, fitted_only), self.datasets, sigmas)]


# ---- a fit problem: free parameters (log space) mapped to overrides -------------------------------------
class Free:
    """A fitted parameter: ``label`` (``"table.m"`` or ``"nut_table_joint.k"``), bounds and start."""

    def __init__(self, label, lower, upper, start):
        self.label, self.lower, self.upper, self.start = label, float(lower), float(upper), float(start)


class Problem:
    """Least squares over the uncertain parameters and the free parameters of some effects.

    ``effects``: list of ``(candidate, values, fit)``; ``uncertain``: list of ``(name, (lo, hi, start))``;
    ``fixed``: dotted overrides held fixed. The residual is the fitted part of every dataset (time series:
    the first half), each dataset scaled by ``1/sqrt(n_d)`` so datasets weigh alike.
    """

    def __init__(self, evaluator, sigmas, fixed, uncertain, effects, systems):
        self.ev, self.sigmas, self.fixed = evaluator, sigmas, dict(fixed)
        self.uncertain, self.effects, self.systems = list(uncertain), effects, systems
        self.free = [Free(name, lo, hi, v) for name, (lo, hi, v) in self.uncertain]
        for cand, values, fit in effects:
            if fit:
                self.free += [Free(f"{cand.name}.{p.name}", p.lower, p.upper, values.get(p.name, p.median))
                              for p in cand.parameters]
        self.nfev = 0
        self.block_sizes = []            # the residual's contiguous blocks (fit_vector; for uncertainty())
        self.only_frf = False          # True: fit the FRF datasets alone (linear evidence)

    def values(self, theta) -> dict:
        return dict(zip([f.label for f in self.free], np.exp(theta).tolist()))

    def overrides(self, theta):
        """(dotted overrides, engine hooks) at ``theta``."""
        vals = self.values(theta)
        ov, hooks = dict(self.fixed), {}
        for name, _ in self.uncertain:
            ov[name] = vals[name]
        ref = next(iter(self.systems.values()))
        for cand, values, fit in self.effects:
            v = dict(values)
            if fit:
                v.update({p.name: vals[f"{cand.name}.{p.name}"] for p in cand.parameters})
            ov.update(cand.overrides(v, ref))
            for k, h in cand.engine_hooks(v, ref).items():
                hooks[k] = hooks.get(k, 0.0) + h
        return ov, hooks

    def all_blocks(self, theta):
        """Residual blocks of what the fit sees: the FRFs and the fitted halves of the time series."""
        ov, hooks = self.overrides(theta)
        if self.only_frf:
            return self.ev.blocks(ov, hooks, self.sigmas, only_frf=True)
        return self.ev.blocks(ov, hooks, self.sigmas, fitted_only=True)

    def fit_vector(self, blocks):
        parts = []
        for b, cut in zip(blocks, self.ev.split):
            bb = [x[:cut] for x in b] if cut else b
            n = sum(x.size for x in bb)
            parts += [np.where(np.isfinite(x), x, 1e6) / math.sqrt(max(n, 1)) for x in bb]
        self.block_sizes = [x.size for x in parts]
        return np.concatenate(parts) if parts else np.zeros(0)

    def residual(self, theta):
        self.nfev += 1
        return self.fit_vector(self.all_blocks(theta))

    def bounds(self):
        return (np.log([f.lower for f in self.free]), np.log([f.upper for f in self.free]))

    def theta0(self):
        lo, hi = self.bounds()
        return np.clip(np.log([f.start for f in self.free]), lo + 1e-9, hi - 1e-9)

    def fit(self, theta0=None, max_nfev=None):
        theta0 = self.theta0() if theta0 is None else np.asarray(theta0, float)
        if not self.free:
            return theta0, None
        lo, hi = self.bounds()
        sol = least_squares(self.residual, np.clip(theta0, lo + 1e-9, hi - 1e-9), bounds=(lo, hi), method="trf",
                            diff_step=1e-4, x_scale=1.0, max_nfev=max_nfev, xtol=1e-6, ftol=1e-8)
        return sol.x, sol

    def uncertainty(self, theta, sol) -> dict:
        """Standard deviations of the fitted parameters: the sandwich covariance with each residual block's
        correlation time (:func:`bscomp.validate.uncertainty.parameter_std`; never below the classical
        ``sigma^2 (J^T J)^-1``), mapped from logs by the delta method."""
        if sol is None or sol.jac is None:
            return {}
        sd, _ = parameter_std(np.asarray(sol.jac), np.asarray(sol.fun), self.block_sizes)
        return {f.label: float(math.exp(t) * s) for f, t, s in zip(self.free, theta, sd)}

    def summary(self, theta, k: int) -> dict:
        r"""Errors of one parameter vector with ``k`` fitted parameters: ``error`` (mean chi^2 of the fitted
        parts), ``per_dataset``, ``heldout`` (mean over the held-out halves, None without any),
        ``heldout_per_dataset``, ``fitted_split`` (the fitted first halves of the datasets that have a held-out
        half, in its order), ``bic`` (:math:`\sum r^2 + k \ln n` on the fitted residuals) and the model ``outputs``
        per dataset."""
        ov, hooks = self.overrides(theta)
        outs = self.ev.outputs(ov, hooks)
        blocks = [residual_blocks(y, d, s) for y, d, s in zip(outs, self.ev.datasets, self.sigmas)]
        fit_d, held_d, n_fit, ss = [], [], 0, 0.0
        for b, cut in zip(blocks, self.ev.split):
            fb = [x[:cut] for x in b] if cut else b
            fit_d.append(block_stats(fb))
            n_fit += sum(x.size for x in fb)
            ss += sum(float(np.sum(np.where(np.isfinite(x), x, 1e6) ** 2)) for x in fb)
            if cut:
                held_d.append(block_stats([x[cut:] for x in b]))
        split_fit = [f for f, cut in zip(fit_d, self.ev.split) if cut]
        return {"error": float(np.mean(fit_d)), "per_dataset": fit_d,
                "heldout": float(np.mean(held_d)) if held_d else None, "heldout_per_dataset": held_d,
                "fitted_split": split_fit,
                "bic": ss + k * math.log(max(n_fit, 2)), "outputs": outs}

    def near_bounds(self, theta, tol=BOUND_TOL) -> np.ndarray:
        """Which entries of ``theta`` (log space) are within ``tol`` of a hard bound of the free parameters."""
        lo, hi = self.bounds()
        theta = np.asarray(theta, float)
        return (theta - lo < tol) | (hi - theta < tol)

    def at_bound(self, theta, names, tol=BOUND_TOL) -> list:
        """Free parameters among ``names`` that ended within ``tol`` (in log) of a hard bound."""
        near = self.near_bounds(theta, tol) if len(self.free) else []
        return [f.label for f, at in zip(self.free, near) if f.label in names and at]



class Structures:
    """Evaluators per model structure (the tuple of candidate names added), built once each.

    Parameters
    ----------
    systems : dict
        ``{condition key: System}``: the nominal model at each measurement condition.
    datasets, keys, free, harmonics
        As :class:`Evaluator`.
    """

    def __init__(self, systems, datasets, keys, free, harmonics=1):
        self.systems, self.datasets, self.keys, self.free = systems, datasets, keys, list(free)
        self.harmonics = harmonics
        self.cache = {}

    def get(self, effects):
        """``(Evaluator, {key: System})`` of the nominal model with ``effects`` (``[(candidate, values, fit)]``)."""
        key = tuple(c.name for c, _, _ in effects)
        if key not in self.cache:
            structured = {}
            for k, s in self.systems.items():
                for cand, _v, _f in effects:
                    s = cand.structure(s, linear=False, for_engine=True)
                structured[k] = s
            self.cache[key] = (Evaluator(structured, self.datasets, self.keys, free=self.free,
                                         harmonics=self.harmonics), structured)
        return self.cache[key]
