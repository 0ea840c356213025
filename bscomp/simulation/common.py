"""The pieces every simulation method shares, each written once: the problem a method receives (model
resolved, grid checked, start point, inputs held on the intervals), the sampled-controller schedule, the
output evaluation, the progress bar and the assembly of the :class:`~.result.SimulationResult`.

Held inputs: input ``u`` is piecewise constant on the output grid ``t``, ``u(t) = U_k`` on
``[t_k, t_{k+1})`` (arrays: the value at the interval start, or one value per interval; callables: the
value at the interval midpoint). A sampled controller (:class:`~.sampled.SampledController`) is updated at
the first grid time at or after each of its sample instants and holds its output until the next one (the
zero-order hold of Eq 4.16); its actuated inputs overwrite the given ones.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import ArgumentTypeError, UnknownNameError, UsageError, check_mapping, check_number
from bscomp.kernel.dae import Dae
from bscomp.kernel.signal_meta import declared_units
from bscomp.model import as_dae, run_overrides
from bscomp.simulation.result import SimulationResult

__all__ = ["SimulationProblem", "SimulationOptions", "prepare", "input_matrix", "SampledLoop",
           "evaluate_outputs", "Progress", "finish"]


@dataclass
class SimulationProblem:
    """What every method receives: the resolved model and one run of it.

    Attributes
    ----------
    dae : Dae
    t : ndarray (nt,)
        Output times, increasing.
    U : ndarray (nu, nt - 1)
        Inputs held on each interval ``[t_k, t_{k+1})`` (:func:`input_matrix`).
    x0 : ndarray (nx,)
        Start states.
    p : ndarray (np,)
        Parameter vector.
    outputs : list of str
        Observables to record (checked to exist).
    controllers : list of SampledController
    progress : bool
        Print a progress bar.
    """

    dae: Dae
    t: np.ndarray
    U: np.ndarray
    x0: np.ndarray
    p: np.ndarray
    outputs: list = field(default_factory=list)
    controllers: list = field(default_factory=list)
    progress: bool = False


@dataclass
class SimulationOptions:
    """The method settings of :func:`bscomp.simulation.simulate` (each method reads the ones it has)."""

    rtol: float = 1e-6
    atol: float = 1e-9
    max_order: int = 2
    max_num_steps: int = 100000
    substeps: int = 1
    newton_iter: int = 2
    jit: bool = False
    modal: dict | None = None

    def fixed_steps(self) -> tuple[int, int]:
        """``(substeps, newton_iter)`` of the fixed-step methods, both at least 1."""
        if int(self.substeps) < 1 or int(self.newton_iter) < 1:
            raise UsageError(f"substeps and newton_iter must be >= 1, got {self.substeps} and {self.newton_iter}")
        return int(self.substeps), int(self.newton_iter)


def prepare(model, t, inputs=None, x0=None, params=None, outputs=None, controllers=None,
            progress=None) -> SimulationProblem:
    """The :class:`SimulationProblem` of a ``simulate`` call (arguments as there).

    The model is anything :func:`bscomp.model.as_dae` takes (a name, ``.py`` path, build function, System,
    Dae or ModelSpec); for a System or Dae, ``params`` are dotted parameter values, for the other forms
    also build keywords (applied when the system is built).
    """
    dae = as_dae(model, params)
    try:
        t = np.asarray(t, float)
    except (TypeError, ValueError):
        raise UsageError(f"t must be an array of times [s], got {type(t).__name__}") from None
    if t.ndim != 1 or len(t) < 2:
        raise UsageError(f"t must be a 1-D array of at least two times, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise UsageError(f"t holds a non-finite time at index {int(np.flatnonzero(~np.isfinite(t))[0])}")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise UsageError(f"t must be strictly increasing: t[{k}] = {t[k]} after t[{k - 1}] = {t[k - 1]}")
    controllers = _controllers(controllers)
    p = dae.parameter_vector(run_overrides(model, dae, params))
    xs = dae.x_start.copy()
    for k, v in check_mapping("x0", x0, "initial state values").items():
        if k not in dae.x_names:
            raise UnknownNameError(f"x0 names '{k}', which is not a state of '{dae.name}' ({dae.x_names[:8]}...)")
        xs[dae.x_names.index(k)] = check_number(f"x0['{k}']", v)
    U = input_matrix(dae, t, inputs, [a for c in controllers for a in c.actuate])
    outputs = [outputs] if isinstance(outputs, str) else list(outputs or [])
    bad = [o for o in outputs if not isinstance(o, str)]
    if bad:
        raise ArgumentTypeError(f"outputs must be names (str), e.g. ['table.s'], got {bad[0]!r}")
    if outputs:
        dae.output_function(outputs)  # unknown output names fail before integrating
    if progress is None:
        progress = len(t) > 200 and sys.stderr.isatty()
    return SimulationProblem(dae, t, U, xs, p, outputs, controllers, bool(progress))


def _controllers(controllers) -> list:
    """``controllers`` as a list of sampled controllers (objects with ``law``, ``Ts``, ``measure``, ``actuate``,
    e.g. from :func:`bscomp.simulation.sampled_controller`), else :class:`ArgumentTypeError` saying so."""
    if controllers is None:
        return []
    what = ("controllers must be a list of SampledController (made by bscomp.simulation.sampled_controller: a "
            "law called every Ts with the measured outputs, returning the actuated inputs)")
    if isinstance(controllers, (str, bytes)) or not hasattr(controllers, "__iter__"):
        controllers = [controllers] if hasattr(controllers, "law") else None
        if controllers is None:
            raise ArgumentTypeError(f"{what}, got {type(controllers).__name__}")
    out = list(controllers)
    for k, c in enumerate(out):
        if not all(hasattr(c, a) for a in ("law", "Ts", "measure", "actuate")) or not callable(c.law):
            raise ArgumentTypeError(f"{what}; controllers[{k}] is {type(c).__name__} {c!r}"[:300])
    return out


HUGE = 1e100  # an input, state or output beyond this is refused: an input in the wrong unit or a runaway (IDAS's
              # IDACalcIC did not return in 120 s on the small drive under a 1e150 N m torque)


def input_matrix(dae, t, inputs, fixed=()):
    """``(nu, nt - 1)`` input values held on each interval ``[t_k, t_{k+1})``.

    ``inputs`` maps input names to a scalar, an array with one value per time point (the interval takes
    its start value) or per interval, or a function of ``t`` (taken at the interval midpoint); the others
    are zero. ``fixed`` are inputs a controller drives (checked to exist).
    """
    nint = len(t) - 1
    U = np.zeros((dae.nu, max(nint, 1)))
    for k, v in check_mapping("inputs", inputs, "input signals").items():
        if k not in dae.u_names:
            raise UnknownNameError(f"'{k}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
        i = dae.u_names.index(k)
        if callable(v):
            U[i] = _input_values(k, v, 0.5 * (t[:-1] + t[1:]))
        else:
            try:
                arr = np.asarray(v, float)
            except (TypeError, ValueError):
                raise UsageError(f"input '{k}' must be a number, an array or a function of t, got {v!r}") from None
            if arr.ndim == 0:
                U[i] = float(arr)
            elif arr.shape == (len(t),):
                U[i] = arr[:-1]
            elif arr.shape == (nint,):
                U[i] = arr
            else:
                raise UsageError(f"input '{k}' has shape {arr.shape}; give one per time point ({len(t)}) or "
                                 f"per interval ({nint}), a scalar, or a function of t")
        if not np.all(np.isfinite(U[i])):
            j = int(np.flatnonzero(~np.isfinite(U[i]))[0])
            raise UsageError(f"input '{k}' is not finite ({U[i, j]}) on the interval starting at t = {t[j]}")
        if np.max(np.abs(U[i]), initial=0.0) > HUGE:
            j = int(np.argmax(np.abs(U[i])))
            raise UsageError(f"input '{k}' = {U[i, j]:.3g} on the interval starting at t = {t[j]:.6g} s is beyond "
                             f"{HUGE:g}: no physical drive takes it (no method would return a meaningful number)",
                             hint="give the input in SI units (N m, V, m) and of a physical size")
    for k in fixed:
        if k not in dae.u_names:
            raise UnknownNameError(f"'{k}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
    return U


def _input_values(name, fn, tm) -> np.ndarray:
    """The input function ``fn`` at the interval midpoints ``tm``: one call with the whole array when ``fn`` is
    written in numpy (the same numbers as point by point, checked at three points), else one call per point
    (~0.4 us each: 2.6 ms of a 6,000-interval run that the modal method finishes in 12 ms)."""
    try:
        with np.errstate(all="ignore"):
            v = np.asarray(fn(tm), float)
    except Exception:  # noqa: BLE001 - a function of one number (`if t < ...`): point by point below
        v = None
    if v is not None and v.shape == tm.shape and np.all(np.isfinite(v)):
        probe = sorted({0, len(tm) // 2, len(tm) - 1})
        if all(np.isclose(v[j], _call_input(name, fn, tm[j]), rtol=1e-12, atol=0.0) for j in probe):
            return v
    return np.array([_call_input(name, fn, tt) for tt in tm])


def _call_input(name, fn, t) -> float:
    """The value of the input function ``fn`` at ``t``: a number, else :class:`UsageError` naming it."""
    try:
        v = fn(t)
    except Exception as exc:  # noqa: BLE001 - the user's function: say which one failed and where
        raise UsageError(f"input '{name}': its function raised {type(exc).__name__} at t = {t:.6g} s: {exc}") from exc
    try:
        return float(v)
    except (TypeError, ValueError):
        raise UsageError(f"input '{name}': its function returned {v!r} at t = {t:.6g} s; it must return a number "
                         "(one input value per call)") from None


class SampledLoop:
    """The sampled controllers of one run: when each is due, what it holds on its actuated inputs.

    A method calls :meth:`sample` at every grid time ``t_k`` where it may stop (a controller due at a
    time between grid points is updated at the next grid point) and :meth:`hold` on the input rows of the
    steps it takes; :attr:`next_time` is where it must stop next.
    """

    def __init__(self, dae, controllers, t0):
        self.controllers = list(controllers)
        self.next = [float(t0) for _ in self.controllers]
        self.held = [None for _ in self.controllers]
        self.columns = [[dae.u_names.index(a) for a in c.actuate] for c in self.controllers]
        names = [m for c in self.controllers for m in c.measure]
        self.offsets = np.cumsum([0] + [len(c.measure) for c in self.controllers])
        self.measured = dae.output_function(names) if names else None

    def __bool__(self):
        return bool(self.controllers)

    @property
    def next_time(self) -> float:
        """The next sample instant of any controller (``inf`` without controllers)."""
        return min(self.next) if self.controllers else np.inf

    def measure(self, xd, x, z, u, p):
        """The measured outputs of all controllers (in their order) at one point."""
        if self.measured is None:
            return np.zeros(0)
        return np.asarray(self.measured(xd, x, z, u, p)).ravel()

    def sample(self, t_k, u_k, y_of):
        """Update the controllers due at ``t_k`` and write every held value into ``u_k`` (in place).

        ``y_of(u_k)`` returns the measured outputs (:meth:`measure`) at ``t_k``; it is called once, when
        the first controller is due.
        """
        y = None
        for ci, c in enumerate(self.controllers):
            if t_k + 1e-12 >= self.next[ci]:
                if y is None:
                    y = y_of(u_k)
                ym = y[self.offsets[ci]:self.offsets[ci + 1]]
                self.held[ci] = np.atleast_1d(np.asarray(c.law(t_k, ym), float))
                while self.next[ci] <= t_k + 1e-12:
                    self.next[ci] += c.Ts
            if self.held[ci] is not None:
                for col, v in zip(self.columns[ci], self.held[ci]):
                    u_k[col] = v
        return u_k

    def hold(self, Uc):
        """Input rows ``Uc`` (steps x nu) with every controller's actuated inputs replaced by its held value."""
        if not self.controllers:
            return Uc
        Uc = Uc.copy()
        for cols, val in zip(self.columns, self.held):
            if val is not None:
                for col, v in zip(cols, val):
                    Uc[:, col] = v
        return Uc


def evaluate_outputs(dae, names, XD, X, Z, Uh, p, chunk=256):
    """Named outputs at every time point: ``{name: (nt,) array}``.

    The output Function is mapped over chunks of time points and called through zero-copy buffers on
    the (nt, n) arrays (CasADi is column-major, so their rows are its columns); converting large arrays
    to and from DM costs ~0.1 µs per number, which would dominate a fast run.
    """
    if not names:
        return {}
    Y = evaluate_mapped(dae, ("outmap", tuple(names)), lambda: dae.output_function(names), (XD, X, Z, Uh), p, chunk)
    return {name: Y[:, i].copy() for i, name in enumerate(names)}


def evaluate_mapped(dae, key, build, data, p, chunk=256):
    """``f(d_1[k], ..., d_n[k], p)`` for every row k of the (nt, ·) arrays ``data``: ``(nt, n_out)``.

    ``build()`` makes the Function (one dense column output); its map over ``min(chunk, nt)`` points is cached
    on the Dae under ``key``, and called through zero-copy buffers (see :func:`evaluate_outputs`). Building the
    map costs about linearly in its width (an output of the moving-nut bed: 3.2 ms for 1,000 points, 1.2 ms for
    256), the calls only a few microseconds each: hence the narrow default."""
    data = [np.ascontiguousarray(a, dtype=float) for a in data]
    nt = data[0].shape[0]
    n = min(chunk, nt)
    mkey = key + (n,)
    if mkey not in dae._cache:
        dae._cache[mkey] = build().map("ymap", "serial", n, [len(data)], [])
    fm = dae._cache[mkey]
    pc = np.ascontiguousarray(p, dtype=float)
    ny = fm.size1_out(0)
    Y = np.zeros((nt, ny))
    buf, ev = fm.buffer()
    buf.set_arg(len(data), memoryview(pc))
    starts = list(range(0, nt - n + 1, n))
    if starts[-1] + n < nt:
        starts.append(nt - n)  # last chunk overlaps the previous one: no padding needed
    ys = np.zeros((n, ny))
    buf.set_res(0, memoryview(ys.reshape(-1)))
    for k in starts:
        for i, a in enumerate(data):
            buf.set_arg(i, memoryview(a[k:k + n].reshape(-1)))
        ev()
        Y[k:k + n] = ys
    return Y


class Progress:
    """The progress bar of one run on stderr: one overwritten line, updated every ``every`` calls of the
    method's stepping kernel and at the end (then a newline)."""

    def __init__(self, name, t, enabled, every=20):
        self.name, self.t, self.enabled, self.every = name, t, bool(enabled), int(every)

    def update(self, calls, k):
        """After ``calls`` kernel calls the run has reached grid index ``k``."""
        last = len(self.t) - 1
        if self.enabled and (calls % self.every == 0 or k == last):
            frac = k / last
            sys.stderr.write(f"\r  simulating '{self.name}' [{'#' * int(30 * frac):<30}] {100 * frac:5.1f}%  "
                             f"t = {self.t[k]:.4g} s")
            if frac >= 1.0:
                sys.stderr.write("\n")


def result_units(dae, outputs) -> dict:
    """:attr:`SimulationResult.units`: the declared unit of each output and input of ``dae`` that has one."""
    return declared_units(dae, [*outputs, *dae.u_names])


def finish(problem, X, XD, Z, Uh, stats, t_wall) -> SimulationResult:
    """The :class:`SimulationResult` of a run: the outputs evaluated, ``wall_s`` (from ``t_wall``, a
    ``time.perf_counter()`` reading) and ``real_time_factor`` added to the method's ``stats``."""
    dae, t = problem.dae, problem.t
    out = evaluate_outputs(dae, problem.outputs, XD, X, Z, Uh, problem.p)
    wall = time.perf_counter() - t_wall
    stats = {"wall_s": wall, **stats, "real_time_factor": (t[-1] - t[0]) / wall if wall > 0 else np.inf}
    return SimulationResult(t=t, x=X, xd=np.ascontiguousarray(XD), z=np.ascontiguousarray(Z), u=Uh,
                            x_names=list(dae.x_names), z_names=list(dae.z_names), u_names=list(dae.u_names),
                            outputs=out, stats=stats, units=result_units(dae, out))
