r"""Stepped-sine frequency response of a nonlinear model at a real excitation amplitude.

A linear analysis (:func:`bscomp.frf`) replaces friction, backlash or a current limit by its tangent at the
operating point, which holds for small motions only; a test engineer measures the FRF of a feed drive with
a shaker or the amplifier at a chosen amplitude, and with guideway friction the result depends on that
amplitude. :func:`stepped_sine` does what such a test does, on the model: at each frequency ``f`` it drives
``input = offset + A sin(2 pi f t)`` (held over ``samples`` intervals per period, as a controller's DAC
would; the amplitude rises over the first ``RAMP`` = 4 periods), waits until the response is periodic, and
takes the first harmonic of each output over whole periods:

.. math:: y(t) \approx c_0 + c_1 t + \sum_k \mathrm{Re}\big(Y_k e^{jk\omega t}\big), \qquad
          H(j\omega) = Y_1 / U, \qquad U = \frac{2}{T_m}\int_{T_m} u(t)\, e^{-j\omega t}\, dt,

``Y_k`` by least squares over the last ``periods`` periods, every harmonic the samples resolve in the basis (the
ramp ``c_1 t`` takes a rigid-body drift, e.g. a position under a free rotation, and only that), ``U`` exactly
from the held input (the hold's amplitude and delay are the input's, so a linear model gives its own ``H``; an
output with feed-through, an acceleration, is sampled at the hold's edges, which costs ``(pi / samples)^2 / 6``,
1e-4 at 128 samples). The response is periodic when
the last ``periods`` periods repeat the ones before to ``tol`` of the fundamental's rms (a drift aside);
otherwise the run goes on from its last state until it has settled 4x longer (up to ``max_settle``
periods). The part of each output the fundamental does not explain is the *distortion*,
``rms(y - fit) / (|Y| / sqrt 2)``: 0 for a linear model, a few percent where friction clips the motion. For a
linear model the result is ``frf``'s (``tests/bscomp/test_stepped_sine.py``); with Coulomb friction it
follows the describing function ``|X| = sqrt(F_0^2 - (4 F_c / pi)^2) / |k - m omega^2|`` where the motion does
not stick (docs/nonlinear.md, "Stepped-sine FRF").
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import ArgumentTypeError, ModelLimitationWarning, UnknownNameError, UsageError, check_number
from bscomp.linear.response import Frf
from bscomp.model import as_dae, run_overrides
from bscomp.simulation.dispatch import simulate

__all__ = ["stepped_sine", "SteppedSine"]

#: periods over which the amplitude rises from 0 (sin^2 envelope): a sine switched on at full amplitude gives a
#: free rigid body a mean velocity A / (m omega), i.e. a position drift, and rings every mode
RAMP = 4


@dataclass
class SteppedSine(Frf):
    """A stepped-sine FRF (:func:`stepped_sine`): :class:`~bscomp.linear.Frf` with ``H[freq, output, 0]`` plus

    Attributes
    ----------
    amplitude : float
        Excitation amplitude (the input's unit).
    distortion : (nf, n_out) ndarray
        ``rms(y - fit) / (|Y| / sqrt 2)`` per frequency and output.
    settle_periods : (nf,) ndarray
        Periods simulated before the measured ones.
    """

    amplitude: float = 0.0
    distortion: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    settle_periods: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def summary(self) -> str:
        """One line: the amplitude and the largest distortion (of the first output)."""
        j = int(np.argmax(d := self.distortion[:, 0]))
        return (f"stepped sine at {self.amplitude:g}: largest distortion {100 * d[j]:.3g} % at {self.freqs[j]:.4g} Hz "
                "(the share of the response that is not the fundamental)")


def _harmonic(t, y, w, samples):
    """``(Y, rms of the rest)``: ``y(t) ~ c0 + c1 t + Σ_k Re(Y_k e^{jkwt})`` by least squares over whole periods
    (columns of ``y``), every harmonic ``k < samples / 2`` the samples resolve in the basis; ``Y = Y_1``, the
    rest ``y - c0 - c1 t - Re(Y e^{jwt})``. With the fundamental alone the drift column ``t``, which is not
    orthogonal to ``sin(k w t)`` over a window, took part of a strong higher harmonic and moved ``Y``: 2.7 % on
    the test bed's table acceleration in stick-slip (its 3rd and 5th harmonics larger than the 1st) with 4
    periods, 15 % with 2, 0.7 % with 6 (``docs/nonlinear.md``, "Describing-function FRF")."""
    tc = t - t.mean()
    k = np.arange(1, max(samples // 2 - 1, 1) + 1)
    ph = w * np.outer(t, k)
    A = np.column_stack([np.ones_like(t), tc, np.cos(ph), np.sin(ph)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    Y = coef[2] - 1j * coef[2 + k.size]
    rest = y - A[:, [0, 1, 2, 2 + k.size]] @ coef[[0, 1, 2, 2 + k.size]]
    return Y, np.sqrt(np.mean(rest ** 2, axis=0))


def _periodic(ya, yb, Y, tol):
    """True when two blocks of whole periods repeat: ``rms(y_b - y_a - mean) <= tol |Y| / sqrt 2`` per output (the
    mean difference is a rigid-body drift; anything else -- a decaying mode, a beat, a sub-harmonic -- is not
    periodic)."""
    d = yb - ya
    d = d - d.mean(axis=0)
    return bool(np.all(np.sqrt(np.mean(d ** 2, axis=0)) <= tol * np.abs(Y) / np.sqrt(2)))


def _input_harmonic(t, u, w):
    """Fundamental ``(2/T) int u e^{-jwt} dt`` of ``u`` held on the intervals ``[t_k, t_k+1)`` (exact)."""
    seg = (np.exp(-1j * w * t[:-1]) - np.exp(-1j * w * t[1:])) / (1j * w)
    return 2.0 / (t[-1] - t[0]) * np.sum(u * seg)


def check_sine_request(who, input, output, freqs, amplitude):
    """``(outputs, freqs)`` of an FRF-at-an-amplitude request (``who``: the function, in the messages), or a
    named :class:`~bscomp.errors.ArgumentTypeError` / :class:`~bscomp.errors.UsageError`."""
    if not isinstance(input, str):
        raise ArgumentTypeError(f"{who}: input must be one input name (str), got {type(input).__name__}")
    outs = [output] if isinstance(output, str) else output
    if not isinstance(outs, (list, tuple)) or not outs or not all(isinstance(o, str) for o in outs):
        raise ArgumentTypeError(f"{who}: output must be a name or a list of names, got {output!r}")
    try:
        f = np.atleast_1d(np.asarray(freqs, float))
    except (TypeError, ValueError):
        raise UsageError(f"{who}: freqs must be an array of frequencies [Hz], got {freqs!r}") from None
    if f.ndim != 1 or not f.size or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise UsageError(f"{who}: freqs must be positive, finite frequencies [Hz], got {f}")
    check_number("amplitude", amplitude, positive=True)
    return list(outs), f


def _check(input, output, freqs, amplitude, offset, samples, settle, periods, max_settle, tol):
    outs, f = check_sine_request("stepped_sine", input, output, freqs, amplitude)
    for name, v, lo in (("samples", samples, 16), ("settle", settle, 1), ("periods", periods, 1),
                        ("max_settle", max_settle, 1)):
        check_number(name, v, integer=True, minimum=lo)
    check_number("tol", tol, positive=True)
    offset = check_number("stepped_sine: offset", offset)
    if max_settle < settle:
        raise UsageError(f"stepped_sine: max_settle = {max_settle} periods is less than settle = {settle}: the "
                         "settling check could never run; give max_settle >= settle")
    return outs, f, offset, float(amplitude)


def stepped_sine(model, input: str, output, freqs, amplitude: float, *, offset: float = 0.0, params: dict | None = None,
                 method: str = "modal", samples: int = 128, settle: int = 10, periods: int = 4,
                 max_settle: int = 640, tol: float = 1e-3, progress: bool | None = None,
                 **simulate_options) -> SteppedSine:
    """Frequency response of ``output`` to a sine of amplitude ``amplitude`` on ``input``, one simulation per
    frequency (module docstring): what a stepped-sine test measures on a drive with friction or backlash.

    Parameters
    ----------
    model : str, path, System, Dae or ModelSpec
        Anything :func:`bscomp.simulate` takes.
    input : str
        The driven input (``"amp.u"``, ``"motor.tau"``...).
    output : str or list of str
        Observables (``"table.a"``...).
    freqs : array_like
        Frequencies [Hz].
    amplitude : float
        Sine amplitude in the input's unit; ``offset`` is added (a bias that keeps a clearance closed).
    params : dict, optional
        Parameter overrides.
    method : str
        Simulation method (default ``"modal"``: exact for the linear part, friction/backlash/moving nut as
        corrections; ``"idas"`` for other nonlinear models).
    samples : int
        Input hold intervals (and output samples) per period.
    settle, periods : int
        Periods simulated before measuring, and measured.
    max_settle : int
        Longest settling [periods] (about: a continuation is at least ``2 periods`` long) before the response
        is reported as not periodic (a :class:`~bscomp.errors.ModelLimitationWarning`).
    tol : float
        Largest rms difference between the last two blocks of ``periods`` periods, relative to the fundamental's
        rms, accepted as periodic.
    progress : bool, optional
        One line per frequency on stderr (default: more than 3 frequencies and stderr is a terminal).
    **simulate_options
        Passed to :func:`bscomp.simulate` (``jit=True``, ``modal_options``, ``rtol``...).

    Returns
    -------
    SteppedSine
        ``H[freq, output, 0]`` with ``distortion`` and ``settle_periods``.

    Raises
    ------
    UsageError, ArgumentTypeError
        Bad frequencies, amplitude or counts (named).
    UnknownNameError
        ``input`` is not an input of the model, or an output is not a signal of it (a parameter, a constant).
    """
    outs, f, offset, amplitude = _check(input, output, freqs, amplitude, offset, samples, settle, periods, max_settle,
                                        tol)
    _check_simulate_options(simulate_options)
    dae = as_dae(model, params)
    if input not in dae.u_names:
        raise UnknownNameError(f"stepped_sine: '{input}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
    dae.require_signals(outs, "stepped_sine")
    own = run_overrides(model, dae, params) or None     # structural ones are in dae already: no re-flattening
    show = (len(f) > 3 and sys.stderr.isatty()) if progress is None else bool(progress)
    H = np.zeros((len(f), len(outs), 1), complex)
    dist = np.zeros((len(f), len(outs)))
    used = np.zeros(len(f), int)
    unsettled = []
    for i, fi in enumerate(f):
        w, m = 2 * np.pi * fi, periods * samples
        n_set = max(int(settle), RAMP)
        t = np.arange((n_set + 2 * periods) * samples + 1) / (fi * samples)
        x0 = None
        while True:
            tm = (t[:-1] + t[1:]) / 2                                              # held: the midpoint values
            ramp = np.sin(np.pi / 2 * np.minimum(tm * fi / RAMP, 1.0)) ** 2         # a soft start: no drift
            u = offset + amplitude * ramp * np.sin(w * tm)
            r = simulate(dae, t, inputs={input: u}, x0=x0, outputs=outs, params=own, method=method, progress=False,
                         **simulate_options)
            y = np.column_stack([r[o] for o in outs])
            n = len(t) - 1
            Yb, rms = _harmonic(t[n - m:], y[n - m:], w, samples)
            settled = _periodic(y[n - 2 * m:n - m + 1], y[n - m:], Yb, tol)
            if settled or n_set >= max_settle:
                break
            # continue from the last state until 4x as long (at least the two blocks compared)
            extra = max(min(3 * n_set, int(max_settle) - n_set), 2 * periods)
            n_set += extra
            t = t[-1] + np.arange(extra * samples + 1) / (fi * samples)
            x0 = dict(zip(dae.x_names, r.x[-1], strict=True))
        if not settled:
            unsettled.append(float(fi))
        U = _input_harmonic(t[n - m:], u[n - m:], w)
        H[i, :, 0] = Yb / U
        dist[i] = rms / np.maximum(np.abs(Yb) / np.sqrt(2), 1e-300)
        used[i] = n_set
        if show:
            sys.stderr.write(f"\r  stepped sine on '{dae.name}': {i + 1}/{len(f)} frequencies ({fi:.4g} Hz)")
            if i + 1 == len(f):
                sys.stderr.write("\n")
    notes = [f"stepped sine, {input} = {offset:g} + {amplitude:g} sin(2 pi f t), method '{method}', {samples} "
             f"samples per period, the last {periods} of the periods measured"]
    if unsettled:
        warnings.warn(f"stepped_sine on '{dae.name}': the response at {unsettled[:6]} Hz did not become periodic to "
                      f"{tol:g} within {max_settle} periods (a slowly decaying mode, a drift, or a response that is "
                      "not periodic: sub-harmonics, chaos); raise max_settle or check it in the time domain",
                      ModelLimitationWarning, stacklevel=2)
        notes.append(f"not periodic to {tol:g} at {unsettled} Hz")
    return SteppedSine(freqs=f, H=H, inputs=[input], outputs=outs, name=dae.name, notes=notes,
                       amplitude=float(amplitude), distortion=dist, settle_periods=used)


#: ``simulate`` arguments stepped_sine sets itself (per frequency), so they are not simulate_options
_OWN = {"model": "model", "t": "freqs", "inputs": "input and amplitude", "x0": "(the settled state)",
        "outputs": "output", "params": "params", "method": "method", "progress": "progress"}


def _check_simulate_options(options) -> None:
    """Every keyword passed on to :func:`bscomp.simulate` is one of its options and not one stepped_sine sets;
    else :class:`UsageError` naming it (with the nearest option name)."""
    import difflib
    import inspect

    allowed = [k for k in inspect.signature(simulate).parameters if k not in _OWN]
    for k in options:
        if k in _OWN:
            raise UsageError(f"stepped_sine sets simulate's {k!r} itself (from {_OWN[k]}); do not pass {k}=",
                             hint=f"options passed on to simulate: {allowed}")
        if k not in allowed:
            near = difflib.get_close_matches(k, allowed, n=1)
            raise UsageError(f"stepped_sine: unknown option {k!r}" + (f" (did you mean {near[0]!r}?)" if near else ""),
                             hint=f"options passed on to simulate: {allowed}")
