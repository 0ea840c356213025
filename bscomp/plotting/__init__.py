"""Every figure bscomp draws. Plotting receives numbers and never calls a computation; matplotlib is
imported only when a figure is drawn."""

from bscomp.plotting.base import bode_plot, frequency_position_plot, frf_overlay_plot, mode_shape_plot, time_plot

__all__ = ["bode_plot", "frequency_position_plot", "frf_overlay_plot", "mode_shape_plot", "time_plot"]
