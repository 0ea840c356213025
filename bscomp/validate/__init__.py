"""Validation: compare a model with measurements, find where it fails and which effect is missing.

* :mod:`~bscomp.validate.measurements` -- :class:`FrfData`, :class:`TimeData`, CSV readers/writers;
* :mod:`~bscomp.validate.residuals` -- the model evaluated at the measurements, residuals, cost, fit %;
* :mod:`~bscomp.validate.compare` -- :func:`compare` -> :class:`Comparison` (where the model fails);
* :mod:`~bscomp.validate.report` -- an HTML report of comparisons (and diagnoses).

Importing this package is light: the engine (CasADi, python-control) is imported when a function
needs it, and matplotlib only by ``Comparison.plot`` (through :mod:`bscomp.plotting.validate`).
"""

from bscomp.validate.comparison import Comparison, compare, peak_pick, resid
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
from bscomp.validate.report import write_report
from bscomp.validate.residuals import cost, fit_percent, frf_residuals, model_frf, model_time, time_residuals

__all__ = ["FrfData", "TimeData", "MeasurementFileError", "load", "load_all", "read_frf_csv", "read_time_csv",
           "write_frf_csv", "write_time_csv", "model_frf", "model_time", "frf_residuals", "time_residuals", "cost",
           "fit_percent", "compare", "Comparison", "peak_pick", "resid", "write_report"]


def __getattr__(name):  # the diagnose engineer's modules, imported on first use
    if name in ("diagnose", "Diagnosis"):
        import importlib

        _d = importlib.import_module(".diagnose", __name__)  # the submodule, not this attribute
        value = getattr(_d, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'bscomp.validate' has no attribute '{name}'")
