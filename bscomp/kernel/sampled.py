"""Sampled (discrete-time) blocks: a MISO difference equation with memory, the base of the digital controllers.

The continuous DAE cannot hold a sampled block, so digital controllers (``DigitalPController``,
``NotchFilter``, ``RSTController``) are plain objects that (i) hold the coefficients of their difference
equation, (ii) give the python-control discrete ``TransferFunction`` for linear analysis, and (iii) advance
one sample per :meth:`SampledBlock.step` call for a simulator that runs them every ``T_s`` and holds the
output over the next period (the zero-order hold of Eq 4.16, the D/A converter of Fig 4.3).

With polynomials in ``z`` (descending powers, ``deg num_j <= deg den = n``) the block computes

.. math:: \\mathrm{den}(z)\\, y = \\sum_j \\mathrm{num}_j(z)\\, u_j

i.e. ``a_0 y_k = sum_j sum_i b_{j,i} u_{j,k-i} - sum_{i>=1} a_i y_{k-i}``, realised in transposed
direct form II (n delay states, no history buffers).

Closing a loop with blocks is the simulation's business: :func:`bscomp.simulation.sampled_controller`
wraps one block, or a series chain of blocks (e.g. the P controller and the notch filter of Fig 4.14), as a
:class:`bscomp.simulation.SampledController` for ``simulate(..., controllers=[...])``.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ParameterError

__all__ = ["SampledBlock"]


class SampledBlock:
    """Discrete-time MISO block ``den(z) y = sum_j num_j(z) u_j`` sampled every ``T_s``.

    Parameters
    ----------
    nums : sequence of array_like
        Numerator polynomial in ``z`` for each input (descending powers).
    den : array_like
        Common denominator polynomial in ``z`` (descending powers, leading coefficient non-zero).
    T_s : float
        Sampling period [s] (> 0).
    inputs : sequence of str
        Input names (one per numerator).
    output : str
        Output name.
    """

    def __init__(self, nums, den, T_s: float, inputs, output: str):
        T_s = float(T_s)
        if not (np.isfinite(T_s) and T_s > 0):
            raise ParameterError(f"{type(self).__name__}: sampling period T_s = {T_s!r} s must be > 0")
        den = np.trim_zeros(np.atleast_1d(np.asarray(den, float)), "f")
        if den.size == 0 or not np.all(np.isfinite(den)):
            raise ParameterError(f"{type(self).__name__}: denominator {den!r} is zero or not finite")
        nums = [np.atleast_1d(np.asarray(b, float)) for b in nums]
        n = den.size - 1
        padded = []
        for name, b in zip(inputs, nums):
            b = np.trim_zeros(b, "f") if np.any(b) else np.zeros(1)
            if b.size - 1 > n:
                raise ParameterError(f"{type(self).__name__}: numerator of input '{name}' has degree "
                                     f"{b.size - 1} > denominator degree {n}: the block would need future "
                                     "samples (not causal)")
            if not np.all(np.isfinite(b)):
                raise ParameterError(f"{type(self).__name__}: numerator of input '{name}' is not finite")
            padded.append(np.concatenate([np.zeros(n + 1 - b.size), b]))
        if len(padded) != len(inputs):
            raise ParameterError(f"{type(self).__name__}: {len(padded)} numerators for inputs {list(inputs)}")
        self.T_s = T_s
        self.inputs = list(inputs)
        self.output = output
        self.den = den  # as given (descending powers of z)
        self.nums = [np.trim_zeros(p, "f") if np.any(p) else np.zeros(1) for p in padded]
        self._a = den / den[0]  # normalised, length n + 1
        self._b = np.array(padded) / den[0]  # (n_inputs, n + 1)
        self._state = np.zeros(n)

    # ---- simulation ---------------------------------------------------------------------------
    @property
    def order(self) -> int:
        """Number of delay states (degree of the denominator)."""
        return self._a.size - 1

    def reset(self, state=None) -> None:
        """Clear the memory (or set the transposed-direct-form-II state vector)."""
        self._state = np.zeros(self.order) if state is None else np.array(state, float).reshape(self.order)

    def step(self, *u_k) -> float:
        """Advance one sample: take the inputs ``u_k`` (one float per input), return ``y_k``."""
        if len(u_k) != len(self.inputs):
            raise TypeError(f"{type(self).__name__}.step() takes {len(self.inputs)} input(s) {self.inputs}, "
                            f"got {len(u_k)}")
        u = np.asarray(u_k, float)
        b, a, s = self._b, self._a, self._state
        y = float(b[:, 0] @ u + (s[0] if s.size else 0.0))
        n = s.size
        for i in range(n):
            nxt = s[i + 1] if i + 1 < n else 0.0
            s[i] = b[:, i + 1] @ u + nxt - a[i + 1] * y
        return y

    def simulate(self, u) -> np.ndarray:
        """Run :meth:`step` over samples ``u`` of shape ``(n_inputs, N)`` (or ``(N,)`` for one input)."""
        u = np.atleast_2d(np.asarray(u, float))
        return np.array([self.step(*u[:, k]) for k in range(u.shape[1])])

    # ---- linear analysis ----------------------------------------------------------------------
    def tf(self):
        """python-control discrete ``TransferFunction`` (1 output x n_inputs, ``dt = T_s``)."""
        import control

        return control.tf([[list(b) for b in self.nums]], [[list(self.den)] * len(self.nums)], self.T_s,
                          inputs=self.inputs, outputs=[self.output])

    def ss(self):
        """python-control discrete ``StateSpace`` of the same transposed-direct-form-II realisation that
        :meth:`step` runs (so its state matches the block's memory)."""
        import control

        n, a, b = self.order, self._a, self._b
        A = np.zeros((n, n))
        if n:
            A[:, 0] = -a[1:]
            A[:-1, 1:] = np.eye(n - 1)
        B = (b[:, 1:] - np.outer(b[:, 0], a[1:])).T if n else np.zeros((0, len(self.inputs)))
        C = np.zeros((1, n))
        if n:
            C[0, 0] = 1.0
        D = b[:, 0].reshape(1, -1)
        return control.ss(A, B, C, D, self.T_s, inputs=self.inputs, outputs=[self.output])

    def __repr__(self):
        return f"<{type(self).__name__} order {self.order}, T_s = {self.T_s:g} s, inputs {self.inputs}>"

