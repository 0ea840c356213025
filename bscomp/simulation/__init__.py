"""Time simulation: one :func:`simulate`, one :class:`SimulationResult`, one file per method, and the
compiled exact-ZOH simulator (:class:`CompiledModel`) that diagnose and others reuse."""

from bscomp.simulation.compiled import CompiledModel, ModalModel, nonlinear_elements
from bscomp.simulation.compiled_time import CompiledModelError
from bscomp.simulation.dispatch import SampledController, SimulationError, SimulationResult, simulate

__all__ = ["simulate", "SimulationResult", "SimulationError", "SampledController", "CompiledModel",
           "ModalModel", "nonlinear_elements", "CompiledModelError"]
