"""Parts of the thesis test bed built from its parameter file (thesis Table 3.1, Table B.1, Table B.3).

Thesis data live here and in ``systems/data/fadal_vmc2216_x.toml``, not in the components: a component
knows its physics and takes every number as a parameter. These builders read the numbers from the toml
(each entry cites its table or equation) and return the components of the Fadal VMC 2216 x-axis drive,
for tests, examples and the drives of :mod:`bscomp.systems.testbed`:

* :func:`thesis_sections`: the stepped screw of Table B.1 (sections A..F, 47 elements, 920.5 mm;
  section C stiffness from the root diameter, mass from the equivalent diameter of Eq 3.1);
* :func:`thesis_ballscrew`: a :class:`~bscomp.components.Ballscrew` on those sections with the steel
  of App B.1 and the shear factor of Eq A.6;
* :func:`thesis_screw_nut`: the rigid-ballscrew interface :class:`~bscomp.components.ScrewNut` of
  Table 3.1 / Table B.3 (oversize balls, 100 balls, k_ball 20.7 N/um, alpha 4.55 deg, beta 50 deg,
  R 20 mm, +-1800 deg, Eq 3.35).

``params`` names a bundled parameter set or a ``.toml`` path (:func:`bscomp.systems.parameters.load_parameters`).
"""

from __future__ import annotations

from bscomp.components import Ballscrew, ScrewNut, Section

from .parameters import get_value, load_parameters

__all__ = ["thesis_parameters", "thesis_sections", "thesis_ballscrew", "thesis_screw_nut"]

#: DOF of a full 6-DOF screw node.
_ALL_DOFS = ("u", "v", "w", "tx", "ty", "tz")

_PARAMS_CACHE: dict = {}


def thesis_parameters(name: str = "fadal_vmc2216_x") -> dict:
    """The parsed parameter file ``name`` (cached; treat as read-only)."""
    key = str(name)
    if key not in _PARAMS_CACHE:
        _PARAMS_CACHE[key] = load_parameters(name)
    return _PARAMS_CACHE[key]


def thesis_sections(d_root: float | None = None, d_equiv: float | None = None, n_elements_C: int | None = None,
                     reverse: bool = False, params: str = "fadal_vmc2216_x") -> list[Section]:
    """The ballscrew sections of thesis Table B.1, from the toml group ``[screw.sections]``.

    ======= ======== ======== ========== ==========
    Section I.D [mm] O.D [mm] Length[mm] Elements
    ======= ======== ======== ========== ==========
    A       0.0      23.0     24.5       1
    B       12.0     25.0     18.0       1
    C       12.0     35.5     780        39
    D       12.0     31.8     38.0       2
    E       0.0      20.0     30.0       2
    F       0.0      20.0     30.0       2
    ======= ======== ======== ========== ==========

    Total 920.5 mm and 47 elements (Table 3.1: "Total Length = 921 mm; N_Elm = 47").

    Parameters
    ----------
    d_root : float, optional
        Stiffness (root) diameter of the threaded section C [m]; default ``screw.root_diameter`` (Table
        B.1's 35.5 mm; Table 3.1 lists ``d_r = 40 mm``, see the toml note).
    d_equiv : float, optional
        Mass (equivalent) diameter of section C [m], Eq 3.1; default ``screw.equivalent_diameter``
        (37.35 mm, App B.1). Independent of ``d_root``: a stiffer thread is not a heavier one.
    n_elements_C : int, optional
        Elements in section C; default Table B.1's 39 (about 20 mm elements, L/d ~ 0.5, Sec 3.3.1).
    reverse : bool
        Return F..A (section F at z = 0) instead of A..F.
    params : str
        Parameter set name or ``.toml`` path.

    Returns
    -------
    list of Section
        Sections A..F in table order (z increasing), unless ``reverse``.
    """
    p = thesis_parameters(params)
    out = []
    for name in "ABCDEF":
        g = f"screw.sections.{name}"
        d_out, d_mass, n_el = get_value(p, f"{g}.outer_diameter"), None, int(get_value(p, f"{g}.n_elements"))
        if name == "C":
            d_out = get_value(p, "screw.root_diameter") if d_root is None else float(d_root)
            d_mass = get_value(p, "screw.equivalent_diameter") if d_equiv is None else float(d_equiv)
            n_el = n_el if n_elements_C is None else int(n_elements_C)
        out.append(Section(get_value(p, f"{g}.length"), d_out, get_value(p, f"{g}.inner_diameter"), n_el, d_mass,
                           name))
    return out[::-1] if reverse else out


def thesis_ballscrew(dofs=_ALL_DOFS, points: dict | None = None, d_root: float | None = None,
                      d_equiv: float | None = None, reverse: bool = False, params: str = "fadal_vmc2216_x",
                      sections: list | None = None, **overrides) -> Ballscrew:
    """The test-bed screw: :func:`thesis_sections` with the steel of App B.1 (E, rho, nu) and the shear
    factor of Eq A.6 from the toml group ``[screw.material]``.

    ``dofs`` and ``points`` are those of :class:`~bscomp.components.Ballscrew`; ``sections`` replace
    :func:`thesis_sections` (another mesh of them); ``overrides`` replace parameters (``E=...``).
    """
    p = thesis_parameters(params)
    g = "screw.material"
    material = {"E": get_value(p, f"{g}.youngs_modulus"), "rho": get_value(p, f"{g}.density"),
                "nu": get_value(p, f"{g}.poissons_ratio"), "kappa": get_value(p, f"{g}.shear_factor")}
    material.update(overrides)
    if sections is None:
        sections = thesis_sections(d_root=d_root, d_equiv=d_equiv, reverse=reverse, params=params)
    return Ballscrew(sections, dofs=dofs, points=points, **material)


def thesis_screw_nut(params: str = "fadal_vmc2216_x", **overrides) -> ScrewNut:
    """The test-bed screw-nut interface (Table 3.1 / Table B.3, toml group ``[screw_nut]``): oversize
    balls (four-point contact, Eq 3.41), ``k_ball``, ``n_ball``, ``alpha``, ``beta``, ``R`` and the
    azimuth range of Eq B.2; ``overrides`` replace any of them (``alpha=...``)."""
    p = thesis_parameters(params)
    preload = get_value(p, "screw_nut.preload_type")
    values = {"k_ball": get_value(p, "screw_nut.k_ball"), "n_ball": get_value(p, "screw_nut.N_ball"),
              "alpha": get_value(p, "screw_nut.alpha"), "beta": get_value(p, "screw_nut.beta"),
              "R": get_value(p, "screw_nut.R"), "phi_start": get_value(p, "screw_nut.phi_start"),
              "phi_end": get_value(p, "screw_nut.phi_end")}
    values.update(overrides)
    return ScrewNut(preload={"oversize-ball": "oversize"}.get(preload, preload), **values)
