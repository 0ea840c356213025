"""Every script in examples/ imports cleanly (its names resolve against the current API) and guards its run behind
``if __name__ == "__main__"``: the scripts are run by hand (minutes each), so an API change that breaks one shows
here first. examples/stepped_sine.py is also run whole on one frequency per amplitude."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.py"))


def _load(path):
    name = f"example_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod                  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_imports_without_running(path):
    text = path.read_text()
    assert 'if __name__ == "__main__":' in text, f"{path.name} runs on import"
    mod = _load(path)
    assert (mod.__doc__ or "").strip(), f"{path.name} has no docstring saying what it shows and how to run it"


def test_stepped_sine_example_runs(tmp_path, monkeypatch):
    mod = _load(next(p for p in EXAMPLES if p.stem == "stepped_sine"))
    monkeypatch.setattr(mod, "FREQS", np.array([10.0, 200.0]))
    monkeypatch.setattr(mod, "DENSE", np.array([10.0, 50.0, 200.0]))
    lin, runs, desc = mod.main(tmp_path)
    assert (tmp_path / "stepped_sine.png").stat().st_size > 10_000
    ratio = np.abs(runs[2.0].H[0, 1, 0] / lin.H[0, 1, 0])       # table.a at 10 Hz: the table slides at 2 V
    assert ratio > 10 and abs(np.abs(runs[0.2].H[1, 1, 0] / lin.H[1, 1, 0]) - 1) < 0.05
    assert abs(desc[2.0].H[0, 1, 0] / runs[2.0].H[0, 1, 0] - 1) < 0.25     # the describing function: one harmonic
