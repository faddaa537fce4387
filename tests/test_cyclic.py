"""Cyclic symmetry (geometry/sector.py, geometry/sector_sweep.py, fem/cyclic.py): one sector of
the drill and its harmonics.

References: the whole drill replicated from the same sector (geometry.sector.replicate) and
solved as it is by fem.modal: every one of its modes is a mode of one harmonic of the sector,
to TOL_EXACT, a harmonic 0 < k < N/2 twice, and its shape lies in the whole drill's eigenspace
to the solvers' promise (eigenspace_bound); the replicated mesh closes (no boundary face left on
an inner cut, its volume N times the sector's).
The stack ceramic is PZT-4 here: its tabulated c66 equals (c11 - c12) / 2, so the drill is
exactly symmetric. PZT-8's table rounds c66 1.5e-4 away from it, which splits the whole
model's k = 2 pairs by 2e-5 (measured) and moves k = 0 and 1 by under 1e-7: below any mesh's
discretisation error, but not round-off.
"""

import dataclasses
import math

import numpy as np
import pytest

from fem.assembly import assemble
from fem.cyclic import cyclic_basis, cyclic_modes, expand, harmonics
from fem.modal import modal_analysis
from geometry.builder import build
from geometry.examples import article_design
from geometry.design_rpud import filleted
from geometry.sector import AXIAL_RULE, LATERAL_RULE, check_sectors, replicate, sector_pairs, symmetry_order
from rpud_common import ParameterError
from reference_designs import reference_default

N = 6
TOL_EXACT = 1e-9
"""The reduction is exact, so full and cyclic eigenvalues agree to the eigensolvers' accuracy: both
solve omega^2 to tol = 1e-10 relative (fem.eigen's bound), f to 5e-11, so they differ by at most
1e-10; 1e-9 leaves 10x for the round-off of the Rayleigh quotients."""


def eigenspace_bound(f, f_all, near_hz, tol=1e-10):
    """Largest squared sine of the angle between two solvers' shapes of the mode at ``f`` (Hz) that
    their promise allows. A residual rho (relative) puts a mode's eigenspace within rho / g of the
    exact one (g: gap in theta = 1 / (lam - sigma) to the other modes, ``f_all`` beyond 1e-3,
    relative to |theta|); fem.eigen stops once rho^2 |lam - sigma| / (g lam) <= tol, so each
    solver's sin^2 <= tol lam / (|lam - sigma| g), and the two together (2 sqrt of that)^2."""
    sigma = (2 * math.pi * near_hz) ** 2
    lam, lam_all = (2 * math.pi * f) ** 2, (2 * math.pi * np.asarray(f_all)) ** 2
    theta, theta_all = 1 / (lam - sigma), 1 / (lam_all - sigma)
    g = np.abs(theta_all - theta)[np.abs(f_all - f) > 1e-3 * f].min() / abs(theta)
    return 4 * tol * lam / (abs(lam - sigma) * g)


def _pzt4(d):
    return dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))


@pytest.fixture(scope="module", params=["free", "revolve"])
def sector(request):
    tm, report = build(_pzt4(article_design()), mesher=request.param, sectors=N, refine=2.0)
    assert report.sectors == N and report.mesher == request.param
    return tm


@pytest.fixture(scope="module")
def full(sector):
    return replicate(sector, N)


def test_replicated_mesh_closes(sector, full):
    whole, index = full
    assert index.shape == (N, sector.n_points)
    assert whole.cell_volumes().sum() == pytest.approx(N * sector.cell_volumes().sum(), rel=1e-12)
    # no crack: no boundary triangle lies on one of the inner cut planes
    p = whole.points
    tri = whole.boundary_triangles()
    for s in range(N):
        a = 2 * math.pi * s / N
        on = (np.abs(-math.sin(a) * p[:, 0] + math.cos(a) * p[:, 1]) < 1e-9) & \
             (math.cos(a) * p[:, 0] + math.sin(a) * p[:, 1] > -1e-9)
        assert not np.all(on[tri], axis=1).any()
    # each electrode is N copies of the sector's
    for e in sector.electrodes:
        assert len(whole.facet_sets[e.name]) == N * len(sector.facet_sets[e.name])
    pairs = sector_pairs(sector.points, N)
    assert len(pairs.near) == len(pairs.far) > 0 and len(pairs.axis) > 0
    # the coupler meets the first ring face to face: no boundary triangle inside their annulus at z = 0
    d = article_design()
    r = np.hypot(p[:, 0], p[:, 1])
    inside = (np.abs(p[:, 2]) < 1e-12) & (r > d.coupler_bore / 2 + 1e-9) & (r < d.coupler.outer_diameter / 2 - 1e-9)
    assert not np.all(inside[tri], axis=1).any()


def _extent(tm, name):
    """{z plane: (min r, max r)} (m) of a facet set's nodes."""
    p = tm.points[np.unique(tm.facet_sets[name])]
    r = np.hypot(p[:, 0], p[:, 1])
    out = {}
    for z in np.unique(np.round(p[:, 2], 9)):
        on = np.abs(p[:, 2] - z) < 1e-9
        out[float(z)] = (round(float(r[on].min()), 9), round(float(r[on].max()), 9))
    return out


def test_sector_facet_sets_are_the_whole_drills(sector):
    """A sector's named surfaces span what the whole drill's do, plane by plane: the flange's
    exposed ring beside the horn (from the shoulder fillet to 22.5 mm) included, which a per-triangle radius rule lost."""
    swept = len(sector.cells_in(region="ring_1")) > 200     # prisms cut in three: many more ring cells
    whole, _ = build(_pzt4(article_design()), mesher="revolve" if swept else "free", refine=2.0)
    for name in ("flange", "horn_tip", "teeth_tops", "electrode_0", "electrode_2", "electrode_4"):
        assert _extent(sector, name) == _extent(whole, name), name
    # from the horn's shoulder fillet (12 mm horn radius + the fillet) to the flange's rim
    fillet = article_design().horn.flange_fillet
    assert _extent(sector, "flange")[0.023] == (round(0.012 + fillet, 9), 0.0225)


def test_harmonics_equal_the_whole_drill(sector, full):
    whole, _ = full
    sw = assemble(whole)
    res = modal_analysis(sw, 15000.0, 16)
    system = assemble(sector)
    modes = {k: cyclic_modes(system, N, k, 15000.0, 8) for k in harmonics(N)}
    # the shapes too: each harmonic's mode, expanded onto the whole drill (a pair: both parts),
    # lies in the whole drill's eigenspace of that frequency, to the solvers' promise (at most
    # 6e-8 of the squared norm here, next to the shift; a wrong expansion leaves O(1))
    M = sw.M[: sw.n_u, : sw.n_u]
    for k in (0, 1):
        U = expand(system, modes[k].vectors, k, N, sw.nodes)
        for i, f in enumerate(modes[k].f_hz):
            same = np.flatnonzero(np.abs(res.f_r_hz - f) < 1e-7 * f)
            if not len(same):
                continue
            Phi = res.shapes[same].reshape(len(same), -1).T
            for part in (U[i].real.ravel(), U[i].imag.ravel()):
                norm = float(part @ (M @ part))
                if norm < 1e-20 * float(np.abs(U[i]).max() ** 2 + 1e-300):
                    continue
                c = np.linalg.solve(Phi.T @ (M @ Phi), Phi.T @ (M @ part))
                r = part - Phi @ c
                assert float(r @ (M @ r)) < eigenspace_bound(f, res.f_r_hz, 15000.0) * norm
    count = {k: 0 for k in modes}
    for f_r, f_a in zip(res.f_r_hz, res.f_a_hz):
        err, k, j = min((abs(c - f_r) / f_r, k, j) for k, m in modes.items() for j, c in enumerate(m.f_hz))
        assert err < TOL_EXACT
        assert modes[k].f_open_hz[j] == pytest.approx(f_a, rel=TOL_EXACT, nan_ok=True)
        count[k] += 1
    # the working mode and the torsion are k = 0 and single; bending pairs are k = 1, twice
    assert count[0] >= 3 and count[1] >= 4 and count[1] % 2 == 0
    assert np.nanmax(modes[0].f_open_hz) > modes[0].f_hz.max()      # k = 0 is driven: f_a > f_r there
    assert np.array_equal(modes[1].f_open_hz, modes[1].f_hz)        # k > 0: no net charge
    assert modes[1].ndof > 1.9 * modes[0].ndof                      # complex phase: the doubled pencil
    # the free body's rigid motions of k = 0 (axial translation, spin) are found and set apart
    assert len(modes[0].rigid_hz) <= 2 and np.all(np.abs(modes[0].rigid_hz) < 1.0)


def test_basis_ties_the_far_cut_to_the_near_one(sector):
    system = assemble(sector)
    pairs = sector_pairs(system.nodes, N)
    for k in (0, 1, 3):
        T = cyclic_basis(system, pairs, k)
        q = np.random.default_rng(k).standard_normal(T.shape[1])
        u = system.displacement((T @ q))
        R = np.array([[math.cos(2 * math.pi / N), -math.sin(2 * math.pi / N), 0],
                      [math.sin(2 * math.pi / N), math.cos(2 * math.pi / N), 0], [0, 0, 1]])
        phase = np.exp(2j * math.pi * k / N)
        assert np.allclose(u[pairs.far], phase * u[pairs.near] @ R.T, atol=1e-12)
        # the axis: u_z alone for k = 0, circular u_x + i u_y for k = 1, at rest for k = 3
        ax = u[pairs.axis]
        if k == 0:
            assert np.allclose(ax[:, :2], 0) and np.abs(ax[:, 2]).max() > 0
        elif k == 1:
            assert np.allclose(ax[:, 1], 1j * ax[:, 0]) and np.allclose(ax[:, 2], 0)
        else:
            assert np.allclose(ax, 0)


def test_sector_pairs_refuses_faces_that_do_not_match(sector):
    pairs = sector_pairs(sector.points, N)
    points = sector.points.copy()
    points[pairs.far[0]] += [0.0, 0.0, 1e-6]
    with pytest.raises(ParameterError, match="rotated"):
        sector_pairs(points, N)
    with pytest.raises(ParameterError, match="same number"):
        sector_pairs(np.delete(sector.points, pairs.far[:1], axis=0), N)


def test_sector_counts_follow_the_coupler_symmetry():
    d = article_design()
    assert symmetry_order(d) == 6
    assert check_sectors(d, 3) == 3 and check_sectors(d, 6) == 6
    for bad in (4, 12, 2, 6.0, True):
        with pytest.raises(ParameterError, match="--sectors"):
            check_sectors(d, bad)
    plain = dataclasses.replace(d, coupler=dataclasses.replace(d.coupler, n_slots=0, n_teeth=0))
    assert symmetry_order(plain) == 0 and check_sectors(plain, 24) == 24
    with pytest.raises(ParameterError, match=r"\[3, 72\]"):
        check_sectors(plain, 100)
    narrow = dataclasses.replace(d, coupler=dataclasses.replace(d.coupler, outer_diameter=0.034))
    with pytest.raises(ParameterError, match="face to face"):
        build(narrow, mesher="revolve", sectors=6)


PLAIN_REFERENCE = {"f_r": 19682.31, "f_a": 21410.33, "torsion": 15286.16, "bending": 5161.55}
"""Converged (r, z) answers of the default design with sharp horn corners, without slots and teeth, Hz (the independent
model of tests/axisym_reference.py: harmonic n = 0 for the working mode and the
torsion, n = 1 for the first bending pair)."""


def test_command_line_rules_meet_the_targets_on_the_design_without_slots():
    """The accuracy targets for the meshes ``python -m fem.modal`` uses by default (AXIAL_RULE for
    k = 0, LATERAL_RULE for k = 1): f_r, f_a within 0.05 %, first torsion and bending within
    0.1 % (measured +0.019 / +0.022 / +0.023 / +0.075 %)."""
    d = filleted(reference_default(), 0.0).replace({"stack.bolt_diameter": 0.0})   # PLAIN_REFERENCE's design
    d = dataclasses.replace(d, coupler=dataclasses.replace(d.coupler, n_slots=0, n_teeth=0))
    got = {}
    for (refine, meshing), k, near in ((AXIAL_RULE, 0, 17000.0), (LATERAL_RULE, 1, 5000.0)):
        tm, _ = build(d, mesher="revolve", sectors=N, refine=refine, sector_meshing=meshing)
        m = cyclic_modes(assemble(tm), N, k, near, 4 if k == 0 else 1)
        if k == 0:
            work = np.argmin(abs(m.f_hz - PLAIN_REFERENCE["f_r"]))
            got.update(f_r=m.f_hz[work], f_a=m.f_open_hz[work],
                       torsion=m.f_hz[np.argmin(abs(m.f_hz - PLAIN_REFERENCE["torsion"]))])
        else:
            got["bending"] = m.f_hz[0]
    for key, tol in (("f_r", 5e-4), ("f_a", 5e-4), ("torsion", 1e-3), ("bending", 1e-3)):
        err = got[key] / PLAIN_REFERENCE[key] - 1
        # P2 on a finer mesh converges from above (tests/test_revolve.py)
        assert 0 < err < tol, (key, err)


def _modal(tmp_path, *args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "fem.modal", *args], capture_output=True, text=True, cwd=tmp_path,
                          timeout=600)


def test_command_line_solves_the_article_drill_by_harmonics(tmp_path):
    """``python -m fem.modal --design article`` (sectors by default) at --refine 2: its working mode equals
    cyclic_modes on the same rule's mesh, every listed mode count sums to --modes (a pair twice),
    and the JSON says how it was solved."""
    import json

    r = _modal(tmp_path, "--design", "article", "--refine", "2", "--modes", "8", "--json", "m.json")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "m.json").read_text())
    assert data["sectors"] == 6 and data["harmonics"] == [0, 1] and data["mesher"] == "revolve"
    modes = data["modes"]
    assert sum(m["multiplicity"] for m in modes) in (8, 9)       # the last row may be a pair
    assert {m["harmonic"] for m in modes} == {0, 1}
    assert all(m["multiplicity"] == (2 if m["harmonic"] == 1 else 1) for m in modes)
    assert all(m["label"] == "bending" for m in modes if m["harmonic"] == 1)
    work = [m for m in modes if m["label"] == "longitudinal" and m["harmonic"] == 0]
    assert work and work[0]["f_a_hz"] > work[0]["f_r_hz"] and 0.3 < work[0]["k_eff"] < 0.5
    # refine 2 is off the checked rule: its own two-level estimate on the k = 0 sector
    assert work[0]["f_r_hz_error"] > 0 and data["discretisation_error"]["method"].startswith("two-level")
    refine, meshing = AXIAL_RULE
    tm, _ = build(article_design(), mesher="revolve", sectors=N, refine=refine * 2, sector_meshing=meshing.scaled(2))
    m = cyclic_modes(assemble(tm), N, 0, 20000.0, 4)
    assert min(abs(m.f_hz - work[0]["f_r_hz"])) < 1e-9 * work[0]["f_r_hz"]
    assert "swept sector (1/6)" in r.stdout and "+0.029 %" in r.stdout


@pytest.mark.parametrize("args, word", [(["--sectors", "4"], "--sectors"), (["--sectors", "6", "--match"], "--match"),
                                        (["--harmonics", "4"], "--harmonics"),
                                        (["--sectors", "off", "--harmonics", "0"], "--harmonics"),
                                        (["--refine", "0.22"], "--refine"),
                                        (["--sectors", "6", "--order", "1"], "--order")])
def test_command_line_refuses_sector_options_in_one_line(tmp_path, args, word):
    r = _modal(tmp_path, *args, "--json", "m.json")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and word in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_straightening_keeps_the_cut_faces_copies():
    """A node straightened on one cut carries its partner along (geometry.sector.keep_periodic);
    untouched pairs keep their coordinates bit for bit."""
    from geometry.sector import keep_periodic, rotation

    R = rotation(2 * math.pi / N)
    near = np.array([[0.01, 0.0, 0.0], [0.02, 0.0, 0.01], [0.015, 0.0, 0.02]])
    before = np.vstack([near, near @ R.T, [[0.01, 0.003, 0.0]]])
    after = before.copy()
    after[1] += [1e-4, 0.0, 0.0]                        # near node 1 straightened
    after[5] += 1e-4 * R[:, 0]                          # the far partner of near node 2 straightened
    out = keep_periodic(before, after, N)
    pairs = sector_pairs(before, N)
    assert np.abs(out[pairs.far] - out[pairs.near] @ R.T).max() < 1e-15
    assert np.array_equal(out[1], after[1]) and np.allclose(out[2], after[5] @ R, atol=1e-15)
    assert np.array_equal(out[[0, 3, 6]], before[[0, 3, 6]])


def test_rule_error_only_on_the_design_it_was_measured_on():
    """The command line's measured rule error belongs to the sharp-cornered default at the lengths
    of the measurement; the same drill at other lengths (the matched default's) is another design
    and gets its own two-level estimate."""
    from fem.cyclic_cli import _default_geometry

    assert _default_geometry(filleted(reference_default(), 0.0))
    assert not _default_geometry(filleted(article_design(), 0.0))
    assert not _default_geometry(article_design())


def test_nearest_modes_continues_from_a_first_round_solved_elsewhere(sector):
    """The command line starts each harmonic's first solve as soon as its mesh exists
    (``first``); the search then picks the same modes, bit for bit, as when it solves them itself."""
    from fem.cyclic import first_ask, nearest_modes

    system = assemble(sector)
    systems = {0: system, 1: system}
    ask = first_ask(systems, 6)
    first = {k: cyclic_modes(system, N, k, 20000.0, ask[k]) for k in systems}
    plain, chosen = nearest_modes(systems, N, 20000.0, 6)
    given, chosen_given = nearest_modes(systems, N, 20000.0, 6, first=first)
    assert chosen_given == chosen
    for k in systems:
        assert np.array_equal(given[k].f_hz, plain[k].f_hz)
        # the first round is taken as given, not solved again (a harmonic asked for more is)
        assert given[k] is first[k] or len(given[k].f_hz) > ask[k]
    assert any(given[k] is first[k] for k in systems)
