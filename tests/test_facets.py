"""Facet bases on curved P2 tetrahedra (fem.facets) against scikit-fem's own inverse mapping.

References: the forward isoparametric map (its inverse must reproduce the facet quadrature
points), and scikit-fem's Newton inverse wherever that one converges (same coordinates).
"""

import numpy as np
import pytest
from skfem import ElementTetP2
from skfem.quadrature import get_quadrature

from geometry import build_mesh, default_design
from fem.facets import CentroidNewtonMapping, facet_basis
from fem.modeshape import mesh_context


@pytest.fixture(scope="module")
def meshes():
    d = default_design()
    return {m: mesh_context(build_mesh(d, refine=2, mesher=m)).sk for m in ("revolve", "free")}


def _points(sk, name):
    facets = sk.boundaries[name]
    X, _ = get_quadrature(sk.brefdom, 4)
    return sk.mapping().G(X, find=facets), sk.f2t[0, facets]


def test_swept_flange_is_inverted_exactly(meshes):
    sk = meshes["revolve"]
    x, tind = _points(sk, "flange")
    # scikit-fem's own inverse stalls here ("Newton iteration didn't converge" with scikit-fem
    # 12.0, the reason fem.facets exists); ours must invert whatever scikit-fem does
    mp = sk.mapping()
    ours = CentroidNewtonMapping(mp.mesh, mp.elem, mp.bndelem)
    X = ours.invF(x, tind=tind)
    assert np.abs(ours.F(X, tind) - x).max() < 1e-12             # m: the points come back
    assert X.min() > -1e-9 and X.sum(axis=0).max() < 1 + 1e-9     # inside the reference tetrahedron
    # the swept flange's area against the free mesh's (two P2 meshes of one surface at refine 2:
    # measured 8.8e-4 apart, the curved facets' geometric error), m^2
    areas = [facet_basis(m, ElementTetP2(), m.boundaries["flange"]).dx.sum() for m in meshes.values()]
    assert areas[0] == pytest.approx(areas[1], rel=2e-3)


def test_same_coordinates_as_scikit_fem_where_it_converges(meshes):
    sk = meshes["free"]
    for name in ("horn_tip", "flange", "teeth_tops"):
        x, tind = _points(sk, name)
        mp = sk.mapping()
        theirs = mp.invF(x, tind=tind)
        ours = CentroidNewtonMapping(mp.mesh, mp.elem, mp.bndelem).invF(x, tind=tind)
        assert np.abs(ours - theirs).max() < 1e-10, name

