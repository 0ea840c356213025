"""Measured data: frequency responses (:class:`FrfData`), time series (:class:`TimeData`) and the error a
file that cannot be used raises (:class:`MeasurementFileError`).

Values are held in SI units (the readers of :mod:`bscomp.validate.readers` convert on reading), with the
operating conditions of the measurement (``nut_position``, ``table.m``...) and where each channel was
declared in its file, so later checks (an unknown channel name) can point at the file's line and column.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import BscompError

__all__ = ["FrfData", "TimeData", "MeasurementFileError"]


class MeasurementFileError(BscompError, ValueError):
    """A measurement file cannot be used; the message names the file, line and column.

    Attributes
    ----------
    path : str
    line : int or None
        1-based line in the file (of the CSV, or of the sidecar for sidecar problems).
    column : int or None
        1-based CSV column (field number), or character column in a sidecar or metadata line.
    """

    def __init__(self, path, line, column, message, column_name=None):
        self.path, self.line, self.column, self.column_name = str(path), line, column, column_name
        where = str(path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column {column}"
            if column_name:
                where += f" ({column_name!r})"
        super().__init__(f"{where}: {message}")


# ---- data classes -------------------------------------------------------------------------------------
@dataclass
class FrfData:
    """Measured frequency responses.

    Attributes
    ----------
    freqs : (nf,) ndarray
        Frequencies [Hz], strictly increasing.
    H : dict (input, output) -> (nf,) complex ndarray
        Response of ``output`` to ``input``, in SI units (:attr:`units`).
    units : dict (input, output) -> str
        SI unit of each response, e.g. ``"rad/s/(N m)"``.
    conditions : dict str -> float or str
        Operating conditions (``nut_position``...); passed to a build function by
        :func:`bscomp.validate.residuals.model_frf`.
    coherence : dict (input, output) -> ndarray or None
        Ordinary coherence in [0, 1] per pair (None: not measured).
    source : str
        File name or description.
    locations : dict
        Where things were declared in the file (``("column", pair)`` / ``("unit", pair)`` -> (line,
        column)), so later checks can point at the file.
    """

    freqs: np.ndarray
    H: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    coherence: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)

    kind = "frf"

    @property
    def pairs(self) -> list:
        """(input, output) pairs in file order."""
        return list(self.H)

    @property
    def inputs(self) -> list:
        return list(dict.fromkeys(i for i, _ in self.H))

    @property
    def outputs(self) -> list:
        return list(dict.fromkeys(o for _, o in self.H))

    def __post_init__(self):
        self.freqs = np.asarray(self.freqs, float)
        self.H = {tuple(k): np.asarray(v, complex) for k, v in self.H.items()}
        self.coherence = {tuple(k): (None if v is None else np.asarray(v, float))
                          for k, v in (self.coherence or {}).items()}
        self.units = {tuple(k): v for k, v in (self.units or {}).items()}


@dataclass
class TimeData:
    """Measured time series.

    Attributes
    ----------
    t : (nt,) ndarray
        Sample times [s], strictly increasing.
    inputs : dict name -> (nt,) ndarray
        Excitations applied to the model (``motor.tau``), SI.
    outputs : dict name -> (nt,) ndarray
        Measured responses compared with the model (``table.a``), SI.
    units : dict name -> str
        SI unit of each channel.
    conditions : dict str -> float or str
    source : str
    locations : dict
        ``("column", name)`` / ``("unit", name)`` -> (line, column) in the file.
    """

    t: np.ndarray
    inputs: dict
    outputs: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)

    kind = "time"

    def __post_init__(self):
        self.t = np.asarray(self.t, float)
        self.inputs = {k: np.asarray(v, float) for k, v in self.inputs.items()}
        self.outputs = {k: np.asarray(v, float) for k, v in self.outputs.items()}

