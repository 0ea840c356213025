"""Fuzz the measurement loader with ≥ 10⁵ hypothesis examples (the CI test runs a few thousand).

Runs the property of ``tests/bscomp/validate/test_loader_fuzz.py`` -- nothing but ``MeasurementFileError``
escapes ``bscomp.validate.load`` and what loads is finite and monotonic -- and prints the number of examples,
how many loaded, how many were refused with a named error, and every escape (type, message, case).

    python benchmarks/fuzz_loader.py [--examples 100000]
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
import traceback
from pathlib import Path

from hypothesis import HealthCheck, given, settings

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "bscomp" / "validate"))
import test_loader_fuzz as fuzz  # noqa: E402  (the strategies and the property live with the test)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=100_000)
    args = ap.parse_args(argv)
    counts: collections.Counter = collections.Counter()
    escapes: list = []

    @settings(max_examples=args.examples, deadline=None, database=None, derandomize=False,
              suppress_health_check=list(HealthCheck))
    @given(fuzz.measurement_file())
    def run(case):
        try:
            counts[fuzz.check_one(*case)] += 1
        except Exception as exc:  # an escape: record it, keep fuzzing
            counts["escape"] += 1
            if len(escapes) < 20:
                escapes.append((type(exc).__name__, str(exc)[:200], case, traceback.format_exc(limit=3)))

    t0 = time.perf_counter()
    run()
    dt = time.perf_counter() - t0
    total = sum(counts.values())
    print(f"examples: {total} in {dt:.0f} s; loaded {counts['loaded']}, MeasurementFileError {counts['error']}, "
          f"escapes {counts['escape']}")
    for name, msg, case, tb in escapes:
        print(f"ESCAPE {name}: {msg}\n  case: {case!r}\n{tb}")
    return 1 if counts["escape"] else 0


if __name__ == "__main__":
    sys.exit(main())
