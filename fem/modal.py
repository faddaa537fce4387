"""Modal analysis of the coupled piezo-elastic system: resonance / anti-resonance pairs.

API
---
``modal_analysis(system, near_hz, n_modes, clamp=(), *, sigma=None, rigid_hz=None,
backend=None, tol=1e-10, open_circuit=True, eigen="block", factor=None) -> ModalResult``

* Shift-invert Lanczos on the coupled pencil ``(K, M)`` with ``(K - sigma M)^-1`` from
  :func:`fem.solvers.factorize` without PARDISO's weighted matching (the shifted pencil has a
  full non-zero diagonal; ~20 % less factorisation work; refactorised with it if a pivot had
  to be perturbed) (or ``factor``, an existing one at the same shift):
  ``eigen="block"`` (default) is the block Lanczos of :mod:`fem.eigen` (block right-hand sides,
  Rayleigh-quotient eigenvalues); ``eigen="arpack"`` is scipy ``eigsh`` (``mode="normal"``,
  one right-hand side per call), kept as an independent reference.
  The potential DOFs have zero mass: ``(K - sigma M)^-1 M`` maps every vector onto
  ``u``-driven fields whose potential is the static (condensed) electric response, so the
  infinite eigenvalues of the massless DOFs never appear and no explicit Schur complement is
  formed (ARPACK mode 3 accepts a semi-definite ``M``).
* Short circuit (``V_hot`` removed: resonance ``f_r``) and open circuit (``V_hot`` free with
  zero net charge: anti-resonance ``f_a``) share ONE factorisation: the open-circuit matrix is
  the short-circuit one bordered by the hot row/column, solved by a scalar Schur complement.
  ``open_circuit="joint"`` (default with the block solver): the open-circuit operator is the
  short-circuit one plus ``z z^T M / delta`` (``z = (K - sigma M)^-1 a``, the response to the
  hot column ``a``; ``delta`` its Schur complement), so the block Krylov space of the short
  circuit started with ``z`` in its first block contains the open-circuit one: ONE block
  Lanczos run gives both, the open circuit by Rayleigh-Ritz of ``T + g g^T / delta``
  (``g = Q^T M z``) in the same basis, with the same residual bound (:mod:`fem.eigen`). If a
  mode is left unpaired (or the basis had to be restarted) the seeded path runs.
  ``"seeded"``: the open-circuit modes are found by a few block solves started from the
  short-circuit modes and ``z`` (each target followed by MAC); if a mode is left unpaired the
  from-scratch path runs. ``"scratch"``: ARPACK on the bordered operator from a random start
  (an independent reference; equal to 1e-9 relative, tested). ``False``: no anti-resonances.
* Modes are paired by the mass-weighted MAC of their displacement parts (``fem.modeshape.mac``
  on the system's mass; Hungarian assignment),
  not by index (a pair needs MAC >= ``mac_min``, default 0.5, else ``f_a`` is NaN; the
  open-circuit window is widened until every mode has a partner); ``k_eff = sqrt(1 - (f_r / f_a)^2)`` (0 where ``f_a = f_r`` to round-off; a partner below
  ``f_r`` is not the mode's own anti-resonance: NaN, see :func:`own_anti_resonance`).
* ``sigma`` defaults to ``(2 pi near_hz)^2``; ``near_hz <= 0`` means the bottom of the spectrum
  with the negative shift ``-(2 pi 1 kHz)^2`` (shift-invert exactly at 0 meets the rigid modes).
  In a free (unclamped) body up to six extra modes are computed; modes below ``rigid_hz``
  (default ``max(10 Hz, 1 % of near_hz)``) are rigid-body modes: reported in ``rigid_hz`` and
  excluded from the pairs.
* ``tol``: relative accuracy of the eigenvalues (default 1e-10; ARPACK's ``tol``, or the
  block solver's error bound).

``ModalResult``: ``f_r_hz``, ``f_a_hz``, ``k_eff``, ``mac`` (pairing MAC), ``shapes``
(``(n, n_nodes, 3)`` short-circuit displacement at the P2 nodes, mass-normalised:
``Phi^T M Phi = I``), ``vectors`` / ``vectors_open`` (full ``x`` per mode, ``(ndof, n)``),
``mode_shares`` (``fem.modeshape.energy_shares`` of the shapes on the system's own mass
matrix), ``shares`` (``(n, 3)`` of them: axial / torsional / lateral about the z axis),
``labels`` (``fem.modeshape.classify`` of ``mode_shares``), ``rigid_hz``, ``ndof``, ``backend``, ``timings`` (assembly_s, factorisation_s
(0 when ``factor`` was given), eigen_s = eigen_short_s + eigen_open_s, modal_s, total_s), ``to_dict()``.

CLI
---
``python -m fem.modal --design FILE --near HZ --modes N [--json OUT] [--mesh-size M]
[--order 1|2] [--clamp SURFACE ...] [--select NAME] [--solver auto|pardiso|superlu]
[--sectors auto|off|N] [--harmonics K,..|all]`` (a cyclically symmetric RPUD is solved by
harmonics on swept sectors by default, :mod:`fem.cyclic_cli`; ``--sectors off``: this module on
the whole drill)
(``--design default``: the built-in default design) prints a table (f_r kHz, f_a kHz, k_eff, dominant
motion) and writes JSON (``modes``: list of ``{f_r_hz, f_a_hz, k_eff, mac, label, shares}``,
``ndof``, ``timings``, ``backend``; the sector path writes its own record, see
:mod:`fem.cyclic_cli`: per mode ``harmonic``, ``multiplicity``, ``shares`` as axial / tangential /
radial, the working mode's ``f_r_hz_error`` / ``f_a_hz_error``). Bad input: one line, exit 2, no
file written.
"""

from __future__ import annotations

if __name__ == "__main__":
    # python -m fem.modal: the command line lives in fem.modal_cli (named, not imported:
    # physics modules do not parse arguments); signal handling comes before any heavy import
    import sys

    from rpud_common.launch import launch

    sys.exit(launch("fem.modal_cli", prog="fem.modal"))

import logging
import time
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from rpud_common import ParameterError, check_choice, check_nonnegative
from rpud_common.result import Result

from .assembly import PiezoSystem
from .eigen import (arpack_eigs as _eig, block_eigs, bordered_mass as _bordered_mass, bordered_solve,
                    deflated as _deflated, restricted as _restricted, rigid_basis as _rigid_basis, smooth_start)
from .modeshape import ModeShares, classify, energy_shares, mac
from .solvers import blas_threads, factorize

__all__ = ["modal_analysis", "ModalResult", "working_mode", "own_anti_resonance", "frequency_hz"]

log = logging.getLogger(__name__)

BLOCK_MIN = 8
"""Smallest block size of the block Lanczos (the joint open circuit adds one column)."""


@dataclass(eq=False, repr=False)
class ModalResult(Result):
    """Paired short/open-circuit modes (see the module docstring).

    ``repr`` shows the band and the mode nearest ``near_hz``; :meth:`to_dict` is the JSON
    record of every mode; :meth:`save` writes it with the frequencies and mode shapes (npz).
    """

    f_r_hz: np.ndarray
    f_a_hz: np.ndarray
    k_eff: np.ndarray
    mac: np.ndarray
    shapes: np.ndarray
    vectors: np.ndarray
    vectors_open: np.ndarray | None
    shares: np.ndarray
    rigid_hz: np.ndarray
    ndof: int
    backend: str
    sigma: float
    near_hz: float
    clamp: tuple[str, ...]
    timings: dict = field(default_factory=dict)
    system: PiezoSystem | None = field(default=None, repr=False)
    mode_shares: ModeShares | None = field(default=None, repr=False)
    factor: object = field(default=None, repr=False)
    """With ``keep_factor``: the factorisation of ``K - sigma M`` on the short-circuit free set,
    which :func:`fem.harmonic.modal_basis` reuses for its residual at the same shift (a solver
    handle: not pickled)."""

    def __getstate__(self):
        return {**self.__dict__, "factor": None}

    @property
    def labels(self) -> list[str]:
        """Dominant motion per mode: ``fem.modeshape.classify`` of :attr:`mode_shares`."""
        return classify(self.mode_shares) if self.n_modes else []

    @property
    def n_modes(self) -> int:
        return len(self.f_r_hz)

    @property
    def working(self) -> int:
        """Index of the working (longitudinal) mode: :func:`working_mode` near ``near_hz``."""
        if self.system is None:
            raise ValueError("this result keeps no system; use fem.modal.working_mode")
        return working_mode(self.system, self.f_r_hz, self.vectors, self.near_hz)

    @property
    def nearest(self) -> int:
        """Index of the mode whose f_r is nearest ``near_hz``."""
        return int(np.argmin(np.abs(self.f_r_hz - self.near_hz)))

    def _headline(self) -> str:
        if not self.n_modes:
            return f"no modes, {self.ndof} DOF"
        i = self.nearest
        fa = f", f_a {self.f_a_hz[i]:.1f} Hz, k_eff {self.k_eff[i]:.3f}" if np.isfinite(self.f_a_hz[i]) else ""
        return (f"{self.n_modes} modes {self.f_r_hz.min() / 1e3:.2f}-{self.f_r_hz.max() / 1e3:.2f} kHz; "
                f"nearest {self.near_hz / 1e3:g} kHz: mode {i} {self.labels[i]}, f_r {self.f_r_hz[i]:.1f} Hz{fa}; "
                f"{self.ndof} DOF")

    def _arrays(self) -> dict:
        return {"f_r_hz": self.f_r_hz, "f_a_hz": self.f_a_hz, "k_eff": self.k_eff, "shares": self.shares,
                "shapes_m": self.shapes}

    def _record(self) -> dict:
        modes = []
        for i in range(self.n_modes):
            modes.append({
                "f_r_hz": float(self.f_r_hz[i]),
                "f_a_hz": None if not np.isfinite(self.f_a_hz[i]) else float(self.f_a_hz[i]),
                "k_eff": None if not np.isfinite(self.k_eff[i]) else float(self.k_eff[i]),
                "mac": None if not np.isfinite(self.mac[i]) else float(self.mac[i]),
                "label": self.labels[i],
                "shares": {"axial": float(self.shares[i, 0]), "torsional": float(self.shares[i, 1]),
                           "lateral": float(self.shares[i, 2])},
            })
        return {"near_hz": self.near_hz, "sigma": self.sigma, "clamp": list(self.clamp),
                "modes": modes, "rigid_hz": [float(f) for f in self.rigid_hz],
                "ndof": int(self.ndof), "backend": self.backend,
                "timings": {k: float(v) for k, v in self.timings.items()},
                "materials": self.system.materials_block() if self.system is not None else None}


def working_mode(system: PiezoSystem, f_hz: np.ndarray, vectors: np.ndarray, near_hz: float,
                 previous: np.ndarray | None = None) -> int:
    """Index of the working (longitudinal) mode among computed modes.

    With ``previous`` (the working mode's displacement on the same mesh topology) the mode of
    largest mass-weighted MAC is taken; otherwise the mode with the largest axial kinetic-energy
    share among those within 40 % of ``near_hz`` (rigid modes excluded). Both come from
    :mod:`fem.modeshape` on the system's mass matrix, so the pick agrees with the modal labels.
    """
    shapes = system.displacement(vectors)
    ok = (np.abs(f_hz) > 0.01 * near_hz) & (np.abs(f_hz - near_hz) < 0.4 * near_hz)
    if not ok.any():
        raise ParameterError("target_hz", near_hz, "no elastic mode within 40 % of the target")
    if previous is not None:
        score = mac(previous, shapes, mesh=system)[0]
    else:
        score = energy_shares(system, shapes).axial
    return int(np.argmax(np.where(ok, score, -1.0)))


ROUND_OFF = 1e-9
"""Relative distance below which an anti-resonance equals its resonance (the eigen-solvers'
frequencies are good to 5e-11, fem.eigen)."""


def own_anti_resonance(f_r: np.ndarray, f_a: np.ndarray) -> np.ndarray:
    """``f_a`` with NaN where the paired open-circuit mode lies below its resonance beyond
    :data:`ROUND_OFF`. Charge coupling only raises a mode (the open circuit adds a positive
    rank-one stiffness); a partner below it is the admittance zero that interlacing puts between
    it and a lower, more strongly coupled mode whose own anti-resonance passes above it (a
    torsion beside the working mode): the mode has no anti-resonance of its own. Within round-off
    it is the mode's own (an uncoupled mode: ``f_a = f_r``, ``k_eff = 0``)."""
    f_r, f_a = np.asarray(f_r, float), np.asarray(f_a, float).copy()
    with np.errstate(invalid="ignore"):
        below = f_a < f_r * (1 - ROUND_OFF)
        f_a[below] = np.nan
        near = np.isfinite(f_a) & (f_a < f_r)
    f_a[near] = f_r[near]
    return f_a


def frequency_hz(lam):
    """Frequency in Hz of eigenvalues ``lam`` (rad^2/s^2), negative for a negative eigenvalue."""
    lam = np.asarray(lam, dtype=float)
    return np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * np.pi)


def _pair(system, shapes, vec_o, free_o, f_o, mac_min):
    """Hungarian MAC pairing of short-circuit shapes with open-circuit vectors."""
    from scipy.optimize import linear_sum_assignment

    full_o_all = np.zeros((system.ndof, vec_o.shape[1]))
    full_o_all[free_o] = vec_o
    MAC = mac(shapes, system.displacement(full_o_all), mesh=system)
    rows, cols = linear_sum_assignment(-MAC)
    ok = len(rows) == len(shapes) and MAC[rows, cols].min() >= mac_min
    return ok, rows, cols, MAC, full_o_all


def modal_analysis(system: PiezoSystem, near_hz: float, n_modes: int, clamp: Iterable[str] = (), *,
                   sigma: float | None = None, rigid_hz: float | None = None,
                   backend: str | None = None, tol: float = 1e-10,
                   open_circuit: bool | str = True, mac_min: float = 0.5,
                   eigen: str = "block", factor=None, keep_factor: bool = False) -> ModalResult:
    """Short- and open-circuit modes nearest ``near_hz`` (see the module docstring).

    ``eigen="block"`` (default): :func:`fem.eigen.block_eigs`, block right-hand sides, Rayleigh
    quotient eigenvalues; ``"arpack"``: scipy ``eigsh`` one vector at a time (the reference).
    ``open_circuit``: ``True`` (``"joint"`` with the block solver, ``"scratch"`` with ARPACK),
    ``"joint"`` (block solver only: the open circuit from the short circuit's own Lanczos basis,
    whose start block holds the response to the hot electrode), ``"seeded"`` (a second block
    iteration started from the short-circuit modes and the response to the hot electrode),
    ``"scratch"`` (ARPACK from a random start, window widened until every mode has a partner),
    ``False`` (no anti-resonances). ``factor``: an existing factorisation of ``K - sigma M`` on
    ``system.reduce("short", clamp)`` (same ``sigma``), reused instead of factorising again;
    ``keep_factor``: the result keeps the factorisation (:attr:`ModalResult.factor`).

    Parameters
    ----------
    system : PiezoSystem
        The assembled system (:func:`fem.assemble`).
    near_hz : float
        Frequency the modes are sought around, Hz (0: the bottom of the spectrum).
    n_modes : int
        Number of elastic modes nearest ``near_hz``.
    clamp : sequence of str
        Facet sets whose displacements are fixed (default: free-free).
    sigma : float, optional
        Shift, rad^2/s^2 (default ``(2 pi near_hz)^2``).
    rigid_hz : float, optional
        Modes below it are rigid-body modes (default ``max(10 Hz, 1 % of near_hz)``).
    backend, tol, open_circuit, mac_min, eigen, factor
        Solver choices, see above and the module docstring.

    Returns
    -------
    ModalResult
        Resonances ``f_r_hz`` (short circuit) and anti-resonances ``f_a_hz`` (open circuit),
        Hz, the effective coupling ``k_eff``, mode shapes and labels; ``nearest`` indexes the
        mode nearest ``near_hz``.

    Examples
    --------
    The length mode of a PZT-4 k33 rod (40 mm): its effective coupling ``k_eff`` near the
    one-dimensional value 0.66 that the material's k33 = 0.70 gives:

    >>> from geometry import build_mesh
    >>> from geometry.examples import k33_rod
    >>> from fem import assemble
    >>> system = assemble(build_mesh(k33_rod(), mesh_size=0.01, order=1))
    >>> modal_analysis(system, near_hz=40e3, n_modes=2)
    ModalResult(2 modes 38.24-46.19 kHz; nearest 40 kHz: mode 0 longitudinal, f_r 38235.1 Hz, f_a 50681.9 Hz, k_eff 0.656; 12895 DOF)
    """
    plan = _plan(near_hz, n_modes, clamp, sigma, rigid_hz, tol, open_circuit, mac_min, eigen)
    t0 = time.perf_counter()
    Ks, Ms, free_s = system.reduce("short", plan.clamp)
    F = _short_factor(Ks, Ms, len(free_s), plan.sigma, factor, backend)
    t1 = time.perf_counter()
    info = {}
    lam_s, vec_s, run, border = _short_circuit(system, F, Ks, Ms, free_s, plan, info)
    t2 = time.perf_counter()
    rigid_f, f_r, Vs = _keep_nonrigid(lam_s, vec_s, plan)
    n_found = len(f_r)
    full_s = np.zeros((system.ndof, n_found))
    full_s[free_s] = Vs
    shapes = system.displacement(full_s) if n_found else np.zeros((0, system.n_nodes, 3))
    f_a, pair_mac, full_o, t3 = np.full(n_found, np.nan), np.full(n_found, np.nan), None, t2
    if plan.open_circuit and system.hot_dof is not None and n_found:
        found = _open_circuit(system, F, Ms, free_s, shapes, Vs, run, border, plan, info)
        t3 = time.perf_counter()
        f_a, pair_mac, full_o = _partners(*found, plan.mac_min, system.ndof, n_found)
    elif system.hot_dof is None:
        f_a = f_r.copy()
        pair_mac = np.ones(n_found)
    f_a = own_anti_resonance(f_r, f_a)
    k_eff = _coupling(f_r, f_a)
    # the shares and labels of fem.modeshape, on the matrix the shapes are normalised with
    mode_shares = energy_shares(system, shapes) if n_found else None
    shares = mode_shares.overall.table() if n_found else np.zeros((0, 3))
    timings = _timings(system, F, factor, (t0, t1, t2, t3, time.perf_counter()))
    log.info("modal: %d modes near %.1f Hz, %d DOFs, %s, factor %.2f s, eigen %.2f s (%s, open circuit %s) %s",
             n_found, near_hz, system.ndof, F.backend, timings["factorisation_s"], timings["eigen_s"], eigen,
             plan.open_circuit, info)
    return ModalResult(f_r_hz=f_r, f_a_hz=f_a, k_eff=k_eff, mac=pair_mac, shapes=shapes, vectors=full_s,
                       vectors_open=full_o, shares=shares, rigid_hz=rigid_f,
                       ndof=system.ndof, backend=F.backend, sigma=float(plan.sigma),
                       near_hz=float(near_hz), clamp=plan.clamp, timings=timings, system=system,
                       mode_shares=mode_shares, factor=F if keep_factor else None)


@dataclass(frozen=True)
class _Plan:
    """The checked settings of one modal analysis (frequencies Hz, shift rad^2/s^2)."""

    near_hz: float
    n_modes: int
    clamp: tuple[str, ...]
    sigma: float
    rigid_hz: float
    tol: float
    open_circuit: bool | str
    mac_min: float
    eigen: str
    deflate: bool
    """A free body solved above 1 kHz: its rigid-body modes are projected out."""
    n_req: int
    """Modes asked of the eigensolver: ``n_modes``, plus six rigid-body ones when not deflated."""


def _plan(near_hz, n_modes, clamp, sigma, rigid_hz, tol, open_circuit, mac_min, eigen) -> _Plan:
    """The arguments of :func:`modal_analysis` checked, with their defaults resolved."""
    check_nonnegative("near_hz", near_hz, "Hz")
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ParameterError("n_modes", n_modes, "must be an integer >= 1")
    check_choice("eigen", eigen, ("block", "arpack"))
    if open_circuit is True:
        open_circuit = "joint" if eigen == "block" else "scratch"
    if open_circuit is not False:
        check_choice("open_circuit", open_circuit, ("joint", "seeded", "scratch"))
    if open_circuit == "joint" and eigen != "block":
        raise ParameterError("open_circuit", open_circuit, "needs eigen='block'")
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    if sigma is None:
        sigma = (2 * np.pi * near_hz) ** 2 if near_hz > 0 else -(2 * np.pi * 1e3) ** 2
    if rigid_hz is None:
        rigid_hz = max(10.0, 0.01 * near_hz)
    free_body = len(clamp) == 0
    # A free body has six rigid-body modes at ~0 Hz. Near 0 Hz they are computed (and
    # reported in rigid_hz); above 1 kHz they are deflated: the shift-invert operator is
    # followed by the M-orthogonal projector away from the exact rigid-body vectors.
    deflate = free_body and near_hz >= 1e3
    n_req = n_modes + (6 if free_body and not deflate else 0)
    return _Plan(near_hz, n_modes, clamp, sigma, rigid_hz, tol, open_circuit, mac_min, eigen, deflate, n_req)


def _short_factor(Ks, Ms, ns, sigma, factor, backend):
    """The factorisation of ``Ks - sigma Ms``: ``factor`` if given (checked on its size), else a new one."""
    if factor is None:
        # the shifted pencil has a full non-zero diagonal: no weighted matching needed
        return factorize((Ks - sigma * Ms).tocsr(), backend=backend, matching=False)
    if getattr(factor, "n", ns) != ns:
        raise ParameterError("factor", getattr(factor, "n", None), f"must factorise the {ns} short-circuit DOFs")
    return factor


def _short_circuit(system, F, Ks, Ms, free_s, plan: _Plan, info: dict):
    """Short-circuit eigenpairs: ``(lam, vectors, block run or None, border or None)``.

    The block run started with the response to the hot electrode (``border``) also holds the
    open-circuit modes (``open_circuit="joint"``).
    """
    ns = len(free_s)
    Rs, Ms_ = _rigid_basis(system, free_s, Ms) if plan.deflate else (None, None)
    if plan.eigen == "arpack":
        lam_s, vec_s = _eig(Ks, Ms, plan.n_req, plan.sigma, _deflated(F, Rs, Ms_), plan.tol, ns)
        return lam_s, vec_s, None, None
    # block size: 8 for 12 modes measured best (9 solves of 8 vs 7 of 16 or 6 of 24: the
    # per-vector price of a block solve falls slower than the vector count grows)
    b = min(max(BLOCK_MIN, plan.n_req // 2 + 2), max(ns - 2, 1))
    start = smooth_start(system.nodes, free_s, system.ndof, b, n_random=max(2, b // 4))
    border = None
    if plan.open_circuit == "joint" and system.hot_dof is not None:
        # the open-circuit operator is the short-circuit one plus z z^T M / delta (z: the
        # response to the hot column), so the block Krylov space of the short circuit
        # started with z holds the open-circuit one: both from one run
        krow = system.K.getrow(system.hot_dof).toarray().ravel()   # = the hot column
        a_hot = krow[free_s]
        z_hot = np.asarray(F(a_hot)).ravel()
        border = (a_hot, float(krow[system.hot_dof]), z_hot)
        start = np.column_stack([start, z_hot / np.linalg.norm(z_hot)])
    with blas_threads(1):
        res = block_eigs(F, Ks, Ms, plan.sigma, start, n_wanted=min(plan.n_req, ns - 2), locked=Rs, tol=plan.tol,
                         border=border)
    info["short_block_solves"], info["short_vectors"] = res.n_solves, res.n_vectors
    return res.lam, res.vectors, res, border


def _keep_nonrigid(lam, vec, plan: _Plan, limit: bool = True):
    """``(rigid-body frequencies, elastic frequencies, their vectors)``, Hz: the ``n_modes``
    elastic modes nearest the target (all of them if not ``limit``), in ascending frequency."""
    f = frequency_hz(lam)
    rigid = np.abs(f) < plan.rigid_hz
    f_ok, v_ok = f[~rigid], vec[:, ~rigid]
    sel = np.argsort(np.abs(f_ok - max(plan.near_hz, 0.0)))
    sel = np.sort(sel[:plan.n_modes] if limit else sel)
    return f[rigid], f_ok[sel], v_ok[:, sel]


def _open_circuit(system, F, Ms, free_s, shapes, Vs, run, border, plan: _Plan, info: dict):
    """Open-circuit modes paired with the short-circuit ``shapes``: ``(f_o, rows, cols, MAC, vectors)``.

    Tried in turn until every mode has a partner: the joint block run's own open-circuit modes,
    the seeded block solve, ARPACK from scratch (``plan.open_circuit`` names where to start).
    """
    hot = system.hot_dof
    free_o = np.append(free_s, hot)
    krow = system.K.getrow(hot).toarray().ravel()      # = the hot column (K symmetric)
    joint = plan.open_circuit == "joint"
    solve_open, z = bordered_solve(F, krow[free_s], float(krow[hot]), z=border[2] if joint else None)
    if joint and run.vectors_open is not None and run.converged_open:
        info["open_from_short_run"] = True
        f_o = frequency_hz(run.lam_open)
        ok, *pairs = _pair(system, shapes, run.vectors_open, free_o, f_o, plan.mac_min)
        if ok:
            return (f_o, *pairs)
    if joint:
        log.info("modal: joint open-circuit solve did not pair every mode; seeded solve")
    Mo = _bordered_mass(Ms)
    Ro = _rigid_basis(system, free_o, Mo)[0] if plan.deflate else None
    if plan.open_circuit != "scratch":
        # the open-circuit pencil is the short-circuit one plus a rank-1 stiffening through
        # the hot electrode: its modes lie in the span of the short-circuit ones and the
        # static response z, refined by a few block solves
        seeds = np.vstack([Vs, np.zeros((1, Vs.shape[1]))])
        start = np.column_stack([seeds, np.append(z, 0.0)])
        with blas_threads(1):
            res_o = block_eigs(solve_open, _restricted(system.K, free_o), Mo, plan.sigma, start,
                               targets=seeds, locked=Ro, tol=plan.tol)
        info["open_block_solves"], info["open_vectors"] = res_o.n_solves, res_o.n_vectors
        f_o = frequency_hz(res_o.lam)
        ok, *pairs = _pair(system, shapes, res_o.vectors, free_o, f_o, plan.mac_min)
        if ok:
            return (f_o, *pairs)
        log.info("modal: seeded open-circuit solve left a mode unpaired; solving from scratch")
    return _open_from_scratch(system, solve_open, free_o, Mo, Ro, shapes, len(free_s), plan)


def _open_from_scratch(system, solve_open, free_o, Mo, Ro, shapes, ns, plan: _Plan):
    """Open-circuit modes by ARPACK from a random start: ``(f_o, rows, cols, MAC, vectors)``.

    Anti-resonances lie above their resonances (by up to ~1/sqrt(1-k^2)): the open-circuit
    window is widened until every short-circuit mode has a partner (MAC >= ``mac_min``).
    """
    k_open = plan.n_req + 2
    Ko = system.K[free_o][:, free_o].tocsr()
    for attempt in range(3):
        lam_o, vec_o = _eig(Ko, Mo, k_open, plan.sigma, _deflated(solve_open, Ro, Mo), plan.tol, ns + 1)
        _, f_o, Vo = _keep_nonrigid(lam_o, vec_o, plan, limit=False)
        ok, *pairs = _pair(system, shapes, Vo, free_o, f_o, plan.mac_min)
        if ok or k_open >= ns - 2:
            break
        k_open = min(2 * k_open, ns - 2)
    return (f_o, *pairs)


def _partners(f_o, rows, cols, MAC, full_o_all, mac_min, ndof, n_found):
    """Per short-circuit mode: its anti-resonance, Hz (NaN below ``mac_min``), pairing MAC and
    open-circuit vector (NaN columns when unpaired)."""
    f_a = np.full(n_found, np.nan)
    pair_mac = np.full(n_found, np.nan)
    full_o = np.full((ndof, n_found), np.nan)
    for r_, c_ in zip(rows, cols):
        pair_mac[r_] = MAC[r_, c_]
        if MAC[r_, c_] >= mac_min:
            f_a[r_] = f_o[c_]
            full_o[:, r_] = full_o_all[:, c_]
    return f_a, pair_mac, full_o


def _coupling(f_r, f_a):
    """Effective coupling ``k_eff = sqrt(1 - (f_r / f_a)^2)``, 0 where round-off puts ``f_a`` below
    ``f_r``, NaN without an anti-resonance."""
    with np.errstate(invalid="ignore"):
        ratio = np.where(np.isfinite(f_a), f_r / f_a, np.nan)
        return np.sqrt(np.clip(1 - ratio ** 2, 0.0, None))


def _timings(system, F, factor, marks):
    """Stage times, s, from the marks (start, factorised, short circuit, open circuit, end)."""
    t0, t1, t2, t3, t4 = marks
    timings = {"assembly_s": float(system.timings.get("assembly_s", np.nan)),
               "factorisation_s": F.seconds if factor is None else 0.0,
               "eigen_s": (t2 - t1) + (t3 - t2), "eigen_short_s": t2 - t1, "eigen_open_s": t3 - t2,
               "modal_s": t4 - t0}
    timings["total_s"] = timings["assembly_s"] + timings["modal_s"]
    return timings
