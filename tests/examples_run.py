"""Running the literate examples of results/examples/ as a user runs them (a fresh interpreter, an
empty working folder) with their ``--fast`` settings, as the documentation's gallery runs them.
Shared by tests/test_examples.py and tests/test_examples_studies.py (two files, so the two
``--dist loadfile`` workers share the examples' minutes)."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "results" / "examples"
TEST_FILES = ("test_examples.py", "test_examples_studies.py")
"""The files whose tests run the examples (each example in one of them)."""


def run_example(name, tmp_path):
    """Run example ``name`` with ``--fast`` in ``tmp_path``: its stdout and its output folder
    (the example must end with exit 0; its stderr's tail is the failure message)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, str(EXAMPLES / name), "--fast"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout, tmp_path / "example_output"
