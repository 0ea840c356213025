"""Torque source driven by a signal: the input ``tau`` acts on ``flange`` (``flange.tau = -tau``).

Used for the motor torque ``tau = K_a K_t u`` (Eq 4.1); unconnected, its input is the system input
``<name>.tau`` (e.g. ``"motor.tau"``).
"""

from bscomp.kernel.component import Component
from bscomp.kernel.ports import RealInput, RotFlange


class Torque(Component):
    """Ideal torque source.

    Attributes
    ----------
    flange : RotFlange
        Rotational flange the torque acts on.
    tau : RealInput
        Torque [N.m]; unconnected, it becomes the system input ``<name>.tau``.
    """

    flange = RotFlange("flange the torque acts on")
    tau = RealInput("torque [N.m], positive in +phi direction", unit="N.m")

    def equations(self):
        return [self.flange.tau + self.tau.u]
