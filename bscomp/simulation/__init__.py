"""Time simulation: one :func:`simulate`, one :class:`SimulationResult`, one file per method, and the
compiled exact-ZOH simulator (:class:`CompiledModel`) that diagnose and others reuse.

Modules: :mod:`~bscomp.simulation.dispatch` (``simulate`` and its table of methods),
:mod:`~bscomp.simulation.idas`, :mod:`~bscomp.simulation.fixed_step`, :mod:`~bscomp.simulation.zoh`,
:mod:`~bscomp.simulation.split` (with ``split_regime``, ``split_kernels``) one per method;
:mod:`~bscomp.simulation.common` (problem set-up, held inputs, sampled-controller schedule, output
evaluation, progress), :mod:`~bscomp.simulation.sampled` (sampled controllers in the loop),
:mod:`~bscomp.simulation.result`, :mod:`~bscomp.simulation.native` (C compilation, native messages);
:mod:`~bscomp.simulation.compiled` / :mod:`~bscomp.simulation.compiled_time` (CompiledModel);
:mod:`~bscomp.simulation.stepped` (the FRF of a nonlinear model at a real amplitude, by simulation) and
:mod:`~bscomp.simulation.describing` (the same by the describing function: one harmonic, milliseconds);
:mod:`~bscomp.simulation.travel` (a moving nut kept on its screw, every method).
"""

from bscomp.simulation.compiled import CompiledModel, ModalModel, nonlinear_elements
from bscomp.simulation.compiled_time import CompiledModelError
from bscomp.simulation.describing import DescribingFrf, DescribingFunctionError, describing_frf
from bscomp.simulation.dispatch import METHODS, simulate
from bscomp.simulation.result import SimulationError, SimulationResult
from bscomp.simulation.sampled import SampledController, sampled_controller
from bscomp.simulation.stepped import SteppedSine, stepped_sine
from bscomp.simulation.travel import NutOffScrewError

__all__ = ["simulate", "METHODS", "SimulationResult", "SimulationError", "SampledController", "sampled_controller",
           "CompiledModel", "ModalModel", "nonlinear_elements", "CompiledModelError", "stepped_sine", "SteppedSine",
           "describing_frf", "DescribingFrf", "DescribingFunctionError", "NutOffScrewError"]
