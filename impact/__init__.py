"""rpud.impact: the free-mass collision model of the RPUD percussive system (article section 3).

Public API (loaded on first use, so ``import impact`` stays light)::

    from impact import ImpactParams, simulate, ensemble_statistics, sweep

    p = ImpactParams(m_free=0.008)                 # Table 1 + calibrated defaults, SI units
    r = simulate(p)                                # one trajectory: one sample of a chaotic motion
    st = ensemble_statistics(p, "device")          # means with 95 % confidence intervals
    sw = sweep(p, [0.002, 0.004, 0.008], scenario="article")   # tool KE against free mass

See :mod:`impact.model` (the model and its corrections to the article), :mod:`impact.stats`
(ensembles, confidence intervals, scenarios) and :mod:`impact.sweeps`; :mod:`impact.coupled`
runs the model with a modal horn (:class:`impact.horn.ModalHorn`, e.g. the FE transducer reduced
by ``fem.reduced``) in place of the kinematic tip; :mod:`impact.drilling` presses the drill on
rock with a weight on bit (elastic tool rod :mod:`impact.rod`, bit-rock law :mod:`impact.rock`).
"""

from rpud_common.lazy import exports

_WHERE = {"ImpactParams": "params", "simulate": "model", "ImpactResult": "model", "SimulationError": "model",
          "ensemble_statistics": "stats", "EnsembleStats": "stats", "Estimate": "stats", "Scenario": "stats",
          "SCENARIOS": "stats", "StatsSettings": "stats", "sweep": "sweeps", "SweepResult": "sweeps",
          "reproduce": "article", "plot_history": "plots", "plot_spectrum": "plots", "plot_ke_vs_mass": "plots",
          "plot_tool_ke_history": "plots", "ModalHorn": "horn", "simulate_coupled": "coupled",
          "CoupledResult": "coupled", "coupled_batch": "coupled", "HuntCrossley": "contact",
          "HertzLaw": "hertz", "ContactGeometry": "hertz", "ModalBody": "compliant", "strike": "compliant",
          "simulate_compliant": "compliant_loop",
          "DrillParams": "drilling", "DrillSettings": "drilling", "drilling_sweep": "drilling",
          "drilling_statistics": "drilling", "RockLaw": "rock", "ToolRod": "rod",
          "plot_depth_vs_mass": "drilling_plots"}
__all__ = list(_WHERE)
__getattr__, __dir__ = exports(__name__, _WHERE)
