"""SIGINT -> "interrupted", exit 130; SIGTERM -> "terminated", exit 143; nothing half-written.

In-process: ``run_cli`` with a signal raised inside ``atomic_output``/``atomic_folder`` (the last
pipeline stage writes through them). Subprocess: the geometry CLI while Gmsh meshes, and the
pipeline during its mesh and modal stages, with a previous results folder that must survive.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from geometry.common import atomic_folder, atomic_output, run_cli, write_json

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                             (signal.SIGTERM, 143, "terminated")])
def test_signal_inside_atomic_writers_leaves_nothing(tmp_path, capsys, sig, code, word):
    out = tmp_path / "res"
    out.mkdir()
    (out / "old.txt").write_text("previous run")

    def main(argv):
        with atomic_folder(out) as tmp:
            write_json(tmp / "summary.json", {"a": 1})
            with atomic_output(tmp_path / "x.json") as part:
                part.write_text("half")
                os.kill(os.getpid(), sig)
                time.sleep(5)                   # the handler raises before this ends
        return 0

    assert run_cli(main, [], prog="p") == code
    assert capsys.readouterr().err == f"p: {word}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]
    assert [p.name for p in out.iterdir()] == ["old.txt"]
    assert signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, signal.default_int_handler) or callable(
        signal.getsignal(signal.SIGTERM))


def test_atomic_folder_swaps_whole(tmp_path):
    out = tmp_path / "res"
    out.mkdir()
    (out / "old.txt").write_text("previous run")
    with atomic_folder(out) as tmp:
        (tmp / "new.txt").write_text("new run")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]
    assert [p.name for p in out.iterdir()] == ["new.txt"]


def test_nan_result_is_refused_before_any_file(tmp_path, capsys):
    def main(argv):
        write_json(tmp_path / "o.json", {"fit": {"slope": float("nan")}})

    assert run_cli(main, [], prog="p") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fit.slope" in err
    assert list(tmp_path.iterdir()) == []


def _run_and_signal(args, sig, cwd, marker=None, delay=2.0, timeout=120):
    """Start ``python -m args``; send ``sig`` when ``marker`` is printed (or after ``delay`` s)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", *args], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        if marker is None:
            time.sleep(delay)
        else:
            t0 = time.time()
            for line in proc.stdout:
                if marker in line or time.time() - t0 > timeout:
                    break
            time.sleep(0.5)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


@pytest.mark.xfail(strict=False, reason="about 1 run in 5 the abandoned Gmsh worker crashes the process "
                                       "after the clean line (SIGSEGV) before os._exit; open issue")
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                             (signal.SIGTERM, 143, "terminated")])
def test_geometry_cli_while_gmsh_meshes(tmp_path, sig, code, word):
    rc, err = _run_and_signal(["geometry", "--json", "out.json", "--mesh", "out.msh", "-q"], sig, tmp_path,
                              delay=2.5)
    assert rc == code, err
    assert err.strip().splitlines()[-1].endswith(word) and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("sig, code, word, marker", [
    (signal.SIGINT, 130, "interrupted", "[1/7]"),
    (signal.SIGTERM, 143, "terminated", "[2/7]"),
])
def test_pipeline_stages_end_cleanly(tmp_path, sig, code, word, marker):
    out = tmp_path / "res"
    out.mkdir()
    (out / "old.txt").write_text("previous run")
    rc, err = _run_and_signal(["results", "--out", "res", "--no-match", "--no-render"], sig, tmp_path,
                              marker=marker)
    assert rc == code, err
    assert err.strip().splitlines()[-1].endswith(word) and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]
    assert [p.name for p in out.iterdir()] == ["old.txt"]
