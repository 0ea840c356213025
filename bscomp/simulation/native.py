"""Native code in a simulation: CasADi Functions compiled to C (:func:`native_function`, ``jit=True``), and
the native solvers' console messages kept quiet (:func:`quiet_native_stderr`).

SUNDIALS prints messages such as "The linesearch algorithm failed ..." with C-level writes to file
descriptor 2 that Python's ``sys.stderr`` cannot filter. The solver's own failure still raises (and
:class:`~bscomp.simulation.SimulationError` quotes it)."""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

from bscomp.errors import BscompError

__all__ = ["quiet_native_stderr", "native_function", "native_functions", "cached_functions", "library_job",
           "load_library", "CFLAGS", "NATIVE_CFLAGS", "cpu_id"]

#: The C compiler's flags everywhere. -O3 over -O2: the modal steps' loops run 10 % faster, the same compile time;
#: no fused multiply-add contraction (GCC contracts by default where the CPU has FMA), so the numbers are those of
#: CasADi's virtual machine to the bit. ``-fno-tree-slp-vectorize``: GCC 12's straight-line (SLP) vectorizer emits
#: vector FMAs under ``-march=native`` *despite* ``-ffp-contract=off`` (4 of 80 random chains of
#: ``benchmarks/fuzz_compiled.py`` left the VM's numbers by ~1e-13 of their scale, ``docs/validation.md`` "Engine");
#: the loops (products) are still vectorized, and the modal steps ran no slower without it.
CFLAGS = "-O3 -ffp-contract=off -fno-tree-slp-vectorize"
#: Added on an x86 Linux whose CPU is identified (:func:`cpu_id`, part of the cache key: a library built here is
#: never loaded on another CPU): its vector width for the modal steps' products (moving-nut bed: the compiled steps
#: 62 -> 50 ms of a 0.6 s run). A compiler that refuses it is asked again without.
NATIVE_CFLAGS = "-march=native"
_CPU = None                                             # cpu_id(), read once


def cpu_id() -> str:
    """A short hash of this CPU's model and instruction-set flags (``/proc/cpuinfo``), or ``""`` where they are
    not readable or not an x86's (then :data:`NATIVE_CFLAGS` are not used)."""
    global _CPU
    if _CPU is None:
        _CPU = ""
        try:
            info = Path("/proc/cpuinfo").read_text(errors="replace")
        except OSError:
            return _CPU
        lines = {}
        for line in info.splitlines():
            k, _, v = line.partition(":")
            lines.setdefault(k.strip(), v.strip())
            if not line.strip() and lines:
                break                                   # the first processor's block
        if "flags" in lines:
            _CPU = hashlib.sha1(f"{lines.get('model name')}|{lines['flags']}".encode()).hexdigest()[:12]
    return _CPU


def _flags() -> tuple[list, list]:
    """``(flags, fallback)``: ``$BSCOMP_JIT_CFLAGS`` alone if set, else :data:`CFLAGS` and, where :func:`cpu_id`
    knows the CPU, :data:`NATIVE_CFLAGS` (fallback: without them)."""
    user = os.environ.get("BSCOMP_JIT_CFLAGS")
    if user:
        return user.split(), user.split()
    base = CFLAGS.split()
    return (base + NATIVE_CFLAGS.split(), base) if cpu_id() else (base, base)


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
    milliseconds in later runs and in worker processes. The compiler flags are :data:`CFLAGS` (and
    :data:`NATIVE_CFLAGS` on an identified x86 CPU) unless ``$BSCOMP_JIT_CFLAGS`` gives others; flags and CPU are
    part of the cache key.
    """
    return native_functions([f], cache_dir)[0]


def _root(cache_dir=None) -> Path:
    """The compiled libraries' folder: ``<cache_dir or $BSCOMP_CACHE_DIR or ~/.cache/bscomp>/jit``."""
    return Path(cache_dir or os.environ.get("BSCOMP_CACHE_DIR") or Path.home() / ".cache" / "bscomp") / "jit"


def _tag(flags) -> str:
    """What else a library's code depends on: the flags, the CPU under ``-march=native``, the product loops."""
    return f"{flags}|{cpu_id() if '-march=native' in flags else ''}|{_AXPY_ORDER}|{_FIXED_PRODUCT}"


def _keyed(root, key, names, tag) -> Path:
    digest = hashlib.sha1(f"{key}|{ca.__version__}|{tag}".encode()).hexdigest()[:16]
    return root / f"{names[0]}_k{digest}.so"


def cached_functions(key, names, cache_dir=None) -> list | None:
    """The Functions ``names`` of a library :func:`native_functions` compiled under ``key`` earlier (in any process),
    loaded; ``None`` when there is none (nothing is generated or compiled)."""
    so = _keyed(_root(cache_dir), key, names, _tag(_flags()[0]))
    return load_library(so, names) if so.exists() else None


def native_functions(functions, cache_dir=None, key=None, names=None) -> list:
    """Several Functions in one C library (one compiler run; shared callees generated once), loaded.

    ``functions`` may be a callable that builds them: with a ``key`` (any string that identifies them) and
    their ``names``, a library already in the cache is loaded without building or generating anything.
    """
    build, so, names = library_job(functions, cache_dir, key, names)
    build()
    return load_library(so, names)


def library_job(functions, cache_dir=None, key=None, names=None) -> tuple:
    """``(build, so, names)`` of :func:`native_functions`' library: the C is generated here (nothing when a library
    under ``key`` is in the cache), ``build()`` runs the compiler into ``so`` (no CasADi: it may run in another
    thread; atomic, a no-op once ``so`` is there) and :func:`load_library` loads it."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise BscompError("jit=True needs a C compiler (cc or gcc on PATH, or $CC)")
    root = _root(cache_dir)
    root.mkdir(parents=True, exist_ok=True)
    flags, fallback = _flags()
    tag = _tag(flags)
    if key is not None:
        so = _keyed(root, key, names, tag)
        if so.exists():
            return (lambda: None), so, list(names)
    if callable(functions):
        functions = functions()
    name = functions[0].name()
    cg = ca.CodeGenerator(name + ".c", {"with_header": False})
    for f in functions:
        cg.add(f)
    src = _fixed_products(_axpy_order(cg.dump()))
    if key is None:
        so = root / f"{name}_{hashlib.sha1(f'{src}|{tag}'.encode()).hexdigest()[:16]}.so"

    def build():
        if so.exists():
            return
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            c = Path(tmp) / f"{name}.c"
            c.write_text(src)
            out = Path(tmp) / so.name

            def compile_(fl):
                return subprocess.run([cc, *fl, "-shared", "-fPIC", str(c), "-o", str(out)], capture_output=True,
                                      text=True)

            run = compile_(flags)
            if run.returncode and fallback != flags:
                run = compile_(fallback)
            if run.returncode:
                raise BscompError(f"compiling {name} failed: {run.stderr[-500:]}")
            os.replace(out, so)  # atomic: concurrent workers never load a half-written file

    return build, so, [f.name() for f in functions]


def load_library(so, names) -> list:
    """The Functions ``names`` of the compiled library ``so``."""
    return [ca.external(n, str(so)) for n in names]


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


_PRODUCT_CALL = re.compile(r"casadi_mtimes_dense\(([\w+]+), (\d+), (\d+), ([\w+]+), (\d+), ([\w+]+), 0\);")
_FIXED_PRODUCT = """static inline void bscomp_mv_{a}_{b}_{c}(const casadi_real* x, const casadi_real* y,
    casadi_real* z) {{
  casadi_int i, j, k;
  for (i=0; i<{c}; ++i) {{
    for (k=0; k<{b}; ++k) {{
      for (j=0; j<{a}; ++j) {{
        z[j + i*{a}] += x[j + k*{a}] * y[k + i*{b}];
      }}
    }}
  }}
}}
"""


def _fixed_products(src: str) -> str:
    """Every dense product ``z += x y`` of constant sizes (all of them in a CasADi MX Function) through its own copy
    of :func:`_axpy_order`'s loop with the sizes written in: the compiler unrolls and vectorizes a loop whose
    trip counts it knows (CasADi's one helper takes them at run time). The same operations in the same order: the
    numbers to the bit."""
    sizes = sorted({(int(a), int(b), int(c)) for _, a, b, _, c, _ in _PRODUCT_CALL.findall(src)})
    anchor = src.find("void casadi_mtimes_dense(")
    if not sizes or anchor < 0:
        return src
    src = _PRODUCT_CALL.sub(lambda m: f"bscomp_mv_{m[2]}_{m[3]}_{m[5]}({m[1]}, {m[4]}, {m[6]});", src)
    defs = "".join(_FIXED_PRODUCT.format(a=a, b=b, c=c) for a, b, c in sizes)
    return src[:anchor] + defs + "\n" + src[anchor:]
