"""Linear analysis of a Dae: linearization, second-order form, modes, real modal form, FRFs, sweeps, damping,
reduction."""

from bscomp.kernel.damping import (  # damping models live in the kernel (flattening applies them)
    ModalDamping,
    RayleighDamping,
    damped_modal_properties,
    modal_damping_matrix,
    rayleigh_coefficients,
    rayleigh_damping_matrix,
)
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.linear.linearization import (
    OperatingPoint,
    SecondOrderModel,
    control_labels,
    linearize,
    resolve_model,
    second_order,
)
from bscomp.linear.modal import Modes, modal_poles, modes
from bscomp.linear.real_form import ModalError, modal_basis
from bscomp.linear.reduction import ReducedModel, ReducedPort, cms_reduce, reduce_second_order
from bscomp.linear.response import Frf, ModalSection, frf, transfer_function
from bscomp.linear.sweeps import PositionSweep, build_system, position_sweep

__all__ = ["ModalDamping", "RayleighDamping", "damped_modal_properties", "modal_damping_matrix",
           "rayleigh_coefficients", "rayleigh_damping_matrix",
           "system_damping_matrix", "OperatingPoint", "SecondOrderModel", "control_labels", "linearize",
           "resolve_model", "second_order", "Modes", "modal_poles", "modes", "ReducedModel", "ReducedPort",
           "cms_reduce", "reduce_second_order", "Frf", "ModalSection", "frf", "transfer_function",
           "PositionSweep", "build_system", "position_sweep", "ModalError", "modal_basis"]
