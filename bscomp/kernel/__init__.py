"""The modelling kernel: ports, components and their partial bases, System, flattening and the Dae.

Flattening (:func:`flatten`, orchestrated in :mod:`bscomp.kernel.flattening`) runs in steps, one module
each: :mod:`~bscomp.kernel.aliases` (connection sets), :mod:`~bscomp.kernel.templates` and
:mod:`~bscomp.kernel.instances` (component equations), :mod:`~bscomp.kernel.signals`,
:mod:`~bscomp.kernel.constraints` (constraint elimination), :mod:`~bscomp.kernel.states` (state
selection), :mod:`~bscomp.kernel.system_damping` (with :mod:`~bscomp.kernel.mechanics`, the
second-order ``M, K`` it needs) and :mod:`~bscomp.kernel.checks`.

Imports nothing above it (only :mod:`bscomp.errors`); every analysis and every component builds on it.
"""

from bscomp.kernel.component import Component, Constraint, LinearStructure, Parameter, PortRef, Variable
from bscomp.kernel.dae import Dae, MechanicalInfo
from bscomp.kernel.flattening import flatten
from bscomp.kernel.interface import InsertionPoint, NotApplicable, UncertainParameter, ValidationInterface
from bscomp.kernel.partials import PartialCompliant, PartialRotCompliant
from bscomp.kernel.ports import Flange, Generalized, Node6, RealInput, RealOutput, RotFlange
from bscomp.kernel.sampled import SampledBlock
from bscomp.kernel.system import System

__all__ = ["Component", "Constraint", "LinearStructure", "Parameter", "PortRef", "Variable", "Dae",
           "MechanicalInfo", "flatten", "InsertionPoint", "NotApplicable", "UncertainParameter",
           "ValidationInterface", "PartialCompliant", "PartialRotCompliant", "Flange", "Generalized", "Node6",
           "RealInput", "RealOutput", "RotFlange", "SampledBlock", "System"]
