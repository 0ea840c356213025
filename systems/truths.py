"""Truth systems for testing a diagnosis on data the candidates did not make (issue 13, point 6).

A *truth* is the FE test bed of :mod:`bscomp.systems.testbed` (``"axial_torsional"`` or ``"full"``) as
the real drive would differ from the model a user has:

* **mis-set uncertain parameters**: the table mass heavier and the coupling stiffness off by a few per
  cent (drawn per seed, recorded);
* **another FE mesh**: the threaded section C meshed with 30, 34, 45 or 52 elements instead of the
  parameter file's 39 (a modified copy of ``fadal_vmc2216_x.toml`` in a temporary folder);
* **the moving nut** (``nut_joint="moving"``): the nut travels with the table in the time series;
* and at most two **hidden effects**, each with a structure of its own (no class of
  :mod:`bscomp.validate.candidates` is used here):

  ``joint``
      a part of the table (20-60 kg, taken out of the table so the total mass stays) on its own axial
      spring and dashpot beside the nut (3-5 % of critical), the spring chosen so that the truth has an
      undamped mode at a frequency drawn between the drive's first two modes.
  ``friction``
      guideway friction with its own smoothing, ``f = F_c (2/pi) atan(v / v_s) + d v``
      (:class:`AtanFriction`; F_c 800-3000 N, v_s 20-100 um/s, d 500-2000 N s/m).
  ``backlash``
      a clearance of total width b = 5-40 um on the nut-table line, with a finite contact stiffness
      (1e9-3e9 N/m) switched in smoothly (softplus over a width of 5 % of b, :class:`SoftBacklash`).
  ``delay``
      an amplifier / D-A delay T = 0.1-1.0 ms, applied exactly: ``e^{-j omega T}`` on the FRF, the input
      shifted on the integration grid (8 points per sample) in the time series.
  ``joint_friction``
      ``joint`` and ``friction`` together.
  ``ripple``
      an effect **outside the candidates' library**: the motor's torque ripple (cogging),
      ``tau = A sin(p phi + phi_0)`` on the rotor (:class:`TorqueRipple`; A 1-3 % of the square wave's
      peak torque, p 6-12 periods per revolution, phi_0 uniform). A diagnosis should not name a
      candidate for it: the honest answer is that the error stays, unexplained.

  ``housing``
      the thrust bearing's housing is not rigid (the block Sec 3.5.2.3 blames for a missing mode): the
      angular-contact pair ``b1`` un-grounded, its outer ring on a seat (5-15 % of the housing's mass)
      joined by a stiff seat spring (10-30x the fasteners, log) to the housing block, the block on its
      fasteners to the frame -- two bodies and two springs (no class of the candidates), 15-60 kg in all,
      the fastener stiffness chosen so that the truth has an undamped mode at a frequency drawn in 400-900 Hz
      (inside the FRF band), each spring with a dashpot of 2-5 % of critical (:class:`HeldBodyDamping`: the
      drive's modal damping as with the rigid housing).

  ``damping``
      the drive is damped more than the model's modal ratios (Tables 4.1/4.2: 6 %, 10 %) say, by two dashpots
      the model does not have -- axial at the thrust bearing ``b1`` (its ``c_axial``, to the frame) and
      torsional across the coupling's insert (a ``TorsionalDamper``) -- sized so that the drive's first mode
      gains 1-4 and its second (the coupling's torsion) 1-5 percentage points of critical damping: a loss
      by location, not the same ratio on every mode as the ``extra_damping`` candidate adds.

  ``control`` has none of them (mis-set parameters, mesh and moving nut only).

  ``bearing_friction`` (one of :data:`EXTRA_CASES`: drawn by seed, no bundled data)
      friction that is not at the guideways: a torque on the screw at the thrust bearing ``b1`` (its bearings,
      seals and the preloaded nut), ``tau = T_c (2/pi) atan(w / w_s) + d w`` (:class:`AtanTorqueFriction`; T_c
      0.3-1.5 N m, 5-23 % of the square wave's peak motor torque, w_s 0.01-0.06 rad/s, d 5e-4-5e-3 N m s/rad).
      The thesis keeps friction at the guideways only (Sec 5.2.2.1); on a drive with roller guideways this
      torque is often the larger part.

Every random value comes from ``numpy.random.default_rng([seed, stream])``: the same seed gives the
same truth and the same noise. Values are drawn uniformly (the stiffnesses log-uniformly) within
physical ranges, not at the prior medians of any candidate.

Measurements (:func:`make_frf`, :func:`make_time`) use the amplifier voltage ``amp.u`` [V] as the
input and the channels and sign convention of the test bed (``table.s`` positive in the direction a
positive voltage moves the table). :func:`generate_case` writes ``frf.csv``, ``time.csv`` (with
:func:`bscomp.validate.measurements.write_frf_csv` / ``write_time_csv``, condition ``nut_position``)
and ``truth.json``; ``examples/make_truth_data.py`` writes the bundled set in ``systems/data/truths``.
"""

from __future__ import annotations

import inspect
import json
import math
import tempfile
import time as _time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bscomp.components import Damper, Fixed, FixedRotational, Mass, NodeToRotFlange, Spring

from .parameters import get_value, load_parameters, write_variant
from .testbed import testbed, thesis_parameters
from .truth_effects import (
    AtanFriction,
    AtanTorqueFriction,
    HeldBodyDamping,
    RigidJointDamping,
    SoftBacklash,
    TorqueRipple,
)
from .truth_parts import add_dashpots, add_housing, drive_modes, joint_stiffness

__all__ = ["CASES", "EXTRA_CASES", "MODELS", "AtanFriction", "SoftBacklash", "RigidJointDamping", "HeldBodyDamping",
           "draw",
           "truth_system",
           "make_frf", "make_time", "generate_case", "DRIVES", "drive_overrides",
           "default_seed", "square_wave", "TIME_NOISE", "FRF_NOISE",
           "TorqueRipple"]

CASES = ("control", "joint", "friction", "backlash", "delay", "joint_friction", "ripple", "housing", "damping")
MODELS = ("axial_torsional", "full")
HIDDEN = {"control": (), "joint": ("joint",), "friction": ("friction",), "backlash": ("backlash",),
          "delay": ("delay",), "joint_friction": ("joint", "friction"), "ripple": ("ripple",),
          "housing": ("housing",), "damping": ("damping",), "bearing_friction": ("bearing_friction",)}
#: Cases drawn by seed only (no bundled data in ``systems/data/truths``; ``benchmarks/diagnose_table.py --case``).
EXTRA_CASES = ("bearing_friction",)

#: Ranges of the random draws (uniform; ``log`` = log-uniform).
RANGES = {
    "nut_position": (0.153, 0.712),        # L..R, toml table.nut_position_L/R [m]
    "mesh_C": (30, 34, 45, 52),            # elements of section C (the model: 39)
    "table_mass_factor": (1.05, 1.10),     # truth / nominal (250 kg, a CAD estimate, Sec B.3)
    "coupling_factor": (0.05, 0.08),       # |truth / nominal - 1|, sign drawn (k_T from one test, Sec B.4)
    "joint_mass": (20.0, 60.0),            # kg
    "joint_frequency": (0.2, 0.8),         # position of the target between the drive's first two modes
    "joint_zeta": (0.03, 0.05),
    "friction_F_c": (800.0, 3000.0),       # N (Table 5.2: 2066)
    "friction_v_s": (2.0e-5, 1.0e-4),      # m/s, log
    "friction_d": (500.0, 2000.0),         # N s/m, extra guideway viscous part
    "backlash_b": (5.0e-6, 40.0e-6),       # m, total gap
    "backlash_c": (1.0e9, 3.0e9),          # N/m, log (screw-nut axial stiffness: 1.7e9)
    "delay_T": (1.0e-4, 1.0e-3),           # s
    "ripple_fraction": (0.01, 0.03),       # torque ripple amplitude / the square wave's peak torque
    "ripple_periods": (6, 12),             # ripple periods per motor revolution (integers, inclusive)
    "housing_mass": (15.0, 60.0),          # kg, seat + block ("a huge block", Sec 3.5.2.3)
    "housing_seat_fraction": (0.05, 0.15),  # seat (bearing ring and its bore) / housing mass
    "housing_seat_ratio": (10.0, 30.0),    # seat stiffness / fastener stiffness, log
    "housing_frequency": (400.0, 900.0),   # Hz, the truth's extra mode: inside the FRF band (2 Hz - 1 kHz)
    "housing_zeta": (0.02, 0.05),
    "damping_mode1": (0.01, 0.04),         # added ratio of the first drive mode (model: 6 %, Table 4.1)
    "damping_mode2": (0.01, 0.05),         # added ratio of the second, the coupling's torsion (model: 10 %, Table 4.2)
    "bearing_T_c": (0.3, 1.5),             # N m, friction torque on the screw (peak motor torque 6.6 N m)
    "bearing_w_s": (0.01, 0.06),           # rad/s, log (the guideway v_s range over r_g = 1.6 mm/rad)
    "bearing_d": (5.0e-4, 5.0e-3),         # N m s/rad (the motor's B: 0.0321)
}
#: The drives truths are made of (``drive=``): parameter-file changes and build options. ``"other"`` is a drive
#: that is not the thesis's, built from the same components, to try a diagnosis on a drive whose numbers none of
#: its rules, starts or bounds were ever checked on: a table with a fixture (450 kg instead of 250), a larger motor
#: (rotor 1.1e-2 instead of 5.98e-3 kg m^2), one angular-contact bearing instead of the pair (1.35e8 N/m axial,
#: Sec B.5's single-bearing value, instead of 2.7e8) and the bellows coupling (45 940 N m/rad, Sec 4.4.1) -- its
#: first axial and torsional modes move from ~122 / 284 Hz to ~75 / 507 Hz (docs/validation.md, "Another drive").
DRIVES = {"thesis": {"params": {}, "build": {}},
          "other": {"params": {"table.mass": 450.0, "rotor.Izz": 1.1e-2, "bearings.b1_k_axial": 1.35e8},
                    "build": {"coupling": "bellows"}}}
BACKLASH_WIDTH = 0.05                      # softplus width / b

FRF_NOISE = 0.02                           # complex multiplicative, relative standard deviation
TIME_NOISE = {"rotor.phi": 2.0e-4, "rotor.w": 0.01, "table.s": 3.0e-7, "table.a": 0.05}
OUTPUTS = ("rotor.phi", "rotor.w", "table.s", "table.a")
DT, DURATION, FINE = 2.0e-4, 0.6, 8        # 5 kHz, 0.6 s, integration grid 8x finer (25 us)
AMPLITUDE, FREQUENCY = 2.125, 5.0          # Sec 5.3.1: 4.25 V peak-to-peak, 5 Hz


# ---- random draws ------------------------------------------------------------------------------------
def default_seed(case: str, model: str = "axial_torsional") -> int:
    """The seed of the bundled data set: ``1300 + 10 * model index + case index`` (:data:`EXTRA_CASES` after
    :data:`CASES`)."""
    return 1300 + 10 * MODELS.index(model) + (CASES + EXTRA_CASES).index(case)


def draw(seed: int) -> dict:
    """Every random value of a truth, drawn in a fixed order (a case uses those of its effects)."""
    rng = np.random.default_rng([int(seed), 0])
    R = RANGES
    u = lambda key: float(rng.uniform(*R[key]))                                    # noqa: E731
    logu = lambda key: float(np.exp(rng.uniform(*np.log(R[key]))))                 # noqa: E731
    d = {"nut_position": round(u("nut_position"), 4), "mesh_C": int(rng.choice(R["mesh_C"])),
         "table_mass_factor": u("table_mass_factor")}
    d["coupling_factor"] = 1.0 + float(rng.choice([-1.0, 1.0])) * u("coupling_factor")
    d["joint"] = {"m": u("joint_mass"), "frequency_position": u("joint_frequency"), "zeta": u("joint_zeta")}
    d["friction"] = {"F_c": u("friction_F_c"), "v_s": logu("friction_v_s"), "d": u("friction_d")}
    d["backlash"] = {"b": u("backlash_b"), "c": logu("backlash_c")}
    d["backlash"]["w"] = BACKLASH_WIDTH * d["backlash"]["b"]
    step = DT / FINE                             # the exact delay is a whole number of integration steps
    d["delay"] = {"T": round(u("delay_T") / step) * step}
    # drawn last: the draws above (and so every truth generated before this case existed) are unchanged
    lo, hi = R["ripple_periods"]
    d["ripple"] = {"fraction": u("ripple_fraction"), "p": int(rng.integers(lo, hi + 1)),
                   "phase": float(rng.uniform(0.0, 2.0 * math.pi))}
    d["housing"] = {"m": u("housing_mass"), "seat_fraction": u("housing_seat_fraction"),
                    "seat_ratio": logu("housing_seat_ratio"), "f_target": u("housing_frequency"),
                    "zeta": u("housing_zeta")}
    d["damping"] = {"mode1": u("damping_mode1"), "mode2": u("damping_mode2")}
    d["bearing_friction"] = {"T_c": u("bearing_T_c"), "w_s": logu("bearing_w_s"), "d": u("bearing_d")}
    return d


# ---- the truth system --------------------------------------------------------------------------------
def _mesh_params(n_C: int, drive: str = "thesis") -> Path:
    """A copy of the parameter file of ``drive`` (:data:`DRIVES`) with ``n_C`` elements in section C (in a
    temporary folder)."""
    changes, _ = _drive(drive)
    total = 1 + 1 + int(n_C) + 2 + 2 + 2
    name = "fadal_vmc2216_x" if drive == "thesis" else f"{drive}_drive"
    return write_variant({**changes, "screw.sections.C.n_elements": int(n_C), "screw.n_elements": total},
                         _variant_path(f"{name}_C{int(n_C)}.toml"))


def _variant_path(name: str) -> Path:
    """Where the truths' parameter-file variants are written (a temporary folder shared by the processes)."""
    return Path(tempfile.gettempdir()) / "bscomp_truths" / name


def _drive(drive: str) -> tuple[dict, dict]:
    if drive not in DRIVES:
        raise ValueError(f"truths: unknown drive {drive!r}; use one of {sorted(DRIVES)}")
    return DRIVES[drive]["params"], DRIVES[drive]["build"]


def drive_overrides(drive: str = "thesis") -> dict:
    """The build arguments of the *model* of ``drive`` (:data:`DRIVES`): its parameter file with the model's own
    mesh and its build options -- ``diagnose(..., overrides=drive_overrides("other"))`` on a test bed name, or the
    CLI's ``--set params=... --set coupling=...``."""
    changes, build = _drive(drive)
    if not changes:
        return dict(build)
    return {"params": str(write_variant(changes, _variant_path(f"{drive}_drive.toml"))), **build}


def _voltage_input() -> bool:
    return "drive_input" in inspect.signature(testbed).parameters


def _base(model, x, params: Path, build: dict, misset, nut_joint="moving"):
    """The test bed at nut position ``x`` from the truth's parameter file (its drive and mesh) and build options,
    with its mis-set parameters (no hidden effect)."""
    kw = {"drive_input": "voltage"} if _voltage_input() else {}
    s = testbed(model, nut_position=x, nut_joint=nut_joint, params=str(params), **kw, **build)
    for k, f in misset.items():
        s.set(k, float(s.get(k)) * f)
    return s


def truth_system(case: str, model: str = "axial_torsional", seed: int | None = None, *, linear: bool = False,
                 nut_joint: str = "moving", drive: str = "thesis"):
    """The truth of ``case`` on the test bed ``model``, drawn with ``seed``.

    Parameters
    ----------
    case : str
        One of :data:`CASES` or :data:`EXTRA_CASES`.
    model : {"axial_torsional", "full"}
    seed : int, optional
        Default :func:`default_seed` ``(case, model)``.
    linear : bool
        Return :meth:`System.linear_equivalent` (friction: its viscous part; backlash: the contact spring).
    nut_joint : {"moving", "point"}
        The nut joint of the truth (the bundled time series use ``"moving"``; linearized at rest both agree).
    drive : str
        Which drive (:data:`DRIVES`): ``"thesis"``, the test bed of the bundled data, or ``"other"``, another drive
        built from the same components; its model is the test bed with :func:`drive_overrides`.

    Returns
    -------
    (System, dict)
        The truth and ``info``: case, model, seed, nut position, mesh, mis-set factors, the hidden values
        (``joint``: spring ``k`` [N/m], moving mass ``m`` [kg], dashpot ``d``, ``zeta``, target and the
        drive's first two modes; ``friction``: ``F_c``, ``v_s``, ``d``; ``backlash``: ``b``, ``c``,
        ``w``; ``delay``: ``T`` [s], not in the system: apply it exactly as :func:`make_frf` and
        :func:`make_time` do) and the input name.
    """
    if case not in CASES + EXTRA_CASES:
        raise ValueError(f"truths: unknown case {case!r}; use one of {CASES + EXTRA_CASES}")
    if model not in MODELS:
        raise ValueError(f"truths: unknown model {model!r}; use one of {MODELS}")
    seed = default_seed(case, model) if seed is None else int(seed)
    dr = draw(seed)
    x = dr["nut_position"]
    changes, build = _drive(drive)
    path = _mesh_params(dr["mesh_C"], drive)
    p = load_parameters(path)
    m_total = get_value(p, "table.mass") * dr["table_mass_factor"]
    misset = {"table.m": dr["table_mass_factor"], "coupling.k_T": dr["coupling_factor"]}
    s = _base(model, x, path, build, misset, nut_joint)
    coupling_truth = float(s.get("coupling.k_T"))
    hidden = {}
    base_damping = s.damping
    if "joint" in HIDDEN[case]:
        j = dr["joint"]
        f12 = drive_modes(s)                       # the drive's first two modes, table rigid on the nut
        s.set("table.m", m_total - j["m"])
        s.add("table_part", Mass(m=j["m"]))
        s.add("part_spring", Spring(c=1.0))        # k -> 0 first: the table-on-drive mode without the part
        s.add("part_damper", Damper(d=1.0))
        for el in ("part_spring", "part_damper"):
            s.connect("table.flange_a", f"{el}.flange_a")
            s.connect(f"{el}.flange_b", "table_part.flange_a")
        s.damping = RigidJointDamping(base_damping, "table_part.s")
        f0 = drive_modes(s)[0]
        lo = max(f12[0], f0)
        f_t = lo + j["frequency_position"] * (f12[1] - lo)
        k = joint_stiffness(s, j["m"], f_t)
        d = 2.0 * j["zeta"] * math.sqrt(k * j["m"])
        s.set("part_spring.c", k)
        s.set("part_damper.d", d)
        hidden["joint"] = {"k": k, "m": j["m"], "d": d, "zeta": j["zeta"], "f_target": f_t,
                           "f_drive": [float(v) for v in f12], "table_m": m_total - j["m"]}
    if "friction" in HIDDEN[case]:
        fr = dr["friction"]
        s.add("guide_ground", Fixed())
        s.add("guide_friction", AtanFriction(F_c=fr["F_c"], v_s=fr["v_s"], d=fr["d"]))
        s.connect("guide_ground.flange", "guide_friction.flange_a")
        s.connect("guide_friction.flange_b", "table.flange_b")
        hidden["friction"] = dict(fr)
    if "backlash" in HIDDEN[case]:
        bl = dr["backlash"]
        s.insert("clearance", SoftBacklash(b=bl["b"], c=bl["c"], w=bl["w"]),
                 between=("table_joint.flange", "table.flange_a"))
        s.damping = RigidJointDamping(base_damping, "table.s")
        hidden["backlash"] = dict(bl)
    if "bearing_friction" in HIDDEN[case]:
        bf = dr["bearing_friction"]
        s.add("bearing_frame", FixedRotational())
        s.add("bearing_node", NodeToRotFlange())
        s.add("bearing_friction", AtanTorqueFriction(T_c=bf["T_c"], w_s=bf["w_s"], d=bf["d"]))
        s.connect("bearing_node.node", "screw.b1")
        s.connect("bearing_frame.flange", "bearing_friction.flange_a")
        s.connect("bearing_friction.flange_b", "bearing_node.flange")
        hidden["bearing_friction"] = dict(bf)
    if "housing" in HIDDEN[case]:
        hidden["housing"] = add_housing(s, dr["housing"], base_damping)
    if "damping" in HIDDEN[case]:
        hidden["damping"] = add_dashpots(s, dr["damping"])
    if "delay" in HIDDEN[case]:
        hidden["delay"] = dict(dr["delay"])
    if "ripple" in HIDDEN[case]:
        rp = dr["ripple"]
        tau_peak = get_value(p, "electrical.K_a") * get_value(p, "electrical.K_t") * AMPLITUDE
        A = rp["fraction"] * tau_peak
        s.add("ripple_frame", FixedRotational())
        s.add("ripple", TorqueRipple(A=A, p=float(rp["p"]), phi_0=rp["phase"]))
        s.connect("ripple_frame.flange", "ripple.flange_a")
        s.connect("ripple.flange_b", "rotor.flange_a")
        hidden["ripple"] = {"A": A, "p": rp["p"], "phi_0": rp["phase"], "fraction_of_peak_torque": rp["fraction"]}
    s.name = f"truth_{case}_{model}"
    info = {"case": case, "model": model, "seed": seed, "nut_position": x, "nut_joint": nut_joint,
            "drive": {"name": drive, "parameters": changes, "build": build},
            "mesh": {"section_C_elements": dr["mesh_C"],
                     "model_section_C_elements": int(get_value(thesis_parameters(), "screw.sections.C.n_elements"))},
            "misset": {"table.m": {"factor": dr["table_mass_factor"], "truth": m_total},
                       "coupling.k_T": {"factor": dr["coupling_factor"], "truth": coupling_truth}},
            "hidden": hidden, "input": "amp.u" if _voltage_input() else "motor.tau"}
    return (s.linear_equivalent() if linear else s), info


# ---- measurements ------------------------------------------------------------------------------------
def _convert(inp: str) -> tuple[float, float]:
    """(input scale to volts, table-channel sign) for a test bed without the voltage input: the torque
    input with tau = K_a K_t u (Eq 4.1) and, as that version had it, the table along the screw's +z."""
    if inp == "amp.u":
        return 1.0, 1.0
    p = thesis_parameters()
    return get_value(p, "electrical.K_a") * get_value(p, "electrical.K_t"), -1.0


def _source(seed: int, what: str) -> str:
    return f"synthetic {what} of an FE test-bed truth (bscomp.systems.truths, seed {seed}; see truth.json)"


def make_frf(case: str, model: str = "axial_torsional", seed: int | None = None, *, freqs=None,
             noise: float = FRF_NOISE, drive: str = "thesis"):
    """FRF data of a truth: ``amp.u`` -> ``rotor.w`` and -> ``table.a`` at the truth's nut position.

    From the truth's linear equivalent (:func:`bscomp.linear.response.frf`), times ``e^{-j omega T}`` for a hidden
    delay, times ``1 + eps`` with ``eps`` complex normal of relative standard deviation ``noise``
    (seeded, stream ``[seed, 1]``); coherence 1.

    Returns
    -------
    (FrfData, dict)
        The data (condition ``nut_position``) and the truth's ``info`` with ``frf_noise_free``
        ``{(input, output): H}``.
    """
    from bscomp.linear.response import frf
    from bscomp.validate.measurements import FrfData

    s, info = truth_system(case, model, seed, linear=True, drive=drive)
    seed = info["seed"]
    f = np.logspace(np.log10(2.0), 3.0, 300) if freqs is None else np.asarray(freqs, float)
    inp = info["input"]
    scale, sign = _convert(inp)
    # the moving nut is linearized at its position: what an FRF measured with the nut standing there is
    r = frf(s, inp, ["rotor.w", "table.a"], freqs=f, warn=False)
    T = info["hidden"].get("delay", {}).get("T", 0.0)
    lag = np.exp(-2j * np.pi * f * T)
    rng = np.random.default_rng([seed, 1])
    H, H0, coh = {}, {}, {}
    for j, (out, sg) in enumerate((("rotor.w", 1.0), ("table.a", sign))):
        h = r.H[:, j, 0] * scale * sg * lag
        eps = noise / math.sqrt(2.0) * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
        H0[("amp.u", out)] = h
        H[("amp.u", out)] = h * (1.0 + eps)
        coh[("amp.u", out)] = np.ones(f.size)
    units = {("amp.u", "rotor.w"): "rad/s/V", ("amp.u", "table.a"): "m/s^2/V"}
    data = FrfData(freqs=f, H=H, units=units, conditions={"nut_position": info["nut_position"]}, coherence=coh,
                   source=_source(seed, "FRF"))
    info["frf_noise_free"] = H0
    info["frf"] = {"freqs_hz": [float(f[0]), float(f[-1]), int(f.size)], "spacing": "log",
                   "noise": f"complex multiplicative, relative std {noise} (re, im each {noise}/sqrt 2)",
                   "coherence": 1.0, "from": "linear equivalent of the truth at rest (System.linear_equivalent)"}
    return data, info


def square_wave(n: int, dt: float = DT, amplitude: float = AMPLITUDE, frequency: float = FREQUENCY):
    """The Sec 5.3.1 command at samples ``k = 0..n-1``: +amplitude first, switching every half period
    (a whole number of samples)."""
    half = int(round(0.5 / (frequency * dt)))
    k = np.arange(n)
    return amplitude * np.where((k // half) % 2 == 0, 1.0, -1.0)


def make_time(case: str, model: str = "axial_torsional", seed: int | None = None, *, duration: float = DURATION,
              dt: float = DT, fine: int = FINE, method: str = "idas", rtol: float = 1e-7, atol: float = 1e-10,
              noise: dict | None = None, nut_joint: str = "moving", progress: bool = False, drive: str = "thesis"):
    """Square-wave time series of a truth (Sec 5.3.1: +-2.125 V, 5 Hz) from rest at the nut position.

    The truth (moving nut) is integrated by :func:`bscomp.simulation.simulate` on a grid ``fine`` times the
    sample rate, the command held per sample (D/A) and delayed by a hidden ``T`` (a whole number of grid
    steps: exact); outputs ``rotor.phi``, ``rotor.w``, ``table.s``, ``table.a`` are sampled at ``dt`` and
    get white noise of standard deviations :data:`TIME_NOISE` (seeded, stream ``[seed, 2]``).

    Returns
    -------
    (TimeData, dict)
        The data (input ``amp.u``, condition ``nut_position``) and ``info`` with ``time`` (method,
        tolerances, wall time) and ``time_noise_free``.
    """
    from bscomp.simulation.dispatch import simulate
    from bscomp.validate.measurements import TimeData

    s, info = truth_system(case, model, seed, nut_joint=nut_joint, drive=drive)
    seed = info["seed"]
    n = int(round(duration / dt))
    t = np.round(np.arange(n + 1) * dt, 12)
    u = square_wave(n + 1, dt)
    tf = np.arange(n * fine + 1) * (dt / fine)
    shift = int(round(info["hidden"].get("delay", {}).get("T", 0.0) / (dt / fine)))
    kf = np.arange(n * fine) - shift                 # fine interval k holds the command of sample (k - shift) // fine
    uf = np.where(kf >= 0, u[np.clip(kf, 0, None) // fine], 0.0)
    inp = info["input"]
    scale, sign = _convert(inp)
    kw = {"rtol": rtol, "atol": atol} if method == "idas" else {}
    t0 = _time.perf_counter()
    r = simulate(s, tf, inputs={inp: uf * scale}, outputs=list(OUTPUTS), method=method, max_num_steps=10**7,
                 progress=progress, **kw)
    wall = _time.perf_counter() - t0
    sig = dict(TIME_NOISE, **(noise or {}))
    rng = np.random.default_rng([seed, 2])
    Y0, Y = {}, {}
    for name in OUTPUTS:
        y = np.asarray(r[name], float)[::fine] * (sign if name.startswith("table.") else 1.0)
        Y0[name] = y
        Y[name] = y + sig[name] * rng.standard_normal(y.size)
    units = {"amp.u": "V", "rotor.phi": "rad", "rotor.w": "rad/s", "table.s": "m", "table.a": "m/s^2"}
    data = TimeData(t=t, inputs={"amp.u": u}, outputs=Y, units=units,
                    conditions={"nut_position": info["nut_position"]}, source=_source(seed, "square-wave run"))
    info["time_noise_free"] = Y0
    info["time"] = {"duration_s": duration, "dt_s": dt, "integration_grid_s": dt / fine, "method": method,
                    **({"rtol": rtol, "atol": atol} if method == "idas" else {}), "wall_s": wall,
                    "nut_joint": nut_joint, "noise_std": sig,
                    "input": f"square wave +-{AMPLITUDE} V, {FREQUENCY} Hz, positive first, held per sample",
                    "stats": {k: float(v) for k, v in r.stats.items() if isinstance(v, (int, float))}}
    return data, info


def _rounded(a, digits):
    return np.array([float(f"{v:.{digits}g}") for v in np.asarray(a, float)])


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def generate_case(case: str, model: str, out_dir, seed: int | None = None, *, time: bool = True,
                  drive: str = "thesis", freqs=None, **time_kw) -> dict:
    """Write ``frf.csv``, ``time.csv`` (unless ``time=False``) and ``truth.json`` of one truth of ``drive``
    (:data:`DRIVES`) into ``out_dir/model/case``; returns ``{"frf": path, "time": path, "truth": path,
    "info": info}``. ``freqs`` goes to :func:`make_frf`, ``time_kw`` (e.g. ``dt``) to :func:`make_time`."""

    from bscomp.validate.measurements import write_frf_csv, write_time_csv

    folder = Path(out_dir) / model / case
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    t0 = _time.perf_counter()
    frf_data, info = make_frf(case, model, seed, freqs=freqs, drive=drive)
    frf_wall = _time.perf_counter() - t0
    info.pop("frf_noise_free")
    frf_data = replace(frf_data, H={k: _rounded(v.real, 9) + 1j * _rounded(v.imag, 9) for k, v in frf_data.H.items()})
    out["frf"] = write_frf_csv(frf_data, folder / "frf.csv")
    info["frf"]["wall_s"] = frf_wall
    info["files"] = {"frf": "frf.csv"}
    if time:
        time_data, tinfo = make_time(case, model, info["seed"], drive=drive, **time_kw)
        info["time"] = tinfo["time"]
        time_data = replace(time_data, outputs={k: _rounded(v, 8) for k, v in time_data.outputs.items()})
        out["time"] = write_time_csv(time_data, folder / "time.csv")
        info["files"]["time"] = "time.csv"
    info["generator"] = "bscomp.systems.truths.generate_case"
    info["draw_ranges"] = {k: list(v) for k, v in RANGES.items()}
    path = folder / "truth.json"
    path.write_text(json.dumps(_jsonable(info), indent=2) + "\n")
    out["truth"], out["info"] = path, info
    return out
