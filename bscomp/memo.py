"""A bounded memo (a leaf module: imports nothing of bscomp).

The engine keeps what it has computed for the arguments it meets again -- a modal model per parameter vector, the
FRFs of a modal model, a simulator's set-up per start point -- in a dict of at most a few entries, the oldest
dropped first (the runs that meet an entry again come close together: finite-difference columns, screening scans,
repeated simulations from one start).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, MutableMapping
from typing import Any

__all__ = ["kept"]


def kept(cache: MutableMapping, key: Hashable, build: Callable[[], Any], size: int) -> Any:
    """``cache[key]``, made by ``build()`` when it is not there; then at most ``size`` entries stay, the oldest
    (first inserted) dropped."""
    if key not in cache:
        value = build()
        while len(cache) >= size:
            cache.pop(next(iter(cache)))
        cache[key] = value
    return cache[key]
