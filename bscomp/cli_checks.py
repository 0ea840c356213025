"""Argument checks of the command line (:mod:`bscomp.cli`), each done before any computation and naming the
option it checks: ``--set``, ``--uncertain``, ``--t-end``/``--dt``, output folders, the system file's
``build()``, and SIGTERM turned into the same clean exit as Ctrl-C (no partial output file left).

A helper of :mod:`bscomp.cli` only: it imports the errors, :mod:`bscomp.files` and (lazily) the model
resolution, never the CLI itself.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import threading

from bscomp.errors import ModelDefinitionError, ParameterError, UnknownNameError, UsageError
from bscomp.files import _check_replaceable, writable_dir

__all__ = ["number", "parse_set", "parse_uncertain", "steps", "output_folder", "check_system", "build_guard",
           "check_file_system", "reference_table", "Terminated",
           "sigterm_as_interrupt"]


def number(flag, low=None, high=None, integer=False, open_low=True):
    """An argparse type: a finite number (an int if ``integer``) in (low, high]; the error names the flag."""
    def parse(text):
        kind = "an integer" if integer else "a number"
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} must be {kind}, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{flag} must be finite, got {text!r}")
        if low is not None and (v <= low if open_low else v < low):
            raise argparse.ArgumentTypeError(f"{flag} must be {'>' if open_low else '>='} {low:g}, got {text!r}")
        if high is not None and v > high:
            raise argparse.ArgumentTypeError(f"{flag} must be <= {high:g}, got {text!r}")
        return v

    return parse


def parse_set(items) -> dict:
    """``--set NAME=VALUE`` (repeatable) -> ``{name: value}`` (a number when it reads as one)."""
    out = {}
    for item in items or []:
        name, eq, value = item.partition("=")
        if not eq or not name.strip():
            raise ParameterError(f"--set expects NAME=VALUE (e.g. coupling.c=45940), got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            out[name.strip()] = value.strip()
    return out


UNCERTAIN_FORMAT = "--uncertain component.parameter[=spread][,...]"


def parse_uncertain(items):
    """``--uncertain NAME[=SPREAD][,NAME...]`` -> ``{name: spread}`` (None when not given); every NAME must be
    ``component.parameter`` and every SPREAD a finite number > 0."""
    if not items:
        return None
    out = {}
    for item in items:
        toks = [t.strip() for t in item.split(",")]
        if not any(toks):
            raise UsageError(f"--uncertain got {item!r}, which names no parameter", hint=f"write {UNCERTAIN_FORMAT}, "
                             "e.g. --uncertain table.m=0.2")
        for tok in (t for t in toks if t):
            name, eq, spread = (s.strip() for s in tok.partition("="))
            parts = name.split(".")
            if len(parts) < 2 or not all(p.strip() for p in parts):
                raise UsageError(f"--uncertain: {tok!r} does not name a parameter as component.parameter",
                                 hint=f"write {UNCERTAIN_FORMAT}, e.g. --uncertain table.m=0.2")
            try:
                value = float(spread) if eq else 0.2
            except ValueError:
                value = None
            if value is None or not math.isfinite(value) or value <= 0:
                raise UsageError(f"--uncertain {name}: the spread must be a finite relative number > 0, got "
                                 f"{spread!r}", hint=f"write {UNCERTAIN_FORMAT}, e.g. --uncertain {name}=0.2")
            out[name] = value
    return out


def steps(t_end: float, dt: float, most: int = 10 ** 7) -> int:
    """The number of ``--dt`` steps in ``--t-end``: a whole number (to 1e-9 relative), 1 to ``most``."""
    ratio = t_end / dt
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-9 * max(ratio, 1.0):
        k = max(math.ceil(ratio - 1e-9), 1)
        raise UsageError(f"--t-end {t_end:g} s is not a whole number of --dt {dt:g} s steps ({ratio:.6g} steps); "
                         "the run would end at another time", hint=f"give --dt {t_end / k:.6g} ({k} steps) or "
                         f"--t-end {max(n, 1) * dt:.6g}")
    if n > most:
        raise UsageError(f"--t-end {t_end:g} s over --dt {dt:g} s gives {n} steps (1 to {most:.0e})",
                         hint="give a larger --dt or a shorter --t-end")
    return n


def output_folder(path, flag: str):
    """Check the folder of ``flag`` (``--report``, ``--out``) can be written, before computing; names ``flag``."""

    p = writable_dir(path, f"{flag} folder")
    if flag == "--report":
        _check_replaceable(p)
    return p


@contextlib.contextmanager
def build_guard(source):
    """Calls that run a system file's ``build()``: a ``sys.exit()`` in it becomes a one-line error naming the
    file (instead of the command exiting silently with that code)."""
    try:
        yield
    except SystemExit as exc:
        raise ModelDefinitionError(f"system file {source}: build() (or loading the file) called sys.exit({exc.code!r})",
                                   hint="build() must return a bscomp.System; raise an exception to report a "
                                        "problem") from None


def check_system(system, source):
    """``system`` (what ``source``'s build returned) must be a :class:`bscomp.System`, else an error naming the
    file and build()."""
    from bscomp.kernel import System

    if not isinstance(system, System):
        what = f"system file {source}" if str(source).endswith(".py") else f"system '{source}'"
        raise ModelDefinitionError(f"{what}: build() returned {type(system).__name__} "
                                   f"{str(system)[:60]!r}, not a bscomp.System",
                                   hint="make build() end with `return system` (a bscomp.System)")
    return system


def reference_table(md, reference) -> str:
    """The mode table, modal masses at ``--reference`` (a coordinate of the modes, named in the error)."""

    if not reference:
        return md.table()
    try:
        return md.table(reference)
    except (UnknownNameError, KeyError, ValueError, IndexError) as exc:
        raise UnknownNameError(f"--reference {reference!r}: {exc}; coordinates of the modes: "
                               f"{list(md.coordinates)[:12]}", hint="give one of those, e.g. --reference "
                               f"{md.coordinates[0]}") from None


def check_file_system(source, overrides=None) -> None:
    """A ``.py`` system file is built once up front, so a build() that exits or returns no System is named."""
    if str(source).endswith(".py"):
        from bscomp.linear.sweeps import build_system

        with build_guard(source):
            check_system(build_system(source, overrides or None), source)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C, so every ``with`` block removes its temporary files."""


def _raise_terminated(signum, frame):
    raise Terminated()


@contextlib.contextmanager
def sigterm_as_interrupt():
    """While the block runs (in the main thread), SIGTERM raises :class:`Terminated`; the previous handler is
    restored after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
