"""The one way to turn "a model" into what an analysis needs.

Every analysis (``modes``, ``frf``, ``simulate``, ``Ocp``, ``compare``, ``diagnose``, sweeps) accepts the
same things for its model argument:

* a registered system name (``"testbed_axial_torsional"``, see ``bscomp systems``),
* a path to a ``.py`` file that defines ``build()`` returning a :class:`~bscomp.System`,
* a build function (called with the build keywords),
* a :class:`~bscomp.System`, or a flattened :class:`~bscomp.Dae`,
* a :class:`ModelSpec`.

:func:`build_keywords` says which build keywords a model takes (read from the build function's source,
or from a ``.py`` file's syntax tree without running it), so every analysis drops or honours an
operating condition the same way.

:class:`ModelSpec` is the picklable pair ``(name or path, overrides)``: what travels to a worker process
(or a Dask worker) so that it rebuilds the drive itself instead of receiving compiled CasADi objects.
Override keys without a dot (``nut_position``) are keyword arguments of the build function (structural
choices fixed at construction); dotted keys (``coupling.k_T``) are parameter values set with
:meth:`System.set`.

This module is the only place in the engine that reaches ``bscomp.systems`` (lazily, for names).
"""

from __future__ import annotations

import ast
import inspect
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bscomp.errors import BscompError, UnknownNameError, check_mapping
from bscomp.kernel.dae import Dae
from bscomp.kernel.flattening import flatten
from bscomp.kernel.mechanics import start_matrices
from bscomp.kernel.system import System

__all__ = ["ModelSpec", "as_system", "as_dae", "resolve_model", "run_overrides", "spec_of", "split_overrides",
           "model_name", "build_keywords"]


def split_overrides(overrides: dict | None) -> tuple[dict, dict]:
    """``(build keywords, dotted parameter values)`` of an override mapping."""
    overrides = dict(overrides or {})
    return ({k: v for k, v in overrides.items() if "." not in k},
            {k: v for k, v in overrides.items() if "." in k})


@dataclass(frozen=True)
class ModelSpec:
    """A drive as ``(registered name or .py path, overrides)``: picklable, hashable, rebuilt on demand.

    Parameters
    ----------
    source : str
        A registered system name (``bscomp.systems.available()``) or a path to a ``.py`` file defining
        ``build()``.
    overrides : dict, optional
        Build keywords (no dot, e.g. ``nut_position``) and parameter values (dotted, e.g.
        ``"coupling.k_T"``; numbers or ``"250 kg"``-style strings).

    Examples
    --------
    >>> spec = ModelSpec("small_drive", {"table.m": 50.0})
    >>> spec.system().name
    'small_drive'
    """

    source: str
    overrides: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.source, str) or not self.source:
            raise UnknownNameError(f"ModelSpec.source must be a system name or a .py path, got {self.source!r}")
        object.__setattr__(self, "overrides", dict(self.overrides or {}))

    def __hash__(self):
        return hash((self.source, tuple(sorted((k, repr(v)) for k, v in self.overrides.items()))))

    def with_overrides(self, overrides: dict | None = None, **more) -> ModelSpec:
        """A new spec with these overrides added (later keys win)."""
        return ModelSpec(self.source, {**self.overrides, **(overrides or {}), **more})

    def system(self) -> System:
        """Build the System (registered name or ``.py`` file) and apply the overrides."""
        from bscomp.systems import get  # lazily: the engine itself never needs the drives

        return get(self.source, self.overrides)

    def dae(self) -> Dae:
        """Build and flatten."""
        return flatten(self.system())


def as_system(model, params: dict | None = None) -> System:
    """A :class:`System` from a name, ``.py`` path, :class:`ModelSpec`, build function or System.

    ``params`` are overrides: for a name, path, spec or build function, keys without a dot are build
    keywords; for a System every key must be a dotted parameter (applied to a copy).
    """
    params = check_mapping("params", params, "parameter overrides")
    if isinstance(model, System):
        build_kw, dotted = split_overrides(params)
        if build_kw:
            raise UnknownNameError(f"overrides {sorted(build_kw)} are build keywords, but the model was given as a "
                                   f"built System '{model.name}': pass its name or build function to use them")
        return model.with_parameters(dotted) if dotted else model
    if isinstance(model, ModelSpec):
        return model.with_overrides(params).system()
    if isinstance(model, (str, Path)):
        return ModelSpec(str(model), params or {}).system()
    if isinstance(model, Dae):
        if model.system is None:
            raise UnknownNameError(f"the Dae '{model.name}' keeps no System: pass the System or its name")
        return as_system(model.system, params)
    if callable(model):
        from bscomp.systems import _call_build  # one implementation of "name the bad build keyword"

        build_kw, dotted = split_overrides(params)
        system = _call_build(model, getattr(model, "__name__", "build"), build_kw)
        if not isinstance(system, System):
            raise UnknownNameError(f"build function {getattr(model, '__name__', model)!r} returned "
                                   f"{type(system).__name__}, not a bscomp.System")
        return system.with_parameters(dotted) if dotted else system
    raise UnknownNameError(f"cannot use {type(model).__name__} as a model: give a system name, a .py path, a "
                           "build function, a bscomp.System, a bscomp.Dae or a bscomp.model.ModelSpec")


def as_dae(model, params: dict | None = None, *, damping_refreshed: bool = False) -> Dae:
    """A flattened :class:`Dae` from anything :func:`as_system` takes, or a Dae.

    A Dae is returned as is unless the overrides are structural (re-mesh) or change a parameter its
    system-level damping depends on (then it is re-flattened from its System); callers that re-derive
    that damping themselves (``second_order``) pass ``damping_refreshed``.
    """
    if isinstance(model, (System, Dae)):
        return resolve_model(model, params, damping_refreshed=damping_refreshed)
    return flatten(as_system(model, params))


def spec_of(model, params: dict | None = None) -> ModelSpec:
    """The picklable :class:`ModelSpec` of a name, path or spec (with ``params`` added).

    A System or Dae built in memory has no such pair; it raises, naming what to pass instead.
    """
    if isinstance(model, ModelSpec):
        return model.with_overrides(params)
    if isinstance(model, (str, Path)):
        return ModelSpec(str(model), params or {})
    raise UnknownNameError(f"a {type(model).__name__} cannot travel to a worker: pass the system's registered "
                           "name or .py path (with overrides) instead, e.g. ModelSpec('testbed_axial_torsional', "
                           "{'nut_position': 0.3})")


def model_name(model) -> str:
    """A display name for any accepted model."""
    if isinstance(model, ModelSpec):
        return model.source
    if isinstance(model, (str, Path)):
        return str(model)
    return getattr(model, "name", None) or getattr(model, "__name__", type(model).__name__)


def resolve_model(model, params: dict | None = None, *, damping_refreshed: bool = False) -> Dae:
    """A Dae from a System or Dae, with parameter overrides applied (re-flattening if structural).

    A Dae with a system-level damping (modal/Rayleigh, computed from the modes at flattening) is also
    re-flattened when the overrides change its parameter values, since its damping matrix follows the
    modes; callers that re-derive the damping themselves (``second_order``) pass ``damping_refreshed``.
    """
    params = check_mapping("params", params, "parameter overrides")
    if isinstance(model, System):
        return flatten(model.with_parameters(params) if params else model)
    if isinstance(model, Dae):
        structural = [k for k in params if k in model.structural_parameters]
        stale = (not damping_refreshed and getattr(model, "system_damping", None) is not None and params
                 and not np.array_equal(model.parameter_vector(params), model.parameter_vector({}))
                 and _damping_basis_changed(model, params))
        if structural or stale:
            if model.system is None:
                why = (f"parameters {structural} are structural" if structural else
                       "its system damping depends on the parameters")
                raise UnknownNameError(f"{why} and the Dae has no system to re-flatten; pass the System instead")
            return flatten(model.system.with_parameters(params))
        return model
    return as_dae(model, params)


def run_overrides(model, dae: Dae, params: dict | None) -> dict:
    """The overrides a run on ``dae = as_dae(model, params)`` still applies through its parameter vector: the
    non-structural ones of a System or Dae (a Dae keeps its flattening's ``p0``); none for the other forms and
    none structural (building or re-flattening put those in ``p0``). ``dae.parameter_vector(run_overrides(...))``
    is the run's ``p``."""
    own = (params or {}) if isinstance(model, (System, Dae)) else {}
    return {k: v for k, v in own.items() if k not in dae.structural_parameters}


def _damping_basis_changed(dae: Dae, params: dict) -> bool:
    """True when the overrides change the start point's ``(M, K)`` the system damping was computed from
    (``dae.system_damping_basis``): a friction force, a controller gain or a motor constant leaves the modes
    and so the damping as they are, and the Dae is used as is (no re-flattening: ~0.7 s on the FE test bed)."""
    M0, K0, _ = dae.system_damping_basis
    try:
        M, K = start_matrices(dae, {k: v for k, v in params.items() if k not in dae.structural_parameters})
    except (BscompError, ArithmeticError, ValueError, RuntimeError):
        return True                                   # cannot tell: re-flatten (the safe side)

    def same(A, B):
        D = abs(A - B)
        return D.nnz == 0 or D.max() <= 1e-13 * max(abs(B).max(), 1e-300)

    return not (same(M, M0) and same(K, K0))


# ---- which build keywords a model takes -------------------------------------------------------------------
def build_keywords(model) -> set | None:
    """Keyword arguments the build function of ``model`` accepts; None when it may accept any.

    Parameters
    ----------
    model : str, callable, ModelSpec, System or Dae
        A registered system name or ``.py`` path (the file's ``build`` is read from its syntax tree, not
        run), a build function, or a spec (its source). A built System or Dae takes none (empty set).

    Notes
    -----
    A build function taking ``**kwargs`` that forwards them to exactly one other function it can name
    (the test bed's ``testbed_axial_torsional(**kw)`` calls ``testbed("axial_torsional", **kw)``) takes
    that function's keyword arguments, minus those the call fills itself (followed up to four levels).

    Examples
    --------
    >>> sorted(build_keywords("validation_drive"))
    ['k_axial']
    """
    if isinstance(model, (System, Dae)):
        return set()
    if isinstance(model, ModelSpec):
        model = model.source
    if isinstance(model, Path):
        model = str(model)
    if isinstance(model, str):
        from bscomp.systems import REGISTRY  # lazily: a registered name

        if model not in REGISTRY:
            return _file_build_keywords(model)
        model = REGISTRY[model]
    node = _function_node(model)
    if node is None:                     # no Python source (a builtin, a C function): the signature only
        try:
            params = inspect.signature(model).parameters.values()
        except (TypeError, ValueError):
            return None
        if any(p.kind is p.VAR_KEYWORD for p in params):
            return None
        return {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return _node_keywords(node, _resolver(model))


def _function_node(fn):
    """The ``def`` of a Python function, from its source; None when unavailable."""
    fn = inspect.unwrap(fn) if callable(fn) else fn
    if not inspect.isfunction(fn):
        return None
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    except (OSError, TypeError, SyntaxError):
        return None
    node = tree.body[0] if tree.body else None
    return node if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else None


def _resolver(fn):
    """Name -> (def node, resolver) for the module-level functions ``fn`` can call."""
    scope = getattr(inspect.unwrap(fn), "__globals__", {})

    def resolve(name):
        target = scope.get(name)
        node = _function_node(target) if target is not None else None
        return (node, _resolver(target)) if node is not None else None

    return resolve


def _file_build_keywords(path: str) -> set | None:
    """Keywords of ``build`` in a system file, read from its syntax tree (the file is not run)."""
    try:
        tree = ast.parse(Path(path).read_text())
    except (OSError, SyntaxError, UnicodeDecodeError):
        return None                      # building it reports the problem
    defs = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}

    def resolve(name):
        return (defs[name], resolve) if name in defs else None

    return _node_keywords(defs["build"], resolve) if "build" in defs else None


def _node_keywords(node, resolve, depth: int = 0) -> set | None:
    """Keywords a ``def`` accepts; ``**kwargs`` forwarded to exactly one resolvable function add that
    function's keywords (minus those the call fills itself); None when any name may be accepted."""
    a = node.args
    names = {x.arg for x in a.args + a.kwonlyargs}
    if a.kwarg is None:
        return names
    calls = [c for c in ast.walk(node) if isinstance(c, ast.Call) and any(
        k.arg is None and isinstance(k.value, ast.Name) and k.value.id == a.kwarg.arg for k in c.keywords)]
    if depth >= 4 or len(calls) != 1 or not isinstance(calls[0].func, ast.Name) \
            or any(isinstance(x, ast.Starred) for x in calls[0].args):
        return None
    target = resolve(calls[0].func.id)
    if target is None:
        return None
    inner = _node_keywords(target[0], target[1], depth + 1)
    if inner is None:
        return None
    positional = [x.arg for x in target[0].args.posonlyargs + target[0].args.args]
    filled = set(positional[:len(calls[0].args)]) | {k.arg for k in calls[0].keywords if k.arg}
    return names | (inner - filled)
