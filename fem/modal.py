"""Modal analysis of the coupled piezo-elastic system: resonance / anti-resonance pairs.

API
---
``modal_analysis(system, near_hz, n_modes, clamp=(), *, sigma=None, rigid_hz=None,
backend=None, tol=0.0, open_circuit=True) -> ModalResult``

* Shift-invert Lanczos (scipy ``eigsh``, ``mode="normal"``) on the coupled pencil
  ``(K, M)`` with ``OPinv = (K - sigma M)^-1`` from :func:`fem.solvers.factorize`.
  The potential DOFs have zero mass: ``(K - sigma M)^-1 M`` maps every vector onto
  ``u``-driven fields whose potential is the static (condensed) electric response, so the
  infinite eigenvalues of the massless DOFs never appear and no explicit Schur complement is
  formed (ARPACK mode 3 accepts a semi-definite ``M``).
* Short circuit (``V_hot`` removed: resonance ``f_r``) and open circuit (``V_hot`` free with
  zero net charge: anti-resonance ``f_a``) share ONE factorisation: the open-circuit matrix is
  the short-circuit one bordered by the hot row/column, solved by a scalar Schur complement.
* Modes are paired by the mass-weighted MAC of their displacement parts (``fem.modeshape.mac``
  on the system's mass; Hungarian assignment),
  not by index (a pair needs MAC >= ``mac_min``, default 0.5, else ``f_a`` is NaN; the
  open-circuit window is widened until every mode has a partner); ``k_eff = sqrt(1 - (f_r / f_a)^2)`` (0 where ``f_a <= f_r`` to round-off).
* ``sigma`` defaults to ``(2 pi near_hz)^2``; ``near_hz <= 0`` means the bottom of the spectrum
  with the negative shift ``-(2 pi 1 kHz)^2`` (shift-invert exactly at 0 meets the rigid modes).
  In a free (unclamped) body up to six extra modes are computed; modes below ``rigid_hz``
  (default ``max(10 Hz, 1 % of near_hz)``) are rigid-body modes: reported in ``rigid_hz`` and
  excluded from the pairs.
* ``tol``: ARPACK relative accuracy of the eigenvalues (default 1e-10).

``ModalResult``: ``f_r_hz``, ``f_a_hz``, ``k_eff``, ``mac`` (pairing MAC), ``shapes``
(``(n, n_nodes, 3)`` short-circuit displacement at the P2 nodes, mass-normalised:
``Phi^T M Phi = I``), ``vectors`` / ``vectors_open`` (full ``x`` per mode, ``(ndof, n)``),
``mode_shares`` (``fem.modeshape.energy_shares`` of the shapes on the system's own mass
matrix), ``shares`` (``(n, 3)`` of them: axial / torsional / lateral about the z axis),
``labels`` (``fem.modeshape.classify`` of ``mode_shares``), ``rigid_hz``, ``ndof``, ``backend``, ``timings`` (assembly_s, factorisation_s,
eigen_s, total_s), ``to_json()``.

CLI
---
``python -m fem.modal --design FILE --near HZ --modes N [--json OUT] [--mesh-size M]
[--order 1|2] [--clamp SURFACE ...] [--select NAME] [--solver auto|pardiso|superlu]``
(``--design default``: the built-in default design) prints a table (f_r kHz, f_a kHz, k_eff, dominant
motion) and writes JSON (``modes``: list of ``{f_r_hz, f_a_hz, k_eff, mac, label, shares}``,
``ndof``, ``timings``, ``backend``). Bad input: one line, exit 2, no file written.
"""

from __future__ import annotations

if __name__ == "__main__":
    # python -m fem.modal: signal handling before the heavy imports below (numpy, scipy, skfem)
    import sys

    from geometry.launch import launch

    sys.exit(launch("fem.modal", prog="fem.modal"))

import contextlib
import logging
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np
import scipy.sparse.linalg as spla

from geometry.common import ParameterError, check_nonnegative, check_positive

from .assembly import PiezoSystem
from .modeshape import ModeShares, classify, energy_shares, mac
from .solvers import blas_threads, factorize

__all__ = ["modal_analysis", "ModalResult", "main"]

log = logging.getLogger(__name__)


@dataclass(eq=False)
class ModalResult:
    """Paired short/open-circuit modes (see the module docstring)."""

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

    @property
    def labels(self) -> list[str]:
        """Dominant motion per mode: ``fem.modeshape.classify`` of :attr:`mode_shares`."""
        return classify(self.mode_shares) if self.n_modes else []

    @property
    def n_modes(self) -> int:
        return len(self.f_r_hz)

    def to_json(self) -> dict:
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
                "timings": {k: float(v) for k, v in self.timings.items()}}


def _freq(lam):
    lam = np.asarray(lam, dtype=float)
    return np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * np.pi)


def _rigid_basis(system, free):
    """M-orthonormal rigid-body modes (3 translations, 3 rotations; zero potential) on ``free``."""
    x0 = system.nodes.mean(axis=0)
    r = system.nodes - x0
    R = np.zeros((system.ndof, 6))
    for c in range(3):
        R[c: system.n_u: 3, c] = 1.0
    for c in range(3):
        w = np.zeros(3)
        w[c] = 1.0
        R[: system.n_u, 3 + c] = np.cross(w, r).ravel()
    R = R[free]
    M = system.M[free][:, free]
    G = R.T @ (M @ R)
    L = np.linalg.cholesky(G)
    return np.linalg.solve(L, R.T).T, M       # R L^-T: R^T M R = I


def _deflated(solve, R, M):
    """OPinv followed by the M-orthogonal projection away from span(R)."""
    if R is None:
        return solve

    def op(b):
        y = solve(b)
        return y - R @ (R.T @ (M @ y))
    return op


def _eig(K, M, k, sigma, solve, tol, n):
    k = int(min(k, n - 2))
    op = spla.LinearOperator((n, n), matvec=solve, dtype=float)
    # a fixed start vector: ARPACK's default is random, which makes reruns differ in the last
    # digits (and the chaotic impact model downstream amplifies that)
    v0 = np.random.default_rng(20000).standard_normal(n)
    with blas_threads(1):
        vals, vecs = spla.eigsh(K, k=k, M=M, sigma=sigma, OPinv=op, which="LM", tol=tol, mode="normal",
                                v0=v0)
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    # mass normalisation (ARPACK returns M-orthonormal vectors; enforce against round-off)
    mnorm = np.sqrt(np.abs(np.einsum("ij,ij->j", vecs, M @ vecs)))
    vecs = vecs / np.where(mnorm > 0, mnorm, 1.0)
    return vals, vecs


def modal_analysis(system: PiezoSystem, near_hz: float, n_modes: int, clamp: Iterable[str] = (), *,
                   sigma: float | None = None, rigid_hz: float | None = None,
                   backend: str | None = None, tol: float = 1e-10,
                   open_circuit: bool = True, mac_min: float = 0.5) -> ModalResult:
    """Short- and open-circuit modes nearest ``near_hz`` (see the module docstring)."""
    check_nonnegative("near_hz", near_hz, "Hz")
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ParameterError("n_modes", n_modes, "must be an integer >= 1")
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    t0 = time.perf_counter()
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

    Ks, Ms, free_s = system.reduce("short", clamp)
    ns = len(free_s)
    A = (Ks - sigma * Ms).tocsr()
    F = factorize(A, backend=backend)
    t1 = time.perf_counter()
    Rs, Ms_ = _rigid_basis(system, free_s) if deflate else (None, None)
    lam_s, vec_s = _eig(Ks, Ms, n_req, sigma, _deflated(F, Rs, Ms_), tol, ns)
    t2 = time.perf_counter()

    def keep_nonrigid(lam, vec, limit=True):
        f = _freq(lam)
        rigid = np.abs(f) < rigid_hz
        f_ok, v_ok = f[~rigid], vec[:, ~rigid]
        # the n_modes nearest the target, in ascending frequency
        sel = np.argsort(np.abs(f_ok - max(near_hz, 0.0)))
        sel = np.sort(sel[:n_modes] if limit else sel)
        return f[rigid], f_ok[sel], v_ok[:, sel]

    rigid_f, f_r, Vs = keep_nonrigid(lam_s, vec_s)
    n_found = len(f_r)
    full_s = np.zeros((system.ndof, n_found))
    full_s[free_s] = Vs
    shapes = system.displacement(full_s) if n_found else np.zeros((0, system.n_nodes, 3))

    f_a = np.full(n_found, np.nan)
    pair_mac = np.full(n_found, np.nan)
    full_o = None
    t3 = t2
    if open_circuit and system.hot_dof is not None and n_found:
        hot = system.hot_dof
        free_o = np.append(free_s, hot)
        Ko, Mo = system.K[free_o][:, free_o].tocsr(), system.M[free_o][:, free_o].tocsr()
        a = np.asarray(system.K[free_s][:, [hot]].toarray()).ravel()
        alpha = float(system.K[hot, hot])
        z = F(a)
        delta = alpha - a @ z

        def solve_open(b):
            b = np.asarray(b).ravel()
            x1 = F(b[:-1])
            y = (b[-1] - a @ x1) / delta
            return np.append(x1 - z * y, y)

        from scipy.optimize import linear_sum_assignment

        # anti-resonances lie above their resonances (by up to ~1/sqrt(1-k^2)): widen the
        # open-circuit window until every short-circuit mode has a partner (MAC >= mac_min)
        k_open = n_req + 2
        Ro = _rigid_basis(system, free_o)[0] if deflate else None
        for attempt in range(3):
            lam_o, vec_o = _eig(Ko, Mo, k_open, sigma, _deflated(solve_open, Ro, Mo), tol, ns + 1)
            _, f_o, Vo = keep_nonrigid(lam_o, vec_o, limit=False)
            full_o_all = np.zeros((system.ndof, Vo.shape[1]))
            full_o_all[free_o] = Vo
            MAC = mac(shapes, system.displacement(full_o_all), mesh=system)
            rows, cols = linear_sum_assignment(-MAC)
            if len(rows) == n_found and MAC[rows, cols].min() >= mac_min:
                break
            if k_open >= ns - 2:
                break
            k_open = min(2 * k_open, ns - 2)
        t3 = time.perf_counter()
        full_o = np.full((system.ndof, n_found), np.nan)
        for r_, c_ in zip(rows, cols):
            pair_mac[r_] = MAC[r_, c_]
            if MAC[r_, c_] >= mac_min:
                f_a[r_] = f_o[c_]
                full_o[:, r_] = full_o_all[:, c_]
    elif system.hot_dof is None:
        f_a = f_r.copy()
        pair_mac = np.ones(n_found)
    with np.errstate(invalid="ignore"):
        ratio = np.where(np.isfinite(f_a), f_r / f_a, np.nan)
        k_eff = np.sqrt(np.clip(1 - ratio ** 2, 0.0, None))
    # the shares and labels of fem.modeshape, on the matrix the shapes are normalised with
    mode_shares = energy_shares(system, shapes) if n_found else None
    shares = mode_shares.overall.table() if n_found else np.zeros((0, 3))
    t4 = time.perf_counter()
    timings = {"assembly_s": float(system.timings.get("assembly_s", np.nan)),
               "factorisation_s": F.seconds, "eigen_s": (t2 - t1) + (t3 - t2),
               "modal_s": t4 - t0}
    timings["total_s"] = timings["assembly_s"] + timings["modal_s"]
    log.info("modal: %d modes near %.1f Hz, %d DOFs, %s, factor %.2f s, eigen %.2f s",
             n_found, near_hz, system.ndof, F.backend, F.seconds, timings["eigen_s"])
    return ModalResult(f_r_hz=f_r, f_a_hz=f_a, k_eff=k_eff, mac=pair_mac, shapes=shapes, vectors=full_s,
                       vectors_open=full_o, shares=shares, rigid_hz=rigid_f,
                       ndof=system.ndof, backend=F.backend, sigma=float(sigma),
                       near_hz=float(near_hz), clamp=clamp, timings=timings, system=system,
                       mode_shares=mode_shares)


# --------------------------------------------------------------------------- CLI


def format_table(res: ModalResult) -> str:
    lines = [f"{'#':>3} {'f_r kHz':>10} {'f_a kHz':>10} {'k_eff':>7} {'MAC':>5}  "
             f"{'ax/tor/lat':>14}  motion"]
    for i in range(res.n_modes):
        fa = f"{res.f_a_hz[i] / 1e3:10.4f}" if np.isfinite(res.f_a_hz[i]) else f"{'-':>10}"
        ke = f"{res.k_eff[i]:7.4f}" if np.isfinite(res.k_eff[i]) else f"{'-':>7}"
        mc = f"{res.mac[i]:5.2f}" if np.isfinite(res.mac[i]) else f"{'-':>5}"
        sh = "/".join(f"{100 * s:.0f}" for s in res.shares[i])
        lines.append(f"{i + 1:3d} {res.f_r_hz[i] / 1e3:10.4f} {fa} {ke} {mc}  {sh:>14}  {res.labels[i]}")
    t = res.timings
    lines.append(f"{res.ndof} DOFs, {res.backend}; assembly {t['assembly_s']:.2f} s, "
                 f"factorisation {t['factorisation_s']:.2f} s, eigen {t['eigen_s']:.2f} s"
                 + (f"; {len(res.rigid_hz)} rigid-body modes skipped" if len(res.rigid_hz) else ""))
    return "\n".join(lines)


def build_parser(prog="python -m fem.modal"):
    from geometry.common import CliParser

    p = CliParser(prog=prog, description="Resonance (short-circuit) and anti-resonance (open-circuit) "
                  "modes of a design near a target frequency; with --match, tune the horn and coupler "
                  "lengths until both resonate together at the target.")
    g = p.add_argument_group("design")
    g.add_argument("--design", default="default",
                   help="design TOML file (geometry package layout), or 'default' for the built-in design "
                        "(default)")
    g.add_argument("--select", metavar="NAME", help="design to pick from a file holding several")
    g.add_argument("--mesh-size", type=float, metavar="M", help="characteristic mesh size in m")
    g.add_argument("--order", type=int, default=2, choices=(1, 2), help="field order (default 2)")
    g = p.add_argument_group("modal analysis")
    g.add_argument("--near", type=float, metavar="HZ",
                   help="target frequency in Hz (0: lowest modes; default: the design's target frequency)")
    g.add_argument("--modes", type=int, default=None, metavar="N",
                   help=f"number of modes, 1-{MAX_MODES} (default 12; with --match: modes per iteration, default 4)")
    g.add_argument("--clamp", action="append", default=[], metavar="SURFACE",
                   help="clamp the named surface (repeatable; default: free)")
    g.add_argument("--solver", choices=("auto", "pardiso", "superlu"), default=None,
                   help="sparse direct solver (default: pardiso if installed; env RPUD_SOLVER)")
    g = p.add_argument_group("resonance matching")
    g.add_argument("--match", action="store_true",
                   help="tune design lengths until the working longitudinal mode is at the target and the "
                        "horn and coupler sides resonate together")
    g.add_argument("--target", type=float, metavar="HZ",
                   help="matching target frequency in Hz (default: the design's target_frequency)")
    g.add_argument("--tune", metavar="A[,B]",
                   help="design lengths to tune: a horn/flange length, then a coupler/stack length "
                        "(default horn.length,coupler.length)")
    g.add_argument("--bracket", metavar="LO,HI", default="0.5,2.0",
                   help="search interval of each tuned length as factors of its start (default 0.5,2.0)")
    g.add_argument("--tol", type=float, default=None, metavar="REL",
                   help=f"relative frequency tolerance of the match, in [{MATCH_TOL_RANGE[0]:g}, {MATCH_TOL_RANGE[1]:g}] "
                        "(default 0.005 = 0.5 %%)")
    g.add_argument("--out-design", metavar="FILE",
                   help="write the tuned design as TOML (default: <design name>-tuned.toml beside --json, "
                        "else not written)")
    g = p.add_argument_group("output")
    g.add_argument("--json", metavar="OUT", help="write the result as JSON to OUT")
    g.add_argument("--render", metavar="DIR",
                   help="off-screen PNGs of the working mode and its neighbours into DIR")
    g.add_argument("--vtu", metavar="FILE", help="VTU file with every computed mode as point data (ParaView)")
    g.add_argument("--allow-large", action="store_true",
                   help="solve even above the resource budget (geometry.guard.MAX_DOFS estimated DOFs)")
    p.add_argument("-v", "--verbose", action="count", default=0)
    return p


MAX_MODES = 200
"""Most modes one CLI run computes (shift-invert Lanczos cost grows with their square)."""

MATCH_TOL_RANGE = (1e-6, 0.2)
"""Accepted relative frequency tolerances of ``--match`` (``--tol``)."""


def _check_options(args) -> dict:
    """Validate every option before the design is meshed; returns the checked output paths."""
    from geometry.common import check_integer, check_output_paths, check_range
    from geometry.validate import FREQUENCY_BAND

    if args.near is not None and args.near != 0:
        check_range("--near", args.near, *FREQUENCY_BAND, "Hz")
    if args.modes is not None:
        check_integer("--modes", args.modes, 1, MAX_MODES)
    if args.mesh_size is not None:
        check_range("--mesh-size", args.mesh_size, 1e-5, 1.0, "m")
    if args.target is not None:
        check_range("--target", args.target, *FREQUENCY_BAND, "Hz")
    if args.tol is not None:
        # below 1e-6 (0.02 Hz at 20 kHz) the FE frequency itself is not that exact: unattainable
        check_range("--tol", args.tol, *MATCH_TOL_RANGE)
    for opt, suffix in (("json", ".json"), ("vtu", ".vtu"), ("out_design", ".toml")):
        val = getattr(args, opt)
        if val is not None and not str(val).endswith(suffix):
            raise ParameterError("--" + opt.replace("_", "-"), val, f"must end in {suffix}")
    if args.select is not None and str(args.design) == "default":
        raise ParameterError("--select", args.select, "needs --design FILE")
    if not args.match:
        for opt in ("target", "tune", "out_design", "tol"):
            if getattr(args, opt) is not None:
                raise ParameterError("--" + opt.replace("_", "-"), getattr(args, opt), "applies to --match only")
        if args.bracket != "0.5,2.0":
            raise ParameterError("--bracket", args.bracket, "applies to --match only")
    else:
        # matching is free-free with its own nodal-plane cut and shift: refuse what it cannot honour
        if args.clamp:
            raise ParameterError("--clamp", args.clamp[0], "cannot be used with --match (the match is free-free)")
        if args.near is not None:
            raise ParameterError("--near", args.near, "cannot be used with --match; give --target HZ")
    if args.solver not in (None, "auto"):
        from .solvers import backend_name

        backend_name(args.solver)                  # pardiso without MKL: refused before meshing
    tuned = None
    if args.match and args.out_design is None and args.json is not None:
        tuned = "beside --json"
    outputs = check_output_paths(inputs={"--design": None if str(args.design) == "default" else args.design},
                                 folders=("render",), json=args.json, vtu=args.vtu, out_design=args.out_design,
                                 render=args.render)
    outputs["tuned"] = tuned
    return outputs


def _factors(text: str, name: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError(name, text, "must be two numbers LO,HI") from None
    if not (0.05 <= lo < 1 < hi <= 20):
        raise ParameterError(name, text, "must be two factors with 0.05 <= LO < 1 < HI <= 20")
    return lo, hi


def _outputs(args, mesh, res, working: int) -> None:
    """--render and --vtu: the working mode and two neighbours each side; every mode."""
    if args.render:
        from .render import around, render_modes

        paths = render_modes(mesh, res.shapes, args.render, modes=around(working, res.n_modes, 2),
                             frequencies=res.f_r_hz, labels=res.labels)
        print(f"renders: {', '.join(str(p) for p in paths)}")
    if args.vtu:
        from .render import write_modes_vtu

        print(f"modes: {write_modes_vtu(mesh, res.shapes, args.vtu, frequencies=res.f_r_hz)}")


def main(argv=None) -> int:
    import geometry
    from geometry.common import atomic_write_text, check_output_paths, json_text, setup_logging
    from geometry.guard import check_budget

    from .assembly import assemble

    args = build_parser().parse_args(argv)
    setup_logging(args.verbose - 1)
    if args.verbose < 2:
        logging.getLogger("skfem").setLevel(logging.WARNING)
    outputs = _check_options(args)
    bracket = _factors(args.bracket, "--bracket") if args.match else None
    design = geometry.default_design() if str(args.design) == "default" else geometry.load_design(args.design,
                                                                                                  args.select)
    check_budget(design, args.mesh_size, args.order, allow_large=args.allow_large)
    if args.match:
        from .matching import MatchSettings, match

        extra = {"n_modes": args.modes} if args.modes is not None else {}
        settings = MatchSettings(
            target_hz=float(args.target or getattr(design, "target_frequency", 20e3)), tolerance=0.005 if args.tol is None else args.tol,
            tune=tuple(args.tune.split(",")) if args.tune else getattr(design, "default_tuned", ()),
            bracket=bracket, mesh_size=args.mesh_size, order=args.order, **extra)
        out_design = args.out_design
        if out_design is None and outputs["tuned"]:
            out_design = str(Path(args.json).parent / f"{design.name}-tuned.toml")
            check_output_paths(inputs={"--design": None if str(args.design) == "default" else args.design,
                                       "--json": args.json}, out_design=out_design)
        print(f"matching {', '.join(settings.tune)} to {settings.target_hz:.1f} Hz", flush=True)

        def show(rec):
            print(f"  [{rec['stage']:5s}] {rec['parameter']} = "
                  f"{rec['value_m'] * 1e3:9.4f} mm -> {rec['f_hz']:10.2f} Hz  ({rec['seconds']:5.1f} s)",
                  flush=True)

        with _solver(args.solver):
            res_m = match(design, settings, progress=show)
        res = res_m.modal
        print(format_table(res))
        print(f"matched {res_m.matched_hz:.2f} Hz (target {res_m.target_hz:.1f} Hz, "
              f"{'converged' if res_m.converged else 'NOT converged'}) in {len(res_m.iterations)} iterations, "
              f"{res_m.timings['total_s']:.1f} s; tuned: "
              + ", ".join(f"{k} = {v * 1e3:.4f} mm (start {res_m.start[k] * 1e3:.4f})" for k, v in res_m.tuned.items()))
        if res_m.teeth:
            print(f"teeth: axial {res_m.teeth['axial']:.3g}, tangential {res_m.teeth['tangential']:.3g} "
                  f"(ellipse ratio {res_m.teeth['ellipse_ratio']:.3f}); flange/tip axial {res_m.node_ratio:.3f}")
        # NaN marks "not available" here (a stack design has no flange/tip ratio, unpaired modes no f_a)
        text = json_text(res_m.to_json(), nonfinite="null") if args.json else None
        if out_design:
            atomic_write_text(out_design, res_m.design.to_toml())
            print(f"tuned design: {out_design}")
        else:
            print("tuned design not written (give --out-design FILE or --json)")
        _outputs(args, res_m.mesh, res, res_m.working_index)
        if text is not None:
            atomic_write_text(args.json, text)
        return 0 if res_m.converged else 1
    near = float(args.near if args.near is not None else getattr(design, "target_frequency", 20e3))
    mesh = geometry.build_mesh(design, mesh_size=args.mesh_size, order=args.order)
    for name in args.clamp:
        mesh.facets(name)
    system = assemble(mesh, order=args.order)
    n_modes = 12 if args.modes is None else args.modes
    if n_modes > system.ndof // 4:
        raise ParameterError("--modes", n_modes, f"must be <= {system.ndof // 4} for this mesh ({system.ndof} DOFs)")
    res = modal_analysis(system, near, n_modes, clamp=args.clamp,
                         backend=None if args.solver in (None, "auto") else args.solver)
    print(format_table(res))
    data = None
    if args.json:
        data = res.to_json()
        data["design"] = str(args.design)
        data["mesh_size"] = args.mesh_size
        data = json_text(data, nonfinite="null")
    if args.render or args.vtu:
        from .matching import working_mode

        _outputs(args, mesh, res, working_mode(system, res.f_r_hz, res.vectors, max(near, 1.0)) if near > 0 else 0)
    if data is not None:
        atomic_write_text(args.json, data)
    return 0


@contextlib.contextmanager
def _solver(name):
    """The sparse solver for code that picks it from ``RPUD_SOLVER`` (the matching loop)."""
    if name in (None, "auto"):
        yield
        return
    old = os.environ.get("RPUD_SOLVER")
    os.environ["RPUD_SOLVER"] = name
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("RPUD_SOLVER", None)
        else:
            os.environ["RPUD_SOLVER"] = old
