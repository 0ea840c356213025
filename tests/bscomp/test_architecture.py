"""The package layout of docs/architecture.md, checked: no import cycle, arrows one way, sizes bounded.

The import graph is read from the syntax trees of every module (module-level and function-local
imports alike), so a cycle hidden inside a function counts.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DIRS = {"bscomp": "bscomp", "components": "bscomp.components", "systems": "bscomp.systems"}

#: package -> the bscomp packages it may import (besides itself, bscomp.errors and bscomp.files); results'
#: ``.plot()`` reach bscomp.plotting, which imports nothing of bscomp (and matplotlib only when drawing)
ALLOWED = {
    "bscomp.kernel": set(),
    "bscomp.components": {"bscomp.kernel"},
    "bscomp.model": {"bscomp.kernel", "bscomp.systems"},
    "bscomp.linear": {"bscomp.kernel", "bscomp.model", "bscomp.plotting"},
    "bscomp.simulation": {"bscomp.kernel", "bscomp.model", "bscomp.linear", "bscomp.components", "bscomp.plotting"},
    "bscomp.control": {"bscomp.kernel", "bscomp.model", "bscomp.linear", "bscomp.simulation", "bscomp.components",
                       "bscomp.plotting"},
    "bscomp.optimal": {"bscomp.kernel", "bscomp.model", "bscomp.linear", "bscomp.simulation", "bscomp.plotting"},
    "bscomp.validate": {"bscomp.kernel", "bscomp.model", "bscomp.linear", "bscomp.simulation", "bscomp.components",
                        "bscomp.plotting"},
    "bscomp.plotting": set(),
}
LEAVES = {"bscomp.errors", "bscomp.files", "bscomp.memo"}


def _modules():
    for top, pkg in DIRS.items():
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT / top).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            yield ".".join([pkg, *parts]) if parts else pkg, path


MODULES = dict(_modules())


def _imports(name: str, path: Path):
    """(imported bscomp module, line, inside a function) for every import of a module."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    parents = {}
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            parents[child] = node

    def in_function(node):
        while node in parents:
            node = parents[node]
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                return True
        return False

    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = name.split(".") if is_pkg else name.split(".")[:-1]
                pkg = pkg[: len(pkg) - (node.level - 1)]
                base = ".".join(pkg + ([base] if base else []))
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        for t in targets:
            while t and t not in MODULES:
                t = t.rpartition(".")[0]
            if t and t != name and t.startswith("bscomp"):
                yield t, node.lineno, in_function(node)


GRAPH = {m: sorted({t for t, _, _ in _imports(m, p)}) for m, p in MODULES.items()}


def _package(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else module


def test_no_import_cycle():
    """Tarjan's strongly connected components over every bscomp import (function-local ones included)."""
    index, low, stack, on, cycles = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in GRAPH.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_arrows_point_one_way(package):
    bad = []
    for module, path in MODULES.items():
        if _package(module) != package and not (package == "bscomp.model" and module == "bscomp.model"):
            continue
        for target, line, _ in _imports(module, path):
            tp = _package(target)
            if tp in (package, "bscomp") or target in LEAVES or tp in ALLOWED[package]:
                continue
            bad.append(f"{path.relative_to(ROOT)}:{line} -> {target}")
    assert not bad, f"{package} may import only {sorted(ALLOWED[package] | LEAVES)}: {bad}"


def test_function_local_imports_only_for_optional_heavy_dependencies():
    """Inside functions: matplotlib, python-control, or bscomp.model -> bscomp.systems; nothing else of
    bscomp (a local bscomp import would hide a cycle) -- except in the CLI (bscomp.cli, bscomp.cli_checks: a
    command imports only what it runs, so `bscomp --help` starts fast) and the plotting package."""
    bad = []
    for module, path in MODULES.items():
        if not module.startswith("bscomp.") or module.startswith(("bscomp.systems", "bscomp.components")):
            continue
        for target, line, local in _imports(module, path):
            if local and not (module == "bscomp.model" and target.startswith("bscomp.systems")) \
                    and not module.startswith(("bscomp.cli", "bscomp.plotting")):
                bad.append(f"{path.relative_to(ROOT)}:{line} -> {target}")
    assert not bad, bad


def test_module_and_function_sizes():
    """No module over 600 lines, no function over 120 (docs/architecture.md)."""
    big = []
    for path in MODULES.values():
        text = path.read_text()
        n = text.count("\n")
        if n > 600:
            big.append(f"{path.relative_to(ROOT)}: {n} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > 120:
                    big.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {length} lines")
    assert not big, big


def test_no_module_is_shadowed_by_a_function_of_its_name():
    """``import bscomp.x.y`` returns the module, never a function re-exported under the same name."""
    import importlib

    shadowed = []
    for module in MODULES:
        if module.startswith(("bscomp.systems", "bscomp.components")) or module.count(".") < 2:
            continue
        parent, _, leaf = module.rpartition(".")
        obj = getattr(importlib.import_module(parent), leaf, None)
        if obj is not None and not isinstance(obj, type(importlib)):
            shadowed.append(module)
    assert not shadowed, shadowed


def test_public_surface_is_reachable_from_the_top():
    import bscomp

    for name in ("modes", "frf", "simulate", "Ocp", "compare", "diagnose", "calibrate", "linearize",
                 "second_order", "CompiledModel"):
        assert getattr(bscomp, name) is not None, name
