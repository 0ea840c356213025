"""The validate package's import rules (DESIGN.md layer table): no bscomp.systems, plotting apart, nouns."""

import ast
import importlib
import pkgutil
from pathlib import Path

import bscomp
import bscomp.validate

ROOT = Path(bscomp.__file__).parent


def _imports(f):
    for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level:
            yield from (f"{node.module}.{a.name}" for a in node.names)   # from bscomp import systems


def test_validate_never_imports_the_drives():
    """Models are resolved by bscomp.model, the one resolver; thesis data stay in systems/."""
    bad = [f"{f.relative_to(ROOT)}: {n}" for f in sorted((ROOT / "validate").rglob("*.py")) for n in _imports(f)
           if n == "bscomp.systems" or n.startswith("bscomp.systems.")]
    assert not bad


def test_plotting_receives_data_and_imports_no_analysis():
    bad = [n for n in _imports(ROOT / "plotting" / "validate.py") if n.startswith("bscomp.")
           and not n.startswith("bscomp.plotting")]
    assert not bad


def test_no_submodule_is_shadowed_by_a_function():
    """``bscomp.validate.<module>`` is the module (module names are nouns, functions verbs)."""
    for m in pkgutil.iter_modules(bscomp.validate.__path__):
        mod = importlib.import_module(f"bscomp.validate.{m.name}")
        assert getattr(bscomp.validate, m.name) is mod, m.name
