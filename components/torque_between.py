"""A torque between two rotational flanges set by a signal: ``tau = w`` (as a torsional spring's torque).

The rotational twin of :class:`~components.force_between.ForceBetween`:
:class:`bscomp.simulation.compiled.CompiledModel` cuts a rotational nonlinear element
(:class:`~components.rotational_friction.RotationalFriction`,
:class:`~components.rotational_backlash.RotationalBacklash`) out of a drive with it. Flange sign convention
:class:`~bscomp.kernel.partials.PartialRotCompliant`'s: ``flange_b.tau = tau``, ``flange_a.tau = -tau``.
"""

from bscomp.kernel.partials import PartialRotCompliant
from bscomp.kernel.ports import RealInput


class TorqueBetween(PartialRotCompliant):
    """Signal-driven element torque between two rotational flanges.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialRotCompliant`).
    w : RealInput
        Element torque ``tau`` [N.m]; unconnected, it becomes the system input ``<name>.w``.
    """

    w = RealInput("element torque [N.m], positive as a torsional spring's", unit="N.m")

    def equations(self):
        return [self.tau - self.w.u]
