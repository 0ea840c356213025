"""Measurements: frequency responses (:class:`FrfData`) and time series (:class:`TimeData`) read from and
written to plain CSV (format documented in ``docs/measurements.md``) -- the measurement API in one import.

A file is a header row of column names and rows of numbers. Its metadata -- kind, units, which channels
are inputs, operating conditions such as the nut position -- is given either as ``# key: value`` comment
lines above the header or in a JSON/TOML sidecar (``data.csv.json``, ``data.csv.toml``, ``data.json`` or
``data.toml``)::

    # kind: frf
    # source: stepped sine, test bed x-axis, 2024-03-02
    # condition nut_position: 0.43
    # unit rotor.w/motor.tau: rad/s/(N m)
    f,re(rotor.w/motor.tau),im(rotor.w/motor.tau),coh(rotor.w/motor.tau)
    10.0,-0.05,-2.6,0.99

The FRF columns are ``re(<out>/<in>)``/``im(...)`` or a magnitude (``mag``, ``mag_db``) and a phase
(``phase_deg``, ``phase_rad``), optional ``coh(...)``; :meth:`bscomp.linear.response.Frf.to_csv` writes
``<in>-><out> re`` (``im``, ``mag_db``, ``phase_deg``) columns of SI values, read the same way (a pair's unit,
unless declared, from the channel names by the Modelica naming convention; magnitude and phase given with
re/im must agree with them).

Values are converted to SI on reading (a channel in ``um`` is multiplied by 1e-6; ``deg`` becomes
``rad``), so :attr:`FrfData.units` and :attr:`TimeData.units` hold SI spellings. Data files are parsed,
never executed. Every problem raises :class:`MeasurementFileError` naming the file, the line and the
column.

The pieces: the data classes and the error in :mod:`~bscomp.validate.datasets`, the readers
(:func:`load`, :func:`read_frf_csv`, :func:`read_time_csv`) in :mod:`~bscomp.validate.readers`, the writers
(:func:`write_frf_csv`, :func:`write_time_csv`) in :mod:`~bscomp.validate.writers`.
"""

from bscomp.validate.datasets import FrfData, MeasurementFileError, TimeData
from bscomp.validate.readers import load, load_all, read_frf_csv, read_time_csv
from bscomp.validate.writers import write_frf_csv, write_time_csv

__all__ = ["FrfData", "TimeData", "MeasurementFileError", "read_frf_csv", "write_frf_csv", "read_time_csv",
           "write_time_csv", "load", "load_all"]
