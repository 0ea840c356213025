"""Named errors of bscomp.

Every error says which component, port, parameter or variable is involved and how to fix it.
"""

__all__ = [
    "BscompError",
    "ModelDefinitionError",
    "PortConnectionError",
    "UnconnectedPortError",
    "DuplicateNameError",
    "UnknownNameError",
    "ParameterError",
    "StructuralError",
    "UnderdeterminedError",
    "OverdeterminedError",
    "HighIndexError",
    "SingularSystemError",
    "NotLinearError",
    "SolverError",
    "OutputFileError",
    "UsageError",
    "ArgumentTypeError",
    "ParameterFileError",
    "MissingParameterFileError",
    "ModelLimitationWarning",
    "SlowMethodWarning",
    "check_number",
    "check_mapping",
    "FmuExportError",
    "CompilerNotFoundError",
]


class BscompError(Exception):
    """Base class of all bscomp errors.

    ``hint`` (optional keyword) says how to fix it; the CLI prints ``<message> -- <hint>``.
    ``exit_code`` is what the command line returns: 2 for a user mistake, 1 for a solver that ran and failed.
    """

    exit_code = 2

    def __init__(self, *args, hint: str | None = None):
        super().__init__(*args)
        if hint is not None:
            self.hint = hint

    hint: str | None = None


class ModelDefinitionError(BscompError):
    """A component class is written in a way the kernel cannot use (e.g. a flow is not defined)."""


class PortConnectionError(BscompError):
    """Two ports cannot be connected (different kinds or units, two outputs on one signal, ...)."""


class UnconnectedPortError(BscompError):
    """A required port is not connected and has no default."""


class DuplicateNameError(BscompError):
    """A name is used twice in one system."""


class UnknownNameError(BscompError, KeyError):
    """A dotted name (component, port, parameter, variable) does not exist."""

    def __str__(self):  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class ParameterError(BscompError, ValueError):
    """A parameter value is non-physical (outside its bounds, NaN or inf) or malformed."""


class StructuralError(BscompError):
    """The flattened equations are not a well-posed index-1 DAE."""


class UnderdeterminedError(StructuralError):
    """More unknowns than independent equations."""


class OverdeterminedError(StructuralError):
    """More equations than unknowns, or redundant/inconsistent constraints."""


class HighIndexError(StructuralError):
    """An algebraic constraint acts on differential states: differentiation index > 1."""


class SingularSystemError(StructuralError):
    """A matrix that must be invertible is numerically singular (e.g. mass matrix of a mechanism)."""


class NotLinearError(BscompError):
    """A second-order (M, C, K) form was requested for a system that has no such form."""


class SolverError(BscompError):
    """A solver ran on a well-posed problem and failed (integrator, Newton, Ipopt): CLI exit code 1."""

    exit_code = 1


class OutputFileError(BscompError, OSError):
    """An output file cannot be written (a directory, a missing or read-only folder, a wrong extension)."""


class UsageError(BscompError, ValueError):
    """A command-line argument or a function argument is malformed or out of range."""


class ArgumentTypeError(UsageError, TypeError):
    """A function argument has the wrong type (a ``TypeError`` too, for Python callers that catch that)."""


class ParameterFileError(BscompError, ValueError):
    """A parameter file (TOML) is missing, unreadable or malformed; names the file and the dotted key.

    A missing file is also a ``FileNotFoundError`` (:class:`MissingParameterFileError`)."""


class MissingParameterFileError(ParameterFileError, FileNotFoundError):
    """The parameter file does not exist (a ``FileNotFoundError`` too, for callers that catch that)."""


class ModelLimitationWarning(UserWarning):
    """A method ignores part of the model (e.g. ``simulate(method="lti")`` on a nonlinear model)."""


class SlowMethodWarning(UserWarning):
    """A method chosen for a model it handles orders of magnitude slower than another one (named in the
    message), e.g. ``simulate(method="split")`` with a nut moving along the screw."""


def check_number(name: str, value, *, positive: bool = False, nonnegative: bool = False, integer: bool = False,
                 minimum=None, error=None):
    """``value`` as a float (int if ``integer``), finite and in range, else ``error`` (:class:`UsageError`)
    naming the argument ``name``."""
    error = error or UsageError
    if isinstance(value, (bool, str, bytes)) or type(value).__name__ in ("bool", "bool_"):   # True is not 1
        raise error(f"{name} must be a number, got {value!r} ({type(value).__name__})")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, got {value!r}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise error(f"{name} must be finite, got {v}")
    if integer:
        if v != int(v):
            raise error(f"{name} must be an integer, got {value!r}")
        v = int(v)
    if positive and not v > 0:
        raise error(f"{name} must be > 0, got {value!r}")
    if nonnegative and not v >= 0:
        raise error(f"{name} must be >= 0, got {value!r}")
    if minimum is not None and v < minimum:
        raise error(f"{name} must be >= {minimum}, got {value!r}")
    return v


def check_names(name: str, value, *, unique: bool = False) -> list | None:
    """``value`` as a list of names (``None`` stays ``None``): one string is one name (``inputs="motor.tau"``,
    not its characters); anything but strings is an :class:`ArgumentTypeError` naming the argument ``name``;
    with ``unique`` a name listed twice is a :class:`UsageError` (an FMU variable, a CSV column)."""
    if value is None:
        return None
    if isinstance(value, str):
        return [value]
    try:
        out = None if isinstance(value, (bytes, dict)) else list(value)
    except TypeError:
        out = None
    if out is None or not all(isinstance(n, str) for n in out):
        raise ArgumentTypeError(f"{name} must be a name or a list of names (e.g. ['motor.tau']), got "
                                f"{type(value).__name__} {value!r}"[:300])
    dup = [n for k, n in enumerate(out) if n in out[:k]]
    if unique and dup:
        raise UsageError(f"{name} lists {dup[0]!r} twice: give each name once")
    return out


def check_mapping(name: str, value, what: str = "values") -> dict:
    """``value`` as a dict ``{name: ...}`` (``None`` -> ``{}``), else :class:`ArgumentTypeError` naming the
    argument; keys must be strings (dotted names)."""
    if value is None:
        return {}
    if not hasattr(value, "items"):
        raise ArgumentTypeError(f"{name} must be a dict of {what} by name, e.g. {{'table.s': 0.0}}, got "
                                f"{type(value).__name__} {value!r}"[:300])
    bad = [k for k in value if not isinstance(k, str)]
    if bad:
        raise ArgumentTypeError(f"{name}: keys must be names (str), got {bad[0]!r}")
    return dict(value)


class FmuExportError(BscompError):
    """A model cannot be exported as an FMU as asked (bad path, structural tunable parameter, name clash...)."""


class CompilerNotFoundError(FmuExportError):
    """The C compiler needed to build an FMU binary is not on PATH."""
