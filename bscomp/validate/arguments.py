"""The arguments of :func:`~bscomp.validate.compare`, :func:`~bscomp.validate.calibrate` and
:func:`~bscomp.validate.diagnose`, checked before any model is built or fitted.

A malformed argument is a :class:`~bscomp.errors.UsageError` (a wrong type an
:class:`~bscomp.errors.ArgumentTypeError`, an unknown name an :class:`~bscomp.errors.UnknownNameError`)
naming the argument and how to fix it -- never a report computed from a meaningless setting
(``pair_tolerance=0`` pairing no resonance, ``max_effects=-1`` reporting "no missing effect").
"""

from __future__ import annotations

import difflib
import math
import warnings
from pathlib import Path

from bscomp.errors import ArgumentTypeError, UnknownNameError, UsageError, check_number
from bscomp.simulation.harmonic_balance import check_harmonics
from bscomp.validate.candidates import Candidate
from bscomp.validate.candidates import library as candidate_library
from bscomp.validate.datasets import FrfData, TimeData, check_points
from bscomp.validate.readers import load_all

__all__ = ["load_datasets", "check_bands", "check_compare", "check_fit", "check_diagnose", "resolve_candidates",
           "check_uncertain_names", "LEGACY_DIAGNOSE"]

#: keywords of earlier versions of diagnose, accepted and ignored (with a DeprecationWarning)
LEGACY_DIAGNOSE = ("compare_signatures", "n_starts", "n_swap")
_EXAMPLE = "e.g. 'systems/data/validation/frf.csv', or an FrfData / TimeData"


def load_datasets(datasets, who: str) -> list:
    """The datasets of ``who`` (one or a list of paths / FrfData / TimeData), read and with enough points."""
    if isinstance(datasets, (FrfData, TimeData, str, Path)):
        datasets = [datasets]
    if isinstance(datasets, (list, tuple)) and not datasets:
        raise UsageError(f"{who}: datasets is empty: give at least one measurement", hint=f"pass FRF or "
                         f"time-series files ({_EXAMPLE})")
    out = load_all(datasets)
    for d in out:
        check_points(d, who)
    return out


def _pair(b):
    try:
        lo, hi = b
        return float(lo), float(hi)
    except (TypeError, ValueError):
        return None


def check_bands(bands, datasets=()) -> list | None:
    """``bands`` as ``[(lo, hi)]`` [Hz] with ``0 < lo < hi``, each holding a measured frequency; None: octaves."""
    if bands is None:
        return None
    if isinstance(bands, (str, bytes)) or not hasattr(bands, "__iter__"):
        raise ArgumentTypeError(f"bands must be a list of (lo, hi) frequency bands in Hz, e.g. [(10, 100), (100, "
                                f"1000)], got {type(bands).__name__} {bands!r}"[:300])
    out = []
    for k, b in enumerate(bands):
        p = _pair(b)
        if p is None:
            raise ArgumentTypeError(f"bands[{k}] must be a pair (lo, hi) of frequencies in Hz, got {b!r}"[:300])
        lo, hi = p
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise UsageError(f"bands[{k}] = ({lo:g}, {hi:g}): a band needs finite frequencies 0 < lo < hi [Hz]")
        out.append((lo, hi))
    if not out:
        raise UsageError("bands is empty: give at least one (lo, hi) band in Hz, or leave it out for octaves")
    freqs = [d.freqs for d in datasets if isinstance(d, FrfData)]
    for k, (lo, hi) in enumerate(out):
        if freqs and not any(((f >= lo) & (f < hi)).any() for f in freqs):
            rng = ", ".join(f"{f.min():.4g}-{f.max():.4g} Hz" for f in freqs)
            raise UsageError(f"bands[{k}] = ({lo:g}, {hi:g}) Hz holds no measured frequency (measured: {rng}): "
                             "give bands inside the measured range")
    return out


def check_compare(bands, pair_tolerance, n_windows, datasets):
    """``(bands, pair_tolerance, n_windows)`` of :func:`~bscomp.validate.compare`, checked."""
    tol = check_number("pair_tolerance", pair_tolerance, positive=True)
    nw = check_number("n_windows", n_windows, integer=True, minimum=1)
    return check_bands(bands, datasets), tol, nw


def check_fit(default_spread, max_nfev=None):
    """``default_spread`` (> 0: bounds v0/(1+s) .. v0(1+s)) and ``max_nfev`` (None or an integer >= 1)."""
    spread = check_number("default_spread", default_spread, positive=True)
    if max_nfev is not None:
        max_nfev = check_number("max_nfev", max_nfev, integer=True, minimum=1)
    return spread, max_nfev


def check_diagnose(legacy: dict, allowed, **numbers) -> dict:
    """The numeric settings of :func:`~bscomp.validate.diagnose`, checked; ``legacy`` (the extra keywords) may
    hold only :data:`LEGACY_DIAGNOSE` (ignored, with a DeprecationWarning)."""
    for k in legacy:
        if k not in LEGACY_DIAGNOSE:
            close = difflib.get_close_matches(k, list(allowed), n=1)
            raise UsageError(f"diagnose() got an unknown keyword argument {k!r}"
                             + (f": did you mean {close[0]!r}?" if close else ""),
                             hint=f"its keywords: {', '.join(allowed)}")
    if legacy:
        warnings.warn(f"diagnose: {', '.join(sorted(legacy))} no longer do anything and are ignored",
                      DeprecationWarning, stacklevel=3)
    ints = {"max_effects": 0, "n_refine": 1, "n_screen": 1, "n_scan": 2}     # max_effects 0: re-calibrate only
    out = {}
    for k, v in numbers.items():
        if k in ints:
            out[k] = check_number(k, v, integer=True, minimum=ints[k])
        elif k == "bic_threshold":
            out[k] = check_number(k, v)
        elif k == "default_spread":
            out[k] = check_number(k, v, positive=True)
        elif k == "harmonics":
            out[k] = check_harmonics("diagnose", v)     # at the balance's 256 phases
        else:                                   # min_drop, min_heldout_drop, noise_tolerance
            out[k] = check_number(k, v, nonnegative=True)
    return out


def resolve_candidates(candidates):
    """``candidates`` as Candidate objects: Candidate instances or names of the library's
    (:func:`~bscomp.validate.candidates.library`: the defaults and the optional ones); None keeps the default. An effect
    given twice (``default_candidates() + ["rotor_friction"]``, written when that one was optional) is kept once,
    where it first appears; two that differ under one name are a :class:`UsageError`."""
    if candidates is None:
        return None
    if isinstance(candidates, (str, Candidate)):
        candidates = [candidates]
    if not isinstance(candidates, (list, tuple)):
        raise ArgumentTypeError(f"candidates must be a list of candidate names or Candidate objects, got "
                                f"{type(candidates).__name__} {candidates!r}"[:300])
    library = candidate_library()
    out = []
    for k, c in enumerate(candidates):
        if isinstance(c, str):
            if c not in library:
                close = difflib.get_close_matches(c, list(library), n=1)
                raise UnknownNameError(f"candidates[{k}] = {c!r} is not a candidate effect"
                                       + (f" (did you mean {close[0]!r}?)" if close else "")
                                       + f"; candidates: {', '.join(library)}")
            c = library[c]
        elif not isinstance(c, Candidate):
            raise ArgumentTypeError(f"candidates[{k}] must be a candidate name or a Candidate, got "
                                    f"{type(c).__name__} {c!r}; names: {', '.join(library)}"[:400])
        prev = next((o for o in out if o.name == c.name), None)
        if prev is None:
            out.append(c)
        elif type(prev) is not type(c) or vars(prev) != vars(c):
            raise UsageError(f"candidates[{k}] is named {c.name!r} like an earlier one that differs from it "
                             f"({type(prev).__name__}, here {type(c).__name__}): each effect once, under its own name",
                             hint="leave one out, or give it another name (candidate.name = ...)")
    if not out:
        raise UsageError("candidates is empty: name at least one effect, or leave it out for all of them",
                         hint=f"names: {', '.join(library)}")
    return out


def check_uncertain_names(system, names) -> None:
    """Each uncertain parameter must be a numeric parameter ``component.parameter`` of ``system``."""
    params = system.parameters()
    for name in names:
        if not isinstance(name, str):
            raise ArgumentTypeError(f"uncertain parameters are named 'component.parameter' (str), got "
                                    f"{type(name).__name__} {name!r}")
        if name.split("[", 1)[0] in params:
            continue
        close = difflib.get_close_matches(name, list(params), n=3) or [
            p for p in params if p.rsplit(".", 1)[-1] == name][:3]
        some = close or list(params)[:6]
        raise UnknownNameError(f"uncertain parameter {name!r} is not a parameter of '{system.name}': uncertain "
                               f"parameters are named 'component.parameter', e.g. {', '.join(some)}")
