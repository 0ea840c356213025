"""Write the truths drawn anew that tests/integration/test_diagnose_fe.py diagnoses (run from the repository root:
``python tests/integration/drawn_truths.py``, ~90 s; IDAS on the truths' moving-nut models).

Each is :func:`bscomp.systems.truths.generate_case` -- the generator of the bundled truths
(``systems/data/truths``) and of ``benchmarks/diagnose_table.py``'s seeds -- written to
``data/truths/<seed>/axial_torsional/<case>/`` (``frf.csv``, ``time.csv``, ``truth.json`` with the hidden effect).
The tests read the files instead of drawing the truths again at each run (their time series are 12-47 s of IDAS
each); ``test_the_drawn_truths_are_the_generators`` checks that each FRF file is what the generator draws today.
"""

from pathlib import Path

import numpy as np

#: (case, seed, generate_case keywords)
TRUTHS = [
    ("damping", 2203, {"freqs": np.geomspace(2.0, 1000.0, 120), "dt": 5e-4}),   # 120 of 300 points, 2 kHz
    ("backlash", 2231, {}),
    ("joint_friction", 2213, {}),
]

HERE = Path(__file__).resolve().parent / "data" / "truths"


def main():
    from bscomp.systems.truths import generate_case

    for case, seed, kw in TRUTHS:
        out = generate_case(case, "axial_torsional", HERE / str(seed), seed, **kw)
        print(case, seed, out["info"]["time"]["wall_s"], "s")


if __name__ == "__main__":
    main()
