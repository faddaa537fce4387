"""Harmonic response of the driven transducer: tip amplitude per volt, admittance, power.

The hot electrode is driven at a voltage amplitude ``V`` (time factor ``exp(+j w t)``); the
ground electrodes are at 0 V. With the hysteretic loss matrix ``L`` (mechanical ``1/Q`` per
region, dielectric ``tan(delta)``, see :class:`LossModel`) the free unknowns solve::

    (K + j L - w^2 M) x_f = b,   b = -(k_hot + j l_hot) V / s        (fem.assembly.Split)

Two solution methods
--------------------
``direct``
    One complex-symmetric factorisation per frequency (``fem.solvers.factorize``; PARDISO
    solves it through its real symmetric 2n x 2n equivalent). Exact; used at the working
    point and as the reference of the tests.
``modal`` (default for sweeps)
    Superposition of the short-circuit modes ``phi_i`` (``Phi^T M Phi = I``,
    ``Phi^T K Phi = Lambda``) near the band, each with its modal loss factor
    ``eta_i = phi_i^T L phi_i / lambda_i``, plus a residual for the truncated modes taken at
    a shift ``sigma`` in the band: with ``A_T^-1 = (K - sigma M)^-1 - sum_i phi_i phi_i^T /
    (lambda_i - sigma)`` (the inverse on the truncated modes), ``R = A_T^-1 b - j A_T^-1 L A_T^-1
    b``, the truncated response to first order in the losses (two solves with one real
    factorisation)::

        x_f(w) = sum_i phi_i (phi_i^T b) / (lambda_i (1 + j eta_i) - w^2) + R

    (in full: the modal loss matrix ``Phi^T L Phi`` is kept whole, a small dense solve per
    frequency; the first-order loss coupling between the modes and the truncated space is
    included; and the truncated response is expanded to second order in ``w^2 - sigma``,
    ``R(w) = R + d A_T^-1 M R0 + d^2 (A_T^-1 M)^2 R0``, because the higher longitudinal modes that
    carry the clamped-field charge change by ~10 % across a resonance/anti-resonance band; see
    :class:`ModalBasis`). The modal basis and the residual are computed once; each frequency then costs O(n_modes),
    because every output (surface means, charge) is a linear functional precomputed on the
    basis. This is what makes a 200-point admittance sweep cheap.

Outputs
-------
Electrode charge ``Q = -(K + j L)[hot] x / s`` (fem.assembly convention), current
``I = j w Q``, admittance ``Y = I / V``, input power ``P = Re(V conj(I)) / 2``; complex
area-weighted mean displacements on named surfaces: ``axial`` (along z), ``tangential``
(about the z axis) and ``radial``, in m (``fem.modeshape.surface_rows``: the field projected on
the cylindrical unit vectors at the surface's quadrature points, the same means as
``fem.modeshape.surface_motion``).
"""

from __future__ import annotations

if __name__ == "__main__":
    # python -m fem.harmonic: the command line lives in fem.harmonic_cli (named, not imported:
    # physics modules do not parse arguments); signal handling comes before any heavy import
    import sys

    from rpud_common.launch import launch

    sys.exit(launch("fem.harmonic_cli", prog="fem.harmonic"))

import logging
import time
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
import scipy.sparse as sp

from rpud_common import ParameterError, check_positive, check_range
from rpud_common.result import Result

from .assembly import PiezoSystem
from .modeshape import COMPONENTS, surface_rows
from .solvers import factorize

__all__ = ["LossModel", "loss_matrix", "SurfaceFunctional", "surface_functional",
           "solve_direct", "ModalBasis", "modal_basis", "HarmonicResult", "harmonic_sweep",
           "working_point", "WorkingPoint", "charge_row"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LossModel:
    """Losses of a driven analysis.

    Attributes
    ----------
    q_mech : float or None
        Mechanical quality factor applied to every region (``inf``: lossless). ``None`` takes
        each material's ``q_mech`` from the library (PZT-8 1000, steel 5000, ...).
    tan_delta : float or None
        Dielectric loss tangent of every ceramic region; ``None`` takes the material values.
    """

    q_mech: float | None = None
    tan_delta: float | None = None

    def __post_init__(self):
        if self.q_mech is not None and not (self.q_mech == np.inf or
                                            (np.isfinite(self.q_mech) and self.q_mech > 0)):
            raise ParameterError("q_mech", self.q_mech, "must be > 0 (inf for lossless)")
        if self.tan_delta is not None:
            check_range("tan_delta", self.tan_delta, 0.0, 1.0)

    @property
    def lossless(self) -> bool:
        return self.q_mech == np.inf and self.tan_delta == 0.0


def loss_matrix(system: PiezoSystem, loss: LossModel = LossModel()) -> sp.csr_matrix:
    """The hysteretic loss matrix ``L`` (same layout as ``system.K``) for a loss model."""
    if loss.q_mech is None and loss.tan_delta is None:
        return system.K_loss
    n_u = system.n_u
    blocks = []
    L = system.K_loss.tocsr()
    K = system.K.tocsr()
    is_u = np.zeros(system.ndof, dtype=bool)
    is_u[:n_u] = True
    sel_u = sp.diags(is_u.astype(float))
    sel_e = sp.diags((~is_u).astype(float))
    if loss.q_mech is None:
        blocks.append(sel_u @ L @ sel_u)
    elif np.isfinite(loss.q_mech):
        blocks.append(sel_u @ K @ sel_u / loss.q_mech)
    if loss.tan_delta is None:
        blocks.append(sel_e @ L @ sel_e)
    elif loss.tan_delta > 0:
        # K's potential block is -s^2 K_phiphi; the dielectric loss is +tan(delta) s^2 K_phiphi
        blocks.append(-loss.tan_delta * (sel_e @ K @ sel_e))
    out = sum(blocks) if blocks else sp.csr_matrix(K.shape)
    return sp.csr_matrix(out)


# --------------------------------------------------------------------------- surface outputs


@dataclass(frozen=True, eq=False)
class SurfaceFunctional:
    """Linear maps from a full solution vector to the mean motion of one surface.

    ``rows`` is (3, ndof): applied to ``x`` it gives the area-weighted mean axial, tangential
    and radial displacement (m) on the surface ``name`` of area ``area`` (m^2).
    """

    name: str
    area: float
    rows: sp.csr_matrix

    def __call__(self, x: np.ndarray) -> dict[str, complex]:
        vals = self.rows @ np.asarray(x)
        return {c: vals[i] for i, c in enumerate(COMPONENTS)}


def surface_functional(system: PiezoSystem, name: str) -> SurfaceFunctional:
    """Area-weighted mean displacement on the facet set ``name`` as a linear functional:
    :func:`fem.modeshape.surface_rows` (about the z axis) on the u DOFs, zero on the potential."""
    rows, area = surface_rows(system, name)
    rows = rows.tocoo()
    out = sp.csr_matrix((rows.data, (rows.row, rows.col)), shape=(3, system.ndof))
    tie = getattr(system, "tie", None)            # a sector system's vectors hold its unknowns only
    return SurfaceFunctional(name, area, out if tie is None else (out @ tie).tocsr())


def charge_row(system: PiezoSystem, L: sp.csr_matrix) -> np.ndarray:
    """Dense row r with Q = r @ x (complex; the lossy hot row over -s)."""
    hot = system.hot_dof
    row = system.K[hot].toarray().ravel() + 1j * L[hot].toarray().ravel()
    return -row / system.phi_scale


def _check_freqs(freqs) -> np.ndarray:
    f = np.atleast_1d(np.asarray(freqs, dtype=float))
    if f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError("freq", freqs, "frequencies must be finite numbers > 0 Hz")
    return f


LOSSLESS_RESONANCE_RTOL = 1e-6
"""A lossless drive closer than this (relative) to a resonance is refused: unbounded response."""


def _refuse_lossless_resonance(system, f: np.ndarray, loss: LossModel, clamp, backend, f_r_hz=None) -> None:
    """Without any loss the response at a short-circuit resonance is unbounded: a finite number
    printed there would be round-off. Refused with the resonance named; the resonances come from
    ``f_r_hz`` (a basis) or one small eigen solve per frequency."""
    if not loss.lossless:
        return
    from .modal import modal_analysis

    f = np.atleast_1d(f)
    if f_r_hz is None and f.size > 1:
        f_r_hz = _band_modes(system, f, 12, int(min(MAX_BASIS_MODES, system.ndof // 4)), clamp, backend)[0].f_r_hz
    for fk in f:
        if f_r_hz is None:
            # shift just below the drive frequency (a shift on an eigenvalue would be singular)
            near = modal_analysis(system, fk, 2, clamp=clamp, backend=backend, open_circuit=False,
                                  sigma=(2 * np.pi * fk) ** 2 * (1 - 1e-3)).f_r_hz
        else:
            near = np.asarray(f_r_hz, float)
        if near.size and np.min(np.abs(near - fk)) <= LOSSLESS_RESONANCE_RTOL * fk:
            fr = float(near[np.argmin(np.abs(near - fk))])
            raise ParameterError("freq", float(fk), f"is the resonance {fr:.6f} Hz of a lossless model: the response "
                                                    "is unbounded there; add loss (q_mech, tan_delta) or drive off "
                                                    "the resonance")


def _check_voltage(voltage) -> float:
    check_positive("voltage", voltage, "V")
    return float(voltage)


# --------------------------------------------------------------------------- direct solution


def solve_direct(system: PiezoSystem, freq_hz: float, voltage: float = 1.0, *,
                 clamp: Iterable[str] = (), loss: LossModel = LossModel(),
                 backend: str | None = None) -> np.ndarray:
    """Full complex solution vector ``x`` at one frequency by a direct factorisation."""
    f = _check_freqs(freq_hz)[0]
    _check_voltage(voltage)
    split = system.split(tuple(clamp))
    L = loss_matrix(system, loss)
    Lf = L[split.free][:, split.free]
    w2 = (2 * np.pi * f) ** 2
    A = (split.K - w2 * split.M + 1j * Lf).tocsr()
    lh = np.asarray(L[:, [system.hot_dof]].toarray()).ravel()[split.free]
    b = -(split.k_hot + 1j * lh) * (voltage / system.phi_scale)
    xf = factorize(A, backend=backend)(b)
    return system.expand(xf, split.free, voltage)


# --------------------------------------------------------------------------- modal superposition


@dataclass(eq=False)
class ModalBasis:
    """Short-circuit modes + residual on the driven free set, ready for superposition.

    ``Phi`` (n_free, n) mass-normalised modes, ``lam`` (n,) eigenvalues (rad/s)^2, ``eta``
    (n,) modal loss factors (diagonal of ``D / lam``), ``D = Phi^T L Phi`` the modal loss
    matrix, ``R`` (n_free,) complex residual response to the unit-voltage load ``b1``,
    ``gamma = Phi^T b1``; ``W = (A_T + j L_T)^-1 L Phi``, ``E = Phi^T L W`` and
    ``g = gamma - j Phi^T L R`` carry the loss coupling between modes and truncated space (all
    orders at the shift). Solutions scale linearly with the voltage.
    """

    free: np.ndarray
    Phi: np.ndarray
    lam: np.ndarray
    eta: np.ndarray
    gamma: np.ndarray
    R: np.ndarray
    R_terms: np.ndarray
    D: np.ndarray
    W: np.ndarray
    E: np.ndarray
    g: np.ndarray
    b1: np.ndarray
    sigma: float
    loss: LossModel
    clamp: tuple[str, ...]
    f_r_hz: np.ndarray
    seconds: float = 0.0
    L: sp.csr_matrix | None = field(default=None, repr=False)
    """The loss matrix of ``loss`` on the whole system (for charges and working points)."""
    factor: object = field(default=None, repr=False)
    """The factorisation of ``K - sigma M`` behind the residual (another loss model may reuse it)."""

    def coordinates(self, freq_hz: np.ndarray, damper: tuple[np.ndarray, float] | None = None) -> np.ndarray:
        """Modal coordinates per volt, (n_freq, n_modes) complex:
        ``(Lambda + j D + E + j w c s s^T - w^2 I) q = g`` with the full modal loss matrix ``D``
        and an optional viscous damper ``damper = (s, c)``: ``c`` (N s/m) acting on the
        displacement ``s^T q`` (``s``: the damped output per modal coordinate)."""
        w = 2 * np.pi * np.atleast_1d(np.asarray(freq_hz, dtype=float))
        n = len(self.lam)
        A = (np.diag(self.lam) + 1j * self.D + self.E)[None, :, :] - (w ** 2)[:, None, None] * np.eye(n)[None]
        if damper is not None:
            s, c = damper
            A = A + 1j * (w * c)[:, None, None] * np.outer(s, s)[None]
        return np.linalg.solve(A, np.broadcast_to(self.g, (len(w), n))[..., None])[..., 0]

    def columns(self) -> np.ndarray:
        """(n_free, n_modes + n_terms): ``x_f = columns @ weights(f)`` per volt: the modes
        (corrected for the loss coupling into the truncated space), then the residual terms."""
        return np.column_stack([self.Phi - 1j * self.W, self.R_terms])

    def weights(self, freq_hz: np.ndarray, damper=None) -> np.ndarray:
        """(n_freq, n_modes + n_terms): modal coordinates, then ``(w^2 - sigma)^k``."""
        f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
        d = (2 * np.pi * f) ** 2 - self.sigma
        powers = d[:, None] ** np.arange(self.R_terms.shape[1])[None, :]
        return np.column_stack([self.coordinates(f, damper), powers])

    def solution_free(self, freq_hz: float, voltage: float = 1.0, damper=None) -> np.ndarray:
        """``x_f`` at one frequency (complex, on ``free``); ``damper`` as in :meth:`coordinates`."""
        return self.columns() @ self.weights(freq_hz, damper)[0] * voltage


def modal_basis(system: PiezoSystem, near_hz: float, n_modes: int = 12, *, clamp: Iterable[str] = (),
                loss: LossModel = LossModel(), modes=None, residual_order: int = 2,
                backend: str | None = None, reuse: "ModalBasis | None" = None) -> ModalBasis:
    """Build the superposition basis: short-circuit modes near ``near_hz`` and the residual.

    ``modes`` may be a :class:`fem.modal.ModalResult` already computed for the same system and
    clamp (its vectors are reused); otherwise ``n_modes`` modes are computed. The residual
    needs one factorisation of ``K - sigma M`` (the modal shift); ``reuse``, a basis of the same
    system, modes and clamp under another loss model, lends its factorisation (it does not
    depend on the losses); so do ``modes`` that kept theirs (:attr:`fem.modal.ModalResult.factor`)
    when the residual's shift is the modal shift.
    """
    from .modal import modal_analysis

    t0 = time.perf_counter()
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    if system.hot_dof is None:
        raise ParameterError("electrodes", "none hot", "a driven problem needs a hot electrode")
    if modes is None:
        # shift slightly below the centre: a shift exactly on an eigenvalue is singular
        sigma = (2 * np.pi * near_hz) ** 2 * (1 - 2e-3)
        modes = modal_analysis(system, near_hz, n_modes, clamp=clamp, backend=backend,
                               open_circuit=False, sigma=sigma)
    if tuple(modes.clamp) != clamp:
        raise ParameterError("clamp", clamp, f"must match the modal analysis' clamp {tuple(modes.clamp)}")
    split = system.split(clamp)
    free = split.free
    Phi = modes.vectors[free]                      # short-circuit free set == driven free set
    L = loss_matrix(system, loss)
    Lf = L[free][:, free]
    lam = (2 * np.pi * modes.f_r_hz) ** 2
    eta = np.einsum("ij,ij->j", Phi, Lf @ Phi) / lam
    lh = np.asarray(L[:, [system.hot_dof]].toarray()).ravel()[free]
    b1 = -(split.k_hot + 1j * lh) / system.phi_scale
    gamma = Phi.T @ b1
    sigma = _residual_shift(float(modes.sigma), lam)
    if reuse is not None and reuse.factor is not None and reuse.sigma == sigma and reuse.clamp == clamp:
        F = reuse.factor
    elif getattr(modes, "factor", None) is not None and float(modes.sigma) == sigma:
        F = modes.factor                           # the modal analysis' own, at the same shift and free set
    else:
        log.debug("harmonic: the residual factorises K - sigma M at %.6g (the modes' shift %.6g)", sigma, modes.sigma)
        F = factorize((split.K - sigma * split.M).tocsr(), backend=backend)

    def solve_truncated(v):
        """(K - sigma M)^-1 v with the basis modes deflated (exact: Phi is M-orthonormal);
        ``v`` one vector (n,) or several columns (n, k), solved in one call."""
        V = v.reshape(len(v), -1)
        k = V.shape[1]
        y = F(np.column_stack([V.real, V.imag]))
        out = y[:, :k] + 1j * y[:, k:] - Phi @ ((Phi.T @ V) / (lam - sigma)[:, None])
        return out.reshape(v.shape)

    def solve_lossy(v):
        """(A_T + j L_T)^-1 v on the truncated space: the Neumann series z = T v - j T L z on
        the real factorisation (|T L| ~ the loss factors, so a few terms reach round-off).
        First order in the losses is not enough at an anti-resonance, where |Y| itself is of
        the order of the losses (tan delta 0.01 gave a 9 % error in |Y| there)."""
        z0 = solve_truncated(v)
        z = z0
        for it in range(60):
            z_new = z0 - 1j * solve_truncated(real_times(Lf, z))
            done = np.linalg.norm(z_new - z) <= 1e-10 * max(np.linalg.norm(z_new), 1e-300)
            z = z_new
            if done:
                break
        log.debug("harmonic: lossy truncated solve, %d terms", it + 1)
        return z

    # the truncated modes' response, with their (and the clamped field's) dielectric and
    # mechanical loss; deflating first keeps the expansion valid near resonance
    # (one multi-column series for the residual and the mode coupling below)
    LPhi = (Lf @ Phi).astype(complex) if Phi.shape[1] else np.zeros((len(free), 0), complex)
    RW = solve_lossy(np.column_stack([b1, LPhi]))
    R0 = solve_truncated(b1)
    R, W = RW[:, 0], RW[:, 1:]
    # frequency dependence of the truncated modes: (A_T - d M)^-1 b = sum_k d^k (A_T^-1 M)^k A_T^-1 b
    # with d = w^2 - sigma; the higher longitudinal modes that carry the clamped-field charge
    # change by ~10 % across the band, so the series is kept to second order
    Mf = split.M
    terms = [R]
    for _ in range(residual_order):
        terms.append(solve_truncated(real_times(Mf, terms[-1] if len(terms) > 1 else R0)))
    # loss couples the modes with each other and with the truncated space (first order)
    D = Phi.T @ (Lf @ Phi)
    E = Phi.T @ real_times(Lf, W)
    g = gamma - 1j * (Phi.T @ real_times(Lf, R))
    seconds = time.perf_counter() - t0
    log.info("harmonic: modal basis of %d modes (%.1f-%.1f kHz) + residual at sigma, %.2f s",
             len(lam), modes.f_r_hz.min() / 1e3 if len(lam) else 0, modes.f_r_hz.max() / 1e3 if len(lam) else 0,
             seconds)
    return ModalBasis(free=free, Phi=Phi, lam=lam, eta=eta, gamma=gamma, R=R, D=D, W=W, E=E, g=g, b1=b1,
                      R_terms=np.column_stack(terms), sigma=sigma,
                      loss=loss, clamp=clamp, f_r_hz=np.asarray(modes.f_r_hz, float), seconds=seconds,
                      L=L, factor=F)


def real_times(A, z: np.ndarray) -> np.ndarray:
    """``A @ z`` for a real sparse ``A`` and a (complex) ``z``, the real and imaginary parts as
    the columns of one real product: scipy would copy ``A`` to complex on every call (the
    product itself is the same, bit for bit, and ~3x cheaper on the article's drill)."""
    if not np.iscomplexobj(z) or np.iscomplexobj(A.data):
        return A @ z
    Z = z.reshape(len(z), -1)
    k = Z.shape[1]
    y = A @ np.column_stack([Z.real, Z.imag])
    return (y[:, :k] + 1j * y[:, k:]).reshape(z.shape)


def _residual_shift(sigma: float, lam: np.ndarray) -> float:
    """A shift in the band but not on an eigenvalue (K - sigma M must be regular)."""
    for _ in range(50):
        if len(lam) == 0 or np.min(np.abs(lam - sigma)) > 1e-3 * abs(sigma):
            return sigma
        sigma *= 0.995
    return sigma


# --------------------------------------------------------------------------- sweep


@dataclass(eq=False, repr=False)
class HarmonicResult(Result):
    """Frequency response at a drive voltage.

    Attributes
    ----------
    freqs_hz : (n,) Hz
    voltage : V (amplitude)
    admittance : (n,) complex, S
    current : (n,) complex, A (amplitude)
    power_w : (n,) W, time-averaged electrical input power
    surfaces : dict name -> dict component -> (n,) complex mean displacement, m
    method : "modal" or "direct"
    f_r_hz, f_a_hz : resonance / anti-resonance of the admittance in the band (Hz): the
        frequencies of max and min ``|Y|`` refined by parabolic interpolation, NaN if at an edge.
    timings : dict, s
    """

    freqs_hz: np.ndarray
    voltage: float
    admittance: np.ndarray
    current: np.ndarray
    power_w: np.ndarray
    surfaces: dict
    method: str
    loss: LossModel
    timings: dict = field(default_factory=dict)
    basis_modes: int = 0
    """Modes in the modal basis (0 for the direct method)."""
    check_error: float = float("nan")
    """Worst relative difference to the direct check solves (NaN: not checked)."""
    materials: dict = field(default_factory=dict)
    """The material constants assembled, name -> record (``PiezoSystem.materials_block``)."""

    @property
    def f_r_hz(self) -> float:
        return _extremum(self.freqs_hz, np.abs(self.admittance), "max")

    @property
    def f_a_hz(self) -> float:
        return _extremum(self.freqs_hz, np.abs(self.admittance), "min")

    def amplitude(self, surface: str = "horn_tip", component: str = "axial") -> np.ndarray:
        """Modulus of the mean displacement (m) of a surface component over the band."""
        if surface not in self.surfaces:
            raise ParameterError("surface", surface, "not computed; computed: " + ", ".join(self.surfaces))
        return np.abs(self.surfaces[surface][component])

    def _headline(self) -> str:
        f = self.freqs_hz
        head = (f"{self.method}, {f.size} frequencies {f.min() / 1e3:.3f}-{f.max() / 1e3:.3f} kHz at "
                f"{self.voltage:g} V: f_r {self.f_r_hz:.1f} Hz, f_a {self.f_a_hz:.1f} Hz")
        if "horn_tip" in self.surfaces:
            head += f", peak tip {self.amplitude().max() / self.voltage * 1e6:.3g} um/V"
        return head

    def _record(self) -> dict:
        return {
            "method": self.method, "voltage_v": self.voltage, "basis_modes": self.basis_modes,
            "check_error": self.check_error,
            "loss": {"q_mech": self.loss.q_mech, "tan_delta": self.loss.tan_delta},
            "f_r_hz": _nan_none(self.f_r_hz), "f_a_hz": _nan_none(self.f_a_hz),
            "freqs_hz": self.freqs_hz.tolist(),
            "admittance_s": {"re": self.admittance.real.tolist(), "im": self.admittance.imag.tolist()},
            "power_w": self.power_w.tolist(),
            "surfaces": {s: {c: {"abs_m": np.abs(v).tolist(), "phase_deg": np.degrees(np.angle(v)).tolist()}
                             for c, v in comps.items()} for s, comps in self.surfaces.items()},
            "timings": self.timings,
            "materials": self.materials,
        }


def _nan_none(v):
    return None if v is None or not np.isfinite(v) else float(v)


def _extremum(f: np.ndarray, y: np.ndarray, kind: str) -> float:
    k = int(np.argmax(y) if kind == "max" else np.argmin(y))
    if k == 0 or k == len(f) - 1:
        return float("nan")
    # parabola through the three samples around the extremum (in log |Y|: peaks are sharp)
    y3 = np.log(y[k - 1:k + 2])
    f3 = f[k - 1:k + 2]
    c = np.polyfit(f3 - f3[1], y3, 2)
    if c[0] == 0:
        return float(f[k])
    return float(f3[1] - c[1] / (2 * c[0]))


BAND_TOL = 0.01
"""Largest relative difference between the modal sweep and a direct solve at a check frequency."""

MAX_BASIS_MODES = 192
"""Most modes a basis grows to while it tries to represent a wide band."""

_REACH = 0.5        # rule for the basis size: |w^2 - sigma| <= _REACH * (basis radius) in the band


def basis_reach(basis, freqs_hz) -> float:
    """How far the band reaches out of the basis: ``max |w^2 - sigma| / max |lam_i - sigma|``.

    The residual (truncated modes) is a power series in ``w^2 - sigma``; every truncated
    eigenvalue lies farther from ``sigma`` than the farthest basis mode, so the series converges
    in the band when this ratio is below 1 and is accurate to ~ratio^3 of the residual. ``inf``
    for a basis without modes. ``basis``: a :class:`ModalBasis` or the
    :class:`fem.modal.ModalResult` it is built from.
    """
    w2 = (2 * np.pi * np.atleast_1d(np.asarray(freqs_hz, float))) ** 2
    lam = (2 * np.pi * np.asarray(basis.f_r_hz, float)) ** 2
    radius = float(np.max(np.abs(lam - basis.sigma))) if len(lam) else 0.0
    return float(np.max(np.abs(w2 - basis.sigma)) / radius) if radius > 0 else np.inf


def _band_modes(system, f, n, cap, clamp, backend):
    """Short-circuit modes for a basis over ``f``: ``n`` modes, doubled while the band reaches
    out of them (:func:`basis_reach` > 0.5) and the size limit ``cap`` allows."""
    from .modal import modal_analysis

    near = float(np.sqrt(f.min() * f.max()))
    sigma = (2 * np.pi * near) ** 2 * (1 - 2e-3)       # not on an eigenvalue
    while True:
        modes = modal_analysis(system, near, n, clamp=clamp, backend=backend, open_circuit=False, sigma=sigma)
        if basis_reach(modes, f) <= _REACH or n >= cap:
            return modes, n
        n = min(2 * n, cap)
        log.info("harmonic: the band %.6g-%.6g Hz reaches out of the basis: %d modes", f.min(), f.max(), n)


def _modal_values(system, basis, f, funcs, qrow, voltage):
    """Charge and surface means over ``f`` from the basis (outputs as functionals of it)."""
    free = basis.free
    cols = basis.columns()
    full = np.zeros((system.ndof, cols.shape[1]), complex)
    full[free] = cols
    hot_x = np.zeros(cols.shape[1], complex)
    hot_x[len(basis.lam)] = 1.0 / system.phi_scale   # the hot voltage rides on the weight-1 term
    full[system.hot_dof] = hot_x
    coef = basis.weights(f) * voltage
    Q = coef @ (qrow @ full)
    out = {}
    for s in funcs:
        vals = coef @ (s.rows @ full).T                # (n_f, 3)
        out[s.name] = {c: vals[:, i] for i, c in enumerate(COMPONENTS)}
    return Q, out


def _direct_values(system, fk, voltage, clamp, loss, backend, funcs, qrow):
    x = solve_direct(system, fk, voltage, clamp=clamp, loss=loss, backend=backend)
    return qrow @ x, {s.name: s.rows @ x for s in funcs}


def _band_check(system, basis, f, Q, out_s, voltage, clamp, loss, backend, funcs, qrow) -> tuple[float, float]:
    """Worst relative difference to direct solves at the band's two ends and its middle, and
    where. Charges are compared relative to the direct charge, surface motion relative to the
    largest modal amplitude of that surface in the band (a node is not a 100 % error)."""
    idx = sorted({0, len(f) // 2, len(f) - 1})
    worst, where = 0.0, float(f[0])
    for k in idx:
        q_d, s_d = _direct_values(system, float(f[k]), voltage, clamp, loss, backend, funcs, qrow)
        errs = [abs(Q[k] - q_d) / max(abs(q_d), 1e-300)]
        for s in funcs:
            scale = max(max(np.abs(v).max() for v in out_s[s.name].values()), 1e-300)
            errs += [abs(out_s[s.name][c][k] - s_d[s.name][i]) / scale for i, c in enumerate(COMPONENTS)]
        if max(errs) > worst:
            worst, where = max(errs), float(f[k])
    return worst, where


def harmonic_sweep(system: PiezoSystem, freqs_hz: Sequence[float], voltage: float = 1.0, *,
                   clamp: Iterable[str] = (), loss: LossModel = LossModel(),
                   surfaces: Sequence[str] = ("horn_tip",), method: str = "modal",
                   basis: ModalBasis | None = None, n_modes: int = 12,
                   backend: str | None = None, progress=None, check: bool | None = None) -> HarmonicResult:
    """Admittance and surface motion over a band of frequencies.

    Parameters
    ----------
    system : PiezoSystem
    freqs_hz : sequence of float, Hz
    voltage : float, V amplitude on the hot electrode (> 0)
    clamp : facet sets clamped (default: free)
    loss : LossModel
    surfaces : facet sets whose mean motion is reported
    method : "modal" (superposition, default) or "direct" (one factorisation per frequency)
    basis : a ModalBasis to reuse (modal method)
    n_modes : modes in the basis if it is built here (centred on the band); a wide band grows
        the basis (doubling, up to :data:`MAX_BASIS_MODES`) until :func:`basis_reach` <= 0.5
    progress : optional callable(i, n) for progress reporting
    check : compare the modal sweep with direct solves at the band's ends and middle (three
        factorisations). ``None`` (default): when a basis built here stays beyond the rule above
        at its size limit; within the rule the sweep was verified against direct solves to
        0.04 % over three resonances (tests). A given basis is the caller's choice (its reach
        is a lower bound: the truncated modes may lie much farther out than its own span), so
        it is checked only with ``check=True``. A difference above :data:`BAND_TOL` (1 %) grows a
        basis built here and sweeps again; with a given basis, or at the size limit, it is a
        :class:`ParameterError` naming the frequency.
    """
    t0 = time.perf_counter()
    f = _check_freqs(freqs_hz)
    voltage = _check_voltage(voltage)
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    if method not in ("modal", "direct"):
        raise ParameterError("method", method, "must be 'modal' or 'direct'")
    funcs = [surface_functional(system, s) for s in surfaces]
    L = loss_matrix(system, loss)
    qrow = charge_row(system, L)
    timings, basis_modes, check_error = {}, 0, float("nan")
    if method == "modal":
        given = basis is not None
        if given and (basis.loss != loss or basis.clamp != clamp):
            raise ParameterError("basis", "mismatch", "was built for another loss model or clamp")
        cap = int(min(MAX_BASIS_MODES, system.ndof // 4))
        n = int(n_modes)
        while True:
            if not given:
                modes, n = _band_modes(system, f, n, cap, clamp, backend)
                basis = modal_basis(system, float(np.sqrt(f.min() * f.max())), clamp=clamp, loss=loss,
                                    modes=modes, backend=backend)
            _refuse_lossless_resonance(system, f, loss, clamp, backend, basis.f_r_hz)
            Q, out_s = _modal_values(system, basis, f, funcs, qrow, voltage)
            if not (check or (check is None and not given and basis_reach(basis, f) > _REACH)):
                break
            err, where = _band_check(system, basis, f, Q, out_s, voltage, clamp, loss, backend, funcs, qrow)
            check_error = err
            if err <= BAND_TOL:
                break
            if given or n >= cap:
                raise ParameterError(
                    "freqs", f"{f.min():.6g}-{f.max():.6g} Hz",
                    f"the modal basis of {len(basis.lam)} modes misses the direct solution by {err:.1%} at "
                    f"{where:.6g} Hz (limit {BAND_TOL:.0%}); use a narrower band or method='direct'")
            n = min(2 * n, cap)
            log.info("harmonic: modal sweep off by %.2g %% at %.6g Hz: basis grows to %d modes", 100 * err, where, n)
        timings["basis_s"] = basis.seconds
        basis_modes = len(basis.lam)
    else:
        _refuse_lossless_resonance(system, f, loss, clamp, backend)
        Q = np.zeros(len(f), complex)
        out_s = {s.name: {c: np.zeros(len(f), complex) for c in COMPONENTS} for s in funcs}
        for k, fk in enumerate(f):
            Q[k], vals = _direct_values(system, fk, voltage, clamp, loss, backend, funcs, qrow)
            for s in funcs:
                for i, c in enumerate(COMPONENTS):
                    out_s[s.name][c][k] = vals[s.name][i]
            if progress:
                progress(k + 1, len(f))
    w = 2 * np.pi * f
    current = 1j * w * Q
    Y = current / voltage
    power = 0.5 * np.real(voltage * np.conj(current))
    timings = {"sweep_s": time.perf_counter() - t0, **timings}
    return HarmonicResult(f, voltage, Y, current, power, out_s, method, loss, timings, basis_modes, check_error,
                          system.materials_block())


# --------------------------------------------------------------------------- working point


@dataclass(eq=False, repr=False)
class WorkingPoint(Result):
    """Response at one frequency and voltage (direct solution).

    ``tip_amplitude_m`` and ``tip_per_volt_m`` are the axial mean amplitude of ``tip_surface``
    (the first surface requested, ``horn_tip`` by default);
    ``surfaces`` the complex means of every requested surface; ``admittance`` (S),
    ``current_a``, ``power_w``; ``x`` the full solution; ``teeth_ellipse_ratio`` the
    tangential/axial amplitude ratio on ``teeth_tops`` (NaN if absent) and
    ``teeth_phase_deg`` the phase of the tangential relative to the axial motion.
    """

    freq_hz: float
    voltage: float
    surfaces: dict
    admittance: complex
    current_a: complex
    power_w: float
    x: np.ndarray
    method: str
    seconds: float
    tip_surface: str = "horn_tip"

    @property
    def tip_amplitude_m(self) -> float:
        return float(abs(self.surfaces[self.tip_surface]["axial"]))

    @property
    def tip_per_volt_m(self) -> float:
        return self.tip_amplitude_m / self.voltage

    @property
    def teeth_ellipse_ratio(self) -> float:
        s = self.surfaces.get("teeth_tops")
        if s is None or abs(s["axial"]) == 0:
            return float("nan")
        return float(abs(s["tangential"]) / abs(s["axial"]))

    @property
    def teeth_phase_deg(self) -> float:
        s = self.surfaces.get("teeth_tops")
        if s is None:
            return float("nan")
        return float(np.degrees(np.angle(s["tangential"] / s["axial"])))

    def _headline(self) -> str:
        head = (f"{self.freq_hz:.1f} Hz, {self.voltage:g} V: {self.tip_surface} {self.tip_amplitude_m * 1e6:.3g} um "
                f"({self.tip_per_volt_m * 1e6:.4g} um/V), |Y| {abs(self.admittance) * 1e3:.3g} mS, "
                f"power {self.power_w:.3g} W")
        if np.isfinite(self.teeth_ellipse_ratio):
            head += f", teeth ellipse ratio {self.teeth_ellipse_ratio:.3f}"
        return head

    def _record(self) -> dict:
        return {
            "freq_hz": self.freq_hz, "voltage_v": self.voltage, "method": self.method,
            "tip_amplitude_m": self.tip_amplitude_m, "tip_per_volt_m": self.tip_per_volt_m,
            "teeth_ellipse_ratio": _nan_none(self.teeth_ellipse_ratio),
            "teeth_phase_deg": _nan_none(self.teeth_phase_deg),
            "admittance_s": {"re": float(np.real(self.admittance)), "im": float(np.imag(self.admittance))},
            "current_a": float(abs(self.current_a)), "power_w": self.power_w,
            "surfaces": {s: {c: {"abs_m": float(abs(v)), "phase_deg": float(np.degrees(np.angle(v)))}
                             for c, v in comps.items()} for s, comps in self.surfaces.items()},
            "seconds": self.seconds,
        }


def working_point(system: PiezoSystem, freq_hz: float, voltage: float, *, clamp: Iterable[str] = (),
                  loss: LossModel = LossModel(), surfaces: Sequence[str] = ("horn_tip",),
                  basis: ModalBasis | None = None, tip_damping: float = 0.0,
                  backend: str | None = None) -> WorkingPoint:
    """The response at the working frequency: direct solution, or modal if ``basis`` is given.

    ``tip_damping`` (N s/m, modal path only) adds a viscous damper on the mean axial motion of
    the first surface (the tip): the load of the free-mass impacts, for instance. Being a
    rank-one term on the modal coordinates it couples every mode of the basis.

    Parameters
    ----------
    system : PiezoSystem
    freq_hz : float
        Drive frequency, Hz.
    voltage : float
        Voltage amplitude on the hot electrodes, V.
    clamp, loss, surfaces, basis, tip_damping, backend
        As :func:`harmonic_sweep`; ``surfaces``: the tip first.

    Returns
    -------
    WorkingPoint
        Mean motion of each surface (m), admittance (S), current (A) and electrical power (W).

    Examples
    --------
    A PZT-4 k33 rod driven at 5 kHz, far below its 38 kHz length resonance: the current is
    that of its free capacitance, within the dynamic amplification ``1/(1 - (f/f_r)^2)``:

    >>> import math
    >>> from geometry import build_mesh
    >>> from geometry.examples import k33_rod
    >>> from fem import assemble
    >>> system = assemble(build_mesh(k33_rod(), mesh_size=0.01, order=1))
    >>> wp = working_point(system, 5e3, 1.0, surfaces=("electrode_top",))
    >>> c = wp.admittance.imag / (2 * math.pi * 5e3)                # F
    >>> round(float(c / system.capacitance_static("free")), 3)
    1.008
    """
    t0 = time.perf_counter()
    f = float(_check_freqs(freq_hz)[0])
    voltage = _check_voltage(voltage)
    surfaces = tuple(surfaces)
    if not surfaces:
        raise ParameterError("surfaces", surfaces, "name at least one surface (the tip first)")
    funcs = [surface_functional(system, s) for s in surfaces]
    if tip_damping < 0 or not np.isfinite(tip_damping):
        raise ParameterError("tip_damping", tip_damping, "must be a finite number >= 0 N s/m")
    if tip_damping > 0 and basis is None:
        raise ParameterError("tip_damping", tip_damping, "needs the modal method (pass basis=)")
    if basis is not None:
        _refuse_lossless_resonance(system, f, basis.loss, basis.clamp, backend, basis.f_r_hz)
        damper = None
        if tip_damping > 0:
            axial = funcs[0].rows[0, basis.free]
            damper = (np.asarray(axial @ basis.Phi).ravel(), float(tip_damping))
        x = system.expand(basis.solution_free(f, voltage, damper), basis.free, voltage)
        method = "modal"
    else:
        _refuse_lossless_resonance(system, f, loss, tuple(clamp), backend)
        x = solve_direct(system, f, voltage, clamp=clamp, loss=loss, backend=backend)
        method = "direct"
    L = basis.L if basis is not None and basis.L is not None else loss_matrix(system, loss if basis is None else basis.loss)
    Q = charge_row(system, L) @ x
    current = 1j * 2 * np.pi * f * Q
    sv = {s.name: s(x) for s in funcs}
    return WorkingPoint(f, voltage, sv, current / voltage, current,
                        float(0.5 * np.real(voltage * np.conj(current))), x, method,
                        time.perf_counter() - t0, tip_surface=surfaces[0])
