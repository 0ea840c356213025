"""Signal limiter (saturation), ``y = min(max(u, y_min), y_max)``, hard or with rounded corners.

Amplifier and actuator saturation limit the achievable gain K_p of the position loop (Sec 4.3.2: "the
value of K_p is also limited by the saturation limits of the amplifier and actuator"); the thesis
ignores them in its designs, this block lets a simulation include them.

Linear analysis: the block is *exactly* ``y = u`` for ``y_min + delta <= u <= y_max - delta`` (the
hard clip when ``delta = 0``; C1 quadratic corners of half-width ``delta`` otherwise, see
``components/_limits.py``). :func:`bscomp.linearize` at an operating point inside the limits therefore
gives gain 1 and the closed-loop analyses of Chapter 4 are unchanged; at a point beyond a limit the
gain is 0 (the loop is open), as it should be. ``delta > 0`` removes the slope discontinuity, which helps
variable-step integrators; the hard clip needs event handling for an accurate switch time.
"""

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RealInput, RealOutput

from ._limits import limit


class Saturation(Component):
    """Limiter.

    Attributes
    ----------
    u : RealInput
        Input signal.
    y : RealOutput
        Limited output signal.
    """

    u = RealInput("input signal")
    y = RealOutput("limited output signal")
    y_max = Parameter(1.0, unit="1", doc="upper limit, in the unit of the signal")
    y_min = Parameter(-1.0, unit="1", doc="lower limit, below y_max (constructor default: -y_max)")
    delta = Parameter(0.0, unit="1", min=0.0, doc="half-width of the rounded corners (0 = hard clip)")

    def __init__(self, y_max: float | str = 1.0, y_min: float | str | None = None, **params):
        if y_min is None:                       # validate first: a string or NaN y_max gets a ParameterError
            y_min = -Saturation.y_max.validate(y_max)
        super().__init__(y_max=y_max, y_min=y_min, **params)

    def check(self, values):
        """``y_min < y_max`` and ``2 delta <= y_max - y_min`` (a linear region remains, see ``_limits``)."""
        lo, hi, delta = values["y_min"], values["y_max"], values["delta"]
        if lo is None or hi is None:
            return
        if not lo < hi:
            raise ParameterError(f"{self._where('y_min', 'y_max')}: the limits need y_min < y_max, got y_min = "
                                 f"{lo!r}, y_max = {hi!r}; set them in order (e.g. y_min = -y_max)")
        if delta is not None and 2 * delta > hi - lo:
            raise ParameterError(f"{self._where('delta')}: corner half-width delta = {delta!r} is more than half "
                                 f"the range [y_min, y_max] = [{lo!r}, {hi!r}], so no linear region would remain; "
                                 f"use delta <= {(hi - lo) / 2:.6g}")

    def equations(self):
        return [self.y.y - limit(self.u.u, self.y_min, self.y_max, self.delta)]
