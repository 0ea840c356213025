"""Frequency responses and modal transfer functions (thesis Sec 4.2, Eq 4.2-4.9).

* :func:`frf` -> :class:`Frf`: ``H(j omega)`` from the sparse second-order form,

  .. math:: H(j\\omega) = (C_q + j\\omega C_v - \\omega^2 C_a)(K + j\\omega C - \\omega^2 M)^{-1} B + D,

  one sparse LU per frequency and no dense inverse; systems without a second-order form (controller
  states) fall back to the linearized state space, ``C (j\\omega I - A)^{-1} B + D`` by sparse solves.
* :func:`transfer_function` -> ``control.TransferFunction`` from the rigid-body part and the residues of
  chosen modes (Eq 4.3-4.8):

  .. math:: G(s) = \\frac{R_0\\,s^r}{s\\,(s + B/J)} + \\sum_k \\frac{R_k\\,s^r}{s^2 + 2\\zeta_k\\omega_k s
            + \\omega_k^2} + D

  ``r`` = 0, 1, 2 for displacement, velocity, acceleration outputs. With non-proportional damping the
  numerators become first-order polynomials (exact residues of the damped modal model); with all modes
  the result equals the full FRF.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.errors import ArgumentTypeError, NotLinearError, UnknownNameError, UsageError, check_names, check_number
from bscomp.files import atomic_write
from bscomp.kernel import Dae, System
from bscomp.kernel.units import convention_units, parse_unit
from bscomp.linear.linearization import SIMULATE_INSTEAD, SecondOrderModel, control_labels, linearize, warn_linearized
from bscomp.linear.modal import _condense, _group_poles, _second_order, _undamped
from bscomp.model import as_dae, as_system
from bscomp.plotting.base import bode_plot

__all__ = ["frf", "Frf", "transfer_function", "ModalSection"]


@dataclass
class Frf:
    """Frequency response (result of :func:`frf`).

    Attributes
    ----------
    freqs : (nf,) ndarray
        Frequencies [Hz].
    H : (nf, n_out, n_in) complex ndarray
        Response of each output to each input.
    inputs, outputs : list of str
    name : str
    units : dict
        Declared units of the inputs and outputs (``{"amp.u": "V"}``; the plot's legend and :meth:`pair_unit`).
    """

    freqs: np.ndarray
    H: np.ndarray
    inputs: list
    outputs: list
    name: str = ""
    notes: list = field(default_factory=list)
    units: dict = field(default_factory=dict)

    @property
    def magnitude_db(self) -> np.ndarray:
        """``20 log10 |H|`` [dB], same shape as :attr:`H`."""
        return 20 * np.log10(np.abs(self.H) + 1e-300)

    @property
    def phase_deg(self) -> np.ndarray:
        """Phase [deg], unwrapped along frequency."""
        return np.degrees(np.unwrap(np.angle(self.H), axis=0))

    def response(self, output: str | None = None, input: str | None = None) -> np.ndarray:
        """``H`` of one output/input pair (default: the first), shape (nf,)."""
        j = 0 if output is None else self._index(self.outputs, output, "output")
        i = 0 if input is None else self._index(self.inputs, input, "input")
        return self.H[:, j, i]

    @staticmethod
    def _index(names, n, what):
        if n not in names:
            raise UnknownNameError(f"'{n}' is not an {what} of this FRF; {what}s: {names}")
        return names.index(n)

    def _pairs(self):
        return [(j, i) for j in range(len(self.outputs)) for i in range(len(self.inputs))]

    def to_csv(self, path, units: dict | None = None, conditions: dict | None = None) -> None:
        """Columns ``freq_hz`` then, per output/input pair, ``re``, ``im``, ``mag_db``, ``phase_deg`` (named
        ``<input>-><output> re`` and so on): a plain table that :func:`bscomp.validate.load` reads back.

        The values are SI. Read back, each response's unit is :meth:`pair_unit` of its names (the Modelica
        naming convention); given ``units`` or ``conditions``, or for an FRF taken at an excitation amplitude
        (:func:`~bscomp.simulation.stepped.stepped_sine`, :func:`~bscomp.simulation.describing.describing_frf`),
        ``#`` metadata lines above the header (``kind``, ``source``, ``condition``, ``excitation``, ``unit`` per
        pair) record them with the data.

        Parameters
        ----------
        path : str, Path or text file
            A file name, or an open text file (e.g. ``sys.stdout``).
        units : dict, optional
            SI units of inputs and outputs by name (``{"amp.u": "V"}``), for channels the naming convention
            does not cover.
        conditions : dict, optional
            Operating conditions of the model (``{"nut_position": 0.43}``), written with the data.
        """
        lines = []
        if units or conditions or self._excitation():
            lines = ["# kind: frf", f"# source: {self.name or 'bscomp.frf'}"]
            lines += [f"# condition {k}: {v}" for k, v in (conditions or {}).items()]
            lines += [f"# excitation {k}: {v!r}" for k, v in self._excitation().items()]
            for j, i in self._pairs():
                out, inp = self.outputs[j], self.inputs[i]
                lines.append(f"# unit {out}/{inp}: {self.pair_unit(out, inp, units)}")
        mag, ph = self.magnitude_db, self.phase_deg
        with atomic_write(path, what="Frf.to_csv: path", suffixes=(".csv",), newline="") as fh:
            fh.writelines(line + "\n" for line in lines)
            w = csv.writer(fh, lineterminator="\n")
            head = ["freq_hz"]
            for j, i in self._pairs():
                pre = f"{self.inputs[i]}->{self.outputs[j]}"
                head += [f"{pre} re", f"{pre} im", f"{pre} mag_db", f"{pre} phase_deg"]
            w.writerow(head)
            for k, f in enumerate(self.freqs):
                row = [repr(float(f))]
                for j, i in self._pairs():
                    h = self.H[k, j, i]
                    row += [repr(float(h.real)), repr(float(h.imag)), repr(float(mag[k, j, i])),
                            repr(float(ph[k, j, i]))]
                w.writerow(row)

    def _excitation(self) -> dict:
        """``{input: amplitude}`` of an FRF taken at an excitation amplitude (written as ``# excitation`` lines;
        none for a linear FRF)."""
        amp = getattr(self, "amplitude", 0.0)
        return {self.inputs[0]: float(amp)} if amp and len(self.inputs) == 1 else {}

    @staticmethod
    def pair_unit(output: str, input: str, units: dict | None = None) -> str:
        """SI unit of the response of ``output`` to ``input``: ``output unit/(input unit)``.

        A channel's unit is ``units[name]`` if given, else the Modelica naming convention's for its last
        name part (``s`` m, ``v`` m/s, ``a`` m/s^2, ``f`` N, ``phi`` rad, ``w`` rad/s, ``tau`` N m), else
        ``1`` (a signal). Raises UsageError (a ValueError) for a unit that is not SI (the FRF holds SI values).
        """
        def unit(name):
            text = (units or {}).get(name) or convention_units.get(name.rsplit(".", 1)[-1], ("1",))[0]
            if parse_unit(text).scale != 1.0:
                raise UsageError(f"unit {text!r} of {name!r} is not SI: the FRF holds SI values (give e.g. 'm', "
                                 "not 'mm')")
            return text

        out, inp = unit(output), unit(input)
        return out if inp == "1" else f"{out}/({inp})"

    def _unit_label(self, output, input) -> str:
        """`` [dB re 1 unit]`` of a pair for the legend (the declared units, else the naming convention's), or ``""``
        where a unit is not SI or not known."""
        try:
            unit = self.pair_unit(output, input, self.units)
        except UsageError:
            return ""
        return "" if unit == "1" else f" [dB re 1 {unit}]"

    def to_dict(self) -> dict:
        return {"name": self.name, "freqs_hz": self.freqs.tolist(), "inputs": list(self.inputs),
                "outputs": list(self.outputs), "H_re": self.H.real.tolist(), "H_im": self.H.imag.tolist(),
                "notes": list(self.notes)}

    def to_json(self, path=None) -> str:
        """JSON text (``H_re``/``H_im`` indexed [freq][output][input]); written to ``path`` if given."""
        text = json.dumps(self.to_dict())
        if path is not None:
            with atomic_write(path, what="Frf.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def plot(self, path=None, title=None):
        """Bode plot of every pair (:func:`bscomp.plotting.bode_plot`); returns the figure."""

        pairs = self._pairs()
        H = np.stack([self.H[:, j, i] for j, i in pairs], axis=1)
        labels = [f"{self.inputs[i]} -> {self.outputs[j]}{self._unit_label(self.outputs[j], self.inputs[i])}"
                  for j, i in pairs]
        return bode_plot(self.freqs, H, labels=labels, title=title or f"{self.name}: FRF", path=path)


def _freq_grid(freqs, fmin, fmax, n):
    if freqs is not None:
        try:
            f = np.atleast_1d(np.asarray(freqs, float))
        except (TypeError, ValueError):
            raise UsageError(f"freqs must be an array of frequencies [Hz], got {freqs!r}") from None
    else:
        fmin, fmax = check_number("fmin", fmin, positive=True), check_number("fmax", fmax, positive=True)
        if not fmin < fmax:
            raise UsageError(f"need fmin < fmax, got fmin={fmin}, fmax={fmax}")
        f = np.logspace(np.log10(fmin), np.log10(fmax), check_number("n", n, integer=True, minimum=1))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise UsageError("freqs must be a non-empty 1-D array of finite positive frequencies [Hz]" + (
            f", got {float(f[~np.isfinite(f) | (f <= 0)][0])!r}" if f.ndim == 1 and f.size else ""))
    return f


def _statespace_frf(lin, f):
    A = sp.csc_matrix(lin.A)
    B, C, D = np.asarray(lin.B), np.asarray(lin.C), np.asarray(lin.D)
    n = A.shape[0]
    H = np.empty((f.size, C.shape[0], B.shape[1]), complex)
    I = sp.identity(n, format="csc")
    for k, fk in enumerate(f):
        if n:
            H[k] = C @ spla.splu((2j * np.pi * fk * I - A).tocsc()).solve(B.astype(complex)) + D
        else:
            H[k] = D
    return H


def frf(model, input=None, output=None, freqs=None, *, fmin: float = 1.0, fmax: float = 1000.0, n: int = 500,
        at: dict | None = None, params: dict | None = None, warn: bool = True) -> Frf:
    """Frequency response of ``output`` to ``input`` from the sparse second-order form.

    Parameters
    ----------
    model : System, Dae, SecondOrderModel or str
        A system name registered in ``bscomp.systems`` (or ``.py`` path) is built with ``params``.
    input, output : str or list of str, optional
        Input and output names (default: all inputs; the coordinates).
    freqs : array_like, optional
        Frequencies [Hz]; default ``n`` log-spaced points from ``fmin`` to ``fmax``.
    at, params : dict, optional
        Operating point and parameter overrides.
    warn : bool
        Warn (:class:`~bscomp.errors.ModelLimitationWarning`) when the model has nonlinear components, which
        the FRF linearizes at the operating point; ``False`` for callers that account for them.

    Returns
    -------
    Frf
        ``H[freq, output, input]``.

    Notes
    -----
    Solves :math:`(K + j\\omega C - \\omega^2 M) X = B` with a sparse LU per frequency
    (:meth:`~bscomp.linear.SecondOrderModel.frf`); a model with internal (controller) states is
    evaluated from its linearized state space instead.
    """

    f = _freq_grid(freqs, fmin, fmax, n)
    ins, outs = check_names("input", input), check_names("output", output)
    name = model if isinstance(model, str) else getattr(model, "name", "")
    try:
        so = _second_order(model, ins, outs, at, params)
    except NotLinearError:
        if not isinstance(model, (System, Dae)):
            model, params = as_system(model, params), None
        lin = linearize(model, inputs=ins, outputs=outs, at=at, params=params)
        refuse_constant_outputs(model, params, [s.replace("/", ".") for s in lin.output_labels], [lin.C, lin.D])
        warn_linearized(getattr(lin, "linearized", ()) if warn else (), "frf", SIMULATE_INSTEAD)
        return Frf(freqs=f, H=_statespace_frf(lin, f), inputs=[s.replace("/", ".") for s in lin.input_labels],
                   outputs=[s.replace("/", ".") for s in lin.output_labels], name=name,
                   notes=["from the linearized state space (no second-order form)"])
    if isinstance(model, SecondOrderModel):
        so = _restrict(so, ins, outs)
    else:
        refuse_constant_outputs(model, params, list(so.outputs), [so.Cq, so.Cv, so.Ca, so.D])
    warn_linearized(so.linearized if warn else (), "frf", SIMULATE_INSTEAD)
    return Frf(freqs=f, H=so.frf(f), inputs=list(so.inputs), outputs=list(so.outputs), name=name,
               units=dict(so.signal_units))


def refuse_constant_outputs(model, params, outputs, rows, who="frf") -> None:
    """:class:`UnknownNameError` for an output that is a parameter or a constant (:meth:`bscomp.Dae.require_signals`:
    its FRF would be 0 at every frequency). Only outputs whose rows of the output matrices ``rows`` are all zero
    are looked at symbolically, so a valid call costs nothing."""
    zero = np.ones(len(outputs), bool)
    for R in rows:
        R = sp.csr_matrix(R)
        if R.shape[0] == len(outputs) and R.nnz:
            zero &= np.asarray(abs(R).sum(axis=1)).ravel() == 0
    if zero.any():
        dae = model if isinstance(model, Dae) else as_dae(model, params)
        dae.require_signals([o for o, z in zip(outputs, zero, strict=True) if z], who)


def _restrict(so, ins, outs):
    """A SecondOrderModel restricted to some of its inputs/outputs."""
    from dataclasses import replace

    i = list(range(len(so.inputs))) if ins is None else [Frf._index(so.inputs, x, "input") for x in ins]
    j = list(range(len(so.outputs))) if outs is None else [Frf._index(so.outputs, x, "output") for x in outs]
    csr = sp.csr_matrix
    return replace(so, B=csr(so.B)[:, i], Cq=csr(so.Cq)[j], Cv=csr(so.Cv)[j], Ca=csr(so.Ca)[j],
                   D=csr(so.D)[j][:, i], inputs=[so.inputs[k] for k in i], outputs=[so.outputs[k] for k in j])


# ---- modal transfer function ------------------------------------------------------------------------------
@dataclass
class ModalSection:
    """One term ``num(s) / den(s)`` of a modal transfer function (polynomial coefficients, highest first).

    ``mode`` is the index in :func:`~bscomp.linear.modal.modes` ordering; ``poles`` the damped poles [1/s];
    ``f_n`` [Hz] and ``zeta`` the undamped frequency and damping ratio (NaN for a rigid-body mode, whose
    denominator is ``s (s + B/J)`` or ``s^2``).
    """

    mode: int
    f_n: float
    zeta: float
    rigid: bool
    num: np.ndarray
    den: np.ndarray
    poles: np.ndarray

    def __call__(self, s):
        return np.polyval(self.num, s) / np.polyval(self.den, s)


def _section_from_poles(lam, res):
    """``sum_i r_i / (s - lam_i)`` as one real rational function (num, den)."""
    den = np.real(np.poly(lam))
    num = np.zeros(max(len(lam), 1), complex)
    for i in range(len(lam)):
        others = np.atleast_1d(np.poly(np.delete(lam, i)))
        num[len(num) - len(others):] += res[i] * others
    return np.real(num), den


def _cancel_s(num, den, tol=1e-12):
    """Cancel common factors ``s`` (a rigid-body pole at 0 with zero residue)."""
    num, den = np.atleast_1d(num), np.atleast_1d(den)
    while len(den) > 1 and den[-1] == 0 and len(num) > 1 and abs(num[-1]) <= tol * np.max(np.abs(num)):
        num, den = num[:-1], den[:-1]
    return num, den


def transfer_function(model, input: str, output: str, modes=None, include_rigid: bool = True,
                      at: dict | None = None, params: dict | None = None, fmax: float | None = None):
    """Transfer function ``output/input`` from rigid-body part and modal residues (Eq 4.3-4.8).

    The model is truncated to the chosen undamped modes :math:`\\Phi_s` (mass-normalised),

    .. math:: \\ddot\\eta + \\Phi_s^T C \\Phi_s\\,\\dot\\eta + \\Omega_s^2 \\eta = \\Phi_s^T B u,

    and each mode contributes the exact partial fractions of its damped poles. For proportional damping
    and a displacement output this is Eq 4.3, :math:`R_k / (s^2 + 2\\zeta_k\\omega_k s + \\omega_k^2)` with
    :math:`R_k = c\\phi_k\\,\\phi_k^T b` (Eq 4.4); a velocity output multiplies by ``s`` (Eq 4.5-4.6);
    a rigid-body mode gives :math:`R_0/(s(s + B/J))` (Eq 4.8) or :math:`R_0/s^2` without viscous damping.

    Parameters
    ----------
    model : System, Dae, SecondOrderModel or str
    input, output : str
        One input and one output name.
    modes : None, int or sequence of int
        None: all modes; an int ``k``: the rigid-body modes and the ``k`` lowest elastic modes; a
        sequence: indices in the ordering of :func:`bscomp.linear.modal.modes` (0 = lowest).
    include_rigid : bool
        Keep the rigid-body term(s).
    at, params : dict, optional
        Operating point and parameter overrides.
    fmax : float, optional
        Only modes up to ``fmax`` [Hz] (applied before ``modes``).

    Returns
    -------
    control.TransferFunction
        SISO, with attributes ``sections`` (list of :class:`ModalSection`) and ``feedthrough`` (the
        constant term). Evaluating the sections one by one is better conditioned than the expanded
        polynomial for many modes.
    """
    import control


    if not isinstance(input, str) or not isinstance(output, str):
        raise ArgumentTypeError(f"transfer_function is SISO: give one input name and one output name (str), got "
                                f"input={input!r}, output={output!r}")
    if fmax is not None:
        fmax = check_number("fmax", fmax, positive=True)
    if isinstance(modes, (int, np.integer)) and not isinstance(modes, bool):
        modes = check_number("modes", modes, integer=True, minimum=0)
    so = _second_order(model, [input], [output], at, params)
    warn_linearized(so.linearized, "transfer_function", SIMULATE_INSTEAD)
    so = _restrict(so, [input], [output]) if len(so.inputs) > 1 or len(so.outputs) > 1 else so
    red = _condense(so)
    lam, phi, rigid, _ = _undamped(red, fmax=fmax)
    idx = np.arange(lam.size)
    if modes is not None:
        if isinstance(modes, (int, np.integer)):
            idx = np.r_[np.flatnonzero(rigid), np.flatnonzero(~rigid)[: int(modes)]]
        else:
            idx = np.asarray(list(modes), int)
            if np.any(idx < 0) or np.any(idx >= lam.size):
                raise UnknownNameError(f"mode indices {list(idx)} out of range: the model has "
                                       f"{lam.size} modes")
    if not include_rigid:
        idx = idx[~rigid[idx]]
    idx = np.unique(idx)
    lam, phi, rigid = lam[idx], phi[:, idx], rigid[idx]
    omega = np.sqrt(lam)
    m = omega.size
    Cm = phi.T @ (red.C @ phi)
    Cm = 0.5 * (Cm + Cm.T)
    b = phi.T @ red.B[:, 0]
    cq, cv, ca = red.Cq[0] @ phi, red.Cv[0] @ phi, red.Ca[0] @ phi
    # modal state space x = (eta, eta'): y = (cq - ca Omega^2) eta + (cv - ca Cm) eta' + (D + ca b) u
    Cy = np.r_[cq - ca * omega**2, cv - ca @ Cm]
    Bx = np.r_[np.zeros(m), b]
    d = float(red.D[0, 0] + ca @ b)
    groups = _group_poles(omega, Cm, rigid)
    sections = []
    for k in range(m):
        if groups.decoupled[k]:
            num, den = np.array([cv[k] * b[k], cq[k] * b[k]]), np.array([1.0, 0.0, 0.0])
            poles = np.zeros(2)
        else:
            V, W = groups.vectors[k]
            res = (Cy @ V) * (W @ Bx)
            poles = groups.poles[k]
            num, den = _section_from_poles(poles, res)
        num, den = _cancel_s(num, den)
        z = np.nan
        if not rigid[k] and len(den) == 3 and den[2] > 0:
            z = float(den[1] / (2 * np.sqrt(den[2])))
        sections.append(ModalSection(mode=int(idx[k]), f_n=float(omega[k] / (2 * np.pi)), zeta=z,
                                     rigid=bool(rigid[k]), num=num, den=den, poles=np.asarray(poles)))
    den = np.array([1.0])
    for s_ in sections:
        den = np.polymul(den, s_.den)
    num = d * den
    for i, s_ in enumerate(sections):
        part = s_.num
        for j, o in enumerate(sections):
            if j != i:
                part = np.polymul(part, o.den)
        num = np.polyadd(num, part)
    tf = control.tf(num, den, inputs=control_labels([input]), outputs=control_labels([output]),
                    name=f"{input}->{output}".replace(".", "/"))
    tf.sections = sections
    tf.feedthrough = d
    return tf
