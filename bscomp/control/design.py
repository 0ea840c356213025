"""Controller design for the feed drive, thesis Chapter 4 (Sec 4.3-4.5).

* :func:`pi_gains` -- analog PI velocity loop by pole placement, Eq (4.10)-(4.12);
* :func:`second_order_z` -- z-plane image ``z^2 + c_1 z + c_2`` of an s-plane pole pair (the pattern of
  Eq (4.20), (4.21), (4.36) and (4.38));
* :func:`notch` -- digital notch coefficients, Eq (4.18)-(4.21) (Table 4.3);
* :func:`zoh_polynomials` -- ``B(z)/A(z)``, the zero-order-hold equivalent of ``G_e(s) G_m(s)`` (Eq 4.31);
* :func:`ppc_polynomials` -- desired closed-loop factors ``A_c`` and ``A_o``, Eq (4.35)-(4.38) (Table 4.5);
* :func:`diophantine` / :func:`rst_design` -- the pole-placement (RST) controller, Eq (4.24)-(4.29)
  (Table 4.6), by a Sylvester-matrix solve.

Polynomials are numpy arrays of coefficients in *descending* powers of ``z`` (``numpy.polymul`` order).
Nothing here imports python-control except the functions that return python-control objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bscomp.components import NotchFilter, RSTController
from bscomp.components.notch_filter import notch_coefficients
from bscomp.control._checks import integer, lti, polynomial, real
from bscomp.errors import ArgumentTypeError, ParameterError, SingularSystemError, UsageError

__all__ = [
    "PIGains", "pi_gains", "velocity_loop_tf", "second_order_z", "NotchCoefficients", "notch",
    "zoh_polynomials", "PPCPolynomials", "ppc_polynomials", "diophantine", "RSTDesign", "rst_design",
    "split_polynomial",
]


def _positive(func, **kw):
    """The values of ``kw`` as floats, each a finite real number > 0 (else an error naming ``func``)."""
    return [real(func, k, v, positive=True) for k, v in kw.items()]


# ---------------------------------------------------------------------------------------------------
# analog PI velocity loop (Sec 4.3.1)
@dataclass(frozen=True)
class PIGains:
    """Gains of the parallel analog PI controller ``C(s) = K_v + K_i/s`` (Eq 4.10).

    Attributes
    ----------
    K_v : float
        Proportional gain [V/V].
    K_i : float
        Integral gain [1/s] (printed "rad/s" in Eq 4.14).
    """

    K_v: float
    K_i: float

    def __iter__(self):
        return iter((self.K_v, self.K_i))


def pi_gains(J: float, B: float, K_a: float, K_t: float, H_g: float, wn: float, zeta: float) -> PIGains:
    """PI gains placing the velocity-loop poles at ``s^2 + 2 zeta wn s + wn^2`` (Eq 4.11-4.12).

    Parameters
    ----------
    J : float
        Inertia reflected at the motor [kg m^2] (8.55e-3, Sec 4.2.1).
    B : float
        Viscous damping reflected at the motor [kg m^2/s] (0.0321).
    K_a, K_t, H_g : float
        Amplifier gain [A/V], torque constant [N m/A], tachometer gain [V s/rad] (Eq 4.1, Sec 4.3).
    wn : float
        Closed-loop natural frequency [rad/s] (314.16, Eq 4.13).
    zeta : float
        Closed-loop damping ratio (0.7071, Eq 4.13).

    Returns
    -------
    PIGains
        ``K_v`` [V/V] and ``K_i`` [1/s].

    Notes
    -----
    With :math:`K = K_a K_t H_g`, comparing the denominator of Eq (4.10) with
    :math:`s^2 + 2\\zeta\\omega_n s + \\omega_n^2` gives (Eq 4.12, where the extracted text prints
    :math:`K_a K_i H_g` for :math:`K_a K_t H_g`)

    .. math:: K_i = \\frac{J\\omega_n^2}{K_a K_t H_g}, \\qquad
              K_v = \\frac{2\\zeta\\omega_n J - B}{K_a K_t H_g}.

    Raises
    ------
    ParameterError
        If a gain, J, wn or zeta is not positive, or the requested damping is below the plant's own
        (``K_v`` would be negative).
    """
    J, K_a, K_t, H_g, wn, zeta = _positive("pi_gains", J=J, K_a=K_a, K_t=K_t, H_g=H_g, wn=wn, zeta=zeta)
    B = real("pi_gains", "B", B, nonnegative=True, unit="kg m^2/s")
    K = K_a * K_t * H_g
    K_v = (2 * zeta * wn * J - B) / K
    if K_v < 0:
        raise ParameterError(f"2 zeta wn J = {2 * zeta * wn * J:g} < B = {B:g}: the plant alone is more "
                             "damped than requested, K_v would be negative (Eq 4.12); raise zeta or wn")
    return PIGains(K_v=float(K_v), K_i=float(J * wn**2 / K))


def velocity_loop_tf(J, B, K_a, K_t, H_g, K_v, K_i):
    """Closed velocity loop ``G_v(s) = w(s)/u_v(s)`` of the rigid drive, Eq (4.10) (python-control TF).

    ``u_v`` is the velocity command [V]; the DC gain is ``1/H_g`` [rad/s per V].
    """
    import control

    f = "velocity_loop_tf"
    J = real(f, "J", J, positive=True)
    B, K_a, K_t, H_g, K_v, K_i = (real(f, k, v) for k, v in
                                  zip(("B", "K_a", "K_t", "H_g", "K_v", "K_i"), (B, K_a, K_t, H_g, K_v, K_i)))
    num = [K_a * K_t * K_v / J, K_a * K_t * K_i / J]
    den = [1.0, (B + K_a * K_t * K_v * H_g) / J, K_a * K_t * K_i * H_g / J]
    return control.tf(num, den, inputs=["u_v"], outputs=["w"])


# ---------------------------------------------------------------------------------------------------
# digital notch (Sec 4.4.2)
def second_order_z(zeta: float, omega: float, T_s: float) -> tuple[float, float]:
    """Coefficients ``(c_1, c_2)`` of ``z^2 + c_1 z + c_2`` whose roots are ``exp(s T_s)`` of the roots of
    ``s^2 + 2 zeta omega s + omega^2``.

    Notes
    -----
    .. math:: c_1 = -2 e^{-\\zeta\\omega T_s}\\cos(\\omega T_s\\sqrt{1-\\zeta^2}), \\qquad
              c_2 = e^{-2\\zeta\\omega T_s}

    (Eq 4.20, 4.21, 4.36, 4.38); for ``zeta > 1`` the cosine becomes ``cosh(omega T_s sqrt(zeta^2 - 1))``
    (two real poles).
    """
    omega, T_s = _positive("second_order_z", omega=omega, T_s=T_s)
    zeta = real("second_order_z", "damping ratio zeta", zeta, nonnegative=True)
    x = omega * T_s
    if zeta <= 1:
        c = math.cos(x * math.sqrt(1 - zeta * zeta))
    else:
        c = math.cosh(x * math.sqrt(zeta * zeta - 1))
    return -2 * math.exp(-zeta * x) * c, math.exp(-2 * zeta * x)


@dataclass(frozen=True)
class NotchCoefficients:
    """``G_N(z) = K_N (z^2 + n1 z + n2)/(z^2 + d1 z + d2)`` (Eq 4.18), Table 4.3 layout."""

    n1: float
    n2: float
    d1: float
    d2: float
    K_N: float
    T_s: float

    def filter(self):
        """The sampled block (:class:`bscomp.components.NotchFilter`)."""
        return NotchFilter(self.n1, self.n2, self.d1, self.d2, self.K_N, self.T_s)

    def tf(self):
        """python-control discrete transfer function ``G_N(z)``."""
        return self.filter().tf()


def notch(zeta_N: float, omega_N: float, zeta_D: float, Ts: float, omega_D: float | None = None
          ) -> NotchCoefficients:
    """Digital notch filter cancelling the mode ``(zeta_N, omega_N)``, Eq (4.18)-(4.21).

    Parameters
    ----------
    zeta_N, omega_N : float
        Damping ratio and natural frequency [rad/s] of the mode to cancel (numerator, Eq 4.20);
        0.0855 and 753.98 rad/s in Sec 4.4.2.
    zeta_D : float
        Damping ratio of the replacing poles (denominator, Eq 4.21); 0.5 in Sec 4.4.2.
    Ts : float
        Sampling period [s] (200e-6).
    omega_D : float, optional
        Natural frequency of the replacing poles; default ``omega_N`` as in the thesis.

    Returns
    -------
    NotchCoefficients
        ``n1, n2, d1, d2`` and ``K_N = (1 + d1 + d2)/(1 + n1 + n2)`` (unit DC gain, Eq 4.19).
    """
    f = "notch"
    zeta_N, zeta_D = (real(f, k, v, nonnegative=True) for k, v in (("zeta_N", zeta_N), ("zeta_D", zeta_D)))
    omega_N, Ts = _positive(f, omega_N=omega_N, Ts=Ts)
    if omega_D is not None:
        omega_D = real(f, "omega_D", omega_D, positive=True, unit="rad/s")
    nyquist = math.pi / Ts
    for k, v in (("omega_N", omega_N), ("omega_D", omega_D)):
        if v is not None and v >= nyquist:
            raise UsageError(f"notch: {k} = {v:g} rad/s is at or above the Nyquist frequency pi/Ts = "
                             f"{nyquist:g} rad/s of Ts = {Ts:g} s: a sampled notch cannot act there "
                             "(the mode aliases); give omega_N/omega_D in rad/s (not Hz?) or shorten Ts")
    return NotchCoefficients(*notch_coefficients(zeta_N, omega_N, zeta_D, Ts, omega_D=omega_D), float(Ts))


# ---------------------------------------------------------------------------------------------------
# pole placement (Sec 4.5)
def zoh_polynomials(plant, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """``A(z)`` (monic) and ``B(z)``: zero-order-hold equivalent of a continuous SISO plant (Eq 4.31).

    Parameters
    ----------
    plant : control.StateSpace or control.TransferFunction
        Continuous SISO system, e.g. ``G_e(s) G_m(s)`` from the amplifier command [V] to the table
        position [m].
    Ts : float
        Sampling period [s].

    Returns
    -------
    A, B : numpy.ndarray
        Descending powers of z; ``deg B = deg A - 1`` for a strictly proper plant.
    """
    import control

    (Ts,) = _positive("zoh_polynomials", Ts=Ts)
    lti("zoh_polynomials", "plant", plant)
    if plant.ninputs != 1 or plant.noutputs != 1:
        raise ParameterError(f"zoh_polynomials needs a SISO plant, got {plant.noutputs}x{plant.ninputs}")
    if plant.dt is not None and plant.dt != 0:
        raise UsageError(f"zoh_polynomials: plant must be continuous (dt = 0), got dt = {plant.dt!r}")
    sysd = control.c2d(control.ss(plant), Ts, "zoh")
    A = np.poly(sysd.A)
    # B from the Markov form: B(z)/A(z) = C adj(zI - Ad) Bd + D  ->  B = C (A(z) (zI-Ad)^-1) Bd + D A
    n = sysd.A.shape[0]
    Bz = np.zeros(n + 1)
    # Faddeev-LeVerrier: adj(zI - Ad) = sum_k N_k z^(n-1-k), N_0 = I, N_k = Ad N_{k-1} + a_k I
    Nk = np.eye(n)
    for k in range(n):
        Bz[k + 1] += (sysd.C @ Nk @ sysd.B).item()
        Nk = sysd.A @ Nk + A[k + 1] * np.eye(n)
    Bz = Bz + np.asarray(sysd.D).item() * A
    return A, np.trim_zeros(Bz, "f")


@dataclass(frozen=True)
class PPCPolynomials:
    """Desired closed-loop polynomial ``A_cl = A_c A_o`` of Eq (4.23), Table 4.5 layout.

    Attributes
    ----------
    A_c : numpy.ndarray
        ``B^+ (z + a_c)(z^2 + a_c1 z + a_c2)`` (Eq 4.35).
    A_o : numpy.ndarray
        ``z^k (z^2 + a_o1 z + a_o2)`` (Eq 4.37).
    coefficients : dict
        ``a_c, a_c1, a_c2, a_o1, a_o2`` (Eq 4.36, 4.38).
    """

    A_c: np.ndarray
    A_o: np.ndarray
    coefficients: dict = field(default_factory=dict)

    @property
    def A_cl(self) -> np.ndarray:
        return np.polymul(self.A_c, self.A_o)


def ppc_polynomials(zeta_c: float, omega_c: float, alpha: float, zeta_o: float, omega_o: float, Ts: float,
                    B_plus=(1.0,), n_origin: int = 3) -> PPCPolynomials:
    """Controller and observer polynomials of the pole-placement design, Eq (4.35)-(4.38).

    Parameters
    ----------
    zeta_c, omega_c : float
        Complex controller poles ``s^2 + 2 zeta_c omega_c s + omega_c^2`` (1.0, 565.49 rad/s; the text's
        Eq 4.35 prints ``omega_c`` for ``omega_c^2``).
    alpha : float
        Real controller pole at ``s = -alpha omega_c`` (1.0).
    zeta_o, omega_o : float
        Complex observer poles (0.7071, 763.43 rad/s = the resonant mode, Eq 4.37).
    Ts : float
        Sampling period [s].
    B_plus : array_like
        Cancelled plant zeros, a factor of ``A_c`` (``z - 0.535``, Eq 4.32).
    n_origin : int
        Observer poles at ``z = 0`` (3 in Eq 4.37).

    Returns
    -------
    PPCPolynomials
    """
    f = "ppc_polynomials"
    omega_c, alpha, omega_o, Ts = _positive(f, omega_c=omega_c, alpha=alpha, omega_o=omega_o, Ts=Ts)
    zeta_c, zeta_o = (real(f, k, v, nonnegative=True) for k, v in (("zeta_c", zeta_c), ("zeta_o", zeta_o)))
    B_plus = polynomial(f, "B_plus", B_plus)
    n_origin = integer(f, "n_origin (observer poles at z = 0)", n_origin, minimum=0)
    a_c = -math.exp(-alpha * omega_c * Ts)
    a_c1, a_c2 = second_order_z(zeta_c, omega_c, Ts)
    a_o1, a_o2 = second_order_z(zeta_o, omega_o, Ts)
    A_c = np.polymul(np.polymul(B_plus, [1.0, a_c]), [1.0, a_c1, a_c2])
    A_o = np.concatenate([[1.0, a_o1, a_o2], np.zeros(n_origin)])
    return PPCPolynomials(A_c, A_o, dict(a_c=a_c, a_c1=a_c1, a_c2=a_c2, a_o1=a_o1, a_o2=a_o2))


def diophantine(a, b, c, deg_x: int, deg_y: int) -> tuple[np.ndarray, np.ndarray]:
    """Solve ``a x + b y = c`` for polynomials ``x`` (degree ``deg_x``) and ``y`` (degree ``deg_y``).

    The coefficients are found from the Sylvester (convolution) matrix
    ``[T_a | T_b] [x; y] = c`` with ``deg_x + deg_y + 2 = deg c + 1`` unknowns and equations; the
    columns are scaled to unit norm first (the plant's ``B`` coefficients are ~1e-10 next to ``A``'s ~1).

    Raises
    ------
    ParameterError
        If the degrees do not give a square system.
    SingularSystemError
        If ``a`` and ``b`` have a common factor (plant not reachable/observable, Sec 4.5).
    """
    a, b, c = (polynomial("diophantine", k, p) for k, p in (("a", a), ("b", b), ("c", c)))
    deg_x, deg_y = (integer("diophantine", k, v, minimum=0) for k, v in (("deg_x", deg_x), ("deg_y", deg_y)))
    n = c.size  # equations: coefficients of z^(n-1) .. z^0
    if deg_x + deg_y + 2 != n:
        raise ParameterError(f"Diophantine a x + b y = c: deg x + deg y + 2 = {deg_x + deg_y + 2} unknowns "
                             f"but deg c + 1 = {n} equations; choose deg x = deg c - deg a, "
                             "deg y = deg a - 1 (Eq 4.28)")
    cols = []
    for poly, deg in ((a, deg_x), (b, deg_y)):
        for k in range(deg + 1):  # column for the coefficient of z^(deg - k)
            col = np.zeros(n)
            p = np.concatenate([poly, np.zeros(deg - k)])  # poly * z^(deg-k)
            if p.size > n:
                raise ParameterError(f"Diophantine: deg {poly.size - 1} + {deg} exceeds deg c = {n - 1}")
            col[n - p.size:] = p
            cols.append(col)
    M = np.array(cols).T
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    Ms = M / scale
    if np.linalg.cond(Ms) > 1e13:
        raise SingularSystemError("Diophantine equation is singular: A and B share a factor (a common "
                                  "pole/zero, Sec 4.5: the plant must be reachable and observable)")
    sol = np.linalg.solve(Ms, c) / scale
    return sol[:deg_x + 1], sol[deg_x + 1:]


@dataclass(frozen=True)
class RSTDesign:
    """Result of :func:`rst_design`: ``R``, ``S``, ``T = t0 A_o`` (Table 4.6) and the design data.

    Attributes
    ----------
    R, S, T : numpy.ndarray
        Controller polynomials (descending powers of z), ``R = B^+ R_d R^*``, ``S = A^+ S_d S^*``.
    t0 : float
        ``A_c(1)/B(1)`` (Eq 4.29).
    R_star, S_star : numpy.ndarray
        Remainders of Eq (4.25) (``R^* = z^3 + r_1 z^2 + r_2 z + r_3`` and ``S^* = s_0 z^4 + ... + s_4`` in
        Eq 4.34).
    A, B, A_c, A_o : numpy.ndarray
        Plant and desired polynomials.
    Ts : float
    """

    R: np.ndarray
    S: np.ndarray
    T: np.ndarray
    t0: float
    R_star: np.ndarray
    S_star: np.ndarray
    A: np.ndarray
    B: np.ndarray
    A_c: np.ndarray
    A_o: np.ndarray
    Ts: float

    @property
    def r(self) -> np.ndarray:
        """``r_1, r_2, ...`` of ``R^*`` (Table 4.6)."""
        return self.R_star[1:] / self.R_star[0]

    @property
    def s(self) -> np.ndarray:
        """``s_0, s_1, ...`` of ``S^*`` (Table 4.6)."""
        return self.S_star

    def controller(self):
        """The sampled block (:class:`bscomp.components.RSTController`)."""
        return RSTController(self.R, self.S, self.T, self.Ts)

    def closed_loop_residual(self) -> float:
        """``max |A R + B S - A_c A_o|`` relative to ``max |A_c A_o|`` (checks Eq 4.26)."""
        lhs = np.polyadd(np.polymul(self.A, self.R), np.polymul(self.B, self.S))
        acl = np.polymul(self.A_c, self.A_o)
        return float(np.max(np.abs(np.polysub(lhs, acl))) / np.max(np.abs(acl)))


def _divide_exact(num, den, what):
    num = np.asarray(num, float)
    q, r = np.polydiv(num, np.asarray(den, float))
    rel = np.max(np.abs(r)) / np.max(np.abs(num)) if r.size else 0.0
    if rel > 1e-7:
        raise ParameterError(f"{what} does not divide exactly (relative remainder {rel:.3g}): give the exact "
                             "factor, e.g. from split_polynomial(B, near=[0.535])")
    return q


def _targets(near, deg):
    """``near`` of :func:`split_polynomial` as a 1-D complex array of at most ``deg`` finite numbers."""
    what = "a number or a sequence of numbers (the roots to pick, e.g. [0.535])"
    try:
        t = np.atleast_1d(np.asarray(near))
    except (TypeError, ValueError):
        t = np.array([object()])
    if isinstance(near, (str, bytes)) or near is None or t.ndim != 1 or t.dtype.kind not in "iufc":
        raise ArgumentTypeError(f"split_polynomial: near must be {what}, got {type(near).__name__} {near!r}"[:300])
    if not np.all(np.isfinite(t)):
        raise ParameterError(f"split_polynomial: near = {t.tolist()} must be finite")
    if not 1 <= t.size <= deg:
        raise UsageError(f"split_polynomial: near has {t.size} targets, P has {deg} roots: give 1 to {deg}")
    return t.astype(complex)


def split_polynomial(P, near) -> tuple[np.ndarray, np.ndarray]:
    """Factor ``P = P^+ P^-`` with ``P^+`` monic, made of the roots of ``P`` nearest to ``near``.

    The thesis prints the cancelled zero rounded (``B^+ = z - 0.535``, Eq 4.32); the Diophantine solve
    needs the exact root of ``B`` (0.53543 for Table 4.4), which this returns.

    Returns
    -------
    P_plus, P_minus : numpy.ndarray
    """
    P = polynomial("split_polynomial", "P", P, min_degree=1)
    targets = _targets(near, P.size - 1)
    roots = list(np.roots(P))
    chosen = []
    for target in targets:
        k = int(np.argmin([abs(r - target) for r in roots]))
        chosen.append(roots.pop(k))
    P_plus = np.real_if_close(np.poly(chosen)).real
    return P_plus, _divide_exact(P, P_plus, "P by P+")


def _rst_polynomials(A, B, A_c, A_o, B_plus, A_plus, R_d, S_d):
    """The polynomial arguments of :func:`rst_design`, checked, as float arrays without leading zeros."""
    f = "rst_design"
    raw_A = polynomial(f, "A", A, trim=False)
    if raw_A[0] == 0:
        raise ParameterError(f"rst_design: A = {raw_A.tolist()} has a zero leading coefficient: A(z) is the "
                             "plant denominator in descending powers of z, monic (Eq 4.31), e.g. "
                             "[1.0, -0.9] for z - 0.9")
    A = polynomial(f, "A", A, min_degree=1)
    B = polynomial(f, "B", B)
    if B.size > A.size:
        raise ParameterError(f"rst_design: deg B = {B.size - 1} > deg A = {A.size - 1}: B(z)/A(z) is not "
                             "causal; give both in descending powers of z")
    rest = (polynomial(f, k, v) for k, v in (("A_c", A_c), ("A_o", A_o), ("B_plus", B_plus),
                                              ("A_plus", A_plus), ("R_d", R_d), ("S_d", S_d)))
    return (A, B, *rest)


def rst_design(A, B, A_c, A_o, B_plus=(1.0,), A_plus=(1.0,), R_d=(1.0,), S_d=(1.0,), Ts: float = 2.0e-4,
               t0: float | None = None) -> RSTDesign:
    """Pole-placement (RST) controller from the Diophantine equation ``A R + B S = A_c A_o`` (Eq 4.26).

    Parameters
    ----------
    A, B : array_like
        Plant ``B(z)/A(z)`` (Eq 4.31), e.g. from :func:`zoh_polynomials` or Table 4.4.
    A_c, A_o : array_like
        Controller and observer polynomials (Eq 4.23), e.g. from :func:`ppc_polynomials`; ``A_c`` must
        contain ``B^+`` (a cancelled zero stays a closed-loop pole) and ``A_c A_o`` must contain ``A^+``.
    B_plus, A_plus : array_like
        Cancelled well-damped plant zeros and poles (Eq 4.24, 4.32): ``B = B^+ B^-``, ``A = A^+ A^-``.
    R_d, S_d : array_like
        Imposed factors of ``R`` and ``S`` (Eq 4.25, 4.33): ``z - 1`` (integral action against constant
        disturbances) and ``z + 1`` (no noise feedback at the Nyquist frequency).
    Ts : float
        Sampling period [s].
    t0 : float, optional
        Feed-forward gain; default ``A_c(1)/B(1)`` (unit static gain, Eq 4.29).

    Returns
    -------
    RSTDesign

    Notes
    -----
    With ``R = B^+ R_d R^*`` and ``S = A^+ S_d S^*`` (Eq 4.25), Eq (4.26) divided by ``A^+ B^+`` is

    .. math:: A^- R_d\\, R^* + B^- S_d\\, S^* = \\frac{A_c A_o}{A^+ B^+}

    solved at minimum degree (Eq 4.27-4.28): ``deg S^* = deg A^- + deg R_d - 1`` and
    ``deg R^* = deg(A_c A_o) - deg(A^+ B^+) - deg A^- - deg R_d``. ``R^*`` comes out monic when
    ``deg(B^- S_d S^*)`` is below the right-hand side's degree. ``T = t_0 A_o``.
    """
    A, B, A_c, A_o, B_plus, A_plus, R_d, S_d = _rst_polynomials(A, B, A_c, A_o, B_plus, A_plus, R_d, S_d)
    (Ts,) = _positive("rst_design", Ts=Ts)
    if t0 is not None:
        t0 = real("rst_design", "t0", t0)
    A_minus = _divide_exact(A, A_plus, "A by A+")
    B_minus = _divide_exact(B, B_plus, "B by B+")
    rhs = _divide_exact(np.polymul(A_c, A_o), np.polymul(A_plus, B_plus), "A_c A_o by A+ B+")
    a = np.polymul(A_minus, R_d)
    b = np.polymul(B_minus, S_d)
    deg_s = a.size - 2
    if deg_s < 0:
        raise ParameterError(f"rst_design: A^- R_d = {a.tolist()} has degree 0 (A = {A.tolist()}, "
                             f"A+ = {A_plus.tolist()}, R_d = {R_d.tolist()}): nothing is left to place and S "
                             "would be empty; give the plant's A with degree >= 1 and cancel less in A_plus")
    deg_r = rhs.size - 1 - (a.size - 1)
    if deg_r < 0:
        raise ParameterError(f"deg(A_c A_o) = {np.polymul(A_c, A_o).size - 1} is too low for "
                             f"deg A = {A.size - 1}: Eq 4.27 asks deg A_cl = 2 deg A + deg R_d + deg S_d - 1")
    R_star, S_star = diophantine(a, b, rhs, deg_r, deg_s)
    R = np.polymul(np.polymul(B_plus, R_d), R_star)
    S = np.polymul(np.polymul(A_plus, S_d), S_star)
    if t0 is None:
        B1 = np.polyval(B, 1.0)
        if B1 == 0:
            raise SingularSystemError("B(1) = 0: the plant has a zero at z = 1, t0 of Eq 4.29 is undefined")
        t0 = float(np.polyval(A_c, 1.0) / B1)
    return RSTDesign(R=R, S=S, T=t0 * A_o, t0=float(t0), R_star=R_star, S_star=S_star, A=A, B=B, A_c=A_c,
                     A_o=A_o, Ts=float(Ts))
