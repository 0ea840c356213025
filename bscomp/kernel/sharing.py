"""When two instances of a component class may share one template (flattening step 2).

A template is the symbolic result of calling a component's ``equations()``, ``constraints()`` and
``observables()`` once (:mod:`bscomp.kernel.templates`). Parameters are symbols there, so instances with
other parameter *values* share it. A plain instance attribute is not a symbol: ``self.k = k`` in
``__init__`` read in ``equations()`` is baked into the template as a number. So while a template is built
the instance attributes its methods read are recorded (:func:`tracking_reads`), and another instance reuses
the template only if those attributes hold equal values (:func:`fingerprint`); otherwise it gets its own.
Identical elements (a chain of masses, bearings, FE elements) still share one template; a configuration
attribute that differs (``self.k``, ``self.hand``, a list of dofs) gets one template per distinct value.

Templates are also kept across flattenings in one process (:func:`bscomp.kernel.templates.shared_template`:
a diagnose's candidate structures and a design sweep's variants flatten the same drive again), keyed by the
template key and the parameter values, reused only when the attributes read hold the same values *and* what the
names read resolve to on the class is unchanged (:func:`class_fingerprint`: a class attribute or method patched in
between gets a new template). A template whose fingerprint holds an object identity is not kept (ids are reused).

Equality is by value for numbers, strings, arrays (a digest of their bytes), lists, tuples, dicts, sets
and dataclasses; by identity for any other object (conservative: equal but distinct objects get their
own templates, never a wrong shared one). Reads that bypass attribute access (``vars(self)``,
``self.__dict__[...]``, module globals) are not seen: a module constant an ``equations()`` reads, changed between two
flattenings in one process, is not noticed (call :func:`bscomp.kernel.templates.clear_shared`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
from contextlib import contextmanager

import numpy as np

__all__ = ["tracking_reads", "fingerprint", "by_value", "class_fingerprint"]

_PRIVATE = frozenset({"_ctx", "_name", "_parent", "_read_params", "_extra_ports"})
"""Kernel bookkeeping on a component, never part of its physics (names, context, added ports)."""

_MAX_DEPTH = 6


@contextmanager
def tracking_reads(comp):
    """While active, record in the yielded set the attribute names read on ``comp`` (its class is swapped
    for a subclass that records them). If the class cannot be swapped, every instance attribute counts as
    read (no sharing unless all of them are equal)."""
    reads: set = set()
    cls = type(comp)

    def __getattribute__(obj, name):
        if not name.startswith("__") and name not in _PRIVATE:
            reads.add(name)
        return cls.__getattribute__(obj, name)

    try:
        tracker = type(cls.__name__, (cls,), {"__getattribute__": __getattribute__, "__module__": cls.__module__,
                                              "__qualname__": cls.__qualname__, "__doc__": cls.__doc__,
                                              "_read_tracker": True})
        comp.__class__ = tracker
    except TypeError:   # __slots__, an __init_subclass__ that needs arguments...
        reads.update(k for k in comp.__dict__ if k not in _PRIVATE)
        yield reads
        return
    try:
        yield reads
    finally:
        comp.__class__ = cls


def fingerprint(comp, names) -> tuple:
    """Hashable value of the instance attributes ``names`` of ``comp`` (absent ones included as such)."""
    d = comp.__dict__
    return tuple((n, _fp(d[n], 0) if n in d else ("<absent>",)) for n in sorted(names))


def _fp(v, depth):
    if v is None or isinstance(v, (bool, int, float, complex, str, bytes)):
        return (type(v).__name__, v)
    if isinstance(v, np.generic):
        return ("np", v.dtype.str, v.item())
    if isinstance(v, np.ndarray) and v.dtype.kind != "O":
        return ("nd", v.shape, v.dtype.str, hashlib.sha1(np.ascontiguousarray(v).tobytes()).hexdigest())
    if depth >= _MAX_DEPTH:
        return ("id", id(v))
    if isinstance(v, np.ndarray):   # of objects
        return ("ndO", v.shape, tuple(_fp(x, depth + 1) for x in v.ravel()))
    if isinstance(v, (list, tuple)):
        return (type(v).__name__, tuple(_fp(x, depth + 1) for x in v))
    if isinstance(v, dict):
        return ("dict", tuple((_fp(k, depth + 1), _fp(x, depth + 1)) for k, x in v.items()))
    if isinstance(v, (set, frozenset)):
        return ("set", frozenset(_fp(x, depth + 1) for x in v))
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return (type(v), tuple((f.name, _fp(getattr(v, f.name), depth + 1)) for f in dataclasses.fields(v)))
    return ("id", id(v))


def by_value(fp) -> bool:
    """True if a :func:`fingerprint` holds values only, no object identity (``("id", ...)``): only such a
    fingerprint may be compared with one taken in another flattening (an ``id`` is reused after its object is
    freed)."""
    if isinstance(fp, tuple):
        if len(fp) == 2 and fp[0] == "id":
            return False
        return all(by_value(x) for x in fp)
    if isinstance(fp, frozenset):
        return all(by_value(x) for x in fp)
    return True


def class_fingerprint(comp, names) -> tuple:
    """Hashable value of what the read names ``names`` absent from the instance resolve to on its class: a data
    attribute by value, a function by its code (bytes, constants, defaults), a kernel declaration (port,
    parameter, variable: already in the template key) by its kind. Within one flattening every instance sees the
    same class, so :func:`fingerprint` leaves these out; across flattenings a class attribute may have been
    changed (``Damp.mode = "param"``, a monkeypatched method). Anything else is taken by identity (then
    :func:`by_value` is False and the template is not shared across flattenings)."""
    d, cls = comp.__dict__, type(comp)
    out = []
    for n in sorted(names):
        if n in d:
            continue
        try:
            v = inspect.getattr_static(cls, n)
        except AttributeError:
            out.append((n, ("<absent>",)))
            continue
        out.append((n, _class_fp(v)))
    return tuple(out)


def _class_fp(v):
    if isinstance(v, (staticmethod, classmethod)):
        v = v.__func__
    if isinstance(v, property):
        return ("property", _class_fp(v.fget))
    code = getattr(v, "__code__", None)
    if code is not None:
        closure = tuple(_fp(c.cell_contents, 1) for c in (v.__closure__ or ()))
        return ("fn", v.__qualname__, hashlib.sha1(code.co_code).hexdigest(), repr(code.co_consts),
                _fp(v.__defaults__, 1), closure)
    if type(v).__module__.startswith("bscomp.kernel"):
        return ("kernel", type(v).__qualname__)
    return _fp(v, 0)
