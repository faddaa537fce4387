"""Facet bases on curved P2 tetrahedra (fem.facets) against scikit-fem's own inverse mapping.

References: the forward isoparametric map (its inverse must reproduce the facet quadrature
points), and scikit-fem's Newton inverse wherever that one converges (same coordinates).
"""

import numpy as np
import pytest
from skfem import ElementTetP2
from skfem.quadrature import get_quadrature

from geometry import build_mesh
from geometry.examples import article_design
from fem.facets import CentroidNewtonMapping, facet_basis
from fem.modeshape import mesh_context


@pytest.fixture(scope="module")
def meshes():
    d = article_design()
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



def test_small_curved_elements_far_from_the_origin_are_inverted_to_their_roundoff():
    # curved P2 tetrahedra 1 mm .. 1 um in size, 0.1 m from the origin (the horn tip's small
    # elements): their points carry the rounding of coordinates near 0.17 m, which the inverse
    # map magnifies by 1 / h in reference coordinates, so Newton's steps stall above 1e-12 for
    # h <= 0.1 mm. The inverse must still return: its points must come back to within the
    # rounding of the coordinates (a few units in the last place; 16 allowed) and lie inside
    # the reference tetrahedron
    from skfem import MeshTet, MeshTet2

    base = MeshTet2.from_mesh(MeshTet().refined(1))
    q, _ = get_quadrature(base.brefdom, 4)
    for h in (1e-3, 1e-4, 1e-5, 1e-6):
        p = 0.1 + h * (base.doflocs + 0.05 * np.sin(3 * base.doflocs[[1, 2, 0]]))
        mesh = MeshTet2(p, base.t)
        facets = mesh.boundary_facets()
        mp = mesh.mapping()
        x, tind = mp.G(q, find=facets), mesh.f2t[0, facets]
        ours = CentroidNewtonMapping(mp.mesh, mp.elem, mp.bndelem)
        X = ours.invF(x, tind=tind)
        assert np.abs(ours.F(X, tind) - x).max() <= 16 * np.finfo(float).eps * np.abs(x).max(), h
        assert X.min() > -1e-9 and X.sum(axis=0).max() < 1 + 1e-9, h
