"""Argument checks of :class:`bscomp.simulation.compiled.CompiledModel`'s FRF and time-series requests: every bad
argument a named error saying what is expected."""

from __future__ import annotations

import numpy as np

from bscomp.errors import ArgumentTypeError, BscompError, UnknownNameError, UsageError, check_mapping, check_number
from bscomp.simulation.harmonic_balance import check_harmonics

__all__ = ["CompiledModelError", "check_frf", "check_run"]


class CompiledModelError(BscompError):
    """A model that the compiled evaluator cannot handle (named element, what to do instead)."""


def check_frf(cm, freqs, pairs, amplitude, extra_damping, delay, points, tol, harmonics=1):
    """``(freqs, pairs, {input: amplitude})`` of an :meth:`frf` request, every argument checked."""
    try:
        f = np.atleast_1d(np.asarray(freqs, float))
    except (TypeError, ValueError):
        raise UsageError(f"CompiledModel.frf: freqs must be an array of frequencies [Hz], got {freqs!r}"[:300]) \
            from None
    if f.ndim != 1 or not f.size or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise UsageError(f"CompiledModel.frf: freqs must be a non-empty 1-D array of positive, finite frequencies "
                         f"[Hz], got {f!r}"[:300])
    if isinstance(pairs, (str, bytes)) or not hasattr(pairs, "__iter__"):
        raise ArgumentTypeError(f"CompiledModel.frf: pairs must be a list of (input, output) tuples, got {pairs!r}")
    pairs = [tuple(pq) if isinstance(pq, (tuple, list)) else pq for pq in pairs]
    for pq in pairs:
        if not (isinstance(pq, tuple) and len(pq) == 2 and all(isinstance(x, str) for x in pq)):
            raise ArgumentTypeError(f"CompiledModel.frf: each pair must be (input, output) names, got {pq!r}")
        if pq[0] not in cm.inputs:
            raise UnknownNameError(f"CompiledModel.frf: '{pq[0]}' is not an input of this compiled model; inputs: "
                                   f"{cm.inputs} (give it to CompiledModel(inputs=...))")
        if pq[1] not in cm.outputs:
            raise UnknownNameError(f"CompiledModel.frf: '{pq[1]}' is not an output of this compiled model; "
                                   f"outputs: {cm.outputs} (give it to CompiledModel(outputs=...))")
    amp = check_mapping("CompiledModel.frf: amplitude", amplitude, "excitation amplitudes")
    for k, v in amp.items():
        if k not in cm.inputs:
            raise UnknownNameError(f"CompiledModel.frf: amplitude given for '{k}', which is not an input of this "
                                   f"compiled model; inputs: {cm.inputs}")
        amp[k] = check_number(f"CompiledModel.frf: amplitude['{k}']", v, positive=True)
    check_number("CompiledModel.frf: extra_damping", extra_damping, nonnegative=True)
    check_number("CompiledModel.frf: delay", delay, nonnegative=True)
    if amp:
        check_number("CompiledModel.frf: points", points, integer=True, minimum=16)
        if points % 4:
            raise UsageError(f"CompiledModel.frf: points must be a multiple of 4, got {points}")
        check_number("CompiledModel.frf: tol", tol, positive=True)
        check_harmonics("CompiledModel.frf", harmonics, points)
    return f, pairs, amp


def check_run(cm, t, inputs, outputs):
    """``(t, inputs, outputs)`` of a :meth:`simulate` request, each checked (named errors)."""
    try:
        t = np.asarray(t, float)
    except (TypeError, ValueError):
        raise UsageError(f"CompiledModel.simulate: t must be an array of times [s], got {t!r}"[:300]) from None
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise UsageError("CompiledModel.simulate: t must be a 1-D array of at least 2 finite, increasing times [s]")
    dt = float(t[1] - t[0])
    if np.max(np.abs(np.diff(t) - dt)) > 1e-6 * dt:
        raise CompiledModelError("CompiledModel.simulate needs a uniformly sampled time grid")
    inputs = check_mapping("CompiledModel.simulate: inputs", inputs, "input histories")
    for k, v in inputs.items():
        if k not in cm.inputs:
            raise UnknownNameError(f"CompiledModel.simulate: '{k}' is not an input of this compiled model; inputs: "
                                   f"{cm.inputs}")
        if np.shape(v) != t.shape or not np.all(np.isfinite(np.asarray(v, float))):
            raise UsageError(f"CompiledModel.simulate: inputs['{k}'] must be {t.size} finite values (one per "
                             f"time), got shape {np.shape(v)}")
    known = list(cm.outputs) + list(getattr(cm, "nl_outputs", []))
    if outputs is None:
        outputs = list(cm.outputs)
    elif isinstance(outputs, str):
        outputs = [outputs]
    elif not all(isinstance(o, str) for o in outputs):
        raise ArgumentTypeError(f"CompiledModel.simulate: outputs must be names, got {outputs!r}"[:300])
    bad = [o for o in outputs if o not in known]
    if bad:
        raise UnknownNameError(f"CompiledModel.simulate: {bad} are not outputs of this compiled model; outputs: "
                               f"{cm.outputs} (give them to CompiledModel(outputs=...))")
    return t, inputs, list(outputs)
