"""Stress recovery, peaks over a cycle, bolt preload, material limits, utilisation table.

References: the 1-D free-free bar (sigma_max = E k u_max at the node), a uniform axial preload
(P/A), Euler-Bernoulli beam bending (sigma = M c / I), numpy's eigvalsh and dense phase sampling.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import geometry
from geometry import examples
from rpud_common import ParameterError


@pytest.fixture(scope="module")
def rod():
    """Steel rod 200 x D10 (free-free / cantilever tests), the default mesh of the example."""
    from fem.assembly import assemble

    return assemble(geometry.build_mesh(examples.slender_rod()))


@pytest.fixture(scope="module")
def langevin():
    """Steel / 2 x PZT-8 / steel sandwich, D 30 mm (preload and table tests)."""
    from fem.assembly import assemble

    return assemble(geometry.build_mesh(examples.langevin_sandwich()))


# --------------------------------------------------------------------------- the three physics checks


def test_free_free_bar_first_longitudinal_mode_against_1d_closed_form(rod):
    """sigma_max = E k u_max with k = pi / L, at the node (mid-length); within 1 %."""
    from fem.modal import modal_analysis
    from fem.stress import StressRecovery
    from fem.stress_table import stress_table

    L, E = 0.2, 209e9
    modes = modal_analysis(rod, near_hz=5100 / (2 * L), n_modes=8)
    w = [i for i, lab in enumerate(modes.labels) if lab == "longitudinal"][0]
    x = modes.vectors[:, w]
    u = rod.displacement(x)
    u_end = abs(u[rod.surface_nodes("top"), 2].mean())
    assert abs(u[rod.surface_nodes("bottom"), 2].mean()) == pytest.approx(u_end, rel=1e-3)
    table = stress_table(StressRecovery(rod).field(x))
    (row,) = table.rows
    ref = E * math.pi / L * u_end
    assert row.quantity == "von_mises"
    assert row.value == pytest.approx(ref, rel=0.01)            # measured: +0.1 %
    assert abs(row.location[2] - L / 2) < 0.01                  # at the node
    assert row.error_estimate < 0.01 * row.value


def test_cantilever_tip_load_against_beam_theory(rod):
    """Clamped at z = 0, transverse tip force F: sigma_zz = -F (L - z) x / I in the middle third,
    within 2 % of the section's peak (Saint-Venant: exact for a tip-loaded prismatic beam)."""
    from fem.preload import face_area, static_solve, traction_load
    from fem.stress import StressRecovery

    L, r, F = 0.2, 0.005, 10.0
    I = math.pi * r ** 4 / 4
    f = traction_load(rod, "top", (F / face_area(rod, "top"), 0.0, 0.0))
    assert f[0: rod.n_u: 3].sum() == pytest.approx(F, rel=1e-10)
    fld = StressRecovery(rod).field(static_solve(rod, f, clamp=("bottom",)))
    p = fld.points.reshape(-1, 3)
    szz = fld.nodal_average("stress").reshape(-1, 6)[:, 2]
    mid = (p[:, 2] > L / 3) & (p[:, 2] < 2 * L / 3)
    beam = -F * (L - p[mid, 2]) * p[mid, 0] / I
    peak = F * (L - p[mid, 2]) * r / I
    assert np.max(np.abs(szz[mid] - beam) / peak) < 0.02        # measured 1.5 %
    # the section peak (outer fibre) scaled by the lever arm
    assert np.max(np.abs(szz[mid]) / (L - p[mid, 2])) == pytest.approx(F * r / I, rel=0.02)   # measured +1.6 %


def test_static_preload_gives_p_over_a_in_the_ceramic():
    """A k33 rod (PZT-4, 40 x D4) squeezed on its electrode faces: sigma_zz = -P/A everywhere
    (1 %), electrodes shorted: E ~ 0; the table's compressive peak is P/A."""
    from fem.assembly import assemble
    from fem.preload import preload_solve
    from fem.stress import StressRecovery
    from fem.stress_table import stress_table

    system = assemble(geometry.build_mesh(examples.k33_rod(), mesh_size=0.003))
    P = 1000.0
    pre = preload_solve(system, P)
    assert pre.faces == ("electrode_bottom", "electrode_top")
    A = pre.areas_m2[0]
    assert A == pytest.approx(math.pi * 0.002 ** 2, rel=1e-3)
    fld = StressRecovery(system).field(pre.x)
    s = fld.stress.reshape(-1, 6)
    assert np.max(np.abs(s[:, 2] / (-P / A) - 1)) < 0.01          # measured 8e-4
    assert np.max(np.abs(s[:, :2])) < 0.01 * P / A
    table = stress_table(None, fld, preload_n=P)
    rows = {r.quantity: r for r in table.rows}
    assert rows["principal_min"].value == pytest.approx(-P / A, rel=0.01)
    assert rows["principal_min"].utilisation == pytest.approx(P / A / 82.7e6, rel=0.01)   # PZT-4 record
    # uniform stress between shorted electrodes: no field (D = d33 T instead)
    assert rows["efield"].value < 1e-4 * (P / A) / 15.1


def test_preload_in_a_langevin_stack_carries_p_through_the_ceramic(langevin):
    """Langevin sandwich: the stack end faces are found (electrode_0, electrode_2); the volume
    mean of sigma_zz over the ceramic is -P/A (every section carries -P) within 1 %; the metal
    beyond the faces carries no net force; the free-free solve has no rigid-body motion."""
    from fem.preload import preload_solve
    from fem.stress import StressRecovery

    system = langevin
    P = 5000.0
    pre = preload_solve(system, P)
    assert pre.faces == ("electrode_0", "electrode_2")
    A = pre.areas_m2[0]
    fld = StressRecovery(system).field(pre.x)
    vol = np.asarray(system.basis.dx).sum(axis=1)[fld.cells]          # cell volumes
    corner = fld.stress[:, :4, 2].mean(axis=1)                        # mean of the linear field
    piezo = np.array([system.regions[r].piezo for r in fld.region])
    mean_c = np.sum(corner[piezo] * vol[piezo]) / vol[piezo].sum()
    mean_m = np.sum(corner[~piezo] * vol[~piezo]) / vol[~piezo].sum()
    assert mean_c == pytest.approx(-P / A, rel=0.01)
    assert abs(mean_m) < 0.01 * P / A
    # the singular lines: where the bonded interfaces (z = 40, 45, 50 mm) meet the rim (r = 15 mm)
    from fem.stress_table import bonded_edge_nodes

    e = system.nodes[bonded_edge_nodes(system)]
    assert len(e) > 100
    assert np.allclose(np.hypot(e[:, 0], e[:, 1]), 0.015, atol=1e-6)
    assert np.all(np.min(np.abs(e[:, 2:3] - np.array([[0.04, 0.045, 0.05]])), axis=1) < 1e-9)
    from fem.preload import _rigid_modes

    R = _rigid_modes(system)
    MR = system.M @ R
    rigid = R @ np.linalg.solve(R.T @ MR, MR.T @ pre.x)          # M-projection on the rigid modes
    assert np.linalg.norm(rigid) < 1e-8 * np.linalg.norm(pre.x[: system.n_u])


# --------------------------------------------------------------------------- cycle peaks and tensor algebra


def _dense(hat, s0, fn, n=20000):
    """Max over ``n`` phases of ``fn`` (applied to rows), all phases at once."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    s = s0[None] + np.real(hat[None] * np.exp(1j * th)[:, None, None])
    return fn(s.reshape(-1, s.shape[-1])).reshape(n, -1).max(axis=0)


def test_cycle_peaks_against_dense_phase_sampling():
    """The reference samples n phases: its maximum lies below the true one by at most
    max|f''| (pi / n)^2 / 2 (the peak is within half a step of a sample). von Mises and |E| are
    sqrt(q) with q >= 0 a trigonometric polynomial of degree 2 in the phase, whose harmonics'
    amplitudes are at most twice its mean (as q >= 0), so at the peak |f''| / f = |q''| / 2q
    <= (1 + 4) 2 / 2 = 5: at n = 20000 the reference is low by at most 6.2e-8 relative
    (asserted 1e-7). A principal value's curvature is |s''| + 2 |s'|^2 / gap <= ~30 |hat| unless
    two principal values nearly cross at the peak: at n = 4000 the reference is low by at most
    3.1e-7 x 30 |hat| (asserted 1e-5 |hat|)."""
    from fem.stress import (efield_cycle_peak, principal_cycle_extremes, principal_values, vm_cycle_peak,
                            von_mises)

    rng = np.random.default_rng(17)
    hat = rng.normal(size=(12, 6)) + 1j * rng.normal(size=(12, 6))
    s0 = 1.3 * rng.normal(size=(12, 6))
    for static in (None, s0):
        base = np.zeros((12, 6)) if static is None else static
        ref = _dense(hat, base, von_mises)
        got, _ = vm_cycle_peak(hat, static)
        assert np.max(np.abs(got - ref) / ref) < 1e-7
        p1, p3 = principal_cycle_extremes(hat, static)
        amp = np.abs(hat).max()
        r1 = _dense(hat, base, lambda s: np.linalg.eigvalsh(_tensor(s))[:, -1], n=4000)
        r3 = -_dense(hat, base, lambda s: -np.linalg.eigvalsh(_tensor(s))[:, 0], n=4000)
        assert np.max(np.abs(p1 - r1)) < 1e-5 * amp and np.max(np.abs(p3 - r3)) < 1e-5 * amp
    e_hat = rng.normal(size=(30, 3)) + 1j * rng.normal(size=(30, 3))
    e0 = rng.normal(size=(30, 3))
    got, _ = efield_cycle_peak(e_hat, e0)
    assert np.allclose(got, _dense(e_hat, e0, lambda e: np.linalg.norm(e, axis=1)), rtol=1e-7)
    # the table's search (rows preselected by bounds) finds the same peak as the full evaluation
    from fem.stress import quadratic_peak

    for kind, fn, h, st0 in (("von_mises", vm_cycle_peak, hat, s0), ("von_mises", vm_cycle_peak, hat, None),
                             ("efield", efield_cycle_peak, e_hat, e0)):
        i, v = quadratic_peak(kind, h, st0)
        full = fn(h, st0)[0]
        assert i == int(np.argmax(full)) and v == pytest.approx(full.max(), rel=1e-12)
    # one component: the peak is the modulus; principal values vs eigvalsh (degenerate cases too)
    one = np.zeros((1, 6), complex)
    one[0, 2] = 3.0 * np.exp(0.7j)
    assert vm_cycle_peak(one)[0][0] == pytest.approx(3.0, rel=1e-12)
    cases = np.vstack([rng.normal(size=(200, 6)), [[1, 1, 1, 0, 0, 0], [0] * 6, [2, 2, -1, 0, 0, 0]]])
    assert np.allclose(principal_values(cases), np.linalg.eigvalsh(_tensor(cases)), atol=1e-9)


def _tensor(s):
    s = np.asarray(s)
    return np.stack([np.stack([s[:, 0], s[:, 5], s[:, 4]], -1), np.stack([s[:, 5], s[:, 1], s[:, 3]], -1),
                     np.stack([s[:, 4], s[:, 3], s[:, 2]], -1)], -2)


# --------------------------------------------------------------------------- limits, table, outputs, CLI


def test_material_limits_are_validated_and_missing_ones_are_na():
    from geometry.materials import builtin_library, records_from_mapping

    lib = builtin_library()
    assert lib["ti6al4v"].fatigue_strength == 510e6 and lib["PZT-8"].depolarisation_field == 1.5e6
    assert lib["steel_45"].fatigue_strength is None
    rec = {"kind": "isotropic", "density": 2700.0, "youngs_modulus": 68.9e9, "poisson_ratio": 0.33,
           "fatigue_strength": 96.5e6}
    m = records_from_mapping({"al6061": rec}, "test")["al6061"]
    assert m.to_record()["fatigue_strength"] == 96.5e6
    for value, word in ((-1.0, "> 0"), (math.inf, "> 0"), ("high", "> 0"), (510.0, "[100000")):
        with pytest.raises(ParameterError, match=r"materials\.al6061\.fatigue_strength") as exc:
            records_from_mapping({"al6061": {**rec, "fatigue_strength": value}}, "test")
        assert word in str(exc.value)
    with pytest.raises(ParameterError, match=r"materials\.al6061\.depolarisation_field.*piezo"):
        records_from_mapping({"al6061": {**rec, "depolarisation_field": 1e6}}, "test")


def test_table_text_json_and_outputs(tmp_path, langevin):
    """Utilisation table of a driven Langevin sandwich (steel without a limit: n/a), strict JSON,
    node fields in a VTU, the PNG, and the peaks along a short sweep equal the table's headlines."""
    import meshio

    from fem.harmonic import LossModel, modal_basis, working_point
    from fem.modal import modal_analysis
    from fem.stress import StressRecovery
    from fem.stress_output import node_fields, render_stress, write_stress_vtu
    from fem.stress_table import stress_sweep, stress_table

    system = langevin
    modes = modal_analysis(system, near_hz=25000, n_modes=6)
    w = int(np.argmax(np.nan_to_num(modes.k_eff)))
    loss = LossModel(q_mech=100)
    basis = modal_basis(system, modes.f_r_hz[w], loss=loss, modes=modes)
    f = float(modes.f_r_hz[w])
    wp = working_point(system, f, 10.0, loss=loss, basis=basis, surfaces=("top",))
    rec = StressRecovery(system)
    fld = rec.field(wp.x)
    table = stress_table(fld, freq_hz=f, voltage=10.0)
    text = table.text()
    assert "n/a" in text and "PZT-8" in text and "MPa" in text
    data = json.loads(json.dumps(table.to_dict(), allow_nan=False))
    steel = [r for r in data["rows"] if r["material"] == "steel_45"]
    assert steel and all(r["utilisation"] is None and r["limit"] is None for r in steel)
    ring = [r for r in table.rows if r.quantity == "principal_max"][0]
    assert ring.utilisation == pytest.approx(ring.value / 24.1e6)
    # a linear problem: twice the voltage, twice every peak
    wp2 = working_point(system, f, 20.0, loss=loss, basis=basis, surfaces=("top",))
    t2 = stress_table(rec.field(wp2.x), freq_hz=f, voltage=20.0)
    assert all(b.value == pytest.approx(2 * a.value, rel=1e-9) for a, b in zip(table.rows, t2.rows))
    sw = stress_sweep(system, basis, [f * 0.99, f], 10.0, recovery=rec)
    for r in table.rows:
        assert sw.peaks[(r.region, r.quantity)][1] == pytest.approx(r.headline, rel=1e-9)   # off a singular edge
    fields = node_fields(fld)
    vm_table = max(r.value for r in table.rows if r.quantity == "von_mises")
    assert fields["von_mises"].max() >= vm_table * (1 - 1e-12)
    write_stress_vtu(system, fields, tmp_path / "s.vtu")
    back = meshio.read(tmp_path / "s.vtu")
    assert np.allclose(back.point_data["von_mises_Pa"], fields["von_mises"])
    render_stress(system, fields["von_mises"], tmp_path / "s.png", title="test", mark=ring.location)
    assert (tmp_path / "s.png").stat().st_size > 10_000


@pytest.mark.parametrize("argv, name", [
    (["--stress", "OUT", "--preload", "-5"], "--preload"),
    (["--stress", "OUT", "--preload", "nan"], "--preload"),
    (["--stress", "OUT", "--preload", "inf"], "--preload"),
    (["--preload", "100"], "--preload"),
    (["--stress", "OUT", "--stress-points", "-1"], "--stress-points"),
])
def test_cli_bad_stress_options_exit_2_before_meshing(tmp_path, capsys, argv, name, monkeypatch):
    import geometry as g
    from fem.harmonic_cli import main
    from rpud_common.cli import run_cli

    def no_mesh(*a, **k):
        raise AssertionError("meshed before checking the options")

    monkeypatch.setattr(g, "build_mesh", no_mesh)
    argv = [str(tmp_path / a) if a == "OUT" else a for a in argv]
    assert run_cli(main, argv, prog="fem.harmonic") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and name in err[0]
    assert not (tmp_path / "OUT").exists()


def test_cli_stress_runs_on_the_commands_path(tmp_path, capsys, monkeypatch):
    """``--stress`` takes the path the rest of ``fem.harmonic`` takes: ``auto`` is the k = 0
    sector for the sweepable default drill and the whole drill for a stack; ``--path sector``
    on a design that cannot be swept is one line naming the path, exit 2, before meshing, no
    folder written."""
    from types import SimpleNamespace

    import geometry as g
    from fem.harmonic_cli import main, resolve_path
    from rpud_common.cli import run_cli

    def args(path):
        return SimpleNamespace(path=path, mesher="auto", stress=str(tmp_path / "s"))

    assert resolve_path(args("auto"), g.default_design()) == "sector"
    assert resolve_path(args("sector"), g.default_design()) == "sector"
    assert resolve_path(args("whole"), g.default_design()) == "whole"
    assert resolve_path(args("auto"), examples.langevin_sandwich()) == "whole"

    def no_mesh(*a, **k):
        raise AssertionError("meshed before checking the path")

    design = tmp_path / "langevin.toml"
    examples.langevin_sandwich().save(design)
    monkeypatch.setattr(g, "build_mesh", no_mesh)
    out = tmp_path / "OUT"
    assert run_cli(main, ["--design", str(design), "--path", "sector", "--stress", str(out)], prog="fem.harmonic") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "path" in err[0] and "swept" in err[0]
    assert not out.exists()


# --------------------------------------------------------------------------- two-mesh error estimates


def test_coarse_table_is_the_working_point_at_the_drive_voltage(langevin):
    """The estimator's hook (fem.stress_converged.CoarseTable) gets the working point at 1 V: its
    table is the one of the state at the drive voltage (a linear state: peaks equal to 1e-9), with
    the preload's static stress added as the direct call adds it."""
    from fem.harmonic import LossModel, modal_basis, working_point
    from fem.modal import modal_analysis
    from fem.preload import preload_solve
    from fem.stress import StressRecovery
    from fem.stress_converged import CoarseTable
    from fem.stress_table import stress_table

    system = langevin
    modes = modal_analysis(system, near_hz=25000, n_modes=6)
    w = int(np.argmax(np.nan_to_num(modes.k_eff)))
    f = float(modes.f_r_hz[w])
    basis = modal_basis(system, f, loss=LossModel(q_mech=100), modes=modes)
    wp1 = working_point(system, f, 1.0, loss=LossModel(q_mech=100), basis=basis, surfaces=("top",))
    wp = working_point(system, f, 40.0, loss=LossModel(q_mech=100), basis=basis, surfaces=("top",))
    rec = StressRecovery(system)
    direct = stress_table(rec.field(wp.x), rec.field(preload_solve(system, 2000.0).x), freq_hz=f, voltage=40.0,
                          preload_n=2000.0)
    hooked = CoarseTable(40.0, 2000.0)(system, wp1)["stress"]
    assert hooked.voltage == 40.0 and hooked.preload_n == 2000.0 and hooked.freq_hz == pytest.approx(f)
    assert len(hooked.rows) == len(direct.rows)
    for a, b in zip(direct.rows, hooked.rows):
        assert (a.region, a.quantity) == (b.region, b.quantity)
        assert b.value == pytest.approx(a.value, rel=1e-9) and b.singular == a.singular


def test_with_error_uses_the_coarse_table_or_says_it_has_none():
    """fem.stress_converged.with_error: the coarse table of the estimate gives each row
    |fine - coarse| / (r^2 - 1) with r the estimate's h ratio; without one the rows keep their
    single-mesh estimate and the note says so."""
    from types import SimpleNamespace

    from fem.stress_converged import ZZ_NOTE, with_error
    from fem.stress_table import StressRow, StressTable

    def table(v):
        return StressTable((StressRow("horn", "horn", "ti6al4v", "von_mises", v, (0.0, 0.0, 0.0), 510e6, 1e6),),
                           20e3, 100.0, 0.0)

    est = SimpleNamespace(extra={"stress": table(90e6)}, ratio=1.3, ndof=1000, coarse_ndof=455, refine=1.0,
                          coarse_refine=1.4)
    out = with_error(table(100e6), est)
    assert out.rows[0].error_estimate == pytest.approx(10e6 / (1.3 ** 2 - 1))
    assert "two meshes" in out.note and "455 DOFs" in out.note
    for none in (None, SimpleNamespace(extra={})):
        kept = with_error(table(100e6), none)
        assert kept.rows[0].error_estimate == 1e6 and kept.note == ZZ_NOTE


def test_cli_stress_table_states_a_two_mesh_error(tmp_path, capsys):
    """``fem.harmonic --stress`` at the mode's own f_r runs the discretisation-error estimate with
    the stress hook: the JSON table's note names the two meshes, every row has a finite error; at
    a drive frequency of the user's (no two-mesh comparison there) the note says single-mesh."""
    from fem.harmonic_cli import main

    design = tmp_path / "langevin.toml"
    examples.langevin_sandwich().save(design)
    # refine 2: what is checked is which estimate runs and what the table says of it, at any mesh
    base = ["--design", str(design), "--surface", "top", "--voltage", "50", "--q-mech", "100", "--points", "5",
            "--stress-points", "0", "--refine", "2", "-q"]
    assert main(base + ["--stress", str(tmp_path / "a"), "--json", str(tmp_path / "a.json")]) == 0
    rec = json.loads((tmp_path / "a.json").read_text())
    table = rec["stress"]["working_point"]
    assert "two meshes" in table["note"] and rec["discretisation_error"]["coarse_ndof"] > 0
    assert all(math.isfinite(r["error_estimate"]) and r["error_estimate"] >= 0 for r in table["rows"])
    assert "two meshes" in capsys.readouterr().out
    f = rec["working_mode"]["f_r_hz"] if "working_mode" in rec else None
    drive = ["--freq", f"{(f or 25000.0) * 1.001:.1f}"]
    assert main(base + drive + ["--stress", str(tmp_path / "b"), "--json", str(tmp_path / "b.json")]) == 0
    assert json.loads((tmp_path / "b.json").read_text())["stress"]["working_point"]["note"].startswith(
        "error estimates: recovered minus raw")
