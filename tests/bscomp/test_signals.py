"""bscomp.simulation.signals: the test signals and their one-line spelling (bscomp simulate --input)."""

import math

import pytest

from bscomp.errors import UsageError
from bscomp.simulation.signals import parse_signal, ramp, sine, square, step


def test_the_thesis_square_wave_and_the_others():
    u = square(2.125, 5.0)                       # Sec 5.3.1: 4.25 V peak to peak, 5 Hz
    assert [u(t) for t in (0.0, 0.05, 0.099, 0.1, 0.15, 0.2)] == [2.125, 2.125, 2.125, -2.125, -2.125, 2.125]
    assert step(3.0, 0.2)(0.1) == 0.0 and step(3.0, 0.2)(0.2) == 3.0
    assert sine(2.0, 10.0)(0.025) == pytest.approx(2.0)
    assert ramp(4.0, 0.5)(0.25) == 0.0 and ramp(4.0, 0.5)(1.0) == pytest.approx(2.0)


def test_parse_signal_spellings():
    assert parse_signal("2.5") == 2.5
    assert parse_signal("square:2.125:5")(0.15) == -2.125
    assert parse_signal("step:1")(0.0) == 1.0
    assert parse_signal(" sine:1:0.25 ")(1.0) == pytest.approx(math.sin(math.pi / 2))


@pytest.mark.parametrize("text, words", [("squre:1:2", "cannot read"), ("square:1", "takes 2"),
                                         ("sine:1:0", "must be > 0"), ("nan", "cannot read"),
                                         ("step:1:2:3", "takes 1 or 2"), ("ramp:inf", "finite")])
def test_bad_spellings_name_the_argument(text, words):
    with pytest.raises(UsageError, match=words) as info:
        parse_signal(text, "--input amp.u")
    assert "--input amp.u" in str(info.value)


def test_an_input_function_is_evaluated_once_for_the_grid_when_it_is_written_in_numpy():
    """input_matrix calls a numpy function once with every midpoint (the same numbers as point by point); a
    function of one number (an ``if``), or one that returns a constant for an array, is called point by point."""
    import numpy as np

    from bscomp import flatten
    from bscomp.simulation.common import input_matrix
    from bscomp.systems import small_drive

    dae = flatten(small_drive())
    t = np.linspace(0.0, 0.3, 3001)
    tm = 0.5 * (t[:-1] + t[1:])
    calls = []

    def counted(fn):
        def f(tt):
            calls.append(np.ndim(tt))
            return fn(tt)
        return f

    for fn in (square(2.125, 5.0), sine(1.0, 7.0), ramp(4.0, 0.1), step(3.0, 0.2)):
        calls.clear()
        U = input_matrix(dae, t, {"motor.tau": counted(fn)})
        assert calls.count(1) == 1 and len(calls) <= 4                     # one array call, three checks
        np.testing.assert_allclose(U[0], [float(fn(x)) for x in tm], rtol=1e-12, atol=0.0)
    for fn, ref in ((lambda tt: 1.0 if tt < 0.1 else -1.0, np.where(tm < 0.1, 1.0, -1.0)),
                    (lambda tt: 2.0, np.full(tm.size, 2.0))):
        calls.clear()
        np.testing.assert_array_equal(input_matrix(dae, t, {"motor.tau": counted(fn)})[0], ref)
        assert calls.count(0) >= tm.size                                 # point by point
