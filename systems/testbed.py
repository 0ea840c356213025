"""The thesis test bed: x-axis ballscrew feed drive of the Fadal VMC 2216 (thesis Sec 3.5, Ch 4, Ch 5).

Composed only from components; every number comes from ``systems/data/fadal_vmc2216_x.toml`` (loaded
with :func:`bscomp.systems.parameters.load_parameters`; the screw and the screw-nut interface through
:mod:`bscomp.systems.thesis_parts`), whose entries cite the thesis table or equation.

Layout (thesis Sec 3.5.1, Fig 3.3), axial coordinate ``x`` = screw axis ``z`` of the FE model, ``x = 0``
at the free end of section A, increasing towards section F (toml ``[meta].coordinate``)::

    x=0    b2 (deep-groove, radial)        nut (P)                     b1 (angular-contact pair)   x=0.9205
     |A|B|--------------- C (thread, 39 elements) ---------------|D|E|F|--coupling--rotor <- motor <- kt <- amp <- amp.u
                                          |
                                        table (250 kg, z only; rigid box way), Fd.f

* ``screw``: :class:`Ballscrew`, Timoshenko FE of Table B.1 (47 elements, stiffness from the root
  diameter, mass from the equivalent diameter of Eq 3.1; E, rho, nu, k^s from Sec B.1 / Eq A.6).
* ``b1``: angular-contact pair, ``k_axial`` 2.70e8, ``k_radial`` 1.9e8 N/m (Table 3.1, Sec B.5),
  grounded (rigid housing, Sec 3.5.2.3); ``b2``: floating deep-groove bearing, radial 4e7 N/m.
* ``sn``: :class:`ScrewNut`, rigid-ballscrew K_SN (Eq 3.35; Table 3.1 / B.3: 100 balls, 20.7 N/um,
  alpha 4.55 deg, beta 50 deg, +-1800 deg) between the screw point ``screw.nut`` and the nut.
* ``nut``: :class:`RigidBody` (1.49 kg, Table 3.1). Bolted to the table, which the rigid box way lets
  move only along z (Sec 3.5.1): the nut keeps only ``w``. This is what closes the loop of the rank-5
  K_SN: with the nut's rotation held, the free helical relative motion of the interface becomes the
  drive's single rigid-body mode (screw turns, table advances ``r_g`` per radian). In the free-free
  tests (Sec 3.5.2.2) the nut keeps all six DOF.
* ``table``: :class:`Mass` 250 kg (Table 3.1) on the nut's ``w``; disturbance force input ``Fd.f``.
* ``B``: rigid-body viscous damping B = 0.0321 kg m^2/s at the motor shaft (Sec 4.2.1, Eq 4.2), used once:
  ``viscous="guide"`` puts the same damping on the table instead (12 673 N s/m, Table 5.2).
* ``coupling``: :class:`Coupling`, k_T 3938 N m/rad (Sec B.4; bellows 45 940, Sec 4.4.1), jaws J1/J2;
  ``rotor``: :class:`Inertia` 5.98e-3 kg m^2 (Table 3.1) driven by the torque source ``motor``.
* Input (``drive_input``): by default the amplifier command voltage ``amp.u`` [V], the channel users
  measure: ``amp`` (:class:`CurrentAmplifier`, K_a = 6.4898 A/V) and ``kt`` (:class:`Gain`, K_t = 0.4769
  N m/A) in series before ``motor.tau`` (Eq 4.1: current mode, G_e = K_a K_t, as in
  :mod:`bscomp.systems.validation_drive`). ``drive_input="torque"`` leaves the torque ``motor.tau`` [N m]
  as the input (the Ch 4 plant, the form the design equations of Sec 4.2-4.5 are written in).
* Damping: :class:`DriveModalDamping`, 6 % (mode 1), 10 % (mode 2), 6 % (others) (Tables 4.1/4.2, toml
  ``[damping]``), rigid-body mode undamped (Sec 5.2.2.1).

Sign convention
---------------
Motor angle ``rotor.phi`` is positive about the screw axis +z (right-hand rule). Table position and
acceleration (``table.s``, ``table.a``) and the disturbance force ``Fd.f`` are along the machine's table
axis, positive in the direction a positive command moves the table (thesis Eq 4.2: G_x = r_g / s and
G_d = r_g / (J s + B); the same as :mod:`bscomp.systems.validation_drive`): a positive voltage or torque
gives a positive motor angle and a positive table position, ``table.s = r_g rotor.phi`` at low frequency
(r_g = lead / 2 pi = 1.59e-3 m/rad), and a positive ``Fd.f`` pushes the table forward.
The screw's thread is right-handed (Eq 3.12), so a positive screw rotation drives the nut towards -z: the
table axis is the screw's -z axis, and the nut-to-table joint ``table_joint`` (:class:`NodeToFlange`)
carries ``direction = -1``. The FE coordinates stay in screw z: the nut's ``nut.w``, the moving joint's
nut position ``sn.z0 + nut.w`` and every screw node are measured along +z from the free end of section A.

Validation interface
--------------------
Every drive variant declares ``s.validation`` (:class:`bscomp.kernel.interface.ValidationInterface`): the
measured input (``amp.u``, or ``motor.tau``) and outputs (``rotor.phi``, ``rotor.w``, ``table.s``,
``table.a``), the uncertain parameters with spreads (table mass, coupling stiffness, thrust-bearing
stiffness) and insertion points by role (nut-table joint, table on its guideways, thrust support ``b1``,
coupling, amplifier, rotor, table, whole structure). See ``docs/validation.md``.

Choices where the thesis is silent (toml notes starting with CHOICE; see ``docs/testbed-sensitivity.md``
for how the results move with each): the motor at the F end, the angular-contact pair acting at the
middle node of section E (x = 875.5 mm), the deep-groove bearing at the middle of section B (a screw point
at x = 33.5 mm; its radial stiffness reaches B's two nodes through the shape functions of Eq 3.27), the
coupling's screw-side jaw J2 on the end node of F, J1 on the motor shaft (rigid, sharing the rotor DOF),
the table travel 22 in centred on the thread (L/C/R = 153.1/432.5/711.9 mm) and the free-free nut
positions 1/2/3 = 92.5/432.5/772.5 mm.

Build with :func:`testbed` or by name through :func:`bscomp.systems.get`, e.g.
``get("testbed", {"nut_position": 0.43})``: a key without a dot is a build argument (the nut position
is fixed when the screw's point ports are made), a dotted key a parameter override.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp

from bscomp import System
from bscomp.components import (
    Bearing,
    Bushing,
    Coupling,
    CurrentAmplifier,
    Damper,
    Fixed,
    FixedRotational,
    Force,
    Gain,
    Inertia,
    LinearGuide,
    Mass,
    MovingScrewNut,
    NodeToFlange,
    NodeToRotFlange,
    RigidBody,
    Torque,
    TorsionalDamper,
)
from bscomp.errors import ModelDefinitionError, UsageError
from bscomp.kernel.damping import matrix_from_ratios
from bscomp.kernel.interface import InsertionPoint, UncertainParameter, ValidationInterface

from .parameters import get_value
from .testbed_options import VARIANTS, check_choices, check_geometry
from .thesis_parts import thesis_ballscrew, thesis_parameters, thesis_screw_nut, thesis_sections

__all__ = [
    "testbed", "testbed_free_screw", "testbed_screw_nut", "testbed_no_table", "testbed_full",
    "testbed_axial_torsional", "testbed_submodel1", "testbed_bellows", "testbed_appendix_c",
    "VARIANTS", "nut_positions", "thesis_parameters", "DriveModalDamping", "drive_fraction",
]

#: Verification steps of thesis Sec 3.5.2 and the models of Ch 4/5 and App C.

def nut_positions(params: str = "fadal_vmc2216_x") -> dict:
    """Named nut-centre positions x [m]: ``L``, ``C``, ``R`` (Tables 4.1/4.2) and ``1``, ``2``, ``3``
    (free-free tests, Tables 3.2/3.3). All CHOICE entries of the toml ``[table]`` group."""
    p = thesis_parameters(params)
    ff = get_value(p, "table.free_free_positions")
    return {"L": get_value(p, "table.nut_position_L"), "C": get_value(p, "table.nut_position_C"),
            "R": get_value(p, "table.nut_position_R"), "1": ff[0], "2": ff[1], "3": ff[2]}


def _position(value, named: dict) -> float:
    if isinstance(value, str):
        if value not in named:
            raise ModelDefinitionError(f"testbed: unknown named nut position {value!r}; use a number [m] or "
                                       f"one of {sorted(named)}")
        return float(named[value])
    return float(value)


#: Coordinate fields of bending/radial motion; every other coordinate (axial w, torsion tz, phi, s, and the
#: generalized coordinates q of an axial + torsional CMS superelement) belongs to the drive.
BENDING_FIELDS = ("u", "v", "tx", "ty")


def drive_fraction(shapes, M, coordinates) -> np.ndarray:
    """Share of each mode's kinetic energy ``phi^T M phi`` in the axial/torsional (non-bending) coordinates."""

    drive = np.array([c.rsplit(".", 1)[-1] not in BENDING_FIELDS for c in coordinates], float)
    M = sp.csr_matrix(M)
    total = np.sum(shapes * (M @ shapes), axis=0)
    sd = shapes * drive[:, None]                                # (D phi)^T M (D phi), D the drive mask
    drive_e = np.sum(sd * (M @ sd), axis=0)
    return drive_e / np.where(total > 0, total, 1.0)


class DriveModalDamping:
    """Modal damping (Eq A.10-A.15) with the ratios of Tables 4.1/4.2 given by mode *character*.

    Tables 4.1/4.2 damp the first and second modes seen from the motor -- the axial screw-nut mode
    (6 %) and the coupling torsion mode (10 %). In the 6-DOF model screw bending modes can fall between
    them (e.g. at the L position), so ascending order (:class:`bscomp.kernel.damping.ModalDamping`) would give
    10 % to a bending mode. Here ``zeta1``/``zeta2`` go to the first two elastic modes whose kinetic
    energy is mostly axial/torsional (:func:`drive_fraction` > 0.5), ``zeta_other`` to every other
    elastic mode; the rigid-body mode gets none (Sec 5.2.2.1). Without coordinate names (older
    kernels) it falls back to ascending order.
    """

    needs_coordinates = True

    def __init__(self, zeta1: float, zeta2: float, zeta_other: float):
        self.zeta = (float(zeta1), float(zeta2), float(zeta_other))

    def modal_ratios(self, lam, phi, M, coordinates=None) -> np.ndarray:
        """Damping ratio of each mode of ``K phi = M phi lam`` (ascending, mass-normalised); 0 for rigid."""
        rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
        z = np.full(lam.size, self.zeta[2])
        el = np.flatnonzero(~rigid)
        if coordinates is None:
            drive = el[:2]
        else:
            drive = el[drive_fraction(phi[:, el], M, coordinates) > 0.5][:2]
        z[drive] = self.zeta[: drive.size]
        z[rigid] = 0.0
        return z

    def matrix(self, M, K, coordinates=None):
        return matrix_from_ratios(self, M, K, coordinates)

    def __repr__(self):
        return "DriveModalDamping(zeta1={}, zeta2={}, zeta_other={})".format(*self.zeta)


def testbed(variant: str = "full", nut_position="C", *, dofs=None, coupling: str = "jaw",
            motor_end: str | None = None, b1_position: float | None = None, b2_position: float | None = None,
            coupling_position: float | None = None, root_diameter: float | None = None,
            jaw1: str = "motor", ksn: str = "full", pitch: float | None = None, damping: bool = True,
            viscous: str = "motor", nut_joint: str = "point", drive_input: str = "voltage",
            params: str = "fadal_vmc2216_x", n_elements: int | None = None) -> System:
    """Build the test bed (or one of its verification steps) as a :class:`bscomp.System`.

    Parameters
    ----------
    variant : str
        ``"free_screw"`` (Sec 3.5.2.1: the free-free screw), ``"screw_nut"`` (Sec 3.5.2.2: free-free
        screw with the free 6-DOF nut), ``"no_table"`` (Sec 3.5.2.3: screw, bearings and nut on the
        frame, no table, coupling or rotor), ``"full"`` (Sec 3.5.2.4 / Ch 4), ``"axial_torsional"``
        (Ch 5: the full drive with the axial and torsional DOF only, sub-models 1 + 2 of Table 5.1),
        ``"submodel1"`` (Table 5.1/5.3: screw, bearings, coupling, rotor; axial + torsional) or
        ``"appendix_c"`` (App C: table+nut one rigid body on four roller slides, Table C.1).
    nut_position : float or str
        Nut centre x [m], or a named position ``"L"``, ``"C"``, ``"R"`` (Tables 4.1/4.2) or ``"1"``,
        ``"2"``, ``"3"`` (Tables 3.2/3.3), see :func:`nut_positions`. Ignored without a nut.
    dofs : tuple of str, optional
        FE fields per screw node; default all six (``("w", "tz")`` for the Ch 5 variants).
    coupling : {"jaw", "bellows"}
        Jaw coupling k_T = 3938 N m/rad (Sec B.4) or the bellows coupling 45 940 N m/rad (Sec 4.4.1).
    motor_end : {"F", "A"}, optional
        Screw end at the motor (toml CHOICE "F"). ``"A"`` mirrors the support layout: coupling at
        x = 0, thrust pair and floating bearing at the mirrored distances from the ends.
    b1_position, b2_position, coupling_position : float, optional
        x [m] of the angular-contact pair, the deep-groove bearing and the screw-side jaw
        (toml CHOICEs 0.8755 / 0.0335 / 0.9205, for ``motor_end="F"``).
    root_diameter : float, optional
        Stiffness diameter [m] of the thread, in (bore 0.012, 1) (Table B.1: 35.5 mm default; Table 3.1 prints 40 mm).
    jaw1 : {"motor", "screw"}
        Where J1 sits: on the motor shaft (toml CHOICE) or with J2 on the screw side (sensitivity only).
    ksn : {"full", "axial_torsional"}
        Interface matrix: the full K_SN of Eq 3.35/3.45, or only its direct terms plus the axial-torsional
        coupling (Eq 3.46, Case A of App C; built as a :class:`Bushing` with the same 6x6 block).
    pitch : float, optional
        Lead [m] > 0 of the interface for the App C pitch study (default Sec B.1's 10 mm); alpha follows
        Eq 3.6 with d_p = 40 mm when given.
    damping : bool
        Attach the modal damping of the toml ``[damping]`` group (drive variants only) as
        :class:`DriveModalDamping`: 6 % / 10 % on the first / second axial-torsional mode, 6 % on all
        others, none on the rigid-body mode.
    viscous : {"motor", "guide", "none"}
        Where the rigid-body viscous damping acts: ``"motor"`` = B = 0.0321 kg m^2/s on the rotor (Sec
        4.2.1, Eq 4.2: it damps the rigid-body mode; the elastic modes keep their Table 4.1 ratios to
        0.5 %: 6.03 % / 10.02 %), ``"guide"`` = 12 673 N s/m on the table (Table 5.2; the same B seen from
        the table, which also raises the 120 Hz mode's ratio by 3.0 points, to 9.0 %), or ``"none"``.
    nut_joint : {"point", "moving"}
        How the interface reaches the screw: ``"point"`` = a point port of the screw at the nut position
        (shape-function constraint, re-made for every position) or ``"moving"`` = a
        :class:`MovingScrewNut` attached to every screw node at the nut's current position
        ``sn.z0 + nut.w`` (Sec 5.2.2.3). Linearized at rest both give the same matrices (to round-off,
        tests/systems/test_testbed_moving.py); with ``"moving"`` the position is the ordinary parameter
        ``sn.z0``, so one flattening serves every position (fast sweeps) and the nut can travel in time
        simulations. Needs ``ksn="full"``.
    drive_input : {"voltage", "torque"}
        System input of the drive variants: the amplifier command voltage ``amp.u`` [V] (default; amplifier
        ``amp`` with K_a and torque constant ``kt`` with K_t of Eq 4.1 in series before the motor torque),
        or the motor torque ``motor.tau`` [N m] (the Ch 4 plant the design equations are written for).
    params : str
        Parameter set name or path (default the thesis test bed).
    n_elements : int, optional
        About this many screw elements, Table B.1's counts scaled (47 by default; for mesh-growth studies).

    Returns
    -------
    System
        With ``position_parameter = "nut_position"`` (``"sn.z0"`` for ``nut_joint="moving"``) where a nut
        exists, ``sources`` citing the thesis, ``build_args`` (the resolved choices) and, for the drive
        variants, ``validation`` (:class:`~bscomp.kernel.interface.ValidationInterface`, see the module docstring).
    """
    check_choices(variant, coupling=coupling, ksn=ksn, nut_joint=nut_joint, jaw1=jaw1, viscous=viscous,
                   drive_input=drive_input)
    p = thesis_parameters(params)
    v = lambda key: get_value(p, key)  # noqa: E731
    motor_end = check_geometry(v, root_diameter, pitch, motor_end)
    if dofs is None:
        dofs = ("w", "tz") if variant in ("axial_torsional", "submodel1") else ("u", "v", "w", "tx", "ty", "tz")
    dofs = tuple(dofs)
    sections = _scaled_mesh(thesis_sections(d_root=root_diameter, params=params), n_elements)
    x_b1, x_b2, x_cp = _support_positions(v, motor_end, sum(s.length for s in sections), b1_position,
                                          b2_position, coupling_position)
    has_nut = variant not in ("free_screw", "submodel1")
    has_drive = variant in ("full", "axial_torsional", "submodel1", "appendix_c")
    has_bearings = variant not in ("free_screw", "screw_nut")
    x_nut = _position(nut_position, nut_positions(params)) if has_nut else None

    s = System(_NAMES[variant] + ("_bellows" if coupling == "bellows" else ""))
    s.description = _DESCRIPTIONS[variant] + (f", {coupling} coupling" if has_drive else "")
    src = {}
    points = {"nut": x_nut} if has_nut and nut_joint == "point" else {}
    if has_bearings:
        points["b1"], points["b2"] = x_b1, x_b2
    if has_drive:
        points["coupling"] = x_cp
    # ---- screw (Table B.1, Sec B.1, Eq 3.1, Eq A.6)
    s.add("screw", thesis_ballscrew(dofs=dofs, points=points, d_root=root_diameter, params=params, sections=sections))
    src.update({"screw": "Table B.1; Sec B.1 (E, rho, nu); Eq 3.1 (d_e); Eq A.6 (k^s)",
                "screw.nut": f"nut centre x = {x_nut} m (toml table.nut_position_*, CHOICE)" if has_nut else ""})
    if has_bearings:
        _add_bearings(s, v, x_b1, x_b2, src)
    if has_nut:
        _add_nut(s, v, params, variant, x_nut, ksn, nut_joint, pitch, viscous, src)
    if has_drive:
        _add_drive(s, v, variant, coupling, jaw1, viscous, drive_input, damping, x_cp, src)

    s.sources = {k: t for k, t in src.items() if t}
    if has_drive:
        s.validation = _validation_interface(s, variant, drive_input)
    if has_nut:
        s.position_parameter = "nut_position" if nut_joint == "point" else "sn.z0"
    s.build_args = dict(variant=variant, nut_position=x_nut, dofs=dofs, coupling=coupling, motor_end=motor_end,
                        b1_position=x_b1 if has_bearings else None, b2_position=x_b2 if has_bearings else None,
                        coupling_position=x_cp if has_drive else None, root_diameter=sections[2].d_out,
                        jaw1=jaw1, ksn=ksn, pitch=pitch, viscous=viscous, nut_joint=nut_joint,
                        drive_input=drive_input if has_drive else None, params=params, n_elements=n_elements)
    return s


def _scaled_mesh(sections, n_elements):
    """Table B.1's sections with every element count scaled to about ``n_elements`` in all (at least one)."""
    if n_elements is None:
        return sections
    if int(n_elements) < len(sections):
        raise ModelDefinitionError(f"testbed: n_elements = {n_elements} is below one element per section "
                                   f"({len(sections)})")
    scale = int(n_elements) / sum(sec.n_elements for sec in sections)
    return [dataclasses.replace(sec, n_elements=max(1, round(sec.n_elements * scale))) for sec in sections]


_NAMES = {"full": "testbed", "free_screw": "testbed_free_screw", "screw_nut": "testbed_screw_nut",
          "no_table": "testbed_no_table", "axial_torsional": "testbed_axial_torsional",
          "submodel1": "testbed_submodel1", "appendix_c": "testbed_appendix_c"}
_DESCRIPTIONS = {
    "free_screw": "free-free ballscrew (thesis Sec 3.5.2.1)",
    "screw_nut": "free-free ballscrew with the nut (Sec 3.5.2.2, Tables 3.2/3.3)",
    "no_table": "screw, bearings and nut on the frame; no table, coupling, rotor (Sec 3.5.2.3)",
    "full": "Fadal VMC 2216 x-axis test bed, full 6-DOF FE model (Sec 3.5.2.4, Ch 4)",
    "axial_torsional": "test bed, axial + torsional DOF only (Ch 5, sub-models 1 + 2 of Table 5.1)",
    "submodel1": "sub-model 1 of Table 5.1: screw, bearings, coupling, rotor (axial + torsional)",
    "appendix_c": "App C: table+nut rigid body on four roller slides (Table C.1)",
}
def _support_positions(v, motor_end, length, b1_position, b2_position, coupling_position) -> tuple:
    """x [m] of the thrust pair b1, the deep-groove bearing b2 and the screw-side jaw: the toml CHOICEs
    (for the motor at F) unless given; ``motor_end="A"`` mirrors the defaults about the screw's middle."""
    x_b1 = v("bearings.b1_position") if b1_position is None else float(b1_position)
    x_b2 = v("bearings.b2_position") if b2_position is None else float(b2_position)
    x_cp = v("coupling.attach_position") if coupling_position is None else float(coupling_position)
    if motor_end == "A":
        x_b1 = length - x_b1 if b1_position is None else x_b1
        x_b2 = length - x_b2 if b2_position is None else x_b2
        x_cp = length - x_cp if coupling_position is None else x_cp
    return x_b1, x_b2, x_cp


def _add_bearings(s: System, v, x_b1: float, x_b2: float, src: dict) -> None:
    """Bearings (Table 3.1, Sec B.5) on rigid housings (Sec 3.5.2.3) at the screw points b1, b2."""
    s.add("b1", Bearing(k_axial=v("bearings.b1_k_axial"), k_radial=v("bearings.b1_k_radial"), grounded=True))
    s.add("b2", Bearing(k_axial=v("bearings.b2_k_axial"), k_radial=v("bearings.b2_k_radial"), grounded=True))
    s.connect("screw.b1", "b1.node_a")
    s.connect("screw.b2", "b2.node_a")
    src.update({"b1": f"Table 3.1, Sec B.5; acts at x = {x_b1} m (CHOICE)",
                "b2": f"Table 3.1, Sec B.5; acts at x = {x_b2} m (CHOICE)"})


def _add_nut(s: System, v, params, variant, x_nut, ksn, nut_joint, pitch, viscous, src: dict) -> None:
    """Screw-nut interface (Eq 3.35, Table 3.1, Table B.3, Sec B.6), the nut (Table 3.1, Sec B.2) and, in
    the drive variants, the table it is bolted to (Table 3.1, Sec B.3; App C: :func:`_appendix_c_table`)."""
    lead = v("screw.lead") if pitch is None else float(pitch)
    phi_half = v("nut.length") / (2.0 * lead) * 2.0 * math.pi          # Eq B.2
    sn = thesis_screw_nut(params) if pitch is None else thesis_screw_nut(
        params, alpha=math.atan(lead / (math.pi * v("screw.pitch_diameter"))), phi_start=-phi_half, phi_end=phi_half)
    if nut_joint == "moving":
        screw = s.component("screw")
        s.add("sn", MovingScrewNut.from_screw_nut(screw, sn, z0=x_nut))
        for i in range(screw.n_nodes):
            s.connect(f"screw.n{i}", f"sn.n{i}")
        nut_port = "sn.nut"
    elif ksn == "full":
        s.add("sn", sn)
        s.connect("screw.nut", "sn.screw")
        nut_port = "sn.nut"
    else:                                   # Eq 3.46: direct terms + axial-torsional coupling only
        A = sn.stiffness_matrix()[:6, :6]
        keep = np.diag(np.diag(A))
        keep[2, 5] = keep[5, 2] = A[2, 5]
        s.add("sn", Bushing(K=keep))
        s.connect("screw.nut", "sn.node_a")
        nut_port = "sn.node_b"
    src["sn"] = "Eq 3.35 (rigid-ballscrew); Table 3.1; Table B.3; Eq B.2" + (
        "" if ksn == "full" else "; Eq 3.46 terms only (App C Case A)")
    m_nut, I_nut = v("nut.mass"), [v("nut.Ixx"), v("nut.Iyy"), v("nut.Izz")]
    if variant in ("screw_nut", "no_table"):
        s.add("nut", RigidBody(m=m_nut, I=I_nut))                          # free 6-DOF nut
        s.connect(nut_port, "nut.com")
        src["nut"] = "Table 3.1, Sec B.2 (6x6 inertia at the interface node, Sec B.6)"
        return
    if variant == "appendix_c":
        _appendix_c_table(s, v, nut_port)
        src["table"] = "Table C.1 (table+nut one rigid body, four roller slides)"
        return
    s.add("nut", RigidBody(m=m_nut, I=I_nut, dofs=("w",)))             # bolted to the table
    s.connect(nut_port, "nut.com")
    # the table axis is the screw's -z for a right-hand thread (module docstring, "Sign convention")
    s.add("table_joint", NodeToFlange(direction=-float(sn.hand)))
    s.add("table", Mass(m=v("table.mass")))
    s.add("Fd", Force())
    s.connect("nut.com", "table_joint.node")
    s.connect("table_joint.flange", "table.flange_a")
    s.connect("Fd.flange", "table.flange_a")
    src.update({"nut": "Table 3.1 (mass); moves with the table along z only (Sec 3.5.1)",
                "table_joint": "table axis = -z: positive in the direction a positive command moves "
                               "the table (Eq 4.2, G_x = r_g/s; right-hand thread, Eq 3.12)",
                "table": "Table 3.1, Sec B.3", "Fd": "disturbance force F_d on the table (Fig 4.1)"})
    if viscous == "guide":
        s.add("guide", Damper(d=v("guideways.viscous_coefficient")))
        s.add("frame", Fixed())
        s.connect("table.flange_b", "guide.flange_a")
        s.connect("guide.flange_b", "frame.flange")
        src["guide"] = "Table 5.2 (B = 12673 N s/m = 0.0321 kg m^2/s of Sec 4.2.1 seen from the table)"


def _add_drive(s: System, v, variant, coupling, jaw1, viscous, drive_input, damping, x_cp, src: dict) -> None:
    """Coupling (Sec B.4 / Sec 4.4.1), rotor (Table 3.1, Sec B.3), the amplifier and torque constant (Eq 4.1),
    the motor-side viscous damping B (Sec 4.2.1) and the modal damping (Tables 4.1/4.2)."""
    k_T = v("coupling.kT") if coupling == "jaw" else v("coupling.bellows_kT")
    J1, J2 = v("coupling.J1"), v("coupling.J2")
    s.add("motor", Torque())
    if drive_input == "voltage":             # current mode: G_e = K_a K_t (Eq 4.1), input amp.u [V]
        s.add("amp", CurrentAmplifier(K_a=v("electrical.K_a")))
        s.add("kt", Gain(k=v("electrical.K_t")))
        s.connect("amp.i", "kt.u")
        s.connect("kt.y", "motor.tau")
        src.update({"amp": "Eq 4.1 (Sec 4.2): current amplifier K_a = 6.4898 A/V, input amp.u [V]",
                    "kt": "Eq 4.1 (Sec 4.2): motor torque constant K_t = 0.4769 N m/A"})
    if jaw1 == "screw":                     # sensitivity only: both jaws on the screw side
        J1, J2 = 0.0, J1 + J2
    s.add("rotor", Inertia(J=v("rotor.Izz")))
    s.add("coupling", Coupling(k_T=k_T, J1=J1, J2=J2))
    s.add("screw_end", NodeToRotFlange())
    s.connect("motor.flange", "rotor.flange_a")
    s.connect("rotor.flange_b", "coupling.flange_a")
    s.connect("coupling.flange_b", "screw_end.flange")
    s.connect("screw_end.node", "screw.coupling")
    if viscous == "motor" and variant != "submodel1":
        s.add("B", TorsionalDamper(d=v("control.B")))
        s.add("frame_rot", FixedRotational())
        s.connect("rotor.flange_a", "B.flange_a")
        s.connect("B.flange_b", "frame_rot.flange")
        src["B"] = "Sec 4.2.1 (Eq 4.2): B = 0.0321 kg m^2/s at the motor shaft (= Table 5.2 x r_g^2)"
    src.update({"coupling": ("Sec B.4 (k_T = 3938, Eq B.1)" if coupling == "jaw" else "Sec 4.4.1 (bellows "
                             "k_T = 45940)") + f"; J1, J2 Table 3.1; J2 at x = {x_cp} m (CHOICE)",
                "rotor": "Table 3.1, Sec B.3",
                "motor": "motor torque tau = K_a K_t u (Eq 4.1)" if drive_input == "voltage" else
                         "torque input motor.tau (Eq 4.1: tau = K_a K_t u, amplifier left out)"})
    if damping and variant != "appendix_c":
        s.damping = DriveModalDamping(v("damping.zeta_mode1"), v("damping.zeta_mode2"), v("damping.zeta_other"))
        src["damping"] = "Tables 4.1/4.2 (6 %, 10 %); others 6 % (CHOICE); rigid mode undamped (Sec 5.2.2.1)"


#: The sign convention of the test bed's measured channels, in words (module docstring).
SIGN_CONVENTION = ("motor angle positive about the screw axis +z; table position/acceleration and the disturbance "
                   "Fd.f along the table axis (= screw -z, right-hand thread), positive in the direction a positive "
                   "command moves the table: table.s = r_g rotor.phi at low frequency (Eq 4.2, G_x = r_g/s); FE "
                   "coordinates (nut.w, sn.z0, screw nodes) stay in screw z")


def _validation_interface(s: System, variant: str, drive_input: str) -> ValidationInterface:
    """The declared validation interface of a drive variant (module docstring, "Validation interface")."""
    has_table = variant in ("full", "axial_torsional")
    joint = ("table_joint.flange", "table.flange_a")
    frame = "frame.flange" if "frame" in s._components else None
    points = [
        InsertionPoint("screw_support", "support", ("screw.b1", "b1"),
                       doc="the grounded angular-contact pair b1 (thrust support); its housing becomes a mass on "
                           "a fastener spring"),
        InsertionPoint("coupling", "parameter", parameters=("coupling.k_T",), doc="coupling torsional stiffness"),
        InsertionPoint("rotor", "rotational", ("rotor.flange_a",), doc="motor rotor"),
        InsertionPoint("structure", "all", doc="modal damping of the whole FE structure"),
    ]
    if drive_input == "voltage":
        points.append(InsertionPoint("amplifier", "connection", ("amp.i", "kt.u"),
                                     doc="amplifier current -> torque constant (D/A + amplifier delay)"))
    if has_table:
        points += [
            InsertionPoint("nut_table", "connection", joint,
                           doc="nut-to-table joint flange -> table (the disturbance Fd stays on the table)"),
            InsertionPoint("screw_nut", "joint", joint,
                           doc="the screw-nut clearance, modelled in series between nut and table: with a 1.49 kg "
                               "nut on a 250 kg table this is what the gap does to the table"),
            InsertionPoint("table_guide", "attach", ("table.flange_b",), ground=frame,
                           doc="the table on its guideways" + ("" if frame else " (no frame flange: add a Fixed)")),
            InsertionPoint("table", "attach", ("table.flange_a",), doc="the table (added mass)"),
        ]
    uncertain = [UncertainParameter("coupling.k_T", 0.2, "Sec B.4 (Eq B.1): from the 805 Hz mode of the coupling "
                                                         "measured alone; the bellows value is a catalogue value"),
                 UncertainParameter("b1.k_axial", 0.3, "Table 3.1: catalogue value for an assumed 700 N preload, "
                                                       "doubled for the pair (Sec B.5)")]
    if variant != "submodel1":
        uncertain.insert(0, UncertainParameter("table.m", 0.2, "Table 3.1: CAD estimate (Sec B.3)"
                                               + ("; Table C.1 table + nut" if variant == "appendix_c" else "")))
    outputs = ["rotor.phi", "rotor.w"] + (["table.s", "table.a"] if has_table else [])
    notes = SIGN_CONVENTION if has_table else "motor angle positive about the screw axis +z"
    return ValidationInterface(inputs=["amp.u" if drive_input == "voltage" else "motor.tau"], outputs=outputs,
                               uncertain=uncertain, points=points, ground=frame, notes=notes)


def _appendix_c_table(s: System, v, nut_port: str) -> None:
    """App C: table and nut lumped into one rigid body (Table C.1) on four roller slides.

    The table geometry (Fig C.1) is missing from the text; the box that has Table C.1's inertias
    (I_xx, I_yy, I_zz = 24.2, 21.0, 3.7 kg m^2 with m = 250 + 1.49 kg) is 0.109 m high (x, vertical),
    0.406 m wide (y, lateral) and 0.995 m long (z). CHOICE: the slides sit at the four bottom corners of
    that box, the box's bottom face 50 mm above the screw axis, the nut centre under the COM.
    """
    m = v("table.mass") + v("nut.mass")
    Ixx, Iyy, Izz = v("guideways.appC_table_inertia")
    s2 = 12.0 / m
    a2, b2, c2 = ((Iyy + Izz - Ixx) * s2 / 2.0, (Ixx + Izz - Iyy) * s2 / 2.0, (Ixx + Iyy - Izz) * s2 / 2.0)
    h, w, ln = math.sqrt(a2), math.sqrt(b2), math.sqrt(c2)       # x (vertical), y (lateral), z (feed)
    com_x = 0.05 + h / 2.0                                       # COM above the screw axis (50 mm gap)
    corners = {f"s{i}": [-h / 2.0, sy * w / 2.0, sz * ln / 2.0]
               for i, (sy, sz) in enumerate(((1, 1), (-1, 1), (1, -1), (-1, -1)))}
    s.add("table", RigidBody(m=m, I=[Ixx, Iyy, Izz], points={"P": [-com_x, 0.0, 0.0], **corners}))
    s.add("guide", LinearGuide(slides=list(corners), vertical="x", k_vertical=v("guideways.appC_k_vertical"),
                               k_lateral=v("guideways.appC_k_lateral")))
    s.connect(nut_port, "table.P")
    for c in corners:
        s.connect(f"table.{c}", f"guide.{c}")
    s.table_box = dict(height=h, width=w, length=ln, com_above_axis=com_x)


# ---- registered builders (bscomp.systems.REGISTRY) --------------------------------------------------------
def _fixed(variant: str, kw: dict) -> str:
    """The variant a registered builder fixes; a ``variant`` keyword (popped from ``kw``) may only repeat it."""
    if (given := kw.pop("variant", variant)) != variant:
        raise UsageError(f"build option variant={given!r}: this system is the test bed's {variant!r} variant; build "
                         f"another by name ({sorted(_NAMES.values())}) or call testbed(variant=...), one of {VARIANTS}")
    return variant


def testbed_full(**kw) -> System:
    """Full 6-DOF test bed with the jaw coupling (Sec 3.5.2.4, Table 4.1)."""
    return testbed(_fixed("full", kw), **kw)


def testbed_free_screw(**kw) -> System:
    """Free-free ballscrew (Sec 3.5.2.1)."""
    return testbed(_fixed("free_screw", kw), **kw)


def testbed_screw_nut(**kw) -> System:
    """Free-free ballscrew + nut (Sec 3.5.2.2, Tables 3.2/3.3); default nut position 2."""
    kw.setdefault("nut_position", "2")
    return testbed(_fixed("screw_nut", kw), **kw)


def testbed_no_table(**kw) -> System:
    """Screw, bearings and nut on the frame (Sec 3.5.2.3)."""
    return testbed(_fixed("no_table", kw), **kw)


def testbed_axial_torsional(**kw) -> System:
    """Axial + torsional model of Ch 5 (sub-models 1 + 2 of Table 5.1)."""
    return testbed(_fixed("axial_torsional", kw), **kw)


def testbed_submodel1(**kw) -> System:
    """Sub-model 1 of Table 5.1 (Table 5.3 frequencies)."""
    return testbed(_fixed("submodel1", kw), **kw)


def testbed_bellows(**kw) -> System:
    """Full test bed with the bellows coupling of Sec 4.4.1 (Table 4.2)."""
    kw.setdefault("coupling", "bellows")
    return testbed(_fixed("full", kw), **kw)


def testbed_appendix_c(**kw) -> System:
    """App C set-up: table+nut rigid body on roller slides (Table C.1)."""
    return testbed(_fixed("appendix_c", kw), **kw)
