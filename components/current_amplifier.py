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

    def equations(self):
        import casadi as ca

        i_lin = self.K_a * self.u.u
        limited = limit(i_lin, -self.i_max, self.i_max, self.delta)
        return [self.i.y - ca.if_else(self.i_max > 0, limited, i_lin)]
