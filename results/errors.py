"""The pipeline's discretisation-error stage and where its numbers go in ``summary.json``.

:func:`estimate_stage` runs :func:`fem.errors.estimate` on the tuned design: one solve on a mesh
1.4x coarser than the pipeline's (modal, 4 modes, and the harmonic working point at the coarse
mesh's own f_r with the pipeline's losses, on those modes + residual as the fine one). :func:`annotate_summary`
puts the errors beside the values (``X`` -> ``X_error``, same units; :mod:`fem.errors`):

- ``working_mode``: ``f_r_hz``, ``f_a_hz``, ``k_eff``; ``matching``: ``matched_hz``;
- ``harmonic``: ``tip_per_volt_m``, ``teeth_ellipse_ratio``, ``teeth_phase_deg`` (estimated; the teeth's from
  their finer mesh's estimate where it ran, :mod:`results.stage_teeth`), and the amplitudes
  proportional to the tip amplitude per volt (at the voltage, with datasheet losses, after the
  ring-up), which carry its relative error;
- ``A0``: ``per_volt_m``, ``used_m``, ``unloaded_m`` and ``per_mass_error``; each row of
  ``kinetic_energy_table``: ``A0_fe_m``. The impact load changes A0 through the impact model,
  not the mesh: the FE part of its error is the tip amplitude's relative error;
- ``discretisation_error``: the method block (:meth:`fem.errors.ErrorEstimate.to_dict`), or
  None with ``discretisation_error_note`` when no estimate was made (``--refine`` above 3.57:
  the coarse mesh would exceed the refine range).

The impact stage never sees these numbers: they change no result, only state its precision.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)

__all__ = ["estimate_stage", "annotate_summary", "error_text"]

TIP = "tip_per_volt_m"


def estimate_stage(design, options, settings, system, modal, w: int, wp, surfaces, near_hz: float, say=None,
                   loss=None, extra=None):
    """The two-level estimate of the working mode's outputs (:class:`fem.errors.ErrorEstimate`) on
    the path that ran (``options``: the resolved :class:`results.stage_fe.MeshOptions`), or None
    when ``options.refine`` leaves no room for a coarser mesh. The coarse harmonic response has
    the losses ``loss`` (:class:`fem.harmonic.LossModel`), default those of ``settings``
    (:class:`results.pipeline.PipelineSettings`). ``extra``: more outputs of the coarse working
    point (:func:`fem.errors.estimate`; the stress stage's :func:`results.stress_stage.coarse_hook`)."""
    from fem.errors import ESTIMATOR_RATIO, estimate, harmonic_quantities, plus_minus

    if options.refine * ESTIMATOR_RATIO > 5.0:
        log.warning("no discretisation-error estimate: refine %g x %g exceeds 5", options.refine, ESTIMATOR_RATIO)
        return None
    values = {"f_r_hz": float(modal.f_r_hz[w]), "f_a_hz": float(modal.f_a_hz[w]), "k_eff": float(modal.k_eff[w]),
              **harmonic_quantities(wp)}
    est = estimate(design, values, system.ndof, refine=options.refine, mesh_size=options.mesh_size,
                   grade=options.grade, near_hz=near_hz,
                   loss=settings.losses().loss_model() if loss is None else loss,
                   surfaces=tuple(surfaces), n_modes=4, mesher=options.mesher, path=options.path, extra=extra)
    if say:
        v, e = est.values, est.error
        say(f"      discretisation error ({est.coarse_ndof} DOFs at refine {est.coarse_refine:g}, order {est.order:g}): "
            f"f_r {plus_minus(v['f_r_hz'], e('f_r_hz'), 'Hz')}, f_a {plus_minus(v['f_a_hz'], e('f_a_hz'), 'Hz')}, "
            f"k_eff {plus_minus(v['k_eff'], e('k_eff'))}, tip {plus_minus(v[TIP], e(TIP), 'nm/V', 1e9)}"
            + (f", ellipse {plus_minus(v['teeth_ellipse_ratio'], e('teeth_ellipse_ratio'))}"
               if "teeth_ellipse_ratio" in est.errors else ""))
    return est


def annotate_summary(summary: dict, est, teeth=None) -> dict:
    """Add the ``X_error`` keys and the ``discretisation_error`` block to ``summary`` (in place);
    ``teeth``: the estimate of the teeth motion on its finer mesh (:mod:`results.stage_teeth`),
    which then gives the teeth's errors."""
    from fem.errors import annotate

    annotate(summary["working_mode"], est, {"f_r_hz": "f_r_hz", "f_a_hz": "f_a_hz", "k_eff": "k_eff"})
    if summary.get("matching"):
        m = summary["matching"]
        m["matched_hz_error"] = est.error("f_r_hz") if est is not None else None
    annotate(summary["harmonic"], est, {TIP: TIP, "tip_amplitude_m": TIP, "teeth_ellipse_ratio": "teeth_ellipse_ratio",
                                        "teeth_phase_deg": "teeth_phase_deg", "tip_per_volt_datasheet_losses_m": TIP,
                                        "tip_amplitude_datasheet_losses_m": TIP, "ring_up_steady_m": TIP})
    if teeth is not None:
        annotate(summary["harmonic"], teeth, {"teeth_ellipse_ratio": "teeth_ellipse_ratio",
                                              "teeth_phase_deg": "teeth_phase_deg"})
    a0 = summary["A0"]
    annotate(a0, est, {"per_volt_m": TIP, "used_m": TIP, "unloaded_m": TIP})
    a0["per_mass_error"] = {k: (est.scaled(TIP, v) if est is not None else None) for k, v in a0["per_mass"].items()}
    for row in summary["kinetic_energy_table"]:
        if "A0_fe_m" in row:
            annotate(row, est, {"A0_fe_m": TIP})
    summary["discretisation_error"] = est.to_dict() if est is not None else None
    if est is None:
        summary["discretisation_error_note"] = "not estimated: refine x 1.4 exceeds the refine range (5)"
    return summary


def error_text(value, error, unit: str = "", scale: float = 1.0) -> str:
    """``value ± error`` for the report (:func:`fem.errors.plus_minus`); '-' for a missing value."""
    from fem.errors import plus_minus

    if value is None:
        return "-"
    return plus_minus(value, error, unit, scale)
