"""Keep messages printed by native solver code (SUNDIALS' "The linesearch algorithm failed ...") off the
console: they are C-level writes to file descriptor 2 that Python's ``sys.stderr`` cannot filter. The
solver's own failure still raises (and :class:`~bscomp.simulation.SimulationError` quotes it)."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile

__all__ = ["quiet_native_stderr"]


@contextlib.contextmanager
def quiet_native_stderr():
    """Send fd 2 to a scratch file for the duration of the block (no-op where fd 2 cannot be redirected).

    Set ``BSCOMP_SOLVER_MESSAGES=1`` to see the messages.
    """
    if os.environ.get("BSCOMP_SOLVER_MESSAGES"):
        yield
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, AttributeError, ValueError):
        yield
        return
    with tempfile.TemporaryFile() as scratch:
        try:
            os.dup2(scratch.fileno(), 2)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
