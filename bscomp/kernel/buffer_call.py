"""Numeric calls of a CasADi Function through its buffer, sparse outputs handed out as scipy matrices.

``F(*args)`` from Python converts every argument and result to a ``DM``; reading a sparse result back into scipy
(``DM.nonzeros()``, a Python list) costs more than the evaluation itself for a Jacobian of a few hundred rows: the
6-DOF test bed's ``dF/dx`` (582 x 582, 168,000 structural nonzeros) took 10 ms to evaluate and 20 ms to convert.
:class:`SparseCall` evaluates into preallocated numpy arrays (``Function.buffer``) and builds each sparse result
from the output's compressed-column pattern read once -- the same numbers, bit for bit.
"""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import scipy.sparse as sp

__all__ = ["SparseCall"]


class SparseCall:
    """Call ``F`` with numeric arguments: the outputs numbered in ``arrays`` as 1-D arrays (column-major values),
    the others as ``scipy.sparse.csc_matrix`` with ``F``'s structural pattern (explicit zeros kept; an empty or
    dense output too). Results are copies: nothing handed out is overwritten by the next call. Thread-safe (one
    buffer, a lock)."""

    def __init__(self, F: ca.Function, arrays=()):
        self.F = F
        self._buf, self._trigger = F.buffer()
        self._args = [np.zeros(F.nnz_in(i)) for i in range(F.n_in())]
        self._res = [np.zeros(F.nnz_out(i)) for i in range(F.n_out())]
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._res):
            self._buf.set_res(i, memoryview(r))
        self._pattern = []
        for i in range(F.n_out()):
            s = F.sparsity_out(i)
            if i in arrays:
                self._pattern.append(None)
            else:
                colind, row = s.get_ccs()
                self._pattern.append((np.asarray(row, np.int32), np.asarray(colind, np.int32), s.shape))
        self._lock = threading.Lock()

    def __call__(self, *args):
        if len(args) != len(self._args):
            raise TypeError(f"{self.F.name()}: {len(self._args)} arguments expected, {len(args)} given")
        with self._lock:
            for i, (slot, a) in enumerate(zip(self._args, args, strict=True)):
                v = np.ravel(np.asarray(a.full() if isinstance(a, ca.DM) else a, float), order="F")
                if v.size != slot.size:
                    raise ValueError(f"{self.F.name()}: argument {self.F.name_in(i)} has {v.size} numbers, "
                                     f"{slot.size} expected")
                slot[:] = v
            self._trigger()
            out = []
            for r, pat in zip(self._res, self._pattern, strict=True):
                if pat is None:
                    out.append(r.copy())
                else:
                    row, colind, shape = pat
                    out.append(sp.csc_matrix((r.copy(), row.copy(), colind.copy()), shape=shape))
            return out
