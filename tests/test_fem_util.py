"""Mesh builders for the fem tests (no tests here): slender rods and bars as TaggedMesh.

A circular rod is a tensor-product box mapped onto a disk (elliptical square-to-disk map),
with curved 10-node geometry (every P2 node mapped exactly), so no faceting error.
"""

import numpy as np
from skfem import Basis, ElementTetP2, MeshTet, MeshTet2

from geometry.mesh import Electrode, Region, TaggedMesh


def _disk_map(radius):
    """Map the square [-1, 1]^2 cross-section onto a disk of ``radius`` (z unchanged)."""

    def mapping(p):
        x, y = p[:, 0], p[:, 1]
        out = p.copy()
        out[:, 0] = radius * x * np.sqrt(1 - y * y / 2)
        out[:, 1] = radius * y * np.sqrt(1 - x * x / 2)
        return out

    return mapping


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

    mapping = _disk_map(radius)

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


def sandwich(radius=0.015, back=0.02, ring=0.005, n_rings=4, front=0.045, n_r=2, dz=0.005,
             back_material="steel_45", ceramic="PZT-8", front_material="al7075"):
    """A Langevin sandwich: steel back mass, ``n_rings`` PZT discs poled alternately +z/-z,
    aluminium front mass; solid circular section (no bolt). Electrodes on every ceramic
    interface: ground at the outer faces and every second interface, hot in between (internal
    facet sets ``electrode_k``, k = 0..n_rings). Axial element size about ``dz`` (at least two
    layers per ring); ``n_r`` sets the cross-section (2 n_r x 2 n_r squares mapped to a disk).
    """
    z_levels = [0.0, back] + [back + ring * (k + 1) for k in range(n_rings)] + [back + n_rings * ring + front]
    zs = [np.array([0.0])]
    for a, b in zip(z_levels[:-1], z_levels[1:]):
        n = max(2 if (a >= back and b <= back + n_rings * ring + 1e-12) else 1, int(round((b - a) / dz)))
        zs.append(np.linspace(a, b, n + 1)[1:])
    z = np.concatenate(zs)
    s = np.linspace(-1, 1, 2 * n_r + 1)
    m = MeshTet.init_tensor(s, s, z)
    zc = m.p[2, m.t].mean(axis=0)
    regions = [Region("back", "back", back_material), Region("front", "front", front_material)]
    cell_region = np.where(zc < back, 0, 1)
    for k in range(n_rings):
        lo, hi = back + k * ring, back + (k + 1) * ring
        regions.append(Region(f"ring_{k + 1}", "stack", ceramic, (0.0, 0.0, 1.0 if k % 2 == 0 else -1.0)))
        cell_region[(zc > lo) & (zc < hi)] = 2 + k
    sets = {"back_face": lambda p: np.isclose(p[2], 0), "tip": lambda p: np.isclose(p[2], z_levels[-1])}

    mapping = _disk_map(radius)

    tm = _to_tagged(m, mapping, tuple(regions), cell_region, sets, ())
    # internal electrode facets at the ceramic interfaces
    facet_sets = dict(tm.facet_sets)
    electrodes = []
    fz = m.p[2, m.facets]
    for k in range(n_rings + 1):
        zk = back + k * ring
        facet_sets[f"electrode_{k}"] = m.facets[:, np.all(np.isclose(fz, zk), axis=0)].T
        electrodes.append(Electrode(f"electrode_{k}", "ground" if k % 2 == 0 else "hot"))
    return tm.replace(facet_sets=facet_sets, electrodes=tuple(electrodes))


def bent_bimorph(length=0.04, width=0.004, thickness=0.002, n=(8, 2, 2)):
    """A bar whose first half (x < length/2) is poled PZT-4 and whose second half is steel bent
    upwards (z += 2 (x - length/2)^2 / length): straight and curved 10-node cells, two
    materials with different Q_m; electrodes on the top (hot) and bottom (ground) faces."""
    m = MeshTet.init_tensor(np.linspace(0, length, n[0] + 1), np.linspace(0, width, n[1] + 1),
                            np.linspace(0, thickness, n[2] + 1))
    sets = {"bottom": lambda p: np.isclose(p[2], 0), "top": lambda p: np.isclose(p[2], thickness)}
    regions = (Region("ceramic", "stack", "PZT-4", (0.0, 0.0, 1.0)), Region("metal", "horn", "steel_45", None))
    cell_region = (m.p[0, m.t].mean(axis=0) > length / 2).astype(int)

    def bend(p):
        out = p.copy()
        out[:, 2] += 2 * np.maximum(p[:, 0] - length / 2, 0) ** 2 / length
        return out

    el = (Electrode("top", "hot"), Electrode("bottom", "ground"))
    return _to_tagged(m, bend, regions, cell_region, sets, el)

