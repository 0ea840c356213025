"""Native code in a simulation: CasADi Functions compiled to C (:func:`native_function`, ``jit=True``), and
the native solvers' console messages kept quiet (:func:`quiet_native_stderr`).

SUNDIALS prints messages such as "The linesearch algorithm failed ..." with C-level writes to file
descriptor 2 that Python's ``sys.stderr`` cannot filter. The solver's own failure still raises (and
:class:`~bscomp.simulation.SimulationError` quotes it)."""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

from bscomp.errors import BscompError

__all__ = ["quiet_native_stderr", "native_function", "native_functions", "CFLAGS"]

#: The C compiler's flags. -O3 over -O2: the modal steps' loops over the step matrices run 10 % faster (moving-nut
#: bed 160 -> 145 ms warm), the same numbers to the bit on the four benchmark beds (no -ffast-math, no FMA
#: contraction without -march), and the same compile time.
CFLAGS = "-O3"


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


def native_function(f, cache_dir=None):
    """``f`` generated as C, compiled with the system C compiler and loaded; cached on disk by source hash.

    The cache directory is ``$BSCOMP_CACHE_DIR`` or ``~/.cache/bscomp``; a model compiled once loads in
    milliseconds in later runs and in worker processes. The compiler flags are :data:`CFLAGS` unless
    ``$BSCOMP_JIT_CFLAGS`` gives others (e.g. ``-O3 -march=native``; they are part of the cache key).
    """
    return native_functions([f], cache_dir)[0]


def native_functions(functions, cache_dir=None, key=None, names=None) -> list:
    """Several Functions in one C library (one compiler run; shared callees generated once), loaded.

    ``functions`` may be a callable that builds them: with a ``key`` (any string that identifies them) and
    their ``names``, a library already in the cache is loaded without building or generating anything.
    """
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise BscompError("jit=True needs a C compiler (cc or gcc on PATH, or $CC)")
    root = Path(cache_dir or os.environ.get("BSCOMP_CACHE_DIR") or Path.home() / ".cache" / "bscomp") / "jit"
    root.mkdir(parents=True, exist_ok=True)
    flags = (os.environ.get("BSCOMP_JIT_CFLAGS") or CFLAGS).split()
    if key is not None:
        digest = hashlib.sha1(f"{key}|{ca.__version__}|{flags}|{_AXPY_ORDER}".encode()).hexdigest()[:16]
        so = root / f"{names[0]}_k{digest}.so"
        if so.exists():
            return [ca.external(n, str(so)) for n in names]
    if callable(functions):
        functions = functions()
    name = functions[0].name()
    cg = ca.CodeGenerator(name + ".c", {"with_header": False})
    for f in functions:
        cg.add(f)
    src = _axpy_order(cg.dump())
    if key is None:
        so = root / f"{name}_{hashlib.sha1(f'{src}|{flags}'.encode()).hexdigest()[:16]}.so"
    if not so.exists():
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            c = Path(tmp) / f"{name}.c"
            c.write_text(src)
            out = Path(tmp) / so.name
            run = subprocess.run([cc, *flags, "-shared", "-fPIC", str(c), "-o", str(out)], capture_output=True,
                                 text=True)
            if run.returncode:
                raise BscompError(f"compiling {name} failed: {run.stderr[-500:]}")
            os.replace(out, so)  # atomic: concurrent workers never load a half-written file
    return [ca.external(f.name(), str(so)) for f in functions]


_DOT_ORDER = """  } else {
    for (i=0; i<ncol_y; ++i) {
      for (j=0; j<nrow_x; ++j) {
        for (k=0; k<ncol_x; ++k) {
          z[j + i*nrow_x] += x[j + k*nrow_x] * y[k + i*ncol_x];
        }
      }
    }
  }
}"""
_AXPY_ORDER = """  } else {
    for (i=0; i<ncol_y; ++i) {
      for (k=0; k<ncol_x; ++k) {
        for (j=0; j<nrow_x; ++j) {
          z[j + i*nrow_x] += x[j + k*nrow_x] * y[k + i*ncol_x];
        }
      }
    }
  }
}"""


def _axpy_order(src: str) -> str:
    """CasADi's dense matrix product ``z += x y`` with its two inner loops swapped: column after column into all rows.

    CasADi's C runs ``z_j += x_jk y_k`` row by row: one dependent chain of additions per row, read with a stride
    of the row count. Column by column the rows are independent and the column contiguous (the compiler
    vectorizes it). Every ``z_j`` still sums its terms in the order
    ``k = 0, 1, ...``: the same numbers to the bit. A CasADi whose helper reads differently is left as it is."""
    return src.replace(_DOT_ORDER, _AXPY_ORDER)
