"""rpud.fem: coupled piezo-elastic finite elements on scikit-fem.

Modules: ``fem.materials`` (constitutive matrices, poling rotation), ``fem.assembly``
(``assemble(mesh) -> PiezoSystem``: K, M, K_loss, DOF layout, boundary conditions),
``fem.solvers`` (``factorize``: PARDISO or SuperLU), ``fem.modal`` (``modal_analysis``),
``fem.matching`` (``match``), ``fem.harmonic`` (``harmonic_sweep``, ``working_point``),
``fem.transient`` (``ring_up``), ``fem.reduced`` (``reduce_transducer``), ``fem.modeshape`` (shares, labels, MAC, surface motion),
``fem.render``, ``fem.cyclic`` (``cyclic_modes``: the modes of one harmonic from one sector of a
cyclically symmetric drill), ``fem.sector_system`` (``axial_sector``, ``default_system``: the k = 0 sector
system every driven analysis takes in place of the whole drill, the default FE path of a design), ``fem.convergence`` (refinement studies), ``fem.errors`` (the estimated discretisation
error every output states); stress and limits in ``fem.stress`` (recovery, peaks over a cycle),
``fem.stress_table`` (utilisation table, sweep), ``fem.preload`` (static solves, bolt preload),
``fem.stress_output`` (node fields, PNG, VTU); command lines in ``fem.modal_cli`` and ``fem.harmonic_cli``
(``python -m fem.modal``, ``python -m fem.harmonic``). Importing ``fem`` imports none of them
(no scikit-fem load): the names below load on first use.
"""

from rpud_common.lazy import exports

_WHERE = {"assemble": "assembly", "PiezoSystem": "assembly", "factorize": "solvers",
          "modal_analysis": "modal", "ModalResult": "modal", "match": "matching", "MatchSettings": "matching",
          "LossModel": "harmonic", "modal_basis": "harmonic", "harmonic_sweep": "harmonic",
          "working_point": "harmonic", "working_mode": "modal", "HarmonicResult": "harmonic", "WorkingPoint": "harmonic",
          "ModalBasis": "harmonic", "MatchResult": "matching", "ring_up": "transient",
          "TransientResult": "transient", "energy_shares": "modeshape",
          "classify": "modeshape", "mac": "modeshape", "surface_motion": "modeshape",
          "render_mode": "render", "render_modes": "render", "write_modes_vtu": "render",
          "plot_admittance": "plots:admittance", "plot_tip_response": "plots:tip_response",
          "plot_ring_up": "plots:ring_up", "reduce_transducer": "reduced", "ReducedTransducer": "reduced",
          "ErrorEstimate": "errors", "estimate_error": "errors:estimate",
          "StressRecovery": "stress", "utilisation_table": "stress_table:stress_table", "StressTable": "stress_table",
          "stress_sweep": "stress_table", "StressSweep": "stress_table", "preload_solve": "preload",
          "static_solve": "preload", "traction_load": "preload", "render_stress": "stress_output",
          "write_stress_vtu": "stress_output", "stress_node_fields": "stress_output:node_fields",
          "cyclic_modes": "cyclic", "CyclicModes": "cyclic", "SectorSystem": "sector_system",
          "axial_sector": "sector_system", "default_system": "sector_system", "system_label": "sector_system"}
__all__ = list(_WHERE)
__getattr__, __dir__ = exports(__name__, _WHERE)
