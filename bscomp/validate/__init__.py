"""Validation: compare a model with measurements, re-calibrate it, find where it fails and which effect is missing.

* :mod:`~bscomp.validate.measurements` -- :class:`FrfData`, :class:`TimeData`, CSV readers/writers
  (:mod:`~bscomp.validate.datasets`, :mod:`~bscomp.validate.readers`, :mod:`~bscomp.validate.writers`);
* :mod:`~bscomp.validate.residuals` -- the model evaluated at the measurements, residuals, cost, fit %;
* :mod:`~bscomp.validate.peaks` -- resonances identified from measured FRFs (peak picking, local modal fit);
* :mod:`~bscomp.validate.residual_tests` -- MATLAB ``resid``'s whiteness and independence tests;
* :mod:`~bscomp.validate.comparison` -- :func:`compare` -> :class:`Comparison` (where the model fails), with
  :mod:`~bscomp.validate.frf_comparison`, :mod:`~bscomp.validate.time_comparison` and
  :mod:`~bscomp.validate.signatures`;
* :mod:`~bscomp.validate.amplitude` -- :func:`amplitude_dependence`: FRFs measured at two amplitudes compared
  with themselves (is the drive nonlinear in the band?);
* :mod:`~bscomp.validate.calibration` -- :func:`calibrate` -> :class:`Calibration` (the uncertain parameters
  fitted, no effect added);
* :mod:`~bscomp.validate.diagnostics` -- :func:`diagnose` -> :class:`Diagnosis` (which effect is missing),
  on :mod:`~bscomp.validate.evaluation` and :mod:`~bscomp.validate.candidates`;
* :mod:`~bscomp.validate.report` -- an HTML report of comparisons (and diagnoses);
* :mod:`~bscomp.validate.synthetic` -- synthetic measurements with hidden effects (the diagnosis test bench).

Results draw themselves through :mod:`bscomp.plotting.validate`, imported (with matplotlib) only when a
figure is asked for.
"""

from bscomp.validate.amplitude import AmplitudeDependence, amplitude_dependence
from bscomp.validate.calibration import Calibration, calibrate
from bscomp.validate.comparison import Comparison, compare, user_errors
from bscomp.validate.diagnosis import Diagnosis
from bscomp.validate.diagnostics import diagnose
from bscomp.validate.frf_comparison import FrfComparison, ModePair
from bscomp.validate.measurements import (
    FrfData,
    MeasurementFileError,
    TimeData,
    load,
    load_all,
    read_frf_csv,
    read_time_csv,
    write_frf_csv,
    write_time_csv,
)
from bscomp.validate.peaks import peak_pick
from bscomp.validate.report import write_report
from bscomp.validate.residual_tests import ResidTest, resid
from bscomp.validate.residuals import cost, fit_percent, frf_residuals, model_frf, model_time, time_residuals
from bscomp.validate.time_comparison import TimeComparison

__all__ = ["FrfData", "TimeData", "MeasurementFileError", "load", "load_all", "read_frf_csv", "read_time_csv",
           "write_frf_csv", "write_time_csv", "model_frf", "model_time", "frf_residuals", "time_residuals", "cost",
           "fit_percent", "compare", "Comparison", "FrfComparison", "TimeComparison", "ModePair", "user_errors",
           "peak_pick", "resid", "ResidTest", "calibrate", "Calibration", "diagnose", "Diagnosis", "write_report",
           "amplitude_dependence", "AmplitudeDependence"]
