"""Facet bases on curved (isoparametric P2) tetrahedra that also work on the swept mesh.

A scikit-fem ``FacetBasis`` finds the reference coordinates of its facet quadrature points in the
neighbouring element by Newton's method (``MappingIsoparametric.invF``). That iteration starts at
(0.5, 0.5, 0.5), which lies outside the reference tetrahedron, and clips every step to the unit
cube; on the swept mesh's long curved elements (30-degree arcs at the flange's rim) it stalls
and raises "Newton iteration didn't converge". Started at the centroid and left unclipped it
converges in about five steps (the exact inverse of a valid element is inside it).
"""

from __future__ import annotations

import numpy as np
from skfem import FacetBasis
from skfem.mapping import MappingIsoparametric

__all__ = ["facet_basis", "CentroidNewtonMapping"]


class CentroidNewtonMapping(MappingIsoparametric):
    """``MappingIsoparametric`` whose inverse starts at the reference centroid, unclipped."""

    def invF(self, x, tind=None, newton_max_iters=50, newton_tol=1e-12, floor_tol=1e-9):
        """Reference coordinates of the points ``x``: Newton from the centroid until every step is
        below ``newton_tol``, or until the steps, all below ``floor_tol``, stop shrinking (the
        roundoff floor of the map, which on small curved elements lies near 1e-12)."""
        X = np.full(x.shape, 1.0 / (x.shape[0] + 1))
        last = np.inf
        for _ in range(newton_max_iters):
            dX = np.einsum("ijkl,jkl->ikl", self.invDF(X, tind), x - self.F(X, tind))
            X = X + dX
            step = np.linalg.norm(dX, 1, (0, 2))
            if (step < newton_tol).all() or (step.max() < floor_tol and step.max() >= last):
                return X
            last = step.max()
        raise ArithmeticError(f"inverse isoparametric map: no convergence to {newton_tol:g} in "
                              f"{newton_max_iters} Newton steps (a folded element?)")


def facet_basis(skmesh, elem, facets, **kwargs) -> FacetBasis:
    """``skfem.FacetBasis(skmesh, elem, facets=facets, **kwargs)``, with
    :class:`CentroidNewtonMapping` on a curved mesh (an affine mesh keeps its own mapping)."""
    mapping = skmesh.mapping()
    if isinstance(mapping, MappingIsoparametric):
        mapping = CentroidNewtonMapping(mapping.mesh, mapping.elem, mapping.bndelem)
    return FacetBasis(skmesh, elem, facets=facets, mapping=mapping, **kwargs)
