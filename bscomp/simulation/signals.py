"""Test signals for :func:`bscomp.simulation.simulate` inputs, and their one-line spelling for the CLI.

Each function returns a callable ``u(t)`` (what ``simulate(inputs={name: u})`` takes; held on each interval at
its midpoint value), written in numpy so that ``simulate`` evaluates it once for the whole grid. The thesis's
Ch 5 open-loop run is ``square(2.125, 5.0)`` on ``amp.u`` (4.25 V peak to peak, 5 Hz, Sec 5.3.1).

=================================  ===========================================================
spelling (``bscomp simulate``)      signal
=================================  ===========================================================
``2.5``                             constant 2.5
``step:A[:T0]``                     0 before ``T0`` (default 0 s), ``A`` from it on
``square:A:F``                      ``+A`` on the first half of each period ``1/F``, ``-A`` on the second
``sine:A:F``                        ``A sin(2 pi F t)``
``ramp:RATE[:T0]``                  ``RATE (t - T0)`` from ``T0`` on, 0 before
=================================  ===========================================================
"""

from __future__ import annotations

import math

import numpy as np

from bscomp.errors import UsageError

__all__ = ["step", "square", "sine", "ramp", "parse_signal", "SPELLINGS"]

SPELLINGS = "a number, step:A[:T0], square:A:F, sine:A:F or ramp:RATE[:T0]"


def step(amplitude: float, t0: float = 0.0):
    """``0`` before ``t0`` [s], ``amplitude`` from it on."""
    return lambda t: np.where(np.asarray(t) >= t0, amplitude, 0.0)


def square(amplitude: float, frequency: float):
    """``+amplitude`` on the first half of each period ``1/frequency`` [Hz], ``-amplitude`` on the second."""
    return lambda t: np.where((np.asarray(t) * frequency) % 1.0 < 0.5, amplitude, -amplitude)


def sine(amplitude: float, frequency: float):
    """``amplitude sin(2 pi frequency t)``."""
    return lambda t: amplitude * np.sin(2 * math.pi * frequency * np.asarray(t))


def ramp(rate: float, t0: float = 0.0):
    """``rate (t - t0)`` from ``t0`` [s] on, 0 before."""
    return lambda t: np.where(np.asarray(t) >= t0, rate * (np.asarray(t) - t0), 0.0)


_KINDS = {"step": (step, 1, 2, False), "square": (square, 2, 2, True), "sine": (sine, 2, 2, True),
          "ramp": (ramp, 1, 2, False)}


def parse_signal(text: str, what: str = "signal"):
    """A signal from its spelling (module table): a float for a constant, else a callable ``u(t)``.

    Raises
    ------
    UsageError
        The spelling is not one of the table's, a number is malformed or not finite, or a frequency is not
        positive; the message quotes ``what`` (e.g. ``--input amp.u``) and the text.
    """
    text = text.strip()
    kind, _, rest = text.partition(":")
    try:
        values = [float(v) for v in rest.split(":")] if rest else []
        if kind not in _KINDS:
            value = float(text)
            if not math.isfinite(value):
                raise ValueError
            return value
    except ValueError:
        raise UsageError(f"{what}: cannot read {text!r} as a signal", hint=f"give {SPELLINGS}") from None
    fn, lo, hi, positive_last = _KINDS[kind]
    if not lo <= len(values) <= hi or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{what}: {kind} takes {lo}{'' if lo == hi else f' or {hi}'} finite number(s) after "
                         f"'{kind}:', got {text!r}", hint=f"give {SPELLINGS}")
    if positive_last and values[-1] <= 0:
        raise UsageError(f"{what}: the frequency of {text!r} must be > 0 Hz", hint=f"give {SPELLINGS}")
    return fn(*values)
