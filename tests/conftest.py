"""Shared test set-up: one BLAS thread per process, session fixtures for the drives and data many tests use.

The suite runs on pytest-xdist workers (``python -m pytest -n 2``, the README command); each worker is a
process, so a BLAS library that spawns a thread per core would oversubscribe the machine (small
``eigh`` calls then run 100x slower). Every fixture below builds its object once per worker.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

_LIMITS = threadpool_limits(1)   # for libraries already loaded by plugins


def pytest_collection_modifyitems(config, items):
    """Files holding a long test (marked ``slow``) run first, each file's tests in their order (module fixtures
    stay together): the two xdist workers (``--dist worksteal``) then end on short tests and stay busy to the
    end, instead of one idling while the other finishes a diagnose it took last."""
    slow = {it.nodeid.split("::")[0] for it in items if it.get_closest_marker("slow")}
    items.sort(key=lambda it: it.nodeid.split("::")[0] not in slow)      # stable: False (slow files) first


@pytest.fixture(scope="session")
def small_drive():
    """The 5-coordinate lumped drive of ``systems/small_drive.py`` (do not mutate: copy first)."""
    from bscomp.systems import small_drive as build

    return build()


@pytest.fixture(scope="session")
def testbed_at():
    """The thesis FE test bed, axial + torsional (Ch 5), amplifier-voltage input (do not mutate)."""
    from bscomp.systems import get

    return get("testbed_axial_torsional")


@pytest.fixture(scope="session")
def testbed_at_dae(testbed_at):
    """``testbed_at`` flattened once."""
    from bscomp import flatten

    return flatten(testbed_at)


@pytest.fixture(scope="session")
def truth_data():
    """``truth_data(model, case)`` -> the bundled measurements of an independent truth (loaded once)."""
    from importlib import resources

    from bscomp.validate import load_all

    cache = {}

    def load(model: str, case: str):
        if (model, case) not in cache:
            root = resources.files("bscomp.systems") / "data" / "truths" / model / case
            files = [str(root / n) for n in ("frf.csv", "time.csv") if (root / n).is_file()]
            cache[model, case] = load_all(files)
        return cache[model, case]

    return load
