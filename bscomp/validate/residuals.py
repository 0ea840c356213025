"""The model evaluated at the measurements, residuals, a scalar cost and MATLAB's fit %.

Sign convention (as MATLAB's ``resid``): a residual is **measured minus model**, ``e = y - y_hat``.

* FRF residuals per pair, stacked: :math:`\\log_{10}|H_m| - \\log_{10}|\\hat H|` and the wrapped phase
  difference :math:`\\angle H_m - \\angle \\hat H` [rad], each multiplied by :math:`\\sqrt{\\gamma^2}`
  (coherence) where it was measured, so the squared residual is coherence-weighted. One decade of
  magnitude error (20 dB) weighs as much as one radian of phase.
* Time residuals per channel: :math:`(y - \\hat y) / \\mathrm{rms}(y)`.
* :func:`cost`: the mean over datasets of each dataset's mean squared residual, so an FRF of 400 points
  and a time series of 4000 samples weigh alike.
* :func:`fit_percent`: :math:`100\\,(1 - \\lVert y - \\hat y\\rVert / \\lVert y - \\bar y\\rVert)`
  (MATLAB ``compare``'s NRMSE fit; complex data allowed).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from bscomp.errors import BscompError, UnknownNameError
from bscomp.kernel.dae import Dae
from bscomp.kernel.flattening import flatten
from bscomp.kernel.system import System
from bscomp.linear.response import frf
from bscomp.model import ModelSpec, as_system, build_keywords, model_name
from bscomp.simulation.compiled import nonlinear_elements
from bscomp.simulation.dispatch import simulate
from bscomp.simulation.modal_channels import ModalSimulationError
from bscomp.validate.datasets import FrfData, MeasurementFileError, TimeData, check_condition
from bscomp.validate.units_check import check_units

__all__ = ["model_frf", "model_time", "frf_residuals", "time_residuals", "cost", "fit_percent",
           "build_for", "build_for_data", "data_label", "frf_errors", "frf_at", "simulate_for", "simulate_at",
           "check_channels", "ConditionIgnoredWarning"]


# ---- the model at the measurement's conditions ---------------------------------------------------------
class ConditionIgnoredWarning(UserWarning):
    """A dataset's condition that the model cannot take (not a build argument, not a parameter)."""


def build_for(system_or_build, conditions: dict | None = None, params: dict | None = None, source: str = "",
              locations: dict | None = None):
    """The System a dataset is compared with.

    Conditions are split by name: a **dotted** name (``table.m``) is a parameter override
    (``System.set``); a name **without a dot** (``nut_position``) is a keyword argument of the build
    function. A plain condition the build function does not take is dropped with a
    :class:`ConditionIgnoredWarning` naming the condition and the system -- the same for a callable, a
    registered name and a ``.py`` path. A build function taking ``**kwargs`` that forwards them to one
    other function (the test bed's ``testbed_axial_torsional(**kw)`` calls ``testbed("axial_torsional",
    **kw)``) takes that function's keyword arguments.

    Parameters
    ----------
    system_or_build : System, callable, str or ModelSpec
        A System is used as is: dotted conditions are applied to a copy, plain ones dropped with the
        warning (pass the build function or the name to honour them). A callable is called as
        ``build(**conditions)``. A string is a registered system name or ``.py`` path. Both are built by
        :func:`bscomp.model.as_system`, their keywords read by :func:`bscomp.model.build_keywords` (a path's
        ``build`` signature is read from the file, not run).
    conditions : dict, optional
        Operating conditions of the measurement (e.g. ``nut_position``, ``table.m``).
    params : dict, optional
        Parameter overrides by dotted name, applied last.
    source : str, optional
        The dataset's name (its file's path), for the warning and the errors.
    locations : dict, optional
        ``{condition: (file, line, column)}`` where each condition was declared: a condition the model
        refuses (an unknown parameter, a value out of bounds) is a
        :class:`~bscomp.validate.datasets.MeasurementFileError` pointing there.
    """
    where = {k: tuple((locations or {}).get(k) or (source or "<measurement>", None, None))
             for k in (conditions or {})}
    conditions = {k: check_condition(k, v, where[k])
                  for k, v in (conditions or {}).items()}      # never a file path, never a parameter set
    plain = {k: v for k, v in conditions.items() if "." not in k}
    dotted = {k: v for k, v in conditions.items() if "." in k}
    if isinstance(system_or_build, System):
        _ignore(plain, "the model was given as a built System (pass its build function or name to honour it)",
                source)
        system = system_or_build
    elif isinstance(system_or_build, (str, Path, ModelSpec)) or callable(system_or_build):
        accepted = build_keywords(system_or_build)
        kept = plain if accepted is None else {k: v for k, v in plain.items() if k in accepted}
        label = model_name(system_or_build)
        _ignore([k for k in plain if k not in kept], f"not a build argument of system '{label}' (build arguments: "
                f"{', '.join(sorted(accepted or ())) or 'none'}) nor a parameter ('component.parameter')", source)
        try:
            system = as_system(system_or_build, kept)
        except BscompError as exc:
            if not kept or not _builds(system_or_build):
                raise
            raise _condition_error(exc, kept, where) from None
    else:
        raise UnknownNameError(f"cannot use {type(system_or_build).__name__} as a model: give a system name, a .py "
                               "path, a build function, a bscomp.System or a bscomp.model.ModelSpec")
    mine = {k: v for k, v in dotted.items() if k not in (params or {})}
    for k, v in mine.items():
        try:
            system = system.with_parameters({k: v})
        except BscompError as exc:
            raise _condition_error(exc, {k: v}, where) from None
    return system.with_parameters(params) if params else system


def _builds(system_or_build) -> bool:
    """Whether the model builds without the file's conditions (else the error is not theirs)."""
    try:
        as_system(system_or_build, {})
    except BscompError:
        return False
    return True


def _condition_error(exc, conds: dict, where: dict) -> MeasurementFileError:
    """The model's refusal of a file's ``# condition`` line(s), at the first of them."""
    first = next(iter(conds))
    w = where.get(first, ("<measurement>", None, None))
    names = ", ".join(f"{k} = {v!r}" for k, v in conds.items())
    return MeasurementFileError(w[0], w[1], w[2], f"condition {names}: {exc} (fix or remove the '# condition' "
                                "line)", first)


def data_label(data) -> str:
    """A dataset as warnings name it: its file's path, with its ``# source`` text after it when it has one."""
    path, src = getattr(data, "path", ""), getattr(data, "source", "")
    return data.label if not path or src in ("", path) else f"{path} ({src})"


def build_for_data(system_or_build, data, params: dict | None = None):
    """:func:`build_for` at a dataset's conditions, its errors and warnings naming the dataset's file and the
    condition's line."""
    return build_for(system_or_build, data.conditions, params, source=data_label(data),
                     locations={k: v for (kind, k), v in data.locations.items() if kind == "condition"})


def _ignore(dropped, why: str, source: str) -> None:
    """One warning line per dropped condition."""
    for k in dropped:
        warnings.warn(f"{source + ': ' if source else ''}condition '{k}' ignored: {why}", ConditionIgnoredWarning,
                      stacklevel=3)


def check_channels(dae, data, inputs, outputs):
    """Every measured channel must exist in the model; the error points at the file's column."""
    for name in inputs:
        if name not in dae.u_names:
            key = ("column", name) if isinstance(data, TimeData) else None
            ln, col = data.locations.get(key, (None, None)) if key else (None, None)
            if isinstance(data, FrfData):
                pair = next(p for p in data.H if p[0] == name)
                ln, col = data.locations.get(("column", pair), (None, None))
            raise MeasurementFileError(data.label, ln, col, f"unknown channel: {name!r} is not an input of the "
                                       f"model '{dae.name}' (inputs: {dae.u_names})", name)
    obs = set(dae.output_names())
    for name in outputs:
        if name not in obs:
            ln, col = (None, None)
            if isinstance(data, TimeData):
                ln, col = data.locations.get(("column", name), (None, None))
            else:
                pair = next(p for p in data.H if p[1] == name)
                ln, col = data.locations.get(("column", pair), (None, None))
            close = [k for k in obs if k.split(".")[0] == name.split(".")[0]][:10]
            raise MeasurementFileError(data.label, ln, col, f"unknown channel: {name!r} is not an output of the "
                                       f"model '{dae.name}'" + (f" (outputs of that component: {close})" if close
                                                                else ""), name)
    check_units(dae, data)


def model_frf(system_or_build, data: FrfData, params: dict | None = None) -> dict:
    """The model's FRF at the measured frequencies and conditions, ``{(input, output): H}``.

    Uses the sparse second-order form, or the linearized state space when the model has controller
    states (:func:`bscomp.linear.response.frf`), of the system's small-signal equivalent
    (:meth:`bscomp.System.linear_equivalent`: friction reduced to its viscous part, backlash engaged).
    """
    return frf_at(build_for_data(system_or_build, data, params), data)


def frf_at(system, data: FrfData) -> dict:
    """:func:`model_frf` of a System already built at the dataset's conditions (or of its linear
    equivalent's flattened :class:`~bscomp.Dae`)."""
    dae = system if isinstance(system, Dae) else flatten(system.linear_equivalent())
    ins, outs = data.inputs, data.outputs
    check_channels(dae, data, ins, outs)
    res = frf(dae, input=ins, output=outs, freqs=data.freqs, warn=False)   # compare/diagnose model them
    return {(i, o): res.H[:, res.outputs.index(o), res.inputs.index(i)] for i, o in data.H}


def simulate_for(system_or_build, data: TimeData, params: dict | None = None, extra=(), rtol=1e-7, atol=1e-10):
    """Simulate with the measured inputs; record the measured outputs and ``extra`` observables.

    Returns ``(SimulationResult, system)``. Inputs are held constant from each sample to the next
    (zero-order hold, as a D/A converter does). A linear model is stepped exactly (``method="lti"``), a nonlinear
    one by ``method="modal"`` at :data:`MODAL_TOL`; ``rtol``, ``atol`` are IDAS's, used where the modal method
    refuses the model (``result.stats["method"]`` says which ran).
    """
    system = build_for_data(system_or_build, data, params)
    return simulate_at(system, data, extra, rtol, atol), system


#: ``simulate(method="modal")``'s interpolation tolerance in :func:`simulate_at` (compare's time series of a nonlinear
#: model; IDAS at rtol 1e-7 until 2026-12-07). On the demo's model with friction (NRMSE against IDAS at rtol 1e-10):
#: table.a 1.5e-5 in 0.27 s at 1e-4, 9.8e-5 in 0.10-0.17 s at the default 1e-3, IDAS rtol 1e-7 3.0e-4 in 10.7 s; on
#: random chains with a clearance and friction (``benchmarks/fuzz_modal.py --compare``) the default 1e-3 is >10x less
#: accurate than IDAS rtol 1e-7 on some (a light mass beside large impacts), 1e-4 on none: docs/validation.md,
#: "compare's time series through the modal method".
MODAL_TOL = 1e-4


def simulate_at(system, data: TimeData, extra=(), rtol=1e-7, atol=1e-10):
    """:func:`simulate_for` of a System already built at the dataset's conditions (the SimulationResult)."""
    dae = flatten(system)
    check_channels(dae, data, list(data.inputs), list(data.outputs))
    obs = set(dae.output_names())
    names = list(data.outputs) + [n for n in dict.fromkeys(extra) if n in obs and n not in data.outputs]
    run = dict(inputs=dict(data.inputs), outputs=names)
    # a linear model driven by held inputs is stepped exactly (zero-order hold, as the data were sampled)
    if not nonlinear_elements(system) and not dae.mech.has_internal_states and dae.nz == 0:
        return simulate(dae, data.t, method="lti", **run)
    # friction, backlash, a moving nut, internal states (a Pade delay): the modal method at MODAL_TOL (the linear
    # part exact, the laws' forces held with their error checked); models it does not take (a nonlinear equation it
    # does not correct, such as an active current limit: ModalSimulationError) go to IDAS.
    try:
        return simulate(dae, data.t, method="modal", modal_options={"tol": MODAL_TOL}, **run)
    except ModalSimulationError:
        return simulate(dae, data.t, rtol=rtol, atol=atol, method="idas", **run)


def model_time(system_or_build, data: TimeData, params: dict | None = None) -> dict:
    """Simulated output channels ``{name: y_hat}`` for the measured inputs and conditions."""
    res, _ = simulate_for(system_or_build, data, params)
    return {n: np.asarray(res[n], float) for n in data.outputs}


# ---- residuals ----------------------------------------------------------------------------------------
def _log10abs(h):
    a = np.abs(h)
    tiny = 1e-300 if not np.any(a > 0) else 1e-12 * float(np.max(a))
    return np.log10(np.maximum(a, tiny))


def frf_errors(model_H: dict, data: FrfData) -> dict:
    """Per pair: ``(log10-magnitude error, wrapped phase error [rad], weight)``, measured minus model."""
    out = {}
    for pair, hm in data.H.items():
        if pair not in model_H:
            raise KeyError(f"model FRF has no pair {pair}; pairs: {list(model_H)}")
        h = np.asarray(model_H[pair], complex)
        e_mag = _log10abs(hm) - _log10abs(h)
        e_ph = np.angle(hm * np.conj(h)) if np.any(h != 0) else np.zeros(hm.size)
        g = data.coherence.get(pair)
        w = np.ones(hm.size) if g is None else np.sqrt(np.clip(g, 0.0, 1.0))
        out[pair] = (e_mag, e_ph, w)
    return out


def frf_residuals(model_H: dict, data: FrfData) -> np.ndarray:
    """Stacked, coherence-weighted residuals: per pair ``[w e_mag, w e_phase]`` (see module notes)."""
    parts = []
    for e_mag, e_ph, w in frf_errors(model_H, data).values():
        parts += [w * e_mag, w * e_ph]
    return np.concatenate(parts) if parts else np.zeros(0)


def _rms(y):
    r = float(np.sqrt(np.mean(np.square(y)))) if len(y) else 0.0
    return r if r > 0 else 1.0


def time_residuals(model_y: dict, data: TimeData) -> np.ndarray:
    """Stacked residuals per output channel, ``(y - y_hat) / rms(y)``."""
    parts = []
    for name, y in data.outputs.items():
        if name not in model_y:
            raise KeyError(f"model response has no channel {name!r}; channels: {list(model_y)}")
        parts.append((y - np.asarray(model_y[name], float)) / _rms(y))
    return np.concatenate(parts) if parts else np.zeros(0)


def residuals(system_or_build, data, params: dict | None = None) -> np.ndarray:
    """Residual vector of one dataset (FRF or time series)."""
    if isinstance(data, FrfData):
        return frf_residuals(model_frf(system_or_build, data, params), data)
    if isinstance(data, TimeData):
        return time_residuals(model_time(system_or_build, data, params), data)
    raise TypeError(f"expected FrfData or TimeData, got {type(data).__name__}")


def cost(system_or_build, datasets, params: dict | None = None) -> float:
    """Mean over datasets of the mean squared residual (0 for a perfect model)."""
    if isinstance(datasets, (FrfData, TimeData)):
        datasets = [datasets]
    datasets = list(datasets)
    if not datasets:
        raise ValueError("cost needs at least one dataset")
    return float(np.mean([np.mean(np.square(residuals(system_or_build, d, params))) for d in datasets]))


def fit_percent(model, measured) -> float:
    """MATLAB ``compare`` fit: :math:`100 (1 - \\lVert y - \\hat y\\rVert / \\lVert y - \\bar y\\rVert)` [%].

    100 is a perfect fit, 0 no better than the mean, negative worse. Works for complex FRFs.
    """
    y = np.asarray(measured)
    yh = np.asarray(model)
    if y.shape != yh.shape:
        raise ValueError(f"model {yh.shape} and measured {y.shape} differ in shape")
    den = np.linalg.norm(y - np.mean(y))
    num = np.linalg.norm(y - yh)
    if den == 0:
        return 100.0 if num == 0 else -np.inf
    return float(100.0 * (1.0 - num / den))
