r"""Design sweeps on any ``concurrent.futures.Executor``: parameters x nut position -> a tidy table.

:func:`design_study` evaluates one analysis for every variant of a grid (a full factorial ``{name: values}``
or an explicit list of ``{name: value}`` variants, e.g. a tolerance Monte Carlo) and returns a
:class:`SweepTable`, one row per variant, one column per parameter and result.

What travels to a worker is the picklable :class:`bscomp.model.ModelSpec` ``(name or path, overrides)``
plus chunks of parameter values -- never compiled CasADi objects. Each worker process builds the model
once per spec and swept names and keeps it (module-level cache), so a chunk costs its variants only:

* **modes** (built in, and the other built-ins' basis): flatten once; every swept parameter is
  classified once by measuring the second-order matrices at two more values: *affine* (bearing and
  coupling stiffness, masses: ``X(p) = X_0 + \sum_i \Delta X_i (p_i - p_{i0})`` for ``X`` in ``M, K``,
  structural ``C``, ``B`` and the output maps, verified at a third value to 1e-8), a *position* with an
  exact component tangent (``sn.z0`` of the moving nut joint, :meth:`bscomp.Component.tangent`), or
  *direct* (anything else, e.g. the build keyword ``nut_position``: re-flattened per variant, slow but
  exact). A variant then costs one symmetric eigen-decomposition of the 98-coordinate test bed (~3 ms)
  instead of a flattening (~0.4 s). The system damping (modal, Eq A.10-A.15) is re-derived from each
  variant's modes, as flattening does.
* **frf**: peak magnitude and frequency of every output/input pair at ``freqs`` from the same modes
  (:func:`bscomp.linear.frf_engine.modal_frf`).
* a **callable** ``analysis(spec) -> dict`` (module-level, picklable): anything else, e.g. closed-loop
  margins (:mod:`bscomp.control`) or a simulation metric (:func:`bscomp.simulate`); it receives the
  variant's ModelSpec and pays its own build.

Executors: ``executor=None`` runs on a local :class:`~concurrent.futures.ProcessPoolExecutor` (``workers``
processes, default the CPU count; serial when 1), ``executor="serial"`` in this process, or any object
with ``submit`` -- e.g. ``distributed.Client(...).get_executor()`` for a Dask cluster. Rows come back in
grid order whatever ran them. See ``docs/sweeps.md``.
"""

from __future__ import annotations

import itertools
import json
import os
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from bscomp._sweep_eval import ModesEvaluator
from bscomp.errors import (
    ArgumentTypeError,
    BscompError,
    ParameterError,
    UnknownNameError,
    UsageError,
    check_names,
    check_number,
)
from bscomp.files import atomic_path, atomic_write
from bscomp.kernel.system import System
from bscomp.linear.sweeps import check_count
from bscomp.memo import kept
from bscomp.model import ModelSpec, spec_of
from bscomp.plotting.sweep_map import sweep_map

__all__ = ["design_study", "SweepTable"]

_CACHE: dict = {}
"""Per process: (spec, swept names, inputs, outputs) -> _Evaluator (what a worker keeps between chunks)."""


@dataclass
class SweepTable:
    """One row per variant: the swept parameters, then the results.

    Attributes
    ----------
    columns : list of str
    data : ndarray (n_variants, n_columns)
    parameters : list of str
        The swept names (the first columns).
    stats : dict
        ``wall_s``, ``variants_per_s``, ``executor``, ``kinds`` (how each parameter was evaluated).
    """

    columns: list
    data: np.ndarray
    parameters: list
    name: str = ""
    stats: dict = field(default_factory=dict)

    def __len__(self):
        return self.data.shape[0]

    def __getitem__(self, column) -> np.ndarray:
        if column not in self.columns:
            raise UnknownNameError(f"no column '{column}' in this sweep; columns: {self.columns}")
        return self.data[:, self.columns.index(column)]

    def rows(self) -> list:
        """The rows as dicts."""
        return [dict(zip(self.columns, map(float, r))) for r in self.data]

    def to_csv(self, path) -> None:
        """Write a CSV file with a header row (atomic: complete or absent)."""
        with atomic_path(path, what="SweepTable.to_csv: path", suffixes=(".csv",)) as tmp:
            np.savetxt(tmp, self.data, delimiter=",", header=",".join(self.columns), comments="", fmt="%.17g")

    def to_json(self, path=None) -> str:
        """JSON ``{"columns", "rows", "parameters", "stats"}`` (NaN as null); written to ``path`` if given."""
        rows = [[None if not np.isfinite(v) else float(v) for v in r] for r in self.data]
        text = json.dumps({"name": self.name, "parameters": self.parameters, "columns": self.columns, "rows": rows,
                           "stats": self.stats}, indent=1)
        if path is not None:
            with atomic_write(path, what="SweepTable.to_json: path", suffixes=(".json",)) as f:
                f.write(text)
        return text

    def to_pandas(self):
        """A ``pandas.DataFrame`` (needs pandas)."""
        try:
            import pandas as pd
        except ImportError as exc:
            raise UsageError("SweepTable.to_pandas needs pandas (pip install pandas); to_csv / to_json / rows() "
                             "work without it") from exc
        return pd.DataFrame(self.data, columns=self.columns)

    def grid(self, x: str, y: str, value: str):
        """``(xs, ys, Z)`` with ``Z[j, i]`` the value at ``(xs[i], ys[j])``, for a full factorial over x and y
        (other swept parameters must have one value)."""
        xs, ys = np.unique(self[x]), np.unique(self[y])
        Z = np.full((ys.size, xs.size), np.nan)
        Z[np.searchsorted(ys, self[y]), np.searchsorted(xs, self[x])] = self[value]
        return xs, ys, Z

    def plot_map(self, x: str, y: str, value: str = "f1", path=None, title=None, labels: dict | None = None):
        """Filled contour map of ``value`` over two swept parameters (e.g. the first-mode frequency);
        ``labels`` maps column names to axis labels (``{"b1.k_axial": "thrust bearing k [N/m]"}``)."""
        lab = {x: x, y: y, value: value, **(labels or {})}
        xs, ys, Z = self.grid(x, y, value)
        return sweep_map(xs, ys, Z, lab[x], lab[y], lab[value], title=title or self.name, path=path)


def _variants(grid) -> tuple[list, list]:
    """(names, list of raw value tuples) of a factorial dict or an explicit list of dicts (values as given:
    numbers or ``"250 kg"``-style strings, converted by :func:`_checked_variants`)."""
    if isinstance(grid, dict):
        names = list(grid)
        axes = [np.atleast_1d(np.asarray(grid[n], dtype=object)) for n in names]
        if not names or any(a.size == 0 for a in axes):
            raise UsageError("design_study: grid must map each parameter name to at least one value")
        deep = [n for n, a in zip(names, axes) if a.ndim != 1]
        if deep:
            raise UsageError(f"design_study: grid['{deep[0]}'] must be a flat list of values, got an array of shape "
                             f"{axes[names.index(deep[0])].shape}")
        return names, list(itertools.product(*[a.tolist() for a in axes]))
    variants = list(grid)
    if not variants or not all(isinstance(v, dict) for v in variants):
        raise UsageError("design_study: grid must be {name: values} (full factorial) or a list of {name: value}")
    names = list(variants[0])
    bad = [i for i, v in enumerate(variants) if list(v) != names]
    if bad:
        raise UsageError(f"design_study: variant {bad[0]} has the keys {list(variants[bad[0]])}, the first "
                         f"{names}: give every variant the same parameters")
    return names, [tuple(v[n] for n in names) for v in variants]


def _checked_variants(spec: ModelSpec, names: list, raw: list) -> list:
    """The variants as float tuples, each value checked as ``modes(params=...)`` would check it.

    A dotted name's value goes through its parameter's :meth:`~bscomp.Parameter.validate` (bounds, NaN,
    ``"250 kg"`` strings converted to the declared unit), then each component with a swept parameter gets its
    cross-parameter conditions checked (:meth:`~bscomp.Component.check`: ``lead != 0``, ``y_min < y_max``,
    the moving nut's ``z0`` on the screw) on the variant's values. A build keyword (no dot) must be a number;
    the build function checks it when the variant is built. Raises :class:`~bscomp.errors.ParameterError`
    naming the variant and the parameter before anything is computed.
    """
    system = spec.system() if any("." in n for n in names) else None
    params = {}
    for n in names:
        if "." in n:
            path, _, pname = n.rpartition(".")
            comp = system.component(path)
            param = None if isinstance(comp, System) else comp.parameters().get(pname.partition("[")[0])
            if param is None:
                raise UnknownNameError(f"design_study: '{spec.source}' has no parameter '{n}' (build keywords have "
                                       "no dot, e.g. nut_position)")
            if not param.scalar and "[" not in pname:
                raise UsageError(f"design_study: '{n}' [{param.unit}] is a vector or matrix parameter; a grid sweeps "
                                 "numbers: sweep a scalar parameter or a build keyword")
            params[n] = (path, pname, comp, param)
    out = []
    for k, row in enumerate(raw):
        vals, per_comp = [], {}
        try:
            for n, v in zip(names, row):
                if n in params:
                    path, pname, comp, param = params[n]
                    x = param.validate(v, comp)
                    if "[" not in pname:
                        per_comp.setdefault(path, (comp, {}))[1][pname] = x
                else:
                    x = check_number(f"build keyword {n}", v)
                vals.append(float(x))
            for comp, over in per_comp.values():
                comp.check({**comp._values, **over})
        except (ParameterError, UsageError) as exc:
            raise type(exc)(f"design_study: variant {k} {dict(zip(names, row))}: {exc}") from None
        out.append(tuple(vals))
    return out


def _checked_freqs(freqs) -> np.ndarray:
    """The ``"frf"`` frequency grid [Hz]: a non-empty 1-D array of finite positive numbers."""
    try:
        f = np.atleast_1d(np.asarray(np.logspace(0, np.log10(2000), 400) if freqs is None else freqs, float))
    except (TypeError, ValueError):
        raise UsageError(f"design_study: freqs must be an array of frequencies [Hz], got {freqs!r}") from None
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        bad = f[~np.isfinite(f) | (f <= 0)] if f.ndim == 1 and f.size else []
        raise UsageError("design_study: freqs must be a non-empty 1-D array of finite positive frequencies [Hz]"
                         + (f", got {float(bad[0])!r}" if len(bad) else f", got shape {f.shape}"))
    return f


def design_study(model, grid, analysis="modes", *, n_modes: int = 6, inputs=None, outputs=None, freqs=None,
                 executor=None, workers: int | None = None, chunksize: int | None = None) -> SweepTable:
    """Evaluate an analysis for every variant of a parameter grid (see the module docstring).

    Parameters
    ----------
    model : str, path or ModelSpec
        The drive as a registered name, a ``.py`` path or a :class:`~bscomp.model.ModelSpec` (its overrides
        apply to every variant). A System built in memory cannot travel to a worker: pass its name.
    grid : dict or list of dict
        ``{name: values}`` for the full factorial (first name slowest), or explicit variants. Names are
        dotted parameters (``b1.k_axial``, ``sn.z0``) or build keywords (``nut_position``, re-flattened).
    analysis : {"modes", "frf"} or callable
        ``"modes"``: columns ``f1..fn`` [Hz] (elastic modes) and ``zeta1..n``. ``"frf"``: ``peak[o/i]`` and
        ``f_peak[o/i]`` [Hz] per output/input pair over ``freqs``. A callable ``analysis(spec) -> dict`` of
        numbers with the same keys for every variant (picklable for workers); an error it raises is reported
        with the variant.
    n_modes : int
        Elastic modes reported by ``"modes"`` (>= 1).
    inputs, outputs : list of str, optional
        For ``"frf"`` (default: the system's declared measured inputs/outputs, else all inputs and
        coordinates).
    freqs : array_like, optional
        Frequencies [Hz] for ``"frf"`` (default 400 log-spaced points 1 Hz - 2 kHz).
    executor : None, "serial" or concurrent.futures.Executor
        None: a local process pool with ``workers`` processes (serial when ``workers == 1``).
    workers : int, optional
        Local pool size, >= 1 (default the CPU count).
    chunksize : int, optional
        Variants per task, >= 1 (default: about 4 tasks per worker, at most 500).

    Returns
    -------
    SweepTable

    Raises
    ------
    UsageError, ArgumentTypeError
        A bad grid, analysis, count (``n_modes``, ``workers``, ``chunksize``) or frequency, or a callable that
        fails or returns something else than a dict of numbers (named, with the variant).
    UnknownNameError
        An unknown parameter, input or output, or an output that is a parameter or a constant.
    """
    t0 = time.perf_counter()
    spec = spec_of(model)
    names, raw = _variants(grid)
    if not callable(analysis) and analysis not in ("modes", "frf"):
        raise UsageError(f"design_study: analysis must be 'modes', 'frf' or a callable, got {analysis!r}")
    freqs = None if analysis != "frf" else _checked_freqs(freqs)
    n_modes = check_count("n_modes", n_modes, "design_study", allow_none=False)
    workers = check_count("workers", workers, "design_study")
    chunksize = check_count("chunksize", chunksize, "design_study")
    inputs, outputs = check_names("inputs", inputs), check_names("outputs", outputs)
    values = _checked_variants(spec, names, raw)
    job = (spec, tuple(names), analysis, n_modes, None if inputs is None else tuple(inputs),
           None if outputs is None else tuple(outputs), None if freqs is None else tuple(freqs))
    own_pool, label = None, ""
    if executor is None:
        workers = (os.cpu_count() or 1) if workers is None else workers
        if workers > 1 and len(values) > 1:
            from concurrent.futures import ProcessPoolExecutor

            own_pool = executor = ProcessPoolExecutor(max_workers=workers)
            label = f"ProcessPoolExecutor({workers})"
    elif executor != "serial" and not hasattr(executor, "submit"):
        raise UsageError(f"design_study: executor must be None, 'serial' or a concurrent.futures.Executor (with "
                         f"submit), got {executor!r}")
    try:
        if executor is None or executor == "serial":
            label = "serial"
            chunks = [_run_chunk(job, values)]
        else:
            label = label or type(executor).__name__
            n_workers = workers or _executor_workers(executor)
            size = chunksize or max(1, min(500, -(-len(values) // (4 * n_workers))))
            futures = [executor.submit(_run_chunk, job, values[i:i + size], i)
                       for i in range(0, len(values), size)]
            chunks = [f.result() for f in futures]
    finally:
        if own_pool is not None:
            own_pool.shutdown()
    for k, (cols, _, _) in enumerate(chunks):
        if cols != chunks[0][0]:
            start = sum(len(c[1]) for c in chunks[:k])
            raise UsageError(f"design_study: the analysis returned the keys {cols} for variant {start} "
                             f"{dict(zip(names, values[start]))}, but {chunks[0][0]} for variant 0: it must return "
                             "the same keys for every variant")
    columns = names + chunks[0][0]
    rows = [r for (_, rs, _) in chunks for r in rs]
    data = np.array([list(v) + r for v, r in zip(values, rows)], float)
    wall = time.perf_counter() - t0
    kinds = chunks[0][2]
    return SweepTable(columns=columns, data=data, parameters=names, name=spec.source,
                      stats={"wall_s": wall, "variants": len(values), "variants_per_s": len(values) / wall,
                             "executor": label, "kinds": kinds})


def _executor_workers(executor) -> int:
    for attr in ("_max_workers",):
        if getattr(executor, attr, None):
            return int(getattr(executor, attr))
    client = getattr(executor, "_client", None)
    if client is not None:
        try:
            return max(1, len(client.scheduler_info()["workers"]))
        except Exception:  # noqa: BLE001 - a count is only for the chunk size
            pass
    return os.cpu_count() or 1


def _run_chunk(job, values, start=0):
    """One task, in this process or a worker: ``(result columns, rows, parameter kinds)``; ``start`` is the
    index of the first of ``values`` in the grid (for the messages)."""
    spec, names, analysis, n_modes, inputs, outputs, freqs = job
    with threadpool_limits(limits=1, user_api="blas"):
        if callable(analysis):
            return _run_callable(analysis, spec, names, values, start)
        ev = kept(_CACHE, (spec, names, inputs, outputs), lambda: ModesEvaluator(spec, names, inputs, outputs), 8)
        if analysis == "modes":
            cols = [f"f{i + 1}" for i in range(n_modes)] + [f"zeta{i + 1}" for i in range(n_modes)]
            return cols, [ev.modes_row(dict(zip(names, v)), n_modes) for v in values], ev.kinds
        pairs = [f"{o}/{i}" for o in ev.outputs for i in ev.inputs]
        cols = [f"peak[{p}]" for p in pairs] + [f"f_peak[{p}]" for p in pairs]
        f = np.asarray(freqs, float)
        return cols, [ev.frf_row(dict(zip(names, v)), f) for v in values], ev.kinds


def _run_callable(analysis, spec, names, values, start):
    """``(columns, rows, {})`` of a user's ``analysis(spec) -> dict`` over ``values``, every result checked: a dict
    of numbers with the keys of the first variant; a failure names the variant."""
    cols, rows = None, []
    what = getattr(analysis, "__name__", "analysis")
    for k, v in enumerate(values, start):
        variant = f"variant {k} {dict(zip(names, v))}"
        try:
            r = analysis(spec.with_overrides(dict(zip(names, v))))
        except BscompError as exc:
            raise _with_context(exc, f"design_study: the analysis {what!r} failed on {variant}: {exc}") from exc
        except Exception as exc:
            raise UsageError(f"design_study: the analysis {what!r} raised {type(exc).__name__} on {variant}: "
                             f"{exc}") from exc
        if not isinstance(r, dict) or not r:
            raise ArgumentTypeError(f"design_study: the analysis {what!r} must return a non-empty dict of numbers "
                                    f"({{'name': value}}), got {type(r).__name__} {r!r} on {variant}"[:400])
        if cols is None:
            cols = [str(c) for c in r]
        if [str(c) for c in r] != cols:
            raise UsageError(f"design_study: the analysis {what!r} returned the keys {list(r)} on {variant}, but "
                             f"{cols} before: it must return the same keys for every variant")
        bad = {c: x for c, x in r.items() if isinstance(x, (bool, str, bytes)) or not np.isscalar(x)
               or not isinstance(x, (int, float, np.number))}
        if bad:
            raise ArgumentTypeError(f"design_study: the analysis {what!r} must return numbers, got {bad!r} on "
                                    f"{variant}"[:400])
        rows.append([float(x) for x in r.values()])
    return cols, rows, {}


def _with_context(exc: BscompError, message: str) -> BscompError:
    """``exc``'s class with ``message`` (and its hint), or a :class:`UsageError` when that class cannot be
    made from a message alone."""
    try:
        new = type(exc)(message)
    except Exception:  # noqa: BLE001 - an error class with other constructor arguments
        new = UsageError(message)
    if getattr(exc, "hint", None):
        new.hint = exc.hint
    return new


def model_spec(model, overrides: dict | None = None) -> ModelSpec:
    """The ModelSpec of a name, path or spec with overrides (what :func:`design_study` sends to workers)."""
    return spec_of(model, overrides)
