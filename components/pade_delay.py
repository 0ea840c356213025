"""Time delay on a signal by a Padé approximant of :math:`e^{-sT}` (D/A converter + amplifier latency).

Sec 3.5.2.4 of the thesis blames part of the measured phase lag on "the dynamics of the electronic
components [that] definitely add a time delay to the response due to the influence of the D/A
converters". A pure delay is not a finite-dimensional system; its (1,1) and (2,2) Padé approximants are

.. math::

    P_1(s) = \\frac{1 - sT/2}{1 + sT/2}, \\qquad
    P_2(s) = \\frac{1 - sT/2 + (sT)^2/12}{1 + sT/2 + (sT)^2/12}.

Both are all-pass (``|P| = 1`` exactly); only the phase differs from the exact ``-omega T``. Realisation
(``y = u - T s/den(s) u``): order 1 ``x' = (2/T)(u - x)``, ``y = 2x - u``; order 2
``x' = v``, ``(T^2/12) v' = u - x - (T/2) v``, ``y = u - T v``.

Accuracy
--------
Phase error ``angle(P_n(j omega)) + omega T`` (the approximant lags less than the true delay):

=============  ==========  ==========
``omega T``    order 1     order 2
=============  ==========  ==========
0.5            0.58 deg    0.00 deg
1.0            4.2 deg     0.07 deg
1.5            12.2 deg    0.52 deg
2.0            24.6 deg    1.97 deg
2.5            40.6 deg    5.2 deg
3.0            59.3 deg    10.8 deg
=============  ==========  ==========

So order 2 is within 2 degrees up to ``omega T = 2``: for a 0.3 ms delay that is 1.06 kHz, beyond the
~1 kHz band of the test-bed FRFs (Figs 3.32-3.33). Order 1 needs ``omega T < 1``. In time responses a
Padé approximant shows the non-minimum-phase undershoot of its zeros at a step instead of a clean shift;
sampled at intervals longer than ``T`` the difference is small.
"""

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Parameter, Variable
from bscomp.kernel.ports import RealInput, RealOutput


class PadeDelay(Component):
    """Signal delay ``y(t) ~ u(t - T)`` by a first- or second-order Padé approximant.

    Parameters
    ----------
    order : int
        1 or 2 (structural, fixed at construction). Default 2.

    Attributes
    ----------
    u : RealInput
        Input signal.
    y : RealOutput
        Delayed signal (units follow the connected signals).
    x, v : variable
        Internal states [1] and [1/s] (``v`` unused for order 1).
    """

    u = RealInput("input signal")
    y = RealOutput("delayed signal")
    T = Parameter(1.0e-4, unit="s", positive=True, doc="time delay")
    x = Variable("1", doc="first internal state")
    v = Variable("1/s", doc="second internal state (order 2)")

    def __init__(self, order: int = 2, **params):
        if order not in (1, 2):
            raise ParameterError(f"PadeDelay order must be 1 or 2, got {order!r}")
        self.order = int(order)
        super().__init__(**params)

    def equations(self):
        T, u = self.T, self.u.u
        if self.order == 1:
            return [self.der(self.x) - 2.0 / T * (u - self.x), self.v, self.y.y - (2.0 * self.x - u)]
        return [self.der(self.x) - self.v,
                T * T / 12.0 * self.der(self.v) - (u - self.x - T / 2.0 * self.v),
                self.y.y - (u - T * self.v)]
