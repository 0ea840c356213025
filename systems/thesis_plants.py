"""The controller-design plants of thesis Chapter 4, from the modal parameters of Tables 4.1 and 4.2.

Table 4.1 (jaw coupling) and Table 4.2 (bellows coupling, ``k_T`` = 45940 N m/rad) give, at the nut
positions L, C and R, the natural frequency ``f_n`` and the residues ``R_w`` (motor speed, Eq 4.5) and
``R_m`` (table position, Eq 4.7) of the first two normal modes; the damping ratios are 6 % and 10 %
(``damping.zeta_mode1``, ``zeta_mode2``) and ``J``, ``B``, ``r_g`` the rigid-body values of Sec 4.2.1
(``control`` group). All are read from ``systems/data/fadal_vmc2216_x.toml`` (``reference_results``).

* :func:`thesis_modes` -- the ``(f_n, zeta, R_w, R_m)`` rows of one table at one position;
* :func:`thesis_modal_plant` -- the :class:`~bscomp.control.closed_loop.DrivePlant` of Eq (4.3)-(4.7)
  built from them by :func:`bscomp.control.closed_loop.modal_plant`.
"""

from __future__ import annotations

from bscomp.control.closed_loop import DrivePlant, modal_plant
from bscomp.errors import UnknownNameError
from bscomp.systems.parameters import get_value, load_parameters

__all__ = ["POSITIONS", "thesis_modes", "thesis_modal_plant"]

POSITIONS = {"L": 0, "C": 1, "R": 2}
"""Nut positions of Tables 4.1/4.2 (left, centre, right) and their column in the printed tables."""

_TABLES = {"4.1": "table41", "4.2": "table42"}


def thesis_modes(table: str = "4.1", position: str = "C", n_modes: int = 2, params=None) -> list[tuple]:
    """Modal parameters of Table 4.1 (jaw coupling) or 4.2 (bellows coupling) at one nut position.

    Parameters
    ----------
    table : {"4.1", "4.2"}
    position : {"L", "C", "R"}
    n_modes : int
        How many of the two tabulated modes to return (0, 1 or 2).
    params : dict, optional
        A parameter set from :func:`bscomp.systems.parameters.load_parameters`; default the bundled test bed.

    Returns
    -------
    list of (f_n [Hz], zeta, R_w, R_m)
        As :func:`~bscomp.control.closed_loop.modal_plant` takes them (residues in the units printed).

    Raises
    ------
    UnknownNameError
        For a table or position the thesis does not tabulate.
    """
    if table not in _TABLES:
        raise UnknownNameError(f"table '{table}': use '4.1' (jaw coupling) or '4.2' (bellows coupling)")
    if position not in POSITIONS:
        raise UnknownNameError(f"position '{position}': use one of {sorted(POSITIONS)}")
    p = load_parameters() if params is None else params
    t, i = _TABLES[table], POSITIONS[position]
    zetas = (get_value(p, "damping.zeta_mode1"), get_value(p, "damping.zeta_mode2"))
    ref = p["reference_results"]
    return [(ref[f"{t}_fn{k}"]["value"][i], zetas[k - 1], ref[f"{t}_Rw{k}"]["value"][i],
             ref[f"{t}_Rm{k}"]["value"][i]) for k in (1, 2)[:n_modes]]


def thesis_modal_plant(table: str = "4.1", position: str = "C", n_modes: int = 2) -> DrivePlant:
    """Modal plant of Eq (4.5)-(4.7) with the parameters of Table 4.1 (jaw coupling) or 4.2 (bellows).

    ``J``, ``B``, ``r_g`` come from the ``control`` group of ``systems/data/fadal_vmc2216_x.toml``
    (Sec 4.2.1), the modes from :func:`thesis_modes`.

    Examples
    --------
    >>> from bscomp.systems.thesis_plants import thesis_modal_plant
    >>> plant = thesis_modal_plant("4.1", "C")          # the flexible plant of Sec 4.4 (GM 3.12 dB at K_p 7000)
    """
    p = load_parameters()
    modes = thesis_modes(table, position, n_modes, params=p)
    J, B, r_g = (get_value(p, f"control.{k}") for k in ("J", "B", "r_g"))
    return modal_plant(J, B, r_g, modes, name=f"Table {table} {position}-position, {n_modes} mode(s)")
