"""Drives composed from components (``bscomp.systems``).

Each system is a function returning a :class:`bscomp.System`; :func:`get` builds one by name with
parameter overrides, so ``(name, overrides)`` is all a worker process needs to rebuild it.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from bscomp.errors import UnknownNameError

from .small_drive import small_drive  # noqa: E402

REGISTRY = {
    "small_drive": small_drive,
}

__all__ = ["small_drive", "get", "REGISTRY"]


def get(name_or_path: str, overrides: dict | None = None):
    """Build a system from a registered name or a ``.py`` file defining ``build()`` (or one function
    returning a System), then apply parameter overrides by dotted name."""
    if name_or_path in REGISTRY:
        system = REGISTRY[name_or_path]()
    elif name_or_path.endswith(".py") and Path(name_or_path).is_file():
        spec = importlib.util.spec_from_file_location("bscomp_user_system", name_or_path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        build = getattr(mod, "build", None)
        if build is None:
            raise UnknownNameError(f"system file {name_or_path} must define build() returning a bscomp.System")
        system = build()
    else:
        raise UnknownNameError(f"unknown system '{name_or_path}': use one of {sorted(REGISTRY)} or a path to a .py "
                               "file that defines build()")
    for k, v in (overrides or {}).items():
        system.set(k, v)
    return system
