"""Current amplifier in current mode, ``i = K_a u`` (Eq 4.1), optionally limited to ``|i| <= i_max``.

The amplifier of the test bed works in current mode, so its dynamics are taken much faster than the
mechanics and ``G_e(s) = K_a K_t`` (Eq 4.1, K_a = 6.4898 A/V). The motor torque constant K_t is the
plain :class:`Gain` ``k = K_t`` [N.m/A] feeding a :class:`Torque` source: a dedicated class would only
rename Gain.

Saturation: ``i_max = 0`` (default) means no limit; ``i_max > 0`` clips the output current to
``[-i_max, i_max]`` (hard clip, or rounded corners of half-width ``delta`` [A]). Inside the limits the
block is exactly linear, so linear analyses see ``K_a`` (see :class:`Saturation`). The voltage
compliance of the amplifier (back-EMF headroom) is not modelled.
"""

from bscomp.errors import ParameterError
from bscomp.kernel.component import Component, Parameter
from bscomp.kernel.ports import RealInput, RealOutput

from ._limits import limit


class CurrentAmplifier(Component):
    """Current amplifier (transconductance).

    Attributes
    ----------
    u : RealInput
        Command voltage [V].
    i : RealOutput
        Output current [A].
    """

    u = RealInput("command voltage [V]", unit="V")
    i = RealOutput("motor current [A]", unit="A")
    K_a = Parameter(6.4898, unit="A/V", positive=True, doc="amplifier gain (Eq 4.1; 6.4898 A/V on the test bed)")
    i_max = Parameter(0.0, unit="A", min=0.0, doc="output current limit (0 = unlimited)")
    delta = Parameter(0.0, unit="A", min=0.0, doc="half-width of the rounded limiter corners (0 = hard clip)")

    def check(self, values):
        """With a limit (``i_max > 0``) the rounded corners must fit in ``[-i_max, i_max]``: ``delta <= i_max``
        (beyond it the limiter has no linear region and its output can take the wrong sign)."""
        i_max, delta = values["i_max"], values["delta"]
        if i_max is not None and delta is not None and i_max > 0 and delta > i_max:
            raise ParameterError(f"{self._where('delta', 'i_max')}: corner half-width delta = {delta!r} A exceeds "
                                 f"the current limit i_max = {i_max!r} A, so no linear region of the limiter "
                                 f"[-i_max, i_max] would remain; use delta <= i_max (or i_max = 0 for no limit)")

    def equations(self):
        import casadi as ca

        i_lin = self.K_a * self.u.u
        limited = limit(i_lin, -self.i_max, self.i_max, self.delta)
        return [self.i.y - ca.if_else(self.i_max > 0, limited, i_lin)]
