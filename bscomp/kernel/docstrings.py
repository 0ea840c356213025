"""The numpydoc ``Parameters`` section a component class gets from its declared parameters."""

from __future__ import annotations

import inspect

import numpy as np

__all__ = ["parameters_docstring"]


def _format_default(value) -> str:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return f"{float(arr):.6g}"
    if arr.size > 9:
        return f"array of shape {arr.shape}"
    return np.array2string(arr, separator=", ", formatter={"float_kind": lambda x: f"{x:.6g}"})


def _is_header(lines: list, i: int) -> bool:
    under = lines[i + 1].strip() if i + 1 < len(lines) else ""
    return bool(lines[i].strip()) and len(under) >= 3 and set(under) == {"-"}


def parameters_docstring(doc: str | None, params: dict) -> str | None:
    """``doc`` with the numpydoc ``Parameters`` entries of ``params`` (declared :class:`Parameter` s).

    They are appended to the docstring's ``Parameters`` section when it has one (constructor arguments
    such as ``ends`` come first), else a ``Parameters`` section is put before the first other section.
    """
    if not params:
        return doc
    lines = inspect.cleandoc(doc).splitlines() if doc else []
    entries = [line for p in params.values() for line in p.doc_entry()]
    headers = [i for i in range(len(lines)) if _is_header(lines, i)]
    own = [i for i in headers if lines[i].strip() == "Parameters"]
    if own:
        nxt = [i for i in headers if i > own[0]]
        end = nxt[0] if nxt else len(lines)
        while end > own[0] + 2 and not lines[end - 1].strip():
            end -= 1
        lines[end:end] = entries
    else:
        at = headers[0] if headers else len(lines)
        block = ["Parameters", "----------"] + entries
        if at > 0 and lines[at - 1].strip():
            block = [""] + block
        lines[at:at] = block + ([""] if headers else [])
    return "\n".join(lines) + "\n"
