"""The utilisation table on the k = 0 sector: the whole drill's table, one table per design.

References
----------
* The whole drill replicated from the same sector (geometry.sector.replicate), assembled and
  solved as it is: the k = 0 restriction is exact (fem.cyclic), so the sector's recovered field
  (its cut-face and axis nodes averaged with the neighbouring sectors' cells,
  fem.stress.periodic_sums) is the whole drill's to the solvers' round-off. The working points
  agree to TOL_SOLVE = 1e-8 of the largest DOF (tests/test_sector_system.py, its derivation
  there); a stress is a gradient of that error: at most TOL_SOLVE x L / h_min of the largest
  stress of the field (L the drill's length, h_min its shortest element edge), the bound used
  below for every peak of a kind (Pa or V/m) against the largest peak of that kind.

``python -m fem.harmonic --stress`` against the pipeline's table: tests/test_default_design_answers.py.
"""

import dataclasses

import numpy as np
import pytest

from fem.assembly import assemble
from fem.harmonic import LossModel, modal_basis, working_point
from fem.modal import modal_analysis
from fem.preload import preload_solve
from fem.sector_system import sector_system
from fem.stress_output import node_fields, whole_drill_fields
from fem.stress_state import working_point_stress
from geometry.builder import build
from geometry.examples import article_design
from geometry.sector import replicate

N = 6
TOL_SOLVE = 1e-8
KIND = {"von_mises": "Pa", "principal_max": "Pa", "principal_min": "Pa", "efield": "V/m"}


@pytest.fixture(scope="module")
def states():
    """The same working point (100 V at the working mode's f_r, Q 100, 10 kN preload) on the
    sector and on the whole drill replicated from it; PZT-4 in the stack (its c66 equals
    (c11 - c12) / 2: the drill is exactly symmetric, tests/test_cyclic.py)."""
    d = article_design()
    d = dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))
    tm, _ = build(d, mesher="revolve", sectors=N, refine=2.0)
    whole, _ = replicate(tm, N)
    out = []
    for system in (sector_system(assemble(tm), N), assemble(whole)):
        modes = modal_analysis(system, 20e3, 4)
        f = float(modes.f_r_hz[modes.working])
        loss = LossModel(q_mech=100)
        basis = modal_basis(system, f, loss=loss, modes=modes)
        wp = working_point(system, f, 100.0, loss=loss, basis=basis, surfaces=("horn_tip",))
        out.append(working_point_stress(system, wp, preload_solve(system, 10e3)))
    return out


def _gradient_tolerance(system) -> float:
    """TOL_SOLVE x L / h_min of the whole drill (module docstring)."""
    p = system.mesh.points
    edges = np.concatenate([system.mesh.cells[:, [i, j]] for i in range(4) for j in range(i + 1, 4)])
    h_min = float(np.min(np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)))
    return TOL_SOLVE * float(np.ptp(p[:, 2])) / h_min


def test_sector_table_is_the_whole_drills(states):
    """Every row: peak, off-edge headline, singular mark and limit of the sector's table equal
    the whole drill's (the location may be any of the N rotated copies of the peak)."""
    sec, whole = states
    tol = _gradient_tolerance(whole.system)
    assert 1e-7 < tol < 1e-4                       # the bound is a few micro, not a loose one
    largest = {u: max(abs(r.value) for r in whole.table.rows if KIND[r.quantity] == u) for u in set(KIND.values())}
    assert [(r.region, r.quantity) for r in sec.table.rows] == [(r.region, r.quantity) for r in whole.table.rows]
    for a, b in zip(sec.table.rows, whole.table.rows):
        scale = largest[KIND[a.quantity]]
        assert abs(a.value - b.value) <= tol * scale, (a.region, a.quantity, a.value, b.value)
        assert abs(a.headline - b.headline) <= tol * scale, (a.region, a.quantity, a.headline, b.headline)
        assert a.singular == b.singular and a.limit == b.limit
        r_a, r_b = np.hypot(*a.location[:2]), np.hypot(*b.location[:2])
        assert abs(r_a - r_b) < 1e-9 and abs(a.location[2] - b.location[2]) < 1e-9   # same ring of copies


def test_sector_node_fields_expand_to_the_whole_drills(states, tmp_path):
    """The picture's and the VTU's node fields on the whole drill built from the sector equal the
    whole drill's own (same node positions), and the files are written on the whole drill."""
    import meshio
    from scipy.spatial import cKDTree

    from fem.modeshape import p2_nodes

    sec, whole = states
    mesh, fields = whole_drill_fields(sec.system, node_fields(sec.dynamic, sec.static))
    ref = node_fields(whole.dynamic, whole.static)
    dist, j = cKDTree(whole.system.nodes).query(p2_nodes(mesh))
    assert dist.max() < 1e-12 and len(np.unique(j)) == len(j) == whole.system.n_nodes
    tol = _gradient_tolerance(whole.system)
    for key, v in fields.items():
        assert np.max(np.abs(v - ref[key][j])) <= tol * np.max(np.abs(ref[key])), key
    files = sec.write_files(tmp_path / "s.png", tmp_path / "s.vtu", "100 V")
    back = meshio.read(files["vtu"])
    assert len(back.points) == whole.system.n_nodes
    assert np.allclose(back.point_data["von_mises_Pa"], fields["von_mises"], rtol=0, atol=0)
    assert files["png"].stat().st_size > 10_000

