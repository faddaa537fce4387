"""Provenance: every command answers ``--version``, every JSON result says which code and which
command line wrote it, and the project carries the licence its metadata declares."""

import contextlib
import io
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rpud_common.files import json_text, write_json
from rpud_common.provenance import provenance_record, version

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _mains():
    from fem.harmonic_cli import main as harmonic
    from fem.modal_cli import main as modal
    from geometry.__main__ import main as geometry
    from impact.__main__ import main as impact
    from results.__main__ import main as results

    return {"geometry": geometry, "fem.modal": modal, "fem.harmonic": harmonic, "impact": impact,
            "results": results}


# every command line rpud has: the five entry points and the commands they dispatch to
COMMANDS = [("geometry", [], "python -m geometry"), ("fem.modal", [], "python -m fem.modal"),
            ("fem.harmonic", [], "python -m fem.harmonic"), ("impact", [], "python -m impact"),
            ("impact", ["sweep"], "python -m impact sweep"), ("impact", ["article"], "python -m impact article"),
            ("impact", ["--load", "rock"], "python -m impact --load rock"),
            ("impact", ["--horn", "fem"], "python -m impact --horn fem"), ("results", [], "python -m results"),
            ("results", ["explore"], "python -m results explore")]


@pytest.mark.parametrize("module, head, prog", COMMANDS, ids=[c[2] for c in COMMANDS])
def test_every_command_prints_its_version(module, head, prog):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as exc:
        _mains()[module]([*head, "--version"])
    assert exc.value.code in (0, None)
    assert out.getvalue().strip() == f"{prog} {version()}"


def test_version_is_the_packages():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert version() == declared


@pytest.mark.parametrize("name", ["rpud-impact", "rpud-pipeline"])
def test_installed_command_prints_its_version(name):
    exe = BIN / name
    if not exe.exists():
        pytest.skip(f"{name} not installed in this environment (pip install -e . installs it)")
    res = subprocess.run([str(exe), "--version"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == f"{name} {version()}" and res.stderr == ""


def test_record_names_version_commit_command_and_date():
    rec = provenance_record(["python", "-m", "impact", "--json", "a b.json"])
    assert rec["rpud_version"] == version()
    assert rec["command"] == "python -m impact --json 'a b.json'"       # quoted to rerun as typed
    assert rec["date_utc"].endswith("+00:00") and rec["date_utc"][:2] == "20"
    if (ROOT / ".git").exists():
        assert rec["git_commit"] is not None and len(rec["git_commit"].split("+")[0]) == 40


def test_json_results_carry_the_record_and_keep_their_keys(tmp_path):
    data = {"b": 1, "a": [1.5, 2]}
    path = write_json(tmp_path / "r.json", data)
    back = json.loads(path.read_text())
    assert list(back) == ["b", "a", "provenance"] and back["a"] == [1.5, 2]
    assert set(back["provenance"]) == {"rpud_version", "git_commit", "command", "date_utc", "python"}
    assert data == {"b": 1, "a": [1.5, 2]}                                  # the caller's dict is not changed
    # one the data already carries is kept; non-objects and resume rows get none
    assert json.loads(json_text({"provenance": {"x": 1}}))["provenance"] == {"x": 1}
    assert json.loads(json_text([1, 2])) == [1, 2]
    assert "provenance" not in json.loads(json_text({"a": 1}, provenance=False))


def test_a_command_writes_the_record_with_its_command_line(tmp_path):
    out = tmp_path / "impact.json"
    argv = ["--t-end", "0.005", "--members", "2", "--no-progress", "-q", "--json", str(out)]
    res = subprocess.run([sys.executable, "-m", "impact", *argv], capture_output=True, text=True, timeout=300,
                         cwd=ROOT)
    assert res.returncode == 0, res.stderr
    rec = json.loads(out.read_text())["provenance"]
    assert rec["command"] == "python -m impact " + " ".join(argv)
    assert rec["rpud_version"] == version()


def test_license_is_the_declared_one():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]["text"]
    text = (ROOT / "LICENSE").read_text()
    assert declared == "MIT" and text.startswith("MIT License")
    assert "the rpud developers" in text and "WITHOUT WARRANTY OF ANY KIND" in text
