"""rpud.fem: coupled piezo-elastic finite elements on scikit-fem.

Modules: ``fem.materials`` (constitutive matrices, poling rotation), ``fem.assembly``
(``assemble(mesh) -> PiezoSystem``: K, M, K_loss, DOF layout, boundary conditions),
``fem.solvers`` (``factorize``: PARDISO or SuperLU), ``fem.modal`` (``modal_analysis``),
``fem.matching`` (``match``), ``fem.harmonic`` (``harmonic_sweep``, ``working_point``),
``fem.transient`` (``ring_up``), ``fem.reduced`` (``reduce_transducer``), ``fem.modeshape`` (shares, labels, MAC, surface motion),
``fem.render``, ``fem.convergence`` (refinement studies), ``fem.errors`` (the estimated discretisation
error every output states); command lines in ``fem.modal_cli`` and ``fem.harmonic_cli``
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
          "ErrorEstimate": "errors", "estimate_error": "errors:estimate"}
__all__ = list(_WHERE)
__getattr__, __dir__ = exports(__name__, _WHERE)
