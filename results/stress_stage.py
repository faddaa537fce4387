"""The pipeline's stress stage: the utilisation table at the drive voltage, a picture, a VTU.

The state is the harmonic working point of the pipeline (drive voltage, working frequency,
the assembled-transducer quality factor, no free-mass load: the unloaded tip amplitude, the
larger one), with the design's bolt preload (its static stress added; a design without a bolt
runs without one): :func:`results.operating_point.preload_stage` solves it and reports the
preload window of every ring beside the table.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

log = logging.getLogger(__name__)

__all__ = ["stress_stage", "coarse_hook", "report_lines", "FIXES"]


FIXES = {"principal_min": "a local peak of the bolt's static compression plus the dynamic one: a lower "
                          "stack.bolt_prestress (toward the window's lower end) or a lower drive relieves it",
         "principal_max": "tension in the ceramic: a higher stack.bolt_prestress (within the window) or a lower "
                          "drive relieves it",
         "efield": "the AC field approaches the depoling field: a lower drive voltage relieves it",
         "von_mises": "a metal part above its fatigue strength: a lower drive, or a fillet at the peak's corner"}
"""What relieves a utilisation above 100 %, per peak quantity (printed with it)."""


def stress_stage(system, wp, out: Path, *, render: bool = True, say=None, coarse=None, preload=None,
                 mesh: str | None = None, submit=None, state=None) -> dict:
    """Stress peaks of the working point ``wp`` (:class:`fem.harmonic.WorkingPoint`, its
    solution ``wp.x`` on ``system``, the ``k = 0`` sector or the whole drill); writes
    ``renders/stress_von_mises.png`` and ``stress.vtu`` (the whole drill) into ``out`` when
    ``render``. ``coarse``: the discretisation-error estimate (:class:`fem.errors.ErrorEstimate`)
    run with the hook :func:`coarse_hook` of this state: its coarse mesh's table gives every row
    its two-mesh estimate (None: the single-mesh estimate, said in the table's note).
    ``preload``: the bolt's static state (:class:`fem.preload.PreloadState` solved on ``system``),
    added to the dynamic one before the peaks are taken. ``mesh``: the mesh that ran, in words.
    ``submit``: ``submit(write, *args)`` runs the files' drawing and writing elsewhere (a worker
    process; the caller waits for it before the folder is complete), None: here.
    ``state``: :func:`fem.stress_state.working_point_state` of these arguments, computed
    beforehand (beside the estimate), or None: computed here.
    The table is :func:`fem.stress_state.working_point_stress`'s, as ``fem.harmonic --stress``'s.
    Returns the JSON record (``summary.json["stress"]``)."""
    from fem.stress_state import with_estimate, working_point_state

    t0 = time.perf_counter()
    res = with_estimate(working_point_state(system, wp, preload, mesh) if state is None else state, coarse)
    table = res.table
    files = {"png": None, "vtu": None}
    if render:
        paths = {"png": Path(out) / "renders" / "stress_von_mises.png", "vtu": Path(out) / "stress.vtu"}
        write, args = res.file_job(paths["png"], paths["vtu"], f"{wp.voltage:g} V at {wp.freq_hz:.1f} Hz")
        if submit is not None:
            submit(write, *args)
        else:
            paths = write(*args)
        files = {k: str(Path(v).relative_to(out)) for k, v in paths.items()}
    w = table.worst()
    if say is not None and w is not None:
        say(f"      stress: highest utilisation {100 * w.utilisation:.0f} % ({w.region}, {w.quantity}, "
            f"{w.headline * 1e-6:.1f} ± {w.error_estimate * 1e-6:.2g} {'MPa' if w.quantity != 'efield' else 'kV/mm'}"
            f"{', off a singular edge' if w.singular else ''})"
            + (f"; {FIXES[w.quantity]}" if w.utilisation > 1 and w.quantity in FIXES else ""))
    return {"utilisation": table.to_dict(), "markdown": table.markdown(), "files": files, "mesh": res.mesh,
            "state": "harmonic working point at the drive voltage, unloaded tip, " + (
                f"bolt preload {res.preload_n * 1e-3:.1f} kN on the stack" if res.static is not None
                else "no bolt preload"),
            "seconds": time.perf_counter() - t0}


def coarse_hook(voltage: float, preload=None):
    """The ``extra`` hook of the discretisation-error stage that gives :func:`stress_stage` its
    coarse table: the working point at ``voltage`` (V) with the bolt's ``preload``
    (:class:`fem.preload.PreloadState` or None) on the coarse mesh (:class:`fem.stress_converged.CoarseTable`)."""
    from fem.stress_converged import CoarseTable

    force = preload.force_n if preload is not None else 0.0
    return CoarseTable(float(voltage), float(force))


def report_lines(stress: dict | None) -> list[str]:
    """The report's section on stress and limits (empty without a stress record)."""
    if not stress:
        return []
    u = stress["utilisation"]
    lines = ["## Stress and limits at the drive voltage", "",
             f"Peaks over one cycle at {u['voltage_v']:g} V and {u['freq_hz'] / 1e3:.3f} kHz ({stress['state']}): "
             "von Mises per metal region against its fatigue strength, the largest tensile and compressive "
             "principal stress and |E| per ceramic ring against the material's ratings (`geometry/materials.toml`, "
             "sources there; n/a: the record gives no limit). Peaks are taken on the recovered field (element "
             "values averaged per region at each node); '± est.' is the two-mesh (Richardson) estimate from the "
             "discretisation-error stage's coarser mesh (without it: the difference to the raw element values around "
             "the peak, a single-mesh indicator; the table's note says which). Peaks on "
             "singular edges (bonded bimaterial edges: the ring bores and rims at the electrode planes and on the "
             "flange; sharp corners and creases: an unfilleted flange/horn edge or horn step, a slot's end or V apex, "
             "a tooth's root) grow with mesh refinement: such a row is marked singular and its utilisation is that of "
             "the peak off the edge. The horn's fillet radii (horn.flange_fillet, horn.step_fillet) make its "
             "shoulders converge.", "",
             stress["markdown"], ""]
    if u.get("note"):
        lines += [f"Errors: {u['note']}.", ""]
    if stress["files"].get("png"):
        lines += [f"![stress]({stress['files']['png']})", ""]
    if stress["files"].get("vtu"):
        lines += [f"Node fields (von Mises, principal, |E| peaks) for ParaView: `{stress['files']['vtu']}` "
                  "(not committed).", ""]
    return lines
