"""Shared plumbing: parameter errors, TOML round trips, atomic output, CLI error handling."""

from dataclasses import dataclass, field

import pytest

from rpud_common import (
    CliParser, ParameterError, atomic_output, check_positive, dump_toml, from_mapping,
    load_toml, run_cli, to_mapping, write_json,
)


@dataclass(frozen=True)
class Inner:
    length: float = 0.01
    count: int = 4


@dataclass(frozen=True)
class Outer:
    name: str = "x"
    inner: Inner = field(default_factory=Inner)
    sizes: tuple[float, ...] = (1.0, 2.0)

    def __post_init__(self):
        check_positive("inner.length", self.inner.length, "m")


def test_toml_round_trip(tmp_path):
    obj = Outer(name="y", inner=Inner(0.02, 6), sizes=(3.0,))
    path = tmp_path / "o.toml"
    path.write_text(dump_toml(to_mapping(obj)))
    assert from_mapping(Outer, load_toml(path)) == obj


def test_unknown_key_and_bad_value_name_the_parameter():
    with pytest.raises(ParameterError, match=r"inner\.lenght"):
        from_mapping(Outer, {"inner": {"lenght": 1.0}})
    with pytest.raises(ParameterError, match=r"inner\.length = -1\.0: must be a finite number > 0 m"):
        from_mapping(Outer, {"inner": {"length": -1.0}})
    with pytest.raises(ParameterError, match=r"inner\.count"):
        from_mapping(Outer, {"inner": {"count": "four"}})


def test_atomic_output_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.json"
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    write_json(target, {"a": 1})
    assert target.read_text().strip().startswith("{")
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_run_cli_turns_parameter_error_into_one_line(capsys):
    def main(argv):
        raise ParameterError("m_free", -1.0, "must be > 0 kg")

    assert run_cli(main, [], prog="x") == 2
    err = capsys.readouterr().err
    assert err == "x: error: m_free = -1.0: must be > 0 kg\n"


def test_cli_parser_usage_error_is_one_line(capsys):
    p = CliParser(prog="y")
    p.add_argument("--n", type=int)
    with pytest.raises(SystemExit) as exc:
        p.parse_args(["--n", "abc"])
    assert exc.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_results_written_with_umask_022_are_readable_by_others(tmp_path):
    """A colleague on a shared machine can read a results folder: 0755 folders, 0644 files
    (temporary files are created 0600 and would keep that mode through the rename)."""
    import os
    import stat
    import subprocess
    import sys

    out = tmp_path / "shared"
    out.mkdir()
    cmd = [sys.executable, "-m", "impact", "--m-free", "0.008", "--members", "8", "--t-end", "0.01",
           "--json", str(out / "run.json"), "--plots", str(out / "figs")]
    subprocess.run(cmd, check=True, capture_output=True, preexec_fn=lambda: os.umask(0o022), timeout=300)
    paths = list(out.rglob("*"))             # what the command created
    assert len([p for p in paths if p.is_file()]) >= 4
    for p in paths:
        mode = stat.S_IMODE(p.stat().st_mode)
        assert mode == (0o755 if p.is_dir() else 0o644), (p, oct(mode))


def test_a_toml_integer_too_long_to_convert_is_a_parameter_error(tmp_path):
    """Python refuses int() of more than sys.get_int_max_str_digits() digits with a plain ValueError."""
    import sys

    path = tmp_path / "big.toml"
    path.write_text(f"x = {'9' * (sys.get_int_max_str_digits() + 1)}\n")
    with pytest.raises(ParameterError, match="digits"):
        load_toml(path, "--design")


def test_an_integer_beyond_the_float_range_is_not_a_finite_number():
    """math.isfinite raises OverflowError on such an int; the checks refuse it as a bad value."""
    from rpud_common import check_finite, check_positive, check_range, is_finite_number

    huge = 10 ** 400
    assert not is_finite_number(huge) and is_finite_number(3) and not is_finite_number(True)
    for check in (lambda: check_finite("x", huge), lambda: check_positive("x", huge),
                  lambda: check_range("x", huge, 0.0, 1.0)):
        with pytest.raises(ParameterError, match="x = "):
            check()


def test_an_interrupt_while_a_native_worker_runs_ends_the_process_without_finalisation(tmp_path):
    """A run interrupted while a :func:`rpud_common.cli.start_native_worker` thread still runs ends
    at once with 130 and its one line, by ``os._exit``: the interpreter's exit handlers (here an
    ``atexit`` marker file; in a real run the C library's, which crashed under the running
    worker) do not run. Without the worker, the same script exits normally and they do run."""
    import subprocess
    import sys
    import time
    from pathlib import Path

    script = tmp_path / "run.py"
    script.write_text(
        "import atexit, sys, time\n"
        "from pathlib import Path\n"
        "from rpud_common.cli import run_cli, start_native_worker\n"
        "atexit.register(lambda: Path(sys.argv[2]).write_text('finalised'))\n"
        "def main(argv):\n"
        "    if sys.argv[1] == 'worker':\n"
        "        start_native_worker(lambda: time.sleep(60), 'sleeper')\n"
        "    raise KeyboardInterrupt\n"
        "sys.exit(run_cli(main, [], prog='x', final=True))\n")
    root = Path(__file__).resolve().parents[1]
    for mode, finalised in (("worker", False), ("none", True)):
        marker = tmp_path / f"{mode}.txt"
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, str(script), mode, str(marker)], capture_output=True, text=True,
                              env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"}, timeout=60)
        assert proc.returncode == 130, proc.stderr
        assert proc.stderr.strip() == "x: interrupted"
        assert time.monotonic() - t0 < 30          # the 60 s worker was not waited for
        assert marker.exists() is finalised
