"""bscomp: ballscrew feed drives as acausal components compiled with CasADi.

Flow (one way): ``components`` -> :class:`System` (connect) -> :func:`flatten` -> :class:`Dae` ->
analyses (:func:`linearize`, modes, FRFs, simulation, optimal control, validation).
"""

from .component import Component, Constraint, LinearStructure, Parameter, Variable
from .dae import Dae
from .errors import (
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
from .flatten import flatten
from .system import System

__version__ = "0.1.0"

__all__ = [
    "Component", "Constraint", "LinearStructure", "Parameter", "Variable", "Dae", "System", "flatten",
    "linearize", "second_order", "BscompError", "DuplicateNameError", "HighIndexError",
    "ModelDefinitionError", "NotLinearError", "OverdeterminedError", "ParameterError", "PortConnectionError",
    "SingularSystemError", "StructuralError", "UnconnectedPortError", "UnderdeterminedError",
    "UnknownNameError",
]


def __getattr__(name):  # lazy: linear analysis imports python-control only when used
    if name in ("linearize", "second_order"):
        from . import linear
        return getattr(linear, name)
    raise AttributeError(f"module 'bscomp' has no attribute '{name}'")
