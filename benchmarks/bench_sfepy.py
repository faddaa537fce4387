"""Modal analysis of the default drill against SfePy on the same tetrahedra.

The problem: the default design (``geometry.build(default_design())``), P2 displacement on every
cell, P2 potential on the four PZT-8 rings (poling alternating -z/+z), short circuit (every
electrode at 0 V), free mechanical boundary, the 12 modes nearest 20 kHz (shift
sigma = (2 pi 20 kHz)^2). Meshing is done once and is not timed.

Our side: ``assemble`` + ``modal_analysis`` as the toolkit runs them (short + open circuit; also
short circuit only, ``open_circuit=False``), on

* the mesh as built: 10-node tetrahedra with curved mid-edge nodes (isoparametric geometry);
* the same tetrahedra with straight edges (corner nodes only; P2 fields, affine geometry).

SfePy has affine simplices only (``3_4`` cells; no 10-node geometry), so it gets the corner
nodes and builds its own P2 fields: it solves exactly the problem of the straight-edged row, and
that row is the like-for-like comparison (frequencies must agree to round-off). The curved row is
the toolkit's default result; its frequencies differ from the straight-edged ones by the
geometry error of straight edges on the curved surfaces, which is reported, not hidden.

SfePy side (imperative API, following ``sfepy/examples/linear_elasticity/modal_analysis.py``
and ``sfepy/examples/multi_physics/piezo_elastodynamic.py``): ``Mesh.from_data`` with one cell
group per (material, poling sign), electrode vertex sets as ``nodal_bcs``; ``Field``s of order 2
(displacement on all cells, potential on the ceramic cells); per group ``dw_lin_elastic`` (full
stiffness, c^E of PZT-8 or isotropic Ti6Al4V), ``dw_piezo_coupling`` (e, sign flipped for -z
poling: the half turn about x flips every entry of a 6mm ``e`` and leaves c^E, eps^S as they are)
and ``dw_diffusion`` (eps^S), ``dw_dot`` (density); constants permuted to SfePy's Voigt order
(11 22 33 12 13 23). Quadrature as ours on straight cells: order 2 for stiffness, coupling and
permittivity, order 4 for the mass (exact). ``EssentialBC`` phi = 0 on every electrode facet
region; matrices by ``Equation.evaluate(mode='weak', dw_mode='matrix')`` on the active DOFs, the
potential rows negated so that ``K = [[K_uu, K_up], [K_up^T, -K_pp]]`` is symmetric. Eigen:
scipy ``eigsh`` in shift-invert mode with ``OPinv`` from SfePy's linear solver (``presolve``
factorises ``K - sigma M`` once, each ARPACK step calls the solver), the mass of the potential
is zero (semi-definite M, as in ours). The rigid modes are not deflated, so SfePy asks for
12 + 6 eigenpairs and keeps the 12 elastic ones nearest sigma (ours deflates the six rigid
modes with a projector and asks for 12). SfePy's own ``eig.scipy`` with ``linear_solver`` was
not used: it builds its ``LinearOperator`` without a dtype, scipy probes it with an int8
vector, and ``ls.pypardiso`` rejects that (TypeError); the operator here is the same thing with
``dtype=float64``. SfePy runs twice per round: with OpenBLAS's default threads around ``eigsh``
(what a user gets) and with one OpenBLAS thread (as ours runs its Lanczos, ``fem.solvers.
blas_threads``); neither was consistently faster here, and the faster row is SfePy's reference.
ARPACK starts from a random vector, so SfePy's solve count varies from run to run (48-58 seen).

SfePy's direct solvers tried in order of speed: ``ls.pypardiso`` (MKL PARDISO through pypardiso,
real unsymmetric LU, mtype 11), ``ls.mumps``, ``ls.scipy_umfpack``, ``ls.scipy_superlu``; the
first that works is the "best available" row (``--superlu`` also times SuperLU, one run).
pypardiso keeps the last factorisation and skips refactorising an identical matrix: its stored
factorisation is dropped before every SfePy run.

Checks: the active DOF counts (u and phi) of SfePy equal ours in short circuit; the SfePy
frequencies are compared with ours (max relative difference; the straight row must agree to
1e-8 or the script exits 1).

Timing: best of ``--repeat`` (default 3) runs, ours and SfePy alternating; ratio = SfePy total
(its faster thread setting) / row total. ``--hybrid`` adds a row that is NOT SfePy's solver:
SfePy's matrices and ``eigsh`` with our symmetric PARDISO factor (``fem.solvers.factorize``),
to show how much of the ratio is the linear solver and how much the rest. SfePy "assembly" =
problem set-up (mesh, domain, regions, fields, terms, EBCs) + matrix evaluation; "eigen" =
factorisation + Lanczos for both.

``--cyclic``: the same comparison on a cyclically symmetric mesh: the default design's free
60-degree sector (stack in PZT-4, whose tabulated c66 = (c11 - c12) / 2 makes the drill exactly
6-fold symmetric) replicated into the whole drill (geometry.sector.replicate). SfePy and our
whole-drill rows solve that whole mesh; the cyclic rows solve its sector per harmonic
(fem.cyclic, harmonics 0..3, each asked for its share of the 12 modes nearest 20 kHz and more
where it may hold nearer ones; a pair counts twice) and must agree with SfePy to 1e-8 too.

Usage: ``python benchmarks/bench_sfepy.py [--repeat 3] [--quick] [--superlu] [--hybrid] [--cyclic]``
(``--quick``: one run, no short-circuit-only rows).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import logging
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geometry  # noqa: E402
from fem.assembly import assemble  # noqa: E402
from fem.modal import modal_analysis  # noqa: E402
from fem.solvers import backend_name, blas_threads  # noqa: E402

NEAR, N_MODES = 20e3, 12
SIGMA = (2 * np.pi * NEAR) ** 2
RIGID_HZ = max(10.0, 0.01 * NEAR)          # as fem.modal: below this a mode is rigid
SFEPY_VOIGT = [0, 1, 2, 5, 4, 3]           # ours xx yy zz yz xz xy -> SfePy xx yy zz xy xz yz
SOLVERS = ("ls.pypardiso", "ls.mumps", "ls.scipy_umfpack", "ls.scipy_superlu")
HYBRID = "fem.solvers PARDISO LDL^T"      # --hybrid: SfePy's matrices, our factorisation


# ----------------------------------------------------------------------------- our side
def straight(tm):
    """The same tetrahedra with straight edges (corner nodes only: affine geometry)."""
    return tm.replace(cells=np.ascontiguousarray(tm.cells[:, :4]))


def run_ours(tm, open_circuit):
    t0 = time.perf_counter()
    system = assemble(tm)
    t1 = time.perf_counter()
    res = modal_analysis(system, NEAR, N_MODES, open_circuit=open_circuit)
    t2 = time.perf_counter()
    return dict(ndof=len(system.free_dofs("short")), n_phi=system.n_phi, asm=t1 - t0, eig=t2 - t1,
                fact=res.timings["factorisation_s"], total=t2 - t0, f=np.sort(res.f_r_hz),
                backend=res.backend)


def run_ours_cyclic(tm, sectors, open_circuit):
    """Our cyclic-symmetry path on the sector ``tm``: the N_MODES modes of the whole drill nearest
    NEAR from its harmonics (a pair twice), as ``python -m fem.modal --sectors`` selects them."""
    from fem.cyclic import harmonics, multiplicity, nearest_modes

    t0 = time.perf_counter()
    system = assemble(tm)
    t1 = time.perf_counter()
    res, chosen = nearest_modes({k: system for k in harmonics(sectors)}, sectors, NEAR, N_MODES,
                                open_circuit=open_circuit)
    t2 = time.perf_counter()
    f = np.sort([float(res[k].f_hz[j]) for k, j in chosen for _ in range(multiplicity(k, sectors))][:N_MODES])
    return dict(ndof=len(system.free_dofs("short")), n_phi=system.n_phi, asm=t1 - t0, eig=t2 - t1,
                fact=float("nan"), total=t2 - t0, f=f, backend="cyclic, " + backend_name())


# ----------------------------------------------------------------------------- SfePy side
def sfepy_available():
    import io

    try:
        # sfepy prints a notice (stdout) and a warning (stderr) about the optional jax terms
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            import sfepy
            from sfepy.base.base import output
            import sfepy.discrete  # noqa: F401
            import sfepy.solvers  # noqa: F401
            import sfepy.terms  # noqa: F401
    except Exception as exc:  # ImportError and anything sfepy raises while importing
        return None, f"{type(exc).__name__}: {exc}"
    output.set_output(quiet=True)
    return sfepy.__version__, None


def sfepy_solver_status():
    """{name: None if usable else reason} for SfePy's direct solvers."""
    from sfepy.base.base import Struct
    from sfepy.solvers import Solver

    out = {}
    hook, sys.unraisablehook = sys.unraisablehook, lambda *_: None   # ls.mumps' __del__ after a failed init
    try:
        for name in SOLVERS:
            try:
                Solver.any_from_conf(Struct(name="ls", kind=name, use_presolve=True))
                out[name] = None
            except Exception as exc:
                out[name] = f"{type(exc).__name__}: {str(exc).splitlines()[0][:60]}"
            gc.collect()
    finally:
        sys.unraisablehook = hook
    return out


def _forget_pardiso():
    """Drop pypardiso's stored factorisation (it would skip refactorising an equal matrix)."""
    try:
        from pypardiso.scipy_aliases import pypardiso_solver
    except ImportError:
        return
    pypardiso_solver.free_memory(everything=True)


def sfepy_problem(tm):
    """Set up and assemble the short-circuit problem in SfePy: ``(K, M, n_dof, t_setup, t_asm)``."""
    import operator
    from functools import reduce

    from sfepy.discrete import (Conditions, Equation, Equations, FieldVariable, Integral, Material,
                                Problem)
    from sfepy.discrete.conditions import EssentialBC
    from sfepy.discrete.fem import FEDomain, Field, Mesh
    from sfepy.mechanics.matcoefs import stiffness_from_youngpoisson
    from sfepy.terms import Term

    t0 = time.perf_counter()
    corners = np.unique(tm.cells[:, :4])
    old_to_new = np.full(tm.n_points, -1, dtype=np.int64)
    old_to_new[corners] = np.arange(len(corners))
    conn = old_to_new[tm.cells[:, :4]].astype(np.int32)
    groups, group_of_region = [], np.zeros(len(tm.regions), dtype=np.int32)
    for i, r in enumerate(tm.regions):
        key = (r.material, None if r.poling is None else int(np.sign(r.poling[2])))
        if r.poling is not None and (abs(r.poling[0]) > 1e-12 or abs(r.poling[1]) > 1e-12):
            raise SystemExit(f"region {r.name}: poling {r.poling} is not along +/-z (not handled here)")
        if key not in groups:
            groups.append(key)
        group_of_region[i] = groups.index(key) + 1
    mat_ids = group_of_region[tm.cell_region]
    nodal_bcs = {e.name: old_to_new[np.unique(tm.facet_sets[e.name])] for e in tm.electrodes}
    mesh = Mesh.from_data("rpud", tm.points[corners], None, [conn], [mat_ids], ["3_4"],
                          nodal_bcs=nodal_bcs)
    domain = FEDomain("domain", mesh)
    omega = domain.create_region("Omega", "all")
    cell_regions = [domain.create_region(f"G{g + 1}", f"cells of group {g + 1}") for g in range(len(groups))]
    ceramic_groups = [g + 1 for g, (_, pol) in enumerate(groups) if pol is not None]
    ceramic = domain.create_region("Ceramic", " +c ".join(f"cells of group {g}" for g in ceramic_groups))
    electrodes = [domain.create_region(e.name, f"vertices of set {e.name}", "facet") for e in tm.electrodes]

    field_u = Field.from_args("displacement", np.float64, "vector", omega, approx_order=2)
    field_p = Field.from_args("potential", np.float64, "scalar", ceramic, approx_order=2)
    u = FieldVariable("u", "unknown", field_u)
    v = FieldVariable("v", "test", field_u, primary_var_name="u")
    phi = FieldVariable("phi", "unknown", field_p)
    psi = FieldVariable("psi", "test", field_p, primary_var_name="phi")
    i2, i4 = Integral("i2", order=2), Integral("i4", order=4)

    rows_u, rows_p, mass = [], [], []
    for g, (name, pol) in enumerate(groups):
        rec, reg, mn = tm.material(name), cell_regions[g], f"m{g}"
        if pol is None:
            mat = Material(mn, C=stiffness_from_youngpoisson(3, rec.youngs_modulus, rec.poisson_ratio),
                           rho=np.array([[rec.density]]))
        else:
            c, e, eps = (np.asarray(a, dtype=float) for a in rec.voigt_matrices())   # material frame
            mat = Material(mn, C=c[np.ix_(SFEPY_VOIGT, SFEPY_VOIGT)], e=pol * e[:, SFEPY_VOIGT],
                           kappa=eps, rho=np.array([[rec.density]]))
            rows_u.append(Term.new(f"dw_piezo_coupling({mn}.e, v, phi)", i2, reg, **{mn: mat}, v=v, phi=phi))
            rows_p.append(Term.new(f"dw_piezo_coupling({mn}.e, u, psi)", i2, reg, **{mn: mat}, u=u, psi=psi))
            rows_p.append(-Term.new(f"dw_diffusion({mn}.kappa, psi, phi)", i2, reg, **{mn: mat},
                                    psi=psi, phi=phi))
        rows_u.append(Term.new(f"dw_lin_elastic({mn}.C, v, u)", i2, reg, **{mn: mat}, v=v, u=u))
        mass.append(Term.new(f"dw_dot({mn}.rho, v, u)", i4, reg, **{mn: mat}, v=v, u=u))
    eq_u = Equation("K_u", reduce(operator.add, rows_u))
    eq_p = Equation("K_phi", reduce(operator.add, rows_p))
    eq_m = Equation("M", reduce(operator.add, mass))
    pb = Problem("rpud_piezo", equations=Equations([eq_u, eq_p, eq_m]))
    pb.time_update(ebcs=Conditions([EssentialBC(f"phi0_{r.name}", r, {"phi.0": 0.0}) for r in electrodes]))
    pb.update_materials()
    t1 = time.perf_counter()

    def evaluate(eq):
        A = pb.mtx_a.copy()
        A.data[:] = 0.0
        return eq.evaluate(mode="weak", dw_mode="matrix", asm_obj=A)

    K = evaluate(eq_u)
    K.data += evaluate(eq_p).data          # same sparsity pattern (copies of pb.mtx_a)
    M = evaluate(eq_m)
    t2 = time.perf_counter()
    n_dof = dict(pb.equations.variables.adi.n_dof)
    return K, M, n_dof, t1 - t0, t2 - t1


def sfepy_eigen(K, M, ls_name, openblas_one=True):
    """12 elastic modes nearest sigma: eigsh shift-invert with SfePy's linear solver."""
    import scipy.sparse as sps
    import scipy.sparse.linalg as spla
    from sfepy.base.base import Struct
    from sfepy.solvers import Solver

    t0 = time.perf_counter()
    A = (K - SIGMA * M).tocsr()
    if ls_name == HYBRID:                  # not SfePy's: our symmetric PARDISO factor (fem.solvers)
        from fem.solvers import factorize

        F = factorize(sps.csr_matrix(A), matching=False)
        ls = lambda b, mtx=None: F(b)      # noqa: E731
    else:
        ls = Solver.any_from_conf(Struct(name="ls", kind=ls_name, use_presolve=True))
        ls.presolve(A)                     # factorise once; each call below reuses it
    t1 = time.perf_counter()
    calls = [0]

    def solve(b):
        calls[0] += 1
        return ls(np.asarray(b, dtype=np.float64).ravel(), mtx=A)

    op = spla.LinearOperator(A.shape, matvec=solve, dtype=np.float64)
    ctx = blas_threads(1) if openblas_one else contextlib.nullcontext()
    with ctx:
        lam = spla.eigsh(A, k=N_MODES + 6, M=M, sigma=SIGMA, which="LM", OPinv=op, tol=1e-10,
                         return_eigenvectors=False)
    t2 = time.perf_counter()
    f = np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * np.pi)
    elastic = np.flatnonzero(np.abs(f) >= RIGID_HZ)
    keep = elastic[np.argsort(np.abs(lam[elastic] - SIGMA))[:N_MODES]]
    return np.sort(f[keep]), t1 - t0, t2 - t0, calls[0]


def run_sfepy(tm, ls_name, openblas_one=True):
    _forget_pardiso()
    gc.collect()
    K, M, n_dof, t_setup, t_asm = sfepy_problem(tm)
    f, t_fact, t_eig, calls = sfepy_eigen(K, M, ls_name, openblas_one)
    del K, M
    _forget_pardiso()
    gc.collect()
    return dict(ndof=sum(n_dof.values()), n_phi=n_dof["phi"], setup=t_setup, asm=t_setup + t_asm,
                fact=t_fact, eig=t_eig, total=t_setup + t_asm + t_eig, f=f, solves=calls)


# ----------------------------------------------------------------------------- driver
def _best(runs):
    """The run of least total time (the least disturbed one on a shared machine)."""
    return min(runs, key=lambda r: r["total"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per row; the best is reported (default 3)")
    ap.add_argument("--quick", action="store_true", help="one run per row, no short-circuit-only rows")
    ap.add_argument("--superlu", action="store_true", help="also time SfePy with ls.scipy_superlu (one run, slow)")
    ap.add_argument("--cyclic", action="store_true",
                    help="a cyclically symmetric mesh (the default design's free 60-degree sector in PZT-4, "
                         "replicated): SfePy and our whole-drill rows on the whole mesh, our cyclic rows on "
                         "its sector")
    ap.add_argument("--hybrid", action="store_true",
                    help="also time SfePy's set-up/assembly + eigsh with OUR PARDISO factor (symmetric "
                         "LDL^T, fem.solvers): splits the ratio into solver and algorithm; not a SfePy row")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("skfem").setLevel(logging.ERROR)
    repeat = 1 if args.quick else max(1, args.repeat)

    backend_name()                                       # load MKL before any timing
    version, why = sfepy_available()
    t = time.perf_counter()
    sector = None
    if args.cyclic:
        import dataclasses

        from geometry.sector import replicate

        d = geometry.default_design()
        d = dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))
        sector, _report = geometry.build(d, mesher="free", sectors=6)
        tm_curved, _ = replicate(sector, 6)
    else:
        tm_curved, _report = geometry.build(geometry.default_design())
    print(f"mesh: {tm_curved.n_cells} tetrahedra (10-node), {tm_curved.n_points} nodes, "
          f"{time.perf_counter() - t:.1f} s (not timed below)")
    tm_straight = straight(tm_curved)

    cases = [("ours, curved 10-node (default), SC + OC", tm_curved, True),
             ("ours, straight edges, SC + OC", tm_straight, True)]
    if not args.quick:
        cases += [("ours, curved 10-node, SC only", tm_curved, False),
                  ("ours, straight edges, SC only", tm_straight, False)]
    if sector is not None:
        cases += [("ours, cyclic sector, straight edges, SC + OC", straight(sector), "cyclic-oc"),
                  ("ours, cyclic sector, straight edges, SC only", straight(sector), "cyclic")]
    ls_best = None
    if version is None:
        print(f"sfepy is not importable ({why}): only our rows are timed")
    else:
        status = sfepy_solver_status()
        usable = [n for n in SOLVERS if status[n] is None]
        print(f"sfepy {version}; direct solvers: " +
              "; ".join(f"{n} {'available' if status[n] is None else 'unavailable (' + status[n] + ')'}"
                        for n in SOLVERS))
        ls_best = usable[0] if usable else None
        if ls_best is None:
            print("no SfePy direct solver works: only our rows are timed")

    runs = {label: [] for label, *_ in cases}
    sf_runs, sf_one, sf_hybrid = [], [], []
    for k in range(repeat):
        for label, tm, oc in cases:
            if isinstance(oc, str):
                runs[label].append(run_ours_cyclic(tm, 6, oc == "cyclic-oc"))
            else:
                runs[label].append(run_ours(tm, oc))
        if ls_best is not None:
            sf_runs.append(run_sfepy(tm_curved, ls_best, openblas_one=False))
            sf_one.append(run_sfepy(tm_curved, ls_best, openblas_one=True))
            if args.hybrid:
                sf_hybrid.append(run_sfepy(tm_curved, HYBRID))
        print(f"round {k + 1}/{repeat}: " + ", ".join(f"{lab.split(',')[1].strip()} {runs[lab][-1]['total']:.1f} s"
                                                 for lab, *_ in cases)
              + (f", SfePy {sf_runs[-1]['total']:.1f} / {sf_one[-1]['total']:.1f} s" if sf_runs else ""),
              flush=True)

    rows = [(label, _best(runs[label])) for label, *_ in cases]
    if ls_best is not None:
        rows.append((f"SfePy {version}, {ls_best} (straight edges, SC)", _best(sf_runs)))
        rows.append((f"SfePy {version}, {ls_best}, 1 OpenBLAS thread in eigsh", _best(sf_one)))
        if sf_hybrid:
            rows.append((f"(not SfePy's solver) SfePy matrices + eigsh, {HYBRID}", _best(sf_hybrid)))
        if args.superlu and ls_best != "ls.scipy_superlu":
            rows.append(("SfePy, ls.scipy_superlu (1 run)", run_sfepy(tm_curved, "ls.scipy_superlu")))

    ours_straight = rows[1][1]["f"]
    sf = _best(sf_runs + sf_one) if sf_runs else None
    ok = True
    if sf is not None:
        ours_sc = _best(runs[cases[1][0]])
        same_dofs = sf["ndof"] == ours_sc["ndof"] and sf["n_phi"] == ours_sc["n_phi"]
        ok = same_dofs
        print(f"active DOFs (short circuit): ours {ours_sc['ndof']} ({ours_sc['n_phi']} phi), "
              f"SfePy {sf['ndof']} ({sf['n_phi']} phi): {'same' if same_dofs else 'DIFFERENT'}")
    ref = sf["f"] if sf is not None else ours_straight
    if sf is not None:
        which = "1 OpenBLAS thread" if any(sf is r for r in sf_one) else "default threads"
        print(f"SfePy reference: its faster run ({which})")

    def fdiff(f):
        return float(np.max(np.abs(f / ref - 1))) if len(f) == len(ref) else np.nan

    d_straight = fdiff(ours_straight)
    if sf is not None:
        ok = ok and d_straight < 1e-8
        for label, r in rows:
            if "cyclic" in label and not fdiff(r["f"]) < 1e-8:
                print(f"CHECK FAILED: {label}: frequencies differ from SfePy's by {fdiff(r['f']):.1e}")
                ok = False
    print()
    print(f"Default design, 12 short-circuit modes nearest 20 kHz, free-free; best of {repeat} run(s) "
          f"(least total time); SC = short circuit, OC = open circuit; ratio = "
          f"{'SfePy (faster run)' if sf is not None else 'straight SC + OC'} total / row total; "
          f"rel. diff f_r against {'SfePy' if sf is not None else 'our straight-edged row'}.")
    headers = ("case", "DOFs", "assembly s", "eigen s (factorise)", "total s", "ratio", "max rel. diff f_r")
    base = sf["total"] if sf is not None else rows[1][1]["total"]
    table = []
    for label, r in rows:
        table.append((label, str(r["ndof"]), f"{r['asm']:.2f}", f"{r['eig']:.2f} ({r['fact']:.2f})",
                      f"{r['total']:.2f}", f"{base / r['total']:.2f}x", f"{fdiff(r['f']):.1e}"))
    from _table import print_table
    print_table(table, headers)
    print()
    print("f_r kHz  ours curved | ours straight | SfePy")
    fc = rows[0][1]["f"]
    for i in range(len(ref)):
        print(f"  {fc[i] / 1e3:9.4f} | {ours_straight[i] / 1e3:9.4f} | "
              + (f"{sf['f'][i] / 1e3:9.4f}" if sf is not None else "-"))
    if sf is not None:
        print(f"SfePy reference run: set-up {sf['setup']:.2f} s of its assembly; eigsh called the solver "
              f"{sf['solves']} times for {N_MODES} + 6 eigenpairs (rigid modes not deflated; solves per run: "
              f"{[r['solves'] for r in sf_runs + sf_one]}); our backend: {rows[0][1]['backend']}")
        print(f"curved vs straight edges (geometry of the same tetrahedra): max rel. diff "
              f"{float(np.max(np.abs(fc / ours_straight - 1))):.1e}")
        if not ok:
            print("CHECK FAILED: SfePy and our straight-edged model do not solve the same problem")
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
