"""rpud.results: the end-to-end run, geometry -> modes -> A0 -> impacts -> kinetic energy.

Public API (loaded on first use)::

    import geometry, results
    res = results.run_pipeline(geometry.default_design(), results.PipelineSettings(), "out/")
    res                      # PipelineResult(out: f_r ..., A0 ..., tool KE ... ± ... mJ (95 % CI))
    res.summary              # everything summary.json holds

``python -m results`` is the command line (whole-or-nothing results folder, progress, checks).
"""

from rpud_common.lazy import exports

_WHERE = {"run_pipeline": "pipeline", "PipelineSettings": "pipeline", "PipelineResult": "pipeline",
          "plot_kinetic_energy": "figures:kinetic_energy", "plot_a0_coupling": "figures:a0_coupling",
          "plot_impact_history": "figures:impact_history"}
__all__ = list(_WHERE)
__getattr__, __dir__ = exports(__name__, _WHERE)
