"""Parameter standard deviations with correlated residuals (bscomp.validate.uncertainty): checked against the
spread of the estimates over many noise draws (the quantity a standard deviation claims), and against the
AR(1) correlation time (1 + phi) / (1 - phi)."""

import numpy as np
import pytest
from scipy.signal import lfilter

from bscomp.validate.uncertainty import correlation_time, parameter_std


def _ar1(rng, phi, shape):
    w = rng.standard_normal(shape)
    return lfilter([1.0], [1.0, -phi], w, axis=-1)


@pytest.mark.parametrize("phi", [0.0, 0.5, 0.9])
def test_correlation_time_of_ar1(phi):
    e = _ar1(np.random.default_rng(3), phi, 200_000)
    assert correlation_time(e) == pytest.approx((1 + phi) / (1 - phi), rel=0.1)


def test_correlation_time_of_a_residual_that_keeps_its_sign_is_long():
    """A misfit that stays positive (a model off by a constant) is one piece of evidence, not n."""
    e = 1.0 + 0.01 * np.random.default_rng(0).standard_normal(1000)
    assert correlation_time(e) == 500.0          # capped at half the block


@pytest.mark.parametrize("phi, lo, hi, classical_hi", [(0.0, 0.8, 1.15, 1.15), (0.5, 0.8, 1.15, 0.7),
                                                        (0.9, 0.72, 1.15, 0.3)])
def test_std_matches_the_spread_over_noise_draws(phi, lo, hi, classical_hi):
    """A line and a sine fitted to AR(1) noise, 2,000 samples, 300 draws: the median reported std of the slope
    against its actual spread over the draws. The classical (J^T J)^-1 formula reports 1/sqrt(tau) of it."""
    rng = np.random.default_rng(1)
    n = 2000
    t = np.linspace(0.0, 1.0, n)
    J = np.column_stack([np.ones(n), t, np.sin(7 * t)])
    E = _ar1(rng, phi, (300, n))
    est, cla, slopes = [], [], []
    for e in E:
        b, *_ = np.linalg.lstsq(J, e, rcond=None)
        r = e - J @ b
        s, c = parameter_std(-J, r, [n])             # the residual's Jacobian is -J
        est.append(s[1])
        cla.append(c[1])
        slopes.append(b[1])
    true = np.std(slopes)
    assert lo < np.median(est) / true < hi
    assert np.median(cla) / true < classical_hi
    assert np.all(np.array(est) >= np.array(cla))     # never below the classical value


def test_blocks_are_judged_separately():
    """One white block beside one strongly correlated block: the correlated block's batches set the extra
    spread of the parameter it informs, the white one's parameter keeps the classical value."""
    rng = np.random.default_rng(2)
    n = 4000
    J = np.zeros((2 * n, 2))
    J[:n, 0] = 1.0
    J[n:, 1] = 1.0
    r = np.r_[rng.standard_normal(n), _ar1(rng, 0.95, n)]
    r[:n] -= r[:n].mean()
    r[n:] -= r[n:].mean()
    s, c = parameter_std(-J, r, [n, n])
    assert s[0] == pytest.approx(c[0], rel=0.2)
    assert s[1] > 3 * c[1]


def test_sizes_that_do_not_add_up_give_the_classical_value():
    rng = np.random.default_rng(4)
    J = rng.standard_normal((50, 2))
    r = rng.standard_normal(50)
    s, c = parameter_std(J, r, [20, 20])
    np.testing.assert_array_equal(s, c)
