r"""Does the drive respond differently at another excitation amplitude? A check on the measurements alone.

A linear drive has one FRF at every amplitude; friction and backlash make it depend on how hard the drive was
excited (at 0.2 V the test bed's table stays stuck on its guideways, at 2 V it slides). When two FRF files of
the same pair, at the same conditions, state different sine amplitudes (``# excitation amp.u: 2 V``), their
difference says so without any model: at their common frequencies

.. math:: \chi^2_A = \frac{1}{2}\left[\operatorname{mean}_k \frac{(\log_{10}|H_2| - \log_{10}|H_1|)^2}
          {\sigma_{m,1}^2 + \sigma_{m,2}^2} + \operatorname{mean}_k \frac{(\angle H_2 - \angle H_1)^2}
          {\sigma_{\phi,1}^2 + \sigma_{\phi,2}^2}\right]

with the files' noise levels per frequency where they state a coherence
(:func:`~bscomp.validate.noise.noise_levels`), else the difference's own noise: the robust scale of the third
differences of :math:`\log_{10}|H_2/H_1|` and of its phase, in which the drive's response cancels (a file's own
scatter on a sparse stepped sine is mostly the resonance's curvature: on the FE truths' 8 points 10-200 Hz it
read a 26 dB difference as :math:`\chi^2` 6), and a smooth amplitude dependence barely shows; never below
:data:`RESOLUTION` (0.1 dB, 1 degree). :math:`\chi^2_A \approx 1` where the two differ by noise (a noise read
from the difference is believed up to :data:`NOISE_CREDIBLE`, 1 dB and 6 degrees: beyond it, two files not
found apart are *undetermined*, not the same); above :data:`CHI2_LIMIT` (with a noise read from fewer than 20
points, above the 99 % quantile of :data:`H0_Q99`) the drive is **amplitude-dependent** there: a nonlinearity
(friction, backlash) acts in the band, which no linear effect -- and no small-signal model, the one
``diagnose`` and ``calibrate`` fit FRFs with -- can explain at both amplitudes. :func:`~bscomp.validate.compare` and
:func:`~bscomp.validate.diagnose` report it.

Only frequencies present in both files are compared (within 1e-6 relative): interpolating a resonance between
points would make differences of its own.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from bscomp.errors import BscompError
from bscomp.kernel.flattening import flatten
from bscomp.simulation.describing import describing_frf, frequency_share
from bscomp.validate.datasets import FrfData
from bscomp.validate.noise import FLOOR, noise_levels, robust_sigma

__all__ = ["AmplitudeDependence", "amplitude_dependence", "frf_confirmation", "amplitude_note", "stuck_note",
           "CHI2_LIMIT", "RESOLUTION", "NOISE_CREDIBLE", "H0_Q99"]

CHI2_LIMIT = 4.0
"""Normalised difference above which two amplitudes' FRFs differ by more than noise."""
H0_Q99 = ((6, 76.0), (8, 23.0), (10, 13.0), (14, 5.9), (20, 4.0))
r"""99th percentile of :math:`\chi^2_A` when the difference is pure white noise and its level is read from its own
third differences at ``n`` common frequencies (4000 Monte-Carlo draws; ``tests/bscomp/validate/test_amplitude.py``
re-draws it): the limit for a scatter-read noise is the larger of this and :data:`CHI2_LIMIT`, so that two
files of a linear drive are called amplitude-dependent in at most 1 % of cases however few their points."""
MIN_COMMON = 6
"""Fewest common frequencies for a comparison (third differences need six points)."""
NOISE_CREDIBLE = (1.0, 6.0)
"""Largest noise [dB, deg] of a difference read from its own scatter that is believed to be noise: above it the
scatter is mostly the response's shape (the FE truths' stepped sines: 3-25 dB and 4-36 deg read on the friction
truth's differences at 8-14 frequencies, 0.1 dB and 1 deg on the linear truth's with 1 % noise), and two
files that do not differ beyond it are *undetermined*, not the same."""
RESOLUTION = (0.1 / 20.0, math.radians(1.0))
"""Least noise of a difference [log10 units, rad]: 0.1 dB and 1 degree, a stepped sine's settling and a
measurement's repeatability; smaller differences are never reported as amplitude dependence."""


@dataclass
class AmplitudeDependence:
    """One pair measured at two amplitudes (:func:`amplitude_dependence`).

    Attributes
    ----------
    pair : (str, str)
        ``(input, output)``.
    amplitudes : (float, float)
        The lower and the higher excitation amplitude (SI).
    sources : (str, str)
        The files, in the same order.
    freqs : ndarray
        The common frequencies [Hz].
    db : ndarray
        ``20 log10 |H_high / H_low|`` per frequency [dB].
    phase_deg : ndarray
        Wrapped phase of ``H_high / H_low`` per frequency [deg].
    z : ndarray
        Normalised difference per frequency (the root of the mean of its two squared whitened terms).
    chi2 : float
        Normalised difference (module docstring); 1 = noise.
    noise : (float, float)
        The median noise level of the difference used [dB, deg].
    stated : bool
        True when it came from a stated coherence, False when read from the difference's scatter.
    """

    pair: tuple
    amplitudes: tuple
    sources: tuple
    freqs: np.ndarray
    db: np.ndarray
    phase_deg: np.ndarray
    z: np.ndarray
    chi2: float
    noise: tuple = (0.0, 0.0)
    stated: bool = False

    @property
    def limit(self) -> float:
        r"""The :math:`\chi^2_A` above which the two differ beyond noise: :data:`CHI2_LIMIT`, raised for a noise read
        from few points (:data:`H0_Q99`)."""
        if self.stated:
            return CHI2_LIMIT
        n, q = np.array(H0_Q99, float).T
        return float(max(CHI2_LIMIT, np.exp(np.interp(math.log(self.freqs.size), np.log(n), np.log(q)))))

    @property
    def significant(self) -> bool:
        """True if the two amplitudes differ by more than noise (``chi2 > limit``)."""
        return bool(self.chi2 > self.limit)

    @property
    def verdict(self) -> str:
        """``"amplitude-dependent"``, ``"same"`` (within a credible noise) or ``"undetermined"`` (not beyond a
        noise read from too few points to be believed: :data:`NOISE_CREDIBLE`)."""
        if self.significant:
            return "amplitude-dependent"
        if self.stated or (self.noise[0] <= NOISE_CREDIBLE[0] and self.noise[1] <= NOISE_CREDIBLE[1]):
            return "same"
        return "undetermined"

    @property
    def rms_db(self) -> float:
        return float(np.sqrt(np.mean(self.db ** 2)))

    @property
    def worst(self) -> tuple:
        """``(frequency [Hz], dB)`` of the largest magnitude difference."""
        k = int(np.argmax(np.abs(self.db)))
        return float(self.freqs[k]), float(self.db[k])

    @property
    def band(self):
        """``(f_low, f_high)`` [Hz] spanning the frequencies where the two differ by more than twice their noise
        (``z > 2``), or None."""
        k = np.flatnonzero(self.z > 2.0)
        return (float(self.freqs[k[0]]), float(self.freqs[k[-1]])) if k.size else None

    def summary(self) -> str:
        i, o = self.pair
        lo, hi = self.amplitudes
        f, db = self.worst
        head = (f"{o}/{i} at {hi:g} vs {lo:g}: {self.rms_db:.2f} dB rms apart (largest {db:+.1f} dB at {f:.4g} Hz), "
                f"phase {float(np.sqrt(np.mean(self.phase_deg ** 2))):.1f} deg rms; chi^2 {self.chi2:.3g}")
        if self.significant:
            b = self.band
            where = f" between {b[0]:.4g} and {b[1]:.4g} Hz" if b else ""
            return (head + f" > {self.limit:.3g}: the drive is amplitude-dependent{where} (friction or backlash act "
                    "there; no linear effect explains both amplitudes)")
        if self.verdict == "same":
            return head + ": within the noise of both files (linear at these amplitudes)"
        return (head + f": undetermined -- the noise read from these {self.freqs.size} frequencies "
                f"({self.noise[0]:.2g} dB, {self.noise[1]:.2g} deg) is mostly the response's own shape; measure "
                "more frequencies or state the coherence")

    def to_dict(self) -> dict:
        return {"pair": list(self.pair), "amplitudes": list(self.amplitudes), "sources": list(self.sources),
                "freqs": self.freqs.tolist(), "db": self.db.tolist(), "phase_deg": self.phase_deg.tolist(),
                "z": self.z.tolist(), "band": self.band, "chi2": self.chi2, "rms_db": self.rms_db,
                "limit": self.limit, "significant": self.significant, "verdict": self.verdict,
                "noise_db_deg": list(self.noise), "noise_stated": self.stated, "summary": self.summary()}


def _conditions_key(d) -> tuple:
    return tuple(sorted((k, str(v)) for k, v in (d.conditions or {}).items()))


def _common(f1, f2):
    """Indices ``(i1, i2)`` of the frequencies of ``f1`` and ``f2`` that agree to 1e-6 relative."""
    f1, f2 = np.asarray(f1, float), np.asarray(f2, float)
    j = np.searchsorted(f2, f1)
    cand = np.clip(np.stack([j - 1, j]), 0, f2.size - 1)          # the neighbours of each f1 in f2
    near = cand[np.argmin(np.abs(f2[cand] - f1), axis=0), np.arange(f1.size)]
    ok = np.abs(f2[near] - f1) <= 1e-6 * np.maximum(np.abs(f1), 1e-300)
    return np.flatnonzero(ok), near[ok]


def _sigma_at(s, idx):
    return np.asarray(s, float)[idx] if np.ndim(s) else np.full(idx.size, float(s))


def amplitude_dependence(datasets) -> list:
    """Every pair measured at two (or more) stated excitation amplitudes under the same conditions, compared with
    itself (module docstring): one :class:`AmplitudeDependence` per pair and pair of amplitudes (the lowest
    against each higher one), most significant first. FRF files without a stated amplitude, or with fewer than
    :data:`MIN_COMMON` common frequencies, are not compared."""
    frfs = [d for d in datasets if isinstance(d, FrfData) and d.excitation]
    levels = [noise_levels(d) for d in frfs]
    groups = {}
    for k, d in enumerate(frfs):
        for idx, pair in enumerate(d.H):
            a = d.excitation.get(pair[0])
            if a:
                groups.setdefault((pair, _conditions_key(d)), []).append((float(a), k, idx))
    out = []
    for (pair, _), members in groups.items():
        members.sort()
        a_lo, k_lo, i_lo = members[0]
        for a_hi, k_hi, i_hi in members[1:]:
            if a_hi <= a_lo * (1 + 1e-9):
                continue
            d1, d2 = frfs[k_lo], frfs[k_hi]
            j1, j2 = _common(d1.freqs, d2.freqs)
            if j1.size < MIN_COMMON:
                continue
            h1, h2 = np.asarray(d1.H[pair], complex)[j1], np.asarray(d2.H[pair], complex)[j2]
            r = h2 / h1
            dmag = np.log10(np.abs(r))
            dph = np.angle(r)
            s1, s2 = levels[k_lo][2 * i_lo:2 * i_lo + 2], levels[k_hi][2 * i_hi:2 * i_hi + 2]
            stated = bool(np.ndim(s1[0]) or np.ndim(s2[0]))
            if stated:                                # a stated coherence: the files' levels per frequency
                sm = np.sqrt(_sigma_at(s1[0], j1) ** 2 + _sigma_at(s2[0], j2) ** 2)
                sp = np.sqrt(_sigma_at(s1[1], j1) ** 2 + _sigma_at(s2[1], j2) ** 2)
            else:                                     # the difference's own scatter: the response cancels in it
                sm, sp = robust_sigma(dmag, FLOOR), robust_sigma(np.unwrap(dph), FLOOR)
            sm, sp = np.maximum(sm, RESOLUTION[0]), np.maximum(sp, RESOLUTION[1])
            z2 = 0.5 * ((dmag / sm) ** 2 + (dph / sp) ** 2)
            chi2 = float(np.mean(z2))
            noise = (float(20.0 * np.median(sm)), float(np.degrees(np.median(sp))))
            out.append(AmplitudeDependence(pair=pair, amplitudes=(a_lo, a_hi), sources=(d1.source, d2.source),
                                           freqs=np.asarray(d1.freqs, float)[j1], db=20.0 * dmag,
                                           phase_deg=np.degrees(dph), z=np.sqrt(z2),
                                           chi2=chi2 if math.isfinite(chi2) else math.inf, noise=noise,
                                           stated=stated))
    out.sort(key=lambda x: -x.chi2)
    return out


def frf_confirmation(amplitude, datasets, harmonics: int = 1) -> tuple:
    """``(why a linear effect is not confirmed, why a nonlinear one is not)`` by ``datasets``, ``""`` each where it is.

    FRFs measured at a stated sine amplitude (``FrfData.excitation``) confirm little on their own. A linear
    effect fitted to them may stand for friction or backlash acting at that amplitude (on the FE truths' stepped
    sines at 2 V: a fake bearing housing for Coulomb friction, a fake nut-table joint for arc-tangent friction;
    ``docs/validation.md``); it is confirmed by a time series (held-out halves) or by the same pairs at a second
    amplitude found the same (:func:`~bscomp.validate.amplitude.amplitude_dependence`), and refuted by pairs
    found amplitude-dependent. A nonlinear effect is fitted to them by the harmonic balance of its law
    (``harmonics`` odd orders): with one harmonic a clearance's imitates friction's (the FE truth ``friction`` at
    2 V: a compliant backlash accepted); with five the clearance is told apart but the friction law's level and
    shape are not pinned (the same truth's arc-tangent friction, 1151 N, at 0.2 and 2 V: F_c 2891 N fitted,
    ``docs/validation.md``); only a time series confirms it."""
    at_amp = [d for d in datasets if isinstance(d, FrfData) and d.excitation]
    if not at_amp or any(not isinstance(d, FrfData) for d in datasets):
        return "", ""
    balance = "one harmonic" if harmonics == 1 else f"{harmonics} odd harmonics"
    nonlinear = (f"it was fitted to FRFs alone by the harmonic balance ({balance}), which does not pin a friction "
                 "law's level and shape" + (" and where a clearance can imitate friction and the reverse"
                                            if harmonics == 1 else "")
                 + "; record a time series (a square wave or a reversal)")
    sig = [a for a in amplitude if a.significant]
    if sig:
        a = sig[0]
        return (f"the FRFs measured at {a.amplitudes[0]:g} and {a.amplitudes[1]:g} on {a.pair[0]} differ beyond "
                f"their noise ({a.pair[1]} {a.rms_db:.1f} dB rms apart): no linear effect explains both; record a "
                "time series (a square wave or a reversal) for friction and backlash"), nonlinear
    if any(a.verdict == "same" for a in amplitude):
        return "", nonlinear
    exc = "; ".join(sorted({", ".join(f"{v:g} on {k}" for k, v in d.excitation.items()) for d in at_amp}))
    return (f"the FRFs were measured at one stated amplitude ({exc}) and nothing else confirms them: a linear "
            "effect fitted to them may stand for friction or backlash acting at that amplitude; measure the FRFs "
            "at a second amplitude (found the same: linear) or record a time series"), nonlinear


def amplitude_note(amplitude, datasets) -> str:
    """A sentence for the message when FRFs measured at two amplitudes differ beyond noise."""
    sig = [a for a in amplitude if a.significant]
    if not sig:
        return ""
    a = sig[0]
    b = a.band
    where = f" between {b[0]:.4g} and {b[1]:.4g} Hz" if b else ""
    has_time = any(not isinstance(d, FrfData) for d in datasets)
    what = ("the friction and backlash candidates were fitted to the time series" if has_time else
            "diagnose fits FRFs at their stated amplitudes by the harmonic balance but confirms friction and "
            "backlash by a time series only: give a record of a square wave or a reversal")
    return (f". The FRFs measured at {a.amplitudes[0]:g} and {a.amplitudes[1]:g} on {a.pair[0]} differ beyond their "
            f"noise ({a.pair[1]} {a.rms_db:.1f} dB rms apart{where}, chi^2 {a.chi2:.3g}): a nonlinearity acts there; "
            f"{what}")


def stuck_note(setup, result, recalibrated) -> str:
    """Where a nonlinear candidate fitted to FRFs at stated amplitudes stays at its slope at rest: ``"; at 0.2 on
    amp.u the fitted friction stays at its slope at rest at 13 of 14 frequencies (...): ..."`` or ``""``.

    The candidate is added with its fitted values to the model at each such file's conditions (the uncertain
    parameters at ``recalibrated``) and balanced at the file's amplitude (one harmonic,
    :meth:`~bscomp.simulation.describing.DescribingFrf.small_signal`): where its element's force stays within
    5 % of its tangent at rest, friction is stuck on its regularised slope and the file measures ``F_c / v_reg``,
    not ``F_c`` (the FE truth ``friction`` at 0.2 V: F_c 2891 N fitted for 1151 N, ``docs/validation.md``)."""
    cand = result.candidate
    if not cand.nonlinear:
        return ""
    parts, fitted = [], {}
    for d, key in zip(setup.datasets, setup.keys, strict=True):
        if not (isinstance(d, FrfData) and d.excitation):
            continue
        if key not in fitted:                          # the fitted model, flattened once per condition
            s = setup.systems[key].copy()
            for k, v in recalibrated.items():
                s.set(k, v)
            s = cand.apply(s, **result.values)
            fitted[key] = (flatten(s), set(cand.added(s)))
        dae, mine = fitted[key]
        for inp, a in d.excitation.items():
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    r = describing_frf(dae, inp, [o for i, o in d.H if i == inp], d.freqs, a)
            except BscompError:
                continue
            parts += [f"at {a:g} on {inp} the fitted {el} stays at its slope at rest {frequency_share(r.freqs, f)}"
                      for el, f in r.small_signal().items() if el in mine]
    if not parts:
        return ""
    what = cand.slope_at_rest or "its slope at rest"
    return (f"; {'; '.join(parts)}: there those files measure its slope at rest ({what}), not its level -- an FRF at "
            "a larger amplitude, or a time series, pins the level")
