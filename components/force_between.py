"""A force between two flanges set by a signal: ``f = w`` (tension positive, as a spring's force).

Used by :class:`bscomp.simulation.compiled.CompiledModel` to cut a nonlinear element (friction, backlash) out of a
drive: the element is replaced by its small-signal equivalent plus this force, whose signal the
compiled simulator computes from the element's own :meth:`force_law` at every step. The flange sign
convention is :class:`~bscomp.kernel.partials.PartialCompliant`'s: ``flange_b.f = f``, ``flange_a.f = -f``.
"""

from bscomp.kernel.partials import PartialCompliant
from bscomp.kernel.ports import RealInput


class ForceBetween(PartialCompliant):
    """Signal-driven element force between two flanges.

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    w : RealInput
        Element force ``f`` [N]; unconnected, it becomes the system input ``<name>.w``.
    """

    w = RealInput("element force [N], positive in tension", unit="N")

    def equations(self):
        return [self.f - self.w.u]
