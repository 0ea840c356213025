"""Controller design (thesis Ch 4 equations) and closed-loop analysis of a drive."""

from bscomp.control.closed_loop import (
    DrivePlant,
    LoopAnalysis,
    freqresp,
    loop_metrics,
    margins,
    modal_plant,
    p_pi_loop,
    plant_from_system,
    rigid_plant,
    rst_loop,
    thesis_modal_plant,
    velocity_loop,
)
from bscomp.control.design import (
    NotchCoefficients,
    PIGains,
    PPCPolynomials,
    RSTDesign,
    diophantine,
    notch,
    pi_gains,
    ppc_polynomials,
    rst_design,
    second_order_z,
    split_polynomial,
    velocity_loop_tf,
    zoh_polynomials,
)

__all__ = ["DrivePlant", "LoopAnalysis", "freqresp", "loop_metrics", "margins", "modal_plant", "p_pi_loop",
           "plant_from_system", "rigid_plant", "rst_loop", "thesis_modal_plant", "velocity_loop",
           "NotchCoefficients", "PIGains", "PPCPolynomials", "RSTDesign", "diophantine", "notch", "pi_gains",
           "ppc_polynomials", "rst_design", "second_order_z", "split_polynomial", "velocity_loop_tf",
           "zoh_polynomials"]
