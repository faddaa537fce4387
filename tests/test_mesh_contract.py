"""TaggedMesh: conversions to scikit-fem and meshio keep regions, facet sets and volumes."""

import meshio
import numpy as np
import pytest
from skfem import Basis, ElementTetP2, MeshTet, MeshTet2

from rpud_common import ParameterError
from geometry.materials import get_material
from geometry.mesh import Electrode, Region, TaggedMesh


def _bar(order=1):
    m = MeshTet.init_tensor(np.linspace(0, 0.01, 4), np.linspace(0, 0.002, 3), np.linspace(0, 0.04, 9))
    if order == 2:
        m2 = MeshTet2.from_mesh(m)
        basis = Basis(m2, ElementTetP2())
        points, cells = basis.doflocs.T, basis.element_dofs.T
    else:
        points, cells = m.p.T, m.t.T
    f = m.facets[:, m.boundary_facets()].T
    z = m.p[2, f]
    sets = {"bottom": f[np.all(np.isclose(z, 0), axis=1)], "top": f[np.all(np.isclose(z, 0.04), axis=1)]}
    regions = (Region("lower", "rod", "PZT-4", (0.0, 0.0, 1.0)), Region("upper", "rod", "steel_45"))
    centroid_z = m.p[2, m.t].mean(axis=0)
    return TaggedMesh(points, cells, (centroid_z > 0.02).astype(int), regions, sets,
                      (Electrode("top", "hot"), Electrode("bottom", "ground")))


@pytest.mark.parametrize("order", [1, 2])
def test_skfem_conversion_keeps_tags_and_volume(order):
    tm = _bar(order)
    sk = tm.to_skfem()
    assert set(sk.subdomains) == {"lower", "upper"}
    assert len(sk.subdomains["lower"]) + len(sk.subdomains["upper"]) == tm.n_cells
    for name in ("top", "bottom"):
        facets = sk.boundaries[name]
        assert len(facets) == 2 * 3 * 2
        zf = sk.p[2, sk.facets[:, facets]]
        assert np.allclose(zf, 0.04 if name == "top" else 0.0)
    assert tm.cell_volumes().sum() == pytest.approx(0.01 * 0.002 * 0.04, rel=1e-12)
    mass = sum(get_material(r.material).density * tm.cell_volumes()[tm.cells_in(region=r.name)].sum()
               for r in tm.regions)
    assert mass == pytest.approx(0.5 * 8e-7 * (7500 + 7890), rel=1e-12)


def test_msh_round_trip_through_meshio_and_skfem(tmp_path):
    from skfem.io.meshio import from_meshio

    tm = _bar()
    tm.write(tmp_path / "bar.msh")
    tm.write(tmp_path / "bar.vtu")
    back = from_meshio(meshio.read(tmp_path / "bar.msh"))
    assert set(back.subdomains) == {"lower", "upper"} and set(back.boundaries) == {"top", "bottom"}
    vtu = meshio.read(tmp_path / "bar.vtu")
    assert vtu.cells_dict["tetra"].shape == (tm.n_cells, 4)
    with pytest.raises(ParameterError, match="must end in .vtu or .msh"):
        tm.write(tmp_path / "bar.stl")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.msh", "bar.vtu"]


def test_unknown_names_are_clear_errors():
    tm = _bar()
    with pytest.raises(ParameterError, match="surface = 'tip'"):
        tm.facets("tip")
    with pytest.raises(ParameterError, match="part = 'horn'"):
        tm.cells_in(part="horn")
