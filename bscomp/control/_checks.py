"""Argument checks shared by the public functions of :mod:`bscomp.control`.

Each helper names the calling function and the argument, says what is expected and returns the value in
the form the caller computes with, so a bad argument never reaches numpy or python-control:
a wrong type is an :class:`~bscomp.errors.ArgumentTypeError`, a non-physical number a
:class:`~bscomp.errors.ParameterError` (as before these checks existed), a malformed structure a
:class:`~bscomp.errors.UsageError`.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ArgumentTypeError, ParameterError, UsageError

__all__ = ["real", "integer", "polynomial", "lti"]


def _shown(value) -> str:
    return f"{type(value).__name__} {value!r}"[:120]


def real(func: str, name: str, value, *, positive: bool = False, nonnegative: bool = False,
         unit: str = "") -> float:
    """``value`` as a finite float: a real number (Python or numpy, not bool/str/complex), else
    :class:`ArgumentTypeError`; NaN/inf, ``<= 0`` (``positive``) or ``< 0`` (``nonnegative``) is a
    :class:`ParameterError`. Both name ``func`` and ``name``."""
    arr = np.asarray(value) if not isinstance(value, (str, bytes, bool, np.bool_)) else None
    if arr is None or arr.ndim != 0 or arr.dtype.kind not in "iuf":
        raise ArgumentTypeError(f"{func}: {name} must be a real number{f' [{unit}]' if unit else ''}, "
                                f"got {_shown(value)}")
    v = float(arr)
    u = f" {unit}" if unit else ""
    if not np.isfinite(v):
        raise ParameterError(f"{func}: {name} = {v!r}{u} must be a finite number")
    if positive and not v > 0:
        raise ParameterError(f"{func}: {name} = {v!r}{u} must be a finite number > 0")
    if nonnegative and not v >= 0:
        raise ParameterError(f"{func}: {name} = {v!r}{u} must be a finite number >= 0")
    return v


def integer(func: str, name: str, value, *, minimum: int | None = None) -> int:
    """``value`` as an int (a whole Python/numpy number), at least ``minimum``, else a :class:`UsageError`
    (:class:`ArgumentTypeError` for a non-number) naming ``func`` and ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, float, np.floating)):
        raise ArgumentTypeError(f"{func}: {name} must be an integer, got {_shown(value)}")
    if not (np.isfinite(value) and float(value) == int(value)):
        raise UsageError(f"{func}: {name} must be an integer, got {value!r}")
    v = int(value)
    if minimum is not None and v < minimum:
        raise UsageError(f"{func}: {name} = {v} must be >= {minimum}")
    return v


def polynomial(func: str, name: str, value, *, min_degree: int = 0, trim: bool = True,
               nonzero: bool = True) -> np.ndarray:
    """``value`` as a 1-D float array of finite polynomial coefficients (descending powers of ``z``),
    leading zeros removed if ``trim``; it must not be empty or all zero (``nonzero``) and have at least
    ``min_degree``. A non-numeric value is an :class:`ArgumentTypeError`, the rest :class:`ParameterError`."""
    what = "a sequence of real polynomial coefficients (descending powers of z), e.g. [1.0, -0.9]"
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise ArgumentTypeError(f"{func}: {name} must be {what}, got {_shown(value)}")
    try:
        arr = np.atleast_1d(np.asarray(value))
    except (TypeError, ValueError):  # ragged nesting
        raise ArgumentTypeError(f"{func}: {name} must be {what}, got {_shown(value)}") from None
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iuf"):
        raise ArgumentTypeError(f"{func}: {name} must be {what}, got {_shown(value)}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{func}: {name} = {arr.tolist()} has NaN or infinite coefficients")
    if trim:
        arr = np.trim_zeros(arr, "f")
    if nonzero and (arr.size == 0 or not np.any(arr)):
        raise ParameterError(f"{func}: {name} is empty or zero; give {what}")
    if arr.size - 1 < min_degree:
        raise ParameterError(f"{func}: {name} = {arr.tolist()} has degree {max(arr.size - 1, 0)}, needs at "
                             f"least {min_degree}")
    return arr


def lti(func: str, name: str, value, *, siso: bool = False):
    """``value`` if it is a python-control LTI system (``StateSpace`` or ``TransferFunction``), SISO if
    asked, else :class:`ArgumentTypeError` (:class:`UsageError` for the wrong size)."""
    import control

    if not isinstance(value, control.LTI):
        raise ArgumentTypeError(f"{func}: {name} must be a python-control LTI system (control.StateSpace or "
                                f"control.TransferFunction), got {_shown(value)}")
    if siso and (value.ninputs != 1 or value.noutputs != 1):
        raise UsageError(f"{func}: {name} must be SISO (one input, one output), got {value.noutputs} "
                         f"outputs x {value.ninputs} inputs; select one channel, e.g. sys[0, 0]")
    return value
