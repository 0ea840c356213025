"""Sampled-data controllers in a simulation: :class:`SampledController` (a discrete law the simulator runs
every ``Ts`` with zero-order hold, Eq 4.16) and :func:`sampled_controller`, which closes a loop with the
difference-equation blocks of the kernel (:class:`bscomp.kernel.SampledBlock`: ``DigitalPController``,
``NotchFilter``, ``RSTController``, the P controller and notch filter in series of Fig 4.14).

When the simulator runs a controller is :mod:`bscomp.simulation.common` (:class:`~.common.SampledLoop`),
one implementation for every method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from bscomp.errors import ArgumentTypeError, ParameterError
from bscomp.kernel.sampled import SampledBlock

__all__ = ["SampledController", "sampled_controller"]


@dataclass
class SampledController:
    """A discrete controller in the loop: every ``Ts`` it reads ``measure`` and sets ``actuate`` (ZOH).

    Parameters
    ----------
    law : callable
        ``law(t_k, y_k) -> u_k`` with ``y_k`` the measured outputs (array, order of ``measure``) and
        ``u_k`` the values of the actuated inputs (order of ``actuate``). It may keep internal state.
    measure : list of str
        Output names read at each sample (any observable).
    actuate : list of str
        System inputs it drives.
    Ts : float
        Sampling period [s].
    """

    law: Callable
    measure: list
    actuate: list
    Ts: float


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) or (
        hasattr(v, "dtype") and getattr(v, "ndim", 1) == 0 and v.dtype.kind in "iuf")


def _blocks(blocks) -> list:
    """``blocks`` of :func:`sampled_controller` as a list of SampledBlock, else :class:`ArgumentTypeError`."""
    what = ("a sequence of sampled blocks (bscomp.kernel.SampledBlock: DigitalPController, NotchFilter, "
            "RSTController, e.g. [design.controller()])")
    if isinstance(blocks, SampledBlock):
        raise ArgumentTypeError(f"sampled_controller: blocks must be {what}, got one block {blocks!r}; "
                                "pass it in a list: [block]")
    if isinstance(blocks, (str, bytes)) or not hasattr(blocks, "__iter__"):
        raise ArgumentTypeError(f"sampled_controller: blocks must be {what}, got {type(blocks).__name__} "
                                f"{blocks!r}"[:300])
    blocks = list(blocks)
    for k, b in enumerate(blocks):
        if not isinstance(b, SampledBlock):
            raise ArgumentTypeError(f"sampled_controller: blocks[{k}] is {type(b).__name__} {b!r}, not a "
                                    f"SampledBlock; blocks must be {what}"[:400])
    return blocks


def sampled_controller(blocks, measure: str, actuate: str, reference, measure_gain: float = 1.0):
    """Run sampled blocks in series as a :class:`SampledController`.

    At each sample ``t_k`` the first block gets the reference and the measurement,
    ``r_k = g reference(t_k)`` and ``y_k = g y(t_k)`` (two inputs ``r, y`` as :class:`DigitalPController`
    and :class:`RSTController`), or the error ``r_k - y_k`` (one input); each further block takes the
    previous block's output (one input, e.g. :class:`NotchFilter`). The last output is held on the
    actuated input until the next sample (zero-order hold, Eq 4.16).

    Parameters
    ----------
    blocks : sequence of SampledBlock
        The chain, all with the same sampling period ``T_s``. Their memory is cleared here.
    measure : str
        Observable read at each sample (e.g. ``"table.s"``).
    actuate : str
        System input driven by the chain (e.g. ``"pi.u_s"`` or ``"amp.u"``).
    reference : callable or float
        ``reference(t)`` in the units of ``measure`` (a float is a constant set point).
    measure_gain : float
        Sensor gain and polarity ``g`` applied to both measurement and reference: the controller works
        in the coordinate ``g * measure`` (``-1`` when the positive motor direction moves the table
        towards ``-z``).

    Returns
    -------
    SampledController
        Its ``law`` also records the samples: ``law.t``, ``law.u`` (lists of ``t_k`` and ``u_k``).

    Raises
    ------
    ParameterError
        Empty chain, different sampling periods, or a block with the wrong number of inputs.
    """
    blocks = _blocks(blocks)
    for k, v in (("measure", measure), ("actuate", actuate)):
        if not isinstance(v, str):
            raise ArgumentTypeError(f"sampled_controller: {k} must be one signal name (str), e.g. 'table.s', "
                                    f"got {type(v).__name__} {v!r}"[:300])
    if not (callable(reference) or _is_number(reference)):
        raise ArgumentTypeError(f"sampled_controller: reference must be a function reference(t) or a number "
                                f"(a constant set point), got {type(reference).__name__} {reference!r}"[:300])
    if not blocks:
        raise ParameterError("sampled_controller: no blocks given")
    T_s = blocks[0].T_s
    for b in blocks:
        if abs(b.T_s - T_s) > 1e-12 * T_s:
            raise ParameterError(f"sampled_controller: {b!r} has T_s = {b.T_s:g} s, the chain runs at {T_s:g} s")
    if len(blocks[0].inputs) not in (1, 2):
        raise ParameterError(f"sampled_controller: the first block {blocks[0]!r} must take (r, y) or the error")
    for b in blocks[1:]:
        if len(b.inputs) != 1:
            raise ParameterError(f"sampled_controller: {b!r} in series must have one input")
    if not _is_number(measure_gain):
        raise ArgumentTypeError(f"sampled_controller: measure_gain must be a number (sensor gain and polarity, "
                                f"e.g. 1.0 or -1.0), got {type(measure_gain).__name__} {measure_gain!r}"[:300])
    g = float(measure_gain)
    if not (math.isfinite(g) and g != 0):
        raise ParameterError(f"sampled_controller: measure_gain = {g!r} must be finite and non-zero "
                             "(sensor gain and polarity, e.g. 1.0 or -1.0)")
    ref = reference if callable(reference) else (lambda t, c=float(reference): c)
    for b in blocks:
        b.reset()

    def law(t_k, y):
        r_k, y_k = g * float(ref(t_k)), g * float(y[0])
        first = blocks[0]
        v = first.step(r_k, y_k) if len(first.inputs) == 2 else first.step(r_k - y_k)
        for b in blocks[1:]:
            v = b.step(v)
        law.t.append(t_k)
        law.u.append(v)
        return [v]

    law.t, law.u = [], []
    return SampledController(law=law, measure=[measure], actuate=[actuate], Ts=T_s)
