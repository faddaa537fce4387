"""The command lines state the discretisation error: ``python -m fem.harmonic --error / --converge``,
``python -m fem.modal --match --error`` (fem.errors, fem.errors_cli).

Small cases (a PZT-4 k33 rod, 8 mm mesh): the numbers are checked against the estimator's own
definition, |q(h) - q(1.4 h)| / (r^p - 1) with the coarse values and r written in the same JSON
(order 2: no re-entrant edges), and against a direct call of fem.errors.estimate; the estimator's
accuracy is tests/test_discretisation_error.py's.
"""

import json

import pytest

from geometry.examples import k33_rod

ROD = ["--surface", "electrode_top", "--mesh-size", "0.008", "--modes", "4"]


@pytest.fixture(scope="module")
def rod(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rod")
    k33_rod().save(folder / "rod.toml")
    return folder


def _two_level(block, q, fine):
    return abs(fine - block["coarse"][q]) / (block["ratio"] ** block["order"] - 1)


def test_harmonic_error_prints_and_writes_every_error(rod, capsys):
    from fem.harmonic_cli import main

    out = rod / "h.json"
    assert main(["--design", str(rod / "rod.toml"), *ROD, "--points", "5", "--error", "--json", str(out), "-q"]) == 0
    text = capsys.readouterr().out
    assert "estimated discretisation error:" in text and "order 2 assumed" in text
    d = json.loads(out.read_text())
    wm, wp, block = d["working_mode"], d["working_point"], d["discretisation_error"]
    assert block["order"] == 2.0 and not block["reentrant_edges"] and block["coarse_refine"] == pytest.approx(1.4)
    for q in ("f_r_hz", "f_a_hz", "k_eff"):
        assert wm[f"{q}_error"] == pytest.approx(_two_level(block, q, wm[q]), rel=0.05)     # 2 significant digits
        assert wm[f"{q}_error"] == block["errors"][q]
    assert wp["tip_per_volt_m_error"] == pytest.approx(_two_level(block, "tip_per_volt_m", wp["tip_per_volt_m"]), rel=0.05)
    # the amplitude at the drive voltage carries the same relative error
    assert wp["tip_amplitude_m_error"] / wp["tip_amplitude_m"] == pytest.approx(
        wp["tip_per_volt_m_error"] / wp["tip_per_volt_m"], rel=1e-9)
    assert f"f_r {wm['f_r_hz']:.1f} Hz" in text.splitlines()[0]          # the plain line is unchanged
    assert "±" in text


def test_harmonic_converge_runs_the_study(rod, capsys):
    from fem.harmonic_cli import main

    out = rod / "c.json"
    rc = main(["--design", str(rod / "rod.toml"), *ROD, "--refine", "1.5", "--converge", "1e-3", "--json", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and "order p" in text and "Richardson" in text and "converged" in text
    c = json.loads(out.read_text())["convergence"]
    assert len(c["levels"]) == 3 and c["converged"]
    assert [lv["refine"] for lv in c["levels"]] == pytest.approx([1.5, 1.2, 0.96])
    assert {"f_r_hz", "f_a_hz", "k_eff", "tip_per_volt_m"} <= set(c["levels"][-1])
    assert c["estimate"]["tip_per_volt_m"]["change"] < 1e-3


@pytest.mark.parametrize("argv, what", [
    (["--converge", "0.5"], "--converge"),
    (["--converge", "1e-3", "--error"], "--converge"),
    (["--converge", "1e-3", "--freq", "30000"], "--converge"),
    (["--error", "--mode", "1"], "--error"),
    (["--error", "--freq", "30000"], "--error"),
    (["--error", "--refine", "4"], "--refine"),
])
def test_harmonic_error_options_refused_before_meshing(rod, argv, what, monkeypatch):
    """Refused with a ParameterError naming the option (the launcher's one line, exit 2) before any mesh."""
    import geometry
    from fem.harmonic_cli import main
    from rpud_common import ParameterError

    monkeypatch.setattr(geometry, "build_mesh", lambda *a, **k: pytest.fail("meshed before refusing"))
    with pytest.raises(ParameterError, match=what):
        main(["--design", str(rod / "rod.toml"), *ROD, *argv])


def test_match_error_on_the_tuned_design(rod, capsys):
    from fem.errors import estimate
    from fem.modal_cli import main

    out = rod / "m.json"
    argv = ["--match", "--design", str(rod / "rod.toml"), "--tune", "segments.rod.length", "--target", "39000",
            "--mesh-size", "0.008", "--error", "--json", str(out), "--out-design", str(rod / "tuned.toml")]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "estimated discretisation error:" in text and "±" in text
    d = json.loads(out.read_text())
    w, block = d["working_mode"], d["discretisation_error"]
    mode = d["modes"][w]
    assert mode["f_r_hz_error"] == d["matched_hz_error"] == block["errors"]["f_r_hz"]
    assert mode["k_eff_error"] == pytest.approx(_two_level(block, "k_eff", mode["k_eff"]), rel=0.05)
    # the same estimate as a direct call on the tuned design (deterministic)
    from geometry.design import load_design

    tuned = load_design(rod / "tuned.toml")
    est = estimate(tuned, {"f_r_hz": mode["f_r_hz"]}, d["ndof"], mesh_size=0.008, near_hz=39000.0, harmonic=False)
    assert est.error("f_r_hz") == mode["f_r_hz_error"]
