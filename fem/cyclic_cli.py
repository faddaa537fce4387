"""``python -m fem.modal --sectors``: the modal table of a cyclically symmetric drill from one
sector per circumferential harmonic (:mod:`fem.cyclic`, :mod:`geometry.sector`).

The physics lives in :mod:`fem.cyclic`; this module resolves the options, meshes, calls and
prints. With the swept mesher each harmonic family gets the mesh its accuracy needs
(:data:`geometry.sector.AXIAL_RULE` for ``k = 0``: the working mode and the torsion,
:data:`geometry.sector.LATERAL_RULE` for ``k >= 1``: the bending pairs).
"""

from __future__ import annotations

import time

import numpy as np

from rpud_common import ParameterError

__all__ = ["sectors_for", "parse_harmonics", "run", "format_rows", "own_note", "CYCLIC_NOTE", "HARMONICS"]

HARMONICS = "0,1"
"""Default ``--harmonics``: the longitudinal, torsional and driven modes (0) and the bending pairs (1)."""

CYCLIC_NOTE = ("mesh: swept sector (1/{n}), a mesh per harmonic family as listed. Measured at --refine 1 on the "
               "article's drill (no bolt part) with sharp horn corners at horn 67.1 mm / coupler 49.9 mm against the best estimates "
               "of the converged values (docs: theory/piezo-elastic): f_r +0.029 %, f_a +0.025 %, first torsion "
               "+0.073 % (+-0.02 %), first bending pair +0.083 %; without slots and teeth against the converged "
               "(r, z) model: {plain}")
"""The discretisation error of the command line's sector meshes (``{n}``: sectors)."""

CYCLIC_PLAIN = "f_r +0.019 %, f_a +0.022 %, torsion +0.023 %, bending +0.075 %"
"""Measured errors of the same rules on the article's drill (no bolt part) without slots and teeth."""

RULE_ERRORS = {"f_r": 2.9e-4, "f_a": 2.5e-4}
"""Relative discretisation error of the working mode under the command line's rules (``--refine
1``, order 2, the design of :data:`RULE_DESIGN_FILLET` and :data:`RULE_DESIGN_LENGTHS`): the
JSON's ``f_r_hz_error`` / ``f_a_hz_error`` of the working mode on that design only."""

RULE_DESIGN_FILLET = 0.0
"""Horn fillet radius (m) of the design :data:`RULE_ERRORS` was measured on: the sharp-cornered
article's drill (no bolt part; the converged references of that measurement, a coupler refinement study and the (r, z)
model of the design without slots, were computed for it)."""

RULE_DESIGN_LENGTHS = {"horn.length": 0.0671, "coupler.length": 0.0499}
"""Horn and coupler lengths (m) of the design :data:`RULE_ERRORS` was measured on; any other
lengths get the two-level estimate (an error is never borrowed from another design)."""


def _eligible(design) -> bool:
    from .sector_system import sweepable

    return sweepable(design)


def sectors_for(args, design) -> int | None:
    """The number of sectors ``--sectors`` gives for ``design`` (None: the whole drill).

    ``auto``: the coupler's symmetry order (6 for a body of revolution) when the run is a plain
    modal analysis of a design that can be swept as a sector, else the whole drill; ``off``: the
    whole drill; ``N``: N sectors (refused where they cannot be used). ``--error`` and
    ``--converge`` run on the sectors too (the ``k = 0`` sector of the working mode).
    """
    from geometry.options import mesher_of
    from geometry.sector import check_sectors, symmetry_order

    value = str(getattr(args, "sectors", "off"))
    if value == "off":
        return None
    clash = ["--match"] if args.match else []
    if value == "auto":
        if clash or args.mesher == "free" or args.order != 2 or not _eligible(design):
            return None
        _check_refine(args)
        return symmetry_order(design) or 6
    try:
        n = int(value)
    except ValueError:
        raise ParameterError("--sectors", value, "must be auto, off or an integer") from None
    if clash:
        raise ParameterError("--sectors", value, f"cannot be combined with {clash[0]} (use --sectors off)")
    n = check_sectors(design, n)
    if mesher_of(args, design) == "revolve":
        if not _eligible(design):
            raise ParameterError("--sectors", value, "needs a design that can be swept as a sector (stepped or "
                                 "conical horn, coupler and stack face to face, bored); use --mesher free")
        if args.order != 2:
            raise ParameterError("--order", args.order, "must be 2 for a swept sector (or use --mesher free)")
        _check_refine(args)
    return n


def _check_refine(args) -> None:
    """``--refine`` such that every sector rule's refine stays in the builder's range."""
    from geometry.sector import AXIAL_RULE, LATERAL_RULE
    from geometry.sizing import REFINE_RANGE

    low = REFINE_RANGE[0] / min(AXIAL_RULE[0], LATERAL_RULE[0])
    if args.refine < low:
        raise ParameterError("--refine", args.refine, f"must be >= {low:g} with sectors (the k = 0 rule refines "
                             f"{AXIAL_RULE[0]:g} x further); use --sectors off for finer whole-drill meshes")


def parse_harmonics(text: str | None, sectors: int) -> tuple[int, ...]:
    """``"0,1"`` or ``"all"`` (0 .. N/2) as sorted harmonics, or a ParameterError (None:
    :data:`HARMONICS`)."""
    from .cyclic import harmonics

    text = HARMONICS if text is None else text
    if text == "all":
        return harmonics(sectors)
    try:
        ks = sorted({int(v) for v in text.split(",")})
    except ValueError:
        raise ParameterError("--harmonics", text, "must be 'all' or integers like 0,1") from None
    if not ks or ks[0] < 0 or ks[-1] > sectors // 2:
        raise ParameterError("--harmonics", text, f"must lie in [0, {sectors // 2}] for {sectors} sectors")
    return tuple(ks)


def _meshes(args, design, sectors, ks, single: bool, built=None, pool=None):
    """``{k: (system, mesh, rule)}``: one assembled sector per mesh rule the harmonics need, the
    rule of the highest harmonic first (its solve is the longest); ``built(harmonics, system)``
    is called as each is assembled. With a ``pool`` (an executor) each mesh is assembled there
    (``built`` then called from there) while Gmsh (one at a time) makes the next mesh; the lines
    are printed here, in order."""
    import geometry
    from geometry.options import mesher_of
    from geometry.sector import AXIAL_RULE, LATERAL_RULE

    from .assembly import assemble

    swept = mesher_of(args, design) == "revolve"
    rules = {}
    for k in ks:
        if not swept:
            rules[k] = (args.refine, None)
        else:
            refine, meshing = AXIAL_RULE if (k == 0 or single) else LATERAL_RULE
            rules[k] = (refine * args.refine, meshing.scaled(args.refine))

    def assembled(mesh, rule):
        system = assemble(mesh, order=args.order)
        t1 = time.perf_counter()
        if built is not None:
            built([k for k in ks if rules[k] == rule], system)
        return system, t1

    def finish(rule, mesh, t0, job):
        system, t1 = job.result() if pool is not None else job
        users = ", ".join(str(k) for k in ks if rules[k] == rule)
        print(f"sector mesh for k = {users}: {_describe(rule)}, {system.ndof} DOFs, {t1 - t0:.1f} s", flush=True)
        done[rule] = (system, mesh)

    done, last = {}, None
    for rule in dict.fromkeys(rules[k] for k in sorted(ks, reverse=True)):
        kw = {"refine": rule[0], "grade": args.grade, "mesher": "revolve" if swept else "free", "sectors": sectors}
        if swept:
            kw["sector_meshing"] = rule[1]
        t0 = time.perf_counter()
        mesh = geometry.build_mesh(design, mesh_size=args.mesh_size, order=args.order, **kw)
        for name in args.clamp:
            mesh.facets(name)
        job = pool.submit(assembled, mesh, rule) if pool is not None else assembled(mesh, rule)
        if last is not None:
            finish(*last)           # the previous mesh's assembly, done beside this meshing
        last = (rule, mesh, t0, job)
    finish(*last)
    return {k: (*done[rules[k]], rules[k]) for k in ks}


def _describe(rule) -> str:
    refine, m = rule
    if m is None:
        return f"free, refine {refine:g}"
    return (f"swept parts at refine {refine:g}, layers <= {m.layer_deg:g} deg, coupler x{m.coupler_refine:g}"
            + (f", slot zone x{m.slot_refine:g}" if m.slot_refine != 1.0 else "")
            + (f", notch edges graded to {m.notch_fraction:g} of the slot zone's size" if m.notch_fraction else "")
            + (" (" + ", ".join(f"{k} {v:g}" for k, v in m.notch_classes.items()) + ")"
               if m.notch_fraction and m.notch_classes else "")
            + (f", outer junctions graded to {m.junction_fraction:g}" if m.junction_fraction else ""))


def own_note(f_a, driven: bool) -> list[str]:
    """The table's footnote on modes without an anti-resonance of their own (a ``-`` in f_a)."""
    if driven and not np.all(np.isfinite(np.asarray(f_a, float))):
        return ["f_a -: no anti-resonance of its own (its open-circuit partner lies below it: the admittance zero "
                "between it and a more strongly coupled mode below, whose anti-resonance passes above it)"]
    return []


def format_rows(rows) -> str:
    """The table of every computed mode (rows: dicts of :func:`run`)."""
    lines = [f"{'#':>3} {'k':>2} {'f_r kHz':>10} {'f_a kHz':>10} {'k_eff':>7}  {'ax/tan/rad':>12}  motion"]
    for i, r in enumerate(rows):
        fa = f"{r['f_a_hz'] / 1e3:10.4f}" if r["f_a_hz"] is not None else f"{'-':>10}"
        ke = f"{r['k_eff']:7.4f}" if r["k_eff"] is not None else f"{'-':>7}"
        sh = "/".join(f"{100 * s:.0f}" for s in r["shares"].values())
        pair = " (pair)" if r["multiplicity"] == 2 else ""
        lines.append(f"{i + 1:3d} {r['harmonic']:2d} {r['f_r_hz'] / 1e3:10.4f} {fa} {ke}  {sh:>12}  {r['label']}{pair}")
    return "\n".join(lines)


def run(args, design, near: float, sectors: int) -> int:
    """Mesh, solve and report (``python -m fem.modal --sectors``); returns the exit code."""
    from geometry.options import mesher_of
    from rpud_common import atomic_write_text, json_text

    from .cyclic import harmonic_labels, harmonic_shares, multiplicity

    ks = parse_harmonics(args.harmonics, sectors)
    n_modes = 12 if args.modes is None else args.modes
    backend = None if args.solver in (None, "auto") else args.solver
    t0 = time.perf_counter()
    checked = (mesher_of(args, design) == "revolve" and args.refine == 1 and args.mesh_size is None
               and args.order == 2 and not args.clamp and not (args.render or args.vtu) and not args.grade
               and _default_geometry(design))
    estimated = args.error or (not checked and not args.clamp and mesher_of(args, design) == "revolve")
    meshes, (results, chosen), coarse = _solved(args, design, sectors, ks, near, n_modes, backend,
                                                estimated and 0 in ks)
    shares = {k: harmonic_shares(meshes[k][0], results[k].vectors) for k in ks}
    labels = {k: harmonic_labels(shares[k], k) for k in ks}
    rows = []
    for k, j in chosen:
        cm = results[k]
        f_r, f_a = float(cm.f_hz[j]), float(cm.f_open_hz[j])
        driven = k == 0 and meshes[k][0].hot_dof is not None and np.isfinite(f_a)
        k_eff = float(np.sqrt(max(0.0, 1 - (f_r / f_a) ** 2))) if driven else None
        rows.append({"harmonic": k, "f_r_hz": f_r, "f_a_hz": f_a if driven else None, "k_eff": k_eff,
                     "label": labels[k][j], "multiplicity": multiplicity(k, sectors),
                     "shares": {"axial": float(shares[k][j, 0]), "tangential": float(shares[k][j, 1]),
                                "radial": float(shares[k][j, 2])},
                     "_index": j})
    rows.sort(key=lambda r: r["f_r_hz"])
    est = _estimate(args, design, rows, near, meshes, coarse) if coarse is not None else None
    _attach_errors(rows, near, checked, est)
    print(format_rows(rows))
    for line in own_note([np.nan if r["harmonic"] == 0 and r["f_a_hz"] is None else 0.0 for r in rows],
                         meshes[min(ks)][0].hot_dof is not None and 0 in ks):
        print(line)
    ndofs = {k: results[k].ndof for k in ks}
    print(f"{sectors} sectors, harmonics {', '.join(map(str, ks))}: reduced unknowns "
          + ", ".join(f"k={k} {n}" for k, n in ndofs.items()) + f"; {time.perf_counter() - t0:.1f} s")
    how = ("the two-level estimate on the k = 0 sector, refine x 1.4: " + est.method if est is not None
           else "the rule's measured discretisation error on this design, upper side")
    for r in rows:
        if r["f_r_hz_error"] is not None:
            print(f"working mode: f_r {r['f_r_hz']:.1f} +- {r['f_r_hz_error']:.2g} Hz, f_a {r['f_a_hz']:.1f} +- "
                  f"{r['f_a_hz_error']:.2g} Hz ({how})")
    swept = mesher_of(args, design) == "revolve"
    if swept:
        note = CYCLIC_NOTE.format(n=sectors, plain=CYCLIC_PLAIN)
        print(note + ("" if checked else " (this run departs from that check: the sharp-cornered article drill at --refine 1, "
                                        "no --mesh-size, --grade, --clamp, --render or --vtu)"))
    else:
        print("mesh: free sector; its working mode is high by ~0.1 % (--grade) to ~0.5 % (ungraded) at the "
              "re-entrant edges (the article's drill); the swept sector (--mesher revolve) is converged")
    text = None
    if args.json:
        text = json_text({
            "design": str(args.design), "sectors": sectors, "harmonics": list(ks), "near_hz": near,
            "modes": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows],
            "reduced_unknowns": {str(k): n for k, n in ndofs.items()},
            "meshes": {str(k): {"ndof_sector": int(meshes[k][0].ndof), "rule": _describe(meshes[k][2])} for k in ks},
            "mesher": "revolve" if swept else "free", "mesh_size": args.mesh_size, "refine": args.refine,
            "clamp": list(args.clamp), "timings": {str(k): results[k].timings for k in ks},
            "mesh": "; ".join(f"k = {k}: {_describe(meshes[k][2])}" for k in ks),
            "discretisation_error": ({"method": "measured rule error (this design)", "note": CYCLIC_NOTE.format(
                n=sectors, plain=CYCLIC_PLAIN), **({"errors": RULE_ERRORS} if checked else {})}
                if est is None else est.to_dict()),
        }, nonfinite="null")
    if args.render or args.vtu:
        _pictures(args, meshes, results, rows, sectors, near)
    if text is not None:
        atomic_write_text(args.json, text)
    return 0


def _working_row(rows, near: float):
    """The working mode's row: the longitudinal k = 0 mode nearest the target (None: none)."""
    axial = [r for r in rows if r["harmonic"] == 0 and r["label"].startswith("longitudinal")]
    return min(axial, key=lambda r: abs(r["f_r_hz"] - near)) if axial else None


def _solved(args, design, sectors, ks, near, n_modes, backend, estimate: bool):
    """``(meshes, (results, chosen), coarse)``: the sector meshes (:func:`_meshes`), the modes
    nearest ``near`` (:func:`fem.cyclic.nearest_modes`) and, with ``estimate``, the two-level
    estimate's coarse level (else None).

    Each mesh is assembled in a worker thread while this thread has Gmsh make the next one (Gmsh
    is started from here), and each harmonic's first solve starts there as soon as its mesh is
    assembled, while this thread goes on to the coarse level: on two cores the assemblies and
    solves fill the core that meshing leaves idle. OpenBLAS and MKL (PARDISO) stay on
    one thread across all of them (three jobs on two cores: more threads only compete), so every
    run gets the same numbers."""
    from concurrent.futures import ThreadPoolExecutor

    from .cyclic import cyclic_modes, first_ask, nearest_modes
    from .solvers import backend_name, blas_threads

    kw = {"clamp": args.clamp, "backend": backend}
    ask = first_ask(ks, n_modes)
    backend_name(backend)                   # loads MKL (PARDISO), so that its threads can be limited
    with blas_threads(1, mkl=True), ThreadPoolExecutor(max_workers=len(ks), thread_name_prefix="harmonic") as pool:
        futures = {}

        def start(users, system):
            for k in users:
                futures[k] = pool.submit(_one_thread, cyclic_modes, system, sectors, k, near, ask[k], **kw)

        meshes = _meshes(args, design, sectors, ks, single=bool(args.render or args.vtu), built=start, pool=pool)
        coarse = _coarse(args, design, near) if estimate else None
        first = {k: f.result() for k, f in futures.items()}
    return meshes, nearest_modes({k: meshes[k][0] for k in ks}, sectors, near, n_modes, first=first, **kw), coarse


def _one_thread(fn, *args, **kw):
    """``fn(*args, **kw)`` with OpenBLAS and MKL on one thread (MKL's limit holds for the thread
    that sets it: each worker sets its own)."""
    from .solvers import blas_threads

    with blas_threads(1, mkl=True):
        return fn(*args, **kw)


def _estimate_options(args, near) -> dict:
    """The options of the two-level estimate on the ``k = 0`` sector (``--refine`` x 1.4): the same
    for its coarse level and for the estimate made from it."""
    return {"refine": args.refine, "mesh_size": args.mesh_size, "grade": args.grade, "near_hz": near,
            "harmonic": False, "n_modes": 8, "path": "sector"}


def _coarse(args, design, near):
    """The coarse level of the two-level estimate (:func:`fem.errors.coarse_level`)."""
    from .errors import coarse_level

    return coarse_level(design, **_estimate_options(args, near))


def _estimate(args, design, rows, near, meshes, coarse):
    """The two-level estimate (:func:`fem.errors.estimate`) of the working mode on the ``k = 0``
    sector from its ``coarse`` level (None without a working mode)."""
    from .errors import estimate

    work = _working_row(rows, near)
    if work is None or 0 not in meshes:
        return None
    values = {"f_r_hz": work["f_r_hz"], "f_a_hz": work["f_a_hz"], "k_eff": work["k_eff"]}
    values = {k: v for k, v in values.items() if v is not None}
    return estimate(design, values, meshes[0][0].ndof, coarse=coarse, **_estimate_options(args, near))


def _attach_errors(rows, near: float, checked: bool, est=None) -> None:
    """``f_r_hz_error`` / ``f_a_hz_error`` / ``k_eff_error`` (the fem.errors convention) of the
    working mode: the two-level estimate ``est`` when given, else the checked rule's error
    measured on this design (:data:`RULE_ERRORS`); None for the other modes."""
    work = _working_row(rows, near)
    for r in rows:
        r["f_r_hz_error"] = r["f_a_hz_error"] = r["k_eff_error"] = None
        if r is not work:
            continue
        if est is not None:
            r["f_r_hz_error"] = est.error("f_r_hz")
            r["f_a_hz_error"] = est.error("f_a_hz") if r["f_a_hz"] is not None else None
            r["k_eff_error"] = est.error("k_eff") if r["k_eff"] is not None else None
        elif checked:
            r["f_r_hz_error"] = RULE_ERRORS["f_r"] * r["f_r_hz"]
            r["f_a_hz_error"] = RULE_ERRORS["f_a"] * r["f_a_hz"] if r["f_a_hz"] is not None else None


def _default_geometry(design) -> bool:
    """The design meshes as the one the rule's error was measured on (the article's drill,
    :func:`geometry.examples.article_design`, with sharp horn corners at the lengths of the measurement, :data:`RULE_DESIGN_FILLET`,
    :data:`RULE_DESIGN_LENGTHS`): same parts, bore and mesh-size inputs,
    whatever its name. Any other design, the filleted one and the default drill included, gets the two-level
    estimate instead."""
    from geometry.design_rpud import filleted
    from geometry.examples import article_design

    ref = filleted(article_design().replace(RULE_DESIGN_LENGTHS), RULE_DESIGN_FILLET)
    return all(getattr(design, f, None) == getattr(ref, f) for f in
               ("coupler", "stack", "flange", "horn", "bore_diameter", "target_frequency", "elements_per_wavelength"))


def _pictures(args, meshes, results, rows, sectors, near) -> None:
    """--render / --vtu: the whole drill replicated from the (single) sector mesh, every listed
    mode expanded onto it (a pair as its real member)."""
    from geometry.sector import replicate

    from .cyclic import expand
    from .modeshape import p2_nodes
    from .render import around, render_modes, write_modes_vtu

    system, mesh, _rule = meshes[rows[0]["harmonic"]]
    whole, _ = replicate(mesh, sectors)
    nodes = p2_nodes(whole)
    shapes = np.stack([np.real(expand(system, results[r["harmonic"]].vectors[:, [r["_index"]]], r["harmonic"],
                                      sectors, nodes)[0]) for r in rows])
    freqs = [r["f_r_hz"] for r in rows]
    labels = [f"{r['label']} (k={r['harmonic']})" for r in rows]
    if args.render:
        axial = [i for i, r in enumerate(rows) if r["harmonic"] == 0 and r["label"].startswith("longitudinal")]
        working = min(axial, key=lambda i: abs(rows[i]["f_r_hz"] - near)) if axial else 0
        paths = render_modes(whole, shapes, args.render, modes=around(working, len(rows), 2), frequencies=freqs,
                             labels=labels)
        print(f"renders: {', '.join(str(p) for p in paths)}")
    if args.vtu:
        print(f"modes: {write_modes_vtu(whole, shapes, args.vtu, frequencies=freqs)}")
