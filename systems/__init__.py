"""Drives composed from components (``bscomp.systems``).

Each system is a function returning a :class:`bscomp.System`; :func:`get` builds one by name with
parameter overrides, so ``(name, overrides)`` is all a worker process needs to rebuild it.
"""

from __future__ import annotations

import contextlib
import importlib.util
import inspect
import traceback
from pathlib import Path

from bscomp.errors import BscompError, ModelDefinitionError, ParameterError, UnknownNameError
from bscomp.kernel.system import System

from .chain import free_chain, friction_oscillator, mass_spring_chain  # noqa: E402
from .small_drive import small_drive  # noqa: E402
from .validation_drive import validation_drive  # noqa: E402

REGISTRY = {
    "small_drive": small_drive,
    "validation_drive": validation_drive,
}

# ---- the thesis test bed (systems/testbed.py): one entry per verification step / model variant ------------
from .testbed import (  # noqa: E402
    testbed_appendix_c,
    testbed_axial_torsional,
    testbed_bellows,
    testbed_free_screw,
    testbed_full,
    testbed_no_table,
    testbed_screw_nut,
    testbed_submodel1,
)


class LazyBuilder:
    """A registered build function in a module imported only when the drive is built: builders that use an analysis
    (the CMS-reduced test bed needs :mod:`bscomp.linear`) are registered by module path, so importing
    ``bscomp.systems`` never imports an analysis (which reaches this registry through :mod:`bscomp.model`)."""

    def __init__(self, module: str, name: str, doc: str):
        self.module, self.name, self.__doc__ = module, name, doc

    def load(self):
        return getattr(importlib.import_module(self.module), self.name)

    def __call__(self, *args, **kwargs):
        return self.load()(*args, **kwargs)

    @property
    def __signature__(self):
        return inspect.signature(self.load())


testbed_reduced = LazyBuilder("bscomp.systems.reduced_testbed", "testbed_reduced",
                              "CMS-reduced axial + torsional test bed with the moving nut (Sec 5.2.3/5.3.2: 6 + 2 "
                              "coordinates).")

REGISTRY.update({
    "testbed": testbed_full,                          # Sec 3.5.2.4 / Ch 4 (Table 4.1)
    "testbed_free_screw": testbed_free_screw,         # Sec 3.5.2.1
    "testbed_screw_nut": testbed_screw_nut,           # Sec 3.5.2.2 (Tables 3.2/3.3)
    "testbed_no_table": testbed_no_table,             # Sec 3.5.2.3
    "testbed_axial_torsional": testbed_axial_torsional,  # Ch 5 (Table 5.1 sub-models 1 + 2)
    "testbed_submodel1": testbed_submodel1,           # Table 5.3
    "testbed_bellows": testbed_bellows,               # Sec 4.4.1 (Table 4.2)
    "testbed_appendix_c": testbed_appendix_c,         # App C (Table C.1)
    "testbed_reduced": testbed_reduced,               # Sec 5.2.3 / 5.3.2 (CMS + MA, Table 5.3)
})

# test beds: bscomp.systems.testbed
__all__ = ["small_drive", "validation_drive", "mass_spring_chain", "free_chain", "friction_oscillator", "get",
           "available", "REGISTRY"]


def available() -> dict[str, str]:
    """The registered drives, ``{name: one-line description}`` (the first line of each build function's
    docstring), in registration order: what :func:`get` builds by name."""
    return {name: ((inspect.getdoc(build) or "").strip().splitlines() or [""])[0] for name, build in REGISTRY.items()}


def get(name_or_path: str, overrides: dict | None = None):
    """Build a system from a registered name or a ``.py`` file defining ``build()`` (or one function
    returning a System), then apply parameter overrides by dotted name.

    An override whose key has no dot (e.g. ``{"nut_position": 0.43}``) is a keyword argument of the build
    function (structural choices fixed at construction, such as the test bed's nut position); dotted keys
    (``"coupling.k_T"``) are parameter overrides applied with ``System.set``.
    """
    overrides = dict(overrides or {})
    build_kwargs = {k: v for k, v in overrides.items() if "." not in k}
    overrides = {k: v for k, v in overrides.items() if "." in k}
    if name_or_path in REGISTRY:
        system = _call_build(REGISTRY[name_or_path], name_or_path, build_kwargs)
    elif name_or_path.endswith(".py") and Path(name_or_path).is_file():
        spec = importlib.util.spec_from_file_location("bscomp_user_system", name_or_path)
        mod = importlib.util.module_from_spec(spec)
        with _user_file(name_or_path, "loading it"):
            spec.loader.exec_module(mod)
        build = getattr(mod, "build", None)
        if build is None:
            raise UnknownNameError(f"system file {name_or_path} must define build() returning a bscomp.System")
        with _user_file(name_or_path, "in its build()"):
            system = _call_build(build, name_or_path, build_kwargs)
        if not isinstance(system, System):
            raise ModelDefinitionError(f"system file {name_or_path}: build() returned {type(system).__name__} "
                                       f"{system!r}"[:200] + ", not a bscomp.System",
                                       hint="end build() with 'return system' (the System it assembled)")
    elif str(name_or_path).endswith(".py"):
        raise UnknownNameError(f"system file {name_or_path!r} does not exist (or is not a file)")
    else:
        raise UnknownNameError(f"unknown system '{name_or_path}': use one of {sorted(REGISTRY)} or a path to a .py "
                               "file that defines build()")
    for k, v in overrides.items():
        system.set(k, v)
    return system


@contextlib.contextmanager
def _user_file(path, when: str):
    """Errors of a user's system file (a syntax error, an exception in build()) as a ModelDefinitionError naming
    the file and line; the library's own named errors pass through."""
    try:
        yield
    except BscompError:
        raise
    except SyntaxError as exc:
        raise ModelDefinitionError(f"system file {path}, line {exc.lineno}: {exc.msg}",
                                   hint="fix the Python syntax of the file") from exc
    except Exception as exc:
        tb = traceback.extract_tb(exc.__traceback__)
        line = next((f.lineno for f in reversed(tb) if Path(f.filename).resolve() == Path(path).resolve()), None)
        where = f", line {line}" if line else ""
        raise ModelDefinitionError(f"system file {path}{where}: {type(exc).__name__} {when}: {exc}",
                                   hint="run the file with python to debug it, or use --debug") from exc


def _call_build(build, name: str, kwargs: dict):
    """Call a build function with keyword arguments, naming the bad key if it does not take one."""

    if kwargs:
        sig = inspect.signature(build)
        takes_any = any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())
        bad = [k for k in kwargs if k not in sig.parameters and not takes_any]
        if bad:
            raise UnknownNameError(f"'{bad[0]}' is neither a parameter ('component.parameter') nor a build "
                                   f"argument of system '{name}' (build arguments: {sorted(sig.parameters)})")
    try:
        return build(**kwargs)
    except TypeError as exc:
        if kwargs and "unexpected keyword argument" in str(exc):
            raise UnknownNameError(f"system '{name}': {exc}") from exc
        raise
    except ParameterError as exc:
        if not kwargs:
            raise
        given = ", ".join(f"{k}={v!r}" for k, v in kwargs.items())
        raise ParameterError(f"system '{name}' built with {given}: {exc} (a build argument sets this "
                             "component's parameter; give it a physical value)") from exc
