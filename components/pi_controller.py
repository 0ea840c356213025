"""Analog PI controller of the velocity loop, ``y = K_v e + K_i x_i``, ``x_i' = e``, ``e = u_s - u_m``.

Eq (4.10) of the thesis, whose numerator ``K_a K_t K_i H_g / J (1/H_g + K_v/(K_i H_g) s)`` and
denominator constant ``K_a K_t K_i H_g / J`` (Eq 4.11) fix the controller as the *parallel* form

.. math:: C(s) = K_v + \\frac{K_i}{s}

with K_v = 18.217 V/V and K_i = 4081.2 1/s (Eq 4.14, from Eq 4.12). (The series form
``K_v (1 + K_i/s)`` would need ``K_i = 4081.2 / 18.217 = 224.0`` 1/s to give the same loop.) The
integrator state ``x_i`` [V.s] starts at 0 (an analysis sets other initial states by name); there is no
anti-windup: put a :class:`Saturation` after it and mind the wind-up in large moves.
"""

from bscomp.kernel.component import Component, Parameter, Variable
from bscomp.kernel.ports import RealInput, RealOutput


class PIController(Component):
    """Parallel PI controller with set-point and measurement inputs.

    Attributes
    ----------
    u_s : RealInput
        Set point [V].
    u_m : RealInput
        Measurement [V] (e.g. a :class:`Tachometer`).
    y : RealOutput
        Output [V].
    x_i : variable
        Integral of the error [V.s] (a differential state).
    """

    u_s = RealInput("set point [V]", unit="V")
    u_m = RealInput("measurement [V]", unit="V")
    y = RealOutput("control signal [V]", unit="V")
    K_v = Parameter(18.217, unit="V/V", min=0.0, doc="proportional gain (Eq 4.14)")
    K_i = Parameter(4081.2, unit="1/s", min=0.0, doc="integral gain, parallel form (Eq 4.10; value of Eq 4.14)")
    x_i = Variable("V.s", start=0.0, doc="integral of the error")

    @property
    def e(self):
        return self.u_s.u - self.u_m.u

    def equations(self):
        return [self.der(self.x_i) - self.e, self.y.y - (self.K_v * self.e + self.K_i * self.x_i)]

    def observables(self):
        return {"e": self.e, "x_i": self.x_i}
