"""The preload window of a Langevin stack (fem.preload.preload_windows) against a 1-D wave model.

Reference: the free-free steel / 2 x PZT-8 / steel sandwich (geometry.examples.langevin_sandwich,
D 30 mm) as a 1-D rod written here: per segment ``u = a cos kz + b sin kz``, axial force
``F = E A u'``, ``k = w sqrt(rho / E)`` (steel E, rho from references.md; the ceramic with
``1 / s33^E``, its short-circuit rod modulus: at resonance the voltage-driven state has the
short-circuit mode's shape), free ends ``F = 0`` at both faces; its first longitudinal resonance
and mode shape, scaled to the FE's mean axial amplitude of the back face, give the section force
at the rings and the dynamic stress amplitude ``F / A``; the window's lower end is
``P_min = A sigma_dyn``.

Tolerance 2 %: the 1-D rod neglects lateral inertia (Rayleigh-Love: 0.5 nu^2 (R^2/2) k^2 ~ 0.3 %
on the frequency of this D 30 / L 90 mm stack, and of that order on the shape) and the ceramic's
lateral constraint at the bonded faces (it moves the ceramic's modulus by a few %, which enters the
force through the frequency shift it causes: the ceramic is 11 % of the length, ~0.5 % here);
the FE drive adds the off-resonant modes and the static piezoelectric deformation at 1/Q = 1 %
of the resonant amplitude.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import geometry
from geometry import examples

A = math.pi * 0.015 ** 2
STEEL = (209e9, 7890.0)
L_METAL, L_RING = 0.04, 0.005


@pytest.fixture(scope="module")
def driven():
    from fem.assembly import assemble
    from fem.harmonic import LossModel, modal_basis, working_point
    from fem.modal import modal_analysis

    system = assemble(geometry.build_mesh(examples.langevin_sandwich()))
    modes = modal_analysis(system, 25e3, 8)
    w = int(np.nanargmax(modes.k_eff))
    loss = LossModel(100.0, 0.0)
    basis = modal_basis(system, modes.f_r_hz[w], loss=loss, modes=modes)
    wp = working_point(system, modes.f_r_hz[w], 100.0, loss=loss, surfaces=("bottom", "top"), basis=basis)
    return system, float(modes.f_r_hz[w]), wp


def _segments():
    from fem.materials import piezo_matrices, strain_charge
    from geometry.materials import get_material

    s33 = strain_charge(piezo_matrices(get_material("PZT-8")))[0][2, 2]
    pzt = (1.0 / s33, get_material("PZT-8").density)
    return [(L_METAL, *STEEL), (L_RING, *pzt), (L_RING, *pzt), (L_METAL, *STEEL)]


def _rod(omega: float, n: int = 400):
    """(z, u, F) along the free-free rod from u = 1, F = 0 at z = 0 (F: section force per unit u)."""
    zs, us, fs = [], [], []
    u, F, z0 = 1.0, 0.0, 0.0
    for length, E, rho in _segments():
        k = omega * math.sqrt(rho / E)
        z = np.linspace(0.0, length, n)
        uu = u * np.cos(k * z) + F / (E * A * k) * np.sin(k * z)
        ff = -u * E * A * k * np.sin(k * z) + F * np.cos(k * z)
        zs.append(z0 + z)
        us.append(uu)
        fs.append(ff)
        u, F, z0 = uu[-1], ff[-1], z0 + length
    return np.concatenate(zs), np.concatenate(us), np.concatenate(fs)


def test_dynamic_stress_and_p_min_against_the_1d_wave_model(driven):
    from fem.preload import preload_windows

    system, f_fe, wp = driven
    f1d = brentq(lambda f: _rod(2 * math.pi * f, 50)[2][-1], 0.8 * f_fe, 1.2 * f_fe)
    assert f1d == pytest.approx(f_fe, rel=0.02)              # the same mode (measured: within 1 %)
    z, u, F = _rod(2 * math.pi * f1d)
    scale = abs(wp.surfaces["bottom"]["axial"])             # FE mean axial amplitude of the back face
    rings = {"ring_1": (L_METAL, L_METAL + L_RING), "ring_2": (L_METAL + L_RING, L_METAL + 2 * L_RING)}
    win = preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, 0.0)
    by = {r.region: r for r in win.rings}
    for name, (a, b) in rings.items():
        sel = (z >= a) & (z <= b)
        sigma_1d = scale * abs(np.trapezoid(F[sel], z[sel]) / (b - a)) / A      # mean over the ring
        assert by[name].sigma_dyn_pa == pytest.approx(sigma_1d, rel=0.02)
        assert by[name].p_min_n == pytest.approx(A * sigma_1d, rel=0.02)
        # the window's upper end and the drive limit follow from the same stress (definitions)
        assert by[name].p_max_n == pytest.approx((82.7e6 - by[name].sigma_dyn_pa) * A, rel=0.01)
    assert win.drive_factor_max == pytest.approx(min(82.7e6 / (2 * max(r.sigma_dyn_pa for r in win.rings)),
                                                     1.5e6 / max(r.efield_v_per_m for r in win.rings)), rel=1e-12)


def test_verdict_names_the_failure_and_the_fix(driven):
    from fem.preload import preload_windows

    system, _f, wp = driven
    win = preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, 0.0)
    assert not win.ok and "OUTSIDE the window" in win.verdict() and "go into tension" in win.verdict()
    mid = 0.5 * (win.p_min_n + win.p_max_n)
    assert preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, mid).ok
    # the drive scaled beyond the window's end: the state scales linearly, no preload is left
    f = 1.05 * win.drive_factor_max
    over = preload_windows(system, wp.x * f, wp.voltage * f, wp.tip_amplitude_m * f, mid)
    assert over.p_min_n > over.p_max_n and not over.ok
    text = over.verdict()
    assert text.startswith("NO preload window") and "fix: drive at most" in text
    assert f"{win.drive_factor_max * wp.voltage:.4g} V" in text


def test_harmonic_stress_command_prints_and_writes_the_windows(driven, tmp_path, capsys):
    """``fem.harmonic --stress`` on the same design and drive prints every ring's window and the
    verdict, and writes the same numbers as the library call (same mesh and modes: 1e-6)."""
    import json

    from fem.harmonic_cli import main
    from fem.preload import preload_windows

    system, _f, wp = driven
    design = tmp_path / "langevin.toml"
    examples.langevin_sandwich().save(design)
    out = tmp_path / "stress"
    assert main(["--design", str(design), "--surface", "top", "--voltage", "100", "--q-mech", "100", "--tan-delta", "0", "--points", "5",
                 "--stress", str(out), "--stress-points", "0", "-q"]) == 0
    text = capsys.readouterr().out
    assert "preload window per ring" in text and "ring_1: window" in text and "OUTSIDE the window" in text
    rec = json.loads((out / "stress.json").read_text())["preload_window"]
    lib = preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, 0.0)
    assert rec["preload_n"] == 0.0 and rec["ok"] is False
    assert rec["p_min_n"] == pytest.approx(lib.p_min_n, rel=1e-6)
    assert rec["voltage_max_v"] == pytest.approx(lib.drive_factor_max * 100.0, rel=1e-6)


def _segment_bound(system, face: str, radii) -> float:
    """Sum over the face's boundary edges on the circles ``radii`` of the circular segment between
    the arc and its chord, R^2 (theta - sin theta) / 2, m^2: how far a face meshed with chords (or
    curved elements between the same nodes) can differ from the exact annulus."""
    f = system.mesh.facets(face)[:, :3]
    pts = system.mesh.points
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    total = 0.0
    for a, b in uniq[count == 1]:             # the face's boundary edges
        ra, rb = np.hypot(*pts[a, :2]), np.hypot(*pts[b, :2])
        for R in radii:
            if abs(ra - R) < 1e-6 and abs(rb - R) < 1e-6:
                th = abs(math.atan2(pts[a, 1], pts[a, 0]) - math.atan2(pts[b, 1], pts[b, 0]))
                total += R * R * (th - math.sin(th)) / 2
    return total * int(getattr(system, "sectors", 1) or 1)


def test_bolt_on_the_k0_sector_carries_p_through_every_ring():
    """The pipeline's default path is the k = 0 sector of the drill: the bolt's force pair on it
    (each sector its share, the load restricted to the k = 0 unknowns) puts -P/A on every ring's
    mean axial stress (every section carries -P: equilibrium; 1 % for the stress recovery, as the
    whole-drill check of tests/test_stress.py)."""
    from geometry.examples import article_design
    from fem.preload import preload_solve, ring_means
    from fem.sector_system import axial_sector
    from fem.stress import StressRecovery

    system = axial_sector(article_design())
    P = 10e3
    pre = preload_solve(system, P)
    A = math.pi / 4 * (0.035 ** 2 - 0.015 ** 2)
    # each face's mesh area differs from the annulus by at most the circular segments between its
    # boundary arcs and their chords (the swept mesh's geometric error), summed over its edges
    for face, area in zip(pre.faces, pre.areas_m2):
        assert area == pytest.approx(A, abs=_segment_bound(system, face, (0.0075, 0.0175)) + 1e-12 * A), face
    means = ring_means(system, StressRecovery(system).field(pre.x))
    assert len(means) == 4
    for name, (sz, _ez) in means.items():
        assert sz.real == pytest.approx(-P / A, rel=0.01), name
