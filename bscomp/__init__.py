"""bscomp: ballscrew feed drives as acausal components compiled with CasADi.

Flow (one way): ``components`` -> :class:`System` (connect) -> :func:`flatten` -> :class:`Dae` ->
analyses (:func:`linearize`, modes, FRFs, simulation, optimal control, validation).

The analyses are reached lazily from here (``bscomp.modes``, ``bscomp.frf``, ``bscomp.simulate``,
``bscomp.Ocp``, ``bscomp.compare``, ``bscomp.diagnose``, ``bscomp.calibrate``), so ``import bscomp`` costs
the kernel only. Package layout and import rules: ``docs/architecture.md``.
"""

from bscomp.errors import (
    BscompError,
    DuplicateNameError,
    HighIndexError,
    ModelDefinitionError,
    NotLinearError,
    OverdeterminedError,
    ParameterError,
    PortConnectionError,
    SingularSystemError,
    StructuralError,
    UnconnectedPortError,
    UnderdeterminedError,
    UnknownNameError,
)
from bscomp.kernel import Component, Constraint, Dae, LinearStructure, Parameter, System, Variable, flatten

__version__ = "0.1.0"

# public name -> module that defines it; imported on first use (PEP 562)
_LAZY = {
    "linearize": "bscomp.linear", "second_order": "bscomp.linear", "modes": "bscomp.linear",
    "frf": "bscomp.linear", "transfer_function": "bscomp.linear", "position_sweep": "bscomp.linear",
    "cms_reduce": "bscomp.linear", "simulate": "bscomp.simulation", "SimulationResult": "bscomp.simulation",
    "stepped_sine": "bscomp.simulation", "describing_frf": "bscomp.simulation",
    "CompiledModel": "bscomp.simulation", "Ocp": "bscomp.optimal", "compare": "bscomp.validate",
    "diagnose": "bscomp.validate", "calibrate": "bscomp.validate", "load": "bscomp.validate",
    "export_fmu": "bscomp.fmu", "design_study": "bscomp.design_sweep", "ModelSpec": "bscomp.model",
}

__all__ = [
    "Component", "Constraint", "LinearStructure", "Parameter", "Variable", "Dae", "System", "flatten",
    "BscompError", "DuplicateNameError", "HighIndexError",
    "ModelDefinitionError", "NotLinearError", "OverdeterminedError", "ParameterError", "PortConnectionError",
    "SingularSystemError", "StructuralError", "UnconnectedPortError", "UnderdeterminedError",
    "UnknownNameError", *_LAZY,
]


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'bscomp' has no attribute '{name}'")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
