"""The time series' sample steps compiled to C once they are hot (:class:`HotSteps`).

:meth:`bscomp.simulation.compiled.CompiledModel.simulate` runs a sample (its sub-steps, each with the Newton on the
element forces) as an expanded SX Function in CasADi's virtual machine. A fit runs the same sample Function hundreds
of times (diagnose of the bundled backlash truth: 91 runs of one 16-sub-step shape, 7.4 of its 43 s). Compiled to C
from the MX graph before it is expanded -- the Newton one called function (:func:`skipping_newton`), the products
loops, runs of 4-256 samples as nested calls (:func:`_blocks`) -- it compiles in ~1 s (the expanded straight-line
code: ~12 s) and that sample's 1,500-sample run takes 24 ms instead of 130, with the same numbers to the bit. So a
shape is compiled when the virtual machine has run :data:`HOT_WORK` instructions of it -- in a background thread
(:data:`BACKGROUND`; the virtual machine runs it until the library is there) -- and a shape compiled before
(in any process, on this machine) is loaded from the on-disk cache at its first run
(:func:`bscomp.simulation.native.cached_functions`). Where no C compiler is found, the compilation fails or the cache
folder cannot be written, the virtual machine goes on (``CompiledModel.stats["native_steps"]`` says which ran).
``BSCOMP_NATIVE_STEPS=0`` keeps every run in the virtual machine. Measured: ``docs/validation.md``, "Engine".
"""

from __future__ import annotations

import hashlib
import os
from concurrent.futures import Future, ThreadPoolExecutor

import casadi as ca
import numpy as np

from bscomp.errors import BscompError
from bscomp.simulation.native import cached_functions, library_job, load_library

__all__ = ["BACKGROUND", "BLOCKS", "HOT_WORK", "HotSteps", "NativeRun", "skipping_newton"]

#: SX instructions x samples the virtual machine runs of one sample Function before it is compiled (~0.7 s of it;
#: a compilation costs ~0.9 s and saves ~60 % of every later run).
HOT_WORK = 3e8


#: Compile in a background thread (the virtual machine goes on meanwhile; the compiler runs on another core where there
#: is one); ``False``: compile at once, in the caller's thread.
BACKGROUND = True
_POOL = None                                   # the one compiler thread (made at the first compilation)


class HotSteps:
    """Per CompiledModel: the virtual machine's work per sample Function and the compiled runs (:class:`NativeRun`)."""

    def __init__(self):
        self.work = {}          # key -> instructions x samples run in the virtual machine
        self.native = {}        # key -> NativeRun, or None (not available: keep the VM)
        self.graphs = {}        # key -> (the MX sample Function, its cache key); built at its first run, when the
                                #        on-disk library is looked for
        self.pending = {}       # key -> (future of the compiler's run, library path, names)
        self.enabled = os.environ.get("BSCOMP_NATIVE_STEPS", "1") != "0"

    def get(self, key, build, vm, n_samples):
        """The :class:`NativeRun` of ``key`` (``build()``: the MX sample Function to compile, ``vm()``: the SX one the
        virtual machine runs -- expanded only where it runs), or ``None``: then the caller runs ``vm()`` for
        ``n_samples`` samples, counted here."""
        if not self.enabled:
            return None
        if key in self.native:
            return self.native[key]
        if key in self.pending:
            return self._finish(key)
        if key not in self.graphs:
            graph = build()
            self.graphs[key] = graph, _ident(graph)
            try:
                found = cached_functions(self.graphs[key][1], _names(graph))
            except (OSError, RuntimeError):      # a library there that does not load: compiled anew when hot
                found = None
            if found is not None:
                self.native[key] = NativeRun(found)
                return self.native[key]
        done = self.work.get(key, 0.0)
        if done < HOT_WORK:
            self.work[key] = done + vm().n_instructions() * n_samples
            return None
        graph, ident = self.graphs[key]
        try:                                     # the C generated here (CasADi stays in this thread)
            job, so, names = library_job(lambda: _blocks(graph), key=ident, names=_names(graph))
        except (BscompError, OSError):           # no C compiler, or the cache folder cannot be written
            self.native[key] = None
            return None
        if not BACKGROUND:
            self.pending[key] = (_done(job), so, names)
            return self._finish(key)
        global _POOL
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bscomp-cc")
        self.pending[key] = (_POOL.submit(job), so, names)
        return None

    def _finish(self, key):
        """The compiled run of a pending compilation once the compiler is done (else ``None``: the VM goes on)."""
        future, so, names = self.pending[key]
        if not future.done():
            return None
        del self.pending[key]
        try:
            future.result()
            self.native[key] = NativeRun(load_library(so, names))
        except (BscompError, OSError, RuntimeError):   # it failed, or the library does not load: the VM goes on
            self.native[key] = None
        return self.native[key]


def _done(job) -> Future:
    """``job()`` run now, as a finished Future (its exception kept for ``result()``)."""
    future = Future()
    try:
        future.set_result(job())
    except Exception as exc:                     # noqa: BLE001 -- handed to _finish, which names what it catches
        future.set_exception(exc)
    return future


def _ident(graph) -> str:
    """The on-disk cache's key of a sample Function: a hash of its serialized graph (what its code is made from)."""
    return f"time_series_sample|{hashlib.sha1(graph.serialize().encode()).hexdigest()}"


def _names(graph) -> list:
    return [f"{graph.name()}_x{n}" for n in BLOCKS]


def skipping_newton(step, residual, n_iter):
    """MX Function ``(a_s, a_v, Gs, Gv, w0, pl) -> (w, residual)``: ``n_iter`` calls of the Newton ``step`` (SX,
    ``-> (w_next, R)``), each skipped once an iteration returned its start exactly (``Function.if_else``: the skipped
    call is not computed in C). A fixed point of the step stays one, so the result is that of every iteration run (the
    virtual machine's, to the bit)."""
    ins = step.mx_in()
    keep = ca.Function("newton_keep", ins, [ins[4], ca.MX.zeros(step.sparsity_out(1))])
    maybe = ca.Function.if_else("newton_maybe", keep, step)
    w, done = ins[4], ca.MX(0)
    for _ in range(n_iter):
        wn = maybe(done, *ins[:4], w, ins[5])[0]
        done = ca.logic_or(done, ca.norm_inf(wn - w) == 0)
        w = wn
    return ca.Function("newton_skipping", ins, [w, residual(*ins[:4], w, ins[5])])


#: Samples per compiled call: a run of n samples is cut greedily into calls of these (largest first).
BLOCKS = (256, 64, 16, 4, 1)


def _blocks(graph) -> list:
    """The sample Function ``graph`` ``(x, up, uc, *matrices) -> (x, y, bad)`` and its runs over 4, 16, 64 and 256
    samples (``up``, ``uc``, ``y``, ``bad`` with a column per sample), each four calls of the next shorter one: the
    code grows with the levels, not the samples, and the matrices are passed by reference (a ``mapaccum`` copies
    them for every sample). Longest first, as :data:`BLOCKS`."""
    name = graph.name()
    ins = graph.mx_in()
    out = [ca.Function(f"{name}_x1", ins, graph.call(ins))]
    for n in BLOCKS[-2::-1]:
        sub, q = out[-1], n // 4
        ins = graph.mx_in()
        x, rest = ins[0], ins[3:]
        up, uc = ca.MX.sym("up", graph.size1_in(1), n), ca.MX.sym("uc", graph.size1_in(2), n)
        ys, bads = [], []
        for j in range(4):
            x, y, b = sub(x, up[:, j * q:(j + 1) * q], uc[:, j * q:(j + 1) * q], *rest)
            ys.append(y)
            bads.append(b)
        out.append(ca.Function(f"{name}_x{n}", [ins[0], up, uc, *rest], [x, ca.horzcat(*ys), ca.horzcat(*bads)]))
    return out[::-1]


class NativeRun:
    """A run of the compiled sample: ``(x0, up, uc, matrices) -> (Y, bad)`` for ``up``, ``uc`` (nu, n)."""

    def __init__(self, functions):
        self.f = dict(zip(BLOCKS, functions, strict=True))

    def __call__(self, x0, up, uc, mats):
        n = up.shape[1]
        mats = [ca.DM(m) for m in mats]       # converted once, not at every call (~30 arguments a call)
        x, Y, bad, k = x0, [], [], 0
        for size in BLOCKS:
            while n - k >= size:
                x, y, b = self.f[size](x, up[:, k:k + size], uc[:, k:k + size], *mats)
                Y.append(np.asarray(y))
                bad.append(np.asarray(b))
                k += size
        return np.hstack(Y), float(np.max(np.hstack(bad)))
