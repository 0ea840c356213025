"""Noise levels estimated from the data (bscomp.validate.noise): each estimator against a known noise, and the
whole noise model against the truth of the lumped joint case (the exact truth model must score chi^2 ~ 1)."""

import math
import warnings

import numpy as np
import pytest

from bscomp.errors import UsageError
from bscomp.validate.datasets import FrfData, TimeData
from bscomp.validate.noise import FLOOR, h1_averages, noise_levels, quantisation_step, robust_sigma, time_sigma


def _two_mode_frf(f):
    """An FRF with two resonances and an anti-resonance between them (coherence drops there)."""
    s = 2j * np.pi * f
    w1, w2, wa = 2 * np.pi * 120, 2 * np.pi * 600, 2 * np.pi * 300
    num = (s * s + 2 * 0.02 * wa * s + wa * wa) * w1 * w1 * w2 * w2 / (wa * wa)
    return num / ((s * s + 2 * 0.05 * w1 * s + w1 * w1) * (s * s + 2 * 0.05 * w2 * s + w2 * w2))


def _h1_data(n_avg, seed, eps=3e-3, n=600):
    """H1 estimate with coherence gamma^2 = 1 / (1 + (eps max|H| / |H|)^2) and Bendat & Piersol's random error."""
    rng = np.random.default_rng(seed)
    f = np.logspace(np.log10(2.0), 3.0, n)
    h = _two_mode_frf(f)
    g2 = 1.0 / (1.0 + (eps * np.max(np.abs(h)) / np.abs(h)) ** 2)
    sd = np.sqrt((1 - g2) / (2 * n_avg * g2))
    hm = h * (1 + sd * (rng.standard_normal(n) + 1j * rng.standard_normal(n)))
    return FrfData(freqs=f, H={("u", "y"): hm}, coherence={("u", "y"): g2}), h, g2


@pytest.mark.parametrize("n_avg", [5, 20, 80])
def test_h1_averages_recovered_from_the_scatter(n_avg):
    """The number of averages the scatter corresponds to, pooled over magnitude and phase: within 15 % of the
    true one (mean over 5 records of 600 points; one record scatters by ~10 %)."""
    est = [h1_averages(_h1_data(n_avg, seed)[0]) for seed in range(5)]
    assert abs(np.mean(est) / n_avg - 1) < 0.15, est


def test_h1_noise_levels_whiten_the_error_per_frequency():
    """Residuals of the exact FRF divided by the per-frequency levels have chi^2 ~ 1 in magnitude and phase,
    including the anti-resonance, where one level per block (the former model) gave chi^2 >> 1."""
    data, h, g2 = _h1_data(20, 7)
    s_mag, s_ph = noise_levels(data)
    assert np.ndim(s_mag) == 1 and s_mag.size == h.size
    assert s_mag.max() / s_mag.min() > 100                       # the noise spans orders of magnitude
    hm = data.H[("u", "y")]
    e_mag = np.log10(np.abs(hm)) - np.log10(np.abs(h))
    e_ph = np.angle(hm * np.conj(h))
    assert 0.75 < np.mean((e_mag / s_mag) ** 2) < 1.3
    assert 0.75 < np.mean((e_ph / s_ph) ** 2) < 1.3
    flat = robust_sigma(np.log10(np.abs(hm)), FLOOR)               # one level for the whole block
    assert np.mean((e_mag / flat) ** 2) > 10


def test_frf_without_a_noise_statement_has_one_level_per_block():
    """Coherence 1 everywhere (the FE truths' files) or none: the robust scale of second differences, as before."""
    rng = np.random.default_rng(1)
    f = np.logspace(0, 3, 400)
    h = _two_mode_frf(f) * (1 + 0.02 / math.sqrt(2) * (rng.standard_normal(400) + 1j * rng.standard_normal(400)))
    for coh in ({("u", "y"): np.ones(400)}, {}):
        s_mag, s_ph = noise_levels(FrfData(freqs=f, H={("u", "y"): h}, coherence=coh))
        assert np.ndim(s_mag) == 0 and np.ndim(s_ph) == 0
        assert abs(s_mag / (0.02 / math.sqrt(2) / math.log(10)) - 1) < 0.2
        assert abs(s_ph / (0.02 / math.sqrt(2)) - 1) < 0.2


def test_coherence_one_at_some_points_and_zero_at_others():
    """Coherence stated as exactly 1 (rounded) takes the pair's smallest stated error; 0 carries no weight."""
    data, _, g2 = _h1_data(20, 3)
    g = g2.copy()
    g[g > 0.9999] = 1.0
    g[:3] = 0.0
    s_mag, s_ph = noise_levels(FrfData(freqs=data.freqs, H=data.H, coherence={("u", "y"): g}))
    assert np.all(np.isfinite(s_mag[3:])) and np.all(s_mag[3:] > 0) and np.all(np.isinf(s_mag[:3]))
    ones = g == 1.0
    assert ones.any() and np.allclose(s_mag[ones], np.min(s_mag[~ones & (g > 0)]), rtol=1e-3)


def test_quantisation_step_of_a_quantised_and_of_a_continuous_channel():
    t = np.linspace(0, 1, 2001)
    rng = np.random.default_rng(0)
    q = 2 * np.pi / 10000
    y = np.round((3 * t ** 2 + 1e-4 * rng.standard_normal(t.size)) / q) * q
    assert quantisation_step(y) == pytest.approx(q, rel=1e-9)
    assert quantisation_step(3 * t ** 2 + 1e-4 * rng.standard_normal(t.size)) == 0.0
    assert quantisation_step(np.zeros(100)) == 0.0


def test_time_noise_levels():
    """White noise: its standard deviation; a quantised channel whose scatter is below one step: q / sqrt(12)
    (the median of a few discrete differences reads 1.15 q / sqrt(12) here); a ringing sampled at 17 samples
    per period barely touches the third differences (second differences: 1.3x)."""
    rng = np.random.default_rng(2)
    t = np.arange(4001) * 5e-4
    assert time_sigma(0.05 * rng.standard_normal(t.size)) == pytest.approx(0.05, rel=0.08)
    q = 1e-6
    y = np.round(0.02 * np.sin(2 * np.pi * 5 * t) / q) * q       # a linear encoder, 1 um, moving 100 um/s
    assert time_sigma(y) == pytest.approx(q / math.sqrt(12))
    ring = 2.0 * np.exp(-60 * (t % 0.1)) * np.sin(2 * np.pi * 117 * t)   # 8 % damped, restarted every 0.1 s
    noisy = ring + 0.02 * rng.standard_normal(t.size)
    assert time_sigma(noisy) == pytest.approx(0.02, rel=0.1)
    assert robust_sigma(noisy, 0.0, order=2) > 1.2 * 0.02


def test_noise_levels_of_a_time_series_per_channel():
    rng = np.random.default_rng(4)
    t = np.arange(2001) * 1e-3
    d = TimeData(t=t, inputs={"u": np.ones(t.size)}, outputs={"a": 0.1 * rng.standard_normal(t.size),
                                                               "b": 3e-3 * rng.standard_normal(t.size)})
    assert noise_levels(d) == pytest.approx([0.1, 3e-3], rel=0.1)


def test_the_truth_scores_the_noise_floor():
    """The lumped joint truth's own model (the candidate at the truth's values, the truth's table mass and
    coupling) against its data: chi^2 ~ 1 in every block (0.81-0.88 FRF, 0.85-1.03 time; one level per FRF
    block gave 23-68 there)."""
    from bscomp.systems.validation_drive import validation_drive
    from bscomp.validate.calibration import FitSetup
    from bscomp.validate.candidates import default_candidates
    from bscomp.validate.evaluation import Problem, residual_blocks
    from bscomp.validate.synthetic import MISSET, TRUTH_VALUES, generate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = generate(hidden={"nut_table_joint": {}}, seed=3)
    setup = FitSetup.build(validation_drive(), data.datasets)
    cand = next(c for c in default_candidates() if c.name == "nut_table_joint")
    effects = [(cand, dict(TRUTH_VALUES["nut_table_joint"]), False)]
    ev, st = setup.structures.get(effects)
    unc = {k: float(setup.reference.get(k)) * MISSET.get(k, 1.0) for k in setup.uncertain}
    pr = Problem(ev, setup.sigmas, unc, [], effects, st)
    outs = ev.outputs(*pr.overrides(np.zeros(0)))
    for y, d, s in zip(outs, ev.datasets, setup.sigmas):
        chi2 = [float(np.mean(b ** 2)) for b in residual_blocks(y, d, s)]
        assert all(0.7 < c < 1.2 for c in chi2), (type(d).__name__, chi2)


def test_a_delay_the_fine_grid_cannot_hold_is_refused():
    """The generator applies a hidden delay as a whole number of integration sub-steps (0.4 ms at 0.5 ms
    samples: 10 sub-steps), and refuses one that no sub-step count up to 64 per sample makes exact."""
    from bscomp.validate.synthetic import _substeps

    assert _substeps(4e-4, 5e-4) == 10 and _substeps(0.0, 5e-4) == 8 and _substeps(1e-3, 5e-4) == 8
    with pytest.raises(UsageError, match="not a rational multiple"):
        _substeps(math.pi * 1e-4, 5e-4)
