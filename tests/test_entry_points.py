"""Console entry points: declared in pyproject, installed with the package, each the same
command line as its ``python -m`` twin (help exits 0, bad input is one line and exit 2)."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rpud_common.entry import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def test_pyproject_declares_every_command():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {name: f"rpud_common.entry:{func}" for name, func in COMMANDS.items()}


@pytest.mark.parametrize("name, bad", [("rpud-geometry", "--mesh-size=-1"), ("rpud-modal", "--modes=abc"),
                                       ("rpud-harmonic", "--voltage=inf"), ("rpud-impact", "--m-free=-1"),
                                       ("rpud-pipeline", "--voltage=nan")])
def test_installed_command_runs_like_python_m(name, bad):
    exe = BIN / name
    if not exe.exists():
        pytest.skip(f"{name} not installed in this environment (pip install -e . installs it)")
    ok = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0 and ok.stdout.startswith(f"usage: {name}")
    err = subprocess.run([str(exe), bad], capture_output=True, text=True, timeout=120)
    assert err.returncode == 2 and err.stdout == ""
    lines = err.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{name}: ")
