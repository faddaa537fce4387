"""Hostile options of every command line other than ``geometry`` and ``results explore``.

Families: options that apply only with another one, given without it; empty text and
subnormal numbers; ``python -m impact --g 0`` (a weightless free mass, no spring) in bounded
time; output paths where nothing can be written (/proc, /sys: unwritable even for root),
refused before any computation; the inputs line every command prints first, with units; the
one-line warning on a value far outside the drill's range (a likely unit slip).

Refusals run in-process through ``run_cli`` (``tests/test_cli_fuzz.run_clean``: exit 2, one
stderr line, no traceback, no new file); the echo tests stop each command right after its
inputs line by replacing its first expensive call.
"""

from __future__ import annotations

import contextlib
import io
import time

import pytest

from rpud_common import ParameterError, run_cli
from rpud_common.cli import check_usual, inputs_lines, quantity

from test_cli_fuzz import run_clean


def _impact(argv):
    from impact.__main__ import main

    return main(argv)


def _results(argv):
    from results.__main__ import main

    return main(argv)


def _modal(argv):
    from fem.modal_cli import main

    return main(argv)


def _harmonic(argv):
    from fem.harmonic_cli import main

    return main(argv)


QUICK = ["--members", "2", "--t-end", "0.001", "--no-progress"]
"""A kinematic impact run of a few milliseconds."""


# ----------------------------------------------------------------------------- dependent options


@pytest.mark.parametrize("main, argv, names", [
    (_results, ["--wob", "5"], ("--wob", "--load rock")),
    (_results, ["--coupled-modes", "3", "--no-coupled-model"], ("--coupled-modes", "--no-coupled-model")),
    (_impact, ["--wob", "5"], ("--wob", "--load rock")),
    (_impact, ["sweep", "--m-free", "0.004", "--drill-time", "9"], ("--drill-time", "--load rock")),
    (_impact, ["--voltage", "100"], ("--voltage", "--horn fem")),
    (_impact, ["--members", "8", "--rel-tol", "0.1"], ("--rel-tol", "--members")),
    (_impact, ["sweep", "--m-free", "0.004", "--members", "8", "--max-members", "9"], ("--max-members", "--members")),
    (_impact, ["--m-horn", "0.1"], ("--m-horn", "--horn-law article")),
    (_impact, ["--horn", "fem", "--contact", "hunt-crossley", "--history", "0.01"], ("--history", "hunt-crossley")),
    (_impact, ["--horn", "fem", "--contact", "hunt-crossley", "--sample-dt", "1e-6"], ("--sample-dt", "hunt-crossley")),
    (_impact, ["--horn", "fem", "--members", "4", "--rel-tol", "0.1"], ("--rel-tol", "--members")),
    (_harmonic, ["--preload", "0"], ("--preload", "--stress")),
    (_harmonic, ["--stress-points", "21"], ("--stress-points", "--stress")),
    (_harmonic, ["--converge", "1e-3", "--points", "10"], ("--converge", "--points")),
    (_harmonic, ["--converge", "1e-3", "--stress", "s"], ("--converge", "--stress")),
    (_modal, ["--bracket", "0.5,2.0"], ("--bracket", "--match")),
    (_modal, ["--harmonics", "0,1", "--sectors", "off"], ("--harmonics", "--sectors")),
])
def test_an_option_without_the_one_it_needs_is_refused_naming_both(main, argv, names):
    text = run_clean(main, argv)
    assert all(name in text for name in names), text


# ----------------------------------------------------------------------------- empty and subnormal values


@pytest.mark.parametrize("main, argv, name", [
    (_harmonic, ["--band="], "--band"),
    (_harmonic, ["--surface="], "--surface"),
    (_harmonic, ["--ring-up", "1e-320"], "--ring-up"),
    (_harmonic, ["--ring-up", "1e-12"], "--ring-up"),          # normal, but no time to ring up in
    (_harmonic, ["--tan-delta", "1e-320"], "--tan-delta"),
    (_harmonic, ["--stress", "s", "--preload", "1e-320"], "--preload"),
    (_modal, ["--match", "--tune="], "--tune"),
    (_modal, ["--clamp="], "--clamp"),
    (_modal, ["--near", "1e-320"], "--near"),
    (_results, ["--load", "rock", "--wob", "1e-320"], "--wob"),
    (_results, ["--rel-tol", "1e-300"], "--rel-tol"),
    (_impact, ["--t-end", "1e-300"], "t_end"),
    (_impact, ["--rel-tol", "1e-300"], "--rel-tol"),
    (_impact, ["--load", "rock", "--wob", "1e-320"], "--wob"),
    (_impact, ["--load", "rock", "--rel-tol", "1e-300"], "--rel-tol"),
    (_impact, ["--horn", "fem", "--series-resistance", "1e-300"], "--series-resistance"),
    (_impact, ["--horn", "fem", "--design="], "--design"),
])
def test_empty_and_subnormal_values_are_refused(main, argv, name):
    assert name in run_clean(main, argv)


# ----------------------------------------------------------------------------- a weightless free mass


def test_weightless_free_mass_runs_in_bounded_time():
    """g = 0 and no spring: the free mass flies straight between the horn and the tool (which
    sends it back). The horn's contact search must close once the flight leaves the horn's
    band, as it does under gravity: the adaptive run as fast as with g (it took ~7x as long
    while the search stayed open over the whole flight)."""

    def best(argv):
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            assert run_cli(_impact, argv) == 0
            times.append(time.perf_counter() - t0)
        return min(times)

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert _impact(QUICK) == 0                          # compiled kernel loaded
        weightless = best(["--g", "0", "--no-progress"])
        under_gravity = best(["--g", "9.8", "--no-progress"])
    assert weightless < 5.0 and weightless < 3.0 * under_gravity + 0.05, (weightless, under_gravity)
    assert "free-mass/tool impacts per second" in out.getvalue()


def test_weightless_free_mass_same_events_in_both_engines():
    from impact.model import simulate
    from impact.params import ImpactParams

    for p in (ImpactParams(g=0.0), ImpactParams(g=0.0, v0=0.3, t_end=0.02)):
        assert simulate(p).events() == simulate(p, engine="python").events()


# ----------------------------------------------------------------------------- unwritable outputs


@pytest.mark.parametrize("main, argv", [
    (_results, ["--out", "/proc/rpud-results"]),
    (_impact, ["--json", "/proc/x.json"]),
    (_impact, ["--plots", "/sys/rpud-plots"]),
    (_impact, ["sweep", "--m-free", "0.004", "--csv", "/proc/x.csv"]),
    (_impact, ["article", "--out", "/proc/rpud-article"]),
    (_impact, ["--load", "rock", "--json", "/proc/x.json"]),
    (_impact, ["--load", "rock", "--plots", "/proc/rpud-plots"]),
    (_impact, ["--horn", "fem", "--json", "/proc/x.json"]),
    (_impact, ["--horn", "fem", "--history-csv", "/sys/x.csv"]),
    (_impact, ["--horn", "fem", "--plots", "/proc/rpud-plots"]),
    (_modal, ["--json", "/proc/x.json"]),
    (_modal, ["--vtu", "/proc/x.vtu"]),
    (_modal, ["--render", "/proc/rpud-render"]),
    (_modal, ["--match", "--out-design", "/proc/x.toml"]),
    (_harmonic, ["--json", "/proc/x.json"]),
    (_harmonic, ["--plots", "/sys/rpud-plots"]),
    (_harmonic, ["--stress", "/proc/rpud-stress"]),
    (_impact, ["--json", "/dev/null"]),                   # replacing it would replace the device
])
def test_unwritable_outputs_are_refused_before_any_work(main, argv, monkeypatch):
    import geometry

    monkeypatch.setattr(geometry, "build_mesh", lambda *a, **k: pytest.fail("meshed before refusing"))
    t0 = time.perf_counter()
    text = run_clean(main, argv)
    assert time.perf_counter() - t0 < 5.0
    assert any(word in text for word in ("not writable", "not a regular file")), text


def test_an_existing_output_folder_must_take_files(tmp_path, monkeypatch):
    from rpud_common import check_output_paths
    from rpud_common import files

    locked = tmp_path / "locked"
    locked.mkdir()
    real = files._writable
    monkeypatch.setattr(files, "_writable", lambda d: "Read-only file system" if d == locked else real(d))
    with pytest.raises(ParameterError, match="is a folder that is not writable"):
        check_output_paths(plots=str(locked), folders=("plots",))
    assert sorted(tmp_path.iterdir()) == [locked] and not list(locked.iterdir())


# ----------------------------------------------------------------------------- the inputs line


class _Stop(Exception):
    """Raised by the stand-in of a command's first expensive call."""


def _stop(*args, **kwargs):
    raise _Stop


def _echo(main, argv, capsys) -> tuple[str, str]:
    """stdout up to the first expensive call, and stderr."""
    with pytest.raises(_Stop):
        main(argv)
    captured = capsys.readouterr()
    return captured.out, captured.err


def _first(out: str) -> str:
    lines = out.splitlines()
    assert lines and lines[0].startswith("inputs: "), out
    return " ".join(line.strip() for line in lines if line.startswith(("inputs: ", "       ")))


def test_impact_echoes_its_inputs_with_units(capsys):
    assert _impact(QUICK) == 0
    line = _first(capsys.readouterr().out)
    for part in ("free mass 8 g", "A0 15 um", "f 20 kHz", "tool mass 50 g", "gap 2.15 mm", "g 9.8 m/s^2",
                 "members 2", "seed 20260"):
        assert part in line, line
    assert _impact(QUICK + ["-q"]) == 0
    assert "inputs:" not in capsys.readouterr().out


def test_impact_sweep_and_article_echo_their_inputs(capsys, monkeypatch):
    assert _impact(["sweep", "--m-free", "0.002,0.004"] + QUICK) == 0
    assert "free masses 2 g, 4 g" in _first(capsys.readouterr().out)
    import impact.article

    monkeypatch.setattr(impact.article, "reproduce", _stop)
    out, _ = _echo(_impact, ["article", "--out", "a", "--no-progress"], capsys)
    assert "free mass 8 g" in _first(out) and "Table 1" in _first(out)


def test_drilling_echoes_its_inputs(capsys, monkeypatch):
    import impact.drilling_cli

    monkeypatch.setattr(impact.drilling_cli, "drilling_sweep", _stop)
    out, err = _echo(_impact, ["--load", "rock", "--m-free", "0,0.004"], capsys)
    line = _first(out)
    assert "WOB 7 N" in line and "free masses 0 kg, 4 g" in line and "A0 15 um" in line and "f 19.95 kHz" in line
    assert err == ""


def test_coupled_model_echoes_its_inputs(capsys, monkeypatch):
    import results.coupled

    monkeypatch.setattr(results.coupled, "build_transducer", _stop)
    out, _ = _echo(_impact, ["--horn", "fem", "--voltage", "100"], capsys)
    line = _first(out)
    assert "design rpud-default" in line and "voltage 100 V" in line and "free mass 8 g" in line
    assert "history 50 ms" in line


def test_pipeline_echoes_its_inputs(capsys, monkeypatch, tmp_path):
    import results.pipeline

    monkeypatch.setattr(results.pipeline, "run_pipeline", _stop)
    out, _ = _echo(_results, ["--out", str(tmp_path / "r"), "--load", "rock", "--wob", "9"], capsys)
    line = _first(out)
    assert "design rpud-default" in line and "voltage 225 V" in line and "mesh swept sector 1/6 (k = 0)" in line
    assert "WOB 9 N" in line and "Q_mech 100 (assumed)" in line
    assert not (tmp_path / "r").exists()


def test_fem_commands_echo_their_inputs(capsys, monkeypatch):
    import fem.matching
    import geometry

    monkeypatch.setattr(geometry, "build_mesh", _stop)
    line = _first(_echo(_harmonic, ["--voltage", "100", "--points", "50"], capsys)[0])
    assert "design rpud-default" in line and "voltage 100 V" in line and "50 points" in line
    line = _first(_echo(_modal, ["--modes", "6", "--sectors", "off"], capsys)[0])
    assert "design rpud-default" in line and "modes 6" in line and "sectors off" in line
    monkeypatch.setattr(fem.matching, "match", _stop)
    line = _first(_echo(_modal, ["--match", "--target", "20500"], capsys)[0])
    assert "20.5 kHz" in line and "mesher free" in line
    with pytest.raises(_Stop):
        _harmonic(["-q"])
    assert capsys.readouterr().out == ""


# ----------------------------------------------------------------------------- unit slips


def test_eight_kilograms_of_free_mass_run_with_a_one_line_warning(capsys):
    assert _impact(["--m-free", "8"] + QUICK) == 0
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "--m-free 8 kg" in err and "did you mean 0.008 (8 g)?" in err
    assert "free mass 8 kg" in _first(out)
    assert _impact(["--m-free", "8", "-q"] + QUICK) == 0          # quiet: no echo, the warning stays
    out, err = capsys.readouterr()
    assert "inputs:" not in out and "--m-free 8 kg" in err


def test_a_drive_voltage_far_above_the_drills_warns(capsys, monkeypatch):
    import geometry

    monkeypatch.setattr(geometry, "build_mesh", _stop)
    out, err = _echo(_harmonic, ["--voltage", "5000"], capsys)
    assert err.count("\n") == 1 and "--voltage 5000 V" in err and "warning" in err
    assert "voltage 5 kV" in _first(out)


def test_slip_guess_and_quantities():
    assert [quantity(v, u) for v, u in ((0.008, "kg"), (8.0, "kg"), (15e-6, "m"), (19950.0, "Hz"), (0.9, ""))] == \
        ["8 g", "8 kg", "15 um", "19.95 kHz", "0.9"]
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert check_usual("p", "--freq", 20.0, "freq")
        assert not check_usual("p", "--freq", 20e3, "freq")
    assert err.getvalue() == "p: warning: --freq 20 Hz: the drill vibrates at 10-50 kHz; did you mean 20000 (20 kHz)?\n"
    lines = inputs_lines({"a": "x" * 60, "b": "y" * 60})
    assert lines[0].startswith("inputs: a ") and lines[1].startswith("       b ")
