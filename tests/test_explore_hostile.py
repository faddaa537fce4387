"""Hostile input to ``python -m results explore``: every refusal ends the same clean way.

Study files with values of the wrong type or range, broken resume records (a list, a FIFO, wrong
field types), schedulers that are unsupported, absent or silent, studies that would run for days:
each must end with exit code 2, exactly one stderr line naming the field, no traceback, no new
file (not even the default ``results/`` folder), before any cluster starts. The CLI runs
in-process through ``run_cli`` in a fresh folder; an interrupt of a running study is one line
(subprocess, signal to the whole process group as a terminal's Ctrl-C sends it).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rpud_common import run_cli
from results import explore as explore_mod
from results import explore_cluster, explore_cost
from results.explore_cli import main
from results.study import OUTPUTS, SAMPLINGS, STAGES

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = str(ROOT / "geometry" / "examples.toml")
NAN, INF = float("nan"), float("inf")

BASE = {"study": {"name": "h", "stages": ["mesh"], "sampling": "grid"},
        "settings": {"match": False},
        "parameters": {"horn.length": {"values": [0.067]}}}
"""A valid one-point study: every case below breaks it in one place."""


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


class _Alarm(BaseException):
    pass


def _alarm(signum, frame):
    raise _Alarm()


def refused(tmp_path: Path, study: dict | str | None, extra: list[str] = (), setup=None, limit: float = 30.0) -> str:
    """Run the CLI on ``study`` in ``tmp_path``; assert exit 2, one stderr line, no file written."""
    path = tmp_path / "s.toml"
    if study is not None:
        path.write_text(study if isinstance(study, str) else tomli_w.dumps(study))
    if setup:
        setup(tmp_path)
    before = _files(tmp_path)
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(tmp_path)
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, limit)   # a hang fails the test instead of blocking the suite
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = run_cli(main, ["s.toml", "-q", *extra], prog="results")
    except SystemExit as exc:
        code = exc.code
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        os.chdir(cwd)
    text = err.getvalue()
    assert code == 2, f"exit {code}, stderr {text!r}"
    assert text.count("\n") == 1 and text.endswith("\n") and "Traceback" not in text, text
    assert _files(tmp_path) == before, f"new files {sorted(_files(tmp_path) - before)}"
    return text


def _with(**tables) -> dict:
    """BASE with keys of [study] and [settings] replaced (None removes one), other tables replaced."""
    data = json.loads(json.dumps(BASE))
    for table, changes in tables.items():
        if table not in ("study", "settings") or not isinstance(changes, dict):
            data[table] = changes
            continue
        target = data.setdefault(table, {})
        for k, v in changes.items():
            if v is None:
                target.pop(k, None)
            else:
                target[k] = v
    return data


# ----------------------------------------------------------------------------- study file: every key

STUDY_BAD = {
    "name": [5, [], {"a": 1}, True, "", "a/b", "x" * 81, 1.5],
    "design": [5, [], {"a": 1}, True, "", "no_such.toml"],
    "select": [5, [], {"a": 1}, True, "langevin"],
    "stages": [5, "mesh", [], [5], [["mesh"]], ["mesh", "mesh"], ["match"], ["mesh", "bogus"], {"a": 1}, True],
    "sampling": [5, [], {"a": 1}, True, "sobol", ["grid"]],
    "samples": ["x", 1.5, -1, True, [1], 10 ** 6],
    "seed": ["x", 1.5, -1, True, [1], 2 ** 40],
    "outputs": [5, "f_r_hz", [["f_r_hz"]], ["tetrahedra", "tetrahedra"], ["bogus"], [5], {"a": 1}, ["f_r_hz"]],
    "pareto": [5, "x", ["tetrahedra"], ["tetrahedra", "tetrahedra"], ["tetrahedra", "nodes", "tetrahedra"],
               [["tetrahedra"]], {"a": 1}],
    "colour": [1],
}

SETTINGS_BAD = {
    "voltage": ["x", -1.0, 0, NAN, INF, 1e300, 10 ** 400, True, [1.0]],
    "q_mech": ["x", 0.5, -INF, NAN, 1e9, False, {"a": 1}],
    "mesh_size": ["x", -0.01, NAN, INF, 5.0, True, [0.01]],
    "match": [1, "yes", [True], 0.0],
    "scenario": [5, "space", [], True],
    "rel_tol": [0, -0.1, 2.0, "x", NAN, True],
    "max_members": [1, 1.5, "x", 10 ** 7, True, [64]],
    "tip_surface": [5, ["a"], "a b", "x" * 100, True],
    "bogus": [1],
}


@pytest.mark.parametrize("key, value", [(k, v) for k, vs in STUDY_BAD.items() for v in vs],
                         ids=lambda x: repr(x)[:30])
def test_study_table_key_of_wrong_type_or_range(tmp_path, key, value):
    text = refused(tmp_path, _with(study={key: value}))
    assert f"study.{key}" in text


@pytest.mark.parametrize("key, value", [(k, v) for k, vs in SETTINGS_BAD.items() for v in vs],
                         ids=lambda x: repr(x)[:30])
def test_settings_key_of_wrong_type_or_range(tmp_path, key, value):
    text = refused(tmp_path, _with(settings={key: value}))
    assert f"settings.{key}" in text


PARAMETER_BAD = [
    ({"horn.length": {"values": 5}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": []}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": [[0.06]]}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": ["a"]}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": [NAN]}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": [1e300]}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": [10 ** 400]}}, "parameters.horn.length.values"),
    ({"horn.length": {"values": [0.06, 0.06]}}, "parameters.horn.length.values"),
    ({"horn.length": {"range": [0.06]}}, "parameters.horn.length.range"),
    ({"horn.length": {"range": [0.07, 0.06], "n": 3}}, "parameters.horn.length.range"),
    ({"horn.length": {"range": "x", "n": 3}}, "parameters.horn.length.range"),
    ({"horn.length": {"range": [0.06, 0.07], "n": 1}}, "parameters.horn.length.n"),
    ({"horn.length": {"range": [0.06, 0.07], "n": 2.5}}, "parameters.horn.length.n"),
    ({"horn.length": {"range": [0.06, 0.07], "n": "3"}}, "parameters.horn.length.n"),
    ({"horn.length": {"values": [0.06], "range": [0.06, 0.07], "n": 2}}, "parameters.horn.length"),
    ({"horn.length": {"values": [0.06], "tolerance": 0.1}}, "parameters.horn.length.tolerance"),
    ({"horn.length": {"values": [0.06], "bogus": 1}}, "parameters.horn.length.bogus"),
    ({"horn.length": {}}, "parameters.horn.length"),
    ({"horn.length": 5}, "parameters.horn.length"),
    ({"horn.length": [0.06]}, "parameters.horn.length"),
    ({"horn": {"length": {"values": [0.06]}}}, "parameters.horn.length"),
    ({"horn.colour": {"values": [1.0]}}, "parameters.horn.colour"),
    ({"horn.material": {"values": [1.0]}}, "parameters.horn.material"),
    ({"coupler": {"values": [1.0]}}, "parameters.coupler"),
    ({"coupler.n_slots": {"values": [4.5]}}, "parameters.coupler.n_slots"),
    ({"a..b": {"values": [1.0]}}, "parameters.a..b"),
    ({"drive.colour": {"values": [1.0]}}, "parameters.drive.colour"),
    ({"impact.colour": {"values": [1.0]}}, "parameters.impact.colour"),
]


@pytest.mark.parametrize("params, where", PARAMETER_BAD, ids=lambda x: repr(x)[:40])
def test_parameter_tables(tmp_path, params, where):
    text = refused(tmp_path, _with(parameters=params))
    assert where in text


@pytest.mark.parametrize("data, where", [
    (_with(study={"stages": ["mesh", "match", "harmonic"]}, parameters={"drive.voltage": {"values": [-5.0]}}),
     "parameters.drive.voltage"),
    (_with(study={"stages": list(STAGES)}, parameters={"impact.e1": {"values": [2.0]}}),
     "parameters.impact.e1"),
    (_with(study={"stages": ["mesh"]}, parameters={"impact.m_free": {"values": [0.004]}}),
     "parameters.impact.m_free"),
    # tolerance sampling around a field that is not a number (a material name), or is 0
    (_with(study={"sampling": "tolerance", "samples": 4}, parameters={"horn.material": {"tolerance": 0.1}}),
     "parameters.horn.material"),
    (_with(study={"sampling": "tolerance", "samples": 4, "stages": list(STAGES)},
           parameters={"impact.spring_force": {"tolerance": 0.1}}), "parameters.impact.spring_force"),
    (_with(study={"sampling": "lhs", "samples": 4}, parameters={"coupler.n_slots": {"range": [4, 8]}}),
     "parameters.coupler.n_slots"),
    (_with(study={"sampling": "lhs", "samples": 4}, parameters={"horn.length": {"values": [0.06]}}),
     "parameters.horn.length"),
    # list sampling: [[points]]
    (_with(study={"sampling": "list"}, parameters={}, points=5), "points"),
    (_with(study={"sampling": "list"}, parameters={}, points=[]), "points"),
    (_with(study={"sampling": "list"}, parameters={}, points=[{}]), "points"),
    (_with(study={"sampling": "list"}, parameters={}, points=[{"horn.length": 0.06}, {"horn.length": 0.06}]),
     "points[1]"),
    (_with(study={"sampling": "list"}, parameters={}, points=[{"horn.length": 0.06}, {"coupler.length": 0.05}]),
     "points[1]"),
    (_with(study={"sampling": "list"}, parameters={}, points=[{"horn.length": "x"}]), "points[0].horn.length"),
    (_with(study={"sampling": "list"}, points=[{"horn.length": 0.06}]), "parameters.horn.length"),
    (_with(points=[{"horn.length": 0.06}]), "points"),
    # whole tables of the wrong type, unknown tables
    (_with(study=5), "study"),
    (_with(settings=5), "settings"),
    (_with(parameters=5), "parameters"),
    (_with(parameters={}), "parameters"),
    (_with(colour={"a": 1}), "colour"),
])
def test_study_families(tmp_path, data, where):
    assert where in refused(tmp_path, data)


def test_default_results_folder_that_is_a_file(tmp_path):
    (tmp_path / "results").write_text("not a folder")
    refused(tmp_path, BASE)


def test_study_file_itself(tmp_path):
    refused(tmp_path, "[study\nname = ")
    refused(tmp_path, "[study]\nseed = " + "9" * 5000 + "\n")
    refused(tmp_path, "[study]\nname = 'x'\n" + "a = [" * 40 + "]" * 40 + "\n")
    (tmp_path / "s.toml").unlink()
    refused(tmp_path, None)
    os.mkfifo(tmp_path / "s.toml")
    refused(tmp_path, None)


# ----------------------------------------------------------------------------- study file: fuzz

_JUNK = st.recursive(
    st.one_of(st.integers(), st.sampled_from([10 ** 400, -10 ** 400]), st.floats(), st.text(max_size=12),
              st.booleans()),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.text(min_size=1, max_size=6), inner, max_size=2)),
    max_leaves=5)


def _not(*types):
    return _JUNK.filter(lambda v: isinstance(v, bool) or not isinstance(v, types))


_NOT_LIST_OF_NAMES = st.one_of(_not(list), st.lists(_not(str), min_size=1, max_size=3),
                               st.lists(st.text(max_size=6).filter(lambda t: t not in OUTPUTS and t not in STAGES),
                                        min_size=1, max_size=3))
_OUT_OF_RANGE = st.sampled_from([NAN, INF, -INF, -1.0, 1e300, -1e-300, 10 ** 400])
WRONG = {
    ("study", "name"): st.one_of(_not(str), st.text(min_size=81), st.just(""), st.just("a b")),
    ("study", "design"): st.one_of(_not(str), st.just("")),
    ("study", "select"): st.one_of(_not(str), st.text(min_size=1, max_size=8)),
    ("study", "stages"): _NOT_LIST_OF_NAMES,
    ("study", "sampling"): st.one_of(_not(str), st.text(max_size=8).filter(lambda t: t not in SAMPLINGS)),
    ("study", "samples"): st.one_of(_not(int), st.integers(max_value=-1), st.integers(10 ** 6, 2 ** 63 - 1)),
    ("study", "seed"): st.one_of(_not(int), st.integers(max_value=-1), st.integers(2 ** 32, 2 ** 63 - 1)),
    ("study", "outputs"): _NOT_LIST_OF_NAMES,
    ("study", "pareto"): _NOT_LIST_OF_NAMES,
    ("settings", "voltage"): st.one_of(_not(int, float), _OUT_OF_RANGE),
    ("settings", "q_mech"): st.one_of(_not(int, float), _OUT_OF_RANGE),
    ("settings", "mesh_size"): st.one_of(_not(int, float), _OUT_OF_RANGE),
    ("settings", "rel_tol"): st.one_of(_not(int, float), _OUT_OF_RANGE),
    ("settings", "match"): _JUNK.filter(lambda v: not isinstance(v, bool)),
    ("settings", "scenario"): st.one_of(_not(str),
                                        st.text(max_size=8).filter(lambda t: t not in ("device", "article"))),
    ("settings", "max_members"): st.one_of(_not(int), st.integers(max_value=1), st.integers(10 ** 6 + 1, 2 ** 63 - 1)),
    ("settings", "tip_surface"): st.one_of(_not(str), st.just("a b")),
    ("parameters", "horn.length"): st.one_of(_not(dict), st.fixed_dictionaries({"values": _not(list)}),
                                             st.fixed_dictionaries({"values": st.lists(_not(int, float), min_size=1,
                                                                                       max_size=3)}),
                                             st.fixed_dictionaries({"range": _JUNK, "n": _not(int)})),
}


@settings(max_examples=150, derandomize=True, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.sampled_from(sorted(WRONG)), min_size=1, max_size=3, unique=True).flatmap(
    lambda keys: st.tuples(*[st.tuples(st.just(k), WRONG[k]) for k in keys])))
def test_fuzzed_study_files_are_refused(tmp_path_factory, changes):
    tmp = tmp_path_factory.mktemp("fuzz")
    data = json.loads(json.dumps(BASE))
    for (table, key), value in changes:
        data[table][key] = value
    refused(tmp, data)


# ----------------------------------------------------------------------------- resume store

def _store_study(tmp_path: Path):
    """The one-point study, its point id and a record as the run writes it."""
    from results.study import load_study

    (tmp_path / "s.toml").write_text(tomli_w.dumps(BASE))
    study = load_study(tmp_path / "s.toml")
    pid = explore_mod.point_id(study, 0, study.points()[0])
    rec = {"point": 0, "id": pid, "in.horn.length": 0.067, "status": "ok", "error": "", "failed_stage": "",
           "tetrahedra": 12925, "nodes": 21794, "mesh_s": 1.4}
    return pid, rec


def _write_store(tmp_path: Path, name: str, content) -> None:
    store = tmp_path / ".o.resume"
    store.mkdir(exist_ok=True)
    path = store / name
    if callable(content):
        content(path)
    else:
        path.write_bytes(content if isinstance(content, bytes) else json.dumps(content).encode())


def _symlink(path: Path, rec: dict) -> None:
    real = path.parent / "real"
    real.write_text(json.dumps(rec))
    path.symlink_to(real)


def _changed(rec, **kw):
    out = dict(rec)
    for k, v in kw.items():
        if v is None:
            out.pop(k, None)
        else:
            out[k] = v
    return out


@pytest.mark.parametrize("case", [
    "list", "no_status", "status_int", "point_str", "point_bool", "output_str", "output_bool", "input_str",
    "inputs_differ", "unknown_field", "nan_literal", "id_mismatch", "ok_with_error", "failed_no_stage",
    "missing_output", "not_utf8", "not_json", "deep", "huge", "fifo", "folder", "symlink", "foreign_list",
])
def test_bad_resume_record_is_refused(tmp_path, case):
    pid, rec = _store_study(tmp_path)
    name = f"{pid}.json"
    contents = {
        "list": [rec], "no_status": _changed(rec, status=None), "status_int": _changed(rec, status=1),
        "point_str": _changed(rec, point="0"), "point_bool": _changed(rec, point=False),
        "output_str": _changed(rec, tetrahedra="many"), "output_bool": _changed(rec, nodes=True),
        "input_str": _changed(rec, **{"in.horn.length": "x"}),
        "inputs_differ": _changed(rec, **{"in.horn.length": 0.5}),
        "unknown_field": _changed(rec, colour=1), "id_mismatch": _changed(rec, id="p00000-0000000000"),
        "ok_with_error": _changed(rec, error="boom"), "failed_no_stage": _changed(rec, status="failed", error="x"),
        "missing_output": _changed(rec, nodes=None),
        "nan_literal": json.dumps(rec).replace('"mesh_s": 1.4', '"mesh_s": NaN').encode(),
        "not_utf8": b"\xff\xfe{}", "not_json": b"{", "deep": b"[" * 100_000 + b"]" * 100_000,
        "huge": b" " * (explore_mod.MAX_RECORD_BYTES + 1) + json.dumps(rec).encode(),
        "fifo": lambda p: os.mkfifo(p), "folder": lambda p: p.mkdir(),
        "symlink": lambda p: _symlink(p, rec),
    }
    if case == "foreign_list":
        name, content = "p00007-0123456789.json", [1, 2]
    else:
        content = contents[case]
    _write_store(tmp_path, name, content)
    t0 = time.monotonic()
    text = refused(tmp_path, None, ["--out", "o", "--resume"], limit=20)
    assert time.monotonic() - t0 < 15
    assert name in text and "resume" in text


@pytest.mark.parametrize("resume", [True, False])
def test_resume_store_that_is_not_a_folder(tmp_path, resume):
    _store_study(tmp_path)
    os.mkfifo(tmp_path / ".o.resume")
    text = refused(tmp_path, None, ["--out", "o"] + (["--resume"] if resume else []), limit=20)
    assert ".o.resume" in text and "FIFO" in text


def test_valid_and_foreign_records_resume_without_a_cluster(tmp_path):
    """A record as the run writes it is taken (no cluster is needed: nothing is left to compute);
    a well-formed record of other settings is ignored, and not copied into the results."""
    pid, rec = _store_study(tmp_path)
    _write_store(tmp_path, f"{pid}.json", rec)
    other = _changed(rec, id="p00000-0123456789")
    _write_store(tmp_path, "p00000-0123456789.json", other)
    err = io.StringIO()
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = run_cli(main, ["s.toml", "-q", "--out", "o", "--resume", "--no-figures"], prog="results")
    finally:
        os.chdir(cwd)
    assert code == 0 and err.getvalue() == ""
    summary = json.loads((tmp_path / "o" / "study.json").read_text())
    assert summary["resumed"] == 1 and summary["computed"] == 0
    assert sorted(p.name for p in (tmp_path / "o" / "points").iterdir()) == [f"{pid}.json"]
    assert not (tmp_path / ".o.resume").exists()


# ----------------------------------------------------------------------------- scheduler

@pytest.mark.parametrize("address", ["tls://127.0.0.1:8786", "ucx://127.0.0.1:8786", "inproc://x", "ws://h:1",
                                     "nonsense", "tcp://", "tcp://h", "tcp://h:0", "tcp://h:99999", "tcp://a b:1",
                                     "tcp://h:1\n2", " ", "x" * 400])
def test_scheduler_address_refused(tmp_path, address):
    assert "--scheduler" in refused(tmp_path, BASE, ["--scheduler", address])


@contextlib.contextmanager
def _silent_server():
    """A TCP server that accepts connections and never answers."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    held = []

    def accept():
        with contextlib.suppress(OSError):
            while True:
                held.append(srv.accept()[0])

    threading.Thread(target=accept, daemon=True).start()
    try:
        yield srv.getsockname()[1]
    finally:
        srv.close()
        for c in held:
            c.close()


def test_silent_scheduler_ends_within_the_timeout(tmp_path, monkeypatch):
    monkeypatch.setattr(explore_cluster, "SCHEDULER_TIMEOUT_S", 1.5)
    with _silent_server() as port:
        t0 = time.monotonic()
        text = refused(tmp_path, BASE, ["--scheduler", f"tcp://127.0.0.1:{port}"], limit=20)
        assert time.monotonic() - t0 < 10
    assert "--scheduler" in text and "1.5 s" in text


def test_scheduler_without_workers_is_refused(tmp_path):
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=None) as cluster:
        text = refused(tmp_path, BASE, ["--scheduler", cluster.scheduler_address])
    assert "no workers" in text


# ----------------------------------------------------------------------------- cost

@pytest.mark.parametrize("data", [
    # 300 x 300 over all stages: one FE chain, 90 000 impact ensembles
    _with(study={"stages": list(STAGES)},
          parameters={"impact.m_free": {"range": [0.002, 0.008], "n": 300},
                      "drive.voltage": {"range": [100.0, 300.0], "n": 300}}),
    # a 100 000-sample hypercube of designs
    _with(study={"sampling": "lhs", "samples": 100_000}, parameters={"horn.length": {"range": [0.06, 0.07]}}),
    # one point on a mesh far finer than the FE budget
    _with(settings={"mesh_size": 2e-4}),
])
def test_long_study_is_refused_with_its_estimate(tmp_path, data):
    t0 = time.monotonic()
    text = refused(tmp_path, data)
    assert "--allow-large" in text and time.monotonic() - t0 < 20


def test_point_count_is_capped_before_expanding(tmp_path):
    t0 = time.monotonic()
    data = _with(parameters={k: {"range": [0.01, 0.02], "n": 1000} for k in ("horn.length", "coupler.length",
                                                                             "coupler.slot_depth")})
    assert "at most 100000 points" in refused(tmp_path, data)
    assert time.monotonic() - t0 < 10


def test_cost_estimate_shares_fe_tasks():
    from results.study import load_study

    study = load_study(ROOT / "results" / "examples" / "study_free_mass_voltage.toml")
    cost = explore_mod.estimate_cost(study, study.points(), 2)
    assert (cost.points, cost.meshes, cost.harmonics) == (12, 1, 1)
    one_chain = explore_cost.MESH_SECONDS + explore_cost.MODAL_SECONDS + explore_cost.HARMONIC_SECONDS
    assert cost.core_seconds > one_chain and cost.seconds < explore_cost.MAX_HOURS * 3600


def test_help_documents_the_override(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "--allow-large" in capsys.readouterr().out


# ----------------------------------------------------------------------------- runs

def _langevin_study(tmp_path: Path, points: int) -> None:
    lengths = ", ".join(f"{0.030 + 0.001 * k:.3f}" for k in range(points))
    (tmp_path / "s.toml").write_text(
        f'[study]\nname = "i"\ndesign = "{EXAMPLES}"\nselect = "langevin"\nstages = ["mesh"]\n'
        f'[settings]\nmesh_size = 0.012\n[parameters."segments.front.length"]\nvalues = [{lengths}]\n')


def _start(tmp_path: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "results", "explore", "s.toml", "--workers", "2", *extra],
                            cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_normal_run_is_silent_on_stderr(tmp_path):
    """No Dask log line, from this process or its workers; the default results/ folder is made."""
    _langevin_study(tmp_path, 2)
    proc = _start(tmp_path, "-q", "--no-figures")
    _, err = proc.communicate(timeout=180)
    assert proc.returncode == 0 and err == "", err
    assert len(list((tmp_path / "results" / "study-i" / "points").glob("p*.json"))) == 2


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_is_one_line(tmp_path, sig):
    """A signal to the whole process group (a terminal's Ctrl-C) while the cluster computes."""
    _langevin_study(tmp_path, 30)
    proc = _start(tmp_path, "--out", "o", "-q")
    store = tmp_path / ".o.resume"
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60 and not list(store.glob("p*.json")) and proc.poll() is None:
        time.sleep(0.1)
    os.killpg(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert err.splitlines() == ["results: interrupted" if sig == signal.SIGINT else "results: terminated"], err
    assert not (tmp_path / "o").exists()
