"""Every figure bscomp draws. Plotting receives numbers and never calls a computation; matplotlib is
imported only when a figure is drawn.

* :mod:`bscomp.plotting.base` -- FRFs (:func:`bode_plot`, :func:`frf_overlay_plot`), mode shapes,
  frequencies against position, time signals;
* :mod:`bscomp.plotting.control` -- closed loops (:func:`loop_plot` and the loop comparisons), from the
  :class:`~bscomp.control.loop_analysis.LoopCurves` of a loop analysis;
* :mod:`bscomp.plotting.validate` -- comparisons with measurements and diagnoses.
"""

from bscomp.plotting.base import (
    bode_plot,
    frequency_position_plot,
    frf_overlay_plot,
    mode_shape_plot,
    pyplot,
    time_plot,
)
from bscomp.plotting.control import (
    bode_comparison_plot,
    disturbance_comparison_plot,
    loop_plot,
    sensitivity_comparison_plot,
    step_comparison_plot,
)

__all__ = ["pyplot", "bode_plot", "frequency_position_plot", "frf_overlay_plot", "mode_shape_plot", "time_plot",
           "loop_plot", "bode_comparison_plot", "step_comparison_plot", "sensitivity_comparison_plot",
           "disturbance_comparison_plot"]
