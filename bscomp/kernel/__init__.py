"""The modelling kernel: ports, components and their partial bases, System, flattening and the Dae.

Imports nothing above it (only :mod:`bscomp.errors`); every analysis and every component builds on it.
"""

from bscomp.kernel.component import Component, Constraint, LinearStructure, Parameter, PortRef, Variable
from bscomp.kernel.dae import Dae, MechanicalInfo
from bscomp.kernel.flatten import flatten
from bscomp.kernel.interface import InsertionPoint, NotApplicable, UncertainParameter, ValidationInterface
from bscomp.kernel.partials import PartialCompliant, PartialRotCompliant
from bscomp.kernel.ports import Flange, Generalized, Node6, RealInput, RealOutput, RotFlange
from bscomp.kernel.system import System

__all__ = ["Component", "Constraint", "LinearStructure", "Parameter", "PortRef", "Variable", "Dae",
           "MechanicalInfo", "flatten", "InsertionPoint", "NotApplicable", "UncertainParameter",
           "ValidationInterface", "PartialCompliant", "PartialRotCompliant", "Flange", "Generalized", "Node6",
           "RealInput", "RealOutput", "RotFlange", "System"]
