"""Controller design (thesis Ch 4 equations), closed-loop analysis of a drive, and the sampled-controller
runtime that runs designed controllers inside a time simulation.

* :mod:`bscomp.control.design` -- PI gains, notch, pole-placement (RST) design, Eq (4.10)-(4.38);
* :mod:`bscomp.control.closed_loop` -- plants (Eq 4.2-4.7, or any bscomp model) and the velocity,
  P-PI and RST loops of Figs 4.3, 4.14, 4.19;
* :mod:`bscomp.control.loop_analysis` -- :class:`LoopAnalysis` (margins, bandwidth, step responses) and
  the loop-comparison figures;
* :func:`sampled_controller` / :class:`SampledController` -- sampled blocks wired between a measured and
  an actuated signal of a System, run by :func:`bscomp.simulate`.

The thesis plants of Tables 4.1/4.2 are data and live in :mod:`bscomp.systems.thesis_plants`.
"""

from bscomp.control.closed_loop import (
    DrivePlant,
    modal_plant,
    p_pi_loop,
    plant_from_system,
    rigid_plant,
    rst_loop,
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
from bscomp.control.loop_analysis import (
    LoopAnalysis,
    LoopCurves,
    freqresp,
    loop_metrics,
    margins,
    plot_bode_comparison,
    plot_disturbance_comparison,
    plot_sensitivity_comparison,
    plot_step_comparison,
)
from bscomp.simulation.dispatch import SampledController
from bscomp.simulation.sampled import sampled_controller

__all__ = ["DrivePlant", "modal_plant", "p_pi_loop", "plant_from_system", "rigid_plant", "rst_loop", "velocity_loop",
           "NotchCoefficients", "PIGains", "PPCPolynomials", "RSTDesign", "diophantine", "notch", "pi_gains",
           "ppc_polynomials", "rst_design", "second_order_z", "split_polynomial", "velocity_loop_tf",
           "zoh_polynomials",
           "LoopAnalysis", "LoopCurves", "freqresp", "loop_metrics", "margins", "plot_bode_comparison",
           "plot_disturbance_comparison", "plot_sensitivity_comparison", "plot_step_comparison",
           "sampled_controller", "SampledController"]
