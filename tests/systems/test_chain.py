"""systems/chain.py: the grounded spring-mass chain against its closed-form modes, and its bad input."""

import math

import numpy as np
import pytest

from bscomp.errors import ParameterError
from bscomp.linear.modal import modes
from bscomp.systems import mass_spring_chain


def test_equal_chain_has_the_closed_form_frequencies():
    """N equal masses and springs, fixed-free: ``w_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2N + 1)))``."""
    N, m, k = 40, 0.5, 2.0e6
    md = modes(mass_spring_chain([m] * N, [k] * N, first=0), inputs=["F.f"], outputs=[f"m{N - 1}.s"])
    j = np.arange(1, N + 1)
    w = 2 * math.sqrt(k / m) * np.sin((2 * j - 1) * math.pi / (2 * (2 * N + 1)))
    np.testing.assert_allclose(md.omega, w, rtol=1e-9)


@pytest.mark.parametrize("masses, springs", [([1.0, 2.0], [1.0e4]), ([], [])])
def test_one_spring_per_mass_or_a_named_error(masses, springs):
    with pytest.raises(ParameterError, match="one spring per mass"):
        mass_spring_chain(masses, springs)
