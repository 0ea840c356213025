"""Measured data: frequency responses (:class:`FrfData`), time series (:class:`TimeData`) and the error a
file that cannot be used raises (:class:`MeasurementFileError`).

Values are held in SI units (the readers of :mod:`bscomp.validate.readers` convert on reading), with the
operating conditions of the measurement (``nut_position``, ``table.m``...) and where each channel was
declared in its file, so later checks (an unknown channel name) can point at the file's line and column.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import BscompError, ModelLimitationWarning

__all__ = ["FrfData", "TimeData", "MeasurementFileError", "MeasurementWarning", "check_condition",
           "MIN_COHERENCE", "MIN_FRF_POINTS", "MIN_TIME_SAMPLES", "check_points", "warn_amplitude_fit",
           "AMPLITUDE_HARMONICS"]

#: a pair whose coherence stays below this everywhere carries no usable signal (error)
MIN_COHERENCE = 0.1
#: fewest frequencies of an FRF compared or fitted: its fit % measures the error against the response's spread
#: over frequency (one point has none) and the phase error's slope (an apparent delay) needs three points
MIN_FRF_POINTS = 3
#: fewest samples of a time series compared or fitted: its noise floor is the robust scale of third differences,
#: which needs six samples (:func:`bscomp.validate.noise.robust_sigma`), and a fit % the channel's spread
MIN_TIME_SAMPLES = 6
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_FILE_SUFFIX = re.compile(r"\.(toml|json|py|pyc|csv|txt|ya?ml|ini|cfg|pkl|pickle|npz|npy|so|dll|sh)$", re.I)
#: build arguments a data file may not set: they name files the library would open
FORBIDDEN_CONDITIONS = frozenset({"params", "path", "file", "filename", "parameters", "parameter_file"})


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


class MeasurementWarning(UserWarning):
    """A measurement can be used but part of it is doubtful (e.g. low coherence over much of the band)."""


def check_condition(name, value, where=(None, None, None)):
    """A measurement condition as a build function may take it: a finite number or a short plain string.

    Nothing from a data file becomes a path that is opened: a condition named like a file argument
    (``params``...) or whose value looks like a path (``../x``, ``a/b``, ``~``, ``x.toml``) is refused.
    Returns the value; raises :class:`MeasurementFileError` at ``where`` = ``(file, line, column)``.
    """
    def fail(msg):
        raise MeasurementFileError(where[0] or "<measurement>", where[1], where[2], msg, str(name))

    name = str(name)
    if not _NAME.match(name):
        fail(f"condition name {name!r} is not a plain or dotted identifier (e.g. nut_position, table.m)")
    if name.rsplit(".", 1)[-1].lower() in FORBIDDEN_CONDITIONS:
        fail(f"condition {name!r} is not allowed: a measurement file cannot choose files or parameter sets "
             "(pass params= to the function instead)")
    if isinstance(value, bool) or not isinstance(value, (int, float, str, np.floating, np.integer)):
        fail(f"condition {name!r} must be a number or a string, not {type(value).__name__}")
    if isinstance(value, str):
        v = value.strip()
        if len(v) > 100 or any(ch in v for ch in "/\\\0") or v.startswith(("~", ".")) or _FILE_SUFFIX.search(v):
            fail(f"condition {name!r} = {v[:60]!r} looks like a file path: conditions are numbers or plain words "
                 "and never name files")
        return v
    v = float(value)
    if not math.isfinite(v):
        fail(f"condition {name!r} = {v} is not finite")
    return v


def check_points(data, who: str = "the comparison"):
    """An FRF needs :data:`MIN_FRF_POINTS` frequencies, a time series :data:`MIN_TIME_SAMPLES` samples for
    ``who`` (compare, calibrate, diagnose: their noise floors and fit % need them); else
    :class:`MeasurementFileError` naming the file. (A shorter file still reads.)"""
    n, least, what = ((np.size(data.freqs), MIN_FRF_POINTS, "frequencies") if isinstance(data, FrfData) else
                      (np.size(data.t), MIN_TIME_SAMPLES, "samples"))
    if n < least:
        why = ("a fit % and the phase error's slope need three frequencies" if isinstance(data, FrfData) else
               "its noise floor, the robust scale of third differences, needs six samples")
        raise MeasurementFileError(data.label, None, None, f"{data.kind} data with {n} {what}: {who} needs at least "
                                   f"{least} ({why}); measure more points")
    if who in ("calibrate", "diagnose") and isinstance(data, TimeData):
        for name, y in data.outputs.items():          # residuals are divided by the noise floor: 0 for these
            if np.ptp(np.asarray(y, float)) == 0:
                ln, col = data.locations.get(("column", name), (None, None))
                raise MeasurementFileError(data.label, ln, col, f"output {name} is {float(y[0]):g} in every sample: "
                                           f"{who} whitens each channel by its noise, which a constant channel does "
                                           "not show; drop the column or record a longer run", name)


def check_coherence(pair, g, source, where=(None, None)):
    """Coherence all below :data:`MIN_COHERENCE` is an error (it would weight every error to zero and give a
    perfect score); below 0.5 on more than half the band a :class:`MeasurementWarning`."""
    if g is None or g.size == 0:
        return
    label = f"{pair[1]}/{pair[0]}"
    if not np.all(np.isfinite(g)) or np.any((g < 0) | (g > 1)):
        raise MeasurementFileError(source or "<measurement>", where[0], where[1], f"coherence of {label} must be "
                                   "finite and in [0, 1]", f"coh({label})")
    if float(np.max(g)) < MIN_COHERENCE:
        raise MeasurementFileError(source or "<measurement>", where[0], where[1], f"coherence of {label} is below "
                                   f"{MIN_COHERENCE} at every frequency (max {float(np.max(g)):.3g}): the response "
                                   "is not related to the excitation; re-measure or drop the pair", f"coh({label})")
    low = float(np.mean(g < 0.5))
    if low > 0.5:
        warnings.warn(f"{source}: coherence of {label} is below 0.5 at {100 * low:.0f}% of the frequencies: "
                      "the comparison rests on few points", MeasurementWarning, stacklevel=3)


AMPLITUDE_HARMONICS = 5   # odd harmonics (orders 1..9) calibrate and compare balance for an FRF at an amplitude


def warn_amplitude_fit(datasets, who: str, stacklevel: int = 3, harmonics: int = 1) -> None:
    """Warn (:class:`~bscomp.errors.ModelLimitationWarning`) that ``who`` fits FRFs measured at a stated sine
    amplitude (``FrfData.excitation``) by the harmonic balance of the model's friction and backlash (``harmonics``
    odd orders; one -- the describing function -- is biased where the drive sticks and slips)."""
    at_amp = [f"{d.source} ({', '.join(f'{v:g} on {k}' for k, v in d.excitation.items())})" for d in datasets
              if isinstance(d, FrfData) and d.excitation]
    if not at_amp:
        return
    if harmonics == 1:
        how = ("the describing function of its friction and backlash, where it has them (one harmonic; where the "
               "drive sticks and slips fits by it are biased: F_c -13..-30 %, the table mass -17..+29 % on the FE "
               "truths; calibrate balances 5 odd harmonics: F_c -0.6..+0.0 % with the model's own law")
    else:
        how = (f"the harmonic balance of its friction and backlash, where it has them ({harmonics} odd harmonics; "
               "with the model's own friction law F_c and the table mass within 2 % on the FE truths, with another "
               "law F_c -20 %")
    warnings.warn(f"{who} compares {at_amp}, measured at a stated sine amplitude, with the model at that "
                  f"amplitude: {how}, docs/measurements.md, 'Fitting FRFs measured at an amplitude'; a model without "
                  "them has one FRF at every amplitude); a time series identifies friction and backlash",
                  ModelLimitationWarning, stacklevel=stacklevel)


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
    excitation : dict input -> float
        Amplitude of the sine the response was measured with, per input (SI; ``# excitation amp.u: 2 V``).
        :func:`~bscomp.validate.compare` then also compares the model at that amplitude (describing
        function of its friction and backlash).
    path : str
        The file it was read from ("" when built in memory); errors and warnings name it (:attr:`label`).
    excitation_units : dict input -> str
        SI unit of each stated excitation amplitude, as the file gave it (checked against the model's input).
    """

    freqs: np.ndarray
    H: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    coherence: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)
    excitation: dict = field(default_factory=dict)
    path: str = ""
    excitation_units: dict = field(default_factory=dict)

    kind = "frf"

    @property
    def label(self) -> str:
        """What errors and warnings name: the file's path, else its source text."""
        return self.path or self.source or "<measurement>"

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
        for pair, g in self.coherence.items():
            check_coherence(pair, g, self.label, self.locations.get(("column", pair), (None, None)))
        for name, a in (self.excitation or {}).items():
            ln, col = self.locations.get(("excitation", name), (None, None))
            if name not in self.inputs:
                raise MeasurementFileError(self.label, ln, col, f"excitation given for {name!r}, which is not an "
                                           f"input of the file's pairs (inputs: {self.inputs})", name)
            if not (np.isfinite(a) and a > 0):
                raise MeasurementFileError(self.label, ln, col, f"excitation of {name!r} must be a positive "
                                           f"amplitude, got {a!r}", name)
            self.excitation[name] = float(a)


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
    path : str
        The file it was read from ("" when built in memory); errors and warnings name it (:attr:`label`).
    """

    t: np.ndarray
    inputs: dict
    outputs: dict
    units: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    source: str = ""
    locations: dict = field(default_factory=dict, repr=False)
    path: str = ""

    kind = "time"

    @property
    def label(self) -> str:
        """What errors and warnings name: the file's path, else its source text."""
        return self.path or self.source or "<measurement>"

    def __post_init__(self):
        self.t = np.asarray(self.t, float)
        self.inputs = {k: np.asarray(v, float) for k, v in self.inputs.items()}
        self.outputs = {k: np.asarray(v, float) for k, v in self.outputs.items()}

