"""Synthetic measurements with a hidden effect: the test bench of :func:`~bscomp.validate.diagnostics.diagnose`.

The *truth* is the nominal drive with (a) one or more hidden effects from the candidate library at
chosen values and (b) slightly mis-set nominal parameters. From it:

* **FRF data** -- amplifier voltage to motor speed and to table acceleration, as a stepped-sine / H1
  estimate would give them: coherence ``gamma^2 = 1 / (1 + (eps max|H| / |H|)^2)`` (it drops at
  anti-resonances, where the output is near the noise floor ``eps``), and a complex relative error
  with variance ``(1 - gamma^2) / (n_avg gamma^2)`` (Bendat & Piersol's H1 random error). A hidden
  delay enters the FRF **exactly** (``e^{-j omega T}``), not through the Padé model that is fitted.
  Nonlinear effects (friction, backlash) are not in the FRF (large-amplitude excitation).
* **Time data** -- a square-wave voltage (thesis Sec 5.3.1: 4.25 V peak-to-peak, 5 Hz) applied
  open loop through the current amplifier; the truth is integrated by IDAS (rtol 1e-9) on a grid of
  8 sub-steps per sample (more where a hidden delay must be a whole number of them; the fit uses another
  engine, :class:`bscomp.simulation.compiled.CompiledModel`), a hidden delay as an exact shift of the input on
  that fine grid. Sensors: motor encoder 10 000 counts/rev, tachometer
  noise, linear encoder 1 um, accelerometer noise and 16-bit quantisation over +-50 m/s^2.

The nominal drive is an argument (a System, or anything :func:`bscomp.model.as_system` resolves; by
default the registered ``"validation_drive"``). Everything is seeded; :func:`write_demo_data` writes the
CSV files (:mod:`bscomp.validate.writers`) and a README naming the hidden effects and the seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from bscomp.errors import UsageError
from bscomp.files import atomic_write
from bscomp.linear.response import frf as model_frf
from bscomp.model import as_system
from bscomp.simulation.dispatch import simulate
from bscomp.validate.candidates import default_candidates
from bscomp.validate.datasets import FrfData, TimeData
from bscomp.validate.writers import write_frf_csv, write_time_csv

__all__ = ["generate", "SyntheticData", "truth_system", "write_demo_data", "TRUTH_VALUES", "MISSET"]

TRUTH_VALUES = {
    "nut_table_joint": {"k": 3.0e8, "d": 5.0e3},
    "guideway_compliance": {"m": 25.0, "k": 8.0e8},
    "bearing_housing": {"m": 8.0, "k": 6.0e8},
    "missing_inertia": {"J": 1.5e-3},
    "guideway_friction": {"F_c": 2066.0},
    "guideway_stribeck": {"F_c": 2066.0, "F_s": 500.0},
    "screw_nut_backlash": {"b": 2.0e-5},
    "amplifier_delay": {"T": 4.0e-4},
    "extra_damping": {"zeta": 0.03},
}
"""Default hidden values: Table 5.2 friction (2066 N); a worn nut's 20 um clearance; a 0.4 ms D/A +
amplifier latency (two 0.2 ms sample periods, Eq 4.17); a joint 2x stiffer than the lumped axial chain."""

MISSET = {"table.m": 1.06, "coupling.c": 0.93}
"""Default truth/nominal factors of mis-set nominal parameters (the CAD table mass is 6 % light, the
coupling 7 % stiff)."""


@dataclass
class SyntheticData:
    """Generated measurements and what produced them."""

    frf: FrfData
    time: TimeData
    hidden: dict
    misset: dict
    seed: int
    truth: object = None
    info: dict = field(default_factory=dict)

    @property
    def datasets(self) -> list:
        return [self.frf, self.time]


def _library():
    return {c.name: c for c in default_candidates()}


def truth_system(nominal, hidden: dict, misset: dict | None = None, linear: bool = False, exact_delay=True):
    """Nominal with mis-set parameters and hidden effects ``{candidate name: values}`` applied.

    With ``exact_delay`` a hidden ``amplifier_delay`` is left out (the generator applies it exactly).
    """
    lib = _library()
    s = nominal.copy()
    for k, f in (misset or {}).items():
        s.set(k, float(s.get(k)) * f)
    for name, values in hidden.items():
        if name == "amplifier_delay" and exact_delay:
            continue
        cand = lib[name]
        s = cand.structure(s, linear=linear)
        if cand.nonlinear and linear:
            continue
        for k, v in cand.overrides(cand.check({**cand.medians(), **values}), s).items():
            s.set(k, v)
    return s


def square_wave(t, amplitude=2.125, frequency=5.0):
    """The Sec 5.3.1 excitation: +-amplitude [V], starting positive, D/A-quantised (12 bit, +-10 V)."""
    u = amplitude * np.where(np.floor(2 * frequency * t + 1e-9) % 2 == 0, 1.0, -1.0)
    q = 20.0 / 4096
    return np.round(u / q) * q


def _substeps(delay: float, dt: float, least: int = 8) -> int:
    """Integration sub-steps per sample: at least ``least``, and a whole number of them in ``delay``, so the
    delayed input is exact on the fine grid (with 8 sub-steps of 0.5 ms a 0.4 ms delay would round to
    0.375 ms in the time series while the FRF has 0.4 ms: a truth inconsistent with itself)."""
    if delay <= 0:
        return least
    frac = Fraction(delay / dt).limit_denominator(64)
    if abs(float(frac) * dt - delay) > 1e-9 * delay:
        raise UsageError(f"hidden delay {delay:g} s is not a rational multiple p/q (q <= 64) of the sample "
                         f"interval {dt:g} s: the time series could not apply it exactly")
    q = frac.denominator
    return q * -(-least // q)


def generate(hidden: dict | None = None, misset: dict | None = None, seed: int = 0, nominal="validation_drive",
             freqs=None, n_avg: int = 20, eps: float = 3e-3, duration: float = 0.2, dt: float = 5e-4,
             amplitude: float = 2.125, frequency: float = 5.0, noise: dict | None = None) -> SyntheticData:
    """Measurements of a truth = nominal + hidden effects + mis-set parameters.

    Parameters
    ----------
    hidden : dict, optional
        ``{candidate name: {parameter: value}}``; values default to :data:`TRUTH_VALUES`. ``{}``: none.
    misset : dict, optional
        ``{dotted parameter: truth / nominal factor}`` (default :data:`MISSET`).
    seed : int
    nominal : System, str or callable, optional
        The nominal drive, resolved by :func:`bscomp.model.as_system` (default the registered
        ``"validation_drive"``; None means the same).
    freqs : array, optional
        FRF frequencies [Hz] (default 300 log-spaced, 2 Hz to 1 kHz).
    n_avg, eps : FRF averages and relative output noise floor (see the module docstring).
    duration, dt, amplitude, frequency : time record [s], sample interval [s], square wave [V], [Hz].
    noise : dict, optional
        Sensor noise standard deviations ``{"rotor.w": 0.05, "table.a": 0.02}`` (SI).

    Returns
    -------
    SyntheticData
    """
    nominal = as_system("validation_drive" if nominal is None else nominal)
    hidden = {k: {**TRUTH_VALUES.get(k, {}), **(v or {})} for k, v in (hidden or {}).items()}
    misset = dict(MISSET if misset is None else misset)
    rng = np.random.default_rng(seed)
    inp = getattr(nominal, "input", "amp.u")
    outs = list(getattr(nominal, "outputs", ["rotor.phi", "rotor.w", "table.s", "table.a"]))
    delay = hidden.get("amplifier_delay", {}).get("T", 0.0)

    # ---- FRF ----
    freqs = np.logspace(np.log10(2.0), 3.0, 300) if freqs is None else np.asarray(freqs, float)
    # the small-signal equivalent, as compare and diagnose model an FRF: a nominal's own friction or backlash (not
    # only a hidden candidate's) enters by its viscous part / contact spring, not by its tangent at rest (stuck)
    lin = truth_system(nominal, hidden, misset, linear=True).linear_equivalent()
    res = model_frf(lin, input=inp, output=["rotor.w", "table.a"], freqs=freqs)
    H = {(inp, o): res.H[:, res.outputs.index(o), 0] for o in ("rotor.w", "table.a")}
    Hm, coh, units = {}, {}, {}
    for pair, h in H.items():
        h = h * np.exp(-2j * np.pi * freqs * delay)
        g2 = 1.0 / (1.0 + (eps * np.max(np.abs(h)) / np.abs(h)) ** 2)
        var = (1 - g2) / (n_avg * g2)
        err = np.sqrt(var / 2) * (rng.standard_normal(h.size) + 1j * rng.standard_normal(h.size))
        Hm[pair] = h * (1 + err)
        coh[pair] = g2
        units[pair] = "rad/s/V" if pair[1] == "rotor.w" else "m/s^2/V"
    frf = FrfData(freqs=freqs, H=Hm, units=units, coherence=coh,
                  source=f"synthetic FRF (bscomp.validate.synthetic, seed {seed})")

    # ---- time series ----
    sub = _substeps(delay, dt)
    t = np.arange(int(round(duration / dt)) + 1) * dt
    u = square_wave(t, amplitude, frequency)
    uf = np.repeat(u[:-1], sub)
    uf = np.r_[uf, u[-1]]
    if delay > 0:
        shift = int(round(delay / (dt / sub)))
        uf = np.r_[np.zeros(shift), uf[:len(uf) - shift]]
    nl = truth_system(nominal, hidden, misset, linear=False)
    tf = np.arange(uf.size) * (dt / sub)
    sim = simulate(nl, tf, inputs={inp: uf}, outputs=outs, rtol=1e-9, atol=1e-12)
    Y = np.vstack([np.asarray(sim[n], float) for n in outs])[:, ::sub]
    sig = {"rotor.phi": 0.0, "rotor.w": 0.05, "table.s": 0.0, "table.a": 0.02, **(noise or {})}
    quant = {"rotor.phi": 2 * np.pi / 10000, "table.s": 1e-6, "table.a": 100.0 / 65536}
    meas = {}
    for i, name in enumerate(outs):
        y = Y[i] + sig.get(name, 0.0) * rng.standard_normal(len(t))
        q = quant.get(name)
        meas[name] = np.round(y / q) * q if q else y
    tunits = {inp: "V", "rotor.phi": "rad", "rotor.w": "rad/s", "table.s": "m", "table.a": "m/s^2"}
    time = TimeData(t=t, inputs={inp: u}, outputs=meas, units={k: tunits.get(k, "") for k in [inp] + outs},
                    source=f"synthetic square-wave run (bscomp.validate.synthetic, seed {seed})")
    return SyntheticData(frf=frf, time=time, hidden=hidden, misset=misset, seed=seed,
                         info={"truth_frf_noise_free": H, "truth_time_noise_free": dict(zip(outs, Y))})


def write_demo_data(directory, hidden: dict | None = None, seed: int = 2024, **kwargs) -> list:
    """Generate and write ``frf.csv``, ``time.csv`` and a README to ``directory``; returns the paths."""
    hidden = {"nut_table_joint": {}, "guideway_friction": {}} if hidden is None else hidden
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    data = generate(hidden=hidden, seed=seed, **kwargs)
    p1 = write_frf_csv(data.frf, d / "frf.csv")
    p2 = write_time_csv(data.time, d / "time.csv")
    lines = ["# Validation demo data (SYNTHETIC)", "",
             "These files are **synthetic**: generated by `bscomp.validate.synthetic.write_demo_data` from the",
             "nominal `validation_drive` with hidden effects and mis-set parameters, to demonstrate",
             "`bscomp compare` and `bscomp diagnose`. They are not measurements of the thesis test bed.", "",
             f"- seed: {seed}",
             "- hidden effects: " + "; ".join(f"{k} {v}" for k, v in data.hidden.items()),
             "- mis-set nominal parameters (truth / nominal): "
             + ", ".join(f"{k} x{v}" for k, v in data.misset.items()),
             "- `frf.csv`: amplifier voltage -> motor speed and table acceleration, 2 Hz - 1 kHz, with coherence",
             "- `time.csv`: 4.25 V peak-to-peak 5 Hz square wave (thesis Sec 5.3.1), 0.2 s at 2 kHz", "",
             "Regenerate: `python -c \"from bscomp.validate.synthetic import write_demo_data; "
             f"write_demo_data('systems/data/validation', seed={seed})\"`", ""]
    with atomic_write(d / "README.md") as fh:
        fh.write("\n".join(lines))
    return [Path(p1), Path(p2), d / "README.md"]
