"""rpud.fem: coupled piezo-elastic finite elements on scikit-fem.

Modules: ``fem.materials`` (constitutive matrices, poling rotation), ``fem.assembly``
(``assemble(mesh) -> PiezoSystem``: K, M, K_loss, DOF layout, boundary conditions),
``fem.solvers`` (``factorize``: PARDISO or SuperLU), ``fem.modal`` (``modal_analysis``,
CLI ``python -m fem.modal``). Importing ``fem`` imports none of them (no scikit-fem load).
"""

__all__ = ["assemble", "modal_analysis", "factorize"]


def __getattr__(name):
    if name == "assemble":
        from .assembly import assemble
        return assemble
    if name == "modal_analysis":
        from .modal import modal_analysis
        return modal_analysis
    if name == "factorize":
        from .solvers import factorize
        return factorize
    raise AttributeError(name)
