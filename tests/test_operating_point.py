"""The operating point every drive command states: the voltage convention and the default losses.

References: the definition of a sinusoid's RMS value (V / sqrt 2, exact) and the one default
of :mod:`fem.losses` (every command that drives the transducer must resolve to it).
"""

from __future__ import annotations

import math

import pytest

from rpud_common import ParameterError
from rpud_common.voltage import DriveVoltage

from test_hostile_options import _echo, _first, _harmonic, _results, _stop
from test_cli_fuzz import run_clean


def test_rms_voltage_is_the_amplitude_over_root_two():
    d = DriveVoltage(225.0)
    assert d.rms_v == pytest.approx(225.0 / math.sqrt(2), rel=1e-15)
    assert d.text() == "225 V amplitude (159.1 V rms)"
    r = DriveVoltage(100.0 * math.sqrt(2), "rms")
    assert r.given_v == pytest.approx(100.0, rel=1e-15) and r.text().startswith("100 V rms")
    assert r.record() == {"amplitude_v": r.amplitude_v, "rms_v": r.rms_v, "peak_to_peak_v": 2 * r.amplitude_v,
                          "given_as": "rms"}
    with pytest.raises(ParameterError, match="convention"):
        DriveVoltage(1.0, "peak-to-peak")


def _coupled(argv):
    from results.coupled_cli import main

    return main(argv)


@pytest.mark.parametrize("main, extra", [(_harmonic, []), (_results, []), (_coupled, ["--horn", "fem"])])
def test_every_drive_command_echoes_the_convention_and_the_default_losses(main, extra, capsys, monkeypatch):
    """--voltage is an amplitude, --voltage-rms an RMS value; each command prints which one ran
    and the same assumed Q_mech (fem.losses.ASSEMBLED_Q_MECH)."""
    import geometry
    import results.coupled
    import results.pipeline
    from fem.losses import ASSEMBLED_Q_MECH

    monkeypatch.setattr(geometry, "build_mesh", _stop)
    monkeypatch.setattr(results.pipeline, "run_pipeline", _stop)
    monkeypatch.setattr(results.coupled, "build_transducer", _stop)
    line = _first(_echo(main, extra + ["--voltage-rms", "100"], capsys)[0])
    assert "voltage 100 V rms (141.4 V amplitude)" in line
    assert f"Q_mech {ASSEMBLED_Q_MECH:g} (assumed)" in line
    line = _first(_echo(main, extra + ["--voltage", "100"], capsys)[0])
    assert "voltage 100 V amplitude (70.71 V rms)" in line


@pytest.mark.parametrize("main", [_harmonic, _results])
def test_voltage_and_rms_voltage_together_are_refused(main):
    err = run_clean(main, ["--voltage", "100", "--voltage-rms", "70"])
    assert "not allowed with argument" in err


def test_pipeline_and_harmonic_share_the_default_losses():
    from fem.losses import ASSEMBLED_Q_MECH, default_losses
    from results.pipeline import PipelineSettings

    s = PipelineSettings()
    assert s.q_mech == ASSEMBLED_Q_MECH and s.losses() == default_losses()
    assert "not measured" in s.losses().source
    assert PipelineSettings(q_mech=None).losses().origin == "datasheet"


def test_report_states_the_bolt_model_form_of_each_kind_of_design():
    """The operating-point table's bolt row: a design without a bolt part quotes the stiffness a
    part would add (measured on the article's drill), one with a part how much the other joint
    model moves f_r (measured on the bolted example) and what neither models; the figures are the
    documented constants', printed to their stated digits."""
    import geometry
    from fem.preload import BOLT_JOINT_FR_SHIFT, ELASTIC_BOLT_FR_SHIFT
    from geometry.examples import article_design, bolted_design
    from results.operating_point import bolt_row

    def row(design):
        return bolt_row(design.to_mapping()["stack"])

    bare = row(article_design())
    assert f"{100 * ELASTIC_BOLT_FR_SHIFT[0]:+.2f} ± {100 * ELASTIC_BOLT_FR_SHIFT[1]:.2f} %" in bare
    assert "no elastic part" in bare
    shift, err = BOLT_JOINT_FR_SHIFT
    threaded = row(geometry.default_design())
    assert "joint 'thread'" in threaded and f"{-100 * shift:+.2f} ± {100 * err:.2f} %" in threaded
    assert "flanks' compliance is not modelled" in threaded
    faces = row(bolted_design())
    assert "joint 'faces'" in faces and f"{100 * shift:+.2f} ± {100 * err:.2f} %" in faces
    assert bolt_row({}) is None                                # a stack design: no row
