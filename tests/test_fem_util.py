"""Mesh builders for the fem tests (no tests here): slender rods and bars as TaggedMesh.

A circular rod is a tensor-product box mapped onto a disk (elliptical square-to-disk map),
with curved 10-node geometry (every P2 node mapped exactly), so no faceting error.
"""

import numpy as np
from skfem import Basis, ElementTetP2, MeshTet, MeshTet2

from geometry.mesh import Electrode, Region, TaggedMesh


def _to_tagged(m, mapping, regions, cell_region, sets, electrodes, curved=True):
    f = m.facets[:, m.boundary_facets()].T
    facet_sets = {}
    for name, pred in sets.items():
        sel = np.all(pred(m.p[:, f]), axis=1)
        facet_sets[name] = f[sel]
    if curved:
        m2 = MeshTet2.from_mesh(m)
        basis = Basis(m2, ElementTetP2())
        points, cells = basis.doflocs.T.copy(), basis.element_dofs.T
    else:
        points, cells = m.p.T.copy(), m.t.T
    points = mapping(points)
    return TaggedMesh(points, cells, cell_region, regions, facet_sets, electrodes)


def rod(length=0.1, radius=0.0025, n_r=2, n_z=40, material="steel_45", poling=None,
        electrodes=False, curved=True):
    """Circular rod along z, z in [0, length]; facet sets ``bottom``/``top`` (ends), ``side``.

    With ``electrodes``: ``top`` is hot, ``bottom`` ground (a k33 rod if poled along z)."""
    s = np.linspace(-1, 1, 2 * n_r + 1)
    m = MeshTet.init_tensor(s, s, np.linspace(0, length, n_z + 1))

    def mapping(p):
        x, y = p[:, 0], p[:, 1]
        out = p.copy()
        out[:, 0] = radius * x * np.sqrt(1 - y * y / 2)
        out[:, 1] = radius * y * np.sqrt(1 - x * x / 2)
        return out

    sets = {"bottom": lambda p: np.isclose(p[2], 0), "top": lambda p: np.isclose(p[2], length),
            "side": lambda p: np.isclose(np.maximum(abs(p[0]), abs(p[1])), 1)}
    regions = (Region("rod", "rod", material, poling),)
    el = (Electrode("top", "hot"), Electrode("bottom", "ground")) if electrodes else ()
    return _to_tagged(m, mapping, regions, np.zeros(m.t.shape[1], dtype=int), sets, el, curved)


def bar(length=0.04, width=0.004, thickness=0.001, n=(40, 4, 2), material="PZT-4",
        poling=(0.0, 0.0, 1.0), electrodes=True):
    """Rectangular bar, length along x, thickness along z; electrodes on the large faces
    ``top`` (z = thickness, hot) and ``bottom`` (z = 0, ground): a k31 bar."""
    m = MeshTet.init_tensor(np.linspace(0, length, n[0] + 1), np.linspace(0, width, n[1] + 1),
                            np.linspace(0, thickness, n[2] + 1))
    sets = {"bottom": lambda p: np.isclose(p[2], 0), "top": lambda p: np.isclose(p[2], thickness),
            "end": lambda p: np.isclose(p[0], 0)}
    regions = (Region("bar", "bar", material, poling),)
    el = (Electrode("top", "hot"), Electrode("bottom", "ground")) if electrodes else ()
    return _to_tagged(m, lambda p: p, regions, np.zeros(m.t.shape[1], dtype=int), sets, el, curved=False)
